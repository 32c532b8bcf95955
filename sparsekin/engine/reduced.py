"""Square systems cut out of an assembler: redundant equations left out, free coordinates held.

A model with redundant but consistent equations is solved without them; a model with
free motions is assembled (by `sparsekin.analysis.check`) with one coordinate of each free motion
held at its drawn value.  `ReducedSystem` presents either as a system of its own —
``fill_residual_jacobian``, ``residual``, ``jacobian``, ``velocity_rhs``,
``acceleration_rhs`` — that `sparsekin.engine.newton` and the linear solvers take like an
`Assembler`.  The CSR pattern of its rows and the positions of their values in the
assembler's Jacobian are computed once; each refill is one gather, not a new matrix —
or no gather at all once a refactorization fixes its value order (`fill_in_order`): the
assembler then writes the kept rows' values straight in the factor's order, the left-out
rows' values after them.
"""

from __future__ import annotations

import numpy as np

from .assembly import Assembler

__all__ = ["ReducedSystem", "CONSISTENCY_TOLERANCE", "kept_equations"]

#: A redundant equation left out is consistent while its residual stays below this
#: (lengths relative to the model size, angles in rad).
CONSISTENCY_TOLERANCE = 1e-9


def kept_equations(n_equations: int, redundant: np.ndarray) -> np.ndarray:
    """The equations ``0 .. n_equations - 1`` but the `redundant` ones, ascending (int64): what
    ``np.setdiff1d`` gives, through a mask (numpy 2's setdiff1d hashes: 3.4 s at 3·10^6 rows)."""
    keep = np.ones(n_equations, dtype=bool)
    keep[redundant] = False
    return np.flatnonzero(keep).astype(np.int64, copy=False)


class ReducedSystem:
    """The rows `rows` of an assembler's system, then one row per held coordinate.

    Parameters
    ----------
    assembler : Assembler
    rows : ndarray of int
        The equations kept, in order.
    held : ndarray of int, optional
        Coordinates held: row ``len(rows) + k`` reads ``q[held[k]] - held_values[k] = 0``.
    held_values : ndarray, optional
        Their values (m, rad).

    Attributes
    ----------
    residual, velocity_rhs, acceleration_rhs : ndarray, shape (n_rows,)
    jacobian : csr_array, shape (n_rows, n_coordinates)
    values : ndarray
        The Jacobian's values: ``jacobian.data``, or after `fill_in_order` the same values
        in the order given there (then a view of the assembler's values).
    weights : ndarray, shape (n_rows,)
        The assembler's weights of the kept rows; those of the held rows weigh
        coordinates like `ConstraintPattern.coordinate_weights`.
    """

    def __init__(self, assembler: Assembler, rows: np.ndarray, held=None, held_values=None) -> None:
        self.assembler = assembler
        self.rows = np.asarray(rows, dtype=np.int64)
        self.held = np.zeros(0, dtype=np.int64) if held is None else np.asarray(held, dtype=np.int64)
        self.held_values = np.zeros(0) if held_values is None else np.asarray(held_values, dtype=float)
        from scipy.sparse import csr_array  # here: only a model with redundant equations needs it

        full = assembler.jacobian
        n_kept, n_held = self.rows.size, self.held.size
        starts, ends = full.indptr[self.rows], full.indptr[self.rows + 1]
        lengths = (ends - starts).astype(np.int64)
        kept_indptr = np.zeros(n_kept + 1, dtype=np.int64)
        np.cumsum(lengths, out=kept_indptr[1:])
        n_kept_values = int(kept_indptr[-1])
        #: Positions in the assembler's Jacobian values of the kept rows' values, in order.
        self._entries = np.repeat(starts - kept_indptr[:-1], lengths) + np.arange(n_kept_values)
        indptr = np.concatenate([kept_indptr, n_kept_values + np.arange(1, n_held + 1)])
        indices = np.concatenate([full.indices[self._entries], self.held])
        values = np.zeros(n_kept_values + n_held)
        values[n_kept_values:] = 1.0
        self._csr = csr_array((values, indices, indptr), shape=(n_kept + n_held, full.shape[1]))
        self.values = self._csr.data
        self._csr_position = None  # where each CSR value is in `values`, after fill_in_order
        n_rows = n_kept + n_held
        self.residual = np.zeros(n_rows)
        self.velocity_rhs = np.zeros(n_rows)
        self.acceleration_rhs = np.zeros(n_rows)
        self.weights = np.concatenate([assembler.weights[self.rows], assembler.pattern.coordinate_weights[self.held]])

    @property
    def orderable(self) -> bool:
        """Whether the assembler can fill this system's values in a solver's order: not with
        held coordinates, whose rows the assembler does not have."""
        return not self.held.size

    @property
    def jacobian(self):
        """The reduced Jacobian as a CSR array (after `fill_in_order`, a copy in CSR order)."""
        if self._csr_position is None:
            return self._csr
        from scipy.sparse import csr_array

        return csr_array((self.values[self._csr_position], self._csr.indices, self._csr.indptr), shape=self._csr.shape)

    def fill_in_order(self, positions: np.ndarray | None) -> None:
        """Have the assembler write the k-th CSR value of this Jacobian to
        ``values[positions[k]]`` (``None``: back to the CSR order), as `Assembler.fill_in_order`.

        The kept rows' values take the first places of the assembler's values, in the given
        order, and `values` becomes a view of them: a refill needs no gather.
        """
        if not self.orderable:
            raise ValueError("a reduced system with held coordinates fills in CSR order only")
        assembler, n = self.assembler, self._entries.size
        current = self.jacobian.data.copy()
        if positions is None:
            assembler.fill_in_order(None)
            self.values = self._csr.data
            self._csr_position = None
            self.values[:] = current
            return
        positions = np.asarray(positions, dtype=np.int64)
        if positions.shape != (n,):
            raise ValueError(f"`positions` must be a permutation of range({n}).")
        full = np.empty(assembler.pattern.nnz, dtype=np.int64)
        left_out = np.ones(full.size, dtype=bool)
        left_out[self._entries] = False
        full[self._entries] = positions
        full[left_out] = n + np.arange(full.size - n)
        assembler.fill_in_order(full)  # checks that `positions` is a permutation
        self.values = assembler.values[:n]
        self._csr_position = positions
        self.values[positions] = current

    def set_time(self, t: float) -> None:
        self.assembler.set_time(t)
        np.take(self.assembler.velocity_rhs, self.rows, out=self.velocity_rhs[: self.rows.size])

    def fill_residual_jacobian(self, coordinates: np.ndarray) -> float:
        """Refill the residual and the Jacobian values; returns the weighted residual norm."""
        self.assembler.fill_residual_jacobian(coordinates)
        n_kept = self.rows.size
        np.take(self.assembler.residual, self.rows, out=self.residual[:n_kept])
        np.subtract(coordinates[self.held], self.held_values, out=self.residual[n_kept:])
        if self._csr_position is None:
            np.take(self.assembler.values, self._entries, out=self.values[: self._entries.size])
        weighted = np.abs(self.residual) * self.weights
        return float(np.max(weighted, initial=0.0)) if np.all(np.isfinite(weighted)) else float("nan")

    def fill_acceleration_rhs(self, coordinates: np.ndarray, velocities: np.ndarray) -> None:
        self.assembler.fill_acceleration_rhs(coordinates, velocities)
        np.take(self.assembler.acceleration_rhs, self.rows, out=self.acceleration_rhs[: self.rows.size])
