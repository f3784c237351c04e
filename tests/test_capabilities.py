"""The table of what runs where (antisync/execution/capabilities.py) and its copy in docs/models.md."""

from __future__ import annotations

from pathlib import Path

import pytest

from antisync.execution.capabilities import cell, table
from antisync.execution.compute import host_part
from antisync.plan.config import load_config_text

DOCS = Path(__file__).resolve().parent.parent / "docs" / "models.md"


def test_the_docs_show_the_current_table():
    text = DOCS.read_text()
    begin, end = "<!-- capabilities:begin -->\n", "<!-- capabilities:end -->"
    copy = text[text.index(begin) + len(begin) : text.index(end)]
    assert copy == table(), "docs/models.md is stale: paste `python -m antisync.execution.capabilities` there"


@pytest.mark.parametrize(
    "args, runs, words",
    [
        (("identical", "finite-difference", "euler", "cpu", "float64"), True, None),
        (("identical", "adjoint", "rk4", "cpu", "float64"), True, None),
        (("identical", "finite-difference", "euler", "cuda", "float32"), True, None),
        (("identical", "adjoint", "euler", "cuda", "float64"), True, "Lambda pass on the CPU"),
        (("identical", "orbit", "euler", "cuda", "float32"), False, "float32 runs lambda.method finite"),
        (("identical", "adjoint", "rk4", "cuda", "float64"), False, "rk4 runs on the cpu backend only"),
        (("identical", "pathwise", "rk4", "cpu", "float64"), False, "needs dynamics.integrator euler"),
        (("model", "finite-difference", "rk4", "cuda", "float64"), True, None),
        (("model", "adjoint-hybrid", "rk4", "cuda", "float64"), True, "Lambda pass on the CPU"),
        (("model", "hybrid", "euler", "cpu", "float64"), False, "use adjoint or adjoint-hybrid"),
        (("model", "adjoint", "euler", "cpu", "float32"), False, "float64 only"),
    ],
)
def test_cells_are_the_run_checks_answers(args, runs, words):
    got_runs, why = cell(*args)
    assert got_runs == runs
    if words is None:
        assert why is None
    else:
        assert words in why


def test_a_cuda_model_run_says_what_stays_on_the_cpu():
    cfg = load_config_text(
        "graph: {kind: lollipop, nodes: 6, path: 3}\nmodel: {phase_lag: 0.1}\nlambda: {method: adjoint}\n"
    )
    assert "Lambda pass on the CPU" in host_part(cfg, "cuda")
    assert host_part(cfg, "cpu") is None
    plain = load_config_text("graph: {kind: lollipop, nodes: 6, path: 3}\n")
    assert host_part(plain, "cuda") is None
    derivative = load_config_text("graph: {kind: lollipop, nodes: 6, path: 3}\nlambda: {method: hybrid}\n")
    assert host_part(derivative, "cuda") == "lambda.method hybrid runs its Lambda pass on the CPU"
