"""The compiled time loop (`sparsekin.solve._compiled`) against the Python path and closed forms.

The Python path (`solve_kinematics`: SuperLU, plain Newton) is the reference.  Plain Newton
in the compiled loop (``chord=False``) takes the same iterates up to rounding: results
equal to ~1e-12; its counts follow plain Newton's documented invariant (one factorization
per iterate and at the converged position, one solve per correction and two for the rates).
Chord Newton stops at a different point
below the same tolerance (1e-12 on the weighted residual): positions then differ by up
to the tolerance times the condition number of the Jacobian (about 94 for Task 5), and
velocities and accelerations, solved at those positions, by as much relative to their
scales; so comparisons use ``rtol = 1e-10`` with an ``atol`` of 1e-10 times the scale
(largest magnitude) of the quantity.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import RTOL, assert_same_motion
from scipy.interpolate import CubicSpline

from sparsekin.engine.discretization import Discretization
from sparsekin import (
    AbsoluteDriver,
    Body,
    ConvergenceError,
    Harmonic,
    Linear,
    Mechanism,
    Polynomial,
    Revolute,
    RotationalDriver,
    Spline,
    Torque,
    Translational,
    TranslationalDriver,
    solve_kinematics,
)
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.pattern import build_pattern
from sparsekin.solve._compiled import (
    LoopStatus,
    solve_compiled,
    supports_compiled,
)
from sparsekin.testset import four_bar_chain, lattice, task5, task5_chain



def run_compiled(mechanism, times, *, chord=True, tolerance=1e-12, max_iterations=12):
    """`solve_compiled` with freshly allocated outputs (NaN-filled, to expose gaps)."""
    pattern = build_pattern(mechanism)
    times = np.asarray(times, dtype=float)
    shape = (times.size, pattern.n_coordinates)
    coordinates, velocities, accelerations = (np.full(shape, np.nan) for _ in range(3))
    iterations = np.full(times.size, -1, dtype=np.int64)
    outcome = solve_compiled(
        Discretization(mechanism, pattern), times, tolerance, max_iterations,
        coordinates, velocities, accelerations, iterations, chord=chord,
    )  # fmt: skip
    return outcome, (coordinates, velocities, accelerations), iterations


def python_path(result):
    return result.coordinates, result.velocities, result.accelerations


# ---------------------------------------------------------------------- against the Python path
@pytest.fixture(scope="module")
def task5_runs():
    mechanism = task5()
    times = np.linspace(0.0, 10.0, 2001)
    return mechanism, times, solve_kinematics(mechanism, times, linear_solver="superlu")


def test_task5_chord_agrees_with_python_path(task5_runs):
    mechanism, times, reference = task5_runs
    outcome, solved, iterations = run_compiled(mechanism, times)
    assert (outcome.n_solved, outcome.status, outcome.n_restarts) == (times.size, LoopStatus.SOLVED, 0)
    assert_same_motion(solved, python_path(reference), RTOL, rows=times.size)
    # One factorization per sample (at the converged position) instead of one per Newton
    # iterate; the chord converges linearly, so it needs at least Newton's corrections.
    assert outcome.n_factorizations == times.size + iterations[0]
    assert reference.n_factorizations == times.size + reference.newton_iterations.sum()
    assert np.all(iterations >= reference.newton_iterations)
    assert outcome.n_solves == iterations.sum() + 2 * times.size


def plain_newton_counts(iterations) -> tuple[int, int]:
    """Plain Newton's factorizations and solves over a run without forces: a factorization
    at every iterate, the converged one included, and a solve per correction plus two for
    the velocities and accelerations."""
    return int(iterations.sum()) + iterations.size, int(iterations.sum()) + 2 * iterations.size


def test_task5_plain_newton_agrees_with_python_path(task5_runs):
    mechanism, times, reference = task5_runs
    outcome, solved, iterations = run_compiled(mechanism, times, chord=False)
    assert outcome.complete
    assert_same_motion(solved, python_path(reference), 1e-12, rows=times.size)
    assert (outcome.n_factorizations, outcome.n_solves) == plain_newton_counts(iterations)
    assert (reference.n_factorizations, reference.n_solves) == plain_newton_counts(reference.newton_iterations)
    assert iterations.max() <= 12 and reference.newton_iterations.max() <= 12


FAMILIES = {
    "task5_chain(2)": lambda: task5_chain(2),
    "four_bar_chain(5)": lambda: four_bar_chain(5),
    "lattice(2, 3)": lambda: lattice(2, 3),
}


@pytest.mark.parametrize("name", list(FAMILIES))
def test_test_set_families_agree_with_python_path(name):
    # 2 s: the four-bar chain's cranks turn from π/4 to π/4 + 2, clear of the fold at π.
    mechanism = FAMILIES[name]()
    times = np.linspace(0.0, 2.0, 201)
    reference = solve_kinematics(mechanism, times, linear_solver="superlu")
    for chord in (True, False):
        outcome, solved, iterations = run_compiled(mechanism, times, chord=chord)
        assert outcome.complete, outcome
        assert_same_motion(solved, python_path(reference), RTOL if chord else 1e-12, rows=times.size)
        assert outcome.n_factorizations <= reference.n_factorizations
        if not chord:
            assert (outcome.n_factorizations, outcome.n_solves) == plain_newton_counts(iterations)


# ---------------------------------------------------------------------- laws
SPLINE_TIMES = np.linspace(0.0, 2.0, 9)
SPLINE_VALUES = 0.3 * np.sin(2.0 * SPLINE_TIMES) + 0.1 * SPLINE_TIMES**2
SPLINE_LAWS = {
    "spline": Spline(tuple(SPLINE_TIMES), tuple(SPLINE_VALUES)),
    "spline, 3 samples": Spline((0.0, 0.7, 2.0), (0.2, -0.1, 0.4)),
    "spline, 2 samples": Spline((-1.0, 3.0), (0.5, 0.9)),
}
#: (body, coordinate, law): every kind, with and without an explicit offset or start.
DRIVEN = (
    ("a", "x", Polynomial((None, 0.5, -0.3, 0.05))),
    ("a", "y", Harmonic(amplitude=0.2, omega=2.5, phase=0.3)),
    ("a", "angle", Harmonic(amplitude=0.8, omega=1.7, phase=-0.2, offset=1.0)),
    ("b", "x", Linear(rate=0.4)),
    ("b", "y", Linear(rate=-0.2, start=0.3)),
    ("b", "angle", Polynomial((0.1,))),
    ("c", "x", SPLINE_LAWS["spline"]),
    ("c", "y", SPLINE_LAWS["spline, 3 samples"]),
    ("c", "angle", SPLINE_LAWS["spline, 2 samples"]),
    ("d", "x", Polynomial((0.7, 1.0))),
    ("d", "y", Polynomial((None, 0.0, 0.25))),
    ("d", "angle", Linear(rate=1.5, start=-0.5)),
)
FRAMES = {"a": (0.2, -0.1, 0.3), "b": (0.6, 0.3, -0.4), "c": (-0.5, 0.4, 0.0), "d": (0.1, 0.9, 1.2)}


def driven_bodies() -> Mechanism:
    """Four free bodies, each coordinate driven absolutely: q(t) is the laws' value."""
    return Mechanism(
        points={},
        bodies=[Body(name, origin=(x, y), angle=angle) for name, (x, y, angle) in FRAMES.items()],
        joints=[],
        drivers=[AbsoluteDriver(body, coordinate, law=law) for body, coordinate, law in DRIVEN],
    )


def test_every_law_kind_matches_its_evaluate():
    # The drivers fix each coordinate to its law: q, qd, qdd are the law's value and time
    # derivatives, evaluated by the law objects themselves (`initial` = the drawn value).
    # The times hit the spline breakpoints and the end of the spline range.
    mechanism = driven_bodies()
    times = np.linspace(0.0, 2.0, 41)
    outcome, solved, _ = run_compiled(mechanism, times)
    assert outcome.complete
    for k, (body, coordinate, law) in enumerate(DRIVEN):
        column = 3 * list(FRAMES).index(body) + ("x", "y", "angle").index(coordinate)
        initial = FRAMES[body][("x", "y", "angle").index(coordinate)]
        expected = np.array([law.evaluate(t, initial) for t in times], dtype=float)
        for order in range(3):
            np.testing.assert_allclose(
                solved[order][:, column], expected[:, order], rtol=1e-13, atol=1e-13,
                err_msg=f"drivers[{k}] ({type(law).__name__}), derivative {order}",
            )  # fmt: skip
    reference = solve_kinematics(mechanism, times, linear_solver="superlu")
    assert_same_motion(solved, python_path(reference), 1e-13, rows=times.size)


def test_spline_driven_crank_matches_closed_form():
    # A crank pinned at the origin turns by the spline law: its tip is r (cos θ, sin θ)
    # with θ, θ', θ'' of the not-a-knot cubic spline through the law's samples.
    law = SPLINE_LAWS["spline"]
    radius = 0.25
    crank = Mechanism(
        points={"O": (0.0, 0.0), "A": (radius * np.cos(0.3), radius * np.sin(0.3))},
        bodies=[Body("crank", origin="O", angle=0.3, points=("O", "A"))],
        joints=[Revolute(("crank", "ground"), at="O")],
        drivers=[RotationalDriver(("crank", "ground"), law=law)],
    )
    times = np.linspace(0.0, 2.0, 201)
    outcome, (coordinates, velocities, accelerations), _ = run_compiled(crank, times)
    assert outcome.complete
    curve = CubicSpline(SPLINE_TIMES, SPLINE_VALUES, bc_type="not-a-knot")
    theta = [curve(times, order) for order in range(3)]
    for order, solved in enumerate((coordinates, velocities, accelerations)):
        np.testing.assert_allclose(solved[:, 2], theta[order], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(solved[:, :2], 0.0, atol=1e-12)
    reference = solve_kinematics(crank, times, linear_solver="superlu")
    assert_same_motion((coordinates, velocities, accelerations), python_path(reference), RTOL, rows=times.size)


def test_custom_laws_are_not_supported():
    class Custom:
        def evaluate(self, t, initial):
            return initial + t, 1.0, 0.0

    class Faster(Linear):
        """A subclass may change `evaluate`: refused too."""

    for law in (Custom(), Faster(rate=2.0)):
        mechanism = Mechanism(
            points={}, bodies=[Body("slider", origin=(0.0, 0.0))], joints=[],
            drivers=[AbsoluteDriver("slider", "y", law=Linear(rate=1.0)),
                     AbsoluteDriver("slider", "x", law=law),
                     AbsoluteDriver("slider", "angle", law=Linear(rate=0.0))],
        )  # fmt: skip
        assert not supports_compiled(mechanism)
        expected = (r"^the laws of `mechanism` must be Harmonic, Linear, Polynomial, Spline for the compiled "
                    rf"loop; driver '.*x.*' has a {type(law).__name__}\.$")  # fmt: skip
        with pytest.raises(ValueError, match=expected):
            run_compiled(mechanism, [0.0, 1.0])
    assert supports_compiled(task5())


def test_custom_load_laws_are_not_supported_either():
    """`solve_compiled` refuses what `supports_compiled` refuses: the loads' laws too."""

    class Custom:
        def evaluate(self, t, initial):
            return 1.0 + t, 1.0, 0.0

    mechanism = Mechanism(
        points={}, bodies=[Body("slider", origin=(0.0, 0.0), mass=1.0, inertia=0.1)], joints=[],
        drivers=[AbsoluteDriver("slider", axis, law=Linear(rate=1.0)) for axis in ("x", "y", "angle")],
        loads=[Torque("slider", value=Custom())],
    )  # fmt: skip
    assert not supports_compiled(mechanism)
    with pytest.raises(ValueError, match=r"compiled loop; load 'torque on slider' has a Custom\.$"):
        run_compiled(mechanism, [0.0, 1.0])


def test_output_arrays_are_checked():
    mechanism = task5()
    pattern = build_pattern(mechanism)
    times = np.linspace(0.0, 1.0, 5)
    good = [np.empty((5, 30)) for _ in range(3)]
    counts = np.empty(5, dtype=np.int64)
    expected = r"`velocities` must be a float64 array of shape \(5, 30\), got float64 \(5, 29\)"
    with pytest.raises(ValueError, match=expected):
        solve_compiled(
            Discretization(mechanism, pattern), times, 1e-12, 12, good[0], np.empty((5, 29)), good[2], counts
        )
    with pytest.raises(ValueError, match=r"`iterations` must be a int64 array"):
        solve_compiled(Discretization(mechanism, pattern), times, 1e-12, 12, *good, np.empty(5))


# ---------------------------------------------------------------------- the failure contract
@pytest.fixture(scope="module")
def failing_run():
    """Task 5 at 0.06 m of stroke amplitude loses its assembly near t = 0.756 s."""
    mechanism = task5(amplitude=0.06)
    times = np.linspace(0.0, 10.0, 10_001)
    with pytest.raises(ConvergenceError, match="Newton stalled") as failure:
        solve_kinematics(mechanism, times, linear_solver="superlu")
    return mechanism, times, failure.value.result


def condition_numbers(mechanism, times, coordinates):
    """2-norm condition number of the Jacobian at each solved sample."""
    pattern = build_pattern(mechanism)
    assembler = Assembler(Discretization(mechanism, pattern))
    conditions = []
    for t, q in zip(times, coordinates):
        assembler.set_time(t)
        assembler.fill_residual_jacobian(q)
        conditions.append(np.linalg.cond(assembler.jacobian.toarray()))
    return np.array(conditions)


@pytest.mark.parametrize("chord", [True, False], ids=["chord", "plain"])
def test_stops_at_the_sample_where_the_python_path_fails(failing_run, chord):
    mechanism, times, reference = failing_run
    assert reference.n_times == 756
    outcome, solved, iterations = run_compiled(mechanism, times, chord=chord)
    assert (outcome.n_solved, outcome.status) == (reference.n_times, LoopStatus.STALLED)
    assert not outcome.complete
    n_solved = outcome.n_solved
    if chord:
        # Both paths stop below the 1e-12 tolerance, at different points: each sample's
        # q, qd and qdd may differ by up to the tolerance times the condition number of
        # the Jacobian, which grows from 94 at t = 0 to ~7e3 at the last solved sample.
        bound = 1e-12 * condition_numbers(mechanism, times[:n_solved], reference.coordinates)
        for label, actual, expected in zip(("q", "qd", "qdd"), solved, python_path(reference)):
            error = np.max(np.abs(actual[:n_solved] - expected), axis=1) / np.max(np.abs(expected))
            np.testing.assert_array_less(error, bound, err_msg=label)
        assert outcome.n_restarts > 0  # the chord gave up near the dead point; plain Newton took over
        assert np.all(iterations[:n_solved] >= reference.newton_iterations)
    else:
        assert_same_motion(solved, python_path(reference), 1e-11, rows=n_solved)
        np.testing.assert_array_equal(iterations[:n_solved], reference.newton_iterations)


def test_singular_jacobian_at_the_first_sample():
    # A slider-crank drawn at its dead centre with the slider driven: the crank's angle is
    # not controlled, the Jacobian is exactly singular at t = 0 (an exactly zero pivot).
    mechanism = Mechanism(
        points={"O": (0.0, 0.0), "A": (0.1, 0.0), "B": (0.4, 0.0)},
        bodies=[Body("crank", origin="O", points=("O", "A")), Body("rod", origin="A", points=("A", "B")),
                Body("slider", origin="B", points=("B",))],
        joints=[Revolute(("crank", "ground"), at="O"), Revolute(("crank", "rod"), at="A"),
                Revolute(("rod", "slider"), at="B"),
                Translational(("ground", "slider"), axis=("O", "B"), name="guide")],
        drivers=[TranslationalDriver("guide", law=Linear(rate=-0.1))],
    )  # fmt: skip
    outcome, _, _ = run_compiled(mechanism, [0.0, 0.1])
    assert (outcome.n_solved, outcome.status) == (0, LoopStatus.SINGULAR)
