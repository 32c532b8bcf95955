"""Elements as columns: what the equation builders of `sparsekin.model.elements` read.

A builder sees the elements of one kind as arrays, one entry per element: the stored index
of each body they name, the drawn position of each point, their numbers and vectors, and
the first row of each.  Two sources give those arrays:

* `ObjectColumns` — a list of element objects (a model's own elements): one comprehension
  per field;
* `TiledColumns` — a unit's elements over every copy of a repeat: the unit's few objects
  are read once, and index arithmetic (`sparsekin.model.units.Copies`) gives every copy's
  entries, copy-major, without an object per copy.

Both resolve names through a `Resolver` of the mechanism: its body names (the ground is
``resolver.ground``, stored after the bodies), its point names, and its joints by name.
"""

from __future__ import annotations

import numpy as np

from ..model.elements import GROUND

__all__ = ["Resolver", "ObjectColumns", "TiledColumns"]


class Resolver:
    """Body indices, drawn positions and frames of a mechanism, for its columns.

    Attributes
    ----------
    ground : int
        The stored index of the ground: the number of bodies.
    frames : ndarray, shape (n_bodies + 1, 3)
        Drawn frames of the bodies, the ground last (zeros).
    """

    def __init__(self, mechanism) -> None:
        self.mechanism = mechanism
        self.ground = mechanism.n_bodies
        self.frames = np.zeros((self.ground + 1, 3))
        self.frames[:-1] = mechanism.frames()

    def bodies(self, names) -> np.ndarray:
        index = self.mechanism.body_indices(names)
        index[index < 0] = self.ground
        return index

    def body(self, name: str) -> int:
        return self.ground if name == GROUND else self.mechanism.body_index(name)

    def points(self, references) -> np.ndarray:
        return self.mechanism.positions(references)

    def joint(self, name: str):
        return self.mechanism.joint_named(name)


class ObjectColumns:
    """Columns of a list of element objects, all of one kind.

    Parameters
    ----------
    elements : sequence
    rows : ndarray of int, shape (len(elements),)
        The first row of each element.
    resolver : Resolver
    """

    def __init__(self, elements, rows: np.ndarray, resolver: Resolver) -> None:
        self.elements, self.rows, self.resolver = list(elements), np.asarray(rows, dtype=np.int64), resolver
        self.ground, self.frames = resolver.ground, resolver.frames

    def pair(self, field: str = "bodies") -> tuple[np.ndarray, np.ndarray]:
        both = self.resolver.bodies([name for element in self.elements for name in getattr(element, field)])
        both = both.reshape(-1, 2)
        return both[:, 0].copy(), both[:, 1].copy()

    def body(self, field: str) -> np.ndarray:
        return self.resolver.bodies([getattr(element, field) for element in self.elements])

    def point(self, field: str, item: int | None = None) -> np.ndarray:
        references = [getattr(element, field) for element in self.elements]
        if item is not None:
            references = [None if reference is None else reference[item] for reference in references]
        out = np.full((len(references), 2), np.nan)
        given = [k for k, reference in enumerate(references) if reference is not None]
        if given:
            out[given] = self.resolver.points([references[k] for k in given])
        return out

    def number(self, field: str) -> np.ndarray:
        return np.array([getattr(element, field) for element in self.elements], dtype=float)

    def vector(self, field: str) -> np.ndarray:
        values = [getattr(element, field) for element in self.elements]
        return np.array([(np.nan, np.nan) if value is None else value for value in values], dtype=float).reshape(-1, 2)

    def given(self, field: str) -> np.ndarray:
        return np.array([getattr(element, field) is not None for element in self.elements], dtype=bool)

    def choice(self, field: str, choices) -> np.ndarray:
        return np.array([choices.index(getattr(element, field)) for element in self.elements], dtype=np.int64)

    def joints(self, field: str) -> ObjectColumns:
        named = [self.resolver.joint(getattr(element, field)) for element in self.elements]
        return ObjectColumns(named, self.rows, self.resolver)


class TiledColumns:
    """Columns of a unit's elements of one kind over the copies of a repeat, copy-major.

    Parameters
    ----------
    copies : Copies
    elements : sequence
        The unit's elements of one kind.
    rows : ndarray of int, shape (len(ks) · len(elements),)
        The first row of each copy's element, copy-major.
    resolver : Resolver
    ks : ndarray of int, optional
        The copies that have these elements (a grid leaves some out at its boundaries);
        default all.
    """

    def __init__(self, copies, elements, rows: np.ndarray, resolver: Resolver, ks=None) -> None:
        self.copies, self.elements, self.rows, self.resolver = copies, list(elements), rows, resolver
        self.ks = np.arange(copies.count, dtype=np.int64) if ks is None else ks
        self.ground, self.frames = resolver.ground, resolver.frames
        self._unit = ObjectColumns(self.elements, np.zeros(len(self.elements), dtype=np.int64), resolver)

    def _bodies(self, references) -> np.ndarray:
        return self.copies.body_columns(references, self.resolver.body, self.ks).ravel()

    def pair(self, field: str = "bodies") -> tuple[np.ndarray, np.ndarray]:
        return (self._bodies([getattr(element, field)[0] for element in self.elements]),
                self._bodies([getattr(element, field)[1] for element in self.elements]))  # fmt: skip

    def body(self, field: str) -> np.ndarray:
        return self._bodies([getattr(element, field) for element in self.elements])

    def point(self, field: str, item: int | None = None) -> np.ndarray:
        references = [getattr(element, field) for element in self.elements]
        if item is not None:
            references = [None if reference is None else reference[item] for reference in references]
        given = [k for k, reference in enumerate(references) if reference is not None]
        out = np.full((len(self.ks), len(references), 2), np.nan)
        if given:
            out[:, given] = self.copies.reference_positions([references[k] for k in given], self.ks)
        return out.reshape(-1, 2)

    def _tiled(self, unit_values: np.ndarray) -> np.ndarray:
        return np.tile(unit_values, (len(self.ks),) + (1,) * (unit_values.ndim - 1))

    def number(self, field: str) -> np.ndarray:
        return self._tiled(self._unit.number(field))

    def vector(self, field: str) -> np.ndarray:
        return self._tiled(self._unit.vector(field))

    def given(self, field: str) -> np.ndarray:
        return self._tiled(self._unit.given(field))

    def choice(self, field: str, choices) -> np.ndarray:
        return self._tiled(self._unit.choice(field, choices))

    def joints(self, field: str) -> TiledColumns | ObjectColumns:
        names = [getattr(element, field) for element in self.elements]
        unit_joints = self.copies.joint_index
        if all(name in unit_joints for name in names):  # the copy's own joints
            return TiledColumns(self.copies, [self.copies.unit.joints[unit_joints[name]] for name in names],
                                self.rows, self.resolver, self.ks)  # fmt: skip
        # a joint of the model: the same object in every copy
        named = [self.resolver.joint(self.copies.joint_name(k, name)) for k in self.ks.tolist() for name in names]
        return ObjectColumns(named, self.rows, self.resolver)
