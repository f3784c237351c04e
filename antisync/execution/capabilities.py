"""What runs where: every (model, ``lambda.method``, integrator, backend, precision) cell.

The table is not written by hand: :func:`cell` builds a lollipop config with the cell's values
and asks the checks that a real run goes through (the config's own validation,
:meth:`antisync.plan.config.Config`'s model checks, and :func:`antisync.execution.compute.check_backend`)
whether it runs; a refused cell carries the one-line message a user would get. So the table
cannot disagree with the code. A cell that runs on backend cuda but does part of its work on
the CPU says so (:func:`antisync.execution.compute.host_part`, also printed by the run).
``python -m antisync.execution.capabilities`` prints the table as markdown; docs/models.md shows it
(tests/test_capabilities.py checks that the copy there is current).

The two model rows are the identical first-order oscillators of the paper and a generalized
model (natural frequencies drawn per realization: ``model: {frequencies: {distribution: normal,
sd: 0.1}}``; with inertia, a phase lag or another sync criterion the same cells run). Checks
that depend on the data rather than on these five choices are not cells: ``orbit`` needs a
model that keeps the graph's automorphisms (fixed per-node frequencies, inertia or damping do
not), ``relative`` needs fixed frequencies, a CUDA run at most ``MAX_NODES`` nodes, float32 a
threshold it can resolve.
"""

from __future__ import annotations

from antisync.errors import AntisyncError
from antisync.types import BACKENDS, INTEGRATORS, LAMBDA_METHODS, PRECISIONS

__all__ = ["MODELS", "cell", "table"]

#: the model rows: name -> the config's ``model:`` section
MODELS = {
    "identical": "{}",
    "model": "{frequencies: {distribution: normal, sd: 0.1}}",
}
_GRAPH = "graph: {kind: lollipop, nodes: 6, path: 3}\nedges: ['2->1']\nbetas: []\nrealizations: 10\n"


def cell(model: str, method: str, integrator: str, backend: str, precision: str) -> tuple[bool, str | None]:
    """``(runs, why)``: whether the cell runs, and the one-line message that refuses it, or
    for a cell that runs what of it runs on the CPU all the same (else None)."""
    from antisync.execution.compute import check_backend, host_part
    from antisync.plan.config import load_config_text

    text = (
        _GRAPH
        + f"model: {MODELS[model]}\nlambda: {{method: {method}}}\n"
        + f"dynamics: {{integrator: {integrator}, precision: {precision}, dt: 0.01}}\n"
    )
    try:
        config = load_config_text(text)
        check_backend(config, backend)
    except AntisyncError as err:
        return False, str(err)
    return True, host_part(config, backend)


def table() -> str:
    """The markdown table: a row per (model, method), a column per (backend, precision,
    integrator): "runs", or a footnote, which says why the cell is refused (the message a run
    gets) or, for "runs [k]", what of it runs on the CPU."""
    backends = [b for b in BACKENDS if b != "auto"]
    columns = [(b, p, i) for b in backends for p in PRECISIONS for i in INTEGRATORS]
    notes: dict[str, int] = {}
    head = "| model | lambda.method | " + " | ".join(f"{b} {p} {i}" for b, p, i in columns) + " |"
    lines = [head, "|" + "---|" * (2 + len(columns))]
    for model in MODELS:
        for method in LAMBDA_METHODS:
            cells = []
            for b, p, i in columns:
                runs, why = cell(model, method, i, b, p)
                mark = "" if why is None else f"[{notes.setdefault(why, len(notes) + 1)}]"
                cells.append(f"runs {mark}".strip() if runs else mark)
            lines.append(f"| {model} | {method} | " + " | ".join(cells) + " |")
    lines.append("")
    lines += [f"[{k}] {why}  " for why, k in notes.items()]
    return "\n".join(lines).rstrip() + "\n"


if __name__ == "__main__":
    print(table(), end="")
