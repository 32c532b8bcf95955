"""The workspace of Task 5 over its two strokes against independent runs.

A reachable grid point's position equals a static solve of Task 5 with both strokes held
at its values, started from the drawing (not by continuation); the singular boundary lies
at the stroke of actuator 2 at which a single run with larger amplitudes locks up; limits
mark exactly the grid points outside them.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import sparsekin as sk
from sparsekin.cli import main

TASK5 = Path(__file__).resolve().parent.parent / "examples" / "task5.toml"
RANGES = [(0.78, 0.87), (1.03, 1.16)]


@pytest.fixture(scope="module")
def task5():
    return sk.load_model(TASK5)


@pytest.fixture(scope="module")
def space(task5):
    return sk.workspace(task5, "K", grid=(6, 8), ranges=RANGES)


def held(mechanism, strokes):
    drivers = tuple(
        dataclasses.replace(d, law=sk.Linear(rate=0.0, start=s)) for d, s in zip(mechanism.drivers, strokes)
    )
    return dataclasses.replace(mechanism, drivers=drivers)


def test_reachable_positions_equal_static_solves_from_the_drawing(task5, space):
    assert space.status.shape == (8, 6)
    reachable = np.argwhere(space.reachable)
    assert len(reachable) > 20
    for j, i in reachable[:: max(1, len(reachable) // 8)]:
        strokes = (space.values[0][i], space.values[1][j])
        static = sk.solve_kinematics(held(task5, strokes), [0.0]).point("K").position[0]
        np.testing.assert_allclose(space.positions[j, i], static, rtol=0, atol=1e-9)


def test_singular_boundary_is_where_a_single_run_locks_up(task5, space):
    amplitude = 0.06
    drivers = tuple(
        dataclasses.replace(d, law=sk.Harmonic(amplitude=amplitude, omega=1.5)) for d in task5.drivers
    )
    with pytest.raises(sk.SingularConfigurationError) as stopped:
        sk.solve_kinematics(dataclasses.replace(task5, drivers=drivers), np.linspace(0.0, 2.0, 201))
    lock_stroke = [v for label, v in stopped.value.driver_values.items() if label.startswith("drivers[1]")][0]
    assert len(space.boundary) >= space.status.shape[1]  # one crossing per column at least
    np.testing.assert_allclose(space.boundary[:, 1], lock_stroke, atol=1e-5)
    above = space.values[1] > lock_stroke
    assert (space.status[above] == "beyond_singular").all()
    assert (space.status[~above] == "reachable").all()


def test_limits_mark_the_grid_points_outside_them(task5):
    joints = list(task5.joints)
    k = [joint.name for joint in joints].index("actuator2")
    joints[k] = dataclasses.replace(joints[k], limits=(1.05, 1.10))
    limited = sk.workspace(dataclasses.replace(task5, joints=tuple(joints)), "K", grid=(4, 8), ranges=RANGES)
    b = np.broadcast_to(limited.values[1][:, None], limited.status.shape)
    solved = np.isin(limited.status, ("reachable", "outside_limits"))
    inside = (b >= 1.05) & (b <= 1.10)
    assert (limited.status[solved & inside] == "reachable").all()
    assert (limited.status[solved & ~inside] == "outside_limits").all() and (solved & ~inside).any()
    assert limited.limits_left == (task5.element_label("joints", k),)


def test_a_path_driver_not_moved_is_held_law_by_law(task5, space):
    """A marker body beside Task 5, its point P on a path (law_x, law_y) and its angle
    driven: the workspace over the two strokes holds both of P's laws at their values at
    t = 0 (P stays where it is drawn, though its laws move fast), and K's map is Task 5's."""
    marker = dataclasses.replace(
        task5,
        points={**task5.points, "P": (2.0, 2.0)},
        bodies=(*task5.bodies, sk.Body("marker", origin="P", points=("P",))),
        drivers=(*task5.drivers,
                 sk.PathDriver("marker", point="P", law_x=sk.Linear(rate=5.0), law_y=sk.Harmonic(amplitude=1.0,
                                                                                                     omega=9.0)),
                 sk.AbsoluteDriver("marker", coordinate="angle", law=sk.Linear(rate=3.0))),
    )  # fmt: skip
    on_p = sk.workspace(marker, "P", grid=(6, 8), ranges=RANGES)
    solved = np.isfinite(on_p.positions[..., 0])
    assert solved.sum() > 20
    np.testing.assert_array_equal(on_p.status, space.status)
    np.testing.assert_allclose(on_p.positions[solved], np.broadcast_to([2.0, 2.0], on_p.positions[solved].shape),
                               rtol=0, atol=1e-12)  # fmt: skip
    on_k = sk.workspace(marker, "K", grid=(6, 8), ranges=RANGES)
    np.testing.assert_allclose(on_k.positions, space.positions, rtol=0, atol=1e-9, equal_nan=True)
    with pytest.raises(sk.ModelError, match=r"drivers\[2\] drives 2 quantities; expected one"):
        sk.workspace(marker, "K", drivers=(0, 2), ranges=RANGES)


@pytest.mark.parametrize("arguments, message", [
    (dict(point="Q"), 'point: unknown point "Q"'),
    (dict(point="K", drivers=(0, 0)), r"drivers: expected two different drivers"),
    (dict(point="K", grid=1), r"grid: expected a whole number >= 2"),
    (dict(point="K", ranges=[(0.8, 0.8), (1.0, 1.1)]), r"ranges of drivers\[0\]: expected \(start, stop\)"),
])  # fmt: skip
def test_mistakes_name_the_argument(task5, arguments, message):
    with pytest.raises(sk.ModelError, match=message):
        sk.workspace(task5, **arguments)


def test_cli_writes_the_grid_the_boundary_and_the_plot(tmp_path, capsys):
    status = main(["workspace", str(TASK5), "--point", "K", "--grid", "5", "--range", "0=0.78:0.87",
                   "--range", "1=1.03:1.16", "--out", str(tmp_path), "--plot"])  # fmt: skip
    out = capsys.readouterr().out
    assert status == 0 and "singular boundary" in out
    rows = (tmp_path / "workspace.csv").read_text().splitlines()
    assert rows[0] == "drivers[0],drivers[1],status,K.x,K.y" and len(rows) == 1 + 25
    assert (tmp_path / "boundary.csv").exists() and (tmp_path / "workspace_K.png").stat().st_size > 0
    assert main(["workspace", str(TASK5), "--point", "K", "--range", "0=0.7"]) == 2
    assert "--range 0=0.7: expected D=START:STOP" in capsys.readouterr().err
