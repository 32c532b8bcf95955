"""The rounding floor of a long model's Newton corrections (forward dynamics, large path).

`RoundingFloor` is the part of `sparsekin.solve.dynamics`'s stopping rules that only the
large path (`RefactorSolver`) uses: it knows, from the steps before, the size below which
Newton's corrections of a long chain are rounding noise.
"""

from __future__ import annotations

from ..engine._dynamics_kernels import fill_rounding_probe, weighted_norm

__all__ = ["COLD_MARGIN", "EXTRAPOLATION_GAIN", "EXTRAPOLATION_RATIO", "FLOOR_MARGIN", "FLOOR_STEPS",
           "GROWTH_STEPS", "MAX_MATRIX_AGE", "PROJECTION_NOISE", "RATE_STEPS", "REFINEMENT_MARGIN",
           "RoundingFloor", "rounding_response"]

#: A floor measured by a stalled Newton is trusted for this many steps, then measured again.
FLOOR_STEPS = 100
#: A held matrix's correction within this multiple of the measured floor is noise.
FLOOR_MARGIN = 4.0
#: The projections stop refining once their increment is below this fraction of Newton's
#: noise γ′ · floor (velocities) or β′ · floor (accelerations), the drift at the tolerance
#: (0.1 until the sixth session: the refinement it left off cost a 10^5-body chain's B0 2 %
#: once Newton started from its own last accelerations; docs/design-notes.md).
PROJECTION_NOISE = 0.03
#: A projection skips its refinement when the contraction measured on the held matrix
#: predicts a next increment below this fraction of the projection's noise bound ...
REFINEMENT_MARGIN = 0.01
#: ... the contraction measured at most this many steps ago (then it is measured again).
RATE_STEPS = 8
#: A projection starts from zero when the contraction measured lately predicts a second
#: increment within this fraction of its noise (`RoundingFloor.starts_cold`) ...
COLD_MARGIN = 0.5
#: ... the contraction per step of the factorization's age measured at most this many steps
#: ago, on any factorization (then it is measured again: from zero).
GROWTH_STEPS = 32
#: The predictor extrapolates the accelerations while that leaves Newton a first correction
#: at most this fraction of the last one without (`RoundingFloor.extrapolates`).
EXTRAPOLATION_GAIN = 0.5
#: The predictor extrapolates only over a step at most this many times the step it
#: extrapolates from (a step grows by at most 2): after a short step that ended on an
#: output sample, the line through its accelerations would carry their noise a long way.
EXTRAPOLATION_RATIO = 2.0
#: The held iteration matrix is refactored at a step's first Newton iterate once it is older
#: than this many steps (large path): Newton's and the projections' errors on a held matrix
#: keep their sign step after step and add up with its age.  Measured (10^5 bodies, 1000
#: steps, B0 against a run with a fresh matrix at every iterate): with no limit the matrix
#: lived ~50 steps and B0 strayed 9.4e-8 m from that run at 1 s (before the limit's
#: session: 7.7e-8); at most 24, 16, 8 steps: 8.3e-9, 8.4e-9, 2.4e-9 m, for 56, 71, 115
#: factorizations over the 1000 steps against 39 (docs/design-notes.md).
MAX_MATRIX_AGE = 16


class RoundingFloor:
    """The size of the Newton corrections below which a long model's iterates are rounding
    noise, as measured on the large path (`RefactorSolver`; 0 = not known): the correction
    at which Newton last stalled with a fresh matrix (`sparsekin.solve.dynamics.STALL`), or
    lower with a held one (`sparsekin.solve.dynamics.NOISE`), trusted for `FLOOR_STEPS` steps.

    A chain of 10^5 bodies in absolute coordinates carries the rounding of its coordinates
    (≈ 5·10^4 m × 1e-16) along its length: while its residuals were summed left to right,
    its Newton corrections stopped falling at 4e-10–7e-10 at every step, held or fresh
    matrix alike, above the held matrix's noise allowance ``NOISE √n`` times the rounding
    of q, so that the held factorization was refactored at every step for nothing.  Summed
    exactly (`sparsekin.engine._kernels._gap`) they fall three decades lower, still
    contracting: Newton then settles once the error it predicts is within the rounding
    of q, and the projections' noise is Newton's allowance (`converged`).  Once the floor
    is known, a held matrix's correction within `FLOOR_MARGIN` times it is noise too, and
    the velocity projection stops refining once its increment is below
    ``PROJECTION_NOISE`` times the velocity noise γ′ · floor that Newton leaves anyway and
    the drift is at the tolerance.  Small models (dense path) never measure a floor.

    The same object says whether the large path's iteration matrix carries the (2, 2)
    regularization −r I (`regularization`): only from a failed step until the step is back
    at its largest.  r changes the solution of the saddle system by about
    r ‖(Φq A⁻¹ Φqᵀ)⁻¹‖, which grows as a chain's length squared: 0.05 at 10^5 bodies (the
    projection's refinement, whose matrix has no r, contracted 20× slower for it), over 1
    at 10^6 (the refinement diverged: a 10^6-body chain stopped at t = 10.7 ms).  Where
    Φq loses rank for an instant, a step fails and the regularization is back.

    It also keeps, per projection (velocities, accelerations), the contraction of its
    iterative refinement on the held factorization (second increment / first), measured
    at most `RATE_STEPS` steps ago on the same factorization (`refined`, `skips_refinement`).
    On a 10^5-body chain the first increment is 6e-7 (velocities) and 1e-3
    (accelerations), the contraction 2e-5 to 3e-4, so the second increment is 1e-10 and
    3e-7, 300 times below the noise at which the refinement stops (5e-8 and 1e-4): that
    second solve (a third of a step's solves and refills) only confirmed what the first had
    done.  The contraction grows with the factorization's age a (steps since it was made)
    about as a² (a stale Φq's error times a stale change; measured: 1.5e-4, 3.3e-4,
    5.5e-4, 6.8e-4, 1.2e-3 at ages 2 to 6 on a 10^4-body chain), so a contraction measured
    at age a₀ ≥ 1 predicts ``rate · (a / a₀)²`` now.  When that predicts a second increment
    below `REFINEMENT_MARGIN` times the noise, the projection stops after its first solve
    (once the drift left is within its bound, as always).  The second increment from zero
    over the first grows in proportion to the age (10^5 bodies: 6e-4 to 1.2e-2 at ages 1 to
    13); measured per step of age (`contracted`) it says whether a projection starts from
    zero or from its last change (`starts_cold`).

    And it decides the predictor (`extrapolates`, `predicted`).  Generalized-α's predictor
    takes the last accelerations: its error in q is about β h² (q̈_{n+1} − q̈_n), ~3e-9 on
    the chain, ten times its rounding floor, so that Newton took a correction to remove it
    and two more to reach the floor.  Extrapolated linearly from the step before, q̈_{n+1}
    ≈ q̈_n + (h / h_{n-1}) (q̈_n − q̈_{n-1}), the first correction was 3e-10–6e-10 at 10^5
    bodies and 7e-11 at 10^4 (residuals summed left to right; with exact sums and Newton's
    own q̈ and λ to start from, medians 2e-12–6e-12 at both sizes, the second correction still
    needed: docs/design-notes.md): one correction fewer.  It is used while it pays: its first
    correction at most `EXTRAPOLATION_GAIN` times the last one without; otherwise it is
    tried again after `RATE_STEPS` steps, and only when no factorization was made for as
    many steps (near a flat crossing the accelerations jump, and an extrapolation tried
    there left a first correction of 8e-3).  Never on the dense path nor while the
    iteration matrix is regularized (after a failed step).
    """

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.level = 0.0
        self._age = 0
        self._regularized = not enabled
        self._rates: dict[str, tuple] = {}  # projection -> (contraction, the factorization's age then)
        self._growth: dict[str, tuple] = {}  # projection -> (contraction / age, `_steps` then), kept
        self._steps = 0  # steps taken
        self._matrix_age = 0  # steps begun since the last factorization
        self._newton = 0.0  # Newton's last correction in this step
        # the predictor's: did the last extrapolation pay, steps since it was tried, the last
        # first correction without it, steps since a factorization
        self._paid, self._since_trial, self._constant, self._since_factored = False, RATE_STEPS, 0.0, 0

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
        """One step taken: the floor ages, forgotten after `FLOOR_STEPS`; the refinements'
        contractions age, forgotten after `RATE_STEPS`."""
        self._age += 1
        self._steps += 1
        self._since_factored += 1
        if self._age > FLOOR_STEPS:
            self.level = 0.0

    def step_begins(self) -> bool:
        """A step begins: the factorization is a step older; whether it is older than
        `MAX_MATRIX_AGE` on the large path (to be refactored at the step's first iterate)."""
        self._matrix_age += 1
        return self.enabled and self._matrix_age > MAX_MATRIX_AGE

    def refined(self, what: str, rate: float) -> None:
        """Projection `what`'s refinement contracted by `rate` on the held factorization."""
        if self.enabled:
            self._rates[what] = (rate, self._matrix_age)

    def contracted(self, what: str, rate: float) -> None:
        """Projection `what`'s second increment from zero was `rate` times its first, on the
        held factorization (kept across factorizations, per step of its age: `starts_cold`)."""
        if self.enabled and self._matrix_age >= 1:
            self._growth[what] = (rate / self._matrix_age, self._steps)

    def refactored(self) -> None:
        """A new factorization: its contractions are not known yet."""
        self._rates.clear()
        self._matrix_age = 0
        self._since_factored = 0

    def skips_refinement(self, what: str, increment: float, noise: float) -> bool:
        """Whether projection `what`, whose first increment was `increment`, may stop there:
        the contraction measured lately, grown as the square of the factorization's age,
        predicts a next one below `REFINEMENT_MARGIN` · `noise` (never on the dense path,
        nor before a contraction is measured on a factorization at least a step old)."""
        if what not in self._rates:
            return False
        rate, age = self._rates[what]
        if age < 1 or self._matrix_age - age >= RATE_STEPS:
            return False
        return rate * (self._matrix_age / age) ** 2 * increment <= REFINEMENT_MARGIN * noise

    def starts_cold(self, what: str, change: float, noise: float) -> bool:
        """Whether projection `what`, whose change in the step before was `change`, starts
        from zero rather than from that change (`sparsekin.solve.projections.WARM_START`):
        on a factorization made in this step, when no contraction was measured in the last
        `GROWTH_STEPS` steps (a refinement from zero measures it), or when the last one
        measured (`contracted`), grown in proportion to the factorization's age, predicts a
        second increment from zero within `COLD_MARGIN` times `noise`: two solves from zero
        will do then, and a warm column also takes two and a residual pass more."""
        if self._matrix_age < 1 or what not in self._growth:
            return True
        growth, measured = self._growth[what]
        predicted = growth * self._matrix_age * change
        return self._steps - measured >= GROWTH_STEPS or predicted <= COLD_MARGIN * noise

    def extrapolates(self) -> bool:
        """Whether the next step's predictor extrapolates the accelerations: on the large
        path, not regularized, when the last extrapolation paid, or `RATE_STEPS` steps after
        the last trial with no factorization for as many."""
        if self._regularized:
            return False
        return self._paid or (self._since_trial >= RATE_STEPS and self._since_factored >= RATE_STEPS)

    def extrapolates_multipliers(self) -> bool:
        """Whether the next step's predictor extrapolates λ: on the large path, not
        regularized (always then: Newton's own λ vary smoothly, 3e-3 against 0.4 kept
        constant on a 10^4-body chain)."""
        return not self._regularized

    def predicted(self, extrapolated: bool, correction: float) -> None:
        """Newton's first correction after the predictor, `extrapolated` or not."""
        if extrapolated:
            self._paid, self._since_trial = correction <= EXTRAPOLATION_GAIN * self._constant, 0
        else:
            self._paid, self._since_trial, self._constant = False, self._since_trial + 1, correction

    def settling(self, bound: float, floor: float) -> float:
        """The error Newton may leave in q (weighted): the tolerance's share `bound`, or on
        the large path the rounding `floor` of q if larger (the error its contraction
        predicts below that, a further correction only reaches the rounding of q)."""
        return max(bound, floor) if self.enabled else bound

    def converged(self, correction: float) -> None:
        """Newton's last correction in this step, `correction` (weighted)."""
        self._newton = correction

    def projection_noise(self, rate: float) -> float:
        """A fraction `PROJECTION_NOISE` of the noise Newton leaves in the velocities
        (`rate` γ′) or accelerations (`rate` β′): `rate` times the measured floor or
        Newton's last correction in this step (`converged`), the larger (large path only,
        else 0: refine to the bound).

        With the residuals summed exactly (`sparsekin.engine._kernels._gap`), a long
        chain's Newton stalls three decades lower than it did (10^4 bodies: 1e-14–6e-14
        against 2e-11), at corrections its held matrix still contracts: its last correction,
        not the stall floor, is then the size of what it left."""
        return PROJECTION_NOISE * rate * max(self.level, self._newton) if self.enabled else 0.0

    def noise(self, held_threshold: float) -> float:
        """The largest correction of a held matrix that is noise."""
        return max(held_threshold, FLOOR_MARGIN * self.level)


def rounding_response(solver, work, n: int, row_weights, coordinate_weights, floor: float) -> float:
    """The weighted size of the coordinates' part of S⁻¹ e for Newton's factored matrix S and
    e a residual of the constraints' rounding, `floor` (relative to the coordinates' size) in
    every kept equation (`fill_rounding_probe`; one solve, in `work`, shape (size,)).

    A fresh matrix's corrections that stop contracting below it, where Φ is within the
    rounding of q already, are that rounding through S: Newton has converged as far as the
    arithmetic allows (on the 10^5-body chain a correction of 1.1e-5 passed the test alone,
    with Φ 24 times the rounding, and the next step diverged).  It scales as the far coordinates'
    ulp (a 10^5-body chain's 5·10^4 m: its angles carry 5e-12 rad) over S's conditioning,
    which at a flat crossing of the N-four-bar (Φq short of rank N) amplifies it 100×
    above the ``STALL √n`` allowance of `sparsekin.solve.dynamics` (10^5 bodies: 3.0e-8
    against 2.7e-8; N = 4 with its drawing 10^4 m from the origin: 3–6e-10 against
    1.85e-10; the probe's response there was 40–250 times the stalled corrections).  The
    forces' part of the residual is left out: it moves q through S's leading block, scaled
    by 1/β′ ~ h²/4, not through Φq's vanishing singular values."""
    fill_rounding_probe(row_weights, floor, n, work)
    return weighted_norm(solver.solve(work, out=work)[:n], coordinate_weights)
