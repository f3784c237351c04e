"""Grids over config keys: ``sweep: {grid: {...}, zip: {...}}`` and ``--grid`` / ``--zip``.

A sweep's *points* are the runs of one graph that differ in a few config keys::

    sweep:
      grid: {model.phase_lag: [0, 0.2, 0.4], dynamics.threshold: [0.9, 0.99]}  # every pair
      zip: {model.inertia: [0.5, 1, 2], model.damping: [1, 1, 1]}             # side by side

``grid`` is the cartesian product of its lists (the first key varies slowest); ``zip`` pairs its
lists element by element (equal lengths) and counts as one more axis of the product. Each
point's config is the sweep's run keys with the point's values set at their dotted keys and
validated like a run config (:func:`antisync.config.config_from_mapping`), so a value that a
run would refuse is refused here, naming the key and the point.

:func:`sweep_axes` validates the section, :func:`grid_points` expands it, :func:`point_suffix`
names a point's jobs.
"""

from __future__ import annotations

import copy
import itertools
import math
import re
from dataclasses import dataclass
from pathlib import Path

from antisync.config import Config, apply_values, config_from_mapping, yaml_load
from antisync.errors import ConfigError
from antisync.validation import show, suggest

__all__ = [
    "GRID_KEYS",
    "THRESHOLD_KEYS",
    "Axis",
    "GridPoint",
    "axis_option",
    "grid_points",
    "point_label",
    "point_suffix",
    "sweep_axes",
]

# the keys a grid may sweep: the sections that decide the dynamics and the estimate, and the
# run's realizations and seed; the graph, the links, where and how it runs are the sweep's
_SECTION_KEYS = {
    "dynamics": ("coupling", "integrator", "dt", "threshold", "t_max", "crossing", "precision"),
    "model": ("frequencies", "phase_lag", "inertia", "damping"),
    "sync": ("criterion", "threshold", "fraction", "tolerance"),
    "lambda": ("method", "dbeta", "hybrid_cut"),
    "linear": ("realizations", "method"),
}
_TOP_GRID_KEYS = ("realizations", "seed")
#: every key a ``grid:`` or ``zip:`` may name (deeper keys of a mapping value are allowed below
#: them, e.g. ``model.frequencies.sd``)
GRID_KEYS: tuple[str, ...] = _TOP_GRID_KEYS + tuple(f"{s}.{k}" for s, ks in _SECTION_KEYS.items() for k in ks)
#: grid keys that set the synchronization threshold of a point's jobs
THRESHOLD_KEYS = ("dynamics.threshold", "sync.threshold")
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
    ``index`` (its position on each axis) and the validated :class:`~antisync.config.Config`
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
            if any(_same(a, b) for i, a in enumerate(values) for b in values[i + 1 :]):
                raise ConfigError(f"sweep.{name}.{key} lists a value twice: {show(values)}")
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
    """``model.phase_lag=0.1, dynamics.threshold=0.9``: a point as the user wrote it."""
    items = values.items() if isinstance(values, dict) else values
    return ", ".join(f"{k}={_text(v)}" for k, v in items)


def point_suffix(point: GridPoint, axes: tuple[Axis, ...]) -> str:
    """The part of a job's name that says its point: ``_phase_lag0.1_r0.9``.

    Each key by its last part (``r`` for a threshold), or its whole dotted path (dots as
    underscores) where two keys end alike; a value that is not a number or a short name by
    its position on its axis (``_frequencies#2``).
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
        text = _text(value)
        if not re.fullmatch(r"[A-Za-z0-9.+-]{1,24}", text):
            text = f"#{position[key]}"
        out += f"_{short}{text}"
    return out


def _text(value) -> str:
    if isinstance(value, bool) or value is None:
        return str(value).lower()
    if isinstance(value, int | float):
        return f"{value:g}"
    if isinstance(value, str):
        return value
    return show(value)


def _same(a, b) -> bool:
    if isinstance(a, int | float) and isinstance(b, int | float) and not isinstance(a, bool | str):
        return not isinstance(b, bool) and (a == b or (math.isnan(a) and math.isnan(b)))
    return a == b


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
        key.startswith(k + ".") for k in GRID_KEYS if k.split(".")[-1] == "frequencies"
    ):
        return
    raise ConfigError(
        f"{where}: unknown key {key!r}{suggest(key, GRID_KEYS)}; valid keys: {', '.join(GRID_KEYS)}"
    )
