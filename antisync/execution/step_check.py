"""The step check of an explicit integrator: is ``dynamics.dt`` accurate, not only stable?

A step inside Euler's or RK4's stability bound can still be too coarse for the numbers: RK4 at
IEEE 39's former ``dt = 0.0025`` damped its load buses' fastest mode by 0.75 a step instead of
0.075, moved 12 of 375 synchronization times by 0.1 to 1.3 s and locked one start of 400 that
locks at no smaller step (bench/RESULTS.md, "IEEE 39's step"). So a run of a generalized model
or a law (``antisync run``, a sweep's points) and every dynamic line removal integrate the first
:data:`STEP_CHECK_STARTS` realizations of the undamaged network again at ``dt / 2`` and compare
(:func:`check_step_accuracy`): a start that changes status, or whose time moves by more than
:data:`STEP_CHECK_SHARE` of the sample's median, depends on the step, unless it moves again
between ``dt / 2`` and ``dt / 4``: then its criterion grazes its threshold and its time jumps
from step to step, ill-conditioned rather than inaccurate. The check reports (a note, or a
warning, and the record a removal table keeps); it does not refuse. Nor does it prove a step
accurate: 64 starts do not bound a rare inaccuracy, and two coarse steps can agree and both be
off (IEEE 118's start 14 has the same time at 0.0025 and 0.00125 and another, 1.9 s away, at
0.000625 and 0.0003125: its check passes at 0.0025 and fails at 0.00125). Eq. 2's identical
oscillators are not checked: their step is part of the paper's definition of tau.

Rodas4's steps follow ``rtol`` and ``atol``, and a tolerance can be as coarse as a step: on
ACTIVSg2000 (frequency locking to 1e-3) ``rtol = atol = 1e-4`` locked starts 1.4 to 2.8 s (5-11%)
before the converged time, its error damping the generators' swings (bench/RESULTS.md, "Rodas4's
tolerance"). So a Rodas4 run is checked the same way with both tolerances divided by
:data:`TOLERANCE_REFINE` in place of the step halved (:func:`check_tolerance_accuracy`).
"""

from __future__ import annotations

import numpy as np

from antisync.status import SYNCED

__all__ = [
    "STEP_CHECK_SHARE",
    "STEP_CHECK_STARTS",
    "MAX_STEP_NOTES",
    "TOLERANCE_REFINE",
    "check_step_accuracy",
    "check_tolerance_accuracy",
    "job_step_check",
    "step_check_line",
    "step_check_notes",
    "step_record",
]

#: realizations of the undamaged network integrated again at ``dt / 2``
STEP_CHECK_STARTS = 64
#: a time that moves by more than this share of the sample's median time depends on the step
STEP_CHECK_SHARE = 0.01
#: Rodas4's check divides ``rtol`` and ``atol`` by this (its error is about proportional to them)
TOLERANCE_REFINE = 10.0


def step_record(dt: float, status, times, status_half, times_half) -> dict:
    """The check's record from the same starts at ``dt`` and at ``dt / 2`` (statuses, and times
    in the model's units, NaN where not SYNCED): ``starts``, ``dt``, ``changed`` (statuses that
    differ) and the first start that did, ``jumped`` (times moved by more than
    :data:`STEP_CHECK_SHARE` of the median at ``dt / 2``), the largest change and its start,
    the median, ``share`` and ``passed`` (none changed, none jumped; :func:`check_step_accuracy`
    then forgives the starts that graze)."""
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
        "grazing": 0,
        "passed": not (changed.size or jumped),
    }


def _flagged(status, times, status_half, times_half, limit) -> np.ndarray:
    """The starts whose status differs, or whose times differ by more than ``limit``."""
    moved = np.abs(np.asarray(times) - np.asarray(times_half))
    both = (np.asarray(status) == SYNCED) & (np.asarray(status_half) == SYNCED)
    return (np.asarray(status) != np.asarray(status_half)) | (both & (moved > limit))


def _move(status, times, status_other, times_other) -> np.ndarray:
    """Each start's change of time between two settings (inf where its status changed)."""
    same = np.asarray(status) == np.asarray(status_other)
    moved = np.abs(np.asarray(times, dtype=float) - np.asarray(times_other, dtype=float))
    return np.where(same, np.nan_to_num(moved, nan=0.0), np.inf)


def check_step_accuracy(run_at, dt: float, ks: np.ndarray) -> dict:
    """The step check of ``run_at(dt, ks) -> (status, times)`` on the starts ``ks``: the
    :func:`step_record` of ``dt`` against ``dt / 2``; the starts it flags are integrated once more
    at ``dt / 4``. A flagged start that agrees at ``dt / 2`` and ``dt / 4`` was the coarse step's
    error (the check fails); one that moves again grazes its threshold, its time ill-conditioned
    at any step, and is counted in ``grazing`` without failing the check."""
    return _refined(lambda level, starts: run_at(dt / 2**level, starts), ks, dt)


def check_tolerance_accuracy(run_at, dt: float, rtol: float, atol: float, ks: np.ndarray) -> dict | None:
    """Rodas4's check, :func:`check_step_accuracy` with ``run_at(rtol, atol, ks) -> (status,
    times)`` at the given tolerances against both divided by :data:`TOLERANCE_REFINE` (and once
    more for the starts it flags); the record holds ``rtol``, ``atol`` and ``refine`` too (``dt``:
    the first step, the unit of the times). None when the finer tolerances would pass the
    floor float64 steps allow (:data:`~antisync.plan.config.MIN_TOLERANCE`): nothing to compare."""
    from antisync.plan.config import MIN_TOLERANCE

    if min(rtol, atol) / TOLERANCE_REFINE**2 < MIN_TOLERANCE:
        return None
    record = _refined(
        lambda level, starts: run_at(rtol / TOLERANCE_REFINE**level, atol / TOLERANCE_REFINE**level, starts),
        ks,
        dt,
    )
    return {**record, "rtol": float(rtol), "atol": float(atol), "refine": TOLERANCE_REFINE}


def _refined(run, ks: np.ndarray, dt: float) -> dict:
    """The check's logic: ``run(level, ks)`` at levels 0 (as configured), 1 (refined once) and,
    for the starts level 1 flags, 2."""
    status, times = run(0, ks)
    status_half, times_half = run(1, ks)
    record = step_record(dt, status, times, status_half, times_half)
    if record["passed"]:
        return record
    limit = STEP_CHECK_SHARE * (record["median_tau0"] or 0.0)
    picked = np.flatnonzero(_flagged(status, times, status_half, times_half, limit))
    status_quarter, times_quarter = run(2, ks[picked])
    again = _flagged(status_half[picked], times_half[picked], status_quarter, times_quarter, limit)
    # grazing: it moves again by at least half as much; a move that shrinks as the setting is
    # refined (by 16 for RK4 at dt / 2, by ~10 for Rodas4 at tol / 10) is converging, the
    # coarse setting's error
    first = _move(status[picked], times[picked], status_half[picked], times_half[picked])
    second = _move(status_half[picked], times_half[picked], status_quarter, times_quarter)
    again &= second >= 0.5 * first
    record["grazing"] = int(again.sum())
    record["passed"] = bool(again.all())
    return record


def step_check_line(check: dict) -> str:
    """One line on a :func:`step_record` (a step's, or Rodas4's tolerances')."""
    # a trip table's check (antisync.grids.trip_check) names its trips by line
    unit, time = check.get("unit", "starts"), check.get("time", "tau0")
    labels = check.get("lines")

    def which(k):
        return f"line {labels[k]}" if labels else f"start {k}"

    word = "verdict" if labels else "status"
    moved = f"{check['changed']} changed {word}" + (
        f" (first: {which(check['first_changed'])})" if check["changed"] else ""
    )
    if "rtol" in check:
        k = check["refine"]
        finer = f"rtol = {check['rtol'] / k:g}, atol = {check['atol'] / k:g}"
        text = f"tolerances checked: the first {check['starts']} {unit} again at {finer}: {moved}"
        again = f"rtol and atol / {k * k:g}"
        fix = f"dynamics.rtol = {check['rtol'] / k:g}, dynamics.atol = {check['atol'] / k:g}"
        depend = "the tolerances"
    else:
        half = check["dt"] / 2
        text = f"step checked: the first {check['starts']} {unit} again at dt / 2 = {half:g}: {moved}"
        again, fix, depend = "dt / 4", f"dynamics.dt = {half:g}", "the step"
    if check["worst"] is not None:
        text += (
            f", {check.get('jumped', 0)} moved by more than {check.get('share', STEP_CHECK_SHARE):.0%} of "
            f"the median {time}, the largest by {check['largest_dtau']:.2g} ({which(check['worst'])})"
        )
    grazing = check.get("grazing", 0)
    if grazing:
        text += (
            f"; {grazing} of these moved again at {again} (a criterion that grazes its threshold: "
            f"that time is ill-conditioned at any step, not {depend}' error)"
        )
    if check.get("passed", True):
        return text
    return text + f": these numbers depend on {depend}; run again at {fix}"


#: jobs whose passing step checks are each said in a line (more: one line for all of them)
MAX_STEP_NOTES = 4


def step_check_notes(checked: dict[str, dict]) -> list[str]:
    """The lines a run (and ``antisync summary`` of its file) says of its jobs' step checks
    (``{job: record}``): a WARNING for each that failed, a note for each that passed, or one
    line for all that passed when more than :data:`MAX_STEP_NOTES` jobs were checked."""
    lines = [
        f"{'note' if c['passed'] else 'WARNING'}: {name}: {step_check_line(c)}"
        for name, c in checked.items()
        if not c["passed"] or len(checked) <= MAX_STEP_NOTES
    ]
    passed = sum(c["passed"] for c in checked.values())
    if len(checked) > MAX_STEP_NOTES and passed:
        lines.append(
            f"note: the explicit step checked again at dt / 2 on {len(checked)} jobs: {passed} passed"
        )
    return lines


def job_step_check(job, threads: int | None = None) -> dict | None:
    """:func:`step_record` of ``job``'s undamaged network (its first :data:`STEP_CHECK_STARTS`
    realizations at ``dt`` and ``dt / 2``, or Rodas4's at its tolerances and ten times finer, by
    the job's own driver); None where the check does not apply (module docstring)."""
    from antisync.execution.dispatch import base_network_times, model_kind

    dyn = job.config.dynamics
    if not job.kuramoto or model_kind(job.config) == "identical":
        return None
    ks = np.arange(min(STEP_CHECK_STARTS, job.config.realizations), dtype=np.int64)
    if dyn.integrator == "rodas4":
        rtol, atol = dyn.tolerances

        def at_tolerances(r, a, starts):
            return base_network_times(job, starts, dyn.dt, dyn.max_steps, threads, tolerances=(r, a))

        return check_tolerance_accuracy(at_tolerances, dyn.dt, rtol, atol, ks)

    def run_at(dt, starts):
        return base_network_times(job, starts, dt, round(dyn.max_steps * dyn.dt / dt), threads)

    return check_step_accuracy(run_at, dyn.dt, ks)
