"""The registries of element kinds, their decorators and base classes, and the helpers the
declarations share (`sparsekin.model.elements` describes what a kind declares)."""

from __future__ import annotations

import math
from typing import Protocol, Union

import numpy as np

from ...errors import ModelError
from .. import _validate
from ..laws import Law
from ..primitives import Combination

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
