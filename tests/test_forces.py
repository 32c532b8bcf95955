"""Forces that hold the motion, against independent references.

* energy: the drivers' power plus the loads' power is the rate of change of kinetic plus
  gravitational energy, the energies computed here from the solved positions and
  velocities and differentiated by five-point differences;
* closed forms: a slider-crank at constant crank speed solved by hand as a textbook does
  (Newton–Euler for each body, one 8 × 8 linear system, with the motion in closed form),
  a lever held by a cylinder (moments about its pivot), a pendulum crank;
* virtual work: the quasi-static crank torque of a four-bar under gravity equals the
  derivative of its potential energy along the motion (differences of the kinematics);
* Newton's third law and each body's own balance (free-body diagrams) from the reactions;
* the minimum-norm reactions of a redundant model against numpy's least squares;
* the paths (compiled loop, refactorization, SuperLU, dense, a repeated unit) agree.
"""

from __future__ import annotations

import math

import helpers
import numpy as np
import pytest

import sparsekin as sk
from sparsekin.engine.discretization import Discretization
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.pattern import build_pattern

G = 9.81


# ---------------------------------------------------------------------- helpers
def com_motion(result, mechanism):
    """Position, velocity, acceleration of every body's centre of mass, each (n_times, n_bodies, 2),
    and the angular velocities and accelerations (n_times, n_bodies), from the coordinates."""
    q = result.coordinates.reshape(result.n_times, -1, 3)
    qd = result.velocities.reshape(result.n_times, -1, 3)
    qdd = result.accelerations.reshape(result.n_times, -1, 3)
    local = []
    for body in mechanism.bodies:
        origin = np.array(mechanism.position(body.origin))
        com = origin if body.com is None else np.array(mechanism.position(body.com))
        c, s = math.cos(body.angle), math.sin(body.angle)
        d = com - origin
        local.append((c * d[0] + s * d[1], -s * d[0] + c * d[1]))
    local = np.array(local)
    angle, omega, alpha = q[..., 2], qd[..., 2], qdd[..., 2]
    arm = np.stack([np.cos(angle) * local[:, 0] - np.sin(angle) * local[:, 1],
                    np.sin(angle) * local[:, 0] + np.cos(angle) * local[:, 1]], axis=-1)  # fmt: skip
    across = np.stack([-arm[..., 1], arm[..., 0]], axis=-1)
    position = q[..., :2] + arm
    velocity = qd[..., :2] + omega[..., None] * across
    acceleration = qdd[..., :2] + alpha[..., None] * across - omega[..., None] ** 2 * arm
    return position, velocity, acceleration, omega, alpha


def masses_of(mechanism):
    return (np.array([body.mass or 0.0 for body in mechanism.bodies]),
            np.array([body.inertia or 0.0 for body in mechanism.bodies]))  # fmt: skip


def five_point_derivative(values, h):
    """d/dt at the interior samples 2 … n-3 of uniformly sampled values."""
    return (values[:-4] - 8 * values[1:-3] + 8 * values[3:-1] - values[4:]) / (12 * h)


def slider_crank(r=0.1, l=0.4, masses=(2.0, 3.0, 1.5), omega=12.0, gravity=(0.0, -G)):
    m2, m3, m4 = masses
    points = {"O": (0.0, 0.0), "A": (r, 0.0), "B": (r + l, 0.0), "C2": (r / 2, 0.0), "C3": (r + l / 2, 0.0)}
    bodies = {"crank": {"mass": m2, "inertia": m2 * r * r / 12, "com": "C2"},
              "rod": {"mass": m3, "inertia": m3 * l * l / 12, "com": "C3"}, "slider": {"mass": m4}}  # fmt: skip
    guide = sk.Translational(("ground", "slider"), axis=("O", "B"), name="guide")
    return helpers.slider_crank(points, guide, sk.Linear(rate=omega), masses=bodies, gravity=gravity)


def four_bar(with_motor=True, rate=1.0):
    """Crank O2–A, coupler A–B, rocker O4–B; centres of mass off the links' axes."""
    points = {"O2": (0.0, 0.0), "O4": (1.0, 0.0), "A": (0.0, 0.4), "B": (0.9, 0.75),
              "C2": (0.05, 0.2), "C3": (0.45, 0.65), "C4": (0.9, 0.35)}  # fmt: skip
    bodies = {"crank": {"mass": 1.2, "inertia": 0.02, "com": "C2"}, "coupler": {"mass": 3.0, "inertia": 0.3, "com": "C3"},
              "rocker": {"mass": 2.0, "inertia": 0.1, "com": "C4"}}  # fmt: skip
    law = sk.Linear(rate=rate) if with_motor else None
    return helpers.four_bar(points, law, masses=bodies, gravity=(0.0, -G))


def task5_loaded():
    """examples/task5_dynamics.toml with a spring-damper and a time-varying force added."""
    from pathlib import Path

    base = sk.load_model(Path(__file__).resolve().parents[1] / "examples" / "task5_dynamics.toml")
    loads = (
        *base.loads,
        sk.Spring(("c4", "ground"), points=("D", (-0.5, -0.2)), stiffness=2.0e4, free_length=0.6, damping=50.0,
                  name="spring"),
        sk.Force("c2", at="F", value=(sk.Harmonic(amplitude=150.0, omega=3.0), -80.0), name="push"),
        sk.Torque("c3", value=sk.Harmonic(amplitude=40.0, omega=2.0, phase=0.3), name="twist"),
    )  # fmt: skip
    from dataclasses import replace

    return replace(base, loads=loads)


# ---------------------------------------------------------------------- energy
def test_energy_balance_on_task5_with_gravity_force_torque_and_spring():
    mechanism = task5_loaded()
    h = 1e-3
    times = np.arange(0.0, 4.0 + h / 2, h)
    result = sk.solve_kinematics(mechanism, times)
    mass, inertia = masses_of(mechanism)
    position, velocity, _, omega, _ = com_motion(result, mechanism)
    kinetic = 0.5 * (mass * np.sum(velocity**2, axis=-1)).sum(axis=1) + 0.5 * (inertia * omega**2).sum(axis=1)
    potential = -(mass * (position @ np.array(mechanism.gravity))).sum(axis=1)
    energy_rate = five_point_derivative(kinetic + potential, h)

    drivers = sum(result.driver_force(name).power for name in ("cylinder1", "cylinder2"))
    # the loads' power, from the motion of the points they act on
    k_motion = result.point("K")
    pushed = result.point("F")
    push = np.stack([150.0 * np.sin(3.0 * times), np.full_like(times, -80.0)], axis=1)
    twist = 40.0 * np.sin(2.0 * times + 0.3)
    c3 = mechanism.body_index("c3")
    d = result.point("D")
    anchor = np.array([-0.5, -0.2])
    length = np.hypot(*(d.position - anchor).T)
    length_rate = np.einsum("ij,ij->i", (d.position - anchor) / length[:, None], d.velocity)
    tension = 2.0e4 * (length - 0.6) + 50.0 * length_rate
    loads = (k_motion.velocity @ np.array([0.0, -200.0]) + np.einsum("ij,ij->i", push, pushed.velocity)
             + twist * result.velocities[:, 3 * c3 + 2] - tension * length_rate)  # fmt: skip
    balance = (drivers + loads)[2:-2] - energy_rate
    peak = np.abs(drivers).max()
    assert peak > 100.0  # the actuators do work
    assert np.abs(balance).max() <= 1e-6 * peak


# ---------------------------------------------------------------------- closed forms
def slider_crank_by_hand(t, r, l, masses, omega):
    """Driver torque and pin forces of a slider-crank at constant crank speed, as a textbook
    solves it: the motion in closed form, then Newton–Euler for the three bodies."""
    m2, m3, m4 = masses

    def geometry(theta):
        a = r * np.array([np.cos(theta), np.sin(theta)])
        b = np.array([r * np.cos(theta) + np.sqrt(l * l - (r * np.sin(theta)) ** 2), 0.0])
        return a, b

    def second_derivative(f, theta, h=1e-3):  # d²f/dθ², five points
        return (-f(theta - 2 * h) + 16 * f(theta - h) - 30 * f(theta) + 16 * f(theta + h) - f(theta + 2 * h)) / (12 * h * h)

    theta = omega * t
    a, b = geometry(theta)
    com3 = lambda th: 0.5 * sum(geometry(th))  # noqa: E731
    rod_angle = lambda th: np.arctan2(*(geometry(th)[1] - geometry(th)[0])[::-1])  # noqa: E731
    a2 = -omega**2 * 0.5 * a  # the crank's centre turns at constant speed
    a3 = omega**2 * second_derivative(com3, theta)
    alpha3 = omega**2 * second_derivative(rod_angle, theta)
    a4 = omega**2 * second_derivative(lambda th: geometry(th)[1], theta)
    i3 = m3 * l * l / 12
    c2, c3 = 0.5 * a, 0.5 * (a + b)
    # unknowns: O (on crank from ground), A (on rod from crank), B (on slider from rod), N, torque
    rows, rhs = [], []
    # crank: O - A + m g = m a; moments about its centre: (O - c2) × O + (a - c2) × (-A) + τ = 0 (I α = 0)
    rows += [[1, 0, -1, 0, 0, 0, 0, 0], [0, 1, 0, -1, 0, 0, 0, 0]]
    rhs += [m2 * a2[0], m2 * a2[1] + m2 * G]
    o_arm, a_arm = -c2, a - c2
    rows.append([-o_arm[1], o_arm[0], a_arm[1], -a_arm[0], 0, 0, 0, 1])
    rhs.append(0.0)
    # rod: A - B + m g = m a; moments about its centre
    rows += [[0, 0, 1, 0, -1, 0, 0, 0], [0, 0, 0, 1, 0, -1, 0, 0]]
    rhs += [m3 * a3[0], m3 * a3[1] + m3 * G]
    a_arm, b_arm = a - c3, b - c3
    rows.append([0, 0, -a_arm[1], a_arm[0], b_arm[1], -b_arm[0], 0, 0])
    rhs.append(i3 * alpha3)
    # slider: B + (0, N) + m g = m a
    rows += [[0, 0, 0, 0, 1, 0, 0, 0], [0, 0, 0, 0, 0, 1, 1, 0]]
    rhs += [m4 * a4[0], m4 * a4[1] + m4 * G]
    solution = np.linalg.solve(np.array(rows, dtype=float), np.array(rhs))
    return {"O": solution[0:2], "A": -solution[2:4], "B": -solution[4:6], "N": solution[6], "torque": solution[7],
            "slider x": b[0]}  # fmt: skip


@pytest.mark.parametrize("linear_solver", ["auto", "refactor"])
def test_slider_crank_against_newton_euler_by_hand(linear_solver):
    r, l, masses, omega = 0.1, 0.4, (2.0, 3.0, 1.5), 12.0
    mechanism = slider_crank(r, l, masses, omega)
    times = np.linspace(0.0, 2 * math.pi / omega, 37)
    result = sk.solve_kinematics(mechanism, times, linear_solver=linear_solver)
    torque = result.driver_force("motor").force
    scale = 10.0  # N: forces here are tens of newtons
    for k, t in enumerate(times):
        expected = slider_crank_by_hand(t, r, l, masses, omega)
        assert torque[k] == pytest.approx(expected["torque"], abs=1e-8 * scale)
        for joint in ("O", "A", "B"):
            np.testing.assert_allclose(result.reaction(joint).force[k], expected[joint], rtol=0, atol=1e-8 * scale)
        guide = result.reaction("guide")  # on the ground from the slider: (0, -N), through B
        np.testing.assert_allclose(guide.force[k], [0.0, -expected["N"]], rtol=0, atol=1e-8 * scale)
        assert guide.torque[k] == pytest.approx(-expected["slider x"] * expected["N"], abs=1e-8 * scale)
    power = result.driver_force("motor").power
    np.testing.assert_allclose(power, torque * omega, rtol=1e-14, atol=0)


def test_lever_held_by_a_cylinder_balances_moments_about_its_pivot():
    theta, mass, g = 0.3, 10.0, G
    along = np.array([math.cos(theta), math.sin(theta)])
    q, c, p = 0.5 * along, 0.6 * along, np.array([0.2, -0.5])
    mechanism = sk.Mechanism(
        points={"O": (0.0, 0.0), "R": tuple(q), "C": tuple(c), "E": tuple(along), "P": tuple(p)},
        bodies=[sk.Body("lever", origin="O", points=("O", "R", "E"), mass=mass, inertia=0.5, com="C")],
        joints=[sk.Revolute(("lever", "ground"), at="O", name="pivot")],
        drivers=[sk.DistanceDriver(points=("P", "R"), bodies=("ground", "lever"), law=sk.Linear(rate=0.0),
                                   name="cylinder")],  # fmt: skip
        gravity=(0.0, -g),
    )
    result = sk.solve_kinematics(mechanism, [0.0, 1.0])
    u = (q - p) / np.hypot(*(q - p))
    force = mass * g * c[0] / (q[0] * u[1] - q[1] * u[0])  # F (R × u) = m g C_x
    np.testing.assert_allclose(result.driver_force("cylinder").force, force, rtol=1e-12)
    np.testing.assert_allclose(result.driver_force("cylinder").power, 0.0, atol=1e-12)
    pivot = -(force * u + np.array([0.0, -mass * g]))  # the rest of the balance
    np.testing.assert_allclose(result.reaction("pivot").force, [pivot, pivot], rtol=1e-12)
    assert result.reaction("pivot").torque is None


def test_pendulum_crank_torque_and_pivot_force():
    m, c, w = 2.0, 0.3, 1.7
    mechanism = sk.Mechanism(
        points={"O": (0.0, 0.0), "A": (0.5, 0.0), "C": (c, 0.0)},
        bodies=[sk.Body("crank", origin="O", points=("O", "A"), mass=m, inertia=0.1, com="C")],
        joints=[sk.Revolute(("crank", "ground"), at="O", name="pivot")],
        drivers=[sk.RotationalDriver(("crank", "ground"), law=sk.Linear(rate=w), name="motor")],
        gravity=(0.0, -G),
    )
    times = np.linspace(0.0, 4.0, 81)
    angle = w * times
    centripetal = -m * w**2 * c * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    for quasi_static in (False, True):
        result = sk.solve_kinematics(mechanism, times, quasi_static=quasi_static)
        np.testing.assert_allclose(result.driver_force("motor").force, m * G * c * np.cos(angle), rtol=0, atol=1e-12)
        expected = (0.0 * centripetal if quasi_static else centripetal) - np.array([0.0, -m * G])
        np.testing.assert_allclose(result.reaction("pivot").force, expected, rtol=0, atol=1e-12)
        assert result.quasi_static is quasi_static


# ---------------------------------------------------------------------- virtual work
def test_quasi_static_four_bar_torque_is_the_derivative_of_potential_energy(rng):
    mechanism = four_bar()
    mass, _ = masses_of(mechanism)
    h = 1e-5
    for start in rng.uniform(0.0, 3.0, size=6):  # crank angles past the drawn one, rad (rate 1 rad/s)
        times = np.array([0.0, start - h, start, start + h])
        result = sk.solve_kinematics(mechanism, times, quasi_static=True)
        position = com_motion(result, mechanism)[0]
        height_rate = (position[3, :, 1] - position[1, :, 1]) / (2 * h)  # ∂y_com/∂θ
        torque = result.driver_force("motor").force[2]
        expected = float(np.sum(mass * G * height_rate))  # τ = dV/dθ, V = Σ m g y
        assert torque == pytest.approx(expected, rel=1e-7, abs=1e-9)


# ---------------------------------------------------------------------- Newton's third law, free bodies
def test_reversing_a_joint_reverses_its_reaction():
    mechanism = four_bar(rate=2.0)
    times = np.linspace(0.0, 2.0, 21)
    forward = sk.solve_kinematics(mechanism, times)
    joints = [sk.Revolute(tuple(reversed(joint.bodies)), at=joint.at, name=joint.name) for joint in mechanism.joints]
    from dataclasses import replace

    backward = sk.solve_kinematics(replace(mechanism, joints=tuple(joints)), times)
    for name in ("O2", "A", "B", "O4"):
        np.testing.assert_allclose(backward.reaction(name).force, -forward.reaction(name).force, rtol=0, atol=1e-10)


def test_every_body_of_a_four_bar_balances_its_forces_and_moments():
    mechanism = four_bar(rate=3.0)
    times = np.linspace(0.0, 2.0, 41)
    result = sk.solve_kinematics(mechanism, times)
    mass, inertia = masses_of(mechanism)
    com, _, acceleration, _, alpha = com_motion(result, mechanism)
    gravity = np.array(mechanism.gravity)
    # (joint, body it acts on, sign): the reaction is on bodies[0] from bodies[1]
    acting = {"crank": [("O2", 1.0), ("A", 1.0)], "coupler": [("A", -1.0), ("B", 1.0)], "rocker": [("B", -1.0), ("O4", 1.0)]}
    torque = result.driver_force("motor").force
    for b, body in enumerate(mechanism.bodies):
        force = mass[b] * gravity + np.zeros((times.size, 2))
        moment = np.zeros(times.size)
        for joint, sign in acting[body.name]:
            f = sign * result.reaction(joint).force
            arm = result.point(mechanism.joints[mechanism.index_of("joints", joint)].at).position - com[:, b]
            force = force + f
            moment += arm[:, 0] * f[:, 1] - arm[:, 1] * f[:, 0]
        if body.name == "crank":
            moment += torque
        np.testing.assert_allclose(force, mass[b] * acceleration[:, b], rtol=0, atol=1e-9)
        np.testing.assert_allclose(moment, inertia[b] * alpha[:, b], rtol=0, atol=1e-9)


# ---------------------------------------------------------------------- redundant sets
def test_redundant_parallelogram_gives_the_minimum_norm_reactions():
    """Three equal parallel cranks carry a coupler: one crank is redundant.  The reactions
    are those of the least-squares (minimum-norm) multipliers, computed here with numpy."""
    points = {f"O{k}": (float(k), 0.0) for k in range(3)} | {f"A{k}": (float(k), 1.0) for k in range(3)}
    points["C"] = (0.7, 1.1)
    mechanism = sk.Mechanism(
        points=points,
        bodies=[sk.Body(f"crank{k}", origin=f"O{k}", points=(f"O{k}", f"A{k}"), mass=1.0 + k, inertia=0.1)
                for k in range(3)] + [sk.Body("coupler", origin="A0", points=("A0", "A1", "A2"), mass=5.0, inertia=2.0,
                                              com="C")],  # fmt: skip
        joints=[sk.Revolute((f"crank{k}", "ground"), at=f"O{k}", name=f"O{k}") for k in range(3)]
        + [sk.Revolute((f"crank{k}", "coupler"), at=f"A{k}", name=f"A{k}") for k in range(3)],
        drivers=[sk.RotationalDriver(("crank0", "ground"), law=sk.Linear(rate=1.5), name="motor")],
        gravity=(0.0, -G),
    )
    times = np.linspace(0.0, 1.0, 11)
    with pytest.warns(sk.RedundantConstraintWarning, match="minimum-norm"):
        result = sk.solve_kinematics(mechanism, times)
    # the reference: b = Q - M qdd - h from the motion, then numpy's minimum-norm solution
    pattern = build_pattern(mechanism)
    assembler = Assembler(Discretization(mechanism, pattern))
    mass, inertia = masses_of(mechanism)
    com, _, acceleration, _, alpha = com_motion(result, mechanism)
    for k, t in enumerate(times):
        assembler.set_time(t)
        assembler.fill_residual_jacobian(result.coordinates[k])
        jacobian = assembler.jacobian.toarray()
        b = np.zeros(pattern.n_coordinates)  # gravity minus inertia, on each body frame
        origins = result.coordinates[k].reshape(-1, 3)[:, :2]
        for body in range(len(mechanism.bodies)):
            force = mass[body] * (np.array(mechanism.gravity) - acceleration[k, body])
            arm = com[k, body] - origins[body]
            b[3 * body : 3 * body + 2] = force
            b[3 * body + 2] = arm[0] * force[1] - arm[1] * force[0] - inertia[body] * alpha[k, body]
        multipliers = np.linalg.lstsq(jacobian.T, b, rcond=None)[0]  # minimum norm
        for j, name in enumerate(["O0", "O1", "O2", "A0", "A1", "A2"]):  # on bodies[0] = crank: -λ of its rows
            np.testing.assert_allclose(result.reaction(name).force[k], -multipliers[2 * j : 2 * j + 2], atol=1e-9)
        assert result.driver_force("motor").force[k] == pytest.approx(-multipliers[-1], abs=1e-9)


# ---------------------------------------------------------------------- paths and units
def test_every_linear_solver_path_gives_the_same_forces():
    mechanism = task5_loaded()
    times = np.linspace(0.0, 2.0, 201)
    results = {path: sk.solve_kinematics(mechanism, times, linear_solver=path)
               for path in ("auto", "dense", "refactor", "superlu")}  # fmt: skip
    assert results["auto"].linear_solver == "compiled"
    reference = results["superlu"].force_tracks
    scale = np.abs(reference).max()
    for path, result in results.items():
        assert result.force_labels == results["superlu"].force_labels
        np.testing.assert_allclose(result.force_tracks, reference, rtol=0, atol=1e-9 * scale, err_msg=path)


def test_a_repeated_unit_gives_the_forces_of_the_chain_written_out():
    from sparsekin import testset

    chain = testset.task5_chain(3)
    unit = chain.repeats[0].unit
    bodies = tuple(
        sk.Body(body.name, origin=body.origin, angle=body.angle, points=body.points, mass=1.0 + k, inertia=0.1 * k,
                com=body.points[-1])
        for k, body in enumerate(unit.bodies)
    )  # fmt: skip
    from dataclasses import replace

    loaded_unit = replace(unit, bodies=bodies,
                          loads=(sk.Spring((bodies[0].name, "ground"), points=(bodies[0].points[-1], (0.0, -1.0)),
                                           stiffness=500.0, damping=5.0),
                                 sk.Force(bodies[1].name, at=bodies[1].points[0], value=(10.0, sk.Linear(rate=3.0)))))
    repeat = replace(chain.repeats[0], unit=loaded_unit)
    repeated = replace(chain, repeats=(repeat,), gravity=(0.0, -G))
    written = repeated.expanded()
    times = np.linspace(0.0, 0.5, 11)
    a = sk.solve_kinematics(repeated, times, linear_solver="refactor")
    b = sk.solve_kinematics(written, times, linear_solver="refactor")
    assert a.force_labels == b.force_labels and len(a.force_labels) > 40
    np.testing.assert_allclose(a.force_tracks, b.force_tracks, rtol=0, atol=1e-9 * np.abs(b.force_tracks).max())


# ---------------------------------------------------------------------- files, command line, store
EXAMPLE = __import__("pathlib").Path(__file__).resolve().parents[1] / "examples" / "task5_dynamics.toml"


def test_masses_loads_and_gravity_read_back_equal(tmp_path):
    mechanism = task5_loaded()
    sk.save_model(mechanism, tmp_path / "loaded.toml")
    again = sk.load_model(tmp_path / "loaded.toml")
    assert again.gravity == mechanism.gravity and again.bodies == mechanism.bodies
    assert tuple(again.loads) == tuple(mechanism.loads)
    times = np.linspace(0.0, 1.0, 11)
    np.testing.assert_array_equal(sk.solve_kinematics(again, times).force_tracks,
                                  sk.solve_kinematics(mechanism, times).force_tracks)  # fmt: skip


LOAD_MISTAKES = {
    "unknown body": ('type = "force"\nbody = "c11"\nat = "K"\nvalue = [0.0, 1.0]', r'loads\[1\]\.body: unknown body "c11"'),
    "one component": ('type = "force"\nbody = "c1"\nat = "K"\nvalue = [1.0]', r"loads\[1\]\.value: expected \[fx, fy\]"),
    "text value": ('type = "torque"\nbody = "c1"\nvalue = "big"', r"loads\[1\]\.value: expected a number or a law"),
    "bad law": ('type = "torque"\nbody = "c1"\nvalue = { type = "harmonic", omega = 1.0 }',
                r'loads\[1\]\.value: missing key "amplitude"'),
    "spring at one point": ('type = "spring"\nbodies = ["c1", "c2"]\npoints = ["K", "K"]\nstiffness = 1.0',
                            r"loads\[1\]\.points: K and K coincide in the drawing"),
    "negative stiffness": ('type = "spring"\nbodies = ["c1", "c2"]\npoints = ["K", "J"]\nstiffness = -1.0',
                           r"loads\[1\]\.stiffness"),
    "unknown type": ('type = "pressure"\nbody = "c1"', r'loads\[1\]\.type: expected one of "force", "torque", "spring", "rotational_spring", "actuator", got .pressure.'),
}


@pytest.mark.parametrize("case", LOAD_MISTAKES)
def test_a_mistake_in_a_load_names_it(tmp_path, case):
    table, message = LOAD_MISTAKES[case]
    text = EXAMPLE.read_text(encoding="utf-8").replace("[analysis]", f"[[loads]]\n{table}\n\n[analysis]")
    (tmp_path / "model.toml").write_text(text, encoding="utf-8")
    with pytest.raises(sk.ModelError, match=message):
        sk.load_model(tmp_path / "model.toml")


def test_bad_gravity_names_the_key(tmp_path):
    text = EXAMPLE.read_text(encoding="utf-8").replace("gravity = [0.0, -9.81]", 'gravity = "down"')
    (tmp_path / "model.toml").write_text(text, encoding="utf-8")
    with pytest.raises(sk.ModelError, match=r"model\.toml: gravity: expected"):
        sk.load_model(tmp_path / "model.toml")


def test_run_writes_forces_csv_and_check_reports_the_masses(tmp_path, capsys):
    from sparsekin.cli import main

    assert main(["run", str(EXAMPLE), "--t-end", "1", "--steps", "11", "--out", str(tmp_path)]) == 0
    table = np.loadtxt(tmp_path / "forces.csv", delimiter=",", skiprows=1)
    header = (tmp_path / "forces.csv").read_text(encoding="utf-8").splitlines()[0].split(",")
    assert header[:5] == ["t", "cylinder1.force", "cylinder1.power", "cylinder2.force", "cylinder2.power"]
    assert "actuator1.torque" in header and "joints[0].fx" in header
    result = sk.solve_kinematics(sk.load_model(EXAMPLE), np.linspace(0.0, 1.0, 11))
    np.testing.assert_array_equal(table[:, 1:], result.force_tracks)  # full precision, the same run
    capsys.readouterr()
    assert main(["run", str(EXAMPLE), "--t-end", "1", "--steps", "11", "--out", str(tmp_path / "none"),
                 "--forces", "none"]) == 0  # fmt: skip
    assert not (tmp_path / "none" / "forces.csv").exists()
    assert main(["run", str(EXAMPLE), "--t-end", "1", "--steps", "11", "--out", str(tmp_path / "one"),
                 "--forces", "cylinder2", "--quasi-static"]) == 0  # fmt: skip
    header = (tmp_path / "one" / "forces.csv").read_text(encoding="utf-8").splitlines()[0]
    assert header == "t,cylinder2.force,cylinder2.power"
    assert main(["run", str(EXAMPLE), "--t-end", "1", "--forces", "cylinder9", "--out", str(tmp_path)]) == 2
    assert '--forces: no driver or joint is called "cylinder9"' in capsys.readouterr().err
    assert main(["check", str(EXAMPLE)]) == 0
    assert "masses: total 47.9009 kg; every moving body has a mass; 1 load; gravity (0, -9.81) m/s²" in (
        capsys.readouterr().out)


def test_forces_stream_to_the_store_bit_for_bit(tmp_path):
    xarray = pytest.importorskip("xarray", reason='the Zarr tests need "sparsekin[zarr]"')
    mechanism, times = task5_loaded(), np.linspace(0.0, 2.0, 201)
    memory = sk.solve_kinematics(mechanism, times)
    sk.solve_kinematics(mechanism, times, coordinates=False, store=tmp_path / "run.zarr")
    dataset = xarray.open_zarr(tmp_path / "run.zarr")
    np.testing.assert_array_equal(dataset["forces"].values, memory.force_tracks)
    assert list(dataset["force"].values) == list(memory.force_labels)
    assert list(dataset["force_unit"].values[:2]) == ["N", "W"]
    np.testing.assert_array_equal(memory.to_xarray()["forces"].values, memory.force_tracks)


def test_a_model_without_masses_or_loads_computes_no_forces_unless_asked():
    mechanism = slider_crank(masses=(0.0, 0.0, 0.0))
    mechanism = sk.Mechanism(points=mechanism.points, bodies=[sk.Body(b.name, origin=b.origin, points=b.points)
                             for b in mechanism.bodies], joints=mechanism.joints, drivers=mechanism.drivers)  # fmt: skip
    assert not mechanism.has_forces
    result = sk.solve_kinematics(mechanism, [0.0, 0.1])
    assert result.force_tracks is None
    with pytest.raises(KeyError, match=r"the run recorded no forces"):
        result.driver_force("motor")
    asked = sk.solve_kinematics(mechanism, [0.0, 0.1], forces=["motor", "A"])
    assert asked.force_labels == ("motor.force", "motor.power", "A.fx", "A.fy")
    np.testing.assert_array_equal(asked.force_tracks, 0.0)
    with pytest.raises(ValueError, match=r'`forces`: no driver or joint is called "Z"'):
        sk.solve_kinematics(mechanism, [0.0], forces=["Z"])


def test_a_load_given_by_a_spline_is_refused_outside_its_times():
    """A spline is not extrapolated, in a load as in a driver: the analysis is refused."""
    spline = sk.Spline((0.0, 0.5, 1.0), (0.0, 2.0, 1.0))

    def crank(*loads):
        return sk.Mechanism(
            points={"O": (0.0, 0.0), "A": (0.1, 0.0)},
            bodies=[sk.Body("crank", origin="O", points=("O", "A"), mass=1.0, inertia=0.01)],
            joints=[sk.Revolute(("crank", "ground"), at="O")],
            drivers=[sk.RotationalDriver(("crank", "ground"), law=sk.Linear(rate=2.0))],
            loads=loads,
        )

    late = np.linspace(0.0, 2.0, 5)
    expected = (r"^`times` span \[0, 2\] s but the value of load 'torque on crank', a spline, is defined on "
                r"\[0, 1\] s\.$")  # fmt: skip
    with pytest.raises(ValueError, match=expected):
        sk.solve_kinematics(crank(sk.Torque("crank", value=spline)), late)
    with pytest.raises(ValueError, match=r"the value\[1\] of load 'force on crank at A', a spline, is "):
        sk.solve_kinematics(crank(sk.Force("crank", at="A", value=(1.0, spline))), late)
    times = np.linspace(0.0, 1.0, 5)
    result = sk.solve_kinematics(crank(sk.Torque("crank", value=spline)), times)
    # turning steadily about its centre of mass, the crank is held against the load alone
    load = spline.evaluate(times, 0.0)[0]
    np.testing.assert_allclose(result.driver_force(0).force, -load, rtol=0, atol=1e-12)


# ---------------------------------------------------------------------- gears: the reaction on the ground
def planetary(sun="ground", ratio=0.5, inertia=0.02, swapped=False):
    """An arm turning about O carries a planet pivoted at P (its centre of mass) that meshes
    with a sun gear about O: the ground, or a body held still by a driver (``sun="sun"``).
    The gear is ``bodies = [sun, planet]`` (ratio R_planet / R_sun), or with `swapped` the
    same constraint written ``[planet, sun]`` (ratio R_sun / R_planet)."""
    bodies = [sk.Body("arm", origin="O", points=("O", "P"), mass=1.0, inertia=0.1, com="C"),
              sk.Body("planet", origin="P", points=("P",), mass=0.5, inertia=inertia)]  # fmt: skip
    joints = [sk.Revolute(("arm", "ground"), at="O"), sk.Revolute(("planet", "arm"), at="P")]
    drivers = [sk.RotationalDriver(("arm", "ground"), law=sk.Harmonic(amplitude=1.0, omega=3.0), name="motor")]
    if sun != "ground":
        bodies.append(sk.Body(sun, origin="O", points=("O",)))
        joints.append(sk.Revolute((sun, "ground"), at="O"))
        drivers.append(sk.RotationalDriver((sun, "ground"), law=sk.Linear(rate=0.0), name="brake"))
    gear = sk.Gear(("planet", sun), ratio=1.0 / ratio, carrier="arm", name="mesh") if swapped else sk.Gear(
        (sun, "planet"), ratio=ratio, carrier="arm", name="mesh")  # fmt: skip
    return sk.Mechanism(points={"O": (0.0, 0.0), "P": (0.3, 0.0), "C": (0.1, 0.05)}, bodies=bodies,
                        joints=[*joints, gear], drivers=drivers, gravity=(0.0, -G))  # fmt: skip


def test_a_gear_on_the_ground_reports_the_torque_on_the_ground():
    """The planet's moment balance about its centre (its pivot and its centre of mass) gives
    the gear's torque on it, I α; the tooth force acts on the sun at the sun's pitch radius,
    R_sun = R_planet / ratio, so its torque on the sun is I α / ratio.  The ground as the
    sun, a moving sun held by a brake (whose torque balances the gear's), and the same gear
    written the other way round must all say so."""
    ratio, inertia = 0.5, 0.02
    times = np.linspace(0.0, 2.0, 41)
    grounded = sk.solve_kinematics(planetary("ground", ratio, inertia), times)
    planet = grounded.mechanism.body_names.index("planet")
    alpha = grounded.accelerations.reshape(times.size, -1, 3)[:, planet, 2]
    on_planet = inertia * alpha
    assert np.abs(on_planet).max() > 0.1  # N·m: the planet accelerates
    atol = 1e-9
    np.testing.assert_allclose(grounded.reaction("mesh").torque, on_planet / ratio, rtol=0, atol=atol)
    np.testing.assert_allclose(grounded.reaction("mesh").force, 0.0, rtol=0, atol=atol)
    written_back = sk.solve_kinematics(planetary("ground", ratio, inertia, swapped=True), times)
    np.testing.assert_allclose(written_back.reaction("mesh").torque, on_planet, rtol=0, atol=atol)  # on the planet
    held = sk.solve_kinematics(planetary("sun", ratio, inertia), times)
    np.testing.assert_allclose(held.reaction("mesh").torque, on_planet / ratio, rtol=0, atol=atol)
    np.testing.assert_allclose(held.driver_force("brake").force, -on_planet / ratio, rtol=0, atol=atol)


def test_check_counts_an_inertia_as_a_run_does():
    """A body with an inertia and no mass: the run computes forces, and check says so."""
    from sparsekin.analysis.check import check_model

    mechanism = sk.Mechanism(
        points={"O": (0.0, 0.0), "A": (0.5, 0.0)},
        bodies=[sk.Body("crank", origin="O", points=("O", "A"), inertia=0.3)],
        joints=[sk.Revolute(("crank", "ground"), at="O", name="pivot")],
        drivers=[sk.RotationalDriver(("crank", "ground"), law=sk.Polynomial(coefficients=(0.0, 0.0, 1.0)),
                                     name="motor")],  # fmt: skip
    )
    result = sk.solve_kinematics(mechanism, [0.0, 0.5])
    np.testing.assert_allclose(result.driver_force("motor").force, 0.3 * 2.0, rtol=1e-12)  # I α, α = 2 rad/s²
    report = str(check_model(mechanism))
    assert "a run computes no forces" not in report
    assert "masses: total 0 kg; 1 of 1 moving bodies have no mass (crank); 0 loads; no gravity" in report


# ---------------------------------------------------------------------- the command line, edge cases
def test_plot_without_the_coordinates_still_draws_the_forces(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    from sparsekin.cli import main

    assert main(["run", str(EXAMPLE), "--t-end", "1", "--steps", "11", "--no-coordinates", "--plot", "--out",
                 str(tmp_path)]) == 0  # fmt: skip
    assert (tmp_path / "forces.png").stat().st_size > 0 and (tmp_path / "forces.csv").is_file()
    assert not (tmp_path / "mechanism.png").exists()


def test_loads_without_drivers_or_joints_write_the_time_column_alone(tmp_path, capsys):
    from sparsekin.cli import main

    model = tmp_path / "bare.toml"
    model.write_text('name = "bare"\n\n[points]\nP = [0.0, 0.0]\n\n[[loads]]\ntype = "force"\nbody = "ground"\n'
                     'at = "P"\nvalue = [0.0, -1.0]\n', encoding="utf-8")  # fmt: skip
    assert sk.load_model(model).has_forces
    assert main(["run", str(model), "--t-end", "1", "--steps", "3", "--out", str(tmp_path / "out")]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    assert (tmp_path / "out" / "forces.csv").read_text(encoding="utf-8").splitlines() == ["t", "0.0", "0.5", "1.0"]


@pytest.mark.parametrize("model, options, reason", [
    ("task5.toml", [], "the model has no mass or load"),
    ("task5_dynamics.toml", ["--forces", "none"], "--forces none leaves every force out"),
])  # fmt: skip
def test_quasi_static_without_forces_is_refused(tmp_path, capsys, model, options, reason):
    from sparsekin.cli import main

    path = EXAMPLE.parent / model
    status = main(["run", str(path), "--t-end", "1", "--steps", "3", "--quasi-static", *options, "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and err.startswith("sparsekin: error: --quasi-static changes the forces")
    assert reason in err
    assert not (tmp_path / "points.csv").exists()
