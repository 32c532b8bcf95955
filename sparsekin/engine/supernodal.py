"""`SupernodalSolver`: a multifrontal LU of a mesh's Jacobian in numba kernels, dense blocks by BLAS.

The Jacobian's columns are taken in a geometric nested dissection of the bodies (the order
of `DissectionSolver`), its rows in a matching that puts a large entry on the diagonal
(scipy's `min_weight_full_bipartite_matching` on ``log`` of the entries scaled by their
columns' largest: the product of the diagonal's relative sizes is the largest there is).
The pattern of ``B + Bᵀ`` (``B`` the Jacobian so permuted, its exact zeros kept: the
pattern is structural) gives an elimination tree, postordered; its chains (the dissection's
separators) are the supernodes.  Once per pattern (and values that keep the matching's
pivots good) everything but the numbers is held: the fronts' index sets, where each of
the Jacobian's entries goes, the factors' storage.

A factorization then refills it in place (`sparsekin.engine._supernodal_kernels`): each
supernode's front is assembled from the Jacobian's entries and its children's
contribution blocks, its diagonal block factored with partial pivoting among the
supernode's own rows (threshold `PIVOT_THRESHOLD` against the rest of the column), the
trailing update a matrix product (`np.dot`: BLAS), its Schur complement pushed on a stack
for its parent.  The solves run supernode by supernode on dense blocks, several
right-hand sides in one pass over the factors.

When a pivot misses the threshold (the motion has moved the Jacobian far from the values
the matching saw) the analysis is made again with the current values; if that fails too,
SuperLU factors it (`DissectionSolver`, counted in ``n_fallbacks``), which also tells an
exactly singular Jacobian.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from . import _supernodal_kernels as _kernels
from .dissection import DissectionSolver
from .linalg import MIN_PIVOT_RATIO, SingularMatrix, _checked_rhs, _checked_square, has_pattern

if TYPE_CHECKING:
    from scipy.sparse import csr_array

__all__ = ["PIVOT_THRESHOLD", "SupernodalSolver"]

#: The smallest accepted ratio of a pivot (chosen among its supernode's rows) to the largest
#: entry of its column in the rows below the supernode, which cannot be pivots: the
#: refactorization's guard (`MIN_PIVOT_RATIO`, KLU's default; an entry of L is at most its
#: inverse).  MUMPS's 0.01 failed on the lattice at 10^6 bodies at a generic pose (smallest
#: ratios 0.05 at 10^4, 0.02 at 10^5: they fall with the separators' size).
PIVOT_THRESHOLD = MIN_PIVOT_RATIO

#: Relaxed supernodes: a supernode joins its parent when both hold at most SMALL_SUPERNODE
#: indices together, or when the dense blocks gain at most ZEROS_SHARE of their entries as zeros.
SMALL_SUPERNODE = 16
ZEROS_SHARE = 0.2

_NOT_FACTORED = "no factorization: call `factor` first (the last one failed or none was made)."


class SupernodalSolver:
    """Multifrontal LU on supernodes of a nested dissection of the bodies, numba kernels and BLAS.

    Parameters
    ----------
    points : array_like, shape (n_bodies, 2)
        Where each body is drawn (its origin): the places the dissection cuts between.
        The Jacobian's columns are the bodies' coordinates, `COORDINATES_PER_BODY` a body.

    Attributes
    ----------
    n_factorizations, n_refactorizations, n_solves : int
        As every linear solver's (`sparsekin.engine.linalg`): analyses with their
        numeric factorization, numeric factorizations on the held analysis, right-hand
        sides solved.
    n_fallbacks : int
        Factorizations handed to SuperLU (`DissectionSolver`) after the supernodal one
        missed its pivot threshold with a fresh analysis.
    pivot_ratio : float
        Of the last supernodal factorization: the smallest ratio of a pivot to the largest
        entry below its supernode in its column (1 when every pivot is the largest).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.sparse import csr_array
    >>> solver = SupernodalSolver([[0.0, 0.0], [1.0, 0.0]])
    >>> jacobian = csr_array(np.eye(6) * 2.0 + np.eye(6, k=3))
    >>> solver.factor(jacobian)
    >>> solver.solve(np.full(6, 2.0)).tolist()
    [0.5, 0.5, 0.5, 1.0, 1.0, 1.0]
    """

    name = "supernodal"

    def __init__(self, points) -> None:
        self._dissection = DissectionSolver(points)  # its order, and the fallback
        self.points = self._dissection.points
        self._pattern = None
        self._analysis = None
        self._factors = None
        self._fallback = False
        self._n = 0
        self.pivot_ratio = 1.0
        self.n_factorizations = 0
        self.n_refactorizations = 0
        self.n_fallbacks = 0
        self.n_solves = 0

    @property
    def nnz_factors(self) -> int:
        """Entries of the last factors (the supernodes' dense blocks, or SuperLU's nonzeros)."""
        if self._factors is None:
            raise RuntimeError(_NOT_FACTORED)
        if self._fallback:
            return self._dissection.nnz_factors
        return int(self._analysis["lower"].size + self._analysis["upper"].size)

    def factor(self, jacobian: csr_array) -> None:
        """Factor `jacobian` (square CSR, its columns the bodies' coordinates in turn);
        raise `SingularMatrix` if it is exactly singular or not finite."""
        n = _checked_square(jacobian)
        self._factors = None
        if not np.all(np.isfinite(jacobian.data)):
            self.n_factorizations += 1
            raise SingularMatrix("the Jacobian has entries that are not finite")
        fresh = self._analysis is None or not has_pattern(jacobian, self._pattern)
        if fresh:
            self._analyse(jacobian)
        else:
            self.n_refactorizations += 1
        failed = self._numeric(jacobian.data)
        if failed and not fresh:  # the held matching's pivots gone bad: match the values now
            self._analyse(jacobian)
            failed = self._numeric(jacobian.data)
        self._n = n
        if failed:
            self.n_fallbacks += 1
            self._dissection.factor(jacobian)  # raises SingularMatrix if it is singular
        self._fallback = failed
        self._factors = True

    def solve(
        self, rhs: np.ndarray, out: np.ndarray | None = None, *, transposed: bool = False
    ) -> np.ndarray:
        """Solve ``jacobian @ x = rhs``, or ``jacobian.T @ x = rhs`` if `transposed`: one
        right-hand side, or one per column of a 2-D `rhs` (all in one pass over the
        factors), optionally into `out` (which may be `rhs`); parameters, returns and
        errors as `RefactorSolver.solve`'s."""
        if self._factors is None:
            raise RuntimeError(_NOT_FACTORED)
        rhs, out = _checked_rhs(rhs, self._n, out)
        if self._fallback:
            self._dissection.solve(rhs, out, transposed=transposed)
            self.n_solves += 1 if rhs.ndim == 1 else rhs.shape[1]
            return out
        columns = rhs.reshape(self._n, -1)
        work = self._work if columns.shape[1] == 1 else np.empty(columns.shape)
        finite = _kernels.solve_supernodal(
            self._analysis["factors"], columns, out.reshape(columns.shape), work, transposed
        )
        self.n_solves += columns.shape[1]
        if not finite:
            raise SingularMatrix("the solution is not finite")
        return out

    # ------------------------------------------------------------------ analysis
    def _analyse(self, jacobian: csr_array) -> None:
        """Order, matching, supernodes, fronts and the factors' storage for `jacobian`'s
        pattern and (the matching) values."""
        from scipy.sparse import coo_array

        self.n_factorizations += 1
        self._analysis = self._pattern = None  # until the new analysis is there
        n = jacobian.shape[0]
        order = self._dissection._column_order(jacobian)
        rows = _matching_rows(jacobian, order)
        row_place = np.empty(n, dtype=np.int64)
        row_place[rows] = np.arange(n)
        col_place = np.empty(n, dtype=np.int64)
        col_place[order] = np.arange(n)
        entry_rows = np.repeat(row_place, np.diff(jacobian.indptr))
        entry_cols = col_place[jacobian.indices]
        both = coo_array(
            (np.ones(2 * entry_rows.size, dtype=np.int8),
             (np.concatenate([entry_rows, entry_cols]), np.concatenate([entry_cols, entry_rows]))),
            shape=(n, n),
        ).tocsr()  # fmt: skip
        parent = _kernels.elimination_tree(both.indptr, both.indices)
        post = _kernels.postorder(parent)
        inv_post = np.empty(n, dtype=np.int64)
        inv_post[post] = np.arange(n)
        parent = np.where(parent[post] >= 0, inv_post[np.maximum(parent[post], 0)], -1)
        first = _kernels.supernode_starts(parent)
        structure = _kernels.supernodal_structure(both.indptr, both.indices, post, inv_post, first)
        first = _kernels.amalgamated_starts(first, structure[0], structure[2], SMALL_SUPERNODE, ZEROS_SHARE)
        struct_ptr, struct_idx, super_parent = _kernels.supernodal_structure(
            both.indptr, both.indices, post, inv_post, first
        )
        del both
        entry_ptr, entry_src, entry_pos, relative, lower_ptr, upper_ptr, largest_front = _kernels.front_maps(
            jacobian.indptr, jacobian.indices, inv_post[row_place], inv_post[col_place],
            first, struct_ptr, struct_idx, super_parent,
        )  # fmt: skip
        stack_offset, stack_size, child_ptr, children = _kernels.stack_offsets(struct_ptr, super_parent)
        if stack_size < 0:
            raise AssertionError("the supernodes are not in a postorder of their tree")
        lower = np.empty(lower_ptr[-1])
        upper = np.empty(upper_ptr[-1])
        pivots = np.empty(n, dtype=np.int64)
        self._analysis = {
            "assembly": (first, struct_ptr, entry_ptr, entry_src, entry_pos, relative, child_ptr, children,
                         stack_offset, lower_ptr, upper_ptr, lower, upper, pivots,
                         np.empty(largest_front), np.empty(max(stack_size, 1))),
            "factors": (rows[post], order[post], first, struct_ptr, struct_idx, lower_ptr, upper_ptr,
                        lower, upper, pivots),
            "lower": lower,
            "upper": upper,
        }  # fmt: skip
        self._pattern = (jacobian.indptr.copy(), jacobian.indices.copy())
        self._work = np.empty((n, 1))

    def _numeric(self, values: np.ndarray) -> bool:
        """The supernodal factorization of the held analysis with `values`; whether a pivot
        missed the threshold."""
        failed, ratio = _kernels.factor_supernodal(
            np.asarray(values, dtype=float), *self._analysis["assembly"], PIVOT_THRESHOLD
        )
        self.pivot_ratio = float(ratio)
        return bool(failed >= 0)


def _matching_rows(jacobian: csr_array, order: np.ndarray) -> np.ndarray:
    """``rows[q]``: the row of `jacobian` matched to its column ``order[q]``, a matching of
    its nonzero entries that maximizes the product of their sizes relative to their
    columns' largest; `SingularMatrix` when there is none (the Jacobian is then exactly
    singular)."""
    from scipy.sparse import csr_array as _csr
    from scipy.sparse.csgraph import min_weight_full_bipartite_matching

    sizes = np.abs(jacobian.data)
    largest = np.zeros(jacobian.shape[1])
    np.maximum.at(largest, jacobian.indices, sizes)
    nonzero = sizes > 0.0
    columns = jacobian.indices[nonzero]
    rows_of_entries = np.repeat(np.arange(jacobian.shape[0]), np.diff(jacobian.indptr))[nonzero]
    # weights >= 1: scipy's matching takes no zero weight as an edge
    weights = 1.0 + np.log(largest[columns]) - np.log(sizes[nonzero])
    graph = _csr((weights, (rows_of_entries, columns)), shape=jacobian.shape)
    try:
        matched_rows, matched_columns = min_weight_full_bipartite_matching(graph)
    except ValueError as error:  # "no full matching exists"
        message = f"the Jacobian is structurally singular in its nonzero entries ({error})"
        raise SingularMatrix(message) from error
    row_of_column = np.empty(jacobian.shape[1], dtype=np.int64)
    row_of_column[matched_columns] = matched_rows
    return row_of_column[order]
