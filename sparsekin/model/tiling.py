"""Where a repeat's copies lie: a chain of ``count`` copies or a grid of ``ni × nj``.

`Tiling` answers by index arithmetic, without an object per copy: copy k's expanded names
(``PREFIX{k}.NAME`` in a chain, ``PREFIX{i}_{j}.NAME`` in a grid, copy k = i + ni·j: row
by row), the copy a neighbour reference means (``prev.NAME`` in a chain: copy k − 1;
``left.NAME``: copy (i − 1, j); ``below.NAME``: copy (i, j − 1)), and which copies an
`OnCopies` restriction keeps.  A chain is tiled as a grid of one row, so one arithmetic
serves both.

>>> grid = Tiling("s", (3, 2))
>>> grid.name(4, "sq"), grid.split("s2_1.sq"), grid.label(5)
('s1_1.sq', (5, 'sq'), 'copy (2, 1)')
>>> grid.neighbour(np.arange(6), LEFT).tolist(), grid.neighbour(np.arange(6), BELOW).tolist()
([-1, 0, 1, -1, 3, 4], [-1, -1, -1, 0, 1, 2])
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from ..errors import ModelError

__all__ = ["Tiling", "OnCopies", "PREV", "LEFT", "BELOW", "NEIGHBOURS", "neighbour_prefix"]

#: A chain unit's name for body NAME of the copy before: ``prev.NAME``.
PREV = "prev."
#: A grid unit's names for body NAME of copy (i − 1, j) and of copy (i, j − 1).
LEFT = "left."
BELOW = "below."
NEIGHBOURS = (PREV, LEFT, BELOW)


def neighbour_prefix(reference: str) -> str | None:
    """``"prev."``, ``"left."`` or ``"below."`` if `reference` names a neighbour's body, else None."""
    for prefix in NEIGHBOURS:
        if reference.startswith(prefix):
            return prefix
    return None


def _copy_range(value, element: str) -> tuple[int, int] | None:
    """An `OnCopies` bound: an integer or an inclusive range ``[first, last]``, as a pair."""
    if value is None:
        return None
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return (int(value), int(value))
    if (isinstance(value, (tuple, list)) and len(value) == 2
            and all(isinstance(v, numbers.Integral) and not isinstance(v, bool) for v in value)):  # fmt: skip
        return (int(value[0]), int(value[1]))
    raise ModelError(f"expected a column or row number or a range [first, last] of them, got {value!r}", element=element)


@dataclass(frozen=True, slots=True)
class OnCopies:
    """A unit's body, joint, driver or load that exists only in some copies of a grid.

    Parameters
    ----------
    element : Body or element
        The unit's element.
    i, j : int or (first, last), optional
        The columns and rows that keep it: one number or an inclusive range; negative
        numbers count from the end (-1 is the last column or row).  None: all of them.
        In a chain, ``i`` counts the copies and ``j`` is not given.
    """

    element: object
    i: int | tuple[int, int] | None = None
    j: int | tuple[int, int] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "i", _copy_range(self.i, "copies.i"))
        object.__setattr__(self, "j", _copy_range(self.j, "copies.j"))
        if self.i is None and self.j is None:
            raise ModelError("expected i = … or j = … (the columns or rows that keep the element)", element="copies")


class Tiling:
    """The copies of a repeat: their names, positions in the grid and neighbours.

    Parameters
    ----------
    prefix : str
    shape : (count,) or (ni, nj)
        A chain or a grid.
    """

    def __init__(self, prefix: str, shape: tuple[int, ...]) -> None:
        self.prefix, self.shape = prefix, tuple(shape)
        self.is_grid = len(self.shape) == 2
        self.ni, self.nj = self.shape if self.is_grid else (self.shape[0], 1)
        self.count = self.ni * self.nj

    # ------------------------------------------------------------------ names
    def name(self, k: int, local: str) -> str:
        """The expanded name of the unit's `local` name in copy k."""
        if self.is_grid:
            j, i = divmod(k, self.ni)
            return f"{self.prefix}{i}_{j}.{local}"
        return f"{self.prefix}{k}.{local}"

    def split(self, name: str) -> tuple[int, str] | None:
        """``(k, local)`` if `name` is a copy's expanded name, else None."""
        if not name.startswith(self.prefix):
            return None
        digits, dot, local = name[len(self.prefix) :].partition(".")
        if not dot:
            return None
        numbers_ = digits.split("_") if self.is_grid else [digits]
        if len(numbers_) != len(self.shape):
            return None
        for text, size in zip(numbers_, self.shape):
            if not text.isdigit() or (len(text) > 1 and text[0] == "0") or int(text) >= size:
                return None
        return (int(numbers_[0]) + self.ni * int(numbers_[1]) if self.is_grid else int(digits)), local

    def label(self, k: int) -> str:
        """``copy 17`` or ``copy (3, 7)``, for messages."""
        if self.is_grid:
            j, i = divmod(k, self.ni)
            return f"copy ({i}, {j})"
        return f"copy {k}"

    # ------------------------------------------------------------------ arithmetic
    def columns_rows(self, ks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Column i and row j of copies `ks` (a chain: i = k, j = 0)."""
        return ks % self.ni, ks // self.ni

    def neighbour(self, ks: np.ndarray, prefix: str) -> np.ndarray:
        """The copy that `prefix` (``prev.``, ``left.``, ``below.``) means for copies `ks`; -1 outside."""
        i, j = self.columns_rows(ks)
        if prefix == BELOW:
            return np.where(j > 0, ks - self.ni, -1)
        return np.where(i > 0, ks - 1, -1)  # prev. in a chain, left. in a grid

    def kept(self, restriction: tuple | None) -> np.ndarray | None:
        """Which copies an `OnCopies` ``(i, j)`` restriction keeps (bool, shape (count,)); None: all."""
        if restriction is None:
            return None
        i, j = self.columns_rows(np.arange(self.count))
        keep = np.ones(self.count, dtype=bool)
        for bound, index, size in zip(restriction, (i, j), (self.ni, self.nj)):
            if bound is not None:
                first, last = (b + size if b < 0 else b for b in bound)
                keep &= (index >= first) & (index <= last)
        return keep

    def check_restriction(self, restriction: tuple, element: str) -> None:
        """Refuse an `OnCopies` bound beyond the grid (or an empty range)."""
        for axis, bound, size in zip("ij", restriction, (self.ni, self.nj)):
            if bound is None:
                continue
            one, many = ("copy", "copies") if not self.is_grid else (("column", "columns") if axis == "i" else ("row", "rows"))
            if axis == "j" and not self.is_grid:
                raise ModelError("a chain's copies are counted by i alone; j applies to grids", element=f"{element}.copies.j")
            first, last = (b + size if b < 0 else b for b in bound)
            if not (0 <= first < size and 0 <= last < size):
                raise ModelError(f"{list(bound) if bound[0] != bound[1] else bound[0]} is beyond the repeat's {size} "
                                 f"{many if size > 1 else one} (0 … {size - 1}, or -{size} … -1 from the end)",
                                 element=f"{element}.copies.{axis}")  # fmt: skip
            if first > last:
                raise ModelError(f"the range {list(bound)} keeps no {one}", element=f"{element}.copies.{axis}")

    def corners_and_period(self, period: int) -> list[int]:
        """The copies a check builds as objects: the first `period` copies and the last
        along each axis, in the first two and the last column and row (a cross, not every
        combination: a grid's copies differ by their column, by their row, or by i + j)."""
        along = [sorted({*range(min(period, size)), size - 1}) for size in (self.ni, self.nj)]
        edges = [sorted({*range(min(2, size)), size - 1}) for size in (self.ni, self.nj)]
        cross = {(i, j) for i in along[0] for j in edges[1]} | {(i, j) for i in edges[0] for j in along[1]}
        return sorted(i + self.ni * j for i, j in cross)
