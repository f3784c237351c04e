"""Beyond identical oscillators: the ``model:`` and ``sync:`` config sections (docs/models.md).

``model:`` chooses the dynamics. Its default is the paper's identical first-order Kuramoto
model (Eq. 2), which runs on the unchanged default kernels; anything else runs on the model
kernels of :mod:`antisync.kernels.model_cpu`:

- natural frequencies ``P_i`` (``frequencies``: fixed values, a file, or drawn per
  realization from a counter-based stream of their own, so ``tau0`` and every ``tau(beta)`` of a
  realization share them as they share the initial phases);
- a phase lag ``alpha`` (Kuramoto-Sakaguchi): coupling ``sin(theta_j - theta_i - alpha)``;
- inertia ``m`` and damping ``gamma`` (second-order, swing-equation model)
  ``m theta_i'' + gamma theta_i' = P_i + sum_j w_ij sin(theta_j - theta_i - alpha)``,
  started from the usual random phases with ``theta_i'(0) = 0``.

The mean of the natural frequencies is removed before integrating (``P_i - mean_j P_j``): for
both models that is a frame rotating at a constant rate, which changes neither ``r(t)`` nor
the frequency criterion (it measures deviations from the mean frequency); in the second-order
model it means the initial frequencies are zero in that frame.

``sync:`` chooses when a trajectory counts as synchronized: ``order-parameter`` (``r >=
threshold``, the paper's), ``relative`` (``r >= fraction r*`` with ``r*`` the order parameter
of the stable phase-locked state of the weights in use, :mod:`antisync.locked`) or ``frequency``
(every ``|theta_i' - mean_j theta_j'| < tolerance``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, get_args

import numpy as np
from numba import njit

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.errors import ConfigError
from antisync.phases import make_uniform
from antisync.validation import choice, fraction, positive

__all__ = [
    "CRITERIA",
    "DISTRIBUTIONS",
    "Model",
    "Sync",
    "draw_frequencies",
    "node_frequencies",
]

Criterion = Literal["order-parameter", "relative", "frequency"]
CRITERIA: tuple[Criterion, ...] = get_args(Criterion)
Distribution = Literal["normal", "uniform"]
DISTRIBUTIONS: tuple[Distribution, ...] = get_args(Distribution)

#: Counter streams of :func:`antisync.phases.make_uniform` used by the frequencies (the initial
#: phases are the separate hash :func:`antisync.phases.phase`).
STREAM_FREQ_A = 1
STREAM_FREQ_B = 2

_FREQ_KEYS = {"normal": {"distribution", "sd", "mean"}, "uniform": {"distribution", "width", "mean"}}


def _check_frequencies(value):
    """``None``, a tuple of floats, ``{"file": path}`` or ``{"distribution": ..., ...}``."""
    if value is None:
        return None
    if isinstance(value, list | tuple):
        out = []
        for x in value:
            if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
                raise ConfigError(f"model.frequencies must be finite numbers, got {x!r}")
            out.append(float(x))
        if not out:
            raise ConfigError("model.frequencies is an empty list; give one value per node or null")
        return tuple(out)
    if isinstance(value, dict):
        if set(value) == {"file"}:
            if not isinstance(value["file"], str) or not value["file"]:
                raise ConfigError(f"model.frequencies.file must be a path, got {value['file']!r}")
            return {"file": value["file"]}
        dist = value.get("distribution")
        if "file" in value or dist is None:
            raise ConfigError(
                "model.frequencies must be a list, {file: PATH} or {distribution: normal, sd: S} "
                f"/ {{distribution: uniform, width: W}}, got {value!r}"
            )
        choice("model.frequencies.distribution", dist, DISTRIBUTIONS)
        extra = sorted(set(value) - _FREQ_KEYS[dist])
        if extra:
            raise ConfigError(
                f"unknown key 'model.frequencies.{extra[0]}' for distribution {dist}; valid keys: "
                + ", ".join(sorted(_FREQ_KEYS[dist]))
            )
        scale_key = "sd" if dist == "normal" else "width"
        if scale_key not in value:
            raise ConfigError(f"model.frequencies with distribution {dist} needs {scale_key}")
        out = {"distribution": dist}
        for k in ("mean", scale_key):
            x = value.get(k, 0.0)
            if isinstance(x, str):
                try:
                    x = float(x)
                except ValueError:
                    raise ConfigError(f"model.frequencies.{k} must be a number, got {x!r}") from None
            if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
                raise ConfigError(f"model.frequencies.{k} must be a number, got {x!r}")
            out[k] = float(x)
        if out[scale_key] < 0:
            raise ConfigError(f"model.frequencies.{scale_key} must be >= 0, got {out[scale_key]}")
        return out
    raise ConfigError(
        "model.frequencies must be null, a list of numbers, {file: PATH} or "
        f"{{distribution: normal, sd: S}}, got {value!r}"
    )


@dataclass(frozen=True)
class Model:
    """The oscillators' dynamics (docs/models.md); the defaults are the paper's Eq. 2.

    Attributes
    ----------
    frequencies : None, tuple of float, dict
        Natural frequencies (power injections ``P_i`` of the second-order model): ``None`` (all
        zero), one value per node in node order, ``{"file": path}`` (one value per line, path
        relative to the config) or ``{"distribution": "normal", "sd": s, "mean": 0}`` /
        ``{"distribution": "uniform", "width": w, "mean": 0}`` (uniform on ``mean +- w``),
        drawn per realization. The mean over nodes is removed (module docstring).
    phase_lag : float
        ``alpha`` in ``(-pi/2, pi/2)``: coupling ``sin(theta_j - theta_i - alpha)``.
    inertia : float
        ``m >= 0``; ``0`` is the first-order model.
    damping : float
        ``gamma > 0`` of the second-order model (unused when ``inertia`` is 0).
    """

    frequencies: None | tuple | dict = None
    phase_lag: float = 0.0
    inertia: float = 0.0
    damping: float = 1.0

    def __post_init__(self):
        object.__setattr__(self, "frequencies", _check_frequencies(self.frequencies))
        lag = self.phase_lag
        if isinstance(lag, bool) or not isinstance(lag, int | float) or not -math.pi / 2 < lag < math.pi / 2:
            raise ConfigError(
                f"model.phase_lag must be a number in (-pi/2, pi/2) = (-1.5708, 1.5708), got {lag!r}"
            )
        m = self.inertia
        if isinstance(m, bool) or not isinstance(m, int | float) or not (m >= 0 and math.isfinite(m)):
            raise ConfigError(f"model.inertia must be a number >= 0 (0: first order), got {m!r}")
        positive("model.damping", self.damping)

    @property
    def is_default(self) -> bool:
        """The paper's identical first-order model (runs on the default kernels)."""
        return self.frequencies is None and self.phase_lag == 0 and self.inertia == 0

    @property
    def drawn(self) -> bool:
        """Frequencies drawn per realization."""
        return isinstance(self.frequencies, dict) and "distribution" in self.frequencies

    @property
    def second_order(self) -> bool:
        return self.inertia > 0


@dataclass(frozen=True)
class Sync:
    """When a trajectory counts as synchronized (docs/models.md).

    Attributes
    ----------
    criterion : {"order-parameter", "relative", "frequency"}
    threshold : float or None
        ``order-parameter``: ``r >= threshold``; ``None`` uses ``dynamics.threshold`` (a
        value given here is moved there when the config is read).
    fraction : float
        ``relative``: ``r >= fraction r*``, ``r*`` of the stable locked state of each variant.
    tolerance : float
        ``frequency``: every ``|theta_i' - mean_j theta_j'| < tolerance``.
    """

    criterion: Criterion = "order-parameter"
    threshold: float | None = None
    fraction: float = 0.99
    tolerance: float = 1e-3

    def __post_init__(self):
        choice("sync.criterion", self.criterion, CRITERIA)
        if self.threshold is not None:
            fraction("sync.threshold", self.threshold)
        fraction("sync.fraction", self.fraction)
        positive("sync.tolerance", self.tolerance)

    @property
    def is_default(self) -> bool:
        return self.criterion == "order-parameter" and self.threshold is None


_uniform = make_uniform(lambda f: njit(f, inline="always"))


@njit(cache=True)
def _fill_frequencies(seed, ks, n, normal, mean, scale, out):
    for r in range(ks.shape[0]):
        for i in range(n):
            u1 = _uniform(seed, ks[r], i, STREAM_FREQ_A)
            if normal:
                # Box-Muller: 1 - u1 in (0, 1], so the logarithm is finite
                u2 = _uniform(seed, ks[r], i, STREAM_FREQ_B)
                z = math.sqrt(-2.0 * math.log(1.0 - u1)) * math.cos(2.0 * math.pi * u2)
                out[r, i] = mean + scale * z
            else:
                out[r, i] = mean + scale * (2.0 * u1 - 1.0)


def draw_frequencies(spec: dict, seed: int, ks: np.ndarray, n: int) -> np.ndarray:
    """Natural frequencies of realizations ``ks`` (shape ``(len(ks), n)``), mean not removed.

    ``normal``: ``mean + sd z`` with ``z`` from Box-Muller on two counter streams;
    ``uniform``: ``mean + width (2 u - 1)``. Keyed by ``(seed, k, node)`` like the phases, so
    chunks, threads and backends cannot change them.
    """
    ks = np.ascontiguousarray(ks, dtype=np.uint64)
    out = np.empty((ks.size, n))
    normal = spec["distribution"] == "normal"
    scale = spec["sd"] if normal else spec["width"]
    _fill_frequencies(np.uint64(seed), ks, n, normal, float(spec.get("mean", 0.0)), float(scale), out)
    return out


def node_frequencies(model: Model, n: int) -> np.ndarray | None:
    """Fixed natural frequencies in node order (``None`` when drawn or absent); the file of
    ``{"file": path}`` has one number per line (``#`` comments allowed).

    Raises
    ------
    ConfigError
        A file that cannot be read, is not numbers, or does not have ``n`` values.
    """
    spec = model.frequencies
    if spec is None or model.drawn:
        return None
    if isinstance(spec, dict):
        path = Path(spec["file"])
        try:
            values = np.loadtxt(path, comments="#", ndmin=1, dtype=np.float64)
        except OSError as exc:
            raise ConfigError(f"model.frequencies.file {path}: {exc.strerror or exc}") from None
        except ValueError:
            raise ConfigError(
                f"model.frequencies.file {path}: not a column of numbers (one value per node)"
            ) from None
        source = f"model.frequencies.file {path}"
    else:
        values = np.array(spec, dtype=np.float64)
        source = "model.frequencies"
    if values.ndim != 1 or values.size != n:
        raise ConfigError(f"{source} has {values.size} values; the graph has {n} nodes (one value per node)")
    if not np.isfinite(values).all():
        raise ConfigError(f"{source} contains a value that is not finite")
    return values
