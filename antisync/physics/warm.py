"""Locked states of a network one line change away from a known one: Newton's method warm-started
from the intact network's locked state (docs/power_grids.md, the static table of a large grid).

:func:`antisync.physics.locked.locked_state` continues Newton's method from the in-phase state of
``P = 0`` to ``P``; a table of line removals (:func:`antisync.grids.static.line_indicators`) does
that once per line. :class:`LineChanges` instead starts Newton's method at the intact network's
locked state and accepts the result only where it is provably the state the continuation is
after, so that a different branch is never taken silently:

- the network is lossless: no phase lag and a symmetric ``W`` (else nothing is warm-started);
- Newton's method converges (every ``|F_i|`` below :data:`~antisync.physics.locked.TOL`, or
  below ``10 TOL`` at the floor of rounding: the continuation's own tests, :func:`_warm_newton`);
- the state is *cohesive*: ``|phi_j - phi_i| < pi / 2`` on every line, the phases as Newton left
  them (not wrapped).

Why that is enough: for a lossless network every locked state has ``nu = sum P / sum g``, and the
locked states are the critical points of ``E(psi) = -sum_lines w_ij cos(psi_j - psi_i) -
sum_i (P_i - g_i nu) psi_i``. On the set of phases with ``|psi_j - psi_i| < pi / 2`` on every
line (an intersection of slabs: convex) the Hessian of ``E`` is the Laplacian with the positive
weights ``w_ij cos(psi_j - psi_i)``, positive definite but for the common shift on a connected
network (a line change that islands it, a bridge removed, is refused: its Jacobian is singular):
``E`` is strictly convex there, so that set holds at most one locked state up to the
shift (and to ``2 pi`` per node: any state whose line differences, wrapped, are below ``pi / 2``
and wind zero times around every cycle, lifts into it). It is the normal operating point: with
``cos > 0`` on every line the Jacobian is a negative weighted Laplacian, so the state is stable
(first order, and with inertia, :func:`~antisync.physics.locked.vouched_bound`). The continuation
from the in-phase state (``psi = 0``, in that set) follows that state as long as its path stays
cohesive; a line change refused here (no convergence, or another state, say a winding or an
unstable one) is left to the continuation by the caller.

Newton's method here (:func:`_warm_newton`) is the continuation's (the unknowns ``phi_1..`` and
``nu``, the same residual and tests) but for reusing a Jacobian while the residual falls tenfold a
step (chord steps) and for ending at the floor of rounding (``10 TOL``, the continuation's final
test) instead of iterating there. Below :data:`~antisync.physics.locked.SPARSE_FROM` nodes the
steps and the eigenvalues are the dense ones of :func:`~antisync.physics.locked.locked_state`.
From it on the work is sparse and reuses what the intact network fixes:

- one fill-reducing order (SuperLU's minimum degree on ``A^T + A``) of the Laplacian grounded at
  node 0, and the intact state's factorization in it, computed once. A step factors the grounded
  ``-J`` (symmetric, positive definite on a cohesive state) in that order and eliminates the
  unknown ``nu``: the continuation's bordered step by one factorization and two solves. The first
  step needs no factorization: at the intact state the changed ``-J`` is the intact one plus a
  rank-one term (Sherman and Morrison), and it serves as the chord until the residual stops
  falling tenfold (on ACTIVSg2000 it reaches the floor: no line is refactored before the end);
- the margin and ``lambda2`` from one grounded factorization at the state: ``lambda2``'s operator
  is the Laplacian's pseudo-inverse (:func:`scipy.sparse.linalg.eigsh`), the margin's the
  linearization's inverse on the complement of the rotation's zero mode (its right and left null
  vectors ``(1, 0)`` and ``(gamma, m)``; :func:`scipy.sparse.linalg.eigs`). Their largest
  eigenvalue is one over the eigenvalue nearest zero but the rotation's, the one
  :func:`~antisync.physics.locked.rightmost` needs: with every eigenvalue of real part above
  :func:`~antisync.physics.locked.vouched_bound` real and not positive, a real one above the bound
  is nearer zero than any other, so when the nearest is above the bound it is the rightmost
  (else every eigenvalue, dense, as there). Arnoldi and Lanczos start from the intact network's
  slowest mode plus a tenth of a fixed random vector (so that every mode is in the start).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph
import scipy.sparse.linalg as spla

from antisync.physics import locked
from antisync.physics.locked import (
    STABLE_MARGIN,
    TOL,
    LockedState,
    _max_real,
    _residual_sparse,
    jacobian,
    linearization,
    residual,
    rightmost,
)

__all__ = ["WARM_EIGS", "WARM_ITER", "LineChanges", "WarmState"]

#: Newton iterations a warm start may take before it is refused (the continuation's own cap is 50
#: per step; from the intact state a line change converges in a handful).
WARM_ITER = 25
#: A Newton step reuses the last Jacobian (a chord step) while the largest ``|F_i|`` falls by this
#: factor per step or more, and refactors the Jacobian where it does not.
CONTRACTION = 0.1
#: How many iterates at the rounding floor (``max |F_i| < 10 TOL``, the continuation's final test)
#: end the iteration when ``TOL`` itself is not reached (it is at about the floor of a large grid).
FLOOR_ITERATES = 3
#: The sparse margin and ``lambda2``: this many of the operators' largest eigenvalues (the ones
#: nearest zero but the rotation's; one is enough, module docstring), Arnoldi's / Lanczos's basis
#: ``WARM_NCV``, from the intact network's slowest mode plus ``START_MIX`` of a random vector.
WARM_EIGS = 1
WARM_NCV = 8
START_MIX = 0.1


@dataclass(frozen=True)
class WarmState:
    """A line change's locked state (``state``), its ``lambda2`` (module docstring of
    :mod:`antisync.grids.static`) and the changed network's lines: ``rows``, ``cols``, ``vals``
    (``w``'s nonzero entries in row-major order, as ``numpy.nonzero`` gives them)."""

    state: LockedState
    lambda2: float
    rows: np.ndarray
    cols: np.ndarray
    vals: np.ndarray


class LineChanges:
    """The locked states of ``w`` with one line ``a - b`` scaled by ``factor`` (both directions),
    warm-started from ``base``, the locked state of ``w`` itself (module docstring).

    :attr:`applies` is False where no warm start is offered (a phase lag, an asymmetric ``w``,
    no intact state): then :meth:`state` is always None.
    """

    def __init__(self, w, p, base: LockedState | None, lag: float = 0.0, inertia=0.0, damping=1.0):
        w = np.asarray(w, dtype=np.float64)
        self.p = np.asarray(p, dtype=np.float64)
        n = self.n = self.p.size
        self.lag = float(lag)
        self.inertia, self.damping = inertia, damping
        self.base = base
        self.applies = base is not None and self.lag == 0.0 and bool(np.array_equal(w, w.T))
        self.sparse = n >= locked.SPARSE_FROM
        self.w = w  # the dense matrix: read, never written (the dense branch copies it)
        r, c = np.nonzero(w)
        self.r, self.c, self.v = r, c, w[r, c]
        self.m = np.broadcast_to(np.asarray(inertia, dtype=np.float64), (n,))
        self.gamma = np.broadcast_to(np.asarray(damping, dtype=np.float64), (n,))
        m, gamma = self.m, self.gamma
        self.g = 1.0 if not (m > 0).any() or np.all(gamma == gamma[0]) else gamma / gamma.mean()
        if self.applies and self.sparse:
            self._prepare_sparse()

    # --- the changed network ----------------------------------------------------------------

    def _entries(self, a: int, b: int) -> np.ndarray:
        """The positions of ``w[a, b]`` and ``w[b, a]`` among the nonzero entries."""
        at = np.flatnonzero((self.r == a) & (self.c == b))
        back = np.flatnonzero((self.r == b) & (self.c == a))
        if at.size != 1 or back.size != 1:
            raise ValueError(f"{a}-{b} is not a line of w")
        return np.array([at[0], back[0]])

    # --- the warm start ------------------------------------------------------------------------

    def state(self, a: int, b: int, factor: float) -> WarmState | None:
        """The locked state of ``w`` with the line ``a - b`` times ``factor``, Newton's method
        from ``base``; None where it is refused (a bridge removed, no convergence in
        :data:`WARM_ITER` steps, a state that is not cohesive, an eigensolver that does not
        converge): the caller continues from ``P = 0`` instead."""
        if not self.applies:
            return None
        if not self.sparse:
            return self._dense_state(a, b, factor)
        try:
            return self._sparse_state(a, b, factor)
        except spla.ArpackError:  # an eigensolver did not converge (ArpackNoConvergence): refused
            return None

    def _cohesive(self, phi, rows, cols) -> bool:
        return bool(np.all(np.abs(phi[cols] - phi[rows]) < np.pi / 2))

    def _dense_state(self, a, b, factor) -> WarmState | None:
        w = self.w.copy()
        w[a, b] *= factor
        w[b, a] *= factor
        if w[a, b] == 0 and csgraph.connected_components(w, directed=False, return_labels=False) > 1:
            return None  # a bridge removed: refused
        g, p, lag = self.g, self.p, self.lag
        n = self.n
        gv = np.broadcast_to(np.asarray(g, dtype=np.float64), (n,))

        def factor_at(phi):
            mat = jacobian(phi, w, lag)
            mat[:, 0] = -gv
            try:
                return sla.lu_factor(mat, check_finite=False)
            except (ValueError, np.linalg.LinAlgError):
                return None

        phi, nu, ok = _warm_newton(
            self.base.phi,
            self.base.nu,
            lambda ph, v: residual(ph, v, w, p, lag, g),
            factor_at,
            lambda lu, f: sla.lu_solve(lu, -f, check_finite=False),
        )
        rows, cols = np.nonzero(w)
        if not ok or not self._cohesive(phi, rows, cols):
            return None
        phi = phi - phi[0]
        r = float(np.abs(np.exp(1j * phi).mean()))
        max_real = _max_real(phi, w, lag, self.inertia, self.damping)
        st = LockedState(phi, float(nu), r, bool(max_real < -STABLE_MARGIN), max_real)
        if np.any(self.m > 0):
            lambda2 = -rightmost(jacobian(phi, w, lag))
        else:
            lambda2 = float(-max_real)
        return WarmState(st, lambda2, rows, cols, w[rows, cols])

    # --- sparse: one grounded order, two solves per Newton step -----------------------------------

    def _prepare_sparse(self) -> None:
        """The grounded Laplacian's pattern (every line of ``w``, node 0 left out) in a
        fill-reducing order, and where each entry's value goes in it."""
        n, r, c = self.n, self.r, self.c
        off = np.flatnonzero((r > 0) & (c > 0))
        self.off = off
        self.row0 = np.flatnonzero(r == 0)  # the lines out of node 0: J_0k
        at = np.arange(n - 1)
        rows = np.concatenate([r[off] - 1, at])
        cols = np.concatenate([c[off] - 1, at])
        ids = np.arange(rows.size, dtype=np.float64) + 1.0
        pattern = sp.csc_matrix((ids, (rows, cols)), shape=(n - 1, n - 1))
        # the order: SuperLU's minimum degree on A^T + A of the intact state's grounded -J
        lu = spla.splu(
            self._grounded(self._weights(self.base.phi, self.v), pattern),
            permc_spec="MMD_AT_PLUS_A",
            options={"SymmetricMode": True},
            diag_pivot_thresh=0.0,
        )
        q = np.argsort(lu.perm_c)
        permuted = pattern[q][:, q].tocsc()
        permuted.sort_indices()
        self.q = q
        self.slots = permuted.data.astype(np.int64) - 1  # CSC slot -> entry (off lines, then diagonal)
        self.indices, self.indptr = permuted.indices, permuted.indptr
        # the intact state's weights and factorization: the first step of every line change
        self.w0 = self._weights(self.base.phi, self.v)
        self.lu0 = self._factor(self.w0)
        if self.lu0 is None:
            self.applies = False
            return
        # the intact network's slowest modes: the line changes' eigensolvers start from them
        try:
            self.start_lambda2 = self._slowest(spla.eigsh, self._lambda2_op(self.lu0))
            gen = self.m > 0
            self.start_margin = self._slowest(spla.eigs, self._margin_op(self.lu0)) if gen.any() else None
        except spla.ArpackError:
            self.applies = False

    def _weights(self, phi, vals):
        return vals * np.cos(phi[self.c] - phi[self.r])

    def _grounded(self, weights, pattern=None):
        """``-J`` without node 0's row and column: diagonal the row sums of ``weights``,
        off the diagonal ``-weights``; in the fill-reducing order (``pattern`` None) or in the
        pattern's own order (once, to find that order)."""
        diag = np.bincount(self.r, weights, minlength=self.n)[1:]
        vals = np.concatenate([-weights[self.off], diag])
        if pattern is not None:
            out = pattern.copy()
            out.data = vals[pattern.data.astype(np.int64) - 1]
            return out
        n1 = self.n - 1
        return sp.csc_matrix((vals[self.slots], self.indices, self.indptr), shape=(n1, n1))

    def _factor(self, weights):
        try:
            return spla.splu(self._grounded(weights), permc_spec="NATURAL")
        except RuntimeError:  # singular
            return None

    def _solve(self, lu, rhs):
        """``x`` of ``K x = rhs`` (``K`` the grounded ``-J``; rows 1..N-1, one or more columns)."""
        q = self.q
        x = np.empty_like(rhs)
        x[q] = lu.solve(np.ascontiguousarray(rhs[q]))
        return x

    def _changed_base(self, a, b, at, vals):
        """The first step's handle without a factorization: the grounded ``-J`` at the intact
        state with the line changed is the intact one plus ``delta (e_a - e_b)(e_a - e_b)^T``,
        solved by the intact factorization and Sherman and Morrison's formula."""
        weights = self._weights(self.base.phi, vals)
        delta = float(weights[at[0]] - self.w0[at[0]])
        u = np.zeros(self.n - 1)
        for node, sign in ((a, 1.0), (b, -1.0)):
            if node > 0:
                u[node - 1] = sign
        z = self._solve(self.lu0, u)
        denom = 1.0 + delta * float(u @ z)
        if not np.isfinite(denom) or abs(denom) < 1e-12:
            return None  # singular: the line was a bridge (refused)

        def solve(rhs):
            y = self._solve(self.lu0, rhs)
            return y - np.multiply.outer(z, u @ y) * (delta / denom)

        return solve, weights

    def _sparse_state(self, a, b, factor) -> WarmState | None:
        at = self._entries(a, b)
        vals = self.v.copy()
        vals[at] = vals[at] * factor  # a removed line stays in the pattern with weight 0
        coo = (self.r, self.c, vals)
        n, p, g = self.n, self.p, self.g
        gv = np.broadcast_to(np.asarray(g, dtype=np.float64), (n,))

        def factor_at(phi):
            weights = self._weights(phi, vals)
            lu = self._factor(weights)
            return None if lu is None else (lambda rhs: self._solve(lu, rhs), weights)

        def step(handle, f):
            solve, weights = handle
            x = solve(np.column_stack([f[1:], gv[1:]]))
            j0 = weights[self.row0]
            k0 = self.c[self.row0] - 1
            dnu = (f[0] + j0 @ x[k0, 0]) / (j0 @ x[k0, 1] + gv[0])
            return np.concatenate([[dnu], x[:, 0] - dnu * x[:, 1]])

        first = self._changed_base(a, b, at, vals)
        if first is None:
            return None
        phi, nu, ok = _warm_newton(
            self.base.phi,
            self.base.nu,
            lambda ph, v: _residual_sparse(ph, v, coo, p, 0.0, g),
            factor_at,
            step,
            first=first,
        )
        keep = vals != 0
        rows, cols, kept = self.r[keep], self.c[keep], vals[keep]
        if not ok or not self._cohesive(phi, rows, cols):
            return None
        phi = phi - phi[0]
        r = float(np.abs(np.exp(1j * phi).mean()))
        weights = self._weights(phi, vals)
        lu = self._factor(weights)
        if lu is None:
            return None
        lam2 = self._lambda2(lu)
        if np.any(self.m > 0):
            max_real = self._rightmost(lu, phi, (rows, cols, kept))
        else:
            max_real = -lam2
        st = LockedState(phi, float(nu), r, bool(max_real < -STABLE_MARGIN), max_real)
        return WarmState(st, lam2, rows, cols, kept)

    def _random(self, size: int) -> np.ndarray:
        return np.random.default_rng(0).random(size)  # a fixed start vector: reproducible digits

    def _slowest(self, solver, op) -> np.ndarray:
        """The eigenvector of ``op``'s largest eigenvalue (real part), unit length."""
        theta, vec = solver(
            op, k=WARM_EIGS, which="LM", tol=1e-12, ncv=WARM_NCV, v0=self._random(op.shape[0])
        )
        v = vec[:, np.argmax(np.abs(theta))].real
        return v / np.linalg.norm(v)

    def _start(self, slowest: np.ndarray) -> np.ndarray:
        """A line change's start vector: the intact network's slowest mode plus
        :data:`START_MIX` of the fixed random vector, so that every mode is in it."""
        rand = self._random(slowest.size)
        return slowest + START_MIX * rand / np.linalg.norm(rand)

    def _lambda2_op(self, lu) -> spla.LinearOperator:
        """The loaded Laplacian's pseudo-inverse (``-J`` at the state factored in ``lu``), on the
        complement of the constant vector: eigenvalues one over ``-J``'s, and 0 for the constant."""
        n = self.n

        def op(x):
            y = x - x.mean()
            u = np.zeros(n)
            u[1:] = self._solve(lu, y[1:])
            return u - u.mean()

        return spla.LinearOperator((n, n), matvec=op, dtype=np.float64)

    def _lambda2(self, lu) -> float:
        """The smallest nonzero eigenvalue of the loaded Laplacian ``-J``: one over the largest
        of its pseudo-inverse."""
        theta = _largest(spla.eigsh, self._lambda2_op(lu), "LA", self._start(self.start_lambda2))
        return float(1.0 / np.max(theta))

    def _margin_op(self, lu) -> spla.LinearOperator:
        """The linearization's inverse on the complement of the rotation's zero mode (right null
        vector ``(1, 0)``, left ``(gamma, m)``): eigenvalues one over the linearization's, and 0
        for the rotation."""
        n, m, gamma = self.n, self.m, self.gamma
        gen = np.flatnonzero(m > 0)
        ell = np.concatenate([gamma, m[gen]])
        total = float(gamma.sum())

        def project(x):
            return np.concatenate([x[:n] - (ell @ x) / total, x[n:]])

        def op(x):
            y = project(x)
            # A (u, v) = y: v = y_gen; J u = gamma y_u + m y_v on the generators' rows
            rhs = gamma * y[:n]
            rhs[gen] += m[gen] * y[n:]
            u = np.zeros(n)
            u[1:] = self._solve(lu, -rhs[1:])  # J u = rhs, u_0 = 0: K u = -rhs
            return project(np.concatenate([u, y[gen]]))

        size = n + gen.size
        return spla.LinearOperator((size, size), matvec=op, dtype=np.float64)

    def _rightmost(self, lu, phi, coo) -> float:
        """:func:`~antisync.physics.locked.rightmost` of the linearization at ``phi``: the
        largest eigenvalues of its inverse on the complement of the rotation's zero mode."""
        theta = _largest(spla.eigs, self._margin_op(lu), "LM", self._start(self.start_margin))
        found = float(np.max((1.0 / theta).real))
        bound = self._bound()
        if bound is not None and found > bound:
            return found
        # not vouched for: every eigenvalue, dense (as rightmost does)
        r, c, v = coo
        n = self.n
        jac = sp.csr_matrix((v * np.cos(phi[c] - phi[r]), (r, c)), shape=(n, n))
        jac = jac - sp.diags(np.asarray(jac.sum(axis=1)).ravel())
        return rightmost(linearization(jac.toarray(), self.inertia, self.damping))

    def _bound(self) -> float:
        """:func:`~antisync.physics.locked.vouched_bound` of a cohesive state of a lossless
        network (every ``cos`` positive): ``-min(gamma / m) / 2`` over the nodes with inertia."""
        gen = self.m > 0
        return -float(np.min(self.gamma[gen] / self.m[gen])) / 2 if gen.any() else -np.inf


def _largest(solver, op, which: str, v0: np.ndarray) -> np.ndarray:
    """The :data:`WARM_EIGS` eigenvalues of ``op`` that ``which`` names, by ``solver``
    (:func:`scipy.sparse.linalg.eigsh` or ``eigs``) from the start vector ``v0``."""
    return solver(op, k=WARM_EIGS, which=which, return_eigenvectors=False, tol=1e-12, ncv=WARM_NCV, v0=v0)


def _warm_newton(phi, nu, f_of, factor, solve, first=None):
    """Newton's method on ``phi_1..phi_{N-1}`` and ``nu`` from ``(phi, nu)`` (as
    :func:`antisync.physics.locked.locked_state`'s, ``phi_0`` fixed): ``factor(phi)`` a handle
    on the bordered Jacobian at ``phi`` (None: singular), ``solve(handle, f)`` the step ``(dnu,
    dphi_1..)`` for the residual ``f``; ``first``: the handle at the start (None: factored).

    A handle is reused (a chord step) while the residual falls by :data:`CONTRACTION` per step,
    refactored where it does not. Converged: ``max |F| < TOL``, or :data:`FLOOR_ITERATES`
    iterates below ``10 TOL`` (the floor of rounding; the continuation accepts ``10 TOL`` after
    its 50 iterations). Returns ``(phi, nu, converged)``."""
    phi = np.array(phi, dtype=np.float64)
    handle = first
    floor = 0
    last = np.inf
    for _ in range(WARM_ITER):
        f = f_of(phi, nu)
        res = float(np.max(np.abs(f)))
        if res < TOL:
            return phi, nu, True
        if res < 10 * TOL:
            floor += 1
            if floor >= FLOOR_ITERATES:
                return phi, nu, True
        elif handle is None or res > CONTRACTION * last:
            handle = factor(phi)
            if handle is None:
                return phi, nu, False
        last = res
        step = solve(handle, f)
        if not np.isfinite(step).all() or np.max(np.abs(step)) > 1e3:
            return phi, nu, False
        phi = phi.copy()
        phi[1:] += step[1:]
        nu = nu + float(step[0])
    return phi, nu, False
