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
PATH_FORMS = "drivers[i].law.KEY, drivers.NAME.law.KEY, points.NAME[.x|.y], or units.UNIT. before one of them"

_UNIT_PATH = re.compile(r"units\.([^.]+)\.(.+)")
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
    """What a path changes: a law parameter or a point (the model's own, or a unit's)."""

    path: str
    unit: str | None  # None: the model's own element
    driver: int = -1  # kind "law"
    law_field: str = ""
    key: str = ""
    point: str = ""  # kind "point"
    component: int | None = None  # None: the pair; 0: x; 1: y

    @property
    def is_point(self) -> bool:
        return bool(self.point)


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
                for value in (values[0], values[-1]) if values.ndim == 1 else ():
                    _check_law_value(mechanism, target, float(value))  # e.g. a negative rate
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
        own_points = dict(mechanism.own("points"))
        own_drivers = list(mechanism.own("drivers"))
        units = {c.unit.name: c.unit for c in mechanism.copies}
        unit_points = {name: dict(unit.points) for name, unit in units.items()}
        unit_drivers = {name: list(unit.drivers) for name, unit in units.items()}
        for path, value in self.variants.grid_values(k):
            target = self.targets[path]
            if target.is_point:
                points = own_points if target.unit is None else unit_points[target.unit]
                if target.component is None:
                    points[target.point] = value
                else:
                    pair = list(points[target.point])
                    pair[target.component] = value
                    points[target.point] = tuple(pair)
            else:
                drivers = own_drivers if target.unit is None else unit_drivers[target.unit]
                drivers[target.driver] = _changed_driver(drivers[target.driver], target, value)
        repeats = list(mechanism.repeats)
        changed_units = {name for name in units if unit_points[name] != dict(units[name].points)
                         or unit_drivers[name] != list(units[name].drivers)}  # fmt: skip
        for r, repeat in enumerate(repeats):
            if repeat.unit.name in changed_units:
                unit = dataclasses.replace(repeat.unit, points=unit_points[repeat.unit.name],
                                           drivers=tuple(unit_drivers[repeat.unit.name]))  # fmt: skip
                repeats[r] = dataclasses.replace(repeat, unit=unit)
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
        return dataclasses.replace(
            mechanism, points=own_points, drivers=tuple(own_drivers), repeats=tuple(repeats)
        )

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
        return _resolve_within(
            path, unit_match[2], unit.name, unit.points, unit.drivers, f'unit "{unit.name}"'
        )
    return _resolve_within(path, path, None, mechanism.own("points"), mechanism.own("drivers"), "the model")


def _resolve_within(
    path: str, rest: str, unit: str | None, points: Mapping, drivers: Sequence, owner: str
) -> _Target:
    match = _DRIVER_PATH.fullmatch(rest)
    if match:
        index_text, name, law_field, key = match.groups()
        if index_text is not None:
            index = int(index_text)
            if index >= len(drivers):
                listed = f"drivers[0] … drivers[{len(drivers) - 1}]" if drivers else "none"
                raise ModelError(f"{owner} has {len(drivers)} drivers ({listed})", element=path)
        else:
            names = [driver.name for driver in drivers]
            if name not in names:
                known = _validate.known_list([n for n in names if n]) if any(names) else "none is named"
                raise ModelError(f'{owner} has no driver named "{name}" (named: {known})', element=path)
            index = names.index(name)
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


def _looks_like_copy_point(name: str) -> bool:
    """Whether an unknown point name looks like a copy's point (``u17.Q``)."""
    return "." in name


def _check_law_value(mechanism: Mechanism, target: _Target, value: float) -> None:
    """Check that the target's law takes `value` (a ModelError naming the path otherwise)."""
    if target.is_point:
        return
    drivers = mechanism.own("drivers") if target.unit is None else next(
        c.unit.drivers for c in mechanism.copies if c.unit.name == target.unit
    )  # fmt: skip
    _changed_driver(drivers[target.driver], target, value)


def _changed_driver(driver, target: _Target, value: float):
    law = getattr(driver, target.law_field)
    try:
        changed = dataclasses.replace(law, **{target.key: value})
    except ModelError as error:
        raise ModelError(f"{error.reason} (value {value!r})", element=target.path) from None
    return dataclasses.replace(driver, **{target.law_field: changed})
