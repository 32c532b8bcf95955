"""Accuracy of forward dynamics on the IFToMM references, with wall times (docs/design-notes.md).

``python3 benchmarks/measure_dynamics_accuracy.py a02 --loops 40 --steps 1e-3 5e-4 --rho 0.9``
prints, per step size, B0's largest position and velocity errors over the 401 outputs of
20 s against the exact reduced ODE, the largest energy error over the initial kinetic
energy, the crank-angle spread and the wall time; ``andrews --steps 4e-5 2e-5 1e-5``
prints the largest error of the seven angles at t = 0.03 s against the Test Set's values.
``--rtol R`` makes the steps error-controlled (``--steps`` are then the largest steps);
``--tolerance T`` sets Newton's and the projections' tolerance of ``a02`` and ``andrews``
(default: the library's, 1e-10); ``a02`` also prints the largest drifts of energy.csv.
``cost --loops 40 --t-end 2 --steps 3.5e-4 --rtol 1e-10`` compares the cost per step of
fixed and error-controlled steps on the same (Python) stepper, rounds alternating.
``profile --loops 30 --steps 1e-3 --rtol 1e-10`` follows one run output by output: the
steps taken in each 0.05 s interval, and how much of the crank's phase error (signed,
against the exact angle) and of the energy error is made in the intervals with a flat
crossing against the others (``--angle-length 1``: the estimate's angles weighed as 1 m).  ``--dense-up-to S`` lets the compiled dense loop take saddle
systems of up to S unknowns (default: the library's limit, 400; A02 has 483): a
measurement of what A02 costs on the compiled loop, not a setting of the library.
``steptime --sizes 4 8 16 33 --t-end 1 --rtol 1e-10`` times error-controlled runs of
N-four-bars on the compiled loop and on the Python stepper (same process, rounds
alternating): wall time per step, and the counts per step.
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
from sparsekin.engine.discretization import discretize
from sparsekin.solve.dynamics import DEFAULT_TOLERANCE, run_dynamics
from sparsekin.solve.options import DynamicsOptions, Request, SolveOptions
from sparsekin.solve.policy import Thresholds
from sparsekin.testset import n_four_bar


def thresholds(dense_up_to: int | None) -> Thresholds:
    """The library's thresholds, or with the dense and compiled saddle limits at `dense_up_to`."""
    if dense_up_to is None:
        return Thresholds()
    return Thresholds(saddle_dense_max_size=dense_up_to, compiled_saddle_max_size=dense_up_to)


def a02(loops: int, steps, rho: float, t_end: float, rtol: float | None = None, dense_up_to: int | None = None,
        tolerance: float = DEFAULT_TOLERANCE) -> None:
    times = np.linspace(0.0, t_end, int(round(t_end / 0.05)) + 1)
    position, velocity = n_four_bar_b0(times, n_loops=loops)
    options = SolveOptions(tolerance, thresholds=thresholds(dense_up_to))
    for h in steps:
        start = time.perf_counter()
        try:
            result = run_dynamics(discretize(n_four_bar(loops)), times, options, DynamicsOptions(h, rho, rtol),
                                  Request(forces=None, energy=True))  # fmt: skip
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
              f"spread {np.ptp(cranks, axis=1).max():.1e} rad, drifts {result.energy.drift_position.max():.1e} "
              f"{result.energy.drift_velocity.max():.1e}, {result.n_steps} steps, {wall:.1f} s, "
              f"{result.linear_solver}{note}")


def andrews(steps, rtol: float | None = None, tolerance: float = DEFAULT_TOLERANCE) -> None:
    mechanism = sk.load_model(ROOT / "examples" / "dynamics" / "andrews.toml")
    for h in steps:
        start = time.perf_counter()
        result = sk.solve_dynamics(mechanism, [0.0, 0.03], max_step=h, rtol=rtol, forces=None,
                                   tolerance=tolerance)  # fmt: skip
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


def steptime(sizes, t_end: float, rtol: float, rounds: int) -> None:
    """Wall time per step of error-controlled runs (largest step 1 ms; start and recording
    included, after a warm-up run of each path), compiled loop against the Python stepper, for N-four-bars of `sizes` loops (the compiled loop's dense LU takes
    12 N + 5 ≤ 400 unknowns: N ≤ 32)."""
    times = np.linspace(0.0, t_end, int(round(t_end / 0.05)) + 1)
    paths = {"compiled": Thresholds(), "python": Thresholds(compiled_saddle_max_size=0)}
    for loops in sizes:
        walls = {name: [] for name in paths}
        for limits in paths.values():  # warm-up: the kernels loaded from numba's cache
            run_dynamics(discretize(n_four_bar(loops)), times[:3], SolveOptions(DEFAULT_TOLERANCE, thresholds=limits),
                         DynamicsOptions(1e-3, 0.9, rtol), Request(forces=None, energy=True))  # fmt: skip
        for _ in range(rounds):
            for name, limits in paths.items():
                start = time.perf_counter()
                result = run_dynamics(discretize(n_four_bar(loops)), times, SolveOptions(DEFAULT_TOLERANCE, thresholds=limits),
                                      DynamicsOptions(1e-3, 0.9, rtol), Request(forces=None, energy=True))  # fmt: skip
                walls[name].append((time.perf_counter() - start) / result.n_steps)
                steps = result.n_steps
        pattern = discretize(n_four_bar(loops)).constraints
        print(f"N = {loops} ({pattern.n_coordinates + pattern.n_equations} unknowns), {steps} steps, {np.sum(result.newton_iterations) / steps:.2f} "
              f"Newton, {result.n_factorizations / steps:.3f} factorizations, {result.n_solves / steps:.1f} solves a step: "
              + ", ".join(f"{name} {np.median(wall) * 1e3:.3f} ms" for name, wall in walls.items())
              + f" a step (medians of {rounds}), python / compiled {np.median(walls['python']) / np.median(walls['compiled']):.1f}",
              flush=True)  # fmt: skip


def profile(loops: int, step: float, rho: float, t_end: float, rtol: float | None, dense_up_to: int | None,
            angle_length: float | None = None, quiet: bool = False) -> None:  # fmt: skip
    """One run followed output by output (`__doc__`): where the steps go and where the
    errors are made, flat crossings (every bar horizontal: the crank angle a multiple of π)
    against the rest of the motion.  `angle_length` (m): the estimate weighs an angle error
    as the displacement it makes `angle_length` from the body's frame, over the model size
    like x and y, instead of in rad (a study of the estimate's weights, not a setting: the
    N-four-bar's bars are all 1 m, so 1 is each bar's reach)."""
    from sparsekin.solve._compiled_dynamics import block_stepper
    from sparsekin.solve.dynamics import GeneralizedAlphaStepper

    from dynamics_reference import n_four_bar_motion

    times = np.linspace(0.0, t_end, int(round(t_end / 0.05)) + 1)
    exact = n_four_bar_motion(times, n_loops=loops)
    options = SolveOptions(DEFAULT_TOLERANCE, thresholds=thresholds(dense_up_to))
    stepper = GeneralizedAlphaStepper(discretize(n_four_bar(loops)), options=options,
                                      dynamics=DynamicsOptions(step, rho, rtol))  # fmt: skip
    blocks = block_stepper(stepper, options, 1)
    angle, balance, steps, uncontrolled, b0, b0_rate = [], [], [], [], [], []
    start = time.perf_counter()
    for k in range(times.size):
        block = blocks.advance_block(times[k : k + 1])
        if k == 0 and angle_length is not None:  # before the compiled loop's first block reads them
            weights = stepper.controller.weights.copy()
            weights[2::3] = angle_length * weights[0]
            stepper.controller.weights = weights
        angle.append(block.coordinates[0, 2])
        q, v = block.coordinates[0, :3], block.velocities[0, :3]  # crank 0: frame at O0, B0 1 m along it
        b0.append(q[:2] + [np.cos(q[2]), np.sin(q[2])])
        b0_rate.append(v[:2] + v[2] * np.array([-np.sin(q[2]), np.cos(q[2])]))
        balance.append(block.recorded["energy"][0, 5])
        steps.append(stepper.n_steps)
        uncontrolled.append(0 if stepper.controller is None else stepper.controller.n_uncontrolled)
    wall = time.perf_counter() - start
    angle, balance = np.unwrap(np.array(angle)), np.array(balance)
    phase = angle - exact.angle  # signed: the crank ahead (+) or behind the exact one
    kinetic0 = 0.5 * exact.constants.effective_inertia * exact.constants.initial_rate**2
    turns = np.floor(exact.angle / np.pi)  # the flat positions: angle = k π
    crossing = np.diff(turns) != 0
    steps, uncontrolled = np.diff(steps), np.diff(uncontrolled)
    d_phase, d_energy = np.diff(phase), np.diff(balance) / kinetic0
    print(f"N = {loops}, largest step {step:g} s, rtol {rtol}, {times.size - 1} intervals of 0.05 s, "
          f"{int(crossing.sum())} with a flat crossing; {int(steps.sum())} steps, {wall:.1f} s, "
          f"{stepper.path}/{'compiled' if getattr(blocks, 'n_compiled', 0) else 'python'}")  # fmt: skip
    for name, where in (("crossings", crossing), ("elsewhere", ~crossing)):
        print(f"  {name:9}: {where.sum():3d} intervals, steps {steps[where].sum():6d} (mean step "
              f"{0.05 * where.sum() / max(steps[where].sum(), 1) * 1e3:.3f} ms), uncontrolled {uncontrolled[where].sum()}, "
              f"phase error made {d_phase[where].sum():+.3e} rad (|.| {np.abs(d_phase[where]).sum():.3e}), "
              f"energy error made {d_energy[where].sum():+.3e} KE0 (|.| {np.abs(d_energy[where]).sum():.3e})")  # fmt: skip
    position, velocity = n_four_bar_b0(times, n_loops=loops)
    print(f"  B0 position {np.abs(np.array(b0) - position).max():.3e} m, velocity "
          f"{np.abs(np.array(b0_rate) - velocity).max():.3e} m/s; final phase error {phase[-1]:+.3e} rad, largest "
          f"|energy| {np.abs(balance).max() / kinetic0:.3e} KE0; rate {np.abs(exact.rate).min():.2f}-"
          f"{np.abs(exact.rate).max():.2f} rad/s")  # fmt: skip
    if quiet:
        return
    width = max(1, times.size // 40)
    print("  t      steps  phase error  energy/KE0 (every %d outputs)" % width)
    for k in range(0, times.size - 1, width):
        print(f"  {times[k + 1]:5.2f} {steps[k]:6d} {phase[k + 1]:+.3e} {balance[k + 1] / kinetic0:+.3e}"
              f"{'  crossing' if crossing[k] else ''}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("reference", choices=("a02", "andrews", "cost", "profile", "steptime"))
    parser.add_argument("--sizes", type=int, nargs="+", default=[4, 8, 16, 33], help="steptime: N of each model")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--loops", type=int, default=40)
    parser.add_argument("--steps", type=float, nargs="+", default=[1e-3])
    parser.add_argument("--rho", type=float, default=0.9)
    parser.add_argument("--t-end", type=float, default=20.0)
    parser.add_argument("--rtol", type=float, default=None, help="error-controlled steps (largest step: --steps)")
    parser.add_argument("--dense-up-to", type=int, default=None, help="compiled dense loop up to this saddle size")
    parser.add_argument("--angle-length", type=float, default=None, help="profile: angles weighed as this length, m")
    parser.add_argument("--quiet", action="store_true", help="profile: the summary only")
    parser.add_argument("--tolerance", type=float, default=DEFAULT_TOLERANCE, help="a02, andrews: Newton's")
    arguments = parser.parse_args()
    if arguments.reference == "cost":
        cost(arguments.loops, arguments.t_end, arguments.steps[0], arguments.rtol or 1e-10, arguments.rounds)
    elif arguments.reference == "a02":
        a02(arguments.loops, arguments.steps, arguments.rho, arguments.t_end, arguments.rtol, arguments.dense_up_to,
            arguments.tolerance)
    elif arguments.reference == "steptime":
        steptime(arguments.sizes, arguments.t_end, arguments.rtol or 1e-10, arguments.rounds)
    elif arguments.reference == "profile":
        for step in arguments.steps:
            profile(arguments.loops, step, arguments.rho, arguments.t_end, arguments.rtol, arguments.dense_up_to,
                    arguments.angle_length, arguments.quiet)  # fmt: skip
    else:
        andrews(arguments.steps, arguments.rtol, arguments.tolerance)
