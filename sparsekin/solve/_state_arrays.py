"""The arrays of the forward-dynamics stepper's states, used again once no one holds them.

A step of `sparsekin.solve.dynamics.GeneralizedAlphaStepper` makes a new state: q, q̇, q̈,
ã, λ and Newton's q̈ and λ, seven arrays of the model's size.  Made new at every step, they
were freed two steps later; at 10^6 bodies they are 24 MB each, under glibc's grown mmap
threshold, so they came from its heap and fragmented it (the peak crept up 36 MB in 700
steps, and the new factors of a flat crossing found no room among them).  Here a step
takes the arrays of the states the stepper has let go of (`StateArrays.retire`), and only
those that nothing else holds, by their reference count: a state, an array or a view of one
that a caller keeps (a recorder, a `Linearization`) is never written again.
"""

from __future__ import annotations

import sys

import numpy as np

__all__ = ["StateArrays"]


def _references(array: np.ndarray) -> int:
    return sys.getrefcount(array)


def _unshared_count() -> int:
    """`_references` of an array that one local variable of its caller holds and nothing
    else (the count depends on the Python version: measured the way `StateArrays.take`
    asks)."""
    array = np.empty(1)
    return _references(array)


_UNSHARED = _unshared_count()


class StateArrays:
    """The stepper's private pool of float64 arrays, handed out only as a new state's.

    A step calls `step_begins`, takes its arrays (`take`, `copy_of`), and once it has
    succeeded, `retire`: the arrays of what the stepper let go of become spare.  The arrays
    a step took and did not retire (it failed) are spare again when the next one begins.
    """

    def __init__(self) -> None:
        self.n_made = 0  # arrays made new (`take` found no spare one)
        self._spare: dict[int, list[np.ndarray]] = {}
        self._lent: list[np.ndarray] = []  # taken since the last `retire`

    def step_begins(self, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A step begins: the arrays a failed one took are spare again; the new step's q,
        q̇ and q̈ (`take`)."""
        for array in self._lent:
            self._spare.setdefault(array.size, []).append(array)
        self._lent.clear()
        return self.take(size), self.take(size), self.take(size)

    def take(self, size: int) -> np.ndarray:
        """An array of `size` float64 values, undefined: a spare one that nothing but this
        pool holds, else a new one."""
        spare = self._spare.get(size)
        array = None
        while spare:
            candidate = spare.pop()
            if _references(candidate) == _UNSHARED:
                array = candidate
                break
            del candidate  # someone else holds it: it is theirs (freed when they let go)
        if array is None:
            array = np.empty(size)
            self.n_made += 1
        self._lent.append(array)
        return array

    def copy_of(self, values: np.ndarray) -> np.ndarray:
        """`take` with a copy of `values` (1-d float64)."""
        array = self.take(values.size)
        array[:] = values
        return array

    def retire(self, left, kept) -> None:
        """The step succeeded: the arrays in the tuples `left` (the states and the like the
        stepper let go of; None entries skipped) become spare, but those in the tuples
        `kept` (the new state, what the stepper still holds)."""
        seen = {id(item) for held in kept if held is not None for item in held if isinstance(item, np.ndarray)}
        for held in left:
            for item in held or ():
                if isinstance(item, np.ndarray) and id(item) not in seen:
                    seen.add(id(item))
                    if item.dtype == np.float64 and item.ndim == 1 and item.flags.owndata:
                        self._spare.setdefault(item.size, []).append(item)
        self._lent.clear()
