"""Joints and drivers: every kind declared once, in this module.

A kind is a frozen dataclass whose fields are its keys in the model file, registered with
`joint_kind` or `driver_kind`.  Its declaration says everything the rest of the package
needs of it; the model checks, the pattern builder, the model-file reader and writer,
the drawing, the joint outputs and the generated element reference all iterate over the
registries `JOINT_KINDS` and `DRIVER_KINDS`:

=====================  ==============================================================
``type_name``          its ``type`` in the model file
``file_keys``          the keys it accepts (`sparsekin.model._validate.FileKeys`)
``equation_names``     one name per equation, in row order (their number is
                       ``n_equations``)
``equations``          classmethod: its equations as blocks of the primitives of
                       `sparsekin.model.primitives`, for all elements of the kind at once,
                       read from their `Columns`
``output_names``       its own coordinate and two derivatives (``joints.csv`` column
                       suffixes), or ``()`` if it has none
``outputs``            classmethod: the primitive that measures its own coordinate
``body_fields``,       fields naming bodies, points and joints, which the mechanism
``point_fields``,      checks (and which a unit's copies rename)
``joint_fields``
``check``              method: checks that need the whole mechanism (optional)
``describe``           method: a few words for messages
``draw``               method: its drawing, on a `sparsekin.plots.Canvas`
``law_fields``         drivers only: the field holding the law of each equation, in
                       row order (default ``("law",)``)
``force_names``        drivers only: the ``forces.csv`` column suffix of each
                       equation's force (default ``("force",)``)
``reaction_point``     joints only, classmethod: the point about which the reaction's
                       torque is taken, and the body of the joint that carries it
                       (default: the frame origin of ``bodies[0]``)
``reaction_torque``    joints only: whether ``forces.csv`` has the reaction's torque
=====================  ==============================================================

Loads (`LOAD_KINDS`, registered with `load_kind`) declare ``type_name``, ``file_keys``,
``loads`` (classmethod: their blocks of the primitive loads of `sparsekin.model.loads`, read
from their `Columns`, whose ``rows`` are then the index of each load's first law),
``n_laws`` and ``laws()`` (the law of each component), ``describe`` and ``draw``.

The guide ``docs/adding-an-element.md`` walks through adding a kind.

Equation builders receive the elements of one kind as `Columns`: one array per field,
an entry per element (the model's own elements, or a unit's over all its copies at once;
`sparsekin.engine.columns`), with the first row of each element, the stored index of each body
named (the ground is ``columns.ground``), the drawn positions of points and the drawn
body frames.  Blocks are written in the global coordinates of the drawn configuration;
joints hold the values their equations have there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, Union

import numpy as np

from ..errors import ModelError
from . import _validate
from ._validate import FileKeys
from .laws import Law, Polynomial
from .loads import BodyTorque, PointForce, SpringDamper
from .primitives import Coincidence, Combination, Distance, Projection

__all__ = [
    "GROUND",
    "COORDINATE_NAMES",
    "JOINT_KINDS",
    "DRIVER_KINDS",
    "joint_kind",
    "driver_kind",
    "Revolute",
    "Translational",
    "Rigid",
    "PinInSlot",
    "Gear",
    "RackPinion",
    "TranslationalDriver",
    "RotationalDriver",
    "AbsoluteDriver",
    "DistanceDriver",
    "PathDriver",
    "LOAD_KINDS",
    "load_kind",
    "Load",
    "Force",
    "Torque",
    "Spring",
]

#: Name of the fixed body.
GROUND = "ground"
#: The coordinates of a body frame, in the order they are stored.
COORDINATE_NAMES = ("x", "y", "angle")

#: A point: the name of a point of the model, or its global coordinates (x, y) in m.
PointRef = Union[str, tuple[float, float]]

#: The registries, by file ``type``, in the order kinds are declared.
JOINT_KINDS: dict[str, type] = {}
DRIVER_KINDS: dict[str, type] = {}
LOAD_KINDS: dict[str, type] = {}

#: What every kind must declare (see the module docstring).
_DECLARATION = ("type_name", "file_keys", "equation_names", "equations", "describe", "draw")


class Columns(Protocol):
    """The elements of one kind as arrays, an entry per element (`sparsekin.engine.columns`)."""

    rows: np.ndarray  # (k,): the first row of each element
    ground: int  # the stored index of the ground
    frames: np.ndarray  # (n_bodies + 1, 3): drawn (x, y, angle) of each body, the ground last

    def pair(self, field: str = "bodies") -> tuple[np.ndarray, np.ndarray]: ...  # the two bodies' indices

    def body(self, field: str) -> np.ndarray: ...  # (k,) the body's index

    def point(self, field: str, item: int | None = None) -> np.ndarray: ...  # (k, 2) drawn position; NaN if None

    def number(self, field: str) -> np.ndarray: ...  # (k,)

    def vector(self, field: str) -> np.ndarray: ...  # (k, 2)

    def given(self, field: str) -> np.ndarray: ...  # (k,) bool: the field is not None

    def choice(self, field: str, choices) -> np.ndarray: ...  # (k,) index of the value in `choices`

    def joints(self, field: str) -> Columns: ...  # the joints named by the field, with these rows


def _register(registry: dict[str, type], kind: type, declaration: tuple[str, ...] = _DECLARATION) -> type:
    missing = [name for name in declaration if not hasattr(kind, name)]
    if missing:
        raise TypeError(f"{kind.__name__} does not declare {', '.join(missing)}")
    if kind.type_name in registry:
        raise TypeError(f'two kinds declare the type "{kind.type_name}"')
    fields = set(getattr(kind, "__dataclass_fields__", ()))
    unknown = [key for key in kind.file_keys.keys if key not in fields]
    if unknown:
        raise TypeError(f"{kind.__name__}.file_keys names {unknown}, which are not fields")
    if kind.output_names and not hasattr(kind, "outputs"):
        raise TypeError(f"{kind.__name__} declares output_names but no outputs")
    if registry is not LOAD_KINDS:
        kind.n_equations = len(kind.equation_names)
    registry[kind.type_name] = kind
    return kind


def joint_kind(kind: type) -> type:
    """Class decorator: check the declaration of a joint kind and register it."""
    return _register(JOINT_KINDS, kind)


def driver_kind(kind: type) -> type:
    """Class decorator: check the declaration of a driver kind and register it."""
    if len(kind.law_fields) != len(kind.equation_names):
        raise TypeError(f"{kind.__name__} declares {len(kind.law_fields)} law fields for "
                        f"{len(kind.equation_names)} equations")  # fmt: skip
    return _register(DRIVER_KINDS, kind)


def load_kind(kind: type) -> type:
    """Class decorator: check the declaration of a load kind and register it."""
    return _register(LOAD_KINDS, kind, ("type_name", "file_keys", "loads", "n_laws", "describe", "draw"))


class _Element:
    """Defaults shared by joints, drivers and loads."""

    __slots__ = ()
    output_names: tuple[str, ...] = ()
    body_fields: tuple[str, ...] = ("bodies",)
    point_fields: tuple[str, ...] = ()
    joint_fields: tuple[str, ...] = ()

    def check(self, mechanism, where: str) -> None:
        """Checks that need the mechanism (`where` is ``joints[3]``); none by default."""


class Joint(_Element):
    """Base of the joint kinds."""

    __slots__ = ()
    reaction_torque: bool = False

    @classmethod
    def reaction_point(cls, joints: Columns) -> tuple[np.ndarray, np.ndarray]:
        """``(carrier, point)``: 0 or 1, which of the two bodies carries the point about
        which the reaction's torque is taken, and its drawn position (k, 2); here the
        frame origin of ``bodies[0]``."""
        first, _ = joints.pair()
        return 0, joints.frames[first, :2]


class Driver(_Element):
    """Base of the driver kinds: each equation follows the law in one field."""

    __slots__ = ()
    law_fields: tuple[str, ...] = ("law",)
    force_names: tuple[str, ...] = ("force",)

    def laws(self) -> tuple[Law, ...]:
        """The law of each equation, in row order."""
        return tuple(getattr(self, name) for name in self.law_fields)


# ---------------------------------------------------------------------- joints
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


# ---------------------------------------------------------------------- drivers
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


# ---------------------------------------------------------------------- loads
class Load(_Element):
    """Base of the load kinds: forces and torques applied to the bodies.

    A component given as a number is constant; as a law (`sparsekin.model.laws`), it follows
    the law, whose ``offset``/``start`` default to 0 (a load has no "initial" value).
    """

    __slots__ = ()
    body_fields: tuple[str, ...] = ("body",)
    n_laws = 0

    def laws(self) -> tuple[Law, ...]:
        """The law of each component, in order; numbers as constant laws."""
        return ()


@load_kind
@dataclass(frozen=True, slots=True)
class Force(Load):
    """A force on `body` at its point `at`, ``value = (fx, fy)`` in global axes (N), each
    component a number or a law."""

    body: str
    at: PointRef
    value: tuple[float | Law, float | Law]
    name: str | None = None

    type_name = "force"
    file_keys = FileKeys(required=("body", "at", "value"), optional=("name",))
    point_fields = ("at",)
    n_laws = 2

    def __post_init__(self) -> None:
        _load_checks(self)
        _set(self, "at", _validate.point_reference(self.at, "at"))
        value = self.value
        if isinstance(value, str) or not _validate.is_sequence(value) or len(value) != 2:
            raise ModelError(f"expected [fx, fy], each a number or a law, got {value!r}", element="value")
        _set(self, "value", (_component(value[0], "value[0]"), _component(value[1], "value[1]")))

    def laws(self) -> tuple[Law, ...]:
        return tuple(_as_law(component) for component in self.value)

    def describe(self) -> str:
        return f"force on {self.body} at {shown_point(self.at)}"

    @classmethod
    def loads(cls, loads: Columns):
        return [PointForce(loads.rows, loads.body("body"), loads.point("at"))]

    def draw(self, canvas) -> None:
        direction = [float(law.evaluate(0.0, 0.0)[0]) for law in self.laws()]
        canvas.arrow(canvas.point(self.body, self.at), direction)


@load_kind
@dataclass(frozen=True, slots=True)
class Torque(Load):
    """A torque on `body`, `value` a number or a law (N·m, counter-clockwise positive)."""

    body: str
    value: float | Law
    name: str | None = None

    type_name = "torque"
    file_keys = FileKeys(required=("body", "value"), optional=("name",))
    n_laws = 1

    def __post_init__(self) -> None:
        _load_checks(self)
        _set(self, "value", _component(self.value, "value"))

    def laws(self) -> tuple[Law, ...]:
        return (_as_law(self.value),)

    def describe(self) -> str:
        return f"torque on {self.body}"

    @classmethod
    def loads(cls, loads: Columns):
        return [BodyTorque(loads.rows, loads.body("body"))]

    def draw(self, canvas) -> None:
        canvas.turn(canvas.origin(self.body))


@load_kind
@dataclass(frozen=True, slots=True)
class Spring(Load):
    """A spring-damper between point ``points[0]`` of ``bodies[0]`` and point ``points[1]``
    of ``bodies[1]``: tension ``stiffness · (L - free_length) + damping · L'`` (N) along
    the line between them, L their distance (m).  `free_length` defaults to the drawn
    distance; the points must not coincide in the drawing."""

    bodies: tuple[str, str]
    points: tuple[PointRef, PointRef]
    stiffness: float
    free_length: float | None = None
    damping: float = 0.0
    name: str | None = None

    type_name = "spring"
    file_keys = FileKeys(required=("bodies", "points", "stiffness"), optional=("free_length", "damping", "name"))
    body_fields = ("bodies",)
    point_fields = ("points",)

    def __post_init__(self) -> None:
        _pair_checks(self)
        _set(self, "points", _two_points(self.points))
        _set(self, "stiffness", _validate.non_negative_float(self.stiffness, "stiffness"))
        _set(self, "damping", _validate.non_negative_float(self.damping, "damping"))
        if self.free_length is not None:
            _set(self, "free_length", _validate.non_negative_float(self.free_length, "free_length"))

    def check(self, mechanism, where: str) -> None:
        _check_apart(mechanism, self.points, where, "the spring's force has no direction at zero length")

    def describe(self) -> str:
        return f"spring {_point_pair_words(self)}"

    @classmethod
    def loads(cls, loads: Columns):
        return [SpringDamper(*loads.pair(), loads.point("points", 0), loads.point("points", 1), loads.number("stiffness"),
                             loads.number("free_length"), loads.number("damping"))]  # NaN free length: the drawn one

    def draw(self, canvas) -> None:
        canvas.spring(*(canvas.point(body, point) for body, point in zip(self.bodies, self.points)))


def _load_checks(load) -> None:
    _validate.name(load.body, "body")
    if load.name is not None:
        _validate.name(load.name, "name")


def _component(value, element: str):
    """A load component: a finite number, or a law."""
    if callable(getattr(value, "evaluate", None)):
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ModelError(f"expected a number or a law table {{ type = ... }}, got {value!r}", element=element)
    return _validate.finite_float(value, element)


def _as_law(component) -> Law:
    return component if callable(getattr(component, "evaluate", None)) else Polynomial((component,))


# ---------------------------------------------------------------------- helpers
def shown_point(reference: PointRef | None) -> str:
    """A point reference in words: its name, or ``(x, y)``."""
    if isinstance(reference, str):
        return reference
    return f"({reference[0]:g}, {reference[1]:g})"


def _two_points(points) -> tuple[PointRef, PointRef]:
    """The ``points`` of a two-point element (a distance driver, a spring), validated."""
    if isinstance(points, str) or not _validate.is_sequence(points) or len(points) != 2:
        raise ModelError(f"expected two points [P, Q], got {points!r}", element="points")
    return _validate.point_reference(points[0], "points[0]"), _validate.point_reference(points[1], "points[1]")


def _check_apart(mechanism, points, where: str, why: str) -> None:
    """The two points of a two-point element must not coincide in the drawing."""
    p, q = mechanism.position(points[0]), mechanism.position(points[1])
    if math.hypot(q[0] - p[0], q[1] - p[1]) == 0.0:
        raise ModelError(
            f"{shown_point(points[0])} and {shown_point(points[1])} coincide in the drawing; "
            f"expected two distinct points ({why})",
            element=f"{where}.points",
        )


def _point_pair_words(element) -> str:
    """``c1.A–rod.B``: the two ends of a two-point element in words."""
    (body_i, body_j), (point_i, point_j) = element.bodies, element.points
    return f"{body_i}.{shown_point(point_i)}–{body_j}.{shown_point(point_j)}"


def _angle_difference(rows: np.ndarray, i: np.ndarray, j: np.ndarray) -> Combination:
    """``angle_i - angle_j`` on each row."""
    ones = np.ones(rows.size)
    return Combination(rows, np.stack([i, j], axis=1), np.full((rows.size, 2), 2), np.stack([ones, -ones], axis=1))


def _unit(vectors: np.ndarray) -> np.ndarray:
    return vectors / np.hypot(vectors[:, 0], vectors[:, 1])[:, None]


def _normal(unit: np.ndarray) -> np.ndarray:
    """Each unit vector turned by +90°."""
    return np.stack([-unit[:, 1], unit[:, 0]], axis=1)


def _zeros(rows: np.ndarray) -> np.ndarray:
    return np.zeros(rows.size)


def _direction(value: object) -> tuple[float, float]:
    direction = _validate.pair(value, "direction")
    if math.hypot(*direction) == 0.0:
        raise ModelError("zero-length direction: expected a non-zero [dx, dy]", element="direction")
    return direction


def _set(instance: object, field_name: str, value: object) -> None:
    """Store the canonical form of a field (tuples for sequences, floats for numbers)."""
    object.__setattr__(instance, field_name, value)


def _pair_checks(element) -> None:
    """``bodies``, two different names; ``name`` and ``limits`` when given."""
    _set(element, "bodies", _validate.two_names(element.bodies, "bodies"))
    if element.bodies[0] == element.bodies[1]:
        raise ModelError(f'expected two different bodies, got "{element.bodies[0]}" twice', element="bodies")
    if element.name is not None:
        _validate.name(element.name, "name")
    if getattr(element, "limits", None) is not None:
        _set(element, "limits", _validate.limits(element.limits, "limits"))


def _driver_checks(driver) -> None:
    if driver.name is not None:
        _validate.name(driver.name, "name")
    for field_name in driver.law_fields:
        law = getattr(driver, field_name)
        if not callable(getattr(law, "evaluate", None)):  # the `Law` protocol, without its slow isinstance
            raise ModelError(
                f"expected a law (an object with evaluate(t, initial)), got {type(law).__name__}",
                element=field_name,
            )
