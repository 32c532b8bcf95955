"""The constraint projections of forward dynamics (`sparsekin.solve.dynamics`): after each
step the velocities are moved onto Φq q̇ + Φt = 0 and the accelerations onto Φq q̈ = γ by
the smallest change in the metric of the iteration matrix's leading block (ALI3-P).

`ConstraintProjections` is the part of `GeneralizedAlphaStepper` that solves them
(`_project`, on the held factorization with iterative refinement on the matrix at the
converged state); the stepper chooses their targets, bounds and noise.  It uses the
stepper's ``system``, ``solver``, ``assembler``, ``pattern``, ``_floor``, ``_weights``,
``_projection_work``, ``_factor`` and ``n_singular_projections``.
"""

from __future__ import annotations

import math

import numpy as np

from ..engine import _dynamics_kernels
from .error_control import StepFailed as _StepFailed

__all__ = ["PROJECTION_ITERATIONS", "REFINEMENT_CONTRACTION", "ConstraintProjections"]

#: Most solves of one velocity projection, and the contraction its iterative refinement
#: must keep on the held factorization.
PROJECTION_ITERATIONS = 8
REFINEMENT_CONTRACTION = 0.1


class ConstraintProjections:
    """The projections' solves, a base of `sparsekin.solve.dynamics.GeneralizedAlphaStepper`."""

    def _project(self, q, v, lam, coefficients, drift, bound: float, what: str, noise: float = 0.0):
        """The smallest change Δ, in the metric A, that removes `drift` (Φq times the
        velocities or accelerations minus their target, every equation) and its
        multipliers μ, ``[Δ; μ]`` (None if the drift is within `bound` already):

            [[A, Φqᵀ], [Φq, 0]] [Δ; μ] = [0; drift],

        A the iteration matrix's leading block and Φq at the converged q.  The held
        factorization (of an earlier state) preconditions iterative refinement on the
        matrix at q, refactored when the refinement stops contracting, or contracts too
        slowly to reach `bound` in the solves left (`_converges_in_time`): a correction along
        stale normals would turn part of it along the motion, an energy error that adds
        up step after step.  Where Φq has lost rank for an instant the refinement stalls
        even on a fresh factorization (its (2, 2) block −r I makes it a penalty projection
        there, ALI3-P's): what it removed is kept if it left less drift than there was —
        the rest lies along Φq's vanishing singular values σ, where the drift is σ times
        the velocity error and removing it would take a change drift / σ along a direction
        that the rounding decides.  An increment below `noise` ends the refinement once the
        drift left is within `bound`.  On the large path the refinement's residual is formed
        without assembling the matrix (`DynamicSystem.product`)."""
        system, n = self.system, self.system.n
        weights = system.kept(self.assembler.weights)
        drift = system.kept(drift)
        before = _dynamics_kernels.weighted_norm(drift, weights)
        if before <= bound:
            return None
        # in two arrays made at `start` (10^6 bodies: no temporaries), the increments solved in
        # place of the residual [0; drift] − S · solution
        solution, residual, zeros = self._projection_work[0], self._projection_work[1], self._projection_work[4]
        residual[:n], residual[n:], solution[:] = 0.0, drift, 0.0
        matrix, last, fresh, filled = None, math.inf, False, False
        for iteration in range(PROJECTION_ITERATIONS):
            increment = self.solver.solve(residual, out=residual)
            solution += increment
            size = _dynamics_kernels.weighted_norm(increment[:n], self._weights)
            if size <= bound or (size <= noise and self._drift_left(drift, solution) <= bound):
                if math.isfinite(last):
                    self._floor.refined(what, size / last)
                return solution
            if (iteration == 0 and self._floor.skips_refinement(what, size, noise)
                    and self._drift_left(drift, solution) <= bound):  # fmt: skip
                return solution  # the next increment would be far below the noise (`RoundingFloor`)
            if size > REFINEMENT_CONTRACTION * last or not (fresh or _converges_in_time(
                    size, size / last, bound, PROJECTION_ITERATIONS - iteration - 1)):  # fmt: skip
                if fresh:
                    break
                self._factor(q, v, zeros, lam, coefficients)
                matrix, fresh, filled = None, True, False
                residual[:n], residual[n:], solution[:] = 0.0, drift, 0.0
                last = math.inf
                continue
            last = size
            if self._floor.enabled:  # the large path: S x without assembling S
                product = system.product(q, v, zeros, lam, *coefficients, solution, residual, same_state=filled)
                filled = True
            else:
                matrix = self._projection_matrix(q, v, lam, coefficients) if matrix is None else matrix
                product = matrix @ solution
            np.subtract(0.0, product[:n], out=residual[:n])
            np.subtract(drift, product[n:], out=residual[n:])
        left = self._drift_left(drift, solution)
        if left <= bound:  # Φq near a loss of rank: the normal direction is ill-determined, the drift is not
            return solution
        if fresh and left <= before:
            self.n_singular_projections += 1
            return solution
        raise _StepFailed(f"the {what} projection does not converge (increment {size:.3g})")

    def _projection_matrix(self, q, v, lam, coefficients):
        """The matrix the projections solve with, at the converged state (`_project`)."""
        return self.system.fill_matrix(q, v, np.zeros(self.system.n), lam, *coefficients)

    def _drift_left(self, drift, solution) -> float:
        """The weighted drift of the kept equations, `drift` (theirs), after a projection's
        change ``solution[:n]`` (Φq at the converged q), in one pass."""
        system, p = self.system, self.pattern
        return _dynamics_kernels.drift_left_norm(p.indptr, p.indices, self.assembler.values, system.kept_row,
                                                 solution[: system.n], drift, self.assembler.weights)  # fmt: skip


def _converges_in_time(correction: float, rate: float, target: float, corrections_left: int) -> bool:
    """Whether corrections shrinking by `rate` each reach `target` within `corrections_left`
    more (modified Newton: a held matrix that contracts slowly is refactored before the
    step runs out of corrections, as in Hairer & Wanner's simplified Newton)."""
    return correction * rate ** max(corrections_left, 0) <= target
