"""The compiled dynamics loop on its banded LU (`sparsekin.solve._saddle_factorization`)
against the Python stepper.

A chain's saddle matrix in reverse Cuthill–McKee order is a narrow band; from
`Thresholds.min_banded_saddle_size` unknowns on the compiled loop factors it with the
banded LU of `sparsekin.engine._banded_kernels` instead of the dense one.  The step is the
same; only the LU and the order of its unknowns differ, so the bounds are those of
tests/test_compiled_dynamics.py (its module docstring): positions and velocities within a
small factor of the Newton tolerance, accelerations and forces that times β′/γ′.  The
thresholds are lowered here so that small N-four-bars take the banded path (A02 itself,
N = 40 and 485 unknowns, takes it at the default thresholds: benchmarks/RESULTS.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import sparsekin as sk
from sparsekin.engine.discretization import discretize
from sparsekin.engine.saddle import DynamicSystem
from sparsekin.solve._compiled_dynamics import _LU
from sparsekin.solve._saddle_factorization import compiled_factorization, saddle_band_order
from sparsekin.solve.dynamics import GeneralizedAlpha, run_dynamics
from sparsekin.solve.options import DynamicsOptions, Request, SolveOptions
from sparsekin.solve.policy import Thresholds, plan_compiled_factorization, plan_saddle_solver
from sparsekin.testset import n_four_bar, task5

from helpers import assert_same_through_a_crossing

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
TOLERANCE = 1e-10
PYTHON = Thresholds(compiled_saddle_max_size=0)
#: The banded LU from 20 unknowns on (the N-four-bar at N = 4 has 53, bandwidths 5 and 5).
BANDED = Thresholds(min_banded_saddle_size=20)


def banded(loop) -> bool:
    """Whether `loop` held a banded factorization (a banded order)."""
    return loop._state is not None and loop._state[_LU][1].size > 0


def run(mechanism, times, max_step, thresholds, **request):
    request = Request(energy=True, **({"forces": "all", "points": "all"} | request))
    return run_dynamics(discretize(mechanism), np.asarray(times, dtype=float),
                        SolveOptions(TOLERANCE, thresholds=thresholds), DynamicsOptions(max_step), request)  # fmt: skip


def assert_same_run(python, compiled, max_step, rounds=1.0):
    """tests/test_compiled_dynamics.py's bounds (`rounds`: the factor of a run through
    singular positions)."""
    assert python.complete and compiled.complete
    alpha_m, alpha_f, gamma, beta = GeneralizedAlpha().coefficients
    beta_over_gamma = (1.0 - alpha_m) / (max_step * gamma * (1.0 - alpha_f))  # β′/γ′
    for name in ("coordinates", "velocities", "accelerations", "energy_tracks", "force_tracks", "point_tracks"):
        if getattr(python, name) is None:
            continue
        expected, actual = np.asarray(getattr(python, name)), np.asarray(getattr(compiled, name))
        bound = 10.0 * rounds * TOLERANCE * max(1.0, float(np.max(np.abs(expected))))
        if name not in ("coordinates", "velocities"):
            bound *= beta_over_gamma
        np.testing.assert_allclose(actual, expected, rtol=0.0, atol=bound, err_msg=name)
    np.testing.assert_allclose(compiled.drift_tracks, python.drift_tracks, rtol=0.0, atol=TOLERANCE * 1e-2)
    assert compiled.n_steps == python.n_steps


def test_a02s_saddle_is_a_narrow_band_and_takes_the_banded_lu():
    saddle = DynamicSystem(discretize(n_four_bar(40))).saddle
    order, lower, upper = saddle_band_order(saddle.indptr, saddle.indices)
    assert saddle.size == 485 and (lower, upper) == (9, 9)
    assert plan_compiled_factorization(saddle.size, lower, upper) == "banded"
    assert plan_saddle_solver(saddle.size, "auto", compilable=True).loop == "compiled"
    factorization = compiled_factorization(saddle.indptr, saddle.indices)
    assert factorization[0].shape == (2 * 9 + 9 + 1, 485) and factorization[0].flags.f_contiguous
    assert compiled_factorization(saddle.indptr, saddle.indices, banded=False) is None  # "dense": too large
    assert plan_saddle_solver(saddle.size, "refactor", compilable=True).loop == "python"
    assert plan_saddle_solver(saddle.size, "auto", PYTHON, compilable=True).loop == "python"
    assert plan_compiled_factorization(saddle.size, 300, 300) is None  # not a band: the Python stepper
    assert plan_compiled_factorization(saddle.size, 9, 9, Thresholds(max_banded_work=485 * 17)) is None
    assert plan_compiled_factorization(41, 9, 9) == "dense"  # A03: small, and its band 0.44 of its size
    assert plan_compiled_factorization(101, 30, 30) == "dense"  # a band wider than half the size


def test_n_four_bar_through_a_singular_crossing_on_the_banded_lu(compiled_loops):
    # the first flat crossing of N = 4 comes at t = 0.72 s; the Python stepper on its dense LU.
    # The banded loop factors afresh at every step (the Python stepper holds its matrix), so
    # the two Newton iterations stop at other iterates: up to the crossing they agree to the
    # Newton tolerance; at the crossing the Python stepper halves a few steps where the fresh
    # matrix does not, and from there both are held to the exact answer (the reduced ODE):
    # the banded loop's B0 no further off it than the Python stepper's, within 5 %.
    times = np.linspace(0.0, 1.2, 25)
    python = run(n_four_bar(4), times, 1e-3, PYTHON, forces=None, points="all")
    compiled = run(n_four_bar(4), times, 1e-3, BANDED, forces=None, points="all")
    (loop,) = compiled_loops
    assert banded(loop) and not loop.fell_back and loop.n_compiled == times.size - 1
    assert python.linear_solver == "dense"
    assert compiled.n_subdivisions == 0
    assert_same_through_a_crossing(python, compiled, times, TOLERANCE)


def test_n_four_bar_on_the_banded_lu_is_the_dense_stepper(compiled_loops):
    # the Python stepper on its dense LU, whose rules the compiled loop runs at every size
    # (the refactorization path, which A02 took before, runs the large path's: its
    # projections stop at a tenth of Newton's held-matrix allowance, 1.2e-9 m/s apart from
    # these over 150 steps), forces and points recorded
    times = np.linspace(0.0, 0.15, 4)
    dense = Thresholds(saddle_dense_max_size=10**6, compiled_saddle_max_size=0)
    python = run(n_four_bar(8), times, 1e-3, dense)
    compiled = run(n_four_bar(8), times, 1e-3, Thresholds(saddle_dense_max_size=50, min_banded_saddle_size=50))
    (loop,) = compiled_loops
    assert banded(loop) and not loop.fell_back
    assert (python.linear_solver, compiled.linear_solver) == ("dense", "refactor")  # (the start's)
    assert_same_run(python, compiled, 1e-3)


def test_a_sample_the_banded_loop_cannot_solve_is_handed_back(compiled_loops):
    # as tests/test_compiled_dynamics.py's hand-back, the banded LU forced on Task 5
    forced = Thresholds(min_banded_saddle_size=1, max_band_fraction=1.0)
    for thresholds in (PYTHON, forced):
        with pytest.raises(sk.ConvergenceError, match=r"the step from t = 0\.755\d* s failed after 12 halvings") as failure:
            run_dynamics(discretize(task5(amplitude=0.06)), np.linspace(0.0, 1.0, 101),
                         SolveOptions(TOLERANCE, thresholds=thresholds), DynamicsOptions(1e-3), Request(energy=True))  # fmt: skip
        if thresholds is PYTHON:
            python = failure.value.result
    compiled = failure.value.result
    (loop,) = compiled_loops
    assert banded(loop) and loop.fell_back and loop.n_compiled == 75
    assert python.n_times == compiled.n_times == 76
    np.testing.assert_allclose(compiled.coordinates, python.coordinates, rtol=0.0, atol=10.0 * TOLERANCE)
    np.testing.assert_allclose(compiled.velocities, python.velocities, rtol=0.0, atol=10.0 * TOLERANCE)


def test_the_dense_solver_asked_for_keeps_the_dense_lu(compiled_loops):
    times = np.linspace(0.0, 0.1, 3)
    solve = SolveOptions(TOLERANCE, linear_solver="dense", thresholds=BANDED)
    run_dynamics(discretize(n_four_bar(4)), times, solve, DynamicsOptions(1e-3), Request(energy=True))
    (loop,) = compiled_loops
    assert not banded(loop) and loop.n_compiled == 2


def test_a_model_with_redundant_equations_stays_on_the_python_stepper(compiled_loops):
    # the struck lattice leaves six redundant equations out: their minimum-norm forces are
    # the Python stepper's to publish, banded or not
    lattice = sk.load_model(EXAMPLES / "dynamics" / "struck_lattice.toml")
    with pytest.warns(sk.RedundantConstraintWarning):
        result = run(lattice, np.linspace(0.0, 0.01, 3), 1e-3, BANDED)
    (loop,) = compiled_loops
    assert result.complete and loop.fell_back and loop.n_compiled == 0 and loop._state is None
