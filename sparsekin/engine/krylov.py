"""Solves with a held factorization of an earlier Jacobian: flexible GMRES, and the solver that reuses it.

On a mesh, one factorization costs as much as tens of solves with it (a lattice of 10^5
bodies: about 1 s against 30–40 ms).  Along a motion the Jacobian changes little from one
sample to the next, so the factorization of an earlier sample, ``P``, is a good
preconditioner of today's Jacobian ``J``: right-preconditioned GMRES on ``J P^-1`` reaches
the accuracy of a direct solve in a few iterations, each one solve with ``P`` and one
product with ``J``.  `ReusingSolver` holds such a factorization, solves every system
(Newton's corrections, velocities, accelerations, the forces' transposed systems) by
`fgmres`, and refactors when an iteration count says the held factorization has gone stale.

Symbols: ``J`` the Jacobian to solve with (the one last given to ``factor``), ``P`` the
held factorization, ``b`` the right-hand side, ``x`` the solution, ``r = b - J x``.
"""

from __future__ import annotations

import math

import numpy as np

from . import _krylov_kernels as _kernels
from .linalg import SingularMatrix

__all__ = ["fgmres", "gmres_workspace", "ReusingSolver", "KRYLOV_TOLERANCE", "MAX_KRYLOV_ITERATIONS",
           "REFACTOR_ITERATIONS", "ROUNDING_DROP"]

#: A solve is accepted when ``||b - J x||_2 <= KRYLOV_TOLERANCE * (||b||_2 + ||J||_1 ||x||_2)``: a
#: backward error of a few units of rounding, what a direct LU reaches (measured on the
#: lattice, docs/design-notes.md, "Factorization reuse").
KRYLOV_TOLERANCE = 1e-15
#: Most GMRES iterations of one solve; beyond them the solver refactors and solves directly.
MAX_KRYLOV_ITERATIONS = 12
#: A solve that needed more iterations than this marks the held factorization stale: the
#: next `ReusingSolver.factor` refactors (docs/design-notes.md, "Factorization reuse").
REFACTOR_ITERATIONS = 4

#: `ReusingSolver`'s factorizations, preconditioners of GMRES, leave out (where the inner
#: solver can: `DissectionSolver`) the entries within this factor of the Jacobian's largest:
#: the rounding left where an exact zero moved (a bar that stays along an axis, its angle
#: Newton's rounding away from 0: on the lattice its sin φ at 1e-21 to 1e-14 from the first
#: steps on, 4 % of the entries).  Kept, they cost as much fill as real entries: at 10^4
#: bodies after 150 steps 0.67 M entries of L + U with them, 0.27 M without
#: (docs/design-notes.md, "Sparse LU on meshes", fourth session).
ROUNDING_DROP = 1e-13


def fgmres(matvec, precondition, rhs, tolerance, max_iterations, out, scale, workspace=None):
    """Right-preconditioned (flexible) GMRES from the preconditioned start ``x0 = P^-1 b``.

    Parameters
    ----------
    matvec : callable
        ``matvec(x)``: ``J @ x``.
    precondition : callable
        ``precondition(v, out)``: ``P^-1 v`` into `out`.
    rhs : ndarray, shape (n,)
    tolerance : float
        Accept ``x`` when ``||b - J x||_2 <= tolerance * (||b||_2 + scale * ||x||_2)``.
    max_iterations : int
    out : ndarray, shape (n,)
        Receives ``x``.
    scale : float
        A norm of ``J`` (its largest column sum).
    workspace : tuple of ndarray, optional
        `gmres_workspace` ``(n, max_iterations)``'s arrays, reused from one call to the
        next (default: made for this call).  Its Krylov basis and directions, made afresh,
        are mapped afresh at every call (above the allocator's mapping threshold): at
        n = 3·10^6 (10^6 bodies) 21.7 ms to make the basis and fill two of its rows,
        against 2.6 ms to fill two rows of a held one.

    Returns
    -------
    int
        Iterations taken (0 when the start was accepted), or -1 if the residual did not
        reach the tolerance within `max_iterations` (`out` then holds the last iterate).
    """
    n = rhs.size
    rhs_norm = _kernels.norm2(rhs)
    if workspace is None:
        workspace = gmres_workspace(n, max_iterations)
    basis, directions, start, work = workspace
    if basis.shape[0] < max_iterations + 1 or basis.shape[1] != n:
        raise ValueError(f"`workspace` is for {basis.shape[1]} unknowns and {basis.shape[0] - 1} iterations, "
                         f"not {n} and {max_iterations}.")  # fmt: skip
    precondition(rhs, out)
    beta = _kernels.residual_into(rhs, matvec(out), basis[0])
    if not math.isfinite(beta):
        return -1
    if beta <= tolerance * (rhs_norm + scale * _kernels.norm2(out)):
        return 0
    basis[0] /= beta
    hessenberg = np.zeros((max_iterations + 1, max_iterations))
    cosines, sines = np.zeros(max_iterations), np.zeros(max_iterations)
    g = np.zeros(max_iterations + 1)
    g[0] = beta
    np.copyto(start, out)
    for j in range(max_iterations):
        precondition(basis[j], directions[j])
        w = matvec(directions[j])
        _kernels.orthogonalize(basis, j, w, hessenberg[:, j])
        for i in range(j):  # the earlier rotations on the new column
            a, b = hessenberg[i, j], hessenberg[i + 1, j]
            hessenberg[i, j] = cosines[i] * a + sines[i] * b
            hessenberg[i + 1, j] = -sines[i] * a + cosines[i] * b
        a, b = hessenberg[j, j], hessenberg[j + 1, j]
        radius = math.hypot(a, b)
        if not radius > 0.0:  # breakdown or NaN
            return -1
        cosines[j], sines[j] = a / radius, b / radius
        hessenberg[j, j], hessenberg[j + 1, j] = radius, 0.0
        g[j + 1] = -sines[j] * g[j]
        g[j] = cosines[j] * g[j]
        # GMRES's estimate |g[j + 1]| of the residual drifts from the true one near
        # rounding: the true residual decides, computed when the estimate may pass.
        if abs(g[j + 1]) <= tolerance * (rhs_norm + scale * _kernels.norm2(start)) or j == max_iterations - 1:
            y = np.linalg.solve(np.triu(hessenberg[: j + 1, : j + 1]), g[: j + 1])
            _kernels.combine(start, directions, y, out)
            true = _kernels.residual_into(rhs, matvec(out), work)
            if true <= tolerance * (rhs_norm + scale * _kernels.norm2(out)):
                return j + 1
            if not math.isfinite(true):
                return -1
    return -1


def gmres_workspace(n: int, max_iterations: int) -> tuple:
    """`fgmres`'s arrays for `n` unknowns and up to `max_iterations` iterations: the Krylov
    basis (rows), the preconditioned directions (rows: flexible GMRES keeps them), the
    start and a residual."""
    return np.empty((max_iterations + 1, n)), np.empty((max_iterations, n)), np.empty(n), np.empty(n)


class ReusingSolver:
    """Solves with the held factorization of an earlier Jacobian, by preconditioned GMRES.

    `factor` takes the Jacobian to solve with (a copy of its values) but keeps the held
    factorization of the inner solver, unless a solve since the last refactorization
    needed more than `refactor_iterations` GMRES iterations (then it refactors now).
    An inner solver that can (one with a ``drop_tolerance``: `DissectionSolver`) leaves the
    Jacobian's entries within `drop_tolerance` of its largest out of those factorizations;
    a factorization without them is a preconditioner only, its solves made by GMRES too.
    `solve` runs `fgmres` with that factorization as the preconditioner to the backward
    error `tolerance`; if GMRES does not get there in `max_iterations`, the solver
    refactors at once and solves directly (by GMRES on the new factors if entries were
    left out, and if that fails too, on a factorization that keeps them).  `solve_held`
    solves with the held factorization alone: chord Newton's corrections, which only need
    to contract.

    Parameters
    ----------
    inner : RefactorSolver or SuperLUSolver
        The solver that factors; it may already hold an analysis of the pattern.
    tolerance : float
        `KRYLOV_TOLERANCE`.
    max_iterations : int
        `MAX_KRYLOV_ITERATIONS`.
    refactor_iterations : int
        `REFACTOR_ITERATIONS`.
    drop_tolerance : float
        `ROUNDING_DROP`; 0 keeps every nonzero entry.
    factored : bool
        Whether `inner` already holds the factorization of the Jacobian that the first
        `factor` will give (a run that switches solvers at a converged sample): that
        factorization is then kept instead of being made again.

    Attributes
    ----------
    n_factorizations, n_refactorizations : int
        The inner solver's, since this one was made.
    n_solves : int
        Right-hand sides solved (a 2-D `rhs` of k columns counts k).
    n_krylov_iterations : int
        GMRES iterations over all solves.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.sparse import csr_array
    >>> from sparsekin.engine.linalg import RefactorSolver
    >>> solver = ReusingSolver(RefactorSolver())
    >>> jacobian = csr_array(np.array([[2.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 4.0]]))
    >>> solver.factor(jacobian)
    >>> jacobian.data *= 1.01  # the next sample's Jacobian: the factorization is kept
    >>> solver.factor(jacobian)
    >>> x = solver.solve(np.ones(3))
    >>> bool(np.allclose(jacobian @ x, 1.0, rtol=0, atol=1e-14)), solver.n_refactorizations
    (True, 0)
    """

    name = "reuse"

    def __init__(
        self,
        inner,
        *,
        tolerance: float = KRYLOV_TOLERANCE,
        max_iterations: int = MAX_KRYLOV_ITERATIONS,
        refactor_iterations: int = REFACTOR_ITERATIONS,
        drop_tolerance: float = ROUNDING_DROP,
        factored: bool = False,
    ) -> None:
        if not (tolerance > 0.0):
            raise ValueError(f"`tolerance` must be positive, got {tolerance!r}.")
        if not (0.0 <= drop_tolerance < 1.0):
            raise ValueError(f"`drop_tolerance` must be in [0, 1), got {drop_tolerance!r}.")
        if isinstance(max_iterations, bool) or not isinstance(max_iterations, (int, np.integer)) or max_iterations < 1:
            raise ValueError(f"`max_iterations` must be a whole number >= 1, got {max_iterations!r}.")
        self.inner = inner
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)
        self.refactor_iterations = int(refactor_iterations)
        self.drop_tolerance = float(drop_tolerance)
        self._drops = self.drop_tolerance > 0.0 and hasattr(inner, "drop_tolerance")
        self._base = (inner.n_factorizations, inner.n_refactorizations)
        self.n_solves = 0
        self.n_krylov_iterations = 0
        self._matrix = None  # the Jacobian of the last `factor`: its values copied
        self._factored = bool(factored)  # the first `factor`'s Jacobian is factored already
        self._held = False  # whether the inner solver holds a factorization
        self._exact = False  # whether that factorization is of `_matrix` itself
        self._stale = False
        self._scale = 1.0
        self._workspace = None  # `fgmres`'s arrays, made at the first solve (`gmres_workspace`)

    @property
    def n_factorizations(self) -> int:
        return self.inner.n_factorizations - self._base[0]

    @property
    def n_refactorizations(self) -> int:
        return self.inner.n_refactorizations - self._base[1]

    def factor(self, jacobian) -> None:
        """Take `jacobian` (square CSR) as the matrix to solve with; refactor only if the
        held factorization went stale (or there is none, or the pattern changed)."""
        from scipy.sparse import csr_array

        matrix = self._matrix
        if (
            matrix is None
            or matrix.shape != jacobian.shape
            or not (matrix.indptr is jacobian.indptr or np.array_equal(matrix.indptr, jacobian.indptr))
            or not (matrix.indices is jacobian.indices or np.array_equal(matrix.indices, jacobian.indices))
        ):
            self._matrix = csr_array((jacobian.data.astype(float), jacobian.indices, jacobian.indptr), shape=jacobian.shape)
            self._column_sums = np.empty(jacobian.shape[1])
            self._transposed = None
            self._held = self._factored
            self._exact = self._factored and getattr(self.inner, "factors_exact", True)
        else:
            np.copyto(matrix.data, jacobian.data)
            self._exact = False
        self._factored = False
        self._transposed_fresh = False  # the transposed operator's values are the last factor's
        matrix = self._matrix
        # max(||J||_1, ||J||_inf): a norm of J and of its transpose, for both kinds of solve
        self._scale = _kernels.largest_line_sum(matrix.indptr, matrix.indices, matrix.data, self._column_sums) or 1.0
        if not self._held or self._stale:
            self._refactor()

    def solve(self, rhs: np.ndarray, out: np.ndarray | None = None, *, transposed: bool = False) -> np.ndarray:
        """Solve ``jacobian @ x = rhs`` (``jacobian.T @ x = rhs`` if `transposed`) for the
        Jacobian of the last `factor`, to the backward error `tolerance`.

        Parameters and returns as `sparsekin.engine.linalg.RefactorSolver.solve`.
        """
        if self._matrix is None or not self._held:
            raise RuntimeError("no factorization: call `factor` first (the last one failed or none was made).")
        rhs = np.asarray(rhs, dtype=float)
        n = self._matrix.shape[0]
        if rhs.ndim not in (1, 2) or rhs.shape[0] != n:
            raise ValueError(f"`rhs` must have shape ({n},) or ({n}, n_rhs), got {rhs.shape}.")
        if out is None:
            out = np.empty(rhs.shape)
        self.n_solves += 1 if rhs.ndim == 1 else rhs.shape[1]
        if self._exact:
            return self.inner.solve(rhs, out=out, transposed=transposed)
        if np.shares_memory(rhs, out):  # GMRES reads the right-hand side to the end
            rhs = rhs.copy()
        columns = [(rhs, out)] if rhs.ndim == 1 else [(rhs[:, c].copy(), np.empty(n)) for c in range(rhs.shape[1])]
        for c, (b, x) in enumerate(columns):
            self._solve_one(b, x, transposed)
            if rhs.ndim == 2:
                out[:, c] = x
        return out

    def solve_held(self, rhs: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Solve with the held factorization alone (an earlier Jacobian's): a chord correction."""
        if not self._held:
            raise RuntimeError("no factorization: call `factor` first (the last one failed or none was made).")
        self.n_solves += 1 if np.ndim(rhs) == 1 else np.shape(rhs)[1]
        return self.inner.solve(rhs, out=out)

    # ------------------------------------------------------------------ internals
    def _refactor(self, drop: bool = True) -> None:
        """Factor the Jacobian of the last `factor`, its rounding-level entries left out
        where the inner solver can (`drop_tolerance`) unless `drop` is false."""
        self._held = self._exact = False
        if self._drops:
            try:
                self.inner.factor(self._matrix, drop_tolerance=self.drop_tolerance if drop else 0.0)
            except SingularMatrix:
                if not drop:
                    raise
                # the entries left out were needed (a tiny inertia beside the largest entry):
                # every entry, as a failing GMRES on dropped factors would ask next
                self.inner.factor(self._matrix, drop_tolerance=0.0)
        else:
            self.inner.factor(self._matrix)
        self._held = True
        self._exact = getattr(self.inner, "factors_exact", True)
        self._stale = False

    def _solve_one(self, rhs: np.ndarray, out: np.ndarray, transposed: bool) -> None:
        matrix = self._matrix
        if transposed:
            if self._transposed is None:
                self._transposed = matrix.T.tocsr()  # its pattern, once; values refreshed below
                self._transposed_map = _transpose_map(matrix)
            operator = self._transposed
            if not self._transposed_fresh:  # once per `factor`, not once per solve
                np.take(matrix.data, self._transposed_map, out=operator.data)
                self._transposed_fresh = True
        else:
            operator = matrix
        inner = self.inner

        def precondition(v, target):
            inner.solve(v, out=target, transposed=transposed)

        n = rhs.size
        if self._workspace is None or self._workspace[2].size != n:
            self._workspace = gmres_workspace(n, self.max_iterations)

        def run_gmres():
            return fgmres(operator.__matmul__, precondition, rhs, self.tolerance, self.max_iterations, out,
                          self._scale, workspace=self._workspace)  # fmt: skip

        iterations = run_gmres()
        if iterations < 0:  # the held factorization is too far off: refactor, solve directly
            self._refactor()
            if not self._exact:  # entries left out: the new factors precondition GMRES
                iterations = run_gmres()
                if iterations >= 0:
                    self.n_krylov_iterations += iterations
                    return self._check_finite(out)
                self._refactor(drop=False)
            inner.solve(rhs, out=out, transposed=transposed)
            return
        self.n_krylov_iterations += iterations
        if iterations > self.refactor_iterations:
            self._stale = True
        self._check_finite(out)

    @staticmethod
    def _check_finite(out: np.ndarray) -> None:
        if not np.all(np.isfinite(out)):
            raise SingularMatrix("the solution is not finite")


def _transpose_map(matrix) -> np.ndarray:
    """For ``matrix.T.tocsr()``: the position in ``matrix.data`` of each of its values."""
    from scipy.sparse import csr_array

    positions = csr_array((np.arange(matrix.nnz, dtype=float) + 1.0, matrix.indices, matrix.indptr), shape=matrix.shape)
    transposed = positions.T.tocsr()
    return transposed.data.astype(np.int64) - 1
