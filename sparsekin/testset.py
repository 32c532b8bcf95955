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
* `rotating_squares`, `rotating_rectangles` — Grima and Evans's auxetic metamaterials:
  squares (rectangles) hinged at their corners, one driver, (n − 2)² redundant equations;
  the lattice scales with the opening angle (Poisson's ratio −1 for squares).
* `rotating_rectangles_motif` — the rotating rectangles as a grid of 2 × 2 motifs, as
  ``examples/rotating_squares.toml`` writes the squares; `rotating_lattice_motion` is the
  closed form of all three.
* `parallel_bar_chain` — a tower of parallelogram cells with three parallel bars each (one
  redundant equation per cell), or two (``bars=2``, the non-redundant twin).

The chains and the grids are a unit repeated (`sparsekin.model.units.Repeat`), as their
model files ``examples/task5_chain.toml``, ``examples/four_bar_chain.toml``,
``examples/lattice.toml`` and ``examples/rotating_squares.toml`` write them: a million
bodies are a few arrays, not a million objects.
"""

from __future__ import annotations

import dataclasses
import gc
import math
from contextlib import contextmanager

import numpy as np

from .model.elements import PinInSlot, Revolute, Rigid, RotationalDriver, Translational, TranslationalDriver
from .model.laws import Harmonic, Linear
from .model.mechanism import Body, Mechanism
from .model.units import Cycle, OnCopies, Repeat, Unit

__all__ = ["TASK5_POINTS", "task5", "task5_chain", "task5_chain_unit", "four_bar_chain", "n_four_bar", "lattice",
           "lattice_unit", "rotating_squares", "rotating_squares_unit", "rotating_rectangles",
           "rotating_rectangles_motif", "rotating_lattice_motion", "parallel_bar_chain", "task5_unit_phases",
           "with_masses"]

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


def _whole(value, label: str, smallest: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < smallest:
        raise ValueError(f"`{label}` must be a whole number >= {smallest}, got {value!r}.")
    return int(value)


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
    n_units = _whole(n_units, "n_units", 1)
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
    n_loops = _whole(n_loops, "n_loops", 1)
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


def n_four_bar(n_loops: int, initial_speed: float = 1.0, gravity: float = 9.81) -> Mechanism:
    """The IFToMM A02 N-four-bar for forward dynamics: 2·n+1 uniform bars (1 m, 1 kg), no driver.

    The cranks stand vertical at the start, pinned to the ground at (k, 0); the couplers
    join their tips.  Every bar has its centre of mass at its middle and the inertia
    m L²/12 there; gravity pulls along −y.  The tip B0 of ``crank0`` starts at
    `initial_speed` m/s along +x: every crank turns at −`initial_speed` rad/s and every
    coupler translates at that speed (the bodies' `velocity`, consistent as given).
    Copy k (``u{k}.crank``, ``u{k}.coupler``) is built as in `four_bar_chain`.
    """
    n_loops = _whole(n_loops, "n_loops", 1)
    half, inertia = 0.5, 1.0 / 12.0
    crank = {"mass": 1.0, "inertia": inertia, "velocity": (0.0, 0.0, -initial_speed)}
    loop = Unit(
        "loop",
        points={"T": (0.0, 1.0), "P": (1.0, 0.0), "Q": (1.0, 1.0)},
        bodies=[Body("crank", origin="P", angle=math.pi / 2, points=("P", "Q"), com=(1.0, half), **crank),
                Body("coupler", origin="T", points=("T", "Q"), mass=1.0, inertia=inertia, com=(half, 1.0),
                     velocity=(initial_speed, 0.0, 0.0))],
        joints=[Revolute(("crank", "ground"), at="P"), Revolute(("crank", "coupler"), at="Q"),
                Revolute(("coupler", "prev.crank"), at="T")],
    )  # fmt: skip
    return Mechanism(
        points={"O0": (0.0, 0.0), "B0": (0.0, 1.0)},
        bodies=[Body("crank0", origin="O0", angle=math.pi / 2, points=("O0", "B0"), com=(0.0, half), **crank)],
        joints=[Revolute(("crank0", "ground"), at="O0")],
        repeats=[Repeat(loop, count=int(n_loops), prefix="u", offset=(1.0, 0.0), first={"prev.crank": "crank0"})],
        gravity=(0.0, -float(gravity)),
        name=f"n_four_bar_{n_loops}",
    )


#: Amplitude (rad) and angular frequency (rad/s) of the row actuators of `lattice`.
LATTICE_AMPLITUDE = 0.3
LATTICE_OMEGA = 2.0


#: Prefix of the lattice's copies: cell (i, j) is column i, row j + 1 (``c3_0.V``).
LATTICE_PREFIX = "c"


def lattice_unit(rows: int) -> tuple[Unit, dict]:
    """The lattice's cell and the `vary` of its row actuators (one phase per row).

    Copy (i, j) holds the vertical bar V from node (j, i) (its point B) to node (j + 1, i)
    (T), and — in every column but the last — the horizontal bar H from T to the next
    column's top node (R).  V is pinned to the V below (the ground in row 0) at B; H to V
    and to the next column's V (written by that copy as ``left.H``) at T.  Column 0 drives
    V relative to the H below it (the ground in row 0).
    """
    phases = [2 * np.pi * r / max(rows, 1) for r in range(rows)]
    cell = Unit(
        "cell",
        points={"B": (0.0, 0.0), "T": (0.0, 1.0), "R": (1.0, 1.0)},
        bodies=[Body("V", origin="B", angle=math.pi / 2, points=("B", "T")),
                OnCopies(Body("H", origin="T", points=("T", "R")), i=(0, -2))],
        joints=[Revolute(("V", "below.V"), at="B"), Revolute(("H", "V"), at="T"), Revolute(("left.H", "V"), at="T")],
        drivers=[OnCopies(RotationalDriver(("V", "below.H"), law=Harmonic(amplitude=LATTICE_AMPLITUDE,
                                                                           omega=LATTICE_OMEGA)), i=0)],
    )  # fmt: skip
    vary = {"drivers[0].law.phase": Cycle([float(phase) for phase in phases]),
            "drivers[0].law.offset": Cycle([math.pi / 2 - LATTICE_AMPLITUDE * math.sin(phase) for phase in phases])}
    return cell, vary


def lattice(rows: int, cols: int) -> Mechanism:
    """A grid of rows × cols parallelogram cells on a fixed base: rows·(2·cols+1) bodies.

    Node (r, c) starts at (c, r).  Row r (1 … rows) has vertical bars from node (r-1, c)
    to (r, c) and horizontal bars from (r, c) to (r, c+1); the bottom nodes are ground
    pivots.  Pinned at the nodes, the grid has one degree of freedom per row (its
    shear); an actuator at the left edge drives the angle of the row's first vertical bar
    relative to the bar below it to π/2 + 0.3 (sin(2 t + phase_r) - sin(phase_r)), so the
    grid starts as drawn.  Every vertical bar of row r turns with it and the horizontal
    bars translate; the angles stay within 0.6 rad of vertical, far from the folded
    positions (a bar horizontal, 1.57 rad away).  Interior nodes join four bars, so the
    Jacobian graph is a two-dimensional mesh.

    Built as a grid repeat (``examples/lattice.toml``) of `lattice_unit` over cols + 1
    columns and `rows` rows: the bars of row r, column c are ``c{c}_{r-1}.V`` and
    ``c{c}_{r-1}.H``, node (r, c) is point ``c{c}_{r-1}.T`` (r >= 1) or ``c{c}_0.B`` (r = 0).
    """
    rows, cols = _whole(rows, "rows", 1), _whole(cols, "cols", 1)
    cell, vary = lattice_unit(int(rows))
    repeat = Repeat(cell, count=(int(cols) + 1, int(rows)), prefix=LATTICE_PREFIX,
                    offset=((1.0, 0.0), (0.0, 1.0)), vary=vary, boundary={"below.V": "ground", "below.H": "ground"})  # fmt: skip
    return Mechanism(points={}, bodies=[], repeats=[repeat], name=f"lattice_{rows}x{cols}")


def with_masses(mechanism: Mechanism, mass: float, inertia: float, gravity=(0.0, -9.81), velocity=None) -> Mechanism:
    """`mechanism` for forward dynamics: every body of its repeats' units given `mass` (kg),
    `inertia` (kg·m² about its centre of mass) and, if given, the initial `velocity` ``(vx, vy, ω)``
    of its origin, under `gravity` (m/s²); its own bodies unchanged.

    >>> heavy = with_masses(lattice(2, 3), 1.0, 1.0 / 12.0)
    >>> heavy.gravity, heavy.repeats[0].unit.bodies[0].mass
    ((0.0, -9.81), 1.0)
    """

    def heavy(body):
        return dataclasses.replace(body, mass=mass, inertia=inertia, velocity=velocity)

    repeats = []
    for repeat in mechanism.repeats:
        bodies = tuple(dataclasses.replace(b, element=heavy(b.element)) if isinstance(b, OnCopies) else heavy(b)
                       for b in repeat.unit.bodies)  # fmt: skip
        repeats.append(dataclasses.replace(repeat, unit=dataclasses.replace(repeat.unit, bodies=bodies)))
    return dataclasses.replace(mechanism, repeats=tuple(repeats), gravity=tuple(gravity))


#: Prefix of the rotating squares' copies: square (i, j) is body ``s{i}_{j}.sq``.
SQUARES_PREFIX = "s"
#: Default amplitude (rad) and angular frequency (rad/s) of the rotating squares' driver:
#: with the drawn angle 0.3 rad the opening stays within 0.1 … 0.5 rad, far from the
#: closed (0) and the aligned (π/2) states where the lattice locks.
SQUARES_AMPLITUDE = 0.2
SQUARES_OMEGA = 1.0


def _turned(angle: float, x: float, y: float) -> tuple[float, float]:
    """(x, y) turned by `angle`."""
    cosine, sine = math.cos(angle), math.sin(angle)
    return (cosine * x - sine * y, sine * x + cosine * y)


def _rotating_unit(name: str, body: str, angle: float, width: float, height: float) -> tuple[Unit, dict]:
    """One width × height rectangle of a rotating-rectangles lattice and its checkerboard `vary`.

    The rectangle `body` turns by +angle where i + j is even and −angle where it is odd
    (the cycles of its drawn angle and of its points).  Its points: its centre C, its
    corners (``ll``, ``lr``, ``ur``, ``ul`` in its own frame) and the two corners it
    shares with its neighbours: L with the one on its left, D with the one below.
    """
    signs = (1.0, -1.0)  # i + j even, odd
    half = (width / 2, height / 2)
    corners = {"ll": (-half[0], -half[1]), "lr": (half[0], -half[1]), "ur": half, "ul": (-half[0], half[1])}
    # the corner shared with the left neighbour: ul of a +angle rectangle, ll of a −angle one;
    # with the one below: ll of a +angle rectangle, lr of a −angle one
    shared = {"L": ("ul", "ll"), "D": ("ll", "lr")}
    points = {"C": (0.0, 0.0), **{name_: _turned(angle, *xy) for name_, xy in corners.items()}}
    points |= {name_: points[pair[0]] for name_, pair in shared.items()}
    vary = {f"points.{name_}": Cycle([_turned(s * angle, *xy) for s in signs]) for name_, xy in corners.items()}
    vary |= {f"points.{name_}": Cycle([_turned(s * angle, *corners[corner]) for s, corner in zip(signs, pair)])
             for name_, pair in shared.items()}  # fmt: skip
    vary[f"bodies.{body}.angle"] = Cycle([s * angle for s in signs])
    unit = Unit(
        name,
        points=points,
        bodies=[Body(body, origin="C", angle=angle, points=tuple(corners))],
        joints=[Revolute((body, f"left.{body}"), at="L"), Revolute((body, f"below.{body}"), at="D")],
    )
    return unit, vary


def rotating_squares_unit(angle: float = 0.3) -> tuple[Unit, dict]:
    """One unit square ``sq`` of the rotating-squares lattice and its checkerboard `vary`:
    turned by +angle where i + j is even, −angle where it is odd; points C (centre),
    ``ll``, ``lr``, ``ur``, ``ul`` (corners), L and D (the corners shared with the square
    on the left and the one below)."""
    return _rotating_unit("square", "sq", angle, 1.0, 1.0)


def _rotating_lattice(unit: Unit, vary: dict, body: str, prefix: str, n: tuple[int, int], pitch: tuple[float, float],
                      amplitude: float, omega: float, name: str) -> Mechanism:  # fmt: skip
    """The grid of `unit` with its ground joints and driver: copy (0, 0) pinned at its
    centre and driven relative to the ground, the centre of copy (1, 0) in a slot along x."""
    repeat = Repeat(unit, count=n, prefix=prefix, offset=((pitch[0], 0.0), (0.0, pitch[1])), vary=vary)
    first, second = f"{prefix}0_0", f"{prefix}1_0"
    return Mechanism(
        points={},
        bodies=[],
        joints=[Revolute((f"{first}.{body}", "ground"), at=f"{first}.C"),
                PinInSlot(("ground", f"{second}.{body}"), at=f"{second}.C", direction=(1.0, 0.0))],
        drivers=[RotationalDriver((f"{first}.{body}", "ground"), law=Harmonic(amplitude=amplitude, omega=omega))],
        repeats=[repeat],
        name=name,
    )  # fmt: skip


def rotating_squares(n: int, angle: float = 0.3, amplitude: float = SQUARES_AMPLITUDE,
                     omega: float = SQUARES_OMEGA) -> Mechanism:  # fmt: skip
    """Grima and Evans' rotating squares: n × n unit squares hinged at their corners.

    Square (i, j) (column i, row j; body ``s{i}_{j}.sq``) is centred at (i·p, j·p),
    p = cos(angle) + sin(angle), and turned by +angle where i + j is even, −angle where it
    is odd; neighbours in a row or a column are pinned at their common corner
    (2·n·(n−1) revolutes).  Square (0, 0) is pinned to the ground at its centre, the
    centre of square (1, 0) slides in a slot of the ground along x, and square (0, 0) is
    driven relative to the ground: θ(t) = angle + amplitude · sin(omega · t).

    3·n² coordinates and 4·n² − 4·n + 4 equations of rank 3·n²: no degree of freedom and
    (n − 2)² redundant equations (states of self-stress).  The exact motion: square
    (i, j) is centred at (i·p(θ), j·p(θ)) with p(θ) = cos θ + sin θ and turned by
    (−1)^(i+j)·θ — the lattice's width and height scale alike, Poisson's ratio −1.
    """
    n = _whole(n, "n", 2)
    unit, vary = rotating_squares_unit(angle)
    pitch = math.cos(angle) + math.sin(angle)
    return _rotating_lattice(unit, vary, "sq", SQUARES_PREFIX, (n, n), (pitch, pitch), amplitude, omega,
                             f"rotating_squares_{n}x{n}")  # fmt: skip


def rotating_rectangles(ni: int, nj: int, width: float = 1.0, height: float = 0.5, angle: float = 0.3,
                        amplitude: float = SQUARES_AMPLITUDE, omega: float = SQUARES_OMEGA) -> Mechanism:  # fmt: skip
    """Rotating rectangles (Grima, Gatt, Alderson and Evans 2005): ni × nj rectangles of
    `width` × `height` hinged at their corners, built and held as `rotating_squares`.

    Rectangle (i, j) (body ``r{i}_{j}.rect``) is turned by (−1)^(i+j)·θ and centred at
    (i·a(θ), j·b(θ)) with a(θ) = width·cos θ + height·sin θ and b(θ) = width·sin θ +
    height·cos θ: the lattice opens unequally in x and y, with Poisson's ratio
    ν = −(d ln b / d ln a) = −(a/b)·(width·cos θ − height·sin θ)/(height·cos θ − width·sin θ),
    −1 only for squares.
    """
    ni, nj = _whole(ni, "ni", 2), _whole(nj, "nj", 2)
    for value, label in ((width, "width"), (height, "height")):
        if not (isinstance(value, (int, float)) and value > 0):
            raise ValueError(f"`{label}` must be a positive length, got {value!r}.")
    unit, vary = _rotating_unit("rectangle", "rect", angle, float(width), float(height))
    pitch = (width * math.cos(angle) + height * math.sin(angle), width * math.sin(angle) + height * math.cos(angle))
    return _rotating_lattice(unit, vary, "rect", "r", (ni, nj), pitch, amplitude, omega,
                             f"rotating_rectangles_{ni}x{nj}")  # fmt: skip


def rotating_rectangles_motif(copies_i: int, copies_j: int, width: float = 1.0, height: float = 0.6,
                              angle: float = 0.3, amplitude: float = SQUARES_AMPLITUDE,
                              omega: float = SQUARES_OMEGA) -> Mechanism:  # fmt: skip
    """`rotating_rectangles` of 2·copies_i × 2·copies_j rectangles written as a grid of 2 × 2
    motifs: copy (i, j) holds rectangles a, b (bottom left, right) and c, d (top left,
    right), bodies ``m{i}_{j}.a`` …, hinged to each other and to the copies on their left
    and below; the same ground joints and driver on rectangle a of copy (0, 0).

    Rectangle (I, J) = (2i + column in the motif, 2j + row) follows the closed form of
    `rotating_rectangles` (`rotating_lattice_motion`); only the order of the bodies and of
    the equations differs.
    """
    copies_i, copies_j = _whole(copies_i, "copies_i", 1), _whole(copies_j, "copies_j", 1)
    across = width * math.cos(angle) + height * math.sin(angle)
    up = width * math.sin(angle) + height * math.cos(angle)
    half = ((-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5))

    def centre(column: int, row: int) -> tuple[float, float]:
        return (column * across, row * up)

    def corners(column: int, row: int) -> np.ndarray:
        turn = angle if (column + row) % 2 == 0 else -angle
        return np.array(centre(column, row)) + [_turned(turn, x * width, y * height) for x, y in half]

    def shared(first: tuple[int, int], second: tuple[int, int]) -> tuple[float, float]:
        distance = np.linalg.norm(corners(*first)[:, None] - corners(*second)[None], axis=-1)
        return tuple(float(x) for x in corners(*first)[np.unravel_index(np.argmin(distance), distance.shape)[0]])

    motif = {"a": (0, 0), "b": (1, 0), "c": (0, 1), "d": (1, 1)}
    hinges = {"ab": ("a", "b", (1, 0)), "ac": ("a", "c", (0, 1)), "bd": ("b", "d", (1, 1)), "cd": ("c", "d", (1, 1)),
              "a_left": ("a", "left.b", (-1, 0)), "c_left": ("c", "left.d", (-1, 1)),
              "a_below": ("a", "below.c", (0, -1)), "b_below": ("b", "below.d", (1, -1))}  # fmt: skip
    points = {f"C{name}": centre(*place) for name, place in motif.items()}
    points |= {name: shared(motif[first], neighbour) for name, (first, _, neighbour) in hinges.items()}
    unit = Unit(
        "motif",
        points=points,
        bodies=[Body(name, origin=f"C{name}", angle=angle if sum(place) % 2 == 0 else -angle)
                for name, place in motif.items()],
        joints=[Revolute((first, second), at=name) for name, (first, second, _) in hinges.items()],
    )  # fmt: skip
    repeat = Repeat(unit, count=(copies_i, copies_j), prefix="m", offset=((2 * across, 0.0), (0.0, 2 * up)))
    return Mechanism(
        points={},
        bodies=[],
        joints=[Revolute(("m0_0.a", "ground"), at="m0_0.Ca"),
                PinInSlot(("ground", "m0_0.b"), at="m0_0.Cb", direction=(1.0, 0.0))],
        drivers=[RotationalDriver(("m0_0.a", "ground"), law=Harmonic(amplitude=amplitude, omega=omega))],
        repeats=[repeat],
        name=f"rotating_rectangles_{2 * copies_i}x{2 * copies_j}_motif",
    )  # fmt: skip


def rotating_lattice_motion(ni: int, nj: int, times, width: float = 1.0, height: float = 1.0, angle: float = 0.3,
                            amplitude: float = SQUARES_AMPLITUDE, omega: float = SQUARES_OMEGA):  # fmt: skip
    """The exact motion of `rotating_squares` (width = height = 1), `rotating_rectangles`
    and `rotating_rectangles_motif`: rectangle (i, j) centred at (i·a(θ), j·b(θ)) and turned
    by (−1)^(i+j)·θ, a = width·cos θ + height·sin θ, b = width·sin θ + height·cos θ,
    θ = angle + amplitude·sin(omega·t) (a'' = −a, b'' = −b in θ).

    Returns positions, velocities and accelerations, each of shape (len(times), ni, nj, 3):
    [t, i, j] = (x, y, angle) of rectangle (i, j) and their time derivatives.
    """
    times = np.asarray(times, dtype=float)
    theta = angle + amplitude * np.sin(omega * times)
    rate = amplitude * omega * np.cos(omega * times)
    accel = -amplitude * omega**2 * np.sin(omega * times)
    across = width * np.cos(theta) + height * np.sin(theta)
    up = width * np.sin(theta) + height * np.cos(theta)
    across_d, up_d = height * np.cos(theta) - width * np.sin(theta), width * np.cos(theta) - height * np.sin(theta)
    i, j = np.meshgrid(np.arange(ni), np.arange(nj), indexing="ij")
    sign = (-1.0) ** (i + j)
    out = []
    for a, b, turn in ((across, up, theta), (across_d * rate, up_d * rate, rate),
                       (across_d * accel - across * rate**2, up_d * accel - up * rate**2, accel)):  # fmt: skip
        out.append(np.stack(np.broadcast_arrays(i * a[:, None, None], j * b[:, None, None],
                                                sign * turn[:, None, None]), axis=-1))  # fmt: skip
    return tuple(out)


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
            welded = name == "b" and bars == 2  # carries only its upper end: it is not pinned below
            ends = (f"{node}{k + 1}",) if welded else (f"{node}{k}", f"{node}{k + 1}")
            bodies.append(Body(f"{name}{k}", origin=f"{node}{k}", angle=math.pi / 2, points=ends))
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
