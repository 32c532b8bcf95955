"""What a run did to get its motion: `RunStats`, the counters and the path (as scipy's ``nlu``
sits beside ``y``)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["RunStats", "RunStatsFields"]


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


@dataclass(frozen=True, eq=False)
class RunStatsFields:
    """The fields of `RunStats` (keywords only) on a result beside its `Motion`, and `stats`:
    a result class is ``class XResult(Motion, RunStatsFields)``."""

    newton_iterations: np.ndarray = field(kw_only=True)
    n_factorizations: int = field(kw_only=True)
    n_solves: int = field(kw_only=True)
    n_subdivisions: int = field(default=0, kw_only=True)
    redundant_equations: tuple[str, ...] = field(default=(), kw_only=True)
    n_refactorizations: int = field(default=0, kw_only=True)
    linear_solver: str = field(default="superlu", kw_only=True)

    @property
    def stats(self) -> RunStats:
        """The run's counters and path."""
        return RunStats(self.newton_iterations, self.n_factorizations, self.n_solves, self.n_subdivisions,
                        self.redundant_equations, self.n_refactorizations, self.linear_solver)  # fmt: skip
