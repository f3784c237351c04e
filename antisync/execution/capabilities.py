"""What runs where: every (model, ``lambda.method``, integrator, backend, precision) cell.

The table printed here is the dispatch table (:data:`antisync.execution.dispatch.TABLE`) that
runs the chunks: a cell that runs is a row holding the driver and the Lambda pass that do the
work, a refused cell the one-line message a user gets (the config's on load, or
:func:`antisync.execution.compute.check_backend`'s). So the table cannot disagree with the code.
A cell that runs on backend cuda but does part of its work on the CPU says so (the row's
``host_part``, also printed by the run). ``python -m antisync.execution.capabilities`` and
``antisync capabilities`` print the table as markdown; docs/models.md shows it
(tests/test_capabilities.py checks that the copy there is current, that every cell marked
"runs" runs, and that every refusal is what a run of that cell is told).

The two model rows are the identical first-order oscillators of the paper and a generalized
model (any ``model:`` or ``sync:`` section: drawn or fixed natural frequencies, inertia, a phase
lag, another sync criterion; the same cells run). Checks that depend on the data rather than on
these five choices are not cells: ``orbit`` needs a model that keeps the graph's automorphisms
(fixed per-node frequencies, inertia or damping do not), ``relative`` needs fixed frequencies,
a CUDA run at most ``MAX_NODES`` nodes, float32 a threshold it can resolve, and the CUDA kernels
of the identical oscillators grid crossing times.
"""

from __future__ import annotations

from antisync.execution.dispatch import DESIGN_REFUSALS, MODEL_KINDS, RESOLVED_BACKENDS, TABLE, TRIP_ROWS, Key
from antisync.types import INTEGRATORS, LAMBDA_METHODS, PRECISIONS

__all__ = ["cell", "table"]


def cell(model: str, method: str, integrator: str, backend: str, precision: str) -> tuple[bool, str | None]:
    """``(runs, why)``: whether the cell runs, and the one-line message that refuses it, or
    for a cell that runs what of it runs on the CPU all the same (else None)."""
    row = TABLE[Key(model, method, integrator, backend, precision)]
    if isinstance(row, str):
        return False, row
    return True, row.host_part


def table() -> str:
    """The markdown table: a row per (model, method), a column per (backend, precision,
    integrator): "runs", or a footnote, which says why the cell is refused (the message a run
    gets) or, for "runs [k]", what of it runs on the CPU."""
    columns = [(b, p, i) for b in RESOLVED_BACKENDS for p in PRECISIONS for i in INTEGRATORS]
    notes: dict[str, int] = {}
    head = "| model | lambda.method | " + " | ".join(f"{b} {p} {i}" for b, p, i in columns) + " |"
    lines = [head, "|" + "---|" * (2 + len(columns))]
    for model in MODEL_KINDS:
        for method in LAMBDA_METHODS:
            cells = []
            for b, p, i in columns:
                runs, why = cell(model, method, i, b, p)
                mark = "" if why is None else f"[{notes.setdefault(why, len(notes) + 1)}]"
                cells.append(f"runs {mark}".strip() if runs else mark)
            lines.append(f"| {model} | {method} | " + " | ".join(cells) + " |")
    lines.append("")
    lines += [f"[{k}] {why}  " for why, k in notes.items()]
    runs = [i for i, why in TRIP_ROWS.items() if why is None]
    lines += ["", f"Line trips (`antisync grid --trip`, cpu float64): {', '.join(runs)}.  "]
    lines += [f"{i}: {why}.  " for i, why in TRIP_ROWS.items() if why is not None]
    designs = [i for i in INTEGRATORS if i not in DESIGN_REFUSALS]
    lines += ["", f"Designs (`antisync design`, cpu float64, both models): {', '.join(designs)}.  "]
    lines += [f"{value}: {why}.  " for value, why in DESIGN_REFUSALS.items()]
    return "\n".join(lines).rstrip() + "\n"


if __name__ == "__main__":
    print(table(), end="")
