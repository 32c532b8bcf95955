"""Per-copy values of a repeated unit: `Step` and `Cycle`, and the paths they vary.

A repeat's ``vary`` maps a path inside its unit (`sparsekin.model.paths`: a law
parameter, a point, a body's drawn angle) to a variation.  In a chain copy k takes the
unit's value + k · step, or ``values[k mod len]``; in a grid copy (i, j) takes the unit's
value + i · si + j · sj (``step = [si, sj]``), or ``values[(i + j) mod len]`` (a
checkerboard with two values).  Everything is checked here, once, against the unit, for
every copy: the largest values of a step lie at the corners of the grid.
"""

from __future__ import annotations

import dataclasses
import numbers
from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from . import _validate
from .paths import BODY_ANGLE_PATH, DRIVER_PATH, POINT_PATH
from .tiling import Tiling

__all__ = ["Step", "Cycle", "resolve_path", "checked_variation", "varied_values"]


@dataclass(frozen=True, slots=True)
class Step:
    """Copy k takes the unit's value + k · `value` (a number, or ``(dx, dy)`` for a point).

    In a grid, `value` is a pair, one step along i and one along j: ``(si, sj)``, or
    ``((dxi, dyi), (dxj, dyj))`` for a point; copy (i, j) takes value + i · si + j · sj.
    """

    value: float | tuple


@dataclass(frozen=True, slots=True)
class Cycle:
    """Copy k takes ``values[k % len(values)]``; copy (i, j) of a grid ``values[(i + j) % len(values)]``."""

    values: tuple

    def __post_init__(self) -> None:
        if isinstance(self.values, (str, bytes)) or not _validate.is_sequence(self.values) or not len(self.values):
            raise ModelError(f"expected a non-empty list of values, got {self.values!r}", element="cycle")
        object.__setattr__(self, "values", tuple(self.values))


def resolve_path(unit, path: str):
    """``("law", driver index, law field, key)``, ``("point", name)`` or ``("angle", body
    index)`` for a `vary` path of `unit`."""
    where = f'vary."{path}"'
    if not isinstance(path, str):
        raise ModelError(f"expected a path such as drivers[0].law.phase or points.M, got {path!r}", element="vary")
    match = DRIVER_PATH.fullmatch(path)
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
    match = POINT_PATH.fullmatch(path)
    if match:
        if match[1] not in unit.points:
            raise ModelError(f'unit "{unit.name}" has no point "{match[1]}"', element=where)
        return ("point", match[1])
    match = BODY_ANGLE_PATH.fullmatch(path)
    if match:
        names = [body.name for body in unit.bodies]
        if match[1] not in names:
            raise ModelError(f'unit "{unit.name}" has no body "{match[1]}"', element=where)
        return ("angle", names.index(match[1]))
    raise ModelError("expected drivers[i].law.KEY, drivers.NAME.law.KEY, points.NAME or bodies.NAME.angle",
                     element=where)  # fmt: skip


def base_value(unit, target: tuple):
    """The unit's own value at `target` (`resolve_path`): a number, a point, or None (a law
    parameter left at its default)."""
    if target[0] == "point":
        return unit.points[target[1]]
    if target[0] == "angle":
        return unit.bodies[target[1]].angle
    _, driver, law_field, key = target
    return getattr(getattr(unit.drivers[driver], law_field), key)


def checked_variation(unit, target: tuple, variation: Step | Cycle, tiling: Tiling) -> Step | Cycle:
    """`variation` of `target` (`resolve_path`), checked for every copy of `tiling` and in
    its canonical form (floats; ``(x, y)`` pairs for a point)."""
    is_point = target[0] == "point"
    if isinstance(variation, Cycle):
        if is_point:
            return Cycle(_pairs(variation.values, "cycle"))
        return Cycle(tuple(_validate.finite_float(value, f"cycle[{n}]") for n, value in enumerate(variation.values)))
    base = base_value(unit, target)
    if base is None:
        raise ModelError(f"cannot step a parameter left at its default: give {target[-1]} in the unit, or use a cycle")
    one = _validate.pair if is_point else _validate.finite_float
    if tiling.is_grid:
        value = variation.value
        if isinstance(value, (str, bytes)) or not _validate.is_sequence(value) or len(value) != 2 or (
                is_point and not all(_validate.is_sequence(v) for v in value)):  # fmt: skip
            form = "[[dxi, dyi], [dxj, dyj]]" if is_point else "[si, sj]"
            raise ModelError(f"a grid's step is {form}, one step along i and one along j; got {value!r}",
                             element="step")  # fmt: skip
        step = (one(value[0], "step[0]"), one(value[1], "step[1]"))
    else:
        step = one(variation.value, "step")
    _check_stepped(np.array(base, dtype=float).reshape(-1), _step_rows(step, tiling), tiling)
    return Step(step)


def varied_values(variation: Step | Cycle, base, tiling: Tiling, ks=None) -> np.ndarray:
    """The value of copies `ks` (default every copy; shape (len(ks),), or (len(ks), 2) for a
    point), before the copy's translation; `variation` checked by `checked_variation`."""
    i, j = tiling.columns_rows(np.arange(tiling.count) if ks is None else np.asarray(ks))
    if isinstance(variation, Cycle):
        values = np.array(variation.values, dtype=float)
        return values[(i + j) % len(values)]
    base = np.asarray(base, dtype=float)
    rows = _step_rows(variation.value, tiling)
    if base.ndim == 0:
        return base + i * rows[0, 0] + j * rows[1, 0]
    return base + i[:, None] * rows[0] + j[:, None] * rows[1]


def _step_rows(step, tiling: Tiling) -> np.ndarray:
    """A step as two rows, the step along i and along j (zeros for a chain): shape (2, d)."""
    if tiling.is_grid:
        return np.array([np.reshape(step[0], -1), np.reshape(step[1], -1)], dtype=float)
    row = np.reshape(np.asarray(step, dtype=float), -1)
    return np.stack([row, np.zeros_like(row)])


def _pairs(values: tuple, element: str) -> tuple:
    """`values` as a tuple of ``(x, y)`` pairs of finite numbers of sensible magnitude."""
    if all(type(v) is tuple and len(v) == 2 and type(v[0]) is float and type(v[1]) is float for v in values):
        array = np.array(values)  # the common case (a file's, a sweep's long cycles): checked at once
        if np.all(np.abs(array) <= _validate.MAX_MAGNITUDE):  # False for NaN
            return values
    return tuple(_validate.pair(value, f"{element}[{n}]") for n, value in enumerate(values))


def _check_stepped(base: np.ndarray, rows: np.ndarray, tiling: Tiling) -> None:
    """Refuse a step that takes a copy's value beyond `_validate.MAX_MAGNITUDE`, naming the
    first such copy.  |base + i · si + j · sj| is largest at a corner of the grid: four tests."""
    def good(values):
        return np.isfinite(values) & (np.abs(values) <= _validate.MAX_MAGNITUDE)

    corners = [(i, j) for i in (0, tiling.ni - 1) for j in (0, tiling.nj - 1)]
    if all(good(base + i * rows[0] + j * rows[1]).all() for i, j in corners):
        return
    i, j = tiling.columns_rows(np.arange(tiling.count))
    values = base[None] + i[:, None] * rows[0] + j[:, None] * rows[1]
    k = int(np.flatnonzero(~good(values).all(axis=1))[0])
    shown = ", ".join(f"{v:.6g}" for v in values[k])
    raise ModelError(f"{tiling.label(k)} takes {shown}: the varied value must be a finite number of magnitude at most "
                     f"{_validate.MAX_MAGNITUDE:g}")  # fmt: skip
