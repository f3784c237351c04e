"""Provenance of a result file and of a writer lock: the command, the git revision, the time."""

from __future__ import annotations

import datetime as _dt
import subprocess
import sys
from pathlib import Path

__all__ = ["command_line", "git_revision", "now"]


def git_revision() -> str:
    """The source checkout's git revision, or '' when antisync does not run from a checkout."""
    here = Path(__file__).resolve().parent.parent.parent  # antisync/store/ -> the checkout
    try:
        out = subprocess.run(
            ["git", "-C", str(here), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            timeout=5,
        )
    except (OSError, subprocess.SubprocessError):
        return ""
    return out.stdout.strip() if out.returncode == 0 else ""


def command_line() -> str:
    """The command that runs, as a user would type it (``python -m antisync`` included)."""
    name = Path(sys.argv[0]).name
    if name == "__main__.py":
        name = "antisync"
    return " ".join([name] + sys.argv[1:])


def now() -> str:
    """The current UTC time, ISO 8601 to the second."""
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
