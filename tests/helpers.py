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


def assert_one_line(res, message: str = "") -> None:
    """A failed CLI command (typer's CliRunner result) printed one ``antisync: error:`` line
    containing ``message``, exit 2, no traceback."""
    assert res.exit_code == 2, (res.exit_code, res.output)
    assert "Traceback" not in res.output, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("antisync: error: "), res.stderr
    assert message in lines[0], (message, lines[0])
