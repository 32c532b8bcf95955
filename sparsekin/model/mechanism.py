"""The mechanism: bodies, named points, joints and drivers, as frozen data.

Elements refer to bodies and points by name.  Every body has absolute coordinates
``(x, y, angle)``: the position of its frame origin and the angle of its frame.  The body
``ground`` always exists, is fixed, and has no coordinates.  Points are given by their
global coordinates in the initial (assembly) configuration; a point rides on a body when
the body lists it, and a point that no body lists stays on the ground.  The kinds of
joints and drivers are declared in `sparsekin.model.elements`; `Mechanism` checks every
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
from itertools import islice

import numpy as np

from ..errors import ModelError
from . import _validate
from ._validate import FileKeys
from .bodies import Body, _point_pair, _set, _tuple_of
from .elements import (
    COORDINATE_NAMES,
    DRIVER_KINDS,
    GROUND,
    JOINT_KINDS,
    LOAD_KINDS,
    Driver,
    Joint,
    Load,
    PointRef,
)
from .elements.base import _Element
from .lengths import NO_SHAPES, BodyShapes, body_shapes
from .units import Copies, Cycle, ElementList, PointTable, Repeat, Step, _same_name_message, find_copy

__all__ = ["GROUND", "COORDINATE_NAMES", "Body", "Analysis", "Mechanism"]


@dataclass(frozen=True, slots=True)
class Analysis:
    """Defaults for ``sparsekin run``: end time (s), number of samples, output points; the
    `type` of analysis (``"kinematics"``, or ``"dynamics"``: the equations of motion
    integrated, `sparsekin.solve_dynamics`) and its largest integration step `max_step`
    (s; default the output interval) and `rtol`, the local error of one step relative to
    the model size (angles: rad) under which the steps are chosen (default None: steps of
    `max_step`, halved only on a failure)."""

    t_end: float | None = None
    steps: int | None = None
    points: tuple[str, ...] | None = None
    type: str = "kinematics"
    max_step: float | None = None
    rtol: float | None = None

    file_keys = FileKeys(optional=("type", "t_end", "steps", "points", "max_step", "rtol"))
    #: The kinds of analysis `type` names.
    types = ("kinematics", "dynamics")
    #: Smallest and largest `rtol`: below 1e-12 the error estimate of the index-3 form meets
    #: rounding (a position error δq is an acceleration error δq / h²); above 10 % nothing
    #: is controlled.
    rtol_range = (1e-12, 1e-1)

    def __post_init__(self) -> None:
        _set(self, "type", _validate.choice(self.type, "type", self.types))
        if self.max_step is not None:
            _set(self, "max_step", _validate.finite_float(self.max_step, "max_step"))
            if self.max_step <= 0.0:
                raise ModelError(f"expected max_step > 0, got {self.max_step!r}", element="max_step")
        if self.rtol is not None:
            _set(self, "rtol", _validate.finite_float(self.rtol, "rtol"))
            if not self.rtol_range[0] <= self.rtol <= self.rtol_range[1]:
                raise ModelError(f"expected rtol in [{self.rtol_range[0]:g}, {self.rtol_range[1]:g}], got {self.rtol!r}",
                                 element="rtol")  # fmt: skip
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
        `sparsekin.model.elements.JOINT_KINDS` and `~sparsekin.model.elements.DRIVER_KINDS`.
    loads : sequence
        Forces, torques and springs on the bodies (`~sparsekin.model.elements.LOAD_KINDS`).
    gravity : (gx, gy)
        Acceleration of gravity, m/s² (default none); it pulls on every body's mass.
    name : str
        Name of the model (the default output folder of ``sparsekin run``).
    analysis : Analysis
        Defaults for the command line.
    repeats : sequence of Repeat
        Units repeated into chains (`sparsekin.model.units`).  Their copies come after the
        model's own bodies, joints, drivers and loads, copy by copy; `points`, `bodies`,
        `joints`, `drivers` and `loads` then read the whole model (an
        `~sparsekin.model.units.ElementList` builds a copy's element only when asked), while
        the arguments are the model's own.
    """

    points: Mapping[str, tuple[float, float]]
    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...] = ()
    drivers: tuple[Driver, ...] = ()
    name: str = "mechanism"
    analysis: Analysis = field(default_factory=Analysis)
    repeats: tuple[Repeat, ...] = ()
    loads: tuple[Load, ...] = ()
    gravity: tuple[float, float] = (0.0, 0.0)
    _body_index: dict[str, int] = field(init=False, repr=False, compare=False)
    _joint_index: dict[str, int] = field(init=False, repr=False, compare=False)
    _copies: list[Copies] = field(init=False, repr=False, compare=False)
    _shapes: BodyShapes = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        _validate.name(self.name, "name")
        points = self.points.own if isinstance(self.points, PointTable) else self.points
        if not isinstance(points, Mapping):
            raise ModelError(f"expected a mapping of name to [x, y], got {type(points).__name__}", element="points")
        _set(self, "points", _validate.ReadOnlyDict({_validate.name(key, "points"): _point_pair(key, value)
                                                     for key, value in points.items()}))  # fmt: skip
        for kind, kinds in (("bodies", (Body,)), ("joints", tuple(JOINT_KINDS.values())),
                            ("drivers", tuple(DRIVER_KINDS.values())), ("loads", tuple(LOAD_KINDS.values()))):  # fmt: skip
            given = getattr(self, kind)
            _set(self, kind, _tuple_of(given.own if isinstance(given, ElementList) else given, kinds, kind))
        if not isinstance(self.analysis, Analysis):
            raise ModelError(f"expected an Analysis, got {type(self.analysis).__name__}", element="analysis")
        _set(self, "repeats", _tuple_of(self.repeats, (Repeat,), "repeats"))
        _set(self, "gravity", _validate.pair(self.gravity, "gravity"))
        self._lay_out_copies()
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
        for name, index in self._check_elements("drivers", self.drivers).items():
            if name in self._joint_index:
                raise ModelError(_same_name_message(name, f"joints[{self._joint_index[name]}]"),
                                 element=f"drivers[{index}].name")  # fmt: skip
        self._check_elements("loads", self.loads)
        self._check_copies()
        if self.analysis.points is not None:
            for k, point in enumerate(self.analysis.points):
                self._check_point(point, "analysis.points[{}]", k)
        if self._copies:  # the whole model: own elements, then the copies'
            for kind in ("bodies", "joints", "drivers", "loads"):
                _set(self, kind, ElementList(kind, getattr(self, kind), self._copies))
        _set(self, "_shapes", body_shapes(self) if any(b.lengths for b in self.declared("bodies")) else NO_SHAPES)

    def _lay_out_copies(self) -> None:
        """Where each repeat's copies start among the bodies, joints and drivers."""
        copies: list[Copies] = []
        first = [len(self.bodies), len(self.joints), len(self.drivers), len(self.loads)]
        own_points = self.points
        table = PointTable(own_points, copies)  # filled below: the copies may name each other's points
        for index, repeat in enumerate(self.repeats):
            copies.append(Copies(repeat, index, *first, model_position=table.__getitem__))
            first = [start + copies[-1].total(kind) for start, kind in zip(first, ("bodies", "joints", "drivers", "loads"))]
        _set(self, "_copies", copies)
        if copies:  # the points of the whole model, for every check below
            _set(self, "points", table)

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
        total = sum(element.n_equations for element in (*self.own("joints"), *self.own("drivers")))
        for copies in self._copies:
            for kind in ("joints", "drivers"):
                total += sum(n * element.n_equations for n, element in zip(copies.having(kind), getattr(copies.unit, kind)))
        return total

    @property
    def n_joints(self) -> int:
        return len(self.joints)

    @property
    def n_drivers(self) -> int:
        return len(self.drivers)

    @property
    def n_loads(self) -> int:
        return len(self.loads)

    @property
    def has_forces(self) -> bool:
        """Whether a body has a mass or an inertia, or a load acts: then a run computes the
        forces that hold the motion (`sparsekin.solve_kinematics`)."""
        massive = any(body.mass or body.inertia for body in self.declared("bodies"))
        return massive or any(True for _ in self.declared("loads"))

    @property
    def total_mass(self) -> float:
        """The sum of the bodies' masses, kg."""
        own = sum(body.mass or 0.0 for body in self.own("bodies"))
        return own + sum(n * (body.mass or 0.0) for c in self._copies for n, body in zip(c.having("bodies"), c.unit.bodies))

    def declared(self, kind: str):
        """The bodies, joints, drivers or loads (`kind`) as declared: the model's own, then
        each repeated unit's once (not once per copy).  Enough to know which kinds and laws
        the model uses."""
        yield from self.own(kind)
        for copies in self._copies:
            yield from getattr(copies.unit, kind)

    def expanded(self) -> Mechanism:
        """The same mechanism without repeats: every copy's points and elements written out,
        as one would by hand (for small models: each copy becomes Python objects)."""
        if not self._copies:
            return self
        return Mechanism(
            points=dict(self.points), bodies=tuple(self.bodies), joints=tuple(self.joints),
            drivers=tuple(self.drivers), name=self.name, analysis=self.analysis, loads=tuple(self.loads),
            gravity=self.gravity,
        )  # fmt: skip

    @property
    def shapes(self) -> BodyShapes:
        """The local positions of the points of the bodies with `lengths`
        (`sparsekin.model.lengths`); empty (false) when no body has lengths."""
        return self._shapes

    def local_points(self, bodies: np.ndarray, points: np.ndarray, frames: np.ndarray | None = None) -> np.ndarray:
        """Where the points that start at `points` (k, 2, drawn) sit in the frames of `bodies`
        (k,): their drawn local coordinates, or their body's shape where it has lengths.
        `frames`: the drawn frames (n_bodies (+ 1), 3), if at hand."""
        return self._shapes.local_points(self.frames() if frames is None else frames, bodies, points)

    @property
    def copies(self) -> tuple[Copies, ...]:
        """Each repeat resolved in this mechanism (empty without repeats)."""
        return tuple(self._copies)

    def own(self, kind: str):
        """The model's own bodies, joints, drivers, loads or points (`kind`), without the repeats' copies."""
        elements = getattr(self, kind)
        return elements.own if isinstance(elements, (ElementList, PointTable)) else elements

    @property
    def body_names(self) -> Sequence[str]:
        """The name of every body, in coordinate order (built on demand for copies)."""
        if not self._copies:
            return tuple(body.name for body in self.bodies)
        return _BodyNames(self)

    def body_name(self, index: int) -> str:
        """The name of body `index` (its position in `bodies`)."""
        own = self.own("bodies")
        if index < len(own):
            return own[index].name
        for copies in self._copies:
            within = index - copies.first_body
            if 0 <= within < copies.total("bodies"):
                k, e = copies.locate("bodies", within)
                return copies.name(k, copies.unit.bodies[e].name)
        raise IndexError(f"body index {index} out of range")

    def body_index(self, name: str) -> int:
        """Position of body `name` in `bodies`; -1 for the ground."""
        if name == GROUND:
            return -1
        index = self._body_index.get(name)
        if index is not None:
            return index
        found = find_copy(self._copies, "bodies", name)
        if found is not None:
            copies, k, e = found
            return copies.first_body + int(copies.slot("bodies", k, e))
        raise KeyError(name)

    def position(self, reference: PointRef) -> tuple[float, float]:
        """Global initial coordinates of a point name or an ``(x, y)`` pair, m."""
        return self.points[reference] if isinstance(reference, str) else reference

    def body_indices(self, names: Iterable[str]) -> np.ndarray:
        """`body_index` of each name, as an int64 array (-1 for the ground)."""
        index = self._body_index
        if not self._copies:
            return np.fromiter((-1 if name == GROUND else index[name] for name in names), dtype=np.int64)
        return np.fromiter((index[name] if name in index else self.body_index(name) for name in names), dtype=np.int64)

    def positions(self, references: Iterable[PointRef]) -> np.ndarray:
        """`position` of each reference, as an array of shape (n, 2), m."""
        points = self.points
        flat = [coordinate for ref in references for coordinate in (points[ref] if type(ref) is str else ref)]
        return np.array(flat, dtype=float).reshape(-1, 2)

    def frame(self, body: str) -> tuple[float, float, float]:
        """Initial ``(x, y, angle)`` of the frame of `body`; zeros for the ground."""
        if body == GROUND:
            return (0.0, 0.0, 0.0)
        b = self.bodies[self.body_index(body)]
        x, y = self.position(b.origin)
        return (x, y, b.angle)

    def frames(self) -> np.ndarray:
        """Initial frames ``(x, y, angle)`` of every body, shape (n_bodies, 3)."""
        own = self.own("bodies")
        frames = np.zeros((len(own), 3))
        frames[:, :2] = self.positions([body.origin for body in own])
        frames[:, 2] = [body.angle for body in own]
        return np.concatenate([frames, *(copies.frames() for copies in self._copies)])

    def joint_named(self, name: str) -> Joint:
        """The joint called `name`; KeyError if there is none."""
        index = self._joint_index.get(name)
        if index is not None:
            return self.own("joints")[index]
        found = find_copy(self._copies, "joints", name)
        if found is not None:
            return found[0].element("joints", found[1], found[2])
        raise KeyError(name)

    def index_of(self, kind: str, name: str) -> int:
        """Position in `joints` or `drivers` (`kind`) of the element called `name`; KeyError
        if there is none.  A copy's element is found by its expanded name, without building
        the copies."""
        if kind == "joints":
            index = self._joint_index.get(name)
            if index is not None:
                return index
        else:
            for index, element in enumerate(self.own(kind)):
                if element.name == name:
                    return index
        found = find_copy(self._copies, kind, name)
        if found is not None:
            copies, k, e = found
            return copies.first[kind] + int(copies.slot(kind, k, e))
        raise KeyError(name)

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
                f'unknown point "{reference}" (known: {_known_names(self.points)})',
                element=where.format(*where_arguments),
            )

    def _check_body(self, body: str, where: str, *where_arguments) -> None:
        if body != GROUND and body not in self._body_index and not self._is_copy_body(body):
            for copies in self._copies:  # a copy's name whose copy has not that body (issue 28)
                split = copies.split(body)
                if split is not None and split[1] in copies._local["bodies"]:
                    copy = body[: -len(split[1]) - 1]
                    raise ModelError(f'body "{body}": copy "{copy}" of unit "{copies.unit.name}" has no body '
                                     f'"{split[1]}" (the repeat leaves it out there)',
                                     element=where.format(*where_arguments))  # fmt: skip
            copy_bodies = [f"{copies.name(0, b.name)} …" for copies in self._copies for b in copies.unit.bodies]
            known = _validate.known_list([*self._body_index, GROUND, *copy_bodies])
            raise ModelError(f'unknown body "{body}" (known: {known})', element=where.format(*where_arguments))

    def _is_copy_body(self, name: str) -> bool:
        return find_copy(self._copies, "bodies", name) is not None

    def _check_copies(self) -> None:
        """Each repeat's names are its own, its references resolve, its copies are sound.

        The unit's elements were checked as a unit; here their references to the model
        (bodies, points, joints), what ``prev.NAME`` means for copy 0, and the copies
        whose drawing differs (varied points: the first ones of a cycle, and the last) are
        checked through copies built as objects — a handful, not every copy.
        """
        copies = self._copies
        prefixes = [c.prefix for c in copies]
        for a, first in enumerate(prefixes):
            for b, second in enumerate(prefixes):
                if a != b and second.startswith(first) and (second == first or second[len(first) :][:1].isdigit()):
                    raise ModelError(f'prefix "{second}" of repeat[{b}] cannot be told from prefix "{first}" of '
                                     f"repeat[{a}] in names like {first}12.NAME", element=f"repeat[{b}].prefix")  # fmt: skip
        own_names = [*self.own("points"), *self._body_index, *self._joint_index,
                     *(element.name for kind in ("drivers", "loads") for element in self.own(kind) if element.name)]
        for c in copies:
            for name in own_names:
                split = c.split(name)
                if split is not None and (split[1] in c.point_index or split[1] in c.body_index
                                          or split[1] in c.joint_index or split[1] in c.driver_index
                                          or split[1] in c.load_index):  # fmt: skip
                    raise ModelError(f'"{name}" is also the name of {c.tiling.label(split[0])}\'s {split[1]}',
                                     element=f"{c.label}.prefix")
            for target in c.repeat.first.values():
                self._check_body(target, "{}.first", c.label)
            for k in _copies_to_check(c):
                where = f"{c.label} {c.tiling.label(k)}: units.{c.unit.name}"
                for kind in ("bodies", "joints", "drivers", "loads"):
                    for e in c.parts_of(kind, k):
                        self._check_copy_element(c, kind, k, e, where)

    def _check_copy_element(self, copies: Copies, kind: str, k: int, e: int, where: str) -> None:
        element = copies.element(kind, k, e)
        if kind == "bodies":  # spelled as in the file: units.NAME.bodies.BODY
            label = f"{where}.bodies.{copies.unit.bodies[e].name}"
            self._check_point(element.origin, "{}.origin", label)
            for n, point in enumerate(element.points):
                self._check_point(point, "{}.points[{}]", label, n)
            if element.com is not None:
                self._check_point(element.com, "{}.com", label)
            return
        label = f"{where}.{kind}[{e}]"
        declaration = type(element)
        for field_name in declaration.body_fields:
            value = getattr(element, field_name)
            for n, body in enumerate([value] if type(value) is str else value):
                self._check_body(body, "{}.{}" + ("" if type(value) is str else f"[{n}]"), label, field_name)
        for field_name in declaration.point_fields:
            value = getattr(element, field_name)
            if type(value) is str:
                self._check_point(value, "{}.{}", label, field_name)
            elif value is not None and type(value[0]) is not float:
                for n, reference in enumerate(value):
                    self._check_point(reference, "{}.{}[{}]", label, field_name, n)
        if type(element).check is not _Element.check:
            element.check(self, label)

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
            if type(element).check is not _Element.check:
                element.check(self, f"{kind}[{index}]")
        return names


def _copies_to_check(copies: Copies) -> list[int]:
    """The copies whose elements are checked as objects: the first, those whose drawing a
    cycle changes (up to 64), the last, and the first copy of each part that only some
    copies have."""
    cycles = [len(v.values) for v in copies.repeat.vary.values() if isinstance(v, Cycle)]
    stepped = any(isinstance(v, Step) for v in copies.repeat.vary.values())
    period = min(int(np.lcm.reduce(cycles)) if cycles else 1, 64)
    checked = set(copies.tiling.corners_and_period(period + stepped + copies.is_grid))
    for kind in ("bodies", "joints", "drivers", "loads"):
        checked.update(copies.first_having(kind))
    return sorted(checked)


class _BodyNames(Sequence):
    """The body names of a mechanism with repeats, built on demand."""

    def __init__(self, mechanism: Mechanism) -> None:
        self._mechanism = mechanism

    def __len__(self) -> int:
        return self._mechanism.n_bodies

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        if index < 0:
            index += len(self)
        return self._mechanism.body_name(index)


def _known_names(names) -> str:
    """`_validate.known_list` of the names of `names` (a mapping, or a `PointTable` of
    millions of copies' points), reading only its first and last few."""
    if len(names) <= 6:
        return _validate.known_list(list(names))
    return f"{', '.join(islice(names, 4))} … {', '.join(list(islice(reversed(names), 2))[::-1])}"
