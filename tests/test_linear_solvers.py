"""The linear solvers against scipy and numpy, on test-set Jacobians along their motions.

Accuracy is judged by the normwise backward error ``|J x - b| / (|J| |x| + |b|)`` (max
norms), which a backward-stable LU keeps near the unit roundoff whatever the
conditioning, and by agreement with scipy's `spsolve`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg
from numba import njit
from scipy.sparse import csr_array
from scipy.sparse import eye as sparse_eye
from scipy.sparse import random as sparse_random
from scipy.sparse.linalg import splu, spsolve

from sparsekin.engine.discretization import Discretization
from sparsekin import solve_kinematics, testset
from sparsekin.engine import _lu_kernels, _pivoting_kernels, linalg
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.dense import DenseSolver
from sparsekin.engine.linalg import (
    MAX_GROWTH,
    MIN_PIVOT_RATIO,
    RefactorSolver,
    SingularMatrix,
    SuperLUSolver,
)
from sparsekin.engine.dissection import DissectionSolver
from sparsekin.engine.supernodal import SupernodalSolver
from sparsekin.engine.pattern import build_pattern

#: Largest accepted normwise backward error of a solve.
BACKWARD_ERROR = 1e-14
#: Agreement with `spsolve`, relative to the largest entry of the solution: these small
#: models have condition numbers below 1e4, so two stable solvers agree far closer.
AGREEMENT = 1e-10
#: The families, small, and the time span of the configurations taken along each motion.
FAMILIES = {
    "task5": (testset.task5, 2.0),
    "task5_chain": (lambda: testset.task5_chain(3), 2.0),
    "four_bar_chain": (lambda: testset.four_bar_chain(8), 1.2),
    "lattice": (lambda: testset.lattice(3, 4), 1.0),
}


def _superlu_in_metis_order() -> SuperLUSolver:
    pytest.importorskip("pymetis")  # the `meshes` extra
    return SuperLUSolver(ordering="metis")


#: Each solver made from where the bodies of the Jacobian's model are drawn (only
#: `DissectionSolver` reads it).
SOLVERS = {
    "superlu": lambda points: SuperLUSolver(),
    "superlu-metis": lambda points: _superlu_in_metis_order(),
    "refactor": lambda points: RefactorSolver(),
    "dense": lambda points: DenseSolver(),
    "dissection": DissectionSolver,
    "supernodal": SupernodalSolver,
    "dissection-superlu-solves": lambda points: DissectionSolver(points, take_out_factors=False),
}


def points_in_a_row(n_coordinates: int) -> np.ndarray:
    """Places of the bodies of a matrix that comes from no model: in a row."""
    return np.column_stack([np.arange(n_coordinates // 3, dtype=float), np.zeros(n_coordinates // 3)])
N_CONFIGURATIONS = 4


class Family:
    """A mechanism, its assembler and coordinates at a few times along its motion."""

    def __init__(self, name: str) -> None:
        build, t_end = FAMILIES[name]
        self.mechanism = build()
        self.pattern = build_pattern(self.mechanism)
        self.assembler = Assembler(Discretization(self.mechanism, self.pattern))
        self.times = np.linspace(0.0, t_end, N_CONFIGURATIONS)
        self.points = self.pattern.initial_coordinates.reshape(-1, 3)[:, :2]
        self.coordinates = solve_kinematics(self.mechanism, self.times).coordinates

    def jacobian_at(self, k: int) -> csr_array:
        """The assembler's Jacobian (always the same array, refilled) at configuration k."""
        self.assembler.set_time(self.times[k])
        self.assembler.fill_residual_jacobian(self.coordinates[k])
        return self.assembler.jacobian


@pytest.fixture(scope="module", params=list(FAMILIES))
def family(request) -> Family:
    return Family(request.param)


def backward_error(jacobian, x: np.ndarray, b: np.ndarray) -> float:
    """Normwise backward error of ``jacobian @ x = b`` in max norms."""
    norm = abs(jacobian).sum(axis=1).max()
    return float(np.abs(jacobian @ x - b).max() / (norm * np.abs(x).max() + np.abs(b).max()))


def check_solves(solver, jacobian, rng) -> None:
    """Both systems, one and two right-hand sides, against `spsolve`."""
    n = jacobian.shape[0]
    b = rng.standard_normal(n)
    for matrix, transposed in ((jacobian, False), (jacobian.T.tocsr(), True)):
        x = solver.solve(b, transposed=transposed)
        assert backward_error(matrix, x, b) <= BACKWARD_ERROR
        reference = spsolve(matrix.tocsc(), b)
        np.testing.assert_allclose(x, reference, rtol=0, atol=AGREEMENT * np.abs(reference).max())
        both = solver.solve(np.stack([b, 2.0 * b], axis=1), transposed=transposed)
        expected = np.stack([x, 2.0 * x], axis=1)
        np.testing.assert_allclose(both, expected, rtol=1e-14, atol=1e-14 * np.abs(x).max())


# ---------------------------------------------------------------------- all solvers
@pytest.mark.parametrize("solver_name", list(SOLVERS))
def test_solves_along_the_motion(family, solver_name, rng):
    solver = SOLVERS[solver_name](family.points)
    for k in range(N_CONFIGURATIONS):
        jacobian = family.jacobian_at(k)
        solver.factor(jacobian)
        check_solves(solver, jacobian, rng)
    if solver_name == "refactor":  # one analysis, then refactorizations on its pattern
        counts = (solver.n_factorizations, solver.n_refactorizations, solver.n_fallbacks)
        assert counts == (1, N_CONFIGURATIONS - 1, 0)
        assert solver.pivot_ratio >= MIN_PIVOT_RATIO and solver.growth <= MAX_GROWTH
    elif solver_name == "supernodal":  # one analysis; the matching's pivots hold along the motion
        counts = (solver.n_factorizations, solver.n_refactorizations, solver.n_fallbacks)
        assert counts == (1, N_CONFIGURATIONS - 1, 0)
    else:
        assert solver.n_factorizations == N_CONFIGURATIONS
    assert solver.n_solves == N_CONFIGURATIONS * 2 * 3  # 2 systems × (1 + 2 right-hand sides)


@pytest.mark.parametrize("solver_name", list(SOLVERS))
def test_solve_into_out(solver_name, rng):
    matrix = csr_array(rng.standard_normal((6, 6)) + 6.0 * np.eye(6))
    solver = SOLVERS[solver_name](points_in_a_row(6))
    solver.factor(matrix)
    b = rng.standard_normal(6)
    out = np.empty(6)
    assert solver.solve(b, out=out) is out
    np.testing.assert_allclose(matrix @ out, b, atol=1e-14)
    two = rng.standard_normal((6, 2))
    out2 = np.empty((6, 2))
    assert solver.solve(two, out=out2, transposed=True) is out2
    np.testing.assert_allclose(matrix.T @ out2, two, atol=1e-14)
    in_place = b.copy()
    solver.solve(in_place, out=in_place)  # `out` may be `rhs`
    np.testing.assert_allclose(in_place, out, rtol=1e-15)
    with pytest.raises(ValueError, match=r"`out` must be a C-contiguous float64 array of shape \(6,\)"):
        solver.solve(b, out=np.empty(5))
    with pytest.raises(ValueError, match=r"`out` must be a C-contiguous float64 array of shape \(6, 2\)"):
        solver.solve(two, out=np.empty((2, 6)).T)


@pytest.mark.parametrize("solver_name", list(SOLVERS))
def test_singular_jacobian_raises(family, solver_name):
    """A body whose coordinate appears in no equation: a zero column, pattern unchanged."""
    jacobian = family.jacobian_at(0).copy()
    jacobian.data[jacobian.indices == 2] = 0.0  # the angle of body 0
    solver = SOLVERS[solver_name](family.points)
    with pytest.raises(SingularMatrix):
        solver.factor(jacobian)
    with pytest.raises(RuntimeError, match="no factorization: call `factor` first"):
        solver.solve(np.ones(jacobian.shape[0]))


@pytest.mark.parametrize("solver_name", list(SOLVERS))
def test_non_finite_jacobian_raises(solver_name):
    matrix = csr_array(np.array([[2.0, 1.0, 0.0], [np.nan, 3.0, 0.0], [0.0, 0.0, 1.0]]))
    solver = SOLVERS[solver_name](points_in_a_row(3))
    with pytest.raises(SingularMatrix):  # at the factorization, or at the latest at the solve
        solver.factor(matrix)
        solver.solve(np.ones(3))


@pytest.mark.parametrize("solver_name", ["refactor", "dense", "dissection", "supernodal"])
def test_input_is_validated(solver_name):
    solver = SOLVERS[solver_name](points_in_a_row(3))
    with pytest.raises(ValueError, match="`jacobian` must be a scipy.sparse CSR array, got ndarray"):
        solver.factor(np.eye(3))
    with pytest.raises(ValueError, match=r"`jacobian` must be square, got shape \(2, 3\)"):
        solver.factor(csr_array(np.ones((2, 3))))
    solver.factor(csr_array(np.eye(3)))
    with pytest.raises(ValueError, match=r"`rhs` must have shape \(3,\) or \(3, n_rhs\), got \(4,\)"):
        solver.solve(np.ones(4))


# ---------------------------------------------------------------------- RefactorSolver
def test_permutation_convention():
    """The permutation convention of docs/design-notes.md ("Sparse LU"), for the matrix the solvers
    factor, ``A = jacobian.T``."""
    family = Family("task5")
    a = family.jacobian_at(1).T
    lu = splu(a, permc_spec="COLAMD")
    n = a.shape[0]
    rows = np.zeros((n, n))
    rows[lu.perm_r, np.arange(n)] = 1.0  # Pr: row i of A goes to row perm_r[i]
    columns = np.zeros((n, n))
    columns[np.arange(n), lu.perm_c] = 1.0  # Pc: column c of A goes to column perm_c[c]
    np.testing.assert_allclose(rows @ a.toarray() @ columns, (lu.L @ lu.U).toarray(), atol=1e-14)


def test_structural_pattern_keeps_exact_zeros(rng):
    """Pitfall 1: the four-bar chain starts with exact zeros, which SuperLU drops from L, U.

    Factored there, the solver must refactor correctly anywhere else on the same pattern:
    along the motion and at arbitrary coordinates where the couplers are turned.
    """
    family = Family("four_bar_chain")
    start = family.jacobian_at(0)
    zeros_at_start = np.count_nonzero(start.data == 0.0)  # sin 0 of the couplers, and more
    solver = RefactorSolver()
    solver.factor(start)
    lu = splu(start.T, permc_spec="COLAMD")
    assert lu.L.nnz - start.shape[0] + lu.U.nnz < solver.nnz_factors  # SuperLU's is smaller
    check_solves(solver, start, rng)
    for k in range(1, N_CONFIGURATIONS):
        jacobian = family.jacobian_at(k)
        solver.factor(jacobian)
        check_solves(solver, jacobian, rng)
    for _ in range(3):
        coordinates = family.coordinates[0] + 0.2 * rng.standard_normal(family.pattern.n_coordinates)
        family.assembler.fill_residual_jacobian(coordinates)
        assert np.count_nonzero(family.assembler.jacobian.data == 0.0) < zeros_at_start
        solver.factor(family.assembler.jacobian)
        check_solves(solver, family.assembler.jacobian, rng)
    assert (solver.n_factorizations, solver.n_fallbacks) == (1, 0)


def test_fill_straight_into_factor_order(family, rng):
    """Compose the assembler's slots with `value_positions`: refills land in factor order."""
    solver = RefactorSolver()
    solver.factor(family.jacobian_at(0))
    positions = np.append(solver.value_positions, family.pattern.nnz)  # keep the discard slot
    composed = replace(family.pattern, primitives=family.pattern.primitives.with_slots(positions))
    ordered = Assembler(Discretization(family.mechanism, composed))
    by_gather = RefactorSolver()
    by_gather.factor(family.jacobian_at(0))
    for k in range(1, N_CONFIGURATIONS):
        jacobian = family.jacobian_at(k)
        ordered.fill_residual_jacobian(family.coordinates[k])
        solver.factor_ordered(ordered.jacobian.data)  # its values are in factor order
        check_solves(solver, jacobian, rng)
        by_gather.factor(jacobian)
        b = rng.standard_normal(jacobian.shape[0])
        np.testing.assert_array_equal(solver.solve(b), by_gather.solve(b))  # the same arithmetic
    counts = (solver.n_factorizations, solver.n_refactorizations, solver.layout_version)
    assert counts == (1, N_CONFIGURATIONS - 1, 1)
    message = rf"`values` must be a contiguous float64 array of shape \({family.pattern.nnz},\)"
    with pytest.raises(ValueError, match=message):
        solver.factor_ordered(np.zeros(3))


def test_lean_solver_factors_bit_for_bit(family, rng):
    """`lean` (B's rows read through perm_r at each refactorization, not held): the same
    factors as the default solver, bit for bit, refactored along the motion, in factor
    order and after the guard's fallback to a fresh factorization."""
    held, lean = RefactorSolver(), RefactorSolver(lean=True)
    for k in range(N_CONFIGURATIONS):
        jacobian = family.jacobian_at(k)
        held.factor(jacobian)
        lean.factor(jacobian)
        b = rng.standard_normal(jacobian.shape[0])
        np.testing.assert_array_equal(lean.solve(b), held.solve(b))
        check_solves(lean, jacobian, rng)
    data = family.jacobian_at(1).data[np.argsort(lean.value_positions)]  # in factor order
    held.factor_ordered(data)
    lean.factor_ordered(data)
    b = rng.standard_normal(family.jacobian_at(1).shape[0])
    np.testing.assert_array_equal(lean.solve(b), held.solve(b))
    jacobian = family.jacobian_at(2).copy()  # rescaled: the held pivots trip the guard
    jacobian.data *= (10.0 ** rng.uniform(-6.0, 6.0, jacobian.shape[1]))[jacobian.indices]
    held.factor(jacobian)
    lean.factor(jacobian)
    assert lean.n_fallbacks == held.n_fallbacks and lean.n_refactorizations == held.n_refactorizations
    np.testing.assert_array_equal(lean.solve(b), held.solve(b))
    check_solves(lean, jacobian, rng)


def test_guard_trips_on_a_zero_pivot(rng):
    """Diagonally dominant first: the diagonal pivots.  Then a zero diagonal, not singular."""
    pattern = np.ones((4, 4))
    solver = RefactorSolver()
    solver.factor(csr_array(pattern + 8.0 * np.eye(4)))
    swapped = csr_array(pattern - np.eye(4) + 1e-30)  # same pattern: every entry stored
    swapped.data[:] = (pattern - np.eye(4)).ravel()
    assert swapped.nnz == 16
    solver.factor(swapped)
    assert (solver.n_factorizations, solver.n_refactorizations, solver.n_fallbacks) == (2, 1, 1)
    check_solves(solver, swapped, rng)
    assert solver.layout_version == 1  # the column order depends on the pattern only


def test_guard_trips_on_a_small_pivot_ratio(rng):
    """Coordinates rescaled by up to 1e±6: the old pivot order puts tiny pivots first."""
    family = Family("task5_chain")
    solver = RefactorSolver()
    solver.factor(family.jacobian_at(0))
    jacobian = family.jacobian_at(1).copy()
    scales = 10.0 ** rng.uniform(-6.0, 6.0, jacobian.shape[1])
    jacobian.data *= scales[jacobian.indices]
    solver.factor(jacobian)
    assert (solver.n_factorizations, solver.n_fallbacks) == (2, 1)
    check_solves(solver, jacobian, rng)
    assert solver.pivot_ratio >= MIN_PIVOT_RATIO  # the fresh pivots are SuperLU's
    unguarded = RefactorSolver(min_pivot_ratio=0.0, max_growth=np.inf)
    unguarded.factor(family.jacobian_at(0))
    unguarded.factor(jacobian)
    assert unguarded.n_fallbacks == 0 and unguarded.pivot_ratio < MIN_PIVOT_RATIO  # what tripped


def _column_runs(jacobian: csr_array, perm_c: np.ndarray) -> tuple:
    """B's column pointers and offsets for the column order `perm_c` of ``A = jacobian.T``
    (as `RefactorSolver` holds them), and A's column of each column of B."""
    column_of = np.argsort(perm_c)
    b_indptr = np.concatenate([[0], np.cumsum(np.diff(jacobian.indptr)[column_of])])
    return (b_indptr, jacobian.indptr[column_of] - b_indptr[:-1]), column_of


@pytest.mark.parametrize("trial", range(40))
def test_new_pivots_are_lapacks_partial_pivoting(trial, rng):
    """`partial_pivoting_rows` at threshold 1 on a random sparse matrix and column order
    chooses the rows LAPACK's ``getrf`` chooses for the column-permuted dense matrix (no
    ties: random values), whatever the held rows; reads the values in either order; counts
    the entries that the structural analysis of those pivots then finds.  At threshold 0.1
    it keeps those rows as held rows, and from other held rows takes pivots within 0.1 of
    their column's largest candidate."""
    n = int(rng.integers(1, 40))
    jacobian = csr_array(sparse_random(n, n, density=rng.uniform(0.05, 0.4), random_state=rng) + 0.3 * sparse_eye(n))
    jacobian.sort_indices()
    if np.linalg.matrix_rank(jacobian.toarray()) < n:
        pytest.skip("a singular draw")
    perm_c = rng.permutation(n)
    b_pattern, column_of = _column_runs(jacobian, perm_c)
    work = np.zeros(n)
    held = (rng.permutation(n), perm_c)
    pivot_of, bad_column, l_entries, u_entries = _pivoting_kernels.partial_pivoting_rows(
        jacobian.data, False, b_pattern, jacobian.indices, held, 1.0, 1, work)  # fmt: skip
    assert bad_column == -1 and not work.any()
    _, swaps = scipy.linalg.lu_factor(jacobian.toarray().T[:, column_of])
    order = np.arange(n)  # row k of the pivoted matrix is row order[k]
    for k, row in enumerate(swaps):
        order[[k, row]] = order[[row, k]]
    np.testing.assert_array_equal(pivot_of, np.argsort(order))
    in_factor_order = np.concatenate([jacobian.data[jacobian.indptr[c]:jacobian.indptr[c + 1]] for c in column_of])
    again = _pivoting_kernels.partial_pivoting_rows(
        in_factor_order, True, b_pattern, jacobian.indices, held, 1.0, 1, work)  # fmt: skip
    np.testing.assert_array_equal(again[0], pivot_of)
    b_rows = np.concatenate([pivot_of[jacobian.indices[jacobian.indptr[c]:jacobian.indptr[c + 1]]] for c in column_of])
    l_indptr, _, u_indptr, _ = _lu_kernels.analyse_lu_pattern(b_pattern[0], b_rows.astype(np.int32), 1, 1)
    assert (l_entries, u_entries) == (l_indptr[-1], u_indptr[-1]) == again[2:]
    kept = _pivoting_kernels.partial_pivoting_rows(
        jacobian.data, False, b_pattern, jacobian.indices, (pivot_of, perm_c), 0.1, 1, work)  # fmt: skip
    np.testing.assert_array_equal(kept[0], pivot_of)
    other = _pivoting_kernels.partial_pivoting_rows(jacobian.data, False, b_pattern, jacobian.indices, held, 0.1, 1, work)
    solver = RefactorSolver(min_pivot_ratio=0.0, max_growth=np.inf)
    solver.suggest(other[0], perm_c)
    solver.factor(jacobian)
    assert solver.n_fallbacks == 0 and solver.pivot_ratio >= 0.1 * (1.0 - 1e-12)


def test_new_pivots_without_superlu(monkeypatch, rng):
    """When the guard trips, the new pivots come from partial pivoting on the held column
    order: SuperLU is not called, the layout (column order) stays, the pivots are good and
    the solves agree with `spsolve`; a singular matrix still goes to SuperLU, which says so,
    and the solver refactors the next matrix on its held pivots."""
    family = Family("task5_chain")
    solver = RefactorSolver()
    solver.factor(family.jacobian_at(0))
    perm_c, version = solver.perm_c.copy(), solver.layout_version

    def no_superlu(*args, **kwargs):
        raise AssertionError("SuperLU called")

    monkeypatch.setattr(linalg, "_splu", no_superlu)
    jacobian = family.jacobian_at(1).copy()
    jacobian.data *= (10.0 ** rng.uniform(-6.0, 6.0, jacobian.shape[1]))[jacobian.indices]
    solver.factor(jacobian)
    assert (solver.n_factorizations, solver.n_fallbacks, solver.layout_version) == (2, 1, version)
    np.testing.assert_array_equal(solver.perm_c, perm_c)
    assert solver.pivot_ratio >= linalg.NEW_PIVOT_THRESHOLD * (1.0 - 1e-12)  # |L| <= 10
    check_solves(solver, jacobian, rng)
    ordered = np.empty(jacobian.nnz)
    ordered[solver.value_positions] = family.jacobian_at(2).data
    ordered[solver.value_positions] *= (10.0 ** rng.uniform(-6.0, 6.0, jacobian.shape[1]))[jacobian.indices]
    solver.factor_ordered(ordered)  # the rescaling reversed: the guard trips again
    assert (solver.n_factorizations, solver.n_fallbacks) == (3, 2)
    monkeypatch.undo()
    singular = family.jacobian_at(2).copy()
    singular.data[singular.indices == 5] = 0.0
    with pytest.raises(SingularMatrix, match="singular"):
        solver.factor(singular)
    assert (solver.n_factorizations, solver.n_fallbacks) == (4, 3)
    solver.factor(family.jacobian_at(3))
    check_solves(solver, family.jacobian_at(3), rng)


def test_guard_trips_on_growth(rng):
    """Wilkinson's matrix: |L| <= 1 without any row exchange, yet U grows as 2^(n-1).

    A dense pattern (every entry stored) so that the first factorization's permutations
    can carry the matrix into the pivot order: ``Pr A Pc`` is then Wilkinson's matrix.
    """
    n = 14  # growth 2^13 = 8192 > MAX_GROWTH
    solver = RefactorSolver()
    dominant = rng.uniform(-1.0, 1.0, (n, n)) + 2.0 * n * np.eye(n)
    solver.factor(csr_array(dominant))
    wilkinson = np.eye(n) - np.tril(np.ones((n, n)), -1)
    wilkinson[:, -1] = 1.0
    a = wilkinson[np.ix_(solver.perm_r, solver.perm_c)]  # Pr a Pc = wilkinson
    jacobian = csr_array(dominant)
    jacobian.data[:] = a.T.ravel()  # the solver factors A = jacobian.T
    assert jacobian.nnz == n * n
    solver.factor(jacobian)
    assert solver.n_fallbacks == 1 and solver.growth > MAX_GROWTH  # SuperLU's own has it too
    unguarded = RefactorSolver(max_growth=np.inf)
    unguarded.factor(csr_array(dominant))
    unguarded.factor(jacobian)
    assert unguarded.n_fallbacks == 0 and unguarded.pivot_ratio == 1.0 and unguarded.growth == 2.0 ** (n - 1)
    b = rng.standard_normal(n)  # partial pivoting can do no better: its backward error grows too
    np.testing.assert_allclose(solver.solve(b), np.linalg.solve(jacobian.toarray(), b), rtol=1e-12)


def test_refactor_to_singular_then_recover(rng):
    family = Family("lattice")
    solver = RefactorSolver()
    solver.factor(family.jacobian_at(0))
    singular = family.jacobian_at(1).copy()
    singular.data[singular.indices == 5] = 0.0
    with pytest.raises(SingularMatrix, match="singular"):
        solver.factor(singular)
    assert (solver.n_factorizations, solver.n_refactorizations, solver.n_fallbacks) == (2, 1, 1)
    jacobian = family.jacobian_at(2)
    solver.factor(jacobian)  # the analysis survived: a refactorization
    assert (solver.n_factorizations, solver.n_refactorizations) == (2, 2)
    check_solves(solver, jacobian, rng)


def test_new_pattern_is_analysed_afresh(rng):
    solver = RefactorSolver()
    solver.factor(Family("task5").jacobian_at(0))
    with pytest.raises(SingularMatrix):  # structurally singular: an empty row
        solver.factor(csr_array((np.ones(2), np.array([0, 1]), np.array([0, 1, 2, 2])), shape=(3, 3)))
    with pytest.raises(RuntimeError, match="no analysis yet"):  # that pattern was not kept
        solver.value_positions
    jacobian = Family("lattice").jacobian_at(1)
    solver.factor(jacobian)
    assert (solver.n_factorizations, solver.n_refactorizations, solver.layout_version) == (3, 0, 2)
    check_solves(solver, jacobian, rng)
    with pytest.raises(ValueError, match="canonical CSR"):
        RefactorSolver().factor(csr_array((np.ones(2), np.array([1, 0]), np.array([0, 2, 2])), shape=(2, 2)))
    with pytest.raises(ValueError, match=r"`min_pivot_ratio` must be in \[0, 1\], got 2"):
        RefactorSolver(min_pivot_ratio=2)


# ---------------------------------------------------------------------- dense kernels
@pytest.mark.parametrize("n", [1, 5, 30, 200])
def test_dense_lu_kernels_against_numpy(n, rng):
    matrix = rng.standard_normal((n, n))
    b = rng.standard_normal(n)
    factors = matrix.copy()
    pivots = np.empty(n, dtype=np.int64)
    assert _lu_kernels.dense_lu_factor(factors, pivots)
    x = b.copy()
    _lu_kernels.dense_lu_solve(factors, pivots, x)
    np.testing.assert_allclose(x, np.linalg.solve(matrix, b), rtol=1e-10, atol=1e-10 * np.abs(x).max())
    assert backward_error(matrix, x, b) <= BACKWARD_ERROR
    x = b.copy()  # the transposed system, with the same factors (the forces' solve)
    _lu_kernels.dense_lu_solve_transposed(factors, pivots, x)
    np.testing.assert_allclose(x, np.linalg.solve(matrix.T, b), rtol=1e-10, atol=1e-10 * np.abs(x).max())
    assert backward_error(matrix.T, x, b) <= BACKWARD_ERROR
    swapped = matrix.copy()  # the documented pivot convention: swaps in order give L U
    for k, row in enumerate(pivots):
        swapped[[k, row]] = swapped[[row, k]]
    lower = np.tril(factors, -1) + np.eye(n)
    np.testing.assert_allclose(lower @ np.triu(factors), swapped, atol=1e-12 * np.abs(matrix).max() * n)
    assert np.abs(lower).max() <= 1.0


def test_dense_lu_kernels_report_failure():
    pivots = np.empty(3, dtype=np.int64)
    singular = np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 1.0]])  # exact zero pivot
    assert not _lu_kernels.dense_lu_factor(singular, pivots)
    assert not _lu_kernels.dense_lu_factor(np.array([[1.0, 2.0], [np.nan, 1.0]]), pivots[:2])
    assert not _lu_kernels.dense_lu_factor(np.array([[np.inf, 0.0], [0.0, 1.0]]), pivots[:2])


@njit(cache=True)
def _solve_in_a_compiled_loop(matrices, rhs, pivots, solutions):
    for k in range(matrices.shape[0]):
        a = matrices[k].copy()
        if not _lu_kernels.dense_lu_factor(a, pivots):
            return False
        solutions[k] = rhs[k]
        _lu_kernels.dense_lu_solve(a, pivots, solutions[k])
    return True


def test_dense_lu_kernels_from_compiled_code(rng):
    matrices = rng.standard_normal((3, 8, 8))
    rhs = rng.standard_normal((3, 8))
    solutions = np.empty((3, 8))
    assert _solve_in_a_compiled_loop(matrices, rhs, np.empty(8, dtype=np.int64), solutions)
    np.testing.assert_allclose(solutions, np.linalg.solve(matrices, rhs[..., None])[..., 0], rtol=1e-10)


def test_a_failed_fresh_factorization_leaves_the_fill_in_the_solver_order(rng):
    """The guard trips, and the fresh factorization chooses a new column order, then fails:
    the assembler must fill in the new order from then on, or the next refactorization
    reads every value at the wrong place."""
    from sparsekin.engine.newton import Factorizer

    family = Family("task5_chain")
    assembler = Assembler(Discretization(family.mechanism, family.pattern))  # one that fills in factor order
    jacobian = family.jacobian_at(0)
    other = splu(jacobian.T.tocsc(), permc_spec="MMD_AT_PLUS_A")  # a pivot order that is not COLAMD's
    solver = RefactorSolver()
    solver.suggest(other.perm_r, other.perm_c)
    factor = Factorizer(assembler, solver)
    assembler.set_time(family.times[0])
    assembler.fill_residual_jacobian(family.coordinates[0])
    factor()
    assert solver.layout_version == 1 and np.array_equal(assembler.csr_positions, solver.value_positions)
    assembler.values[0] = np.inf  # the guard trips; SuperLU's COLAMD order is analysed, then fails
    with pytest.raises(SingularMatrix, match="non-finite"):
        factor()
    assert solver.layout_version == 2 and np.array_equal(assembler.csr_positions, solver.value_positions)
    assembler.set_time(family.times[1])
    assembler.fill_residual_jacobian(family.coordinates[1])
    factor()
    check_solves(solver, family.jacobian_at(1), rng)
