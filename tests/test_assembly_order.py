"""The assembler can write the Jacobian in a linear solver's value order."""

from __future__ import annotations

import numpy as np
import pytest

from sparsekin.engine.discretization import Discretization
from sparsekin import testset
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.linalg import RefactorSolver
from sparsekin.engine.pattern import build_pattern


@pytest.fixture(scope="module")
def chain():
    mechanism = testset.task5_chain(3)
    return mechanism, build_pattern(mechanism)


def test_values_in_order_are_the_csr_values_permuted(chain, rng):
    mechanism, pattern = chain
    q = pattern.initial_coordinates + 0.01 * rng.standard_normal(pattern.n_coordinates)
    plain = Assembler(Discretization(mechanism, pattern))
    plain.fill_residual_jacobian(q)
    positions = rng.permutation(pattern.nnz)
    ordered = Assembler(Discretization(mechanism, pattern))
    ordered.fill_in_order(positions)
    ordered.fill_residual_jacobian(q)
    np.testing.assert_array_equal(ordered.values[positions], plain.jacobian.data)
    np.testing.assert_array_equal(ordered.jacobian.toarray(), plain.jacobian.toarray())  # a CSR copy
    np.testing.assert_array_equal(ordered.residual, plain.residual)
    ordered.fill_in_order(None)
    ordered.fill_residual_jacobian(q)
    np.testing.assert_array_equal(ordered.jacobian.data, plain.jacobian.data)


def test_refactor_from_values_in_order_solves_the_system(chain, rng):
    mechanism, pattern = chain
    assembler = Assembler(Discretization(mechanism, pattern))
    assembler.fill_residual_jacobian(pattern.initial_coordinates)
    solver = RefactorSolver()
    solver.factor(assembler.jacobian)
    assembler.fill_in_order(solver.value_positions)
    q = pattern.initial_coordinates + 0.01 * rng.standard_normal(pattern.n_coordinates)
    assembler.fill_residual_jacobian(q)
    solver.factor_ordered(assembler.values)
    rhs = rng.standard_normal(pattern.n_coordinates)
    jacobian = assembler.jacobian
    x = solver.solve(rhs)
    assert np.abs(jacobian @ x - rhs).max() <= 1e-13 * (
        abs(jacobian).max() * np.abs(x).max() + np.abs(rhs).max()
    )


@pytest.mark.parametrize("mistake", ["too short", "duplicate", "out of range"])
def test_positions_must_be_a_permutation(chain, mistake):
    mechanism, pattern = chain
    positions = np.arange(pattern.nnz)
    if mistake == "too short":
        positions = positions[:-1]
    else:
        positions[0] = 1 if mistake == "duplicate" else pattern.nnz
    with pytest.raises(ValueError, match=r"`positions` must be a permutation of range"):
        Assembler(Discretization(mechanism, pattern)).fill_in_order(positions)


def test_gamma_before_any_refill_uses_the_right_angles(chain, rng):
    """γ reuses the cos and sin of the last refill when q has not moved: on a fresh assembler
    (all angles 0), a first γ at q = 0 must see cos 1, sin 0."""
    mechanism, pattern = chain
    q, qd = np.zeros(pattern.n_coordinates), rng.standard_normal(pattern.n_coordinates)
    fresh = Assembler(Discretization(mechanism, pattern))
    fresh.fill_acceleration_rhs(q, qd)
    refilled = Assembler(Discretization(mechanism, pattern))
    refilled.fill_residual_jacobian(q + 1.0)  # other angles first
    refilled.fill_acceleration_rhs(q, qd)
    np.testing.assert_array_equal(fresh.acceleration_rhs, refilled.acceleration_rhs)
