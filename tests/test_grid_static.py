"""Static indicators of power-grid lines (antisync/grids/static.py, docs/power_grids.md): a Braess
example checked against the dynamics, closed forms at P = 0, bridges, and the IEEE 14 grid."""

from __future__ import annotations

from pathlib import Path

import networkx as nx
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from antisync.errors import AntisyncError
from antisync.grids.errors import GridError
from antisync.grids.load import load_grid_config
from antisync.grids.static import grid_state, line_indicators, static_table
from antisync.physics.locked import locked_state

ROOT = Path(__file__).resolve().parent.parent

# --- the Braess example ------------------------------------------------------------------------
#
# Five buses on a line 0 - 1 - 2 - 3 - 4, every line of capacity K = 1.12; generators at 0 and 4
# (P = +1 each), a consumer at 3 (P = -2), 1 and 2 pass power through. The flows are fixed by
# the tree: 1 on every line, towards bus 3, so the largest relative load is 1/K = 0.893 and
# the locked state exists for K >= 1 exactly. The phase of bus 0 is ahead of bus 4 by
# 2 asin(1/K) (three drops against one). Closing the ring with a line 0 - 4 lets power flow
# down that phase difference, 0 -> 4, and on over 4 -> 3, the line next to the consumer that is
# already at 0.893 of its capacity: for K = 1.12 it cannot take the extra flow, and the locked
# state is gone (the ring needs K >= 1.26 with the new line at capacity K). Raising the new
# line's capacity from 0 has the same effect past kappa = 0.133.
K = 1.12
P_BRAESS = np.array([1.0, 0.0, 0.0, -2.0, 1.0])
ADDED = (0, 4)


def braess_grid(kappa: float) -> np.ndarray:
    """The line 0-1-2-3-4 at capacity K, plus the line 0-4 at capacity kappa (0: absent)."""
    w = np.zeros((5, 5))
    for a in range(4):
        w[a, a + 1] = w[a + 1, a] = K
    w[0, 4] = w[4, 0] = kappa
    return w


def stable_state(w, p, **kw) -> bool:
    st = locked_state(w, p, **kw)
    return st is not None and st.stable


def frequency_spread(w, p, theta0, t_end=400.0, inertia=0.0, damping=1.0) -> np.ndarray:
    """Mean frequency of each node over the second half of a long solve_ivp run, minus the
    nodes' mean: zeros when the dynamics frequency-locks, not when some node slips."""
    n = p.size

    def coupling(th):
        return (w * np.sin(th[None, :] - th[:, None])).sum(axis=1)

    if inertia == 0.0:

        def rhs(_t, th):
            return p + coupling(th)

        y0 = theta0
    else:

        def rhs(_t, y):
            th, om = y[:n], y[n:]
            return np.concatenate([om, (p + coupling(th) - damping * om) / inertia])

        y0 = np.concatenate([theta0, np.zeros(n)])
    sol = solve_ivp(rhs, (0.0, t_end), y0, rtol=1e-8, atol=1e-10, dense_output=True)
    assert sol.success
    th = sol.sol(np.array([t_end / 2, t_end]))[:n]
    f = (th[:, 1] - th[:, 0]) / (t_end / 2)
    return f - f.mean()


def critical_coupling(w_unit, p, lo=0.5, hi=3.0) -> float:
    """Smallest scale s with a stable locked state for s * w_unit (bisection)."""
    for _ in range(40):
        mid = (lo + hi) / 2
        if stable_state(mid * w_unit, p):
            hi = mid
        else:
            lo = mid
    return hi


def test_braess_adding_a_line_destroys_the_locked_state_and_the_dynamics_agrees():
    """Braess's paradox in an oscillator network (Witthaut and Timme, New J. Phys. 14, 083036
    (2012)): adding a line to a grid, or raising the capacity of one, can destroy its
    phase-locked state, because the new line's flow follows the phase differences and can pile
    onto a line that is already close to |sin| = 1 (their elementary example and its mechanism).

    This is a construction in the spirit of their elementary example, not their network or
    their numbers: the five-bus line closed into a ring described above. (a) Without the line
    0-4 a stable locked state exists and the first-order dynamics frequency-locks from zero
    phases; (b) with it (capacity K, or raised from 0.1 to 0.15) no stable locked state exists
    (locked_state finds none or an unstable one), the critical coupling rises from 1 to about
    1.26, and the dynamics started in the old operating state does not lock, first order and
    with inertia: the consumer bus 3 slips against the rest.
    """
    p = P_BRAESS
    without, with_line = braess_grid(0.0), braess_grid(K)
    # (a) the tree: flows 1 on every line, stable, K_c = 1 exactly
    st = locked_state(without, p)
    assert st is not None and st.stable
    flows = without * np.sin(st.phi[None, :] - st.phi[:, None])
    assert flows[3, 2] == pytest.approx(1.0) and flows[3, 4] == pytest.approx(1.0)
    assert st.phi[0] - st.phi[4] == pytest.approx(2 * np.arcsin(1 / K))  # 0 leads 4
    assert critical_coupling(without / K, p) == pytest.approx(1.0, abs=1e-6)
    assert np.abs(frequency_spread(without, p, np.zeros(5))).max() < 1e-8
    # (b) adding the line 0-4: no stable locked state, a higher critical coupling
    assert not stable_state(with_line, p)
    assert not stable_state(with_line, p, inertia=1.0, damping=1.0)
    assert critical_coupling(with_line / K, p) == pytest.approx(1.26, abs=0.01)
    # ... or raising its capacity: 0.1 keeps a stable state, 0.15 has none (threshold 0.133)
    assert stable_state(braess_grid(0.10), p) and not stable_state(braess_grid(0.15), p)
    # the dynamics from the old operating state: it does not lock; the consumer slips
    for kw in ({}, {"inertia": 1.0, "damping": 1.0}):
        spread = frequency_spread(with_line, p, st.phi, **kw)
        assert np.abs(spread).max() > 0.1
        assert np.argmin(spread) == 3
    assert np.abs(frequency_spread(braess_grid(0.15), p, st.phi)).max() > 0.1


def test_braess_line_indicators_name_the_added_line():
    """On the grid WITH the line 0-4, removing it (or weakening it by 95%) restores a stable
    locked state: the line is a static Braess line. Removing 2-3 or 3-4 leaves the consumer
    fed by one line of capacity 1.12 < 2, and 0-1, 1-2 give other trees that lock."""
    p = P_BRAESS
    table = line_indicators(braess_grid(K), p, beta=1.0)
    assert not table.base.stable
    assert len(table) == 5
    added = table.row(*ADDED)
    assert added.restores and added.stable
    assert added.max_load == pytest.approx(1 / K)  # the tree's flows back
    assert np.isnan(added.d_margin)  # no change is measured from an unstable state
    braess = [r.line for r in table.braess_lines()]
    assert ADDED in braess
    assert not table.row(2, 3).stable and not table.row(3, 4).stable
    assert table.troublemakers() == []  # nothing stable to destroy
    # weakening instead of removing: kappa = 0.05 K = 0.056 < 0.133
    weak = line_indicators(braess_grid(K), p, beta=0.95, lines=[ADDED])
    assert len(weak) == 1 and weak[0].restores
    # the capacity version: at kappa = 0.1 (stable) the added line is the most loaded ring's
    # Braess line by load: weakening it lowers the largest relative load
    near = line_indicators(braess_grid(0.1), p, beta=0.5)
    assert near.base.stable and near.base.max_load > 0.98
    assert near.row(*ADDED).d_max_load < 0
    assert ADDED in [r.line for r in near.braess_lines()]


# --- sums and closed forms ---------------------------------------------------------------------


def weighted_ring_with_chords(seed=1) -> np.ndarray:
    g = nx.cycle_graph(7)
    g.add_edges_from([(0, 3), (2, 5)])
    rng = np.random.default_rng(seed)
    w = np.zeros((7, 7))
    for u, v in g.edges:
        w[u, v] = w[v, u] = rng.uniform(0.5, 2.0)
    return w


def lambda2(w: np.ndarray) -> float:
    return float(np.sort(np.linalg.eigvalsh(np.diag(w.sum(axis=1)) - w))[1])


def test_no_injections_carry_no_flow_and_the_margin_is_the_laplacians():
    """P = 0: every |sin| = 0 before and after any removal; first order, the margin of each
    network is the second smallest eigenvalue of its Laplacian."""
    w = weighted_ring_with_chords()
    p = np.zeros(7)
    table = line_indicators(w, p)
    assert len(table) == 9  # a ring with two chords has no bridge
    assert table.base.max_load == 0.0 and table.base.max_flow == 0.0
    assert table.base.margin == pytest.approx(lambda2(w), rel=1e-10)
    assert table.base.r == pytest.approx(1.0)
    for row in table:
        assert row.stable and row.max_load == 0.0 and row.max_flow == 0.0
        cut = w.copy()
        a, b = row.nodes
        cut[a, b] = cut[b, a] = 0.0
        assert row.margin == pytest.approx(lambda2(cut), rel=1e-9)
        assert row.lambda2 == row.margin  # first order: the linearization is the Jacobian
        assert row.d_margin < 0  # Rayleigh: removing a line never raises lambda2 at P = 0
    assert table.braess_lines() == []


def test_margin_with_uniform_inertia_is_the_closed_form():
    """m u'' + gamma u' = -L u: the modes are m mu^2 + gamma mu + lambda_k = 0, so the slowest
    nonzero decay rate is (gamma - sqrt(gamma^2 - 4 m lambda_2)) / 2m below gamma^2 / 4m and
    gamma / 2m above (Nishikawa and Motter 2015's linearization, uniform parameters)."""
    w = weighted_ring_with_chords()
    lam = lambda2(w)
    for m, gamma in ((1.0, 3.0), (2.0, 0.5), (0.3, 1.0)):
        expect = (gamma - np.sqrt(max(gamma**2 - 4 * m * lam, 0.0))) / (2 * m)
        st = grid_state(w, np.zeros(7), inertia=m, damping=gamma)
        assert st.margin == pytest.approx(expect, rel=1e-9)
        assert st.lambda2 == pytest.approx(lam, rel=1e-10)
    # per node, all equal, is the uniform case
    st = grid_state(w, np.zeros(7), inertia=np.full(7, 0.5), damping=np.full(7, 3.0))
    assert st.margin == pytest.approx(3.0 - np.sqrt(9.0 - 2.0 * lam), rel=1e-9)


def test_a_bridge_removal_is_refused_with_one_line():
    w = weighted_ring_with_chords()
    big = np.zeros((8, 8))
    big[:7, :7] = w
    big[6, 7] = big[7, 6] = 1.0  # node 7 hangs on 6
    p = np.zeros(8)
    with pytest.raises(GridError, match=r"line 6-7 is a bridge: removing it islands the grid") as e:
        line_indicators(big, p)
    assert "\n" not in str(e.value) and isinstance(e.value, AntisyncError)
    with pytest.raises(GridError, match="line a-b is a bridge"):  # named by the labels
        line_indicators(_path3(), np.zeros(3), labels=["a", "b", "c"])
    skipped = line_indicators(big, p, skip_bridges=True)
    assert skipped.skipped == ((6, 7),) and len(skipped) == 9
    half = line_indicators(big, p, beta=0.5, lines=[(6, 7)])  # weakening a bridge is fine
    assert half[0].stable and half[0].max_load == 0.0
    with pytest.raises(GridError, match="not a line"):
        line_indicators(big, p, lines=[(0, 7)])


def test_bad_requests_are_one_line():
    w, p = weighted_ring_with_chords(), np.zeros(7)
    for beta in (1.5, float("nan"), "x"):
        with pytest.raises(GridError, match="beta must be"):
            line_indicators(w, p, beta=beta)
    with pytest.raises(GridError, match="listed twice"):
        line_indicators(w, p, lines=[(0, 1), (1, 0)])
    with pytest.raises(GridError, match="7 finite injections"):
        line_indicators(w, np.zeros(6))
    with pytest.raises(GridError, match="rank by one of"):
        line_indicators(w, p, lines=[(0, 1)]).ranked("margin")
    # normalized coupling and a lag are accepted
    table = line_indicators(w, p + np.linspace(-0.2, 0.2, 7), coupling="normalized", lag=0.1, beta=0.5)
    assert len(table) == 9 and all(r.stable for r in table)
    # doubling a line (beta = -1) at P = 0 never lowers lambda2 (Rayleigh quotient)
    assert all(r.d_lambda2 >= -1e-12 for r in line_indicators(w, p, beta=-1.0))


def _path3() -> np.ndarray:
    w = np.zeros((3, 3))
    w[0, 1] = w[1, 0] = w[1, 2] = w[2, 1] = 1.0
    return w


# --- IEEE 14 -----------------------------------------------------------------------------------


def test_ieee14_every_line_halved_keeps_a_stable_locked_state():
    """configs/ieee14_grid.yaml (K = 2.5 per line, about twice the critical 1.157, inertia 1,
    damping 1): bus i is node i; halving any of the 20 lines keeps a stable locked state."""
    grid = load_grid_config(ROOT / "configs" / "ieee14_grid.yaml")
    assert grid.labels == list(range(1, 15)) and grid.coupling == "raw"
    assert grid.p.sum() == pytest.approx(0.0, abs=1e-12)
    table = static_table(grid, beta=0.5, skip_bridges=False)
    assert len(table) == 20 and table.base.stable
    assert all(r.stable for r in table)
    assert table.name(table.base.max_load_line) == "1-5"  # a line out of generator bus 1
    # removing: the radial line 7-8 (the synchronous condenser at bus 8) is a bridge
    with pytest.raises(GridError, match="line 7-8 is a bridge"):
        static_table(grid, beta=1.0, skip_bridges=False)
    removed = static_table(grid, beta=1.0)
    assert removed.skipped == ((7, 8),) and len(removed) == 19


def test_ieee300_shipped_operating_point_is_a_stable_locked_state():
    """configs/ieee300_grid.yaml (tools/grid_case.py --case case300): 299 buses (bus 1201, a
    series capacitor without injection, Kron-eliminated into the line 118-120), every line of
    positive capacity, inertia at the 69 generator buses only, and the injections of the solved
    power flow have a stable locked state (docs/power_grids.md, "IEEE 300")."""
    grid = load_grid_config(ROOT / "configs" / "ieee300_grid.yaml")
    assert len(grid.labels) == 299 and 1201 not in grid.labels and grid.labels[-1] == 9533
    i, j = grid.labels.index(118), grid.labels.index(120)
    assert grid.omega[i, j] > 0 and (grid.omega >= 0).all()
    assert int((np.asarray(grid.inertia) > 0).sum()) == 69
    state = grid_state(grid.omega, grid.p, inertia=grid.inertia, damping=grid.damping)
    assert state.exists and state.stable
    assert 0 < state.margin < 0.1 and state.max_load < 0.5


@pytest.mark.parametrize(
    ("config", "count", "dense_calls"),
    [
        # IEEE 118's slow real modes (0.55/s) are faster than its swing modes can be vouched
        # for (locked.vouched_bound: -min(D/m)/2 = -0.5): every margin falls back to dense
        # (every line out: 23 s; these 40 include the largest margin drop, 38-65)
        ("ieee118_grid.yaml", 40, None),
        # IEEE 300's slowest mode (0.07/s) is real and above the bound: sparse throughout
        ("ieee300_grid.yaml", 12, 0),
    ],
)
def test_sparse_matrices_give_the_dense_indicators(monkeypatch, config, count, dense_calls):
    """From locked.SPARSE_FROM nodes on (ACTIVSg2000) Newton's steps use SuperLU, and the
    margins shift-invert Arnoldi where locked.vouched_bound proves the nearest eigenvalues
    enough, else every eigenvalue, dense. Forced on IEEE 118 (every line) and IEEE 300 (a
    dozen lines; all 318: 1e-14 and 12.6x faster, measured when it was written), every line's
    indicators equal the dense eigenvalue problems'."""
    import antisync.grids.static as static
    import antisync.physics.locked as locked

    grid = load_grid_config(ROOT / "configs" / config)
    pairs = np.argwhere(np.triu(grid.omega))[5 : 5 + count]
    if config == "ieee118_grid.yaml":
        pairs = np.argwhere(np.triu(grid.omega))[40 : 40 + count]
    lines = [(grid.labels[a], grid.labels[b]) for a, b in pairs]
    dense = static_table(grid, lines=lines)
    calls = []
    eigvals = np.linalg.eigvals
    monkeypatch.setattr(np.linalg, "eigvals", lambda a: calls.append(a.shape) or eigvals(a))
    monkeypatch.setattr(locked, "SPARSE_FROM", 1)
    monkeypatch.setattr(static, "SPARSE_FROM", 1)
    sparse = static_table(grid, lines=lines)
    assert len(dense) == len(sparse) >= count - 3 and dense.base.stable  # less bridges
    if dense_calls is not None:
        assert len(calls) == dense_calls
    for a, b in zip([dense.base, *dense], [sparse.base, *sparse], strict=True):
        assert (a.exists, a.stable) == (b.exists, b.stable)
        for key in ("margin", "max_flow", "max_load", "r", "lambda2"):
            assert getattr(b, key) == pytest.approx(getattr(a, key), rel=1e-9, abs=1e-12), key


def test_activsg2000_operating_point_is_a_stable_locked_state():
    """configs/activsg2000_grid.yaml (tools/grid_case.py --case ACTIVSg2000): 2,000 buses, 2,667
    lines, inertia at 392 buses, and the published operating point's injections have a stable locked
    state, found on sparse matrices (dense: the same margin to 1e-13, 60x slower)."""
    grid = load_grid_config(ROOT / "configs" / "activsg2000_grid.yaml")
    assert len(grid.labels) == 2000 and int((np.triu(grid.omega) > 0).sum()) == 2667
    assert int((np.asarray(grid.inertia) > 0).sum()) == 392
    state = grid_state(grid.omega, grid.p, inertia=grid.inertia, damping=grid.damping)
    assert state.exists and state.stable
    assert state.margin == pytest.approx(0.158694739611, rel=1e-9)


@pytest.mark.parametrize("sparse_from", [500, 1])
def test_a_stiff_line_does_not_hide_a_locked_state(monkeypatch, sparse_from):
    """A ring with one line of K = 1e5 (ACTIVSg10k's stiffest): the rounding of phi_j - phi_i
    times K keeps |F_i| near 1e-11, above an absolute 10 TOL, and locked_state reported no state.
    The floor scales with the largest row of |w| (locked.rounding_floor): the state is found,
    dense and sparse, a fixed point to that floor, its stiff line nearly rigid, and close to the
    state with that line at K = 1e3."""
    import antisync.physics.locked as locked

    monkeypatch.setattr(locked, "SPARSE_FROM", sparse_from)
    n = 8
    w = np.zeros((n, n))
    for i in range(n):
        w[i, (i + 1) % n] = w[(i + 1) % n, i] = 1.0
    p = np.array([0.9, 0.5, 0.2, -0.1, -0.3, -0.3, -0.4, -0.5])
    p -= p.mean()
    w[4, 5] = w[5, 4] = 1e5
    st = locked_state(w, p)
    assert st is not None and st.stable
    res = locked.residual(st.phi, st.nu, w, p, 0.0)
    assert np.max(np.abs(res)) < locked.rounding_floor(np.abs(w).sum(axis=1)) < 1e-9
    # the stiff line is nearly rigid: its ends' phases agree to P / K
    assert abs(st.phi[5] - st.phi[4]) < 1e-4
    softer = w.copy()
    softer[4, 5] = softer[5, 4] = 1e3
    near = locked_state(softer, p)
    assert np.max(np.abs(near.phi - st.phi)) < 1e-2
