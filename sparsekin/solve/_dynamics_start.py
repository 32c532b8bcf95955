"""The start of a forward-dynamics run (`sparsekin.solve.dynamics`): which equations to
leave out as redundant, the drawing assembled, the bodies' initial velocities, and the
message of a motion that the masses leave undetermined."""

from __future__ import annotations

import numpy as np

from ..engine.linalg import SingularMatrix, SuperLUSolver
from ..engine.pattern import ConstraintPattern
from ..errors import ModelError
from ..model.mechanism import Mechanism

__all__ = ["REDUNDANCY_CHECK_COORDINATES", "assembled", "initial_momenta", "initial_velocities", "redundant_equations",
           "redundant_rows", "undetermined"]

#: Models up to this many coordinates are always searched for redundant equations at the
#: start (larger ones when they have at least as many equations as coordinates).
REDUNDANCY_CHECK_COORDINATES = 3000


def redundant_rows(jacobian, preference: np.ndarray) -> np.ndarray:
    """Equations to leave out so that the others are independent: those
    `sparsekin.analysis.rank.analyse_jacobian` names (later joints first, drivers last, as
    the kinematics names them; `preference` from `sparsekin.analysis.describe.row_preference`).
    Its square branch never hands an exactly singular matrix to SuperLU (which crashed on one).
    A small Jacobian whose rows are clearly independent (`independent_rows`, a dense SVD)
    has none without the analysis's iterations."""
    from ..analysis.rank import analyse_jacobian, independent_rows

    if independent_rows(jacobian):
        return np.zeros(0, dtype=np.int64)
    return analyse_jacobian(jacobian, row_preference=preference).redundant_rows


def redundant_equations(discretization, t: float) -> np.ndarray:
    """The equations of `discretization` to leave out as redundant (`redundant_rows` of its
    Jacobian at the drawing at time `t`, the kinematics' row preference); none searched for
    in a model above `REDUNDANCY_CHECK_COORDINATES` coordinates with fewer equations."""
    from ..analysis.describe import row_preference
    from ..engine.assembly import Assembler

    pattern = discretization.constraints
    n, m = pattern.n_coordinates, pattern.n_equations
    if m == 0 or (n > REDUNDANCY_CHECK_COORDINATES and m < n):
        return np.zeros(0, dtype=np.int64)
    assembler = Assembler(discretization)
    assembler.set_time(t)
    assembler.fill_residual_jacobian(pattern.initial_coordinates)
    return redundant_rows(assembler.jacobian, row_preference(discretization.mechanism, pattern))


def assembled(system, pattern: ConstraintPattern, t: float, tolerance: float, max_corrections: int) -> np.ndarray:
    """The drawing moved onto Φ(q, t) = 0 by the smallest weighted change (Gauss–Newton on
    [[W, Φqᵀ], [Φq, 0]], W = diag(coordinate weights²)), Φ the kept equations of `system`
    (a `sparsekin.engine.saddle.DynamicSystem`)."""
    from scipy.sparse import bmat, diags

    kept = system.kept_rows
    q = pattern.initial_coordinates.copy()
    system.set_time(t)
    metric = None  # (made at the first correction: a drawing on its constraints needs none)
    for _ in range(max_corrections):
        if system.fill_constraints(q) <= tolerance:
            return q
        metric = diags(pattern.coordinate_weights**2) if metric is None else metric
        jacobian = system.assembler.jacobian[kept]
        matrix = bmat([[metric, jacobian.T], [jacobian, None]], format="csr")
        solver = SuperLUSolver()
        try:
            solver.factor(matrix)
        except SingularMatrix:
            break
        q += solver.solve(np.concatenate([np.zeros(q.size), -system.assembler.residual[kept]]))[: q.size]
    raise ModelError(f"the drawing cannot be assembled at t = {t:g} s: the constraints are off by "
                     f"{system.fill_constraints(q):.3g} (relative) after {max_corrections} corrections")  # fmt: skip


def initial_momenta(matrix, velocities: np.ndarray, n_kept: int) -> np.ndarray:
    """M q̇ for the saddle `matrix` S (its first n rows, M's, times the `velocities`, the
    multipliers' part zero).  Zeros without the product where every velocity is zero: the
    product's entries are then +0.0 too (each a sum started at +0.0; S is finite, factored),
    and at 10^6 bodies it was 0.2 s of the start."""
    if not velocities.any():
        return np.zeros(velocities.size)
    return (matrix @ np.concatenate([velocities, np.zeros(n_kept)]))[: velocities.size]


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
