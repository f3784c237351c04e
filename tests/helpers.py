"""Small helpers shared by test modules (tests/ is on sys.path, see conftest.py)."""

import json


def comparable(summary: dict) -> dict:
    """The parts of a sweep summary that must be identical between two runs of one sweep
    (screening times and file paths left out), as plain JSON types."""
    out = {k: summary[k] for k in ("records", "top", "excluded", "symmetry", "complete")}
    out["screen"] = [{k: v for k, v in s.items() if k != "seconds"} for s in summary["screen"]]
    out["jobs"] = summary["meta"]["jobs"]
    return json.loads(json.dumps(out))
