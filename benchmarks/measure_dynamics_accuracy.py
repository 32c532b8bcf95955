"""Accuracy of forward dynamics on the IFToMM references, with wall times (docs/design-notes.md).

``python3 benchmarks/measure_dynamics_accuracy.py a02 --loops 40 --steps 1e-3 5e-4 --rho 0.9``
prints, per step size, B0's largest position and velocity errors over the 401 outputs of
20 s against the exact reduced ODE, the largest energy error over the initial kinetic
energy, the crank-angle spread and the wall time; ``andrews --steps 4e-5 2e-5 1e-5``
prints the largest error of the seven angles at t = 0.03 s against the Test Set's values.
``--rtol R`` makes the steps error-controlled (``--steps`` are then the largest steps).
``cost --loops 40 --t-end 2 --steps 3.5e-4 --rtol 1e-10`` compares the cost per step of
fixed and error-controlled steps on the same (Python) stepper, rounds alternating.
Run from the repository root (the references live in tests/).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from dynamics_reference import (
    ANDREWS_REFERENCE_ANGLES,
    andrews_angles_from_bodies,
    n_four_bar_b0,
)

import sparsekin as sk
from sparsekin.testset import n_four_bar


def a02(loops: int, steps, rho: float, t_end: float, rtol: float | None = None) -> None:
    times = np.linspace(0.0, t_end, int(round(t_end / 0.05)) + 1)
    position, velocity = n_four_bar_b0(times, n_loops=loops)
    for h in steps:
        start = time.perf_counter()
        try:
            result = sk.solve_dynamics(n_four_bar(loops), times, max_step=h, rho_inf=rho, rtol=rtol, forces=None)
            note = ""
        except sk.SparsekinError as error:
            result, note = error.result, f"  stopped: {error}"
        wall = time.perf_counter() - start
        k = result.n_times
        b0 = result.point("B0")
        q = result.coordinates
        cranks = q[:, [2, *range(5, q.shape[1], 6)]]
        print(f"h = {h:g} s: B0 position {np.abs(b0.position - position[:k]).max():.2e} m, velocity "
              f"{np.abs(b0.velocity - velocity[:k]).max():.2e} m/s, energy "
              f"{np.abs(result.energy.balance).max() / result.energy.kinetic[0]:.2e} of the initial kinetic, crank "
              f"spread {np.ptp(cranks, axis=1).max():.1e} rad, {result.n_steps} steps, {wall:.1f} s{note}")


def andrews(steps, rtol: float | None = None) -> None:
    mechanism = sk.load_model(ROOT / "examples" / "dynamics" / "andrews.toml")
    for h in steps:
        start = time.perf_counter()
        result = sk.solve_dynamics(mechanism, [0.0, 0.03], max_step=h, rtol=rtol, forces=None)
        error = np.abs(andrews_angles_from_bodies(result.coordinates[-1, 2::3]) - ANDREWS_REFERENCE_ANGLES).max()
        print(f"h = {h:g} s: angles off by {error:.2e} rad, {result.n_steps} steps, {time.perf_counter() - start:.1f} s")


def cost(loops: int, t_end: float, step: float, rtol: float, rounds: int) -> None:
    """Per step, fixed steps of `step` against `rtol` (largest step 1 ms), both on the Python
    stepper, same process, rounds alternating: Newton corrections, factorizations and solves
    per step (load-independent) and wall time per step."""
    times = np.linspace(0.0, t_end, int(round(t_end / 0.05)) + 1)
    runs = {"fixed": dict(max_step=step), "rtol": dict(max_step=1e-3, rtol=rtol)}
    walls = {name: [] for name in runs}
    for _ in range(rounds):
        for name, keywords in runs.items():
            start = time.perf_counter()
            result = sk.solve_dynamics(n_four_bar(loops), times, forces=None, **keywords)
            walls[name].append((time.perf_counter() - start) / result.n_steps)
            steps = result.n_steps
            print(f"{name}: {steps} steps, per step {np.sum(result.newton_iterations) / steps:.2f} Newton, "
                  f"{result.n_factorizations / steps:.3f} factorizations, {result.n_solves / steps:.1f} solves, "
                  f"{walls[name][-1] * 1e3:.3f} ms", flush=True)
    ratio = np.median(walls["rtol"]) / np.median(walls["fixed"])
    print(f"rtol / fixed, wall per step (medians of {rounds} rounds): {ratio:.2f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("reference", choices=("a02", "andrews", "cost"))
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--loops", type=int, default=40)
    parser.add_argument("--steps", type=float, nargs="+", default=[1e-3])
    parser.add_argument("--rho", type=float, default=0.9)
    parser.add_argument("--t-end", type=float, default=20.0)
    parser.add_argument("--rtol", type=float, default=None, help="error-controlled steps (largest step: --steps)")
    arguments = parser.parse_args()
    if arguments.reference == "cost":
        cost(arguments.loops, arguments.t_end, arguments.steps[0], arguments.rtol or 1e-10, arguments.rounds)
    elif arguments.reference == "a02":
        a02(arguments.loops, arguments.steps, arguments.rho, arguments.t_end, arguments.rtol)
    else:
        andrews(arguments.steps, arguments.rtol)
