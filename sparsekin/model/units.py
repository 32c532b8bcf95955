"""Units repeated into chains: one description, many copies, no object per copy.

A `Unit` is a small sub-mechanism (points, bodies, joints, drivers, loads) whose names are
local to it; a body named ``prev.NAME`` is body NAME of the copy before.  A `Repeat` makes
``count`` copies of a unit: copy k's names are ``PREFIX{k}.NAME``, its drawing is
translated by ``k · offset``, and `vary` gives copies their own law parameters or point
positions (`Step`: the unit's value + k · step; `Cycle`: values[k mod len]).  A
`Mechanism` takes repeats beside its own elements; the result is exactly the mechanism
one would write by hand with the copies' names.

The copies are never built one by one.  `Copies` resolves a repeat inside its mechanism
(where its bodies and elements start, what its references mean) and answers by index
arithmetic: the expanded name of a body, the drawn position of every copy's points (one
array), and — on demand, for messages and small models — any copy's element as an
object (`ElementList`, `PointTable`).  `sparsekin.engine.pattern` tiles the unit's equations
over the copies from the same arithmetic.

>>> from sparsekin import Body, Linear, Mechanism, Revolute, RotationalDriver
>>> loop = Unit(
...     "loop",
...     points={"T": (0.0, 1.0), "P": (1.0, 0.0), "Q": (1.0, 1.0)},
...     bodies=[Body("crank", origin="P", points=("P", "Q")), Body("coupler", origin="T", points=("T", "Q"))],
...     joints=[Revolute(("crank", "ground"), at="P"), Revolute(("crank", "coupler"), at="Q"),
...             Revolute(("coupler", "prev.crank"), at="T")],
... )
>>> chain = Mechanism(
...     points={"O0": (0.0, 0.0), "A0": (0.0, 1.0)},
...     bodies=[Body("crank0", origin="O0", points=("O0", "A0"))],
...     joints=[Revolute(("crank0", "ground"), at="O0")],
...     drivers=[RotationalDriver(("crank0", "ground"), law=Linear(rate=1.0))],
...     repeats=[Repeat(loop, count=1000, prefix="u", offset=(1.0, 0.0), first={"prev.crank": "crank0"})],
... )
>>> chain.n_bodies, chain.joints[-1].bodies, chain.points["u999.Q"]
(2001, ('u999.coupler', 'u998.crank'), (1000.0, 1.0))
"""

from __future__ import annotations

import dataclasses
import numbers
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from . import _validate
from .bodies import Body, _point_pair, _tuple_of
from .elements import DRIVER_KINDS, GROUND, JOINT_KINDS, LOAD_KINDS

__all__ = ["Unit", "Repeat", "Step", "Cycle", "Copies", "ElementList", "PointTable", "PREV"]

#: A unit's name for body NAME of the copy before: ``prev.NAME``.
PREV = "prev."


@dataclass(frozen=True, slots=True)
class Step:
    """Copy k takes the unit's value + k · `value` (a number, or ``(dx, dy)`` for a point)."""

    value: float | tuple[float, float]


@dataclass(frozen=True, slots=True)
class Cycle:
    """Copy k takes ``values[k % len(values)]``."""

    values: tuple

    def __post_init__(self) -> None:
        if isinstance(self.values, (str, bytes)) or not _validate.is_sequence(self.values) or not len(self.values):
            raise ModelError(f"expected a non-empty list of values, got {self.values!r}", element="cycle")
        object.__setattr__(self, "values", tuple(self.values))


@dataclass(frozen=True)
class Unit:
    """A sub-mechanism to be repeated: its points, bodies, joints, drivers and loads.

    Names are local to the unit.  A reference to a body that is not the unit's is either
    ``prev.NAME`` (body NAME of the copy before; for copy 0 what `Repeat.first` says, by
    default the ground) or a body of the model (its own, another repeat's copy, the
    ground); a point reference that is not the unit's names a point of the model.
    """

    name: str
    points: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    bodies: tuple = ()
    joints: tuple = ()
    drivers: tuple = ()
    loads: tuple = ()

    def __post_init__(self) -> None:

        _validate.name(self.name, "name")
        if not isinstance(self.points, Mapping):
            raise ModelError(f"expected a mapping of name to [x, y], got {type(self.points).__name__}", element="points")
        object.__setattr__(self, "points", {_validate.name(k, "points"): _point_pair(k, v) for k, v in self.points.items()})
        object.__setattr__(self, "bodies", _tuple_of(self.bodies, (Body,), "bodies"))
        object.__setattr__(self, "joints", _tuple_of(self.joints, tuple(JOINT_KINDS.values()), "joints"))
        object.__setattr__(self, "drivers", _tuple_of(self.drivers, tuple(DRIVER_KINDS.values()), "drivers"))
        object.__setattr__(self, "loads", _tuple_of(self.loads, tuple(LOAD_KINDS.values()), "loads"))
        bodies: dict[str, int] = {}
        for index, body in enumerate(self.bodies):
            if body.name == GROUND or body.name.startswith(PREV):
                raise ModelError(f'"{body.name}" is reserved; expected a name of the unit', element=f"bodies[{index}].name")
            if body.name in bodies:
                raise ModelError(f'duplicate body name "{body.name}"', element=f"bodies[{index}].name")
            bodies[body.name] = index
        named: dict[str, dict[str, int]] = {}
        for kind in ("joints", "drivers", "loads"):
            seen = named[kind] = {}
            for index, element in enumerate(getattr(self, kind)):
                if element.name is not None:
                    if element.name in seen:
                        raise ModelError(f'duplicate {kind[:-1]} name "{element.name}"', element=f"{kind}[{index}].name")
                    seen[element.name] = index
        for driver_name, index in named["drivers"].items():
            if driver_name in named["joints"]:
                raise ModelError(_same_name_message(driver_name, f'joints[{named["joints"][driver_name]}]'),
                                 element=f"drivers[{index}].name")  # fmt: skip
        for kind in ("joints", "drivers", "loads"):  # a "prev." reference must name a body of the unit
            for index, element in enumerate(getattr(self, kind)):
                for field_name, k, name in _body_references(element):
                    if name.startswith(PREV) and name[len(PREV) :] not in bodies:
                        where = f"{kind}[{index}].{field_name}" + ("" if k is None else f"[{k}]")
                        raise ModelError(f'"{name}" names no body of the unit (its bodies: '
                                         f"{_validate.known_list(list(bodies))})", element=where)  # fmt: skip

    @property
    def body_index(self) -> dict[str, int]:
        return {body.name: index for index, body in enumerate(self.bodies)}


@dataclass(frozen=True)
class Repeat:
    """`count` copies of `unit`, each on the one before.

    Parameters
    ----------
    unit : Unit
    count : int
        Number of copies, at least 1.
    prefix : str, optional
        Copy k's names are ``f"{prefix}{k}.{name}"``; default the unit's name.
    offset : (dx, dy)
        Copy k is drawn translated by ``k · offset`` (m).
    first : mapping
        What ``prev.NAME`` means for copy 0: ``{"prev.crank": "crank0"}``; default the ground.
    vary : mapping of path to Step or Cycle
        Per-copy values of a law's number parameter (``drivers[0].law.phase``,
        ``drivers.NAME.law.amplitude``) or of a point (``points.M``); checked here,
        against the unit, for every copy.
    """

    unit: Unit
    count: int
    prefix: str | None = None
    offset: tuple[float, float] = (0.0, 0.0)
    first: Mapping[str, str] = field(default_factory=dict)
    vary: Mapping[str, Step | Cycle] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.unit, Unit):
            raise ModelError(f"expected a Unit, got {type(self.unit).__name__}", element="unit")
        object.__setattr__(self, "count", _validate.positive_int(self.count, "count"))
        prefix = self.unit.name if self.prefix is None else _validate.name(self.prefix, "prefix")
        object.__setattr__(self, "prefix", prefix)
        object.__setattr__(self, "offset", _validate.pair(self.offset, "offset"))
        if not isinstance(self.first, Mapping):
            raise ModelError(f'expected a table {{ "prev.NAME" = "BODY" }}, got {self.first!r}', element="first")
        unit_bodies = self.unit.body_index
        for key, target in self.first.items():
            if not isinstance(key, str) or not key.startswith(PREV) or key[len(PREV) :] not in unit_bodies:
                raise ModelError(f'expected keys "prev.NAME" with NAME a body of unit "{self.unit.name}", got {key!r}',
                                 element="first")  # fmt: skip
            _validate.name(target, f'first."{key}"')
        object.__setattr__(self, "first", dict(self.first))
        if not isinstance(self.vary, Mapping):
            raise ModelError(f"expected a table of path = {{ step = … }} or {{ cycle = […] }}, got {self.vary!r}",
                             element="vary")  # fmt: skip
        vary = {}
        for path, variation in self.vary.items():
            if not isinstance(variation, (Step, Cycle)):
                raise ModelError(f"expected {{ step = … }} or {{ cycle = […] }}, got {variation!r}", element=f'vary."{path}"')
            target = _resolve_path(self.unit, path)
            try:
                vary[path] = _checked_variation(self.unit, target, variation, self.count)
            except ModelError as error:
                raise error.within(f'vary."{path}"') from None
        object.__setattr__(self, "vary", vary)


# ---------------------------------------------------------------------- variation paths
_DRIVER_PATH = re.compile(r"drivers(?:\[(\d+)\]|\.([^.]+))\.(law(?:_x|_y)?)\.(\w+)")
_POINT_PATH = re.compile(r"points\.(.+)")


def _resolve_path(unit: Unit, path: str):
    """``("law", driver index, law field, key)`` or ``("point", name)`` for a `vary` path."""
    where = f'vary."{path}"'
    if not isinstance(path, str):
        raise ModelError(f"expected a path such as drivers[0].law.phase or points.M, got {path!r}", element="vary")
    match = _DRIVER_PATH.fullmatch(path)
    if match:
        index_text, name, law_field, key = match.groups()
        if index_text is not None:
            index = int(index_text)
            if index >= len(unit.drivers):
                raise ModelError(f'unit "{unit.name}" has {len(unit.drivers)} drivers', element=where)
        else:
            names = [driver.name for driver in unit.drivers]
            if name not in names:
                raise ModelError(f'unit "{unit.name}" has no driver named "{name}"', element=where)
            index = names.index(name)
        driver = unit.drivers[index]
        if law_field not in driver.law_fields:
            raise ModelError(f"drivers[{index}] has no field {law_field} (its laws: {', '.join(driver.law_fields)})",
                             element=where)  # fmt: skip
        law = getattr(driver, law_field)
        if not dataclasses.is_dataclass(law) or key not in {f.name for f in dataclasses.fields(law) if f.init}:
            raise ModelError(f"{type(law).__name__} has no parameter {key}", element=where)
        value = getattr(law, key)
        if value is not None and (isinstance(value, bool) or not isinstance(value, numbers.Real)):
            kind = getattr(law, "type_name", type(law).__name__)
            shown = "a list" if _validate.is_sequence(value) else _validate._shown(value)
            raise ModelError(f"{key} of a {kind} law is {shown}, not a number: vary steps or cycles a law's number "
                             "parameters only", element=where)  # fmt: skip
        return ("law", index, law_field, key)
    match = _POINT_PATH.fullmatch(path)
    if match:
        if match[1] not in unit.points:
            raise ModelError(f'unit "{unit.name}" has no point "{match[1]}"', element=where)
        return ("point", match[1])
    raise ModelError("expected drivers[i].law.KEY, drivers.NAME.law.KEY or points.NAME", element=where)


def _checked_variation(unit: Unit, target: tuple, variation: Step | Cycle, count: int) -> Step | Cycle:
    """`variation` of the parameter or point `target` (`_resolve_path`), checked for every
    copy and in its canonical form (floats; ``(x, y)`` pairs for a point)."""
    if target[0] == "point":
        if isinstance(variation, Cycle):
            return Cycle(_pairs(variation.values, "cycle"))
        step = _validate.pair(variation.value, "step")
        _check_stepped(np.array(unit.points[target[1]]), np.array(step), count)
        return Step(step)
    _, driver, law_field, key = target
    base = getattr(getattr(unit.drivers[driver], law_field), key)
    if isinstance(variation, Cycle):
        return Cycle(tuple(_validate.finite_float(value, f"cycle[{n}]") for n, value in enumerate(variation.values)))
    if base is None:
        raise ModelError(f"cannot step a parameter left at its default: give {key} in the unit, or use a cycle")
    step = _validate.finite_float(variation.value, "step")
    _check_stepped(np.array([float(base)]), np.array([step]), count)
    return Step(step)


def _pairs(values: tuple, element: str) -> tuple:
    """`values` as a tuple of ``(x, y)`` pairs of finite numbers of sensible magnitude."""
    if all(type(v) is tuple and len(v) == 2 and type(v[0]) is float and type(v[1]) is float for v in values):
        array = np.array(values)  # the common case (a file's, a sweep's long cycles): checked at once
        if np.all(np.abs(array) <= _validate.MAX_MAGNITUDE):  # False for NaN
            return values
    return tuple(_validate.pair(value, f"{element}[{n}]") for n, value in enumerate(values))


def _check_stepped(base: np.ndarray, step: np.ndarray, count: int) -> None:
    """Refuse a step that takes a copy's value beyond `_validate.MAX_MAGNITUDE`, naming the
    first such copy.  |base + k · step| is largest at k = 0 or k = count - 1: one test."""
    def good(values):
        return np.isfinite(values) & (np.abs(values) <= _validate.MAX_MAGNITUDE)

    if good(base + (count - 1) * step).all():
        return
    values = base[None] + np.arange(count, dtype=float)[:, None] * step[None]
    k = int(np.flatnonzero(~good(values).all(axis=1))[0])
    shown = ", ".join(f"{v:.6g}" for v in values[k])
    raise ModelError(f"copy {k} takes {shown}: the varied value must be a finite number of magnitude at most "
                     f"{_validate.MAX_MAGNITUDE:g}")  # fmt: skip


def _same_name_message(name: str, other: str) -> str:
    """A driver's name that is also a joint's: their outputs and forces would share labels."""
    return f'driver name "{name}" is also the name of {other}: joints and drivers need distinct names'


def _body_references(element):
    """``(field, index or None, name)`` of every body a joint or driver names."""
    for field_name in type(element).body_fields:
        value = getattr(element, field_name)
        if type(value) is str:
            yield field_name, None, value
        else:
            for k, name in enumerate(value):
                yield field_name, k, name


# ---------------------------------------------------------------------- a repeat in its mechanism
class Copies:
    """A `Repeat` resolved inside a mechanism: where its copies are, what their names mean.

    Parameters
    ----------
    repeat : Repeat
    index : int
        Its position among the mechanism's repeats (for messages).
    first_body, first_joint, first_driver, first_load : int
        Index of copy 0's first body, joint, driver and load in the mechanism.
    model_position : callable
        The drawn position of a point name of the mechanism (for the unit's references to
        the model's points).
    """

    def __init__(self, repeat: Repeat, index: int, first_body: int, first_joint: int, first_driver: int,
                 first_load: int, model_position) -> None:  # fmt: skip
        self.repeat, self.index = repeat, index
        self.model_position = model_position  # the drawn position of a point name of the model
        self.unit = unit = repeat.unit
        self.count, self.prefix = repeat.count, repeat.prefix
        self.offset = np.asarray(repeat.offset, dtype=float)
        self.first_body, self.first_joint, self.first_driver = first_body, first_joint, first_driver
        self.first_load = first_load
        self.n_bodies, self.n_joints, self.n_drivers = len(unit.bodies), len(unit.joints), len(unit.drivers)
        self.n_loads = len(unit.loads)
        self.body_index = unit.body_index
        self.point_index = {name: k for k, name in enumerate(unit.points)}
        self.joint_index = {joint.name: k for k, joint in enumerate(unit.joints) if joint.name is not None}
        self.driver_index = {driver.name: k for k, driver in enumerate(unit.drivers) if driver.name is not None}
        self.load_index = {load.name: k for k, load in enumerate(unit.loads) if load.name is not None}
        self._variations = {path: (_resolve_path(unit, path), variation) for path, variation in repeat.vary.items()}
        self._positions: np.ndarray | None = None

    @property
    def label(self) -> str:
        return f"repeat[{self.index}]"

    # ------------------------------------------------------------------ names
    def name(self, k: int, local: str) -> str:
        """The expanded name of the unit's `local` name in copy k."""
        return f"{self.prefix}{k}.{local}"

    def split(self, name: str) -> tuple[int, str] | None:
        """``(k, local)`` if `name` is ``PREFIX{k}.local`` for one of this repeat's copies."""
        if not name.startswith(self.prefix):
            return None
        digits, dot, local = name[len(self.prefix) :].partition(".")
        if not dot or not digits.isdigit() or (len(digits) > 1 and digits[0] == "0"):
            return None
        k = int(digits)
        return (k, local) if k < self.count else None

    def body_name(self, k: int, reference: str) -> str:
        """What a unit's body reference names in copy k (an expanded name, or the model's)."""
        if reference in self.body_index:
            return self.name(k, reference)
        if reference.startswith(PREV):
            if k == 0:
                return self.repeat.first.get(reference, GROUND)
            return self.name(k - 1, reference[len(PREV) :])
        return reference

    def point_name(self, k: int, reference):
        """What a unit's point reference is in copy k: an expanded name, the model's name, or
        coordinates translated with the copy."""
        if isinstance(reference, str):
            return self.name(k, reference) if reference in self.point_index else reference
        return (reference[0] + k * self.offset[0], reference[1] + k * self.offset[1])

    def joint_name(self, k: int, reference: str) -> str:
        return self.name(k, reference) if reference in self.joint_index else reference

    # ------------------------------------------------------------------ geometry
    @property
    def positions(self) -> np.ndarray:
        """Drawn position of every copy's every unit point, shape (count, n_points, 2), m."""
        if self._positions is None:
            base = np.array(list(self.unit.points.values()), dtype=float).reshape(-1, 2)
            shift = np.arange(self.count, dtype=float)[:, None] * self.offset
            positions = np.repeat(base[None], self.count, axis=0)
            for (target, variation) in self._variations.values():
                if target[0] == "point":
                    p = self.point_index[target[1]]
                    positions[:, p] = self._varied_pairs(variation, base[p])
            positions += shift[:, None, :]
            self._positions = positions
        return self._positions

    def reference_positions(self, references) -> np.ndarray:
        """Drawn positions of unit point references in every copy, shape (count, len(references), 2)."""
        out = np.empty((self.count, len(references), 2))
        ks = np.arange(self.count, dtype=float)[:, None] * self.offset
        for e, reference in enumerate(references):
            if isinstance(reference, str) and reference in self.point_index:
                out[:, e] = self.positions[:, self.point_index[reference]]
            elif isinstance(reference, str):
                out[:, e] = self.model_position(reference)
            else:
                out[:, e] = np.asarray(reference, dtype=float) + ks
        return out

    def body_columns(self, references, resolve) -> np.ndarray:
        """Stored body index of unit body references in every copy, shape (count, len(references)).

        `resolve` maps a model body name to its stored index (the ground included).
        """
        k = np.arange(self.count, dtype=np.int64)[:, None]
        out = np.empty((self.count, len(references)), dtype=np.int64)
        for e, reference in enumerate(references):
            if reference in self.body_index:
                out[:, e] = self.first_body + k[:, 0] * self.n_bodies + self.body_index[reference]
            elif reference.startswith(PREV):
                out[1:, e] = self.first_body + (k[:-1, 0]) * self.n_bodies + self.body_index[reference[len(PREV) :]]
                out[0, e] = resolve(self.repeat.first.get(reference, GROUND))
            else:
                out[:, e] = resolve(reference)
        return out

    def frames(self) -> np.ndarray:
        """Drawn frames ``(x, y, angle)`` of every copy's bodies, shape (count · n_bodies, 3)."""
        origins = self.reference_positions([body.origin for body in self.unit.bodies])
        frames = np.empty((self.count, self.n_bodies, 3))
        frames[:, :, :2] = origins
        frames[:, :, 2] = [body.angle for body in self.unit.bodies]
        return frames.reshape(-1, 3)

    # ------------------------------------------------------------------ variations of laws
    def law_variations(self, driver: int) -> dict[str, dict[str, np.ndarray]]:
        """For unit driver `driver`: law field -> {key: value of every copy}."""
        varied: dict[str, dict[str, np.ndarray]] = {}
        for target, variation in self._variations.values():
            if target[0] == "law" and target[1] == driver:
                _, _, law_field, key = target
                law = getattr(self.unit.drivers[driver], law_field)
                varied.setdefault(law_field, {})[key] = self._varied_numbers(variation, getattr(law, key))
        return varied

    def _varied_numbers(self, variation, base) -> np.ndarray:
        """Every copy's value of a law parameter (`variation` checked by `Repeat`)."""
        k = np.arange(self.count)
        if isinstance(variation, Cycle):
            values = np.array(variation.values, dtype=float)
            return values[k % values.size]
        return base + k * variation.value

    def _varied_pairs(self, variation, base) -> np.ndarray:
        """Every copy's drawn point, before the translation by k · offset (checked by `Repeat`)."""
        k = np.arange(self.count)
        if isinstance(variation, Cycle):
            values = np.array(variation.values, dtype=float).reshape(-1, 2)
            return values[k % len(values)]
        return base + k[:, None] * np.asarray(variation.value, dtype=float)

    # ------------------------------------------------------------------ elements on demand
    def element(self, kind: str, k: int, e: int):
        """Copy k's element e of the unit's `kind` ("bodies", "joints", "drivers", "loads"), as an object."""
        unit_element = getattr(self.unit, kind)[e]
        if kind == "bodies":
            return dataclasses.replace(
                unit_element,
                name=self.name(k, unit_element.name),
                origin=self.point_name(k, unit_element.origin),
                points=tuple(self.point_name(k, p) for p in unit_element.points),
                com=None if unit_element.com is None else self.point_name(k, unit_element.com),
            )
        declaration = type(unit_element)
        changes = {}
        for field_name in declaration.body_fields:
            value = getattr(unit_element, field_name)
            changes[field_name] = (self.body_name(k, value) if type(value) is str
                                   else tuple(self.body_name(k, v) for v in value))  # fmt: skip
        for field_name in declaration.point_fields:
            value = getattr(unit_element, field_name)
            if value is None:
                continue
            if type(value) is str or type(value[0]) is float:
                changes[field_name] = self.point_name(k, value)
            else:
                changes[field_name] = tuple(self.point_name(k, v) for v in value)
        for field_name in declaration.joint_fields:
            changes[field_name] = self.joint_name(k, getattr(unit_element, field_name))
        if unit_element.name is not None:
            changes["name"] = self.name(k, unit_element.name)
        try:
            if kind == "drivers":
                for law_field, keys in self.law_variations(e).items():
                    law = getattr(unit_element, law_field)
                    copy_values = {key: float(values[k]) for key, values in keys.items()}
                    changes[law_field] = dataclasses.replace(law, **copy_values)
            return dataclasses.replace(unit_element, **changes)
        except ModelError as error:
            raise error.within(f"{self.label} copy {k}: units.{self.unit.name}.{kind}[{e}]") from None


# ---------------------------------------------------------------------- lazy views of the whole model
class ElementList(Sequence):
    """The bodies, joints, drivers or loads of a mechanism with repeats: its own, then each
    repeat's copies (copy-major).  Copies' elements are built on demand."""

    def __init__(self, kind: str, own: tuple, copies: list[Copies]) -> None:
        self.kind, self.own, self.copies = kind, own, copies
        self._sizes = [len(own)] + [c.count * _unit_size(c, kind) for c in copies]
        self._starts = np.cumsum([0] + self._sizes)

    def __len__(self) -> int:
        return int(self._starts[-1])

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        if index < 0:
            index += len(self)
        if not 0 <= index < len(self):
            raise IndexError(f"{self.kind} index {index} out of range")
        if index < len(self.own):
            return self.own[index]
        segment = int(np.searchsorted(self._starts, index, side="right")) - 1
        copies = self.copies[segment - 1]
        within = index - int(self._starts[segment])
        size = _unit_size(copies, self.kind)
        return copies.element(self.kind, within // size, within % size)

    def __iter__(self):
        yield from self.own
        for copies in self.copies:
            size = _unit_size(copies, self.kind)
            for k in range(copies.count):
                for e in range(size):
                    yield copies.element(self.kind, k, e)

    def __eq__(self, other) -> bool:
        if isinstance(other, ElementList):
            return self.own == other.own and [c.repeat for c in self.copies] == [c.repeat for c in other.copies]
        return isinstance(other, Sequence) and len(self) == len(other) and all(a == b for a, b in zip(self, other))

    __hash__ = None

    def __repr__(self) -> str:
        return f"ElementList({self.kind}: {len(self.own)} own + {', '.join(f'{c.count}×{c.unit.name}' for c in self.copies)})"


def _unit_size(copies: Copies, kind: str) -> int:
    return {"bodies": copies.n_bodies, "joints": copies.n_joints, "drivers": copies.n_drivers, "loads": copies.n_loads}[kind]


class PointTable(Mapping):
    """The named points of a mechanism with repeats: its own, then every copy's, resolved by
    name on demand (``u17.Q``) without a dict of every point."""

    def __init__(self, own: dict, copies: list[Copies]) -> None:
        self.own, self.copies = own, copies

    def locate(self, name: str):
        """``(copies, k, unit point index)`` of a copy's point, or None."""
        for copies in self.copies:
            split = copies.split(name)
            if split is not None and split[1] in copies.point_index:
                return copies, split[0], copies.point_index[split[1]]
        return None

    def __getitem__(self, name: str) -> tuple[float, float]:
        if name in self.own:
            return self.own[name]
        located = self.locate(name) if isinstance(name, str) else None
        if located is None:
            raise KeyError(name)
        copies, k, p = located
        x, y = copies.positions[k, p]
        return (float(x), float(y))

    def __contains__(self, name) -> bool:
        return name in self.own or (isinstance(name, str) and self.locate(name) is not None)

    def __iter__(self):
        yield from self.own
        for copies in self.copies:
            names = list(copies.unit.points)
            for k in range(copies.count):
                for name in names:
                    yield copies.name(k, name)

    def __len__(self) -> int:
        return len(self.own) + sum(c.count * len(c.unit.points) for c in self.copies)

    def __eq__(self, other) -> bool:
        if isinstance(other, PointTable):
            return self.own == other.own and [c.repeat for c in self.copies] == [c.repeat for c in other.copies]
        return isinstance(other, Mapping) and len(self) == len(other) and all(
            name in other and self[name] == other[name] for name in self
        )

    __hash__ = None

    def __reversed__(self):
        """The names from the last copy's last point back to the model's first point."""
        for copies in reversed(self.copies):
            names = list(copies.unit.points)[::-1]
            for k in range(copies.count - 1, -1, -1):
                for name in names:
                    yield copies.name(k, name)
        yield from reversed(self.own)

    def all_positions(self) -> np.ndarray:
        """Every point's drawn position, own then copies', shape (len(self), 2)."""
        own = np.array(list(self.own.values()), dtype=float).reshape(-1, 2)
        return np.concatenate([own, *(c.positions.reshape(-1, 2) for c in self.copies)])

    def __repr__(self) -> str:
        return f"PointTable({len(self.own)} own + {', '.join(f'{c.count}×{c.unit.name}' for c in self.copies)})"
