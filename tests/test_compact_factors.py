"""The solves' compact factors (`sparsekin.engine.compact_factors`, `_compact_lu_kernels`):
`RefactorSolver` solves with L and U without their exact zeros, compacted in place after
`COMPACT_AFTER_SOLVES` solves of a factorization (set to 0 here: from the first solve).  Checked against the solves of `_lu_kernels` on the structural factors of
the same elimination (the same solution: only products with exact zeros are left out) and
against `spsolve`; the in-place compaction must not disturb the next refactorization."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import csr_array, diags_array
from scipy.sparse import random_array as sparse_random
from scipy.sparse.linalg import spsolve

from sparsekin.engine import _compact_lu_kernels, _lu_kernels, _relative_lu_kernels, compact_factors
from sparsekin.engine.linalg import RefactorSolver
from sparsekin.solve.dynamics import GeneralizedAlphaStepper
from sparsekin.testset import n_four_bar


@pytest.fixture
def compact_at_once(monkeypatch):
    monkeypatch.setattr(compact_factors, "COMPACT_AFTER_SOLVES", 0)


def structural_rows(solver: RefactorSolver) -> tuple[np.ndarray, np.ndarray]:
    """L's and U's structural rows as indices, made from the offsets of a relative pattern
    (whose U has counts, no row pointers), and their row pointers."""
    if solver._relative is None:
        return solver._l_indices, solver._u_indices, solver._u_indptr
    rows = []
    u_indptr = np.concatenate(([0], np.cumsum(solver._relative[1], dtype=np.int64)))
    assert solver._u_indptr is None
    for indptr, offsets, counts in zip((solver._l_indptr, u_indptr), (solver._l_indices, solver._u_indices),
                                       solver._relative):  # fmt: skip
        assert offsets.dtype == np.int8 and counts.dtype == np.uint8
        np.testing.assert_array_equal(counts, np.diff(indptr))
        indices = np.empty(offsets.size, dtype=np.int64)
        _relative_lu_kernels.rows_of(indptr, offsets, indices)
        rows.append(indices)
    return (*rows, u_indptr)


def structural_factors(solver: RefactorSolver, jacobian: csr_array) -> tuple:
    """The factors of `solver`'s analysis refactored afresh on its structural patterns (their
    zeros kept), as `_lu_kernels`' solves read them."""
    l_indices, u_indices, u_indptr = structural_rows(solver)
    lower = (solver._l_indptr, l_indices, np.zeros(l_indices.size))
    upper = (u_indptr, u_indices, np.zeros(u_indices.size), np.zeros(solver._n))
    b_indptr, offsets = solver._b_layout()  # (made again where a lean solver holds `_column_of` instead)
    b_rows = np.empty(jacobian.nnz, dtype=b_indptr.dtype)
    _lu_kernels.fill_column_rows(solver._indices, offsets, b_indptr, solver._perm_r, b_rows)
    stats = np.zeros(_lu_kernels.N_STATS)
    _lu_kernels.refactor_lu(jacobian.data, False, (b_indptr, b_rows, offsets), lower, upper, np.zeros(solver._n),
                            stats)  # fmt: skip
    assert stats[_lu_kernels.STAT_BAD_COLUMN] == -1.0
    return (solver._perm_r, solver._perm_c, lower, upper)


def check_against_structural(solver: RefactorSolver, jacobian: csr_array, rng) -> None:
    """Every solve of `solver` equals the structural factors' (bit for bit, to the sign of
    a zero) and agrees with `spsolve`."""
    n = jacobian.shape[0]
    factors = structural_factors(solver, jacobian)
    b, c = rng.standard_normal(n), rng.standard_normal(n)
    for kernel, transposed in ((_lu_kernels.solve_lu_transposed, False), (_lu_kernels.solve_lu, True)):
        expected = np.empty(n)
        kernel(factors, b, np.zeros(n), expected, np.zeros(1))
        np.testing.assert_array_equal(solver.solve(b, transposed=transposed), expected)
        matrix = jacobian.T if transposed else jacobian
        reference = spsolve(matrix.tocsc(), b)
        np.testing.assert_allclose(expected, reference, rtol=0, atol=1e-10 * np.abs(reference).max())
    first, second = b.copy(), c.copy()
    solver.solve_pair(first, second)
    np.testing.assert_array_equal(first, solver.solve(b))
    np.testing.assert_array_equal(second, solver.solve(c))


def compacted_entries(solver: RefactorSolver) -> tuple[int, int]:
    """Entries of L and U off the diagonal: compact, structural."""
    assert solver._compacted
    compact = sum(int(counts.sum()) for counts, _ in solver._compact)
    return compact, solver._l_indices.size + solver._u_indices.size


def chain_saddle_matrices(loops: int, steps: int) -> list[csr_array]:
    """The iteration matrices the dynamics of an N-four-bar chain factors (copies)."""
    stepper = GeneralizedAlphaStepper(n_four_bar(loops), 1e-3, linear_solver="refactor")
    matrices = []
    stepper.start(0.0)
    factor = stepper.solver.factor
    stepper.solver.factor = lambda matrix: (matrices.append(matrix.copy()), factor(matrix))
    for k in range(1, steps + 1):
        stepper.advance(k * 1e-3)
    return matrices


def small_integer_matrix(n: int, rng) -> csr_array:
    """Random sparse matrix of small integers plus a dominant diagonal: its elimination meets
    exact cancellations, whose zeros stay in the structural factors."""
    pattern = sparse_random((n, n), density=4.0 / n, rng=rng, format="csr")
    pattern.data = rng.integers(-2, 3, pattern.nnz).astype(float)
    matrix = csr_array(pattern + diags_array(np.full(n, 8.0)))
    matrix.sort_indices()
    return matrix


def test_compact_in_place_keeps_the_nonzeros_in_order():
    indptr = np.array([0, 3, 3, 6], dtype=np.int32)
    indices = np.array([4, 1, 2, 5, 0, 3], dtype=np.int32)
    values = np.array([0.0, 2.0, -0.0, np.nan, 3.0, 0.0])
    counts, offsets = np.full(3, 9, dtype=np.uint8), np.full(6, 9, dtype=np.int8)
    _compact_lu_kernels.compact_in_place(indptr, indices, values, counts, offsets)
    np.testing.assert_array_equal(counts, [1, 0, 2])
    np.testing.assert_array_equal(offsets[:3], [1, 3, -2])  # rows 1 (column 0), 5 and 0 (column 2)
    np.testing.assert_array_equal(values[:3], [2.0, np.nan, 3.0])  # NaN kept
    np.testing.assert_array_equal(indices, [4, 1, 2, 5, 0, 3])  # the pattern untouched


def test_offsets_fit_a_byte():
    indptr = np.array([0, 1, 1], dtype=np.int64)
    assert _compact_lu_kernels.offsets_fit(indptr, np.array([127], dtype=np.int64))
    assert not _compact_lu_kernels.offsets_fit(indptr, np.array([128], dtype=np.int64))
    many = np.array([0, 256], dtype=np.int64)  # a column of 256 entries
    assert not _compact_lu_kernels.offsets_fit(many, np.zeros(256, dtype=np.int64))


def test_far_pattern_is_not_compacted(rng, compact_at_once):
    """Rows more than 127 from the diagonal: the structural factors, as main's."""
    matrix = small_integer_matrix(400, rng)
    solver = RefactorSolver()
    solver.factor(matrix)
    check_against_structural(solver, matrix, rng)
    assert solver._compact is False and not solver._compacted


@pytest.mark.parametrize("lean", [False, True])
def test_chain_saddle_solves_as_the_structural_factors(lean, rng, compact_at_once):
    """The N-four-bar chain's iteration matrices, refactored one after the other on the
    compacted factors of the last: each solve equals the structural factors'."""
    matrices = chain_saddle_matrices(6, 4)
    solver = RefactorSolver(lean=lean)
    for matrix in matrices:
        solver.factor(matrix)
        check_against_structural(solver, matrix, rng)
    compact, structural = compacted_entries(solver)
    assert compact < 0.9 * structural  # the chain's factors hold zeros: not a vacuous test
    assert solver.n_refactorizations >= len(matrices) - 1


def test_random_matrices_refactored_and_fallen_back(rng, compact_at_once):
    """Random integer matrices on one pattern, new values each time (a refactorization on
    the compacted arrays), then values that trip the guard (a fresh factorization)."""
    matrix = small_integer_matrix(60, rng)
    solver = RefactorSolver()
    solver.factor(matrix)
    check_against_structural(solver, matrix, rng)
    for _ in range(3):
        matrix.data = rng.integers(-2, 3, matrix.nnz).astype(float)
        matrix.data[matrix.indices == np.repeat(np.arange(60), np.diff(matrix.indptr))] = 8.0
        solver.factor(matrix)
        check_against_structural(solver, matrix, rng)
    assert compacted_entries(solver)[0] < compacted_entries(solver)[1]
    fresh = RefactorSolver()
    fresh.factor(matrix)  # the same values factored by a solver that never compacted
    b = rng.standard_normal(60)
    np.testing.assert_array_equal(solver.solve(b), fresh.solve(b))
    scaled = matrix.copy()
    scaled.data *= (10.0 ** rng.uniform(-6.0, 6.0, 60))[scaled.indices]
    solver.factor(scaled)
    assert solver.n_fallbacks == 1
    check_against_structural(solver, scaled, rng)


def test_compacted_after_some_solves_the_same_solutions(rng):
    """With the default threshold: the first solves read the structural factors, the later
    ones the compact factors, all with the same solution; a new factorization starts over."""
    matrix = chain_saddle_matrices(6, 1)[0]
    solver = RefactorSolver(lean=True)
    solver.factor(matrix)
    b = rng.standard_normal(matrix.shape[0])
    first = solver.solve(b)
    for k in range(compact_factors.COMPACT_AFTER_SOLVES + 2):
        np.testing.assert_array_equal(solver.solve(b), first)
        assert solver._compacted == (k + 2 > compact_factors.COMPACT_AFTER_SOLVES)  # solves so far: k + 2
    solver.factor(matrix)
    assert not solver._compacted
    np.testing.assert_array_equal(solver.solve(b), first)


def solves_of(solver: RefactorSolver, matrices: list[csr_array], rng_seed: int) -> list[np.ndarray]:
    """Every matrix factored in turn, then solved more often than `COMPACT_AFTER_SOLVES`
    (structural factors first, compact ones after), both ways and in pairs."""
    rng = np.random.default_rng(rng_seed)
    out = []
    for matrix in matrices:
        solver.factor(matrix)
        out += [solver._l_values.copy(), solver._u_values.copy(), solver._u_inverse.copy()]
        for _ in range(compact_factors.COMPACT_AFTER_SOLVES // 2 + 1):
            b, c = rng.standard_normal((2, matrix.shape[0]))
            out += [solver.solve(b), solver.solve(b, transposed=True)]
            solver.solve_pair(b, c)
            out += [b, c]
        assert solver._compacted
    return out


@pytest.mark.parametrize("lean", [False, True])
def test_relative_patterns_give_the_factors_of_absolute_ones(lean, rng, monkeypatch):
    """L's and U's rows held as a byte each (`_relative_lu_kernels`, the chain's local order;
    lean: B's columns found through `column_of`, `refactor_lu_by_rows`): the factors and every
    solve bit for bit those of int32 rows, before and after the compaction, and after new
    pivots (values that trip the guard)."""
    matrices = chain_saddle_matrices(6, 3)
    scaled = matrices[-1].copy()
    scaled.data *= (10.0 ** rng.uniform(-6.0, 6.0, scaled.shape[0]))[scaled.indices]
    matrices.append(scaled)
    relative = RefactorSolver(lean=lean)
    relative.factor(matrices[0])
    assert relative._relative is not None and relative._l_indices.dtype == np.int8
    if lean:  # B's columns through `column_of` (perm_c's inverse), not B's pointers and offsets
        assert relative._b_indptr is None and relative._offsets is None
        np.testing.assert_array_equal(relative._perm_c[relative._column_of], np.arange(relative._n))
    expected_rows = structural_rows(relative)
    got = solves_of(relative, matrices, 7)
    assert relative.n_fallbacks == 1
    monkeypatch.setattr(compact_factors, "relative_patterns", lambda lower, upper: None)
    absolute = RefactorSolver(lean=lean)
    absolute.factor(matrices[0])
    assert absolute._relative is None
    for rows, expected in zip((absolute._l_indices, absolute._u_indices, absolute._u_indptr), expected_rows):
        np.testing.assert_array_equal(rows, expected)
    expected = solves_of(absolute, matrices, 7)
    assert absolute.n_fallbacks == 1 and len(got) == len(expected)
    for a, b in zip(got, expected):
        np.testing.assert_array_equal(a, b)


def test_solve_with_inverse_permutations_is_the_scattered_solve(rng, compact_at_once):
    """`solve_lu_transposed_inverted` (the right-hand side read through perm_c's inverse, the
    solution written through perm_r's) against `solve_lu_transposed` (scatter and gather
    passes) on a chain's compact factors: the same numbers, in place too, NaN reported."""
    jacobian = chain_saddle_matrices(6, 3)[-1]
    solver = RefactorSolver()
    solver.factor(jacobian)
    solver.solve(rng.standard_normal(jacobian.shape[0]))  # compacted
    kernels, factors = solver._solve_factors(1)
    assert kernels is _compact_lu_kernels
    perm_r, perm_c = factors[:2]
    inverses = (np.empty_like(perm_r), np.empty_like(perm_c))
    _lu_kernels.inverse_permutation(perm_r, inverses[0])
    _lu_kernels.inverse_permutation(perm_c, inverses[1])
    np.testing.assert_array_equal(perm_r[inverses[0]], np.arange(perm_r.size))
    np.testing.assert_array_equal(inverses, solver._inverse_permutations())
    inverted = inverses + factors[2:]
    n, probe = jacobian.shape[0], np.zeros(1)
    for b in (rng.standard_normal(n), np.where(np.arange(n) == n // 2, np.nan, 1.0)):
        expected, out = np.empty(n), np.empty(n)
        _compact_lu_kernels.solve_lu_transposed(factors, b, np.zeros(n), expected, probe)
        expected_probe = probe[0]
        _compact_lu_kernels.solve_lu_transposed_inverted(inverted, b, np.zeros(n), out, probe)
        np.testing.assert_array_equal(out, expected)
        assert np.isnan(expected_probe) == np.isnan(probe[0]) and (probe[0] == 0.0) == (expected_probe == 0.0)
        in_place = b.copy()
        _compact_lu_kernels.solve_lu_transposed_inverted(inverted, in_place, np.zeros(n), in_place, probe)
        np.testing.assert_array_equal(in_place, expected)
