"""What a run did to get its motion: `RunStats`, the counters and the path (as scipy's ``nlu``
sits beside ``y``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["RunStats"]


@dataclass(frozen=True, eq=False)
class RunStats:
    """The run's statistics.

    Attributes
    ----------
    newton_iterations : ndarray of int, shape (n_times,)
        Newton corrections at each time (over all its sub-steps when the step to it was
        subdivided).
    n_factorizations, n_solves : int
        Factorizations of the iteration matrix and linear solves in the whole run.
    n_subdivisions : int
        How many times a step was halved.
    redundant_equations : tuple of str
        The equations left out as redundant.
    n_refactorizations : int
        Numeric refactorizations on a fixed pattern.
    linear_solver : str
        The path that solved the run (`sparsekin.results.kinematics.KinematicsResult.linear_solver`).
    """

    newton_iterations: np.ndarray
    n_factorizations: int
    n_solves: int
    n_subdivisions: int = 0
    redundant_equations: tuple[str, ...] = ()
    n_refactorizations: int = 0
    linear_solver: str = "superlu"
