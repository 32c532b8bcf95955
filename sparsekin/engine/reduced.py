"""Square systems cut out of an assembler: redundant equations left out, free coordinates held.

A model with redundant but consistent equations is solved without them; a model with
free motions is assembled (by `sparsekin.analysis.check`) with one coordinate of each free motion
held at its drawn value.  `ReducedSystem` presents either as a system of its own —
``fill_residual_jacobian``, ``residual``, ``jacobian``, ``velocity_rhs``,
``acceleration_rhs`` — that `sparsekin.engine.newton` and the linear solvers take like an
`Assembler`.  The CSR pattern of its rows and the positions of their values in the
assembler's Jacobian are computed once; each refill is one gather, not a new matrix.
"""

from __future__ import annotations

import numpy as np

from .assembly import Assembler

__all__ = ["ReducedSystem", "CONSISTENCY_TOLERANCE"]

#: A redundant equation left out is consistent while its residual stays below this
#: (lengths relative to the model size, angles in rad).
CONSISTENCY_TOLERANCE = 1e-9


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
        ``jacobian.data``.
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
        self.jacobian = csr_array((values, indices, indptr), shape=(n_kept + n_held, full.shape[1]))
        self.values = self.jacobian.data
        n_rows = n_kept + n_held
        self.residual = np.zeros(n_rows)
        self.velocity_rhs = np.zeros(n_rows)
        self.acceleration_rhs = np.zeros(n_rows)
        self.weights = np.concatenate([assembler.weights[self.rows], assembler.pattern.coordinate_weights[self.held]])

    def set_time(self, t: float) -> None:
        self.assembler.set_time(t)
        np.take(self.assembler.velocity_rhs, self.rows, out=self.velocity_rhs[: self.rows.size])

    def fill_residual_jacobian(self, coordinates: np.ndarray) -> float:
        """Refill the residual and the Jacobian values; returns the weighted residual norm."""
        self.assembler.fill_residual_jacobian(coordinates)
        n_kept = self.rows.size
        np.take(self.assembler.residual, self.rows, out=self.residual[:n_kept])
        np.subtract(coordinates[self.held], self.held_values, out=self.residual[n_kept:])
        np.take(self.assembler.values, self._entries, out=self.values[: self._entries.size])
        weighted = np.abs(self.residual) * self.weights
        return float(np.max(weighted, initial=0.0)) if np.all(np.isfinite(weighted)) else float("nan")

    def fill_acceleration_rhs(self, coordinates: np.ndarray, velocities: np.ndarray) -> None:
        self.assembler.fill_acceleration_rhs(coordinates, velocities)
        np.take(self.assembler.acceleration_rhs, self.rows, out=self.acceleration_rhs[: self.rows.size])
