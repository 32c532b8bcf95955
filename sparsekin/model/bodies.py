"""Bodies: rigid frames carrying named points, and the checks that the mechanism and its
units share for them (a point's coordinates, a list of elements of given kinds)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from ..errors import ModelError
from . import _validate
from ._validate import FileKeys
from .elements import PointRef

__all__ = ["Body"]


def _set(instance: object, field_name: str, value: object) -> None:
    """Store the canonical form of a field (tuples for sequences, floats for numbers)."""
    object.__setattr__(instance, field_name, value)


@dataclass(frozen=True, slots=True)
class Body:
    """A rigid body with a frame at `origin`, turned by `angle` (rad), carrying `points`.

    For forces: its `mass` (kg, default 0), its `inertia` about its centre of mass
    (kg·m², default 0) and its centre of mass `com` (a point name or (x, y), drawn;
    default the frame origin).  For forward dynamics: its initial `velocity` ``(vx, vy,
    angular velocity)`` of the frame origin (m/s, rad/s; default at rest), made
    consistent with the constraints by the smallest mass-weighted change.

    `lengths`: exact distances between some of its points, ``((P, Q, length), ...)`` (m);
    the drawing then only approximates them: the body takes the local positions of its
    points nearest (least squares) to the drawing that meet them
    (`sparsekin.model.lengths`).  Distances it does not state come from the drawing.
    """

    name: str
    origin: PointRef
    angle: float = 0.0
    points: tuple[str, ...] = ()
    mass: float | None = None
    inertia: float | None = None
    com: PointRef | None = None
    velocity: tuple[float, float, float] | None = None
    lengths: tuple[tuple[str, str, float], ...] = ()

    file_keys = FileKeys(
        required=("origin",), optional=("angle", "points", "mass", "inertia", "com", "velocity", "lengths")
    )

    def __post_init__(self) -> None:
        _validate.name(self.name, "name")
        _set(self, "origin", _validate.point_reference(self.origin, "origin"))
        _set(self, "angle", _validate.finite_float(self.angle, "angle"))
        _set(self, "points", _validate.names(self.points, "points"))
        for field_name in ("mass", "inertia"):
            if getattr(self, field_name) is not None:
                _set(self, field_name, _validate.non_negative_float(getattr(self, field_name), field_name))
        if self.com is not None:
            _set(self, "com", _validate.point_reference(self.com, "com"))
        if self.velocity is not None:
            velocity = self.velocity
            if isinstance(velocity, str) or not _validate.is_sequence(velocity) or len(velocity) != 3:
                raise ModelError(f"expected [vx, vy, angular velocity], got {velocity!r}", element="velocity")
            _set(self, "velocity", tuple(_validate.finite_float(v, f"velocity[{k}]") for k, v in enumerate(velocity)))
        if self.lengths != ():
            _set(self, "lengths", _checked_lengths(self.lengths, self.points))


def _checked_lengths(lengths, points: tuple[str, ...]) -> tuple[tuple[str, str, float], ...]:
    """`lengths` as ``((P, Q, length), ...)``: P and Q two different points of the body,
    each pair once, the length a number > 0."""
    if isinstance(lengths, (str, bytes, Mapping)) or not _validate.is_sequence(lengths):
        raise ModelError(f"expected a list of [P, Q, length], got {type(lengths).__name__}", element="lengths")
    checked, seen = [], set()
    for index, entry in enumerate(lengths):
        where = f"lengths[{index}]"
        if isinstance(entry, (str, bytes)) or not _validate.is_sequence(entry) or len(entry) != 3:
            raise ModelError(f"expected [P, Q, length], got {entry!r}", element=where)
        first, second = (_validate.name(entry[k], f"{where}[{k}]") for k in (0, 1))
        for k, point in enumerate((first, second)):
            if point not in points:
                raise ModelError(f'"{point}" is not one of the body\'s points ({_validate.known_list(list(points))})',
                                 element=f"{where}[{k}]")
        if first == second:
            raise ModelError(f'expected two different points, got "{first}" twice', element=where)
        if frozenset((first, second)) in seen:
            raise ModelError(f"the distance {first}–{second} is given twice", element=where)
        seen.add(frozenset((first, second)))
        length = _validate.finite_float(entry[2], f"{where}[2]")
        if not length > 0.0:
            raise ModelError(f"expected a length > 0, got {length!r}", element=f"{where}[2]")
        checked.append((first, second, length))
    return tuple(checked)


def _point_pair(name: str, value: object) -> tuple[float, float]:
    """The coordinates of point `name` as ``(x, y)``, checked."""
    if type(value) is tuple and len(value) == 2 and type(value[0]) is type(value[1]) is float:
        if abs(value[0]) <= _validate.MAX_MAGNITUDE and abs(value[1]) <= _validate.MAX_MAGNITUDE:
            return value  # the common case, fast
    return _validate.pair(value, f"points.{name}")


def _tuple_of(items, kinds: tuple[type, ...], where: str) -> tuple:
    if isinstance(items, (str, bytes, Mapping)) or not isinstance(items, Sequence):
        raise ModelError(f"expected a list, got {type(items).__name__}", element=where)
    for index, item in enumerate(items):
        if type(item) not in kinds and not isinstance(item, kinds):
            names = " or ".join(k.__name__ for k in kinds)
            raise ModelError(f"expected {names}, got {type(item).__name__}", element=f"{where}[{index}]")
    return tuple(items)
