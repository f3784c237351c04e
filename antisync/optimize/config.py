"""A design config: a run config (``graph:``, ``dynamics:``, ``model:``, ``sync:``, ``seed``)
with a ``design:`` section. Every key, its default and what it means: docs/design.md.

.. code-block:: yaml

    graph: {kind: karate}
    dynamics: {integrator: rk4, dt: 0.04, t_max: 200}
    seed: 1
    design:
      objective: tau          # tau | lambda2 | resistance
      budget: 78              # sum of cost x weight; default: the graph's own total weight
      lower: 0.05             # per-link bounds (0 lets a link be removed)
      upper: null
      candidates: []          # links to add: ["0-9", ...], each at cost candidate_cost
      start: best             # best (baseline on validation starts) | graph | uniform | lambda2 | resistance
      iterations: 200
      starts: 256
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path

from antisync.errors import ConfigError
from antisync.optimize.descent import Settings
from antisync.optimize.ensemble import Problem, check_designable, make_problem
from antisync.plan.config import Config, config_from_mapping, parse_mapping, read_config_text
from antisync.validation import choice, parse_integer, parse_number, unknown_keys

__all__ = ["OBJECTIVES", "STARTS", "DesignSpec", "load_design_config", "design_from_mapping"]

OBJECTIVES = ("tau", "lambda2", "resistance")
"""``tau``: the mean synchronization time over random starts (by gradient); ``lambda2``: the
second eigenvalue of the Laplacian the dynamics couple through (normalized for normalized
coupling), maximized; ``resistance``: the total effective resistance of the weighted
Laplacian, minimized (exact spectral designs, no simulation)."""

STARTS = ("best", "graph", "uniform", "lambda2", "resistance")


@dataclass(frozen=True)
class DesignSpec:
    """The ``design:`` section, checked."""

    objective: str = "tau"
    budget: float | None = None
    lower: float = 0.0
    upper: float = math.inf
    candidates: tuple = ()
    candidate_cost: float = 1.0
    start: str = "best"
    settings: Settings = Settings()
    output: str = ""

    def problem(self, config: Config) -> Problem:
        """The :class:`~antisync.optimize.ensemble.Problem` of ``config``'s network under this
        section's budget, bounds and candidates."""
        return make_problem(
            config,
            self.budget,
            lower=self.lower,
            upper=self.upper,
            candidates=self.candidates,
            candidate_cost=self.candidate_cost,
        )

    def to_dict(self) -> dict:
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "settings"}
        out["candidates"] = list(self.candidates)
        out["upper"] = None if math.isinf(self.upper) else self.upper
        out.update({f.name: getattr(self.settings, f.name) for f in fields(Settings)})
        return out


_SETTING_KEYS = {f.name: f.default for f in fields(Settings)}
_KEYS = {
    "objective",
    "budget",
    "lower",
    "upper",
    "candidates",
    "candidate_cost",
    "start",
    "output",
    *_SETTING_KEYS,
}


def load_design_config(
    path: str | Path, overrides: list[str] | None = None, values: dict | None = None
) -> tuple[Config, DesignSpec]:
    """Read a design config file (``--set`` overrides and typed ``values`` as in
    :func:`antisync.plan.config.load_config`); one-line :class:`ConfigError` naming the file."""
    path = Path(path)
    try:
        raw = parse_mapping(read_config_text(path), overrides, values)
        return design_from_mapping(raw, path)
    except ConfigError as exc:
        msg = str(exc)
        raise ConfigError(msg if msg.startswith(str(path)) else f"{path}: {msg}") from None


def design_from_mapping(raw: dict, source: Path | None = None) -> tuple[Config, DesignSpec]:
    """The run config and the design section of a parsed mapping."""
    raw = dict(raw)
    section = raw.pop("design", None)
    if section is None:
        raise ConfigError(
            "a design config needs a 'design:' section (e.g. design: {objective: tau, budget: 78}); "
            "see docs/design.md"
        )
    if not isinstance(section, dict):
        raise ConfigError(f"'design' must be a mapping, got {section!r}")
    unknown_keys(section, _KEYS, "design.")
    config = config_from_mapping(raw, source)
    spec = _spec(section)
    check_designable(config)
    output = spec.output or str(Path(config.output).with_name(Path(config.output).stem + "_design.h5"))
    if not output.endswith((".h5", ".hdf5")):
        raise ConfigError(f"design.output must be an HDF5 path ending in .h5, got {output!r}")
    return config, DesignSpec(**{**spec.__dict__, "output": output})


def _spec(section: dict) -> DesignSpec:
    objective = section.get("objective", "tau")
    choice("design.objective", objective, OBJECTIVES)
    start = section.get("start", "best")
    choice("design.start", start, STARTS)
    budget = section.get("budget")
    if budget is not None:
        budget = parse_number("design.budget", budget)
        if budget <= 0:
            raise ConfigError(
                f"design.budget must be a positive number (the total weight to spend), got {budget:g}"
            )
    lower = parse_number("design.lower", section.get("lower", 0.0))
    if lower < 0:
        raise ConfigError(f"design.lower must be >= 0 (0 lets a link be removed), got {lower:g}")
    upper = section.get("upper")
    upper = math.inf if upper is None else parse_number("design.upper", upper)
    if upper < lower:
        raise ConfigError(f"design.upper ({upper:g}) must be >= design.lower ({lower:g})")
    cost = parse_number("design.candidate_cost", section.get("candidate_cost", 1.0))
    if cost <= 0:
        raise ConfigError(f"design.candidate_cost must be positive, got {cost:g}")
    candidates = section.get("candidates") or []
    if not isinstance(candidates, list):
        raise ConfigError(f'design.candidates must be a list such as ["0-9", "3-20"], got {candidates!r}')
    settings = {}
    ints = {
        "iterations": (1, 10**6),
        "starts": (2, 10**7),
        "check_every": (1, 10**6),
        "check_starts": (2, 10**8),
        "patience": (1, 1000),
        "evaluate": (2, 10**9),
    }
    for key, (lo, hi) in ints.items():
        if key in section:
            settings[key] = parse_integer(f"design.{key}", section[key], lo, hi, f"{lo}..{hi}")
    for key in ("step", "z"):
        if key in section:
            value = parse_number(f"design.{key}", section[key])
            if value <= 0:
                raise ConfigError(f"design.{key} must be positive, got {value:g}")
            settings[key] = value
    output = section.get("output") or ""
    if not isinstance(output, str):
        raise ConfigError(
            f"design.output must be a file path such as results/karate_design.h5, got {output!r}"
        )
    return DesignSpec(
        objective=objective,
        budget=budget,
        lower=lower,
        upper=upper,
        candidates=tuple(candidates),
        candidate_cost=cost,
        start=start,
        settings=Settings(**settings),
        output=output,
    )
