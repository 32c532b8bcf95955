"""ALI3-P against generalized-α on the IFToMM N-four-bar (issue 25: "study both on the
references and choose"); figures in docs/design-notes.md, "Forward dynamics".

ALI3-P (Bayo & Ledesma 1996; Cuadrado, Cardenal & Bayo 1997) is the trapezoidal rule on the
index-3 equations with an augmented Lagrangian — Newton on q with the symmetric matrix
W + (h²/4) Φqᵀ α Φq, W = M + (h/2) C + (h²/4) K, and λ ← λ + α Φ after each iteration — and
two projections, of the velocities and of the accelerations, that solve with the same
matrix (penalty projections).  This prototype is that method written in the stepper's own
saddle machinery, not a second integrator:

* generalized-α with ρ∞ = 1 *is* the trapezoidal rule (ã = q̈);
* the saddle's Newton with the (2, 2) block −r I, eliminated, is (A + Φqᵀ Φq / r) Δq =
  −f/β′ − Φqᵀ Φ / r with Δλ = β′ (Φq Δq + Φ) / r, A = W here: ALI3-P's iteration for
  α = β′ / r = 4 / (r h²) (its λ update linearized);
* the projections solve the same regularized matrix (`_projection_matrix`), i.e. ALI3-P's
  penalty projections (they leave r / (r + σ²) of the drift along a singular value σ of Φq,
  where the library's exact ones leave none).

``python3 benchmarks/compare_ali3p.py --loops 4 --t-end 5 --steps 1e-3 5e-4 2.5e-4`` prints,
per method and step, B0's largest position and velocity errors against the exact reduced
ODE (tests/dynamics_reference.py), the largest energy error over the initial kinetic energy,
the crank spread, Newton corrections and solves per step, step halvings and the wall time.
Run from the repository root.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from dynamics_reference import n_four_bar_b0

from sparsekin.errors import SparsekinError
from sparsekin.solve import dynamics
from sparsekin.solve.dynamics import DEFAULT_TOLERANCE, GeneralizedAlpha, GeneralizedAlphaStepper
from sparsekin.solve.options import SolveOptions
from sparsekin.testset import n_four_bar

#: Newton corrections a step of ALI3-P may take: its augmented-Lagrangian iteration
#: converges linearly, at r / (r + σ²) along a singular value σ of Φq (the library's 12
#: ran out at once).
ALI3P_ITERATIONS = 60
#: ALI3-P stops when its corrections stop shrinking below this multiple of √n times the
#: rounding floor of q (the library's `STALL` is 1e4: ~2e-10 relative on the N = 4 chain;
#: the penalty iteration stalls at ~1.9e-10 just before each crossing, where its rate → 1).
ALI3P_STALL = 1e5


class Ali3pStepper(GeneralizedAlphaStepper):
    """ALI3-P with penalty `penalty` (α, in N/m per kg of the largest mass: Φq is in metres
    and radians) in the generalized-α stepper: ρ∞ = 1, −r I with r = 4 / (α h²) in the
    iteration matrix, the projections on that same matrix."""

    def __init__(self, model, max_step: float, penalty: float, max_iterations: int = ALI3P_ITERATIONS,
                 stall: float = ALI3P_STALL) -> None:  # fmt: skip
        options = SolveOptions(DEFAULT_TOLERANCE, max_iterations, "auto")
        super().__init__(model, max_step, integrator=GeneralizedAlpha(1.0), options=options)
        self.penalty, self.stall = float(penalty), float(stall)

    def _step(self, state, h: float, t_next: float):
        masses = self.system.loads.arrays.masses
        largest = max(float(masses.mass.max(initial=0.0)), float(masses.inertia.max(initial=0.0)))
        regularization = 4.0 / (self.penalty * largest * h * h)
        if regularization != self._regularization:
            self._regularization, self._factored = regularization, False
        library_stall, dynamics.STALL = dynamics.STALL, self.stall
        try:
            return super()._step(state, h, t_next)
        finally:
            dynamics.STALL = library_stall

    def _constraints_met(self, residual: float, limit: float) -> bool:
        # ALI3-P stops on the corrections: near a loss of rank its penalty iteration moves q
        # by σ·Φ per correction and never brings Φ to the rounding floor there
        return True

    def _projection_matrix(self, q, v, lam, coefficients):
        return self.system.fill_matrix(q, v, np.zeros(self.system.n), lam, *coefficients, self._regularization)


def run(stepper: GeneralizedAlphaStepper, times: np.ndarray, position, velocity) -> str:
    """The stepper over `times`: errors of B0 (crank0's tip, 1 m from the origin), energy, counts."""
    start = time.perf_counter()
    stepper.start(times[0])
    kinetic0 = stepper.recorded()["energy"][0, 0]
    errors, energy, spread, violation, note = np.zeros(2), 0.0, 0.0, 0.0, ""
    for k, t in enumerate(times[1:], 1):
        try:
            stepper.advance(t)
        except SparsekinError as error:
            note = f"  stopped at {stepper.time:.4g} s: {error}"
            break
        q, v = stepper.state.coordinates, stepper.state.velocities
        angle, rate = q[2], v[2]
        tip = np.array([np.cos(angle), np.sin(angle)])
        tip_velocity = rate * np.array([-np.sin(angle), np.cos(angle)])
        errors = np.maximum(errors, [np.abs(tip - position[k]).max(), np.abs(tip_velocity - velocity[k]).max()])
        energy = max(energy, abs(stepper.recorded()["energy"][0, 5]) / kinetic0)
        violation = max(violation, stepper.recorded()["drift"][0, 0])
        spread = max(spread, float(np.ptp(q[[2, *range(5, q.size, 6)]])))
    wall = time.perf_counter() - start
    steps = max(stepper.n_steps, 1)
    return (f"B0 position {errors[0]:.2e} m, velocity {errors[1]:.2e} m/s, energy {energy:.2e} of the initial "
            f"kinetic, crank spread {spread:.1e} rad, ‖Φ‖ {violation:.1e}, {stepper.n_newton / steps:.2f} Newton corrections and "
            f"{stepper.solver.n_solves / steps:.1f} solves per step, {stepper.n_subdivisions} halvings, "
            f"{wall:.1f} s{note}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--loops", type=int, default=4)
    parser.add_argument("--t-end", type=float, default=5.0)
    parser.add_argument("--steps", type=float, nargs="+", default=[1e-3, 5e-4, 2.5e-4])
    parser.add_argument("--penalties", type=float, nargs="*", default=[1e9, 1e11])
    parser.add_argument("--rho", type=float, nargs="*", default=[1.0, 0.9])
    parser.add_argument("--stall", type=float, default=ALI3P_STALL, help="ALI3-P's correction tolerance, × √n × rounding")
    arguments = parser.parse_args()
    times = np.linspace(0.0, arguments.t_end, int(round(arguments.t_end / 0.05)) + 1)
    position, velocity = n_four_bar_b0(times, n_loops=arguments.loops)
    model = n_four_bar(arguments.loops)
    for h in arguments.steps:
        for rho in arguments.rho:
            stepper = GeneralizedAlphaStepper(model, h, integrator=GeneralizedAlpha(rho))
            print(f"h = {h:g} s, generalized-α ρ∞ = {rho:g}: {run(stepper, times, position, velocity)}", flush=True)
        for penalty in arguments.penalties:
            stepper = Ali3pStepper(model, h, penalty, stall=arguments.stall)
            print(f"h = {h:g} s, ALI3-P α = {penalty:g} (stall {arguments.stall:g}): {run(stepper, times, position, velocity)}", flush=True)


if __name__ == "__main__":
    main()
