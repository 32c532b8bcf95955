"""The driver kinds: translational, rotational, absolute, distance and path drivers."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ModelError
from .. import _validate
from .._validate import FileKeys
from ..laws import Law
from ..primitives import Coincidence, Combination, Distance
from .base import (
    COORDINATE_NAMES,
    GROUND,
    Columns,
    Driver,
    PointRef,
    _angle_difference,
    _check_apart,
    _driver_checks,
    _pair_checks,
    _point_pair_words,
    _set,
    _two_points,
    driver_kind,
    shown_point,
)
from .joints import Translational


@driver_kind
@dataclass(frozen=True, slots=True)
class TranslationalDriver(Driver):
    """Drives the stroke of the translational joint named `joint` (m).

    The stroke is the distance from P to Q measured along the axis (for the ``at`` /
    ``direction`` form, the displacement of the second body's point from the first's
    along the direction, 0 at the start).  Positive means the points move apart.
    """

    joint: str
    law: Law
    name: str | None = None

    type_name = "translational"
    file_keys = FileKeys(required=("joint", "law"), optional=("name",))
    equation_names = ("driven value",)
    output_names = ("value", "rate", "accel")
    body_fields = ()
    joint_fields = ("joint",)

    def __post_init__(self) -> None:
        _validate.name(self.joint, "joint")
        _driver_checks(self)

    def check(self, mechanism, where: str) -> None:
        try:
            joint = mechanism.joint_named(self.joint)
        except KeyError:
            known = [j.name for j in mechanism.joints if isinstance(j, Translational) and j.name]
            raise ModelError(
                f'unknown joint "{self.joint}" (known translational joints: '
                f"{_validate.known_list(known) or 'none with a name'})",
                element=f"{where}.joint",
            ) from None
        if not isinstance(joint, Translational):
            raise ModelError(
                f'joint "{self.joint}" is {joint.type_name}; expected a translational joint', element=f"{where}.joint"
            )

    def describe(self) -> str:
        return f'stroke of joint "{self.joint}"'


    @classmethod
    def equations(cls, drivers: Columns):
        return [Translational.stroke(drivers.joints("joint"), drivers.rows)]

    outputs = equations

    def draw(self, canvas) -> None:
        """Drawn by its joint."""


@driver_kind
@dataclass(frozen=True, slots=True)
class RotationalDriver(Driver):
    """Drives the relative angle ``angle(bodies[0]) - angle(bodies[1])`` (rad)."""

    bodies: tuple[str, str]
    law: Law
    name: str | None = None

    type_name = "rotational"
    file_keys = FileKeys(required=("bodies", "law"), optional=("name",))
    equation_names = ("driven value",)
    output_names = ("value", "rate", "accel")

    def __post_init__(self) -> None:
        _pair_checks(self)
        _driver_checks(self)

    def describe(self) -> str:
        return f"angle {self.bodies[0]} − {self.bodies[1]}"


    @classmethod
    def equations(cls, drivers: Columns):
        return [_angle_difference(drivers.rows, *drivers.pair())]

    outputs = equations

    def draw(self, canvas) -> None:
        """Nothing to draw: its bodies are joined by a revolute."""


@driver_kind
@dataclass(frozen=True, slots=True)
class AbsoluteDriver(Driver):
    """Drives one coordinate (``"x"``, ``"y"`` or ``"angle"``) of the frame of `body`."""

    body: str
    coordinate: str
    law: Law
    name: str | None = None

    type_name = "absolute"
    file_keys = FileKeys(required=("body", "coordinate", "law"), optional=("name",))
    equation_names = ("driven value",)
    output_names = ("value", "rate", "accel")
    body_fields = ("body",)

    def __post_init__(self) -> None:
        _validate.name(self.body, "body")
        if self.body == GROUND:
            raise ModelError("the ground cannot be driven: expected a moving body", element="body")
        _validate.choice(self.coordinate, "coordinate", COORDINATE_NAMES)
        _driver_checks(self)

    def describe(self) -> str:
        return f"{self.coordinate} of {self.body}"


    @classmethod
    def equations(cls, drivers: Columns):
        rows = drivers.rows
        coordinate = drivers.choice("coordinate", COORDINATE_NAMES)[:, None]
        return [Combination(rows, drivers.body("body")[:, None], coordinate, np.ones((rows.size, 1)))]

    outputs = equations

    def draw(self, canvas) -> None:
        """Nothing to draw."""


@driver_kind
@dataclass(frozen=True, slots=True)
class DistanceDriver(Driver):
    """Drives the distance between point ``points[0]`` of ``bodies[0]`` and point
    ``points[1]`` of ``bodies[1]`` (m): an actuator without cylinder and rod bodies."""

    points: tuple[PointRef, PointRef]
    bodies: tuple[str, str]
    law: Law
    name: str | None = None
    limits: tuple[float, float] | None = None

    type_name = "distance"
    file_keys = FileKeys(required=("points", "bodies", "law"), optional=("name", "limits"))
    equation_names = ("driven value",)
    output_names = ("value", "rate", "accel")
    point_fields = ("points",)

    def __post_init__(self) -> None:
        _pair_checks(self)
        _set(self, "points", _two_points(self.points))
        _driver_checks(self)

    def check(self, mechanism, where: str) -> None:
        _check_apart(mechanism, self.points, where, "the distance has no direction at zero length")

    def describe(self) -> str:
        return f"distance {_point_pair_words(self)}"

    @classmethod
    def equations(cls, drivers: Columns):
        return [Distance(drivers.rows, *drivers.pair(), drivers.point("points", 0), drivers.point("points", 1))]

    outputs = equations

    def draw(self, canvas) -> None:
        ends = [canvas.point(body, point) for body, point in zip(self.bodies, self.points)]
        drawn = [canvas.drawn_point(point) for point in self.points]
        canvas.actuator(*ends, drawn_length=float(np.hypot(*(drawn[1] - drawn[0]))))
        for body, end in zip(self.bodies, ends):
            canvas.pin(end, grounded=body == GROUND)


@driver_kind
@dataclass(frozen=True, slots=True)
class PathDriver(Driver):
    """The global x and y of the point `point` of `body` follow `law_x` and `law_y` (m).

    Prescribing a point's path instead of the actuators: inverse kinematics.
    """

    body: str
    point: PointRef
    law_x: Law
    law_y: Law
    name: str | None = None

    type_name = "path"
    file_keys = FileKeys(required=("body", "point", "law_x", "law_y"), optional=("name",))
    equation_names = ("x", "y")
    law_fields = ("law_x", "law_y")
    force_names = ("fx", "fy")
    body_fields = ("body",)
    point_fields = ("point",)

    def __post_init__(self) -> None:
        _validate.name(self.body, "body")
        if self.body == GROUND:
            raise ModelError("a point of the ground cannot follow a path: expected a moving body", element="body")
        _set(self, "point", _validate.point_reference(self.point, "point"))
        _driver_checks(self)

    def describe(self) -> str:
        return f"path of {shown_point(self.point)} on {self.body}"


    @classmethod
    def equations(cls, drivers: Columns):
        body = drivers.body("body")
        point = drivers.point("point")
        ground = np.full_like(body, drivers.ground)
        return [Coincidence(drivers.rows, body, ground, point, np.zeros_like(point))]  # minus the ground's origin

    def draw(self, canvas) -> None:
        canvas.target(canvas.point(self.body, self.point))
