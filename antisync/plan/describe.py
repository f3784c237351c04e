"""Which model ran, in one line: the summary's ``model: ...; sync: ...`` (docs/models.md).

Read from the config a result file stores (its root attribute ``config_yaml``, decoded by
:func:`antisync.store.stored_config`), so a summary
says what produced its numbers without the config file at hand. Pure: a mapping in, text out.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from antisync.errors import ConfigError
from antisync.plan.model import Model, Sync

__all__ = ["model_line", "model_text", "r_star_text", "relative_criterion", "stored_name", "sync_text"]

#: ``dynamics.threshold`` of a config that does not give one (antisync.plan.config.Dynamics)
_THRESHOLD = 0.99


def _sections(cfg) -> tuple[Model, Sync, float] | None:
    """``cfg``'s :class:`Model`, :class:`Sync` and ``dynamics.threshold`` (the defaults where a
    section is absent, as in a file written before they existed); None when they are not valid."""
    if not isinstance(cfg, Mapping):
        return None
    model, sync, dynamics = (cfg.get(k) or {} for k in ("model", "sync", "dynamics"))
    if not all(isinstance(x, Mapping) for x in (model, sync, dynamics)):
        return None
    try:
        threshold = float(sync.get("threshold") or dynamics.get("threshold", _THRESHOLD))
        return Model(**model), Sync(**{**sync, "threshold": None}), threshold
    except (ConfigError, TypeError, ValueError):
        return None


def model_line(cfg, r_star: list[dict] | None = None) -> str | None:
    """``model: <dynamics>; sync: <criterion>`` for a config mapping (the YAML a result file
    stores), e.g. ``model: identical first-order Kuramoto (the paper's Eq. 2); sync: r >= 0.99``;
    None when ``cfg`` holds no valid ``model``/``sync`` sections.

    With ``sync.criterion: relative`` and ``r_star`` given (:func:`antisync.stats.summary.r_star_rows`
    of the file's jobs), the line ends with :func:`r_star_text`.
    """
    parts = _sections(cfg)
    if parts is None:
        return None
    model, sync, threshold = parts
    line = f"model: {model_text(model)}; sync: {sync_text(sync, threshold)}"
    if sync.criterion == "relative" and r_star is not None:
        line += f"; {r_star_text(r_star)}"
    return line


def stored_name(cfg: Mapping) -> str | None:
    """The ``name:`` of a stored config mapping (None when it has none): what the summary and
    the report call its job. The mapping comes from :func:`antisync.store.stored_config`."""
    name = cfg.get("name")
    return name if isinstance(name, str) and name else None


def relative_criterion(cfg) -> bool:
    """Whether ``cfg`` synchronizes by ``sync.criterion: relative`` (r >= fraction r*)."""
    parts = _sections(cfg)
    return parts is not None and parts[1].criterion == "relative"


def model_text(model: Model) -> str:
    """The dynamics of ``model`` in words: its order, inertia and damping, phase lag and
    natural frequencies."""
    if model.law is not None:
        law = model.law
        given = ", ".join(
            [f"{k} {_per_node(v)}" for k, v in (model.params or {}).items()]
            + [f"{k} {_per_link(v)}" for k, v in (model.edge_params or {}).items()]
        )
        rates = "; ".join(f"{s}' = {e}" for s, e in law["rates"].items())
        coupling = "; ".join(f"{u} = sum_j {e}" for u, e in law["coupling"].items())
        return f"law {law['name']} ({rates}; {coupling}" + (f"; {given})" if given else ")")
    if model.is_default:
        return "identical first-order Kuramoto (the paper's Eq. 2)"
    lag = f"phase lag {model.phase_lag:g}" if model.phase_lag else ""
    if model.second_order:
        params = [f"inertia {_per_node(model.inertia)}", f"damping {_per_node(model.damping)}", lag]
        kind = "swing equation (" + ", ".join(p for p in params if p) + ")"
    else:
        kind = f"first-order Kuramoto-Sakaguchi ({lag})" if lag else "first-order Kuramoto"
    start = ""
    if model.start is not None:
        start = f", started within {model.start['width']:g} rad of the intact network's locked state"
    return f"{kind}, {_frequencies(model.frequencies)}{start}"


def sync_text(sync: Sync, threshold: float) -> str:
    """The synchronization criterion in words: ``r >= 0.99``, ``r >= 0.98 r* (...)`` or
    ``frequency locking, tolerance 0.001``."""
    if sync.criterion == "relative":
        return f"r >= {sync.fraction:g} r* (r* of each network's stable locked state)"
    if sync.criterion == "frequency":
        return f"frequency locking, tolerance {sync.tolerance:g}"
    return f"r >= {threshold:g}"


def r_star_text(rows: list[dict]) -> str:
    """What ``rows`` (:func:`antisync.stats.summary.r_star_rows`) say about r*: the undamaged
    network's and the range over its damaged variants (over graphs, for several), or that the
    file does not store it."""
    if not rows:
        return "r*: not stored (a file written before antisync stored it)"
    damaged = [r for r in rows if r["damaged"]]
    lo = min((r["damaged_min"] for r in damaged), default=None)
    hi = max((r["damaged_max"] for r in damaged), default=None)
    n = sum(r["damaged"] for r in rows)
    over = f", {lo:.4f} to {hi:.4f} over {n} damaged variant{'s' if n != 1 else ''}" if damaged else ""
    if len(rows) == 1:
        return f"r* = {rows[0]['undamaged']:.4f} undamaged{over}"
    undamaged = [r["undamaged"] for r in rows]
    return f"r* = {min(undamaged):.4f} to {max(undamaged):.4f} undamaged over {len(rows)} graphs{over}"


def _per_node(value) -> str:
    """An inertia or damping: its value, ``a to b per node`` for a list, ``per node from FILE``."""
    if isinstance(value, Mapping):
        return f"per node from {Path(value['file']).name}"
    if isinstance(value, tuple):
        return f"{min(value):g} to {max(value):g} per node"
    return f"{value:g}"


def _per_link(value) -> str:
    """A law's edge parameter: its value on every link, or ``per link from FILE[, column C]``."""
    if isinstance(value, Mapping):
        column = f", column {value['column']}" if value.get("column") else ""
        return f"per link from {Path(value['file']).name}{column}"
    return f"{value:g} on every link"


def _frequencies(spec) -> str:
    """The natural frequencies: identical, fixed per node, from a file, or drawn."""
    if spec is None:
        return "identical natural frequencies"
    if isinstance(spec, tuple):
        return f"natural frequencies given per node ({len(spec)} values, {min(spec):g} to {max(spec):g})"
    if "file" in spec:
        return f"natural frequencies from {Path(spec['file']).name}"
    scale = f"sd {spec['sd']:g}" if spec["distribution"] == "normal" else f"width {spec['width']:g}"
    return f"natural frequencies drawn per realization ({spec['distribution']}, {scale})"
