"""The workspace of a two-actuator mechanism: where a point gets over a grid of two drivers' values.

Driver values are the driven quantities themselves (a stroke in m, an angle in rad), not
times.  From the configuration solved at t = 0 (driver values ``(a0, b0)``):

1. the *spine*: driver b moves from b0 to every grid value of its range, up then down,
   with driver a held at a0;
2. each *row*: from the spine's configuration at ``(a0, b_j)``, driver a moves to every
   grid value of its range, up then down, with driver b held at b_j;
3. each *column* that the rows did not fill: from its solved point nearest b0, driver b
   moves up then down with driver a held, to the grid points the rows did not reach.

Every move is a continuation by `sparsekin.solve.stepper.KinematicStepper` (Taylor predictor,
Newton, branch guard, step halving) in a pseudo-time equal to the distance travelled by
the moving driver; the other drivers stay at their values at t = 0.  A move that meets a
singular configuration stops there: the driver values at which it stopped form the
*singular boundary*, and the grid values beyond are not reached from the start along
these paths (status ``beyond_singular``).  A grid point whose configuration puts a joint
or a distance driver outside its ``limits`` is solved but not reachable
(``outside_limits``).

>>> import sparsekin as sk
>>> space = sk.workspace(sk.load_model("examples/task5.toml"), "K", grid=5,
...                      ranges=[(0.78, 0.87), (1.03, 1.12)])
>>> space.status.shape, space.positions.shape
((5, 5), (5, 5, 2))
>>> int((space.status == "reachable").sum()) > 0
True
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConvergenceError, ModelError, SingularJacobianError
from ..model.geometry import to_global
from ..model.laws import Linear
from ..model.mechanism import Mechanism

__all__ = ["Workspace", "workspace", "WORKSPACE_STATUSES", "RANGE_WIDENING"]

#: A grid point's status: solved within every limit; solved, but outside some element's
#: limits; not reached because a singular configuration lies on the way; not reached
#: because Newton failed on the way for another reason.
WORKSPACE_STATUSES = ("reachable", "outside_limits", "beyond_singular", "no_convergence")
#: Without `ranges`, each driver's range is the span its law covers over ``[analysis]``'s
#: time (0 … t_end), widened about its middle by this factor, so that the grid shows where
#: the motion could go beyond the one analysed.
RANGE_WIDENING = 2.0
#: Samples of a law over 0 … t_end to find its span.
RANGE_SAMPLES = 1001


@dataclass(frozen=True, eq=False)
class Workspace:
    """A point's positions over a grid of two drivers' values.

    Attributes
    ----------
    point : str
    drivers : tuple of str
        Labels of the two drivers (a, b), e.g. ``drivers[0] (stroke of joint "actuator1")``.
    values : tuple of ndarray
        Grid values of driver a, shape (n_a,), and of driver b, shape (n_b,): m or rad.
    start : tuple of float
        The drivers' values at t = 0, where every move starts.
    status : ndarray of str, shape (n_b, n_a)
        One of `WORKSPACE_STATUSES` per grid point (row j: driver b at ``values[1][j]``).
    positions : ndarray, shape (n_b, n_a, 2)
        The point's position at each grid point solved, m (NaN where not reached).
    boundary : ndarray, shape (n_boundary, 2)
        Driver values (a, b) at which a move met a singular configuration.
    boundary_positions : ndarray, shape (n_boundary, 2)
        The point's position at the last configuration solved before each, m.
    limits_left : tuple of str
        The elements whose limits some grid point leaves.
    """

    point: str
    drivers: tuple[str, str]
    values: tuple[np.ndarray, np.ndarray]
    start: tuple[float, float]
    status: np.ndarray
    positions: np.ndarray
    boundary: np.ndarray
    boundary_positions: np.ndarray
    limits_left: tuple[str, ...] = ()

    @property
    def reachable(self) -> np.ndarray:
        """Mask of the reachable grid points, shape (n_b, n_a)."""
        return self.status == "reachable"


def workspace(mechanism: Mechanism, point: str, drivers: Sequence = (0, 1), grid=50, ranges=None,
              tolerance: float | None = None) -> Workspace:  # fmt: skip
    """The positions of `point` over a grid of the values of two drivers.

    Parameters
    ----------
    mechanism : Mechanism
        A mechanism whose repeated units (if any) have no drivers.  The two drivers moved
        must drive one quantity each; the others are held at their values at t = 0, each
        law of a driver of several (a path driver) on its own.
    point : str
        A named point.
    drivers : pair of int or str
        The two drivers (index, name or ``drivers[i]``); default the first two.
    grid : int or pair of int
        Grid values per driver (at least 2).
    ranges : pair of (start, stop), optional
        Each driver's range of values, m or rad.  Default: the span of its law over
        ``[analysis]`` 0 … t_end, widened by `RANGE_WIDENING` about its middle.
    tolerance : float, optional
        Newton's tolerance (as in `solve_kinematics`).

    Returns
    -------
    Workspace

    Raises
    ------
    ModelError
        For an unknown point or driver, a moved driver with several laws, a mechanism
        whose repeated units have drivers, or a range that cannot be found.
    ConvergenceError
        If the mechanism cannot be assembled at t = 0.
    """
    from ..engine.newton import DEFAULT_TOLERANCE
    from ..engine.outputs import element_index, own_coordinates
    from ..engine.pattern import build_output_pattern, build_pattern, build_point_map, limited_elements
    from ..solve.stepper import KinematicStepper

    if not isinstance(mechanism, Mechanism):
        raise TypeError(f"`mechanism` must be a Mechanism, got {type(mechanism).__name__}.")
    if not isinstance(point, str) or point not in mechanism.points:
        raise ModelError(f'unknown point "{point}"', element="point")
    if any(copies.unit.drivers for copies in mechanism.copies):
        raise ModelError(
            "the workspace moves the model's own drivers; this model's repeated units have drivers too"
        )
    if isinstance(drivers, str) or not isinstance(drivers, Sequence) or len(drivers) != 2:
        raise ModelError(f"expected two drivers, got {drivers!r}", element="drivers")
    try:
        chosen = tuple(element_index(mechanism, "drivers", d) for d in drivers)
    except KeyError as error:
        raise ModelError(error.args[0], element="drivers") from None
    if chosen[0] == chosen[1]:
        raise ModelError(f"expected two different drivers, got drivers[{chosen[0]}] twice", element="drivers")
    for k in chosen:
        if mechanism.drivers[k].law_fields != ("law",):
            raise ModelError(f"drivers[{k}] drives {len(mechanism.drivers[k].law_fields)} quantities; expected one",
                             element="drivers")  # fmt: skip
    sizes = (grid, grid) if not isinstance(grid, Sequence) else tuple(grid)
    if len(sizes) != 2 or any(
        isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2 for n in sizes
    ):
        raise ModelError(f"expected a whole number >= 2 (or two), got {grid!r}", element="grid")
    tolerance = DEFAULT_TOLERANCE if tolerance is None else tolerance

    pattern = build_pattern(mechanism)
    first = KinematicStepper(mechanism, tolerance=tolerance, pattern=pattern)
    first.start(0.0)
    q0 = first.coordinates.copy()
    at_start = np.array(first.assembler.driver_values, dtype=float)  # every driven row at t = 0
    row_of = {int(d): int(r) for r, d in enumerate(pattern.driven_driver.tolist())}
    start = tuple(float(at_start[row_of[k]]) for k in chosen)
    if ranges is None:
        ranges = [_default_range(mechanism, k, float(pattern.driven_initial[row_of[k]])) for k in chosen]
    if len(ranges) != 2:
        raise ModelError(f"expected two ranges (start, stop), got {ranges!r}", element="ranges")
    for k, pair in zip(chosen, ranges):
        if (
            len(pair) != 2
            or not all(math.isfinite(float(v)) for v in pair)
            or float(pair[0]) == float(pair[1])
        ):
            raise ModelError(f"expected (start, stop), two different finite values, got {pair!r}",
                             element=f"ranges of drivers[{k}]")  # fmt: skip
    values = tuple(np.linspace(float(low), float(high), n) for (low, high), n in zip(ranges, sizes))
    held = _held_laws(mechanism, pattern, at_start)

    locate = build_point_map(mechanism).locate(point)
    limited = limited_elements(mechanism)
    outputs = build_output_pattern(mechanism, **limited) if limited["joints"] or limited["drivers"] else None
    limited_elements = [(kind, k) for kind in ("joints", "drivers") for k in limited[kind]]
    left: set[str] = set()

    def position(q: np.ndarray) -> np.ndarray:
        body, local = locate
        if body < 0:
            return np.asarray(local, dtype=float)
        return to_global(q[None, 3 * body : 3 * body + 3], np.asarray(local, dtype=float)[None])[0]

    def within_limits(q: np.ndarray) -> bool:
        if outputs is None:
            return True
        rest = np.zeros((1, q.size))
        value = own_coordinates(outputs, q[None], rest, rest)[0][0]
        inside = True
        for e, (kind, k) in enumerate(limited_elements):
            low, high = getattr(mechanism, kind)[k].limits
            if not low <= value[e] <= high:
                left.add(mechanism.element_label(kind, k))
                inside = False
        return inside

    def move(q_start: np.ndarray, fixed: dict, moving: int, origin: float, targets: np.ndarray):
        """Configurations at `targets` of driver `moving` from `origin`: (list of q or None,
        status of those not reached, boundary value or None, q before the boundary)."""
        direction = 1.0 if targets.size == 0 or targets[-1] >= origin else -1.0
        laws = dict(held)
        laws |= {k: {"law": Linear(rate=0.0, start=v)} for k, v in fixed.items()}
        laws[moving] = {"law": Linear(rate=direction, start=origin)}
        variant = dataclasses.replace(
            mechanism, drivers=tuple(dataclasses.replace(d, **laws[k]) for k, d in enumerate(mechanism.drivers))
        )  # fmt: skip
        stepper = KinematicStepper(variant, tolerance=tolerance, pattern=pattern)
        solved: list = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            stepper.start(0.0, coordinates=q_start)
            for value in targets:
                tau = direction * (value - origin)
                try:
                    if tau > 0.0:
                        stepper.advance(tau)
                except SingularJacobianError as error:
                    return (
                        solved,
                        "beyond_singular",
                        origin + direction * error.time,
                        stepper.coordinates.copy(),
                    )
                except ConvergenceError:
                    return solved, "no_convergence", None, None
                solved.append(stepper.coordinates.copy())
        return solved, None, None, None

    n_a, n_b = values[0].size, values[1].size
    status = np.full((n_b, n_a), "", dtype=f"<U{max(map(len, WORKSPACE_STATUSES))}")
    positions = np.full((n_b, n_a, 2), np.nan)
    boundary, boundary_positions = [], []

    def sweep_line(q_start, fixed, moving, origin, grid_values, store):
        """Both directions from `origin` over `grid_values`; `store(i, q or None, status)`."""
        order = np.argsort(grid_values, kind="stable")
        upward = order[grid_values[order] >= origin]
        downward = order[grid_values[order] < origin][::-1]
        for indices in (upward, downward):
            if not indices.size:
                continue
            solved, stop_status, at, q_last = move(q_start, fixed, moving, origin, grid_values[indices])
            for i, q in zip(indices, solved):
                store(i, q, None)
            for i in indices[len(solved) :]:
                store(i, None, stop_status)
            if at is not None:
                other = fixed[chosen[1] if moving == chosen[0] else chosen[0]]
                boundary.append((at, other) if moving == chosen[0] else (other, at))
                boundary_positions.append(position(q_last))

    spine = [None] * n_b
    configurations = np.full((n_b, n_a, pattern.n_coordinates), np.nan)

    def keep(j: int, i: int, q, failed: str | None) -> None:
        if q is None:
            status[j, i] = failed
            return
        configurations[j, i] = q
        positions[j, i] = position(q)
        status[j, i] = "reachable" if within_limits(q) else "outside_limits"

    def keep_spine(j, q, failed):
        spine[j] = q
        if q is None:
            status[j, :] = failed

    sweep_line(q0, {chosen[0]: start[0]}, chosen[1], start[1], values[1], keep_spine)
    for j in range(n_b):
        if spine[j] is None:
            continue

        def keep_cell(i, q, failed, j=j):
            keep(j, i, q, failed)

        sweep_line(spine[j], {chosen[1]: float(values[1][j])}, chosen[0], start[0], values[0], keep_cell)
    for i in range(n_a):  # columns: from the solved point nearest b0, across what the rows did not reach
        solved_rows = np.flatnonzero(np.isfinite(positions[:, i, 0]))
        if not solved_rows.size or solved_rows.size == n_b:
            continue
        j0 = int(solved_rows[np.argmin(np.abs(values[1][solved_rows] - start[1]))])

        def keep_column(j, q, failed, i=i):
            if not np.isfinite(positions[j, i, 0]):
                keep(j, i, q, failed)

        sweep_line(configurations[j0, i], {chosen[0]: float(values[0][i])}, chosen[1], float(values[1][j0]),
                   values[1], keep_column)  # fmt: skip
    labels = tuple(mechanism.element_label("drivers", k) for k in chosen)
    return Workspace(
        point=point, drivers=labels, values=values, start=start, status=status, positions=positions,
        boundary=np.array(boundary, dtype=float).reshape(-1, 2),
        boundary_positions=np.array(boundary_positions, dtype=float).reshape(-1, 2),
        limits_left=tuple(sorted(left)),
    )  # fmt: skip


def _held_laws(mechanism: Mechanism, pattern, at_start: np.ndarray) -> dict:
    """Every driver's laws held at their values at t = 0: driver index -> {law field: a
    constant `Linear` law}, each law of a driver of several (a path driver's ``law_x``,
    ``law_y``) held on its own row."""
    held: dict[int, dict] = {}
    for row, k in enumerate(pattern.driven_driver.tolist()):
        fields = held.setdefault(k, {})
        field_name = mechanism.drivers[k].law_fields[len(fields)]  # a driver's rows follow its law fields
        fields[field_name] = Linear(rate=0.0, start=float(at_start[row]))
    return held


def _default_range(mechanism: Mechanism, k: int, initial: float) -> tuple[float, float]:
    t_end = mechanism.analysis.t_end
    if not t_end:
        raise ModelError(f"no range for drivers[{k}]: give ranges (--range), or [analysis].t_end for the span of "
                         "its law", element="ranges")  # fmt: skip
    law = mechanism.drivers[k].law
    sampled = [law.evaluate(float(t), initial)[0] for t in np.linspace(0.0, t_end, RANGE_SAMPLES)]
    low, high = min(sampled), max(sampled)
    if not high > low:
        raise ModelError(f"no range for drivers[{k}]: its law stays at {low:g} over 0 … {t_end:g} s; give ranges "
                         "(--range)", element="ranges")  # fmt: skip
    middle, half = 0.5 * (low + high), 0.5 * RANGE_WIDENING * (high - low)
    return (middle - half, middle + half)
