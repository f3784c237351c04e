"""The synchronized fraction's response to damage (issue 14, item 7): n_lost and n_gained per
link, dP_sync/dbeta with its interval, and what every Kuramoto number is conditioned on.

A ring has stable twisted states, so random starts on it do not all synchronize; a large
damage (dbeta 0.3) and a short t_max make realizations cross in and out of synchronization
often enough to count.
"""

from __future__ import annotations

import json
import math

import h5py
import numpy as np
import pytest
from scipy.stats import chi2

import antisync
from antisync.errors import StoreError
from antisync.report.figures import conditioning_note
from antisync.stats import estimators
from antisync.status import NOT_SYNCED, SYNCED
from antisync.store import read_views

RING = {
    "graph": {"kind": "networkx", "generator": "cycle_graph", "args": {"n": 10}},
    "edges": ["0->1", "3->4"],
    "betas": [],
    "lambda": {"dbeta": 0.3},
    "dynamics": {"integrator": "rk4", "dt": 0.04, "t_max": 12.0},
    "seed": 5,
}


@pytest.fixture(scope="module")
def ring(tmp_path_factory):
    out = tmp_path_factory.mktemp("ring") / "ring.h5"
    res = antisync.run({**RING, "keep_pairs": 400}, realizations=400, output=out)
    return out, res.records


def test_counts_equal_a_direct_count_of_the_kept_statuses(ring):
    """Per link: lost = tau0 synchronized and tau(dbeta) not, gained = the reverse, counted
    by hand from every realization's stored statuses."""
    path, records = ring
    with h5py.File(path, "r") as f:
        (g,) = f["jobs"].values()
        s0, s = g["kept/status0"][...], g["kept/status"][...]
        edges = json.loads(g.attrs["edges"])
        v_edge, v_beta = g["variant_edge"][...], g["variant_beta"][...]
    by_edge = {r["edge"]: r for r in records}
    total_flips = 0
    for e, label in enumerate(edges):
        (v,) = np.flatnonzero((v_edge == e) & np.isclose(v_beta, 0.3))
        lost = int(np.sum((s0 == SYNCED) & (s[:, v] == NOT_SYNCED)))
        gained = int(np.sum((s0 == NOT_SYNCED) & (s[:, v] == SYNCED)))
        r = by_edge[label]
        assert (r["p_sync_lost"], r["p_sync_gained"]) == (lost, gained)
        assert r["p_sync_response"] == pytest.approx((gained - lost) / (400 * 0.3), abs=1e-15)
        assert r["p_sync_response_ci_low"] <= r["p_sync_response"] <= r["p_sync_response_ci_high"]
        total_flips += lost + gained
    assert total_flips >= 20, total_flips  # the setup really moves realizations across
    # what the Kuramoto numbers are conditioned on
    n_sync0 = int(np.sum(s0 != NOT_SYNCED))
    assert 0 < n_sync0 < 400
    assert records[0]["p_sync"] == pytest.approx(n_sync0 / 400)
    assert records[0]["lambda_km_fraction"] == pytest.approx(records[0]["lambda_n"] / 400)


def test_summary_and_figures_say_what_the_numbers_are_conditioned_on(ring):
    path, records = ring
    (view,) = read_views(path)
    note = conditioning_note(view)
    assert note is not None and f"P_sync = {records[0]['p_sync']:.3f}" in note
    from antisync.report.tables import format_records

    text = format_records(records)
    assert "dPsync" in text.splitlines()[0]
    assert "conditioned on synchronizing" in text


def test_closed_form_of_the_interval():
    """Counts 7 gained, 3 lost in 1000 realizations at dbeta 0.01: value 0.4; the ends are
    Garwood bounds at 97.5% two-sided each (the two misses add to at most 5%)."""
    rec = np.zeros((2, len(estimators.LAMBDA_FIELDS)))
    rec[0, :3] = (600, 0, 100)
    rec[1, :3] = (250, 50, 0)
    rec[0, 6], rec[1, 7], rec[1, 6] = 2, 7, 1
    r = estimators.sync_response(rec, 0.01)
    assert (r["lost"], r["gained"], r["n"]) == (3, 7, 1000)
    assert r["value"] == pytest.approx(0.4)
    g_lo, g_hi = chi2.ppf(0.0125, 14) / 2, chi2.ppf(0.9875, 16) / 2
    l_lo, l_hi = chi2.ppf(0.0125, 6) / 2, chi2.ppf(0.9875, 8) / 2
    assert r["low"] == pytest.approx((g_lo - l_hi) / 10)
    assert r["high"] == pytest.approx((g_hi - l_lo) / 10)
    # no flip at all is not a response of exactly 0: about 4.4 / (N dbeta) either way
    rec[:, 6:] = 0
    z = estimators.sync_response(rec, 0.01)
    assert z["value"] == 0 and z["high"] == pytest.approx(-math.log(0.0125) / 10) and z["low"] == -z["high"]


def test_interval_coverage_on_synthetic_flips():
    """Fixed seed, 400 runs of 2000 realizations with known flip probabilities: the interval
    holds the exact response at least 95% of the time (it is conservative by construction)."""
    rng = np.random.default_rng(42)
    p_gain, p_lose, dbeta, n = 0.003, 0.0015, 0.01, 2000
    truth = (p_gain - p_lose) / dbeta
    hits = 0
    for _ in range(400):
        u = rng.random(n)
        rec = np.zeros((1, len(estimators.LAMBDA_FIELDS)))
        rec[0, 0] = n
        rec[0, 7], rec[0, 6] = np.sum(u < p_gain), np.sum(u > 1 - p_lose)
        r = estimators.sync_response(rec, dbeta)
        hits += r["low"] <= truth <= r["high"]
    assert 0.95 <= hits / 400 <= 1.0


def test_derivative_estimators_report_no_response(tmp_path):
    """The adjoint integrates no damaged network, so it cannot see one fail to synchronize."""
    res = antisync.run({**RING, "lambda": {"method": "adjoint"}}, realizations=100, output=tmp_path / "a.h5")
    for r in res.records:
        assert r["p_sync_response"] is None and r["p_sync_lost"] is None
        assert 0 < r["p_sync"] < 1


def test_a_format2_file_reads_with_unknown_counts(tmp_path, ring):
    """A file written before the counts (format 2, six Lambda fields) still gives records, with
    the response unknown (None), never 0."""
    path, records = ring
    old = tmp_path / "old.h5"
    old.write_bytes(path.read_bytes())
    with h5py.File(old, "r+") as f:
        f.attrs["format_version"] = 2
        (g,) = f["jobs"].values()
        rec = g["lambda_records"][...][..., :6]
        del g["lambda_records"]
        g.create_dataset("lambda_records", data=rec)
    got = antisync.load(old).records
    assert [r["lambda_km"] for r in got] == [r["lambda_km"] for r in records]
    assert all(r["p_sync_response"] is None and r["p_sync"] == records[0]["p_sync"] for r in got)
    # resuming it is refused with one line naming why, and leaves it untouched
    before = old.read_bytes()
    with pytest.raises(StoreError, match="older antisync \\(format 2"):
        antisync.run({**RING, "keep_pairs": 400}, realizations=400, output=old, resume=True)
    assert old.read_bytes() == before
