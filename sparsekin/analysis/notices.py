"""What ``sparsekin check`` tells a modeller beyond rank and redundancy.

Three notices, each a tuple of lines in `sparsekin.analysis.check.ModelReport`:

* `law_offsets`: the drivers whose law at t = 0 is not at the drawn value of what they
  drive (a harmonic law with a `phase`, a spline of absolute values, an explicit
  `offset`): the pose at t = 0 is not the drawing, and by how much (whatever the time of
  the check);
* `actuator_directions`: for each stroke or distance driver, which sign extends the
  actuator, so that a swapped axis, which flips the sign of a stroke, shows;
* `sparsekin.model.shared_points.unjoined_points`: points carried by bodies that no joint
  connects there.
"""

from __future__ import annotations

import math

import numpy as np

from ..engine.discretization import DriverLaws
from ..engine.linalg import RefactorSolver, SingularMatrix
from ..engine.ordering import hub_coordinates, hub_last_ordering
from ..engine.pattern import ConstraintPattern
from ..model.elements import DistanceDriver, Revolute, Translational, TranslationalDriver, shown_point
from ..model.mechanism import Mechanism
from ..model.shared_points import unjoined_points
from .describe import driven_labels

__all__ = ["law_offsets", "actuator_directions", "unjoined_point_lines", "hub_lines", "notice_lines"]

#: Most drivers listed by `law_offsets` and `actuator_directions` (a report stays short
#: for a model of thousands of actuators).
LISTED_NOTICES = 8
#: A law counts as away from the drawing beyond this, relative to the model size for
#: lengths (`ConstraintPattern.residual_weights`), rad for angles: well above the
#: rounding of a drawn value, well below any deliberate offset.
OFFSET_TOLERANCE = 1e-9
#: Factors of more nonzeros than this many times the Jacobian's fill in heavily (the value
#: of `sparsekin.solve.stepper.MAX_REFACTOR_FILL`, beyond which a run reuses its factors).
HEAVY_FILL = 8.0


def law_offsets(mechanism: Mechanism, pattern: ConstraintPattern, time: float = 0.0) -> tuple[str, ...]:
    """One line per driven quantity whose law at `time` (default 0) is not its drawn value:
    ``drivers[2] (stroke of joint "bucket_actuator"): law 0.1 m from the drawing at t = 0 s``.

    The value is the law's minus the drawn one, in the driven quantity's unit.
    """
    if pattern.driven_row.size == 0:
        return ()
    value, rate, acceleration = (np.empty(pattern.driven_row.size) for _ in range(3))
    DriverLaws(mechanism, pattern.driven_initial).evaluate(float(time), value, rate, acceleration)
    away = value - pattern.driven_initial
    weighted = np.abs(away) * pattern.residual_weights[pattern.driven_row]
    rows = np.flatnonzero(weighted > OFFSET_TOLERANCE)
    if rows.size == 0:
        return ()
    listed = rows[:LISTED_NOTICES]
    labels = driven_labels(mechanism, pattern, listed)  # the listed rows only: a model may have 10^5 drivers
    lines = []
    for label, k in zip(labels, listed.tolist()):
        unit = "rad" if pattern.row_is_angle[pattern.driven_row[k]] else "m"
        lines.append(f"{label}: law {away[k]:+.6g} {unit} from the drawing at t = {time:g} s")
    if rows.size > LISTED_NOTICES:
        lines.append(f"… and {rows.size - LISTED_NOTICES} more")
    return tuple(lines)


def actuator_directions(mechanism: Mechanism) -> tuple[str, ...]:
    """One line per stroke or distance driver (the model's own and each unit's, once)
    saying whether a growing driven value extends the actuator.

    An actuator's pins are the revolutes that hold its two bodies to the rest of the
    machine; it extends when they move apart.  A stroke grows as the second body slides
    along the axis P→Q, which moves the second pin by the axis' direction: the stroke
    extends the actuator when that direction points from the first pin to the second.
    """
    groups = [("", mechanism.own("joints"), mechanism.own("drivers"), mechanism.position)]
    seen = set()
    for copies in mechanism.copies:
        unit = copies.unit
        if id(unit) not in seen:
            seen.add(id(unit))
            groups.append((f"units.{unit.name}.", unit.joints, unit.drivers, _unit_position(unit)))
    lines = []
    for prefix, joints, drivers, position in groups:
        for index, driver in enumerate(drivers):
            label = f"{prefix}drivers[{index}]" + (f' "{driver.name}"' if driver.name else "")
            if isinstance(driver, DistanceDriver):
                ends = " and ".join(shown_point(point) for point in driver.points)
                lines.append(f"{label}: a growing distance pushes {ends} apart (extends)")
            elif isinstance(driver, TranslationalDriver):
                joint = next((j for j in joints if j.name == driver.joint), None)
                if isinstance(joint, Translational):
                    lines.append(f"{label}: {_stroke_direction(joint, joints, position)}")
    if len(lines) > LISTED_NOTICES:
        lines = [*lines[:LISTED_NOTICES], f"… and {len(lines) - LISTED_NOTICES} more"]
    return tuple(lines)


def _stroke_direction(joint: Translational, joints, position) -> str:
    if joint.axis is not None:
        start, end = (np.array(position(point), dtype=float) for point in joint.axis)
        axis, along = end - start, f"{shown_point(joint.axis[0])}→{shown_point(joint.axis[1])}"
    else:
        axis, along = np.array(joint.direction, dtype=float), f"{joint.direction}"
    pins = [_pin(body, other, joints) for body, other in (joint.bodies, joint.bodies[::-1])]
    if None in pins:
        return f'a growing stroke of joint "{joint.name}" slides {joint.bodies[1]} along {along} (no pins to tell extension)'
    first, second = (np.array(position(pin), dtype=float) for pin in pins)
    projection = float(np.dot(axis, second - first))
    names = f"{shown_point(pins[0])} and {shown_point(pins[1])}"
    if math.isclose(projection, 0.0, abs_tol=1e-12 * float(np.hypot(*axis))):
        return f'a growing stroke of joint "{joint.name}" moves its pins {names} sideways'
    if projection > 0.0:
        return f'a growing stroke of joint "{joint.name}" pushes its pins {names} apart (extends)'
    return (f'a growing stroke of joint "{joint.name}" pulls its pins {names} together (RETRACTS): the axis runs '
            f"from {joint.bodies[1]}'s pin towards {joint.bodies[0]}'s; write it from {shown_point(pins[0])} "
            f"to {shown_point(pins[1])} for extending = positive")  # fmt: skip


def _pin(body: str, partner: str, joints):
    """The point where `body` is pinned by a revolute to a body other than `partner`."""
    for joint in joints:
        if isinstance(joint, Revolute) and body in joint.bodies and partner not in joint.bodies:
            return joint.at
    return None


def _unit_position(unit):
    def position(reference):
        return unit.points[reference] if isinstance(reference, str) else reference

    return position


def unjoined_point_lines(mechanism: Mechanism) -> tuple[str, ...]:
    """`sparsekin.model.shared_points.unjoined_points` in words, one line each."""
    found = unjoined_points(mechanism)
    lines = [str(point) for point in found[:LISTED_NOTICES]]
    if len(found) > LISTED_NOTICES:
        lines.append(f"… and {len(found) - LISTED_NOTICES} more")
    return tuple(lines)


def hub_lines(discretization, jacobian) -> tuple[str, ...]:
    """One line when bodies carry many attachments (a hub: a crankshaft, a frame): which,
    and how much the factors of `jacobian` fill in with the order the run takes for them
    (`sparsekin.engine.ordering.hub_last_ordering`); a warning with a way out when that is
    heavy."""
    mechanism, pattern = discretization.mechanism, discretization.constraints
    hub = hub_coordinates(pattern)
    if not hub.size or pattern.n_equations != pattern.n_coordinates:
        return ()
    bodies = np.unique(hub // 3)
    names = ", ".join(mechanism.body_name(int(b)) for b in bodies[:LISTED_NOTICES])
    names += " …" if bodies.size > LISTED_NOTICES else ""
    entries = int(np.bincount(pattern.indices, minlength=pattern.n_coordinates)[hub].max())
    ordering = hub_last_ordering(discretization)
    solver = RefactorSolver()
    if ordering is not None:
        solver.suggest(*ordering)
    try:
        solver.factor(jacobian)
    except SingularMatrix:
        return ()
    fill = solver.nnz_factors / max(pattern.nnz, 1)
    carried = f"hub: {names} carr{'y' if bodies.size > 1 else 'ies'} many bodies (up to {entries} Jacobian entries in a column)"
    if ordering is not None and fill <= HEAVY_FILL:
        return (f"{carried}; the run eliminates it last: factors {fill:.3g}× the Jacobian",)
    why = "" if ordering is not None else " (the run cannot eliminate it last: it is not held by joints to the ground alone)"
    return ((f"warning: {carried}{why}; the factors fill in {fill:.3g}× the Jacobian, and each step costs about as "
             "much more: attach the copies one to the next (a chain), or pin the hub to the ground directly"),)


def notice_lines(report) -> list[str]:
    """The lines of the three notices in ``sparsekin check``'s report."""
    lines = []
    if report.law_offsets:
        lines.append("laws away from the drawing at t = 0 s (the pose then is not the drawing):")
        lines += [f"  {line}" for line in report.law_offsets]
    else:
        lines.append("laws away from the drawing at t = 0 s: none")
    if report.actuator_directions:
        lines.append("actuators (a growing driven value):")
        lines += [f"  {line}" for line in report.actuator_directions]
    lines += list(report.hubs)
    if report.unjoined_points:
        lines.append(f"warning: points carried by bodies no joint connects there ({len(report.unjoined_points)}):")
        lines += [f"  {line}" for line in report.unjoined_points]
    return lines
