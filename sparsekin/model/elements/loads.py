"""The load kinds: a force at a point, a torque, a spring-damper, a rotational spring-damper,
an actuator along a joint."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ModelError
from .. import _validate
from .._validate import FileKeys
from ..laws import Law, Polynomial
from ..loads import BodyTorque, JointActuator, PointForce, SpringDamper, TorsionSpring
from .base import (
    Columns,
    Load,
    PointRef,
    _check_apart,
    _pair_checks,
    _point_pair_words,
    _set,
    _two_points,
    load_kind,
    shown_point,
)


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


@load_kind
@dataclass(frozen=True, slots=True)
class RotationalSpring(Load):
    """A torsional spring-damper between ``bodies[0]`` (a) and ``bodies[1]`` (b): the torque
    ``stiffness · (angle(a) - angle(b) - free_angle) + damping · (angle(a)' - angle(b)')``
    (N·m) turns a clockwise and b counter-clockwise.  `free_angle` (rad) defaults to the
    drawn relative angle."""

    bodies: tuple[str, str]
    stiffness: float
    free_angle: float | None = None
    damping: float = 0.0
    name: str | None = None

    type_name = "rotational_spring"
    file_keys = FileKeys(required=("bodies", "stiffness"), optional=("free_angle", "damping", "name"))
    body_fields = ("bodies",)

    def __post_init__(self) -> None:
        _pair_checks(self)
        _set(self, "stiffness", _validate.non_negative_float(self.stiffness, "stiffness"))
        _set(self, "damping", _validate.non_negative_float(self.damping, "damping"))
        if self.free_angle is not None:
            _set(self, "free_angle", _validate.finite_float(self.free_angle, "free_angle"))

    def describe(self) -> str:
        return f"rotational spring {self.bodies[0]}–{self.bodies[1]}"

    @classmethod
    def loads(cls, loads: Columns):
        return [TorsionSpring(*loads.pair(), loads.number("stiffness"), loads.number("free_angle"),
                              loads.number("damping"))]  # fmt: skip  (NaN free angle: the drawn one)

    def draw(self, canvas) -> None:
        canvas.turn(canvas.origin(self.bodies[1]))


@load_kind
@dataclass(frozen=True, slots=True)
class Actuator(Load):
    """A force that an actuator applies along (or about) the joint named `joint`, `value`
    a number or a law: along a translational joint or a pin in a slot, a force (N) along
    its own coordinate, positive pushing its points apart; about a revolute, a torque
    (N·m) on ``bodies[0]`` relative to ``bodies[1]``, counter-clockwise positive.  It does
    the work ``value · d(own coordinate)``."""

    joint: str
    value: float | Law
    name: str | None = None

    type_name = "actuator"
    file_keys = FileKeys(required=("joint", "value"), optional=("name",))
    body_fields = ()
    joint_fields = ("joint",)
    n_laws = 1

    #: The joint kinds an actuator can act along: their own coordinate is a stroke, a
    #: slide or a relative angle.
    joint_types = ("revolute", "translational", "pin_in_slot")

    def __post_init__(self) -> None:
        _validate.name(self.joint, "joint")
        if self.name is not None:
            _validate.name(self.name, "name")
        _set(self, "value", _component(self.value, "value"))

    def check(self, mechanism, where: str) -> None:
        try:
            joint = mechanism.joint_named(self.joint)
        except KeyError:
            known = [j.name for j in mechanism.joints if j.type_name in self.joint_types and j.name]
            raise ModelError(
                f'unknown joint "{self.joint}" (known joints with a name: '
                f"{_validate.known_list(known) or 'none'})",
                element=f"{where}.joint",
            ) from None
        if joint.type_name not in self.joint_types:
            raise ModelError(f'joint "{self.joint}" is {joint.type_name}; expected one of {", ".join(self.joint_types)}',
                             element=f"{where}.joint")  # fmt: skip

    def laws(self) -> tuple[Law, ...]:
        return (_as_law(self.value),)

    def describe(self) -> str:
        return f'actuator along joint "{self.joint}"'

    @classmethod
    def loads(cls, loads: Columns):
        joints = loads.joints("joint")
        kinds = {type(joint) for joint in joints.elements}
        if len(kinds) == 1:
            return [JointActuator(loads.rows, coordinate) for coordinate in kinds.pop().outputs(joints)]
        if hasattr(joints, "copies"):
            raise NotImplementedError("the actuators of a repeated unit act on joints of several kinds; give each kind "
                                      "its own unit or write them out")  # fmt: skip
        blocks = []  # actuators along joints of several kinds: one group per kind
        for kind in kinds:
            chosen = np.array([type(joint) is kind for joint in joints.elements])
            group = type(joints)([j for j, c in zip(joints.elements, chosen) if c], loads.rows[chosen], joints.resolver)
            blocks += [JointActuator(group.rows, coordinate) for coordinate in kind.outputs(group)]
        return blocks

    def draw(self, canvas) -> None:
        """Drawn by its joint."""


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
