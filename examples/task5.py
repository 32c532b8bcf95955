"""The Task 5 ten-body linkage through the Python API.

The same mechanism as ``examples/task5.toml`` (see docs/task5.md): ten bodies,
twelve revolute joints, two hydraulic actuators (translational joints) whose strokes follow
``L0 + 0.05 sin(1.5 t)`` m.  Run it as a script to print the motion of the tool point K, or
import `build_task5` to get the `Mechanism`.
"""

from __future__ import annotations

import math

import numpy as np

from sparsekin import (
    Body,
    Harmonic,
    Mechanism,
    Revolute,
    Translational,
    TranslationalDriver,
    solve_kinematics,
)

POINTS = {
    "A": (-1.0, 0.2), "B": (-0.7, 0.8), "D": (-0.2, 0.5), "E": (0.1, 0.8), "F": (0.9, 0.7),
    "G": (0.3, 0.6), "H": (0.7, -0.4), "I": (0.7, 0.3), "J": (0.0, 0.9), "K": (-1.2, 0.6),
    "L": (0.6, 0.3), "M": (0.2, 0.6), "N": (0.4, -0.2),
}  # fmt: skip


def actuator_angle(start: str, end: str) -> float:
    """Angle of the line from point `start` to point `end`, rad."""
    (x0, y0), (x1, y1) = POINTS[start], POINTS[end]
    return math.atan2(y1 - y0, x1 - x0)


def build_task5(amplitude: float = 0.05, omega: float = 1.5) -> Mechanism:
    """The Task 5 linkage; both actuator strokes follow L0 + amplitude·sin(omega·t)."""
    carried = {
        "c1": ("A", "B", "K"), "c2": ("J", "E", "M", "F"), "c3": ("L", "I", "F", "G"),
        "c4": ("I", "A", "D"), "c5": ("B", "J"), "c6": ("D", "E"),
        "c7": ("M",), "c8": ("N",), "c9": ("G",), "c10": ("H",),
    }  # fmt: skip
    angle = {"c7": actuator_angle("N", "M"), "c8": actuator_angle("N", "M"),
             "c9": actuator_angle("H", "G"), "c10": actuator_angle("H", "G")}  # fmt: skip
    bodies = [
        Body(name, origin=points[0], angle=angle.get(name, 0.0), points=points)
        for name, points in carried.items()
    ]
    pins = [
        ("c3", "ground", "L"), ("c3", "c4", "I"), ("c4", "c1", "A"), ("c1", "c5", "B"),
        ("c5", "c2", "J"), ("c2", "c7", "M"), ("c2", "c3", "F"), ("c3", "c9", "G"),
        ("c4", "c6", "D"), ("c6", "c2", "E"), ("c8", "ground", "N"), ("c10", "ground", "H"),
    ]  # fmt: skip
    joints = [Revolute((i, j), at=at) for i, j, at in pins]
    joints += [
        Translational(("c8", "c7"), axis=("N", "M"), name="actuator1"),
        Translational(("c10", "c9"), axis=("H", "G"), name="actuator2"),
    ]
    stroke = Harmonic(amplitude=amplitude, omega=omega)
    drivers = [TranslationalDriver("actuator1", law=stroke), TranslationalDriver("actuator2", law=stroke)]
    return Mechanism(points=POINTS, bodies=bodies, joints=joints, drivers=drivers, name="task5")


def main() -> None:
    times = np.linspace(0.0, 10.0, 1001)
    result = solve_kinematics(build_task5(), times)
    tool = result.point("K")
    print(f"Task 5: {result.n_times} samples, {result.newton_iterations.sum()} Newton corrections")
    for k in range(0, result.n_times, 100):
        (x, y), (vx, vy), (ax, ay) = tool.position[k], tool.velocity[k], tool.acceleration[k]
        print(f"t = {times[k]:5.2f} s  K = ({x: .5f}, {y: .5f}) m  v = ({vx: .5f}, {vy: .5f}) m/s  "
              f"a = ({ax: .5f}, {ay: .5f}) m/s²")  # fmt: skip


if __name__ == "__main__":
    main()
