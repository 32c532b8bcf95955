"""Each constraint equation against its definition and its derivatives against differences.

For every joint and driver type, at configurations drawn by hypothesis:
* the residual filled by the kernels equals the slow reference of `tests/reference.py`;
* the Jacobian equals central differences of the residual;
* gamma equals minus the second directional derivative of the residual along the
  velocities (a five-point difference), which is what ``Phi_q qdd = gamma`` requires.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from reference import constraint_residual
from sparsekin.engine.discretization import Discretization
from sparsekin import (
    AbsoluteDriver,
    Body,
    DistanceDriver,
    Gear,
    Linear,
    Mechanism,
    PathDriver,
    PinInSlot,
    RackPinion,
    Revolute,
    Rigid,
    RotationalDriver,
    Translational,
    TranslationalDriver,
)
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.pattern import build_pattern

POINTS = {"P": (0.3, -0.2), "Q": (1.1, 0.4), "R": (-0.6, 0.9)}
LAW = Linear(rate=0.0)


def two_bodies(*joints, drivers=(), third=False) -> Mechanism:
    bodies = [
        Body("b1", origin=(0.1, 0.2), angle=0.4, points=("P", "Q")),
        Body("b2", origin="Q", angle=-1.1, points=("Q", "R")),
    ]
    if third:  # a carrier
        bodies.append(Body("b3", origin=(-0.4, 0.7), angle=0.9, points=("R",)))
    return Mechanism(points=POINTS, bodies=bodies, joints=list(joints), drivers=list(drivers))


ELEMENTS = {
    "revolute": two_bodies(Revolute(("b1", "b2"), at="P")),
    "revolute to ground": two_bodies(Revolute(("b2", "ground"), at="R")),
    "revolute from ground": two_bodies(Revolute(("ground", "b1"), at=(0.5, 0.5))),
    "translational axis": two_bodies(Translational(("b1", "b2"), axis=("P", "Q"))),
    "translational on ground": two_bodies(Translational(("ground", "b2"), axis=("R", "Q"))),
    "translational direction": two_bodies(Translational(("b2", "b1"), at="R", direction=(0.3, -2.0))),
    "rigid": two_bodies(Rigid(("b1", "b2"))),
    "rigid to ground": two_bodies(Rigid(("b2", "ground"))),
    "translational driver": two_bodies(
        Translational(("b1", "b2"), axis=("R", "Q"), name="slide"),
        drivers=[TranslationalDriver("slide", law=LAW)],
    ),
    "translational driver, direction": two_bodies(
        Translational(("b2", "b1"), at="P", direction=(1.0, 1.0), name="slide"),
        drivers=[TranslationalDriver("slide", law=LAW)],
    ),
    "rotational driver": two_bodies(drivers=[RotationalDriver(("b2", "b1"), law=LAW)]),
    "absolute drivers": two_bodies(
        drivers=[AbsoluteDriver("b1", c, law=LAW) for c in ("x", "y", "angle")]
        + [AbsoluteDriver("b2", "angle", law=LAW)]
    ),
    "pin in slot": two_bodies(PinInSlot(("b1", "b2"), at="R", direction=(0.6, -0.8))),
    "pin in a ground slot": two_bodies(PinInSlot(("ground", "b2"), at="P", direction=(1.0, 0.2))),
    "gear on the ground": two_bodies(Gear(("b1", "b2"), ratio=2.5)),
    "internal gear on a carrier": two_bodies(Gear(("b2", "b1"), ratio=-3.0, carrier="b3"), third=True),
    "rack and pinion": two_bodies(RackPinion(("b1", "b2"), at="Q", direction=(0.3, 1.0), radius=0.25)),
    "pinion on a ground rack": two_bodies(RackPinion(("ground", "b2"), at="R", direction=(1.0, 0.0), radius=0.4)),
    "distance driver": two_bodies(drivers=[DistanceDriver(("P", "R"), ("b1", "b2"), law=LAW)]),
    "distance driver to the ground": two_bodies(drivers=[DistanceDriver(("Q", (2.0, -1.0)), ("b2", "ground"), law=LAW)]),
    "path driver": two_bodies(drivers=[PathDriver("b2", "R", law_x=LAW, law_y=LAW)]),
}

#: Coordinates of two bodies (three for a carrier), drawn for each test.
coordinates = arrays(np.float64, 9, elements=st.floats(-3.0, 3.0))
velocities = arrays(np.float64, 9, elements=st.floats(-4.0, 4.0))


def sized(mechanism, vector):
    return vector[: mechanism.n_coordinates]


def assembled(mechanism):
    assembler = Assembler(Discretization(mechanism, build_pattern(mechanism)))
    assembler.set_time(0.0)  # targets at the laws' initial values, zero rates
    return assembler


def residual(assembler, q):
    assembler.fill_residual_jacobian(q)
    return assembler.residual.copy()


@pytest.mark.parametrize("element", ELEMENTS, ids=list(ELEMENTS))
@settings(max_examples=40, deadline=None)
@given(q=coordinates)
def test_residual_matches_reference(element, q):
    mechanism = ELEMENTS[element]
    q = sized(mechanism, q)
    np.testing.assert_allclose(residual(assembled(mechanism), q), constraint_residual(mechanism, q), atol=1e-13)


@pytest.mark.parametrize("element", ELEMENTS, ids=list(ELEMENTS))
def test_residual_vanishes_in_initial_configuration(element):
    mechanism = ELEMENTS[element]
    pattern = build_pattern(mechanism)
    np.testing.assert_allclose(residual(assembled(mechanism), pattern.initial_coordinates), 0.0, atol=1e-15)


@pytest.mark.parametrize("element", ELEMENTS, ids=list(ELEMENTS))
@settings(max_examples=40, deadline=None)
@given(q=coordinates)
def test_jacobian_matches_central_differences(element, q):
    q = sized(ELEMENTS[element], q)
    assembler = assembled(ELEMENTS[element])
    assembler.fill_residual_jacobian(q)
    jacobian = assembler.jacobian.toarray()
    step = 1e-6  # truncation ~ step² · |g'''| ~ 1e-11, rounding ~ 1e-16 / step ~ 1e-10
    differences = np.empty_like(jacobian)
    for column in range(q.size):
        shift = np.zeros_like(q)
        shift[column] = step
        differences[:, column] = (residual(assembler, q + shift) - residual(assembler, q - shift)) / (2 * step)
    np.testing.assert_allclose(jacobian, differences, atol=2e-8)


@pytest.mark.parametrize("element", ELEMENTS, ids=list(ELEMENTS))
@settings(max_examples=40, deadline=None)
@given(q=coordinates, qd=velocities)
@example(q=np.array([0.25, -1.875, 1.125, 0.0, -0.375, 1.125, 1.125, 1.125, 1.125]), qd=np.ones(9))  # points 3 cm apart
def test_gamma_is_minus_second_directional_derivative(element, q, qd):
    q, qd = sized(ELEMENTS[element], q), sized(ELEMENTS[element], qd)
    assembler = assembled(ELEMENTS[element])
    assembler.fill_acceleration_rhs(q, qd)
    gamma = assembler.acceleration_rhs.copy()
    def five_point(step):  # truncation ~ step⁴ · |g⁽⁶⁾|, rounding ~ 30·1e-16 / step²
        g = [residual(assembler, q + k * step * qd) for k in (-2, -1, 0, 1, 2)]
        return (-g[0] + 16 * g[1] - 30 * g[2] + 16 * g[3] - g[4]) / (12 * step**2)

    # Richardson's extrapolation of the stencil at 1e-3 and 5e-4 cancels its step⁴ term: a
    # distance driver whose points come within 3 cm has |g⁽⁶⁾| large enough for the
    # stencil alone to be off by 7e-5 (a clean example database found one; the two steps
    # converge on the kernel's gamma as step⁴ there), the extrapolation by 5e-8.
    second = (16 * five_point(5e-4) - five_point(1e-3)) / 15
    scale = 1.0 + np.abs(qd).max() ** 2 * 10.0  # g'' grows like |qd|² · (lever arms ≲ 10 m)
    np.testing.assert_allclose(gamma, -second, atol=1e-7 * scale)


def test_jacobian_pattern_is_fixed_and_shared():
    """Refilling writes into the same CSR arrays: no new pattern, no copy of the values."""
    assembler = assembled(ELEMENTS["translational driver"])
    jacobian = assembler.jacobian
    data, indices, indptr = jacobian.data, jacobian.indices, jacobian.indptr
    assembler.fill_residual_jacobian(np.full(6, 0.3))
    first = data.copy()
    assembler.fill_residual_jacobian(np.full(6, -1.2))
    assert assembler.jacobian.data is data and jacobian.indices is indices and jacobian.indptr is indptr
    assert not np.array_equal(first, data)
    assert jacobian.has_sorted_indices


def test_a_row_that_is_not_finite_leaves_the_others_complete():
    """The weighted norm is NaN, and every other row is still g(q) - target (the
    assembler's `residual`), the driven rows after the non-finite ones included."""
    from pathlib import Path

    from sparsekin import load_model

    mechanism = load_model(Path(__file__).resolve().parent / "data" / "slider_crank.toml")
    pattern = build_pattern(mechanism)
    assembler = Assembler(Discretization(mechanism, pattern))
    assembler.set_time(0.3)  # the driven row's target: the drawn crank angle + 0.3 s · rate
    q = pattern.initial_coordinates.copy()
    assert np.isfinite(assembler.fill_residual_jacobian(q))
    complete = assembler.residual.copy()
    assert complete[pattern.driven_row[0]] != 0.0
    q[3 * mechanism.body_index("slider")] = np.nan  # the rows of joints[2] and of the guide
    assert np.isnan(assembler.fill_residual_jacobian(q))
    finite = np.isfinite(assembler.residual)
    assert not finite[: pattern.driven_row[0]].all() and finite[pattern.driven_row].all()
    np.testing.assert_array_equal(assembler.residual[finite], complete[finite])


#: Elements whose equations subtract two far points (two bodies, or a body and the ground),
#: drawn at the origin and SHIFT m along x.  Points, origins and coordinates lie on a grid of
#: 2^-20 m, so the shifted drawing and coordinates are the same geometry exactly.
SHIFT = 1e5
FAR_ELEMENTS = {
    "revolute": lambda s: [Revolute(("b1", "b2"), at="P")],
    "revolute to ground": lambda s: [Revolute(("b2", "ground"), at="R")],
    "revolute from ground": lambda s: [Revolute(("ground", "b1"), at=(0.5 + s, 0.5))],
    "translational axis": lambda s: [Translational(("b1", "b2"), axis=("P", "Q"))],
    "translational on ground": lambda s: [Translational(("ground", "b2"), axis=("R", "Q"))],
    "pin in a ground slot": lambda s: [PinInSlot(("ground", "b2"), at="P", direction=(1.0, 0.25))],
    "distance driver to the ground": lambda s: [],
}


def drawn_at(element, shift):
    points = {name: (x + shift, y) for name, (x, y) in {"P": (0.25, -0.125), "Q": (1.125, 0.375),
                                                          "R": (-0.625, 0.875)}.items()}  # fmt: skip
    bodies = [Body("b1", origin=(0.125 + shift, 0.25), angle=0.4, points=("P", "Q")),
              Body("b2", origin="Q", angle=-1.1, points=("Q", "R"))]  # fmt: skip
    drivers = []
    if element == "distance driver to the ground":
        drivers = [DistanceDriver(("Q", (2.0 + shift, -1.0)), ("b2", "ground"), law=LAW)]
    return Mechanism(points=points, bodies=bodies, joints=FAR_ELEMENTS[element](shift), drivers=drivers)


@pytest.mark.parametrize("element", FAR_ELEMENTS, ids=list(FAR_ELEMENTS))
@settings(max_examples=40, deadline=None)
@given(q=arrays(np.float64, 6, elements=st.floats(-3.0, 3.0)), qd=arrays(np.float64, 6, elements=st.floats(-4.0, 4.0)))
def test_far_from_the_origin_the_equations_keep_their_digits(element, q, qd):
    """Φ, Φq and γ of a mechanism drawn 10^5 m from the origin equal those of the same one at
    the origin to the rounding of their own size, not to the ulp of 10^5 m (1.5e-11 m).
    That rounding, amplified along Φq's vanishing singular values, is what stopped a chain of
    5·10^4 four-bars at its first flat crossing (docs/design-notes.md)."""
    q = np.round(q * 2.0**20) / 2.0**20
    far = q.copy()
    far[[0, 3]] += SHIFT  # exact: x on the 2^-20 grid, below 2^17
    near_assembler, far_assembler = assembled(drawn_at(element, 0.0)), assembled(drawn_at(element, SHIFT))
    near, far_residual = residual(near_assembler, q), residual(far_assembler, far)
    np.testing.assert_allclose(far_residual, near, rtol=0.0, atol=1e-14)
    np.testing.assert_allclose(far_assembler.jacobian.toarray(), near_assembler.jacobian.toarray(), rtol=0.0, atol=1e-13)
    near_assembler.fill_acceleration_rhs(q, qd)
    far_assembler.fill_acceleration_rhs(far, qd)
    np.testing.assert_allclose(far_assembler.acceleration_rhs, near_assembler.acceleration_rhs, rtol=0.0, atol=1e-12)
