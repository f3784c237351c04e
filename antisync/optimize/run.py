"""``antisync design CONFIG``: a design from its config to its file, resumable.

The order: the problem (:func:`antisync.optimize.ensemble.make_problem`), the baselines (the
uniform weights, the exact spectral designs of :mod:`antisync.optimize.spectral`, the graph's own
weights when the budget set holds them), the descent from ``design.start``
(:mod:`antisync.optimize.descent`, objective ``tau`` only; the spectral objectives *are* their
baseline), the intact network's per-link Lambda, and the paired comparison of every design on
fresh starts. The file (:mod:`antisync.store.design_file`) is rewritten after every iteration.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml
from tqdm.auto import tqdm

from antisync.errors import StoreError
from antisync.optimize import spectral
from antisync.optimize.config import DesignSpec
from antisync.optimize.descent import State, run_descent, stream_seed, verify
from antisync.optimize.ensemble import Problem, evaluate, sample
from antisync.plan.config import Config
from antisync.status import SYNCED
from antisync.store.design_file import check_design_target, read_design, write_design
from antisync.store.lock import writer_lock
from antisync.store.outputs import config_inputs

__all__ = ["baselines", "run_design", "sensitivity"]


def baselines(problem: Problem) -> dict[str, np.ndarray]:
    """The designs every result is compared with, by name: ``uniform`` (the feasible point
    nearest equal weights), ``lambda2`` (lambda_2 of the Laplacian the dynamics couple through,
    maximized: for raw coupling the weighted Laplacian's exact maximum, certified; for normalized
    coupling the best point of a projected ascent with a continuation on the lower bounds,
    :func:`antisync.optimize.spectral.design_normalized_lambda2`, not certified),
    ``resistance`` (the minimum total effective resistance of the weighted Laplacian) and
    ``graph`` (the graph's own weights, when they are in the budget set)."""
    n, links, budget = problem.n_nodes, problem.links, problem.budget
    out = {"uniform": budget.uniform()}
    if problem.coupling_kind == "normalized":
        out["lambda2"] = spectral.design_normalized_lambda2(n, links, budget).x
    else:
        out["lambda2"] = spectral.design_lambda2(n, links, budget).x
    out["resistance"] = spectral.design_resistance(n, links, budget).x
    if budget.contains(problem.start):
        out["graph"] = problem.start.copy()
    return out


def sensitivity(problem: Problem, starts: int, threads: int | None = None) -> dict:
    """Each existing link's Lambda at the graph's own weights, undirected (both directions
    damaged together): per start ``Lambda = x_l (d tau / d x_l) / tau`` (``F = tau0 / tau(beta)``
    with ``x_l -> (1 - beta) x_l``), averaged over the synchronized starts of the ``lambda``
    stream; positive: damage makes the network synchronize faster (antifragile)."""
    ks = np.arange(starts, dtype=np.uint64)
    s = sample(problem, problem.start, stream_seed(problem.config.seed, "lambda"), ks, threads)
    ok = s.status == SYNCED
    per = problem.start[None, :] * s.grad[ok] / s.tau[ok][:, None]
    m = int(ok.sum())
    lam = per.mean(axis=0) if m else np.full(len(problem.links), np.nan)
    se = per.std(axis=0, ddof=1) / math.sqrt(m) if m > 1 else np.full(len(problem.links), np.nan)
    return {"lambda": lam, "lambda_se": se, "starts": np.array([m], dtype=float)}


def run_design(
    config: Config,
    spec: DesignSpec,
    *,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool | None = None,
    threads: int | None = None,
    log: Callable[[str], None] = print,
) -> Path:
    """Run the design of ``config`` and ``spec`` into ``spec.output``; return its path."""
    path = Path(spec.output)
    problem = spec.problem(config)  # its refusals (candidates, bounds) before the file's
    check_design_target(path, resume=resume, overwrite=overwrite, protect=config_inputs(config))
    with writer_lock(path):
        return _run(config, spec, problem, path, resume, progress, threads, log)


def _run(config, spec, problem, path, resume, progress, threads, log) -> Path:
    settings = spec.settings
    config_text = config.to_yaml()
    record = {
        "config": config_text,
        "design": spec.to_dict(),
        "problem": {
            "links": problem.links,
            "labels": list(problem.labels),
            "start": problem.start,
            "cost": problem.budget.cost,
            "lower": problem.budget.lo,
            "upper": problem.budget.hi,
            "candidate": problem.candidate.astype(np.int8),
            "budget": problem.budget.total,
        },
        "iterations": [],
        "checks": [],
    }
    if resume and path.exists():
        old = read_design(path)
        if _work(old["config"]) != _work(config_text) or old["design"] != json.loads(
            json.dumps(spec.to_dict())
        ):
            raise StoreError(
                f"{path} was written by a different design config; --resume continues only the "
                "same config (use --overwrite to start again, or another design.output)"
            )
        if old["complete"]:
            log(f"{path} is complete ({old['reason']}); nothing to do")
            return path
        record.update({k: old[k] for k in ("iterations", "checks", "baselines") if k in old})
        state = _state_of(old.get("state"))
        log(f"resuming {path} at iteration {state.iteration if state else 0}")
    else:
        state = None
    if "baselines" not in record:
        log("spectral baselines (uniform, lambda2, resistance) ...")
        record["baselines"] = baselines(problem)
    # the baselines in the order they are made (a file read back lists them alphabetically)
    made = ("uniform", "lambda2", "resistance", "graph")
    base = record["baselines"]
    base = {k: base[k] for k in sorted(base, key=lambda k: made.index(k) if k in made else len(made))}
    if spec.objective == "tau":
        if state is None:
            if spec.start == "graph" and not problem.budget.contains(problem.start):
                raise StoreError(
                    "design.start graph: the graph's own weights are outside the budget set "
                    "(budget or bounds); start from uniform, lambda2 or resistance"
                )
            first = spec.start
            if first == "best":
                first = _best_start(problem, base, settings, threads, log)
            state = State.first(problem.start if first == "graph" else base[first], settings)
        state = _descend(problem, state, settings, record, path, progress, threads)
        designed = state.best
        record["reason"] = state.reason
    else:
        designed = base[spec.objective]
        record["reason"] = f"exact {spec.objective} design (no descent)"
    record["baselines"] = {"designed": designed, **{k: v for k, v in base.items() if k != "designed"}}
    log(f"Lambda of every link at the graph's own weights ({settings.starts * 4} starts) ...")
    record["sensitivity"] = sensitivity(problem, settings.starts * 4, threads)
    log(f"paired comparison on {settings.evaluate} fresh starts ...")
    record["verification"] = verify(problem, record["baselines"], settings, threads)
    record["complete"] = True
    write_design(path, record)
    return path


def _best_start(problem, base: dict, settings, threads, log) -> str:
    """``design.start: best``: the baseline with the smallest mean tau on ``check_starts``
    starts of the validation stream (the one the descent's checks use; the final comparison's
    fresh starts are another), so that a poor baseline cannot trap the descent."""
    names = list(base)
    ks = np.arange(settings.check_starts, dtype=np.uint64)
    seed = stream_seed(problem.config.seed, "validation")
    tau, _ = evaluate(problem, [base[k] for k in names], seed, ks, threads)
    means = tau.mean(axis=1)
    pick = names[int(np.argmin(means))]
    shown = ", ".join(f"{k} {m:.4g}" for k, m in zip(names, means, strict=True))
    log(f"design.start best: {pick} (mean tau on {ks.size} validation starts: {shown})")
    return pick


#: Config keys that say where a design runs, not what it computes: a resume may change them.
WHERE_KEYS = ("threads", "executor", "backend")


def _work(config_text: str) -> dict:
    """A design's stored config without :data:`WHERE_KEYS`: what a ``--resume`` compares."""
    d = yaml.safe_load(config_text)
    return {k: v for k, v in d.items() if k not in WHERE_KEYS} if isinstance(d, dict) else {"config": d}


def _state_of(stored: dict | None) -> State | None:
    if stored is None:
        return None
    return State(
        iteration=stored["iteration"],
        x=np.asarray(stored["x"], dtype=float),
        best=np.asarray(stored["best"], dtype=float),
        step=stored["step"],
        stall=stored["stall"],
        period_sum=np.asarray(stored["period_sum"], dtype=float),
        period_count=stored["period_count"],
        velocity=np.asarray(stored["velocity"], dtype=float),
        done=stored["done"],
        reason=stored["reason"],
    )


def _state_dict(state: State) -> dict:
    return {
        "x": state.x,
        "best": state.best,
        "period_sum": state.period_sum,
        "velocity": state.velocity,
        "iteration": state.iteration,
        "step": state.step,
        "stall": state.stall,
        "period_count": state.period_count,
        "done": state.done,
        "reason": state.reason,
    }


def _descend(problem, state, settings, record, path, progress, threads) -> State:
    bar = tqdm(
        total=settings.iterations,
        initial=state.iteration,
        desc="design",
        unit="it",
        disable=progress is False,
        leave=False,
    )

    def save(new: State, row: dict, check: dict | None) -> None:
        record["iterations"].append(row)
        if check is not None:
            record["checks"].append(check)
        record["state"] = _state_dict(new)
        write_design(path, record)

    def show(new: State, row: dict) -> None:
        bar.update(1)
        bar.set_postfix_str(f"<tau> {row['tau']:.4g} +- {row['tau_se']:.2g}, step {new.step:.3g}")

    try:
        return run_descent(problem, state, settings, save=save, threads=threads, progress=show)
    finally:
        bar.close()
