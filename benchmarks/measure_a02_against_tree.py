"""IFToMM A02 (N = 40, 20 s, 401 outputs) against the exact answer, timed against another checkout in the same run.

    python3 benchmarks/measure_a02_against_tree.py BASE [--rounds 3] [--steps 1e-3] [--rtol 1.5e-10]

runs `sparsekin.solve_dynamics` on A02 (largest step ``--steps``, ``--rtol``, ρ∞ = 0.9) in
fresh processes, alternating the checkout BASE (e.g. main's tree from ``git archive main |
tar -x -C /tmp/base``) and this one, ``--rounds`` times each, and prints per run: B0's
largest position and velocity errors over the 401 outputs against the exact reduced ODE
(tests/dynamics_reference.py), the largest energy error over the initial kinetic energy, the
steps, and the wall and CPU time of the solve (imports excluded; numba's cache warm: run
once beforehand so that neither tree compiles in a timed run); then the medians and their
ratio, with the load average at each run.  Issue 25 asks for the 20 s run at 1 ms in under
5 s, every bound met (1e-3 on B0's position and velocity, 1e-4 of KE0 on the energy).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: The run in a fresh process (argv: step, rtol); prints one line of numbers.
_RUN = """
import sys, time
import numpy as np
sys.path.insert(0, {tests!r})
from dynamics_reference import n_four_bar_b0
import sparsekin as sk
from sparsekin.testset import n_four_bar
step, rtol = float(sys.argv[1]), float(sys.argv[2])
times = np.linspace(0.0, 20.0, 401)
mechanism = n_four_bar(40)
wall, cpu = time.perf_counter(), time.process_time()
result = sk.solve_dynamics(mechanism, times, max_step=step, rtol=rtol if rtol > 0 else None, forces=None)
wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
position, velocity = n_four_bar_b0(times, n_loops=40)
b0 = result.point("B0")
print(np.abs(b0.position - position).max(), np.abs(b0.velocity - velocity).max(),
      np.abs(result.energy.balance).max() / result.energy.kinetic[0], result.n_steps, wall, cpu)
"""


def run(tree: Path, step: float, rtol: float) -> tuple[float, ...]:
    """One run of `_RUN` with `tree`'s sparsekin; (position, velocity, energy, steps, wall, cpu, load)."""
    load = os.getloadavg()[0]
    environment = {**os.environ, "PYTHONPATH": str(tree)}
    output = subprocess.run([sys.executable, "-c", _RUN.format(tests=str(ROOT / "tests")), str(step), str(rtol)],
                            env=environment, capture_output=True, text=True, check=True, cwd="/")  # fmt: skip
    return (*map(float, output.stdout.split()), load)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("base", type=Path, help="the other checkout (its sparsekin package is used)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--steps", type=float, nargs="+", default=[1e-3])
    parser.add_argument("--rtol", type=float, default=1.5e-10, help="0: fixed steps")
    arguments = parser.parse_args()
    trees = {"base": arguments.base.resolve(), "this": ROOT}
    for step in arguments.steps:
        walls = {name: [] for name in trees}
        for _ in range(arguments.rounds):
            for name, tree in trees.items():
                position, velocity, energy, steps, wall, cpu, load = run(tree, step, arguments.rtol)
                walls[name].append(wall)
                print(f"{name}: step {step:g}, rtol {arguments.rtol:g}: B0 {position:.3e} m, {velocity:.3e} m/s, "
                      f"energy {energy:.3e} KE0, {int(steps)} steps, wall {wall:.2f} s, CPU {cpu:.2f} s, load {load:.1f}",
                      flush=True)  # fmt: skip
        medians = {name: statistics.median(values) for name, values in walls.items()}
        print(f"step {step:g}: median wall base {medians['base']:.2f} s, this {medians['this']:.2f} s, "
              f"this / base {medians['this'] / medians['base']:.2f}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
