"""What went wrong, in words: the errors and warnings of a kinematic analysis.

The time loop (`sparsekin.solve.stepper`) decides *when* something failed; `Diagnosis` decides
*what* it was, with the rank analysis of `sparsekin.analysis.rank`, and writes the message:

* a mechanism whose equations are dependent at the first sample (a driver that the
  joints already fix, a model drawn at a singular configuration) is a `ModelError`
  naming the dependency, as ``sparsekin check`` would;
* more equations than coordinates: the redundant ones are found and left out with a
  `RedundantConstraintWarning`, unless drivers take part or free motions remain
  (`ModelError`);
* a step that fails on the shortest subdivision stops the analysis: a
  `SingularConfigurationError` when the smallest singular value of the scaled Jacobian
  has collapsed (a lock-up, a dead centre), naming the uncontrolled motion and the
  constraints involved, a `ConvergenceError` otherwise.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..engine.discretization import Discretization
from ..engine.reduced import CONSISTENCY_TOLERANCE
from ..errors import (
    ConvergenceError,
    ModelError,
    RedundantConstraintWarning,
    SingularConfigurationError,
    warn_caller,
)
from .describe import (
    describe_motion,
    driven_labels,
    equation_label,
    equations_summary,
    motion_summary,
    row_preference,
)

if TYPE_CHECKING:
    from .rank import JacobianAnalysis


def _analyse(jacobian, **options) -> JacobianAnalysis:
    """`sparsekin.analysis.rank.analyse_jacobian`, imported when a diagnosis first needs it: its scipy
    modules (dense and sparse LU, QR) are loaded by a run that fails, not by every run."""
    from .rank import analyse_jacobian

    return analyse_jacobian(jacobian, **options)

__all__ = ["Diagnosis", "LOCK_RATIO"]

#: Lock-up: after a failure on the shortest step, the configuration is singular if the
#: smallest singular value of the scaled Jacobian, relative to its largest, has fallen
#: below this fraction of its value at the first sample.
LOCK_RATIO = 1e-2
#: How many drivers, coordinates and constraints an error message lists.
LISTED = 4
#: The hint at the end of messages about a model's structure.
_CHECK_HINT = "sparsekin check MODEL.toml shows more"


class Diagnosis:
    """Errors and warnings about one mechanism's analysis.

    Parameters
    ----------
    discretization : Discretization
        The mechanism's arrays (`sparsekin.engine.discretization.discretize`).
    """

    def __init__(self, discretization: Discretization) -> None:
        self.mechanism, self.pattern = discretization.mechanism, discretization.constraints
        self._driven_labels: list[str] | None = None
        self.redundancy_analysis: JacobianAnalysis | None = None

    # ------------------------------------------------------------------ labels
    def label(self, row: int) -> str:
        return equation_label(self.mechanism, self.pattern, int(row))

    def driver_values(self, assembler) -> dict[str, float]:
        """The laws' values at the assembler's last time, by driven row label."""
        if self._driven_labels is None:
            self._driven_labels = driven_labels(self.mechanism, self.pattern)
        return dict(zip(self._driven_labels, map(float, assembler.driver_values)))

    def drivers_text(self, assembler, prefix: str = "drivers: ") -> str:
        drivers = self.driver_values(assembler)
        shown = "; ".join(f"{label} = {value:.6g}" for label, value in list(drivers.items())[:LISTED])
        if len(drivers) > LISTED:
            shown += f"; … ({len(drivers)} drivers)"
        return prefix + (shown or "no drivers")

    def worst_residual(self, system) -> str:
        """``; largest residual 0.3 in joints[2] (…), equation y``, or nothing if not finite."""
        residual = system.residual
        if not residual.size or not np.all(np.isfinite(residual)):
            return ""
        worst = int(np.argmax(np.abs(residual) * system.weights))
        rows = getattr(system, "rows", None)
        row = worst if rows is None else int(rows[worst])
        return f"; largest residual {abs(residual[worst]):.3g} in {self.label(row)}"

    # ------------------------------------------------------------------ at the start
    def redundant_rows(self, assembler, t: float, coordinates: np.ndarray, forces: bool = False, *,
                       tall_lu_from: int | None = None) -> np.ndarray:  # fmt: skip
        """The equations to leave out of a model with more equations than coordinates.

        Warns with `RedundantConstraintWarning` naming them (and, if the run computes
        `forces`, saying which reactions it gives for the redundant set).  `tall_lu_from`:
        see `sparsekin.analysis.rank.analyse_jacobian`.

        Raises
        ------
        ModelError
            Free motions remain, drivers take part in a redundancy, or the drawn
            configuration is too close to singular to tell.
        """
        mechanism, pattern = self.mechanism, self.pattern
        assembler.set_time(t)
        assembler.fill_residual_jacobian(coordinates)
        options = {} if tall_lu_from is None else {"tall_lu_from": tall_lu_from}
        analysis = _analyse(assembler.jacobian, row_preference=row_preference(mechanism, pattern), **options)
        self.redundancy_analysis = analysis  # its factors give the reduced system a pivot order
        n_coordinates, n_equations = pattern.n_coordinates, pattern.n_equations
        if analysis.n_free:
            raise ModelError(self._free_motions_message(analysis, coordinates))
        if n_equations - analysis.n_redundant != n_coordinates:  # borderline ranks: no square system
            raise ModelError(
                f"{n_coordinates} coordinates but {n_equations} equations, of which "
                f"{analysis.n_redundant} depend on the others at t = {t:g} s, where "
                f"{n_equations - n_coordinates} were expected: the drawn configuration is too close to "
                f"singular to tell ({_CHECK_HINT})"
            )
        driver_redundancy = self._driver_redundancy(analysis)
        if driver_redundancy:
            raise ModelError(
                f"{n_coordinates} coordinates but {n_equations} equations, and the drivers take part in "
                f"a redundancy: {driver_redundancy}; the drivers prescribe a motion that the joints already fix "
                "(remove a driver or a joint)"
            )
        rows = analysis.redundant_rows
        listed = "; ".join(self.label(row) for row in rows[:LISTED])
        if rows.size > LISTED:
            listed += f"; … ({rows.size} equations)"
        reactions = ""
        if forces:
            reactions = "; the reactions of the joints involved are not unique: the minimum-norm ones are given"
        warn_caller(
            f"{n_equations} equations for {n_coordinates} coordinates: {rows.size} redundant "
            f"equation{'s' * (rows.size != 1)} left out (each depends on the others at t = {t:g} s): {listed}"
            + reactions,
            RedundantConstraintWarning,
        )
        return rows

    def dependent_at_start(self, analysis: JacobianAnalysis, coordinates: np.ndarray, t: float) -> ModelError:
        """The error for a square model whose equations are dependent at the first sample."""
        redundancy = self._driver_redundancy(analysis) or "; ".join(
            f"{self.label(row)} depends on "
            f"{equations_summary(self.mechanism, self.pattern, analysis.dependency(k), exclude=int(row))}"
            for k, row in enumerate(analysis.redundant_rows[:LISTED])
        )
        motions = self._motions(analysis, coordinates)
        return ModelError(
            f"the {self.pattern.n_equations} equations have rank {analysis.rank} at t = {t:g} s: {redundancy}; "
            f"so the drivers leave a motion free: {motions}; a driver prescribes what the joints already fix (a "
            "cylinder whose two ends sit on one body, say), or the model is drawn at a singular configuration "
            f"({_CHECK_HINT})"
        )

    def _driver_redundancy(self, analysis: JacobianAnalysis) -> str:
        """The first redundancy that a driver takes part in, in words, or ``""``."""
        n_joint_rows = int(self.pattern.element_first_row[len(self.mechanism.joints)])
        involved = np.flatnonzero(analysis.involve(np.arange(n_joint_rows, self.pattern.n_equations)))
        if not involved.size:
            return ""
        k = int(involved[0])
        row = int(analysis.redundant_rows[k])
        others = equations_summary(self.mechanism, self.pattern, analysis.dependency(k), exclude=row)
        return f"{self.label(row)} depends on {others}"

    def _motions(self, analysis: JacobianAnalysis, coordinates: np.ndarray) -> str:
        motions = "; ".join(
            describe_motion(self.mechanism, self.pattern, coordinates, analysis.free_motions[:, k],
                            analysis.scaled_free_motions[:, k], limit=3)
            for k in range(min(analysis.n_free, LISTED))
        )  # fmt: skip
        return motions + (f"; … ({analysis.n_free} in all)" if analysis.n_free > LISTED else "")

    def _free_motions_message(self, analysis: JacobianAnalysis, coordinates: np.ndarray) -> str:
        n_drivers = len(self.mechanism.drivers)
        return (
            f"{self.pattern.n_coordinates} coordinates but {self.pattern.n_equations} equations of rank "
            f"{analysis.rank}: {analysis.n_free} free motion{'s' * (analysis.n_free != 1)} left after the "
            f"{n_drivers} driver{'s' * (n_drivers != 1)}: {self._motions(analysis, coordinates)}; expected one "
            f"driver per degree of freedom ({_CHECK_HINT})"
        )

    def left_out_violated(self, assembler, rows: np.ndarray, t: float) -> str:
        """The message if a redundant equation left out no longer holds at time `t`, else ``""``."""
        residual = np.abs(assembler.residual[rows]) * assembler.weights[rows]
        worst = int(np.argmax(residual))
        if residual[worst] <= CONSISTENCY_TOLERANCE:
            return ""
        row = int(rows[worst])
        return (
            f"the redundant equation {self.label(row)} left out of the analysis is not satisfied at "
            f"t = {t:.6g} s: residual {abs(assembler.residual[row]):.3g}; the redundant joints contradict each other"
        )

    # ------------------------------------------------------------------ a failed step
    def cannot_start(self, system, assembler, t: float, coordinates: np.ndarray, reason: str) -> Exception:
        """The error when the first sample cannot be solved from `coordinates` at time `t`."""
        worst = self.worst_residual(system)
        system.set_time(t)
        system.fill_residual_jacobian(coordinates)
        analysis = _analyse(system.jacobian)
        if analysis.rank < self.pattern.n_coordinates:
            return self.dependent_at_start(analysis, coordinates, t)
        return ConvergenceError(
            f"cannot assemble the model at t = {t:.6g} s: {reason} ({self.drivers_text(assembler)}){worst}",
            time=float(t),
            driver_values=self.driver_values(assembler),
        )

    def stopped(self, system, assembler, first, good, t_failed: float, reason: str) -> Exception:
        """The error for a step that failed on the shortest subdivision.

        Parameters
        ----------
        first, good : tuple (t, coordinates)
            The first sample of the run and the last configuration solved.

        A model error if the equations were already dependent at the first sample; a
        singular configuration if the smallest singular value of the (scaled) Jacobian at
        the last configuration solved has collapsed compared with the first sample;
        another failure otherwise.
        """
        worst = self.worst_residual(system)
        (t_first, q_first), (t_good, q_good) = first, good
        system.set_time(t_first)
        system.fill_residual_jacobian(q_first)
        start = _analyse(system.jacobian)
        if start.rank < start.shape[1]:
            return self.dependent_at_start(start, q_first, t_first)
        reference = start.smallest_singular_value
        system.set_time(t_good)
        system.fill_residual_jacobian(q_good)
        analysis = _analyse(system.jacobian)
        if analysis.rank < analysis.shape[1] or analysis.smallest_singular_value <= LOCK_RATIO * reference:
            return self.singular_configuration(
                system, assembler, analysis, q_good, t_failed, (t_first, reference),
                f"{reason} on a step of {t_failed - t_good:.2g} s",
            )  # fmt: skip
        system.set_time(t_failed)
        return ConvergenceError(
            f"{reason} at t = {t_failed:.6g} s ({self.drivers_text(assembler)}){worst}; the step was halved down "
            f"to {t_failed - t_good:.2g} s and the Jacobian at the last configuration solved "
            f"(t = {t_good:.8g} s) is regular (smallest singular value "
            f"{analysis.smallest_singular_value:.2g} of the largest, scaled)",
            time=float(t_failed),
            driver_values=self.driver_values(assembler),
        )

    def singular_configuration(self, system, assembler, analysis, q, t, reference=None, how="") -> SingularConfigurationError:
        """A `SingularConfigurationError` at time `t`, the motion and constraints from `analysis`.

        `reference` is ``(t_first, smallest singular value there)`` for comparison.
        """
        rows = getattr(system, "rows", None)
        motion = motion_summary(self.mechanism, analysis.smallest_motion, limit=LISTED)
        bodies = describe_motion(
            self.mechanism, self.pattern, q, analysis.column_scale * analysis.smallest_motion,
            analysis.smallest_motion, limit=3,
        )  # fmt: skip
        equations = equations_summary(self.mechanism, self.pattern, analysis.smallest_equations, rows=rows, limit=LISTED)
        value = analysis.smallest_singular_value
        if analysis.rank < analysis.shape[1]:
            size = f"the Jacobian has rank {analysis.rank} for {analysis.shape[1]} coordinates"
        else:
            versus = f" (it was {reference[1]:.2g} at t = {reference[0]:g} s)" if reference is not None else ""
            size = f"smallest singular value of the scaled Jacobian {value:.2g} of the largest{versus}"
        system.set_time(t)
        return SingularConfigurationError(
            f"singular configuration at t = {t:.6g} s: {self.drivers_text(assembler, prefix='')}; uncontrolled "
            f"motion: {motion} — {bodies}; constraints involved: {equations}; {size}" + (f"; {how}" if how else ""),
            time=float(t),
            driver_values=self.driver_values(assembler),
            smallest_singular_value=float(value),
        )
