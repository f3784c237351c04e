"""YAML configs and ``--set`` overrides -> frozen, validated dataclasses.

Every key has a default except ``graph``. Unknown keys are errors that name the key and
suggest the nearest valid one; every value is range-checked here, before any file is touched.
The resolved config (defaults filled in, ``block_size`` fixed) is what gets stored with results.

Example
-------
>>> cfg = load_config_text('''
... graph: {kind: lollipop, nodes: 6, path: 3}
... edges: ["2->1"]
... betas: [0.5]
... realizations: 1000
... ''', overrides=["seed=7"])
>>> cfg.seed, cfg.betas
(7, (0.5,))
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import yaml

from antisync.errors import ConfigError
from antisync.plan.model import Model, Sync, law_drawn
from antisync.types import (
    BACKENDS,
    COUPLINGS,
    CROSSINGS,
    EXECUTORS,
    INTEGRATORS,
    LAMBDA_METHODS,
    LAMBDA_ROWS,
    LINEAR_METHODS,
    MEASURES,
    PRECISIONS,
    RODAS4_ATOL,
    RODAS4_RTOL,
    STOP_RULES,
    Backend,
    Coupling,
    Crossing,
    Executor,
    Integrator,
    LambdaMethod,
    LinearMethod,
    Measure,
    Precision,
    StopRule,
)
from antisync.validation import (
    beta,
    choice,
    fraction,
    integer,
    number,
    parse_number,
    positive,
    read_input_bytes,
    read_input_text,
    show,
    suggest,
    unknown_keys,
    whole,
)

__all__ = [
    "BACKENDS",
    "EXECUTORS",
    "INTEGRATORS",
    "LAMBDA_METHODS",
    "MEASURES",
    "PRECISIONS",
    "Config",
    "Dynamics",
    "Histogram",
    "LambdaSpec",
    "LinearSpec",
    "Stop",
    "apply_values",
    "check_graph",
    "config_from_mapping",
    "load_config",
    "load_config_text",
    "parse_mapping",
    "resolve_graph_path",
]

# BACKENDS, EXECUTORS, INTEGRATORS, CROSSINGS, LAMBDA_METHODS, MEASURES, LINEAR_METHODS and
# PRECISIONS (imported above) are the valid values of the Literal types of antisync.types.

#: At most this many realizations per run: block counts, realization indices (the phase
#: generator's counter) and float64 sums of tau stay exact far below 2**53.
MAX_REALIZATIONS = 10**15
#: At most this many time steps per trajectory (t_max / dt): the kernels count steps in int64
#: and store tau as steps * dt; 2**40 steps (~1e12) is far beyond any run that can finish.
MAX_STEPS = 2**40
#: The commands a config is run by (:meth:`Config.stop_rule` rules which may stop early).
COMMANDS = ("run", "sweep", "design", "removal", "trip")

_GRAPH_KEYS = {
    "lollipop": ({"nodes", "path"}, set()),
    "barbell": ({"m1"}, {"m2"}),
    "atlas": ({"index"}, set()),
    "networkx": ({"generator"}, {"args", "weighted"}),
    "edgelist": ({"path"}, {"delimiter", "header"}),
    "graphml": ({"path"}, {"weight"}),
    "gml": ({"path"}, {"weight"}),
    "inline": ({"links"}, {"nodes"}),
}
#: Graph kinds read from a file: ``graph.path`` is relative to the config file's folder.
_GRAPH_FILE_KINDS = ("edgelist", "graphml", "gml")


#: The smallest ``dynamics.rtol`` / ``atol``: a few hundred float64 epsilons (a step's error
#: estimate is itself a difference of O(1) numbers; at 1e-15 the step size collapsed).
MIN_TOLERANCE = 1e-12


@dataclass(frozen=True)
class Dynamics:
    """Model and integrator (paper Eqs. 2, 20; Sec. 3: Euler, dt = 0.001, r = 0.99)."""

    coupling: Coupling = "normalized"
    integrator: Integrator = "euler"
    dt: float = 0.001
    threshold: float = 0.99
    t_max: float = 200.0
    crossing: Crossing = "auto"
    """``grid``: tau is the first grid time with r >= threshold (the paper's); ``interpolated``:
    the crossing inside that step (linear in R for Euler, cubic Hermite for RK4);
    ``auto``: grid for Euler, interpolated for RK4."""
    precision: Precision = "float64"
    """Arithmetic of the integrated state: ``float64`` (every backend) or ``float32`` (backend
    cuda; on the cpu backend the Euler finite difference with every rotation angle within the
    Taylor range; docs/cuda.md says how much it moves tau and Lambda)."""
    rtol: float | None = None
    """Relative tolerance of ``rodas4``'s step control (default 1e-6; None: the default)."""
    atol: float | None = None
    """Absolute tolerance of ``rodas4``'s step control, radians and rad/s (default 1e-6)."""

    def __post_init__(self):
        choice("dynamics.coupling", self.coupling, COUPLINGS)
        choice("dynamics.integrator", self.integrator, INTEGRATORS)
        choice("dynamics.crossing", self.crossing, CROSSINGS)
        choice("dynamics.precision", self.precision, PRECISIONS)
        if self.integrator != "euler" and self.crossing == "grid":
            raise ConfigError(
                f"dynamics.crossing grid is too coarse for {self.integrator} steps; use interpolated"
            )
        for key in ("rtol", "atol"):
            value = getattr(self, key)
            if value is None:
                continue
            if self.integrator != "rodas4":
                raise ConfigError(
                    f"dynamics.{key} sets the step control of integrator rodas4; {self.integrator} "
                    f"takes fixed steps of dynamics.dt (remove {key} or use integrator rodas4)"
                )
            value = positive(f"dynamics.{key}", value)
            if value >= 1.0:
                raise ConfigError(f"dynamics.{key} must be below 1 (a tolerance), got {value:g}")
            if value < MIN_TOLERANCE:
                raise ConfigError(
                    f"dynamics.{key} = {value:g} is below what float64 steps can deliver: give at least "
                    f"{MIN_TOLERANCE:g} (1e-4 to 1e-8 are usual)"
                )
            object.__setattr__(self, key, value)
        object.__setattr__(self, "dt", positive("dynamics.dt", self.dt))
        object.__setattr__(self, "t_max", positive("dynamics.t_max", self.t_max))
        object.__setattr__(self, "threshold", fraction("dynamics.threshold", self.threshold))
        if self.dt > self.t_max:
            raise ConfigError(f"dynamics.dt ({self.dt}) must be smaller than t_max ({self.t_max})")
        steps = self.t_max / self.dt
        if steps > MAX_STEPS:
            raise ConfigError(
                f"dynamics.t_max / dynamics.dt = {steps:.3g} steps per trajectory; antisync "
                f"integrates at most 2**40 (~{MAX_STEPS:.1e}): raise dt or lower t_max"
            )

    @property
    def interpolate(self) -> bool:
        return self.crossing == "interpolated" or (self.crossing == "auto" and self.integrator != "euler")

    @property
    def tolerances(self) -> tuple[float, float]:
        """``(rtol, atol)`` of ``rodas4``'s step control, the defaults where not set."""
        return (
            RODAS4_RTOL if self.rtol is None else self.rtol,
            RODAS4_ATOL if self.atol is None else self.atol,
        )

    @property
    def max_steps(self) -> int:
        return int(math.ceil(self.t_max / self.dt - 1e-9))


@dataclass(frozen=True)
class LambdaSpec:
    """How Lambda^KM = d<F_beta>/dbeta at beta = 0 is estimated (Eqs. 6, 17).

    - ``finite-difference``: the paper's ``(tau0/tau(dbeta) - 1)/dbeta`` per realization
      (grid crossing times), one damaged trajectory per edge.
    - ``pathwise``: ``-tau0'/tau0`` per realization from the forward sensitivities of the
      undamaged trajectory (interpolated crossing), every edge from one trajectory.
    - ``hybrid``: pathwise, except where ``|-tau0'/tau0| > hybrid_cut`` (trajectories near saddle
      states): there the secant ``(tau0/tau(dbeta) - 1)/dbeta`` of interpolated times.
    - ``adjoint``: the same per-realization values as ``pathwise`` (to rounding), from one
      reverse-mode pass of the discrete integrator per trajectory, whatever the number of edges
      (:mod:`antisync.kernels.adjoint`); Euler or RK4 (Hermite crossing differentiated exactly).
    - ``adjoint-hybrid``: ``hybrid`` with the adjoint's values.
    - ``orbit``: central differences along each edge's automorphism orbit.
    """

    method: LambdaMethod = "finite-difference"
    dbeta: float = 0.01
    hybrid_cut: float = 2.0

    def __post_init__(self):
        choice("lambda.method", self.method, LAMBDA_METHODS)
        object.__setattr__(self, "dbeta", fraction("lambda.dbeta", self.dbeta))
        object.__setattr__(self, "hybrid_cut", positive("lambda.hybrid_cut", self.hybrid_cut))


@dataclass(frozen=True)
class Stop:
    """An optional stopping rule: ``realizations`` becomes a budget (docs/stopping.md).

    With ``when: signs-resolved`` the run looks at its Lambda^KM intervals after
    ``first_look`` realizations, then at twice, four times ... as many, up to ``realizations``,
    and ends at the first look where every link's sign is resolved (or, with ``tolerance``,
    its interval lies inside ``[-tolerance, tolerance]``: the link does not matter). Each look
    uses the interval at level ``1 - 0.05 / looks`` (Bonferroni over the looks), so looking
    often does not make false signs more likely. A run that stops at ``n`` holds exactly the
    numbers of a plain run with ``realizations: n`` and the same ``block_size``.
    """

    when: StopRule = "never"
    first_look: int | Literal["auto"] = "auto"
    """Realizations at the first look; ``auto``: 32 blocks, at least 2,000."""
    tolerance: float = 0.0

    def __post_init__(self):
        choice("stop.when", self.when, STOP_RULES)
        if self.first_look != "auto":
            first = integer("stop.first_look", self.first_look, 1, MAX_REALIZATIONS, "'auto' or 1..10**15")
            object.__setattr__(self, "first_look", first)
        tolerance = parse_number("stop.tolerance", self.tolerance, "a number >= 0")
        if not tolerance >= 0:
            raise ConfigError(f"stop.tolerance must be a number >= 0, got {show(self.tolerance)}")
        object.__setattr__(self, "tolerance", tolerance)
        if self.when == "never" and (self.first_look != "auto" or self.tolerance != 0):
            key = "first_look" if self.first_look != "auto" else "tolerance"
            raise ConfigError(
                f"stop.{key} needs stop.when: signs-resolved (without a stopping rule it would be "
                f"ignored); add stop.when or remove stop.{key}"
            )

    @property
    def active(self) -> bool:
        return self.when != "never"


@dataclass(frozen=True)
class LinearSpec:
    """Lambda^(linear) (Eq. 14) when ``linear`` is in ``measures``.

    Realizations ``0 .. realizations-1`` of the run's seed give the initial phases, so the
    linear model starts where the Kuramoto runs start; ``method`` is ``exact`` (exact solution,
    root finding), ``euler`` (step ``dynamics.dt``) or ``derivative`` (exact per-realization
    derivative, no ``dbeta``), see :func:`antisync.measures.lambda_linear`.
    """

    realizations: int = 2000
    method: LinearMethod = "exact"

    def __post_init__(self):
        n = integer("linear.realizations", self.realizations, 2, MAX_REALIZATIONS, "2..10**15")
        object.__setattr__(self, "realizations", n)
        choice("linear.method", self.method, LINEAR_METHODS)


@dataclass(frozen=True)
class Histogram:
    """2D histogram of (tau0, tau(beta)) pairs (Figs. 1c-f): ``bins`` x ``bins`` on [0, tau_max)."""

    bins: int = 120
    tau_max: float = 40.0
    betas: tuple[float, ...] = (0.5,)
    """Damages whose histograms are kept (those also in the run's ``betas``)."""

    def __post_init__(self):
        betas = self.betas if self.betas is not None else ()
        if not isinstance(betas, list | tuple):
            raise ConfigError(f"histogram.betas must be a list such as [0.5], got {show(betas)}")
        object.__setattr__(self, "betas", tuple(beta("histogram.betas", b) for b in betas))
        object.__setattr__(self, "bins", integer("histogram.bins", self.bins, 2, 4096, "2..4096"))
        object.__setattr__(self, "tau_max", positive("histogram.tau_max", self.tau_max))


@dataclass(frozen=True)
class Config:
    """A resolved antisync experiment: one graph, its damaged edges, the beta grid, the model."""

    graph: dict
    name: str = "run"
    edges: Literal["all"] | tuple[str, ...] = "all"
    """``all`` (every directed link) or link labels such as ``("2->1",)``; a list is stored as a
    tuple."""
    betas: tuple[float, ...] = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
    lambda_: LambdaSpec = field(default_factory=LambdaSpec)
    dynamics: Dynamics = field(default_factory=Dynamics)
    measures: tuple[Measure, ...] = ("km",)
    linear: LinearSpec = field(default_factory=LinearSpec)
    realizations: int = 2000
    seed: int = 1
    block_size: int | Literal["auto"] = "auto"
    chunk_size: int | Literal["auto"] = "auto"
    keep_pairs: int = 10000
    histogram: Histogram = field(default_factory=Histogram)
    model: Model = field(default_factory=Model)
    """Natural frequencies, phase lag, inertia (docs/models.md); default: Eq. 2."""
    sync: Sync = field(default_factory=Sync)
    """When a trajectory counts as synchronized (docs/models.md); default: r >= threshold."""
    stop: Stop = field(default_factory=Stop)
    """An optional stopping rule (docs/stopping.md); default: run every realization."""
    backend: Backend = "cpu"
    executor: Executor = "local"
    threads: int | None = None
    output: str = ""

    def __post_init__(self):
        object.__setattr__(
            self, "realizations", integer("realizations", self.realizations, 1, MAX_REALIZATIONS, "1..10**15")
        )
        object.__setattr__(self, "seed", integer("seed", self.seed, 0, 2**63 - 1, "0..2**63-1"))
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(f"name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.output, str) or not self.output:
            raise ConfigError(f"output must be a file path such as results/run.h5, got {self.output!r}")
        if not isinstance(self.betas, list | tuple):
            raise ConfigError(f"betas must be a list such as [0.1, 0.5], got {show(self.betas)}")
        object.__setattr__(self, "betas", tuple(beta("betas", b) for b in self.betas))
        if self.edges != "all":
            if not isinstance(self.edges, list | tuple) or not self.edges:
                raise ConfigError(
                    f"edges must be 'all' or a non-empty list like [\"2->1\"], got {self.edges!r}"
                )
            object.__setattr__(self, "edges", tuple(self.edges))
        _check_measures(self.measures, self.dynamics.coupling)
        choice("backend", self.backend, BACKENDS)
        choice("executor", self.executor, EXECUTORS)
        for key in ("block_size", "chunk_size"):
            if getattr(self, key) != "auto":
                n = integer(key, getattr(self, key), 1, MAX_REALIZATIONS, "'auto' or 1..10**15")
                object.__setattr__(self, key, n)
        # kept pairs are held in memory: (keep_pairs x variants) int64 arrays
        object.__setattr__(self, "keep_pairs", integer("keep_pairs", self.keep_pairs, 0, 10**7, "0..10**7"))
        tangents = LAMBDA_ROWS[self.lambda_.method].passes == "tangents"
        if tangents and self.dynamics.integrator != "euler":
            raise ConfigError(
                f"lambda.method {self.lambda_.method} needs dynamics.integrator euler "
                "(the tangent is written for the Euler step); use adjoint, finite-difference or "
                "orbit with rk4"
            )
        if self.threads is not None:
            object.__setattr__(self, "threads", integer("threads", self.threads, 1, 4096, "null or 1..4096"))
        check_graph(self.graph)
        self._check_model()
        self._check_stop()
        self._check_give_up()

    @property
    def generalized(self) -> bool:
        """Runs on the model kernels (docs/models.md): a ``model:`` other than Eq. 2's identical
        oscillators, or a ``sync.criterion`` other than ``order-parameter``."""
        return not self.model.is_default or self.sync.criterion != "order-parameter"

    def _check_model(self) -> None:
        if not self.generalized:
            return
        method = self.lambda_.method
        if LAMBDA_ROWS[method].passes == "tangents" and self.model.law is not None:
            raise ConfigError(
                f"lambda.method {method}: its forward tangents are written for the Euler step of "
                "identical first-order oscillators; with a law (model.law) use central-difference (the "
                "derivative d<F>/dbeta), finite-difference (the paper's forward secant) or orbit"
            )
        if LAMBDA_ROWS[method].passes == "tangents":
            raise ConfigError(
                f"lambda.method {method}: its forward tangents are written for the Euler step of "
                "identical first-order oscillators; with this model/sync section use adjoint or "
                "adjoint-hybrid (the same derivative, every link in one backward pass), "
                "central-difference (the derivative d<F>/dbeta) or finite-difference (the paper's "
                "forward secant)"
            )
        if LAMBDA_ROWS[method].orbit == "automorphism" and not self.model.symmetric:
            raise ConfigError(
                "lambda.method orbit averages over the graph's automorphisms, which fixed natural "
                "frequencies, per-node inertia/damping or a law's parameters per node or per link "
                "do not respect (a link and its image see different values); use central-difference "
                "(every link on its own)"
            )
        if self.model.law is not None and self.sync.criterion == "relative":
            drawn = law_drawn(self.model)
            if drawn:
                name = self.model.user_law.params[drawn[0][0]][0]
                raise ConfigError(
                    f"sync.criterion relative needs fixed law parameters: model.params.{name} is drawn "
                    "per realization, so every realization has its own locked state; give it as a number, "
                    "a list or a file, or use criterion frequency or order-parameter"
                )
        if self.sync.criterion == "relative" and self.model.drawn:
            raise ConfigError(
                "sync.criterion relative needs fixed model.frequencies (a list or a file): with "
                "frequencies drawn per realization every realization has its own locked state; "
                "use criterion frequency or order-parameter"
            )

    def stop_rule(self, command: str) -> tuple[float, float] | None:
        """``sync.give_up``'s ``(after, band)`` for ``command`` (one of :data:`COMMANDS`), None
        without the rule: the one place that rules which work the rule may stop early. Only a
        removal's random starts count GAVE_UP (and check the rule: its pilot and audit); every
        other command refuses a config holding the rule, in one line."""
        if command not in COMMANDS:
            raise ValueError(f"stop_rule: command must be one of {', '.join(COMMANDS)}, got {command!r}")
        rule = self.sync.give_up_rule
        if rule is None or command == "removal":
            return rule
        if command == "trip":
            raise ConfigError(
                "sync.give_up stops random starts that keep slipping (removal); a trip runs from the "
                "operating point for t_max: remove give_up"
            )
        raise ConfigError(
            "sync.give_up records trajectories stopped early as GAVE_UP, which only `antisync grid "
            f"--removal` counts: remove give_up (antisync {command} does not take it)"
        )

    def _check_give_up(self) -> None:
        rule = self.sync.give_up_rule
        if rule is None:
            return
        dyn = self.dynamics
        if dyn.integrator != "rodas4":
            raise ConfigError(
                f"sync.give_up stops the adaptive integrator early; dynamics.integrator is "
                f"{dyn.integrator}: use integrator rodas4 or remove give_up"
            )
        if rule[0] >= dyn.t_max:
            raise ConfigError(
                f"sync.give_up.after ({rule[0]:g}) must come before dynamics.t_max ({dyn.t_max:g})"
            )

    def _check_stop(self) -> None:
        if not self.stop.active:
            return
        if "km" not in self.measures:
            raise ConfigError(
                f"stop.when {self.stop.when} watches Lambda^KM: measures must include km, "
                f"got {list(self.measures)}; remove the stop section"
            )
        if self.stop.first_look != "auto" and self.stop.first_look > self.realizations:
            raise ConfigError(
                f"stop.first_look ({self.stop.first_look:,}) is more than realizations "
                f"({self.realizations:,}), the run's budget: give 1..{self.realizations} or 'auto'"
            )

    @property
    def stop_looks(self) -> list[int]:
        """Realizations at each look of the stopping rule: ``first_look`` rounded up to whole
        blocks, doubling, the last one ``realizations`` (``[realizations]`` without a rule)."""
        if not self.stop.active:
            return [self.realizations]
        block = self.resolved_block_size
        first = self.stop.first_look
        if first == "auto":
            first = max(2000, 32 * block)
        n = min(self.realizations, -(-first // block) * block)
        looks = []
        while n < self.realizations:
            looks.append(n)
            n *= 2
        return [*looks, self.realizations]

    @property
    def resolved_block_size(self) -> int:
        """Realizations per statistics block: about 1000 blocks, at least 100 per block."""
        if self.block_size != "auto":
            return int(self.block_size)
        return max(100, -(-self.realizations // 1000))

    def resolved(self) -> Config:
        """This config with ``block_size`` fixed, as stored with results."""
        return replace(self, block_size=self.resolved_block_size)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["lambda"] = d.pop("lambda_")
        d["betas"] = list(self.betas)
        d["histogram"]["betas"] = list(self.histogram.betas)
        d["measures"] = list(self.measures)
        if isinstance(d["edges"], tuple):
            d["edges"] = list(d["edges"])
        # the default model and criterion are not written, so configs and result files of the
        # paper's model read (and --resume) exactly as before these sections existed
        if self.model.is_default and self.model.damping == 1.0:
            d.pop("model")
        else:
            if self.model.start is None:
                d["model"].pop("start")  # the uniform start: files written before it existed read the same
            for key in ("law", "params", "edge_params"):
                if d["model"][key] is None:
                    d["model"].pop(key)  # likewise without a law
                elif key == "params":
                    d["model"][key] = {
                        k: list(v) if isinstance(v, tuple) else v for k, v in d["model"][key].items()
                    }
        if not self.stop.active:
            d.pop("stop")
        elif isinstance(self.model.frequencies, tuple):
            d["model"]["frequencies"] = list(self.model.frequencies)
        if self.sync == Sync():
            d.pop("sync")
        return d

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)

    def simulation_key(self) -> dict:
        """The part of the config that determines the numbers (compared on ``--resume``)."""
        d = self.resolved().to_dict()
        for k in ("name", "backend", "executor", "threads", "output", "chunk_size"):
            d.pop(k)
        for key in _MODEL_FILE_KEYS:
            spec = getattr(self.model, key)
            if isinstance(spec, dict) and "file" in spec:
                # the file's content decides the numbers, not its name: an edited file is another run
                d["model"][key] = {**spec, "sha256": _file_digest(spec["file"])}
        for key in ("params", "edge_params"):
            for name, spec in (getattr(self.model, key) or {}).items():
                if isinstance(spec, dict) and "file" in spec:
                    d["model"][key][name] = {**spec, "sha256": _file_digest(spec["file"])}
        return d


_TOP_KEYS = {
    "name",
    "graph",
    "edges",
    "betas",
    "lambda",
    "dynamics",
    "measures",
    "linear",
    "realizations",
    "seed",
    "block_size",
    "chunk_size",
    "keep_pairs",
    "histogram",
    "model",
    "sync",
    "stop",
    "backend",
    "executor",
    "threads",
    "output",
}
_SECTIONS = {
    "lambda": LambdaSpec,
    "dynamics": Dynamics,
    "histogram": Histogram,
    "linear": LinearSpec,
    "model": Model,
    "sync": Sync,
    "stop": Stop,
}


def load_config(path: str | Path, overrides: list[str] | None = None, values: dict | None = None) -> Config:
    """Read a YAML config file, apply ``key=value`` overrides and ``values``, validate.

    Parameters
    ----------
    path : str or Path
        The YAML file.
    overrides : list of str, optional
        ``key=value`` strings whose values are parsed as YAML (the CLI's ``--set``).
    values : dict, optional
        ``{dotted key: value}`` set as they are, never parsed (the CLI's typed options such as
        ``--out``: ``--out '#a.h5'`` is the file ``#a.h5``, not a YAML comment).

    Raises
    ------
    ConfigError
        With a one-line message naming the file, key or value at fault.
    """
    path = Path(path)
    text = read_config_text(path)
    try:
        return load_config_text(text, overrides, source=path, values=values)
    except ConfigError as exc:
        msg = str(exc)
        raise ConfigError(msg if msg.startswith(str(path)) else f"{path}: {msg}") from None


def read_config_text(path: Path) -> str:
    """The text of a config file, or a one-line :class:`ConfigError` (missing, unreadable, a
    folder, a FIFO or device, too large, not UTF-8): :func:`antisync.validation.read_input_text`."""
    return read_input_text(path, "config file")


def load_config_text(
    text: str, overrides: list[str] | None = None, source: Path | None = None, values: dict | None = None
) -> Config:
    """Like :func:`load_config` for YAML text; relative paths resolve against ``source``'s folder."""
    return _from_mapping(parse_mapping(text, overrides, values), source)


class _Loader(yaml.SafeLoader):
    """YAML's safe loader with numbers in the one grammar of
    :data:`antisync.validation.DECIMAL`: decimal integers and floats, ``1e-3`` included (YAML
    1.1 reads it as a string), ``.inf``/``.nan``. YAML 1.1's other number forms are strings
    here, which the number parser refuses with one line instead of reading another value:
    ``010`` (octal 8 in YAML 1.1), ``0x10``, ``1_000``, ``1:30`` (base 60, i.e. 90)."""


_INT_TAG, _FLOAT_TAG = "tag:yaml.org,2002:int", "tag:yaml.org,2002:float"
_Loader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag not in (_INT_TAG, _FLOAT_TAG)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver(_INT_TAG, re.compile(r"^[-+]?(?:0|[1-9][0-9]*)$"), list("-+0123456789"))
_Loader.add_implicit_resolver(
    _FLOAT_TAG,
    re.compile(
        r"^(?:[-+]?(?:(?:0|[1-9][0-9]*)(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?"
        r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
    ),
    list("-+0123456789."),
)


def yaml_load(text: str):
    """``yaml.safe_load`` with :class:`_Loader`'s number forms (every config and ``--set``)."""
    return yaml.load(text, Loader=_Loader)  # noqa: S506 -- a SafeLoader subclass


def parse_mapping(text: str, overrides: list[str] | None = None, values: dict | None = None) -> dict:
    """YAML text -> mapping with ``key=value`` overrides, then ``values``, applied (not yet
    validated)."""
    try:
        raw = yaml_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or "not valid YAML"
        raise ConfigError(f"invalid YAML{where}: {problem}") from None
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise ConfigError("a config must be a YAML mapping of keys such as graph:, edges:, betas:")
    for item in overrides or []:
        _apply_override(raw, item)
    apply_values(raw, values or {})
    return raw


def _apply_override(raw: dict, item: str) -> None:
    key, sep, value = item.partition("=")
    key = key.strip()
    if not sep or not key or any(not p for p in key.split(".")):
        raise ConfigError(f"--set expects key=value (e.g. realizations=50000), got {item!r}")
    try:
        parsed = yaml_load(value) if value.strip() else None
    except yaml.YAMLError:
        raise ConfigError(f"--set {key}: value {value!r} is not valid YAML") from None
    _set_dotted(raw, key, parsed)


def apply_values(raw: dict, values: dict) -> dict:
    """Set ``{dotted key: value}`` in the mapping ``raw`` as they are (no YAML parsing);
    a missing or non-mapping section on the way becomes a new mapping. Returns ``raw``."""
    for key, value in values.items():
        _set_dotted(raw, key, value)
    return raw


def _set_dotted(raw: dict, key: str, value) -> None:
    parts = key.split(".")
    node = raw
    for p in parts[:-1]:
        if not isinstance(node.get(p), dict):
            node[p] = {}
        node = node[p]
    node[parts[-1]] = value


def config_from_mapping(raw: dict, source: Path | None = None) -> Config:
    """A validated :class:`Config` from an already parsed mapping (used by sweeps)."""
    return _from_mapping(raw, source)


def _from_mapping(raw: dict, source: Path | None) -> Config:
    if "sweep" in raw:
        raise ConfigError(
            "this is a sweep config (it has a 'sweep:' section): run it with "
            "`antisync sweep`, not `antisync run`"
        )
    if "design" in raw:
        raise ConfigError(
            "this is a design config (it has a 'design:' section): run it with "
            "`antisync design`, not `antisync run`"
        )
    unknown_keys(raw, _TOP_KEYS, "")
    if "graph" not in raw:
        raise ConfigError("missing key 'graph' (e.g. graph: {kind: lollipop, nodes: 6, path: 3})")
    kwargs: dict[str, Any] = {}
    for key, value in raw.items():
        if key in _SECTIONS:
            if value is None:
                value = {}
            if not isinstance(value, dict):
                raise ConfigError(f"'{key}' must be a mapping, got {value!r}")
            cls = _SECTIONS[key]
            valid = {f for f in cls.__dataclass_fields__}
            unknown_keys(value, valid, f"{key}.")
            if key == "stop":
                _check_stop_keys(value)
            value = {
                k: number(f"{key}.{k}", v, cls.__dataclass_fields__[k].default) for k, v in value.items()
            }
            if key == "model":
                value = _resolve_frequency_file(value, source)
            kwargs["lambda_" if key == "lambda" else key] = cls(**value)
        elif key == "betas":
            if value is None:
                value = []
            if not isinstance(value, list):
                raise ConfigError(f"betas must be a list such as [0.1, 0.5], got {value!r}")
            kwargs["betas"] = tuple(sorted({beta("betas", number("betas", b, 0.0)) for b in value}))
        elif key == "measures":
            if value is None or value == []:
                raise ConfigError("measures must list at least one measure, e.g. measures: [km, xi2]")
            items = value if isinstance(value, list) else [value]
            if not all(isinstance(m, str) for m in items):
                raise ConfigError(f"measures must be names such as [km, xi2], got {value!r}")
            kwargs["measures"] = tuple(items)
        elif key == "graph":
            kwargs["graph"] = _resolve_graph(value, source)
        elif key in ("name", "output"):
            if value is not None and not isinstance(value, str | int | float) or isinstance(value, bool):
                raise ConfigError(f"{key} must be a string, got {value!r}")
            kwargs[key] = "" if value is None else str(value)
        elif key in _INTEGER_KEYS:
            kwargs[key] = whole(key, value)
        else:
            kwargs[key] = value
    _move_sync_threshold(kwargs, raw)
    if not kwargs.get("name"):
        kwargs["name"] = source.stem if source else _graph_name(kwargs["graph"])
    if not kwargs.get("output"):
        kwargs["output"] = f"results/{kwargs['name']}.h5"
    return Config(**kwargs)


_INTEGER_KEYS = {"realizations", "seed", "keep_pairs"}


def _check_stop_keys(stop: dict) -> None:
    """Refuse ``stop.first_look`` or ``stop.tolerance`` without ``stop.when``: without a rule
    (``when: never``, the default) they would be silently ignored."""
    given = sorted(k for k in stop if k != "when")
    if given and stop.get("when", "never") == "never":
        raise ConfigError(
            f"stop.{given[0]} needs stop.when: signs-resolved (without a stopping rule it would be "
            f"ignored); add stop.when or remove stop.{given[0]}"
        )


def _file_digest(path: str) -> str:
    """SHA-256 of a file's bytes (``""`` when it cannot be read: reading it later says why;
    a FIFO or ``/dev/zero`` is refused by :func:`antisync.validation.read_input_bytes`, not
    waited on or hashed forever)."""
    try:
        return hashlib.sha256(read_input_bytes(path, "file")).hexdigest()
    except ConfigError:
        return ""


#: ``model:`` keys that may name a per-node file, ``{file: PATH}``.
_MODEL_FILE_KEYS = ("frequencies", "inertia", "damping")


def _resolve_frequency_file(value: dict, source: Path | None) -> dict:
    """``model.frequencies`` / ``inertia`` / ``damping: {file: PATH}`` relative to the config's
    folder (like edge lists)."""
    for key in _MODEL_FILE_KEYS:
        spec = value.get(key)
        if isinstance(spec, dict) and set(spec) == {"file"} and isinstance(spec["file"], str) and source:
            p = Path(spec["file"])
            if not p.is_absolute():
                value = {**value, key: {"file": str((source.parent / p).resolve())}}
    law = value.get("law")
    if isinstance(law, str) and law.endswith((".yaml", ".yml")) and source and not Path(law).is_absolute():
        value = {**value, "law": str((source.parent / law).resolve())}
    for key in ("params", "edge_params"):
        params = value.get(key)
        if isinstance(params, dict) and source:
            resolved = {}
            for name, spec in params.items():
                if isinstance(spec, dict) and isinstance(spec.get("file"), str) and spec["file"]:
                    if not Path(spec["file"]).is_absolute():
                        spec = {**spec, "file": str((source.parent / spec["file"]).resolve())}
                resolved[name] = spec
            value = {**value, key: resolved}
    return value


def _move_sync_threshold(kwargs: dict, raw: dict) -> None:
    """``sync.threshold`` is another spelling of ``dynamics.threshold`` (which stays valid):
    the value moves there, so one field holds the threshold everywhere."""
    sync = kwargs.get("sync")
    if sync is None or sync.threshold is None:
        return
    dyn = kwargs.get("dynamics", Dynamics())
    given = isinstance(raw.get("dynamics"), dict) and "threshold" in raw["dynamics"]
    if given and dyn.threshold != sync.threshold:
        raise ConfigError(
            f"sync.threshold ({sync.threshold}) and dynamics.threshold ({dyn.threshold}) disagree; "
            "give one of them"
        )
    if sync.criterion != "order-parameter":
        raise ConfigError(
            f"sync.threshold belongs to criterion order-parameter; criterion {sync.criterion} "
            "uses " + ("sync.fraction" if sync.criterion == "relative" else "sync.tolerance")
        )
    kwargs["dynamics"] = replace(dyn, threshold=sync.threshold)
    kwargs["sync"] = replace(sync, threshold=None)


def _check_measures(measures: tuple, coupling: str) -> None:
    """Names from :data:`MEASURES`, each once; ``km_nnc`` only beside a normalized ``km`` run
    (with raw coupling the second run would repeat the first). Without ``km`` no Kuramoto
    integration runs: the file holds the other measures only."""
    for m in measures:
        choice("measures", m, MEASURES)
    twice = sorted({m for m in measures if measures.count(m) > 1})
    if twice:
        raise ConfigError(f"measures lists {', '.join(twice)} twice")
    if not measures:
        raise ConfigError(f"measures must list at least one of {', '.join(MEASURES)}")
    if "km_nnc" in measures and "km" not in measures:
        raise ConfigError(
            f"measures: km_nnc is a raw-coupling twin of the km run; add km, got {list(measures)}"
        )
    if "km_nnc" in measures and coupling != "normalized":
        raise ConfigError(
            "measures: km_nnc adds a raw-coupling run beside a normalized one; "
            f"it needs dynamics.coupling: normalized, got {coupling!r}"
        )


def _resolve_graph(value, source: Path | None) -> dict:
    if not isinstance(value, dict):
        raise ConfigError(
            f"graph must be a mapping such as {{kind: lollipop, nodes: 6, path: 3}}, got {value!r}"
        )
    return resolve_graph_path(value, source)


def resolve_graph_path(spec: dict, source: Path | None) -> dict:
    """A copy of the graph spec ``spec`` whose file (``graph.path`` of an edge list, GraphML
    or GML file) is an absolute path: a relative one is relative to the folder of the config
    file ``source`` (the current folder when there is none: a mapping given to the API)."""
    g = dict(spec)
    if g.get("kind") in _GRAPH_FILE_KINDS and "path" in g and source is not None:
        p = Path(str(g["path"]))
        if not p.is_absolute():
            g["path"] = str((source.parent / p).resolve())
    return g


def check_graph(g: dict) -> None:
    if not isinstance(g, dict):
        raise ConfigError(
            f"graph must be a mapping such as {{kind: lollipop, nodes: 6, path: 3}}, got {show(g)}"
        )
    kind = g.get("kind")
    if not isinstance(kind, str) or kind not in _GRAPH_KEYS:
        raise ConfigError(
            f"graph.kind must be one of {', '.join(_GRAPH_KEYS)}, got {kind!r}"
            + suggest(str(kind), _GRAPH_KEYS)
        )
    required, optional = _GRAPH_KEYS[kind]
    unknown_keys(g, required | optional | {"kind"}, "graph.")
    missing = sorted(required - set(g))
    if missing:
        raise ConfigError(f"graph of kind {kind} needs key(s) {', '.join(missing)}")


def _graph_name(g: dict) -> str:
    kind = g.get("kind")
    if kind == "lollipop":
        return f"lollipop_{g.get('nodes')}_{g.get('path')}"
    if kind == "atlas":
        return f"G{g.get('index')}"
    if kind == "networkx":
        return str(g.get("generator"))
    if kind in _GRAPH_FILE_KINDS:
        return Path(str(g.get("path"))).stem
    if kind == "inline":
        return "graph"
    return str(kind)


def graph_name(g: dict) -> str:
    """A short name for a graph spec: ``G105`` for atlas graphs, ``lollipop_6_3``, ..."""
    return _graph_name(g)
