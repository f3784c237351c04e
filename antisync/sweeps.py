"""Sweeps: a family of graphs, screened for synchronization, reduced by symmetry, one HDF5 file.

A sweep config is a run config (``betas``, ``lambda``, ``dynamics``, ``realizations``, ``seed``,
``backend``, ``output``, ...) without ``graph:`` and with a ``sweep:`` section::

    name: atlas6
    sweep: {family: atlas, nodes: 6}     # every connected 6-node graph of the networkx atlas
    edges: all                           # all | fig2 (lollipop family) | ["0->1", ...]
    thresholds: [0.9, 0.99, 0.999]       # one job per (graph, threshold); default: dynamics.threshold
    repeats: 1                           # independent Lambda estimates; repeat k uses seed + k
    screen: {realizations: 200, t_max: 200, exclude_fraction: 0}
    top: {graphs: 7, betas: [0.5], realizations: 20000}

Families (``sweep.family``):

- ``atlas``: ``nodes`` (2..7; an int, a list, or ``"a..b"``): every connected graph of
  :func:`networkx.graph_atlas_g` with that many nodes, named ``G<index>`` (112 for six nodes).
- ``lollipop``: ``nodes`` and ``path`` (same forms): lollipops ``lollipop_<N>_<L>`` with the
  paper's labels (:func:`antisync.graphs.lollipop`).
- ``graphs``: ``graphs``: a list of graph specs as in a run config (``{kind: atlas, index: 105}``,
  ...), each with an optional ``name``.

What a sweep does (:func:`run_sweep`):

1. **Screening** (:mod:`antisync.screening`): every graph is integrated from
   ``screen.realizations`` random starts; a graph with realizations that converge to a stable
   non-synchronized state (a twisted state) is excluded, with the reason and the fraction.
2. **Symmetry**: directed edges mapped onto each other by a graph automorphism have the same
   Lambda; one representative per orbit is integrated
   (:func:`~antisync.graphs.edge_orbits`) and its records are fanned out to the whole
   orbit when the file is summarized (:func:`sweep_summary`).
3. **Main stage**: one job per (kept graph, threshold, repeat). Repeat 0 carries ``betas``;
   later repeats estimate Lambda only.
4. **Top stage** (optional, ``top.graphs > 0``): the graphs ranked first by the sum of their
   positive Lambda^KM (Fig. 3 of the paper) get a job for their most antifragile edge with
   ``top.betas`` and ``top.realizations`` (Table 1 and the histograms of Fig. 4).

Everything, screening included, is stored in one HDF5 file (group ``/sweep``, dataset
``meta_json``, next to the usual ``/jobs``) and a sweep killed at any moment and rerun with
``resume=True`` ends with the same numbers as an uninterrupted one.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import networkx as nx
import numpy as np
import yaml

from antisync import graphs as graphs_mod
from antisync.config import (
    Config,
    _choice,
    _number,
    _positive,
    _unknown,
    config_from_mapping,
    graph_name,
    parse_mapping,
    read_config_text,
)
from antisync.errors import ConfigError, StoreError
from antisync.graphs import edge_orbits
from antisync.jobs import check_step

__all__ = [
    "FAMILIES",
    "SWEEP_FORMAT",
    "GraphEntry",
    "Screen",
    "Sweep",
    "Top",
    "edge_lambdas",
    "edge_orbits",
    "trend_in_n",
    "expand_records",
    "family_graphs",
    "is_sweep_file",
    "load_sweep",
    "load_sweep_text",
    "ranking",
    "run_sweep",
    "sweep_summary",
]

FAMILIES = ("atlas", "lollipop", "graphs")
SWEEP_FORMAT = "antisync-sweep"
SWEEP_FORMAT_VERSION = 1
#: the threshold the paper uses for Figs. 3-5 and Table 1
PAPER_THRESHOLD = 0.99

_FAMILY_KEYS = {
    "atlas": ({"nodes"}, set()),
    "lollipop": ({"nodes", "path"}, set()),
    "graphs": ({"graphs"}, set()),
}
_SWEEP_KEYS = {"sweep", "thresholds", "repeats", "screen", "top"}


# ---- schema ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Screen:
    """Synchronization screening before any realization is spent (see :mod:`.screening`).

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
        if isinstance(self.realizations, bool) or not isinstance(self.realizations, int) \
                or self.realizations < 1:
            raise ConfigError(f"screen.realizations must be an integer >= 1, got {self.realizations!r}")
        _positive("screen.t_max", self.t_max)
        if isinstance(self.exclude_fraction, bool) or not isinstance(self.exclude_fraction, int | float) \
                or not 0.0 <= self.exclude_fraction < 1.0:
            raise ConfigError(f"screen.exclude_fraction must be in [0, 1), got {self.exclude_fraction!r}")


@dataclass(frozen=True)
class Top:
    """Second stage on the most antifragile edge of the ``graphs`` top-ranked graphs."""

    graphs: int = 0
    betas: tuple = (0.5,)
    realizations: Any = None

    def __post_init__(self):
        if isinstance(self.graphs, bool) or not isinstance(self.graphs, int) or self.graphs < 0:
            raise ConfigError(f"top.graphs must be an integer >= 0, got {self.graphs!r}")
        for b in self.betas:
            if isinstance(b, bool) or not isinstance(b, int | float) or not 0.0 < b < 1.0:
                raise ConfigError(f"top.betas must lie in (0, 1), got {b!r}")
        if self.realizations is not None and (
            isinstance(self.realizations, bool) or not isinstance(self.realizations, int)
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
    """

    name: str
    family: dict
    edges: Any
    thresholds: tuple
    repeats: int
    screen: Screen
    top: Top
    base: Config

    @property
    def output(self) -> str:
        return self.base.output

    def to_dict(self) -> dict:
        run = self.base.resolved().to_dict()
        for k in ("graph", "edges", "name"):
            run.pop(k)
        run["dynamics"].pop("threshold")
        return {
            "name": self.name,
            "sweep": self.family,
            "edges": self.edges if isinstance(self.edges, str) else list(self.edges),
            "thresholds": list(self.thresholds),
            "repeats": self.repeats,
            "screen": asdict(self.screen),
            "top": {**asdict(self.top), "betas": list(self.top.betas)},
            **run,
        }

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


def load_sweep(path: str | Path, overrides: list[str] | None = None,
               values: dict | None = None) -> Sweep:
    """Read and validate a sweep config file; errors name the file and the key.

    ``overrides`` and ``values`` are those of :func:`antisync.config.load_config`.
    """
    path = Path(path)
    text = read_config_text(path)
    try:
        return load_sweep_text(text, overrides, source=path, values=values)
    except ConfigError as exc:
        msg = str(exc)
        raise ConfigError(msg if msg.startswith(str(path)) else f"{path}: {msg}") from None


def load_sweep_text(text: str, overrides: list[str] | None = None,
                    source: Path | None = None, values: dict | None = None) -> Sweep:
    """Like :func:`load_sweep` for YAML text."""
    raw = parse_mapping(text, overrides, values)
    if "sweep" not in raw:
        raise ConfigError("missing key 'sweep' (e.g. sweep: {family: atlas, nodes: 6}); "
                          "a config with graph: is run with `antisync run`")
    if "graph" in raw:
        raise ConfigError("a sweep config has no 'graph' key: its graphs come from 'sweep:'")
    family = _family(raw["sweep"])
    specs = _family_specs(family)
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
        top_raw = {**top_raw, "betas": tuple(sorted({_number("top.betas", b, 0.0) for b in betas}))}
        raw = {**raw, "top": top_raw}
    top = _section(raw, "top", Top)
    edges = raw.get("edges", "all")
    if edges == "fig2" and family["family"] != "lollipop":
        raise ConfigError("edges: fig2 (the clique edge away from the bridge, Fig. 2) needs "
                          "sweep.family: lollipop")
    rest = {k: v for k, v in raw.items() if k not in _SWEEP_KEYS}
    rest["graph"] = specs[0][1]
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
    base = replace(base, dynamics=replace(base.dynamics, threshold=thresholds[0]))
    name = raw.get("name") or (source.stem if source else "sweep")
    if not raw.get("output"):
        base = replace(base, output=f"results/{name}.h5")
    base = replace(base, name=str(name))
    if edges not in ("all", "fig2"):
        if not isinstance(edges, list) or not edges or not all(isinstance(e, str) for e in edges):
            raise ConfigError(
                f"edges must be 'all', 'fig2' or a non-empty list like [\"2->1\"], got {edges!r}")
        edges = tuple(edges)
    return Sweep(name=str(name), family=family, edges=edges, thresholds=thresholds,
                 repeats=repeats, screen=screen, top=top, base=base)


def _section(raw: dict, key: str, cls):
    value = raw.get(key) or {}
    if not isinstance(value, dict):
        raise ConfigError(f"'{key}' must be a mapping, got {value!r}")
    fields = cls.__dataclass_fields__
    _unknown(value, set(fields), f"{key}.")
    value = {k: _number(f"{key}.{k}", v, fields[k].default) for k, v in value.items()}
    return cls(**value)


def _thresholds(raw: dict) -> tuple:
    dyn = raw.get("dynamics") or {}
    if "thresholds" not in raw:
        t = dyn.get("threshold", 0.99) if isinstance(dyn, dict) else 0.99
        values = [t]
    else:
        if isinstance(dyn, dict) and "threshold" in dyn:
            raise ConfigError("give either thresholds: [...] or dynamics.threshold, not both")
        values = raw["thresholds"]
        if not isinstance(values, list) or not values:
            raise ConfigError(f"thresholds must be a non-empty list such as [0.9, 0.99], got {values!r}")
    out = []
    for t in values:
        t = _number("thresholds", t, 0.0)
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
            raise ConfigError(f"{key} range must look like \"4..20\", got {value!r}") from None
        if not items:
            raise ConfigError(f"{key} range {value!r} is empty")
    elif isinstance(value, list) and value:
        items = value
    elif isinstance(value, int) and not isinstance(value, bool):
        items = [value]
    else:
        raise ConfigError(f"{key} must be an integer, a list of integers or a range \"a..b\", got {value!r}")
    for v in items:
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise ConfigError(f"{key} values must be integers in {lo}..{hi}, got {v!r}")
    return sorted(set(items))


def _family(value) -> dict:
    if not isinstance(value, dict):
        raise ConfigError(f"sweep must be a mapping such as {{family: atlas, nodes: 6}}, got {value!r}")
    fam = value.get("family")
    _choice("sweep.family", fam, FAMILIES)
    required, optional = _FAMILY_KEYS[fam]
    _unknown(value, required | optional | {"family"}, "sweep.")
    missing = sorted(required - set(value))
    if missing:
        raise ConfigError(f"sweep of family {fam} needs key(s) {', '.join('sweep.' + m for m in missing)}")
    if fam == "atlas":
        return {"family": fam, "nodes": _int_list("sweep.nodes", value["nodes"], 2, 7)}
    if fam == "lollipop":
        return {"family": fam, "nodes": _int_list("sweep.nodes", value["nodes"], 3, 500),
                "path": _int_list("sweep.path", value["path"], 1, 498)}
    items = value["graphs"]
    if not isinstance(items, list) or not items:
        raise ConfigError("sweep.graphs must be a non-empty list of graph specs such as "
                          "[{kind: atlas, index: 105}]")
    out = []
    for k, spec in enumerate(items):
        if not isinstance(spec, dict):
            raise ConfigError(f"sweep.graphs[{k}] must be a mapping such as {{kind: atlas, index: 105}}")
        out.append(dict(spec))
    return {"family": fam, "graphs": out}


def _family_specs(family: dict) -> list[tuple[str, dict]]:
    """``(name, graph spec)`` of every graph of the family, before building any graph."""
    fam = family["family"]
    if fam == "atlas":
        wanted = set(family["nodes"])
        out = []
        for index, g in enumerate(nx.graph_atlas_g()):
            if g.number_of_nodes() in wanted and nx.is_connected(g):
                out.append((f"G{index}", {"kind": "atlas", "index": index}))
        return out
    if fam == "lollipop":
        out = []
        for n in family["nodes"]:
            for path in family["path"]:
                if n - path >= 2:
                    out.append((f"lollipop_{n}_{path}", {"kind": "lollipop", "nodes": n, "path": path}))
        if not out:
            raise ConfigError("sweep.nodes and sweep.path give no lollipop with nodes - path >= 2")
        return out
    out, seen = [], set()
    from antisync.config import _check_graph

    for k, spec in enumerate(family["graphs"]):
        spec = dict(spec)
        name = spec.pop("name", None)
        try:
            _check_graph(spec)
        except ConfigError as exc:
            raise ConfigError(f"sweep.graphs[{k}]: {exc}") from None
        name = str(name or graph_name(spec))
        if name in seen:
            raise ConfigError(f"sweep.graphs[{k}]: graph name {name!r} is used twice; "
                              "give the graphs distinct name: keys")
        seen.add(name)
        out.append((name, spec))
    return out


# ---- graphs, edges and symmetry ------------------------------------------------------------
@dataclass
class GraphEntry:
    """One graph of a sweep: its selected directed edges and their automorphism orbits."""

    name: str
    spec: dict
    graph: nx.Graph
    edges: list  # selected directed edges, (u, v) node labels
    rep: dict  # edge -> representative edge (both (u, v))

    @property
    def labels(self) -> list[str]:
        return [graphs_mod.edge_label(*e) for e in self.edges]

    @property
    def representatives(self) -> list:
        return [e for e in self.edges if self.rep[e] == e]

    def orbit_labels(self) -> dict[str, str]:
        return {graphs_mod.edge_label(*e): graphs_mod.edge_label(*self.rep[e]) for e in self.edges}


def family_graphs(sweep: Sweep, *, symmetry: bool = True) -> list[GraphEntry]:
    """Build every graph of the sweep with its selected edges and their orbits."""
    out = []
    for name, spec in _family_specs(sweep.family):
        g = graphs_mod.build_graph(spec, seed=sweep.base.seed)
        g.graph["name"] = name
        try:  # before the screening spends time on a step that cannot synchronize
            check_step(graphs_mod.omega_matrix(g), sweep.base)
        except ConfigError as exc:
            raise ConfigError(f"graph {name}: {exc}") from None
        edges = _select_edges(sweep, spec, g, name)
        rep = edge_orbits(g, edges) if symmetry else {e: e for e in edges}
        out.append(GraphEntry(name, spec, g, edges, rep))
    return out


def fig2_edge(n_nodes: int, path: int) -> tuple[int, int]:
    """The edge of the paper's Fig. 2 in ``lollipop(N, L)``: a clique edge ``a -> b`` not touching
    the bridge node ``L + 1``, here ``(L + 2) -> (L + 3)`` (all such edges are one orbit)."""
    if n_nodes - path < 3:
        raise ConfigError(f"edges: fig2 needs a clique of at least 3 nodes; lollipop N={n_nodes}, "
                          f"L={path} has {n_nodes - path}")
    return (path + 2, path + 3)


def _select_edges(sweep: Sweep, spec: dict, g: nx.Graph, name: str) -> list:
    if sweep.edges == "all":
        return graphs_mod.all_directed_edges(g)
    if sweep.edges == "fig2":
        return [fig2_edge(int(spec["nodes"]), int(spec["path"]))]
    out = []
    for text in sweep.edges:
        try:
            e = graphs_mod.parse_edge(text, g)
        except graphs_mod.GraphError as exc:
            raise ConfigError(f"edges: graph {name}: {exc}") from None
        if e not in out:
            out.append(e)
    return out


# ---- records ---------------------------------------------------------------------------
def expand_records(records: list[dict], orbits: dict[str, str]) -> list[dict]:
    """Fan records of representative edges out to every edge of their orbits.

    ``orbits`` maps each edge label to its representative's label, in the order the records
    should come out. Each output record is a copy of its representative's with ``edge`` set,
    plus ``representative`` and ``orbit_size``.
    """
    by_edge: dict[str, list[dict]] = {}
    for r in records:
        by_edge.setdefault(r["edge"], []).append(r)
    size: dict[str, int] = {}
    for rep in orbits.values():
        size[rep] = size.get(rep, 0) + 1
    out = []
    for label, rep in orbits.items():
        for r in by_edge.get(rep, []):
            out.append({**r, "edge": label, "representative": rep, "orbit_size": size[rep]})
    return out


# ---- running ---------------------------------------------------------------------------
def _job_name(graph: str, threshold: float, repeat: int, sweep: Sweep) -> str:
    name = graph
    if len(sweep.thresholds) > 1:
        name += f"_r{threshold:g}"
    if sweep.repeats > 1:
        name += f"_rep{repeat}"
    return name


def _job_config(sweep: Sweep, entry: GraphEntry, edges: list, *, threshold: float, seed: int,
                betas: tuple, realizations: int | None = None, name: str) -> Config:
    base = sweep.base
    return replace(
        base, name=name, graph=entry.spec, edges=[graphs_mod.edge_label(*e) for e in edges],
        betas=tuple(betas), seed=seed, realizations=realizations or base.realizations,
        dynamics=replace(base.dynamics, threshold=threshold),
    )


def main_jobs(sweep: Sweep, entries: list[GraphEntry]) -> tuple[list, list[dict]]:
    """Jobs of the main stage (representative edges only) and their descriptions."""
    from antisync.jobs import make_job

    jobs, meta = [], []
    for entry in entries:
        for t in sweep.thresholds:
            for k in range(sweep.repeats):
                name = _job_name(entry.name, t, k, sweep)
                betas = sweep.base.betas if k == 0 else ()
                cfg = _job_config(sweep, entry, entry.representatives, threshold=t,
                                  seed=sweep.base.seed + k, betas=betas, name=name)
                jobs.append(make_job(cfg, graph=entry.graph, name=name))
                meta.append({"job": name, "graph": entry.name, "threshold": t, "repeat": k,
                             "stage": "main"})
    return jobs, meta


def top_jobs(sweep: Sweep, entries: list[GraphEntry], records: list[dict]) -> tuple[list, list[dict]]:
    """Top-stage jobs: the most antifragile edge of each of the first ``top.graphs`` graphs."""
    from antisync.jobs import make_job

    if sweep.top.graphs <= 0:
        return [], []
    by_name = {e.name: e for e in entries}
    t = sweep.ranking_threshold()
    jobs, meta = [], []
    for row in ranking(records, t)[: sweep.top.graphs]:
        entry = by_name[row["graph"]]
        edge = graphs_mod.parse_edge(row["max_representative"], entry.graph)
        name = f"{entry.name}_top"
        cfg = _job_config(sweep, entry, [edge], threshold=t, seed=sweep.base.seed,
                          betas=sweep.top.betas, realizations=sweep.top.realizations, name=name)
        cfg = replace(cfg, keep_pairs=0)
        jobs.append(make_job(cfg, graph=entry.graph, name=name))
        meta.append({"job": name, "graph": entry.name, "threshold": t, "repeat": 0,
                     "stage": "top", "rank": row["rank"], "edge": row["max_edge"]})
    return jobs, meta


def edge_lambdas(records: list[dict], threshold: float) -> dict[tuple, dict]:
    """``{(graph, edge): {lambda_km, lambda_km_se, sd, n_repeats, representative}}`` at ``threshold``.

    Repeats are averaged: ``lambda_km`` is their mean, ``lambda_km_se`` the combined standard
    error of that mean and ``sd`` their standard deviation (``nan`` for one repeat).
    """
    per: dict[tuple, dict] = {}
    for r in records:
        if not math.isclose(r.get("threshold", threshold), threshold):
            continue
        # one value per (edge, repeat): the records of different betas repeat the same Lambda
        per.setdefault((r["graph"], r["edge"]), {}).setdefault(
            r.get("repeat", 0), (r["lambda_km"], r["lambda_km_se"], r.get("representative", r["edge"])))
    out = {}
    for key, reps in per.items():
        ok = [v for v in reps.values() if v[0] is not None]
        if not ok:
            continue
        vals = np.array([v[0] for v in ok])
        out[key] = {
            "lambda_km": float(vals.mean()),
            "lambda_km_se": float(math.sqrt(sum((v[1] or 0.0) ** 2 for v in ok)) / len(ok)),
            "sd": float(vals.std(ddof=1)) if len(ok) > 1 else math.nan,
            "n_repeats": len(ok),
            "representative": ok[0][2],
        }
    return out


def trend_in_n(rows: list[dict], z: float = 4.0) -> dict:
    """What Fig. 2b's claim needs: is Lambda positive at every N, and does it decrease with N?

    ``rows`` are ``{N, lambda_km, lambda_km_se}`` sorted by N. A value is *positive* when it
    exceeds ``z`` standard errors; a step N -> N' is a *resolved decrease* when the drop exceeds
    ``z`` combined standard errors and a *resolved increase* when the rise does.

    Returns
    -------
    dict
        ``positive`` / ``not_positive`` (lists of N), ``decreases`` / ``increases`` (resolved
        steps as ``(N, N')``), ``unresolved`` (the other steps), ``z``, and ``gap``: the
        smallest ``k`` such that every pair ``N < N'`` with ``N' - N >= k`` is a resolved
        decrease (``None`` if even the widest pair is not).
    """
    out = {"z": z, "positive": [], "not_positive": [], "decreases": [], "increases": [],
           "unresolved": []}
    for r in rows:
        ok = r["lambda_km"] > z * r["lambda_km_se"]
        out["positive" if ok else "not_positive"].append(r["N"])
    for a, b in zip(rows, rows[1:], strict=False):
        drop = a["lambda_km"] - b["lambda_km"]
        se = math.hypot(a["lambda_km_se"], b["lambda_km_se"])
        key = "decreases" if drop > z * se else "increases" if -drop > z * se else "unresolved"
        out[key].append((a["N"], b["N"]))

    def resolved_drop(a, b) -> bool:
        return a["lambda_km"] - b["lambda_km"] > z * math.hypot(a["lambda_km_se"], b["lambda_km_se"])

    out["gap"] = None
    if len(rows) > 1:
        for k in range(1, rows[-1]["N"] - rows[0]["N"] + 1):
            if all(resolved_drop(a, b) for i, a in enumerate(rows) for b in rows[i + 1:]
                   if b["N"] - a["N"] >= k):
                out["gap"] = k
                break
    return out


def ranking(records: list[dict], threshold: float) -> list[dict]:
    """Graphs sorted by the sum of their positive Lambda^KM (the order of the paper's Fig. 3).

    ``records`` are fanned-out main-stage records; repeats are averaged. Returns one row per
    graph: ``rank``, ``graph``, ``score`` (sum of positive Lambda over all directed edges),
    ``max_edge`` / ``max_representative`` / ``lambda_max`` / ``lambda_max_se`` of its most
    antifragile edge, and ``tau0_mean`` / ``tau0_se`` (repeat 0).
    """
    tau0: dict[str, list] = {}
    for r in records:
        if math.isclose(r.get("threshold", threshold), threshold) and r.get("repeat", 0) == 0:
            tau0.setdefault(r["graph"], [r.get("tau0_mean"), r.get("tau0_se")])
    graphs: dict[str, dict] = {}
    for (g, edge), v in edge_lambdas(records, threshold).items():
        row = graphs.setdefault(g, {"graph": g, "score": 0.0, "lambda_max": -math.inf, "n_edges": 0})
        row["n_edges"] += 1
        if v["lambda_km"] > 0:
            row["score"] += v["lambda_km"]
        if v["lambda_km"] > row["lambda_max"]:
            row.update(lambda_max=v["lambda_km"], lambda_max_se=v["lambda_km_se"], max_edge=edge,
                       max_representative=v["representative"])
    rows = sorted(graphs.values(), key=lambda r: (-r["score"], r["graph"]))
    for k, row in enumerate(rows, 1):
        row["rank"] = k
        row["tau0_mean"], row["tau0_se"] = tau0.get(row["graph"], [None, None])
    return rows


def run_sweep(
    sweep: Sweep,
    *,
    output: str | Path | None = None,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool | None = None,
    executor=None,
    log=None,
    chunk_realizations: int | None = None,
    checkpoint_seconds: float = 30.0,
) -> Path:
    """Screen, run the main stage and the top stage of ``sweep`` into one HDF5 file.

    Parameters are those of :func:`antisync.runner.run_jobs`. Returns the file's path.

    The output is locked once for the whole sweep, before ``overwrite`` deletes anything (the
    ``run_jobs`` call of each stage takes the same lock again). A given ``executor`` is used
    by every stage and left open. ``resume`` on a complete sweep file leaves it untouched.
    A failure before anything was finished removes what the sweep created.
    """
    from antisync.store import ResultStore

    store = ResultStore(output or sweep.output)
    with store.lock(read_only_ok=resume) as writable:
        store.prepare(resume=resume, overwrite=overwrite)
        try:
            return _run_sweep_locked(
                sweep, store, writable, resume=resume, progress=progress, executor=executor,
                log=log, chunk_realizations=chunk_realizations,
                checkpoint_seconds=checkpoint_seconds,
            )
        except BaseException:
            if writable:
                store.discard_unfinished()
            raise


def _run_sweep_locked(sweep: Sweep, store, writable: bool, *, resume: bool, progress, executor,
                      log, chunk_realizations, checkpoint_seconds) -> Path:
    """The body of :func:`run_sweep`, with ``store`` locked and prepared."""
    import sys

    from tqdm import tqdm

    from antisync.runner import run_jobs
    from antisync.screening import ScreenResult, screen_graph

    say = log or (lambda msg: None)
    path = store.path
    key = sweep.key()
    if resume:
        store.load_states([], key)  # a file or journal of another sweep is an error, now
    stored = _read_meta(path) if path.exists() else None
    if resume and stored is not None and stored.get("complete") and store.file_complete():
        # every stage finished with this key: the file stays exactly as it is
        if writable:
            store.drop_journal()  # left by a kill after the last checkpoint
        say(f"{path} is already complete; nothing to do")
        return path
    if not writable:
        raise StoreError(f"cannot write to folder {path.parent} to finish {path}; "
                         "make it writable or use --out for a new file")
    entries = family_graphs(sweep)
    _check_backend(sweep, entries)  # before the journal: nothing is screened in vain
    store.start_journal(key)
    say(f"sweep {sweep.name}: {len(entries)} graph(s) of family {sweep.family['family']}, "
        f"{len(sweep.thresholds)} threshold(s), {sweep.repeats} repeat(s)")

    # -- 1. screening, cached per graph in the journal and in the file ------------------------
    screens: dict[str, ScreenResult] = {}
    if stored:
        for gm in stored["graphs"]:
            if gm.get("screen"):
                screens[gm["graph"]] = ScreenResult.from_dict(gm["screen"])
    cache = store.journal / "screen"
    cache.mkdir(parents=True, exist_ok=True)
    for p in cache.glob("*.json"):
        try:
            d = json.loads(p.read_text())
        except (OSError, ValueError):
            continue  # cut off by a crash: screened again
        screens.setdefault(d["graph"], ScreenResult.from_dict(d))
    show = sys.stderr.isatty() if progress is None else progress
    todo = [e for e in entries if sweep.screen.enabled and e.name not in screens]
    dyn = sweep.base.dynamics
    bar = tqdm(total=len(entries), initial=len(entries) - len(todo), unit="graph", desc="screening",
               disable=not show or not todo, file=sys.stderr, dynamic_ncols=True)
    for entry in todo:
        res = screen_graph(
            graphs_mod.omega_matrix(entry.graph), graph=entry.name, seed=sweep.base.seed,
            realizations=sweep.screen.realizations, t_max=sweep.screen.t_max, dt=dyn.dt,
            threshold=max(sweep.thresholds), coupling_kind=dyn.coupling,
            exclude_fraction=sweep.screen.exclude_fraction, threads=sweep.base.threads,
        )
        screens[entry.name] = res
        _atomic_json(cache / f"{entry.name}.json", res.to_dict())
        bar.update(1)
    bar.close()
    excluded = {n for n, s in screens.items() if s.excluded}
    kept = [e for e in entries if e.name not in excluded]
    for e in entries:
        if e.name in excluded:
            say(f"excluded {e.name}: {screens[e.name].reason}")
    if not kept:
        raise ConfigError(f"sweep {sweep.name}: every graph was excluded by the screening")

    # -- 2. main stage ---------------------------------------------------------------------
    jobs, jobs_meta = main_jobs(sweep, kept)
    saved = _symmetry(sweep, kept, jobs)
    say(f"symmetry: {saved['directed_edges']} directed edges in {saved['representatives']} orbits; "
        f"integrating representatives saves {saved['integrations_saved']:,} of "
        f"{saved['integrations_without_symmetry']:,} integrations ({saved['fraction_saved']:.0%})")
    state = {"jobs_meta": list(jobs_meta), "final": sweep.top.graphs == 0}

    def write_meta(f, states) -> None:
        meta = _meta(sweep, entries, screens, excluded, state["jobs_meta"], saved)
        meta["complete"] = bool(state["final"] and all(st.complete for st in states.values()))
        f.attrs["complete"] = meta["complete"]  # as for a run file: every stage finished
        grp = f.create_group("sweep")
        grp.attrs["format"] = SWEEP_FORMAT
        grp.attrs["format_version"] = SWEEP_FORMAT_VERSION
        grp.create_dataset("meta_json", data=json.dumps(meta))

    common = dict(progress=progress, executor=executor, log=log,
                  chunk_realizations=chunk_realizations, checkpoint_seconds=checkpoint_seconds,
                  key=key, provenance={"config_yaml": sweep.to_yaml(), "sweep": sweep.name},
                  extra=write_meta)
    main_done = False
    if stored is not None:
        states = store.load_states(jobs, key)
        main_done = all(st.complete for st in states.values())
    if not main_done:
        run_jobs(jobs, sweep.base, output=path, resume=True, **common)
    if sweep.top.graphs == 0:
        if main_done:
            # done, but the file did not say complete (a complete one returned above): rewrite
            # it so that its metadata is current
            run_jobs(jobs, sweep.base, output=path, resume=True, **common)
        return path

    # -- 3. top stage ----------------------------------------------------------------------
    records = sweep_summary(path)["records"]
    tjobs, tmeta = top_jobs(sweep, kept, records)
    state["jobs_meta"] = jobs_meta + tmeta
    state["final"] = True
    if tjobs:
        say(f"top stage: {len(tjobs)} graph(s), edge of largest Lambda, betas "
            f"{list(sweep.top.betas)}, {tjobs[0].config.realizations:,} realizations")
    run_jobs(jobs + tjobs, sweep.base, output=path, resume=True, **common)
    return path


def _check_backend(sweep: Sweep, entries: list[GraphEntry]) -> None:
    """Refuse, before anything is written, what the sweep's backend cannot run: its options
    (:func:`~antisync.compute.check_backend`) and, on cuda, a graph with more nodes than
    the kernels hold (the stages' ``run_jobs`` would refuse it only after the screening)."""
    from antisync.backends import resolve_backend
    from antisync.compute import check_backend

    backend, _ = resolve_backend(sweep.base.backend)
    check_backend(sweep.base, backend)
    if backend == "cuda":
        from antisync.kernels.cuda import MAX_NODES

        for e in entries:
            if e.graph.number_of_nodes() > MAX_NODES:
                raise ConfigError(
                    f"graph {e.name} has {e.graph.number_of_nodes()} nodes; the cuda backend runs "
                    f"at most {MAX_NODES}: use --backend cpu"
                )


def _symmetry(sweep: Sweep, kept: list[GraphEntry], jobs) -> dict:
    n_dir = sum(len(e.edges) for e in kept)
    n_rep = sum(len(e.representatives) for e in kept)
    with_sym = without = 0
    by_graph = {e.name: e for e in kept}
    for job in jobs:
        entry = by_graph[job.graph.graph["name"]]
        # the betas and dbeta of one edge (orbit: plus the +-dbeta pair)
        per_edge = (job.integrations_per_realization - 1) // len(job.edges)
        m = job.config.realizations
        with_sym += (1 + per_edge * len(entry.representatives)) * m
        without += (1 + per_edge * len(entry.edges)) * m
    return {
        "directed_edges": n_dir, "representatives": n_rep,
        "integrations": with_sym, "integrations_without_symmetry": without,
        "integrations_saved": without - with_sym,
        "fraction_saved": (without - with_sym) / without if without else 0.0,
    }


def _meta(sweep, entries, screens, excluded, jobs_meta, saved) -> dict:
    graphs = []
    for e in entries:
        s = screens.get(e.name)
        graphs.append({
            "graph": e.name, "spec": e.spec,
            "nodes": [_jsonable(v) for v in graphs_mod.node_order(e.graph)],
            "undirected_edges": [[_jsonable(u), _jsonable(v)] for u, v in e.graph.edges],
            "orbits": e.orbit_labels(),
            "excluded": e.name in excluded,
            "screen": s.to_dict() if s is not None else None,
        })
    return {
        "format": SWEEP_FORMAT, "format_version": SWEEP_FORMAT_VERSION, "name": sweep.name,
        "family": sweep.family, "thresholds": list(sweep.thresholds), "repeats": sweep.repeats,
        "ranking_threshold": sweep.ranking_threshold(),
        "top": asdict(sweep.top) | {"betas": list(sweep.top.betas)},
        "screen": asdict(sweep.screen), "graphs": graphs, "jobs": jobs_meta, "symmetry": saved,
        "coupling": sweep.base.dynamics.coupling, "dbeta": sweep.base.lambda_.dbeta,
        "betas": list(sweep.base.betas),
    }


def _jsonable(v):
    return v if isinstance(v, int | float | str) else str(v)


def _atomic_json(path: Path, obj) -> None:
    import os

    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(obj))
    os.replace(tmp, path)


# ---- reading ---------------------------------------------------------------------------
def is_sweep_file(path: str | Path) -> bool:
    """Whether ``path`` is an antisync result file written by a sweep."""
    from antisync.store import open_results

    with open_results(path) as f:
        try:
            return "sweep" in f and f["sweep"].attrs.get("format") == SWEEP_FORMAT
        except Exception as exc:  # h5py reports a damaged group as OSError, KeyError, ...
            raise StoreError(f"{path} is damaged: its /sweep group cannot be read "
                             f"({type(exc).__name__})") from None


# what sweep_summary and the reports read from /sweep/meta_json: checked once, on reading
_META_KEYS = {"name": str, "family": dict, "thresholds": list, "ranking_threshold": (int, float),
              "graphs": list, "jobs": list, "symmetry": dict}
_META_GRAPH_KEYS = ("graph", "orbits", "excluded")
_META_JOB_KEYS = ("job", "graph", "stage", "threshold", "repeat")


def _read_meta(path: str | Path) -> dict | None:
    """The ``/sweep`` metadata, None for a run file; a damaged one is a :class:`StoreError`."""
    from antisync.store import open_results

    with open_results(path) as f:
        try:
            if "sweep" not in f:
                return None
            grp = f["sweep"]
            raw_version = grp.attrs.get("format_version", 0)
            raw = grp["meta_json"][()]
        except Exception as exc:  # a damaged group: OSError, KeyError, ... from h5py
            raise StoreError(f"{path} is damaged: /sweep/meta_json cannot be read "
                             f"({type(exc).__name__})") from None
    try:
        version = int(raw_version)
    except (TypeError, ValueError):
        raise StoreError(f"{path} is damaged: /sweep attribute format_version is "
                         f"{raw_version!r}, not an integer") from None
    if version > SWEEP_FORMAT_VERSION:
        raise StoreError(f"{path} was written by a newer antisync (sweep format {version}); this "
                         f"one reads sweep format {SWEEP_FORMAT_VERSION} — upgrade antisync")
    try:
        meta = json.loads(raw.decode() if isinstance(raw, bytes) else raw)
    except (TypeError, ValueError, UnicodeDecodeError) as exc:
        why = " ".join(str(exc).split())
        raise StoreError(f"{path} is damaged: /sweep/meta_json is not valid JSON ({why})") from None
    problem = _meta_problem(meta)
    if problem:
        raise StoreError(f"{path} is damaged: /sweep/meta_json {problem}")
    return meta


def _meta_problem(meta) -> str | None:
    """What is wrong with sweep metadata ``meta`` (None if it has what the readers need)."""
    if not isinstance(meta, dict):
        return "is not a JSON object"
    for key, kind in _META_KEYS.items():
        if not isinstance(meta.get(key), kind):
            return f"lacks {key!r} or it is not a {getattr(kind, '__name__', 'number')}"
    for name, items, keys in (("graphs", meta["graphs"], _META_GRAPH_KEYS),
                              ("jobs", meta["jobs"], _META_JOB_KEYS)):
        for i, item in enumerate(items):
            missing = [k for k in keys if not isinstance(item, dict) or k not in item]
            if missing:
                return f"entry {i} of {name!r} lacks {', '.join(map(repr, missing))}"
    return None


def read_meta(path: str | Path) -> dict:
    """The ``/sweep`` metadata of a sweep file (:class:`StoreError` if it is not one)."""
    meta = _read_meta(path)
    if meta is None:
        raise StoreError(f"{path} is a result file of `antisync run`, not of a sweep")
    return meta


def sweep_summary(path: str | Path, views=None) -> dict:
    """Everything a report needs from a sweep file.

    Returns
    -------
    dict
        ``records``: main-stage records fanned out to every selected directed edge of every
        kept graph (keys of :func:`antisync.summary.job_records` plus ``job``,
        ``threshold``, ``repeat``, ``representative``, ``orbit_size``);
        ``top``: records of the top stage (plus ``rank``);
        ``excluded``: ``{graph, reason, fraction_not_synced, fraction_stuck, screened}``;
        ``screen``: the screening of every graph; ``symmetry``: integrations saved;
        ``complete``: whether every stage finished.
    """
    from antisync.summary import read_views, view_records

    meta = read_meta(path)
    views = views if views is not None else read_views(path)
    by_job: dict[str, list] = {}
    # view_records joins lambda_km_nnc from `<job>_nnc` twins (measures: [km, km_nnc])
    for r in view_records(views):
        by_job.setdefault(r["graph"], []).append(r)
    graphs = {g["graph"]: g for g in meta["graphs"]}
    records, top = [], []
    for jm in meta["jobs"]:
        if jm["job"] not in by_job:
            continue
        recs = [{**r, "graph": jm["graph"], "job": jm["job"], "threshold": jm["threshold"],
                 "repeat": jm["repeat"]} for r in by_job[jm["job"]]]
        if jm["stage"] == "main":
            records += expand_records(recs, graphs[jm["graph"]]["orbits"])
        else:
            orbits = graphs[jm["graph"]]["orbits"]
            for r in recs:
                r.update(rank=jm["rank"], edge=jm["edge"], representative=r["edge"],
                         orbit_size=sum(1 for x in orbits.values() if x == r["edge"]))
            top += recs
    excluded = [
        {"graph": g["graph"], "reason": g["screen"]["reason"],
         "fraction_not_synced": g["screen"]["fraction_not_synced"],
         "fraction_stuck": g["screen"]["fraction_stuck"], "screened": g["screen"]["realizations"]}
        for g in meta["graphs"] if g["excluded"]
    ]
    return {
        "sweep": meta["name"], "family": meta["family"], "thresholds": meta["thresholds"],
        "ranking_threshold": meta["ranking_threshold"], "complete": meta.get("complete", False),
        "records": records, "top": top, "excluded": excluded,
        "screen": [g["screen"] for g in meta["graphs"] if g.get("screen")],
        "symmetry": meta["symmetry"], "meta": meta,
    }
