"""The table of what runs where: the dispatch table (antisync/execution/dispatch.py) that runs the
chunks, printed by antisync/execution/capabilities.py and `antisync capabilities`, and its copy
in docs/models.md. Every cell goes through the same checks: a refusal is what a run of it is told,
a CPU row runs a chunk."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.errors import ConfigError
from antisync.execution.capabilities import cell, table
from antisync.execution.compute import check_backend, compute_chunk, host_part
from antisync.execution.dispatch import DRIVERS, PASSES, TABLE, Key, Row
from antisync.plan.config import load_config_text
from antisync.plan.jobs import make_job

DOCS = Path(__file__).resolve().parent.parent / "docs" / "models.md"

#: the model kinds' config sections (a generalized model: natural frequencies drawn per realization)
MODELS = {
    "identical": "{}",
    "model": "{frequencies: {distribution: normal, sd: 0.1}}",
    "law": "{law: stuart-landau, params: {omega: 0.2}}",
}
REFUSED = [key for key, row in TABLE.items() if isinstance(row, str)]
RUNS_ON_CPU = [key for key, row in TABLE.items() if isinstance(row, Row) and key.backend == "cpu"]


def _name(key: Key) -> str:
    return "-".join(key)


def config_text(key: Key, realizations: int = 10) -> str:
    """A lollipop config choosing the cell ``key`` (but its backend)."""
    return (
        "graph: {kind: lollipop, nodes: 6, path: 3}\nedges: ['2->1']\nbetas: [0.5]\n"
        f"realizations: {realizations}\nblock_size: 2\nmodel: {MODELS[key.model]}\n"
        f"lambda: {{method: {key.method}}}\n"
        f"dynamics: {{integrator: {key.integrator}, precision: {key.precision}, dt: 0.01, t_max: 50}}\n"
    )


def test_the_docs_show_the_current_table():
    text = DOCS.read_text()
    begin, end = "<!-- capabilities:begin -->\n", "<!-- capabilities:end -->"
    copy = text[text.index(begin) + len(begin) : text.index(end)]
    assert copy == table(), "docs/models.md is stale: paste `antisync capabilities` there"


def test_the_cli_prints_the_table():
    res = CliRunner().invoke(app, ["capabilities"])
    assert res.exit_code == 0
    assert res.output == table()


def test_every_cell_is_a_row_or_a_refusal():
    """Every combination of the five choices, and a row wherever a driver and a pass exist
    unless a check refuses it."""
    assert len(TABLE) == len(MODELS) * 7 * 3 * 2 * 2  # methods, integrators, backends, precisions
    for key, row in TABLE.items():
        if isinstance(row, Row):
            assert row.driver is DRIVERS[key.model, key.integrator, key.backend]
            assert row.lambda_pass is PASSES[key.model, key.method]
        else:
            assert row and "\n" not in row


@pytest.mark.parametrize("key", list(TABLE), ids=_name)
def test_a_cell_is_what_a_run_of_it_is_told(key):
    """Load the cell's config and check it for its backend as a run does: a refused cell's
    message is the run's error, byte for byte (the config's on load or the backend check's);
    a cell that runs passes both, and the run says what stays on the CPU as the table does."""
    expected = TABLE[key]
    try:
        config = load_config_text(config_text(key))
        row = check_backend(config, key.backend)
    except ConfigError as err:
        assert str(err) == expected
        return
    assert row is expected
    assert host_part(config, key.backend) == row.host_part == cell(*key)[1]


@pytest.mark.parametrize(
    "args, runs, words",
    [
        (("identical", "finite-difference", "euler", "cpu", "float64"), True, None),
        (("identical", "adjoint", "rk4", "cpu", "float64"), True, None),
        (("identical", "finite-difference", "euler", "cuda", "float32"), True, None),
        (("identical", "adjoint", "euler", "cuda", "float64"), True, "Lambda pass on the CPU"),
        (("identical", "orbit", "euler", "cuda", "float32"), False, "float32 runs lambda.method finite"),
        (("identical", "adjoint", "rk4", "cuda", "float64"), False, "rk4 runs on the cpu backend only"),
        (("identical", "central-difference", "rk4", "cuda", "float32"), False, "float32 runs lambda.method"),
        (("identical", "central-difference", "rk4", "cpu", "float32"), False, "float32 runs dynamics.integ"),
        (("identical", "pathwise", "rk4", "cpu", "float64"), False, "needs dynamics.integrator euler"),
        (("model", "finite-difference", "rk4", "cuda", "float64"), True, None),
        (("model", "adjoint-hybrid", "rk4", "cuda", "float64"), True, "Lambda pass on the CPU"),
        (("model", "hybrid", "euler", "cpu", "float64"), False, "use adjoint or adjoint-hybrid"),
        (("model", "hybrid", "rk4", "cpu", "float32"), False, "needs dynamics.integrator euler"),
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


@pytest.mark.parametrize("key", RUNS_ON_CPU, ids=_name)
def test_every_cpu_row_runs(key):
    """A chunk of every CPU row runs end to end (tiny: 4 realizations) and gives finite Lambda
    records of its one edge; the undamaged records are the same whatever the estimator (the
    same tau0 trajectories), checked against the finite difference's row."""
    job = make_job(load_config_text(config_text(key, realizations=4)))
    got = [compute_chunk(job, chunk, "cpu", threads=1) for chunk in job.chunks(2)]
    assert sum(r.count for r in got) == 4
    assert all(np.isfinite(r.lam_rec).all() and r.lam_rec.shape[0] >= 1 for r in got)
    fd = make_job(load_config_text(config_text(key._replace(method="finite-difference"), realizations=4)))
    want = [compute_chunk(fd, chunk, "cpu", threads=1) for chunk in fd.chunks(2)]
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a.rec0, b.rec0)


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


def test_the_cuda_driver_of_the_identical_oscillators_refuses_interpolated_crossings():
    cfg = load_config_text("graph: {kind: lollipop, nodes: 6, path: 3}\ndynamics: {crossing: interpolated}\n")
    check_backend(cfg, "cpu")
    with pytest.raises(ConfigError, match="crossing interpolated runs on the cpu backend only"):
        check_backend(cfg, "cuda")
    model = load_config_text(
        "graph: {kind: lollipop, nodes: 6, path: 3}\nmodel: {phase_lag: 0.1}\n"
        "dynamics: {crossing: interpolated}\n"
    )
    check_backend(model, "cuda")
