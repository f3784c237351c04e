"""The trip table's accuracy check: are its settle times and critical clearing times the
integrator's setting's, or the grid's?

A removal and a run check their step (or Rodas4's tolerances) on the intact grid's first starts
(:mod:`antisync.execution.step_check`). A trip table's numbers are other ones: the time each
trip takes to settle, whether it settles at all, and with ``--cct`` the boundary between the
last fault survived and the first one not. So every trip table integrates its first
:data:`TRIP_CHECK_TRIPS` trips again at a finer setting (RK4: ``dt / 2``; Rodas4: ``rtol`` and
``atol`` divided by :data:`~antisync.execution.step_check.TOLERANCE_REFINE`) and compares:

- **the settling**, by the step check's own rule (:func:`check_step_accuracy`,
  :func:`check_tolerance_accuracy`): a trip whose verdict changes, or whose settle time moves
  by more than :data:`~antisync.execution.step_check.STEP_CHECK_SHARE` of the sample's median,
  depends on the setting, unless it moves again at the next finer one (a criterion that grazes
  its band: ill-conditioned at any setting);
- **the first swing**: each trip's frequency peak and largest angle must move by at most
  :data:`PEAK_SHARE` (relative);
- **the CCT's boundary** (with ``--cct``), on the four lines with the shortest CCTs below
  ``--cct-max`` (:func:`boundary_sample`): the fault of the CCT must still be survived and the
  first failing fault of the scan must still fail. Where a verdict changes, the same faults are
  integrated once more at the next finer setting; a change that holds there moves the CCT by at
  least one step of its scan, and the check fails (one that flips back grazes the boundary).

The check reports; it refuses nothing. Its record is the table's ``accuracy_check`` (JSON and
HDF5), its line printed under the table, a failure a WARNING. The samples are the table's first
trips in its order and its shortest CCTs, read off the table, so a table on a Dask cluster, a
resumed one and a local one check the same trips and hold the same record. What it cannot do:
prove the other trips accurate, or see a window of failure the scan does not see.
"""

from __future__ import annotations

import math

import numpy as np

from antisync.execution.executors.tasks import map_tasks
from antisync.execution.step_check import (
    TOLERANCE_REFINE,
    check_step_accuracy,
    check_tolerance_accuracy,
    step_check_line,
)
from antisync.grids.errors import GridError
from antisync.status import NOT_SYNCED, SYNCED

__all__ = [
    "PEAK_SHARE",
    "TRIP_CHECK_TRIPS",
    "boundary_sample",
    "check_trips",
    "first_failure",
    "trip_check_line",
]

#: the table's first trips integrated again at the finer setting
TRIP_CHECK_TRIPS = 4
#: a frequency peak or largest angle that moves by more than this share at the finer setting
#: depends on the setting
PEAK_SHARE = 0.01


def first_failure(cct: float, cct_tol: float, cct_scan: float, cct_max: float) -> float | None:
    """The first scanned fault that failed above a CCT found by
    :func:`antisync.grids.trip.critical_clearing`: the fine scan's next point ``cct + cct_tol``
    unless the coarse point above ``cct`` comes first; None where every fault up to ``cct_max``
    was survived."""
    if cct >= cct_max:
        return None
    above = cct_scan * (math.floor(cct / cct_scan + 1e-9) + 1)
    return min(cct + cct_tol, above, cct_max)


def _trip_task(integrate, grid, lines, clear, shares, settings) -> np.ndarray:
    """The rows ``[settle_time, max_frequency, max_angle]`` (settle time ``nan``: it does not
    settle) of ``lines`` after their faults ``clear``: a task here or on a worker."""
    return integrate(grid, lines, clear, shares, **settings)[0]


def _settle_times(integrate, grid, items, settings, client) -> np.ndarray:
    """The settle times of ``items`` ``(line, fault, share)`` (:func:`_trip_rows`)."""
    return _trip_rows(integrate, grid, items, settings, client)[:, 0]


def _trip_rows(integrate, grid, items, settings, client) -> np.ndarray:
    """The rows of ``items`` ``(line, fault, share)``: one batch here (the kernel's threads
    share it), or a task per item on ``client``'s cluster."""
    if not items:
        return np.zeros((0, 3))
    groups = [items] if client is None else [[it] for it in items]
    calls = (
        (
            integrate,
            grid,
            [line for line, _, _ in group],
            np.array([t for _, t, _ in group]),
            np.array([s for _, _, s in group]),
            settings,
        )
        for group in groups
    )
    out = [None] * len(groups)
    for i, rows in map_tasks(_trip_task, calls, client=client):
        out[i] = rows
    return np.concatenate(out)


def _finer(settings: dict, level: int) -> dict:
    """``settings`` refined ``level`` times: RK4's step halved, Rodas4's tolerances divided by
    :data:`TOLERANCE_REFINE`."""
    if settings["integrator"] == "rodas4":
        k = TOLERANCE_REFINE**level
        return {**settings, "rtol": settings["rtol"] / k, "atol": settings["atol"] / k}
    return {**settings, "dt": settings["dt"] / 2**level}


def check_trips(integrate, grid, todo, clear, shares, values, settings, cct: dict | None, client=None):
    """The accuracy check's record of a trip table (module docstring), or None where the finer
    tolerances would pass the float64 floor. ``integrate`` is the table's
    :func:`antisync.grids.trip._integrate`; ``todo``, ``shares`` its trips, ``clear`` their
    fault, ``values`` its rows (:data:`antisync.grids.trip.COLUMNS`), ``settings`` its
    integration, ``cct`` its scan (``cct_max``, ``cct_tol``, ``cct_scan``) or None."""
    n = min(TRIP_CHECK_TRIPS, len(todo))
    if n == 0:
        return {"skipped": "no trip to check", "passed": True}
    sample = np.arange(n)
    finer = {}

    def run(level, picked):
        if level == 0:  # the table's own rows
            times = values[picked, 0]
        else:
            items = [(todo[e], float(clear), float(shares[e])) for e in picked]
            rows = _trip_rows(integrate, grid, items, _finer(settings, level), client)
            finer.setdefault(level, rows)  # level 1 runs on the whole sample, first
            times = rows[:, 0]
        return np.where(np.isfinite(times), SYNCED, NOT_SYNCED), times

    dt = settings["dt"]
    try:
        if settings["integrator"] == "rodas4":
            record = check_tolerance_accuracy(
                lambda r, a, picked: run(round(math.log(settings["rtol"] / r, TOLERANCE_REFINE)), picked),
                dt,
                settings["rtol"],
                settings["atol"],
                sample,
            )
        else:
            record = check_step_accuracy(lambda d, picked: run(round(math.log2(dt / d)), picked), dt, sample)
    except GridError as exc:  # a finer setting the trip refuses (a window of too many steps)
        return {"skipped": str(exc), "passed": True}
    if record is None:
        return None
    record.update(unit="trips", time="settle time", lines=[_label(grid, todo[e]) for e in sample])
    record["settling_passed"] = record["passed"]
    # the first swing: the largest relative change of each trip's frequency peak and angle
    peaks = np.abs(finer[1][:, 1:] - values[:n, 1:3]) / np.maximum(np.abs(finer[1][:, 1:]), 1e-300)
    record["peak_change"] = float(peaks[:, 0].max())
    record["angle_change"] = float(peaks[:, 1].max())
    record["passed"] = bool(record["passed"] and max(peaks.max(), 0.0) <= PEAK_SHARE)
    if cct is not None:
        picked = boundary_sample(values[:, 4], cct["cct_max"])
        lines = [todo[e] for e in picked]
        boundary = _boundary(integrate, grid, lines, shares[picked], values[picked], settings, cct, client)
        record["cct"] = boundary
        record["passed"] = record["passed"] and record["cct"]["passed"]
    return record


def boundary_sample(ccts: np.ndarray, cct_max: float) -> np.ndarray:
    """The trips whose CCT boundary is checked: the :data:`TRIP_CHECK_TRIPS` shortest CCTs
    below ``cct_max`` (where a fault fails: the boundary that matters; ties in table order),
    the table's first trips where there are none."""
    below = np.flatnonzero(ccts < cct_max)
    if below.size == 0:
        return np.arange(min(TRIP_CHECK_TRIPS, ccts.size))
    return below[np.argsort(ccts[below], kind="stable")][:TRIP_CHECK_TRIPS]


def _boundary(integrate, grid, lines, shares, values, settings, cct, client) -> dict:
    """The CCT's boundary of each sampled line at the finer setting: its CCT's fault survived
    (where the CCT is above 0) and its first failing fault failed (where it is below
    ``cct_max``); the changed verdicts once more at the next finer setting."""
    items, want, owner = [], [], []
    for e, (line, share) in enumerate(zip(lines, shares, strict=True)):
        value = float(values[e, 4])
        fail = first_failure(value, cct["cct_tol"], cct["cct_scan"], cct["cct_max"])
        if value > 0:
            items.append((line, value, float(share)))
            want.append(True)
            owner.append(e)
        if fail is not None:
            items.append((line, fail, float(share)))
            want.append(False)
            owner.append(e)
    want = np.array(want, dtype=bool)
    finer = np.isfinite(_settle_times(integrate, grid, items, _finer(settings, 1), client))
    changed = np.flatnonzero(finer != want)
    recheck = [items[i] for i in changed]
    again = np.isfinite(_settle_times(integrate, grid, recheck, _finer(settings, 2), client))
    held = changed[again == finer[changed]]  # the change holds at the next finer setting
    moved = sorted({owner[i] for i in held})
    return {
        "lines": [_label(grid, line) for line in lines],
        "faults": len(items),
        "changed": int(changed.size),
        "moved": len(moved),
        "moved_lines": [_label(grid, lines[e]) for e in moved],
        "grazing": int(changed.size - held.size),
        "passed": not moved,
    }


def _label(grid, line) -> str:
    a, b = line
    return f"{grid.labels[a]}-{grid.labels[b]}"


def trip_check_line(check: dict | None, integrator: str) -> str:
    """One line on a trip table's ``accuracy_check`` (None: not checked, and why)."""
    if check is None:
        return (
            f"Not checked: {integrator}'s tolerances / {TOLERANCE_REFINE**2:g} would pass the float64 "
            "floor (1e-12)"
        )
    if "skipped" in check:
        return f"Not checked: the finer setting is refused ({check['skipped']})"
    base = step_check_line({**check, "passed": True})
    # ": these numbers depend on ...; run again at ...", said once, at the end
    tail = step_check_line({**check, "passed": False})[len(base) :]
    text = base[0].upper() + base[1:]
    if "peak_change" in check:
        text += (
            f"; the frequency peaks moved by at most {check['peak_change']:.2g} and the largest angles by "
            f"{check['angle_change']:.2g} (relative; more than {PEAK_SHARE:.0%} fails)"
        )
    boundary = check.get("cct")
    if boundary is not None:
        text += (
            f". The CCT's boundary at the finer setting ({boundary['faults']} faults on "
            f"line{'s' * (len(boundary['lines']) != 1)} {', '.join(boundary['lines'])}: the CCT survived, "
            "the first failing fault failed): "
            f"{boundary['changed']} verdict(s) changed"
        )
        if boundary["grazing"]:
            text += f", {boundary['grazing']} of them back again once finer (grazing the boundary)"
        if boundary["moved"]:
            text += (
                f"; the CCT of {', '.join(boundary['moved_lines'])} moves by at least one step of its scan"
            )
    if not check["passed"]:
        text += tail
    prefix = "" if check["passed"] else "WARNING: "
    return prefix + text
