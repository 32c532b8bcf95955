"""The equations of motion's matrices against differences of their residual and of the energy.

`sparsekin.engine.saddle.DynamicSystem` fills S = [[a M + b C_t + c K_t, Φqᵀ], [Φq, 0]]
from hand-derived kernels.  At random states (not on the constraints: the derivatives hold
everywhere), for every constraint primitive, load kind and actuator kind:

* M equals the Hessian of the kinetic energy in the velocities (a difference of the
  energy, which does not use the mass kernel), and equals ∂f/∂q̈;
* C_t equals central differences of the residual f in q̇;
* K_t, with the derivative of Φqᵀλ and of the actuators' F ∇s, equals central
  differences of f in q (Φq refilled at each perturbed q);
* the Φq blocks are the constraint Jacobian.
"""

from __future__ import annotations

import numpy as np
import pytest

import sparsekin as sk
from sparsekin.engine.discretization import discretize
from sparsekin.engine.saddle import DynamicSystem

POINTS = {"O": (0.0, 0.0), "P": (0.3, -0.2), "Q": (1.1, 0.4), "R": (-0.6, 0.9), "S": (0.7, 1.3)}


def _bodies():
    return [
        sk.Body("b1", origin=(0.1, 0.2), angle=0.4, points=("P", "Q"), mass=2.0, inertia=0.3, com=(0.5, 0.1)),
        sk.Body("b2", origin="Q", angle=-1.1, points=("Q", "R"), mass=1.2, inertia=0.05, com="R"),
        sk.Body("b3", origin=(-0.4, 0.7), angle=0.9, points=("R", "S"), mass=0.7, inertia=0.0, com=(0.0, 1.0)),
    ]


def model(joints=(), drivers=(), loads=()) -> sk.Mechanism:
    return sk.Mechanism(points=POINTS, bodies=_bodies(), joints=list(joints), drivers=list(drivers),
                        loads=list(loads), gravity=(0.3, -9.81))  # fmt: skip


HARMONIC = sk.Harmonic(amplitude=30.0, omega=2.0, phase=0.4)
MODELS = {
    "masses and gravity": model(),
    "revolute (coincidence)": model([sk.Revolute(("b1", "b2"), at="P"), sk.Revolute(("b3", "ground"), at="S")]),
    "translational (combination, projection)": model([sk.Translational(("b1", "b2"), axis=("P", "Q"))]),
    "pin in slot (projection)": model([sk.PinInSlot(("b2", "b3"), at="R", direction=(0.3, 1.0))]),
    "rack and pinion (rolling projection)": model([sk.RackPinion(("b1", "b3"), at="S", direction=(1.0, 0.2),
                                                                radius=0.1)]),  # fmt: skip
    "distance driver": model(drivers=[sk.DistanceDriver(("P", "S"), ("b1", "b3"), sk.Linear(rate=0.1))]),
    "gear": model([sk.Gear(("b1", "b2"), ratio=-2.0, carrier="b3")]),
    "force and torque": model(loads=[sk.Force("b2", at="R", value=(HARMONIC, -40.0)), sk.Torque("b1", value=7.0)]),
    "spring-damper": model(loads=[sk.Spring(("b1", "b3"), points=("P", "S"), stiffness=300.0, free_length=0.4,
                                            damping=12.0),
                                  sk.Spring(("b2", "ground"), points=("R", "O"), stiffness=50.0, damping=3.0)]),
    "rotational spring": model(loads=[sk.RotationalSpring(("b1", "b2"), stiffness=20.0, free_angle=0.2, damping=1.5),
                                      sk.RotationalSpring(("ground", "b3"), stiffness=4.0)]),
    "actuators": model(
        [sk.Revolute(("b1", "b2"), at="Q", name="hinge"), sk.Translational(("b2", "b3"), axis=("R", "S"), name="ram"),
         sk.PinInSlot(("b1", "b3"), at="S", direction=(1.0, -0.5), name="slot")],
        loads=[sk.Actuator("hinge", 5.0), sk.Actuator("ram", HARMONIC), sk.Actuator("slot", -12.0)],
    ),
}  # fmt: skip


def _state(rng, n, m):
    q = rng.uniform(-1.0, 1.0, n)
    return q, rng.normal(size=n) * 2.0, rng.normal(size=n) * 5.0, rng.normal(size=m) * 20.0


def _top_left(system, q, qd, qdd, lam, a, b, c):
    system.fill_constraints(q)
    return system.fill_matrix(q, qd, qdd, lam, a, b, c).toarray()


def _residual(system, q, qd, qdd, lam):
    system.fill_constraints(q)
    return system.residual(q, qd, qdd, lam, np.zeros(system.n))


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mass_damping_and_stiffness_match_differences(name, seed):
    mechanism = MODELS[name]
    system = DynamicSystem(discretize(mechanism))
    pattern = system.pattern
    rng = np.random.default_rng(seed)
    n, m = pattern.n_coordinates, pattern.n_equations
    q, qd, qdd, lam = _state(rng, n, m)
    system.set_time(0.37)
    step = 1e-6
    differences = {}
    for which, argument in (("M", 2), ("C", 1), ("K", 0)):
        columns = []
        for k in range(n):
            plus, minus = [np.array(x) for x in (q, qd, qdd)], [np.array(x) for x in (q, qd, qdd)]
            plus[argument][k] += step
            minus[argument][k] -= step
            columns.append((_residual(system, *plus, lam) - _residual(system, *minus, lam)) / (2 * step))
        differences[which] = np.array(columns).T
    scale = max(1.0, np.abs(differences["K"]).max())
    for which, coefficients in (("M", (1.0, 0.0, 0.0)), ("C", (0.0, 1.0, 0.0)), ("K", (0.0, 0.0, 1.0))):
        matrix = _top_left(system, q, qd, qdd, lam, *coefficients)
        np.testing.assert_allclose(matrix[:n, :n], differences[which], rtol=0, atol=1e-6 * scale, err_msg=which)
    # the constraint blocks are Φq and its transpose
    matrix = _top_left(system, q, qd, qdd, lam, 1.0, 1.0, 1.0)
    jacobian = system.assembler.jacobian.toarray()
    np.testing.assert_array_equal(matrix[n:, :n], jacobian)
    np.testing.assert_array_equal(matrix[:n, n:], jacobian.T)
    np.testing.assert_array_equal(matrix[n:, n:], 0.0)


@pytest.mark.parametrize("seed", [0, 1])
def test_mass_matrix_is_the_hessian_of_the_kinetic_energy(seed):
    mechanism = MODELS["masses and gravity"]
    system = DynamicSystem(discretize(mechanism))
    rng = np.random.default_rng(seed)
    n = system.n
    q, qd = rng.uniform(-1.0, 1.0, n), rng.normal(size=n)
    step = 1e-3  # the energy is quadratic in the velocities: second differences are exact to rounding
    hessian = np.zeros((n, n))
    for i in range(n):
        for j in range(n):
            e = [np.zeros(n), np.zeros(n)]
            e[0][i], e[1][j] = step, step
            values = [system.energies(q, qd + si * e[0] + sj * e[1])[0] for si in (1, -1) for sj in (1, -1)]
            hessian[i, j] = (values[0] - values[1] - values[2] + values[3]) / (4 * step * step)
    system.fill_constraints(q)
    mass = system.fill_matrix(q, qd, np.zeros(n), np.zeros(0), 1.0, 0.0, 0.0).toarray()
    np.testing.assert_allclose(mass, hessian, rtol=0, atol=1e-7)


def test_the_residual_of_gravity_is_the_gradient_of_the_potential():
    mechanism = MODELS["spring-damper"]
    system = DynamicSystem(discretize(mechanism))
    rng = np.random.default_rng(5)
    n = system.n
    q, zero = rng.uniform(-1.0, 1.0, n), np.zeros(n)
    system.set_time(0.0)
    gradient = np.zeros(n)
    step = 1e-6
    for k in range(n):
        e = np.zeros(n)
        e[k] = step
        plus, minus = system.energies(q + e, zero), system.energies(q - e, zero)
        gradient[k] = (plus[1] + plus[2] - minus[1] - minus[2]) / (2 * step)
    # at rest, f = −Q = ∇(potential + elastic)
    np.testing.assert_allclose(_residual(system, q, zero, zero, np.zeros(0)), gradient, rtol=0, atol=1e-6)


@pytest.mark.parametrize("chain", [True, False])
def test_one_pass_refill_and_newton_rhs_are_the_separate_calls(chain):
    """`DynamicSystem.fill_constraints_newton_rhs` (a chain of point coincidences: the refill
    of Φ and Φq and Newton's right-hand side in one pass) gives, bit for bit, Φ, Φq, its
    norm and the right-hand side of `fill_constraints` then `newton_rhs`, and that right-hand
    side is ``[scale · residual; −Φ]`` of `residual` (Φqᵀλ row after row); a system with an
    equation left out does not take it (None).  `fill_constraints_drifts` (the refill with
    Φq q̇ + Φt, Φq q̈, γ and Φq q̈ − γ) gives those of `velocity_drift`, `jacobian_product` and
    `Assembler.fill_acceleration_rhs`."""
    from sparsekin.testset import n_four_bar

    joints = [sk.Revolute(("b2", "b1"), at="Q"), sk.Revolute(("b3", "b2"), at="R"), sk.Revolute(("ground", "b3"), at="S")]
    discretization = discretize(n_four_bar(20) if chain else model(joints))  # (the ground first, bodies in both orders)
    system = DynamicSystem(discretization)
    assert system._coincidence_rows
    n, m = system.n, discretization.constraints.n_equations
    rng = np.random.default_rng(5)
    q = discretization.constraints.initial_coordinates[:n] + 1e-3 * rng.standard_normal(n)
    v, a = rng.standard_normal(n), rng.standard_normal(n)
    lam = rng.standard_normal(m)
    lam[::7] = 0.0  # (rows of λ = 0 add nothing)
    system.set_time(0.0)
    phi = system.fill_constraints(q)
    separate = np.zeros(system.size)
    assert system.newton_rhs(q, v, a, lam, -0.7, separate)
    values, residual = system.assembler.values.copy(), system.assembler.residual.copy()
    system.fill_constraints(q + 1e-3)  # (another state in the arrays first)
    fused = np.zeros(system.size)
    assert system.fill_constraints_newton_rhs(q, v, a, lam, -0.7, fused) == (phi, True)
    for one, other in ((separate, fused), (values, system.assembler.values), (residual, system.assembler.residual)):
        assert np.array_equal(one.view(np.int64), other.view(np.int64))
    expected = np.concatenate([-0.7 * system.residual(q, v, a, lam, np.zeros(n)), -residual])
    assert np.array_equal(expected.view(np.int64), fused.view(np.int64))
    # again, after another state's refill: Φq's constant entries (a joint's ±1) not written again
    system.fill_constraints(q + 2e-3)
    assert not system._constants(system.assembler._jac_buffer)
    assert system.fill_constraints_newton_rhs(q, v, a, lam, -0.7, fused) == (phi, True)
    assert np.array_equal(values.view(np.int64), system.assembler.values.view(np.int64))
    assert np.array_equal(expected.view(np.int64), fused.view(np.int64))
    assert DynamicSystem(discretization, np.arange(m - 1)).fill_constraints_newton_rhs(q, v, a, lam[:-1], -0.7,
                                                                                        fused[:-1]) is None  # fmt: skip
    # the refill with the projections' drifts, Φq q̈ and γ (`fill_constraints_drifts`): the same numbers
    system.assembler.fill_acceleration_rhs(q, v)
    gamma = system.assembler.acceleration_rhs.copy()
    drift, product = system.velocity_drift(v), system.jacobian_product(a)
    acceleration = system.jacobian_product(a, gamma)
    system.fill_constraints(q + 1e-3)
    system.assembler.fill_acceleration_rhs(q + 1e-3, v + 1.0)
    made = np.zeros(m), np.zeros(m), np.zeros(m)
    assert system.fill_constraints_drifts(q, v, a, *made) == phi
    for one, other in ((drift, made[0]), (product, made[1]), (acceleration, made[2]), (values, system.assembler.values),
                       (gamma, system.assembler.acceleration_rhs)):  # fmt: skip
        assert np.array_equal(one.view(np.int64), other.view(np.int64))
