"""Linear solvers for the Newton, velocity and acceleration systems, behind one interface.

A linear solver factors the Jacobian once (`factor`) and then solves any number of
right-hand sides with that factorization (`solve`).  `SuperLUSolver` uses scipy's SuperLU
with the COLAMD ordering.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from scipy.sparse import csr_array
from scipy.sparse.linalg import splu

__all__ = ["LinearSolver", "SuperLUSolver", "SingularMatrix"]


class SingularMatrix(RuntimeError):
    """The factorization met an exactly zero pivot or produced non-finite values."""


class LinearSolver(Protocol):
    n_factorizations: int
    n_solves: int

    def factor(self, jacobian: csr_array) -> None:
        """Factor `jacobian`; raise `SingularMatrix` if it cannot be factored."""
        ...

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve ``jacobian @ x = rhs`` with the last factorization."""
        ...


class SuperLUSolver:
    """scipy's SuperLU, factoring the CSC view ``jacobian.T`` (no copy, no conversion)."""

    name = "superlu"

    def __init__(self) -> None:
        self._lu = None
        self.n_factorizations = 0
        self.n_solves = 0

    def factor(self, jacobian: csr_array) -> None:
        self.n_factorizations += 1
        try:
            self._lu = splu(jacobian.T, permc_spec="COLAMD")
        except RuntimeError as error:  # "Factor is exactly singular"
            self._lu = None
            raise SingularMatrix(str(error)) from error

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        self.n_solves += 1
        solution = self._lu.solve(rhs, trans="T")
        if not np.all(np.isfinite(solution)):
            raise SingularMatrix("the solution is not finite")
        return solution
