"""A Task 5 amplitude sweep on Dask against a serial loop, in the same run.

Both actuators' amplitude takes ``linspace(0.03, 0.07, n)`` (above 0.054 m the linkage
locks up, which is a result), each variant 0 … 10 s at 10 ms (1001 samples) recording
point K.  ``--sizes=full``: 1000 variants; ``smoke`` (the test suite): 8 variants of 101
samples.

* ``serial``: a Python loop over `solve_kinematics` (`measure_serial_sweep.py`, in a
  process with the single BLAS thread Dask gives its workers; its own timing of the loop,
  after a warm-up);
* ``dask-1``, ``dask-2``: `sparsekin.sweep` on a local cluster of 1 and 2 single-threaded
  worker processes, started and warmed up before the timing; the time is the whole call
  (layout, tasks, results gathered in memory).

`make_results.py` reports variants per second and the parallel efficiency
(serial time / (workers × Dask time)).
"""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

import dask  # noqa: E402

import sparsekin as sk  # noqa: E402

SIZES = {"smoke": (8, 101), "full": (1000, 1001)}
TASK5 = Path(__file__).resolve().parent.parent / "examples" / "task5.toml"
SCRIPT = Path(__file__).resolve().parent / "measure_serial_sweep.py"
BOTH = ("drivers[0].law.amplitude", "drivers[1].law.amplitude")


@pytest.fixture
def size(request):
    return SIZES[request.config.getoption("--sizes")]


@pytest.mark.parametrize("runner", ["serial", "dask-1", "dask-2"])
def test_task5_amplitude_sweep(benchmark, runner, size):
    n_variants, n_samples = size
    info = {"runner": runner, "variants": n_variants, "samples": n_samples}
    if runner == "serial":
        environment = dict(os.environ, **{k: str(v) for k, v in dask.config.get(
            "distributed.nanny.pre-spawn-environ").items()})  # fmt: skip

        def measure():
            done = subprocess.run([sys.executable, str(SCRIPT), str(n_variants), str(n_samples)], env=environment,
                                  check=True, capture_output=True, text=True)  # fmt: skip
            return json.loads(done.stdout)

        measured = benchmark.pedantic(measure, rounds=1, iterations=1)
        info |= {"workers": 0, "seconds": measured["seconds"], "locked": measured["locked"]}
    else:
        workers = int(runner.split("-")[1])
        task5 = sk.load_model(TASK5)
        times = np.linspace(0.0, 10.0, n_samples)
        grid = {BOTH: np.linspace(0.03, 0.07, n_variants)}
        with distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                                      silence_logs=logging.ERROR) as cluster, distributed.Client(cluster) as client:  # fmt: skip
            client.wait_for_workers(workers, timeout=60)
            sk.sweep(
                task5,
                {BOTH: [0.05] * workers},
                times[:50],
                client,
                variants_per_task=1,
                coordinates=False,
                points=["K"],
            )  # fmt: skip  (warm-up: each worker loads numba's cache)

            def measure():
                begin = time.perf_counter()
                result = sk.sweep(task5, grid, times, client, coordinates=False, points=["K"])
                return result, time.perf_counter() - begin

            result, seconds = benchmark.pedantic(measure, rounds=1, iterations=1)
        info |= {"workers": workers, "seconds": seconds, "tasks": result.n_tasks,
                 "locked": int((result.status == "singular").sum())}  # fmt: skip
        assert (result.status != "").all()
    info["variants_per_second"] = n_variants / info["seconds"]
    benchmark.extra_info.update(info)
