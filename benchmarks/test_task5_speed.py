"""Task 5 over 10 s at 1 ms (10 001 samples): the whole run and the phases of one step.

Run with ``python -m pytest benchmarks --benchmark-enable --benchmark-only``; in the test
suite (``--benchmark-disable``) each benchmark runs once as a smoke test.
"""

from __future__ import annotations

import numpy as np
import pytest
from examples_loader import load_example

from sparsekin.engine.discretization import Discretization
from sparsekin import solve_kinematics
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.linalg import SuperLUSolver
from sparsekin.engine.pattern import build_pattern

TIMES = np.linspace(0.0, 10.0, 10_001)


@pytest.fixture(scope="module")
def task5():
    return load_example("task5").build_task5()


@pytest.fixture(scope="module")
def assembled(task5):
    pattern = build_pattern(task5)
    assembler = Assembler(Discretization(task5, pattern))
    assembler.set_time(0.0)
    assembler.fill_residual_jacobian(pattern.initial_coordinates)  # compiles the kernels
    solver = SuperLUSolver()
    solver.factor(assembler.jacobian)
    return pattern, assembler, solver


@pytest.mark.parametrize("linear_solver", ["auto", "superlu"])
def test_full_run_10s_at_1ms(benchmark, task5, linear_solver):
    solve_kinematics(task5, TIMES[:3], linear_solver=linear_solver)  # compile outside the timing
    result = benchmark.pedantic(
        solve_kinematics, args=(task5, TIMES), kwargs={"linear_solver": linear_solver}, rounds=5, iterations=1
    )
    assert result.complete
    benchmark.extra_info["path"] = result.linear_solver
    benchmark.extra_info["samples"] = result.n_times
    benchmark.extra_info["newton_corrections_per_step"] = float(result.newton_iterations[1:].mean())
    benchmark.extra_info["factorizations_per_step"] = (
        result.n_factorizations + result.n_refactorizations
    ) / result.n_times


def test_refill_residual_and_jacobian(benchmark, assembled):
    pattern, assembler, _ = assembled
    benchmark(assembler.fill_residual_jacobian, pattern.initial_coordinates)


def test_refill_acceleration_rhs(benchmark, assembled):
    pattern, assembler, _ = assembled
    benchmark(assembler.fill_acceleration_rhs, pattern.initial_coordinates, np.ones(pattern.n_coordinates))


def test_evaluate_driver_laws(benchmark, assembled):
    _, assembler, _ = assembled
    benchmark(assembler.set_time, 1.0)


def test_factorization(benchmark, assembled):
    _, assembler, solver = assembled
    benchmark(solver.factor, assembler.jacobian)


def test_one_solve(benchmark, assembled):
    _, assembler, solver = assembled
    benchmark(solver.solve, assembler.velocity_rhs)
