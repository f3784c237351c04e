"""Stochastic projected descent of the mean synchronization time, with its own stopping rule.

Every iteration draws ``starts`` fresh training starts (seed stream ``train``: iteration ``t``
takes realizations ``t m .. (t + 1) m - 1``), estimates ``g = E[d tau / d x]`` on them
(:func:`antisync.optimize.ensemble.sample`: one adjoint pass per start, all links at once) and
takes a projected step

    v <- MOMENTUM v + (1 - MOMENTUM) g,     x <- P(x - s_t * mean(x) * v / rms(v))

onto the budget set (:func:`antisync.optimize.budget.project`): the step is a fraction ``s_t``
of the mean weight, so it reads the same at any budget and any unit of time. Per start the
derivatives are heavy-tailed even after the hybrid's secants (karate club at its
lambda2-optimal weights: 5 of 78 link means resolved at 40,000 starts), so the direction is
the moving average ``v`` of the iterations' gradients (about ``1 / (1 - MOMENTUM)`` iterations'
starts): with small steps the gradient changes slowly, and the average resolves what one
iteration's starts cannot. Every
``check_every`` iterations the average of the period's iterates (a convex combination, so
feasible; Polyak averaging removes most of the steps' noise) is compared with the best design so
far on ``check_starts`` validation starts (seed stream ``validation``, the same starts at every
check: a paired comparison). The candidate replaces the best only when the improvement is
*resolved* (mean paired difference below zero by more than ``z`` standard errors); otherwise the
step halves and the descent goes on from the best design. After ``patience`` checks in a row
without a resolved improvement the design stops: what is left is smaller than the validation
sample can see.

The final comparison (:func:`verify`) runs the best design and the baselines on ``evaluate``
fresh starts of a third stream, ``fresh``, that neither the descent nor its checks used: the
differences of mean times, paired on common starts, with 95% intervals.

The whole state of the loop is a few arrays (:class:`State`), written after every iteration
(:mod:`antisync.store.design_file`), so a killed design resumes at the next iteration and
continues with exactly the iterates the uninterrupted run would have made.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from antisync.optimize.budget import project
from antisync.optimize.ensemble import Problem, evaluate, sample

__all__ = ["Settings", "State", "step", "stream_seed", "verify"]

STREAMS = ("train", "validation", "fresh", "lambda")

MOMENTUM = 0.9
"""Weight of the past in the moving average of the gradient (the step's direction)."""


def stream_seed(seed: int, stream: str) -> int:
    """The seed of one of a design's independent streams of starts (:data:`STREAMS`): ``train``
    is the config's own seed; the others are derived from it (never equal to it)."""
    if stream == "train":
        return int(seed)
    state = np.random.SeedSequence(int(seed), spawn_key=(STREAMS.index(stream),)).generate_state(2)
    return int((int(state[0]) << 31 ^ int(state[1])) & (2**63 - 1))


@dataclass(frozen=True)
class Settings:
    """The descent's settings (``design:`` keys of the same names)."""

    iterations: int = 200
    """At most this many iterations."""
    starts: int = 256
    """Training starts per iteration."""
    step: float = 0.02
    """First step, as a fraction of the mean weight."""
    check_every: int = 10
    """Iterations per check."""
    check_starts: int = 2000
    """Validation starts of every check (the same at every check)."""
    patience: int = 3
    """Checks in a row without a resolved improvement before the design stops."""
    z: float = 2.0
    """An improvement is resolved when it exceeds ``z`` standard errors."""
    evaluate: int = 20000
    """Fresh starts of the final comparison."""


@dataclass
class State:
    """Everything the next iteration needs; stored after each iteration."""

    iteration: int
    x: np.ndarray
    best: np.ndarray
    step: float
    stall: int = 0
    period_sum: np.ndarray = field(default_factory=lambda: np.zeros(0))
    period_count: int = 0
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(0))
    done: bool = False
    reason: str = ""

    @classmethod
    def first(cls, x0: np.ndarray, settings: Settings) -> State:
        x0 = np.asarray(x0, dtype=float)
        return cls(
            0, x0.copy(), x0.copy(), settings.step, period_sum=np.zeros_like(x0), velocity=np.zeros_like(x0)
        )


def step(
    problem: Problem, state: State, settings: Settings, threads: int | None = None
) -> tuple[State, dict, dict | None]:
    """One iteration from ``state``: the new state, the iteration's record and, at a check,
    the check's record (``None`` otherwise)."""
    seed = problem.config.seed
    m = settings.starts
    t0 = time.perf_counter()
    ks = np.arange(state.iteration * m, (state.iteration + 1) * m, dtype=np.uint64)
    s = sample(problem, state.x, stream_seed(seed, "train"), ks, threads)
    g = s.grad.mean(axis=0)
    g_se = s.grad.std(axis=0, ddof=1) / math.sqrt(m) if m > 1 else np.full_like(g, np.nan)
    record = {
        "x": state.x.copy(),
        "tau": float(s.tau.mean()),
        "tau_se": float(s.tau.std(ddof=1) / math.sqrt(m)) if m > 1 else math.nan,
        "censored": float(np.mean(s.status == 2)),
        "grad": g,
        "grad_se": g_se,
        "step": state.step,
    }
    velocity = MOMENTUM * state.velocity + (1 - MOMENTUM) * g
    rms = float(np.sqrt(np.mean(velocity**2)))
    scale = float(np.mean(state.x)) if np.mean(state.x) > 0 else problem.budget.total / len(state.x)
    x = state.x if rms == 0 else project(state.x - state.step * scale * velocity / rms, problem.budget)
    new = replace(
        state,
        iteration=state.iteration + 1,
        x=x,
        velocity=velocity,
        period_sum=state.period_sum + x,
        period_count=state.period_count + 1,
    )
    check = None
    if new.iteration % settings.check_every == 0 or new.iteration >= settings.iterations:
        new, check = _check(problem, new, settings, threads)
    record["seconds"] = time.perf_counter() - t0
    return new, record, check


def _check(problem: Problem, state: State, settings: Settings, threads) -> tuple[State, dict]:
    """Compare the period's average with the best design on the validation starts."""
    candidate = project(state.period_sum / state.period_count, problem.budget)
    ks = np.arange(settings.check_starts, dtype=np.uint64)
    tau, _ = evaluate(
        problem, [candidate, state.best], stream_seed(problem.config.seed, "validation"), ks, threads
    )
    diff = tau[0] - tau[1]
    mean = float(diff.mean())
    se = float(diff.std(ddof=1) / math.sqrt(diff.size))
    resolved = mean < -settings.z * se
    check = {
        "iteration": state.iteration,
        "candidate_tau": float(tau[0].mean()),
        "best_tau": float(tau[1].mean()),
        "diff": mean,
        "diff_se": se,
        "accepted": resolved,
    }
    if resolved:
        state = replace(state, best=candidate, x=candidate, stall=0)
    else:
        state = replace(state, x=state.best.copy(), step=state.step / 2, stall=state.stall + 1)
    state = replace(state, period_sum=np.zeros_like(state.x), period_count=0)
    if state.stall >= settings.patience:
        state = replace(
            state, done=True, reason=f"{settings.patience} checks in a row without a resolved improvement"
        )
    elif state.iteration >= settings.iterations:
        state = replace(state, done=True, reason=f"reached design.iterations = {settings.iterations}")
    return state, check


def run_descent(
    problem: Problem,
    state: State,
    settings: Settings,
    *,
    save: Callable[[State, dict, dict | None], None],
    threads: int | None = None,
    progress: Callable[[State, dict], None] | None = None,
) -> State:
    """Iterate :func:`step` until the state is done, calling ``save`` after every iteration."""
    while not state.done:
        state, record, check = step(problem, state, settings, threads)
        save(state, record, check)
        if progress is not None:
            progress(state, record)
    return state


def verify(
    problem: Problem, designs: dict[str, np.ndarray], settings: Settings, threads: int | None = None
) -> dict:
    """Every design of ``designs`` (name -> weights; the first is the reference, the designed
    one) on ``settings.evaluate`` fresh starts, paired: mean times with standard errors, the
    synchronized fractions, and each other design's difference to the first with a 95% interval
    (normal: a mean of 10^4 paired differences of bounded times)."""
    names = list(designs)
    ks = np.arange(settings.evaluate, dtype=np.uint64)
    tau, status = evaluate(
        problem, [designs[k] for k in names], stream_seed(problem.config.seed, "fresh"), ks, threads
    )
    m = tau.shape[1]
    out = {"names": names, "tau": tau, "status": status, "rows": []}
    for i, name in enumerate(names):
        diff = tau[i] - tau[0]
        se = float(diff.std(ddof=1) / math.sqrt(m)) if i else 0.0
        out["rows"].append(
            {
                "design": name,
                "mean_tau": float(tau[i].mean()),
                "se": float(tau[i].std(ddof=1) / math.sqrt(m)),
                "synced": float(np.mean(status[i] == 0)),
                "minus_designed": float(diff.mean()),
                "low": float(diff.mean() - 1.96 * se),
                "high": float(diff.mean() + 1.96 * se),
            }
        )
    return out
