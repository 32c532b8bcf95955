"""The start of a forward-dynamics run (`sparsekin.solve.dynamics`): which equations to
leave out as redundant, the bodies' initial velocities, and the message of a motion that
the masses leave undetermined."""

from __future__ import annotations

import numpy as np

from ..engine.pattern import ConstraintPattern
from ..model.mechanism import Mechanism

__all__ = ["REDUNDANCY_CHECK_COORDINATES", "redundant_rows", "initial_velocities", "undetermined"]

#: Models up to this many coordinates are always searched for redundant equations at the
#: start (larger ones when they have at least as many equations as coordinates).
REDUNDANCY_CHECK_COORDINATES = 3000


def redundant_rows(jacobian) -> np.ndarray:
    """Equations to leave out so that the others are independent.

    Small models: a QR factorization with column pivoting of the row-equilibrated Φqᵀ
    (dense; the equations it does not pick are redundant, rank tolerance as NumPy's).
    Larger ones: `sparsekin.analysis.rank.analyse_jacobian`.  (Its square branch factors a
    rank-deficient square Jacobian with SuperLU, which crashes now and then in scipy on an
    exactly singular matrix; the dense path keeps small dynamic models, which often have
    as many equations as coordinates, away from it.)
    """
    m, n = jacobian.shape
    if n > REDUNDANCY_CHECK_COORDINATES:
        from ..analysis.rank import analyse_jacobian

        return analyse_jacobian(jacobian).redundant_rows
    from scipy.linalg import qr

    rows = jacobian.toarray()
    scale = np.abs(rows).max(axis=1)
    rows /= np.where(scale > 0.0, scale, 1.0)[:, None]
    r, pivots = qr(rows.T, mode="r", pivoting=True)
    diagonal = np.abs(np.diag(r)) if r.size else np.zeros(0)
    tolerance = max(m, n) * np.finfo(float).eps * (diagonal[0] if diagonal.size else 0.0)
    rank = int(np.sum(diagonal > tolerance))
    return np.sort(pivots[rank:]).astype(np.int64)


def initial_velocities(mechanism: Mechanism, n: int) -> np.ndarray:
    """The bodies' `velocity` (copies of repeated units included), zero where not given."""
    velocities = np.zeros((n // 3, 3))
    for b, body in enumerate(mechanism.own("bodies")):
        if body.velocity is not None:
            velocities[b] = body.velocity
    for copies in mechanism.copies:
        for body, (_, starts) in zip(copies.unit.bodies, copies.placed("bodies")):
            if body.velocity is not None:
                velocities[copies.first_body + starts] = body.velocity
    return velocities.ravel()


def undetermined(mechanism: Mechanism, pattern: ConstraintPattern) -> str:
    """The one-line message of a motion that the masses and constraints leave undetermined."""
    bodies = mechanism.own("bodies")
    massless = [body.name for body in bodies if not body.mass and not body.inertia]
    named = f" (massless bodies: {', '.join(massless[:4])}{', …' if len(massless) > 4 else ''})" if massless else ""
    return ("the motion is not determined: a moving part has neither mass nor a constraint that fixes it"
            f"{named}; expected masses (and inertias) on every body that moves freely")
