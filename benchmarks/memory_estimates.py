"""The memory estimate of ``sparsekin run`` against its measured peak (issue 28).

For a chain (the four-bar chain), a lattice (the parallelogram lattice, a grid repeat) and
an overconstrained grid (rotating squares: (n - 2)² redundant hinges) of about 10^4, 10^5
and 10^6 bodies, runs ``sparsekin run MODEL --steps 3`` (default outputs) in a new process
and compares the estimate it checks against the memory available before solving (the
parts it adds up, also recorded in ``run.json``; said on stderr by a wrapper, so that a
run stopped later, e.g. by the rank analysis, is measured too) with the peak resident
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


#: ``sparsekin run`` as its command runs it, saying on stderr the parts of the estimate it
#: checks (so that a run the rank analysis refuses later is measured too).
ESTIMATE_MARK = "ESTIMATE"
RUN_SAYING_ESTIMATE = f"""
import json, sys
from sparsekin.cli import main, run

checked = run.check_memory

def saying(parts, *rest):
    print("{ESTIMATE_MARK}", json.dumps(parts), file=sys.stderr, flush=True)
    return checked(parts, *rest)

run.check_memory = saying
sys.exit(main(sys.argv[1:]))
"""

FAMILIES = {"chain": chain, "lattice": lattice, "overconstrained": overconstrained}
if os.environ.get("FAMILIES"):  # e.g. FAMILIES=overconstrained
    FAMILIES = {name: FAMILIES[name] for name in os.environ["FAMILIES"].split(",")}


def measure(model: Path, out: Path) -> tuple[int | None, int | None, int | None, int, float, str]:
    """Run the model; (estimate, its part for the process as it was, peak, exit status,
    seconds, bodies) — peak None if killed."""
    command = [sys.executable, "-c", RUN_SAYING_ESTIMATE, "run", str(model), "--steps", "3", "--t-end", "0.01", "--out",
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
    errors = process.stderr.read().decode()
    said = [line.split(" ", 1)[1] for line in errors.splitlines() if line.startswith(ESTIMATE_MARK)]
    if said:  # what the run checked, also when it stops later (no run.json then)
        parts = json.loads(said[-1])
        estimate, process_part = sum(parts.values()), parts["the process"]
        bodies = next((what.split()[3] for what in parts if what.startswith("a model of ")), bodies)
    if process.returncode != 0:
        sys.stderr.write("\n".join(line for line in errors.splitlines() if not line.startswith(ESTIMATE_MARK))[-2000:] + "\n")
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
                refused = "" if status == 0 else f" (exit {status})"
                print(f"| {family} | {bodies} | {estimate / 2**20:.0f} MB ({process / 2**20:.0f} MB) | {peak / 2**20:.0f} MB{refused} | "
                      f"{estimate / peak:.2f} | {seconds:.1f} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main([int(float(size)) for size in sys.argv[1:]] or [10_000, 100_000, 1_000_000])
