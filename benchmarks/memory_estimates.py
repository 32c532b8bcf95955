"""The memory estimate of ``sparsekin run`` against its measured peak (issue 28).

For a chain (the four-bar chain), a lattice (the parallelogram lattice, a grid repeat) and
an overconstrained grid (rotating squares: (n - 2)² redundant hinges) of about 10^4, 10^5
and 10^6 bodies, runs ``sparsekin run MODEL --steps 3`` (default outputs) in a new process
and compares the estimate it records in ``run.json`` (``memory_estimate_bytes``: what the
command checked against the memory available before solving) with the peak resident
memory of the process (``ru_maxrss`` from ``wait4``).  A watchdog kills a run above
`CAP_BYTES` (the run is then reported as not measured).

    python3 benchmarks/memory_estimates.py [SIZES ...]     # default: 1e4 1e5 1e6

Prints a Markdown table; the ratio estimate / peak should lie within 0.5 … 2.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
#: A run above this resident memory is killed (the machine is shared).
CAP_BYTES = int(7.5 * 2**30)


def chain(bodies: int) -> tuple[str, str, str]:
    """The four-bar chain: 1 + 2 per copy."""
    return "four_bar_chain.toml", "count = 1000", f"count = {max(1, (bodies - 1) // 2)}"


def lattice(bodies: int) -> tuple[str, str, str]:
    """The parallelogram lattice: 2 bodies per copy of an n × n grid."""
    n = max(2, round(math.sqrt(bodies / 2)))
    return "lattice.toml", "count = [9, 6]", f"count = [{n}, {n}]"


def overconstrained(bodies: int) -> tuple[str, str, str]:
    """Rotating squares: 4 per copy of an n × n grid, (2n - 2)² hinges too many."""
    n = max(2, round(math.sqrt(bodies / 4)))
    return "rotating_squares.toml", "count = [4, 4]", f"count = [{n}, {n}]"


FAMILIES = {"chain": chain, "lattice": lattice, "overconstrained": overconstrained}
if os.environ.get("FAMILIES"):  # e.g. FAMILIES=overconstrained
    FAMILIES = {name: FAMILIES[name] for name in os.environ["FAMILIES"].split(",")}


def measure(model: Path, out: Path) -> tuple[int | None, int | None, int | None, int, float, str]:
    """Run the model; (estimate, its part for the process as it was, peak, exit status,
    seconds, bodies) — peak None if killed."""
    command = [sys.executable, "-m", "sparsekin", "run", str(model), "--steps", "3", "--t-end", "0.01", "--out",
               str(out), "--quiet"]  # fmt: skip
    start = time.monotonic()
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               env=dict(os.environ, PYTHONPATH=str(ROOT)))  # fmt: skip
    killed, ended = [], threading.Event()

    def watch() -> None:  # not process.poll(): it would reap the process before wait4
        while not ended.is_set():
            try:
                with open(f"/proc/{process.pid}/status") as status:
                    rss = next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmRSS:"))
            except (OSError, StopIteration):
                return
            if rss > CAP_BYTES:
                killed.append(rss)
                process.send_signal(signal.SIGKILL)
                return
            time.sleep(0.05)

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    _, status, usage = os.wait4(process.pid, 0)
    ended.set()
    process.returncode = os.waitstatus_to_exitcode(status)
    output = process.stdout.read().decode()
    watcher.join()
    seconds = time.monotonic() - start
    bodies = output.split(":", 1)[1].split(" bodies")[0].strip() if " bodies" in output else "?"
    estimate = process_part = None
    if (out / "run.json").exists():
        record = json.loads((out / "run.json").read_text())
        estimate, process_part = record.get("memory_estimate_bytes"), record["memory_estimate_parts"]["the process"]
    if process.returncode != 0:
        sys.stderr.write(process.stderr.read().decode()[-2000:])
    return estimate, process_part, (None if killed else usage.ru_maxrss * 1024), process.returncode, seconds, bodies


def main(sizes: list[int]) -> None:
    print("| family | bodies | estimate (of which the process then) | measured peak | estimate / peak | run, s |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as base:
        for family, make in FAMILIES.items():
            for size in sizes:
                example, old, new = make(size)
                text = (EXAMPLES / example).read_text()
                assert old in text
                model = Path(base) / f"{family}_{size}.toml"
                model.write_text(text.replace(old, new))
                estimate, process, peak, status, seconds, bodies = measure(model, Path(base) / f"out_{family}_{size}")
                if peak is None or estimate is None:
                    why = f"killed above {CAP_BYTES / 2**30:.1f} GB" if peak is None else f"exit {status}"
                    print(f"| {family} | {bodies} | {(estimate or 0) / 2**20:.0f} MB | not measured ({why}) | | "
                          f"{seconds:.1f} |", flush=True)  # fmt: skip
                    continue
                print(f"| {family} | {bodies} | {estimate / 2**20:.0f} MB ({process / 2**20:.0f} MB) | {peak / 2**20:.0f} MB | "
                      f"{estimate / peak:.2f} | {seconds:.1f} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main([int(float(size)) for size in sys.argv[1:]] or [10_000, 100_000, 1_000_000])
