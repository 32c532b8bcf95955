"""Units repeated into chains and grids: one description, many copies, no object per copy.

A `Unit` is a small sub-mechanism (points, bodies, joints, drivers, loads) whose names are
local to it.  A `Repeat` makes copies of it: a chain of ``count`` copies, where
``prev.NAME`` is body NAME of the copy before, or a grid of ``count = (ni, nj)`` copies,
where ``left.NAME`` and ``below.NAME`` are body NAME of copies (i − 1, j) and (i, j − 1).
Copy k's names are ``PREFIX{k}.NAME``, copy (i, j)'s ``PREFIX{i}_{j}.NAME``; its drawing is
translated by ``k · offset`` or ``i · offset[0] + j · offset[1]``, and `vary` gives copies
their own law parameters, points or body angles (`Step`, `Cycle`:
`sparsekin.model.variations`).  A part wrapped in `OnCopies` exists only on some columns
or rows, and a part that names a neighbour outside the grid is left out there (an open
boundary) unless `Repeat.boundary` attaches it.  A `Mechanism` takes repeats beside its
own elements; the result is exactly the mechanism one would write by hand with the
copies' names.

The copies are never built one by one.  `Copies` resolves a repeat inside its mechanism
(where its bodies and elements start, which copies have which parts, what its references
mean) and answers by index arithmetic (`sparsekin.model.tiling`): the expanded name of a
body, the drawn position of every copy's points (one array), and — on demand, for
messages and small models — any copy's element as an object (`ElementList`,
`PointTable`).  `sparsekin.engine.pattern` tiles the unit's equations over the copies
from the same arithmetic.

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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from . import _validate
from .bodies import Body, _point_pair, _tuple_of
from .elements import DRIVER_KINDS, GROUND, JOINT_KINDS, LOAD_KINDS
from .paths import DRIVER_PATH
from .tiling import BELOW, LEFT, PREV, OnCopies, Tiling, neighbour_prefix
from .variations import Cycle, Step, base_value, checked_variation, resolve_path, varied_values

__all__ = ["Unit", "Repeat", "Step", "Cycle", "OnCopies", "Copies", "ElementList", "PointTable", "PREV", "LEFT", "BELOW",
           "DRIVER_PATH", "find_copy"]

#: The kinds of a unit's parts, in the order their copies are laid out.
KINDS = ("bodies", "joints", "drivers", "loads")


@dataclass(frozen=True)
class Unit:
    """A sub-mechanism to be repeated: its points, bodies, joints, drivers and loads.

    Names are local to the unit.  A reference to a body that is not the unit's is either
    a neighbour's body — ``prev.NAME`` in a chain (the copy before; for copy 0 what
    `Repeat.first` says, by default the ground), ``left.NAME`` or ``below.NAME`` in a grid
    (copy (i − 1, j) or (i, j − 1)) — or a body of the model (its own, another repeat's
    copy, the ground); a point reference that is not the unit's names a point of the model.
    A part wrapped in `OnCopies` exists only in the columns and rows it names; the
    wrappers are unwrapped here, into `only`.

    Attributes
    ----------
    only : dict
        ``(kind, index) -> (i, j)`` for the parts restricted to some copies (`OnCopies`:
        each bound None or an inclusive ``(first, last)``).
    """

    name: str
    points: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    bodies: tuple = ()
    joints: tuple = ()
    drivers: tuple = ()
    loads: tuple = ()
    only: Mapping[tuple[str, int], tuple] = field(default_factory=dict)

    def __post_init__(self) -> None:

        _validate.name(self.name, "name")
        if not isinstance(self.points, Mapping):
            raise ModelError(f"expected a mapping of name to [x, y], got {type(self.points).__name__}", element="points")
        object.__setattr__(self, "points", _validate.ReadOnlyDict({_validate.name(k, "points"): _point_pair(k, v)
                                                                   for k, v in self.points.items()}))  # fmt: skip
        only = dict(self.only)
        for kind, kinds in (("bodies", (Body,)), ("joints", tuple(JOINT_KINDS.values())),
                            ("drivers", tuple(DRIVER_KINDS.values())), ("loads", tuple(LOAD_KINDS.values()))):  # fmt: skip
            given = getattr(self, kind)
            parts = list(given) if _validate.is_sequence(given) else given
            if isinstance(parts, list):
                for index, part in enumerate(parts):
                    if isinstance(part, OnCopies):
                        only[(kind, index)] = (part.i, part.j)
                        parts[index] = part.element
            object.__setattr__(self, kind, _tuple_of(parts, kinds, kind))
        object.__setattr__(self, "only", _validate.ReadOnlyDict(only))
        bodies: dict[str, int] = {}
        for index, body in enumerate(self.bodies):
            if body.name == GROUND or neighbour_prefix(body.name):
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
        for kind, index, where, name, prefix in self.neighbour_references():  # must name a body of the unit
            if name[len(prefix) :] not in bodies:
                raise ModelError(f'"{name}" names no body of the unit (its bodies: '
                                 f"{_validate.known_list(list(bodies))})", element=where)  # fmt: skip

    @property
    def body_index(self) -> dict[str, int]:
        return {body.name: index for index, body in enumerate(self.bodies)}

    def neighbour_references(self):
        """``(kind, index, element, name, prefix)`` of every ``prev.``, ``left.`` or ``below.``
        body reference of the unit's joints, drivers and loads (`element` spelled for messages)."""
        for kind in ("joints", "drivers", "loads"):
            for index, element in enumerate(getattr(self, kind)):
                for field_name, k, name in _body_references(element):
                    prefix = neighbour_prefix(name)
                    if prefix is not None:
                        yield kind, index, f"{kind}[{index}].{field_name}" + ("" if k is None else f"[{k}]"), name, prefix


@dataclass(frozen=True)
class Repeat:
    """Copies of `unit`: a chain, each copy on the one before, or a grid of columns and rows.

    Parameters
    ----------
    unit : Unit
    count : int or (ni, nj)
        A chain of `count` copies (at least 1), or a grid of ni columns and nj rows,
        copy (i, j) for i < ni, j < nj, laid out row by row.
    prefix : str, optional
        Copy k's names are ``f"{prefix}{k}.{name}"``, copy (i, j)'s ``f"{prefix}{i}_{j}.{name}"``;
        default the unit's name.
    offset : (dx, dy), or two such vectors for a grid
        Copy k is drawn translated by ``k · offset`` (m); copy (i, j) by
        ``i · offset[0] + j · offset[1]``.
    first : mapping
        A chain's: what ``prev.NAME`` means for copy 0, ``{"prev.crank": "crank0"}``;
        default the ground.
    vary : mapping of path to Step or Cycle
        Per-copy values of a law's number parameter (``drivers[0].law.phase``,
        ``drivers.NAME.law.amplitude``), of a point (``points.M``) or of a body's drawn
        angle (``bodies.NAME.angle``); checked here, against the unit, for every copy.
    boundary : mapping
        A grid's attached boundaries: ``{"below.V": "ground"}`` — where copy (i, j) has no
        such neighbour, the reference means that body of the model and the element is
        kept.  References not listed stay open: their elements are left out there.

    Examples
    --------
    >>> from sparsekin import Body, Revolute
    >>> cell = Unit("cell", points={"A": (0.0, 0.0), "B": (1.0, 0.0)},
    ...             bodies=[Body("bar", origin="A", points=("A", "B"))],
    ...             joints=[Revolute(("bar", "left.bar"), at="A")])
    >>> from sparsekin import Mechanism
    >>> row = Mechanism(points={}, bodies=[], repeats=[Repeat(cell, count=(3, 2), prefix="c",
    ...                 offset=((1.0, 0.0), (0.0, 1.0)))])
    >>> row.n_bodies, row.n_joints, row.joints[0].bodies, row.points["c2_1.B"]
    (6, 4, ('c1_0.bar', 'c0_0.bar'), (3.0, 1.0))
    """

    unit: Unit
    count: int | tuple[int, int]
    prefix: str | None = None
    offset: tuple = (0.0, 0.0)
    first: Mapping[str, str] = field(default_factory=dict)
    vary: Mapping[str, Step | Cycle] = field(default_factory=dict)
    boundary: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.unit, Unit):
            raise ModelError(f"expected a Unit, got {type(self.unit).__name__}", element="unit")
        grid = _validate.is_sequence(self.count) and not isinstance(self.count, (str, bytes))
        if grid:
            if len(self.count) != 2:
                raise ModelError(f"expected a number of copies or [ni, nj], got {self.count!r}", element="count")
            count = (_validate.positive_int(self.count[0], "count[0]"), _validate.positive_int(self.count[1], "count[1]"))
        else:
            count = _validate.positive_int(self.count, "count")
        object.__setattr__(self, "count", count)
        prefix = self.unit.name if self.prefix is None else _validate.name(self.prefix, "prefix")
        object.__setattr__(self, "prefix", prefix)
        tiling = Tiling(prefix, self.shape)
        if grid:
            offset = ((0.0, 0.0), (0.0, 0.0)) if self.offset == (0.0, 0.0) else self.offset
            if (isinstance(offset, (str, bytes)) or not _validate.is_sequence(offset) or len(offset) != 2
                    or not all(_validate.is_sequence(vector) for vector in offset)):  # fmt: skip
                raise ModelError(f"expected two lattice vectors [[dxi, dyi], [dxj, dyj]], got {offset!r}", element="offset")
            offset = (_validate.pair(offset[0], "offset[0]"), _validate.pair(offset[1], "offset[1]"))
        else:
            offset = _validate.pair(self.offset, "offset")
        object.__setattr__(self, "offset", offset)
        unit_bodies = self.unit.body_index
        for attachment, prefixes, what in (("first", (PREV,), "prev.NAME"), ("boundary", (LEFT, BELOW), "left.NAME")):
            table = getattr(self, attachment)
            if not isinstance(table, Mapping):
                raise ModelError(f'expected a table {{ "{what}" = "BODY" }}, got {table!r}', element=attachment)
            if table and (attachment == "first") == grid:
                hint = ("a grid's missing neighbours are attached with boundary = { \"below.NAME\" = \"BODY\" }"
                        if grid else "boundary applies to grids; a chain's copy 0 is attached with first")
                raise ModelError(hint, element=attachment)
            for key, target in table.items():
                prefix_ = neighbour_prefix(key) if isinstance(key, str) else None
                if prefix_ not in prefixes or key[len(prefix_) :] not in unit_bodies:
                    spelled = " or ".join(f'"{p}NAME"' for p in prefixes)
                    raise ModelError(f'expected keys {spelled} with NAME a body of unit "{self.unit.name}", got {key!r}',
                                     element=attachment)  # fmt: skip
                _validate.name(target, f'{attachment}."{key}"')
            object.__setattr__(self, attachment, _validate.ReadOnlyDict(table))
        for kind, index, where, name, prefix_ in self.unit.neighbour_references():
            if grid and prefix_ == PREV:
                raise ModelError(f'"{name}": a grid has no copy before; use "left.NAME" (copy (i−1, j)) or '
                                 f'"below.NAME" (copy (i, j−1))', element=f"units.{self.unit.name}.{where}")  # fmt: skip
            if not grid and prefix_ != PREV:
                raise ModelError(f'"{name}" needs a grid (count = [ni, nj]); in a chain the copy before is "prev.NAME"',
                                 element=f"units.{self.unit.name}.{where}")  # fmt: skip
        for (kind, index), restriction in self.unit.only.items():
            tiling.check_restriction(restriction, f"units.{self.unit.name}.{_part_label(self.unit, kind, index)}")
        if not isinstance(self.vary, Mapping):
            raise ModelError(f"expected a table of path = {{ step = … }} or {{ cycle = […] }}, got {self.vary!r}",
                             element="vary")  # fmt: skip
        vary = {}
        for path, variation in self.vary.items():
            if not isinstance(variation, (Step, Cycle)):
                raise ModelError(f"expected {{ step = … }} or {{ cycle = […] }}, got {variation!r}", element=f'vary."{path}"')
            target = resolve_path(self.unit, path)
            try:
                vary[path] = checked_variation(self.unit, target, variation, tiling)
            except ModelError as error:
                raise error.within(f'vary."{path}"') from None
        object.__setattr__(self, "vary", _validate.ReadOnlyDict(vary))

    @property
    def shape(self) -> tuple[int, ...]:
        """``(count,)`` for a chain, ``(ni, nj)`` for a grid."""
        return tuple(self.count) if isinstance(self.count, tuple) else (self.count,)

    @property
    def is_grid(self) -> bool:
        return isinstance(self.count, tuple)


def _part_label(unit: Unit, kind: str, index: int) -> str:
    """A unit's part as the file spells it: ``bodies.NAME`` or ``joints[3]``."""
    return f"bodies.{unit.bodies[index].name}" if kind == "bodies" else f"{kind}[{index}]"


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

    Copies are laid out one after the other (a grid's row by row), each with the unit's
    parts in the unit's order — those that exist in it: a part restricted to some copies
    (`OnCopies`), or one that names a neighbour outside the grid (an open boundary) or a
    body absent from a copy, is left out of that copy.  Which parts exist where is one
    boolean array per kind (None when every copy has every part: then copy k's part e is
    at ``k · n + e``), and their positions are its running count.

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
        self.tiling = Tiling(repeat.prefix, repeat.shape)
        self.count, self.prefix, self.is_grid = self.tiling.count, repeat.prefix, self.tiling.is_grid
        #: The translation of one step along i and along j, shape (2, 2).
        self.lattice = np.array(repeat.offset if repeat.is_grid else (repeat.offset, (0.0, 0.0)), dtype=float)
        self.offset = self.lattice[0]
        #: What a neighbour reference means where the copy has no such neighbour.
        self.attached = repeat.boundary if repeat.is_grid else repeat.first
        self.first_body, self.first_joint, self.first_driver = first_body, first_joint, first_driver
        self.first_load = first_load
        self.first = {"bodies": first_body, "joints": first_joint, "drivers": first_driver, "loads": first_load}
        self.n_bodies, self.n_joints, self.n_drivers = len(unit.bodies), len(unit.joints), len(unit.drivers)
        self.n_loads = len(unit.loads)
        self.body_index = unit.body_index
        self.point_index = {name: k for k, name in enumerate(unit.points)}
        self.joint_index = {joint.name: k for k, joint in enumerate(unit.joints) if joint.name is not None}
        self.driver_index = {driver.name: k for k, driver in enumerate(unit.drivers) if driver.name is not None}
        self.load_index = {load.name: k for k, load in enumerate(unit.loads) if load.name is not None}
        self._local = {"bodies": self.body_index, "joints": self.joint_index, "drivers": self.driver_index,
                       "loads": self.load_index, "points": self.point_index}  # fmt: skip
        self._variations = {path: (resolve_path(unit, path), variation) for path, variation in repeat.vary.items()}
        self._positions: np.ndarray | None = None
        self._present = self._presence()
        self._slots: dict = {}  # kind (or ("through", kind)) -> running counts, made when asked
        self._totals = {kind: (self.count * len(getattr(unit, kind)) if self._present[kind] is None
                               else int(self._present[kind].sum())) for kind in KINDS}  # fmt: skip

    @property
    def label(self) -> str:
        return f"repeat[{self.index}]"

    # ------------------------------------------------------------------ which parts exist where
    def _presence(self) -> dict[str, np.ndarray | None]:
        """For each kind: which copies have which of the unit's parts, shape (count, n); None if all."""
        unit, tiling, count = self.unit, self.tiling, self.count
        ks = np.arange(count)
        neighbours = {}

        def restricted(kind: str) -> np.ndarray:
            mask = np.ones((count, len(getattr(unit, kind))), dtype=bool)
            for (part_kind, e), restriction in unit.only.items():
                if part_kind == kind:
                    mask[:, e] = tiling.kept(restriction)
            return mask

        bodies = restricted("bodies")

        def reference_present(name: str) -> np.ndarray | None:
            if name in self.body_index:
                return bodies[:, self.body_index[name]]
            prefix = neighbour_prefix(name)
            if prefix is None:
                return None  # a body of the model: in every copy
            if prefix not in neighbours:
                neighbours[prefix] = tiling.neighbour(ks, prefix)
            other = neighbours[prefix]
            inside = other >= 0
            present = np.zeros(count, dtype=bool)
            present[inside] = bodies[other[inside], self.body_index[name[len(prefix) :]]]
            present[~inside] = prefix == PREV or name in self.attached  # a chain's copy 0 is always attached
            return present

        present = {"bodies": bodies}
        for kind in ("joints", "drivers", "loads"):
            mask = restricted(kind)
            for e, element in enumerate(getattr(unit, kind)):
                for _, _, name in _body_references(element):
                    body_present = reference_present(name)
                    if body_present is not None:
                        mask[:, e] &= body_present
                for field_name in type(element).joint_fields:  # a driver of the copy's own joint
                    joint = self.joint_index.get(getattr(element, field_name))
                    if joint is not None:
                        mask[:, e] &= present["joints"][:, joint]
            present[kind] = mask
        return {kind: None if mask.all() else mask for kind, mask in present.items()}

    def total(self, kind: str) -> int:
        """How many bodies, joints, drivers or loads (`kind`) the copies have together."""
        return self._totals[kind]

    def n_left_out(self) -> int:
        """How many of the copies' joints, drivers and loads are left out (open boundaries,
        restricted parts, absent bodies)."""
        return sum(self.count * len(getattr(self.unit, kind)) - self._totals[kind] for kind in ("joints", "drivers", "loads"))

    def having(self, kind: str) -> np.ndarray:
        """For each of the unit's parts of `kind`: how many copies have it."""
        mask = self._present[kind]
        return np.full(len(getattr(self.unit, kind)), self.count) if mask is None else mask.sum(axis=0)

    def first_having(self, kind: str) -> list[int]:
        """For each of the unit's parts of `kind` that some copies have and others not: the
        first copy that has it."""
        mask = self._present[kind]
        if mask is None:
            return []
        some = mask.any(axis=0) & ~mask.all(axis=0)
        return np.argmax(mask[:, some], axis=0).tolist()

    def present(self, kind: str, k: int, e: int) -> bool:
        mask = self._present[kind]
        return True if mask is None else bool(mask[k, e])

    def parts_of(self, kind: str, k: int):
        """The unit's parts of `kind` that copy k has (their indices in the unit)."""
        mask = self._present[kind]
        return range(len(getattr(self.unit, kind))) if mask is None else np.flatnonzero(mask[k]).tolist()

    def slot(self, kind: str, ks, e: int):
        """Position, among the repeat's parts of `kind`, of part e of copies `ks` (-1 where absent)."""
        mask = self._present[kind]
        if mask is None:
            return ks * len(getattr(self.unit, kind)) + e
        if kind not in self._slots:
            slots = np.cumsum(mask.ravel(), dtype=np.int64).reshape(mask.shape) - 1
            slots[~mask] = -1
            self._slots[kind] = slots
        return self._slots[kind][ks, e]

    def placed(self, kind: str, sizes=None) -> list[tuple[np.ndarray, np.ndarray]]:
        """For each of the unit's parts of `kind`: ``(ks, starts)``, the copies that have it
        and its first place in the repeat's block when part e takes ``sizes[e]`` places
        (its equations, its laws; default one)."""
        n = len(getattr(self.unit, kind))
        sizes = np.ones(n, dtype=np.int64) if sizes is None else np.asarray(sizes, dtype=np.int64)
        mask = self._present[kind]
        if mask is None:
            ks = np.arange(self.count, dtype=np.int64)
            before = np.cumsum(sizes) - sizes
            return [(ks, ks * int(sizes.sum()) + before[e]) for e in range(n)]
        weights = (mask * sizes[None]).ravel()
        starts = (np.cumsum(weights) - weights).reshape(mask.shape)
        return [(np.flatnonzero(mask[:, e]), starts[mask[:, e], e]) for e in range(n)]

    def locate(self, kind: str, within: int) -> tuple[int, int]:
        """``(k, e)`` of the repeat's part number `within` of `kind`."""
        n = len(getattr(self.unit, kind))
        mask = self._present[kind]
        if mask is None:
            return divmod(within, n)
        if ("through", kind) not in self._slots:  # the parts of the copies up to each copy, once
            self._slots[("through", kind)] = np.cumsum(mask.sum(axis=1))
        per_copy = self._slots[("through", kind)]
        k = int(np.searchsorted(per_copy, within, side="right"))
        before = int(per_copy[k - 1]) if k else 0
        return k, int(np.flatnonzero(mask[k])[within - before])

    def find(self, kind: str, name: str) -> tuple[int, int] | None:
        """``(k, e)`` if `name` is the expanded name of part e of `kind` (or of point e,
        `kind` ``"points"``) in copy k, which has it; else None."""
        split = self.tiling.split(name)
        if split is None:
            return None
        e = self._local[kind].get(split[1])
        if e is None or (kind != "points" and not self.present(kind, split[0], e)):
            return None
        return split[0], e

    # ------------------------------------------------------------------ names
    def name(self, k: int, local: str) -> str:
        """The expanded name of the unit's `local` name in copy k."""
        return self.tiling.name(k, local)

    def split(self, name: str) -> tuple[int, str] | None:
        """``(k, local)`` if `name` is one of this repeat's copies' names."""
        return self.tiling.split(name)

    def body_name(self, k: int, reference: str) -> str:
        """What a unit's body reference names in copy k (an expanded name, or the model's)."""
        if reference in self.body_index:
            return self.name(k, reference)
        prefix = neighbour_prefix(reference)
        if prefix is not None:
            other = int(self.tiling.neighbour(np.array([k]), prefix)[0])
            if other < 0:
                return self.attached.get(reference, GROUND)
            return self.name(other, reference[len(prefix) :])
        return reference

    def point_name(self, k: int, reference):
        """What a unit's point reference is in copy k: an expanded name, the model's name, or
        coordinates translated with the copy."""
        if isinstance(reference, str):
            return self.name(k, reference) if reference in self.point_index else reference
        x, y = self.shift(np.array([k]))[0]
        return (reference[0] + float(x), reference[1] + float(y))

    def joint_name(self, k: int, reference: str) -> str:
        return self.name(k, reference) if reference in self.joint_index else reference

    # ------------------------------------------------------------------ geometry
    def shift(self, ks: np.ndarray) -> np.ndarray:
        """The translation of copies `ks`, shape (len(ks), 2), m."""
        i, j = self.tiling.columns_rows(np.asarray(ks))
        return i[:, None] * self.lattice[0] + j[:, None] * self.lattice[1]

    @property
    def positions(self) -> np.ndarray:
        """Drawn position of every copy's every unit point, shape (count, n_points, 2), m."""
        if self._positions is None:
            base = np.array(list(self.unit.points.values()), dtype=float).reshape(-1, 2)
            positions = np.repeat(base[None], self.count, axis=0)
            for target, variation in self._variations.values():
                if target[0] == "point":
                    p = self.point_index[target[1]]
                    positions[:, p] = varied_values(variation, base[p], self.tiling)
            positions += self.shift(np.arange(self.count))[:, None, :]
            self._positions = positions
        return self._positions

    def reference_positions(self, references, ks=None) -> np.ndarray:
        """Drawn positions of unit point references in copies `ks` (default all), shape
        (len(ks), len(references), 2)."""
        ks = np.arange(self.count) if ks is None else ks
        out = np.empty((len(ks), len(references), 2))
        shift = None
        for e, reference in enumerate(references):
            if isinstance(reference, str) and reference in self.point_index:
                out[:, e] = self.positions[ks, self.point_index[reference]]
            elif isinstance(reference, str):
                out[:, e] = self.model_position(reference)
            else:
                shift = self.shift(ks) if shift is None else shift
                out[:, e] = np.asarray(reference, dtype=float) + shift
        return out

    def body_columns(self, references, resolve, ks=None) -> np.ndarray:
        """Stored body index of unit body references in copies `ks` (default all), shape
        (len(ks), len(references)).

        `resolve` maps a model body name to its stored index (the ground included).
        """
        ks = np.arange(self.count, dtype=np.int64) if ks is None else ks
        out = np.empty((len(ks), len(references)), dtype=np.int64)
        for e, reference in enumerate(references):
            prefix = neighbour_prefix(reference)
            if reference in self.body_index:
                out[:, e] = self.first_body + self.slot("bodies", ks, self.body_index[reference])
            elif prefix is not None:
                other = self.tiling.neighbour(ks, prefix)
                inside = other >= 0
                out[inside, e] = self.first_body + self.slot("bodies", other[inside], self.body_index[reference[len(prefix) :]])
                if not inside.all():
                    out[~inside, e] = resolve(self.attached.get(reference, GROUND))
            else:
                out[:, e] = resolve(reference)
        return out

    def frames(self) -> np.ndarray:
        """Drawn frames ``(x, y, angle)`` of every copy's bodies, shape (n bodies of the copies, 3)."""
        origins = self.reference_positions([body.origin for body in self.unit.bodies])
        frames = np.empty((self.count, self.n_bodies, 3))
        frames[:, :, :2] = origins
        frames[:, :, 2] = [body.angle for body in self.unit.bodies]
        for target, variation in self._variations.values():
            if target[0] == "angle":
                frames[:, target[1], 2] = varied_values(variation, base_value(self.unit, target), self.tiling)
        mask = self._present["bodies"]
        return frames.reshape(-1, 3) if mask is None else frames[mask]

    # ------------------------------------------------------------------ variations of laws
    def law_variations(self, driver: int, ks=None) -> dict[str, dict[str, np.ndarray]]:
        """For unit driver `driver`: law field -> {key: value of every copy (of copies `ks`)}."""
        varied: dict[str, dict[str, np.ndarray]] = {}
        for target, variation in self._variations.values():
            if target[0] == "law" and target[1] == driver:
                varied.setdefault(target[2], {})[target[3]] = varied_values(variation, base_value(self.unit, target),
                                                                            self.tiling, ks)  # fmt: skip
        return varied

    # ------------------------------------------------------------------ elements on demand
    def element(self, kind: str, k: int, e: int):
        """Copy k's element e of the unit's `kind` ("bodies", "joints", "drivers", "loads"), as an object."""
        unit_element = getattr(self.unit, kind)[e]
        if kind == "bodies":
            angle = unit_element.angle
            for target, variation in self._variations.values():
                if target[0] == "angle" and target[1] == e:
                    angle = float(varied_values(variation, angle, self.tiling, [k])[0])
            return dataclasses.replace(
                unit_element,
                name=self.name(k, unit_element.name),
                origin=self.point_name(k, unit_element.origin),
                points=tuple(self.point_name(k, p) for p in unit_element.points),
                com=None if unit_element.com is None else self.point_name(k, unit_element.com),
                angle=angle,
                lengths=tuple((self.point_name(k, a), self.point_name(k, b), length)
                              for a, b, length in unit_element.lengths),
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
                for law_field, keys in self.law_variations(e, [k]).items():
                    law = getattr(unit_element, law_field)
                    copy_values = {key: float(values[0]) for key, values in keys.items()}
                    changes[law_field] = dataclasses.replace(law, **copy_values)
            return dataclasses.replace(unit_element, **changes)
        except ModelError as error:
            raise error.within(f"{self.label} {self.tiling.label(k)}: units.{self.unit.name}.{kind}[{e}]") from None


def find_copy(copies_list, kind: str, name: str):
    """``(copies, k, e)`` of the copy's part of `kind` (or point) whose expanded name is
    `name`, among the repeats `copies_list`; None if no copy has it."""
    for copies in copies_list:
        found = copies.find(kind, name)
        if found is not None:
            return copies, found[0], found[1]
    return None


# ---------------------------------------------------------------------- lazy views of the whole model
class ElementList(Sequence):
    """The bodies, joints, drivers or loads of a mechanism with repeats: its own, then each
    repeat's copies (copy-major).  Copies' elements are built on demand."""

    def __init__(self, kind: str, own: tuple, copies: list[Copies]) -> None:
        self.kind, self.own, self.copies = kind, own, copies
        self._sizes = [len(own)] + [c.total(kind) for c in copies]
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
        return copies.element(self.kind, *copies.locate(self.kind, index - int(self._starts[segment])))

    def __iter__(self):
        yield from self.own
        for copies in self.copies:
            for k in range(copies.count):
                for e in copies.parts_of(self.kind, k):
                    yield copies.element(self.kind, k, e)

    def __eq__(self, other) -> bool:
        if isinstance(other, ElementList):
            return self.own == other.own and [c.repeat for c in self.copies] == [c.repeat for c in other.copies]
        return isinstance(other, Sequence) and len(self) == len(other) and all(a == b for a, b in zip(self, other))

    __hash__ = None

    def __repr__(self) -> str:
        return f"ElementList({self.kind}: {len(self.own)} own + {', '.join(f'{c.count}×{c.unit.name}' for c in self.copies)})"


class PointTable(Mapping):
    """The named points of a mechanism with repeats: its own, then every copy's, resolved by
    name on demand (``u17.Q``) without a dict of every point."""

    def __init__(self, own: dict, copies: list[Copies]) -> None:
        self.own, self.copies = own, copies

    def locate(self, name: str):
        """``(copies, k, unit point index)`` of a copy's point, or None."""
        return find_copy(self.copies, "points", name)

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
