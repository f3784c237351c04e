"""Sign calls over many links: the false discovery rate (antisync.stats.multiplicity)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from antisync.stats.multiplicity import fdr_signs, p_value

Z = 1.959963984540054


def _record(edge: str, value: float, se: float, graph: str = "g") -> dict:
    return {
        "graph": graph,
        "edge": edge,
        "lambda_km": value,
        "lambda_km_ci_low": value - Z * se,
        "lambda_km_ci_high": value + Z * se,
        "lambda_km_ci_level": 0.95,
    }


@settings(max_examples=50, deadline=None)
@given(st.floats(-10, 10), st.floats(1e-6, 5))
def test_the_p_value_reproduces_the_interval_at_its_level(value, se):
    lo, hi = value - Z * se, value + Z * se
    excludes = lo > 0 or hi < 0
    p = p_value(lo, hi)
    if abs(abs(value) / se - Z) > 1e-6:
        assert (p < 0.05) == excludes


def test_one_link_is_called_as_its_interval_says():
    for value, sign in ((0.3, 1), (-0.3, -1), (0.01, 0)):
        assert fdr_signs([_record("1->2", value, 0.1)]) == [sign]


def test_beta_rows_of_one_link_count_once_and_share_the_call():
    recs = [_record("1->2", 0.5, 0.1) | {"beta": b} for b in (0.1, 0.5)] + [{"graph": "g", "lambda_km": None}]
    assert fdr_signs(recs) == [1, 1, None]


def test_null_links_are_rarely_called_where_per_link_intervals_call_many():
    """40 null links, 400 simulated runs: per-link 95% intervals call at least one sign in most
    runs (1 - 0.95^40 = 0.87), the FDR procedure (= the family-wise rate when every link is
    null) in about 5%."""
    rng = np.random.default_rng(7)
    per_link = fdr = 0
    for _ in range(400):
        recs = [_record(f"{k}->{k + 1}", rng.normal(0, 0.1), 0.1) for k in range(40)]
        per_link += any(r["lambda_km_ci_low"] > 0 or r["lambda_km_ci_high"] < 0 for r in recs)
        fdr += any(fdr_signs(recs))
    assert per_link / 400 > 0.8
    assert fdr / 400 < 0.09


def test_strong_links_are_called_among_nulls_at_a_controlled_false_discovery_rate():
    """36 null links and 4 strong ones (8 se from 0), 300 simulated runs: the strong ones are
    always called, and the mean fraction of false calls among the calls stays below q."""
    rng = np.random.default_rng(3)
    fdp = []
    for _ in range(300):
        recs = [_record(f"{k}->{k + 1}", rng.normal(0, 0.1), 0.1) for k in range(36)]
        recs += [_record(f"s{k}", (-1) ** k * rng.normal(0.8, 0.1), 0.1) for k in range(4)]
        signs = fdr_signs(recs)
        assert signs[-4:] == [1, -1, 1, -1]
        calls = sum(map(abs, signs))
        fdp.append(sum(map(abs, signs[:-4])) / calls)
    assert np.mean(fdp) < 0.05


@pytest.mark.parametrize("bad", [None, float("nan")])
def test_a_missing_interval_is_never_called(bad):
    r = _record("1->2", 0.5, 0.1)
    r["lambda_km_ci_low"] = bad
    assert fdr_signs([r]) == [0]
