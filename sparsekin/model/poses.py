"""A solved pose as the drawing of a new model (`posed`).

The model that `posed` returns is drawn at the pose: every named point where its body has
it, every body's frame at its coordinates.  Its laws are those of the original model
shifted in time, ``law'(t) = law(t + T)``, with every default resolved (``initial`` is the
value the original drawing gave), so that a run of the new model from t = 0 is the
original run from T on.  Springs keep their drawn free length, written out.  A body's
`lengths` stay: the pose meets them.

What cannot be drawn is refused: a point that two bodies carry and the pose separates (a
point of a translational joint's ``at`` form, once it has slid) has no single place.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..errors import ModelError
from .elements import GROUND
from .geometry import rotate, to_global
from .laws import Harmonic, Linear, Polynomial, Spline
from .mechanism import Mechanism

__all__ = ["posed", "shifted_law", "POINT_TOLERANCE"]

#: Largest distance (relative to the model size) between the places of a point on the
#: bodies that carry it, for the point to be drawn at the pose.
POINT_TOLERANCE = 1e-9


def shifted_law(law, time: float, initial: float):
    """`law` started `time` later, ``law'(t) = law(t + time)``, with `initial` (the value of
    the driven quantity in the original drawing) resolved into it.

    Examples
    --------
    >>> shifted_law(Linear(rate=2.0), 0.5, 1.0)
    Linear(rate=2.0, start=2.0)
    """
    time, initial = float(time), float(initial)
    if isinstance(law, (int, float)):  # a constant load component
        return law
    if type(law) is Linear:
        start = initial if law.start is None else law.start
        return Linear(rate=law.rate, start=start + law.rate * time)
    if type(law) is Harmonic:
        offset = initial if law.offset is None else law.offset
        return Harmonic(amplitude=law.amplitude, omega=law.omega, phase=law.phase + law.omega * time, offset=offset)
    if type(law) is Polynomial:
        c = [initial if law.coefficients[0] is None else law.coefficients[0], *law.coefficients[1:]]
        shifted = [sum(c[j] * math.comb(j, k) * time ** (j - k) for j in range(k, len(c))) for k in range(len(c))]
        return Polynomial(tuple(shifted))
    if type(law) is Spline:
        offset = initial if law.offset is None else law.offset
        return Spline(times=tuple(t - time for t in law.times), values=law.values, offset=offset)
    return _Shifted(law, time, initial)


@dataclasses.dataclass(frozen=True)
class _Shifted:
    """A law of the user's own, started later (Python only: it has no spelling in a file)."""

    law: object
    time: float
    initial: float

    def evaluate(self, t: float, initial: float) -> tuple[float, float, float]:
        return self.law.evaluate(t + self.time, self.initial)


def posed(mechanism: Mechanism, coordinates, time: float, driven_initial) -> Mechanism:
    """`mechanism` drawn at the pose `coordinates`, its laws shifted by `time`.

    Parameters
    ----------
    mechanism : Mechanism
        A model with repeats is written out copy by copy (`Mechanism.expanded`).
    coordinates : array_like, shape (n_coordinates,)
        The pose: every body's ``(x, y, angle)``.
    time : float
        The time of the pose, s: the new model's t = 0.
    driven_initial : array_like, shape (n_driven,)
        The drawn value of each driven quantity (`ConstraintPattern.driven_initial`).

    Raises
    ------
    ModelError
        If a point carried by several bodies is at several places in the pose.
    """
    mechanism = mechanism.expanded()
    q = np.asarray(coordinates, dtype=float).reshape(-1, 3)
    if q.shape[0] != mechanism.n_bodies:
        raise ValueError(f"`coordinates` must have {mechanism.n_coordinates} values, got {q.size}.")
    drawn = mechanism.frames()
    scale = max(float(np.abs(np.array(list(mechanism.points.values()), dtype=float)).max(initial=0.0)), 1e-3)
    index = {body.name: b for b, body in enumerate(mechanism.bodies)}

    def carried(bodies: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Where the points that start at `points` on `bodies` (-1: the ground) are in the pose."""
        out = np.array(points, dtype=float).reshape(-1, 2)
        moving = bodies >= 0
        if moving.any():
            local = mechanism.local_points(bodies[moving], out[moving], drawn)
            out[moving] = to_global(q[bodies[moving]], local)
        return out

    points = _posed_points(mechanism, carried, scale, time)
    bodies = []
    for b, body in enumerate(mechanism.bodies):
        origin = body.origin
        if not isinstance(origin, str) or math.dist(points[origin], q[b, :2]) > POINT_TOLERANCE * scale:
            origin = (float(q[b, 0]), float(q[b, 1]))
        com = body.com
        if com is not None and not isinstance(com, str):
            com = tuple(carried(np.array([b]), np.array([com]))[0].tolist())
        bodies.append(dataclasses.replace(body, origin=origin, angle=float(q[b, 2]), com=com))

    def body_of(name: str) -> int:
        return -1 if name == GROUND else index[name]

    turn = np.append(q[:, 2] - drawn[:, 2], 0.0)  # the ground's last
    joints = [_posed_element(j, carried, body_of, turn) for j in mechanism.joints]
    drivers, row = [], 0
    driven_initial = np.asarray(driven_initial, dtype=float)
    for driver in mechanism.drivers:
        element = _posed_element(driver, carried, body_of, turn)
        laws = {}
        for field_name in type(driver).law_fields:
            laws[field_name] = shifted_law(getattr(driver, field_name), time, driven_initial[row])
            row += 1
        drivers.append(dataclasses.replace(element, **laws))
    loads = [_posed_load(load, carried, body_of, turn, mechanism, time) for load in mechanism.loads]
    return Mechanism(points=points, bodies=bodies, joints=joints, drivers=drivers, name=mechanism.name,
                     analysis=mechanism.analysis, loads=loads, gravity=mechanism.gravity)  # fmt: skip


def _posed_points(mechanism: Mechanism, carried, scale: float, time: float) -> dict:
    """Every named point where its bodies have it in the pose (ground points stay)."""
    names = list(mechanism.points)
    pairs = [(name, b) for b, body in enumerate(mechanism.bodies) for name in body.points]
    points = dict(mechanism.points)
    if not pairs:
        return points
    where = carried(np.array([b for _, b in pairs]), np.array([mechanism.points[name] for name, _ in pairs]))
    first: dict[str, tuple[int, np.ndarray]] = {}
    for (name, b), position in zip(pairs, where):
        if name not in first:
            first[name] = (b, position)
            points[name] = (float(position[0]), float(position[1]))
            continue
        b0, position0 = first[name]
        apart = float(np.hypot(*(position - position0)))
        if apart > POINT_TOLERANCE * scale:
            raise ModelError(
                f'carried by {mechanism.bodies[b0].name} and {mechanism.bodies[b].name}, which are {apart:.3g} m apart '
                f"there at t = {time:g} s: the pose cannot be drawn (give each body a point of its own)",
                element=f"points.{name}",
            )
    return {name: points[name] for name in names}


def _placed_points(element, body_of) -> dict[str, list[int]]:
    """For each point field of `element`: the body each of its points rides on (-1: ground)."""
    bodies = [body_of(getattr(element, f)) for f in type(element).body_fields if isinstance(getattr(element, f), str)]
    pair = getattr(element, "bodies", None)
    pair = [body_of(name) for name in pair] if isinstance(pair, tuple) else []
    placed = {}
    for field_name in type(element).point_fields:
        value = getattr(element, field_name)
        if value is None:
            continue
        if isinstance(value, str) or isinstance(value[0], float):
            moving = [b for b in (bodies or pair) if b >= 0]
            placed[field_name] = [moving[0] if moving else -1]
        else:
            placed[field_name] = [pair[k] if k < len(pair) else (bodies or [-1])[0] for k in range(len(value))]
    return placed


def _posed_element(element, carried, body_of, turn: np.ndarray):
    """`element` with its literal points carried into the pose and its directions turned
    with its first body."""
    changes = {}
    for field_name, bodies in _placed_points(element, body_of).items():
        value = getattr(element, field_name)
        if isinstance(value, str) or isinstance(value[0], float):
            if not isinstance(value, str):
                changes[field_name] = tuple(carried(np.array(bodies), np.array([value]))[0].tolist())
        elif any(not isinstance(v, str) for v in value):
            changes[field_name] = tuple(
                v if isinstance(v, str) else tuple(carried(np.array([b]), np.array([v]))[0].tolist())
                for v, b in zip(value, bodies)
            )  # fmt: skip
    direction = getattr(element, "direction", None)
    if direction is not None:
        first = body_of(element.bodies[0])
        changes["direction"] = tuple(rotate(np.array(direction, dtype=float), turn[first]).tolist())
    return dataclasses.replace(element, **changes) if changes else element


def _posed_load(load, carried, body_of, turn: np.ndarray, mechanism: Mechanism, time: float):
    """A load posed like an element, its laws shifted (no initial value: 0), a spring's
    free length written out."""
    element = _posed_element(load, carried, body_of, turn)
    changes = {}
    value = getattr(load, "value", None)
    if isinstance(value, tuple):
        changes["value"] = tuple(shifted_law(v, time, 0.0) for v in value)
    elif value is not None:
        changes["value"] = shifted_law(value, time, 0.0)
    if hasattr(load, "free_length") and load.free_length is None:
        p, r = mechanism.positions(load.points)
        changes["free_length"] = float(np.hypot(*(r - p)))
    return dataclasses.replace(element, **changes) if changes else element
