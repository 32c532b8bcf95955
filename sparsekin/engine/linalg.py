"""Linear solvers for the Newton, velocity and acceleration systems, behind one interface.

A linear solver factors the Jacobian (`factor`) and then solves any number of right-hand
sides with that factorization (`solve`): one vector, or several at once as the columns
of a 2-D array, with ``jacobian`` or its transpose, optionally into a preallocated `out`.

* `SuperLUSolver` — scipy's SuperLU, a fresh factorization every time, with the COLAMD
  ordering or (``ordering="metis"``, meshes) METIS's nested dissection computed once per
  pattern.
* `RefactorSolver` — a first SuperLU factorization fixes the ordering and the pivot
  sequence; every later `factor` is a numeric refactorization on the fixed structural
  patterns of L and U (numba kernels in `sparsekin.engine._lu_kernels`), guarded: when the fixed
  pivots turn bad it chooses new row pivots on the same column order
  (`sparsekin.engine._pivoting_kernels`).
* `sparsekin.engine.dense.DenseSolver` — LAPACK's LU with partial pivoting on a dense
  copy, for small models that the compiled loop cannot run (see the dense kernels of
  `sparsekin.engine._lu_kernels` for compiled loops; docs/design-notes.md compares the paths).

All three factor ``A = jacobian.T`` — for a CSR Jacobian that is the CSC array sharing its
memory, which SuperLU takes without a copy — and solve ``jacobian @ x = rhs`` as the
transposed system ``A.T @ x = rhs``.  Counters: ``n_factorizations`` (fresh
factorizations, with their own pivoting), ``n_refactorizations`` (numeric refactorizations
on a fixed pattern; `RefactorSolver` only) and ``n_solves`` (right-hand sides solved).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Protocol

import numpy as np

from . import _compact_lu_kernels, _lu_kernels, _pivoting_kernels, _relative_lu_kernels, compact_factors

if TYPE_CHECKING:
    from scipy.sparse import csc_array, csr_array

__all__ = [
    "LinearSolver",
    "SuperLUSolver",
    "RefactorSolver",
    "SingularMatrix",
    "MIN_PIVOT_RATIO",
    "MAX_GROWTH",
    "ORDERINGS",
    "COORDINATES_PER_BODY",
]

#: Guard of `RefactorSolver`: the smallest accepted ratio of a pivot to the largest
#: candidate of its column (equivalently, max |L| <= 1 / MIN_PIVOT_RATIO): KLU's default
#: pivot tolerance, far below what linkage Jacobians reach along their motions
#: (docs/design-notes.md, "Sparse LU", pitfall 5).
MIN_PIVOT_RATIO = 1e-3
#: Guard of `RefactorSolver`: the largest accepted growth max |U| / max |A|, far above
#: what motions reach and far below what a static pivot order gone bad does (same note).
#: The rounding errors of LU scale with the growth: at 1e3 they stay below about
#: 1e3 · 1.1e-16 ≈ 1e-13 of max |A| (times a small count of terms per entry).
MAX_GROWTH = 1e3
#: `RefactorSolver`'s new pivots after the guard tripped: a column keeps its held pivot row
#: while that is at least this fraction of the column's largest candidate (threshold partial
#: pivoting, UMFPACK's default): the held factors' fill where the held rows still do, and
#: |L| <= 10, far inside the guard (docs/design-notes.md, "New pivots on the held column order").
NEW_PIVOT_THRESHOLD = 0.1
#: The column ordering of every SuperLU factorization (unless ``ordering="metis"``).
_ORDERING = "COLAMD"
#: A body's coordinates (x, y, angle): `SuperLUSolver(ordering="metis")` orders them together.
COORDINATES_PER_BODY = 3
#: The column orderings of `SuperLUSolver` and of `RefactorSolver`'s fresh factorizations.
ORDERINGS = ("colamd", "metis")
_NOT_FACTORED = "no factorization: call `factor` first (the last one failed or none was made)."


def _splu(matrix: csc_array, ordering: str = _ORDERING, *, pivots_only: bool = False):
    """SuperLU of a CSC matrix with `ordering` (`_ORDERING` unless the columns come ordered
    already).  scipy.sparse.linalg is imported here, on the first factorization: a small
    model's run, all in the compiled loop, never loads it.

    `pivots_only`: the caller keeps only the permutations (`RefactorSolver`), so SuperLU
    runs without supernode relaxation and with panels of one column: the same pivots
    (partial pivoting decides column by column) for 40 % of its working memory and in
    0.55 times the time (the 10^5-body chain's saddle matrix: 107 MB instead of 281 MB
    above what was there, 0.52 s instead of 0.93 s, identical ``perm_r`` and ``perm_c``);
    its solves would be slower, which the permutations do not care about."""
    from scipy.sparse.linalg import splu

    if pivots_only:
        return splu(matrix, permc_spec=ordering, relax=1, panel_size=1)
    return splu(matrix, permc_spec=ordering)


class SingularMatrix(RuntimeError):
    """The factorization met an exactly zero pivot or produced non-finite values."""


class LinearSolver(Protocol):
    """What the position, velocity and acceleration solvers need from a linear solver."""

    name: str
    n_factorizations: int
    n_refactorizations: int
    n_solves: int

    def factor(self, jacobian: csr_array) -> None:
        """Factor `jacobian`; raise `SingularMatrix` if it cannot be factored."""
        ...

    def solve(
        self, rhs: np.ndarray, out: np.ndarray | None = None, *, transposed: bool = False
    ) -> np.ndarray:
        """Solve ``jacobian @ x = rhs`` (``jacobian.T @ x = rhs`` if `transposed`)."""
        ...


def _checked_rhs(rhs, n: int, out) -> tuple[np.ndarray, np.ndarray]:
    """`rhs` as a C-contiguous float array of shape (n,) or (n, n_rhs), and `out` checked or made."""
    rhs = np.ascontiguousarray(rhs, dtype=float)
    if rhs.ndim not in (1, 2) or rhs.shape[0] != n:
        raise ValueError(f"`rhs` must have shape ({n},) or ({n}, n_rhs), got {rhs.shape}.")
    if out is None:
        return rhs, np.empty(rhs.shape)
    if not (isinstance(out, np.ndarray) and out.shape == rhs.shape and out.dtype == np.float64
            and out.flags.c_contiguous):  # fmt: skip
        raise ValueError(f"`out` must be a C-contiguous float64 array of shape {rhs.shape}, got "
                         f"{getattr(out, 'shape', type(out).__name__)}.")  # fmt: skip
    return rhs, out


def solve_factored(kernel, factors, rhs: np.ndarray, out: np.ndarray, work: np.ndarray, probe: np.ndarray) -> bool:
    """Solve with the compressed-column factors `factors` by `kernel` (`_lu_kernels.solve_lu`
    or `solve_lu_transposed`) into `out`, a 2-D `rhs` column by column; whether every entry
    of the solution is finite."""
    if rhs.ndim == 1:
        kernel(factors, rhs, work, out, probe)
        return bool(probe[0] == 0.0)
    column = np.empty(rhs.shape[0])
    finite = True
    for c in range(rhs.shape[1]):
        kernel(factors, np.ascontiguousarray(rhs[:, c]), work, column, probe)
        out[:, c] = column
        finite &= bool(probe[0] == 0.0)
    return finite


def has_pattern(matrix, pattern) -> bool:
    """Whether the CSR `matrix` has the pattern ``(indptr, indices)`` (None: no pattern yet)."""
    return pattern is not None and (
        (matrix.indptr is pattern[0] and matrix.indices is pattern[1])
        or (np.array_equal(matrix.indptr, pattern[0]) and np.array_equal(matrix.indices, pattern[1]))
    )


def _index_dtype(largest: int) -> type:
    """int32 when every index value fits (half the memory traffic), int64 otherwise."""
    return np.int32 if largest < np.iinfo(np.int32).max else np.int64


def _same_memory(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether `a` and `b` are the same values in the same memory: one array, or views of it
    alike (``np.array_equal`` made an array of the pattern's size to tell)."""
    return a is b or (a.dtype == b.dtype and a.shape == b.shape and a.strides == b.strides
                      and a.ctypes.data == b.ctypes.data)  # fmt: skip


def _checked_square(jacobian) -> int:
    """The size of `jacobian`, a square CSR array."""
    if not (hasattr(jacobian, "format") and jacobian.format == "csr"):
        raise ValueError(f"`jacobian` must be a scipy.sparse CSR array, got {type(jacobian).__name__}.")
    n, m = jacobian.shape
    if n != m:
        raise ValueError(f"`jacobian` must be square, got shape {jacobian.shape}.")
    return n


class SuperLUSolver:
    """scipy's SuperLU: COLAMD on the CSC view ``jacobian.T`` (no copy, no conversion), or
    the Jacobian in METIS's order of its bodies.

    Parameters
    ----------
    ordering : {"colamd", "metis"}
        ``"colamd"``: SuperLU's COLAMD on ``A = jacobian.T``.  ``"metis"`` (the ``meshes``
        extra): the Jacobian itself, a CSC copy, its coordinates in METIS's nested
        dissection of the graph of the bodies (a body's three coordinates kept together,
        `sparsekin.engine.ordering.fill_reducing_column_order` with ``block=3``), computed
        once per pattern.  On the lattice it has about half COLAMD's fill, and its
        ordering costs a fraction of a factorization (docs/design-notes.md, "Sparse LU on
        meshes").

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.sparse import csr_array
    >>> solver = SuperLUSolver()
    >>> solver.factor(csr_array(np.array([[2.0, 1.0], [0.0, 4.0]])))
    >>> solver.solve(np.array([3.0, 4.0])).tolist()
    [1.0, 1.0]
    """

    name = "superlu"

    def __init__(self, *, ordering: str = "colamd") -> None:
        if ordering not in ORDERINGS:
            raise ValueError(f"`ordering` must be one of {', '.join(map(repr, ORDERINGS))}, got {ordering!r}.")
        self.ordering = ordering
        self._lu = None
        self._order = None  # METIS's column order of the pattern (`_pattern`), once computed
        self._pattern = None  # (indptr, indices) that `_order` was computed for
        self.n_factorizations = 0
        self.n_refactorizations = 0
        self.n_solves = 0

    @property
    def nnz_factors(self) -> int:
        """Entries of SuperLU's last L and U (its nonzeros; no structural zeros kept)."""
        if self._lu is None:
            raise RuntimeError(_NOT_FACTORED)
        return int(self._lu.nnz)

    def factor(self, jacobian: csr_array) -> None:
        """Factor `jacobian` (square CSR); raise `SingularMatrix` if it is exactly singular."""
        self.n_factorizations += 1
        self._lu = None
        try:
            if self.ordering == "metis":
                self._lu = _splu(jacobian.tocsc()[:, self._column_order(jacobian)], "NATURAL")
            else:
                self._lu = _splu(jacobian.T)
        except RuntimeError as error:  # "Factor is exactly singular"
            raise SingularMatrix(str(error)) from error

    def solve(
        self, rhs: np.ndarray, out: np.ndarray | None = None, *, transposed: bool = False
    ) -> np.ndarray:
        """Solve ``jacobian @ x = rhs``, or ``jacobian.T @ x = rhs`` if `transposed`.

        Parameters
        ----------
        rhs : ndarray, shape (n,) or (n, n_rhs)
            One right-hand side, or one per column.
        out : ndarray, optional
            C-contiguous float64 array of the shape of `rhs` to receive the solution.

        Returns
        -------
        ndarray
            The solution, `out` if given.
        """
        if self._lu is None:
            raise RuntimeError(_NOT_FACTORED)
        rhs = np.asarray(rhs, dtype=float)
        if out is not None:
            _checked_rhs(rhs, self._lu.shape[0], out)
        if self.ordering == "metis":
            # The factors are those of ``J Q = jacobian[:, order]``: J x = rhs is
            # ``(J Q) (Q.T x) = rhs``, J.T x = rhs is ``(J Q).T x = Q.T rhs``.
            if transposed:
                solution = self._lu.solve(rhs[self._order], trans="T")
            else:
                permuted = self._lu.solve(rhs, trans="N")
                solution = np.empty_like(permuted)
                solution[self._order] = permuted
        else:  # the factors are those of A = jacobian.T: jacobian @ x = rhs is the transposed system
            solution = self._lu.solve(rhs, trans="N" if transposed else "T")
        if out is not None:
            out[...] = solution
            solution = out
        self.n_solves += 1 if solution.ndim == 1 else solution.shape[1]
        if not np.all(np.isfinite(solution)):
            raise SingularMatrix("the solution is not finite")
        return solution

    def _column_order(self, jacobian: csr_array) -> np.ndarray:
        """METIS's order of the coordinates (the columns of `jacobian`), by bodies when
        they come three by three; computed again only for a new pattern."""
        if not has_pattern(jacobian, self._pattern):
            from .ordering import fill_reducing_column_order

            self._order = self._pattern = None  # until the new order is there
            n = jacobian.shape[1]
            block = COORDINATES_PER_BODY if n % COORDINATES_PER_BODY == 0 else 1
            self._order = fill_reducing_column_order(jacobian, method="metis", block=block)
            self._pattern = (jacobian.indptr.copy(), jacobian.indices.copy())
        return self._order


class RefactorSolver:
    """Numeric refactorization on a fixed pattern, guarded by a fresh SuperLU factorization.

    The first `factor` runs SuperLU on ``A = jacobian.T`` (COLAMD ordering, partial
    pivoting) and keeps only its permutations: ``Pr A Pc = L U`` where row i of A is row
    ``perm_r[i]`` of ``Pr A Pc`` and column c of A is its column ``perm_c[c]``.  From them
    it computes the *structural* patterns of L and U (every entry that can be nonzero with
    this pivot sequence; SuperLU's own L and U drop the values that happen to be zero).
    Every later `factor` with the same pattern refactors numerically on those patterns;
    if a pivot turns zero, non-finite or smaller than `min_pivot_ratio` times the largest
    candidate of its column, or if max |U| / max |A| exceeds `max_growth`, the solver
    chooses new row pivots by threshold partial pivoting on the held column order
    (`sparsekin.engine._pivoting_kernels`: no SuperLU factors held on top of the caller's
    arrays) and analyses them; only a column without a nonzero candidate goes to a fresh
    SuperLU factorization.  A factorization solved often is solved without its exact zeros
    (`sparsekin.engine.compact_factors`); patterns whose rows lie within a byte of their
    column are held as such offsets (`sparsekin.engine._relative_lu_kernels`).

    Parameters
    ----------
    min_pivot_ratio : float
        Guard on the smallest pivot relative to its column (`MIN_PIVOT_RATIO`).
    max_growth : float
        Guard on the growth max |U| / max |A| (`MAX_GROWTH`).
    ordering : {"colamd", "metis"}
        The column order of the fresh factorizations: SuperLU's COLAMD, or METIS's nested
        dissection (`sparsekin.engine.ordering.fill_reducing_column_order`, the
        ``meshes`` extra), computed once per pattern; on meshes it has less fill and
        much faster refactorizations and solves (docs/design-notes.md, "Fill-reducing
        column order").
    lean : bool
        Hold no permuted copy of the pattern (B's row indices, 4 bytes per entry): each
        refactorization reads them through ``perm_r`` from the matrix's own indices
        (`_lu_kernels.refactor_lu_gathered`: the same factors, ~18 % slower on the 10^5-body
        chain's saddle), and on relative patterns finds B's columns through perm_c's
        inverse instead of B's column pointers and offsets (n indices, not 2 n + 1:
        `_relative_lu_kernels.refactor_lu_by_rows`).  For a solver that refactors rarely and
        holds a large pattern (forward dynamics' held iteration matrix).

    Attributes
    ----------
    n_factorizations : int
        Fresh factorizations: new pivoting (SuperLU's, or partial pivoting on the held
        column order after the guard), then the structural analysis.
    n_refactorizations : int
        Numeric refactorizations attempted on the fixed pattern (including those the guard
        rejected, each of which is followed by new pivots: a fresh factorization).
    n_fallbacks : int
        Refactorizations the guard rejected (each followed by new pivots).
    n_solves : int
        Right-hand sides solved (a 2-D `rhs` of k columns counts k).
    pivot_ratio, growth : float
        Smallest pivot ratio and growth of the last numeric factorization.
    layout_version : int
        Incremented whenever `value_positions` changes (a new pattern, or a fresh
        factorization that chose another column order).

    Notes
    -----
    To skip the gather from ``jacobian.data`` at every refactorization, fill the values
    straight into the factor's order and call `factor_ordered`: the entry
    ``jacobian.data[k]`` goes to ``values[solver.value_positions[k]]``, so compose a fill's
    slot map with `value_positions` once (and again whenever `layout_version` changes).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.sparse import csr_array
    >>> jacobian = csr_array(np.array([[2.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 4.0]]))
    >>> solver = RefactorSolver()
    >>> solver.factor(jacobian)
    >>> jacobian.data *= 2.0  # same pattern, new values
    >>> solver.factor(jacobian)
    >>> (solver.n_factorizations, solver.n_refactorizations)
    (1, 1)
    >>> bool(np.allclose(jacobian @ solver.solve(np.ones(3)), 1.0))
    True
    """

    name = "refactor"

    def __init__(
        self,
        *,
        min_pivot_ratio: float = MIN_PIVOT_RATIO,
        max_growth: float = MAX_GROWTH,
        ordering: str = "colamd",
        lean: bool = False,
    ) -> None:
        if ordering not in ORDERINGS:
            raise ValueError(f"`ordering` must be one of {', '.join(map(repr, ORDERINGS))}, got {ordering!r}.")
        if not (0.0 <= min_pivot_ratio <= 1.0):
            raise ValueError(f"`min_pivot_ratio` must be in [0, 1], got {min_pivot_ratio!r}.")
        if not (max_growth >= 1.0):
            raise ValueError(f"`max_growth` must be >= 1, got {max_growth!r}.")
        self.min_pivot_ratio = float(min_pivot_ratio)
        self.max_growth = float(max_growth)
        self.ordering = ordering
        self.lean = bool(lean)
        self._column_order = None  # METIS's order of the analysed pattern, once computed
        self.n_factorizations = 0
        self.n_refactorizations = 0
        self.n_fallbacks = 0
        self.n_solves = 0
        self.pivot_ratio = np.nan
        self.growth = np.nan
        self.layout_version = 0
        self._n = -1
        self._indptr = self._indices = None
        self._l_indices = self._u_indices = None  # L's and U's patterns, made by `_analyse`
        self._relative = None  # their counts when their rows are offsets (`_relative_lu_kernels`)
        self._inverses = None  # (perm_r, perm_c, their inverses) for the compact solves (`_inverse_permutations`)
        self._b_indptr = self._offsets = self._column_of = None  # B's columns in A (`_b_layout`)
        self._factored, self._suggested = False, None
        self._stats = np.zeros(_lu_kernels.N_STATS)
        self._probe = np.zeros(1)

    # ------------------------------------------------------------------ public
    @property
    def value_positions(self) -> np.ndarray:
        """ndarray of int64, shape (nnz,): where ``jacobian.data[k]`` goes in factor order
        (made on the first request after an analysis: 8 bytes per entry that a caller who
        never asks, forward dynamics, does not hold)."""
        self._require_analysis()
        if self._value_positions is None:
            nnz, (b_indptr, offsets) = self._nnz, self._b_layout()
            gather = np.repeat(offsets, np.diff(b_indptr)) + np.arange(nnz, dtype=np.int64)
            self._value_positions = np.empty(nnz, dtype=np.int64)
            self._value_positions[gather] = np.arange(nnz, dtype=np.int64)
        return self._value_positions

    @property
    def perm_r(self) -> np.ndarray:
        """ndarray, shape (n,): row i of ``A = jacobian.T`` is row ``perm_r[i]`` of ``L U``."""
        self._require_analysis()
        return self._perm_r

    @property
    def perm_c(self) -> np.ndarray:
        """ndarray, shape (n,): column c of ``A = jacobian.T`` is column ``perm_c[c]`` of ``L U``."""
        self._require_analysis()
        return self._perm_c

    @property
    def nnz_factors(self) -> int:
        """Entries of L and U in the structural patterns, diagonal counted once."""
        self._require_analysis()
        return self._l_indices.size + self._u_indices.size + self._n

    def suggest(self, perm_r: np.ndarray, perm_c: np.ndarray) -> None:
        """A pivot order for the next new pattern, instead of SuperLU's (`sparsekin.engine.ordering`).

        The next `factor` of a pattern not analysed yet factors on it, under the usual
        guard; if the guard rejects it, SuperLU decides as usual.  The permutations follow
        `perm_r` and `perm_c`'s convention, for ``A = jacobian.T``.
        """
        self._suggested = (np.array(perm_r, dtype=np.int64), np.array(perm_c, dtype=np.int64))  # (copies: held)

    def factor(self, jacobian: csr_array) -> None:
        """Factor `jacobian` (square CSR): refactor if its pattern is the analysed one.

        Raises
        ------
        SingularMatrix
            If a fresh factorization meets an exactly zero or non-finite pivot.
        """
        n = _checked_square(jacobian)
        self._factored = False
        if not self._same_pattern(jacobian, n):
            self._analyse_and_factor(jacobian.T)
            return
        data = jacobian.data if jacobian.data.dtype == np.float64 else jacobian.data.astype(float)
        self.n_refactorizations += 1
        if not (self._numeric(data, False) and self._guard_accepts()):
            self._new_pivots(data, False)
        self._factored = True

    def factor_ordered(self, values: np.ndarray) -> None:
        """Refactor from values given in factor order (see `value_positions`).

        Parameters
        ----------
        values : ndarray, shape (nnz,), float64
            ``values[value_positions[k]]`` is the k-th CSR value of the Jacobian.  Read
            as it is; if the guard trips and a fresh SuperLU factorization decides, it may
            change `value_positions` (see `layout_version`).
        """
        self._require_analysis()
        if not (isinstance(values, np.ndarray) and values.shape == (self._nnz,) and values.dtype == np.float64
                and values.flags.c_contiguous):  # fmt: skip
            raise ValueError(f"`values` must be a contiguous float64 array of shape ({self._nnz},), got "
                             f"{getattr(values, 'shape', type(values).__name__)}.")  # fmt: skip
        self._factored = False
        self.n_refactorizations += 1
        if not (self._numeric(values, True) and self._guard_accepts()):
            self._new_pivots(values, True)
        self._factored = True

    def solve(
        self, rhs: np.ndarray, out: np.ndarray | None = None, *, transposed: bool = False
    ) -> np.ndarray:
        """Solve ``jacobian @ x = rhs``, or ``jacobian.T @ x = rhs`` if `transposed`.

        Parameters
        ----------
        rhs : ndarray, shape (n,) or (n, n_rhs)
            One right-hand side, or one per column (solved column by column).
        out : ndarray, optional
            C-contiguous float64 array of the shape of `rhs` to receive the solution; may
            be `rhs` itself.

        Returns
        -------
        ndarray
            The solution, `out` if given.

        Raises
        ------
        SingularMatrix
            If the solution is not finite.
        """
        if not self._factored:
            raise RuntimeError(_NOT_FACTORED)
        rhs, out = _checked_rhs(rhs, self._n, out)
        # A = jacobian.T: jacobian @ x = rhs is the transposed system of the factors.
        kernels, factors = self._solve_factors(1 if rhs.ndim == 1 else rhs.shape[1])
        kernel = kernels.solve_lu if transposed else kernels.solve_lu_transposed
        if kernel is _compact_lu_kernels.solve_lu_transposed:  # the permutations' inverses: no scatter and gather passes
            kernel, factors = _compact_lu_kernels.solve_lu_transposed_inverted, self._inverse_permutations() + factors[2:]
        self._work_is_zero = False
        finite = solve_factored(kernel, factors, rhs, out, self._work, self._probe)
        self.n_solves += 1 if rhs.ndim == 1 else rhs.shape[1]
        if not finite:
            raise SingularMatrix("the solution is not finite")
        return out

    def solve_pair(self, first: np.ndarray, second: np.ndarray) -> None:
        """Solve ``jacobian @ x = first`` and ``jacobian @ y = second`` in one pass over the
        factors, in place: `first` becomes x and `second` y (each bit for bit what `solve`
        gives; two C-contiguous float64 arrays of shape (n,)).  A triangular solve of a
        chain waits on its own additions: the second right-hand side costs about a sixth of
        a solve (`_lu_kernels.solve_lu_transposed_pair`).

        Raises
        ------
        SingularMatrix
            If a solution is not finite.
        """
        if not self._factored:
            raise RuntimeError(_NOT_FACTORED)
        for array in (first, second):
            _checked_rhs(array, self._n, array)
        if first.ndim != 1 or second.ndim != 1:
            raise ValueError(f"`first` and `second` must have shape ({self._n},).")
        kernels, factors = self._solve_factors(2)
        self._work_is_zero = False
        kernels.solve_lu_transposed_pair(factors, first, second, self._work, self._probe)
        self.n_solves += 2
        if self._probe[0] != 0.0:
            raise SingularMatrix("the solution is not finite")

    # ------------------------------------------------------------------ internals
    def _require_analysis(self) -> None:
        if self._indptr is None:
            raise RuntimeError("no analysis yet: call `factor` with a Jacobian first.")

    def _same_pattern(self, jacobian, n: int) -> bool:
        if self._indptr is None or n != self._n:
            return False
        if _same_memory(jacobian.indptr, self._indptr) and _same_memory(jacobian.indices, self._indices):
            return True  # (the analysed pattern is the CSC view ``jacobian.T``'s: not the same objects)
        return bool(
            np.array_equal(jacobian.indptr, self._indptr) and np.array_equal(jacobian.indices, self._indices)
        )

    def _transposed_csc(self, data: np.ndarray) -> csc_array:
        """``jacobian.T`` as a CSC array with the analysed pattern and the given values."""
        from scipy.sparse import csc_array

        return csc_array((data, self._indices, self._indptr), shape=(self._n, self._n))

    def _analyse_and_factor(self, matrix: csc_array) -> None:
        """A new pattern: take it, then factor afresh; forget it if that fails."""
        if not matrix.has_canonical_format:
            raise ValueError("`jacobian` must have sorted column indices without duplicates (canonical CSR).")
        self._indptr, self._indices = matrix.indptr, matrix.indices
        self._n, self._nnz = matrix.shape[0], matrix.nnz
        self._perm_c = self._column_order = None
        suggested, self._suggested = self._suggested, None
        if suggested is not None and suggested[0].size == self._n and self._factor_on(matrix, *suggested):
            return
        self._perm_c = None
        try:
            self._fresh_factor(matrix)
        except BaseException:
            if self._perm_c is None:  # the analysis did not complete
                self._indptr = self._indices = None
            raise

    def _factor_on(self, matrix: csc_array, perm_r: np.ndarray, perm_c: np.ndarray) -> bool:
        """Analyse and factor with a given pivot order; False if a pivot is bad (guard)."""
        self.n_factorizations += 1
        data = matrix.data if matrix.data.dtype == np.float64 else matrix.data.astype(float)
        self._analyse(perm_r, perm_c, self._nnz, self._nnz)
        if self._numeric(data, False) and self._guard_accepts():
            self._factored = True
            return True
        self.n_fallbacks += 1
        return False

    def _new_pivots(self, values: np.ndarray, in_factor_order: bool) -> None:
        """The guard rejected the held pivots: new rows by threshold partial pivoting on the
        held column order (`NEW_PIVOT_THRESHOLD`), their analysis and factors, without
        SuperLU's factors on top of the caller's arrays (docs/design-notes.md, "New pivots on
        the held column order").  A column without a nonzero finite candidate (a singular or
        non-finite matrix) goes to SuperLU as before, with the held patterns back."""
        self.n_fallbacks += 1
        held_perm_r, l_capacity, u_capacity = self._perm_r, self._l_indices.size, self._u_indices.size
        self._l_indptr = self._u_indptr = self._l_indices = self._u_indices = self._relative = None  # freed first
        self._l_values = self._u_values = self._compact = self._inverses = None
        self._b_indptr, self._offsets = layout = self._b_layout()  # (held until `_analyse` drops them again)
        perm_r, bad_column, l_entries, u_entries = _pivoting_kernels.partial_pivoting_rows(
            values, in_factor_order, layout, self._indices, (held_perm_r, self._perm_c),
            NEW_PIVOT_THRESHOLD, l_capacity + l_capacity // 4, self._zeroed_work()
        )  # (the kernel leaves the work array zero; L a quarter larger than the held factors' mapped,
        # not copied: at the chain's crossing 6 % more, and doubling held 3 of its L at once)
        if bad_column < 0:
            self._analyse(perm_r, self._perm_c, l_entries, u_entries)
            if self._numeric(values, in_factor_order):
                self.n_factorizations += 1
                return
        del perm_r
        self._analyse(held_perm_r, self._perm_c, l_capacity, u_capacity)
        self._fresh_factor(self._transposed_csc(values[self.value_positions] if in_factor_order else values))

    def _fresh_factor(self, matrix: csc_array) -> None:
        """SuperLU with new pivoting, the structural analysis, then the numeric factors."""
        self.n_factorizations += 1
        data = matrix.data if matrix.data.dtype == np.float64 else matrix.data.astype(float)
        # the old factors' values go before SuperLU makes its own factors (held across it,
        # they would add to the peak); their patterns stay, for a refactorization after a
        # failure here
        self._l_values = self._u_values = self._compact = self._inverses = None
        try:
            if self.ordering == "metis":
                lu, perm_c = self._splu_in_column_order(matrix)
            else:
                lu = _splu(matrix, pivots_only=True)
                perm_c = lu.perm_c.copy()  # (copies: SuperLU's arrays hold its factors)
        except RuntimeError as error:  # "Factor is exactly singular"
            if self._l_indices is not None:
                self._allocate_values()
            raise SingularMatrix(str(error)) from error
        perm_r = lu.perm_r.copy()
        capacity = lu.nnz // 2
        del lu
        self._analyse(perm_r, perm_c, capacity, capacity)
        # SuperLU's own pivots: accepted whatever the guard says, unless one is zero or not finite.
        if not self._numeric(data, False):
            column = int(self._stats[_lu_kernels.STAT_BAD_COLUMN])
            if column < 0:
                raise SingularMatrix("the matrix holds non-finite values")
            raise SingularMatrix(f"zero or non-finite pivot in column {column} of the permuted matrix")
        self._factored = True

    def _splu_in_column_order(self, matrix: csc_array):
        """SuperLU of ``matrix[:, order]`` with METIS's column order (computed once per
        pattern) and the ordering it takes as given; ``(lu, perm_c)`` for `matrix`."""
        from .ordering import fill_reducing_column_order

        if self._column_order is None:
            self._column_order = fill_reducing_column_order(matrix, method="metis")
        order = self._column_order
        lu = _splu(matrix[:, order], "NATURAL", pivots_only=True)
        perm_c = np.empty(order.size, dtype=np.int64)
        perm_c[order] = lu.perm_c  # column order[j] of `matrix` is column j of the ordered one
        return lu, perm_c

    def _analyse(self, perm_r: np.ndarray, perm_c: np.ndarray, l_capacity: int, u_capacity: int) -> None:
        """Pattern of ``B = Pr A Pc`` by columns, the maps to A's values, L and U patterns
        (their first allocations: `l_capacity` and `u_capacity` entries)."""
        n, nnz, indices = self._n, self._nnz, self._indices
        index = _index_dtype(max(n, nnz))
        if self._perm_c is None or not np.array_equal(perm_c, self._perm_c):
            self._b_indptr = self._offsets = self._column_of = None  # (`_b_layout` makes them for perm_c)
            self._value_positions = None  # made when asked for (`value_positions`)
            self._perm_c = perm_c.astype(index)
            self.layout_version += 1
        self._b_indptr, self._offsets = self._b_layout()
        self._perm_r = perm_r.astype(index, copy=False)  # (new pivots: the kernel's own array)
        # the last pattern's, freed before the new one is made
        self._l_indptr = self._u_indptr = self._l_indices = self._u_indices = self._relative = None
        self._l_values = self._u_values = self._compact = self._inverses = None
        # B's rows, a permuted copy of the pattern: reading them through perm_r and the
        # matrix's own indices instead made the refactorization 10-30 % slower (10^5 chain);
        # `lean` does, and holds them for the analysis only
        self._b_rows = None
        b_rows = np.empty(nnz, dtype=index)
        _lu_kernels.fill_column_rows(indices, self._offsets, self._b_indptr, self._perm_r, b_rows)
        # (untrimmed: trimming copied L's and U's rows, which the relative patterns then replace)
        l_indptr, l_indices, u_indptr, u_indices = _lu_kernels.analyse_lu_pattern(self._b_indptr, b_rows, l_capacity,
                                                                                   u_capacity, False)  # fmt: skip
        self._b_rows = np.empty(0, dtype=index) if self.lean else b_rows  # lean: freed before the values
        del b_rows
        # rows a byte each where they fit (a local order: the chain's), not 4 (`_relative_lu_kernels`)
        relative = compact_factors.relative_patterns((l_indptr, l_indices[: l_indptr[-1]]),
                                                     (u_indptr, u_indices[: u_indptr[-1]]))  # fmt: skip
        if relative is not None:
            (l_counts, self._l_indices), (u_counts, self._u_indices) = relative
            self._relative, u_indptr = (l_counts, u_counts), None  # (U's columns are read in order)
            if self.lean:  # B's columns found through `column_of` (n entries, not 2 n + 1: `refactor_lu_by_rows`)
                if self._column_of is None:
                    self._column_of = np.empty_like(self._perm_c)
                    _lu_kernels.inverse_permutation(self._perm_c, self._column_of)
                self._b_indptr = self._offsets = None
        else:  # trimmed (no copy where the capacity was exact)
            self._l_indices, self._u_indices = (rows if rows.size == indptr[-1] else rows[: indptr[-1]].copy()
                                                for indptr, rows in ((l_indptr, l_indices), (u_indptr, u_indices)))
        del l_indices, u_indices
        # int32 row pointers when every entry fits (checked on the last, the largest)
        self._l_indptr = l_indptr.astype(_index_dtype(int(l_indptr[-1])), copy=False)
        self._u_indptr = None if u_indptr is None else u_indptr.astype(_index_dtype(int(u_indptr[-1])), copy=False)
        del l_indptr, u_indptr
        self._allocate_values()
        self._u_inverse = np.zeros(n)
        # the refactorization's accumulator (zero between its columns) and the solves'
        # scratch, one array: `_numeric` zeroes it after the solves have used it
        self._work = np.zeros(n)
        self._work_is_zero = True

    def _allocate_values(self) -> None:
        """The factors' values on the structural patterns."""
        self._l_values, self._u_values = np.zeros(self._l_indices.size), np.zeros(self._u_indices.size)
        self._compact = None  # the compact factors' counts and offsets, made when first compacted

    def _zeroed_work(self) -> np.ndarray:
        """The accumulator of a factorization kernel, zero (the solves leave their scratch in
        it); its kernels leave it zero again."""
        if not self._work_is_zero:
            self._work.fill(0.0)
            self._work_is_zero = True
        return self._work

    def _numeric(self, values: np.ndarray, in_factor_order: bool) -> bool:
        """Numeric factorization on the fixed patterns; False on a zero or non-finite pivot."""
        stats = self._stats
        work = self._zeroed_work()
        lower = (self._l_indptr, self._l_indices, self._l_values)
        kernels, u_columns = (_lu_kernels, self._u_indptr) if self._relative is None else (_relative_lu_kernels,
                                                                                            self._relative[1])  # fmt: skip
        upper = (u_columns, self._u_indices, self._u_values, self._u_inverse)
        rows = (self._indices, self._perm_r)
        if self._b_indptr is None and not in_factor_order:  # (lean on relative patterns)
            kernels.refactor_lu_by_rows(values, (self._indptr, self._indices), self._perm_r, self._column_of, lower,
                                        upper, work, stats)  # fmt: skip
        elif self.lean:
            b_indptr, offsets = self._b_layout()
            kernels.refactor_lu_gathered(values, in_factor_order, (b_indptr, self._b_rows, offsets), rows, lower,
                                         upper, work, stats)  # fmt: skip
        else:
            kernels.refactor_lu(values, in_factor_order, (self._b_indptr, self._b_rows, self._offsets), lower, upper,
                                work, stats)  # fmt: skip
        ratio, largest_u, largest_b, bad_column, non_finite = stats.tolist()
        self.growth = largest_u / largest_b if largest_b > 0.0 else math.inf
        if bad_column >= 0 or non_finite != 0.0:
            self.pivot_ratio = 0.0
            return False
        self.pivot_ratio = ratio
        self._solves_since_factor, self._compacted = 0, False
        return True

    def _solve_factors(self, n_rhs: int) -> tuple:
        """The kernels and factors of the next `n_rhs` solves: the structural factors, or after
        `~sparsekin.engine.compact_factors.COMPACT_AFTER_SOLVES` solves of a factorization L
        and U without their exact zeros, compacted in place (the same solutions)."""
        self._solves_since_factor += n_rhs
        if (not self._compacted and self._compact is not False
                and self._solves_since_factor > compact_factors.COMPACT_AFTER_SOLVES):  # fmt: skip
            l_columns, u_columns = (self._l_indptr, self._u_indptr) if self._relative is None else self._relative
            self._compact = compact_factors.compacted((l_columns, self._l_indices, self._l_values),
                                                      (u_columns, self._u_indices, self._u_values), self._compact,
                                                      self._relative is not None)  # fmt: skip
            self._compacted = self._compact is not False
        if self._compacted or self._relative is not None:  # (relative: every entry, the structural solve's steps)
            lower, upper = self._compact if self._compacted else zip(self._relative, (self._l_indices, self._u_indices))
            return _compact_lu_kernels, (self._perm_r, self._perm_c, (*lower, self._l_values),
                                         (*upper, self._u_values, self._u_inverse))  # fmt: skip
        return _lu_kernels, (self._perm_r, self._perm_c, (self._l_indptr, self._l_indices, self._l_values),
                             (self._u_indptr, self._u_indices, self._u_values, self._u_inverse))  # fmt: skip

    def _inverse_permutations(self) -> tuple:
        """The inverses of ``perm_r`` and ``perm_c`` (`_lu_kernels.inverse_permutation`),
        made again when the permutations are new arrays (each `_analyse` makes them)."""
        held = self._inverses
        if held is None or held[0] is not self._perm_r or held[1] is not self._perm_c:
            inverses = (np.empty_like(self._perm_r), self._column_of)  # (a lean solver's: perm_c's inverse)
            _lu_kernels.inverse_permutation(self._perm_r, inverses[0])
            if inverses[1] is None:
                inverses = (inverses[0], np.empty_like(self._perm_c))
                _lu_kernels.inverse_permutation(self._perm_c, inverses[1])
            self._inverses = held = (self._perm_r, self._perm_c, inverses)
        return held[2]

    def _b_layout(self) -> tuple:
        """B's column pointers and offsets (`_lu_kernels.fill_column_layout`): held, or made
        for perm_c where a lean solver holds `_column_of` instead (new pivots, factor order)."""
        if self._b_indptr is not None:
            return self._b_indptr, self._offsets
        layout = np.empty(2 * self._n + 1, dtype=self._perm_c.dtype)  # (one block: mapped, given back whole)
        b_indptr, offsets = layout[: self._n + 1], layout[self._n + 1 :]  # (|offset| < nnz)
        _lu_kernels.fill_column_layout(self._indptr, self._perm_c, b_indptr, offsets)
        return b_indptr, offsets

    def _guard_accepts(self) -> bool:
        return self.pivot_ratio >= self.min_pivot_ratio and self.growth <= self.max_growth
