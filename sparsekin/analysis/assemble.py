"""Assembly at the first time: from the drawing onto the equations, on the branch nearest it.

A drawing need not satisfy the equations at t = 0: its points only approximate the bodies'
`lengths`, or the drivers' laws start away from the drawn values (a copy drawn at one
phase of its crank and driven at another).  Plain Newton from the drawing fails once the
drawing is far (a crank 240° away) and may land on another assembly branch.  `assemble`
follows the Newton homotopy from the drawing q₀ instead,

    H(q, s) = Φ(q, t) − (1 − s) · Φ(q₀, t) = 0,    s from 0 to 1,

which the drawing satisfies at s = 0 and the mechanism at s = 1: every residual (the gap
of each joint, each driver's distance from its law) shrinks in proportion along the way,
so the path stays on the branch of the drawing.  Each step is predicted by a secant
through the last two solutions and corrected by Newton (sparse LU); a step that Newton
cannot correct is halved, a step it corrects easily is doubled.  A drawing that already
satisfies the equations costs one residual evaluation.

`check_model` reports the result; the run (`sparsekin.solve.kinematics.run_kinematics`)
starts from it (`start_discretization`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..engine.assembly import Assembler
from ..engine.discretization import Discretization
from ..engine.linalg import SingularMatrix, SuperLUSolver
from ..engine.newton import NoConvergence, solve_positions
from ..engine.pattern import build_point_map
from ..engine.reduced import ReducedSystem, kept_equations
from ..model.geometry import to_global
from ..model.mechanism import Mechanism

__all__ = ["Assembly", "AssemblyFailed", "assemble", "start_discretization", "point_moves", "reduced_system",
           "MOST_LISTED_MOVES"]

#: Convergence tolerance of the assembly: lengths relative to the model size, angles in rad.
ASSEMBLY_TOLERANCE = 1e-12
#: Tolerance of the Newton corrections between the drawing and the end of the path.
PATH_TOLERANCE = 1e-8
#: Newton corrections allowed at one step of the path (and at its end).
STEP_MAXITER = 10
#: The path is abandoned when a step would be shorter than this share of it.
SMALLEST_STEP = 1.0 / 4096
#: A step corrected in at most this many Newton corrections doubles the next one.
EASY_CORRECTIONS = 3
#: Largest change of a coordinate over one step (angles in rad, lengths relative to the
#: model size): a longer step is halved, so that Newton never jumps to another branch.
MAX_STEP_CHANGE = 0.1
#: Points whose moves `point_moves` lists, the largest first.
MOST_LISTED_MOVES = 8
#: Above this many named points, `point_moves` does not locate them all.
MOST_LOCATED_POINTS = 200_000


class AssemblyFailed(Exception):
    """The path from the drawing stopped: `reason` in words, `share` how far it got (0–1),
    `coordinates` where it stopped."""

    def __init__(self, reason: str, share: float, coordinates: np.ndarray) -> None:
        self.reason, self.share, self.coordinates = reason, share, coordinates
        super().__init__(reason)


@dataclass(frozen=True)
class Assembly:
    """The mechanism assembled from its drawing.

    Attributes
    ----------
    coordinates : ndarray, shape (n_coordinates,)
        The assembled frames ``(x, y, angle)`` of every body.
    drawn : ndarray, shape (n_coordinates,)
        The drawn frames.
    steps : int
        Steps along the path from the drawing (0 when the drawing satisfied the equations).
    corrections : int
        Newton corrections over all steps.
    residual : float
        The largest weighted residual at the end.
    """

    coordinates: np.ndarray
    drawn: np.ndarray
    steps: int
    corrections: int
    residual: float


class _TooLong(Exception):
    """A step of the path that changes a coordinate by more than `MAX_STEP_CHANGE`."""

    reason = "the steps of the path from the drawing stay too long"


class _Homotopy:
    """``H(q, s) = Φ(q) − (1 − s) Φ(q₀)`` of a system (an assembler or a reduced system),
    as a system of its own for `solve_positions`."""

    def __init__(self, system, start: np.ndarray) -> None:
        self.system = system
        self.weights = system.weights
        system.fill_residual_jacobian(start)
        self.offset = system.residual.copy()
        self.remaining = 1.0  # 1 − s
        self.residual = np.empty_like(self.offset)

    def fill_residual_jacobian(self, q: np.ndarray) -> float:
        self.system.fill_residual_jacobian(q)
        np.subtract(self.system.residual, self.remaining * self.offset, out=self.residual)
        return float(np.max(np.abs(self.residual) * self.weights, initial=0.0))

    @property
    def jacobian(self):
        return self.system.jacobian


def assemble(system, drawn: np.ndarray, coordinate_weights: np.ndarray, *,
             tolerance: float = ASSEMBLY_TOLERANCE) -> Assembly:  # fmt: skip
    """Follow the path from the drawing `drawn` onto the equations of `system`.

    Parameters
    ----------
    system
        An `Assembler` set to the time of the assembly, or a `ReducedSystem` of one
        (redundant equations left out, free coordinates held); square.
    drawn : ndarray, shape (n_coordinates,)
        The drawn frames.
    coordinate_weights : ndarray, shape (n_coordinates,)
        `ConstraintPattern.coordinate_weights`: how changes of the coordinates compare.
    tolerance : float
        Largest weighted residual at the end.

    Returns
    -------
    Assembly

    Raises
    ------
    AssemblyFailed
        If a step of the path cannot be corrected even when short.
    """
    drawn = np.asarray(drawn, dtype=float)
    homotopy = _Homotopy(system, drawn)
    start = float(np.max(np.abs(homotopy.offset) * homotopy.weights, initial=0.0))
    if not start > tolerance:  # also NaN: plain Newton from the drawing says what is wrong
        return Assembly(drawn.copy(), drawn, 0, 0, start)
    solver = SuperLUSolver()
    q, previous, done, step, last_step = drawn.copy(), None, 0.0, 1.0, 1.0
    steps = corrections = 0
    while done < 1.0:
        step = min(step, 1.0 - done)
        target = 1.0 if 1.0 - done - step <= SMALLEST_STEP / 2 else done + step
        guess = q.copy() if previous is None else q + (q - previous) * ((target - done) / last_step)
        homotopy.remaining = 1.0 - target
        try:
            taken = solve_positions(homotopy, solver, guess, tolerance if target == 1.0 else PATH_TOLERANCE,
                                    STEP_MAXITER)  # fmt: skip
            if np.max(np.abs(guess - q) * coordinate_weights, initial=0.0) > MAX_STEP_CHANGE:
                raise _TooLong
        except (NoConvergence, SingularMatrix, _TooLong) as failure:
            step = min(step, target - done) / 2.0
            if step < SMALLEST_STEP:
                reason = getattr(failure, "reason", "the Jacobian is singular")
                where = f"{reason} at {100.0 * done:.3g} % of the way from the drawing"
                raise AssemblyFailed(where, done, q) from None
            continue
        corrections += taken
        steps += 1
        previous, q, last_step, done = q, guess, target - done, target
        if taken <= EASY_CORRECTIONS:
            step = 2.0 * last_step
    # One more correction with the factorization at hand brings the residual to the
    # rounding floor (a rank analysis there is not blurred by a residual below the tolerance).
    q -= solver.solve(homotopy.residual)
    norm = homotopy.fill_residual_jacobian(q)
    return Assembly(q, drawn, steps, corrections, norm)


def start_discretization(discretization: Discretization, t: float) -> Discretization:
    """`discretization` whose constraints start (`~ConstraintPattern.initial_coordinates`)
    at the mechanism assembled at `t` from its drawing, when the drawing does not satisfy
    the equations there; `discretization` itself otherwise, or when the path fails (plain
    Newton from the drawing then says why it cannot start).

    Square constraints only (a model with redundant equations starts from its drawing).
    """
    pattern = discretization.constraints
    if pattern.n_equations != pattern.n_coordinates or pattern.n_equations == 0:
        return discretization
    assembler = Assembler(discretization)
    assembler.set_time(float(t))
    try:
        assembly = assemble(assembler, pattern.initial_coordinates, pattern.coordinate_weights)
    except AssemblyFailed:
        return discretization
    if assembly.steps == 0:
        return discretization
    started = dataclasses.replace(pattern, initial_coordinates=assembly.coordinates)
    return dataclasses.replace(discretization, constraints=started)


def point_moves(mechanism: Mechanism, drawn: np.ndarray, coordinates: np.ndarray,
                most: int = MOST_LISTED_MOVES):  # fmt: skip
    """How far the named points moved from the drawing to `coordinates`, the largest first:
    ``(name, distance)`` pairs (at most `most`) and the number of points that moved
    (more than 1e-12 of the model size); None when the model has too many points to
    locate them all."""
    names = build_point_map(mechanism)
    if len(names.names) > MOST_LOCATED_POINTS:
        return None
    point_names = list(names.names)
    body, local = names.arrays()
    frames = np.asarray(coordinates, dtype=float).reshape(-1, 3)
    drawn_points = mechanism.positions(point_names) if point_names else np.zeros((0, 2))
    now = drawn_points.copy()
    moving = body >= 0
    now[moving] = to_global(frames[body[moving]], local[moving])
    distance = np.hypot(*(now - drawn_points).T) if len(body) else np.zeros(0)
    scale = max(float(np.abs(drawn_points).max(initial=0.0)), 1e-3)
    order = np.argsort(-distance, kind="stable")
    moved = int(np.sum(distance > 1e-12 * scale))
    listed = [(point_names[k], float(distance[k])) for k in order[: min(most, moved)].tolist()]
    return listed, moved


def reduced_system(assembler: Assembler, analysis, drawn: np.ndarray) -> ReducedSystem:
    """The system `check_model` assembles: the redundant equations left out, the free
    coordinates held at their drawn values."""
    kept = kept_equations(assembler.pattern.n_equations, analysis.redundant_rows)
    held = analysis.free_coordinates
    return ReducedSystem(assembler, kept, held, drawn[held])

