"""`solve_kinematics` against closed-form kinematics of classic mechanisms.

Every reference here is derived by hand and evaluated with NumPy alone (plus scipy's
`CubicSpline` for the spline law); none calls into sparsekin.  The mechanisms:

* slider-crank, centred (``axis`` form) and offset (``at`` / ``direction`` form), crank
  driven by `Linear`, `Harmonic` and `Spline` laws;
* Grashof crank-rocker four-bar, both assembly branches (half-angle formula);
* inverted slider-crank: a hydraulic cylinder driving a rocker, stroke by `Polynomial`;
* a slider on an inclined guide, stroke by `Polynomial`;
* a plate driven by three `AbsoluteDriver` laws with an arm welded to it by `Rigid`.

Tolerances
----------
The solver stops Newton at a residual of 1e-12 (lengths relative to the model size, angles
in rad) and, being quadratic, usually far below it.  Away from dead points these
mechanisms are well conditioned, so positions carry an error of ~1e-12 relative to the
model size at worst, and velocities and accelerations, solved with the Jacobian at those
positions, the same relative error times the velocity and acceleration scales.  Closed
forms are exact up to rounding, so every comparison uses ``rtol = 1e-10`` and an
``atol`` of 1e-10 times the scale of the quantity (quantities cross zero, where a pure
``rtol`` means nothing).  A formula or sign error, or an O(h) error anywhere, is many
orders of magnitude above that.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from helpers import RTOL, four_bar, slider_crank
from scipy.interpolate import CubicSpline

from sparsekin import (
    AbsoluteDriver,
    Body,
    Harmonic,
    Linear,
    Mechanism,
    Polynomial,
    Revolute,
    Rigid,
    Spline,
    Translational,
    TranslationalDriver,
    load_model,
    save_model,
    solve_kinematics,
)



# ---------------------------------------------------------------------- helpers
def rotate(vectors: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Vectors (n, 2) turned by angles (n,)."""
    cosine, sine = np.cos(angles), np.sin(angles)
    return np.stack(
        [
            cosine * vectors[..., 0] - sine * vectors[..., 1],
            sine * vectors[..., 0] + cosine * vectors[..., 1],
        ],
        axis=-1,
    )


def perpendicular(vectors: np.ndarray) -> np.ndarray:
    """Vectors turned by +90°."""
    return np.stack([-vectors[..., 1], vectors[..., 0]], axis=-1)


def stacked(*components) -> np.ndarray:
    """Columns (each a scalar or an (n,) array) side by side, broadcast to (n, k)."""
    arrays = np.broadcast_arrays(*[np.asarray(c, dtype=float) for c in components])
    return np.stack(arrays, axis=-1)


def fixed(x: float, y: float):
    """Position, velocity and acceleration of a point that does not move (broadcastable)."""
    return np.array([x, y]), np.zeros(2), np.zeros(2)


def body_motion(origin, angle):
    """Frame coordinates, velocities and accelerations, each (n, 3), of a body.

    `origin` is the (position, velocity, acceleration) of its frame origin and `angle`
    the (value, rate, acceleration) of its frame angle.
    """
    return tuple(stacked(o[..., 0], o[..., 1], a) for o, a in zip(origin, angle))


@dataclass
class Expected:
    """Closed-form motion: per body (n, 3) arrays, per point (n, 2) arrays.

    ``scales`` are the characteristic length (m), velocity (m/s) and acceleration (m/s²)
    of the mechanism; angles, rates and angular accelerations are compared with the same
    scales divided by the length scale.
    """

    bodies: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
    points: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
    scales: tuple[float, float, float]


def assert_matches(result, mechanism: Mechanism, expected: Expected) -> None:
    """Body coordinates and point motion of `result` equal the closed forms."""
    length = expected.scales[0]
    for name, motion in expected.bodies.items():
        k = mechanism.body_index(name)
        solved = (result.coordinates, result.velocities, result.accelerations)
        labels = ("coordinates", "velocities", "accelerations")
        for order, (label, scale) in enumerate(zip(labels, expected.scales)):
            actual = solved[order][:, 3 * k : 3 * k + 3]
            for c, coordinate in enumerate(("x", "y", "angle")):
                atol = RTOL * (scale / length if coordinate == "angle" else scale)
                np.testing.assert_allclose(
                    actual[:, c], motion[order][:, c], rtol=RTOL, atol=atol,
                    err_msg=f"{label} of {name}.{coordinate}",
                )  # fmt: skip
    for name, motion in expected.points.items():
        solved = result.point(name)
        for order, label in enumerate(("position", "velocity", "acceleration")):
            np.testing.assert_allclose(
                solved[order], motion[order], rtol=RTOL, atol=RTOL * expected.scales[order],
                err_msg=f"{label} of point {name}",
            )  # fmt: skip


# ---------------------------------------------------------------------- slider-crank
CRANK, ROD = 0.1, 0.4  # m
CRANK_START = 0.3  # rad, crank angle of the drawn configuration


def slider_crank_reference(theta, theta_d, theta_dd, offset: float):
    """Crank pin A, slider B and rod angle phi of a slider-crank, with time derivatives.

    The crank (length r) turns about the origin by theta; the slider moves on the line
    y = offset, to the right of the crank pin.  From ``l sin(phi) = e - r sin(theta)``:

        phi'  = -r cos(theta) theta' / (l cos(phi))
        phi'' = (r sin(theta) theta'² - r cos(theta) theta'' + l sin(phi) phi'²) / (l cos(phi))

    and ``x_B = r cos(theta) + l cos(phi)`` differentiated twice.
    """
    r, l, e = CRANK, ROD, offset
    s, c = np.sin(theta), np.cos(theta)
    phi = np.arcsin((e - r * s) / l)
    sp, cp = np.sin(phi), np.cos(phi)
    phi_d = -r * c * theta_d / (l * cp)
    phi_dd = (r * s * theta_d**2 - r * c * theta_dd + l * sp * phi_d**2) / (l * cp)
    a = r * stacked(c, s)
    a_d = r * theta_d[:, None] * stacked(-s, c)
    a_dd = r * theta_dd[:, None] * stacked(-s, c) - r * theta_d[:, None] ** 2 * stacked(c, s)
    x_b = r * c + l * cp
    x_b_d = -r * s * theta_d - l * sp * phi_d
    x_b_dd = -r * c * theta_d**2 - r * s * theta_dd - l * cp * phi_d**2 - l * sp * phi_dd
    b, b_d, b_dd = stacked(x_b, e), stacked(x_b_d, 0.0), stacked(x_b_dd, 0.0)
    return (a, a_d, a_dd), (b, b_d, b_dd), (phi, phi_d, phi_dd)


def build_slider_crank(law, offset: float) -> Mechanism:
    """Slider-crank drawn at crank angle CRANK_START; the slider axis is y = offset.

    A centred slider (offset 0) gets its guide in the ``axis`` form through a ground point
    S on the line; an offset slider in the ``at`` / ``direction`` form.
    """
    (a, _, _), (b, _, _), _ = slider_crank_reference(np.array([CRANK_START]), np.zeros(1), np.zeros(1), offset)
    points = {"O": (0.0, 0.0), "A": tuple(a[0]), "B": tuple(b[0]), "S": (-0.2, offset)}
    if offset == 0.0:
        guide = Translational(("ground", "slider"), axis=("S", "B"), name="guide")
    else:
        guide = Translational(("ground", "slider"), at="B", direction=(1.0, 0.0), name="guide")
    return slider_crank(points, guide, law)


def slider_crank_expected(theta, theta_d, theta_dd, offset: float) -> Expected:
    pin_a, pin_b, rod_angle = slider_crank_reference(theta, theta_d, theta_dd, offset)
    omega = np.max(np.abs(theta_d))
    scales = (CRANK + ROD, CRANK * omega, CRANK * max(omega**2, np.max(np.abs(theta_dd))))
    return Expected(
        bodies={
            "crank": body_motion(fixed(0.0, 0.0), (theta, theta_d, theta_dd)),
            "rod": body_motion(pin_a, rod_angle),
            "slider": body_motion(pin_b, (0.0, 0.0, 0.0)),
        },
        points={"A": pin_a, "B": pin_b},
        scales=scales,
    )


OMEGA = 2.0 * np.pi  # rad/s
HARMONIC = dict(amplitude=1.2, omega=3.0, phase=0.4)  # crank swings ±1.2 rad about CRANK_START


def crank_angle(law: str, times: np.ndarray):
    """theta, theta', theta'' of the crank laws below, written out by hand."""
    if law == "linear":
        return CRANK_START + OMEGA * times, OMEGA + 0.0 * times, 0.0 * times
    amplitude, omega, phase = HARMONIC["amplitude"], HARMONIC["omega"], HARMONIC["phase"]
    angle = omega * times + phase
    return (
        CRANK_START + amplitude * np.sin(angle),
        amplitude * omega * np.cos(angle),
        -amplitude * omega**2 * np.sin(angle),
    )


CRANK_LAWS = {"linear": Linear(rate=OMEGA), "harmonic": Harmonic(**HARMONIC)}


@pytest.mark.parametrize("offset", [0.0, 0.05, -0.08], ids=["centred-axis", "offset-above", "offset-below"])
@pytest.mark.parametrize("law", ["linear", "harmonic"])
def test_slider_crank_matches_closed_form(law, offset):
    # Two crank turns at 2π rad/s (linear) or a 3 rad/s swing whose angular acceleration
    # is never zero for long (harmonic); 6° per step at most.
    times = np.linspace(0.0, 2.0, 241)
    mechanism = build_slider_crank(CRANK_LAWS[law], offset)
    result = solve_kinematics(mechanism, times)
    assert result.complete
    assert_matches(result, mechanism, slider_crank_expected(*crank_angle(law, times), offset))


# ---------------------------------------------------------------------- four-bar
#: Crank, coupler, rocker, ground (m): Grashof crank-rocker, 0.1 + 0.4 < 0.35 + 0.3; the
#: transmission angle stays within [54°, 100°] (or its mirror) over a whole crank turn.
FOUR_BAR = dict(crank=0.1, coupler=0.35, rocker=0.3, ground=0.4)
#: Coupler point P in the coupler frame (x along A→B), m: off the line AB.
COUPLER_POINT = np.array([0.5 * FOUR_BAR["coupler"], 0.12])


def four_bar_angles(theta2, branch: int):
    """Rocker and coupler angles by the half-angle (Freudenstein) closed form.

    Loop ``a e^{i θ2} + b e^{i θ3} = d + c e^{i θ4}`` with O2 at the origin and O4 at
    (d, 0).  Eliminating θ3 gives ``P cos θ4 + Q sin θ4 + R = 0`` with
    P = 2c (d - a cos θ2), Q = -2 a c sin θ2, R = a² + c² + d² - b² - 2 a d cos θ2, so
    ``tan(θ4/2) = (-Q ± sqrt(P² + Q² - R²)) / (R - P)``; `branch` is the sign.
    """
    a, b, c, d = FOUR_BAR["crank"], FOUR_BAR["coupler"], FOUR_BAR["rocker"], FOUR_BAR["ground"]
    p = 2.0 * c * (d - a * np.cos(theta2))
    q = -2.0 * a * c * np.sin(theta2)
    r = a * a + c * c + d * d - b * b - 2.0 * a * d * np.cos(theta2)
    theta4 = 2.0 * np.arctan2(-q + branch * np.sqrt(p * p + q * q - r * r), r - p)
    coupler = d + c * np.exp(1j * theta4) - a * np.exp(1j * theta2)  # b e^{i θ3}
    return np.unwrap(np.angle(coupler)), np.unwrap(theta4)


def four_bar_reference(theta2, omega2, alpha2, branch: int):
    """Angles, rates and angular accelerations of crank (2), coupler (3), rocker (4).

    Differentiating the loop once and twice gives, for (θ3', θ4') and (θ3'', θ4''), the
    same matrix ``M = [[-b sin θ3, c sin θ4], [b cos θ3, -c cos θ4]]``.
    """
    a, b, c = FOUR_BAR["crank"], FOUR_BAR["coupler"], FOUR_BAR["rocker"]
    theta3, theta4 = four_bar_angles(theta2, branch)
    s2, c2, s3, c3, s4, c4 = (f(t) for t in (theta2, theta3, theta4) for f in (np.sin, np.cos))
    matrix = np.stack([np.stack([-b * s3, c * s4], -1), np.stack([b * c3, -c * c4], -1)], -2)
    rates = np.linalg.solve(matrix, stacked(a * s2 * omega2, -a * c2 * omega2)[..., None])[..., 0]
    omega3, omega4 = rates.T
    rhs = stacked(
        a * s2 * alpha2 + a * c2 * omega2**2 + b * c3 * omega3**2 - c * c4 * omega4**2,
        -a * c2 * alpha2 + a * s2 * omega2**2 + b * s3 * omega3**2 - c * s4 * omega4**2,
    )
    alpha3, alpha4 = np.linalg.solve(matrix, rhs[..., None])[..., 0].T
    return (theta2, theta3, theta4), (omega2, omega3, omega4), (alpha2, alpha3, alpha4)


def four_bar_points(angles, rates, accelerations):
    """Crank pin A, rocker pin B and coupler point P, each (position, velocity, acceleration)."""
    a, c, d = FOUR_BAR["crank"], FOUR_BAR["rocker"], FOUR_BAR["ground"]
    theta2, theta3, theta4 = angles
    omega2, omega3, omega4 = rates
    alpha2, alpha3, alpha4 = accelerations

    def on_circle(centre, radius, angle, rate, acceleration):
        u = stacked(np.cos(angle), np.sin(angle))
        return (
            np.asarray(centre) + radius * u,
            radius * rate[:, None] * perpendicular(u),
            radius * (acceleration[:, None] * perpendicular(u) - rate[:, None] ** 2 * u),
        )

    pin_a = on_circle((0.0, 0.0), a, theta2, omega2, alpha2)
    pin_b = on_circle((d, 0.0), c, theta4, omega4, alpha4)
    arm = rotate(np.broadcast_to(COUPLER_POINT, (theta3.size, 2)), theta3)  # A→P, global
    point_p = (
        pin_a[0] + arm,
        pin_a[1] + omega3[:, None] * perpendicular(arm),
        pin_a[2] + alpha3[:, None] * perpendicular(arm) - omega3[:, None] ** 2 * arm,
    )
    return pin_a, pin_b, point_p


def build_four_bar(branch: int, theta2_start: float, rate: float) -> Mechanism:
    start, still = np.array([theta2_start]), np.zeros(1)
    angles, _, _ = four_bar_reference(start, still, still, branch)
    (a, _, _), (b, _, _), (p, _, _) = four_bar_points(angles, (still,) * 3, (still,) * 3)
    points = {"O2": (0.0, 0.0), "O4": (FOUR_BAR["ground"], 0.0), "A": tuple(a[0]), "B": tuple(b[0]), "P": tuple(p[0])}
    angles = dict(zip(("crank", "coupler", "rocker"), (float(angle[0]) for angle in angles)))  # unwrapped
    return four_bar(points, Linear(rate=rate), coupler_points=("A", "B", "P"), angles=angles)


def test_four_bar_reference_closes_the_loop():
    # The reference itself: |AB| = coupler length on both branches, to rounding.
    theta2 = np.linspace(0.0, 2.0 * np.pi, 73)
    for branch in (1, -1):
        angles, _, _ = four_bar_reference(theta2, np.ones_like(theta2), np.zeros_like(theta2), branch)
        rates, accelerations = (np.ones_like(theta2),) * 3, (np.zeros_like(theta2),) * 3
        (a, _, _), (b, _, _), _ = four_bar_points(angles, rates, accelerations)
        np.testing.assert_allclose(np.hypot(*(b - a).T), FOUR_BAR["coupler"], rtol=1e-14)


@pytest.mark.parametrize("branch", [1, -1], ids=["branch-plus", "branch-minus"])
def test_four_bar_matches_freudenstein(branch):
    # One whole crank turn (a crank-rocker has no dead point on the crank's side), 2° per step.
    theta2_start, rate = 0.4, 2.0 * np.pi
    times = np.linspace(0.0, 1.0, 181)
    mechanism = build_four_bar(branch, theta2_start, rate)
    result = solve_kinematics(mechanism, times)
    theta2 = theta2_start + rate * times
    motion = four_bar_reference(theta2, np.full_like(times, rate), np.zeros_like(times), branch)
    pin_a, pin_b, point_p = four_bar_points(*motion)
    crank, coupler, rocker = (tuple(m[link] for m in motion) for link in range(3))
    a = FOUR_BAR["crank"]
    expected = Expected(
        bodies={
            "crank": body_motion(fixed(0.0, 0.0), crank),
            "coupler": body_motion(pin_a, coupler),
            "rocker": body_motion(fixed(FOUR_BAR["ground"], 0.0), rocker),
        },
        points={"A": pin_a, "B": pin_b, "P": point_p},
        scales=(FOUR_BAR["ground"], a * rate, a * rate**2),
    )
    assert_matches(result, mechanism, expected)


# ---------------------------------------------------------------------- translational drivers
CYLINDER = dict(pivot_distance=0.5, rocker_arm=0.25, rocker_start=np.radians(100.0))
#: Stroke s(t) = s0 + 0.1 t - 0.05 t² + 0.01 t³ (m): s' > 0 throughout, s grows by 0.08 m
#: over 2 s, keeping the rocker angle within about [60°, 100°].
STROKE = (None, 0.1, -0.05, 0.01)


def cylinder_reference(stroke, stroke_d, stroke_dd):
    """Rocker angle beta and cylinder angle alpha of a cylinder driving a rocker.

    Cylinder pivot C at the origin, rocker pivot O at (d, 0), rod end R = O + ρ (cos β,
    sin β), stroke s = |CR|.  Law of cosines ``s² = d² + ρ² + 2 d ρ cos β``; differentiating,

        β'  = -s s' / (d ρ sin β)
        β'' = -(s'² + s s'' + d ρ cos β β'²) / (d ρ sin β)

    and ``α = atan2(R_y, R_x)``, ``α' = (R × R') / s²``, ``α'' = ((R × R'') - 2 α' s s') / s²``.
    """
    d, rho = CYLINDER["pivot_distance"], CYLINDER["rocker_arm"]
    beta = np.arccos((stroke**2 - d * d - rho * rho) / (2.0 * d * rho))
    sb, cb = np.sin(beta), np.cos(beta)
    beta_d = -stroke * stroke_d / (d * rho * sb)
    beta_dd = -(stroke_d**2 + stroke * stroke_dd + d * rho * cb * beta_d**2) / (d * rho * sb)
    u = stacked(cb, sb)
    end = np.array([d, 0.0]) + rho * u
    end_d = rho * beta_d[:, None] * perpendicular(u)
    end_dd = rho * (beta_dd[:, None] * perpendicular(u) - beta_d[:, None] ** 2 * u)

    def cross(p, q):
        return p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0]

    alpha = np.arctan2(end[:, 1], end[:, 0])
    alpha_d = cross(end, end_d) / stroke**2
    alpha_dd = (cross(end, end_dd) - 2.0 * alpha_d * stroke * stroke_d) / stroke**2
    return (beta, beta_d, beta_dd), (alpha, alpha_d, alpha_dd), (end, end_d, end_dd)


def polynomial(coefficients, times):
    """Value, first and second derivative of c0 + c1 t + c2 t² + c3 t³, by hand."""
    c0, c1, c2, c3 = coefficients
    return (
        c0 + c1 * times + c2 * times**2 + c3 * times**3,
        c1 + 2.0 * c2 * times + 3.0 * c3 * times**2,
        2.0 * c2 + 6.0 * c3 * times,
    )


def test_cylinder_driven_rocker_matches_law_of_cosines():
    d, rho, beta0 = CYLINDER["pivot_distance"], CYLINDER["rocker_arm"], CYLINDER["rocker_start"]
    end0 = (d + rho * np.cos(beta0), rho * np.sin(beta0))
    alpha0 = float(np.arctan2(end0[1], end0[0]))
    stroke0 = float(np.hypot(*end0))
    mechanism = Mechanism(
        points={"C": (0.0, 0.0), "O": (d, 0.0), "R": end0},
        bodies=[
            Body("rocker", origin="O", angle=beta0, points=("O", "R")),
            Body("cylinder", origin="C", angle=alpha0, points=("C",)),
            Body("rod", origin="R", angle=alpha0),
        ],
        joints=[
            Revolute(("cylinder", "ground"), at="C"),
            Revolute(("rocker", "ground"), at="O"),
            Revolute(("rod", "rocker"), at="R"),
            Translational(("cylinder", "rod"), axis=("C", "R"), name="actuator"),
        ],
        drivers=[TranslationalDriver("actuator", law=Polynomial(STROKE))],
    )
    times = np.linspace(0.0, 2.0, 101)
    result = solve_kinematics(mechanism, times)
    stroke = polynomial((stroke0, *STROKE[1:]), times)
    beta, alpha, end = cylinder_reference(*stroke)
    rate = np.max(np.abs(beta[1]))
    expected = Expected(
        bodies={
            "rocker": body_motion(fixed(d, 0.0), beta),
            "cylinder": body_motion(fixed(0.0, 0.0), alpha),
            "rod": body_motion(end, alpha),
        },
        points={"R": end},
        scales=(d, rho * rate, rho * max(rate**2, np.max(np.abs(beta[2])))),
    )
    assert_matches(result, mechanism, expected)


@pytest.mark.parametrize("start", [None, 0.05], ids=["stroke-from-drawing", "stroke-offset"])
def test_inclined_slider_follows_stroke(start):
    # A slider on a 30° guide (direction given unnormalised), its frame turned by 0.7 rad
    # so that the guide is not along a body axis.  Stroke = displacement along the guide
    # from the drawn position, so the slider origin is S0 + s(t) u and its angle stays.
    guide_start, direction, body_angle = np.array([0.2, 0.1]), np.array([3.0, np.sqrt(3.0)]), 0.7
    coefficients = (start, 0.3, -0.1, 0.02)
    mechanism = Mechanism(
        points={"S0": tuple(guide_start)},
        bodies=[Body("slider", origin="S0", angle=body_angle, points=("S0",))],
        joints=[Translational(("ground", "slider"), at="S0", direction=tuple(direction), name="guide")],
        drivers=[TranslationalDriver("guide", law=Polynomial(coefficients))],
    )
    times = np.linspace(0.0, 1.5, 31)
    result = solve_kinematics(mechanism, times)
    stroke = polynomial((start or 0.0, *coefficients[1:]), times)
    u = direction / np.linalg.norm(direction)
    motion = tuple(np.outer(s, u) for s in stroke)
    motion = (guide_start + motion[0], motion[1], motion[2])
    expected = Expected(
        bodies={"slider": body_motion(motion, (body_angle, 0.0, 0.0))},
        points={"S0": motion},
        scales=(0.5, 0.3, 0.2),
    )
    assert_matches(result, mechanism, expected)


# ---------------------------------------------------------------------- absolute drivers, rigid joint
PLATE_ORIGIN, PLATE_ANGLE = np.array([0.2, -0.1]), 0.3
ARM_ORIGIN, ARM_ANGLE = np.array([0.6, 0.3]), -0.4
TOOL = np.array([0.9, 0.5])


@pytest.mark.parametrize("order", [("plate", "arm"), ("arm", "plate")], ids=["plate-arm", "arm-plate"])
def test_absolute_drivers_and_rigid_weld(order):
    # x: c0 + 0.5 t - 0.3 t² + 0.05 t³ (c0 from the drawing); y: harmonic about the drawn
    # y; angle: harmonic about 1.0 rad, i.e. not where it is drawn at t = 0.
    mechanism = Mechanism(
        points={"T": tuple(TOOL)},
        bodies=[
            Body("plate", origin=tuple(PLATE_ORIGIN), angle=PLATE_ANGLE),
            Body("arm", origin=tuple(ARM_ORIGIN), angle=ARM_ANGLE, points=("T",)),
        ],
        joints=[Rigid(order)],
        drivers=[
            AbsoluteDriver("plate", "x", law=Polynomial((None, 0.5, -0.3, 0.05))),
            AbsoluteDriver("plate", "y", law=Harmonic(amplitude=0.2, omega=2.5, phase=0.3)),
            AbsoluteDriver("plate", "angle", law=Harmonic(amplitude=0.8, omega=1.7, phase=-0.2, offset=1.0)),
        ],
    )
    times = np.linspace(0.0, 3.0, 121)
    result = solve_kinematics(mechanism, times)

    x = polynomial((PLATE_ORIGIN[0], 0.5, -0.3, 0.05), times)
    wave = 2.5 * times + 0.3
    y = (PLATE_ORIGIN[1] + 0.2 * np.sin(wave), 0.5 * np.cos(wave), -1.25 * np.sin(wave))
    turn = 1.7 * times - 0.2
    angle = (1.0 + 0.8 * np.sin(turn), 1.36 * np.cos(turn), -0.8 * 1.7**2 * np.sin(turn))

    def carried(initial_point):
        """Rigid-body motion of a point of the plate: r + R(θ - θ0) s, and derivatives."""
        arm = rotate(np.broadcast_to(initial_point - PLATE_ORIGIN, (times.size, 2)), angle[0] - PLATE_ANGLE)
        return (
            stacked(x[0], y[0]) + arm,
            stacked(x[1], y[1]) + angle[1][:, None] * perpendicular(arm),
            stacked(x[2], y[2]) + angle[2][:, None] * perpendicular(arm) - angle[1][:, None] ** 2 * arm,
        )

    arm_origin, tool = carried(ARM_ORIGIN), carried(TOOL)
    expected = Expected(
        bodies={
            "plate": body_motion(tuple(stacked(x[k], y[k]) for k in range(3)), angle),
            "arm": body_motion(arm_origin, (angle[0] + ARM_ANGLE - PLATE_ANGLE, angle[1], angle[2])),
        },
        points={"T": tool},
        scales=(1.0, 1.5, 3.0),
    )
    assert_matches(result, mechanism, expected)


# ---------------------------------------------------------------------- spline law
def test_spline_driven_slider_crank_matches_scipy_spline():
    # Samples of a smooth crank angle; the law is the not-a-knot cubic spline through them,
    # so the crank must follow that spline (not the sampled function) exactly, and the
    # slider the slider-crank closed form evaluated with the spline's θ, θ', θ''.
    sample_times = np.linspace(0.0, 2.0, 21)
    samples = CRANK_START + 0.8 * np.sin(2.0 * sample_times) + 0.3 * sample_times**2
    offset = 0.05
    mechanism = build_slider_crank(Spline(tuple(sample_times), tuple(samples)), offset)
    # the sample times and the midpoints between them
    times = np.sort(np.concatenate([sample_times, 0.5 * (sample_times[1:] + sample_times[:-1])]))
    result = solve_kinematics(mechanism, times)
    curve = CubicSpline(sample_times, samples, bc_type="not-a-knot")
    theta = (curve(times), curve(times, 1), curve(times, 2))
    k = mechanism.body_index("crank")
    np.testing.assert_allclose(result.coordinates[::2, 3 * k + 2], samples, rtol=RTOL, atol=RTOL)
    # |θ'| and |θ''| of this spline stay below 4 rad/s and 4 rad/s²: atol = RTOL × 10.
    for order, solved in enumerate((result.coordinates, result.velocities, result.accelerations)):
        np.testing.assert_allclose(solved[:, 3 * k + 2], theta[order], rtol=RTOL, atol=RTOL * 10.0)
    assert_matches(result, mechanism, slider_crank_expected(*theta, offset))


def test_a_spline_from_the_drawing_adds_the_drawn_value_to_its_samples(tmp_path):
    # offset = "initial": the samples are displacements from the drawn crank angle
    # (CRANK_START), so the crank follows CRANK_START + the spline through them, and the
    # model file keeps that choice.
    sample_times = np.linspace(0.0, 2.0, 21)
    displacements = 0.8 * np.sin(2.0 * sample_times) + 0.3 * sample_times**2
    law = Spline(tuple(sample_times), tuple(displacements), offset=None)
    mechanism = build_slider_crank(law, 0.05)
    times = np.linspace(0.0, 2.0, 41)
    curve = CubicSpline(sample_times, displacements, bc_type="not-a-knot")
    theta = (CRANK_START + curve(times), curve(times, 1), curve(times, 2))
    k = mechanism.body_index("crank")
    saved = tmp_path / "spline.toml"
    save_model(mechanism, saved)
    assert 'offset = "initial"' in saved.read_text()
    for model in (mechanism, load_model(saved)):
        result = solve_kinematics(model, times)
        for order, solved in enumerate((result.coordinates, result.velocities, result.accelerations)):
            np.testing.assert_allclose(solved[:, 3 * k + 2], theta[order], rtol=RTOL, atol=RTOL * 10.0)
    assert law.evaluate(0.0, initial=0.7)[0] == pytest.approx(0.7, abs=1e-15)
    assert Spline((0.0, 1.0), (2.0, 3.0), offset=0.5).evaluate(1.0, initial=9.0)[0] == pytest.approx(3.5, abs=1e-15)


# ---------------------------------------------------------------------- time derivatives
DERIVATIVE_CASES = {
    "slider-crank": lambda: build_slider_crank(CRANK_LAWS["harmonic"], 0.05),
    "four-bar": lambda: build_four_bar(1, 0.4, 2.0 * np.pi),
}


@pytest.mark.parametrize("name", list(DERIVATIVE_CASES))
def test_velocities_and_accelerations_match_central_differences(name):
    # Independent of any closed form: the solver's velocities and accelerations are the
    # time derivatives of its own positions and velocities, on a 1 ms grid.
    mechanism = DERIVATIVE_CASES[name]()
    h = 1e-3
    times = np.arange(0.0, 1.0 + h / 2, h)
    result = solve_kinematics(mechanism, times)
    for lower, higher, label in (
        (result.coordinates, result.velocities, "velocities"),
        (result.velocities, result.accelerations, "accelerations"),
    ):
        differences = (lower[2:] - lower[:-2]) / (2.0 * h)
        # Truncation error of a central difference is h²/6 |f'''|; bound f''' by
        # differencing the next derivative twice more (the data are smooth on this grid),
        # with a factor 2 for that estimate, plus 1e-8 for the rounding of the positions
        # (≤ 1e-12 m) divided by 2h.
        third = np.gradient(np.gradient(higher, h, axis=0), h, axis=0)
        atol = 2.0 * h * h / 6.0 * np.max(np.abs(third), axis=0) + 1e-8
        np.testing.assert_array_less(
            np.abs(differences - higher[1:-1]), np.broadcast_to(atol, differences.shape), err_msg=label
        )
