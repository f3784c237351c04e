"""A user's oscillator model: a node law and an edge law (docs/models.md, "Write your own model").

A :class:`Law` names

- ``states``: the state variables of every node (``[theta]``, ``[x, y]``, ``[theta, omega]``);
- ``params``: per-node parameters with their defaults (``{omega: 0.0}``); a run's
  ``model.params`` gives them values per node;
- ``edge_params``: per-link parameters with their defaults (``{alpha: 0.0}``), read by the edge
  law alone, by their bare names; a run's ``model.edge_params`` gives them values per link (a
  number, or a column of an edge list): what the damage leaves alone, where ``w`` is what it
  scales;
- ``constants``: named numbers the expressions may use (``pi`` always);
- ``coupling``: the edge law, one or more coupling inputs ``u`` of node ``i``, each an
  expression of the link's ends (``theta_i``, ``theta_j``: the receiving node's state and its
  neighbour's; ``omega_i``, ``omega_j`` likewise for parameters) and of its weight ``w`` (the
  link's entry of the coupling matrix, which the damage ``beta`` scales), summed over node
  ``i``'s in-links: ``u_i = sum_j h(state_i, state_j, w_ij)``;
- ``rates``: the node law, every state's time derivative from the node's states, its inputs,
  its parameters and the constants;
- ``phase``: the node's phase, an expression of its states (``theta``, ``atan2(y, x)``), from
  which ``r(t)`` and the order-parameter criterion are computed;
- ``frequency``: what the frequency criterion (``sync.criterion: frequency``) brings within
  its tolerance of the network's mean: one or more per-node expressions of the node's states,
  inputs and parameters (the swing equation's ``[nu, (P + u) / gamma]``: the speed, and the
  speed the node relaxes to, so a start at rest is not "locked"); by default the phase's rate
  ``grad(phase) . rates``;
- ``start``: every state's initial value from the realization's random phase ``phi`` (the
  paper's counter-based phase of the node, uniform on the circle): ``{x: cos(phi), y:
  sin(phi)}``. By default a state that is the phase starts at ``phi`` and every other at 0.

The expressions are read by :mod:`antisync.laws.expressions` (no ``eval``) and differentiated
by sympy (:class:`Symbolic`); :mod:`antisync.kernels.law` compiles them into the kernels.
A law is read from a library name (``kuramoto``, ``stuart-landau``: the files of
``antisync/data/laws/``), a YAML file, or a mapping; its canonical text (:meth:`Law.text`) is
what a run stores and what the compiled kernels are cached by.
"""

from __future__ import annotations

import functools
import json
import keyword
import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import yaml

from antisync.errors import ConfigError
from antisync.laws.expressions import CONSTANTS, FUNCTIONS, parse_expression
from antisync.validation import parse_number, read_input_text, show

__all__ = ["LIBRARY", "Law", "Symbolic", "law_names", "read_law"]

#: the folder of the shipped laws (``<name>.yaml``, a name's ``-`` written ``_``)
LIBRARY = Path(__file__).resolve().parent.parent / "data" / "laws"

_KEYS = {
    "name",
    "about",
    "states",
    "params",
    "edge_params",
    "constants",
    "coupling",
    "rates",
    "phase",
    "start",
    "frequency",
}
_RESERVED = {"w", "phi", "t", *FUNCTIONS, *CONSTANTS}


def law_names() -> list[str]:
    """The names of the shipped laws (``antisync/data/laws/*.yaml``)."""
    return sorted(p.stem.replace("_", "-") for p in LIBRARY.glob("*.yaml"))


def read_law(value, base: Path | None = None, key: str = "model.law") -> Law:
    """The law of ``value``: a library name (:func:`law_names`), a path to a YAML file (relative
    to ``base``, the config's folder), or a mapping of the law's keys."""
    if isinstance(value, Law):
        return value
    if isinstance(value, str) and value:
        library = LIBRARY / f"{value.replace('-', '_')}.yaml"
        if library.is_file():
            return Law.from_mapping(yaml.safe_load(library.read_text(encoding="utf-8")), key)
        if value.endswith((".yaml", ".yml")):
            path = Path(value) if base is None else base / value
            text = read_input_text(path, key)
            try:
                data = yaml.safe_load(text)
            except yaml.YAMLError as exc:
                raise ConfigError(f"{key}: {path} is not YAML ({str(exc).splitlines()[0]})") from None
            return Law.from_mapping(data, key)
        raise ConfigError(
            f"{key} must be a shipped law ({', '.join(law_names())}), a .yaml file or a mapping, "
            f"got {value!r}"
        )
    if isinstance(value, dict):
        return Law.from_mapping(value, key)
    raise ConfigError(
        f"{key} must be a shipped law ({', '.join(law_names())}), a .yaml file or a mapping, "
        f"got {show(value)}"
    )


def _name(key: str, value, what: str) -> str:
    """A declared name: an identifier, not a keyword, not reserved, not ending in ``_i``/``_j``."""
    if not isinstance(value, str) or not value.isidentifier() or keyword.iskeyword(value):
        raise ConfigError(f"{key}: {what} {show(value)} is not a name (letters, digits, _)")
    if value in _RESERVED:
        raise ConfigError(f"{key}: {what} {value!r} is reserved ({', '.join(sorted(_RESERVED))})")
    if value.endswith(("_i", "_j")):
        raise ConfigError(
            f"{key}: {what} {value!r} ends in _i or _j, which the edge law uses for a link's two ends"
        )
    return value


def _mapping(key: str, value, what: str) -> dict:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ConfigError(f"{key} must be a mapping of {what}, got {show(value)}")
    return value


@dataclass(frozen=True)
class Law:
    """A node law and an edge law, checked (module docstring). Build one with
    :meth:`from_mapping` or :func:`read_law`; every field is plain data (the law pickles to a
    Dask worker as its text)."""

    name: str
    about: str
    states: tuple[str, ...]
    params: tuple[tuple[str, float], ...]
    constants: tuple[tuple[str, float], ...]
    coupling: tuple[tuple[str, str], ...]
    rates: tuple[tuple[str, str], ...]
    phase: str
    start: tuple[tuple[str, str], ...]
    frequency: tuple[str, ...] = ()
    """the frequency criterion's quantities (empty: the phase's rate)"""
    edge_params: tuple[tuple[str, float], ...] = ()
    """per-link parameters with their defaults, read by the edge law alone"""

    @classmethod
    def from_mapping(cls, data, key: str = "model.law") -> Law:
        """Read and check a law's mapping; every fault is one line naming its key."""
        if not isinstance(data, dict):
            raise ConfigError(f"{key} must be a mapping with states, coupling and rates, got {show(data)}")
        extra = sorted(set(data) - _KEYS)
        if extra:
            raise ConfigError(f"unknown key '{key}.{extra[0]}'; a law has {', '.join(sorted(_KEYS))}")
        for needed in ("states", "coupling", "rates"):
            if needed not in data:
                raise ConfigError(f"{key} needs {needed}")
        states = data["states"]
        if isinstance(states, str):
            states = [states]
        if not isinstance(states, list) or not states:
            raise ConfigError(
                f"{key}.states must be a list of names, e.g. [theta] or [x, y], got {show(states)}"
            )
        states = tuple(_name(f"{key}.states", s, "state") for s in states)
        params = _mapping(f"{key}.params", data.get("params"), "names to default values")
        params = tuple(
            (_name(f"{key}.params", p, "parameter"), parse_number(f"{key}.params.{p}", v))
            for p, v in params.items()
        )
        edge_params = _mapping(f"{key}.edge_params", data.get("edge_params"), "names to default values")
        edge_params = tuple(
            (_name(f"{key}.edge_params", q, "edge parameter"), parse_number(f"{key}.edge_params.{q}", v))
            for q, v in edge_params.items()
        )
        constants = _mapping(f"{key}.constants", data.get("constants"), "names to numbers")
        constants = tuple(
            (_name(f"{key}.constants", c, "constant"), parse_number(f"{key}.constants.{c}", v))
            for c, v in constants.items()
        )
        coupling = _mapping(f"{key}.coupling", data["coupling"], "input names to expressions")
        if not coupling:
            raise ConfigError(
                f"{key}.coupling needs at least one input, e.g. {{u: w * sin(theta_j - theta_i)}}"
            )
        coupling = tuple(
            (_name(f"{key}.coupling", u, "input"), _text(f"{key}.coupling.{u}", e))
            for u, e in coupling.items()
        )
        rates = _mapping(f"{key}.rates", data["rates"], "states to expressions")
        for s in rates:
            if s not in states:
                raise ConfigError(f"{key}.rates.{s}: {s!r} is not a state (states: {', '.join(states)})")
        for s in states:
            if s not in rates:
                raise ConfigError(f"{key}.rates has no law for the state {s!r}; give {key}.rates.{s}")
        rates = tuple((s, _text(f"{key}.rates.{s}", rates[s])) for s in states)
        names = [
            *states,
            *(p for p, _ in params),
            *(q for q, _ in edge_params),
            *(c for c, _ in constants),
            *(u for u, _ in coupling),
        ]
        seen = set()
        for n in names:
            if n in seen:
                raise ConfigError(
                    f"{key}: the name {n!r} is declared twice (states, params, edge_params, constants, "
                    "coupling)"
                )
            seen.add(n)
        phase = data.get("phase")
        if phase is None:
            if len(states) != 1:
                raise ConfigError(f"{key} needs phase: the node's phase from its states, e.g. atan2(y, x)")
            phase = states[0]
        phase = _text(f"{key}.phase", phase)
        start = _mapping(f"{key}.start", data.get("start"), "states to expressions of phi")
        for s in start:
            if s not in states:
                raise ConfigError(f"{key}.start.{s}: {s!r} is not a state (states: {', '.join(states)})")
        start = tuple(
            (s, _text(f"{key}.start.{s}", start[s]) if s in start else ("phi" if s == phase else "0"))
            for s in states
        )
        frequency = data.get("frequency", [])
        if isinstance(frequency, str | int | float) and not isinstance(frequency, bool):
            frequency = [frequency]
        if not isinstance(frequency, list):
            raise ConfigError(
                f"{key}.frequency must be an expression or a list of them, e.g. [nu, (P + u) / gamma], "
                f"got {show(frequency)}"
            )
        frequency = tuple(_text(f"{key}.frequency[{k}]", e) for k, e in enumerate(frequency))
        name = data.get("name", "law")
        about = data.get("about", "")
        if not isinstance(name, str) or not isinstance(about, str):
            raise ConfigError(f"{key}.name and {key}.about must be text")
        law = cls(
            name, about, states, params, constants, coupling, rates, phase, start, frequency, edge_params
        )
        law.symbolic(key)  # every expression parsed now: a fault is found on load
        return law

    def as_dict(self) -> dict:
        """The law as the mapping :meth:`from_mapping` reads (what a run stores)."""
        return {
            "name": self.name,
            "about": self.about,
            "states": list(self.states),
            "params": dict(self.params),
            "constants": dict(self.constants),
            "coupling": dict(self.coupling),
            "rates": dict(self.rates),
            "phase": self.phase,
            "start": dict(self.start),
            # only when given: the laws without them keep their texts (and cached kernels)
            **({"frequency": list(self.frequency)} if self.frequency else {}),
            **({"edge_params": dict(self.edge_params)} if self.edge_params else {}),
        }

    @property
    def text(self) -> str:
        """The canonical text of the law (what compiled kernels are cached by)."""
        return json.dumps(self.as_dict(), sort_keys=True)

    @property
    def dynamics_text(self) -> str:
        """The canonical text of the equations alone (no ``name``, no ``about``): what the
        generated kernels are keyed by, so two laws that differ only in words share them."""
        d = self.as_dict()
        del d["name"], d["about"]
        return json.dumps(d, sort_keys=True)

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p for p, _ in self.params)

    @property
    def edge_param_names(self) -> tuple[str, ...]:
        return tuple(q for q, _ in self.edge_params)

    def symbolic(self, key: str = "model.law") -> Symbolic:
        """The law's expressions in sympy (:class:`Symbolic`)."""
        return _symbolic(self, key)


def _text(key: str, value) -> str:
    """An expression's text (a number is its text)."""
    if isinstance(value, bool) or not isinstance(value, str | int | float):
        raise ConfigError(f"{key} must be an expression, got {show(value)}")
    if isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f"{key} must be finite, got {value!r}")
    return str(value)


@dataclass(frozen=True)
class Symbolic:
    """A law's expressions over the kernels' symbols (sympy objects).

    The symbols: ``x[k]`` the node's ``k``-th state (the node law; the edge law's receiving
    node), ``xj[k]`` the neighbour's, ``p[k]`` and ``pj[k]`` the parameters likewise, ``w`` the
    link's weight, ``e[k]`` the link's ``k``-th edge parameter, ``u[m]`` the ``m``-th coupling
    input, ``phi`` the start's random phase.
    """

    x: tuple
    xj: tuple
    p: tuple
    pj: tuple
    w: object
    u: tuple
    phi: object
    coupling: tuple
    """the edge law: one expression per input, of ``x, xj, p, pj, w``"""
    rates: tuple
    """the node law: one expression per state, of ``x, u, p``"""
    phase: object
    """of ``x, p``"""
    start: tuple
    """one expression per state, of ``phi, p``"""
    frequency: tuple
    """the frequency criterion's quantities, of ``x, u, p`` (by default the phase's rate)"""
    e: tuple = ()
    """the link's edge parameters (the edge law reads them as it reads ``w``)"""
    derived: tuple = ()
    """functions of the edge parameters alone that the kernels read per link, computed once
    per run (:func:`antisync.kernels.law.with_derived`)"""

    @cached_property
    def phase_gradient(self) -> tuple:
        """``d phase / d x[k]``."""
        return tuple(self.phase.diff(v) for v in self.x)


@functools.lru_cache(maxsize=64)
def _symbolic(law: Law, key: str) -> Symbolic:
    import sympy

    n_s, n_p, n_u = len(law.states), len(law.params), len(law.coupling)
    x = sympy.symbols(f"x0:{n_s}", real=True)
    xj = sympy.symbols(f"xj0:{n_s}", real=True)
    p = sympy.symbols(f"p0:{n_p}", real=True) if n_p else ()
    pj = sympy.symbols(f"pj0:{n_p}", real=True) if n_p else ()
    u = sympy.symbols(f"u0:{n_u}", real=True)
    w, phi = sympy.symbols("w phi", real=True)
    e = sympy.symbols(f"ep0:{len(law.edge_params)}", real=True) if law.edge_params else ()
    consts = {c: sympy.Float(v) for c, v in law.constants}
    params = dict(zip(law.param_names, p, strict=True))
    node = {**consts, **dict(zip(law.states, x, strict=True)), **params}
    edge = {**consts, "w": w, **dict(zip(law.edge_param_names, e, strict=True))}
    for k, s in enumerate(law.states):
        edge[f"{s}_i"], edge[f"{s}_j"] = x[k], xj[k]
    for k, q in enumerate(law.param_names):
        edge[f"{q}_i"], edge[f"{q}_j"] = p[k], pj[k]
    coupling = tuple(parse_expression(f"{key}.coupling.{name}", e, edge) for name, e in law.coupling)
    if not any(h.has(w) for h in coupling):
        raise ConfigError(
            f"{key}.coupling: no input reads the link's weight w, so damaging a link would change "
            "nothing; write the coupling with w (e.g. w * sin(theta_j - theta_i))"
        )
    # an edge parameter read where no link is (the node law, the phase, the start, the
    # frequency quantities): parsed as a marker, refused by name
    markers = {q: sympy.Symbol(f"edge parameter {q}") for q in law.edge_param_names}

    def node_expression(where: str, text, names: dict):
        expr = parse_expression(where, text, {**markers, **names})
        for q, marker in markers.items():
            if expr.has(marker):
                raise ConfigError(
                    f"{where}: {q!r} is an edge parameter, which only the coupling (the edge law) "
                    f"reads; got {text!r} (a per-node value belongs in params)"
                )
        return expr

    inputs = dict(zip((name for name, _ in law.coupling), u, strict=True))
    rates = tuple(node_expression(f"{key}.rates.{s}", e, {**node, **inputs}) for s, e in law.rates)
    phase = node_expression(f"{key}.phase", law.phase, node)
    if not any(phase.has(v) for v in x):
        raise ConfigError(
            f"{key}.phase must read the node's states (e.g. {law.states[0]}), got {law.phase!r}"
        )
    start = tuple(
        node_expression(f"{key}.start.{s}", e, {**consts, **params, "phi": phi}) for s, e in law.start
    )
    if law.frequency:
        frequency = tuple(
            node_expression(f"{key}.frequency[{k}]", e, {**node, **inputs})
            for k, e in enumerate(law.frequency)
        )
        for k, q in enumerate(frequency):
            if not any(q.has(v) for v in (*x, *u)):
                raise ConfigError(
                    f"{key}.frequency[{k}] must read the node's states or inputs (a constant is never "
                    f"off the mean), got {law.frequency[k]!r}"
                )
    else:
        frequency = (sum((phase.diff(v) * r for v, r in zip(x, rates, strict=True)), sympy.Integer(0)),)
    for k, q in enumerate(law.edge_param_names):
        if not any(h.has(e[k]) for h in coupling):
            raise ConfigError(
                f"{key}.edge_params.{q}: no coupling input reads it; use it in the edge law "
                f"(e.g. w * sin(theta_j - theta_i - {q})) or drop it"
            )
    return Symbolic(x, xj, p, pj, w, u, phi, coupling, rates, phase, start, frequency, e)
