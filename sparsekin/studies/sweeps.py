"""Design sweeps on Dask: many variants of one mechanism, each an independent analysis.

The data flow:

1. `VariantSet` describes the variants: a grid of parameter values by path (the
   cartesian product of its axes; several paths on one axis take the same values
   together) and, for a tolerance study, random samples in which every point's drawn
   position moves by a normal deviation.  It is the one description both
   `sparsekin.sweep` and ``sparsekin sweep`` use (`VariantSet.from_arguments` reads the
   command-line spelling).
2. `VariantSet.bind` checks it against a mechanism (`VariantDesign`): every path names a
   parameter, every value is allowed, and variant k's mechanism is a copy of the nominal
   one with its values (`VariantDesign.variant`).
3. The variants go to Dask in tasks of consecutive variants (`task_ranges`).  A task
   solves its variants one after the other with `sparsekin.solve_kinematics`; variants
   that only change law parameters share one constraint pattern, and every task after a
   worker's first finds the numba code compiled.  A variant that locks up is a result:
   status ``singular`` and its times.
4. The client writes each task's block of variants into the output as the task finishes
   (memory, or the Zarr store ``sweep.zarr``, region by region), so that no process holds
   more than a few tasks' results.  `SweepResult` is what comes back.

Parameter paths (`PATH_FORMS`), relative to the model:

=====================================  ================================================
``drivers[i].law.KEY``                 parameter KEY of the law of the model's driver i
``drivers.NAME.law.KEY``               the same, driver by name (``law_x``, ``law_y``
                                       for a path driver)
``points.NAME``                        drawn position of a point, (x, y), m
``points.NAME.x``, ``points.NAME.y``   one coordinate of it, m
``units.UNIT.drivers[i].law.KEY``      a repeated unit's parameter: every copy takes it
``units.UNIT.points.NAME`` (``.x``,    (a repeat's own ``vary`` still applies on top)
``.y``)
=====================================  ================================================

>>> import numpy as np
>>> import sparsekin as sk
>>> design = sk.VariantSet({("drivers[0].law.amplitude", "drivers[1].law.amplitude"): np.linspace(0.03, 0.07, 9)})
>>> design.n_variants, design.columns
(9, ('drivers[0].law.amplitude', 'drivers[1].law.amplitude'))
>>> sk.VariantSet.from_arguments(["drivers[0].law.amplitude=0.04:0.06:3", "points.M.x=0.18:0.22:5"]).n_variants
15
"""

from __future__ import annotations

import csv
import dataclasses
import math
import os
import re
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConvergenceError, ModelError, SingularJacobianError
from ..model import _validate
from ..model.mechanism import Mechanism
from ..model.units import DRIVER_PATH as _DRIVER_PATH, Cycle
from ..results.recording import JOINT_DERIVATIVES, POINT_COMPONENTS

__all__ = [
    "VariantSet",
    "VariantDesign",
    "SweepResult",
    "sweep",
    "write_variants_csv",
    "task_ranges",
    "STATUSES",
    "DISTRIBUTED_EXTRA",
]

#: A variant's outcome: every sample solved; stopped at a singular configuration (a lock-up,
#: a dead centre); stopped because Newton failed otherwise; no mechanism could be analysed
#: with its values (a `ModelError` when it was built or at its first sample).
STATUSES = ("complete", "singular", "no_convergence", "invalid")
#: What to install for sweeps, and the one line that says so.
DISTRIBUTED_EXTRA = 'sweeps need dask and distributed: pip install "sparsekin[distributed]"'
#: Tasks per worker thread when the size of a task is not given: enough for the load to
#: balance and for a lost worker to cost little, few enough that each task amortises its
#: pattern and its Dask overhead (about a millisecond) over many variants.
TASKS_PER_THREAD = 4
#: Most bytes of results one task returns (its variants' arrays together).
TASK_BYTES = 256 * 2**20
#: Most bytes of one chunk of the Zarr store.
CHUNK_BYTES = 64 * 2**20
#: Tasks submitted but not yet written, per worker thread: one running, one waiting.
PENDING_PER_THREAD = 2
#: The path forms, in words (for messages).
PATH_FORMS = "drivers[i].law.KEY, drivers.NAME.law.KEY, points.NAME[.x|.y], or units.UNIT. before one of them"

_UNIT_PATH = re.compile(r"units\.([^.]+)\.(.+)")
_PERTURB_KINDS = ("points",)


# ---------------------------------------------------------------------- the description
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


# ---------------------------------------------------------------------- bound to a mechanism
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


# ---------------------------------------------------------------------- tasks
def task_ranges(
    n_variants: int, n_threads: int, bytes_per_variant: int, variants_per_task: int | None = None
):
    """``(first, stop)`` of each task's variants.

    Without `variants_per_task`: `TASKS_PER_THREAD` tasks per worker thread, each at most
    `TASK_BYTES` of results.

    >>> task_ranges(10, 1, 1000)
    [(0, 3), (3, 6), (6, 9), (9, 10)]
    """
    if variants_per_task is None:
        variants_per_task = math.ceil(n_variants / (TASKS_PER_THREAD * max(1, n_threads)))
        variants_per_task = max(1, min(variants_per_task, TASK_BYTES // max(1, bytes_per_variant)))
    return [
        (first, min(first + variants_per_task, n_variants))
        for first in range(0, n_variants, variants_per_task)
    ]


def solve_variants(design: VariantDesign, first: int, stop: int, times: np.ndarray, options: dict) -> dict:
    """Solve variants ``first … stop - 1`` one after the other: a task's work.

    Returns a dict: ``status`` (str array), ``t_stop``, ``t_failure`` (s, NaN when not
    applicable), ``messages`` (list of str) and the recorded arrays (``q``, ``qd``,
    ``qdd``, ``points``, ``joints``), each of shape (stop - first, n_times, ...), NaN
    after a variant's last solved sample.
    """
    from ..engine.pattern import build_pattern
    from ..results.recording import Selection
    from ..solve.kinematics import solve_kinematics

    n, n_times = stop - first, times.size
    mechanism = design.mechanism
    selection = Selection(mechanism, options["coordinates"], options["points"], options["joints"], options["forces"])
    shapes = _variable_shapes(selection)
    arrays = {key: np.full((n, n_times, *shape), np.nan) for key, shape in shapes.items()}
    status = np.full(n, "", dtype=STATUS_DTYPE)
    t_stop, t_failure = np.full(n, np.nan), np.full(n, np.nan)
    messages = [""] * n
    shared = None if design.geometry_varies else build_pattern(mechanism)
    for row, k in enumerate(range(first, stop)):
        result, notes = None, []
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                variant = design.variant(k)
                result = solve_kinematics(variant, times, pattern=shared, **options)
                status[row] = "complete"
            except SingularJacobianError as error:
                status[row], result, t_failure[row] = "singular", error.result, error.time
                notes.append(str(error))
            except ConvergenceError as error:
                status[row], result, t_failure[row] = "no_convergence", error.result, error.time
                notes.append(str(error))
            except ModelError as error:
                status[row] = "invalid"
                notes.append(str(error))
        notes += [str(warning.message) for warning in caught]
        messages[row] = " | ".join(" ".join(note.split()) for note in notes)
        if result is not None and result.n_times:
            m = result.n_times
            t_stop[row] = result.times[-1]
            for key, source in (("q", result.coordinates), ("qd", result.velocities),
                                ("qdd", result.accelerations), ("points", result.point_tracks),
                                ("joints", result.joint_tracks), ("forces", result.force_tracks)):  # fmt: skip
                if key in arrays:
                    arrays[key][row, :m] = source
    return {"status": status, "t_stop": t_stop, "t_failure": t_failure, "messages": messages, **arrays}


def _variable_shapes(selection) -> dict[str, tuple[int, ...]]:
    """The shape of one sample of each recorded variable."""
    shapes = {}
    if selection.coordinates:
        n = selection.mechanism.n_coordinates
        shapes |= {"q": (n,), "qd": (n,), "qdd": (n,)}
    if selection.point_names:
        shapes["points"] = (len(selection.point_names), 6)
    if selection.joint_indices:
        shapes["joints"] = (len(selection.joint_indices), 3)
    if selection.forces is not None:
        shapes["forces"] = (selection.n_force_columns,)
    return shapes


# ---------------------------------------------------------------------- the result
@dataclass(frozen=True, eq=False)
class SweepResult:
    """What a sweep computed: each variant's values, status and recorded motion.

    Attributes
    ----------
    variants : VariantSet
    columns : tuple of str
        Labels of the columns of `parameters` (the varied numbers; ``deviation.P.x`` ...
        for a tolerance study).
    parameters : ndarray, shape (n_variants, n_columns)
    status : ndarray of str, shape (n_variants,)
        One of `STATUSES` per variant.
    t_stop : ndarray, shape (n_variants,)
        Time of each variant's last solved sample, s (NaN if none was solved).
    t_failure : ndarray, shape (n_variants,)
        For a variant that stopped: the first time it could not reach, s (the lock-up lies
        between `t_stop` and it); NaN otherwise.
    messages : tuple of str
        Why each variant stopped, and any warning (limits left); empty when none.
    times : ndarray, shape (n_times,)
        Sample times, s.
    coordinates, velocities, accelerations : array, shape (n_variants, n_times, n_coordinates) or None
        q, qd, qdd of every variant (NaN after its last solved sample): numpy arrays, or
        zarr arrays read lazily from `store`.
    point_tracks : array, shape (n_variants, n_times, n_points, 6) or None
        x, y, vx, vy, ax, ay of each recorded point, m, m/s, m/s².
    recorded_points : tuple of str
    joint_tracks : array, shape (n_variants, n_times, n_joints, 3) or None
        Each recorded joint's own coordinate, rate and acceleration.
    recorded_joints : tuple of str
        Their labels (name, else ``joints[i]``).
    force_tracks : array, shape (n_variants, n_times, n_force_columns) or None
        The forces each variant recorded (`sparsekin.engine.forces`), columns `force_labels`.
    force_labels, force_units : tuple of str
    store : str or None
        The Zarr store, when the results were written to one.
    n_tasks : int
        How many Dask tasks the variants were split into.
    wall_time : float
        Seconds from the first task submitted to the last result written.
    coordinate_labels : tuple of str
        ``c1.x``, ``c1.y``, ``c1.angle``, ...: the columns of `coordinates`.
    """

    variants: VariantSet
    columns: tuple[str, ...]
    parameters: np.ndarray
    status: np.ndarray
    t_stop: np.ndarray
    t_failure: np.ndarray
    messages: tuple[str, ...]
    times: np.ndarray
    coordinates: object = None
    velocities: object = None
    accelerations: object = None
    point_tracks: object = None
    recorded_points: tuple[str, ...] = ()
    joint_tracks: object = None
    recorded_joints: tuple[str, ...] = ()
    force_tracks: object = None
    force_labels: tuple[str, ...] = ()
    force_units: tuple[str, ...] = ()
    store: str | None = None
    n_tasks: int = 0
    wall_time: float = 0.0
    coordinate_labels: tuple[str, ...] = ()

    @property
    def n_variants(self) -> int:
        return int(self.status.size)

    @property
    def counts(self) -> dict[str, int]:
        """How many variants ended with each status."""
        return {status: int(np.count_nonzero(self.status == status)) for status in STATUSES}

    def point(self, name: str) -> np.ndarray:
        """Position of recorded point `name` for every variant, shape (n_variants, n_times, 2), m."""
        if name not in self.recorded_points:
            raise KeyError(
                f'point "{name}" was not recorded (recorded: {", ".join(self.recorded_points) or "none"})'
            )
        p = self.recorded_points.index(name)
        return np.asarray(self.point_tracks[:, :, p, :2])

    def to_xarray(self):
        """The results as an `xarray.Dataset` (the layout of the store: see `sweep`)."""
        import xarray as xr

        if self.store is not None:
            return xr.open_zarr(self.store)
        arrays = {key: np.asarray(value) for key, value in self._arrays().items()}
        labels = {}
        if self.coordinates is not None:
            labels["coordinate"] = list(self.coordinate_labels)
        if self.recorded_points:
            labels |= {"point": list(self.recorded_points), "component": list(POINT_COMPONENTS)}
        if self.recorded_joints:
            labels |= {"joint": list(self.recorded_joints), "derivative": list(JOINT_DERIVATIVES)}
        if self.force_labels:
            labels |= {"force": list(self.force_labels), "force_unit": ("force", list(self.force_units))}
        shapes = {key: array.shape[2:] for key, array in arrays.items()}
        layout = _Layout(self.n_variants, self.times, self.columns, self.parameters, shapes, labels)
        return layout.dataset(arrays, self.status, self.t_stop, self.t_failure)

    def _arrays(self) -> dict:
        pairs = (("q", self.coordinates), ("qd", self.velocities), ("qdd", self.accelerations),
                 ("points", self.point_tracks), ("joints", self.joint_tracks), ("forces", self.force_tracks))  # fmt: skip
        return {key: value for key, value in pairs if value is not None}


def write_variants_csv(result: SweepResult, path) -> Path:
    """Write ``variants.csv``: ``variant``, the columns of `result.parameters`, ``status``,
    ``t_stop``, ``t_failure`` and ``message``; numbers by `repr` (the shortest decimal
    that reads back as the same double), NaN as ``nan``."""
    path = Path(path)
    with open(path, "w", encoding="utf-8", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["variant", *result.columns, "status", "t_stop", "t_failure", "message"])
        for k in range(result.n_variants):
            writer.writerow([k, *map(repr, result.parameters[k].tolist()), result.status[k],
                             repr(float(result.t_stop[k])), repr(float(result.t_failure[k])), result.messages[k]])  # fmt: skip
    return path


# ---------------------------------------------------------------------- outputs
class _MemoryOutput:
    """Every variant's arrays in this process."""

    def __init__(self, layout: _Layout) -> None:
        self.arrays = {key: np.full((layout.n_variants, layout.times.size, *shape), np.nan)
                       for key, shape in layout.shapes.items()}  # fmt: skip
        self.path = None

    def write(self, first: int, stop: int, block: dict) -> None:
        for key, array in self.arrays.items():
            array[first:stop] = block[key]

    def close(self) -> dict:
        return self.arrays


class _ZarrOutput:
    """A Zarr store laid out in full first (metadata only), then written task by task: a
    task's variants are whole chunks, so each write replaces chunks and a task run twice
    (after a lost worker) writes the same values again."""

    def __init__(self, path, layout: _Layout, variants_per_task: int, attrs: dict) -> None:
        import dask.array as da
        import zarr

        self.path = os.fspath(path)
        lazy, encoding = {}, {}
        n_times = layout.times.size
        for key, shape in layout.shapes.items():
            inner = tuple(min(size, 2**20) for size in shape)
            per_sample = 8 * max(1, int(np.prod(inner)))
            time_chunk = int(min(n_times, max(1, CHUNK_BYTES // (variants_per_task * per_sample))))
            chunks = (variants_per_task, time_chunk, *inner)
            lazy[key] = da.full((layout.n_variants, n_times, *shape), np.nan, chunks=chunks)
            encoding[key] = {"chunks": chunks}
        n = layout.n_variants
        dataset = layout.dataset(
            lazy, np.full(n, "", dtype=STATUS_DTYPE), np.full(n, np.nan), np.full(n, np.nan)
        )
        dataset.attrs.update(attrs)
        for key in ("status", "t_stop", "t_failure"):
            encoding[key] = {"chunks": (variants_per_task,)}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            dataset.to_zarr(self.path, mode="w", compute=False, zarr_format=2, encoding=encoding)
        self.group = zarr.open_group(self.path, mode="r+", zarr_format=2)
        self.group["status"][:] = np.full(n, "", dtype=STATUS_DTYPE)  # not written with compute=False

    def write(self, first: int, stop: int, block: dict) -> None:
        for key in (*_ARRAY_KEYS, "status", "t_stop", "t_failure"):
            if key in self.group and key in block:
                self.group[key][first:stop] = block[key]

    def close(self) -> dict:
        import zarr

        group = zarr.open_group(self.path, mode="r", zarr_format=2)
        return {key: group[key] for key in _ARRAY_KEYS if key in group}


_ARRAY_KEYS = ("q", "qd", "qdd", "points", "joints", "forces")
STATUS_DTYPE = f"<U{max(map(len, STATUSES))}"
_DIMENSIONS = {"q": ("coordinate",), "qd": ("coordinate",), "qdd": ("coordinate",),
               "points": ("point", "component"), "joints": ("joint", "derivative"), "forces": ("force",)}  # fmt: skip


@dataclass(frozen=True, eq=False)
class _Layout:
    """The shape and labels of a sweep's results."""

    n_variants: int
    times: np.ndarray
    columns: tuple[str, ...]
    parameters: np.ndarray
    shapes: dict
    labels: dict

    def dataset(self, arrays: dict, status, t_stop, t_failure):
        """The sweep's `xarray.Dataset` (see `sweep`)."""
        import xarray as xr

        coords = {"variant": np.arange(self.n_variants), "t": ("time", self.times),
                  "parameter": list(self.columns), **self.labels}  # fmt: skip
        variables = {key: (("variant", "time", *_DIMENSIONS[key]), value) for key, value in arrays.items()}
        variables |= {
            "parameters": (("variant", "parameter"), self.parameters),
            "status": ("variant", status),
            "t_stop": ("variant", t_stop),
            "t_failure": ("variant", t_failure),
        }
        return xr.Dataset(variables, coords=coords)


def _layout(design: VariantDesign, times: np.ndarray, selection) -> _Layout:
    from ..model.elements import COORDINATE_NAMES
    from ..results.recording import JOINT_DERIVATIVES, POINT_COMPONENTS

    columns, parameters = design.table()
    labels = {}
    if selection.coordinates:
        labels["coordinate"] = [
            f"{name}.{c}" for name in selection.mechanism.body_names for c in COORDINATE_NAMES
        ]
    if selection.point_names:
        labels |= {"point": list(selection.point_names), "component": list(POINT_COMPONENTS)}
    if selection.joint_indices:
        labels |= {"joint": list(selection.joint_labels), "derivative": list(JOINT_DERIVATIVES)}
    if selection.forces is not None:
        labels |= {"force": list(selection.forces.labels), "force_unit": ("force", list(selection.forces.units))}
    return _Layout(design.n_variants, times, columns, parameters, _variable_shapes(selection), labels)


# ---------------------------------------------------------------------- the sweep
def sweep(
    mechanism: Mechanism,
    vary,
    times,
    client=None,
    *,
    workers: int | None = None,
    store=None,
    coordinates: bool = True,
    points=None,
    joints=None,
    forces="auto",
    quasi_static: bool = False,
    variants_per_task: int | None = None,
    tolerance: float | None = None,
    max_iterations: int | None = None,
    linear_solver: str = "auto",
    progress=None,
) -> SweepResult:
    """Solve every variant of `mechanism` that `vary` describes, on Dask.

    Each variant is an independent `sparsekin.solve_kinematics` run at `times`.  The
    variants are split into tasks of consecutive variants (`task_ranges`); the client
    writes each task's results as it arrives, into memory or into the Zarr store `store`,
    so no process holds every variant's results when there is a store.  A variant that
    locks up is a result (status ``singular``), not a failure of the sweep.

    Parameters
    ----------
    mechanism : Mechanism
        The nominal mechanism.
    vary : VariantSet or mapping
        The variants; a mapping is ``VariantSet(grid=vary)``: path (or tuple of paths
        varied together) -> values.
    times : array_like, shape (n_times,)
        Sample times of every variant, s.
    client : distributed.Client or str, optional
        The Dask client, or a scheduler's address (``"tcp://host:8786"``).  Default: a
        local cluster of `workers` processes, started here and closed at the end.
    workers : int, optional
        Worker processes of the local cluster (default: one per core).
    store : str or path-like, optional
        Write the results to this Zarr store (replaced if it exists): variables
        ``q``, ``qd``, ``qdd`` (variant, time, coordinate), ``points`` (variant, time,
        point, component), ``joints`` (variant, time, joint, derivative), and per variant
        ``parameters`` (variant, parameter), ``status``, ``t_stop``, ``t_failure``.
        Default: in memory.
    coordinates, points, joints, forces, quasi_static
        What each variant records, as in `solve_kinematics` (variable ``forces``
        (variant, time, force) in the store).
    variants_per_task : int, optional
        Variants per Dask task (default: `TASKS_PER_THREAD` tasks per worker thread).
    tolerance, max_iterations, linear_solver
        As in `solve_kinematics`.
    progress : callable, optional
        Called as ``progress(variants_done, n_variants)`` as results arrive.

    Returns
    -------
    SweepResult

    Raises
    ------
    ModelError
        For a path that names no parameter, or a value it does not take.
    ValueError
        For an argument `solve_kinematics` would refuse (times outside a spline law's
        range, an unknown point, a bad tolerance ...): raised before any task is
        submitted.  An exception raised later comes from a task that failed (not a
        variant: those are results) and stops the sweep.
    ImportError
        Without dask and distributed (``pip install "sparsekin[distributed]"``).

    Examples
    --------
    >>> import numpy as np, sparsekin as sk
    >>> task5 = sk.load_model("examples/task5.toml")
    >>> amplitudes = {("drivers[0].law.amplitude", "drivers[1].law.amplitude"): [0.05, 0.06]}
    >>> result = sk.sweep(task5, amplitudes, np.linspace(0.0, 1.0, 101), workers=1, coordinates=False,
    ...                   points=["K"])  # doctest: +SKIP
    >>> result.status.tolist(), result.t_stop.tolist()  # doctest: +SKIP
    (['complete', 'singular'], [1.0, 0.75])
    """
    try:
        import distributed
    except ImportError:
        raise ImportError(DISTRIBUTED_EXTRA) from None
    from ..engine.newton import DEFAULT_TOLERANCE, NEWTON_MAXITER
    from ..results.recording import Selection
    from ..solve.kinematics import _checked_times
    from ..solve.stepper import LINEAR_SOLVERS, checked_max_iterations, checked_tolerance

    if not isinstance(mechanism, Mechanism):
        raise TypeError(f"`mechanism` must be a Mechanism, got {type(mechanism).__name__}.")
    variants = vary if isinstance(vary, VariantSet) else VariantSet(vary)
    design = variants.bind(mechanism)
    times = _checked_times(times, mechanism)
    if progress is not None and not callable(progress):
        raise ValueError(f"`progress` must be a callable (done, total), got {progress!r}.")
    if variants_per_task is not None and (isinstance(variants_per_task, bool) or int(variants_per_task) < 1):
        raise ValueError(f"`variants_per_task` must be a whole number >= 1, got {variants_per_task!r}.")
    # every argument a task would refuse is refused here, before a cluster starts
    tolerance = checked_tolerance(DEFAULT_TOLERANCE if tolerance is None else tolerance)
    max_iterations = checked_max_iterations(NEWTON_MAXITER if max_iterations is None else max_iterations)
    if linear_solver not in LINEAR_SOLVERS:
        raise ValueError(f"`linear_solver` must be one of {', '.join(map(repr, LINEAR_SOLVERS))}, got {linear_solver!r}.")
    if not isinstance(quasi_static, (bool, np.bool_)):
        raise ValueError(f"`quasi_static` must be True or False, got {quasi_static!r}.")
    selection = Selection(mechanism, coordinates, points, joints, forces)
    chosen = selection.forces
    options = dict(coordinates=bool(coordinates), points=selection.point_names or None,
                   joints=list(selection.joint_indices) or None, linear_solver=linear_solver,
                   forces=None if chosen is None else [*(f"drivers[{d}]" for d in chosen.driver_indices),
                                                       *(f"joints[{j}]" for j in chosen.joint_indices)],
                   quasi_static=bool(quasi_static), tolerance=tolerance, max_iterations=max_iterations)  # fmt: skip
    layout = _layout(design, times, selection)
    own_cluster = None
    if client is None:
        own_cluster = _local_cluster(workers)
        client = distributed.Client(own_cluster)
    elif isinstance(client, str):
        client = own_cluster = distributed.Client(client)
    try:
        # Client.nthreads asks the scheduler for every worker (scheduler_info()["workers"]
        # lists at most five in distributed 2025.4 … 2026.6: dask/distributed#9045)
        n_threads = sum(client.nthreads().values()) or 1
        bytes_per_variant = 8 * times.size * sum(int(np.prod(shape)) for shape in layout.shapes.values())
        ranges = task_ranges(design.n_variants, n_threads, bytes_per_variant, variants_per_task)
        size = ranges[0][1] - ranges[0][0]
        attrs = {"model": mechanism.name, "grid": list(variants.paths), "samples": variants.samples,
                 "perturb_points": -1.0 if variants.perturb_points is None else variants.perturb_points,
                 "seed": str(variants.seed)}  # fmt: skip
        output = _ZarrOutput(store, layout, size, attrs) if store is not None else _MemoryOutput(layout)
        status = np.full(design.n_variants, "", dtype=STATUS_DTYPE)
        t_stop, t_failure = np.full(design.n_variants, np.nan), np.full(design.n_variants, np.nan)
        messages = [""] * design.n_variants
        start = time.perf_counter()
        for first, stop, block in _run_tasks(client, design, ranges, times, options, n_threads):
            output.write(first, stop, block)
            status[first:stop], t_stop[first:stop], t_failure[first:stop] = (block["status"], block["t_stop"],
                                                                             block["t_failure"])  # fmt: skip
            messages[first:stop] = block["messages"]
            if progress is not None:
                progress(int(np.count_nonzero(status)), design.n_variants)
        wall_time = time.perf_counter() - start
    finally:
        if own_cluster is not None:
            client.close()
            own_cluster.close()
    arrays = output.close()
    return SweepResult(
        variants=variants, columns=layout.columns, parameters=layout.parameters, status=status, t_stop=t_stop,
        t_failure=t_failure, messages=tuple(messages), times=times, coordinates=arrays.get("q"),
        velocities=arrays.get("qd"), accelerations=arrays.get("qdd"), point_tracks=arrays.get("points"),
        recorded_points=selection.point_names, joint_tracks=arrays.get("joints"),
        recorded_joints=selection.joint_labels, force_tracks=arrays.get("forces"),
        force_labels=() if chosen is None else chosen.labels, force_units=() if chosen is None else chosen.units,
        store=output.path, n_tasks=len(ranges), wall_time=wall_time,
        coordinate_labels=tuple(layout.labels.get("coordinate", ())),
    )  # fmt: skip


def default_worker_count() -> int:
    """Worker processes of a local cluster when none is given: one per core this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _local_cluster(workers: int | None):
    """A local cluster: the scheduler in this process, `workers` single-threaded worker processes."""
    import logging

    from distributed import LocalCluster

    if workers is None:
        workers = default_worker_count()
    if isinstance(workers, bool) or int(workers) < 1:
        raise ValueError(f"`workers` must be a whole number >= 1, got {workers!r}.")
    return LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True, dashboard_address=":0",
                        silence_logs=logging.ERROR)  # fmt: skip


def _run_tasks(client, design: VariantDesign, ranges, times, options, n_threads: int):
    """Submit the tasks a few at a time and yield ``(first, stop, block)`` as they finish.

    At most `PENDING_PER_THREAD` tasks per worker thread are submitted and not yet
    written: the workers' memory holds a few tasks' results, never the sweep's.  A task
    whose worker dies is run again by the scheduler on another worker.
    """
    from distributed import as_completed

    pending_limit = PENDING_PER_THREAD * n_threads + 1
    queue = list(ranges)
    queue.reverse()
    completed = as_completed()
    futures: dict = {}  # key -> (future, first, stop)
    token = f"{os.getpid():x}-{time.monotonic_ns():x}"

    def submit() -> None:
        first, stop = queue.pop()
        future = client.submit(solve_variants, design, first, stop, times, options, pure=False,
                               key=f"sparsekin-variants-{first}-{stop}-{token}")  # fmt: skip
        futures[future.key] = (future, first, stop)
        completed.add(future)

    try:
        while queue and len(futures) < pending_limit:
            submit()
        for future in completed:
            _, first, stop = futures.pop(future.key)
            block = future.result()  # a task that failed (not a variant: those are results) stops the sweep
            future.release()
            yield first, stop, block
            while queue and len(futures) < pending_limit:
                submit()
    finally:
        if futures:  # stopped early (an error, Ctrl-C): the remaining tasks are not wanted
            client.cancel([future for future, _, _ in futures.values()])
