"""Redundant equations of a tall Jacobian: a sparse LU that keeps independent rows.

The common overconstrained mechanism has a Jacobian A of full column rank with many more
rows than columns (rotating squares: 3n² coordinates, (n − 2)² redundant equations).  Its
rank is then the number of columns n, and naming the redundant equations is choosing n
independent rows.  `TallLU` offers the rows of A in turn — the drivers first, then the
joints in their own order, or in a fill-reducing order if that fills in too much
(`row_order`) — to a left-looking sparse LU of ``A^T``
(`sparsekin.analysis._tall_lu_kernels.factor_rows`): a row whose remainder, after the rows
kept so far, is at most `REMAINDER_TOLERANCE` is a combination of them and is named
redundant; the others are kept, each pivoting on a coordinate (partial pivoting).  Rows
offered later are named redundant first: in the model's own order, each redundant row is
the latest joint equation of its dependency (later joints first, the rule of the small
models).  A redundant row is eliminated once and dropped, so the
fill is that of the square system that remains: near-linear on chains and meshes.

Such an LU is not rank-revealing in theory, so a *certificate* decides whether its answer
stands: the smallest singular value of the square block ``B`` of the kept rows, estimated
by inverse subspace iteration with its factors, must exceed the rank tolerance by
`CERTIFICATE_MARGIN`.  Every row of A is a row of B or a combination of them, so
``sigma_min(A) >= sigma_min(B)`` and the rank is n.  A coordinate left without a pivot (a
free coordinate) or a failed certificate sends the analysis back to the dense one of
`sparsekin.analysis.rank`.

The dependency of a redundant row r on the kept ones is computed only when a message
needs it: the weights y of the kept rows in ``y^T B = -a_r^T``, one solve with ``B^T``.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

from ..engine.ordering import fill_reducing_row_order
from . import _tall_lu_kernels as _kernels

__all__ = ["TallLU", "row_order", "NATURAL_FILL_LIMIT"]

#: A row whose remainder after the rows kept before it is at most this (the scaled
#: Jacobian has entries up to 1) is a combination of them.  Measured gap (design notes):
#: skipped remainders up to 1.0e-10 (rotating squares, rounding accumulated over the
#: updates) and 2.2e-16 (parallel-bar chains); kept pivots from 1.2e-2 (squares) and
#: 2.0e-4 (the 10^4-cell chain) up.  At 1e-11 a dependent row of 30×30 squares was kept.
REMAINDER_TOLERANCE = 1e-8
#: A row whose remainder is at most this is offered again after all the others (before
#: the rows a caller wants named redundant): kept only if still needed.  A nearly
#: dependent row kept early makes the kept block ill-conditioned: smallest singular value
#: of that block at 60×60 and 100×100 squares 9.1e-11 and 2.1e-10 without deferring,
#: 5.2e-10 and 1.6e-8 with 0.1, 1.6e-6 and 6.3e-7 with 0.3, 7.8e-7 and 1.5e-7 with 0.5,
#: 4e-16 with 0.9 (the rows offered again then are the nearly dependent ones); 300×300
#: with 0.3: 7.9e-8 (design notes).
DEFER = 0.3
#: The LU's answer stands if the smallest singular value of the kept rows' block is at
#: least this many times the rank tolerance: an estimate from a few sweeps is accurate to
#: a small factor (it comes from above).  Not more: long chains are ill-conditioned in
#: absolute coordinates (the parallel-bar chain's block has sigma_min 5.5e-5, 5.6e-7,
#: 5.6e-9 at 10^2, 10^3, 10^4 cells, against a tolerance of 5e-11 at 10^4), and a
#: failed certificate sends the analysis to the dense one, whose memory grows as
#: equations × redundant.
CERTIFICATE_MARGIN = 10.0
#: The rows are offered in the model's order unless the LU's entries (L and U) then exceed
#: this many times the entries of A; then in a nested-dissection order.  Entries of L + U
#: in the model's order against a minimum-degree one (design notes, issue 26): 1.4× A's
#: entries against 2.4× on rotating squares (100×100: 2.2e5 and 3.8e5), 2.2× against 2.4×
#: on rectangles written as 2×2 motifs, 1.4× on the parallel-bar chain; and the kept block
#: better conditioned (its smallest singular value at 100×100 squares 9.1e-7 against
#: 3.4e-7; 2.0e-5 against 1.6e-6 at 60×60 motif rectangles).  A model whose joints are
#: listed in a scattered order fills in far more (8e5 entries, about 60× A's, at 29×29 squares).
#: Nested dissection against minimum degree on 60×60 squares with their joints shuffled:
#: 1.60e5 against 1.57e5 entries, smallest singular value 3.8e-6 against 7.0e-7.
NATURAL_FILL_LIMIT = 4.0
#: Sweeps and width of the inverse subspace iteration of the certificate.
CERTIFICATE_SWEEPS = 4
CERTIFICATE_BLOCK = 4
#: Dependencies: a kept row takes part in a redundant row's dependency if its weight,
#: relative to the redundant row's own (1), is at least this (shares of 1e-12, squared).
INVOLVEMENT = 1e-6
#: Width of the random sketch that finds the dependencies a few rows take part in, and
#: how far below `INVOLVEMENT` its norm may fall before a dependency is passed over (the
#: squared norm of 4 Gaussians is below 4/10^4 with probability about 2e-8).
SKETCH_WIDTH = 4
SKETCH_SLACK = 100.0
#: Up to this many rows, their weights in every dependency are computed exactly, one solve
#: per row (``-A_R B^-1 e_row``), not by the sketch: with one driver at 300×300 squares the
#: sketch flagged 5 634 dependencies by rounding (weights about 1e-8), one solve each, 29 s
#: of the first sample; the exact weights take one solve.
EXACT_ROWS = 2 * SKETCH_WIDTH


def row_order(matrix: sparse.csr_array, preference: np.ndarray, fill_reducing: bool = False) -> np.ndarray:
    """The order in which the rows of a tall sparse matrix are offered to `TallLU`.

    The rows of preference below 1 (the drivers) first, those of 2 or more (rows a caller
    wants named redundant if they are) last, and in between, and within each group, the
    rows in their own order — or, with `fill_reducing`, a nested dissection of the graph of
    ``A A^T`` (rows sharing a coordinate; `fill_reducing_row_order`).  Rows offered later
    are named redundant first.
    """
    order = fill_reducing_row_order(matrix) if fill_reducing else np.arange(matrix.shape[0])
    group = np.digitize(preference[order], (1.0, 2.0))  # drivers, joints, rows to name first
    return order[np.argsort(group, kind="stable")].astype(np.int64)


class TallLU:
    """The rows of a tall Jacobian split into a square block B of independent rows, factored,
    and the others.

    Parameters
    ----------
    scaled : csr_array, shape (m, n), m >= n
        The (equilibrated) Jacobian.
    preference : ndarray, shape (m,)
        Rows below 1 (drivers) are offered first, hence kept if independent; rows of 2
        or more last, hence named redundant if they are (`row_order`).
    fill_reducing : bool
        Offer the rows in a fill-reducing order; otherwise in their own order, and if
        that fills in more than `NATURAL_FILL_LIMIT` times the entries of A, stop (then
        `complete` is False and `over_budget` True).

    Attributes
    ----------
    complete : bool
        Every coordinate found a pivot (else some are free: the dense analysis decides).
    over_budget : bool
        The rows' own order filled in too much: the factorization stopped.
    kept_rows : ndarray of int, shape (n,)
        The rows of B, in pivot-step order.
    redundant_rows : ndarray of int, shape (m - n,)
        The other rows, ascending.
    max_abs_u, largest_skipped, smallest_pivot : float
        Growth, the largest remainder of a redundant row, the smallest pivot.
    n_entries : int
        Entries of L and U (the fill).
    """

    def __init__(self, scaled: sparse.csr_array, preference: np.ndarray, fill_reducing: bool = False) -> None:
        m, n = scaled.shape
        self.shape = (m, n)
        self.scaled = scaled
        self.order = row_order(scaled, np.asarray(preference, dtype=float), fill_reducing)
        budget = np.iinfo(np.int64).max if fill_reducing else int(NATURAL_FILL_LIMIT * scaled.nnz)
        offered = sparse.csr_array(scaled[self.order])
        offered.sort_indices()
        stats = np.zeros(_kernels.N_STATS)
        (l_indptr, l_rows, l_values, self.u_indptr, self.u_steps, self.u_values, self.step_of_coordinate,
         self.coordinate_of_step, column_of_step) = _kernels.factor_rows(
            offered.indptr.astype(np.int64), offered.indices.astype(np.int64), offered.data, n,
            int(np.count_nonzero(np.asarray(preference)[self.order] < 2.0)), REMAINDER_TOLERANCE, DEFER,
            4 * offered.nnz + 16, budget, stats,
        )  # fmt: skip
        self.max_abs_u = float(stats[_kernels.STAT_MAX_ABS_U])
        self.largest_skipped = float(stats[_kernels.STAT_LARGEST_SKIPPED])
        self.smallest_pivot = float(stats[_kernels.STAT_SMALLEST_PIVOT])
        self.complete = bool(np.all(column_of_step >= 0))
        self.n_entries = int(l_indptr[-1] + self.u_indptr[-1])
        self.over_budget = self.n_entries > budget
        if not self.complete:
            return
        self.kept_rows = self.order[column_of_step]
        self.step_of_row = np.full(m, -1, dtype=np.int64)
        self.step_of_row[self.kept_rows] = np.arange(n)
        self.redundant_rows = np.flatnonzero(self.step_of_row < 0).astype(np.int64)
        self.k_indptr, self.k_steps, self.k_values = _kernels.split_lower(
            l_indptr, l_rows, l_values, self.step_of_coordinate
        )
        self.redundant_jacobian = sparse.csr_array(scaled[self.redundant_rows])

    # ------------------------------------------------------------------ solves with B
    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``x`` with ``B x = rhs``: `rhs` (n,) by pivot step, `x` by coordinate."""
        work = np.array(rhs, dtype=float)
        _kernels.solve_upper_transposed(self.u_indptr, self.u_steps, self.u_values, work)
        _kernels.solve_lower_transposed(self.k_indptr, self.k_steps, self.k_values, work)
        out = np.empty_like(work)
        out[self.coordinate_of_step] = work
        return out

    def solve_transposed(self, rhs: np.ndarray) -> np.ndarray:
        """``y`` with ``B^T y = rhs``: `rhs` (n,) by coordinate, `y` by pivot step."""
        work = np.asarray(rhs, dtype=float)[self.coordinate_of_step]
        _kernels.solve_lower(self.k_indptr, self.k_steps, self.k_values, work)
        _kernels.solve_upper(self.u_indptr, self.u_steps, self.u_values, work)
        return work

    def pivot_order(self, kept: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(perm_r, perm_c)`` of this factorization for the square system of the rows
        `kept` (the kept rows, ascending), as `RefactorSolver.suggest` takes them for
        ``A = jacobian.T``: the coordinate and the equation of step k are its k-th pivot."""
        return self.step_of_coordinate.copy(), self.step_of_row[np.asarray(kept, dtype=np.int64)]

    # ------------------------------------------------------------------ certificate
    def smallest_singular_triplets(self, rng):
        """Ritz values (ascending) and right vectors, in coordinates, of the smallest singular
        values of B, by inverse subspace iteration ``X <- B^-1 B^-T X`` and a Rayleigh–Ritz
        step with B."""
        n = self.shape[1]
        block = np.linalg.qr(rng.standard_normal((n, min(CERTIFICATE_BLOCK, n))))[0]
        for _ in range(CERTIFICATE_SWEEPS):
            block = np.column_stack([self.solve(self.solve_transposed(column)) for column in block.T])
            if not np.all(np.isfinite(block)):  # B^-1 overflowed: B is singular to working precision
                return np.zeros(1), np.zeros((n, 1))  # (rotating squares of 10^6 bodies in their own order)
            block = np.linalg.qr(block)[0]
        image = np.linalg.qr(np.asarray(self.scaled[self.kept_rows] @ block), mode="r")
        _, values, right = np.linalg.svd(image)
        return values[::-1], (block @ right.T)[:, ::-1]

    # ------------------------------------------------------------------ dependencies
    def dependency(self, k: int) -> np.ndarray:
        """Weights y (m,) with ``y^T A = 0``, 1 on redundant row k, 0 on the others."""
        lower = self.redundant_jacobian
        row = np.zeros(self.shape[1])
        start, end = lower.indptr[k], lower.indptr[k + 1]
        row[lower.indices[start:end]] = -lower.data[start:end]
        dependency = np.zeros(self.shape[0])
        dependency[self.kept_rows] = self.solve_transposed(row)
        dependency[self.redundant_rows[k]] = 1.0
        return dependency

    def rows_in_dependencies(self, rows: np.ndarray) -> sparse.csc_array:
        """The weights of the rows `rows` in every dependency: shape (len(rows), m - n),
        sparse, exact in the dependencies that involve them (in all, up to `EXACT_ROWS` rows).

        A sketch finds those dependencies without a solve per row: with a Gaussian block
        W (len(rows), `SKETCH_WIDTH`), ``V = A_R B^-1 E W`` (E the unit vectors of the
        rows' pivot steps) has in row r the combinations ``-y_r(rows) W`` of dependency
        r's weights, whose norm is below ``INVOLVEMENT / SKETCH_SLACK`` with probability
        < 1e-8 unless those weights are all below `INVOLVEMENT`.  The dependencies so
        flagged are then computed exactly (one solve each; few in a sound model).
        """
        rows = np.asarray(rows, dtype=np.int64)
        steps = self.step_of_row[rows]
        kept = steps >= 0
        if rows.size <= EXACT_ROWS:  # a solve per row gives its weight in every dependency
            weights = np.zeros((rows.size, self.redundant_rows.size))
            for index in np.flatnonzero(kept).tolist():
                unit = np.zeros(self.shape[1])
                unit[steps[index]] = 1.0
                weights[index] = -(self.redundant_jacobian @ self.solve(unit))
            own = np.flatnonzero(~kept)
            weights[own, np.searchsorted(self.redundant_rows, rows[own])] = 1.0
            return sparse.csc_array(weights)
        sketch = np.random.default_rng(0).standard_normal((rows.size, SKETCH_WIDTH))
        block = np.zeros((self.shape[1], SKETCH_WIDTH))
        np.add.at(block, steps[kept], sketch[kept])
        image = self.redundant_jacobian @ np.column_stack([self.solve(column) for column in block.T])
        flagged = np.linalg.norm(image, axis=1) >= INVOLVEMENT / SKETCH_SLACK
        flagged[np.searchsorted(self.redundant_rows, rows[~kept])] = True  # a redundant row: its own 1
        columns = np.flatnonzero(flagged)
        weights = np.zeros((rows.size, columns.size))
        for index, k in enumerate(columns.tolist()):
            weights[:, index] = self.dependency(k)[rows]
        entries = sparse.coo_array(weights)
        return sparse.csc_array((entries.data, (entries.row, columns[entries.col])), shape=(rows.size, self.redundant_rows.size))
