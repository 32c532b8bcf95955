"""Assembly of a rough chain: time and peak memory of the path from a drawing to the equations.

The IFToMM chain of four-bar loops (cranks of length 1, 1 m apart, couplers of length 1),
every link given by its exact `lengths`, drawn roughly: every crank top at 1.03 m instead
of 1 m, 0.01 m to the right.  (Each coupler's end on the previous crank, T, is drawn where
that crank's top is drawn: it then takes the top's exact place.)  The drawing
meets neither the lengths nor the joints; `sparsekin.analysis.assemble.start_discretization` brings
it onto them (the run's start).  Each size runs in a fresh process, so that its peak
resident memory is its own (less the same process's peak before the model was built).

Run: ``PYTHONPATH=. python3 benchmarks/measure_assembly.py [COPIES ...]`` (default 1000
10000 100000).
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time

MODEL = """
name = "rough four-bar chain"

[points]
O0 = [0.0, 0.0]
A0 = [0.01, 1.03]

[bodies.crank0]
origin = "O0"
points = ["O0", "A0"]
lengths = [["O0", "A0", 1.0]]

[[joints]]
type = "revolute"
bodies = ["crank0", "ground"]
at = "O0"

[[drivers]]
type = "rotational"
bodies = ["crank0", "ground"]
law = {{ type = "linear", rate = 1.0 }}

[units.loop.points]
T = [0.01, 1.03]
P = [1.0, 0.0]
Q = [1.01, 1.03]

[units.loop.bodies.crank]
origin = "P"
points = ["P", "Q"]
lengths = [["P", "Q", 1.0]]

[units.loop.bodies.coupler]
origin = "T"
points = ["T", "Q"]
lengths = [["T", "Q", 1.0]]

[[units.loop.joints]]
type = "revolute"
bodies = ["crank", "ground"]
at = "P"

[[units.loop.joints]]
type = "revolute"
bodies = ["crank", "coupler"]
at = "Q"

[[units.loop.joints]]
type = "revolute"
bodies = ["coupler", "prev.crank"]
at = "T"

[[repeat]]
unit = "loop"
count = {count}
prefix = "u"
offset = [1.0, 0.0]
first = {{ "prev.crank" = "crank0" }}
"""


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def measure(count: int) -> dict:
    """In this process: build, pattern and assembly of the chain of `count` loops."""
    import tempfile
    from pathlib import Path

    import numpy as np

    from sparsekin.analysis.assemble import start_discretization
    from sparsekin.engine.discretization import discretize
    from sparsekin.model.modelfile import load_model

    with tempfile.TemporaryDirectory() as folder:
        path, warm = Path(folder) / "chain.toml", Path(folder) / "warm.toml"
        path.write_text(MODEL.format(count=count))
        warm.write_text(MODEL.format(count=10))
        small = load_model(warm)  # the kernels compiled (or loaded from the cache) before the clock starts
        start_discretization(discretize(small), 0.0)
        before = _peak_mb()
        t0 = time.perf_counter()
        mechanism = load_model(path)
        t1 = time.perf_counter()
        drawn = discretize(mechanism)
        t2 = time.perf_counter()
        started = start_discretization(drawn, 0.0)
        t3 = time.perf_counter()
    moved = float(np.max(np.abs(started.constraints.initial_coordinates - drawn.constraints.initial_coordinates)))
    return {"bodies": mechanism.n_bodies, "load": t1 - t0, "pattern": t2 - t1, "assembly": t3 - t2,
            "largest change": moved, "peak memory MB": _peak_mb() - before,
            "assembled": started is not drawn}  # fmt: skip


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--one":
        print(json.dumps(measure(int(sys.argv[2]))))
        sys.exit(0)
    sizes = [int(a) for a in sys.argv[1:]] or [1000, 10000, 100000]
    print(f"{'bodies':>8} {'load s':>8} {'pattern s':>10} {'assembly s':>11} {'peak MB':>8}  largest change")
    for count in sizes:
        command = [sys.executable, __file__, "--one", str(count)]
        out = subprocess.run(command, capture_output=True, text=True, check=True)
        row = json.loads(out.stdout.strip().splitlines()[-1])
        print(f"{row['bodies']:>8} {row['load']:>8.3g} {row['pattern']:>10.3g} {row['assembly']:>11.3g} "
              f"{row['peak memory MB']:>8.0f}  {row['largest change']:.3g}")
