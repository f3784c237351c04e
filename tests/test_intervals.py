"""Lambda's interval (estimators.lambda_interval): its parts against exact values, and its
coverage on synthetic heavy tails whose mean is known exactly (issue 18).

Coverage here is checked on a model of what the Lambda tail looks like (a light body plus a
rare, asymmetric Pareto tail cut at 3/dbeta, as bench/RESULTS.md measures on the lollipop);
its coverage on real runs is measured by bench/calibrate_errors.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from antisync.stats import estimators

DBETA = 0.01
CAP = 3.0 / DBETA


def _pareto(rng, a, u, cap, size):
    """Pareto(a, u) truncated at cap, by inversion."""
    r = (u / cap) ** a
    return u * (1.0 - rng.random(size) * (1.0 - r)) ** (-1.0 / a)


def _model(a):
    """A body N(0.1, 0.5^2) and, with probability 1%, a tail value from u = 1: positive 70% of
    the time and cut at 3/dbeta, negative cut at 1/dbeta (as finite differences are).
    Returns (sampler, exact mean)."""
    p_tail, p_pos, u = 0.01, 0.7, 1.0
    pos = float(estimators._pareto_mean(np.array([a]), u, CAP)[0])
    neg = float(estimators._pareto_mean(np.array([a]), u, 1.0 / DBETA)[0])
    mean = (1 - p_tail) * 0.1 + p_tail * (p_pos * pos - (1 - p_pos) * neg)

    def sample(rng, n):
        x = rng.normal(0.1, 0.5, n)
        hit = rng.random(n) < p_tail
        up = rng.random(n) < p_pos
        x[hit & up] = _pareto(rng, a, u, CAP, int((hit & up).sum()))
        x[hit & ~up] = -_pareto(rng, a, u, 1.0 / DBETA, int((hit & ~up).sum()))
        return x

    return sample, mean


def _records(x):
    n = x.size
    return estimators.lambda_block_records(x[:, None], np.zeros((n, 1), np.int8), np.zeros((n, 1), bool), 100)


def _interval(x):
    rec, tail = _records(x)
    return estimators.lambda_interval(x.size, rec[:, 0, 3].sum(), rec[:, 0, 4].sum(), tail[0], tail[0], DBETA)


def test_pareto_mean_matches_quadrature():
    from scipy.integrate import quad

    for a in (0.7, 1.0, 1.5, 2.5):
        u, cap = 2.0, 300.0
        norm = 1 - (u / cap) ** a
        want = quad(lambda y, a=a, u=u, z=norm: y * a * u**a * y ** (-a - 1) / z, u, cap, limit=200)[0]
        got = float(estimators._pareto_mean(np.array([a]), u, cap)[0])
        assert got == pytest.approx(want, rel=1e-9)


@pytest.mark.parametrize("a", [0.8, 1.5, 2.5])
def test_binned_tail_index_recovers_the_pareto_index(a):
    rng = np.random.default_rng(7)
    y = _pareto(rng, a, 1.0, 1e12, 200_000)
    rec, tail = _records(y)
    t, k = estimators._threshold_bin(tail[0, : estimators.TAIL_BINS], 1000)
    u = estimators.TAIL_EDGES[t - 1]
    assert 1.0 <= u < 1e3
    # the index of the values above u (same Pareto): its ML estimate has sd a / sqrt(k)
    assert estimators._tail_index(tail[0, : estimators.TAIL_BINS], t) == pytest.approx(
        a, abs=4 * a / math.sqrt(k)
    )


def test_signed_histogram_counts_each_side():
    x = np.array([0.0, 2.0, -2.0, -2.0, 5e3, -1e-12])
    _, tail = _records(x)
    pos, neg = tail[0, : estimators.TAIL_BINS], tail[0, estimators.TAIL_BINS :]
    b2 = np.searchsorted(estimators.TAIL_EDGES, 2.0, side="right")
    assert pos[0] == 1 and neg[0] == 1  # 0 and -1e-12 underflow on their own side
    assert pos[b2] == 1 and neg[b2] == 2
    assert pos[-1] == 1  # beyond the last edge
    assert tail.sum() == x.size
    assert estimators.tail_share(tail[0]) == estimators.tail_share(pos + neg)


def test_interval_is_none_where_the_model_does_not_apply():
    rng = np.random.default_rng(1)
    zero = np.zeros(5000)
    assert _interval(zero) is None  # a neutral link
    x = rng.normal(size=30)
    assert _interval(x) is None  # 30 values: fewer than 40 in any tail
    rec, tail = _records(rng.normal(size=5000))
    unsigned = tail[0, : estimators.TAIL_BINS] + tail[0, estimators.TAIL_BINS :]
    assert estimators.lambda_interval(5000, 0.0, 5000.0, unsigned, unsigned, DBETA) is None


def test_interval_is_reproducible_and_contains_the_light_tailed_mean():
    rng = np.random.default_rng(2)
    x = rng.normal(0.3, 1.0, 20_000)
    a, b = _interval(x), _interval(x)
    assert a == b
    assert a.low < x.mean() < a.high
    # a light tail: about the normal interval (the tail model adds little)
    half = 1.96 * x.std(ddof=1) / math.sqrt(x.size)
    assert (a.high - a.low) / 2 == pytest.approx(half, rel=0.35)


@pytest.mark.parametrize("a", [1.5, 2.5])
def test_coverage_on_a_known_heavy_tail(a):
    """Fixed seed, 300 runs of 2000: the reported interval (tail model and batch means united)
    covers the exact mean within [0.93, 0.99] (the coverage estimate itself has sd ~0.013),
    never less often than batch means alone."""
    sample, mean = _model(a)
    rng = np.random.default_rng(1234)
    runs = 300
    hit = hit_bm = 0
    for _ in range(runs):
        x = sample(rng, 2000)
        rec, tail = _records(x)
        est = estimators.summarize_lambda(rec[:, 0, :])["lambda"]
        low, high, method, iv = estimators.lambda_ci(est, rec[:, 0, :], tail[0], tail[0], DBETA)
        assert method == estimators.TAIL_MODEL and low <= est.mean <= high
        hit += low <= mean <= high
        hit_bm += abs(est.mean - mean) <= 1.96 * est.se
    assert 0.93 <= hit / runs <= 0.99, (hit / runs, hit_bm / runs)
    assert hit >= hit_bm


def test_a_format1_file_is_read_with_batch_means_and_says_so(tmp_path):
    """A file written before the signed tail counts (format 1) still gives records: the
    interval is batch means, named as such, with a warning that says how to get the other."""
    import h5py

    import antisync
    from antisync.store import records

    out = tmp_path / "r.h5"
    cfg = {
        "graph": {"kind": "lollipop", "nodes": 6, "path": 3},
        "edges": ["5->6", "6->5"],
        "betas": [],
        "seed": 3,
    }
    antisync.run(cfg, realizations=2000, output=out, progress=False)
    new = records(out)
    assert {r["lambda_km_ci_method"] for r in new} == {estimators.TAIL_MODEL}
    with h5py.File(out, "a") as f:
        f.attrs["format_version"] = 1
        for g in f["jobs"].values():
            signed = g["lambda_tail_counts"][...]
            del g["lambda_tail_counts"]
            g.create_dataset(
                "lambda_tail_counts",
                data=signed[:, : estimators.TAIL_BINS] + signed[:, estimators.TAIL_BINS :],
            )
    old = records(out)
    for a, b in zip(new, old, strict=True):
        assert b["lambda_km"] == a["lambda_km"]
        assert b["lambda_km_ci_method"] == "batch-means"
        assert b["lambda_km_se"] == pytest.approx(b["lambda_km_se_batch"]) or b[
            "lambda_km_se"
        ] == pytest.approx(b["lambda_km_se_naive"])
        assert "format-1" in b["lambda_km_warning"]
        assert (
            a["lambda_km_ci_low"] <= b["lambda_km_ci_low"]
            and b["lambda_km_ci_high"] <= a["lambda_km_ci_high"]
        )


def test_pooled_tail_counts_the_links_with_a_value():
    rng = np.random.default_rng(5)
    x = np.column_stack([rng.normal(size=500), np.zeros(500), rng.standard_cauchy(500)])
    n = x.shape[0]
    _, tail = estimators.lambda_block_records(x, np.zeros(x.shape, np.int8), np.zeros(x.shape, bool), 100)
    pooled, links = estimators.pooled_tail(tail)
    assert links == 2  # the all-zero (neutral) link is in no tail
    assert np.array_equal(pooled, tail.sum(axis=0)) and pooled.sum() == 3 * n
    assert estimators.pooled_tail(np.zeros((0, estimators.LAMBDA_TAIL_BINS)))[1] == 0


def test_batch_means_joins_only_a_link_with_ten_tail_values():
    """With fewer than ten values beyond the tail threshold the interval is the tail model's
    alone (a sample variance of a handful of rare values is noise); with ten or more it is
    united with the batch-means interval (bench/RESULTS.md, "Calibration of Lambda's error
    bars")."""
    rng = np.random.default_rng(11)
    sample, _ = _model(1.5)
    for n, few in ((4000, False), (2000, True)):
        x = sample(rng, n)
        if few:  # keep the body, but only three values beyond u = 1 on this link
            big = np.flatnonzero(np.abs(x) > 1.0)
            x[big[3:]] = rng.normal(0.1, 0.1, big.size - 3)
        rec, tail = _records(x)
        # alone, the link sets the threshold (40 values beyond it); with three, a job whose
        # other links fill the pooled tail
        pooled = tail[0] * 50 if few else tail[0]
        est = estimators.summarize_lambda(rec[:, 0, :])["lambda"]
        low, high, method, iv = estimators.lambda_ci(est, rec[:, 0, :], tail[0], pooled, DBETA)
        assert method == estimators.TAIL_MODEL
        assert (iv.tail_events < 10) == few
        if few:
            assert (low, high) == (iv.low, iv.high)
        else:
            assert low == min(iv.low, est.mean - estimators.Z95 * est.se)
            assert high == max(iv.high, est.mean + estimators.Z95 * est.se)


def test_links_of_different_scales_get_batch_means_not_the_pooled_tail():
    """A job whose links differ in scale by decades (IEEE 118's swing equation: a few lines
    ~0.2 in every realization, most ~1e-6) has no tail the links share: the pooled "tail" is
    the big links' body. Its pooled counts are dropped (estimators.pooled_tail), every link's
    interval is its batch means and holds its own mean; with the pooled tail, a tiny link's
    interval was put at the big links' scale, away from zero and from every value it has."""
    rng = np.random.default_rng(3)
    n = 40
    small = rng.normal(1e-7, 1e-6, (n, 30))
    big = rng.normal(-0.2, 0.05, (n, 2))
    x = np.column_stack([small, big])
    rec, tail = estimators.lambda_block_records(x, np.zeros(x.shape, np.int8), np.zeros(x.shape, bool), 10)
    pooled, links = estimators.pooled_tail(tail)
    assert links == 32 and not pooled.any()
    for e in (0, 31):
        est = estimators.summarize_lambda(rec[:, e, :])["lambda"]
        low, high, method, iv = estimators.lambda_ci(est, rec[:, e, :], tail[e], pooled, DBETA)
        assert method == "batch-means" and iv is None and low <= est.mean <= high
    # the pooled tail, as it was: the tiny link's interval left its values' scale
    est = estimators.summarize_lambda(rec[:, 0, :])["lambda"]
    low, high, _, _ = estimators.lambda_ci(est, rec[:, 0, :], tail[0], tail.sum(axis=0), DBETA, links=32)
    assert max(abs(low), abs(high)) > 1e3 * np.abs(x[:, 0]).max()


def test_links_of_one_scale_keep_the_pooled_tail():
    """The calibrated case is unchanged: links that share the heavy model of `_model` at 2,000
    realizations (the calibration runs' size) keep their pooled counts. A link can have more
    than half its values beyond the pooled threshold only when that threshold keeps at least
    n / 2 values, max(40, 0.001 n L, 3.5 L) >= n / 2: with n = 2,000 only for L >= 286 links."""
    rng = np.random.default_rng(4)
    sample, _ = _model(1.5)
    x = np.column_stack([sample(rng, 2000) * s for s in (0.5, 1.0, 2.0, 1.0, 0.7, 1.3)])
    _, tail = estimators.lambda_block_records(x, np.zeros(x.shape, np.int8), np.zeros(x.shape, bool), 100)
    pooled, links = estimators.pooled_tail(tail)
    assert links == 6 and np.array_equal(pooled, tail.sum(axis=0))
