"""Forward dynamics of grid models (issue 29's dynamics item): their saddle matrix factored
afresh (SuperLU, ``"auto"`` above `MIN_MESH_SADDLE_SIZE`) or by `DissectionSolver`, the
bodies' unknowns (coordinates and the multipliers of the equations placed with them) in a
geometric nested dissection.

Checked: the saddle's order is a permutation keeping each body's unknowns together,
coordinates first; bad groups are refused in one line; ``"auto"`` plans the fresh
factorization for grid models above the threshold only (chains keep the refactorization);
a run with either gives the refactorization's motion to rounding, on the struck lattice (six redundant equations
left out) and on a driven lattice with masses and gravity; and the physics, independently:
the struck lattice against its one-variable equation of motion (tests/test_dynamic_gallery.py),
the driven lattice (no degree of freedom) against the kinematics of the same lattice and
its driver torques against inverse dynamics.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from scipy.sparse import csr_array
from test_dynamic_gallery import LATTICE, TIMES, largest_error

import sparsekin as sk
from sparsekin import testset
from sparsekin.engine.discretization import discretize
from sparsekin.engine.dissection import DissectionSolver
from sparsekin.engine.ordering import geometric_column_order
from sparsekin.solve.dynamics import GeneralizedAlphaStepper, run_dynamics
from sparsekin.solve.options import DynamicsOptions, SolveOptions
from sparsekin.solve.policy import Thresholds, plan_saddle_solver

#: The Python stepper on the refactorization at any size, as ``"auto"`` above the dense size.
REFACTOR = Thresholds(saddle_dense_max_size=0, compiled_saddle_max_size=0)
#: The same with a grid model's saddle afresh by SuperLU (``"auto"`` above `MIN_MESH_SADDLE_SIZE`) or
#: by `DissectionSolver`, from any size.
SUPERLU = dataclasses.replace(REFACTOR, min_mesh_saddle_size=0)
DISSECTION = dataclasses.replace(SUPERLU, mesh_saddle_solver="dissection")


def _run(mechanism, times, max_step: float, thresholds: Thresholds, rho_inf: float = 1.0):
    dynamics = DynamicsOptions(max_step, rho_inf).for_run(times, mechanism)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sk.RedundantConstraintWarning)
        return run_dynamics(discretize(mechanism), np.asarray(times, dtype=float), SolveOptions(thresholds=thresholds),
                            dynamics)  # fmt: skip


def massive_lattice(rows: int, cols: int):
    """The test set's lattice (its rows driven) with bars of 1 kg and 1/12 kg·m² under gravity."""
    return testset.with_masses(testset.lattice(rows, cols), 1.0, 1.0 / 12.0)


# ---------------------------------------------------------------------- the order
def test_a_saddles_unknowns_stay_with_their_bodies():
    """Each body's unknowns come together, its coordinates before its multipliers, and every
    unknown once; a multiplier goes with the first body of its equation's row."""
    mechanism = massive_lattice(3, 4)
    stepper = GeneralizedAlphaStepper(mechanism, 1e-3)
    stepper.start(0.0)
    matrix = stepper.system.matrix
    n = stepper.system.n
    solver = DissectionSolver(stepper.pattern.initial_coordinates.reshape(-1, 3)[:, :2])
    solver.factor(matrix)
    order = solver._order
    assert sorted(order.tolist()) == list(range(matrix.shape[0]))
    body = np.where(order < n, order // 3, -1)
    rows = order >= n
    first = matrix.indices[matrix.indptr[order[rows]]]
    body[rows] = first // 3
    changes = np.flatnonzero(np.diff(body)) + 1
    runs = np.split(body, changes)
    assert len(runs) == mechanism.n_bodies  # one run of unknowns a body
    for run, start in zip(runs, np.concatenate([[0], changes])):
        kinds = order[start : start + run.size] >= n
        assert np.all(np.diff(kinds.astype(int)) >= 0)  # coordinates, then multipliers
    rhs = np.random.default_rng(3).standard_normal(matrix.shape[0])
    np.testing.assert_allclose(matrix @ solver.solve(rhs), rhs, rtol=0, atol=1e-11)


def test_bad_groups_and_saddles_are_refused():
    matrix = csr_array(np.eye(4) + np.eye(4, k=1) + np.eye(4, k=-1))
    places = [[0.0, 0.0], [1.0, 0.0]]
    for groups in ([0, 0, 1], [0, 0, 0, 0], [0, 0, 1, 2], [0, 0, 1, -1], [0.0, 0.0, 1.0, 1.0]):
        with pytest.raises(ValueError, match="`groups` must give each unknown"):
            geometric_column_order(matrix, places, groups=groups)
    with pytest.raises(ValueError, match="`groups` must give each unknown"):
        geometric_column_order(csr_array(np.ones((5, 4))), places, groups=[0, 0, 1, 1])
    # a multiplier row without a coordinate of a body
    saddle = csr_array(np.eye(7) + np.eye(7, k=1) + np.eye(7, k=-1))
    saddle = csr_array(saddle.toarray() * (np.arange(7)[:, None] < 6))
    with pytest.raises(ValueError, match="multiplier rows must each hold"):
        DissectionSolver([[0.0, 0.0], [1.0, 0.0]]).factor(saddle)


# ---------------------------------------------------------------------- the plan
@pytest.mark.parametrize(
    ("build", "expected"),
    [(lambda: massive_lattice(6, 8), "superlu"), (lambda: testset.n_four_bar(100), "refactor")],
)
def test_auto_factors_grid_saddles_afresh_only(build, expected):
    discretization = discretize(build())
    size = 2 * discretization.constraints.n_coordinates
    thresholds = Thresholds(min_mesh_saddle_size=100)
    plan = plan_saddle_solver(size, "auto", thresholds, discretization=discretization)
    assert plan.solver == expected and plan.loop == "python"
    assert plan_saddle_solver(size, "auto", discretization=discretization).solver == "refactor"  # below 18 000
    assert plan_saddle_solver(size, "refactor", thresholds, discretization=discretization).solver == "refactor"
    assert plan_saddle_solver(size, "auto", thresholds).solver == "refactor"  # no model: not known as a grid
    asked = dataclasses.replace(thresholds, mesh_saddle_solver="dissection")
    plan = plan_saddle_solver(size, "auto", asked, discretization=discretization)
    assert plan.solver == ("dissection" if expected == "superlu" else "refactor")
    if plan.solver == "dissection":
        with pytest.raises(ValueError, match="`Thresholds.mesh_saddle_solver` must be"):
            plan_saddle_solver(size, "auto", dataclasses.replace(thresholds, mesh_saddle_solver="dense"),
                               discretization=discretization)  # fmt: skip
        solver = plan.make_solver()
        assert isinstance(solver, DissectionSolver) and not solver.take_out_factors
        assert plan.points.shape == (discretization.mechanism.n_bodies, 2)


# ---------------------------------------------------------------------- runs
@pytest.fixture(scope="module")
def struck_lattice():
    return sk.load_model(LATTICE)


@pytest.mark.parametrize("thresholds", [SUPERLU, DISSECTION], ids=["superlu", "dissection"])
def test_the_struck_lattice_factored_afresh_moves_as_its_one_degree_of_freedom(struck_lattice, thresholds):
    """The struck metamaterial (six redundant equations left out) with its saddle factored
    afresh (SuperLU; the dissection): the refactorization's motion to rounding, and both on
    the exact one-angle motion within the integrator's error (7.0e-6 at 5 ms; a spring 1 %
    stiffer is 9.6e-3 away)."""
    refactored = _run(struck_lattice, TIMES, 5e-3, REFACTOR)
    afresh = _run(struck_lattice, TIMES, 5e-3, thresholds)
    assert afresh.stats.linear_solver == thresholds.mesh_saddle_solver
    assert refactored.stats.linear_solver == "refactor"
    assert len(afresh.stats.redundant_equations) == 6
    np.testing.assert_allclose(afresh.coordinates, refactored.coordinates, rtol=0, atol=1e-10)
    assert largest_error(struck_lattice, afresh) < 1e-5
    np.testing.assert_allclose(afresh.energy.balance, refactored.energy.balance, rtol=0,
                               atol=1e-10 * afresh.energy.kinetic[0])  # fmt: skip


def test_a_driven_lattice_with_masses_moves_as_its_kinematics_with_its_forces():
    """A lattice with no degree of freedom (its rows driven), masses and gravity: the dynamics
    on the dissection and on SuperLU is the refactorization's to rounding, its motion the kinematics' (to
    the Newton tolerance) and its driver torques those of inverse dynamics (to generalized-α's
    error in the accelerations)."""
    mechanism = massive_lattice(4, 5)
    times = np.linspace(0.0, 0.2, 11)
    refactored = _run(mechanism, times, 2e-3, REFACTOR, rho_inf=0.9)
    dissected = _run(mechanism, times, 2e-3, DISSECTION, rho_inf=0.9)
    assert dissected.stats.linear_solver == "dissection"
    np.testing.assert_allclose(_run(mechanism, times, 2e-3, SUPERLU, rho_inf=0.9).coordinates, refactored.coordinates,
                               rtol=0, atol=1e-10)  # fmt: skip
    np.testing.assert_allclose(dissected.coordinates, refactored.coordinates, rtol=0, atol=1e-10)
    np.testing.assert_allclose(dissected.velocities, refactored.velocities, rtol=0, atol=1e-8)
    kinematics = sk.solve_kinematics(mechanism, times)
    np.testing.assert_allclose(dissected.coordinates, kinematics.coordinates, rtol=0, atol=1e-9)
    assert mechanism.n_drivers == 4
    for k in range(mechanism.n_drivers):
        torque, expected = dissected.driver_force(k).force, kinematics.driver_force(k).force
        scale = np.abs(expected).max()
        assert scale > 0.5  # gravity and the rows' motion on 1 kg bars: 0.6 to 77 N·m
        # measured 7e-9 to 5e-8 of it (falling 8 times at h / 2); 1 % more mass is 1e-2 away
        np.testing.assert_allclose(torque, expected, rtol=0, atol=1e-6 * scale)
