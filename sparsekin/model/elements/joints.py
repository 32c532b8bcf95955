"""The joint kinds: revolute, translational, rigid, pin-in-slot, gear, rack-and-pinion."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import ModelError
from .. import _validate
from .._validate import FileKeys
from ..primitives import Coincidence, Combination, Projection
from .base import (
    GROUND,
    Columns,
    Joint,
    PointRef,
    _angle_difference,
    _direction,
    _normal,
    _pair_checks,
    _set,
    _unit,
    _zeros,
    joint_kind,
    shown_point,
)


@joint_kind
@dataclass(frozen=True, slots=True)
class Revolute(Joint):
    """Bodies ``bodies[0]`` and ``bodies[1]`` share the point `at` (2 equations).

    Own coordinate: the relative angle ``angle(bodies[0]) - angle(bodies[1])`` of the two
    body frames, rad, continuous in time.
    """

    bodies: tuple[str, str]
    at: PointRef
    name: str | None = None
    limits: tuple[float, float] | None = None

    type_name = "revolute"
    file_keys = FileKeys(required=("bodies", "at"), optional=("name", "limits"))
    equation_names = ("x", "y")
    output_names = ("angle", "rate", "accel")
    point_fields = ("at",)

    def __post_init__(self) -> None:
        _pair_checks(self)
        _set(self, "at", _validate.point_reference(self.at, "at"))

    def describe(self) -> str:
        return f"revolute {self.bodies[0]}–{self.bodies[1]} at {shown_point(self.at)}"

    @classmethod
    def equations(cls, joints: Columns):
        at = joints.point("at")
        return [Coincidence(joints.rows, *joints.pair(), at, at)]

    @classmethod
    def outputs(cls, joints: Columns):
        return [_angle_difference(joints.rows, *joints.pair())]

    @classmethod
    def reaction_point(cls, joints: Columns):
        return 0, joints.point("at")

    def draw(self, canvas) -> None:
        canvas.pin(canvas.point(self.bodies[0], self.at), grounded=GROUND in self.bodies)


@joint_kind
@dataclass(frozen=True, slots=True)
class Translational(Joint):
    """``bodies[1]`` slides along a line fixed in ``bodies[0]``; relative rotation locked.

    Give either ``axis = (P, Q)``, P on the first body and Q on the second (the line
    through P along P→Q), or ``at = P`` with a global initial ``direction = (dx, dy)``.
    2 equations.  Own coordinate: the stroke, the distance from P to Q measured along the
    axis (for the ``at`` form: the displacement of the second body's point from the
    first's along the direction, 0 at the start), m.
    """

    bodies: tuple[str, str]
    axis: tuple[PointRef, PointRef] | None = None
    at: PointRef | None = None
    direction: tuple[float, float] | None = None
    name: str | None = None
    limits: tuple[float, float] | None = None

    type_name = "translational"
    file_keys = FileKeys(required=("bodies",), optional=("name", "limits"), forms=(("axis",), ("at", "direction")))
    equation_names = ("relative angle", "offset from the axis")
    output_names = ("stroke", "speed", "accel")
    point_fields = ("axis", "at")
    reaction_torque = True

    def __post_init__(self) -> None:
        _pair_checks(self)
        if self.axis is not None:
            if self.at is not None or self.direction is not None:
                raise ModelError("give either `axis` or `at` with `direction`, not both", element="axis")
            axis = self.axis
            if isinstance(axis, str) or not _validate.is_sequence(axis) or len(axis) != 2:
                raise ModelError(f"expected two points [P, Q], got {axis!r}", element="axis")
            _set(self, "axis", (_validate.point_reference(axis[0], "axis[0]"),
                                _validate.point_reference(axis[1], "axis[1]")))  # fmt: skip
            if self.axis[0] == self.axis[1]:
                raise ModelError(
                    f"zero-length axis: P and Q are the same point {shown_point(self.axis[0])}; "
                    "expected two distinct points",
                    element="axis",
                )
        else:
            if self.at is None or self.direction is None:
                raise ModelError("expected `axis = [P, Q]`, or `at` with `direction`", element="axis")
            _set(self, "at", _validate.point_reference(self.at, "at"))
            _set(self, "direction", _direction(self.direction))

    def check(self, mechanism, where: str) -> None:
        if self.axis is not None:
            p, q = mechanism.position(self.axis[0]), mechanism.position(self.axis[1])
            if math.hypot(q[0] - p[0], q[1] - p[1]) == 0.0:
                raise ModelError(
                    f"zero-length axis: {shown_point(self.axis[0])} and {shown_point(self.axis[1])} "
                    "coincide; expected two distinct points",
                    element=f"{where}.axis",
                )

    def describe(self) -> str:
        if self.axis is not None:
            where = f"along {shown_point(self.axis[0])}→{shown_point(self.axis[1])}"
        else:
            where = f"at {shown_point(self.at)} along {self.direction}"
        return f"translational {self.bodies[0]}–{self.bodies[1]} {where}"

    @classmethod
    def equations(cls, joints: Columns):
        i, j = joints.pair()
        start, end, axis = cls.geometry(joints)
        rows = joints.rows
        return [_angle_difference(rows, i, j), Projection(rows + 1, i, j, start, end, _normal(axis), _zeros(rows))]

    @classmethod
    def outputs(cls, joints: Columns):
        return [cls.stroke(joints)]

    @classmethod
    def reaction_point(cls, joints: Columns):
        return 0, cls.geometry(joints)[0]  # P, the first axis point (or `at`)

    @classmethod
    def stroke(cls, joints: Columns, rows: np.ndarray | None = None) -> Projection:
        """The stroke of each joint, as a projection on its axis (also what drives it), on
        `rows` (default the joints' own)."""
        start, end, axis = cls.geometry(joints)
        rows = joints.rows if rows is None else rows
        return Projection(rows, *joints.pair(), start, end, axis, _zeros(rows))

    @classmethod
    def geometry(cls, joints: Columns) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Start points, end points and unit axes, drawn, global, each shape (k, 2).

        For the ``at`` / ``direction`` form the start and the end are both ``at``.
        """
        axis_form = joints.given("axis")[:, None]
        at = joints.point("at")
        start = np.where(axis_form, joints.point("axis", 0), at)
        end = np.where(axis_form, joints.point("axis", 1), at)
        return start, end, _unit(np.where(axis_form, end - start, joints.vector("direction")))

    def draw(self, canvas) -> None:
        """A guide on ``bodies[0]`` and a slider on it; one-point bodies (a hydraulic
        cylinder and its rod, a slider block) drawn along the axis (`Canvas.slide`)."""
        if self.axis is not None:
            canvas.slide(*self.bodies, self.axis[0], self.axis[1], limits=self.limits)
        else:
            canvas.slide(*self.bodies, self.at, self.at, direction=self.direction, limits=self.limits)


@joint_kind
@dataclass(frozen=True, slots=True)
class Rigid(Joint):
    """``bodies[0]`` and ``bodies[1]`` are welded together (3 equations)."""

    bodies: tuple[str, str]
    name: str | None = None

    type_name = "rigid"
    file_keys = FileKeys(required=("bodies",), optional=("name",))
    equation_names = ("x", "y", "relative angle")
    reaction_torque = True

    def __post_init__(self) -> None:
        _pair_checks(self)

    def describe(self) -> str:
        return f"rigid {self.bodies[0]}–{self.bodies[1]}"

    @classmethod
    def equations(cls, joints: Columns):
        i, j = joints.pair()
        origin = joints.frames[j, :2]  # the frame origin of bodies[1], welded to bodies[0]
        return [Coincidence(joints.rows, i, j, origin, origin), _angle_difference(joints.rows + 2, i, j)]

    def draw(self, canvas) -> None:
        canvas.weld(canvas.origin(self.bodies[1]))


@joint_kind
@dataclass(frozen=True, slots=True)
class PinInSlot(Joint):
    """The point `at` of ``bodies[1]`` stays on the line of ``bodies[0]`` through `at` along
    `direction` (global, initial); rotation is free.  1 equation.

    Own coordinate: the slide, the position of the pin along the slot from its initial
    place, m.
    """

    bodies: tuple[str, str]
    at: PointRef
    direction: tuple[float, float]
    name: str | None = None
    limits: tuple[float, float] | None = None

    type_name = "pin_in_slot"
    file_keys = FileKeys(required=("bodies", "at", "direction"), optional=("name", "limits"))
    equation_names = ("offset from the slot",)
    output_names = ("slide", "speed", "accel")
    point_fields = ("at",)

    def __post_init__(self) -> None:
        _pair_checks(self)
        _set(self, "at", _validate.point_reference(self.at, "at"))
        _set(self, "direction", _direction(self.direction))

    def describe(self) -> str:
        return f"pin in slot {self.bodies[0]}–{self.bodies[1]} at {shown_point(self.at)} along {self.direction}"

    @classmethod
    def equations(cls, joints: Columns):
        return [cls._along(joints, normal=True)]

    @classmethod
    def outputs(cls, joints: Columns):
        return [cls._along(joints, normal=False)]

    @classmethod
    def reaction_point(cls, joints: Columns):
        return 1, joints.point("at")  # the pin, on bodies[1]

    @classmethod
    def _along(cls, joints: Columns, normal: bool) -> Projection:
        at = joints.point("at")
        along = _unit(joints.vector("direction"))
        return Projection(joints.rows, *joints.pair(), at, at, _normal(along) if normal else along, _zeros(joints.rows))

    def draw(self, canvas) -> None:
        centre = canvas.point(self.bodies[0], self.at)
        along = canvas.direction(self.bodies[0], self.direction)
        canvas.slot(centre, along, self.limits)
        pin = canvas.point(self.bodies[1], self.at)
        if canvas.single_point(self.bodies[1]):  # a block sliding in the slot
            canvas.block(self.bodies[1], pin, along)
        canvas.pin(pin, grounded=False)


@joint_kind
@dataclass(frozen=True, slots=True)
class Gear(Joint):
    """Two gears on a carrier: ``angle(i) - angle(k) = -ratio · (angle(j) - angle(k))`` from
    the initial configuration, with ``bodies = (i, j)`` and ``carrier = k``.

    For external gears of pitch radii R_i and R_j the ratio is ``R_j / R_i``; an internal
    gear (j a ring around i) has a negative ratio, ``-R_j / R_i``.  The gears' pivots on
    the carrier are separate revolute joints.  1 equation.
    """

    bodies: tuple[str, str]
    ratio: float
    carrier: str = GROUND
    name: str | None = None

    type_name = "gear"
    file_keys = FileKeys(required=("bodies", "ratio"), optional=("carrier", "name"))
    equation_names = ("gear ratio",)
    body_fields = ("bodies", "carrier")
    reaction_torque = True  # its equation ties angles only: its reaction is a torque

    def __post_init__(self) -> None:
        _pair_checks(self)
        _set(self, "ratio", _validate.finite_float(self.ratio, "ratio"))
        if self.ratio == 0.0:
            raise ModelError("expected a non-zero ratio (R_j / R_i; negative for an internal gear)", element="ratio")
        _validate.name(self.carrier, "carrier")
        if self.carrier in self.bodies:
            raise ModelError(f'the carrier "{self.carrier}" is one of the gears; expected a third body '
                             f'(default "{GROUND}")', element="carrier")  # fmt: skip

    def describe(self) -> str:
        carrier = "" if self.carrier == GROUND else f" on {self.carrier}"
        return f"gear {self.bodies[0]}–{self.bodies[1]}{carrier}, ratio {self.ratio:g}"

    @classmethod
    def equations(cls, joints: Columns):
        i, j = joints.pair()
        ratio = joints.number("ratio")
        return [Combination(
            joints.rows, np.stack([i, j, joints.body("carrier")], axis=1), np.full((ratio.size, 3), 2),
            np.stack([np.ones_like(ratio), ratio, -1.0 - ratio], axis=1),
        )]  # fmt: skip

    def draw(self, canvas) -> None:
        first, second = (canvas.pivot(body, self.carrier) for body in self.bodies)
        distance = float(np.hypot(*(second - first)))
        # pitch radii from the centre distance: R_i + R_j (external) or R_j - R_i (internal)
        denominator = 1.0 + self.ratio if self.ratio > 0.0 else -self.ratio - 1.0
        if distance > 0.0 and denominator > 0.0:
            radius = distance / denominator
            canvas.circle(first, radius)
            canvas.circle(second, abs(self.ratio) * radius)


@joint_kind
@dataclass(frozen=True, slots=True)
class RackPinion(Joint):
    """A pinion rolling on a rack: ``bodies = (rack, pinion)``, `at` the pinion's centre,
    `direction` the rack's line, `radius` the pinion's pitch radius.

    The travel of the centre along the rack (relative to the rack, from its initial
    place) and the pinion's rotation relative to the rack are tied:
    ``travel = -radius · rotation`` (the rack's pitch line lies on the right of
    `direction`).  The centre is guided separately, e.g. by a pin_in_slot.  1 equation.
    """

    bodies: tuple[str, str]
    at: PointRef
    direction: tuple[float, float]
    radius: float
    name: str | None = None

    type_name = "rack_pinion"
    file_keys = FileKeys(required=("bodies", "at", "direction", "radius"), optional=("name",))
    equation_names = ("rolling",)
    point_fields = ("at",)
    reaction_torque = True

    def __post_init__(self) -> None:
        _pair_checks(self)
        _set(self, "at", _validate.point_reference(self.at, "at"))
        _set(self, "direction", _direction(self.direction))
        _set(self, "radius", _validate.finite_float(self.radius, "radius"))
        if not self.radius > 0.0:
            raise ModelError(f"expected a pitch radius > 0 (m), got {self.radius!r}", element="radius")

    def describe(self) -> str:
        return f"rack {self.bodies[0]} and pinion {self.bodies[1]} at {shown_point(self.at)}, radius {self.radius:g}"

    @classmethod
    def equations(cls, joints: Columns):
        at = joints.point("at")
        return [Projection(joints.rows, *joints.pair(), at, at, _unit(joints.vector("direction")), joints.number("radius"))]

    @classmethod
    def reaction_point(cls, joints: Columns):
        return 1, joints.point("at")  # the pinion's centre

    def draw(self, canvas) -> None:
        centre = canvas.point(self.bodies[1], self.at)
        along = canvas.direction(self.bodies[0], self.direction)
        pitch = canvas.point(self.bodies[0], self.at) + self.radius * np.array([along[1], -along[0]])
        canvas.circle(centre, self.radius)
        canvas.line(pitch - 3.0 * self.radius * along, pitch + 3.0 * self.radius * along)
