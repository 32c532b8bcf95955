"""`DissectionSolver`: the LU of a mesh's Jacobian in a nested-dissection order of its bodies.

On a mesh the first sample is one factorization and every step is solves with it (the
run reuses it across samples: `sparsekin.engine.krylov.ReusingSolver`).  This solver cuts
both costs down to SuperLU's own:

* the order is free: a nested dissection of the bodies' graph with geometric cuts
  (`sparsekin.engine.ordering.geometric_column_order`, from where the bodies are drawn),
  computed once per pattern in O(n log n), where METIS's order cost as much as a
  factorization at 10^6 bodies;
* SuperLU factors the Jacobian's columns in that order (``permc_spec="NATURAL"``: its own
  partial pivoting and supernodes, in panels of `PANEL_SIZE` columns with relaxed
  supernodes of `RELAXED_SUPERNODE` columns), the Jacobian's exact zeros left out (a
  fresh factorization each time: nothing needs room for them later);
* the factors are taken out of SuperLU once, its supernodal storage dropped, and the
  solves run on them by numba kernels (`_lu_kernels.solve_lu_rows` through
  `sparsekin.engine.linalg.solve_factored`): L by compressed columns, U by rows stored
  last row first, so that both sweeps of a solve stream the factors front to back (at
  10^6 bodies half the time of the same factors by columns, `_lu_kernels.solve_lu`),
  faster than SuperLU's own solves with the permutations of its Python wrapper; a
  transposed solve reads U by columns, made back from the rows when one is first asked.

With a drop tolerance (a caller that checks its solutions: GMRES in
`sparsekin.engine.krylov.ReusingSolver`), a `factor` after the first refactors
numerically with the last fresh factorization's pivots held (`_lu_kernels.refactor_lu`
on the structural pattern of the entries kept, the exact zeros and the rounding-level
entries left out: analysed once per such pattern — along a motion the drawing's, then
every moved pose's —, its exact zeros then left out of the factors the solves read),
guarded like `RefactorSolver`'s (`MIN_PIVOT_RATIO`, `MAX_GROWTH`): at 10^4 bodies 11 ms
against 55 ms for SuperLU afresh, at 10^5 0.23 s against 1.4 s (the first at a moved pose,
with the drawing's pivots and its analysis, 1.0 s).  Any other `factor` is a fresh SuperLU
factorization (its pivoting its own), as is one whose refactorization the guard rejects;
a refactorization's factors are `factors_exact` False.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from . import _lu_kernels
from .linalg import (
    COORDINATES_PER_BODY,
    MAX_GROWTH,
    MIN_PIVOT_RATIO,
    SingularMatrix,
    _checked_rhs,
    _checked_square,
    _index_dtype,
    has_pattern,
    solve_factored,
)

if TYPE_CHECKING:
    from scipy.sparse import csr_array

__all__ = ["DissectionSolver", "PANEL_SIZE", "RELAXED_SUPERNODE"]

#: SuperLU's panel size and relaxed-supernode size in the dissection's order.  Its defaults
#: were 1.3–1.5 times slower than these on the lattice at 3·10^5 bodies (three interleaved
#: rounds, one process: 7.3–8.5 s against 5.4–5.6 s; COLAMD 5.6–6.3 s) and 1.2 times at
#: 10^5; other pairs tried (relax 1, 2, 8; panel 2, 8) were not faster.
PANEL_SIZE = 4
RELAXED_SUPERNODE = 4

#: `_lu_kernels.refactor_lu`'s per-column offsets, unused: the refactorization gathers the
#: kept entries into B's column order first.
_NO_OFFSETS = np.zeros(0, dtype=np.int64)
_NOT_FACTORED = "no factorization: call `factor` first (the last one failed or none was made)."


class DissectionSolver:
    """SuperLU on the Jacobian's coordinates in a geometric nested dissection of its bodies,
    solves on its factors by numba kernels.

    Parameters
    ----------
    points : array_like, shape (n_bodies, 2)
        Where each body is drawn (its origin): the places the dissection cuts between.
        The Jacobian's columns are the bodies' coordinates, `COORDINATES_PER_BODY` a body.
        A square matrix with more columns is a saddle matrix of forward dynamics
        (`sparsekin.engine.saddle`), structurally symmetric: its first unknowns the
        coordinates, then one multiplier per kept equation, which goes with the body of
        the first coordinate in its row (`_saddle_groups`); the bodies' unknowns are
        ordered by the same dissection of the bodies.
    take_out_factors : bool
        Solve on L and U taken out of SuperLU by numba kernels (default: worth its cost
        where a factorization serves many solves, the kinematics' reuse across samples), or
        with SuperLU's own solves (forward dynamics, which factors its saddle matrix
        about once a step on a moving lattice: taking the factors out cost a third of
        the factorization there).
    drop_tolerance : float
        Leave out of every factorization the entries of magnitude at most this factor of
        the Jacobian's largest (default 0: only the exact zeros): the factors are then
        those of a nearby matrix, for a caller that checks its solutions (GMRES on the
        held factors: `sparsekin.engine.krylov.ReusingSolver` passes its
        `~sparsekin.engine.krylov.ROUNDING_DROP` to `factor`); `factors_exact` tells whether
        an entry was left out.  With it, every `factor` after the first is refactored
        numerically with the last fresh factorization's pivots held.

    Attributes
    ----------
    n_factorizations, n_refactorizations, n_solves : int
        As every linear solver's (`sparsekin.engine.linalg`): fresh SuperLU factorizations,
        numeric refactorizations on a held pattern (those the guard rejected included), solves.
    n_fallbacks : int
        Refactorizations the guard rejected (each followed by a fresh factorization).
    factors_exact : bool
        Whether the last factorization is of the Jacobian itself by SuperLU's partial
        pivoting (no nonzero entry left out by `drop_tolerance`, not a refactorization).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.sparse import csr_array
    >>> solver = DissectionSolver([[0.0, 0.0], [1.0, 0.0]])
    >>> jacobian = csr_array(np.eye(6) * 2.0 + np.eye(6, k=3))
    >>> solver.factor(jacobian)
    >>> solver.solve(np.full(6, 2.0)).tolist()
    [0.5, 0.5, 0.5, 1.0, 1.0, 1.0]
    """

    name = "dissection"

    def __init__(self, points, take_out_factors: bool = True, drop_tolerance: float = 0.0) -> None:
        points = np.asarray(points, dtype=float)
        if points.ndim != 2 or points.shape[1] != 2:
            raise ValueError(f"`points` must have shape (n_bodies, 2), got {points.shape}.")
        if not (0.0 <= drop_tolerance < 1.0):
            raise ValueError(f"`drop_tolerance` must be in [0, 1), got {drop_tolerance!r}.")
        self.drop_tolerance = float(drop_tolerance)
        self.factors_exact = True
        self.points = points
        self._order = None  # the column order of the pattern `_pattern`, once computed
        self._ordered = None  # (indptr, indices, gather): J[:, order] in CSC is (J.data[gather], indices, indptr)
        self._pattern = None
        self._factors = None
        self._transposed_factors = None  # the factors with U by columns, made at a transposed solve
        self._lu = None  # SuperLU's own factorization, when the factors are not taken out
        self.take_out_factors = bool(take_out_factors)
        self._n = 0
        self._held = None  # the last fresh factorization's pivots and kept entries (`_HeldPivots`)
        self.n_factorizations = 0
        self.n_refactorizations = 0
        self.n_fallbacks = 0
        self.n_solves = 0

    @property
    def nnz_factors(self) -> int:
        """Entries of the last L and U (SuperLU's nonzeros, the diagonals included)."""
        if self._lu is not None:
            return int(self._lu.nnz)
        if self._factors is None:
            raise RuntimeError(_NOT_FACTORED)
        _, _, (l_indptr, _, _), (u_indptr, _, _, _) = self._factors
        return int(l_indptr[-1] + u_indptr[-1] + 2 * self._n)

    def factor(self, jacobian: csr_array, *, drop_tolerance: float | None = None) -> None:
        """Factor `jacobian` (square CSR, its columns the bodies' coordinates in turn), its
        entries within `drop_tolerance` (default: the solver's) of its largest left out;
        raise `SingularMatrix` if it is exactly singular or not finite."""
        drop = self.drop_tolerance if drop_tolerance is None else float(drop_tolerance)
        n = _checked_square(jacobian)
        self._factors = self._lu = self._transposed_factors = None
        order = self._column_order(jacobian)
        if not np.all(np.isfinite(jacobian.data)):
            self.n_factorizations += 1
            raise SingularMatrix("the Jacobian has entries that are not finite")
        data = jacobian.data.astype(float, copy=False)
        # The Jacobian's exact zeros (a bar along an axis at the drawing: a third of the
        # lattice's entries at t = 0) left out: SuperLU's fill and work follow its pattern,
        # and a fresh factorization needs no room for them (a refactorization on a fixed
        # pattern would); 0.41x COLAMD's time at 3·10^5 bodies instead of 1.4x.  With
        # `drop`, the rounding-level entries too.
        magnitudes = np.abs(data)
        kept = magnitudes > drop * magnitudes.max() if data.size else magnitudes > 0.0
        exact = drop == 0.0 or not np.any(~kept & (magnitudes > 0.0))
        held = self._held
        if drop > 0.0 and held is not None:
            if not np.array_equal(kept, held.kept):  # other entries kept: the held pivots on their pattern
                held = _HeldPivots(kept, held.perm_r, held.perm_c, held.entries)
            self.n_refactorizations += 1
            factors = held.refactor(jacobian, data)
            if factors is not None:
                self._held, self._factors, self._n, self.factors_exact = held, factors, n, False
                return
            self.n_fallbacks += 1
        self.n_factorizations += 1
        self._held = None
        self.factors_exact = exact
        from scipy.sparse import csc_array
        from scipy.sparse.linalg import splu

        indptr, indices, gather = self._ordered
        values = np.take(data, gather)
        values[~kept[gather]] = 0.0
        # (a copy of the held pattern: eliminate_zeros works in place)
        ordered = csc_array((values, indices.copy(), indptr.copy()), shape=jacobian.shape, copy=False)
        ordered.eliminate_zeros()
        try:
            lu = splu(ordered, permc_spec="NATURAL", relax=RELAXED_SUPERNODE, panel_size=PANEL_SIZE)
        except RuntimeError as error:  # "Factor is exactly singular"
            raise SingularMatrix(str(error)) from error
        self._n = n
        if not self.take_out_factors:
            self._lu = lu
            return
        # SuperLU: Pr (J Q) Pc = L U with Q = the order; as one column permutation of J,
        # column order[k] of J goes to position perm_c[k].
        perm_c = np.empty(n, dtype=np.int64)
        perm_c[order] = lu.perm_c
        perm_r = lu.perm_r.astype(np.int64)
        entries = int(lu.nnz)
        lower, upper = lu.L, lu.U
        del lu  # its supernodal storage: the factors live on as compressed columns
        unit = np.empty(n)
        l_indptr = _lu_kernels.split_off_diagonal(lower.indptr, lower.indices, lower.data, unit)
        diagonal = np.empty(n)
        u_indptr = _lu_kernels.split_off_diagonal(upper.indptr, upper.indices, upper.data, diagonal)
        with np.errstate(divide="ignore"):
            u_inverse = 1.0 / diagonal
        if not np.all(np.isfinite(u_inverse)):
            raise SingularMatrix("a pivot of the factorization is zero or not finite")
        held = _HeldPivots(kept, perm_r, perm_c, entries)
        u_rows = _rows_last_first(u_indptr, upper.indices, upper.data)
        del upper  # U by columns: the solves read it by rows
        self._factors = (held.row_of, held.column_of, (l_indptr, lower.indices, lower.data), u_rows + (u_inverse,))
        self._held = held
        self._work = np.empty(n)
        self._probe = np.zeros(1)

    def solve(
        self, rhs: np.ndarray, out: np.ndarray | None = None, *, transposed: bool = False
    ) -> np.ndarray:
        """Solve ``jacobian @ x = rhs``, or ``jacobian.T @ x = rhs`` if `transposed`: one
        right-hand side, or one per column of a 2-D `rhs`, optionally into `out` (which may
        be `rhs`); parameters, returns and errors as `RefactorSolver.solve`'s."""
        if self._factors is None and self._lu is None:
            raise RuntimeError(_NOT_FACTORED)
        rhs, out = _checked_rhs(rhs, self._n, out)
        if self._lu is not None:  # J Q y = b, x = Q y; Jᵀ x = b is (J Q)ᵀ x = Qᵀ b
            if transposed:
                out[...] = self._lu.solve(rhs[self._order], trans="T")
            else:
                out[self._order] = self._lu.solve(rhs)
            finite = bool(np.all(np.isfinite(out)))
        elif transposed:
            finite = solve_factored(_lu_kernels.solve_lu_transposed, self._factors_by_columns(), rhs, out, self._work,
                                    self._probe)  # fmt: skip
        else:
            finite = solve_factored(_lu_kernels.solve_lu_rows, self._factors, rhs, out, self._work, self._probe)
        self.n_solves += 1 if rhs.ndim == 1 else rhs.shape[1]
        if not finite:
            raise SingularMatrix("the solution is not finite")
        return out

    def _factors_by_columns(self) -> tuple:
        """The factors as `_lu_kernels.solve_lu_transposed` reads them (U by columns, made
        from U by rows at the first transposed solve of a factorization): its sweeps gather
        along U's columns, 1.1–2 times faster than `solve_lu_rows`'s storage read the other
        way (the lattice's factors at 10^6 and 10^5 bodies)."""
        if self._transposed_factors is None:
            _, _, lower, (u_indptr, u_indices, u_values, u_inverse) = self._factors
            columns = (np.empty(u_indptr.size, dtype=np.int64), np.empty_like(u_indices), np.empty(u_values.size))
            _lu_kernels.columns_from_rows_last_first(u_indptr, u_indices, u_values, *columns)
            self._transposed_factors = (self._held.perm_r, self._held.perm_c, lower, columns + (u_inverse,))
        return self._transposed_factors

    def _column_order(self, jacobian: csr_array) -> np.ndarray:
        """The nested-dissection order of the coordinates; computed again only for a new pattern."""
        if not has_pattern(jacobian, self._pattern):
            from .ordering import geometric_column_order

            self._order = self._pattern = self._held = None  # until the new order is there
            n, coordinates = jacobian.shape[1], COORDINATES_PER_BODY * self.points.shape[0]
            if n < coordinates:
                raise ValueError(
                    f"`jacobian` has {n} columns, expected {COORDINATES_PER_BODY} for each of the "
                    f"{self.points.shape[0]} bodies (and, for a saddle matrix, one per multiplier after them)."
                )
            if n == coordinates:
                self._order = geometric_column_order(jacobian, self.points, block=COORDINATES_PER_BODY)
            else:
                groups = _saddle_groups(jacobian, coordinates)
                self._order = geometric_column_order(jacobian, self.points, groups=groups)
            self._ordered = _lu_kernels.ordered_columns(jacobian.indptr, jacobian.indices, self._order)
            self._pattern = (jacobian.indptr.copy(), jacobian.indices.copy())
        return self._order


class _HeldPivots:
    """A fresh factorization's pivots and the Jacobian entries it factored, and (made at the
    first refactorization) the structural patterns of L and U for them.

    `kept` marks the entries of the Jacobian's CSR values that were factored; row i of the
    ordered Jacobian went to row ``perm_r[i]`` of B = L U, column c of the Jacobian to
    column ``perm_c[c]``; `entries` is SuperLU's count of L + U (room for the analysis).
    """

    def __init__(self, kept: np.ndarray, perm_r: np.ndarray, perm_c: np.ndarray, entries: int) -> None:
        self.kept, self.perm_r, self.perm_c, self.entries = kept, perm_r, perm_c, entries
        index = _index_dtype(perm_r.size)
        self.row_of = np.empty(perm_r.size, dtype=index)  # the inverse permutations, for the solves
        self.row_of[perm_r] = np.arange(perm_r.size, dtype=index)
        self.column_of = np.empty(perm_c.size, dtype=index)
        self.column_of[perm_c] = np.arange(perm_c.size, dtype=index)
        self._analysis = None

    def refactor(self, jacobian, data: np.ndarray):
        """The factors of the kept entries of `jacobian` (values `data`) with the held
        pivots, as `solve_factored` reads them, or None if the guard rejects them."""
        if self._analysis is None:
            self._analyse(jacobian)
        b_indptr, b_rows, gather, ordered, lower, upper, work, stats, compressed = self._analysis
        np.take(data, gather, out=ordered)  # the kept entries in B's column order
        _lu_kernels.refactor_lu(ordered, True, (b_indptr, b_rows, _NO_OFFSETS), lower, upper, work, stats)
        ratio, largest_u, largest_b, bad_column, non_finite = stats.tolist()
        rejected = ratio < MIN_PIVOT_RATIO or largest_u > MAX_GROWTH * largest_b
        if bad_column >= 0 or non_finite != 0.0 or rejected:
            return None
        (l_indptr, l_indices, l_values), (u_indptr, u_indices, u_values, u_inverse) = lower, upper
        (cl_indptr, cl_indices, cl_values), (ru_indptr, ru_indices, ru_values) = compressed
        _lu_kernels.copy_nonzeros(l_indptr, l_indices, l_values, cl_indptr, cl_indices, cl_values)
        _lu_kernels.rows_last_first(u_indptr, u_indices, u_values, ru_indptr, ru_indices, ru_values)
        l_end, u_end = cl_indptr[-1], ru_indptr[-1]
        return (self.row_of, self.column_of, (cl_indptr, cl_indices[:l_end], cl_values[:l_end]),
                (ru_indptr, ru_indices[:u_end], ru_values[:u_end], u_inverse))  # fmt: skip

    def _analyse(self, jacobian) -> None:
        n, nnz = self.perm_r.size, jacobian.nnz
        index = _index_dtype(max(n, nnz))
        column_of = np.empty(n, dtype=np.int64)
        column_of[self.perm_c] = np.arange(n)  # column j of B is column column_of[j] of the Jacobian
        c_indptr, c_rows, c_gather = _lu_kernels.ordered_columns(jacobian.indptr, jacobian.indices, column_of)
        keep = self.kept[c_gather]
        kept_before = np.concatenate([[0], np.cumsum(keep, dtype=np.int64)])
        b_indptr = kept_before[c_indptr]
        b_rows = self.perm_r[c_rows[keep]].astype(index)
        gather = c_gather[keep].astype(index)
        l_indptr, l_indices, u_indptr, u_indices = _lu_kernels.analyse_lu_pattern(
            b_indptr, b_rows, self.entries // 2, self.entries // 2
        )
        lower = (l_indptr, l_indices, np.zeros(l_indices.size))
        upper = (u_indptr, u_indices, np.zeros(u_indices.size), np.zeros(n))
        compressed = tuple((np.zeros(n + 1, dtype=np.int64), np.empty_like(indices), np.empty(indices.size))
                           for indices in (l_indices, u_indices))  # fmt: skip
        stats = np.zeros(_lu_kernels.N_STATS)
        self._analysis = (b_indptr, b_rows, gather, np.empty(gather.size), lower, upper, np.zeros(n), stats, compressed)


def _rows_last_first(indptr: np.ndarray, indices: np.ndarray, values: np.ndarray) -> tuple:
    """``(indptr, indices, values)`` of a compressed-column factor's nonzeros by rows, the last
    row first (`_lu_kernels.rows_last_first`), trimmed to their size."""
    out_indptr = np.empty(indptr.size, dtype=np.int64)
    out_indices, out_values = np.empty_like(indices), np.empty(values.size)
    _lu_kernels.rows_last_first(indptr, indices, values, out_indptr, out_indices, out_values)
    end = out_indptr[-1]
    return out_indptr, out_indices[:end], out_values[:end]


def _saddle_groups(matrix: csr_array, coordinates: int) -> np.ndarray:
    """The body of each unknown of a saddle matrix [[A, Bᵀ], [B, C]] (square, CSR, its
    first `coordinates` unknowns the bodies' coordinates in turn): a coordinate's body, and
    for a multiplier the body of the first coordinate its equation's row holds (the row
    of B: a joint's equation goes with the first of its bodies)."""
    indptr, indices = matrix.indptr, matrix.indices
    rows = indptr[coordinates:]
    lengths = np.diff(rows)
    first = indices[rows[:-1][lengths > 0]] if indices.size else indices[:0]
    if first.size != lengths.size or np.any(first >= coordinates):
        raise ValueError("a saddle matrix's multiplier rows must each hold a coordinate of a body (their columns "
                         "sorted, the coordinates first).")  # fmt: skip
    return np.concatenate([np.arange(coordinates) // COORDINATES_PER_BODY, first // COORDINATES_PER_BODY])
