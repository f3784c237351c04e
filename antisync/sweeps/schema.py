"""A sweep config: the ``sweep:``, ``thresholds``, ``repeats``, ``screen`` and ``top`` keys.

``sweep:`` names a family of graphs, a grid over config keys (``grid``/``zip``,
:mod:`antisync.sweeps.points`) on one ``graph:`` or on a family, or both.

:func:`load_sweep` reads and validates a sweep config into a frozen :class:`Sweep`; errors
name the file and the key. What the keys mean is in :mod:`antisync.sweeps` and
docs/sweeps.md.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Literal

import yaml

from antisync.errors import ConfigError
from antisync.plan.config import (
    Config,
    config_from_mapping,
    parse_mapping,
    read_config_text,
    resolve_graph_path,
)
from antisync.sweeps.families import FAMILIES, family_specs
from antisync.sweeps.points import (
    THRESHOLD_KEYS,
    Axis,
    GridPoint,
    axis_option,
    check_grid_size,
    grid_points,
    sweep_axes,
)
from antisync.validation import choice, number, positive, unknown_keys

__all__ = ["PAPER_THRESHOLD", "Screen", "Sweep", "Top", "load_sweep", "load_sweep_text"]

#: the threshold the paper uses for Figs. 3-5 and Table 1
PAPER_THRESHOLD = 0.99

_FAMILY_KEYS = {
    "atlas": ({"nodes"}, {"grid", "zip"}),
    "lollipop": ({"nodes", "path"}, {"grid", "zip"}),
    "graphs": ({"graphs"}, {"grid", "zip"}),
}
_SWEEP_KEYS = {"sweep", "thresholds", "repeats", "screen", "top"}


@dataclass(frozen=True)
class Screen:
    """Synchronization screening before any realization is spent (see :mod:`antisync.sweeps.screening`).

    ``exclude_fraction``: a graph is excluded when more than this fraction of its screening
    realizations end in a stable non-synchronized state (0: any such realization excludes it).
    """

    enabled: bool = True
    realizations: int = 200
    t_max: float = 200.0
    exclude_fraction: float = 0.0

    def __post_init__(self):
        if not isinstance(self.enabled, bool):
            raise ConfigError(f"screen.enabled must be true or false, got {self.enabled!r}")
        if (
            isinstance(self.realizations, bool)
            or not isinstance(self.realizations, int)
            or self.realizations < 1
        ):
            raise ConfigError(f"screen.realizations must be an integer >= 1, got {self.realizations!r}")
        positive("screen.t_max", self.t_max)
        if (
            isinstance(self.exclude_fraction, bool)
            or not isinstance(self.exclude_fraction, int | float)
            or not 0.0 <= self.exclude_fraction < 1.0
        ):
            raise ConfigError(f"screen.exclude_fraction must be in [0, 1), got {self.exclude_fraction!r}")


@dataclass(frozen=True)
class Top:
    """Second stage on the most antifragile edge of the ``graphs`` top-ranked graphs."""

    graphs: int = 0
    betas: tuple = (0.5,)
    realizations: int | None = None

    def __post_init__(self):
        if isinstance(self.graphs, bool) or not isinstance(self.graphs, int) or self.graphs < 0:
            raise ConfigError(f"top.graphs must be an integer >= 0, got {self.graphs!r}")
        for b in self.betas:
            if isinstance(b, bool) or not isinstance(b, int | float) or not 0.0 < b < 1.0:
                raise ConfigError(f"top.betas must lie in (0, 1), got {b!r}")
        if self.realizations is not None and (
            isinstance(self.realizations, bool)
            or not isinstance(self.realizations, int)
            or self.realizations < 1
        ):
            raise ConfigError(f"top.realizations must be null or an integer >= 1, got {self.realizations!r}")


@dataclass(frozen=True)
class Sweep:
    """A resolved, validated sweep.

    Attributes
    ----------
    family : dict
        The ``sweep:`` section, with ``nodes``/``path`` expanded to sorted lists.
    edges : "all", "fig2" or tuple of str
    thresholds : tuple of float
    repeats : int
    screen : Screen
    top : Top
    base : Config
        The run keys shared by every job (its ``graph`` is the first graph of the family).
    axes : tuple of Axis
        The ``sweep.grid`` and ``sweep.zip`` axes (:mod:`antisync.sweeps.points`); ``()``
        without a grid.
    points : tuple of GridPoint
        Every point of the grid with its validated config; ``()`` without a grid.
    notes : tuple of str
        What the command line changed in the config that the user should hear of (a
        ``--grid KEY`` replacing the config's ``sweep.grid.KEY``); not part of the sweep.
    """

    name: str
    family: dict
    edges: Literal["all", "fig2"] | tuple[str, ...]
    thresholds: tuple
    repeats: int
    screen: Screen
    top: Top
    base: Config
    axes: tuple[Axis, ...] = ()
    points: tuple[GridPoint, ...] = ()
    notes: tuple[str, ...] = ()

    @property
    def output(self) -> str:
        return self.base.output

    def to_dict(self) -> dict:
        run = self.base.resolved().to_dict()
        for k in ("graph", "edges", "name"):
            run.pop(k)
        run["dynamics"].pop("threshold")
        family = dict(self.family)
        for part in ("grid", "zip"):
            given = {k: list(v) for a in self.axes if a.zipped == (part == "zip") for k, v in _columns(a)}
            if given:
                family[part] = given
        out = {
            "name": self.name,
            "sweep": family,
            "edges": self.edges if isinstance(self.edges, str) else list(self.edges),
            "thresholds": list(self.thresholds),
            "repeats": self.repeats,
            "screen": asdict(self.screen),
            "top": {**asdict(self.top), "betas": list(self.top.betas)},
            **run,
        }
        if any(p.threshold is not None for p in self.points):
            del out["thresholds"]  # the grid's (reloading both would be refused)
        return out

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)

    def key(self) -> dict:
        """What determines the numbers (compared on resume)."""
        d = self.to_dict()
        for k in ("name", "backend", "executor", "threads", "output", "chunk_size"):
            d.pop(k, None)
        return json.loads(json.dumps(d))

    def ranking_threshold(self) -> float:
        """The threshold of Fig. 3 / Table 1: 0.99 when swept, else the one closest to it."""
        return min(self.thresholds, key=lambda t: (abs(t - PAPER_THRESHOLD), t))


def _columns(axis: Axis) -> list[tuple[str, tuple]]:
    """``[(key, its values along the axis), ...]``."""
    return [(key, tuple(v[i] for v in axis.values)) for i, key in enumerate(axis.keys)]


def load_sweep(
    path: str | Path,
    overrides: list[str] | None = None,
    values: dict | None = None,
    *,
    grid: list[str] | None = None,
    zip_: list[str] | None = None,
) -> Sweep:
    """Read and validate a sweep config file; errors name the file and the key.

    ``overrides`` and ``values`` are those of :func:`antisync.plan.config.load_config`; ``grid``
    and ``zip_`` are ``KEY=V1,V2,...`` items of the CLI's ``--grid`` / ``--zip``, which set
    ``sweep.grid.KEY`` / ``sweep.zip.KEY`` (a run config with ``graph:`` and no ``sweep:``
    becomes a grid sweep of that graph). An option replaces the config's list of its key, as
    ``--set`` replaces a value, and says so in :attr:`Sweep.notes`; a key given twice on the
    command line, or in ``grid`` on one side and ``zip`` on the other, is refused.
    """
    path = Path(path)
    text = read_config_text(path)
    try:
        return load_sweep_text(text, overrides, source=path, values=values, grid=grid, zip_=zip_)
    except ConfigError as exc:
        msg = str(exc)
        raise ConfigError(msg if msg.startswith(str(path)) else f"{path}: {msg}") from None


def load_sweep_text(
    text: str,
    overrides: list[str] | None = None,
    source: Path | None = None,
    values: dict | None = None,
    *,
    grid: list[str] | None = None,
    zip_: list[str] | None = None,
) -> Sweep:
    """Like :func:`load_sweep` for YAML text."""
    raw = parse_mapping(text, overrides, values)
    notes = _apply_axis_options(raw, grid, zip_)
    if "sweep" not in raw:
        raise ConfigError(
            "missing key 'sweep' (e.g. sweep: {family: atlas, nodes: 6}); "
            "a config with graph: is run with `antisync run` (or swept with --grid KEY=V1,V2)"
        )
    section = raw["sweep"]
    if not isinstance(section, dict):
        raise ConfigError(f"sweep must be a mapping such as {{family: atlas, nodes: 6}}, got {section!r}")
    has_axes = bool(section.get("grid") or section.get("zip"))
    if "graph" in raw:
        if "family" in section:
            raise ConfigError(
                "a sweep config with sweep.family has no 'graph' key: its graphs come from 'sweep:' "
                "(a grid over one graph: graph: plus sweep: {grid: {...}})"
            )
        if not has_axes:
            raise ConfigError(
                "a sweep of one graph: needs sweep.grid or sweep.zip, such as "
                "sweep: {grid: {model.phase_lag: [0, 0.1, 0.2]}}"
            )
        unknown_keys(section, {"grid", "zip"}, "sweep.")
        section = {**section, "family": "graphs", "graphs": [raw["graph"]]}
    family = _family(section)
    axes = sweep_axes(family.pop("axes"))
    if family["family"] == "graphs":  # graph files are relative to the sweep file, as in a run
        family["graphs"] = [resolve_graph_path(spec, source) for spec in family["graphs"]]
    specs = family_specs(family)
    thresholds = _thresholds(raw)
    repeats = raw.get("repeats", 1)
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ConfigError(f"repeats must be an integer >= 1, got {repeats!r}")
    screen = _section(raw, "screen", Screen)
    top_raw = raw.get("top")
    if isinstance(top_raw, dict) and "betas" in top_raw:
        betas = top_raw["betas"]
        if not isinstance(betas, list) or not betas:
            raise ConfigError(f"top.betas must be a non-empty list such as [0.5], got {betas!r}")
        top_raw = {**top_raw, "betas": tuple(sorted({number("top.betas", b, 0.0) for b in betas}))}
        raw = {**raw, "top": top_raw}
    top = _section(raw, "top", Top)
    edges = raw.get("edges", "all")
    if edges == "fig2" and family["family"] != "lollipop":
        raise ConfigError(
            "edges: fig2 (the clique edge away from the bridge, Fig. 2) needs sweep.family: lollipop"
        )
    rest = {k: v for k, v in raw.items() if k not in _SWEEP_KEYS}
    rest["graph"] = specs[0][1]
    rest.pop("name", None)  # the jobs are named by the stages
    rest.setdefault("keep_pairs", 0)  # per-realization pairs of hundreds of jobs would not fit
    if edges == "fig2":
        rest["edges"] = "all"
    dyn = rest.get("dynamics")
    if isinstance(dyn, dict):
        rest["dynamics"] = {k: v for k, v in dyn.items() if k != "threshold"}
    try:
        base = config_from_mapping(rest, source)
    except ConfigError as exc:
        if "unknown key" in str(exc):
            raise ConfigError(f"{exc}; sweep keys: {', '.join(sorted(_SWEEP_KEYS))}") from None
        raise
    if "km" not in base.measures:  # a run may omit km (exact measures only); a sweep may not
        raise ConfigError(
            f"a sweep screens and ranks its graphs by Lambda^KM: measures must include km, got "
            f"{list(base.measures)}; for exact measures only use `antisync run` or antisync.measures"
        )
    # refused from the axes' lengths, before a config is validated per point
    per_point = repeats * (1 if any(k in THRESHOLD_KEYS for a in axes for k in a.keys) else len(thresholds))
    check_grid_size(axes, per_point=per_point, graphs=len(specs))
    points = grid_points(axes, rest, source)
    swept = [p.threshold for p in points if p.threshold is not None]
    if swept:
        if "thresholds" in raw:
            raise ConfigError("give either thresholds: [...] or a grid over dynamics.threshold, not both")
        thresholds = tuple(sorted(set(swept)))
    if points and top.graphs > 0:
        raise ConfigError(
            "top.graphs ranks the graphs at one config; a sweep with a grid has one config per "
            "point: set top.graphs: 0 (or remove top)"
        )
    if base.stop.active:
        _check_stop(top, axes)
    base = replace(base, dynamics=replace(base.dynamics, threshold=thresholds[0]))
    name = raw.get("name") or (source.stem if source else "sweep")
    if not raw.get("output"):
        base = replace(base, output=f"results/{name}.h5")
    base = replace(base, name=str(name))
    if edges not in ("all", "fig2"):
        if not isinstance(edges, list) or not edges or not all(isinstance(e, str) for e in edges):
            raise ConfigError(
                f"edges must be 'all', 'fig2' or a non-empty list like [\"2->1\"], got {edges!r}"
            )
        edges = tuple(edges)
    return Sweep(
        name=str(name),
        family=family,
        edges=edges,
        thresholds=thresholds,
        repeats=repeats,
        screen=screen,
        top=top,
        base=base,
        axes=axes,
        points=points,
        notes=tuple(notes),
    )


def _check_stop(top: Top, axes: tuple[Axis, ...]) -> None:
    """Refuse what a stopping rule cannot combine with: it looks at every main-stage job at
    once (one ``run_jobs``), at looks of one budget (docs/stopping.md, "Sweeps")."""
    if top.graphs > 0:
        raise ConfigError(
            "stop: with top.graphs > 0: the top stage ranks the graphs on the main stage's "
            "finished numbers, and the rule ends only the main stage; set top.graphs: 0 (then run "
            "the chosen edges with their own config) or remove the stop section"
        )
    if any("realizations" in a.keys for a in axes):
        raise ConfigError(
            "stop: with a grid over realizations: the rule's looks are one budget for every job "
            "(realizations: is the budget); remove realizations from sweep.grid/sweep.zip or "
            "remove the stop section"
        )


def _section(raw: dict, key: str, cls):
    value = raw.get(key) or {}
    if not isinstance(value, dict):
        raise ConfigError(f"'{key}' must be a mapping, got {value!r}")
    fields = cls.__dataclass_fields__
    unknown_keys(value, set(fields), f"{key}.")
    value = {k: number(f"{key}.{k}", v, fields[k].default) for k, v in value.items()}
    return cls(**value)


def _thresholds(raw: dict) -> tuple:
    """The swept thresholds: ``thresholds: [...]``, or the one of ``dynamics.threshold`` or of
    its other spelling ``sync.threshold`` (the config's checks then see it where it was given),
    else the paper's 0.99."""
    dyn = raw.get("dynamics") or {}
    sync = raw.get("sync") or {}
    given = [
        f"{section}.threshold"
        for section, value in (("dynamics", dyn), ("sync", sync))
        if isinstance(value, dict) and value.get("threshold") is not None
    ]
    if len(given) == 2 and dyn["threshold"] != sync["threshold"]:
        raise ConfigError(
            f"sync.threshold ({sync['threshold']}) and dynamics.threshold ({dyn['threshold']}) "
            "disagree; give one of them"
        )
    if "thresholds" not in raw:
        t = PAPER_THRESHOLD
        if isinstance(dyn, dict) and dyn.get("threshold") is not None:
            t = dyn["threshold"]
        elif isinstance(sync, dict) and sync.get("threshold") is not None:
            t = sync["threshold"]
        values = [t]
    else:
        if given:
            raise ConfigError(f"give either thresholds: [...] or {given[0]}, not both")
        values = raw["thresholds"]
        if not isinstance(values, list) or not values:
            raise ConfigError(f"thresholds must be a non-empty list such as [0.9, 0.99], got {values!r}")
    out = []
    for t in values:
        t = number("thresholds", t, 0.0)
        if isinstance(t, bool) or not isinstance(t, int | float) or not 0.0 < t < 1.0:
            raise ConfigError(f"thresholds must lie in (0, 1), got {t!r}")
        out.append(float(t))
    if len(set(out)) != len(out):
        raise ConfigError(f"thresholds lists a value twice: {values!r}")
    return tuple(sorted(out))


def _int_list(key: str, value, lo: int, hi: int) -> list[int]:
    """``6``, ``[4, 5, 9]`` or ``"4..20"`` (inclusive) -> sorted list of ints in ``lo..hi``."""
    if isinstance(value, str) and ".." in value:
        a, _, b = value.partition("..")
        try:
            items = list(range(int(a), int(b) + 1))
        except ValueError:
            raise ConfigError(f'{key} range must look like "4..20", got {value!r}') from None
        if not items:
            raise ConfigError(f"{key} range {value!r} is empty")
    elif isinstance(value, list) and value:
        items = value
    elif isinstance(value, int) and not isinstance(value, bool):
        items = [value]
    else:
        raise ConfigError(f'{key} must be an integer, a list of integers or a range "a..b", got {value!r}')
    for v in items:
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise ConfigError(f"{key} values must be integers in {lo}..{hi}, got {v!r}")
    return sorted(set(items))


def _apply_axis_options(raw: dict, grid: list[str] | None, zip_: list[str] | None) -> list[str]:
    """Set ``--grid`` / ``--zip`` items into ``raw["sweep"]`` (made for a run config).

    Returns the notes to show: each config list an option replaced. A key given twice on the
    command line (the first list would be dropped), or given to one part on the command line
    and in the other part in the config, is a :class:`ConfigError` naming it.
    """
    notes: list[str] = []
    if not grid and not zip_:
        return notes
    section = raw.get("sweep")
    if section is None:
        section = raw["sweep"] = {}
    if not isinstance(section, dict):
        return notes  # refused with the config's own message
    given: dict[str, str] = {}  # key -> the option that gave it
    for option, part, items in (("--grid", "grid", grid), ("--zip", "zip", zip_)):
        for item in items or []:
            key, values = axis_option(option, item)
            if key in given:
                if given[key] == option:
                    raise ConfigError(
                        f"{option} {key} is given twice: give all its values in one list "
                        f"({option} {key}=V1,V2,...)"
                    )
                raise ConfigError(f"{key} is given to both --grid and --zip: give it to one of them")
            given[key] = option
            other = "zip" if part == "grid" else "grid"
            if isinstance(section.get(other), dict) and key in section[other]:
                raise ConfigError(
                    f"{option} {key}: the config's sweep.{other} already sweeps {key}; "
                    f"give it in one of sweep.grid and sweep.zip"
                )
            current = section.get(part)
            if current is None:
                current = section[part] = {}
            if not isinstance(current, dict):
                return notes  # refused by sweep_axes, naming sweep.grid / sweep.zip
            if key in current:
                notes.append(
                    f"{option} {key} replaces the config's sweep.{part}.{key} "
                    f"({len(current[key]) if isinstance(current[key], list) else 1} value(s))"
                )
            current[key] = values
    return notes


def _family(value) -> dict:
    """The validated ``sweep:`` section: its family keys, and ``axes`` (its ``grid``/``zip``)."""
    if not isinstance(value, dict):
        raise ConfigError(f"sweep must be a mapping such as {{family: atlas, nodes: 6}}, got {value!r}")
    axes = {k: value[k] for k in ("grid", "zip") if k in value}
    if "family" not in value and axes:
        raise ConfigError(
            "a sweep with a grid needs a graph: (one graph) or sweep.family (atlas, lollipop, graphs)"
        )
    fam = value.get("family")
    choice("sweep.family", fam, FAMILIES)
    required, optional = _FAMILY_KEYS[fam]
    unknown_keys(value, required | optional | {"family"}, "sweep.")
    missing = sorted(required - set(value))
    if missing:
        raise ConfigError(f"sweep of family {fam} needs key(s) {', '.join('sweep.' + m for m in missing)}")
    if fam == "atlas":
        return {"family": fam, "nodes": _int_list("sweep.nodes", value["nodes"], 2, 7), "axes": axes}
    if fam == "lollipop":
        return {
            "family": fam,
            "nodes": _int_list("sweep.nodes", value["nodes"], 3, 500),
            "path": _int_list("sweep.path", value["path"], 1, 498),
            "axes": axes,
        }
    items = value["graphs"]
    if not isinstance(items, list) or not items:
        raise ConfigError(
            "sweep.graphs must be a non-empty list of graph specs such as [{kind: atlas, index: 105}]"
        )
    out = []
    for k, spec in enumerate(items):
        if not isinstance(spec, dict):
            raise ConfigError(f"sweep.graphs[{k}] must be a mapping such as {{kind: atlas, index: 105}}")
        out.append(dict(spec))
    return {"family": fam, "graphs": out, "axes": axes}
