"""Solves with a held factorization of an earlier Jacobian (`sparsekin.engine.krylov`).

Checked against direct solves of the same systems: flexible GMRES reaches the backward
error it is asked for, in one iteration when the matrix is the factored one plus a
low-rank change; `ReusingSolver` keeps its factorization across nearby Jacobians, solves
plain and transposed systems and several right-hand sides, refactors when a solve needed
many iterations (at the next `factor`) or when GMRES cannot converge (at once), and
starts afresh on a new pattern.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import csr_array, random_array
from scipy.sparse.linalg import splu

from sparsekin.engine.krylov import ReusingSolver, fgmres, gmres_workspace
from sparsekin.engine.linalg import RefactorSolver, SuperLUSolver


def _jacobian(n: int, rng) -> csr_array:
    """A well-conditioned sparse matrix with a full diagonal (every pattern entry nonzero)."""
    matrix = random_array((n, n), density=4.0 / n, rng=rng, format="csr") + csr_array(4.0 * np.eye(n))
    matrix.sum_duplicates()
    matrix.data[matrix.data == 0.0] = 0.5
    return csr_array(matrix)


def _backward_error(matrix, x, b) -> float:
    scale = np.abs(matrix.toarray()).sum(axis=0).max()
    return np.linalg.norm(b - matrix @ x) / (np.linalg.norm(b) + scale * np.linalg.norm(x))


def _perturbed(matrix, size, rng) -> csr_array:
    changed = matrix.copy()
    changed.data *= 1.0 + size * rng.standard_normal(changed.nnz)
    return changed


@pytest.mark.parametrize("size", [0.0, 1e-3, 1e-1])
def test_fgmres_reaches_the_backward_error_asked(size, rng):
    matrix = _jacobian(200, rng)
    lu = splu(matrix.tocsc())
    changed = _perturbed(matrix, size, rng)
    b = rng.standard_normal(200)
    x = np.empty(200)
    scale = np.abs(changed.toarray()).sum(axis=0).max()
    iterations = fgmres(changed.__matmul__, lambda v, out: np.copyto(out, lu.solve(v)), b, 1e-15, 30, x, scale)
    assert iterations >= 0
    assert (iterations == 0) == (size == 0.0)
    assert _backward_error(changed, x, b) <= 1e-15
    np.testing.assert_allclose(x, np.linalg.solve(changed.toarray(), b), rtol=0, atol=1e-12 * np.abs(x).max())


def test_fgmres_takes_one_iteration_for_a_rank_one_change(rng):
    """GMRES on ``(P + u vᵀ) P^-1`` converges in at most two iterations (rank one plus the
    identity): the reason it serves Jacobians whose change from sample to sample is a
    few moving bodies."""
    matrix = _jacobian(150, rng).toarray()
    u, v = rng.standard_normal(150), rng.standard_normal(150)
    changed = csr_array(matrix + 0.05 * np.outer(u, v))
    lu = splu(csr_array(matrix).tocsc())
    b = rng.standard_normal(150)
    x = np.empty(150)
    scale = np.abs(changed.toarray()).sum(axis=0).max()
    iterations = fgmres(changed.__matmul__, lambda w, out: np.copyto(out, lu.solve(w)), b, 1e-15, 10, x, scale)
    assert 1 <= iterations <= 2


def test_a_reused_workspace_gives_the_same_iterates(rng):
    """`fgmres` on arrays held from an earlier call (their old contents left in place)
    gives bit for bit what it gives on fresh ones; a workspace of another size is refused."""
    matrix = _jacobian(200, rng)
    lu = splu(matrix.tocsc())
    changed = _perturbed(matrix, 1e-1, rng)
    scale = np.abs(changed.toarray()).sum(axis=0).max()
    workspace = gmres_workspace(200, 30)
    for array in workspace:
        array.fill(np.nan)
    for b in rng.standard_normal((3, 200)):
        fresh, reused = np.empty(200), np.empty(200)
        expected = fgmres(changed.__matmul__, lambda v, out: np.copyto(out, lu.solve(v)), b, 1e-15, 30, fresh, scale)
        iterations = fgmres(changed.__matmul__, lambda v, out: np.copyto(out, lu.solve(v)), b, 1e-15, 30, reused,
                            scale, workspace=workspace)  # fmt: skip
        assert iterations == expected >= 2
        np.testing.assert_array_equal(reused, fresh)
    with pytest.raises(ValueError, match="200 unknowns and 30 iterations, not 200 and 40"):
        fgmres(changed.__matmul__, lambda v, out: np.copyto(out, lu.solve(v)), b, 1e-15, 40, reused, scale,
               workspace=workspace)  # fmt: skip


def test_fgmres_gives_up_with_a_poor_preconditioner(rng):
    matrix = _jacobian(200, rng)
    b = rng.standard_normal(200)
    x = np.empty(200)
    iterations = fgmres(matrix.__matmul__, lambda v, out: np.copyto(out, v), b, 1e-15, 3, x, 5.0)
    assert iterations == -1


@pytest.mark.parametrize("inner", [RefactorSolver, SuperLUSolver])
def test_keeps_the_factorization_for_nearby_jacobians(inner, rng):
    matrix = _jacobian(300, rng)
    # A random change is of full rank: about 5 iterations per solve; never stale here.
    solver = ReusingSolver(inner(), refactor_iterations=12)
    solver.factor(matrix)
    assert (solver.n_factorizations, solver.n_refactorizations) == (1, 0)
    for _ in range(5):
        changed = _perturbed(matrix, 1e-3, rng)
        solver.factor(changed)
        b = rng.standard_normal(300)
        for transposed in (False, True):
            x = solver.solve(b, transposed=transposed)
            operator = changed.T if transposed else changed
            assert _backward_error(operator, x, b) <= 1e-15
            np.testing.assert_allclose(x, np.linalg.solve(operator.toarray(), b), rtol=0, atol=1e-12 * np.abs(x).max())
    assert (solver.n_factorizations, solver.n_refactorizations) == (1, 0)
    assert solver.n_krylov_iterations > 0
    many = solver.solve(np.stack([b, 2 * b], axis=1))
    np.testing.assert_allclose(many[:, 1], 2 * many[:, 0], rtol=1e-12, atol=1e-12)
    in_place = b.copy()
    solver.solve(in_place, out=in_place)
    np.testing.assert_allclose(in_place, solver.solve(b), rtol=0, atol=1e-14 * np.abs(in_place).max())
    held = solver.solve_held(b)
    assert np.linalg.norm(changed @ held - b) > 1e-12 * np.linalg.norm(b)  # an older matrix's solution


def test_refactors_at_the_next_factor_after_a_slow_solve(rng):
    matrix = _jacobian(300, rng)
    solver = ReusingSolver(RefactorSolver(), refactor_iterations=0)
    solver.factor(matrix)
    changed = _perturbed(matrix, 1e-3, rng)
    solver.factor(changed)
    assert solver.n_refactorizations == 0
    b = rng.standard_normal(300)
    solver.solve(b)  # at least one iteration: stale from now on
    solver.factor(changed)
    assert solver.n_refactorizations == 1
    x = solver.solve(b)  # the held factorization is of this very matrix: a direct solve
    assert _backward_error(changed, x, b) <= 1e-15


def test_refactors_at_once_when_gmres_cannot_converge(rng):
    matrix = _jacobian(300, rng)
    solver = ReusingSolver(RefactorSolver(), max_iterations=1)
    solver.factor(matrix)
    other = _perturbed(matrix, 1.0, rng)  # far from the factored one
    solver.factor(other)
    b = rng.standard_normal(300)
    x = solver.solve(b)
    assert solver.n_refactorizations == 1
    np.testing.assert_allclose(x, np.linalg.solve(other.toarray(), b), rtol=0, atol=1e-12 * np.abs(x).max())


def test_a_new_pattern_starts_afresh(rng):
    solver = ReusingSolver(RefactorSolver())
    solver.factor(_jacobian(100, rng))
    matrix = _jacobian(120, rng)
    solver.factor(matrix)
    b = rng.standard_normal(120)
    np.testing.assert_allclose(matrix @ solver.solve(b), b, rtol=0, atol=1e-12)
    assert solver.n_factorizations == 2


def test_bad_calls(rng):
    solver = ReusingSolver(RefactorSolver())
    with pytest.raises(RuntimeError, match="call `factor` first"):
        solver.solve(np.ones(3))
    solver.factor(_jacobian(10, rng))
    with pytest.raises(ValueError, match=r"`rhs` must have shape \(10,\)"):
        solver.solve(np.ones(3))
    with pytest.raises(ValueError, match="`tolerance`"):
        ReusingSolver(RefactorSolver(), tolerance=0.0)
    with pytest.raises(ValueError, match="`max_iterations`"):
        ReusingSolver(RefactorSolver(), max_iterations=0)


def test_takes_over_a_factorization_already_made(rng):
    """``factored=True``: the inner solver's factorization of the first Jacobian is kept."""
    matrix = _jacobian(200, rng)
    inner = RefactorSolver()
    inner.factor(matrix)
    solver = ReusingSolver(inner, factored=True)
    solver.factor(matrix)
    b = rng.standard_normal(200)
    assert _backward_error(matrix, solver.solve(b), b) <= 1e-15
    assert (solver.n_factorizations, solver.n_refactorizations) == (0, 0)


def test_counts_every_right_hand_side(rng):
    matrix = _jacobian(50, rng)
    solver = ReusingSolver(RefactorSolver())
    solver.factor(matrix)
    solver.solve(np.ones(50))  # direct: the held factorization is of this matrix
    solver.factor(_perturbed(matrix, 1e-3, rng))
    solver.solve(np.ones((50, 2)))  # by GMRES
    solver.solve_held(np.ones(50))
    assert solver.n_solves == 4


@pytest.mark.filterwarnings("ignore::sparsekin.RedundantConstraintWarning")
@pytest.mark.parametrize("build", [lambda t: t.lattice(3, 4), lambda t: t.rotating_squares(4)], ids=["lattice", "squares"])
def test_superlu_in_metis_order_reused_along_a_motion(build):
    """The benchmarks' ``superlu-metis`` path (issue 29): SuperLU in METIS's order of the
    bodies, held by `ReusingSolver` across samples, follows the motion SuperLU solves at
    every Newton iteration (the rotating squares through their reduced system)."""
    pytest.importorskip("pymetis")
    from sparsekin import solve_kinematics, testset
    from sparsekin.solve.stepper import KinematicStepper

    mechanism = build(testset)
    times = np.linspace(0.0, 1.0, 21)
    reference = solve_kinematics(mechanism, times, linear_solver="superlu")
    solver = ReusingSolver(SuperLUSolver(ordering="metis"))
    stepper = KinematicStepper(mechanism, linear_solver=solver)
    stepper.start(times[0])
    coordinates = [stepper.coordinates.copy()]
    for t in times[1:]:
        stepper.advance(t)
        coordinates.append(stepper.coordinates.copy())
    np.testing.assert_allclose(np.array(coordinates), reference.coordinates, rtol=0, atol=1e-10)
    assert solver.n_factorizations < len(times) // 2  # held across samples


@pytest.mark.parametrize("shape", [(1, 1), (7, 7), (40, 25)])
def test_the_norm_that_scales_the_tolerance(shape, rng):
    """`ReusingSolver`'s scale is max(||J||_1, ||J||_inf), here in one pass (the kernel)
    against numpy's dense column and row sums."""
    from sparsekin.engine import _krylov_kernels

    matrix = random_array(shape, density=0.3, rng=rng, format="csr") - random_array(shape, density=0.3, rng=rng,
                                                                                       format="csr")  # fmt: skip
    matrix = csr_array(matrix)
    dense = np.abs(matrix.toarray())
    expected = max(dense.sum(axis=0).max(), dense.sum(axis=1).max())
    work = np.full(shape[1], 7.0)  # not zero: the kernel clears it
    found = _krylov_kernels.largest_line_sum(matrix.indptr, matrix.indices, matrix.data, work)
    assert found == pytest.approx(expected, rel=1e-15, abs=0.0)
