"""The variants of a sweep: `VariantSet` describes them (a grid of parameter values by path,
random samples of a tolerance study), `VariantSet.bind` checks them against a mechanism
(`VariantDesign`), and `resolve_path` reads a parameter path (`PATH_FORMS`; the grammar is
in `sparsekin.studies.sweeps`)."""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from ..model import _validate
from ..model.mechanism import Mechanism
from ..model.paths import DRIVER_PATH as _DRIVER_PATH
from ..model.units import Cycle

#: The path forms, in words (for messages).
PATH_FORMS = ("drivers[i].law.KEY, drivers.NAME.law.KEY, points.NAME[.x|.y], bodies.NAME.KEY (mass, inertia, "
              "velocity.vx|vy|omega), loads[i].KEY, loads[i].value.KEY, or units.UNIT. before one of them")

_UNIT_PATH = re.compile(r"units\.([^.]+)\.(.+)")
#: ``bodies.NAME.KEY``: a body's mass, inertia or a component of its initial velocity; groups:
#: the name (copies' names hold dots), the key.
_BODY_PATH = re.compile(r"bodies\.(.+)\.(mass|inertia|velocity\.(?:vx|vy|omega))")
#: ``loads[i].KEY``, ``loads.NAME.KEY`` or ``…value.KEY`` (a parameter of its law); groups:
#: index, name, "value." when the key is the law's, key.
_LOAD_PATH = re.compile(r"loads(?:\[(\d+)\]|\.([^.\[\]]+))\.(value\.)?(\w+)")
#: The components of a body's ``velocity`` (the keys after ``velocity.``).
_VELOCITY_KEYS = ("vx", "vy", "omega")
_PERTURB_KINDS = ("points",)


@dataclass(frozen=True, eq=False)
class VariantSet:
    """The variants of a sweep: a grid of values by path, and random samples.

    Parameters
    ----------
    grid : mapping, optional
        Axis -> values.  An axis is a path (see the module docstring) or a tuple of paths
        that take the same values together; values are an array of shape (n,) for a
        number, (n, 2) for a point's position.  The variants are the cartesian product of
        the axes, the first axis slowest.
    samples : int
        Random samples at each grid point (default 1; more than 1 needs `perturb_points`).
    perturb_points : float, optional
        Standard deviation of the normal deviation added to each coordinate of every
        point's drawn position (the model's own points and every copy's), m.  None: no
        deviation (0 draws deviations of zero: each variant is the nominal drawing).
    seed : int, optional
        Seed of the deviations: variant k draws from ``numpy.random.default_rng([seed, k])``,
        so a variant's deviations do not depend on how the variants are split into tasks.
        Default: a fresh seed, kept in `seed` (and written to the store).

    Attributes
    ----------
    axes : tuple of (tuple of str, ndarray)
        The grid's axes.
    n_variants : int
    columns : tuple of str
        Labels of the columns of `table`: one per varied number, ``points.M.x`` and
        ``points.M.y`` for a point.

    Raises
    ------
    ValueError
        For an axis without paths or values, values of the wrong shape or not finite, or
        a bad count.
    """

    grid: Mapping = field(default_factory=dict)
    samples: int = 1
    perturb_points: float | None = None
    seed: int | None = None
    axes: tuple = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.grid, Mapping):
            raise ValueError(
                f"`grid` must be a mapping of path (or tuple of paths) to values, got {self.grid!r}."
            )
        axes = []
        seen: set[str] = set()
        for key, values in self.grid.items():
            paths = (key,) if isinstance(key, str) else tuple(key) if isinstance(key, Sequence) else None
            if not paths or not all(isinstance(p, str) and p for p in paths):
                raise ValueError(f"`grid` keys must be paths or tuples of paths, got {key!r}.")
            for path in paths:
                if path in seen:
                    raise ValueError(f"`grid`: path {path} is on two axes; expected each path once.")
                seen.add(path)
            array = np.array(values, dtype=float)
            if (
                array.ndim == 0
                or array.shape[0] == 0
                or array.ndim > 2
                or (array.ndim == 2 and array.shape[1] != 2)
            ):
                raise ValueError(f"`grid`: values of {', '.join(paths)} must have shape (n,) or (n, 2), "
                                 f"got {array.shape}.")  # fmt: skip
            if not np.all(np.isfinite(array)):
                raise ValueError(f"`grid`: values of {', '.join(paths)} must be finite.")
            array.setflags(write=False)
            axes.append((paths, array))
        object.__setattr__(self, "axes", tuple(axes))
        object.__setattr__(self, "grid", {paths if len(paths) > 1 else paths[0]: a for paths, a in axes})
        if (
            isinstance(self.samples, bool)
            or not isinstance(self.samples, (int, np.integer))
            or self.samples < 1
        ):
            raise ValueError(f"`samples` must be a whole number >= 1, got {self.samples!r}.")
        object.__setattr__(self, "samples", int(self.samples))
        sigma = self.perturb_points
        if sigma is not None:
            if isinstance(sigma, bool) or not isinstance(sigma, (int, float, np.number)) or not (
                math.isfinite(sigma) and sigma >= 0.0
            ):  # fmt: skip
                raise ValueError(f"`perturb_points` must be None or a finite number >= 0 (m), got {sigma!r}.")
            object.__setattr__(self, "perturb_points", float(sigma))
        if self.seed is None:
            object.__setattr__(self, "seed", int(np.random.SeedSequence().entropy % 2**63))
        elif isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ValueError(f"`seed` must be a whole number >= 0, got {self.seed!r}.")
        if not self.grid and sigma is None:
            raise ValueError("nothing to vary: give `grid` values, or `perturb_points`.")
        if self.samples > 1 and sigma is None:
            raise ValueError(f"`samples` = {self.samples} needs `perturb_points`: without a deviation every sample "
                             "is the same variant.")  # fmt: skip

    # ------------------------------------------------------------------ shape
    @property
    def shape(self) -> tuple[int, ...]:
        """Sizes of the grid's axes, then the samples."""
        return (*(values.shape[0] for _, values in self.axes), self.samples)

    @property
    def n_variants(self) -> int:
        return int(np.prod(self.shape))

    @property
    def paths(self) -> tuple[str, ...]:
        """Every path of the grid, axis by axis."""
        return tuple(path for paths, _ in self.axes for path in paths)

    @property
    def columns(self) -> tuple[str, ...]:
        labels = []
        for paths, values in self.axes:
            for path in paths:
                labels += [f"{path}.x", f"{path}.y"] if values.ndim == 2 else [path]
        return tuple(labels)

    def grid_values(self, k: int) -> list[tuple[str, float | tuple[float, float]]]:
        """``(path, value)`` of every grid path in variant `k`."""
        index = np.unravel_index(k, self.shape)
        out = []
        for (paths, values), i in zip(self.axes, index):
            value = values[i]
            value = (float(value[0]), float(value[1])) if values.ndim == 2 else float(value)
            out += [(path, value) for path in paths]
        return out

    def table(self) -> np.ndarray:
        """The grid's values of every variant, shape (n_variants, len(columns))."""
        columns = []
        index = np.unravel_index(np.arange(self.n_variants), self.shape)
        for (paths, values), i in zip(self.axes, index):
            taken = values[i]
            for _ in paths:
                columns += [taken[:, 0], taken[:, 1]] if values.ndim == 2 else [taken]
        return np.column_stack(columns) if columns else np.zeros((self.n_variants, 0))

    # ------------------------------------------------------------------ from the command line
    @classmethod
    def from_arguments(cls, vary: Sequence[str] = (), samples: int | None = None, perturb: Sequence[str] = (),
                       seed: int | None = None) -> VariantSet:  # fmt: skip
        """The variants the options ``--vary``, ``--samples``, ``--perturb`` and ``--seed`` ask for.

        Parameters
        ----------
        vary : sequence of str
            ``PATH=START:STOP:N`` (N values from START to STOP, both included) or
            ``PATH1,PATH2=START:STOP:N`` (the paths take the same values).  For a point
            (``points.M``) START and STOP are ``x,y`` pairs: N positions on the segment.
        samples : int, optional
            Random samples at each grid point.
        perturb : sequence of str
            ``points=SIGMA``: every point moved by a normal deviation of SIGMA m.
        seed : int, optional

        Raises
        ------
        ValueError
            One line naming the argument and what was expected.

        Examples
        --------
        >>> VariantSet.from_arguments(["points.M=0.2,0.6:0.3,0.6:3"]).grid["points.M"].tolist()
        [[0.2, 0.6], [0.25, 0.6], [0.3, 0.6]]
        >>> VariantSet.from_arguments(["drivers[0].law.amplitude=0.03:0.07"])
        Traceback (most recent call last):
        ...
        ValueError: --vary drivers[0].law.amplitude=0.03:0.07: expected PATH=START:STOP:N (N values from START to STOP)
        """
        grid = {}
        for text in vary:
            paths, values = _parse_vary(text)
            if paths in grid:
                raise ValueError(f"--vary {text}: {', '.join(paths)} given twice")
            grid[paths] = values
        sigma = None
        for text in perturb:
            kind, equals, value = text.partition("=")
            if not equals or kind.strip() not in _PERTURB_KINDS:
                raise ValueError(f"--perturb {text}: expected points=SIGMA (m)")
            sigma = _number(value, f"--perturb {text}", "SIGMA, a number >= 0 (m)")
            if sigma < 0:
                raise ValueError(f"--perturb {text}: expected SIGMA >= 0 (m), got {value.strip()}")
        if samples is not None and samples < 1:
            raise ValueError(f"--samples must be a whole number >= 1, got {samples}")
        if sigma is not None and samples is None:
            raise ValueError("--perturb needs --samples N: how many random variants to draw")
        if seed is not None and seed < 0:
            raise ValueError(f"--seed must be a whole number >= 0, got {seed}")
        if not grid and sigma is None:
            raise ValueError(
                "nothing to vary: give --vary PATH=START:STOP:N, or --samples N --perturb points=SIGMA"
            )
        if samples is not None and samples > 1 and sigma is None:
            raise ValueError(f"--samples {samples} needs --perturb points=SIGMA: without a deviation every sample is "
                             "the same variant")  # fmt: skip
        return cls({key if len(key) > 1 else key[0]: values for key, values in grid.items()},
                   samples=samples or 1, perturb_points=sigma, seed=seed)  # fmt: skip

    def bind(self, mechanism: Mechanism) -> VariantDesign:
        """These variants checked against `mechanism` (see `VariantDesign`)."""
        return VariantDesign(mechanism, self)


def _parse_vary(text: str) -> tuple[tuple[str, ...], np.ndarray]:
    where = f"--vary {text}"
    left, equals, right = text.partition("=")
    parts = right.split(":")
    if not equals or len(parts) != 3:
        raise ValueError(f"{where}: expected PATH=START:STOP:N (N values from START to STOP)")
    paths = tuple(path.strip() for path in left.split(","))
    if not all(paths):
        raise ValueError(f"{where}: empty path in {left!r}: expected paths separated by commas")
    count_text = parts[2].strip()
    if not count_text.isdigit() or int(count_text) < 1:
        raise ValueError(f"{where}: expected N, a whole number >= 1, got {count_text!r}")
    n = int(count_text)
    bounds = []
    for name, part in zip(("START", "STOP"), parts[:2]):
        numbers = part.split(",")
        if len(numbers) not in (1, 2):
            raise ValueError(f"{where}: expected {name} as a number or x,y, got {part.strip()!r}")
        bounds.append([_number(number, where, f"{name} as a number or x,y") for number in numbers])
    start, stop = bounds
    if len(start) != len(stop):
        raise ValueError(f"{where}: START and STOP must both be numbers or both x,y pairs")
    if n == 1 and start != stop:
        raise ValueError(f"{where}: N = 1 needs START = STOP")
    values = np.linspace(start, stop, n)
    return paths, values if len(start) == 2 else values[:, 0]


def _number(text: str, where: str, expected: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{where}: expected {expected}, got {text.strip()!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"{where}: expected {expected}, got {text.strip()!r}")
    return value


@dataclass(frozen=True)
class _Target:
    """What a path changes: a law parameter, a point, a body's number or a load's (the model's own
    element, or a unit's)."""

    path: str
    unit: str | None  # None: the model's own element
    driver: int = -1  # kind "law"
    law_field: str = ""
    key: str = ""
    point: str = ""  # kind "point"
    component: int | None = None  # None: the pair; 0: x; 1: y
    body: str = ""  # kind "body": key "mass", "inertia" or "velocity.vx" …
    load: int = -1  # kind "load": key a number of the load, or of its law when `law_field` is "value"

    @property
    def is_point(self) -> bool:
        return bool(self.point)

    def changed(self, element, value: float):
        """The driver, body or load `element` with this target's value (a ModelError naming
        the path if it does not take it)."""
        try:
            if self.law_field:
                law = getattr(element, self.law_field)
                return dataclasses.replace(element, **{self.law_field: dataclasses.replace(law, **{self.key: value})})
            if self.key.startswith("velocity."):
                velocity = list(element.velocity or (0.0, 0.0, 0.0))
                velocity[_VELOCITY_KEYS.index(self.key.split(".")[1])] = value
                return dataclasses.replace(element, velocity=tuple(velocity))
            return dataclasses.replace(element, **{self.key: value})
        except ModelError as error:
            raise ModelError(f"{error.reason} (value {value!r})", element=self.path) from None


class VariantDesign:
    """A `VariantSet` checked against a mechanism: builds any variant's mechanism.

    Parameters
    ----------
    mechanism : Mechanism
        The nominal mechanism.
    variants : VariantSet

    Raises
    ------
    ModelError
        One line naming the path and what was expected, for a path that names no
        parameter of `mechanism`, a value that parameter does not take, or a point value
        given to a number (or the reverse).
    """

    def __init__(self, mechanism: Mechanism, variants: VariantSet) -> None:
        if not isinstance(mechanism, Mechanism):
            raise TypeError(f"`mechanism` must be a Mechanism, got {type(mechanism).__name__}.")
        self.mechanism, self.variants = mechanism, variants
        targets = {}
        for paths, values in variants.axes:
            for path in paths:
                target = resolve_path(mechanism, path)
                wants_pair = target.is_point and target.component is None
                if wants_pair != (values.ndim == 2):
                    expected = "x,y pairs (a point's position, m)" if wants_pair else "numbers"
                    raise ModelError(f"expected {expected} as values", element=path)
                targets[path] = target
                for value in (values[0], values[-1]) if not target.is_point else ():
                    target.changed(_element(mechanism, target), float(value))  # e.g. a negative rate
        self.targets = targets
        #: Whether variants differ in their drawing (then each needs its own pattern).
        self.geometry_varies = variants.perturb_points is not None or any(
            t.is_point for t in targets.values()
        )

    @property
    def n_variants(self) -> int:
        return self.variants.n_variants

    def deviations(self, k: int) -> np.ndarray:
        """Variant k's deviation of every point (the model's own, then each repeat's copies',
        in the order of ``mechanism.points``), shape (n_points, 2), m."""
        n_points = len(self.mechanism.points)
        rng = np.random.default_rng([self.variants.seed, k])
        return rng.normal(0.0, self.variants.perturb_points, size=(n_points, 2))

    def variant(self, k: int) -> Mechanism:
        """Variant k's mechanism: the nominal one with its values (a `ModelError` if they
        make no valid mechanism)."""
        if not 0 <= k < self.n_variants:
            raise IndexError(f"variant {k} out of range({self.n_variants})")
        mechanism = self.mechanism
        own = {kind: _copied(mechanism.own(kind)) for kind in _VARIED}
        units = {c.unit.name: c.unit for c in mechanism.copies}
        of_unit = {name: {kind: _copied(getattr(unit, kind)) for kind in _VARIED} for name, unit in units.items()}
        for path, value in self.variants.grid_values(k):
            target = self.targets[path]
            elements = own if target.unit is None else of_unit[target.unit]
            if target.is_point:
                points = elements["points"]
                if target.component is None:
                    points[target.point] = value
                else:
                    pair = list(points[target.point])
                    pair[target.component] = value
                    points[target.point] = tuple(pair)
            else:
                kind, index = _element_index(target, elements["bodies"])
                elements[kind][index] = target.changed(elements[kind][index], value)
        repeats = list(mechanism.repeats)
        for r, repeat in enumerate(repeats):
            unit, changed = repeat.unit, of_unit[repeat.unit.name]
            if any(changed[kind] != _copied(getattr(unit, kind)) for kind in _VARIED):
                unit = dataclasses.replace(unit, **{kind: _frozen(kind, changed[kind]) for kind in _VARIED})
                repeats[r] = dataclasses.replace(repeat, unit=unit)
        own_points, own_drivers = own["points"], own["drivers"]
        if self.variants.perturb_points is not None:
            deviations = self.deviations(k)
            for p, name in enumerate(own_points):
                x, y = own_points[name]
                own_points[name] = (x + float(deviations[p, 0]), y + float(deviations[p, 1]))
            first = len(own_points)
            if repeats:  # the copies' points, drawn where the varied units put them
                staged = Mechanism(points=own_points, bodies=mechanism.own("bodies"), joints=mechanism.own("joints"),
                                   drivers=tuple(own_drivers), name=mechanism.name, analysis=mechanism.analysis,
                                   repeats=tuple(repeats))  # fmt: skip
                for r, copies in enumerate(staged.copies):
                    count, n_points = copies.positions.shape[:2]
                    moved = copies.positions + deviations[first : first + count * n_points].reshape(
                        count, n_points, 2
                    )
                    first += count * n_points
                    moved -= np.arange(count)[:, None, None] * np.asarray(
                        copies.offset
                    )  # Cycle values are undrawn
                    vary = dict(copies.repeat.vary)
                    for p, name in enumerate(copies.unit.points):
                        vary[f"points.{name}"] = Cycle(tuple(map(tuple, moved[:, p].tolist())))
                    repeats[r] = dataclasses.replace(copies.repeat, vary=vary)
        return dataclasses.replace(mechanism, **{kind: _frozen(kind, own[kind]) for kind in _VARIED},
                                   repeats=tuple(repeats))  # fmt: skip

    def table(self) -> tuple[tuple[str, ...], np.ndarray]:
        """``(columns, values)``: the grid's values of every variant, then for a tolerance
        study the deviations of the model's own points (columns ``deviation.P.x``,
        ``deviation.P.y``, m); values of shape (n_variants, n_columns)."""
        columns, values = self.variants.columns, self.variants.table()
        if self.variants.perturb_points is not None:
            names = list(self.mechanism.own("points"))
            deviations = np.array([self.deviations(k)[: len(names)].ravel() for k in range(self.n_variants)])
            columns += tuple(f"deviation.{name}.{c}" for name in names for c in "xy")
            values = np.hstack([values, deviations.reshape(self.n_variants, -1)])
        return columns, values


def resolve_path(mechanism: Mechanism, path: str) -> _Target:
    """What `path` names in `mechanism` (see the module docstring).

    Raises
    ------
    ModelError
        Naming the path and what was expected.

    Examples
    --------
    >>> from sparsekin.testset import task5
    >>> resolve_path(task5(), "drivers[0].law.amplitude").key
    'amplitude'
    >>> resolve_path(task5(), "drivers[2].law.amplitude")
    Traceback (most recent call last):
    ...
    sparsekin.errors.ModelError: drivers[2].law.amplitude: the model has 2 drivers (drivers[0] … drivers[1])
    """
    if not isinstance(path, str):
        raise ModelError(f"expected a path ({PATH_FORMS}), got {path!r}")
    unit_match = _UNIT_PATH.fullmatch(path)
    if unit_match:
        units = {c.unit.name: c.unit for c in mechanism.copies}
        if unit_match[1] not in units:
            known = _validate.known_list(list(units)) if units else "none: the model repeats no unit"
            raise ModelError(f'unknown unit "{unit_match[1]}" (known: {known})', element=path)
        unit = units[unit_match[1]]
        elements = {kind: getattr(unit, kind) for kind in _VARIED}
        return _resolve_within(path, unit_match[2], unit.name, elements, f'unit "{unit.name}"')
    return _resolve_within(path, path, None, {kind: mechanism.own(kind) for kind in _VARIED}, "the model")


def _resolve_within(path: str, rest: str, unit: str | None, elements: Mapping, owner: str) -> _Target:
    points, drivers = elements["points"], elements["drivers"]
    if rest.startswith("bodies."):
        return _resolve_body(path, rest, unit, elements["bodies"], owner)
    if rest.startswith("loads"):
        return _resolve_load(path, rest, unit, elements["loads"], owner)
    match = _DRIVER_PATH.fullmatch(rest)
    if match:
        index_text, name, law_field, key = match.groups()
        index = _element_at("drivers", drivers, index_text, name, owner, path)
        driver = drivers[index]
        if law_field not in driver.law_fields:
            raise ModelError(f"drivers[{index}] has no {law_field} (its laws: {', '.join(driver.law_fields)})",
                             element=path)  # fmt: skip
        law = getattr(driver, law_field)
        keys = [f.name for f in dataclasses.fields(law) if f.init] if dataclasses.is_dataclass(law) else []
        if key not in keys:
            raise ModelError(f"the {type(law).__name__} law of drivers[{index}] has no parameter {key} "
                             f"(its parameters: {', '.join(keys) or 'none that can vary'})", element=path)  # fmt: skip
        if not isinstance(getattr(law, key), (float, type(None))):
            raise ModelError(f"{key} of drivers[{index}].{law_field} is not a number; expected a number parameter",
                             element=path)  # fmt: skip
        return _Target(path, unit, driver=index, law_field=law_field, key=key)
    if rest.startswith("points."):
        name = rest[len("points.") :]
        if name in points:
            return _Target(path, unit, point=name)
        if name[-2:] in (".x", ".y") and name[:-2] in points:
            return _Target(path, unit, point=name[:-2], component=".x.y".index(name[-2:]) // 2)
        hint = ""
        if unit is None and _looks_like_copy_point(name):
            hint = "; a repeated unit's point is varied for every copy with units.UNIT.points.NAME"
        raise ModelError(f'{owner} has no point "{name}" (known: {_validate.known_list(list(points))}){hint}',
                         element=path)  # fmt: skip
    raise ModelError(f"expected {PATH_FORMS}", element=path)


def _element_at(kind: str, elements: Sequence, index_text: str | None, name: str | None, owner: str, path: str) -> int:
    """The index of the driver or load (`kind`) that a path names by index (`index_text`) or
    by name; a ModelError naming the path and what there is otherwise."""
    if index_text is not None:
        index = int(index_text)
        if index >= len(elements):
            listed = f"{kind}[0] … {kind}[{len(elements) - 1}]" if elements else "none"
            raise ModelError(f"{owner} has {len(elements)} {kind} ({listed})", element=path)
        return index
    names = [element.name for element in elements]
    if name not in names:
        known = _validate.known_list([n for n in names if n]) if any(names) else "none is named"
        raise ModelError(f'{owner} has no {kind[:-1]} named "{name}" (named: {known})', element=path)
    return names.index(name)


def _resolve_body(path: str, rest: str, unit: str | None, bodies: Sequence, owner: str) -> _Target:
    match = _BODY_PATH.fullmatch(rest)
    if not match:
        raise ModelError("expected bodies.NAME.mass, bodies.NAME.inertia or bodies.NAME.velocity.vx (vy, omega)",
                         element=path)  # fmt: skip
    name, key = match.groups()
    names = [body.name for body in bodies]
    if name not in names:
        raise ModelError(f'{owner} has no body "{name}" (known: {_validate.known_list(names)})', element=path)
    return _Target(path, unit, key=key, body=name)


def _resolve_load(path: str, rest: str, unit: str | None, loads: Sequence, owner: str) -> _Target:
    match = _LOAD_PATH.fullmatch(rest)
    if not match:
        raise ModelError("expected loads[i].KEY, loads.NAME.KEY or loads[i].value.KEY", element=path)
    index_text, name, of_law, key = match.groups()
    index = _element_at("loads", loads, index_text, name, owner, path)
    load = loads[index]
    if of_law:
        law = getattr(load, "value", None)
        keys = [f.name for f in dataclasses.fields(law) if f.init] if dataclasses.is_dataclass(law) else []
        if key not in keys or not isinstance(getattr(law, key), (float, type(None))):
            what = "no value" if law is None else f"the value {law!r}"
            raise ModelError(f"loads[{index}] ({load.describe()}) has {what}: expected a law with the number "
                             f"parameter {key}", element=path)  # fmt: skip
        return _Target(path, unit, law_field="value", key=key, load=index)
    numbers = [f.name for f in dataclasses.fields(load) if f.init and f.name != "name"
               and isinstance(getattr(load, f.name), (float, type(None)))]  # fmt: skip
    if key not in numbers:
        raise ModelError(f"loads[{index}] ({load.describe()}) has no number {key} (its numbers: "
                         f"{', '.join(numbers) or 'none'})", element=path)  # fmt: skip
    return _Target(path, unit, key=key, load=index)


def _looks_like_copy_point(name: str) -> bool:
    """Whether an unknown point name looks like a copy's point (``u17.Q``)."""
    return "." in name


#: The kinds of element a variant may change.
_VARIED = ("points", "drivers", "bodies", "loads")


def _copied(elements):
    """A changeable copy of a kind's elements: a dict of points, else a list."""
    return dict(elements) if isinstance(elements, Mapping) else list(elements)


def _frozen(kind: str, elements):
    return dict(elements) if kind == "points" else tuple(elements)


def _element_index(target: _Target, bodies: Sequence) -> tuple[str, int]:
    """``(kind, index)`` of the driver, body or load that `target` changes among its owner's."""
    if target.body:
        return "bodies", next(b for b, body in enumerate(bodies) if body.name == target.body)
    if target.load >= 0:
        return "loads", target.load
    return "drivers", target.driver


def _element(mechanism: Mechanism, target: _Target):
    """The nominal driver, body or load that `target` changes."""
    owner = mechanism if target.unit is None else next(c.unit for c in mechanism.copies if c.unit.name == target.unit)
    elements = {kind: mechanism.own(kind) if target.unit is None else getattr(owner, kind) for kind in _VARIED}
    kind, index = _element_index(target, elements["bodies"])
    return elements[kind][index]
