"""The counts of `sparsekin check` in the vocabulary of rigidity, and its redundant equations.

Maxwell–Calladine: for a Jacobian Phi_q of m equations in n coordinates and rank r, the
degrees of freedom (the zero modes: motions that no equation controls) are ``n - r`` and
the states of self-stress (the redundant equations: combinations of equations whose
multipliers load nothing) are ``m - r``; ``n - m = (n - r) - (m - r)`` is Maxwell's count.
`counts_line` writes them as ``sparsekin check`` prints them.  Without drivers the zero
modes are the mechanism's degrees of freedom (a rigid motion of the whole counts unless
the ground fixes it).

`describe_redundant` says, for each redundant equation, whether the drivers take part in
its dependency (all at once: a random sketch of a few solves, then one solve per
dependency it flags) and, for the
`LISTED_REDUNDANT` equations a report lists, which equations it depends on (one solve
each): a report of 10^4 redundant equations stays within the budget of the analysis.
"""

from __future__ import annotations

import numpy as np

from ..engine.pattern import ConstraintPattern
from ..model.mechanism import Mechanism
from .describe import equations_summary
from .rank import JacobianAnalysis

__all__ = ["counts_line", "describe_redundant", "listed_redundant", "LISTED_REDUNDANT"]

#: How many redundant equations a report lists with their dependencies (those not
#: satisfied first): more would bury the verdict; the rest are counted.
LISTED_REDUNDANT = 20


def counts_line(n_coordinates: int, n_equations: int, rank: int) -> str:
    """``coordinates 30, equations 32, rank 30: 0 degrees of freedom, 2 states of
    self-stress (redundant equations)``.

    Examples
    --------
    >>> counts_line(30, 32, 30)
    'coordinates 30, equations 32, rank 30: 0 degrees of freedom, 2 states of self-stress (redundant equations)'
    """
    free, stresses = n_coordinates - rank, n_equations - rank
    return (f"coordinates {n_coordinates}, equations {n_equations}, rank {rank}: {free} degree"
            f"{'s' * (free != 1)} of freedom, {stresses} state{'s' * (stresses != 1)} of self-stress "
            "(redundant equations)")  # fmt: skip


def listed_redundant(consistent: np.ndarray) -> np.ndarray:
    """Indices of the redundant equations a report lists: those not satisfied first, then
    the others in order, `LISTED_REDUNDANT` in all, ascending."""
    consistent = np.asarray(consistent, dtype=bool)
    order = np.concatenate([np.flatnonzero(~consistent), np.flatnonzero(consistent)])
    return np.sort(order[:LISTED_REDUNDANT])


def describe_redundant(
    mechanism: Mechanism, pattern: ConstraintPattern, analysis: JacobianAnalysis, consistent: np.ndarray
) -> tuple[list[str], np.ndarray]:
    """What each redundant equation depends on (``""`` for those not listed) and whether
    drivers take part in its dependency.

    Parameters
    ----------
    consistent : ndarray of bool, shape (n_redundant,)
        Whether each redundant equation is satisfied (those not are listed first).
    """
    n_joint_equations = int(pattern.element_first_row[len(mechanism.joints)])
    involves_drivers = analysis.involve(np.arange(n_joint_equations, pattern.n_equations))
    depends_on = [""] * analysis.n_redundant
    for k in listed_redundant(consistent).tolist():
        row = int(analysis.redundant_rows[k])
        depends_on[k] = equations_summary(mechanism, pattern, analysis.dependency(k), exclude=row)
    return depends_on, involves_drivers
