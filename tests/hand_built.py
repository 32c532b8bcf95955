"""Grid mechanisms written out by hand, one loop iteration per copy, for the grid tests.

They share nothing with `sparsekin.model.units` or `sparsekin.model.tiling` but the element
classes: the lattice as `sparsekin.testset` built it before grids existed (its own names),
the same lattice with the copies' names, and the rotating squares of the shared
specification, each hinge placed at the corner its two squares have in common.
"""

from __future__ import annotations

import math
from itertools import product

import numpy as np

from sparsekin import Body, Harmonic, Mechanism, PinInSlot, Revolute, RotationalDriver, testset


def lattice_as_before(rows: int, cols: int) -> Mechanism:
    """The lattice exactly as `testset.lattice` built it element by element before grids
    (bodies V{r}_{c}, H{r}_{c}, nodes n{r}_{c}; rows 1 … rows)."""
    points = {f"n{r}_{c}": (float(c), float(r)) for r in range(rows + 1) for c in range(cols + 1)}
    bodies, joints, drivers = [], [], []
    for r in range(1, rows + 1):
        for c in range(cols + 1):
            bodies.append(Body(f"V{r}_{c}", origin=f"n{r - 1}_{c}", angle=math.pi / 2, points=(f"n{r - 1}_{c}", f"n{r}_{c}")))
        for c in range(cols):
            bodies.append(Body(f"H{r}_{c}", origin=f"n{r}_{c}", points=(f"n{r}_{c}", f"n{r}_{c + 1}")))
        for c in range(cols + 1):
            below = "ground" if r == 1 else f"V{r - 1}_{c}"
            joints.append(Revolute((f"V{r}_{c}", below), at=f"n{r - 1}_{c}"))
            if c < cols:
                joints.append(Revolute((f"H{r}_{c}", f"V{r}_{c}"), at=f"n{r}_{c}"))
            if c > 0:
                joints.append(Revolute((f"H{r}_{c - 1}", f"V{r}_{c}"), at=f"n{r}_{c}"))
        phase = 2 * np.pi * (r - 1) / max(rows, 1)
        below = "ground" if r == 1 else f"H{r - 1}_0"
        drivers.append(
            RotationalDriver(
                (f"V{r}_0", below),
                law=Harmonic(amplitude=testset.LATTICE_AMPLITUDE, omega=testset.LATTICE_OMEGA, phase=float(phase),
                             offset=math.pi / 2 - testset.LATTICE_AMPLITUDE * math.sin(phase)),
            )
        )  # fmt: skip
    return Mechanism(points=points, bodies=bodies, joints=joints, drivers=drivers, name=f"lattice_{rows}x{cols}")


def lattice_by_hand(rows: int, cols: int) -> Mechanism:
    """The same lattice written copy by copy with the grid's names: cell (c, r − 1) holds
    V and H of row r, column c, and its points B, T, R (nodes (r−1, c), (r, c), (r, c+1))."""
    points, bodies, joints, drivers = {}, [], [], []
    for j, i in product(range(rows), range(cols + 1)):
        name = f"c{i}_{j}."
        points |= {name + "B": (float(i), float(j)), name + "T": (float(i), j + 1.0), name + "R": (i + 1.0, j + 1.0)}
    for j, i in product(range(rows), range(cols + 1)):  # row by row, each cell's parts in the unit's order
        name = f"c{i}_{j}."
        bodies.append(Body(name + "V", origin=name + "B", angle=math.pi / 2, points=(name + "B", name + "T")))
        if i < cols:
            bodies.append(Body(name + "H", origin=name + "T", points=(name + "T", name + "R")))
    for j, i in product(range(rows), range(cols + 1)):
        name = f"c{i}_{j}."
        joints.append(Revolute((name + "V", "ground" if j == 0 else f"c{i}_{j - 1}.V"), at=name + "B"))
        if i < cols:
            joints.append(Revolute((name + "H", name + "V"), at=name + "T"))
        if i > 0:
            joints.append(Revolute((f"c{i - 1}_{j}.H", name + "V"), at=name + "T"))
    for j in range(rows):
        phase = 2 * np.pi * j / max(rows, 1)
        drivers.append(RotationalDriver(
            (f"c0_{j}.V", "ground" if j == 0 else f"c0_{j - 1}.H"),
            law=Harmonic(amplitude=testset.LATTICE_AMPLITUDE, omega=testset.LATTICE_OMEGA, phase=float(phase),
                         offset=math.pi / 2 - testset.LATTICE_AMPLITUDE * math.sin(phase)),
        ))  # fmt: skip
    return Mechanism(points=points, bodies=bodies, joints=joints, drivers=drivers, name=f"lattice_{rows}x{cols}")


def square_corners(centre, angle) -> np.ndarray:
    """The four corners of a unit square centred at `centre`, turned by `angle`, shape (4, 2)."""
    half = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
    rotation = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    return np.asarray(centre) + half @ rotation.T


def rotating_squares_by_hand(n: int, angle: float = 0.3, amplitude: float = 0.2, omega: float = 1.0) -> Mechanism:
    """The shared specification, literally: squares s{i}_{j}.sq at (i·p, j·p), turned by
    ±angle on a checkerboard; each pair of neighbours pinned at the corner they share
    (found by comparing their corners); the ground joints; the driver."""
    pitch = math.cos(angle) + math.sin(angle)
    centre = {(i, j): (i * pitch, j * pitch) for i in range(n) for j in range(n)}
    turn = {(i, j): angle if (i + j) % 2 == 0 else -angle for i in range(n) for j in range(n)}

    def common_corner(a, b):
        first, second = square_corners(centre[a], turn[a]), square_corners(centre[b], turn[b])
        distance = np.linalg.norm(first[:, None] - second[None], axis=-1)
        p, q = np.unravel_index(np.argmin(distance), distance.shape)
        assert distance[p, q] < 1e-12, "the squares share no corner"
        return tuple(float(x) for x in first[p])

    bodies = [Body(f"s{i}_{j}.sq", origin=(centre[i, j]), angle=turn[i, j]) for j in range(n) for i in range(n)]
    joints = [Revolute(("s0_0.sq", "ground"), at=(0.0, 0.0)),
              PinInSlot(("ground", "s1_0.sq"), at=(pitch, 0.0), direction=(1.0, 0.0))]  # fmt: skip
    for j, i in product(range(n), range(n)):  # row by row: the hinge to the left, then the one below
        if i > 0:
            joints.append(Revolute((f"s{i}_{j}.sq", f"s{i - 1}_{j}.sq"), at=common_corner((i, j), (i - 1, j))))
        if j > 0:
            joints.append(Revolute((f"s{i}_{j}.sq", f"s{i}_{j - 1}.sq"), at=common_corner((i, j), (i, j - 1))))
    driver = RotationalDriver(("s0_0.sq", "ground"), law=Harmonic(amplitude=amplitude, omega=omega))
    return Mechanism(points={}, bodies=bodies, joints=joints, drivers=[driver], name=f"rotating_squares_{n}x{n}")
