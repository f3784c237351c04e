"""The step check of an explicit integrator: is ``dynamics.dt`` accurate, not only stable?

A step inside Euler's or RK4's stability bound can still be too coarse for the numbers: RK4 at
IEEE 39's former ``dt = 0.0025`` damped its load buses' fastest mode by 0.75 a step instead of
0.075, moved 12 of 375 synchronization times by 0.1 to 1.3 s and locked one start of 400 that
locks at no smaller step (bench/RESULTS.md, "IEEE 39's step"). So a run of a generalized model
or a law (``antisync run``, a sweep's points) and every dynamic line removal integrate the first
:data:`STEP_CHECK_STARTS` realizations of the undamaged network again at ``dt / 2`` and compare
(:func:`step_record`): a start that changes status, or whose time moves by more than
:data:`STEP_CHECK_SHARE` of the sample's median, depends on the step. The check reports (a
note, or a warning, and the record a removal table keeps); it does not refuse, because a start
whose criterion only grazes its threshold can jump at any step, and 64 starts do not bound a
rare one. Rodas4 has no such check (its steps follow ``rtol``), nor do Eq. 2's identical
oscillators, whose step is part of the paper's definition of tau.
"""

from __future__ import annotations

import numpy as np

from antisync.status import SYNCED

__all__ = ["STEP_CHECK_SHARE", "STEP_CHECK_STARTS", "job_step_check", "step_check_line", "step_record"]

#: realizations of the undamaged network integrated again at ``dt / 2``
STEP_CHECK_STARTS = 64
#: a time that moves by more than this share of the sample's median time depends on the step
STEP_CHECK_SHARE = 0.01


def step_record(dt: float, status, times, status_half, times_half) -> dict:
    """The check's record from the same starts at ``dt`` and at ``dt / 2`` (statuses, and times
    in the model's units, NaN where not SYNCED): ``starts``, ``dt``, ``changed`` (statuses that
    differ) and the first start that did, ``jumped`` (times moved by more than
    :data:`STEP_CHECK_SHARE` of the median at ``dt / 2``), the largest change and its start,
    the median, ``share`` and ``passed`` (none changed, none jumped)."""
    status, status_half = np.asarray(status), np.asarray(status_half)
    changed = np.flatnonzero(status != status_half)
    both = (status == SYNCED) & (status_half == SYNCED)
    moved = np.where(both, np.abs(np.asarray(times) - np.asarray(times_half)), -1.0)
    median = float(np.median(np.asarray(times_half)[both])) if both.any() else None
    jumped = int((moved > STEP_CHECK_SHARE * median).sum()) if both.any() else 0
    worst = int(np.argmax(moved)) if both.any() else None
    return {
        "starts": int(status.size),
        "dt": float(dt),
        "changed": int(changed.size),
        "first_changed": int(changed[0]) if changed.size else None,
        "jumped": jumped,
        "largest_dtau": float(moved[worst]) if both.any() else 0.0,
        "worst": worst,
        "median_tau0": median,
        "share": STEP_CHECK_SHARE,
        "passed": not (changed.size or jumped),
    }


def step_check_line(check: dict) -> str:
    """One line on a :func:`step_record`."""
    half = check["dt"] / 2
    moved = f"{check['changed']} changed status" + (
        f" (first: start {check['first_changed']})" if check["changed"] else ""
    )
    text = f"step checked: the first {check['starts']} starts again at dt / 2 = {half:g}: {moved}"
    if check["worst"] is not None:
        text += (
            f", {check.get('jumped', 0)} moved by more than {check.get('share', STEP_CHECK_SHARE):.0%} of "
            f"the median tau0, the largest by {check['largest_dtau']:.2g} (start {check['worst']})"
        )
    if check.get("passed", True):
        return text
    return text + f": these numbers depend on the step; run again at dynamics.dt = {half:g}"


def job_step_check(job, threads: int | None = None) -> dict | None:
    """:func:`step_record` of ``job``'s undamaged network (its first :data:`STEP_CHECK_STARTS`
    realizations at ``dt`` and ``dt / 2``, by the job's own driver); None where the check does not
    apply (module docstring)."""
    from antisync.execution.dispatch import base_network_times, model_kind

    dyn = job.config.dynamics
    if not job.kuramoto or model_kind(job.config) == "identical" or dyn.integrator not in ("euler", "rk4"):
        return None
    ks = np.arange(min(STEP_CHECK_STARTS, job.config.realizations), dtype=np.int64)
    runs = [base_network_times(job, ks, dyn.dt / split, dyn.max_steps * split, threads) for split in (1, 2)]
    return step_record(dyn.dt, runs[0][0], runs[0][1], runs[1][0], runs[1][1])
