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

Overrides are keyword arguments named like the config's keys; a section takes a mapping that
is merged into it (``dynamics={"dt": 0.0005}``; ``lambda_`` stands for ``lambda``). Values are
set as they are, never parsed as YAML, and validated exactly as a config file is.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from antisync.config import Config

__all__ = ["Result", "load", "run", "summarize", "sweep"]

_SWEEP_KEYS = ("sweep", "family", "thresholds", "ranking_threshold", "excluded", "top", "screen", "symmetry")
_SECTIONS = ("dynamics", "lambda", "histogram", "linear", "screen", "top")


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
        ``complete`` and, when computed, ``lambda_xi2``, ``lambda_rw``, ``lambda_linear``,
        ``lambda_km_nnc``; ``antisync summary FILE --format json`` prints the same.
    complete : bool
        Whether every realization (every stage, for a sweep) has been computed.
    config_yaml : str
        The resolved config the file was made with.
    sweep : dict or None
        For a sweep: ``excluded`` graphs, ``top`` stage records, ``screen``, ``symmetry``,
        ``thresholds`` and ``ranking_threshold`` (see :func:`antisync.sweeps.sweep_summary`).
    stop : dict or None
        For a run with a stopping rule (docs/stopping.md): its looks, ``budget``,
        ``stopped_at``, ``stopped_early`` and the last look's counts and open links.
    """

    path: Path
    kind: str
    records: list[dict]
    complete: bool
    config_yaml: str = ""
    sweep: dict | None = field(default=None, repr=False)
    stop: dict | None = field(default=None, repr=False)

    def to_pandas(self):
        """The records as a :class:`pandas.DataFrame` (needs pandas: ``pip install pandas``)."""
        try:
            import pandas as pd
        except ImportError:
            from antisync.errors import AntisyncError

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


def load(path: str | Path) -> Result:
    """Read a run or sweep file written by :func:`run`, :func:`sweep` or the CLI.

    Raises
    ------
    antisync.errors.StoreError
        Missing, foreign, damaged or newer-format files, with a one-line message.
    """
    s = summarize(path)
    sweep = s if s["kind"] == "sweep" else None
    return Result(Path(path), s["kind"], s["records"], s["complete"], s["config_yaml"], sweep, s["stop"])


def summarize(path: str | Path) -> dict:
    """Everything ``antisync summary FILE --format json`` prints, for a run or a sweep file.

    One schema for both: ``kind`` ("run" or "sweep"), ``file``, ``complete``, ``records``,
    ``config_yaml``, and the sweep's ``sweep`` (name), ``family``, ``thresholds``,
    ``ranking_threshold``, ``excluded``, ``top``, ``screen``, ``symmetry`` (for a run file:
    ``null`` or empty lists, and ``thresholds`` the run's one threshold), and ``stop``, what
    a run's stopping rule did (:func:`antisync.store.stop_record`; ``null`` without one). The
    CLI adds to each record its ``sign_resolved`` (:func:`antisync.records.flag_signs`) and orders them with
    ``--sort`` (:func:`antisync.records.sort_records`).
    """
    from antisync.store import is_sweep_file, records, root_attrs, stop_record
    from antisync.sweeps import sweep_summary

    path = Path(path)
    root = root_attrs(path)
    if is_sweep_file(path):
        s = sweep_summary(path)
        return {
            "kind": "sweep",
            "file": str(path),
            "complete": bool(s["complete"]),
            "records": s["records"],
            "config_yaml": root["config_yaml"],
            "stop": None,
            **{k: s[k] for k in _SWEEP_KEYS},
        }
    recs = records(path)
    import yaml

    cfg = yaml.safe_load(root["config_yaml"] or "{}") or {}
    threshold = (cfg.get("dynamics") or {}).get("threshold")
    thresholds = [threshold] if threshold is not None else []
    return {
        "kind": "run",
        "file": str(path),
        "complete": root["complete"],
        "records": recs,
        "config_yaml": root["config_yaml"],
        "stop": stop_record(path),
        "sweep": None,
        "family": None,
        "thresholds": thresholds,
        "ranking_threshold": None,
        "excluded": [],
        "top": [],
        "screen": [],
        "symmetry": None,
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
        (``{"graph": {"kind": "lollipop", "nodes": 6, "path": 3}}``) or a
        :class:`antisync.config.Config`.
    output : path, optional
        The HDF5 file (default: the config's ``output``, ``results/<name>.h5``).
    resume, overwrite : bool
        As the CLI's ``--resume`` (finish an interrupted file; a complete one is returned as
        it is) and ``--overwrite`` (replace an antisync result file). Without either an
        existing file is an error.
    progress : bool
        Show a progress bar on stderr.
    executor : optional
        A :class:`antisync.executors.dask.DaskExecutor` (or any executor); it stays open.
    log : callable, optional
        Receives one-line progress messages.
    **overrides
        Config keys (``realizations=5000``, ``seed=3``, ``betas=[0.5]``,
        ``dynamics={"dt": 0.0005}``, ``lambda_={"method": "orbit"}``).

    Examples
    --------
    >>> import antisync
    >>> res = antisync.run({"graph": {"kind": "lollipop", "nodes": 6, "path": 3},
    ...                     "edges": ["2->1"], "betas": [0.5]}, realizations=200,
    ...                    output=tmp / "l.h5")                      # doctest: +SKIP
    >>> res.records[0]["F_mean"] > 1                                 # doctest: +SKIP
    True
    """
    from antisync.runner import run_config

    cfg = _config(config, overrides, output)
    path = run_config(cfg, resume=resume, overwrite=overwrite, progress=progress, executor=executor, log=log)
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

    Parameters are those of :func:`run`; ``config`` is a YAML file or a mapping.
    """
    from antisync.sweeps import load_sweep, load_sweep_text, run_sweep

    values = _values(overrides, output)
    if isinstance(config, Mapping):
        import yaml

        sw = load_sweep_text(yaml.safe_dump(dict(config)), values=values)
    else:
        sw = load_sweep(config, values=values)
    path = run_sweep(sw, resume=resume, overwrite=overwrite, progress=progress, executor=executor, log=log)
    return load(path)


def _values(overrides: Mapping, output) -> dict:
    """Keyword overrides -> dotted config keys (sections merged key by key)."""
    values: dict[str, Any] = {}
    for key, value in overrides.items():
        key = "lambda" if key == "lambda_" else key
        if key in _SECTIONS and isinstance(value, Mapping):
            for sub, v in value.items():
                values[f"{key}.{sub}"] = v
        else:
            values[key] = value
    if output is not None:
        values["output"] = str(output)
    return values


def _config(config, overrides: Mapping, output) -> Config:
    import copy

    from antisync.config import Config, apply_values, config_from_mapping, load_config

    values = _values(overrides, output)
    if isinstance(config, Config):
        raw = config.to_dict()
    elif isinstance(config, Mapping):
        raw = copy.deepcopy(dict(config))
    else:
        return load_config(config, values=values)
    apply_values(raw, values)  # as load_config applies them to a file's mapping
    return config_from_mapping(raw)
