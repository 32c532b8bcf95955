"""The rounding floor of a long model's Newton corrections (forward dynamics, large path).

`RoundingFloor` is the part of `sparsekin.solve.dynamics`'s stopping rules that only the
large path (`RefactorSolver`) uses: it knows, from the steps before, the size below which
Newton's corrections of a long chain are rounding noise.
"""

from __future__ import annotations

__all__ = ["FLOOR_MARGIN", "FLOOR_STEPS", "RoundingFloor"]

#: A floor measured by a stalled Newton is trusted for this many steps, then measured again.
FLOOR_STEPS = 100
#: A held matrix's correction within this multiple of the measured floor is noise.
FLOOR_MARGIN = 4.0


class RoundingFloor:
    """The size of the Newton corrections below which a long model's iterates are rounding
    noise, as measured on the large path (`RefactorSolver`; 0 = not known): the correction
    at which Newton last stalled with a fresh matrix (`sparsekin.solve.dynamics.STALL`), or
    lower with a held one (`sparsekin.solve.dynamics.NOISE`), trusted for `FLOOR_STEPS` steps.

    A chain of 10^5 bodies in absolute coordinates carries the rounding of its coordinates
    (≈ 5·10^4 m × 1e-16) along its length: its Newton corrections stop falling at
    4e-10–7e-10 at every step, held or fresh matrix alike, above the held matrix's noise
    allowance ``NOISE √n`` times the rounding of q, so that the held factorization was
    refactored at every step for nothing.  Once the floor is known, a held matrix's
    correction within `FLOOR_MARGIN` times it is noise too, and the velocity projection
    stops refining once its increment is below ``PROJECTION_NOISE`` times the velocity noise
    γ′ · floor that Newton leaves anyway and the drift is at the tolerance.  When Newton
    stops is otherwise unchanged; small models (dense path) never measure a floor.

    The same object says whether the large path's iteration matrix carries the (2, 2)
    regularization −r I (`regularization`): only from a failed step until the step is back
    at its largest.  r changes the solution of the saddle system by about
    r ‖(Φq A⁻¹ Φqᵀ)⁻¹‖, which grows as a chain's length squared: 0.05 at 10^5 bodies (the
    projection's refinement, whose matrix has no r, contracted 20× slower for it), over 1
    at 10^6 (the refinement diverged: a 10^6-body chain stopped at t = 10.7 ms).  Where
    Φq loses rank for an instant, a step fails and the regularization is back.
    """

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.level = 0.0
        self._age = 0
        self._regularized = not enabled

    def regularization(self, regularization: float) -> float:
        """The (2, 2) regularization of the iteration matrix now: `regularization`, or 0 on
        the large path unless a step failed lately."""
        return regularization if self._regularized else 0.0

    def failed(self) -> None:
        """A step failed: regularize until `recovered`."""
        self._regularized = True

    def recovered(self) -> None:
        """The step is back at its largest."""
        self._regularized = not self.enabled

    def measured(self, correction: float, fresh: bool) -> None:
        """Newton stalled at `correction`, with a `fresh` matrix (a measurement of the floor)
        or a held one (taken as a floor only downwards: it cannot ratchet up)."""
        if not self.enabled:
            return
        if fresh or self.level == 0.0:
            self.level, self._age = correction, 0
        else:
            self.level = min(self.level, correction)

    def step(self) -> None:
        """One step taken: the floor ages, forgotten after `FLOOR_STEPS`."""
        self._age += 1
        if self._age > FLOOR_STEPS:
            self.level = 0.0

    def noise(self, held_threshold: float) -> float:
        """The largest correction of a held matrix that is noise."""
        return max(held_threshold, FLOOR_MARGIN * self.level)
