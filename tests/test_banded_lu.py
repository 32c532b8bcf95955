"""The banded LU kernels (`sparsekin.engine._banded_kernels`) against LAPACK's dense LU.

Partial pivoting on a band picks the same pivots as on the dense matrix (the entries below
the band are zeros and stay zeros), so the reference is `scipy.linalg.lu_factor`: the same
interchanges and the same U, and solutions to the backward error of a stable LU.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from scipy.sparse import csr_array
from scipy.sparse.linalg import spsolve

from sparsekin.engine._banded_kernels import (
    banded_lu,
    banded_lu_solve,
    compress_factors,
    compressed_lu_solve,
    factor_band,
    solve_band,
)
from sparsekin.solve._saddle_factorization import (
    band_slots,
    bandwidths,
    compiled_factorization,
    factor_saddle,
    saddle_band_order,
    solve_saddle,
)

#: ‖A x − b‖ / (‖A‖ ‖x‖ + ‖b‖) of a stable LU solve, with room for growth at these sizes.
BACKWARD_ERROR = 1e-13


def backward_error(matrix, x, b) -> float:
    return np.abs(matrix @ x - b).max() / (np.abs(matrix).sum(axis=1).max() * np.abs(x).max() + np.abs(b).max())


def random_band(rng, n, lower, upper, diagonal=1.0):
    """A dense (n, n) matrix with random entries in the band and `diagonal` times the
    random diagonal (small: the pivots come from below)."""
    matrix = rng.standard_normal((n, n))
    rows, columns = np.indices((n, n))
    matrix[(rows - columns > lower) | (columns - rows > upper)] = 0.0
    matrix[np.diag_indices(n)] *= diagonal
    return matrix


def to_band(matrix, lower, upper):
    """LAPACK's ``gbtrf`` storage of `matrix`: 2 lower + upper + 1 rows, Fortran order."""
    n = matrix.shape[0]
    band = np.zeros((2 * lower + upper + 1, n), order="F")
    for j in range(n):
        for i in range(max(0, j - upper), min(n, j + lower + 1)):
            band[lower + upper + i - j, j] = matrix[i, j]
    return band


@pytest.mark.parametrize(("n", "lower", "upper", "diagonal"), [
    (1, 0, 0, 1.0), (6, 0, 0, 1.0), (7, 2, 0, 1.0), (7, 0, 3, 1.0), (12, 3, 3, 1.0), (40, 9, 9, 1.0),
    (40, 9, 9, 1e-9), (30, 2, 5, 1e-9), (25, 5, 1, 0.0), (9, 12, 12, 1.0), (200, 9, 9, 1e-3),
])  # fmt: skip
def test_banded_lu_is_lapacks_partial_pivoting(n, lower, upper, diagonal, rng):
    # a small or zero diagonal (as in a saddle matrix's multiplier block) makes every
    # column pivot from below, which widens U to lower + upper above the diagonal
    matrix = random_band(rng, n, lower, upper, diagonal)
    lower, upper = min(lower, n - 1), min(upper, n - 1)
    band = to_band(matrix, lower, upper)
    pivots, extent = np.empty(n, dtype=np.int64), np.empty((2, n), dtype=np.int64)
    assert banded_lu(band, lower, upper, pivots, extent)
    factors, expected_pivots = scipy.linalg.lu_factor(matrix)
    np.testing.assert_array_equal(pivots, expected_pivots)
    u = np.zeros((n, n))
    for j in range(n):  # U's rows 0 … lower + upper of the storage
        for i in range(max(0, j - lower - upper), j + 1):
            u[i, j] = band[lower + upper + i - j, j]
    np.testing.assert_allclose(u, np.triu(factors), rtol=0.0, atol=1e-12 * np.abs(factors).max())
    if diagonal != 1.0 and n > 1:
        assert (pivots != np.arange(n)).any()
    b = rng.standard_normal(n)
    x = b.copy()
    banded_lu_solve(band, lower, upper, pivots, extent, x)
    assert backward_error(matrix, x, b) <= BACKWARD_ERROR
    np.testing.assert_allclose(x, scipy.linalg.lu_solve((factors, expected_pivots), b), rtol=1e-9,
                               atol=1e-9 * np.abs(x).max())  # fmt: skip
    compressed = compressed_factors(band, lower, upper, extent)
    y = b.copy()  # the compressed solve: the same operations on the nonzeros, the same result
    compressed_lu_solve(band, lower, upper, pivots, compressed, y)
    np.testing.assert_array_equal(y, x)


def compressed_factors(band, lower, upper, extent):
    n = band.shape[1]
    factors = (np.empty((2, n + 1), dtype=np.int64), np.empty((2, n * max(lower + upper, 1)), dtype=np.int64),
               np.empty((2, n * max(lower + upper, 1))))  # fmt: skip
    compress_factors(band, lower, upper, extent, factors)
    return factors


def test_banded_lu_reports_a_failed_pivot():
    pivots, extent = np.empty(3, dtype=np.int64), np.empty((2, 3), dtype=np.int64)
    singular = np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 1.0]])  # an exact zero pivot at step 1
    assert not banded_lu(to_band(singular, 1, 1), 1, 1, pivots, extent)
    zero_column = np.array([[1.0, 0.0, 0.0], [3.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    assert not banded_lu(to_band(zero_column, 1, 1), 1, 1, pivots, extent)
    assert not banded_lu(to_band(np.array([[1.0, 2.0], [np.nan, 1.0]]), 1, 1), 1, 1, pivots[:2], extent[:, :2])
    assert not banded_lu(to_band(np.array([[np.inf, 0.0], [0.0, 1.0]]), 1, 1), 1, 1, pivots[:2], extent[:, :2])
    assert banded_lu(to_band(np.array([[0.0, 1.0], [1.0, 0.0]]), 1, 1), 1, 1, pivots[:2], extent[:, :2])  # needs its swap
    np.testing.assert_array_equal(pivots[:2], [1, 1])


def saddle_like(rng, n_bodies):
    """A chain's saddle matrix [[M, Jᵀ], [J, 0]], its coordinates first: a band only in
    another order.  Each body (3 coordinates) has a full mass block, and a joint between
    bodies k and k + 1 two equations on both."""
    n, m = 3 * n_bodies, 2 * (n_bodies - 1)
    matrix = np.zeros((n + m, n + m))
    for k in range(n_bodies):
        block = rng.standard_normal((3, 3))
        matrix[3 * k : 3 * k + 3, 3 * k : 3 * k + 3] = block @ block.T + 3.0 * np.eye(3)
    for k in range(n_bodies - 1):
        jacobian = rng.standard_normal((2, 6))
        matrix[n + 2 * k : n + 2 * k + 2, 3 * k : 3 * k + 6] = jacobian
        matrix[3 * k : 3 * k + 6, n + 2 * k : n + 2 * k + 2] = jacobian.T
    return csr_array(matrix)


def test_factor_band_refills_and_solves_the_saddle_matrix_in_its_order(rng):
    matrix = saddle_like(rng, 30)
    size = matrix.shape[0]
    assert bandwidths(matrix.indptr, matrix.indices, np.arange(size)) == (3 * 30 + 1, 3 * 30 + 1)
    order, lower, upper = saddle_band_order(matrix.indptr, matrix.indices)
    assert lower == upper <= 8 and np.array_equal(np.sort(order), np.arange(size))
    slots = band_slots(matrix.indptr, matrix.indices, order, lower, upper)
    band = np.zeros((2 * lower + upper + 1, size), order="F")
    pivots, scratch, extent = np.empty(size, dtype=np.int64), np.empty(size), np.empty((2, size), dtype=np.int64)
    capacity = size * (lower + upper)
    factors = (np.empty((2, size + 1), dtype=np.int64), np.empty((2, capacity), dtype=np.int64),
               np.empty((2, capacity)))  # fmt: skip
    for _ in range(2):  # the second factorization on the same band: its fill refilled from zeros
        matrix.data[:] = saddle_like(rng, 30).data
        values = np.append(matrix.data, 7.0)  # the discard slot of the loop's values is not read
        assert factor_band(values, slots, band, lower, upper, pivots, extent, factors)
        assert (pivots != np.arange(size)).any()  # the multiplier block's zero diagonal
        kv = lower + upper  # the compressed factors: every nonzero of L and of U off the diagonal
        np.testing.assert_array_equal(factors[0][:, -1], [np.count_nonzero(band[kv + 1 :]), np.count_nonzero(band[:kv])])
        b = rng.standard_normal(size)
        x = b.copy()
        solve_band(band, lower, upper, pivots, factors, order, scratch, x)
        assert backward_error(matrix.toarray(), x, b) <= BACKWARD_ERROR
        np.testing.assert_allclose(x, spsolve(matrix.tocsc(), b), rtol=1e-9, atol=1e-9 * np.abs(x).max())
    matrix.data[:] = 0.0  # singular: reported, not solved
    assert not factor_band(np.append(matrix.data, 0.0), slots, band, lower, upper, pivots, extent, factors)


def test_band_slots_refuse_a_pattern_outside_the_band():
    pattern = csr_array(np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]))
    order = np.arange(3)
    assert bandwidths(pattern.indptr, pattern.indices, order) == (0, 2)
    with pytest.raises(ValueError, match="does not fit a band of 0 below and 1 above"):
        band_slots(pattern.indptr, pattern.indices, order, 0, 1)
    np.testing.assert_array_equal(band_slots(pattern.indptr, pattern.indices, order, 0, 2),
                                  [[2, 0, 2, 2], [0, 2, 1, 2]])  # fmt: skip


def test_held_pivots_refactor_as_factor_band_bit_for_bit(rng):
    # `factor_saddle` on the banded plan holds the pivots of its last fresh factorization
    # (`refactor_band`: the operations on the entries that can be nonzero only); where partial
    # pivoting picks other rows it factors afresh.  Against `factor_band` on a band of its own:
    # the same pivots and band, bit for bit, in all three cases; the solutions (multiplied by
    # U's reciprocal diagonal instead of divided) to a stable LU's backward error, and both
    # solves bit for bit on the same band without the reciprocals.
    matrix = saddle_like(rng, 30)
    size = matrix.shape[0]
    factorization = compiled_factorization(matrix.indptr, matrix.indices)
    band, order, slots, (lower, upper) = factorization[0], factorization[1], factorization[2], factorization[3]
    schedule = factorization[7]
    assert order.size and schedule[5].shape[1] > 0 and np.shares_memory(schedule[0], band)
    reference = np.zeros_like(band, order="F")
    pivots, expected_pivots = np.empty(size, dtype=np.int64), np.empty(size, dtype=np.int64)
    extent, capacity = np.empty((2, size), dtype=np.int64), size * (lower + upper)
    factors = (np.empty((2, size + 1), dtype=np.int64), np.empty((2, capacity), dtype=np.int64),
               np.empty((2, capacity)))  # fmt: skip
    base = matrix.data.copy()
    held, seen = [], []
    for values in (base, base * (1.0 + 1e-6 * rng.standard_normal(base.size)), saddle_like(rng, 30).data):
        values = np.append(values, 7.0)
        assert factor_saddle(matrix.indptr, matrix.indices, values, factorization, pivots)
        held.append(schedule[1][3, 0] >= 0)
        seen.append(pivots.copy())
        assert factor_band(values, slots, reference, lower, upper, expected_pivots, extent, factors)
        np.testing.assert_array_equal(pivots, expected_pivots)
        np.testing.assert_array_equal(band, reference)
        b = rng.standard_normal(size)
        x, y = b.copy(), b.copy()
        solve_saddle(factorization, pivots, x)
        solve_band(reference, lower, upper, expected_pivots, factors, order, np.empty(size), y)
        dense = csr_array((values[:-1], matrix.indices, matrix.indptr)).toarray()
        assert backward_error(dense, x, b) <= BACKWARD_ERROR and backward_error(dense, y, b) <= BACKWARD_ERROR
        np.testing.assert_allclose(x, y, rtol=1e-9, atol=1e-9 * np.abs(y).max())
        z = b.copy()
        solve_band(band, lower, upper, pivots, factorization[6], order, np.empty(size), z)
        np.testing.assert_array_equal(z, y)
    assert held == [True, True, True]
    # the perturbed values kept the pivots (the held schedule ran), the new ones did not
    assert np.array_equal(seen[0], seen[1]) and not np.array_equal(seen[1], seen[2])
    assert not factor_saddle(matrix.indptr, matrix.indices, np.zeros(base.size + 1), factorization, pivots)
