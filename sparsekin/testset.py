"""A scalable test set of planar mechanisms, from ten bodies to a million.

Every function returns a `Mechanism` (which `save_model` can write) whose exact motion is
known independently of the solver:

* `task5` — the ten-body two-actuator linkage of the Task 5 report.
* `task5_chain` — Task 5 units in series: unit k's ground pivots (L, N, H) ride on the
  actuator-2 cylinder c10 of unit k-1.  Drivers are relative, so each unit moves relative
  to its base exactly as a single Task 5 with its phase.
* `four_bar_chain` — the IFToMM "N four-bar" benchmark: the couplers translate rigidly.
* `lattice` — a grid of parallelogram cells, one actuator per row along the left edge;
  its Jacobian graph is a mesh.  Every vertical bar of row r turns with the row's driver;
  the horizontal bars translate.
* `rotating_squares` — Grima and Evans's auxetic mechanism: n×n unit squares hinged at
  their corners, one driver, (n − 2)² redundant equations.
* `parallel_bar_chain` — a tower of parallelogram cells with three parallel bars each
  (one redundant equation per cell), or two and a welded one (the non-redundant twin).

The two chains are a unit repeated (`sparsekin.model.units.Repeat`), as their model files
``examples/task5_chain.toml`` and ``examples/four_bar_chain.toml`` write them: a million
bodies are a few arrays, not a million objects.
"""

from __future__ import annotations

import gc
import math
from contextlib import contextmanager

import numpy as np

from .model.elements import PinInSlot, Revolute, Rigid, RotationalDriver, Translational, TranslationalDriver
from .model.laws import Harmonic, Linear
from .model.mechanism import Body, Mechanism
from .model.units import Cycle, Repeat, Unit

__all__ = ["TASK5_POINTS", "task5", "task5_chain", "task5_chain_unit", "four_bar_chain", "lattice", "task5_unit_phases",
           "rotating_squares", "parallel_bar_chain"]

#: Task 5 points in the drawn configuration, m (docs/task5.md).
TASK5_POINTS = {
    "A": (-1.0, 0.2), "B": (-0.7, 0.8), "D": (-0.2, 0.5), "E": (0.1, 0.8), "F": (0.9, 0.7),
    "G": (0.3, 0.6), "H": (0.7, -0.4), "I": (0.7, 0.3), "J": (0.0, 0.9), "K": (-1.2, 0.6),
    "L": (0.6, 0.3), "M": (0.2, 0.6), "N": (0.4, -0.2),
}  # fmt: skip
#: Points carried by each Task 5 body; the first is the frame origin.
_TASK5_BODIES = {
    "c1": ("A", "B", "K"), "c2": ("J", "E", "M", "F"), "c3": ("L", "I", "F", "G"),
    "c4": ("I", "A", "D"), "c5": ("B", "J"), "c6": ("D", "E"),
    "c7": ("M",), "c8": ("N",), "c9": ("G",), "c10": ("H",),
}  # fmt: skip
#: Revolute joints (body, body, point); "base" is the ground of a unit.
_TASK5_PINS = (
    ("c3", "base", "L"), ("c3", "c4", "I"), ("c4", "c1", "A"), ("c1", "c5", "B"),
    ("c5", "c2", "J"), ("c2", "c7", "M"), ("c2", "c3", "F"), ("c3", "c9", "G"),
    ("c4", "c6", "D"), ("c6", "c2", "E"), ("c8", "base", "N"), ("c10", "base", "H"),
)  # fmt: skip
#: The two actuators: (name, cylinder, rod, start point, end point).
_TASK5_ACTUATORS = (("actuator1", "c8", "c7", "N", "M"), ("actuator2", "c10", "c9", "H", "G"))
#: Angular frequency of the Task 5 actuator strokes, rad/s.
TASK5_OMEGA = 1.5
#: Distance between successive units of `task5_chain` along x, m.
TASK5_CHAIN_SPACING = 2.5
#: Number of distinct actuator phases in `task5_chain`, spread evenly over a period.
TASK5_CHAIN_PHASES = 11


@contextmanager
def _collection_paused():
    """Pause Python's cyclic garbage collector while a large model is built (a decorator).

    A million-body model is some four million small objects and none of them forms a
    reference cycle; the collector's repeated passes over them cost a third of the build.
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def _stroke_lengths() -> tuple[float, float]:
    return tuple(
        math.dist(TASK5_POINTS[start], TASK5_POINTS[end]) for _, _, _, start, end in _TASK5_ACTUATORS
    )


def _task5_unit(base: str, amplitude: float, offsets=None):
    """Bodies, joints and drivers of one Task 5 on the points `TASK5_POINTS`, its ground
    pivots on `base`; the strokes' offsets are `offsets` (default: the drawn lengths)."""
    angle = {}
    for _, cylinder, rod, start, end in _TASK5_ACTUATORS:
        (x0, y0), (x1, y1) = TASK5_POINTS[start], TASK5_POINTS[end]
        angle[cylinder] = angle[rod] = math.atan2(y1 - y0, x1 - x0)
    bodies = [Body(name, origin=carried[0], angle=angle.get(name, 0.0), points=tuple(carried))
              for name, carried in _TASK5_BODIES.items()]  # fmt: skip
    joints = [Revolute((i, base if j == "base" else j), at=at) for i, j, at in _TASK5_PINS]
    joints += [Translational((cylinder, rod), axis=(start, end), name=name)
               for name, cylinder, rod, start, end in _TASK5_ACTUATORS]  # fmt: skip
    offsets = [None] * len(_TASK5_ACTUATORS) if offsets is None else offsets
    drivers = [TranslationalDriver(name, law=Harmonic(amplitude=amplitude, omega=TASK5_OMEGA, offset=offset))
               for (name, *_), offset in zip(_TASK5_ACTUATORS, offsets)]  # fmt: skip
    return bodies, joints, drivers


def task5(amplitude: float = 0.05) -> Mechanism:
    """The Task 5 linkage; both strokes follow L0 + amplitude · sin(1.5 t) m."""
    bodies, joints, drivers = _task5_unit("ground", amplitude)
    return Mechanism(points=TASK5_POINTS, bodies=bodies, joints=joints, drivers=drivers, name="task5")


def task5_unit_phases(n_units: int) -> np.ndarray:
    """Actuator phase of each unit of `task5_chain`, rad: 11 phases spread over 2π, repeated."""
    return 2 * np.pi * (np.arange(n_units) % TASK5_CHAIN_PHASES) / TASK5_CHAIN_PHASES


def _task5_points_at_phases(amplitude: float) -> np.ndarray:
    """Points of a single Task 5 at the phases of `task5_unit_phases`, shape (phases, 13, 2).

    One sweep over a period, at small steps so that Newton follows the branch.
    """
    from .solve.kinematics import solve_kinematics

    steps_per_phase = 40
    times = np.linspace(0.0, 2 * np.pi / TASK5_OMEGA, TASK5_CHAIN_PHASES * steps_per_phase + 1)
    result = solve_kinematics(task5(amplitude), times)
    rows = np.arange(TASK5_CHAIN_PHASES) * steps_per_phase
    return np.stack([result.point(name).position[rows] for name in TASK5_POINTS], axis=1)


def task5_chain_unit(amplitude: float = 0.03) -> Unit:
    """One Task 5 as a unit: its ground pivots L, N and H ride on ``prev.c10``.

    Drawn at phase 0; `task5_chain` draws copy k at its phase (a cycle of the points).
    Both strokes follow ``L0 + amplitude · sin(1.5 t + phase)``, L0 their length at phase 0.
    """
    bodies, joints, drivers = _task5_unit("prev.c10", amplitude, offsets=_stroke_lengths())
    return Unit("task5", points=TASK5_POINTS, bodies=bodies, joints=joints, drivers=drivers)


def task5_chain(n_units: int, amplitude: float = 0.03) -> Mechanism:
    """`n_units` Task 5 units in series: 10·n bodies, 2·n actuators.

    Unit k (names ``u{k}.NAME``) sits `TASK5_CHAIN_SPACING`·k m to the right of unit 0,
    assembled at its phase (`task5_unit_phases`); its pivots L, N and H ride on the
    cylinder c10 of unit k-1 (unit 0's on the ground).  Its strokes follow
    L0 + amplitude · sin(1.5 t + phase).  With amplitude 0.03 m (instead of Task 5's
    0.05 m) every unit stays well clear of the near dead centre at full stroke; with the
    phases spread evenly, the rotations of the bases cancel over every 11 units, so the
    chain wiggles but does not curl up.
    """
    if isinstance(n_units, bool) or not isinstance(n_units, (int, np.integer)) or n_units < 1:
        raise ValueError(f"`n_units` must be a whole number >= 1, got {n_units!r}.")
    assembled = _task5_points_at_phases(amplitude)  # (phases, points, 2)
    phases = task5_unit_phases(TASK5_CHAIN_PHASES).tolist()
    vary = {f"points.{name}": Cycle([tuple(xy) for xy in assembled[:, p].tolist()]) for p, name in enumerate(TASK5_POINTS)}
    vary |= {f"drivers[{d}].law.phase": Cycle(phases) for d in range(len(_TASK5_ACTUATORS))}
    repeat = Repeat(task5_chain_unit(amplitude), count=int(n_units), prefix="u",
                    offset=(TASK5_CHAIN_SPACING, 0.0), vary=vary)  # fmt: skip
    return Mechanism(points={}, bodies=[], repeats=[repeat], name=f"task5_chain_{n_units}")


def four_bar_chain(n_loops: int, initial_angle: float = math.pi / 4, rate: float = 1.0) -> Mechanism:
    """The IFToMM N-four-bar benchmark: n_loops parallelograms side by side, 2·n+1 bodies.

    ``crank0`` turns about O0 = (0, 0), driven at `rate` rad/s from `initial_angle`; copy
    k of the unit (names ``u{k}.NAME``) adds the crank ``u{k}.crank`` about P = (k + 1, 0)
    and the coupler ``u{k}.coupler`` from the previous crank's tip T to this crank's tip Q.
    Cranks and couplers are 1 m long; every crank turns with crank0 and the couplers
    translate.  Keep the crank angle away from 0 and π, where the parallelograms can fold.
    """
    if isinstance(n_loops, bool) or not isinstance(n_loops, (int, np.integer)) or n_loops < 1:
        raise ValueError(f"`n_loops` must be a whole number >= 1, got {n_loops!r}.")
    tip = (math.cos(initial_angle), math.sin(initial_angle))
    loop = Unit(
        "loop",
        points={"T": tip, "P": (1.0, 0.0), "Q": (1.0 + tip[0], tip[1])},
        bodies=[Body("crank", origin="P", angle=initial_angle, points=("P", "Q")),
                Body("coupler", origin="T", points=("T", "Q"))],
        joints=[Revolute(("crank", "ground"), at="P"), Revolute(("crank", "coupler"), at="Q"),
                Revolute(("coupler", "prev.crank"), at="T")],
    )  # fmt: skip
    return Mechanism(
        points={"O0": (0.0, 0.0), "A0": tip},
        bodies=[Body("crank0", origin="O0", angle=initial_angle, points=("O0", "A0"))],
        joints=[Revolute(("crank0", "ground"), at="O0")],
        drivers=[RotationalDriver(("crank0", "ground"), law=Linear(rate=rate))],
        repeats=[Repeat(loop, count=int(n_loops), prefix="u", offset=(1.0, 0.0), first={"prev.crank": "crank0"})],
        name=f"four_bar_chain_{n_loops}",
    )


#: Amplitude (rad) and angular frequency (rad/s) of the row actuators of `lattice`.
LATTICE_AMPLITUDE = 0.3
LATTICE_OMEGA = 2.0


@_collection_paused()
def lattice(rows: int, cols: int) -> Mechanism:
    """A grid of rows × cols parallelogram cells on a fixed base: rows·(2·cols+1) bodies.

    Node (r, c) starts at (c, r).  Row r (1 … rows) has vertical bars V{r}_{c} from node
    (r-1, c) to (r, c) and horizontal bars H{r}_{c} from (r, c) to (r, c+1); the bottom
    nodes are ground pivots.  Pinned at the nodes, the grid has one degree of freedom per
    row (its shear); an actuator at the left edge drives the angle of V{r}_0 relative to
    the bar below it to π/2 + 0.3 (sin(2 t + phase_r) - sin(phase_r)), so the grid starts
    as drawn.  Every vertical bar of row r turns with it and the horizontal bars
    translate; the angles stay within 0.6 rad of vertical, far from the folded positions
    (a bar horizontal, 1.57 rad away).  Interior nodes join four bars, so the
    Jacobian graph is a two-dimensional mesh.
    """
    for value, label in ((rows, "rows"), (cols, "cols")):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"`{label}` must be a whole number >= 1, got {value!r}.")
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
                law=Harmonic(amplitude=LATTICE_AMPLITUDE, omega=LATTICE_OMEGA, phase=float(phase),
                             offset=math.pi / 2 - LATTICE_AMPLITUDE * math.sin(phase)),
            )
        )  # fmt: skip
    return Mechanism(points=points, bodies=bodies, joints=joints, drivers=drivers, name=f"lattice_{rows}x{cols}")


#: Amplitude (rad) and angular frequency (rad/s) of the driver of `rotating_squares`.
SQUARES_AMPLITUDE = 0.2
SQUARES_OMEGA = 1.0


def _whole(value, label: str, smallest: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < smallest:
        raise ValueError(f"`{label}` must be a whole number >= {smallest}, got {value!r}.")
    return int(value)


def _corners(centre: np.ndarray, angle: float) -> np.ndarray:
    """The four corners of a unit square turned by `angle` about its `centre`, shape (4, 2)."""
    c, s = math.cos(angle), math.sin(angle)
    local = np.array([(0.5, 0.5), (-0.5, 0.5), (-0.5, -0.5), (0.5, -0.5)])
    return centre + local @ np.array([[c, s], [-s, c]])


def _shared_corner(first: np.ndarray, second: np.ndarray) -> tuple[float, float]:
    """The corner that two neighbouring squares' corner lists have in common."""
    distances = np.linalg.norm(first[:, None] - second[None], axis=2)
    a, b = np.unravel_index(np.argmin(distances), distances.shape)
    return tuple(map(float, 0.5 * (first[a] + second[b])))


@_collection_paused()
def rotating_squares(n: int, angle: float = 0.3, amplitude: float = SQUARES_AMPLITUDE,
                     omega: float = SQUARES_OMEGA) -> Mechanism:  # fmt: skip
    """Grima and Evans's rotating squares: n×n unit squares hinged at their corners.

    Square (i, j) (column i, row j) is body ``s{i}_{j}.sq``, centred at (i·p, j·p) with
    p = cos(angle) + sin(angle), turned by +angle where i + j is even and −angle where it
    is odd.  Neighbours in a row or a column are pinned at their common corner (2n(n − 1)
    revolutes, named after the hinges); square (0, 0) is pinned to the ground at its
    centre, square (1, 0)'s centre slides in a slot of the ground along x, and a
    rotational driver turns square (0, 0): angle + amplitude·sin(omega·t).

    3n² coordinates, 4n² − 4n + 4 equations of rank 3n² (n >= 3): no degree of freedom
    and (n − 2)² redundant equations.  Closed form, with θ(t) the driven angle: square
    (i, j) is centred at (i·p(θ), j·p(θ)), p(θ) = cos θ + sin θ, turned by (−1)^(i+j)·θ.
    """
    n = _whole(n, "n", 2)
    for value, label in ((angle, "angle"), (amplitude, "amplitude"), (omega, "omega")):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not math.isfinite(value):
            raise ValueError(f"`{label}` must be a finite number, got {value!r}.")
    pitch = math.cos(angle) + math.sin(angle)
    points, bodies, joints, corners, own = {}, [], [], {}, {}
    for j in range(n):
        for i in range(n):
            turn = angle if (i + j) % 2 == 0 else -angle
            points[f"c{i}_{j}"] = (i * pitch, j * pitch)
            corners[i, j] = _corners(np.array(points[f"c{i}_{j}"]), turn)
            own[i, j] = [f"c{i}_{j}"]
            if i > 0:
                points[f"h{i - 1}_{j}"] = _shared_corner(corners[i - 1, j], corners[i, j])
                own[i - 1, j].append(f"h{i - 1}_{j}")
                own[i, j].append(f"h{i - 1}_{j}")
                joints.append(Revolute((f"s{i}_{j}.sq", f"s{i - 1}_{j}.sq"), at=f"h{i - 1}_{j}"))
            if j > 0:
                points[f"v{i}_{j - 1}"] = _shared_corner(corners[i, j - 1], corners[i, j])
                own[i, j - 1].append(f"v{i}_{j - 1}")
                own[i, j].append(f"v{i}_{j - 1}")
                joints.append(Revolute((f"s{i}_{j}.sq", f"s{i}_{j - 1}.sq"), at=f"v{i}_{j - 1}"))
    for j in range(n):
        for i in range(n):
            turn = angle if (i + j) % 2 == 0 else -angle
            bodies.append(Body(f"s{i}_{j}.sq", origin=f"c{i}_{j}", angle=turn, points=tuple(own[i, j])))
    joints.append(Revolute(("s0_0.sq", "ground"), at="c0_0"))
    joints.append(PinInSlot(("ground", "s1_0.sq"), at="c1_0", direction=(1.0, 0.0)))
    driver = RotationalDriver(("s0_0.sq", "ground"), law=Harmonic(amplitude=float(amplitude), omega=float(omega)))
    return Mechanism(points=points, bodies=bodies, joints=joints, drivers=[driver], name=f"rotating_squares_{n}x{n}")


#: Amplitude (rad) and angular frequency (rad/s) of the drivers of `parallel_bar_chain`,
#: and how many distinct phases the cells cycle through.
BAR_CHAIN_AMPLITUDE = 0.3
BAR_CHAIN_OMEGA = 2.0
BAR_CHAIN_PHASES = 7


@_collection_paused()
def parallel_bar_chain(n: int, bars: int = 3) -> Mechanism:
    """A tower of n parallelogram cells: 4n bodies, one driver per cell.

    Cell k (0 … n−1) joins plate k−1 (the ground for k = 0) at height k to plate k at
    height k + 1 by vertical bars of length 1 at x = 0, 0.5 and 1 (``a{k}``, ``b{k}``,
    ``c{k}``), pinned at both ends.  With ``bars=3`` the middle bar is a third parallel
    bar: one redundant equation per cell.  With ``bars=2`` it is welded to plate k
    instead (a `Rigid` joint, 3 equations for its 3 coordinates): the non-redundant twin,
    with the same bodies and nearly the same equations.  A rotational driver turns bar
    ``a{k}`` relative to plate k−1 to π/2 + 0.3·(sin(2t + φ_k) − sin φ_k), φ_k = 2π·(k mod
    7)/7.

    Closed form: the plates translate; with θ_k(t) the driven angle, plate k's frame
    origin (its left node) is plate k−1's plus (cos θ_k, sin θ_k), and bars a, c (and b
    with ``bars=3``) turn to θ_k, their origins at their lower nodes.
    """
    n = _whole(n, "n", 1)
    if bars not in (2, 3):
        raise ValueError(f"`bars` must be 2 or 3, got {bars!r}.")
    points = {f"{name}{k}": (x, float(k)) for k in range(n + 1) for name, x in (("L", 0.0), ("M", 0.5), ("R", 1.0))}
    bodies, joints, drivers = [], [], []
    for k in range(n):
        below, top = ("ground" if k == 0 else f"p{k - 1}"), f"p{k}"
        for name, node in (("a", "L"), ("b", "M"), ("c", "R")):
            bodies.append(Body(f"{name}{k}", origin=f"{node}{k}", angle=math.pi / 2,
                               points=(f"{node}{k}", f"{node}{k + 1}")))  # fmt: skip
        bodies.append(Body(top, origin=f"L{k + 1}", points=(f"L{k + 1}", f"M{k + 1}", f"R{k + 1}")))
        for name, node in (("a", "L"), ("b", "M"), ("c", "R")):
            if name == "b" and bars == 2:
                joints.append(Rigid((top, f"b{k}")))
                continue
            joints.append(Revolute((f"{name}{k}", below), at=f"{node}{k}"))
            joints.append(Revolute((top, f"{name}{k}"), at=f"{node}{k + 1}"))
        phase = 2 * math.pi * (k % BAR_CHAIN_PHASES) / BAR_CHAIN_PHASES
        drivers.append(
            RotationalDriver(
                (f"a{k}", below),
                law=Harmonic(amplitude=BAR_CHAIN_AMPLITUDE, omega=BAR_CHAIN_OMEGA, phase=phase,
                             offset=math.pi / 2 - BAR_CHAIN_AMPLITUDE * math.sin(phase)),
            )
        )  # fmt: skip
    return Mechanism(points=points, bodies=bodies, joints=joints, drivers=drivers,
                     name=f"parallel_bar_chain_{n}_{bars}")  # fmt: skip
