"""Redundant equations of a tall Jacobian by a sparse LU with threshold row pivoting.

The common overconstrained mechanism has a Jacobian of full column rank with many more
rows than columns (rotating squares: 3n² coordinates, (n − 2)² redundant equations).
Its rank is then the number of columns, and naming the redundant equations is choosing
n independent rows.  `TallLU` factors the tall (scaled) Jacobian ``A`` column by column
(left-looking, Gilbert–Peierls; `sparsekin.analysis._tall_lu_kernels`), the columns in a
fill-reducing order (`column_order`), the pivot of each column chosen among the rows not
yet chosen whose remainder is within `PIVOT_THRESHOLD` of the largest, by the analysis's
row preference (drivers first, later joints last).  The rows never chosen are the
redundant ones; the cost follows the fill of the factors, near-linear on chains and
meshes, instead of (equations × redundant²) for a dense basis of the left null space.

Such an LU is not rank-revealing in theory, so a *certificate* decides whether its answer
stands: the smallest singular value of the square block ``B`` of the chosen rows,
estimated by inverse subspace iteration with its factors, must exceed the rank tolerance
by `CERTIFICATE_MARGIN`.  Every row of ``A`` is a row of ``B`` or a combination of them,
so ``sigma_min(A) >= sigma_min(B)`` and the rank is n.  A column without a candidate
above the tolerance (a free coordinate) or a failed certificate sends the analysis back to
the dense one of `sparsekin.analysis.rank`.

The dependency of a redundant row r on the chosen ones is computed only when a message
needs it: row r of ``A`` equals its row ``l_r`` of ``L`` times ``U``, so the weights y of
the chosen rows in ``y^T B = -a_r^T`` solve ``L_K^T y = -l_r``: one triangular solve.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

from . import _tall_lu_kernels as _kernels

__all__ = ["TallLU", "column_order"]

#: A pivot is chosen among the rows whose remainder is at least this fraction of the
#: column's largest: the row preference decides among them.  0.1, the classic threshold of
#: sparse LU codes, chose on 60×60 rotating squares a block of smallest singular value
#: 1e-10 (the certificate fails); 0.5 gave 2.5e-5, as did 0.9 and 0.999, at 1.4× the fill
#: of 0.1 (docs/design-notes.md, "Redundant equations at scale").  It bounds L by 2.
PIVOT_THRESHOLD = 0.5
#: The LU's answer stands if the smallest singular value of the chosen rows' block is at
#: least this many times the rank tolerance: an estimate from a few sweeps is accurate to
#: a small factor (it comes from above).  Not more: long chains are ill-conditioned in
#: absolute coordinates (the parallel-bar chain's block has sigma_min 4.5e-5, 4.4e-7,
#: about 4e-9 at 10^2, 10^3, 10^4 cells, against a tolerance of 5e-11 at 10^4), and a
#: failed certificate sends the analysis to the dense one, whose memory grows as
#: equations × redundant.
CERTIFICATE_MARGIN = 10.0
#: Remainders of rows not chosen at most this fraction of the rank tolerance are rounding:
#: they are left out of L, so that a redundant row, once a combination of the chosen rows,
#: stops spreading fill (without this, its rounding residue reaches every later column:
#: 4 % fewer entries on 100×100 rotating squares, docs/design-notes.md).
DROP = 1e-2
#: Sweeps and width of the inverse subspace iteration of the certificate.
CERTIFICATE_SWEEPS = 4
CERTIFICATE_BLOCK = 4
#: Dependencies: a chosen row takes part in a redundant row's dependency if its weight,
#: relative to the redundant row's own (1), is at least this (shares of 1e-12, squared).
INVOLVEMENT = 1e-6
#: Width of the random sketch that finds the dependencies a few rows take part in, and
#: how far below `INVOLVEMENT` its norm may fall before a dependency is passed over (the
#: squared norm of 4 Gaussians is below 4/10^4 with probability about 2e-8).
SKETCH_WIDTH = 4
SKETCH_SLACK = 100.0


def column_order(matrix: sparse.csr_array) -> np.ndarray:
    """A fill-reducing order of the columns of a (tall) sparse matrix.

    Multiple minimum degree on the graph of ``A^T A`` (columns sharing a row), taken from
    SuperLU: it factors ``A^T A + c I`` (symmetric mode, diagonal pivots; a fraction of
    the tall LU's time) and hands out its column permutation.  On 60×60 rotating squares
    the tall LU's factors hold 2.3·10^6 entries in this order, 1.9·10^7 in reverse
    Cuthill–McKee's and 1.7·10^7 in the natural one (docs/design-notes.md).  One function,
    so that a nested dissection is a one-line change.
    """
    from scipy.sparse.linalg import splu

    pattern = sparse.csr_array((np.ones(matrix.nnz), matrix.indices, matrix.indptr), shape=matrix.shape)
    graph = sparse.csc_array(pattern.T @ pattern)
    shifted = graph + sparse.diags_array(np.full(matrix.shape[1], 1.0 + float(np.max(graph.sum(axis=0), initial=0.0))))
    factor = splu(sparse.csc_array(shifted), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                  options={"SymmetricMode": True})  # fmt: skip
    return np.argsort(factor.perm_c).astype(np.int64)


class TallLU:
    """``A(chosen rows, order) = L_K U`` and the other rows as combinations of them.

    Parameters
    ----------
    scaled : csr_array, shape (m, n), m >= n
        The (equilibrated) Jacobian.
    preference : ndarray, shape (m,)
        Larger values are left out (named redundant) first.
    tolerance : float
        Absolute rank tolerance: a column whose largest remainder is at most this fails.

    Attributes
    ----------
    complete : bool
        Every column found a pivot; otherwise `failed_column` is the coordinate where the
        factorization stopped.
    order : ndarray of int, shape (n,)
        Column order of the factorization.
    chosen_rows : ndarray of int, shape (n,)
        The row chosen at each pivot step.
    redundant_rows : ndarray of int, shape (m - n,)
        The rows never chosen, ascending.
    min_pivot_ratio, max_abs_u, max_abs_l : float
        Pivoting statistics.
    n_entries : int
        Entries of L and U (the fill).
    """

    def __init__(self, scaled: sparse.csr_array, preference: np.ndarray, tolerance: float) -> None:
        m, n = scaled.shape
        self.shape = (m, n)
        self.scaled = scaled
        self.order = column_order(scaled)
        columns = sparse.csc_array(scaled[:, self.order])
        columns.sort_indices()
        stats = np.zeros(_kernels.N_STATS)
        capacity = 4 * columns.nnz + 16
        (l_indptr, l_rows, l_values, self.u_indptr, self.u_steps, self.u_values, self.step_of_row,
         self.row_of_step) = _kernels.factor_tall(
            columns.indptr.astype(np.int64), columns.indices.astype(np.int64), columns.data, m,
            np.ascontiguousarray(preference, dtype=float), PIVOT_THRESHOLD, tolerance, DROP * tolerance, capacity, stats,
        )  # fmt: skip
        self.min_pivot_ratio = float(stats[_kernels.STAT_MIN_PIVOT_RATIO])
        self.max_abs_u = float(stats[_kernels.STAT_MAX_ABS_U])
        self.max_abs_l = float(stats[_kernels.STAT_MAX_ABS_L])
        failed = int(stats[_kernels.STAT_FAILED_COLUMN])
        self.complete = failed < 0
        self.failed_column = int(self.order[failed]) if failed >= 0 else -1
        self.chosen_rows = self.row_of_step
        self.redundant_rows = np.flatnonzero(self.step_of_row < 0).astype(np.int64)
        self.n_entries = int(l_indptr[-1] + self.u_indptr[-1])
        if self.complete:
            self._split_lower(l_indptr, l_rows, l_values)

    def _split_lower(self, l_indptr, l_rows, l_values) -> None:
        """L's rows split: the chosen ones (L_K, by pivot step, for the solves) and the
        redundant ones (a CSR array, a row per redundant equation, for the dependencies)."""
        n_redundant, n = self.redundant_rows.size, self.shape[1]
        self.k_indptr, self.k_steps, self.k_values, *redundant = _kernels.split_lower(
            l_indptr, l_rows, l_values, self.step_of_row, n_redundant
        )
        self.redundant_lower = sparse.csr_array((redundant[2], redundant[1], redundant[0]), shape=(n_redundant, n))

    # ------------------------------------------------------------------ solves with B
    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``B^-1 rhs``: `rhs` by pivot step, the result by column of the factorization."""
        out = np.array(rhs, dtype=float)
        _kernels.solve_lower(self.k_indptr, self.k_steps, self.k_values, out)
        _kernels.solve_upper(self.u_indptr, self.u_steps, self.u_values, out)
        return out

    def solve_transposed(self, rhs: np.ndarray) -> np.ndarray:
        """``B^-T rhs``: `rhs` by column of the factorization, the result by pivot step."""
        out = np.array(rhs, dtype=float)
        _kernels.solve_upper_transposed(self.u_indptr, self.u_steps, self.u_values, out)
        _kernels.solve_lower_transposed(self.k_indptr, self.k_steps, self.k_values, out)
        return out

    def pivot_order(self, kept: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(perm_r, perm_c)`` of this factorization for the square system of the rows
        `kept` (the chosen rows, ascending), as `RefactorSolver.suggest` takes them for
        ``A = jacobian.T``: coordinate ``order[k]`` and the equation chosen at step k are the
        k-th pivot."""
        perm_r = np.empty(self.shape[1], dtype=np.int64)
        perm_r[self.order] = np.arange(self.shape[1])
        return perm_r, self.step_of_row[np.asarray(kept, dtype=np.int64)]

    # ------------------------------------------------------------------ certificate
    def smallest_singular_triplets(self, rng):
        """Ritz values (ascending) and right vectors, in coordinates, of the smallest singular
        values of B, by inverse subspace iteration ``X <- B^-1 B^-T X`` and a Rayleigh–Ritz
        step with B."""
        n = self.shape[1]
        block = np.linalg.qr(rng.standard_normal((n, min(CERTIFICATE_BLOCK, n))))[0]
        for _ in range(CERTIFICATE_SWEEPS):
            block = np.column_stack([self.solve(self.solve_transposed(column)) for column in block.T])
            block = np.linalg.qr(block)[0]
        square = self.scaled[self.row_of_step][:, self.order]
        image = np.linalg.qr(np.asarray(square @ block), mode="r")
        _, values, right = np.linalg.svd(image)
        vectors = np.empty_like(block)
        vectors[self.order] = block @ right.T
        return values[::-1], vectors[:, ::-1]

    # ------------------------------------------------------------------ dependencies
    def dependency(self, k: int) -> np.ndarray:
        """Weights y (m,) with ``y^T A = 0``, 1 on redundant row k, 0 on the others."""
        m, n = self.shape
        lower = self.redundant_lower
        start, end = lower.indptr[k], lower.indptr[k + 1]
        weights = np.zeros(n)
        weights[lower.indices[start:end]] = -lower.data[start:end]
        _kernels.solve_lower_transposed(self.k_indptr, self.k_steps, self.k_values, weights)
        dependency = np.zeros(m)
        dependency[self.row_of_step] = weights
        dependency[self.redundant_rows[k]] = 1.0
        return dependency

    def rows_in_dependencies(self, rows: np.ndarray) -> sparse.csc_array:
        """The weights of the rows `rows` in every dependency: shape (len(rows), m - n),
        sparse, exact in the dependencies that involve them.

        A sketch finds those dependencies without a solve per row: with a Gaussian block
        W (len(rows), `SKETCH_WIDTH`), ``V = L_R L_K^-1 E W`` (E the unit vectors of the
        rows' pivot steps) has in row r the combinations ``y_r(rows) W`` of dependency r's
        weights, whose norm is below ``INVOLVEMENT / SKETCH_SLACK`` with probability
        < 1e-8 unless those weights are all below `INVOLVEMENT`.  The dependencies so
        flagged are then computed exactly (one solve each; few in a sound model).
        """
        m, n = self.shape
        rows = np.asarray(rows, dtype=np.int64)
        steps = self.step_of_row[rows]
        chosen = steps >= 0
        sketch = np.random.default_rng(0).standard_normal((rows.size, SKETCH_WIDTH))
        block = np.zeros((n, SKETCH_WIDTH))
        np.add.at(block, steps[chosen], sketch[chosen])
        for column in block.T:
            _kernels.solve_lower(self.k_indptr, self.k_steps, self.k_values, column)
        image = self.redundant_lower @ block
        flagged = np.linalg.norm(image, axis=1) >= INVOLVEMENT / SKETCH_SLACK
        flagged[np.searchsorted(self.redundant_rows, rows[~chosen])] = True  # a redundant row: its own 1
        columns = np.flatnonzero(flagged)
        weights = np.zeros((rows.size, columns.size))
        for index, k in enumerate(columns.tolist()):
            weights[:, index] = self.dependency(k)[rows]
        entries = sparse.coo_array(weights)
        return sparse.csc_array((entries.data, (entries.row, columns[entries.col])), shape=(rows.size, self.redundant_rows.size))
