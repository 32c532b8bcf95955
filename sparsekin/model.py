"""The mechanism: bodies, named points, joints and drivers, as frozen data.

Elements refer to bodies and points by name.  Every body has absolute coordinates
``(x, y, angle)``: the position of its frame origin and the angle of its frame.  The body
``ground`` always exists, is fixed, and has no coordinates.  Points are given by their
global coordinates in the initial (assembly) configuration; a point rides on a body when
the body lists it, and a point that no body lists stays on the ground.  The kinds of
joints and drivers are declared in `sparsekin.elements`; `Mechanism` checks every
element's references to bodies and points from those declarations.

>>> from sparsekin import Linear, Revolute, RotationalDriver
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

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from . import _validate
from ._validate import FileKeys
from .elements import COORDINATE_NAMES, DRIVER_KINDS, GROUND, JOINT_KINDS, Driver, Joint, PointRef
from .errors import ModelError

__all__ = ["GROUND", "COORDINATE_NAMES", "Body", "Analysis", "Mechanism"]


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

    file_keys = FileKeys(required=("origin",), optional=("angle", "points", "mass", "inertia", "com"))

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
class Analysis:
    """Defaults for ``sparsekin run``: end time (s), number of samples, output points."""

    t_end: float | None = None
    steps: int | None = None
    points: tuple[str, ...] | None = None

    file_keys = FileKeys(optional=("t_end", "steps", "points"))

    def __post_init__(self) -> None:
        if self.t_end is not None:
            _set(self, "t_end", _validate.finite_float(self.t_end, "t_end"))
            if self.t_end < 0.0:
                raise ModelError(f"expected t_end >= 0, got {self.t_end!r}", element="t_end")
        if self.steps is not None:
            _set(self, "steps", _validate.positive_int(self.steps, "steps"))
        if self.points is not None:
            _set(self, "points", _validate.names(self.points, "points"))


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
        Kinematic joints and driving constraints: instances of the kinds registered in
        `sparsekin.elements.JOINT_KINDS` and `~sparsekin.elements.DRIVER_KINDS`.
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
        _set(self, "bodies", _tuple_of(self.bodies, (Body,), "bodies"))
        _set(self, "joints", _tuple_of(self.joints, tuple(JOINT_KINDS.values()), "joints"))
        _set(self, "drivers", _tuple_of(self.drivers, tuple(DRIVER_KINDS.values()), "drivers"))
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
        _set(self, "_joint_index", self._check_elements("joints", self.joints))
        self._check_elements("drivers", self.drivers)
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

    def frames(self) -> np.ndarray:
        """Initial frames ``(x, y, angle)`` of every body, shape (n_bodies, 3)."""
        frames = np.zeros((self.n_bodies, 3))
        frames[:, :2] = self.positions([body.origin for body in self.bodies])
        frames[:, 2] = [body.angle for body in self.bodies]
        return frames

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

    def _check_elements(self, kind: str, elements) -> dict[str, int]:
        """Check the body and point references each element's kind declares, names unique,
        then the kinds' own checks; returns the index of each name."""
        names: dict[str, int] = {}
        for index, element in enumerate(elements):
            declaration = type(element)
            for field_name in declaration.body_fields:
                value = getattr(element, field_name)
                if type(value) is str:
                    self._check_body(value, "{}[{}].{}", kind, index, field_name)
                else:
                    for k, body in enumerate(value):
                        self._check_body(body, "{}[{}].{}[{}]", kind, index, field_name, k)
            for field_name in declaration.point_fields:
                value = getattr(element, field_name)
                if type(value) is str:
                    self._check_point(value, "{}[{}].{}", kind, index, field_name)
                elif value is not None and type(value[0]) is not float:  # a list of references
                    for k, reference in enumerate(value):
                        self._check_point(reference, "{}[{}].{}[{}]", kind, index, field_name, k)
            if element.name is not None:
                if element.name in names:
                    singular = kind[:-1]
                    raise ModelError(f'duplicate {singular} name "{element.name}"', element=f"{kind}[{index}].name")
                names[element.name] = index
        for index, element in enumerate(elements):
            if type(element).check is not Joint.check:
                element.check(self, f"{kind}[{index}]")
        return names


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
