"""What several test files build or check the same way: the slider-crank and the four-bar
written out element by element, and the comparison of two motions.

Each mechanism is drawn from its points: every body's frame sits on its first pin and
points along its link, so a test gives the points (from its own closed form) and the law,
and the helper writes the elements.  Their keywords: ``masses``, the keywords of `Body`
(``mass``, ``inertia``, ``com``) by body name; ``angles``, drawn angles by body name, rad
(a body's angle coordinate starts there; default along its link); ``gravity`` and ``name``
of the `Mechanism`.
"""

from __future__ import annotations

import math

import numpy as np

from sparsekin import Body, Mechanism, Revolute, RotationalDriver

#: Agreement with a closed form or another path, relative to each quantity's scale.
RTOL = 1e-10
#: The three arrays of a motion: q, qd, qdd; or a point's position, velocity, acceleration.
MOTION = ("coordinates", "velocities", "accelerations")


def assert_close(actual, expected, rtol: float = RTOL, err_msg: str = "", scale: float | None = None) -> None:
    """Agreement to `rtol` of `scale`, by default the largest magnitude of `expected`
    (quantities cross zero, where a relative tolerance means nothing)."""
    expected = np.asarray(expected, dtype=float)
    scale = float(np.max(np.abs(expected))) if scale is None else scale
    np.testing.assert_allclose(actual, expected, rtol=0.0, atol=rtol * scale, err_msg=err_msg)


def assert_same_motion(actual, expected, rtol: float = RTOL, labels=MOTION, rows: int | None = None) -> None:
    """Each array of `actual` (q, qd, qdd, or a point's position, velocity and
    acceleration) agrees with the one of `expected` to `rtol` of its own scale (over the
    first `rows` samples, if given)."""
    for label, mine, theirs in zip(labels, actual, expected, strict=True):
        assert_close(mine[:rows], theirs[:rows], rtol, err_msg=label)


def link_angle(points: dict, start: str, end: str) -> float:
    """The direction of the link from point `start` to point `end`, rad."""
    (x0, y0), (x1, y1) = points[start], points[end]
    return math.atan2(y1 - y0, x1 - x0)


def _links(points: dict, links: dict, masses: dict | None, angles: dict | None) -> list[Body]:
    """A body by name for each of `links` (name -> the points it carries), on its first two
    points: its drawn angle from `angles`, else along the link; its mass, inertia and
    centre of mass from `masses`, if given."""
    masses, angles = masses or {}, angles or {}
    return [
        Body(name, origin=carried[0], angle=angles.get(name, link_angle(points, *carried[:2])),
             points=carried, **masses.get(name, {}))
        for name, carried in links.items()
    ]  # fmt: skip


def _crank_driven(points: dict, bodies: list, pins, others, law, gravity, name) -> Mechanism:
    """A revolute joint named after its point for each ``(body, body, point)`` of `pins`,
    then the `others`; the crank turned by `law` about the ground (driver ``motor``)."""
    return Mechanism(
        points=points,
        bodies=bodies,
        joints=[*(Revolute((first, second), at=point, name=point) for first, second, point in pins), *others],
        drivers=[] if law is None else [RotationalDriver(("crank", "ground"), law=law, name="motor")],
        gravity=gravity,
        **({} if name is None else {"name": name}),
    )


def slider_crank(points: dict, guide, law, *, masses: dict | None = None, angles: dict | None = None,
                 gravity=(0.0, 0.0), name=None) -> Mechanism:  # fmt: skip
    """Crank O–A turning about the ground pivot O (driver ``motor``), rod A–B, slider at B
    on `guide` (a translational joint between the ground and the slider).

    `points` holds O, A and B (and any others the masses name), m.
    """
    bodies = [*_links(points, {"crank": ("O", "A"), "rod": ("A", "B")}, masses, angles),
              Body("slider", origin="B", points=("B",), **(masses or {}).get("slider", {}))]  # fmt: skip
    pins = [("crank", "ground", "O"), ("crank", "rod", "A"), ("rod", "slider", "B")]
    return _crank_driven(points, bodies, pins, [guide], law, gravity, name)


def four_bar(points: dict, law, *, coupler_points=("A", "B"), masses: dict | None = None,
             angles: dict | None = None, gravity=(0.0, 0.0), name=None) -> Mechanism:  # fmt: skip
    """Crank O2–A, coupler A–B, rocker O4–B, pinned to the ground at O2 and O4; the crank
    follows `law` (driver ``motor``), or nothing moves it if `law` is None.

    `points` holds O2, O4, A, B and the other points of `coupler_points` (those the
    coupler carries, A and B first) and of the masses, m.
    """
    links = {"crank": ("O2", "A"), "coupler": tuple(coupler_points), "rocker": ("O4", "B")}
    pins = [("crank", "ground", "O2"), ("crank", "coupler", "A"), ("coupler", "rocker", "B"),
            ("rocker", "ground", "O4")]
    return _crank_driven(points, _links(points, links, masses, angles), pins, [], law, gravity, name)


def solve_with(mechanism, times, *, thresholds=None, guard=None, chunk_samples=None, store=None, **options):
    """`solve_kinematics` with the thresholds of ``"auto"`` (`sparsekin.solve.policy.Thresholds`),
    the branch guard or the recorder's chunk given as arguments (the layer under the
    facade, `sparsekin.solve.kinematics.run_kinematics`); `options` are those of
    `solve_kinematics` (tolerance, max_iterations, linear_solver, what to record)."""
    from sparsekin.engine.discretization import discretize
    from sparsekin.solve.kinematics import run_kinematics
    from sparsekin.solve.options import BranchGuard, Request, SolveOptions, check_times
    from sparsekin.solve.policy import Thresholds

    how = {key: options.pop(key) for key in ("tolerance", "max_iterations", "linear_solver") if key in options}
    solve_options = SolveOptions(**how, thresholds=thresholds or Thresholds(), guard=guard or BranchGuard())
    request = Request(**options, chunk_samples=chunk_samples)
    return run_kinematics(discretize(mechanism), check_times(times, mechanism), solve_options, request, store=store)


def actuator_round_trip(horizon: float, sampling: float):
    """Task 5 with masses (examples/task5_dynamics.toml) with its drivers replaced by actuators
    pushing with their inverse-dynamics forces (splines through the kinematic run's samples
    every `sampling` s up to `horizon`), from the same initial velocities: ``(the free
    linkage, the kinematic run)``, the prescribed motion that forward dynamics must give back."""
    import dataclasses
    from pathlib import Path

    import sparsekin as sk

    mechanism = sk.load_model(Path(__file__).resolve().parents[1] / "examples" / "task5_dynamics.toml")
    samples = np.arange(0.0, horizon + sampling / 2, sampling)
    kinematic = sk.solve_kinematics(mechanism, samples)
    start = kinematic.velocities[0].reshape(-1, 3)
    actuators = [sk.Actuator(f"actuator{k}", sk.Spline(tuple(samples), tuple(kinematic.driver_force(f"cylinder{k}").force)))
                 for k in (1, 2)]  # fmt: skip
    free = dataclasses.replace(
        mechanism, drivers=[], loads=[*mechanism.loads, *actuators],
        bodies=[dataclasses.replace(body, velocity=tuple(start[k])) for k, body in enumerate(mechanism.bodies)],
    )  # fmt: skip
    return free, kinematic


def assert_same_through_a_crossing(python, compiled, times, tolerance: float, loops: int = 4) -> None:
    """The N-four-bar through its first flat crossing (0.72 s) on the Python stepper and the
    compiled loop: up to it the two agree to the Newton tolerance; the crossing amplifies
    their rounding, so from there both are held to the exact answer (the reduced ODE), the
    loop's B0 no further off it than the Python stepper's, within 5 %; drifts alike."""
    from dynamics_reference import n_four_bar_b0

    before = times < 0.7
    bound = 10.0 * tolerance * float(np.max(np.abs(python.coordinates)))
    np.testing.assert_allclose(compiled.coordinates[before], python.coordinates[before], rtol=0.0, atol=bound)
    np.testing.assert_allclose(compiled.velocities[before], python.velocities[before], rtol=0.0, atol=bound)
    position, velocity = n_four_bar_b0(times, n_loops=loops)
    for name, exact in (("position", position), ("velocity", velocity)):
        errors = [np.abs(getattr(result.point("B0"), name) - exact).max() for result in (python, compiled)]
        assert errors[1] <= 1.05 * errors[0], (name, errors)
    np.testing.assert_allclose(compiled.drift_tracks, python.drift_tracks, rtol=0.0, atol=tolerance * 1e-2)
