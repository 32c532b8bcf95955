"""The supernodal (multifrontal) LU of meshes (issue 29): `SupernodalSolver` and its kernels.

Checked: the elimination tree against its definition (the first entry below the diagonal
of the Cholesky factor's pattern, by dense symbolic elimination); the postorder and the
supernodes' index sets against the dense symbolic factor (every entry of L and U inside
the fronts); solves on the lattice's Jacobian at the drawing (a third of its entries
exactly zero) and at a perturbed configuration against scipy's `splu` and a dense solve,
both systems, one and three right-hand sides; a refactorization on the held analysis; a
matching gone bad (new analysis) and the fallback to SuperLU (counted).  Every solver
test of tests/test_linear_solvers.py runs it too (singular and non-finite Jacobians,
`out`, validation).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import csr_array, random_array
from scipy.sparse.linalg import splu
from test_column_order import _lattice_jacobian

from sparsekin.engine import _supernodal_kernels, supernodal
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.discretization import Discretization
from sparsekin.engine.pattern import build_pattern
from sparsekin.engine.supernodal import SupernodalSolver
from sparsekin.testset import lattice

#: Normwise backward error accepted of a solve (as tests/test_linear_solvers.py's).
BACKWARD_ERROR = 1e-14


def _symmetric_pattern(n: int, rng, density: float) -> csr_array:
    matrix = random_array((n, n), density=density, rng=rng, format="csr")
    matrix = abs(matrix) + abs(matrix.T) + csr_array(np.eye(n))
    matrix.sort_indices()
    return matrix


def _dense_symbolic_cholesky(pattern: np.ndarray) -> np.ndarray:
    """The pattern of L of a symmetric pattern, by eliminating in turn (dense, small n)."""
    filled = pattern.copy()
    n = filled.shape[0]
    for j in range(n):
        below = np.flatnonzero(filled[j + 1 :, j]) + j + 1
        filled[np.ix_(below, below)] = True
    return np.tril(filled)


@pytest.mark.parametrize("n, density", [(1, 1.0), (12, 0.1), (60, 0.04), (80, 0.02)])
def test_elimination_tree_is_the_first_entry_below_the_diagonal(n, density, rng):
    matrix = _symmetric_pattern(n, rng, density)
    parent = _supernodal_kernels.elimination_tree(matrix.indptr, matrix.indices)
    lower = _dense_symbolic_cholesky(matrix.toarray() != 0)
    for j in range(n):
        below = np.flatnonzero(lower[j + 1 :, j])
        assert parent[j] == (below[0] + j + 1 if below.size else -1)
    post = _supernodal_kernels.postorder(parent)
    assert sorted(post.tolist()) == list(range(n))
    place = np.empty(n, dtype=np.int64)
    place[post] = np.arange(n)
    assert all(parent[j] == -1 or place[parent[j]] > place[j] for j in range(n))  # children first


@pytest.mark.parametrize("n, density", [(12, 0.1), (60, 0.04), (80, 0.02)])
def test_fronts_hold_the_whole_factor(n, density, rng):
    """Every entry of the symbolic factor of the postordered pattern lies in its supernode's
    front, whether or not supernodes were joined; the children come right before."""
    matrix = _symmetric_pattern(n, rng, density)
    parent = _supernodal_kernels.elimination_tree(matrix.indptr, matrix.indices)
    post = _supernodal_kernels.postorder(parent)
    inv_post = np.empty(n, dtype=np.int64)
    inv_post[post] = np.arange(n)
    relabelled = np.where(parent[post] >= 0, inv_post[np.maximum(parent[post], 0)], -1)
    lower = _dense_symbolic_cholesky(matrix.toarray()[np.ix_(post, post)] != 0)
    first = _supernodal_kernels.supernode_starts(relabelled)
    for joined in (False, True):
        struct_ptr, struct_idx, super_parent = _supernodal_kernels.supernodal_structure(
            matrix.indptr, matrix.indices, post, inv_post, first
        )
        for s in range(first.size - 1):
            reach = struct_idx[struct_ptr[s] : struct_ptr[s + 1]].tolist()
            front = set(range(first[s], first[s + 1])) | set(reach)
            for j in range(first[s], first[s + 1]):
                assert set(np.flatnonzero(lower[:, j]).tolist()) <= front
        _, peak, _, _ = _supernodal_kernels.stack_offsets(struct_ptr, super_parent)
        assert peak >= 0
        if not joined:
            first = _supernodal_kernels.amalgamated_starts(first, struct_ptr, super_parent, 4, 0.5)


def _lattice_at(rows: int, cols: int, perturbation: float, rng):
    mechanism = lattice(rows, cols)
    pattern = build_pattern(mechanism)
    assembler = Assembler(Discretization(mechanism, pattern))
    assembler.set_time(0.0)
    q = pattern.initial_coordinates + perturbation * rng.standard_normal(pattern.n_coordinates)
    assembler.fill_residual_jacobian(q)
    return assembler.jacobian.copy(), pattern.initial_coordinates.reshape(-1, 3)[:, :2].copy()


def _backward_error(matrix, x, b) -> float:
    norm = abs(matrix).sum(axis=1).max()
    return float(np.abs(matrix @ x - b).max() / (norm * np.abs(x).max() + np.abs(b).max()))


@pytest.mark.parametrize("perturbation", [0.0, 0.05])
def test_lattice_solves_against_splu_and_dense(perturbation, rng):
    """At the drawing (a third of the entries exactly zero) and at a generic configuration."""
    jacobian, points = _lattice_at(9, 11, perturbation, rng)
    solver = SupernodalSolver(points)
    solver.factor(jacobian)
    assert solver.n_fallbacks == 0 and solver.pivot_ratio >= supernodal.PIVOT_THRESHOLD
    n = jacobian.shape[0]
    b = rng.standard_normal((n, 3))
    for matrix, transposed in ((jacobian, False), (jacobian.T.tocsr(), True)):
        reference = splu(matrix.tocsc()).solve(b)
        scale = np.abs(reference).max()
        dense = np.linalg.solve(matrix.toarray(), b)
        np.testing.assert_allclose(dense, reference, rtol=0, atol=1e-10 * scale)
        together = solver.solve(b, transposed=transposed)
        for c in range(3):
            alone = solver.solve(b[:, c], transposed=transposed)
            assert _backward_error(matrix, alone, b[:, c]) <= BACKWARD_ERROR
            np.testing.assert_allclose(alone, reference[:, c], rtol=0, atol=1e-10 * scale)
            np.testing.assert_allclose(together[:, c], alone, rtol=0, atol=1e-13 * np.abs(alone).max())


def test_refactorization_on_the_held_analysis(rng):
    drawn, points = _lattice_at(8, 8, 0.0, rng)
    solver = SupernodalSolver(points)
    solver.factor(drawn)
    moved, _ = _lattice_at(8, 8, 0.05, rng)
    assert np.array_equal(moved.indices, drawn.indices)
    solver.factor(moved)
    assert (solver.n_factorizations, solver.n_refactorizations, solver.n_fallbacks) == (1, 1, 0)
    b = rng.standard_normal(moved.shape[0])
    assert _backward_error(moved, solver.solve(b), b) <= BACKWARD_ERROR


def test_a_matching_gone_bad_is_made_again(rng):
    """Values whose large entry moved off the matched diagonal: the held analysis misses
    its threshold, a new one (a new matching) factors them.  An arrow matrix: each column
    but the last its own supernode, its front its own row and the last."""
    n = 6
    arrow = np.eye(n) * 4.0
    arrow[-1, :] = arrow[:, -1] = 1.0
    arrow[-1, -1] = 4.0
    first = csr_array(arrow)
    arrow[0, 0] = 1e-9  # column 0's large entry now in the last row
    swapped = csr_array(arrow)
    solver = SupernodalSolver(np.column_stack([np.arange(2.0), np.zeros(2)]))
    solver.factor(first)
    solver.factor(swapped)
    assert (solver.n_factorizations, solver.n_refactorizations, solver.n_fallbacks) == (2, 1, 0)
    b = rng.standard_normal(n)
    assert _backward_error(swapped, solver.solve(b), b) <= BACKWARD_ERROR


def test_fallback_to_superlu_when_pivots_miss_the_threshold(rng, monkeypatch):
    """A threshold no pivot meets: SuperLU factors it, counted, its solves are right."""
    jacobian = _lattice_jacobian(5, 6, rng)
    points = build_pattern(lattice(5, 6)).initial_coordinates.reshape(-1, 3)[:, :2]
    monkeypatch.setattr(supernodal, "PIVOT_THRESHOLD", 1e300)
    solver = SupernodalSolver(points)
    solver.factor(jacobian)
    assert solver.n_fallbacks == 1
    b = rng.standard_normal((jacobian.shape[0], 2))
    for matrix, transposed in ((jacobian, False), (jacobian.T.tocsr(), True)):
        x = solver.solve(b, transposed=transposed)
        assert max(_backward_error(matrix, x[:, c], b[:, c]) for c in range(2)) <= BACKWARD_ERROR
    monkeypatch.undo()
    solver.factor(jacobian)  # the supernodal factors again
    assert solver.n_fallbacks == 1 and solver.nnz_factors > 0


def test_random_unsymmetric_matrices(rng):
    """Matrices with no mesh behind them (places in a row): against a dense solve."""
    for n in (3, 30, 90):
        matrix = random_array((n, n), density=min(1.0, 4.0 / n), rng=rng, format="csr")
        matrix = matrix + csr_array(np.diag(rng.uniform(1, 2, n)))
        matrix = csr_array(matrix[rng.permutation(n)])  # the large entries off the diagonal
        solver = SupernodalSolver(np.column_stack([np.arange(n // 3, dtype=float), np.zeros(n // 3)]))
        solver.factor(matrix)
        b = rng.standard_normal(n)
        assert _backward_error(matrix, solver.solve(b), b) <= BACKWARD_ERROR
        assert _backward_error(matrix.T.tocsr(), solver.solve(b, transposed=True), b) <= BACKWARD_ERROR
