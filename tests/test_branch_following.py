"""Branch following: coarse steps must not jump to the other assembly branch.

The reference is a closed form independent of sparsekin: a four-bar's rocker pin is the
intersection of two circles (centred on the crank pin and on the rocker pivot), on the
side of the line between them that defines the assembly branch; velocities and
accelerations follow from differentiating the loop closure, a 2 × 2 linear system.

The four-bar is a Grashof crank-rocker close to its change point: crank 0.1, ground 0.4,
coupler 0.3, rocker 0.202 (0.1 + 0.4 = 0.5 against 0.3 + 0.202 = 0.502).  With the crank
at 180°, coupler and rocker are 16° short of aligned, so the two branches come within
about 0.1 m of each other; at 8 steps per crank turn, a step across that position lands on
the wrong branch unless the solver notices and subdivides.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import RTOL, four_bar, solve_with

from sparsekin import Linear, Mechanism, solve_kinematics
from sparsekin.solve.branch_guard import BranchGuard, branch_jump
from sparsekin.testset import task5

CRANK, COUPLER, ROCKER, GROUND = 0.1, 0.3, 0.202, 0.4  # m
START, RATE = 0.3, 2.0 * math.pi  # crank angle at t = 0 (rad) and its rate (rad/s)


def four_bar_positions(theta: np.ndarray, branch: int):
    """Crank pin A and rocker pin B (each (n, 2)) on the given branch (+1 or -1)."""
    a = CRANK * np.stack([np.cos(theta), np.sin(theta)], axis=1)
    pivot = np.array([GROUND, 0.0])
    gap = pivot - a
    distance = np.linalg.norm(gap, axis=1)
    along = (COUPLER**2 - ROCKER**2 + distance**2) / (2.0 * distance)
    across = branch * np.sqrt(COUPLER**2 - along**2)
    unit = gap / distance[:, None]
    normal = np.stack([-unit[:, 1], unit[:, 0]], axis=1)
    return a, a + along[:, None] * unit + across[:, None] * normal


def turn(vectors: np.ndarray) -> np.ndarray:
    """Vectors (n, 2) turned by +90°."""
    return np.stack([-vectors[:, 1], vectors[:, 0]], axis=1)


def four_bar_motion(times: np.ndarray, branch: int):
    """Position, velocity and acceleration of the rocker pin B, each (n, 2), crank at constant rate."""
    theta = START + RATE * times
    a, b = four_bar_positions(theta, branch)
    coupler, rocker = b - a, b - np.array([GROUND, 0.0])
    # Loop: B = A + coupler = pivot + rocker; differentiate with coupler' = w3 J coupler,
    # rocker' = w4 J rocker (J turns by +90°):  w4 J rocker - w3 J coupler = A'.
    matrix = np.stack([-turn(coupler), turn(rocker)], axis=2)  # columns: w3, w4
    a_velocity = RATE * turn(a)
    w3, w4 = np.linalg.solve(matrix, a_velocity[..., None])[..., 0].T
    a_acceleration = -(RATE**2) * a
    rhs = a_acceleration - w3[:, None] ** 2 * coupler + w4[:, None] ** 2 * rocker
    _, e4 = np.linalg.solve(matrix, rhs[..., None])[..., 0].T
    velocity = w4[:, None] * turn(rocker)
    acceleration = e4[:, None] * turn(rocker) - w4[:, None] ** 2 * rocker
    return b, velocity, acceleration


def build_four_bar(branch: int = 1) -> Mechanism:
    (a,), (b,) = four_bar_positions(np.array([START]), branch)
    points = {"O2": (0.0, 0.0), "O4": (GROUND, 0.0), "A": tuple(a), "B": tuple(b)}
    return four_bar(points, Linear(rate=RATE), name="near_change_point")


def test_the_closed_form_closes_the_loop():
    for branch in (1, -1):
        a, b = four_bar_positions(START + RATE * np.linspace(0.0, 1.0, 97), branch)
        np.testing.assert_allclose(np.linalg.norm(b - a, axis=1), COUPLER, rtol=1e-14)
        np.testing.assert_allclose(np.linalg.norm(b - [GROUND, 0.0], axis=1), ROCKER, rtol=1e-14)
    # and its derivatives are those of the positions (central differences, O(h²))
    times, h = np.linspace(0.1, 0.9, 9), 1e-5
    b, velocity, acceleration = four_bar_motion(times, 1)
    ahead, behind = four_bar_motion(times + h, 1)[0], four_bar_motion(times - h, 1)[0]
    np.testing.assert_allclose((ahead - behind) / (2 * h), velocity, atol=1e-8)
    np.testing.assert_allclose((ahead - 2 * b + behind) / h**2, acceleration, atol=1e-3)


COARSE = np.linspace(0.0, 1.0, 9)  # 45° of crank per step, one turn


def test_coarse_steps_stay_on_their_branch():
    result = solve_kinematics(build_four_bar(), COARSE)
    assert result.complete and result.n_subdivisions > 0
    expected = four_bar_motion(COARSE, 1)
    scales = (GROUND, CRANK * RATE * 5, CRANK * RATE**2 * 25)  # m, m/s, m/s² (the rocker moves fast near 180°)
    for solved, exact, scale in zip(result.point("B"), expected, scales):
        np.testing.assert_allclose(solved, exact, rtol=RTOL, atol=RTOL * scale)


def test_without_the_guard_the_same_steps_jump_to_the_other_branch():
    """The guard is what keeps the branch: switched off, the step across 180° lands on the mirror image."""
    result = solve_with(build_four_bar(), COARSE, guard=BranchGuard(defect_ratio=math.inf))
    assert result.complete and result.n_subdivisions == 0
    position = result.point("B").position
    right, mirror = four_bar_motion(COARSE, 1)[0], four_bar_motion(COARSE, -1)[0]
    jump = 4  # the step from crank angle 0.3 + 3π/4 to 0.3 + π
    np.testing.assert_allclose(position[:jump], right[:jump], atol=1e-12)
    np.testing.assert_allclose(position[jump:], mirror[jump:], atol=1e-12)
    assert np.min(np.linalg.norm(position[jump:] - right[jump:], axis=1)) > 0.07


def test_fine_steps_do_not_subdivide():
    result = solve_kinematics(build_four_bar(), np.linspace(0.0, 1.0, 361))
    assert result.complete and result.n_subdivisions == 0
    np.testing.assert_allclose(result.point("B").position, four_bar_motion(result.times, 1)[0], atol=RTOL * GROUND)


def test_task5_at_1_ms_never_subdivides():
    result = solve_kinematics(task5(), np.linspace(0.0, 2.0, 2001))
    assert result.complete and result.n_subdivisions == 0
    assert result.newton_iterations[1:].max() <= 2


@pytest.mark.parametrize("t_end", [2.0, 5.0, 10.0])
def test_a_single_huge_step_is_subdivided_onto_the_right_branch(t_end):
    """Newton from a 5 s predictor fails or lands elsewhere; halving recovers the motion, no error."""
    fine = solve_kinematics(task5(), np.linspace(0.0, t_end, int(100 * t_end) + 1))
    result = solve_kinematics(task5(), [0.0, t_end])
    assert result.complete and result.n_subdivisions > 0
    np.testing.assert_allclose(result.coordinates[-1], fine.coordinates[-1], rtol=0, atol=1e-10)
    np.testing.assert_allclose(result.velocities[-1], fine.velocities[-1], rtol=0, atol=1e-10)
    np.testing.assert_allclose(result.accelerations[-1], fine.accelerations[-1], rtol=0, atol=1e-10)


def test_the_guard_measures_the_corrected_trapezoidal_rule():
    """`branch_jump` directly: a smooth rotation passes, the same end point with the mirror velocity does not."""
    h, omega = 0.1, 1.0
    times = np.array([0.0, h])
    angle, rate, acceleration = np.sin(omega * times), omega * np.cos(omega * times), -(omega**2) * np.sin(omega * times)
    weights = np.ones(1)
    smooth = [np.array([value]) for value in (angle[0], rate[0], acceleration[0], angle[1], rate[1], acceleration[1])]
    predicted = smooth[3] - 0.01  # Newton moved 0.01 rad from its predictor
    assert not branch_jump(h, smooth[:3], smooth[3:], predicted, weights)
    mirrored = smooth.copy()
    mirrored[4] = -smooth[4]  # the velocity of the other branch
    assert branch_jump(h, mirrored[:3], mirrored[3:], predicted, weights)
    # ... unless Newton hardly moved from the predictor: then it cannot have left the branch
    assert not branch_jump(h, mirrored[:3], mirrored[3:], smooth[3] - 1e-4, weights)
