"""The Python API: run a config, run a sweep, load a result, compute the exact measures.

Everything the CLI does is here as a function that returns data, so a notebook needs no
shell and no file parsing::

    import antisync

    res = antisync.run("configs/lollipop6.yaml", realizations=2000, betas=[0.5],
                       output="lollipop.h5", overwrite=True)
    res.records[0]["lambda_km"], res.records[0]["lambda_km_se"]
    df = res.to_pandas()                      # pandas is optional
    antisync.load("lollipop.h5").records      # the same records, from the file
    antisync.measures.for_graph(nx.karate_club_graph())  # exact Lambda^xi2, Lambda^RW
    antisync.run({"graph": nx.karate_club_graph(), "name": "karate"}, output="karate.h5")

Overrides are keyword arguments named like the config's keys; a section (a key whose value is
a mapping of its own options: ``dynamics``, ``lambda``, ``histogram``, ``linear``, ``model``,
``sync``, ``stop``, and a sweep's ``screen`` and ``top``) takes a mapping that is merged into it
key by key (``model={"damping": 2}`` keeps the config's frequencies and inertia; ``lambda_``
stands for ``lambda``). Values are set
as they are, never parsed as YAML, and validated exactly as a config file is; numpy scalars and
arrays count as the Python numbers and lists they hold.

A networkx graph object is a graph spec too (``{"graph": G}``, ``graph=G``, an item of a
sweep's ``sweep.graphs``): it is read as :func:`antisync.measures.for_graph` reads it and
written into the config as ``{kind: inline, links: [...]}`` (:func:`antisync.physics.graphs.graph_spec`),
so the result file holds the graph and ``resume``, ``antisync summary`` and ``antisync report``
need no object.

Every argument is checked before any file or folder is made: a bad one raises a
:class:`~antisync.errors.ConfigError` (or, for a result file to read, a
:class:`~antisync.errors.StoreError`) whose one-line message names the argument, what it got and
what is valid.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from antisync.errors import AntisyncError, ConfigError, StoreError
from antisync.execution.runner import run_config
from antisync.optimize.config import design_from_mapping
from antisync.optimize.run import run_design
from antisync.plan.config import Config, parse_mapping, read_config_text
from antisync.plan.describe import model_line
from antisync.plan.sources import (
    file_path,
    flag,
    override_values,
    plain,
    resolve_config,
    sections,
    shown,
    sweep_graphs,
)
from antisync.stats.records import flag_signs
from antisync.stats.sum_rule import views_sums
from antisync.stats.summary import r_star_rows, view_records
from antisync.store import is_sweep_file, read_views, root_attrs, stop_record
from antisync.store.design_file import read_design
from antisync.store.layout import decode_config
from antisync.sweeps import Sweep, load_sweep, load_sweep_text, run_sweep, sweep_summary

__all__ = ["Result", "design", "load", "run", "summarize", "sweep"]

_SWEEP_KEYS = (
    "sweep",
    "family",
    "thresholds",
    "ranking_threshold",
    "excluded",
    "top",
    "screen",
    "symmetry",
    "grid",
)


@dataclass(frozen=True)
class Result:
    """What a run or sweep file holds, decoded.

    Attributes
    ----------
    path : Path
        The HDF5 file.
    kind : {"run", "sweep"}
    records : list of dict
        One record per (graph, directed edge, beta): ``F_mean``, ``lambda_km``, ``tau0_mean``
        with their standard errors, status counts (``n``, ``n_excluded``, ``n_not_synced``),
        ``complete``, ``sign_resolved`` and ``sign_per_link``
        (:func:`antisync.stats.records.flag_signs`), ``r_star`` and ``r_star_damaged``
        (``sync.criterion: relative``, else None) and, when computed, ``lambda_xi2``,
        ``lambda_rw``, ``lambda_linear``, ``lambda_km_nnc``; ``antisync summary FILE --format
        json`` prints the same.
    complete : bool
        Whether every realization (every stage, for a sweep) has been computed.
    config_yaml : str
        The resolved config the file was made with.
    sweep : dict or None
        For a sweep: ``excluded`` graphs, ``top`` stage records, ``screen``, ``symmetry``,
        ``thresholds`` and ``ranking_threshold`` (see :func:`antisync.sweeps.sweep_summary`).
    stop : dict or None
        For a run or sweep with a stopping rule (docs/stopping.md): its looks, ``budget``,
        ``stopped_at``, ``stopped_early`` and the last look's counts and open links.
    model : str or None
        Which model ran, in one line (:func:`antisync.plan.describe.model_line`).
    r_star : list of dict
        ``sync.criterion: relative``: per graph, the r* of the undamaged network and its range
        over the damaged variants (:func:`antisync.stats.summary.r_star_rows`); empty for another
        criterion and for a file written before r* was stored.
    """

    path: Path
    kind: str
    records: list[dict]
    complete: bool
    config_yaml: str = ""
    sweep: dict | None = field(default=None, repr=False)
    stop: dict | None = field(default=None, repr=False)
    model: str | None = field(default=None, repr=False)
    r_star: list[dict] = field(default_factory=list, repr=False)

    def to_pandas(self):
        """The records as a :class:`pandas.DataFrame` (needs pandas: ``pip install pandas``)."""
        try:
            import pandas as pd
        except ImportError:
            raise AntisyncError(
                "Result.to_pandas needs pandas (pip install pandas); "
                "Result.records holds the same data as dicts"
            ) from None
        return pd.DataFrame.from_records(self.records)

    def __repr__(self) -> str:
        graphs = sorted({r["graph"] for r in self.records})
        shown = ", ".join(graphs[:3]) + (", ..." if len(graphs) > 3 else "")
        return (
            f"Result({self.kind} {str(self.path)!r}, {len(self.records)} records, "
            f"graphs {shown or '-'}, complete={self.complete})"
        )


def load(path: str | Path):
    """Read a run or sweep file written by :func:`run`, :func:`sweep` or the CLI, as a
    :class:`Result`; a table of ``antisync grid removal|trip --out`` (JSON or HDF5) as the
    :class:`antisync.api.grids.GridResult` its run returned (:func:`antisync.api.grids.load_table`).

    Raises
    ------
    antisync.errors.StoreError
        Missing, foreign, damaged or newer-format files, and a ``path`` that is no file path,
        with a one-line message.
    """
    path = _result_path(path)
    if _grid_table(path):
        from antisync.api.grids import load_table

        return load_table(path)
    s = summarize(path)
    sweep = s if s["kind"] == "sweep" else None
    fields = {k: s[k] for k in ("config_yaml", "stop", "model", "r_star")}
    return Result(path, s["kind"], s["records"], s["complete"], sweep=sweep, **fields)


def summarize(path: str | Path) -> dict:
    """Everything ``antisync summary FILE --format json`` prints, for a run or a sweep file.

    One schema for both: ``kind`` ("run" or "sweep"), ``file``, ``complete``, ``records``,
    ``config_yaml``, and the sweep's ``sweep`` (name), ``family``, ``thresholds``,
    ``ranking_threshold``, ``excluded``, ``top``, ``screen``, ``symmetry``, ``grid`` (a grid
    sweep's axes, docs/sweeps.md; ``null`` without a grid) (for a run file:
    ``null`` or empty lists, and ``thresholds`` the run's one threshold), and ``stop``, what
    a run's or sweep's stopping rule did (:func:`antisync.store.stop_record`; ``null`` without
    one), and
    ``sum_rule``, per node whose out-links were all measured with normalized coupling, the sum
    of their Lambda with its interval (:func:`antisync.stats.sum_rule.node_sums`), ``model``, which
    model ran in one line (:func:`antisync.plan.describe.model_line`), and ``r_star``, per
    graph run with ``sync.criterion: relative`` the r* of the undamaged network and its range
    over the damaged variants (:func:`antisync.stats.summary.r_star_rows`; empty for a file written
    before r* was stored). The records carry ``sign_resolved`` (at false discovery rate 0.05
    over the file's links) and ``sign_per_link`` (:func:`antisync.stats.records.flag_signs`); the CLI
    orders them with ``--sort`` (:func:`antisync.stats.records.sort_records`).

    Raises
    ------
    antisync.errors.StoreError
        As :func:`load`.
    """
    path = _result_path(path)
    try:
        return _summarize(path)
    except OSError as exc:  # the machine refused: permission denied, an unreadable disk
        raise StoreError(f"cannot read result file {path}: {exc.strerror or exc}") from None


def _summarize(path: Path) -> dict:
    root = root_attrs(path)
    views = read_views(path)  # decoded once: the records and the sum rule read the same jobs
    cfg = decode_config(root["config_yaml"], path)  # the store's one decoder, one policy
    model = {"model": model_line(cfg), "r_star": r_star_rows(views)}
    if is_sweep_file(path):
        s = sweep_summary(path)
        return {
            "kind": "sweep",
            "file": str(path),
            "complete": bool(s["complete"]),
            "records": flag_signs(s["records"]),
            "sum_rule": views_sums(views),
            "config_yaml": root["config_yaml"],
            "stop": stop_record(path),
            **model,
            **{k: s[k] for k in _SWEEP_KEYS},
        }
    recs = view_records(views)
    dynamics = cfg.get("dynamics")
    threshold = dynamics.get("threshold") if isinstance(dynamics, dict) else None
    thresholds = [threshold] if threshold is not None else []
    return {
        "kind": "run",
        "file": str(path),
        "complete": root["complete"],
        "records": flag_signs(recs),
        "sum_rule": views_sums(views),
        "config_yaml": root["config_yaml"],
        "stop": stop_record(path),
        **model,
        "sweep": None,
        "family": None,
        "thresholds": thresholds,
        "ranking_threshold": None,
        "excluded": [],
        "top": [],
        "screen": [],
        "symmetry": None,
        "grid": None,
    }


def run(
    config: str | Path | Mapping | Config,
    /,
    *,
    output: str | Path | None = None,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool = False,
    executor=None,
    log: Callable[[str], None] | None = None,
    **overrides: Any,
) -> Result:
    """Run one config (one graph) into an HDF5 file and return its :class:`Result`.

    Parameters
    ----------
    config : path, mapping or Config
        A YAML file (``"configs/lollipop6.yaml"``), the same keys as a mapping
        (``{"graph": {"kind": "lollipop", "nodes": 6, "path": 3}}``, or ``{"graph": G}`` with
        a networkx graph ``G``: its ``weight`` attributes, default 1; records and figures are
        named by the config's ``name``, default ``graph``) or a
        :class:`antisync.plan.config.Config`.
    output : path, optional
        The HDF5 file (default: the config's ``output``, ``results/<name>.h5``).
    resume, overwrite : bool
        As the CLI's ``--resume`` (finish an interrupted file; a complete one is returned as
        it is) and ``--overwrite`` (replace an antisync result file); they exclude each other.
        Without either an existing file is an error.
    progress : bool
        Show a progress bar on stderr.
    executor : optional
        A :class:`antisync.execution.executors.dask.DaskExecutor` (or any object with ``run``,
        ``describe`` and ``close``); it stays open. Default: a local executor.
    log : callable, optional
        Receives one-line progress messages (``log=print`` prints what the CLI prints).
    **overrides
        Config keys (``realizations=5000``, ``seed=3``, ``betas=[0.5]``,
        ``dynamics={"dt": 0.0005}``, ``lambda_={"method": "orbit"}``). A mapping given to a
        section is merged into the config's section key by key (``model={"damping": 2}`` keeps
        the config's frequencies); ``None`` puts a section back to its defaults; any other key
        (``graph`` included, which may be a networkx graph) is replaced whole. numpy scalars
        and arrays are taken as the Python numbers and lists they hold.

    Raises
    ------
    antisync.errors.ConfigError
        A bad argument or config value, with a one-line message naming it; raised before any
        file or folder is made.
    antisync.errors.StoreError
        An existing output without ``resume`` or ``overwrite``, or one that cannot be used.

    Examples
    --------
    >>> import antisync
    >>> res = antisync.run({"graph": {"kind": "lollipop", "nodes": 6, "path": 3},
    ...                     "edges": ["2->1"], "betas": [0.5]}, realizations=200,
    ...                    output=tmp / "l.h5")                      # doctest: +SKIP
    >>> res.records[0]["F_mean"] > 1                                 # doctest: +SKIP
    True
    """
    if not isinstance(config, str | os.PathLike | Mapping | Config):
        raise ConfigError(
            f"antisync.run: config must be a YAML file path, a mapping of config keys or an "
            f"antisync.plan.config.Config, got {shown(config)}"
        )
    opts = _options("antisync.run", resume, overwrite, progress, executor, log)
    cfg = resolve_config(config, overrides, output)
    path = run_config(cfg, **opts)
    return load(path)


def sweep(
    config: str | Path | Mapping,
    /,
    *,
    output: str | Path | None = None,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool = False,
    executor=None,
    log: Callable[[str], None] | None = None,
    **overrides: Any,
) -> Result:
    """Run a sweep (a config with a ``sweep:`` section, see ``configs/atlas6.yaml``): screen
    the family's graphs, integrate one edge per automorphism orbit, run the top stage.

    Parameters are those of :func:`run`; ``config`` is a YAML file or a mapping. Besides the
    sections of a run, ``screen`` and ``top`` are sections too (merged); ``sweep`` (the
    family) is replaced whole, as its keys depend on its ``family``. The graph specs of
    ``sweep: {family: graphs, graphs: [...]}`` may be networkx graph objects, named
    ``graph1``, ``graph2``, ... by their place in the list (a spec of
    :func:`antisync.physics.graphs.graph_spec` with a ``name`` key names one).
    """
    if not isinstance(config, str | os.PathLike | Mapping):
        raise ConfigError(
            f"antisync.sweep: config must be a YAML file path or a mapping with a sweep: section "
            f"(see configs/atlas6.yaml), got {shown(config)}"
        )
    opts = _options("antisync.sweep", resume, overwrite, progress, executor, log)
    overrides = {k: sweep_graphs(v) if k == "sweep" else v for k, v in overrides.items()}
    values = override_values(overrides, output, sections(Sweep))
    if isinstance(config, Mapping):
        raw = plain({k: sweep_graphs(v) if k == "sweep" else v for k, v in config.items()}, "config")
        sw = load_sweep_text(yaml.safe_dump(raw), values=values)
    else:
        sw = load_sweep(file_path("config", config, ConfigError), values=values)
    path = run_sweep(sw, **opts)
    return load(path)


def design(
    config: str | Path | Mapping,
    /,
    *,
    output: str | Path | None = None,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool = False,
    log: Callable[[str], None] | None = None,
    **overrides: Any,
) -> dict:
    """Design the link weights of a network under a budget (docs/design.md) and return the
    design file's record (:func:`antisync.store.design_file.read_design`).

    Parameters
    ----------
    config : path or mapping
        A design config: a run config with a ``design:`` section (``configs/karate_design.yaml``),
        as a YAML file or the same keys as a mapping.
    output : path, optional
        The design's HDF5 file (default: ``design.output``, else ``results/<name>_design.h5``).
    resume, overwrite, progress, log
        As in :func:`run`.
    **overrides
        Config keys; a mapping given to a section (``design={"iterations": 50}``) is merged into
        it key by key.

    Returns
    -------
    dict
        ``baselines`` (name -> weights, ``designed`` first), ``verification`` (``rows``: each
        design's mean tau on fresh starts and its paired difference to the designed one with a
        95% interval), ``iterations``, ``checks``, ``problem`` (``labels`` of the links) and
        ``sensitivity``.

    Examples
    --------
    >>> rec = antisync.design("configs/karate_design.yaml", design={"iterations": 20},
    ...                       output=tmp / "k.h5")                   # doctest: +SKIP
    >>> rec["verification"]["rows"][1]["design"]                     # doctest: +SKIP
    'uniform'
    """
    opts = _options("antisync.design", resume, overwrite, progress, None, log)
    if isinstance(config, Mapping):
        raw = {k: (dict(v) if isinstance(v, Mapping) else v) for k, v in config.items()}
        source = None
    elif isinstance(config, str | os.PathLike):
        source = Path(config)
        raw = None
    else:
        raise ConfigError(
            "antisync.design: config must be a YAML file path or a mapping of config keys, "
            f"got {shown(config)}"
        )
    if raw is None:
        raw = parse_mapping(read_config_text(source))
    for key, value in overrides.items():
        if isinstance(value, Mapping) and isinstance(raw.get(key), Mapping):
            raw[key] = {**raw[key], **value}
        else:
            raw[key] = value
    if output is not None:
        raw["design"] = {**(raw.get("design") or {}), "output": str(output)}
    cfg, spec = design_from_mapping(raw, source)
    path = run_design(
        cfg,
        spec,
        resume=opts["resume"],
        overwrite=opts["overwrite"],
        progress=opts["progress"],
        log=opts["log"] or (lambda m: None),
    )
    return read_design(path)


def _options(where: str, resume, overwrite, progress, executor, log) -> dict:
    """The keyword arguments of :func:`run` and :func:`sweep` that are not config keys, checked."""

    opts = {
        name: flag(f"{where}: {name}", value)
        for name, value in (("resume", resume), ("overwrite", overwrite), ("progress", progress))
    }
    if opts["resume"] and opts["overwrite"]:
        # as the CLI's --resume --overwrite: finishing a file and replacing it are two wishes
        raise ConfigError(f"{where}: resume and overwrite exclude each other: choose one")
    if executor is not None:
        # a class has run/describe/close too, as unbound functions that would fail mid-run
        usable = not isinstance(executor, type) and all(
            callable(getattr(executor, m, None)) for m in ("run", "describe", "close")
        )
        if not usable:
            raise ConfigError(
                f"{where}: executor must be None (a local executor) or an executor object such as "
                f"antisync.execution.executors.dask.DaskExecutor (with run, describe and close), got "
                f"{shown(executor)}"
            )
    if log is not None and not callable(log):
        raise ConfigError(
            f"{where}: log must be None or a callable taking one string (e.g. print), got {shown(log)}"
        )
    return {**opts, "executor": executor, "log": log}


def _grid_table(path: Path) -> bool:
    """Whether ``path`` is a table of ``antisync grid`` (its JSON or HDF5 file)."""
    from antisync.report.grid_tables import table_kind

    try:
        return table_kind(path) is not None
    except AntisyncError:
        return False  # JSON of another kind: the result readers name what is wrong


def _result_path(path) -> Path:

    return file_path("path", path, StoreError)
