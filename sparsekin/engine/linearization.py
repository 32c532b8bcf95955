"""What a stepper publishes after each solved sample: `Linearization`.

Whatever runs after a sample (the forces of inverse dynamics, a dynamics run's
reactions from its multipliers, a diagnostic) reads this value, never the stepper: the
time and state, the Jacobian Φq there (its values as the kernels wrote them and where
each CSR value sits), the driver rates −Φt, and the factorization of the kept rows of Φq
at that configuration, with which a transposed solve gives multipliers.

It holds references to the stepper's arrays, not copies: it is valid until the stepper's
next step, which refills them in place.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

__all__ = ["Linearization"]


class Linearization(NamedTuple):
    """The system at a solved sample (valid until the stepper's next step).

    Attributes
    ----------
    time : float
        s.
    coordinates, velocities, accelerations : ndarray, shape (n_coordinates,)
        q, qd, qdd.
    motion : tuple of ndarray
        ``(q, qd, turns)`` as the kernels read them: q and qd with the ground appended
        (three zeros), and the cos and sin of every body's angle (the ground last).
    jacobian_values : ndarray, shape (nnz,)
        The values of Φq as the kernels write them.
    csr_positions : ndarray of int or None
        Where the k-th CSR value of Φq is in `jacobian_values` (None: in CSR order).
    jacobian : callable
        ``jacobian()`` is Φq as a CSR array (every row, the redundant ones included).
    velocity_rhs : ndarray, shape (n_equations,)
        −Φt: the time derivative of each row's target (a driver's rate).
    factorization : LinearSolver or None
        Holds the factorization of the kept rows of Φq at this sample:
        ``factorization.solve(rhs, transposed=True)`` solves Φq[kept]ᵀ λ = rhs.  None for
        forward dynamics, which factors its saddle matrix instead and gives `multipliers`.
    kept_rows : ndarray of int or None
        The rows of Φq the factorization holds; None: every row (a square Φq).
    redundant_rows : ndarray of int
        The rows left out as redundant (empty for most models).
    multipliers : ndarray, shape (n_equations,), or None
        λ of every equation when the stepper solved for it (forward dynamics; 0 on the
        rows left out); None: forces take a transposed solve with `factorization`.
    """

    time: float
    coordinates: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    motion: tuple
    jacobian_values: np.ndarray
    csr_positions: np.ndarray | None
    jacobian: Callable
    velocity_rhs: np.ndarray
    factorization: object
    kept_rows: np.ndarray | None
    redundant_rows: np.ndarray
    multipliers: np.ndarray | None = None
