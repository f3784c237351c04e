"""Grids over config keys: ``sweep: {grid: {...}, zip: {...}}`` and ``--grid`` / ``--zip``.

A sweep's *points* are the runs of one graph that differ in a few config keys::

    sweep:
      grid: {model.phase_lag: [0, 0.2, 0.4], dynamics.threshold: [0.9, 0.99]}  # every pair
      zip: {model.inertia: [0.5, 1, 2], model.damping: [1, 1, 1]}             # side by side

``grid`` is the cartesian product of its lists (the first key varies slowest); ``zip`` pairs its
lists element by element (equal lengths) and counts as one more axis of the product. Each
point's config is the sweep's run keys with the point's values set at their dotted keys and
validated like a run config (:func:`antisync.plan.config.config_from_mapping`), so a value that a
run would refuse is refused here, naming the key and the point.

:func:`sweep_axes` validates the section, :func:`grid_points` expands it, :func:`point_suffix`
names a point's jobs and :func:`point_label` labels it. Both are injective on the values (a
number is written as ``:g`` writes it when that reads back as the same number, else in full:
``0.1`` and ``0.1000001``, seeds ``1000001`` and ``1000002``), so two points never share a job
or a label. A grid has at most :data:`MAX_GRID_JOBS` jobs, refused from the axes' lengths
before any point is expanded (:func:`check_grid_size`).
"""

from __future__ import annotations

import copy
import itertools
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

from antisync.errors import ConfigError
from antisync.plan.config import Config, apply_values, config_from_mapping, yaml_load
from antisync.validation import show, suggest

__all__ = [
    "GRID_KEYS",
    "MAX_GRID_JOBS",
    "THRESHOLD_KEYS",
    "Axis",
    "GridPoint",
    "axis_option",
    "check_grid_size",
    "grid_points",
    "number_name",
    "point_text",
    "point_label",
    "point_suffix",
    "sweep_axes",
]

# the keys a grid may sweep: the sections that decide the dynamics and the estimate, and the
# run's realizations and seed; the graph, the links, where and how it runs are the sweep's
_SECTION_KEYS = {
    "dynamics": ("coupling", "integrator", "dt", "threshold", "t_max", "crossing", "precision"),
    "model": ("frequencies", "phase_lag", "inertia", "damping", "law", "params", "edge_params"),
    "sync": ("criterion", "threshold", "fraction", "tolerance"),
    "lambda": ("method", "dbeta", "hybrid_cut"),
    "linear": ("realizations", "method"),
}
_TOP_GRID_KEYS = ("realizations", "seed")
#: every key a ``grid:`` or ``zip:`` may name (deeper keys of a mapping value are allowed below
#: them, e.g. ``model.frequencies.sd``, ``model.params.omega``: a law's parameter,
#: ``model.edge_params.alpha``: its edge parameter)
GRID_KEYS: tuple[str, ...] = _TOP_GRID_KEYS + tuple(f"{s}.{k}" for s, ks in _SECTION_KEYS.items() for k in ks)
#: grid keys that set the synchronization threshold of a point's jobs
THRESHOLD_KEYS = ("dynamics.threshold", "sync.threshold")
#: the most jobs (graphs x points x thresholds x repeats) a sweep with a grid may have: each is
#: a job group of the file, planned (graph, coupling arrays, checks) before anything runs, and
#: every checkpoint rewrites the sweep's job list; 10,000 jobs already take minutes to plan and
#: days to run at a few thousand realizations each (docs/sweeps.md, "Grids over any key")
MAX_GRID_JOBS = 10_000
# keys that are never swept, with the reason said when one is named
_REFUSED = {
    "graph": "the graph of a grid sweep is its graph: (or sweep.family)",
    "sweep": "sweep: describes the sweep itself",
    "output": "a sweep writes one file",
    "name": "a sweep has one name",
    "edges": "the links are the sweep's edges:",
    "betas": "the betas are the sweep's betas:",
    "measures": "every point computes the sweep's measures:",
    "stop": "stop: is one rule over every job of the sweep",
    "thresholds": "give the thresholds as a grid over dynamics.threshold, or as thresholds:",
}


@dataclass(frozen=True)
class Axis:
    """One axis of the product: a ``grid`` key, or every ``zip`` key moving together."""

    keys: tuple[str, ...]
    values: tuple[tuple, ...]  # one tuple (a value per key) per position on the axis
    zipped: bool = False

    def __len__(self) -> int:
        return len(self.values)


@dataclass(frozen=True)
class GridPoint:
    """One point of a sweep's grid: ``values`` (``((key, value), ...)``, in the axes' order),
    ``index`` (its position on each axis) and the validated :class:`~antisync.plan.config.Config`
    of its jobs (the sweep's first graph; the stages put in each graph)."""

    values: tuple
    index: tuple[int, ...]
    config: Config

    def as_dict(self) -> dict:
        return dict(self.values)

    @property
    def threshold(self) -> float | None:
        """The threshold the point sets (``None``: the sweep's ``thresholds`` apply)."""
        if any(k in THRESHOLD_KEYS for k, _ in self.values):
            return self.config.dynamics.threshold
        return None


def axis_option(option: str, item: str) -> tuple[str, list]:
    """``KEY=V1,V2,...`` of ``--grid`` / ``--zip`` -> ``(KEY, [V1, V2, ...])``, each value
    parsed as YAML (``--grid model.frequencies={distribution: normal, sd: 0.1},...`` too)."""
    key, sep, text = item.partition("=")
    key = key.strip()
    example = f"{option} model.phase_lag=0,0.1,0.2"
    if not sep or not key or not text.strip():
        raise ConfigError(f"{option} expects KEY=V1,V2,... (e.g. {example}), got {item!r}")
    try:
        values = yaml_load(f"[{text}]")
    except Exception:
        raise ConfigError(f"{option} {key}: {text!r} is not a comma-separated list of values") from None
    return key, values


def sweep_axes(section: dict) -> tuple[Axis, ...]:
    """The validated axes of a ``sweep:`` section's ``grid`` and ``zip`` (``()`` without them).

    Raises
    ------
    ConfigError
        For a key that is not a config key a grid can sweep (naming the valid ones), an empty
        list, ``zip`` lists of unequal lengths, a key in both, or a value listed twice.
    """
    grid = section.get("grid") or {}
    zipped = section.get("zip") or {}
    for name, part in (("grid", grid), ("zip", zipped)):
        if not isinstance(part, dict):
            raise ConfigError(
                f"sweep.{name} must be a mapping of config keys to lists, such as "
                f"{{model.phase_lag: [0, 0.1, 0.2]}}, got {show(part)}"
            )
        for key, values in part.items():
            _check_key(f"sweep.{name}", key)
            if not isinstance(values, list) or not values:
                raise ConfigError(
                    f"sweep.{name}.{key} must be a non-empty list of values such as [0, 0.1, 0.2], "
                    f"got {show(values)}"
                )
            twice = _repeated(values)
            if twice is not None:
                raise ConfigError(
                    f"sweep.{name}.{key} lists a value twice ({point_text(twice)}): {show(values)}"
                )
    both = sorted(set(grid) & set(zipped))
    if both:
        raise ConfigError(f"{both[0]} is in both sweep.grid and sweep.zip: give it in one of them")
    keys = list(grid) + list(zipped)
    for a, b in itertools.combinations(keys, 2):
        if b.startswith(a + ".") or a.startswith(b + "."):
            raise ConfigError(f"sweep keys {a} and {b} overlap: {b} sets part of {a}")
    if sum(k in THRESHOLD_KEYS for k in keys) > 1:
        raise ConfigError("dynamics.threshold and sync.threshold are one key: sweep one of them")
    axes = [Axis((key,), tuple((v,) for v in values)) for key, values in grid.items()]
    if zipped:
        lengths = {key: len(values) for key, values in zipped.items()}
        if len(set(lengths.values())) > 1:
            detail = ", ".join(f"{k}: {n}" for k, n in lengths.items())
            raise ConfigError(f"the lists of sweep.zip must have equal lengths, got {detail}")
        axes.append(Axis(tuple(zipped), tuple(zip(*zipped.values(), strict=True)), zipped=True))
    return tuple(axes)


def check_grid_size(axes: tuple[Axis, ...], per_point: int = 1, graphs: int = 1) -> None:
    """Refuse a grid of more than :data:`MAX_GRID_JOBS` jobs from its axes' lengths alone.

    ``per_point`` is the jobs of one point on one graph (thresholds x repeats), ``graphs`` the
    family's graphs. Called before :func:`grid_points`, whose work (a validated config per
    point) and the stages' (a job per point) grow with the count: a 900,000-point grid is
    refused at once instead of being planned for many minutes.

    Raises
    ------
    ConfigError
        Naming the number of points (and jobs, where they differ) and the limit.
    """
    if not axes:
        return
    points = math.prod(len(a) for a in axes)
    jobs = points * per_point * graphs
    if jobs <= MAX_GRID_JOBS:
        return
    count = f"{points:,} grid points ({' x '.join(f'{len(a):,}' for a in axes)})"
    if graphs > 1:
        count += f" x {graphs:,} graphs"
    if per_point > 1:
        count += f" x {per_point:,} (thresholds x repeats)"
    if jobs != points:
        count += f" = {jobs:,} jobs"
    raise ConfigError(
        f"the sweep's grid has {count}; a grid sweep runs at most {MAX_GRID_JOBS:,} jobs "
        "(docs/sweeps.md): use fewer values, or split it into several sweeps"
    )


def grid_points(axes: tuple[Axis, ...], rest: dict, source: Path | None) -> tuple[GridPoint, ...]:
    """Every point of the product of ``axes``, each validated as a run config.

    ``rest`` is the sweep's run mapping (with a ``graph``); each point sets its values at their
    dotted keys in a copy of it. Without axes: no point.
    """
    if not axes:
        return ()
    out = []
    for index in itertools.product(*(range(len(a)) for a in axes)):
        values = tuple(
            (key, value)
            for a, i in zip(axes, index, strict=True)
            for key, value in zip(a.keys, a.values[i], strict=True)
        )
        raw = copy.deepcopy(rest)
        apply_values(raw, {key: copy.deepcopy(value) for key, value in values})
        try:
            cfg = config_from_mapping(raw, source)
        except ConfigError as exc:
            raise ConfigError(f"sweep point {point_label(values)}: {exc}") from None
        out.append(GridPoint(values, index, cfg))
    return tuple(out)


def point_label(values) -> str:
    """``model.phase_lag=0.1, dynamics.threshold=0.9``: a point as the user wrote it.

    Injective: points with different values get different labels (:func:`point_text`); the
    summary groups records by this label.
    """
    items = values.items() if isinstance(values, dict) else values
    return ", ".join(f"{k}={point_text(v)}" for k, v in items)


def point_suffix(point: GridPoint, axes: tuple[Axis, ...]) -> str:
    """The part of a job's name that says its point: ``_phase_lag0.1_r0.9``.

    Each key by its last part (``r`` for a threshold), or its whole dotted path (dots as
    underscores) where two keys end alike; a value that is not a number or a short name by
    its position on its axis (``_frequencies#2``). Injective on the points of one grid: a
    value's text (:func:`point_text`) holds no ``_``, so the keys' parts cannot run together,
    and different values of a key have different texts or positions.
    """
    keys = [k for a in axes for k in a.keys]
    last = [k.rsplit(".", 1)[-1] for k in keys]
    out = ""
    flat = dict(point.values)
    position = {k: i for a, i in zip(axes, point.index, strict=True) for k in a.keys}
    for key, short in zip(keys, last, strict=True):
        if key in THRESHOLD_KEYS:
            short = "r"
        elif last.count(short) > 1:
            short = key.replace(".", "_")
        value = flat[key]
        text = point_text(value)
        if not re.fullmatch(r"[A-Za-z0-9.+-]{1,24}", text):
            text = f"#{position[key]}"
        out += f"_{short}{text}"
    return out


def number_name(value: float) -> str:
    """A number as a name: ``f"{value:g}"`` where that reads back as ``value`` (``0.1``,
    ``1000``, ``1e+06``, ``0.001``: the names of files written before this rule), else in full
    (an integer's digits, a float's shortest round-trip ``repr``: ``1000001``, ``0.1000001``).

    Different numbers always get different texts, where ``:g`` (six significant digits) wrote
    seeds 1000001 and 1000002 both as ``1e+06``.
    """
    try:
        text = f"{value:g}"
    except OverflowError:  # an integer beyond the float range
        return str(value)
    if float(text) == value:
        return text
    return str(value) if isinstance(value, int) else repr(float(value))


def point_text(value) -> str:
    """A grid value as :func:`point_label` and :func:`point_suffix` write it, one text per value:
    a number by :func:`number_name`, ``true``/``false``/``none``, a plain string as it is
    (quoted, ``"0.1"``, ``"true"``, ``"none"``, where it would read back as another value or
    holds spaces or punctuation), a list or mapping in YAML's flow style, items written alike."""
    if isinstance(value, bool) or value is None:
        return str(value).lower()
    if isinstance(value, int | float):
        return number_name(value)
    if isinstance(value, str):
        if re.fullmatch(r"[A-Za-z0-9.+/-]+", value) and _plain(value):
            return value
        return json.dumps(value)
    if isinstance(value, dict):
        return "{" + ", ".join(f"{point_text(k)}: {point_text(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(point_text(v) for v in value) + "]"
    return json.dumps(str(value))  # YAML's dates and the like: as their text, quoted


def _plain(text: str) -> bool:
    """Whether ``text`` can be shown unquoted: YAML reads it as that string (not ``0.1``,
    ``true``) and it is not the text of another value (``nan``, ``inf``, ``none``)."""
    if text.lower() == "none":
        return False
    try:
        float(text)
        return False
    except ValueError:
        pass
    try:
        return yaml_load(text) == text
    except Exception:
        return False


def _canonical(value):
    """A hashable stand-in for ``value``, equal for values that set the same config: numbers by
    value (``1`` and ``1.0`` are one value, every NaN is one), booleans apart from numbers,
    containers item by item."""
    if isinstance(value, bool) or value is None:
        return ("const", value)
    if isinstance(value, int | float):
        return ("nan",) if isinstance(value, float) and math.isnan(value) else ("num", value)
    if isinstance(value, dict):
        return ("dict", frozenset((_canonical(k), _canonical(v)) for k, v in value.items()))
    if isinstance(value, list | tuple):
        return ("list", tuple(_canonical(v) for v in value))
    if isinstance(value, str):
        return ("str", value)
    return ("other", repr(value))


def _repeated(values: list):
    """The first value of ``values`` listed twice (:func:`_canonical`), or None; one pass."""
    seen = set()
    for v in values:
        c = _canonical(v)
        if c in seen:
            return v
        seen.add(c)
    return None


def _check_key(where: str, key) -> None:
    if not isinstance(key, str) or not key:
        raise ConfigError(
            f"{where}: keys must be dotted config keys such as model.phase_lag, got {show(key)}"
        )
    head = key.split(".", 1)[0]
    if key in _REFUSED or head in _REFUSED:
        name = key if key in _REFUSED else head
        raise ConfigError(
            f"{where}: {key} cannot be swept ({_REFUSED[name]}); valid keys: {', '.join(GRID_KEYS)}"
        )
    if key in GRID_KEYS or any(
        key.startswith(k + ".")
        for k in GRID_KEYS
        if k.split(".")[-1] in ("frequencies", "params", "edge_params")
    ):
        return
    raise ConfigError(
        f"{where}: unknown key {key!r}{suggest(key, GRID_KEYS)}; valid keys: {', '.join(GRID_KEYS)}"
    )
