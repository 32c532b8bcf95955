"""The load kinds: a force at a point, a torque, a spring-damper."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ModelError
from .. import _validate
from .._validate import FileKeys
from ..laws import Law, Polynomial
from ..loads import BodyTorque, PointForce, SpringDamper
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
