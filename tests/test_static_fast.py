"""Warm-started static tables (antisync/physics/warm.py, antisync/grids/static.py): each line's
locked state by Newton's method from the intact grid's, and its margin and lambda2 from one
grounded factorization, equal today's continuation from P = 0 (``warm=False``) line by line; a
warm start that converges to another state, or to none, falls back to the continuation."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from test_grid_static import P_BRAESS, K, braess_grid, weighted_ring_with_chords

from antisync.grids.load import load_grid_config
from antisync.grids.static import line_indicators, static_table
from antisync.physics import warm
from antisync.physics.locked import _residual_sparse, locked_state

ROOT = Path(__file__).resolve().parent.parent
KEYS = ("margin", "max_flow", "max_load", "r", "lambda2")
# the lines of ACTIVSg2000 whose removal lowers the margin most (the full table, both paths)
TROUBLEMAKERS = [(4195, 4196), (4195, 6239), (5239, 6210), (5120, 5239)]


def assert_same_rows(old, new, rel=1e-9):
    """Every row's state and indicators agree (``rel``); the changes ``d_*`` to ``rel`` of the
    indicator they are a change of (a change is a difference of two close numbers)."""
    assert len(old) == len(new)
    for a, b in zip([old.base, *old], [new.base, *new], strict=True):
        assert (a.exists, a.stable) == (b.exists, b.stable)
        for key in KEYS:
            x, y = getattr(a, key), getattr(b, key)
            assert (math.isnan(x) and math.isnan(y)) or y == pytest.approx(x, rel=rel, abs=1e-300), key
    for a, b in zip(old, new, strict=True):
        assert a.line == b.line and (a.restores, a.destroys) == (b.restores, b.destroys)
        for key in KEYS:
            x, y = getattr(a, f"d_{key}"), getattr(b, f"d_{key}")
            scale = abs(getattr(a, key))
            assert (math.isnan(x) and math.isnan(y)) or abs(x - y) <= rel * scale, key


def test_ieee118_every_line_warm_equals_the_continuation():
    """IEEE 118 (dense: below SPARSE_FROM nodes), every line removed: the warm start finds each
    line's state (none falls back) and every indicator equals the continuation's."""
    grid = load_grid_config(ROOT / "configs" / "ieee118_grid.yaml")
    new = static_table(grid)
    old = static_table(grid, warm=False)
    assert len(new) == 170 and new.continued == ()
    assert old.continued == tuple(r.line for r in old)
    assert_same_rows(old, new)


def _sparse_ieee300(monkeypatch):
    """IEEE 300 with the sparse path forced (as ACTIVSg2000 runs)."""
    import antisync.grids.static as static
    import antisync.physics.locked as locked

    monkeypatch.setattr(locked, "SPARSE_FROM", 1)
    monkeypatch.setattr(static, "SPARSE_FROM", 1)
    return load_grid_config(ROOT / "configs" / "ieee300_grid.yaml")


#: IEEE 300's lines whose removal leaves no locked state
NO_STATE_300 = ((62, 64), (63, 64))


def test_ieee300_sparse_sample_warm_equals_the_continuation(monkeypatch):
    """IEEE 300 on the sparse path, every 13th line and the two whose removal leaves no locked
    state: equal to the continuation's sparse indicators (themselves the dense ones,
    test_grid_static.py); the two fall back to the continuation, which finds none either."""
    grid = _sparse_ieee300(monkeypatch)
    pairs = np.argwhere(np.triu(grid.omega))[1::13]
    lines = [(grid.labels[a], grid.labels[b]) for a, b in pairs] + list(NO_STATE_300)
    new = static_table(grid, lines=lines)
    old = static_table(grid, lines=lines, warm=False)
    assert len(new) >= 25  # the sample's bridges are not in a table of removals
    assert new.continued == NO_STATE_300
    assert not any(new.row(*line).exists for line in new.continued)
    assert_same_rows(old, new)


#: every line (12.4 s of a fresh clone's `make test`) in test-slow: `make test` checks the sample
#: above on the same path, the two fallbacks included
@pytest.mark.slow
def test_ieee300_every_line_sparse_warm_equals_the_continuation(monkeypatch):
    """IEEE 300 on the sparse path, every line removed: equal to the continuation, and only the
    two lines that leave no locked state fall back to it."""
    grid = _sparse_ieee300(monkeypatch)
    new = static_table(grid)
    old = static_table(grid, warm=False)
    assert len(new) == 318
    assert new.continued == NO_STATE_300
    assert not any(new.row(*line).exists for line in new.continued)
    assert_same_rows(old, new)


@pytest.mark.parametrize("beta", [0.5, -1.0])
def test_weakened_and_strengthened_lines_warm_equal_the_continuation(monkeypatch, beta):
    """Halving or doubling a line (bridges included: the grid stays connected), sparse."""
    grid = _sparse_ieee300(monkeypatch)
    pairs = np.argwhere(np.triu(grid.omega))[3::10]
    lines = [(grid.labels[a], grid.labels[b]) for a, b in pairs]
    new = static_table(grid, lines=lines, beta=beta)
    old = static_table(grid, lines=lines, beta=beta, warm=False)
    assert len(new) == len(lines) and new.continued == ()
    assert_same_rows(old, new)


def test_ieee300_dense_sample_warm_equals_the_continuation():
    """IEEE 300 on its own dense path (a sample: every line takes a minute there)."""
    grid = load_grid_config(ROOT / "configs" / "ieee300_grid.yaml")
    pairs = np.argwhere(np.triu(grid.omega))[::25]
    lines = [(grid.labels[a], grid.labels[b]) for a, b in pairs] + [(62, 64)]
    new = static_table(grid, lines=lines)
    old = static_table(grid, lines=lines, warm=False)
    assert new.continued == ((62, 64),)
    assert_same_rows(old, new)


@pytest.fixture(scope="module")
def activsg():
    return load_grid_config(ROOT / "configs" / "activsg2000_grid.yaml")


def test_activsg2000_sample_warm_equals_the_continuation(activsg):
    """ACTIVSg2000 (sparse): the four lines whose removal lowers the margin most and 16 others
    spread over the grid (bridges skipped), warm and continued, to 1e-9 (measured: 1e-13)."""
    grid = activsg
    pairs = np.argwhere(np.triu(grid.omega))[7::167]
    lines = TROUBLEMAKERS + [(grid.labels[a], grid.labels[b]) for a, b in pairs]
    new = static_table(grid, lines=lines)
    old = static_table(grid, lines=lines, warm=False)
    assert len(new) >= 18 and new.continued == () and new.base.stable
    assert_same_rows(old, new)
    for line in TROUBLEMAKERS:
        assert new.row(*line).d_margin < -0.018  # from 0.1587 to at most 0.1399


def test_a_warm_start_to_another_state_is_refused():
    """The Braess ring at kappa = 0.13 (just below the 0.133 where its stable state is lost):
    removing the line 0-4 leaves a tree whose stable state has load 1/K on two lines. Newton's
    method from the ring's state converges, but to a state with a line past pi/2 (unstable, on
    another branch); LineChanges refuses it and the table takes the continuation's stable tree
    state instead."""
    w, p = braess_grid(0.13), P_BRAESS
    base = locked_state(w, p)
    assert base.stable
    changes = warm.LineChanges(w, p, base)
    assert changes.applies
    # the warm Newton iteration by itself: converged, not cohesive
    cut = w.copy()
    cut[0, 4] = cut[4, 0] = 0.0
    coo = np.nonzero(cut) + (cut[np.nonzero(cut)],)
    phi, nu, ok = warm._warm_newton(
        base.phi,
        base.nu,
        lambda ph, v: _residual_sparse(ph, v, coo, p, 0.0),
        lambda ph: ph,  # the handle: the phases, solved densely below
        lambda ph, f: _bordered_step(ph, f, cut),
    )
    assert ok and np.max(np.abs(phi[coo[1]] - phi[coo[0]])) > np.pi / 2
    assert changes.state(0, 4, 0.0) is None
    table = line_indicators(w, p)
    row = table.row(0, 4)
    assert (0, 4) in table.continued and row.stable and row.max_load == pytest.approx(1 / K)
    assert row.d_max_load < 0  # the Braess line by load, as in test_grid_static.py
    # the lines whose removal leaves no locked state: Newton fails, the continuation too
    assert {(0, 1), (1, 2), (2, 3), (3, 4)} <= set(table.continued)
    assert not any(table.row(*line).exists for line in ((0, 1), (1, 2), (2, 3), (3, 4)))


def _bordered_step(phi, f, w):
    from antisync.physics.locked import _dense_step

    return _dense_step(phi, f, w, 0.0, 1.0)


def test_no_warm_start_with_a_lag_or_normalized_coupling():
    """The uniqueness argument is the lossless one: with a phase lag or the (asymmetric)
    normalized coupling every line takes the continuation."""
    w = weighted_ring_with_chords()
    p = np.linspace(-0.3, 0.3, 7)
    for kw in ({"lag": 0.1}, {"coupling": "normalized"}):
        table = line_indicators(w, p, **kw)
        assert len(table.continued) == len(table) == 9
    plain = line_indicators(w, p)
    assert plain.continued == ()
    assert_same_rows(line_indicators(w, p, warm=False), plain)


@pytest.mark.parametrize("sparse_from", [500, 1])
def test_a_bridge_removed_is_refused(monkeypatch, sparse_from):
    """Removing a bridge islands the grid (the uniqueness argument needs it connected):
    LineChanges refuses it, dense and sparse; halving it is fine."""
    import antisync.physics.locked as locked

    monkeypatch.setattr(locked, "SPARSE_FROM", sparse_from)
    big = np.zeros((8, 8))
    big[:7, :7] = weighted_ring_with_chords()
    big[6, 7] = big[7, 6] = 1.0  # node 7 hangs on 6
    p = np.linspace(-0.2, 0.2, 8)
    changes = warm.LineChanges(big, p, locked_state(big, p))
    assert changes.applies and changes.sparse == (sparse_from == 1)
    assert changes.state(6, 7, 0.0) is None
    assert changes.state(6, 7, 0.5) is not None and changes.state(0, 1, 0.0) is not None
