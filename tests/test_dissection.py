"""Meshes' LU (issue 29): the geometric nested dissection of the bodies
(`sparsekin.engine.ordering.geometric_column_order`), `DissectionSolver`, and ``"auto"``'s
plan for meshes.

Checked: the order is a permutation keeping each body's coordinates together whose last
block is a separator (a whole grid line on a grid graph); on the lattice its fill is far
below the drawing's order and near METIS's and COLAMD's (measured ratios in the test);
the solver computes it once per pattern; ``"auto"`` takes the solver on square grid
models only (chains and overconstrained grids keep their path) and the motion it gives
is ``linear_solver="superlu"``'s.  The solver's solves against `spsolve`, singular and
non-finite input: tests/test_linear_solvers.py, with every solver.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from helpers import solve_with
from scipy.sparse import csr_array
from test_column_order import _fill, _lattice_jacobian
from test_linear_solver_paths import assert_same_run

from sparsekin import solve_kinematics, testset
from sparsekin.engine import _ordering_kernels
from sparsekin.engine.discretization import discretize
from sparsekin.engine.dissection import DissectionSolver
from sparsekin.engine.ordering import fill_reducing_column_order, geometric_column_order, metis_installed
from sparsekin.engine.pattern import build_pattern
from sparsekin.solve.policy import Thresholds, plan_linear_solver

#: ``"auto"``'s thresholds with the mesh solver from any size.
MESH_FROM_ANY_SIZE = Thresholds(min_dissection_coordinates=0)


def _drawn_places(mechanism) -> np.ndarray:
    return build_pattern(mechanism).initial_coordinates.reshape(-1, 3)[:, :2]


def _grid_graph(k: int):
    """A k x k grid graph (4 neighbours) in CSR form, and its vertices' places."""
    index = np.arange(k * k).reshape(k, k)
    pairs = np.concatenate([np.column_stack([index[:, :-1].ravel(), index[:, 1:].ravel()]),
                            np.column_stack([index[:-1, :].ravel(), index[1:, :].ravel()])])  # fmt: skip
    pairs = np.concatenate([pairs, pairs[:, ::-1]])
    graph = csr_array((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(k * k, k * k))
    places = np.column_stack([(index % k).ravel(), (index // k).ravel()]).astype(float)
    return graph.indptr.astype(np.int64), graph.indices.astype(np.int64), places


@pytest.mark.parametrize("k", [2, 9, 16])
def test_a_grid_is_cut_along_a_grid_line(k):
    """On a k x k grid the last k vertices are one whole grid line (the first separator),
    and every vertex comes once."""
    xadj, adjacency, places = _grid_graph(k)
    order = _ordering_kernels.geometric_dissection(xadj, adjacency, places, 1)
    assert sorted(order.tolist()) == list(range(k * k))
    last = places[order[-k:]]
    assert np.unique(last[:, 0]).size == 1 or np.unique(last[:, 1]).size == 1


def test_points_on_one_place_and_no_edges():
    """Degenerate parts: every body drawn at one place, or a graph without edges."""
    xadj, adjacency, _ = _grid_graph(6)
    order = _ordering_kernels.geometric_dissection(xadj, adjacency, np.zeros((36, 2)), 1)
    assert sorted(order.tolist()) == list(range(36))
    alone = _ordering_kernels.geometric_dissection(np.zeros(37, dtype=np.int64), np.zeros(0, dtype=np.int64),
                                                   np.random.default_rng(1).random((36, 2)), 2)  # fmt: skip
    assert sorted(alone.tolist()) == list(range(36))


def test_lattice_fill_near_metis_and_colamd(rng):
    """30 x 30 lattice at a perturbed drawing (measured over three seeds: 0.52–0.57 of the
    drawing's order's fill, 1.15–1.23 of COLAMD's, 1.05–1.06 of METIS's in the bodies'
    order; at 10^5 bodies it is below COLAMD's, docs/design-notes.md)."""
    mechanism = testset.lattice(30, 30)
    jacobian = _lattice_jacobian(30, 30, rng)
    order = geometric_column_order(jacobian, _drawn_places(mechanism))
    bodies = order.reshape(-1, 3)
    assert np.all(bodies == bodies[:, :1] + np.arange(3)) and np.all(bodies[:, 0] % 3 == 0)
    fill = _fill(jacobian, order)
    assert fill < 0.65 * _fill(jacobian, np.arange(jacobian.shape[1]))
    assert fill < 1.3 * _fill(jacobian)
    if metis_installed():
        assert fill < 1.15 * _fill(jacobian, fill_reducing_column_order(jacobian, method="metis", block=3))


def test_bad_places_are_refused():
    with pytest.raises(ValueError, match=r"`points` must be 2 finite places \(x, y\), one a body, got shape \(3, 2\)"):
        geometric_column_order(csr_array(np.eye(6)), np.zeros((3, 2)))
    with pytest.raises(ValueError, match="`points` must be 2 finite places"):
        geometric_column_order(csr_array(np.eye(6)), [[0.0, np.nan], [1.0, 0.0]])
    with pytest.raises(ValueError, match="`block` must be a whole number >= 1 dividing the 6 columns"):
        geometric_column_order(csr_array(np.eye(6)), np.zeros((2, 2)), block=4)
    with pytest.raises(ValueError, match=r"`points` must have shape \(n_bodies, 2\), got \(4,\)"):
        DissectionSolver(np.zeros(4))
    with pytest.raises(ValueError, match="`jacobian` has 6 columns, expected 3 for each of the 3 bodies"):
        DissectionSolver(np.zeros((3, 2))).factor(csr_array(np.eye(6)))


def test_the_order_is_computed_once_a_pattern(rng, monkeypatch):
    """Along a motion the pattern is the same: one order; a new pattern gets its own.  The
    solves agree with SuperLU's on the Jacobian itself, both systems, two right-hand sides."""
    from scipy.sparse.linalg import splu

    from sparsekin.engine import ordering

    orders = []
    original = ordering.geometric_column_order
    monkeypatch.setattr(ordering, "geometric_column_order", lambda *a, **k: orders.append(1) or original(*a, **k))
    jacobian = _lattice_jacobian(12, 12, rng)
    solver = DissectionSolver(_drawn_places(testset.lattice(12, 12)))
    for _ in range(3):
        jacobian.data *= 1.0 + 0.01 * rng.standard_normal(jacobian.nnz)
        solver.factor(jacobian)
        rhs = rng.standard_normal((jacobian.shape[0], 2))
        for transposed, operator in ((False, jacobian), (True, jacobian.T)):
            expected = splu(operator.tocsc()).solve(rhs)
            np.testing.assert_allclose(solver.solve(rhs, transposed=transposed), expected, rtol=0,
                                       atol=1e-10 * np.abs(expected).max())  # fmt: skip
    assert len(orders) == 1 and (solver.n_factorizations, solver.n_solves) == (3, 12)
    assert solver.nnz_factors < 1.3 * splu(jacobian.T.tocsc()).nnz
    solver.factor(jacobian[:, :].tocsr())  # the same pattern in new arrays: no new order
    assert len(orders) == 1
    smaller = _lattice_jacobian(12, 11, rng)
    DissectionSolver(_drawn_places(testset.lattice(12, 11))).factor(smaller)
    assert len(orders) == 2


@pytest.mark.parametrize(
    ("build", "expected"),
    [
        (lambda: testset.lattice(6, 8), "dissection"),
        (lambda: testset.rotating_squares(5), "dense"),  # a grid, overconstrained: the reduced system's path
        (lambda: testset.four_bar_chain(60), "refactor"),  # chains keep theirs
        (lambda: testset.task5_chain(12), "refactor"),
    ],
)
def test_auto_takes_the_mesh_solver_for_square_grids_only(build, expected):
    model = discretize(build())
    plan = plan_linear_solver(model, "auto", MESH_FROM_ANY_SIZE)
    assert plan.solver == expected
    if expected == "dissection":
        solver = plan.make_solver()
        assert isinstance(solver, DissectionSolver) and solver.points.shape == (model.mechanism.n_bodies, 2)
        assert plan.chord and plan.reuses(solver, model.constraints.nnz)
    assert plan_linear_solver(model, "auto").solver != "dissection"  # below the threshold
    assert plan_linear_solver(model, "superlu", MESH_FROM_ANY_SIZE).solver == "superlu"  # as asked


def test_a_mesh_runs_as_superlu_does():
    """The lattice under ``"auto"`` with the mesh solver: reused across samples from the
    first on, few factorizations, the motion (velocities and accelerations too) of
    ``linear_solver="superlu"``; with masses and gravity, its forces (transposed systems)
    at every sample."""
    mechanism, times = testset.lattice(6, 8), np.linspace(0.0, 1.0, 51)
    result = solve_with(mechanism, times, thresholds=MESH_FROM_ANY_SIZE)
    assert result.linear_solver == "reuse"
    assert result.n_factorizations < result.n_times // 5
    assert_same_run(result, solve_kinematics(mechanism, times, linear_solver="superlu"), 8.0)
    repeat = mechanism.repeats[0]  # every bar of the cell with a mass: still a grid repeat
    cell = replace(repeat.unit, bodies=tuple(replace(body, mass=2.0, inertia=0.2) for body in repeat.unit.bodies))
    heavy = replace(mechanism, repeats=[replace(repeat, unit=cell)], gravity=(0.0, -9.81))
    times = times[:11]
    result = solve_with(heavy, times, forces="all", thresholds=MESH_FROM_ANY_SIZE)
    reference = solve_kinematics(heavy, times, forces="all", linear_solver="superlu")
    assert result.linear_solver == "reuse" and result.force_labels == reference.force_labels
    assert len(result.force_labels) > 100 and np.abs(reference.force_tracks).max() > 1.0
    scale = np.abs(reference.force_tracks).max()
    np.testing.assert_allclose(result.force_tracks, reference.force_tracks, rtol=0, atol=1e-9 * scale)


def test_the_ordered_columns_are_scipys(rng):
    """`_lu_kernels.ordered_columns` (the gather the solver refills through) against
    scipy's ``matrix.tocsc()[:, order]``, rows sorted."""
    from scipy.sparse import random_array

    from sparsekin.engine import _lu_kernels

    matrix = csr_array(random_array((30, 24), density=0.15, rng=rng, format="csr"))
    order = rng.permutation(24)
    indptr, indices, gather = _lu_kernels.ordered_columns(matrix.indptr, matrix.indices, order)
    expected = matrix.tocsc()[:, order]
    expected.sort_indices()
    assert np.array_equal(indptr, expected.indptr) and np.array_equal(indices, expected.indices)
    np.testing.assert_array_equal(matrix.data[gather], expected.data)


def test_the_row_stored_solves_are_the_factors_solves(rng):
    """`_lu_kernels.rows_last_first` (U's nonzeros by rows, the last row first, its exact
    zeros left out) and back (`columns_from_rows_last_first`), `solve_lu_rows` and
    `solve_lu_transposed` on them with ``Pr A Pc = L U`` against dense products with A, for
    random triangular factors and permutations."""
    from scipy.sparse import csc_array

    from sparsekin.engine import _lu_kernels

    n = 40
    lower = np.tril(rng.standard_normal((n, n)) * (rng.random((n, n)) < 0.2), -1)
    upper = np.triu(rng.standard_normal((n, n)) * (rng.random((n, n)) < 0.2), 1)
    diagonal = rng.uniform(1.0, 2.0, n) * rng.choice([-1.0, 1.0], n)
    perm_r, perm_c = rng.permutation(n), rng.permutation(n)
    product = (np.eye(n) + lower) @ (upper + np.diag(diagonal))  # B = Pr A Pc
    matrix = product[perm_r][:, perm_c]  # row i of A is row perm_r[i] of B, column c is column perm_c[c]
    # U by columns on a pattern with explicit zeros (a refactorization's structural zeros)
    pattern = (upper != 0.0) | ((rng.random((n, n)) < 0.1) & (np.triu(np.ones((n, n)), 1) > 0))
    u_columns = csc_array((upper[pattern], np.nonzero(pattern)), shape=(n, n))
    assert np.any(u_columns.data == 0.0)
    out_indptr = np.empty(n + 1, dtype=np.int64)
    out_indices, out_values = np.empty_like(u_columns.indices), np.empty(u_columns.nnz)
    _lu_kernels.rows_last_first(u_columns.indptr, u_columns.indices, u_columns.data, out_indptr, out_indices,
                                out_values)  # fmt: skip
    end = out_indptr[-1]
    assert end == np.count_nonzero(upper)
    rebuilt = np.zeros((n, n))
    for k in range(n):
        for p in range(out_indptr[k], out_indptr[k + 1]):
            rebuilt[n - 1 - k, out_indices[p]] = out_values[p]
    np.testing.assert_array_equal(rebuilt, upper)
    for k in range(n):  # each stored row by increasing column
        assert np.all(np.diff(out_indices[out_indptr[k]:out_indptr[k + 1]]) > 0)
    u_back = (np.empty(n + 1, dtype=np.int64), np.empty(end, dtype=out_indices.dtype), np.empty(end))
    _lu_kernels.columns_from_rows_last_first(out_indptr, out_indices[:end], out_values[:end], *u_back)
    nonzero = csc_array(upper)
    assert np.array_equal(u_back[0], nonzero.indptr) and np.array_equal(u_back[1], nonzero.indices)
    np.testing.assert_array_equal(u_back[2], nonzero.data)
    l_columns = csc_array(lower)
    lower_factor = (l_columns.indptr.astype(np.int64), l_columns.indices, l_columns.data)
    by_rows = (np.argsort(perm_r), np.argsort(perm_c), lower_factor,
               (out_indptr, out_indices[:end], out_values[:end], 1.0 / diagonal))  # fmt: skip
    by_columns = (perm_r, perm_c, lower_factor, u_back + (1.0 / diagonal,))
    rhs, work, out, probe = rng.standard_normal(n), np.empty(n), np.empty(n), np.ones(1)
    for kernel, factors, operator in ((_lu_kernels.solve_lu_rows, by_rows, matrix),
                                      (_lu_kernels.solve_lu_transposed, by_columns, matrix.T)):  # fmt: skip
        kernel(factors, rhs, work, out, probe)
        assert probe[0] == 0.0
        np.testing.assert_allclose(operator @ out, rhs, rtol=0, atol=1e-10 * np.abs(rhs).max())
