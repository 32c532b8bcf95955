"""Joints' and drivers' own coordinates (a stroke, a relative angle) from the output
pattern, and the elements' limits checked against them."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..model.mechanism import Mechanism
from . import _kernels
from .pattern import OutputPattern, limited_elements

__all__ = ["LimitState", "own_coordinates", "limit_states", "element_index"]


class LimitState(NamedTuple):
    """An element with ``limits`` and its own coordinate: at a time, or the first time outside.

    ``label`` names the element (``joints[3] "boom" (translational …)``), ``quantity`` its
    coordinate (``stroke``), ``unit`` "m" or "rad".
    """

    label: str
    quantity: str
    unit: str
    value: float
    limits: tuple[float, float]
    time: float
    within: bool

    def __str__(self) -> str:
        low, high = self.limits
        where = "within" if self.within else "outside"
        return (f"{self.label}: {self.quantity} {self.value:.6g} {self.unit} at t = {self.time:.6g} s, {where} its "
                f"limits [{low:g}, {high:g}]")  # fmt: skip


def own_coordinates(outputs: OutputPattern, coordinates, velocities, accelerations):
    """The own coordinates of `outputs` at every sample, and their rates and accelerations.

    Parameters
    ----------
    outputs : OutputPattern
    coordinates, velocities, accelerations : ndarray, shape (n_times, n_coordinates)

    Returns
    -------
    value, rate, acceleration : ndarray, shape (n_times, outputs.n_rows)
    """
    shape = (coordinates.shape[0], outputs.n_rows)
    value, rate, acceleration = np.empty(shape), np.empty(shape), np.empty(shape)
    if outputs.n_rows and shape[0]:
        _kernels.fill_outputs(
            outputs.primitives, outputs.indptr.astype(np.int64), outputs.indices.astype(np.int64),
            np.ascontiguousarray(coordinates, dtype=float), np.ascontiguousarray(velocities, dtype=float),
            np.ascontiguousarray(accelerations, dtype=float), value, rate, acceleration,
        )  # fmt: skip
    return value, rate, acceleration


def limit_states(mechanism: Mechanism, outputs: OutputPattern, values: np.ndarray, times) -> list[LimitState]:
    """Each element with ``limits``: its coordinate at the first sample outside them, or at
    the last sample if it stays within.  `values` are the own coordinates (n_times, n_rows)."""
    states = []
    limited = limited_elements(mechanism)
    for kind, rows in (("joints", outputs.row_of_joint), ("drivers", outputs.row_of_driver)):
        for index in limited[kind]:
            element = getattr(mechanism, kind)[index]
            limits = element.limits
            if rows[index] < 0:
                continue
            row = int(rows[index])
            column = values[:, row]
            outside = np.flatnonzero((column < limits[0]) | (column > limits[1]))
            sample = int(outside[0]) if outside.size else column.size - 1
            quantity = type(element).output_names[0] if kind == "joints" else element.type_name
            states.append(LimitState(
                mechanism.element_label(kind, index), quantity, "rad" if outputs.row_is_angle[row] else "m",
                float(column[sample]), limits, float(times[sample]), not outside.size,
            ))  # fmt: skip
    return states


def element_index(mechanism: Mechanism, kind: str, name: str | int) -> int:
    """The index of the joint or driver (`kind`) called `name`, labelled ``kind[i]``, or i."""
    elements = getattr(mechanism, kind)
    if isinstance(name, (int, np.integer)) and not isinstance(name, bool):
        if 0 <= name < len(elements):
            return int(name)
        raise KeyError(f"{kind}[{name}] does not exist: the model has {len(elements)} {kind}")
    if not isinstance(name, str):  # e.g. 1.5: one line, not an AttributeError further on
        raise KeyError(f"expected a {kind[:-1]}'s name, {kind}[i] or the index i, got {name!r}")
    try:
        return mechanism.index_of(kind, name)
    except KeyError:
        pass
    if name.startswith(f"{kind}[") and name.endswith("]") and name[len(kind) + 1 : -1].isdigit():
        index = int(name[len(kind) + 1 : -1])
        if index < len(elements):
            return index
    named = [element.name for element in mechanism.declared(kind) if element.name]
    if mechanism.copies:
        named = [*(e.name for e in mechanism.own(kind) if e.name), *(
            c.name(0, e.name) + " …" for c in mechanism.copies for e in getattr(c.unit, kind) if e.name)]
    raise KeyError(
        f'unknown {kind[:-1]} "{name}": expected a name ({", ".join(named) or "none given"}) or '
        f"{kind}[i] with i < {len(elements)}"
    )
