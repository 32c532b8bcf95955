"""The mechanism: bodies, named points, joints and drivers, as frozen data.

Elements refer to bodies and points by name.  Every body has absolute coordinates
``(x, y, angle)``: the position of its frame origin and the angle of its frame.  The body
``ground`` always exists, is fixed, and has no coordinates.  Points are given by their
global coordinates in the initial (assembly) configuration; a point rides on a body when
the body lists it, and a point that no body lists stays on the ground.

>>> from sparsekin import Linear
>>> mechanism = Mechanism(
...     points={"O": (0.0, 0.0), "A": (0.1, 0.0)},
...     bodies=[Body("crank", origin="O", points=("O", "A"))],
...     joints=[Revolute(("crank", "ground"), at="O")],
...     drivers=[RotationalDriver(("crank", "ground"), law=Linear(rate=1.0))],
... )
>>> mechanism.n_bodies, mechanism.n_equations
(1, 3)
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Union

import numpy as np

from . import _validate
from .errors import ModelError
from .laws import Law

__all__ = [
    "GROUND",
    "Body",
    "Revolute",
    "Translational",
    "Rigid",
    "TranslationalDriver",
    "RotationalDriver",
    "AbsoluteDriver",
    "Analysis",
    "Mechanism",
]

#: Name of the fixed body.
GROUND = "ground"

#: A point: the name of a point of the model, or its global coordinates (x, y) in m.
PointRef = Union[str, tuple[float, float]]


def _set(instance: object, field_name: str, value: object) -> None:
    """Store the canonical form of a field (tuples for sequences, floats for numbers)."""
    object.__setattr__(instance, field_name, value)


@dataclass(frozen=True, slots=True)
class Body:
    """A rigid body with a frame at `origin`, turned by `angle` (rad), carrying `points`."""

    name: str
    origin: PointRef
    angle: float = 0.0
    points: tuple[str, ...] = ()
    mass: float | None = None
    inertia: float | None = None
    com: PointRef | None = None

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


@dataclass(frozen=True, slots=True)
class Revolute:
    """Bodies ``bodies[0]`` and ``bodies[1]`` share the point `at` (2 equations)."""

    bodies: tuple[str, str]
    at: PointRef
    name: str | None = None

    type_name = "revolute"
    n_equations = 2

    def __post_init__(self) -> None:
        _joint_checks(self)
        _set(self, "at", _validate.point_reference(self.at, "at"))

    def describe(self) -> str:
        return f"revolute {self.bodies[0]}–{self.bodies[1]} at {_shown_point(self.at)}"


@dataclass(frozen=True, slots=True)
class Translational:
    """``bodies[1]`` slides along a line fixed in ``bodies[0]``; relative rotation locked.

    Give either ``axis = (P, Q)``, P on the first body and Q on the second (the line
    through P along P→Q), or ``at = P`` with a global initial ``direction = (dx, dy)``.
    2 equations.
    """

    bodies: tuple[str, str]
    axis: tuple[PointRef, PointRef] | None = None
    at: PointRef | None = None
    direction: tuple[float, float] | None = None
    name: str | None = None

    type_name = "translational"
    n_equations = 2

    def __post_init__(self) -> None:
        _joint_checks(self)
        if self.axis is not None:
            if self.at is not None or self.direction is not None:
                raise ModelError("give either `axis` or `at` with `direction`, not both", element="axis")
            axis = self.axis
            if isinstance(axis, str) or not _validate.is_sequence(axis) or len(axis) != 2:
                raise ModelError(f"expected two points [P, Q], got {axis!r}", element="axis")
            _set(
                self,
                "axis",
                (_validate.point_reference(axis[0], "axis[0]"), _validate.point_reference(axis[1], "axis[1]")),
            )
            if self.axis[0] == self.axis[1]:
                raise ModelError(
                    f"zero-length axis: P and Q are the same point {_shown_point(self.axis[0])}; "
                    "expected two distinct points",
                    element="axis",
                )
        else:
            if self.at is None or self.direction is None:
                raise ModelError("expected `axis = [P, Q]`, or `at` with `direction`", element="axis")
            _set(self, "at", _validate.point_reference(self.at, "at"))
            direction = _validate.pair(self.direction, "direction")
            if math.hypot(*direction) == 0.0:
                raise ModelError("zero-length direction: expected a non-zero [dx, dy]", element="direction")
            _set(self, "direction", direction)

    def describe(self) -> str:
        if self.axis is not None:
            where = f"along {_shown_point(self.axis[0])}→{_shown_point(self.axis[1])}"
        else:
            where = f"at {_shown_point(self.at)} along {self.direction}"
        return f"translational {self.bodies[0]}–{self.bodies[1]} {where}"


@dataclass(frozen=True, slots=True)
class Rigid:
    """``bodies[0]`` and ``bodies[1]`` are welded together (3 equations)."""

    bodies: tuple[str, str]
    name: str | None = None

    type_name = "rigid"
    n_equations = 3

    def __post_init__(self) -> None:
        _joint_checks(self)

    def describe(self) -> str:
        return f"rigid {self.bodies[0]}–{self.bodies[1]}"


@dataclass(frozen=True, slots=True)
class TranslationalDriver:
    """Drives the stroke of the translational joint named `joint`.

    The stroke is the distance from P to Q measured along the axis (for the ``at`` /
    ``direction`` form, the displacement of the second body's point from the first's
    along the direction, 0 at the start).  Positive means the points move apart.
    """

    joint: str
    law: Law
    name: str | None = None

    type_name = "translational"
    n_equations = 1

    def __post_init__(self) -> None:
        _validate.name(self.joint, "joint")
        _driver_checks(self)

    def describe(self) -> str:
        return f'stroke of joint "{self.joint}"'


@dataclass(frozen=True, slots=True)
class RotationalDriver:
    """Drives the relative angle ``angle(bodies[0]) - angle(bodies[1])`` (rad)."""

    bodies: tuple[str, str]
    law: Law
    name: str | None = None

    type_name = "rotational"
    n_equations = 1

    def __post_init__(self) -> None:
        _set(self, "bodies", _validate.two_names(self.bodies, "bodies"))
        if self.bodies[0] == self.bodies[1]:
            raise ModelError(f'expected two different bodies, got "{self.bodies[0]}" twice', element="bodies")
        _driver_checks(self)

    def describe(self) -> str:
        return f"angle {self.bodies[0]} − {self.bodies[1]}"


@dataclass(frozen=True, slots=True)
class AbsoluteDriver:
    """Drives one coordinate (``"x"``, ``"y"`` or ``"angle"``) of the frame of `body`."""

    body: str
    coordinate: str
    law: Law
    name: str | None = None

    type_name = "absolute"
    n_equations = 1

    def __post_init__(self) -> None:
        _validate.name(self.body, "body")
        if self.body == GROUND:
            raise ModelError('the ground cannot be driven: expected a moving body', element="body")
        _validate.choice(self.coordinate, "coordinate", COORDINATE_NAMES)
        _driver_checks(self)

    def describe(self) -> str:
        return f"{self.coordinate} of {self.body}"


@dataclass(frozen=True, slots=True)
class Analysis:
    """Defaults for ``sparsekin run``: end time (s), number of samples, output points."""

    t_end: float | None = None
    steps: int | None = None
    points: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if self.t_end is not None:
            _set(self, "t_end", _validate.finite_float(self.t_end, "t_end"))
            if self.t_end < 0.0:
                raise ModelError(f"expected t_end >= 0, got {self.t_end!r}", element="t_end")
        if self.steps is not None:
            _set(self, "steps", _validate.positive_int(self.steps, "steps"))
        if self.points is not None:
            _set(self, "points", _validate.names(self.points, "points"))


#: The coordinates of a body frame, in the order they are stored.
COORDINATE_NAMES = ("x", "y", "angle")

Joint = Union[Revolute, Translational, Rigid]
Driver = Union[TranslationalDriver, RotationalDriver, AbsoluteDriver]


@dataclass(frozen=True)
class Mechanism:
    """A planar mechanism: named points, bodies, joints and drivers.

    Parameters
    ----------
    points : mapping of str to (x, y)
        Global coordinates of the named points in the initial configuration, m.
    bodies : sequence of Body
        The moving bodies; their order is the order of the coordinates
        ``(x, y, angle)`` in every result.
    joints, drivers : sequences
        Kinematic joints and driving constraints.
    name : str
        Name of the model (the default output folder of ``sparsekin run``).
    analysis : Analysis
        Defaults for the command line.
    """

    points: Mapping[str, tuple[float, float]]
    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...] = ()
    drivers: tuple[Driver, ...] = ()
    name: str = "mechanism"
    analysis: Analysis = field(default_factory=Analysis)
    _body_index: dict[str, int] = field(init=False, repr=False, compare=False)
    _joint_index: dict[str, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        _validate.name(self.name, "name")
        if not isinstance(self.points, Mapping):
            raise ModelError(f"expected a mapping of name to [x, y], got {type(self.points).__name__}", element="points")
        _set(self, "points", {_validate.name(key, "points"): _point_pair(key, value) for key, value in self.points.items()})
        _set(self, "bodies", _tuple_of(self.bodies, Body, "bodies"))
        _set(self, "joints", _tuple_of(self.joints, (Revolute, Translational, Rigid), "joints"))
        _set(self, "drivers", _tuple_of(self.drivers, (TranslationalDriver, RotationalDriver, AbsoluteDriver), "drivers"))
        if not isinstance(self.analysis, Analysis):
            raise ModelError(f"expected an Analysis, got {type(self.analysis).__name__}", element="analysis")
        body_index: dict[str, int] = {}
        for index, body in enumerate(self.bodies):
            if body.name == GROUND:
                raise ModelError(f'"{GROUND}" is reserved for the fixed body', element=f"bodies[{index}].name")
            if body.name in body_index:
                raise ModelError(f'duplicate body name "{body.name}"', element=f"bodies[{index}].name")
            body_index[body.name] = index
            self._check_point(body.origin, "bodies[{}].origin", index)
            for k, point in enumerate(body.points):
                self._check_point(point, "bodies[{}].points[{}]", index, k)
            if body.com is not None:
                self._check_point(body.com, "bodies[{}].com", index)
        _set(self, "_body_index", body_index)
        self._check_joints()
        self._check_drivers()
        if self.analysis.points is not None:
            for k, point in enumerate(self.analysis.points):
                self._check_point(point, "analysis.points[{}]", k)

    # ------------------------------------------------------------------ queries
    @property
    def n_bodies(self) -> int:
        """Number of moving bodies (the ground excluded)."""
        return len(self.bodies)

    @property
    def n_coordinates(self) -> int:
        """Number of coordinates, 3 per moving body."""
        return 3 * len(self.bodies)

    @property
    def n_equations(self) -> int:
        """Number of constraint equations, joints and drivers."""
        return sum(element.n_equations for element in (*self.joints, *self.drivers))

    @property
    def body_names(self) -> tuple[str, ...]:
        return tuple(body.name for body in self.bodies)

    def body_index(self, name: str) -> int:
        """Position of body `name` in `bodies`; -1 for the ground."""
        return -1 if name == GROUND else self._body_index[name]

    def position(self, reference: PointRef) -> tuple[float, float]:
        """Global initial coordinates of a point name or an ``(x, y)`` pair, m."""
        return self.points[reference] if isinstance(reference, str) else reference

    def body_indices(self, names: Iterable[str]) -> np.ndarray:
        """`body_index` of each name, as an int64 array (-1 for the ground)."""
        index = self._body_index
        return np.fromiter((-1 if name == GROUND else index[name] for name in names), dtype=np.int64)

    def positions(self, references: Iterable[PointRef]) -> np.ndarray:
        """`position` of each reference, as an array of shape (n, 2), m."""
        points = self.points
        flat = [coordinate for ref in references for coordinate in (points[ref] if type(ref) is str else ref)]
        return np.array(flat, dtype=float).reshape(-1, 2)

    def frame(self, body: str) -> tuple[float, float, float]:
        """Initial ``(x, y, angle)`` of the frame of `body`; zeros for the ground."""
        if body == GROUND:
            return (0.0, 0.0, 0.0)
        b = self.bodies[self._body_index[body]]
        x, y = self.position(b.origin)
        return (x, y, b.angle)

    def joint_named(self, name: str) -> Joint:
        """The joint called `name`; KeyError if there is none."""
        return self.joints[self._joint_index[name]]

    def element_label(self, kind: str, index: int) -> str:
        """``joints[3] "pivot" (revolute c3–c4 at I)``: a label for messages."""
        element = (self.joints if kind == "joints" else self.drivers)[index]
        named = f' "{element.name}"' if element.name else ""
        return f"{kind}[{index}]{named} ({element.describe()})"

    # ------------------------------------------------------------------ checks
    # Each check takes its element as a format string and its arguments, formatted only
    # when it fails: a million-body model is checked without a million f-strings.
    def _check_point(self, reference: PointRef, where: str, *where_arguments) -> None:
        if isinstance(reference, str) and reference not in self.points:
            raise ModelError(
                f'unknown point "{reference}" (known: {_validate.known_list(list(self.points))})',
                element=where.format(*where_arguments),
            )

    def _check_body(self, body: str, where: str, *where_arguments) -> None:
        if body != GROUND and body not in self._body_index:
            known = _validate.known_list([*self._body_index, GROUND])
            raise ModelError(f'unknown body "{body}" (known: {known})', element=where.format(*where_arguments))

    def _check_joints(self) -> None:
        joint_names: dict[str, int] = {}
        _set(self, "_joint_index", joint_names)
        for index, joint in enumerate(self.joints):
            for k, body in enumerate(joint.bodies):
                self._check_body(body, "joints[{}].bodies[{}]", index, k)
            if joint.name is not None:
                if joint.name in joint_names:
                    raise ModelError(f'duplicate joint name "{joint.name}"', element=f"joints[{index}].name")
                joint_names[joint.name] = index
            if isinstance(joint, Revolute):
                self._check_point(joint.at, "joints[{}].at", index)
            elif isinstance(joint, Translational):
                if joint.axis is not None:
                    self._check_point(joint.axis[0], "joints[{}].axis[0]", index)
                    self._check_point(joint.axis[1], "joints[{}].axis[1]", index)
                    p, q = self.position(joint.axis[0]), self.position(joint.axis[1])
                    if math.hypot(q[0] - p[0], q[1] - p[1]) == 0.0:
                        raise ModelError(
                            f"zero-length axis: {_shown_point(joint.axis[0])} and "
                            f"{_shown_point(joint.axis[1])} coincide; expected two distinct points",
                            element=f"joints[{index}].axis",
                        )
                else:
                    self._check_point(joint.at, "joints[{}].at", index)

    def _check_drivers(self) -> None:
        driver_names: set[str] = set()
        for index, driver in enumerate(self.drivers):
            if driver.name is not None:
                if driver.name in driver_names:
                    raise ModelError(f'duplicate driver name "{driver.name}"', element=f"drivers[{index}].name")
                driver_names.add(driver.name)
            if isinstance(driver, TranslationalDriver):
                try:
                    joint = self.joint_named(driver.joint)
                except KeyError:
                    known = [j.name for j in self.joints if isinstance(j, Translational) and j.name]
                    raise ModelError(
                        f'unknown joint "{driver.joint}" (known translational joints: '
                        f"{_validate.known_list(known) or 'none with a name'})",
                        element=f"drivers[{index}].joint",
                    ) from None
                if not isinstance(joint, Translational):
                    raise ModelError(
                        f'joint "{driver.joint}" is {joint.type_name}; expected a translational joint',
                        element=f"drivers[{index}].joint",
                    )
            elif isinstance(driver, RotationalDriver):
                for k, body in enumerate(driver.bodies):
                    self._check_body(body, "drivers[{}].bodies[{}]", index, k)
            else:
                self._check_body(driver.body, "drivers[{}].body", index)


def _point_pair(name: str, value: object) -> tuple[float, float]:
    """The coordinates of point `name` as ``(x, y)``, checked."""
    if type(value) is tuple and len(value) == 2 and type(value[0]) is type(value[1]) is float:
        if abs(value[0]) <= _validate.MAX_MAGNITUDE and abs(value[1]) <= _validate.MAX_MAGNITUDE:
            return value  # the common case, fast
    return _validate.pair(value, f"points.{name}")


def _joint_checks(joint) -> None:
    _set(joint, "bodies", _validate.two_names(joint.bodies, "bodies"))
    if joint.bodies[0] == joint.bodies[1]:
        raise ModelError(f'expected two different bodies, got "{joint.bodies[0]}" twice', element="bodies")
    if joint.name is not None:
        _validate.name(joint.name, "name")


def _driver_checks(driver) -> None:
    if driver.name is not None:
        _validate.name(driver.name, "name")
    if not callable(getattr(driver.law, "evaluate", None)):  # the `Law` protocol, without its slow isinstance
        raise ModelError(
            f"expected a law (an object with evaluate(t, initial)), got {type(driver.law).__name__}",
            element="law",
        )


def _tuple_of(items, kinds, where: str) -> tuple:
    if isinstance(items, (str, bytes, Mapping)) or not isinstance(items, Sequence):
        raise ModelError(f"expected a list, got {type(items).__name__}", element=where)
    for index, item in enumerate(items):
        if not isinstance(item, kinds):
            names = kinds.__name__ if isinstance(kinds, type) else " or ".join(k.__name__ for k in kinds)
            raise ModelError(f"expected {names}, got {type(item).__name__}", element=f"{where}[{index}]")
    return tuple(items)


def _shown_point(reference: PointRef | None) -> str:
    if isinstance(reference, str):
        return reference
    return f"({reference[0]:g}, {reference[1]:g})"

