"""Small helpers shared by test modules (tests/ is on sys.path, see conftest.py)."""

import json

# How long a test waits for a process of its own before calling it hung. A hang guard, not a
# speed target: a fresh process may first compile every kernel (numba caches by source), and
# CI machines are slower and busier than a workstation (a simulator check that takes 11 s here
# once took over 240 s there).
HANG_GUARD_S = 1800


def comparable(summary: dict) -> dict:
    """The parts of a sweep summary that must be identical between two runs of one sweep
    (screening times and file paths left out), as plain JSON types."""
    out = {k: summary[k] for k in ("records", "top", "excluded", "symmetry", "complete")}
    out["screen"] = [{k: v for k, v in s.items() if k != "seconds"} for s in summary["screen"]]
    out["jobs"] = summary["meta"]["jobs"]
    return json.loads(json.dumps(out))
