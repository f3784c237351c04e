"""Streaming statistics of tau0, tau(beta), F_beta and Lambda^KM (paper Eqs. 5, 6 and 17).

Realizations are grouped into fixed-size *blocks* (block ``j`` holds realizations
``j*B .. (j+1)*B - 1``, whatever the chunking). Each block is reduced in realization order to a
small record of counts and sums; estimates combine block records in block order. So results
do not depend on chunk size, thread count, backend or executor, memory does not grow with the
number of realizations, and block means give batch-means standard errors that stay honest
when per-realization values are heavy-tailed.

A realization contributes to ``F_beta`` for variant ``v`` only when both ``tau0`` and
``tau(beta)`` ended :attr:`~antisync.status.Status.SYNCED`; the others are counted, never
averaged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np
from numba import njit

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.status import ALREADY_SYNCED, NOT_SYNCED, SYNCED

__all__ = [
    "BATCH_MEANS_ESTIMATORS",
    "BLOCK_FIELDS",
    "LAMBDA_FIELDS",
    "LAMBDA_QUANTITY",
    "MIXED_QUANTITY",
    "LAMBDA_TAIL_BINS",
    "TAIL_BINS",
    "TAU0_FIELDS",
    "TAIL_MODEL",
    "UNCALIBRATED_ESTIMATORS",
    "Z95",
    "Estimate",
    "Interval",
    "block_records",
    "crossing_times",
    "estimate_mean",
    "histogram2d",
    "lambda_interval",
    "lambda_quantity",
    "lambda_block_records",
    "lambda_ci",
    "summarize_variant",
    "summarize_lambda",
    "summarize_lambda_tau",
    "lambda_tau_interval",
    "summarize_tau0",
    "sync_response",
    "tail_share",
]

# per (block, variant) record: counts, then sums of d = F - 1, d^2, tau(beta), tau(beta)^2
BLOCK_FIELDS = ("n", "n_already", "n_not_synced", "sum_d", "sum_d2", "sum_tau", "sum_tau2")
# per block record for the undamaged network
TAU0_FIELDS = ("n", "n_already", "n_not_synced", "sum_tau", "sum_tau2")
# per (block, edge) record of the per-realization Lambda values of any estimator; n_lost and
# n_gained count (finite difference only) the realizations whose undamaged network synchronized
# and damaged one did not, and the reverse: the synchronized fraction's response (format 3)
# sum_slope_tau and sum_tau0 (format 4) sum, over the same realizations as ``sum``, the
# estimator's slope of tau(beta) at 0 and tau0: the additive response Lambda^tau
# = -sum_slope_tau / sum_tau0 (:func:`summarize_lambda_tau`)
LAMBDA_FIELDS = (
    "n",
    "n_already",
    "n_not_synced",
    "sum",
    "sum2",
    "n_flagged",
    "n_lost",
    "n_gained",
    "sum_slope_tau",
    "sum_tau0",
)
# log-spaced bins of |F - 1| for the tail diagnostic: 8 per decade from 1e-9 to 1e3
TAIL_EDGES = np.logspace(-9, 3, 97)
TAIL_BINS = TAIL_EDGES.size + 1  # plus underflow (|d| < 1e-9, including 0) and overflow
# Lambda's histogram is signed: bins [0, TAIL_BINS) count |x| of values x >= 0, bins
# [TAIL_BINS, 2 TAIL_BINS) of values x < 0 (the interval of lambda_interval needs each side)
LAMBDA_TAIL_BINS = 2 * TAIL_BINS


@njit(cache=True)
def _reduce_blocks(status0, t0s, status, ts, dt, block, edges, rec, rec0, tail):
    m, n_var = status.shape
    n_blocks = rec.shape[0]
    for bl in range(n_blocks):
        lo = bl * block
        hi = min(lo + block, m)
        for r in range(lo, hi):
            st0 = status0[r]
            if st0 == SYNCED:
                t0 = t0s[r] * dt
                rec0[bl, 0] += 1
                rec0[bl, 3] += t0
                rec0[bl, 4] += t0 * t0
            elif st0 == ALREADY_SYNCED:
                rec0[bl, 1] += 1
            else:
                rec0[bl, 2] += 1
            for v in range(n_var):
                st = status[r, v]
                if st0 == SYNCED and st == SYNCED:
                    d = t0s[r] / ts[r, v] - 1.0
                    t = ts[r, v] * dt
                    rec[bl, v, 0] += 1
                    rec[bl, v, 3] += d
                    rec[bl, v, 4] += d * d
                    rec[bl, v, 5] += t
                    rec[bl, v, 6] += t * t
                    tail[v, np.searchsorted(edges, abs(d), side="right")] += 1
                elif st0 == NOT_SYNCED or st == NOT_SYNCED:
                    rec[bl, v, 2] += 1
                else:
                    rec[bl, v, 1] += 1


def crossing_times(sim, interpolate: bool):
    """Crossing times in units of dt: the grid step (paper) or ``steps - 1 + frac`` (interpolated)."""
    if not interpolate:
        return sim.steps0.astype(np.float64), sim.steps.astype(np.float64)
    if sim.frac0 is None:
        raise ValueError("interpolated crossing times need the lane driver's crossing fractions")
    return sim.steps0 - 1.0 + sim.frac0, sim.steps - 1.0 + sim.frac


def block_records(sim, dt: float, block: int, interpolate: bool = False):
    """Reduce a batch that starts on a block boundary to block records.

    Parameters
    ----------
    sim : :class:`antisync.kernels.shared.SimResult`
        Per-realization outcomes; its length need not be a multiple of ``block`` (the last
        block of a run may be short).
    dt : float
        Time step, ``tau = steps * dt``.
    block : int
        Block size ``B``.

    Returns
    -------
    rec : ndarray, shape (n_blocks, V, len(BLOCK_FIELDS))
    rec0 : ndarray, shape (n_blocks, len(TAU0_FIELDS))
    tail : int64 ndarray, shape (V, TAIL_BINS)
        Counts of ``|F - 1|`` in log bins (integer, so it merges exactly).
    """
    m, n_var = sim.status.shape
    n_blocks = -(-m // block)
    rec = np.zeros((n_blocks, n_var, len(BLOCK_FIELDS)))
    rec0 = np.zeros((n_blocks, len(TAU0_FIELDS)))
    tail = np.zeros((n_var, TAIL_BINS), dtype=np.int64)
    t0, t = crossing_times(sim, interpolate)
    _reduce_blocks(sim.status0, t0, sim.status, t, dt, block, TAIL_EDGES, rec, rec0, tail)
    return rec, rec0, tail


def _readonly(a, dtype):
    """``a`` as a read-only C-contiguous array of ``dtype`` (a view where it is one already): the
    callers' C, Fortran, broadcast and read-only arrays all reach :func:`_reduce_lambda` as one
    type, so numba compiles it once rather than once per layout."""
    view = np.ascontiguousarray(a, dtype=dtype).view()
    view.flags.writeable = False
    return view


@njit(cache=True)
def _reduce_lambda(values, code, flagged, flip, slope, tau0, block, edges, rec, tail):
    m, n_edges = values.shape
    for bl in range(rec.shape[0]):
        for r in range(bl * block, min(bl * block + block, m)):
            for e in range(n_edges):
                if flip[r, e] < 0:
                    rec[bl, e, 6] += 1
                elif flip[r, e] > 0:
                    rec[bl, e, 7] += 1
                if code[r, e] == SYNCED:
                    x = values[r, e]
                    rec[bl, e, 0] += 1
                    rec[bl, e, 3] += x
                    rec[bl, e, 4] += x * x
                    rec[bl, e, 5] += flagged[r, e]
                    rec[bl, e, 8] += slope[r, e]
                    rec[bl, e, 9] += tau0[r, e]
                    b = np.searchsorted(edges, abs(x), side="right")
                    tail[e, b + (edges.size + 1 if x < 0 else 0)] += 1
                elif code[r, e] == ALREADY_SYNCED:
                    rec[bl, e, 1] += 1
                else:
                    rec[bl, e, 2] += 1


def lambda_block_records(
    values: np.ndarray,
    code: np.ndarray,
    flagged: np.ndarray,
    block: int,
    flip: np.ndarray | None = None,
    slope: np.ndarray | None = None,
    tau0: np.ndarray | None = None,
):
    """Block records of per-realization Lambda values (any estimator).

    Parameters
    ----------
    values : float array (m, E)
        Per-realization estimates of Lambda for each edge (used where ``code`` is SYNCED).
    code : int8 array (m, E)
        :class:`~antisync.status.Status` of the realization for that edge: SYNCED when every
        time it needs was finite and positive.
    flagged : bool array (m, E)
        Realizations the hybrid estimator treated by a secant (counted).
    flip : int8 array (m, E), optional
        ``-1`` where the undamaged network synchronized and the damaged one did not, ``+1``
        for the reverse, else 0 (counted as ``n_lost`` and ``n_gained``; finite difference).
    slope, tau0 : float arrays (m, E), optional
        The estimator's per-realization slope of ``tau(beta)`` at 0 (in time units per unit
        beta) and ``tau0``, summed where ``code`` is SYNCED (``sum_slope_tau``, ``sum_tau0``:
        Lambda^tau); without them those fields are NaN.

    Returns
    -------
    rec : ndarray (n_blocks, E, len(LAMBDA_FIELDS))
    tail : int64 (E, LAMBDA_TAIL_BINS)
        Signed log histogram: ``|value|`` of values ``>= 0`` in the first ``TAIL_BINS`` bins,
        of negative values in the last ``TAIL_BINS``.
    """
    m, n_edges = values.shape
    rec = np.zeros((-(-m // block), n_edges, len(LAMBDA_FIELDS)))
    tail = np.zeros((n_edges, LAMBDA_TAIL_BINS), dtype=np.int64)
    flip = np.zeros(values.shape, np.int8) if flip is None else flip
    missing = slope is None or tau0 is None
    zeros = np.zeros(values.shape)
    slope, tau0 = (zeros, zeros) if missing else (slope, tau0)
    inputs = (values, code, flagged, flip, slope, tau0)
    dtypes = (np.float64, np.int8, np.int64, np.int8, np.float64, np.float64)
    _reduce_lambda(*map(_readonly, inputs, dtypes), block, TAIL_EDGES, rec, tail)
    if missing:
        rec[:, :, 8:10] = np.nan
    return rec, tail


def summarize_lambda(rec_e: np.ndarray) -> dict:
    """Lambda estimate for one edge from its block records ``(n_blocks, len(LAMBDA_FIELDS))``."""
    b = _coarsen(rec_e)
    return {
        "lambda": estimate_mean(b[:, 0], b[:, 3], b[:, 4]),
        **_status_counts(rec_e),
        "n_flagged": int(rec_e[:, 5].sum()),
    }


def summarize_lambda_tau(rec_e: np.ndarray) -> Estimate | None:
    """The additive response ``Lambda^tau = -d ln<tau(beta)>/dbeta`` at 0 of one edge, from its
    Lambda block records: the ratio of means ``-sum_slope_tau / sum_tau0`` over the realizations
    that give a Lambda value, with a batch-means standard error (the ratio linearized over
    batches: ``u_b = -(slope_b + R tau0_b)``, ``var R = sum u_b^2 / (sum tau0)^2 * k / (k - 1)``).

    None where the records predate the fields (format 1-3 files and blocks, NaN) or hold no
    value.
    """
    if rec_e.shape[-1] <= 9:
        return None
    b = _coarsen(rec_e)
    n, s, t = b[:, 0], b[:, 8], b[:, 9]
    total_t = float(np.sum(t))
    if not (np.isfinite(s).all() and np.isfinite(t).all()) or total_t <= 0:
        return None
    ratio = -float(np.sum(s)) / total_t
    used = n > 0
    k = int(used.sum())
    if k < 2:
        return Estimate(ratio, math.nan, math.nan, math.nan, int(n.sum()), k)
    u = -(s[used] + ratio * t[used])
    se = math.sqrt(float(np.sum(u * u)) * k / (k - 1)) / total_t
    return Estimate(ratio, se, math.nan, se, int(n.sum()), k)


def lambda_tau_interval(est: Estimate, level: float = 0.95) -> tuple[float, float]:
    """Lambda^tau's interval at ``level`` from :func:`summarize_lambda_tau`'s estimate: ``R +- t
    se`` with Student's ``t`` quantile on ``n_batches - 1`` degrees of freedom, since the error
    comes from the batches' spread (a normal quantile covered 0.925-0.955 per link, 0.940 over
    all, at 20 batches of the lollipop; bench/RESULTS.md, "Lambda^tau: time to precision and
    coverage")."""
    # lazy: scipy.stats takes ~0.5 s to import, and `antisync --help` loads this module
    from scipy.stats import t as student

    if est.n_batches < 2 or not math.isfinite(est.se):
        return math.nan, math.nan
    q = float(student.ppf((1 + level) / 2, est.n_batches - 1))
    return est.mean - q * est.se, est.mean + q * est.se


def sync_response(rec_e: np.ndarray, dbeta: float, level: float = 0.95) -> dict | None:
    """Response of the synchronized fraction to the damage of one link, from its Lambda block
    records ``(n_blocks, len(LAMBDA_FIELDS))`` (finite difference):
    ``dP/dbeta = (n_gained - n_lost) / (N dbeta)`` over all ``N`` realizations, paired (the
    same initial phases with and without the damage).

    The interval joins exact Poisson (Garwood) bounds of the two counts at ``(1 + level) / 2``
    each, so it holds at least ``level`` and stays honest when the counts are 0 (no flip in
    ``N`` realizations bounds ``|dP/dbeta|`` by about ``3.7 / (N dbeta)``, not by 0).

    Returns ``{"value", "low", "high", "lost", "gained", "n"}``, or None where the records
    predate the counts (format 1-2 files, NaN) or hold no realization.
    """
    # lazy: scipy.stats takes ~0.5 s to import, and `antisync --help` loads this module
    from scipy.stats import chi2

    lost, gained = float(rec_e[:, 6].sum()), float(rec_e[:, 7].sum())
    n = float(rec_e[:, 0].sum() + rec_e[:, 1].sum() + rec_e[:, 2].sum())
    if math.isnan(lost) or math.isnan(gained) or n == 0:
        return None
    a = (1 - level) / 2  # each count's two-sided level is 1 - a

    def bounds(k):
        lo = chi2.ppf(a / 2, 2 * k) / 2 if k > 0 else 0.0
        return lo, chi2.ppf(1 - a / 2, 2 * k + 2) / 2

    (g_lo, g_hi), (l_lo, l_hi) = bounds(gained), bounds(lost)
    scale = n * dbeta
    return {
        "value": (gained - lost) / scale,
        "low": (g_lo - l_hi) / scale,
        "high": (g_hi - l_lo) / scale,
        "lost": int(lost),
        "gained": int(gained),
        "n": int(n),
    }


def histogram2d(
    sim, variants: np.ndarray, dt: float, bins: int, tau_max: float, interpolate: bool = False
) -> np.ndarray:
    """Counts of ``(tau0, tau(beta))`` pairs on a ``bins x bins`` grid over ``[0, tau_max)``.

    Only pairs with both times SYNCED are counted; pairs beyond ``tau_max`` go to the last bin
    (so counts always sum to the number of valid pairs). Returns int64, shape
    ``(len(variants), bins, bins)``, indexed ``[v, i_tau0, i_tau_beta]``.
    """
    out = np.zeros((len(variants), bins, bins), dtype=np.int64)
    scale = bins / (tau_max / dt)
    t0, t = crossing_times(sim, interpolate)
    i0 = np.minimum((t0 * scale).astype(np.int64), bins - 1)
    for k, v in enumerate(variants):
        ok = (sim.status0 == SYNCED) & (sim.status[:, v] == SYNCED)
        i1 = np.minimum((t[ok, v] * scale).astype(np.int64), bins - 1)
        np.add.at(out[k], (i0[ok], i1), 1)
    return out


@dataclass(frozen=True)
class Estimate:
    """A mean with a naive and a batch-means standard error.

    ``se`` is the larger of the two, the one to quote; ``se_naive`` is the iid formula and
    ``se_batch`` comes from the spread of block means (weighted by block counts).
    """

    mean: float
    se: float
    se_naive: float
    se_batch: float
    n: int
    n_batches: int


def estimate_mean(n: np.ndarray, s: np.ndarray, s2: np.ndarray, shift: float = 0.0) -> Estimate:
    """Mean of a quantity from per-block counts ``n``, sums ``s`` and sums of squares ``s2``.

    ``shift`` is added to the mean (used for ``F = 1 + d``); it does not change the errors.
    Block arrays are combined in block order, so the result is deterministic.
    """
    n = np.asarray(n, dtype=np.float64)
    total = float(n.sum())
    if total == 0:
        return Estimate(math.nan, math.nan, math.nan, math.nan, 0, 0)
    mean = float(np.sum(s)) / total
    if total < 2:
        return Estimate(mean + shift, math.nan, math.nan, math.nan, int(total), 0)
    var = max(float(np.sum(s2)) / total - mean * mean, 0.0) * total / (total - 1)
    se_naive = math.sqrt(var / total)
    used = n > 0
    k = int(used.sum())
    if k >= 2:
        means = np.asarray(s)[used] / n[used]
        w = n[used]
        var_b = float(np.sum(w * (means - mean) ** 2)) / (k - 1)
        se_batch = math.sqrt(var_b / total)
    else:
        se_batch = math.nan
    se = se_naive if math.isnan(se_batch) else max(se_naive, se_batch)
    return Estimate(mean + shift, se, se_naive, se_batch, int(total), k)


def _coarsen(rec: np.ndarray, min_batches: int = 32, max_batches: int = 128) -> np.ndarray:
    """Merge consecutive blocks into at most ``max_batches`` batches (never below ``min_batches``
    when there are enough blocks): batch means need batches large enough to be near-normal."""
    n_blocks = rec.shape[0]
    if n_blocks <= max_batches:
        return rec
    group = -(-n_blocks // max(min_batches, max_batches))
    pad = (-n_blocks) % group
    padded = np.concatenate([rec, np.zeros((pad,) + rec.shape[1:])]) if pad else rec
    return padded.reshape((-1, group) + rec.shape[1:]).sum(axis=1)


def summarize_variant(rec_v: np.ndarray) -> dict:
    """Estimates for one variant from its block records ``(n_blocks, len(BLOCK_FIELDS))``."""
    b = _coarsen(rec_v)
    f = estimate_mean(b[:, 0], b[:, 3], b[:, 4], shift=1.0)
    tau = estimate_mean(b[:, 0], b[:, 5], b[:, 6])
    return {
        "F": f,
        "tau": tau,
        **_status_counts(rec_v),
    }


def summarize_tau0(rec0: np.ndarray) -> dict:
    """``<tau0>`` and status counts from the undamaged blocks ``(n_blocks, len(TAU0_FIELDS))``."""
    b = _coarsen(rec0)
    return {
        "tau0": estimate_mean(b[:, 0], b[:, 3], b[:, 4]),
        **_status_counts(rec0),
    }


def _status_counts(rec: np.ndarray) -> dict[str, int]:
    """``n``, ``n_already``, ``n_not_synced`` (the first fields of every block record), summed."""
    return {
        "n": int(rec[:, 0].sum()),
        "n_already": int(rec[:, 1].sum()),
        "n_not_synced": int(rec[:, 2].sum()),
    }


def tail_share(tail_counts: np.ndarray, top: float = 1e-3) -> float:
    """Approximate share of ``sum (F-1)^2`` carried by the largest ``top`` fraction of samples.

    Uses the integer log-histogram of ``|F - 1|`` (bin centres, 8 bins per decade), so it is a
    diagnostic, good to about 30%: near 0 for light tails, approaching 1 when a handful of
    realizations dominate the variance, in which case no standard error can be trusted.
    """
    counts = np.asarray(tail_counts, dtype=np.float64)
    if counts.size == LAMBDA_TAIL_BINS:  # a signed histogram: fold the two signs
        counts = counts[:TAIL_BINS] + counts[TAIL_BINS:]
    total = counts.sum()
    if total == 0:
        return math.nan
    centres = np.concatenate([[0.0], np.sqrt(TAIL_EDGES[:-1] * TAIL_EDGES[1:]), [TAIL_EDGES[-1]]])
    energy = counts * centres**2
    if energy.sum() == 0:
        return 0.0
    # walk down from the largest values until `top` of the samples are taken
    want = top * total
    taken = 0.0
    share = 0.0
    for k in range(counts.size - 1, -1, -1):
        if taken >= want:
            break
        take = min(counts[k], want - taken)
        share += take * centres[k] ** 2
        taken += take
    return float(share / energy.sum())


# ---- Lambda's interval: a Pareto model of the heavy tail --------------------------------------

#: the name of the interval method of :func:`lambda_interval` (stored in every record)
TAIL_MODEL = "pareto-tail"
# the pooled top fraction of |Lambda| (all links of a job) modelled as a Pareto tail, the
# fewest pooled values above the threshold the model needs, and the fewest per link with a
# value: at 2,000 realizations the top 0.1% of a 30-link job is two values a link, too few for
# its tail. 3.5 a link brought a random 3-regular graph's coverage from 0.988 to 0.976 and a
# barbell's from 0.970 to 0.964; four and five lowered the lollipop's heaviest links to 0.905
# and 0.90 (their tail steepens beyond |Lambda| ~ 80, and a lower threshold fits it lighter)
_TAIL_TOP = 1e-3
_TAIL_MIN = 40
_TAIL_PER_LINK = 3.5
# pseudo-events of the pooled tail shape in each link's (and sign's) tail index
_SHAPE_PRIOR = 10.0
# a link's tail rate: Gamma(k + _RATE_PRIOR, 1) given its k events. Two pseudo-events: with a
# handful of tail values a link's unseen far tail (|Lambda| > 50 at ~1e-4, a third of some
# links' mean) must still widen the interval; k + 1 left the heaviest lollipop links at 0.89
# coverage at 2,000 realizations once the union below is not taken, k + 1/2 lower still
# (bench/RESULTS.md)
_RATE_PRIOR = 2.0
# the batch-means interval joins the tail model's only for a link with at least this many
# values beyond the tail threshold (the summary's heavy-tail warning asks for the same ten)
_UNION_MIN_EVENTS = 10
# the tail is cut at max(largest pooled value, _CAP_DBETA / dbeta): a finite-difference value
# is >= -1/dbeta exactly (tau(beta) <= t_max), and the largest seen are below ~3/dbeta
_CAP_DBETA = 3.0
# the pooled tail is no link's prior when some link has more than this share of its values
# beyond the pooled threshold (:func:`pooled_tail`)
_BODY_SHARE = 0.5
_DRAWS = 4000
_SEED = 20261123


@dataclass(frozen=True)
class Interval:
    """A two-sided interval for Lambda from :func:`lambda_interval`.

    ``tail_events`` is the number of the link's values beyond the tail threshold ``u``: when it
    is small, the interval's width is mostly the unseen tail's.
    """

    low: float
    high: float
    level: float
    u: float
    tail_events: int


def _bin_lower(t: int) -> float:
    return TAIL_EDGES[t - 1]


def _tail_index(counts: np.ndarray, t: int) -> float:
    """Maximum-likelihood Pareto index of the binned ``counts`` (one sign, ``TAIL_BINS``) at
    and above bin ``t``, whose threshold is ``u = TAIL_EDGES[t - 1]``."""
    # lazy: scipy.optimize takes ~0.3 s to import; only the tail fit needs it
    from scipy.optimize import minimize_scalar

    u = _bin_lower(t)
    lo = TAIL_EDGES[t - 1 : -1] / u  # bins t .. TAIL_BINS - 2 span [lo, hi)
    hi = TAIL_EDGES[t:] / u
    c = np.asarray(counts[t:-1], dtype=np.float64)
    c_over = float(counts[-1])  # beyond the last edge
    log_over = math.log(TAIL_EDGES[-1] / u)

    def nll(a):
        p = np.maximum(lo**-a - hi**-a, 1e-300)
        return -(float(np.sum(c * np.log(p))) - a * c_over * log_over)

    return float(minimize_scalar(nll, bounds=(0.05, 20.0), method="bounded").x)


def _pareto_mean(a: np.ndarray, u: float, cap: float) -> np.ndarray:
    """``E[Y]`` of a Pareto(``a``, ``u``) variable truncated at ``cap > u`` (elementwise in a)."""
    r = cap / u
    one = np.abs(a - 1.0) < 1e-9
    safe = np.where(one, 2.0, a)
    integral = np.where(one, math.log(r), (r ** (1.0 - safe) - 1.0) / (1.0 - safe))
    return u * a * integral / (1.0 - r ** (-a))


def _threshold_bin(counts: np.ndarray, k: float) -> tuple[int, int]:
    """The highest bin ``t >= 1`` with at least ``k`` counts at or above it, and that count."""
    cum = np.cumsum(counts[::-1])[::-1]  # cum[b] = counts in bins >= b
    ok = np.flatnonzero(cum[1:] >= k)
    t = int(ok[-1]) + 1 if ok.size else 1
    return t, int(cum[t])


def _pooled_threshold(both: np.ndarray, links: int) -> tuple[int, int]:
    """The tail threshold's bin and the pooled count beyond it (:func:`lambda_interval`):
    the pooled top :data:`_TAIL_TOP` of ``|Lambda|``, at least :data:`_TAIL_MIN` values and
    :data:`_TAIL_PER_LINK` a link. ``both``: the pooled counts of the two signs added."""
    return _threshold_bin(both, max(_TAIL_MIN, _TAIL_TOP * both[1:].sum(), _TAIL_PER_LINK * links))


def pooled_tail(tails: np.ndarray) -> tuple[np.ndarray, int]:
    """``(pooled, links)``: the signed tail counts ``tails`` (E, LAMBDA_TAIL_BINS) of a job's
    links summed (the tail model's prior and threshold), and how many links have a value
    (neutral links, every value 0, are in no tail).

    The pooled tail is every link's prior only where the links share one. When some link has
    more than :data:`_BODY_SHARE` of its values beyond the pooled threshold, that "tail" is the
    link's body: the links' scales differ by decades (a power grid's lines: IEEE 118's swing
    equation gives a few lines ~0.2 in every realization and most ~1e-6), and the pooled shape
    and sizes would be put on links that never come near them (at 40 realizations 316 of its
    358 links got intervals near ``[-0.1, -0.003]`` around means of ``+-1e-6``). Then the
    pooled counts are returned as zeros, and every link's interval is its batch means
    (:func:`lambda_ci`)."""
    tails = np.asarray(tails)
    if tails.size == 0:
        return tails.reshape(-1), 0
    nonzero = tails.sum(axis=1) - tails[:, 0] - (tails[:, TAIL_BINS] if tails.shape[1] > TAIL_BINS else 0)
    pooled, links = tails.sum(axis=0), int(np.count_nonzero(nonzero))
    if tails.shape[1] == LAMBDA_TAIL_BINS:
        per_link = tails[:, :TAIL_BINS] + tails[:, TAIL_BINS:]
        t, _ = _pooled_threshold(per_link.sum(axis=0), links)
        if np.any(per_link[:, t:].sum(axis=1) > _BODY_SHARE * per_link.sum(axis=1)):
            return np.zeros_like(pooled), links
    return pooled, links


def lambda_interval(
    n: int,
    s1: float,
    s2: float,
    tail: np.ndarray,
    pooled: np.ndarray,
    dbeta: float,
    level: float = 0.95,
    links: int = 1,
) -> Interval | None:
    """Interval for one link's Lambda whose coverage holds under its heavy tail.

    The per-realization values split at a threshold ``u`` (the pooled top 0.1% of ``|Lambda|``
    over every link of the job) into a light *body* and two Pareto *tails* (one per sign):

    ``Lambda = body mean + sum over signs s of s * rate_s * E[Y_s] / n``.

    The body mean is normal with the body's sample variance; each tail's count of events is
    Poisson, its rate given the link's ``k_s`` observed events is ``Gamma(k_s + 2)``; the sizes
    ``Y_s`` are Pareto from ``u`` to a cap, with an index fitted by maximum likelihood on the
    link's binned tail plus ten pseudo-events of the pooled shape. A run that missed the rare
    huge values (most runs, when they carry most of the variance) still gets their share of
    the width; one that caught them is not thrown off by their sizes, only by their count. The
    interval is the ``level`` quantile range of 4000 draws from a fixed seed (so a summary is
    reproducible), widened by the histogram's bin widths where bin centres stand in for the
    tail values. Measured coverage: bench/RESULTS.md.

    Parameters
    ----------
    n, s1, s2 : the link's count, sum and sum of squares of values (exact, from block records)
    tail : int64 (LAMBDA_TAIL_BINS,) the link's signed log histogram
    pooled : int64 (LAMBDA_TAIL_BINS,) the sum of ``tail`` over the job's links
    dbeta : the finite-difference step (the tail's cap is at least ``3 / dbeta``)
    links : how many links ``pooled`` sums (with a value; :func:`pooled_tail`): the threshold
        keeps at least four tail values a link

    Returns
    -------
    Interval, or None when the pooled tail has fewer than 40 values (use batch means), the
    histogram is unsigned (a format-1 file) or every value is 0 (a neutral link).
    """
    if tail.size != LAMBDA_TAIL_BINS or n < 2:
        return None
    if tail[1:TAIL_BINS].sum() + tail[TAIL_BINS + 1 :].sum() == 0:
        return None  # every value is 0 to 1e-9 (a neutral link): nothing to model
    tail = np.asarray(tail, dtype=np.float64)
    pooled = np.asarray(pooled, dtype=np.float64)
    sides = ((1.0, tail[:TAIL_BINS], pooled[:TAIL_BINS]), (-1.0, tail[TAIL_BINS:], pooled[TAIL_BINS:]))
    both = pooled[:TAIL_BINS] + pooled[TAIL_BINS:]
    # exact zeros (neutral links) are not part of any tail
    t, k_pool = _pooled_threshold(both, links)
    if k_pool < _TAIL_MIN or t < 2:
        return None
    u = _bin_lower(t)
    # bin b covers [lower[b], upper[b]); the histogram's centres stand in for the tail values
    lower = np.concatenate([[0.0], TAIL_EDGES])
    upper = np.concatenate([TAIL_EDGES, [np.inf]])
    centre = np.concatenate([[0.0], np.sqrt(TAIL_EDGES[:-1] * TAIL_EDGES[1:]), [TAIL_EDGES[-1]]])
    sum_t = sum_t2 = widen_lo = widen_hi = 0.0
    for sign, h, _ in sides:
        c = h[t:]
        sum_t += sign * float(np.sum(c * centre[t:]))
        sum_t2 += float(np.sum(c * centre[t:] ** 2))
        up = float(np.sum(c * (np.minimum(upper[t:], 10 * TAIL_EDGES[-1]) - centre[t:]) ** 2))
        down = float(np.sum(c * (centre[t:] - lower[t:]) ** 2))
        widen_hi += up if sign > 0 else down
        widen_lo += down if sign > 0 else up
    body = (s1 - sum_t) / n
    body_var = max((s2 - sum_t2) / n - body * body, 0.0)
    rng = np.random.default_rng(_SEED)
    draws = body + rng.normal(0.0, math.sqrt(body_var / n), _DRAWS)
    events = 0
    for sign, h, p in sides:
        k = float(h[t:].sum())
        events += int(k)
        k_side = float(p[t:].sum())
        top = np.flatnonzero(p)
        cap = max(upper[top[-1]] if top.size else u, _CAP_DBETA / dbeta, 1.0001 * u)
        if not math.isfinite(cap):
            cap = 10 * TAIL_EDGES[-1]
        # the index is a plug-in estimate: drawing it from its posterior as well widened
        # the light-tailed links' intervals to 99-100% coverage (bench/RESULTS.md)
        if k_side >= 5:
            shape = _tail_index(h + (_SHAPE_PRIOR / k_side) * p, t)
        else:  # hardly any pooled events of this sign: a tail as heavy as a mean allows
            shape = 1.0
        rate = rng.gamma(k + _RATE_PRIOR, 1.0, _DRAWS)
        draws += sign * rate * float(_pareto_mean(np.array([shape]), u, cap)[0]) / n
    lo, hi = np.quantile(draws, [(1 - level) / 2, (1 + level) / 2])
    # a centre is within a bin's half-width of each tail value: widen by those errors added as
    # independent ones (the square root of the sum of their squares)
    return Interval(
        float(lo - math.sqrt(widen_lo) / n), float(hi + math.sqrt(widen_hi) / n), level, float(u), events
    )


#: what each ``lambda.method`` estimates, as every record names it (``lambda_quantity``;
#: docs/equations.md "Lambda near saddle passages"): the paper's forward secant
#: ``(<F_dbeta> - 1)/dbeta`` of Eq. 17 at the record's ``lambda_dbeta``, or the derivative
#: ``d<F>/dbeta`` at 0 of Eq. 6. Near saddle passages the two differ at every usable dbeta.
LAMBDA_QUANTITY = {
    "finite-difference": "forward-secant",
    "central-difference": "derivative",
    "orbit": "derivative",
    "hybrid": "derivative",
    "adjoint-hybrid": "derivative",
    "pathwise": "derivative",
    "adjoint": "derivative",
}
#: the hybrids of files written before their flagged values became central secants: a
#: derivative bulk with the forward secant's tail (neither quantity; rerun to get the derivative)
MIXED_QUANTITY = "derivative with forward-secant tail (a file from before central secants)"


def lambda_quantity(method: str, recorded: str | None = None) -> str:
    """The quantity a job's Lambda values estimate: ``recorded`` (the job's ``lambda_quantity``
    attribute) when the file has it, else what ``method`` estimated when the file was written."""
    if recorded:
        return recorded
    if method in ("hybrid", "adjoint-hybrid"):
        return MIXED_QUANTITY
    return LAMBDA_QUANTITY.get(method, "unknown")


#: the normal quantile of a two-sided 95% interval
Z95 = 1.959963984540054
#: Lambda estimators whose batch-means interval is calibrated as it is (see lambda_ci)
BATCH_MEANS_ESTIMATORS = ("orbit",)
#: Lambda estimators with an unbounded per-realization tail, whose interval no method makes
#: hold (measured 74-98% coverage, bench/RESULTS.md), each with the estimator to use instead
UNCALIBRATED_ESTIMATORS = {"pathwise": "hybrid", "adjoint": "adjoint-hybrid"}


def lambda_ci(
    est: Estimate,
    rec_e: np.ndarray,
    tail_e: np.ndarray,
    pooled: np.ndarray,
    dbeta: float,
    level: float = 0.95,
    estimator: str = "finite-difference",
    links: int = 1,
):
    """Lambda's interval for one link: ``est`` is its mean (``summarize_lambda(rec_e)["lambda"]``),
    ``rec_e`` its block records and ``tail_e`` its signed tail counts; ``pooled`` and ``links``
    are :func:`pooled_tail` of the job's links.

    For the ``orbit`` estimator (central differences averaged over an orbit's links, a light
    tail) the batch-means interval, which covers 96-97% there (bench/RESULTS.md; the tail
    model's covered 97-100%, needlessly wide). For the others the tail model's interval
    (:func:`lambda_interval`), united with the batch-means normal interval ``mean +- z se``
    once the link has at least ten values beyond the tail threshold:

    - with ten or more, the sample variance carries the link's own tail, and the union guards
      against a misfit of the model (an index pulled lighter than the link's by the pooled
      prior biases the model's centre low: at 20,000 realizations the heaviest lollipop links
      fell to 0.86 coverage without it);
    - with fewer, the sample variance is mostly noise (inflated when one rare value is in the
      run, too small when none is), and the union only widened the links with a moderate,
      symmetric tail to 98-99.5% coverage at 2,000 without helping the heavy ones.

    Where the model does not apply, the batch-means interval alone.

    Returns
    -------
    ``(low, high, method, interval)``: the interval's ends, its method (``TAIL_MODEL`` or
    ``"batch-means"``) and the tail model's :class:`Interval` (None where it did not apply).
    """
    if not 0 < level < 1:
        raise ValueError(f"level must be in (0, 1), got {level}")
    # coverage is measured at 95% (bench/RESULTS.md); other levels (the stopping rule's
    # Bonferroni levels) are the same model's quantiles
    z = Z95 if level == 0.95 else NormalDist().inv_cdf((1 + level) / 2)
    bm_low, bm_high = est.mean - z * est.se, est.mean + z * est.se
    iv = None
    if est.n >= 2 and estimator not in BATCH_MEANS_ESTIMATORS:
        iv = lambda_interval(
            est.n, float(rec_e[:, 3].sum()), float(rec_e[:, 4].sum()), tail_e, pooled, dbeta, level, links
        )
    if iv is None:
        return bm_low, bm_high, "batch-means", None
    if iv.tail_events < _UNION_MIN_EVENTS:
        return iv.low, iv.high, TAIL_MODEL, iv
    return min(iv.low, bm_low), max(iv.high, bm_high), TAIL_MODEL, iv
