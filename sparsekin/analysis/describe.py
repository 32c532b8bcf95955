"""Words for messages: labels of equations and coordinates, and what a motion or a
dependency between equations means for the bodies of a mechanism.

The rank analysis (`sparsekin.analysis.rank`) gives vectors; these functions name the elements,
equations, coordinates and bodies behind them, largest share first.
"""

from __future__ import annotations

import math

import numpy as np

from ..engine.pattern import ConstraintPattern, build_point_map
from ..model.geometry import to_global
from ..model.mechanism import COORDINATE_NAMES, Mechanism

__all__ = [
    "equation_label",
    "driven_labels",
    "coordinate_label",
    "shares",
    "motion_summary",
    "equations_summary",
    "describe_motion",
    "row_preference",
]

#: Shares of a motion or of a dependency below this are not listed.
LISTED_SHARE = 0.01
#: How many coordinates, bodies or equations a line of a report lists at most.
LISTED = 6


def equation_label(mechanism: Mechanism, pattern: ConstraintPattern, row: int) -> str:
    """``joints[2] (revolute c4–c1 at A), equation y``: the element and equation of a row."""
    element = int(np.searchsorted(pattern.element_first_row, row, side="right")) - 1
    within = row - int(pattern.element_first_row[element])
    n_joints = len(mechanism.joints)
    if element < n_joints:
        label = mechanism.element_label("joints", element)
        equation = mechanism.joints[element].equation_names[within]
    else:
        label = mechanism.element_label("drivers", element - n_joints)
        equation = mechanism.drivers[element - n_joints].equation_names[within]
    return f"{label}, equation {equation}"


def driven_labels(mechanism: Mechanism, pattern: ConstraintPattern, which=None) -> list[str]:
    """A label per driven row (or per driven row of the indices `which`): the driver's,
    with the equation's name for a driver of several rows (``drivers[0] (path of K on c1) x``)."""
    labels = []
    which = slice(None) if which is None else which
    for row, k in zip(pattern.driven_row[which].tolist(), pattern.driven_driver[which].tolist()):
        label = mechanism.element_label("drivers", k)
        driver = mechanism.drivers[k]
        if driver.n_equations > 1:
            label += " " + driver.equation_names[row - int(pattern.element_first_row[len(mechanism.joints) + k])]
        labels.append(label)
    return labels


def coordinate_label(mechanism: Mechanism, column: int) -> str:
    """``c3.angle``: the body and coordinate of a column."""
    return f"{mechanism.bodies[column // 3].name}.{COORDINATE_NAMES[column % 3]}"


def shares(vector: np.ndarray) -> np.ndarray:
    """Each entry's share of the squared norm of `vector` (they sum to 1)."""
    squared = np.square(vector)
    total = squared.sum()
    return squared / total if total > 0 else squared


def motion_summary(mechanism: Mechanism, scaled_motion: np.ndarray, limit: int = LISTED) -> str:
    """``c3.angle 31%, c4.angle 25%, c1.x 12%``: the coordinates a motion moves most.

    `scaled_motion` is in the scaled coordinates of a `JacobianAnalysis` (a rotation
    counts as the displacement it causes at the body's farthest joint point), so that
    the shares compare translations and rotations fairly.
    """
    share = shares(scaled_motion)
    listed = [int(c) for c in np.argsort(-share, kind="stable")[:limit] if share[c] >= LISTED_SHARE]
    text = ", ".join(f"{coordinate_label(mechanism, c)} {_percent(share[c])}" for c in listed)
    rest = int(np.count_nonzero(share >= LISTED_SHARE)) - len(listed)
    return text + (f", … ({rest} more)" if rest > 0 else "")


def equations_summary(
    mechanism: Mechanism,
    pattern: ConstraintPattern,
    scaled_weights: np.ndarray,
    rows: np.ndarray | None = None,
    limit: int = LISTED,
    exclude: int | None = None,
) -> str:
    """``joints[2] (revolute c4–c1 at A), equation y 40%; …``: equations by their share.

    `scaled_weights` weigh the rows `rows` (all rows when None) of the scaled Jacobian.
    """
    rows = np.arange(scaled_weights.size) if rows is None else np.asarray(rows)
    if exclude is not None:  # the shares of the other equations of a dependency
        scaled_weights = np.where(rows == exclude, 0.0, scaled_weights)
    share = shares(scaled_weights)
    order = [int(k) for k in np.argsort(-share, kind="stable") if share[k] >= LISTED_SHARE]
    text = "; ".join(
        f"{equation_label(mechanism, pattern, int(rows[k]))} {_percent(share[k])}" for k in order[:limit]
    )
    return text + (f"; … ({len(order) - limit} more)" if len(order) > limit else "")


def _percent(share: float) -> str:
    return f"{100 * share:.0f}%" if share >= 0.005 else "<1%"


def describe_motion(
    mechanism: Mechanism,
    pattern: ConstraintPattern,
    coordinates: np.ndarray,
    motion: np.ndarray,
    scaled_motion: np.ndarray,
    limit: int = LISTED,
) -> str:
    """How the bodies move in a motion: ``c6 rotates about D (-0.2, 0.5)``.

    Parameters
    ----------
    mechanism, pattern
    coordinates : ndarray, shape (n,)
        The configuration, m and rad.
    motion : ndarray, shape (n,)
        A velocity of the coordinates (m, rad), up to a factor.
    scaled_motion : ndarray, shape (n,)
        The same in scaled coordinates: it decides which bodies move noticeably.
    limit : int
        Most bodies described.

    Returns
    -------
    str
        Each body that takes a share of at least 1 % of the motion, in the order its
        coordinates appear in `motion_summary` (by the largest share of one of its
        coordinates): ``rotates about`` its instantaneous centre (named when it is a
        named point), or ``translates along`` a unit direction.
    """
    coordinate_share = shares(scaled_motion).reshape(-1, 3)
    share, largest = coordinate_share.sum(axis=1), coordinate_share.max(axis=1)
    moving = [int(b) for b in np.argsort(-largest, kind="stable") if share[b] >= LISTED_SHARE]
    points = _current_points(mechanism, coordinates, moving[:limit])
    parts = []
    for body in moving[:limit]:
        x, y, _ = coordinates[3 * body : 3 * body + 3]
        vx, vy, omega = motion[3 * body : 3 * body + 3]
        speed = math.hypot(vx, vy)
        name = mechanism.bodies[body].name
        if abs(omega) * pattern.length_scale <= 1e-9 * speed:
            parts.append(f"{name} translates along ({_shown(vx / speed, 1.0)}, {_shown(vy / speed, 1.0)})")
            continue
        centre = (x - vy / omega, y + vx / omega)
        label = _named_point(points, centre, pattern.length_scale)
        shown = f"({_shown(centre[0], pattern.length_scale)}, {_shown(centre[1], pattern.length_scale)})"
        where = f"{label} {shown}" if label else shown
        parts.append(f"{name} rotates about {where}")
    if len(moving) > limit:
        parts.append(f"… ({len(moving)} bodies move)")
    return ", ".join(parts) if parts else "nothing moves noticeably"


def _shown(value: float, scale: float) -> str:
    """`value` to 4 digits, and 0 when it is rounding noise against `scale`."""
    return f"{value:.4g}" if abs(value) > 1e-9 * scale else "0"


#: Up to this many named points, every one is a candidate for naming a centre of rotation;
#: beyond, only the points of the bodies described.
NAMED_CANDIDATES = 10_000


def _current_points(mechanism: Mechanism, coordinates: np.ndarray, bodies) -> dict[str, tuple[float, float]]:
    """Global position, in the configuration `coordinates`, of the named points that may
    name a centre of rotation: all of them in a model of at most `NAMED_CANDIDATES`, else
    those the given `bodies` (indices) carry."""
    point_map = build_point_map(mechanism)
    if len(mechanism.points) <= NAMED_CANDIDATES:
        names = list(point_map.names)
    else:
        names = list(dict.fromkeys(point for b in bodies for point in mechanism.bodies[b].points))
    located = [point_map.locate(name) for name in names]
    body = np.array([b for b, _ in located], dtype=np.int64).reshape(-1)
    local = np.array([point for _, point in located], dtype=float).reshape(-1, 2)
    frames = np.zeros((body.size, 3))  # ground points: the identity frame
    frames[body >= 0] = coordinates.reshape(-1, 3)[body[body >= 0]]
    positions = to_global(frames, local)
    return dict(zip(names, map(tuple, positions.tolist())))


def _named_point(points: dict[str, tuple[float, float]], where: tuple[float, float], scale: float):
    """The named point nearest to `where`, if within a millionth of `scale`."""
    best, distance = None, 1e-6 * scale
    for name, (x, y) in points.items():
        gap = math.hypot(x - where[0], y - where[1])
        if gap <= distance:
            best, distance = name, gap
    return best


def row_preference(mechanism: Mechanism, pattern: ConstraintPattern) -> np.ndarray:
    """Which equations to name redundant first: later joints, and drivers only as a last resort."""
    m = pattern.n_equations
    preference = 1.0 + np.arange(m) / max(m, 1)
    preference[int(pattern.element_first_row[len(mechanism.joints)]) :] *= 1e-3
    return preference
