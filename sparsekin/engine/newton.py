"""Newton–Raphson on the positions: the rules, written once, and the Python loop.

At each Newton iterate the residual norm decides what happens next; `newton_verdict`
holds those rules and both loops call it: `solve_positions` below, which solves with any
linear solver of `sparsekin.engine.linalg` on any *system* (an `Assembler`, or a reduced system
of `sparsekin.engine.reduced`), and the compiled time loop of `sparsekin.solve._compiled`, which
solves with a dense LU inside numba.  The loops differ only in how they fill, factor
and solve.

Plain Newton factors the Jacobian at every iterate.  *Chord* Newton solves with the
factorization already at hand (that of the previous sample) while each correction
divides the residual by at least ``1 / CHORD_CONTRACTION``; otherwise the caller restarts
with plain Newton.  Either way the Jacobian at the converged position is factored, so
velocities and accelerations are solved with it; chord corrections, which converge only
linearly, end with one Newton correction with that factorization (the *polish*) unless
the residual is already below ``POLISH_BELOW · tolerance`` or no chord correction was
taken (the start had converged).  The polish is counted as a correction and comes on top
of `max_iterations`: a converged chord Newton may report ``max_iterations + 1``.

A *system* has ``fill_residual_jacobian(q) -> weighted norm``, ``residual``,
``jacobian`` and ``values`` (see `sparsekin.engine.assembly.Assembler`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import JIT
from .linalg import SingularMatrix

__all__ = [
    "NEWTON_MAXITER",
    "DEFAULT_TOLERANCE",
    "CHORD_CONTRACTION",
    "POLISH_BELOW",
    "STALL_RATIO",
    "NoConvergence",
    "Factorizer",
    "newton_verdict",
    "solve_positions",
]

#: Most Newton corrections at one time sample.
NEWTON_MAXITER = 12
#: Default convergence tolerance: the largest residual, lengths relative to the model size
#: and angles in rad.  Near the rounding floor, so that positions carry full accuracy.
DEFAULT_TOLERANCE = 1e-12
#: A chord correction must divide the residual by at least 1 / CHORD_CONTRACTION.
CHORD_CONTRACTION = 0.1
#: Chord Newton ends with one Newton correction with the factorization at the converged
#: position, unless the residual is already this fraction of the tolerance (at the
#: default tolerance, a few rounding errors), where that correction would change nothing.
POLISH_BELOW = 1e-3
#: Plain Newton stalls when, from its third correction on, a correction leaves more than
#: this fraction of the residual.
STALL_RATIO = 0.5

# Verdicts of `newton_verdict` (numba sees plain integers).
CORRECT, CONVERGED, NOT_FINITE, STALLED, NOT_CONVERGED, CHORD_REJECTED, SINGULAR = range(7)


@njit(**JIT)
def newton_verdict(iteration, norm, previous_norm, tolerance, max_iterations, chord):
    """What to do at Newton iterate `iteration` whose weighted residual norm is `norm`.

    Returns `CONVERGED` (factor the Jacobian here and stop), `CORRECT` (take a
    correction) or why Newton stops without converging: `NOT_FINITE`, `STALLED`,
    `NOT_CONVERGED` (plain Newton) or `CHORD_REJECTED` (chord Newton: restart plain).
    """
    if norm <= tolerance:
        return CONVERGED
    if chord:
        if not norm <= CHORD_CONTRACTION * previous_norm or iteration == max_iterations:  # also NaN
            return CHORD_REJECTED
        return CORRECT
    if not math.isfinite(norm):
        return NOT_FINITE
    if iteration == max_iterations:
        return NOT_CONVERGED
    if iteration >= 3 and norm > STALL_RATIO * previous_norm:
        return STALLED
    return CORRECT


@njit(inline="always", **JIT)
def polishes(iteration, norm, tolerance, chord):
    """Whether a converged chord Newton takes the polishing correction."""
    return chord and iteration > 0 and norm > POLISH_BELOW * tolerance


class NoConvergence(Exception):
    """Newton stopped without converging; `reason` says why, in words."""

    def __init__(self, verdict: int, iteration: int, max_iterations: int) -> None:
        self.verdict = verdict
        self.reason = {
            NOT_FINITE: "the residual is not finite",
            STALLED: f"Newton stalled after {iteration} corrections",
            NOT_CONVERGED: f"no convergence in {max_iterations} Newton corrections",
            CHORD_REJECTED: "chord Newton did not contract",
        }[verdict]
        super().__init__(self.reason)


class Factorizer:
    """Factors the Jacobian of `system` with `linear_solver`, reading its values in place.

    With a solver that reads values in its own order (`RefactorSolver`) on a system that
    can fill in that order (an `Assembler`), the first factorization fixes the solver's
    value order; from then on the kernels write the Jacobian straight in that order
    (`Assembler.fill_in_order`) and the solver refactors from it without a gather — a
    random access over every value that cost about as much as the kernels at 10^6 bodies.
    """

    def __init__(self, system, linear_solver) -> None:
        self.system, self.linear_solver = system, linear_solver
        self._may_order = (hasattr(linear_solver, "factor_ordered") and hasattr(system, "fill_in_order")
                           and getattr(system, "orderable", True))  # fmt: skip
        self._layout = None  # the solver's layout the system fills in, once ordered

    def __call__(self) -> None:
        system, solver = self.system, self.linear_solver
        try:
            if self._layout is None:
                solver.factor(system.jacobian)
            else:
                solver.factor_ordered(system.values)
        finally:  # also when a fresh factorization failed after it had changed the order
            if self._may_order and solver.layout_version != self._layout:
                self._follow_layout()

    def _follow_layout(self) -> None:
        """Have the system fill in the solver's current value order (the CSR order if the
        solver holds no analysis, its last one having failed)."""
        solver = self.linear_solver
        try:
            positions = solver.value_positions
        except RuntimeError:  # no analysis: the next factorization reads the CSR Jacobian
            self.system.fill_in_order(None)
            self._layout = None
            return
        self.system.fill_in_order(positions)
        self._layout = solver.layout_version


def solve_positions(
    system, linear_solver, q, tolerance=DEFAULT_TOLERANCE, max_iterations=NEWTON_MAXITER, chord=False,
    factor=None, restart=None, work=None,
) -> int:  # fmt: skip
    """Newton–Raphson from `q`, which it refines in place; returns the number of corrections.

    Parameters
    ----------
    system
        The equations (set to the right time): an `Assembler` or a reduced system.
    linear_solver
        A solver of `sparsekin.engine.linalg`; with `chord`, it holds a factorization already.
    q : ndarray, shape (n_coordinates,)
        The start, refined in place.
    tolerance : float
        Largest accepted weighted residual.
    max_iterations : int
        Most corrections before the residual is within `tolerance` (a chord Newton's
        polish comes on top).
    chord : bool
        Try chord Newton first, then plain Newton from the original `q`.
    factor : callable, optional
        Factors the Jacobian just filled (a `Factorizer`); by default one for `system`.
    restart : ndarray, optional
        A copy of the original `q` that the caller keeps anyway (the predictor); by
        default one is made when `chord`.
    work : ndarray, optional
        Scratch of `q`'s shape for the corrections, kept by a caller that solves many
        samples (no allocation per correction); by default one is made here.

    Returns
    -------
    int
        Corrections taken (those of the attempt that converged, with the polish: at most
        ``max_iterations + 1``).  On return `linear_solver` holds the factorization of the
        Jacobian at the converged `q`.

    Raises
    ------
    NoConvergence
        Plain Newton did not converge.
    SingularMatrix
        A factorization or a solve of plain Newton failed.
    """
    if factor is None:
        factor = Factorizer(system, linear_solver)
    correction = np.empty_like(q) if work is None else work
    if chord:
        start = q.copy() if restart is None else restart
        try:
            return _newton(system, linear_solver, q, tolerance, max_iterations, True, factor, correction)
        except (NoConvergence, SingularMatrix):
            q[:] = start
    return _newton(system, linear_solver, q, tolerance, max_iterations, False, factor, correction)


def _newton(system, linear_solver, q, tolerance, max_iterations, chord, factor, correction) -> int:
    previous_norm = np.inf
    # A chord correction only has to contract: a solver that holds an older factorization
    # than the Jacobian it solves with (`sparsekin.engine.krylov.ReusingSolver`) solves it
    # with that factorization alone, the polish included (one more contraction of a
    # residual already within the tolerance: docs/design-notes.md, "Factorization reuse").
    solve_chord = getattr(linear_solver, "solve_held", linear_solver.solve) if chord else linear_solver.solve
    for iteration in range(max_iterations + 1):
        norm = system.fill_residual_jacobian(q)
        verdict = newton_verdict(iteration, norm, previous_norm, tolerance, max_iterations, chord)
        if verdict == CONVERGED:
            factor()
            if polishes(iteration, norm, tolerance, chord):
                q -= solve_chord(system.residual, out=correction)
                return iteration + 1
            return iteration
        if verdict != CORRECT:
            raise NoConvergence(verdict, iteration, max_iterations)
        if not chord:
            factor()
        previous_norm = norm
        q -= solve_chord(system.residual, out=correction)
    raise AssertionError("newton_verdict stops at max_iterations")  # pragma: no cover
