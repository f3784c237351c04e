"""Beyond identical oscillators: the ``model:`` and ``sync:`` config sections (docs/models.md).

``model:`` chooses the dynamics. Its default is the paper's identical first-order Kuramoto
model (Eq. 2), which runs on the unchanged default kernels; anything else runs on the model
kernels of :mod:`antisync.kernels.model_steps` (run by the lane driver of :mod:`antisync.kernels.cpu`):

- natural frequencies ``P_i`` (``frequencies``: fixed values, a file, or drawn per
  realization from a counter-based stream of their own, so ``tau0`` and every ``tau(beta)`` of a
  realization share them as they share the initial phases);
- a phase lag ``alpha`` (Kuramoto-Sakaguchi): coupling ``sin(theta_j - theta_i - alpha)``;
- inertia ``m`` and damping ``gamma`` (second-order, swing-equation model)
  ``m theta_i'' + gamma theta_i' = P_i + sum_j w_ij sin(theta_j - theta_i - alpha)``,
  started from the usual random phases with ``theta_i'(0) = 0``;
- where the trajectories start (``start``): by default the paper's phases, uniform on the
  circle; ``{around: locked, width: w}`` draws them near the undamaged network's stable
  phase-locked state ``phi`` (the operating point of a power grid),
  ``theta_i(0) = phi_i + w (2 u_i - 1)`` with the same counter-based ``u_i`` in ``[0, 1)``
  (:func:`antisync.physics.phases.phase` ``/ 2 pi``): random perturbations of bounded size
  around the operating point, as basin-stability studies draw them (Menck, Heitzig, Marwan and
  Kurths, Nat. Phys. 9, 89 (2013)). ``tau0`` and every ``tau(beta)`` of a realization share
  the start, so a damaged or removed line is judged from the same perturbed operating point
  of the intact network.

The mean of the natural frequencies is removed before integrating (``P_i - mean_j P_j``): for
both models that is a frame rotating at a constant rate, which changes neither ``r(t)`` nor
the frequency criterion (it measures deviations from the mean frequency); in the second-order
model it means the initial frequencies are zero in that frame.

``sync:`` chooses when a trajectory counts as synchronized: ``order-parameter`` (``r >=
threshold``, the paper's), ``relative`` (``r >= fraction r*`` with ``r*`` the order parameter
of the stable phase-locked state of the weights in use, :mod:`antisync.physics.locked`) or ``frequency``
(every ``|theta_i' - mean_j theta_j'| < tolerance``).
"""

from __future__ import annotations

import dataclasses
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, get_args

import numpy as np

from antisync.errors import ConfigError
from antisync.physics.locked import linearization, locked_state
from antisync.validation import choice, fraction, number_text, parse_number, positive, read_input_text, show

__all__ = [
    "CRITERIA",
    "DISTRIBUTIONS",
    "DTARGET_STEP",
    "LawSetup",
    "Model",
    "ModelSetup",
    "Sync",
    "check_second_order_step",
    "drawn_frequencies",
    "law_edges",
    "law_r_star",
    "law_setup",
    "law_targets",
    "law_values",
    "model_setup",
    "node_frequencies",
    "node_parameters",
    "start_phases",
    "with_law_dtarget",
    "with_law_r_star",
    "unsynced_hint",
]

Criterion = Literal["order-parameter", "relative", "frequency"]
CRITERIA: tuple[Criterion, ...] = get_args(Criterion)
Distribution = Literal["normal", "uniform"]
DISTRIBUTIONS: tuple[Distribution, ...] = get_args(Distribution)

_FREQ_KEYS = {"normal": {"distribution", "sd", "mean"}, "uniform": {"distribution", "width", "mean"}}


#: Largest ``|value|`` of a natural frequency, and of a distribution's ``mean``, ``sd`` or
#: ``width``: far beyond any frequency a step resolves (``dt |P_i|`` is the rotation per step),
#: and small enough that every draw (at most ~8.6 sd from the mean), sum and mean of the
#: frequencies of a graph stays finite in float64 (``sd: 1e308`` overflowed to inf and NaN).
MAX_FREQUENCY = 1e100
#: ``antisync.plan.config.MAX_STEPS`` (not imported: config imports this module).
MAX_STEPS_HINT = 2**40


def _frequency(key: str, value, lo: float = -MAX_FREQUENCY) -> float:
    """One natural frequency (or ``mean``, or with ``lo = 0`` a ``sd``/``width``): a finite
    number in ``[lo, MAX_FREQUENCY]``."""
    valid = f"a number in [{lo:g}, {MAX_FREQUENCY:g}]"
    x = parse_number(key, value, valid)
    if not lo <= x <= MAX_FREQUENCY:
        raise ConfigError(f"{key} must be {valid}, got {show(value)}")
    return x


def _check_frequencies(value):
    """``None``, a tuple of floats, ``{"file": path}`` or ``{"distribution": ..., ...}``."""
    if value is None:
        return None
    if isinstance(value, list | tuple):
        out = tuple(_frequency("model.frequencies", x) for x in value)
        if not out:
            raise ConfigError("model.frequencies is an empty list; give one value per node or null")
        return out
    if isinstance(value, dict):
        if set(value) == {"file"}:
            if not isinstance(value["file"], str) or not value["file"]:
                raise ConfigError(f"model.frequencies.file must be a path, got {show(value['file'])}")
            return {"file": value["file"]}
        dist = value.get("distribution")
        if "file" in value or dist is None:
            raise ConfigError(
                "model.frequencies must be a list, {file: PATH} or {distribution: normal, sd: S} "
                f"/ {{distribution: uniform, width: W}}, got {show(value)}"
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
        out = {"distribution": dist, "mean": _frequency("model.frequencies.mean", value.get("mean", 0.0))}
        out[scale_key] = _frequency(f"model.frequencies.{scale_key}", value[scale_key], lo=0.0)
        return out
    raise ConfigError(
        "model.frequencies must be null, a list of numbers, {file: PATH} or "
        f"{{distribution: normal, sd: S}}, got {show(value)}"
    )


#: The places a start can be drawn around (``model.start.around``): the undamaged network's stable
#: phase-locked state (:func:`antisync.physics.locked.locked_state`).
START_AROUND = ("locked",)


def _check_start(value):
    """``None`` (the paper's uniform phases) or ``{"around": "locked", "width": w}`` with ``w``
    in ``(0, pi]`` (radians)."""
    if value is None:
        return None
    valid = "{around: locked, width: W} with W in (0, pi] radians (null: uniform phases)"
    if not isinstance(value, dict):
        raise ConfigError(f"model.start must be {valid}, got {show(value)}")
    extra = sorted(set(value) - {"around", "width"})
    if extra:
        raise ConfigError(f"unknown key 'model.start.{extra[0]}'; valid keys: around, width")
    if "width" not in value:
        raise ConfigError(f"model.start needs width: {valid}")
    choice("model.start.around", value.get("around", "locked"), START_AROUND)
    in_range = "a number in (0, pi] = (0, 3.14159]"
    width = parse_number("model.start.width", value["width"], in_range)
    if not 0 < width <= math.pi:
        raise ConfigError(f"model.start.width must be {in_range}, got {show(value['width'])}")
    return {"around": value.get("around", "locked"), "width": width}


#: Largest per-node inertia or damping: ``m / gamma`` and ``gamma / m`` stay finite, and a
#: stability check on ``dt gamma / m`` cannot overflow to a pass.
MAX_NODE_PARAMETER = 1e100


def _node_parameter(key: str, value, positive_only: bool):
    """``model.inertia`` / ``model.damping``: a number, one number per node (a list), or
    ``{file: PATH}`` (one number per line, read when the graph is known)."""
    top = f"at most {MAX_NODE_PARAMETER:g}"
    valid = f"a positive number {top}" if positive_only else f"a number >= 0 (0: first order) {top}"
    hint = f"{valid}, one such number per node (a list) or {{file: PATH}}"

    def one(where, x):
        v = parse_number(where, x, valid)
        if not (0 < v if positive_only else 0 <= v) or not v <= MAX_NODE_PARAMETER:
            raise ConfigError(f"{where} must be {valid}, got {show(x)}")
        return v

    if isinstance(value, list | tuple):
        if not value:
            raise ConfigError(f"{key} is an empty list; give {hint}")
        return tuple(one(f"{key}[{i}]", x) for i, x in enumerate(value))
    if isinstance(value, dict):
        if set(value) != {"file"} or not isinstance(value["file"], str) or not value["file"]:
            raise ConfigError(f"{key} must be {hint}, got {show(value)}")
        return {"file": value["file"]}
    return one(key, value)


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
    inertia : float, tuple of float, dict
        ``m >= 0``, one value for every node or per node (a list in node order, or ``{"file":
        path}``); ``0`` everywhere is the first-order model. Per node, ``m_i = 0`` makes node
        ``i`` first order, ``gamma_i theta_i' = P_i + ...`` (load buses beside generators).
    damping : float, tuple of float, dict
        ``gamma > 0``, one value or per node like ``inertia`` (unused when every ``m_i`` is 0).
    start : None or dict
        ``None``: the paper's phases, uniform on the circle; ``{"around": "locked", "width":
        w}``: ``theta_i(0) = phi_i + w (2 u_i - 1)`` around the undamaged network's stable
        phase-locked state ``phi`` (module docstring), ``w`` in ``(0, pi]``; needs fixed
        frequencies (drawn ones move the locked state with every realization).
    """

    frequencies: None | tuple | dict = None
    phase_lag: float = 0.0
    inertia: float | tuple | dict = 0.0
    damping: float | tuple | dict = 1.0
    start: None | dict = None
    law: None | str | dict = None
    """A user's model (docs/models.md, "Write your own model"): a shipped law's name, a law file
    or a mapping (:func:`antisync.laws.read_law`); stored as the law's mapping, so a result file
    holds the equations it ran. With a law the keys above keep their defaults."""
    params: None | dict = None
    """The law's per-node parameters: ``{name: number, list (one per node) or {file: PATH}}``;
    a parameter not given keeps the law's default."""
    edge_params: None | dict = None
    """The law's per-link parameters: ``{name: number or {file: PATH, column: NAME}}`` (an edge
    list of ``u v value`` lines, or a named column of one: :func:`law_edges`); a parameter not
    given keeps the law's default on every link."""

    def __post_init__(self):
        if self.law is not None or self.params is not None or self.edge_params is not None:
            self._check_law()
            return
        object.__setattr__(self, "frequencies", _check_frequencies(self.frequencies))
        object.__setattr__(self, "start", _check_start(self.start))
        if self.start is not None and self.drawn:
            raise ConfigError(
                "model.start around the locked state needs fixed model.frequencies (values or a "
                "file): frequencies drawn per realization move the locked state with every "
                "realization; fix them, or drop model.start"
            )
        lag_range = "a number in (-pi/2, pi/2) = (-1.5708, 1.5708)"
        lag = parse_number("model.phase_lag", self.phase_lag, lag_range)
        if not -math.pi / 2 < lag < math.pi / 2:
            raise ConfigError(f"model.phase_lag must be {lag_range}, got {show(self.phase_lag)}")
        object.__setattr__(self, "phase_lag", lag)
        inertia = _node_parameter("model.inertia", self.inertia, positive_only=False)
        damping = _node_parameter("model.damping", self.damping, positive_only=True)
        if isinstance(inertia, tuple) and not any(inertia):
            raise ConfigError(
                "model.inertia lists 0 for every node: that is the first-order model, whose damping "
                "is unused; write model.inertia: 0, or give some node a positive inertia"
            )
        if inertia == 0 and not isinstance(damping, float):
            raise ConfigError(
                "model.damping per node needs model.inertia > 0 on some node (with inertia 0 "
                "everywhere the first-order model has no damping)"
            )
        if inertia == 0 and damping != 1.0:
            # theta' = omega + sum w sin(...) has no gamma: a damping would be ignored by every
            # kernel (a run's, a removal's), silently; a grid's time scale is its K and P
            raise ConfigError(
                f"model.damping {damping:g} needs model.inertia > 0 on some node (with inertia 0 "
                "everywhere the first-order model has no damping, and it would be ignored): remove "
                "damping, or scale the couplings and frequencies by 1 / damping"
            )
        object.__setattr__(self, "inertia", inertia)
        object.__setattr__(self, "damping", damping)

    def _check_law(self) -> None:
        """A law and its parameters, checked; the built-in model's keys must keep their defaults."""
        from antisync.laws import read_law

        if self.law is None:
            key = "params" if self.params is not None else "edge_params"
            raise ConfigError(
                f"model.{key} gives a law's parameters: it needs model.law (e.g. law: stuart-landau)"
            )
        for key, default in (
            ("frequencies", None),
            ("phase_lag", 0.0),
            ("inertia", 0.0),
            ("damping", 1.0),
        ):
            if getattr(self, key) != default:
                raise ConfigError(
                    f"model.{key} belongs to the built-in model; with model.law give the law's parameters "
                    "in model.params (and write the dynamics in the law)"
                )
        object.__setattr__(self, "start", _check_start(self.start))
        law = read_law(self.law)
        object.__setattr__(self, "law", law.as_dict())
        for key, known, what, read in (
            ("params", law.param_names, "parameters", _law_parameter),
            ("edge_params", law.edge_param_names, "edge parameters", _law_edge_parameter),
        ):
            given = getattr(self, key) or {}
            if not isinstance(given, dict):
                raise ConfigError(f"model.{key} must be a mapping of the law's {what}, got {show(given)}")
            out = {}
            for name, value in given.items():
                if name not in known:
                    have = ", ".join(known) or "none"
                    raise ConfigError(
                        f"unknown key 'model.{key}.{name}'; law {law.name} has the {what}: {have}"
                    )
                out[name] = read(f"model.{key}.{name}", value)
            object.__setattr__(self, key, out or None)
        drawn = law_drawn(self)
        if self.start is not None and drawn:
            raise ConfigError(
                f"model.start around the locked state needs fixed law parameters: model.params."
                f"{law.params[drawn[0][0]][0]} is drawn per realization, which moves the locked state "
                "with every realization; fix it (a number, a list or a file), or drop model.start"
            )

    @property
    def user_law(self):
        """The :class:`~antisync.laws.spec.Law` of ``model.law``, or None (the built-in model)."""
        if self.law is None:
            return None
        from antisync.laws import read_law

        return read_law(self.law)

    @property
    def is_default(self) -> bool:
        """The paper's identical first-order model from uniform phases (runs on the default
        kernels)."""
        if self.law is not None:
            return False
        return self.frequencies is None and self.phase_lag == 0 and self.inertia == 0 and self.start is None

    @property
    def drawn(self) -> bool:
        """Frequencies drawn per realization."""
        return isinstance(self.frequencies, dict) and "distribution" in self.frequencies

    @property
    def second_order(self) -> bool:
        """Some node has inertia (a file of inertias counts: it is checked when read)."""
        m = self.inertia
        return isinstance(m, dict) or (any(m) if isinstance(m, tuple) else m > 0)

    @property
    def symmetric(self) -> bool:
        """Every automorphism of the graph is one of the model: no fixed per-node values
        (frequencies drawn i.i.d. per realization are exchangeable, so averages keep the
        symmetry)."""
        fixed = self.frequencies is not None and not self.drawn
        return not fixed and not self.per_node and not self.per_link

    @property
    def per_link(self) -> bool:
        """A law's edge parameter given per link (a file): an automorphism of the graph need not
        map a link to one of the same value."""
        return any(isinstance(v, dict) for v in (self.edge_params or {}).values())

    @property
    def per_node(self) -> bool:
        """Inertia or damping given per node (or, for a law, a parameter given per node; one
        drawn i.i.d. per realization and node is exchangeable, as drawn frequencies are)."""
        if self.law is not None:
            return any(
                not isinstance(v, float) and not (isinstance(v, dict) and "distribution" in v)
                for v in (self.params or {}).values()
            )
        return not (isinstance(self.inertia, float) and isinstance(self.damping, float))


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
    give_up : dict or None
        ``frequency`` with ``dynamics.integrator: rodas4``, ``antisync grid --removal`` only:
        ``{after: T, band: B}`` stops a trajectory at time ``T`` when the largest of the
        deviations the criterion tests has not once been below ``B`` (rad/s) by then (a machine
        still slipping, a solitary state) and records it as ``GAVE_UP``, counted as not
        synchronized and apart.
        A rule measured on the grid it is set for, not a proof (docs/power_grids.md); None: every
        trajectory runs to its criterion or ``t_max``.
    """

    criterion: Criterion = "order-parameter"
    threshold: float | None = None
    fraction: float = 0.99
    tolerance: float = 1e-3
    give_up: dict | None = None

    def __post_init__(self):
        choice("sync.criterion", self.criterion, CRITERIA)
        if self.threshold is not None:
            object.__setattr__(self, "threshold", fraction("sync.threshold", self.threshold))
        object.__setattr__(self, "fraction", fraction("sync.fraction", self.fraction))
        object.__setattr__(self, "tolerance", positive("sync.tolerance", self.tolerance))
        if self.give_up is not None:
            object.__setattr__(self, "give_up", self._give_up())

    def _give_up(self) -> dict:
        """``give_up`` checked: ``{after, band}``, both positive, the band wider than the
        tolerance, under the frequency criterion."""
        want = "a mapping {after: seconds, band: rad/s}, e.g. {after: 20, band: 1.0}"
        g = self.give_up
        if not isinstance(g, dict) or set(g) != {"after", "band"}:
            raise ConfigError(f"sync.give_up must be {want}, got {show(g)}")
        if self.criterion != "frequency":
            raise ConfigError(
                f"sync.give_up watches frequency deviations: it needs sync.criterion frequency, not "
                f"{self.criterion} (remove give_up)"
            )
        after = positive("sync.give_up.after", g["after"])
        band = positive("sync.give_up.band", g["band"])
        if band <= self.tolerance:
            raise ConfigError(
                f"sync.give_up.band ({band:g}) must be wider than sync.tolerance ({self.tolerance:g}): "
                "a trajectory inside the tolerance is synchronized, not slipping"
            )
        return {"after": after, "band": band}

    @property
    def give_up_rule(self) -> tuple[float, float] | None:
        """``(after, band)`` of :attr:`give_up`, or None."""
        return None if self.give_up is None else (self.give_up["after"], self.give_up["band"])

    @property
    def is_default(self) -> bool:
        return self.criterion == "order-parameter" and self.threshold is None


def node_frequencies(model: Model, n: int) -> np.ndarray | None:
    """Fixed natural frequencies in node order (``None`` when drawn or absent); the file of
    ``{"file": path}`` has one number per line (``#`` comments allowed), read by
    :func:`read_frequency_file`.

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
        values = read_frequency_file(path)
        source = f"model.frequencies.file {path}"
        if values.size != n:
            raise ConfigError(
                f"{source} has {values.size} values; the graph has {n} nodes: give one number per "
                "line, one line per node in node order"
            )
    else:
        values = np.array(spec, dtype=np.float64)
        if values.size != n:
            raise ConfigError(
                f"model.frequencies has {values.size} values; the graph has {n} nodes (one value per node)"
            )
    return values


def read_frequency_file(path: str | Path, what: str = "model.frequencies.file") -> np.ndarray:
    """The numbers of a per-node file: one number per line (a single column), ``#`` starts a
    comment, blank lines are skipped. Read by :func:`antisync.validation.read_input_text`
    (regular files only, UTF-8). Every number is written in the grammar of
    :data:`antisync.validation.DECIMAL`: ``1,5``, ``0x10``, ``1_000`` or a unicode minus are
    refused, never read as another value, and so is a line with two numbers (a second column
    would otherwise change which value belongs to which node).

    Raises
    ------
    ConfigError
        Naming the file, the line and what was expected there.
    """
    path = Path(path)
    text = read_input_text(path, what)
    values = []
    for lineno, line in enumerate(text.splitlines(), 1):
        tokens = line.split("#", 1)[0].split()
        if not tokens:
            continue
        if len(tokens) != 1:
            raise ConfigError(
                f"{what} {path}:{lineno}: expected one number per line (one line per node), got "
                f"{len(tokens)} values: {show(line.strip())}"
            )
        x = number_text(tokens[0])
        if x is None:
            raise ConfigError(
                f"{what} {path}:{lineno}: {show(tokens[0])} is not a number; give one number per line "
                "(such as -0.25 or 1.5e-3)"
            )
        if not abs(x) <= MAX_FREQUENCY:
            raise ConfigError(
                f"{what} {path}:{lineno}: {show(tokens[0])} is not a finite number in "
                f"[-{MAX_FREQUENCY:g}, {MAX_FREQUENCY:g}]"
            )
        values.append(x)
    return np.array(values, dtype=np.float64)


@dataclass(frozen=True)
class LawSetup:
    """A user's law resolved for a graph: the :class:`~antisync.laws.spec.Law`, its parameters per
    node ``values`` ``(n_params, n)``, the criterion (``CRIT_ORDER`` or ``CRIT_FREQUENCY`` of
    :mod:`antisync.kernels.core`) and its target: ``R = (r N)^2`` at the threshold, or the
    frequency tolerance, the same for every network of the job; with the relative criterion
    (``fraction``) ``R = (fraction r* N)^2`` of the undamaged network, each other network's from
    its own ``r*`` (:func:`law_targets`)."""

    law: object
    values: np.ndarray
    target: float
    criterion: int = 0
    drawn: tuple = ()
    """``(k, distribution)`` per parameter drawn per realization (:func:`law_drawn`)."""
    edges: np.ndarray | None = None
    """``(n_edge_params, nnz)``: the law's edge parameters per in-link in the coupling's CSR order
    (:func:`law_edges`); None without edge parameters."""
    fraction: float | None = None
    """``sync.fraction`` with the relative criterion, else None."""
    lock_t_max: float = 0.0
    """How long the law may take to lock from its in-phase state (:func:`law_r_star`)."""
    r_star: np.ndarray | None = None
    """``(1 + V,)`` with the relative criterion: ``r*`` of the undamaged network and of each
    variant (:func:`with_law_r_star`), what the records store."""
    start_width: float | None = None
    """``model.start.width``: starts drawn around the undamaged network's locked state, else
    None (the paper's uniform phases)."""
    start: np.ndarray | None = None
    """``(2, n)`` with ``model.start``: the undamaged network's locked phase per node and the
    width (:func:`with_law_start`; :attr:`antisync.kernels.law.LawParams.start`)."""
    dtarget: np.ndarray | None = None
    """``(E,)`` for the adjoint with the relative criterion: ``d target / d beta_e`` at 0, the
    target ``(fraction r* N)^2`` moving with each link's damage (:func:`with_law_dtarget`)."""

    def relative_target(self, r_star):
        """The relative criterion's ``R = (fraction r* N)^2`` of networks with ``r_star``."""
        return (self.fraction * np.asarray(r_star) * self.values.shape[1]) ** 2


#: How long a law may take to lock from its in-phase state, in units of ``dynamics.t_max`` (and
#: at least :data:`LOCK_T_MIN`): the relative criterion's ``r*`` (:mod:`antisync.kernels.law_locked`).
LOCK_T_FACTOR = 10.0
LOCK_T_MIN = 1000.0
#: The law's locked states already found in this process, by the law, its values and the
#: network's weights: a chunk's secant rows are the same networks in every chunk.
_LOCKED: dict = {}


def _law_locked(setup: LawSetup, indptr, indices, weights, state: bool = False):
    """The law's locked state on the network ``weights`` (a
    :class:`~antisync.kernels.law_locked.LawLocked`), or None where it does not lock from its
    in-phase state within ``lock_t_max``; each network found once per process. The cache keeps
    ``r*`` and, only where ``state`` asked for it, the state itself (``y`` is None otherwise: a
    10,000-bus grid's thousands of secant networks would hold gigabytes)."""
    from antisync.kernels.law_locked import locked_state

    ip = np.ascontiguousarray(indptr, dtype=np.int64)
    ix = np.ascontiguousarray(indices, dtype=np.int64)
    w = np.ascontiguousarray(weights, dtype=np.float64)
    edges = None if setup.edges is None else setup.edges.tobytes()
    key = (setup.law.text, setup.values.tobytes(), edges, ip.tobytes(), ix.tobytes(), setup.lock_t_max)
    key += (w.tobytes(),)
    have = _LOCKED.get(key, False)
    if have is False or (state and have is not None and have.y is None):
        if len(_LOCKED) > 4096:
            _LOCKED.clear()
        have = locked_state(setup.law, setup.values, setup.edges, ip, ix, w, t_max=setup.lock_t_max)
        _LOCKED[key] = have if have is None or state else dataclasses.replace(have, y=None)
    return have


def _no_lock(setup: LawSetup, label: str) -> str:
    return (
        f"{label}: law {setup.law.name} does not lock from its in-phase state within t = "
        f"{setup.lock_t_max:g} (no locked state connected to synchrony; its parameters may be too "
        "spread for the coupling)"
    )


def law_r_star(setup: LawSetup, indptr, indices, weights, labels) -> np.ndarray:
    """``r*`` of the law's locked state on each network (rows of ``weights``, named by
    ``labels`` in a refusal), by :func:`antisync.kernels.law_locked.locked_state`.

    Raises
    ------
    ConfigError
        A network where the law does not lock from its in-phase state within ``lock_t_max``.
    """
    from tqdm import tqdm

    out = np.empty(len(weights))
    networks = tqdm(
        zip(weights, labels, strict=True),
        total=len(weights),
        unit="network",
        desc="locked states (r*)",
        delay=1.0,
        disable=not sys.stderr.isatty(),
        file=sys.stderr,
        dynamic_ncols=True,
        leave=False,
    )
    for row, (w, label) in enumerate(networks):
        state = _law_locked(setup, indptr, indices, w)
        if state is None:
            raise ConfigError(
                f"sync.criterion relative: {_no_lock(setup, label)}: use sync.criterion frequency or "
                "order-parameter"
            )
        out[row] = state.r
    return out


def with_law_start(setup: LawSetup, indptr, indices, weights) -> LawSetup:
    """``setup`` with ``model.start``'s rows: the locked phase of every node of the undamaged
    network ``weights`` (the law's ``phase`` in the state it locks to from its in-phase state,
    :func:`~antisync.kernels.law_locked.locked_state`) and the width; the start of node ``i`` is
    the law's ``start`` at ``phi_i = center_i + width (2 u_i - 1)``, the built-in model's
    :func:`start_phases` (nothing to do without ``model.start``).

    Raises
    ------
    ConfigError
        The undamaged network does not lock from its in-phase state within ``lock_t_max``.
    """
    from antisync.kernels.law import node_phases

    if setup.start_width is None or setup.start is not None:
        return setup
    state = _law_locked(setup, indptr, indices, weights, state=True)
    if state is None:
        raise ConfigError(
            f"model.start around the locked state: {_no_lock(setup, 'the undamaged network')}: drop "
            "model.start (uniform phases)"
        )
    center = node_phases(setup.law, setup.values, state.y)
    return dataclasses.replace(setup, start=np.vstack([center, np.full(center.size, setup.start_width)]))


def with_law_r_star(setup: LawSetup, indptr, indices, weights, labels) -> LawSetup:
    """``setup`` with the relative criterion's ``r*`` of the undamaged network (``weights[0]``)
    and of each variant, and its target from the undamaged one (nothing to do without the
    criterion)."""
    if setup.fraction is None:
        return setup
    r_star = law_r_star(setup, indptr, indices, weights, ["the undamaged network", *labels])
    return dataclasses.replace(setup, r_star=r_star, target=float(setup.relative_target(r_star[0])))


def with_law_dtarget(setup: LawSetup, indptr, indices, rows, labels, h: float) -> LawSetup:
    """``setup`` with :attr:`LawSetup.dtarget`: the central difference of the relative target
    over ``rows`` (each link at ``+h`` then ``-h`` of damage; ``labels`` name them), each
    network's ``r*`` found as :func:`law_r_star` finds it."""
    target = setup.relative_target(law_r_star(setup, indptr, indices, rows, labels))
    return dataclasses.replace(setup, dtarget=(target[0::2] - target[1::2]) / (2.0 * h))


def law_targets(setup: LawSetup, indptr, indices, weights) -> np.ndarray:
    """The targets of the undamaged network and of each network of ``weights`` (rows): the one
    target of the order-parameter and frequency criteria, or ``(fraction r* N)^2`` of each
    (:func:`law_r_star`; the variants' from :attr:`LawSetup.r_star` where ``weights`` are
    they)."""
    out = np.full(len(weights) + 1, setup.target)
    if setup.fraction is None or not len(weights):
        return out
    labels = [f"network {k + 1} of {len(weights)}" for k in range(len(weights))]
    out[1:] = setup.relative_target(law_r_star(setup, indptr, indices, weights, labels))
    return out


def law_setup(config, n: int, edges: np.ndarray | None = None) -> LawSetup:
    """``config.model``'s law for a graph of ``n`` nodes (:class:`LawSetup`), with the edge
    parameters ``edges`` of :func:`law_edges`."""
    from antisync.kernels.core import CRIT_FREQUENCY, CRIT_ORDER

    values = law_values(config.model, n)
    law, drawn = config.model.user_law, law_drawn(config.model)
    if law.edge_params and edges is None:
        raise ValueError("law_setup: the law has edge parameters; give edges (law_edges)")
    start = config.model.start
    common = {
        "drawn": drawn,
        "edges": edges,
        "lock_t_max": max(LOCK_T_MIN, LOCK_T_FACTOR * config.dynamics.t_max),
        "start_width": None if start is None else float(start["width"]),
    }
    if config.sync.criterion == "frequency":
        return LawSetup(law, values, float(config.sync.tolerance), CRIT_FREQUENCY, **common)
    if config.sync.criterion == "relative":  # the target is r*'s: with_law_r_star
        return LawSetup(law, values, np.nan, CRIT_ORDER, fraction=float(config.sync.fraction), **common)
    return LawSetup(law, values, float((config.dynamics.threshold * n) ** 2), CRIT_ORDER, **common)


def law_on_network(config, nodes, graph, csr, variants, labels, check=None) -> LawSetup:
    """``config``'s law on a network as built (``graph``, its ``nodes`` in the order of the
    coupling ``csr``): :func:`law_setup` with the edge parameters read onto it, ``check(setup)``
    if given (before any locking), then ``r*`` of the undamaged network and of each row of
    ``variants`` (``labels`` name them; relative criterion) and ``model.start``'s locked phases:
    what a run's job and a grid's removal integrate."""
    setup = law_setup(config, len(nodes), law_edges(config.model, csr.indptr, csr.indices, nodes, graph))
    if check is not None:
        check(setup)
    setup = with_law_r_star(setup, csr.indptr, csr.indices, [csr.weights, *variants], labels)
    return with_law_start(setup, csr.indptr, csr.indices, csr.weights)


def law_edges(model: Model, indptr, indices, nodes=None, graph=None) -> np.ndarray | None:
    """The law's edge parameters per in-link, ``(n_edge_params, nnz)`` in the CSR order of
    ``indptr``/``indices`` (the coupling's weights), or None for a law without them. Each from
    ``model.edge_params``: a number on every link, or a file read by
    :func:`antisync.physics.graphs.link_values` onto ``graph`` (node ``i`` of the CSR is
    ``nodes[i]``; both directions of a link share its value); the law's default where not given.

    Raises
    ------
    ConfigError
        A file of values where no graph is given (a design's candidate links have none).
    GraphError
        A file that does not give every link of ``graph`` one finite value (one line).
    """
    from antisync.physics.graphs import link_values

    law = model.user_law
    if law is None or not law.edge_params:
        return None
    indptr = np.asarray(indptr, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    rows = np.repeat(np.arange(indptr.size - 1), np.diff(indptr))
    given = model.edge_params or {}
    out = np.empty((len(law.edge_params), indices.size))
    for k, (name, default) in enumerate(law.edge_params):
        spec = given.get(name, default)
        if isinstance(spec, float):
            out[k] = spec
            continue
        if graph is None:
            raise ConfigError(
                f"model.edge_params.{name}: a file of values per link needs the graph's links; here "
                "links may be added (a design's candidates), so give one number for every link"
            )
        values = link_values(spec["file"], graph, spec.get("column"), f"model.edge_params.{name}.file")
        out[k] = [values[nodes[i], nodes[j]] for i, j in zip(rows, indices, strict=True)]
    return out


def _law_edge_parameter(key: str, value):
    """A law's edge parameter: a finite number (every link), or ``{file: PATH}`` / ``{file:
    PATH, column: NAME}`` (:func:`law_edges`)."""
    valid = "a number (every link) or {file: PATH} (u v value lines; column: NAME for a named column)"
    if isinstance(value, dict):
        extra = sorted(set(value) - {"file", "column"})
        if extra:
            raise ConfigError(f"unknown key '{key}.{extra[0]}'; valid keys: file, column")
        if not isinstance(value.get("file"), str) or not value["file"]:
            raise ConfigError(f"{key} must be {valid}, got {show(value)}")
        column = value.get("column")
        if column is not None and (not isinstance(column, str) or not column):
            raise ConfigError(
                f"{key}.column must be a column's name from the file's header, got {show(column)}"
            )
        return {"file": value["file"], **({"column": column} if column is not None else {})}
    if isinstance(value, list | tuple):
        raise ConfigError(f"{key} must be {valid}, got a list: a link has no order a list could follow")
    return parse_number(key, value, valid)


def _law_parameter(key: str, value):
    """A law's parameter: a finite number, one per node (a list), ``{file: PATH}``, or a
    distribution drawn per realization and node (``{distribution: normal, sd: S, mean: M}`` or
    ``{distribution: uniform, width: W, mean: M}``, as ``model.frequencies`` takes it)."""
    valid = "a number, a list (one per node), {file: PATH} or {distribution: normal, sd: S, mean: M}"
    if isinstance(value, list | tuple):
        if not value:
            raise ConfigError(f"{key} is an empty list; give a number or one number per node")
        return tuple(parse_number(f"{key}[{i}]", x) for i, x in enumerate(value))
    if isinstance(value, dict) and "distribution" in value:
        dist = value["distribution"]
        choice(f"{key}.distribution", dist, DISTRIBUTIONS)
        extra = sorted(set(value) - _FREQ_KEYS[dist])
        if extra:
            raise ConfigError(
                f"unknown key '{key}.{extra[0]}' for distribution {dist}; valid keys: "
                + ", ".join(sorted(_FREQ_KEYS[dist]))
            )
        scale = "sd" if dist == "normal" else "width"
        if scale not in value:
            raise ConfigError(f"{key} with distribution {dist} needs {scale}")
        return {
            "distribution": dist,
            "mean": _frequency(f"{key}.mean", value.get("mean", 0.0)),
            scale: _frequency(f"{key}.{scale}", value[scale], lo=0.0),
        }
    if isinstance(value, dict):
        if set(value) != {"file"} or not isinstance(value["file"], str) or not value["file"]:
            raise ConfigError(f"{key} must be {valid}, got {show(value)}")
        return {"file": value["file"]}
    return parse_number(key, value, valid)


def law_drawn(model: Model) -> tuple:
    """``(k, distribution)`` for each of the law's parameters that ``model.params`` draws per
    realization (``k``: its index in the law's parameters)."""
    params = model.params or {}
    return tuple(
        (k, dict(params[name]))
        for k, (name, _) in enumerate(model.user_law.params)
        if isinstance(params.get(name), dict) and "distribution" in params[name]
    )


def law_values(model: Model, n: int) -> np.ndarray:
    """The law's parameters per node, ``(n_params, n)`` in the law's order: each one's value
    from ``model.params`` (a number, a list or a file, read like a frequency file) or the law's
    default."""
    law = model.user_law
    params = model.params or {}
    out = np.empty((len(law.params), n))
    for k, (name, default) in enumerate(law.params):
        value = params.get(name, default)
        key = f"model.params.{name}"
        if isinstance(value, float):
            out[k] = value
            continue
        if isinstance(value, dict) and "distribution" in value:
            out[k] = value["mean"]  # drawn per realization by the kernels' caller (law_drawn)
            continue
        if isinstance(value, dict):
            key = f"{key}.file {value['file']}"
            values = read_frequency_file(Path(value["file"]), f"model.params.{name}.file")
        else:
            values = np.array(value, dtype=np.float64)
        if values.size != n:
            raise ConfigError(
                f"{key} has {values.size} values; the graph has {n} nodes: give one value per node, "
                "in node order"
            )
        out[k] = values
    return out


def node_parameters(model: Model, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-node inertia ``m_i`` and damping ``gamma_i`` in node order (shape ``(n,)`` each).

    A model without inertia anywhere gets ``gamma = 1`` (its damping is unused: ``theta_i' =
    P_i + ...``). Files (``{"file": path}``) are read like a frequency file.

    Raises
    ------
    ConfigError
        A list or file of the wrong length, a value out of range, or every inertia 0.
    """
    out = []
    for key, value, positive_only in (
        ("model.inertia", model.inertia, False),
        ("model.damping", model.damping, True),
    ):
        if isinstance(value, float):
            out.append(np.full(n, value))
            continue
        if isinstance(value, dict):
            path = Path(value["file"])
            source = f"{key}.file {path}"
            values = read_frequency_file(path, f"{key}.file")
            for i, x in enumerate(values):
                if not (0 < x if positive_only else 0 <= x) or not x <= MAX_NODE_PARAMETER:
                    what = "a positive number" if positive_only else "a number >= 0"
                    raise ConfigError(
                        f"{source}: value {i + 1} ({x:g}) must be {what} at most {MAX_NODE_PARAMETER:g}"
                    )
        else:
            source = key
            values = np.array(value, dtype=np.float64)
        if values.size != n:
            raise ConfigError(
                f"{source} has {values.size} values; the graph has {n} nodes: give one value per node, "
                "in node order"
            )
        out.append(values)
    mass, gamma = out
    if not (mass > 0).any():
        if not isinstance(model.inertia, float):
            raise ConfigError(
                f"model.inertia.file {model.inertia['file']} has 0 for every node: that is the first-order "
                "model, whose damping is unused; write model.inertia: 0, or give some node a positive inertia"
            )
        gamma = np.ones(n)
    return mass, gamma


def drawn_frequencies(model: Model, seed: int, ks: np.ndarray, n: int) -> np.ndarray:
    """Natural frequencies of realizations ``ks`` drawn by ``model.frequencies`` (shape
    ``(len(ks), n)``), in the rotating frame: each realization's mean removed.

    The distribution's ``mean`` is never added: it would be removed again, and adding it first
    rounds the spread away (``1e6 + 0.1 z`` keeps ~10 of z's 16 digits; ``1e17 + z`` none). A
    common frequency changes neither ``r(t)`` nor the frequency criterion, which measures
    deviations from the mean frequency, nor the second-order model, which starts with
    ``theta_i' = 0`` in the rotating frame (module docstring). So the numbers are those of
    ``mean: 0`` bit for bit, whatever the mean.
    """
    # lazy: the kernels load numba (~0.2 s), and `import antisync.api` reads configs through here
    from antisync.kernels.model_steps import draw_frequencies

    freqs = draw_frequencies({**model.frequencies, "mean": 0.0}, seed, ks, n)
    freqs -= freqs.mean(axis=1, keepdims=True)
    return freqs


@dataclass(frozen=True)
class ModelSetup:
    """A job's model resolved for the kernels (:func:`model_setup`).

    Attributes
    ----------
    freqs : ndarray (N,) or None
        Fixed natural frequencies, mean removed (``None``: drawn per realization, or none).
    cos_lag, sin_lag : float
    inertia, damping : ndarray (N,)
        Per-node ``m_i`` and ``gamma_i`` (:func:`node_parameters`; ``gamma = 1`` without inertia).
    criterion : int
        :data:`antisync.kernels.core.CRIT_ORDER` or ``CRIT_FREQUENCY``.
    targets : ndarray (1 + V,)
        Per trajectory kind (undamaged, then each variant): ``R = (r N)^2`` at the threshold, or
        the frequency tolerance.
    r_star : ndarray (1 + V,) or None
        ``relative``: the order parameter of each one's stable locked state.
    orbit_targets, orbit_r_star : ndarray (2 E,) or None
        The same for the ``+dbeta``/``-dbeta`` rows of ``central-difference`` and ``orbit``
        (:attr:`antisync.plan.jobs.Job.orbit_weights`), when the method has them.
    secant_targets : ndarray (2 E,) or None
        The hybrids' central secants' rows (:attr:`antisync.plan.jobs.Job.secant_weights`).
    dtarget : ndarray (E,) or None
        ``d target / d beta_e`` at 0 for the adjoint with the relative criterion (``r*`` moves
        with the damage), by a central difference of ``r*`` at ``+-DTARGET_STEP``.
    start : ndarray (N,) or None
        ``model.start``'s centre: the undamaged network's stable locked state ``phi`` (``None``:
        uniform phases).
    """

    freqs: np.ndarray | None
    cos_lag: float
    sin_lag: float
    inertia: np.ndarray
    damping: np.ndarray
    criterion: int
    targets: np.ndarray
    r_star: np.ndarray | None
    orbit_targets: np.ndarray | None = None
    orbit_r_star: np.ndarray | None = None
    secant_targets: np.ndarray | None = None
    dtarget: np.ndarray | None = None
    start: np.ndarray | None = None


#: The damage step of :attr:`ModelSetup.dtarget`'s central difference: the relative target
#: ``(fraction r* N)^2`` is smooth in beta, so its error is ~1e-10 relative (rounding ~1e-11).
DTARGET_STEP = 1e-5


def model_setup(
    config, indptr: np.ndarray, indices: np.ndarray, weights: list, labels: list, extra_rows: int = 0
) -> tuple[ModelSetup, np.ndarray, np.ndarray | None]:
    """Resolve ``config.model`` and ``config.sync`` for a graph whose coupling ``W`` (CSR
    ``indptr``, ``indices``) takes the CSR ``weights[0]`` undamaged and ``weights[1 + v]`` in
    variant ``v`` (``labels[v]`` names it in messages). The last ``extra_rows`` of them are
    other damaged networks (central differences' rows): their targets and ``r*`` are returned
    beside the setup, ``(setup, extra_targets, extra_r_star)``.

    Raises
    ------
    ConfigError
        A frequency list or file of the wrong length, or (``relative``, or ``model.start``
        around the locked state) a network without a stable phase-locked state.
    """
    # lazy: the kernels load numba (~0.2 s), and `import antisync.api` reads configs through here
    from antisync.kernels.core import CRIT_FREQUENCY, CRIT_ORDER

    model, sync = config.model, config.sync
    n = indptr.size - 1
    mass, gamma = node_parameters(model, n)
    if (mass > 0).any() and config.dynamics.integrator in STABLE_STEP:
        check_second_order_step(config, indptr, indices, weights[0], mass, gamma)
    fixed = node_frequencies(model, n)
    freqs = None if fixed is None else fixed - fixed.mean()
    lag = float(model.phase_lag)
    n_kinds = len(weights)
    p = np.zeros(n) if freqs is None else freqs
    rows = np.repeat(np.arange(n), np.diff(indptr))
    cache: dict = {}

    def locked(w_csr):
        """The locked state of the CSR weights ``w_csr`` (each network solved once)."""
        key = np.asarray(w_csr).tobytes()
        if key not in cache:
            w = np.zeros((n, n))
            w[rows, indices] = w_csr
            cache[key] = locked_state(w, p, lag, mass, gamma)
        return cache[key]

    r_star = None
    if sync.criterion == "frequency":
        criterion = CRIT_FREQUENCY
        targets = np.full(n_kinds, float(sync.tolerance))
    elif sync.criterion == "order-parameter":
        criterion = CRIT_ORDER
        targets = np.full(n_kinds, (config.dynamics.threshold * n) ** 2)
    else:
        criterion = CRIT_ORDER
        r_star = np.empty(n_kinds)
        for v, w_csr in enumerate(weights):
            state = locked(w_csr)
            if state is None or not state.stable:
                what = "the undamaged network" if v == 0 else f"variant {labels[v - 1]}"
                raise ConfigError(
                    f"sync.criterion relative: {what} has {_no_state(state, p)}: use "
                    "sync.criterion frequency or order-parameter, or smaller frequencies"
                )
            r_star[v] = state.r
        targets = (sync.fraction * r_star * n) ** 2
    start = None
    if model.start is not None:
        state = locked(weights[0])
        if state is None or not state.stable:
            raise ConfigError(
                f"model.start around the locked state: the undamaged network has {_no_state(state, p)}; "
                "drop model.start (uniform phases), or use smaller frequencies"
            )
        start = state.phi
    cut = n_kinds - extra_rows
    setup = ModelSetup(
        freqs=freqs,
        cos_lag=math.cos(lag),
        sin_lag=math.sin(lag),
        inertia=mass,
        damping=gamma,
        criterion=criterion,
        targets=targets[:cut],
        r_star=None if r_star is None else r_star[:cut],
        start=start,
    )
    return setup, targets[cut:], None if r_star is None else r_star[cut:]


def _no_state(state, p: np.ndarray) -> str:
    """Why ``state`` (a :class:`~antisync.physics.locked.LockedState` or None) is no stable locked
    state, for a message, with the frequencies' spread that may be the cause."""
    why = (
        "no phase-locked state connected to synchrony"
        if state is None
        else f"an unstable locked state (largest eigenvalue real part {state.max_real:.3g})"
    )
    spread = float(np.max(np.abs(p))) if p.size else 0.0
    return (
        f"{why}; the natural frequencies (max |P_i - mean| = {spread:.3g}) may be too spread for the coupling"
    )


def start_phases(center: np.ndarray, width: float, seed: int, ks: np.ndarray) -> np.ndarray:
    """``model.start``'s phases of realizations ``ks``, shape ``(len(ks), N)``:
    ``theta_i = center_i + width (2 u_i - 1)`` with ``u_i = phase(seed, k, i) / 2 pi`` (the
    paper's phases rescaled; module docstring)."""
    # lazy: the kernels load numba (~0.2 s), and `import antisync.api` reads configs through here
    from antisync.physics.phases import phases_of

    u = phases_of(seed, np.asarray(ks, dtype=np.uint64), center.size) * (1.0 / np.pi) - 1.0
    return center[None, :] + width * u


def unsynced_hint(config) -> str | None:
    """Why a generalized run may not lock, for the summary's warning when (almost) nothing
    synchronized; ``None`` for the paper's model."""
    if config.model.frequencies is None:
        return None
    if config.sync.criterion == "order-parameter":
        return (
            "the natural frequencies may be too spread for the coupling (no locked state, or "
            "its r* below the threshold: try sync.criterion relative or frequency)"
        )
    return "the natural frequencies may be too spread for the coupling (no locked state)"


#: The real stability interval of each explicit step for y' = -xi y: Euler is stable for
#: dt * xi < 2, classical RK4 for dt * xi < 2.785 (the negative real axis of its region);
#: ``rodas4`` is L-stable (no limit, absent here).
STABLE_STEP = {"euler": 2.0, "rk4": 2.785}


def check_second_order_step(config, indptr, indices, weights, mass, gamma) -> None:
    """Refuse a ``dt`` at which the explicit integrator is unstable near synchrony.

    Linearized at the in-phase state, ``m u'' + gamma u' = -L u`` (``L`` the coupling's
    Laplacian) has, for each eigenvalue ``xi`` of ``L``, the rates ``lambda`` with ``m lambda^2
    + gamma lambda + xi = 0`` (per-node ``m_i``, ``gamma_i``: the eigenvalues of
    :func:`antisync.physics.locked.linearization`'s matrix). An explicit step multiplies such a mode by
    ``R(dt lambda)`` (Euler ``1 + z``, RK4 its 4th-order polynomial); ``|R| > 1`` makes synchrony
    repel (the damping mode ``-gamma/m`` of a small inertia, or weakly damped oscillations under
    Euler). The first-order model's check is :func:`antisync.plan.jobs.check_step`.

    The comparison is NaN-safe: a growth that overflows (``inertia: 1e-110`` puts ``dt
    lambda`` near 1e107, whose 4th power is inf and the polynomial NaN) is refused, not passed.
    Eigenvalues of ``L`` within rounding of 0 are 0: the rotation's ``xi = 0`` computed as
    ``-1e-16`` gave a rate ``+1e-16 / gamma`` and a false "amplifies a mode by 1 per step".
    The message gives the largest stable ``dt`` (found by bisection on the same test).
    """
    dyn = config.dynamics
    n = indptr.size - 1
    w = np.zeros((n, n))
    w[np.repeat(np.arange(n), np.diff(indptr)), indices] = weights
    lap = np.diag(w.sum(axis=1)) - w
    # rounding of an eigenvalue solver is ~ n eps ||L||: anything that close to 0 is the zero
    # of the global rotation (or another exact zero), and its sign means nothing
    scale = float(np.max(np.abs(lap.diagonal()))) if n else 0.0
    zero = 64 * n * np.finfo(float).eps * scale
    gen = mass > 0
    # the damping mode -gamma_i/m_i of the node where it is fastest (inf for a tiny m_i)
    with np.errstate(over="ignore"):
        worst_node = int(np.argmax(np.where(gen, gamma / np.where(gen, mass, 1.0), -np.inf)))
    m, g = float(mass[worst_node]), float(gamma[worst_node])
    uniform = gen.all() and np.all(mass == mass[0]) and np.all(gamma == gamma[0])
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        if uniform:
            xi = np.linalg.eigvals(lap)
            xi = np.where(np.abs(xi) <= zero, 0.0, xi)
            disc = np.sqrt(g * g - 4 * m * xi.astype(complex))
            lam = np.concatenate([(-g + disc) / (2 * m), (-g - disc) / (2 * m)])
        else:
            lam = np.linalg.eigvals(linearization(-lap, mass, gamma))
            lam = np.where(np.abs(lam) <= zero * float(np.max(1.0 / np.where(gen, mass, gamma))), 0.0, lam)
    lam = lam[lam != 0]  # the rotation's own mode: neither grows nor decays

    def worst_growth(dt: float) -> float:
        with np.errstate(over="ignore", invalid="ignore"):
            z = dt * lam
            growth = 1 + z if dyn.integrator == "euler" else 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
            g = np.abs(growth)
        if not lam.size:
            return 0.0
        return math.inf if not np.isfinite(g).all() else float(np.max(g))

    def stable(dt: float) -> bool:
        return worst_growth(dt) <= 1 + 1e-12  # NaN and inf fail

    worst = worst_growth(dyn.dt)
    if stable(dyn.dt):
        return
    lo, hi = 0.0, dyn.dt
    while lo == 0.0 and hi > 1e-300:  # the largest stable dt: bracket it geometrically ...
        if stable(hi / 256):
            lo = hi / 256
        else:
            hi /= 256
    for _ in range(60):  # ... then bisect to 0.1%
        if lo == 0.0 or hi - lo <= 1e-3 * lo:
            break
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    # the damping mode -gamma/m alone needs dt gamma / m below the step's real stability limit
    m_min = dyn.dt * g / (2.0 if dyn.integrator == "euler" else 2.785)
    usable = lo > 0.0 and dyn.t_max / lo <= MAX_STEPS_HINT
    node = f" at node {worst_node}" if config.model.per_node else ""
    if m < m_min:
        fix = f"model.inertia{node} must be at least ~{m_min:.3g} at this dt (or 0: the first-order model)"
        if usable:
            fix += f", or dynamics.dt below ~{lo:.3g}"
    elif usable:
        fix = f"dynamics.dt must be below ~{lo:.3g} with this model.inertia and model.damping"
    else:
        fix = "no dynamics.dt of at most 2**40 steps to t_max is stable: change model.inertia/damping"
    shown = f"{worst:.6g}" if math.isfinite(worst) else "an overflowing factor (inf)"
    raise ConfigError(
        f"dynamics.dt = {dyn.dt:g} is unstable for the second-order model (model.inertia {m:g}, "
        f"model.damping {g:g}{node}): an explicit {dyn.integrator} step amplifies a mode near synchrony "
        f"by {shown} per step; {fix}"
    )
