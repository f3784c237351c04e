"""Block statistics: exact against direct computation, invariant to chunking, honest errors."""

import math

import numpy as np
import pytest

from antisync.kernels.cpu import SimResult
from antisync.stats import estimators
from antisync.status import Status


def _fake_sim(seed=0, m=1000, n_var=3):
    """Per-realization outcomes with all three statuses (real arrays, as a kernel returns)."""
    rng = np.random.default_rng(seed)
    steps0 = rng.integers(2000, 20000, m)
    steps = (steps0[:, None] * rng.uniform(0.7, 1.4, (m, n_var))).astype(np.int64) + 1
    status0 = np.zeros(m, dtype=np.int8)
    status = np.zeros((m, n_var), dtype=np.int8)
    status0[rng.choice(m, 5, replace=False)] = Status.ALREADY_SYNCED
    status[rng.choice(m, 7, replace=False), 1] = Status.NOT_SYNCED
    steps0[status0 == Status.ALREADY_SYNCED] = 0
    return SimResult(status0, steps0, status, steps)


def test_block_records_match_direct_computation():
    sim = _fake_sim()
    dt = 0.001
    rec, rec0, tail = estimators.block_records(sim, dt, block=128)
    for v in range(3):
        ok = (sim.status0 == Status.SYNCED) & (sim.status[:, v] == Status.SYNCED)
        f = sim.steps0[ok] / sim.steps[ok, v]
        s = estimators.summarize_variant(rec[:, v])
        assert s["n"] == ok.sum()
        assert s["F"].mean == pytest.approx(f.mean(), rel=1e-12)
        assert s["F"].se_naive == pytest.approx(f.std(ddof=1) / math.sqrt(f.size), rel=1e-9)
        assert s["tau"].mean == pytest.approx((sim.steps[ok, v] * dt).mean(), rel=1e-12)
        assert s["n_already"] + s["n_not_synced"] + s["n"] == sim.status0.size
        assert tail[v].sum() == ok.sum()
    assert estimators.summarize_variant(rec[:, 1])["n_not_synced"] == 7
    t0 = estimators.summarize_tau0(rec0)
    assert t0["n_already"] == 5
    assert t0["tau0"].mean == pytest.approx(sim.steps0[sim.status0 == 0].mean() * dt, rel=1e-12)


def test_block_records_do_not_depend_on_chunking():
    sim = _fake_sim(m=1000)
    whole = estimators.block_records(sim, 0.001, block=100)
    parts = [
        estimators.block_records(
            SimResult(sim.status0[a:b], sim.steps0[a:b], sim.status[a:b], sim.steps[a:b]), 0.001, 100
        )
        for a, b in [(0, 300), (300, 700), (700, 1000)]
    ]
    assert np.array_equal(whole[0], np.concatenate([p[0] for p in parts]))
    assert np.array_equal(whole[1], np.concatenate([p[1] for p in parts]))
    assert np.array_equal(whole[2], sum(p[2] for p in parts))


def test_batch_means_catch_correlated_blocks():
    """Blocks with different means (non-iid data) must widen the quoted error beyond the naive one."""
    n = np.full(64, 100.0)
    rng = np.random.default_rng(1)
    means = rng.normal(0, 1, 64)  # block-level noise far above the within-block spread
    s = n * means
    s2 = n * (means**2 + 0.01)
    est = estimators.estimate_mean(n, s, s2)
    assert est.se_batch > 5 * est.se_naive
    assert est.se == est.se_batch
    assert est.se_batch == pytest.approx(means.std(ddof=1) / math.sqrt(64), rel=1e-9)


def test_tail_share_separates_light_and_heavy_tails():
    light = np.zeros(estimators.TAIL_BINS, dtype=np.int64)
    heavy = np.zeros(estimators.TAIL_BINS, dtype=np.int64)
    centre = np.searchsorted(estimators.TAIL_EDGES, 0.01)
    light[centre] = 100_000
    heavy[centre] = 100_000
    heavy[np.searchsorted(estimators.TAIL_EDGES, 5.0)] = 100  # 0.1% of samples, 500x larger
    assert estimators.tail_share(light) < 0.01
    assert estimators.tail_share(heavy) > 0.9


def test_histogram_counts_every_valid_pair():
    sim = _fake_sim()
    h = estimators.histogram2d(sim, np.array([0, 1]), 0.001, bins=30, tau_max=15.0)
    for k, v in enumerate([0, 1]):
        ok = (sim.status0 == Status.SYNCED) & (sim.status[:, v] == Status.SYNCED)
        assert h[k].sum() == ok.sum()
    # steps beyond tau_max land in the last row/column
    assert h[0, -1, :].sum() + h[0, :, -1].sum() > 0
