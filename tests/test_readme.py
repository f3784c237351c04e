"""Every command the README prints is checked here, so the front door cannot point anywhere
that does not work.

A shell block's lines are read as commands (a trailing ``\\`` joins lines, ``#`` starts a
comment). ``make T``: the Makefile has target T. ``antisync run CONFIG ...`` is validated with
its overrides (``antisync validate``; its ``--realizations`` and ``--out`` become ``--set``s),
and a ``summary`` or ``report`` must read a file an earlier ``run`` of its block writes.
``antisync paper`` runs as ``--dry-run``; ``antisync grid [static] CONFIG`` runs for real, and
the config of ``grid removal|trip`` (or ``--removal``) is validated. The Python block runs as
written (its output path moved to a temporary folder) and its printed number is the paper's
within 4 standard errors.
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parent.parent
README = REPO / "README.md"


def _blocks(lang: str) -> list[str]:
    """The README's fenced blocks whose opening fence names ``lang`` ("" for a bare fence)."""
    blocks, current, inside = [], [], None
    for line in README.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            if inside is None:
                inside, current = line[3:].strip(), []
            else:
                if inside == lang:
                    blocks.append("\n".join(current) + "\n")
                inside = None
        elif inside is not None:
            current.append(line)
    return blocks


def _commands(block: str) -> list[list[str]]:
    joined = re.sub(r"\\\n\s*", " ", block)
    out = []
    for line in joined.splitlines():
        words = shlex.split(line, comments=True)
        if words:
            out.append(words)
    return out


def _cli(*args: str, cwd: Path = REPO) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "antisync", *args], capture_output=True, text=True, cwd=cwd)


def _targets() -> set[str]:
    text = (REPO / "Makefile").read_text(encoding="utf-8")
    return set(re.findall(r"^([A-Za-z0-9_-]+):", text, flags=re.M))


def _run_to_validate(words: list[str]) -> tuple[list[str], str]:
    """``antisync run CONFIG [options]`` -> (``validate`` arguments, the output it writes)."""
    config, rest, sets = words[2], words[3:], []
    out = None
    while rest:
        opt = rest.pop(0)
        if opt == "--set":
            sets.append(rest.pop(0))
        elif opt == "--realizations":
            sets.append(f"realizations={rest.pop(0)}")
        elif opt == "--out":
            out = rest.pop(0)
        elif opt in ("--resume", "--overwrite", "--quiet", "-q"):
            pass
        else:
            raise AssertionError(f"README: an option this test does not know: {opt} in {words}")
    if out is None:
        out = yaml.safe_load((REPO / config).read_text(encoding="utf-8"))["output"]
    args = ["validate", config]
    for s in sets:
        args += ["--set", s]
    return args, out


def test_every_shell_command_of_the_readme_works(tmp_path):
    blocks = _blocks("")
    assert len(blocks) >= 4, "the README's shell blocks were not found"
    seen = set()
    for block in blocks:
        written = set()
        for words in _commands(block):
            what = " ".join(words)
            if words[0] == "make":
                assert words[1] in _targets(), f"README: no make target {words[1]!r}"
            elif words[:2] == ["antisync", "run"]:
                args, out = _run_to_validate(words)
                res = _cli(*args)
                assert res.returncode == 0, f"README: {what}\n{res.stderr}"
                written.add(out)
            elif words[:2] in (["antisync", "summary"], ["antisync", "report"]):
                assert words[2] in written, f"README: {what} reads a file no run above it writes"
            elif words[:2] == ["antisync", "paper"]:
                res = _cli(*words[1:], "--dry-run")
                assert res.returncode == 0 and "min" in res.stdout, f"README: {what}\n{res.stderr}"
            elif words[:2] == ["antisync", "grid"] and (
                "--removal" in words or words[2] in ("removal", "trip")
            ):
                res = _cli("validate", words[3] if words[2] in ("removal", "trip") else words[2])
                assert res.returncode == 0, f"README: {what}\n{res.stderr}"
            elif words[:2] == ["antisync", "grid"]:
                res = _cli(*words[1:])
                assert res.returncode == 0 and "intact:" in res.stdout, f"README: {what}\n{res.stderr}"
            else:
                raise AssertionError(f"README: a command this test does not check: {what}")
            seen.add(tuple(words[:2]))
    assert {("make", "run"), ("make", "test"), ("antisync", "run"), ("antisync", "grid")} <= seen


def test_the_readmes_python_runs_and_prints_the_papers_number(tmp_path):
    (block,) = _blocks("python")
    out = tmp_path / "example.h5"
    assert '"/tmp/example.h5"' in block
    code = block.replace('"/tmp/example.h5"', repr(str(out)))
    namespace: dict = {}
    import contextlib
    import io
    import os

    here = os.getcwd()
    os.chdir(REPO)  # the block names configs/ relative to the checkout, as a reader runs it there
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            exec(compile(code, "README.md", "exec"), namespace)
    finally:
        os.chdir(here)
    rec = namespace["res"].records[0]
    assert rec["edge"] == "2->1" and rec["beta"] == 0.5 and out.is_file()
    assert abs(rec["F_mean"] - 1.181) < 4 * rec["F_se"], rec  # the paper's <F_0.5> of 2->1
