"""Sizes: the memory a command needs, estimated before anything large is allocated, and
what the machine (or ``--max-memory``, or ``SPARSEKIN_MAX_MEMORY``) lets it use.

A size a command refuses is one line and exit status 2, before any work::

    sparsekin: error: needs about 74 GB (a model of 3e+06 bodies: 41 GB; 1001 samples kept: 33 GB),
    this machine has 24 GB available; write to Zarr with fewer outputs (--format zarr --no-coordinates) …

The estimates count what dominates at scale (measured against the peak resident memory of
``sparsekin run`` on chains, lattices and overconstrained grids of 10^4 to 10^6 bodies:
see ``benchmarks/memory_estimates.py``):

* the process as it is when the estimate is made (the interpreter, numpy, scipy, numba),
  read from the system, plus the kernels' compilation (`COMPILE_BYTES`);
* the model while it is solved: per coordinate (`BYTES_PER_COORDINATE`: the pattern, the
  Jacobian and its sparse LU factors, the solver's vectors) and per equation beyond the
  coordinates (`BYTES_PER_EXCESS_EQUATION`: an overconstrained model's redundancy);
* the samples kept in memory (every recorded value of every sample, 8 bytes each; one
  chunk for a Zarr store), and the CSV files' rows as Python numbers when they are written.

Before a model file is read, its repeats are counted (`check_model_document`): a model
whose copies alone would not fit is refused before they are built.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

from .common import CommandError

#: The environment variable that sets the memory a command may use (as ``--max-memory``).
MEMORY_VARIABLE = "SPARSEKIN_MAX_MEMORY"
#: Memory a run takes beside the process as it is at the estimate whatever the model: the
#: modules it imports then and its compiled kernels (read from numba's cache), bytes.
COMPILE_BYTES = 80 * 2**20
#: Memory of the model while it is solved, per coordinate, and per equation beyond the
#: coordinates (an overconstrained model's, whose redundant equations are found by a
#: factorization that offers the equations one by one), bytes.  Measured peaks
#: (``benchmarks/memory_estimates.py``, 10^4 to 10^6 bodies, benchmarks/RESULTS.md): a chain
#: takes about 510 per coordinate, a lattice 1290 (its factors fill in more), and one
#: constant between them keeps both within a factor 2 (estimate / peak 1.20–1.73 and
#: 0.75–1.09); an overconstrained grid of rotating squares about 1600 per coordinate with
#: 1 excess equation every 3 coordinates (1.09–1.11 up to 2.5·10^5 bodies; larger grids
#: are refused by the rank analysis, `sparsekin.analysis.rank.RankUndetermined`, at
#: 1.32–1.40 of their peak up to 10^6 bodies).
BYTES_PER_COORDINATE = 900
BYTES_PER_EXCESS_EQUATION = 2500
#: Memory of a model being built from its file, per element (body, joint, driver, load), bytes.
BYTES_PER_ELEMENT_BUILT = 500
#: A number of a CSV file as it is written: a Python float and its place in a list, bytes.
BYTES_PER_CSV_VALUE = 32
_UNITS = {"": 1, "b": 1, "k": 2**10, "kb": 2**10, "m": 2**20, "mb": 2**20, "g": 2**30, "gb": 2**30, "t": 2**40,
          "tb": 2**40, "kib": 2**10, "mib": 2**20, "gib": 2**30, "tib": 2**40}  # fmt: skip


@dataclass(frozen=True)
class MemoryLimit:
    """What a command may use, bytes, and where that comes from (``this machine has``,
    ``--max-memory is``, ...)."""

    bytes: int
    source: str


def parse_size(text: str, option: str) -> int:
    """A size such as ``8G``, ``512 MB``, ``1.5GiB`` or ``1000000`` (bytes), in bytes.

    Examples
    --------
    >>> parse_size("1.5G", "--max-memory")
    1610612736
    >>> parse_size("a lot", "--max-memory")
    Traceback (most recent call last):
    ...
    sparsekin.cli.common.CommandError: --max-memory: expected a size such as 8G, 512M or a number of bytes, got 'a lot'
    """
    match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([a-zA-Z]*)\s*", text)
    unit = match.group(2).lower() if match else None
    if match is None or unit not in _UNITS or not math.isfinite(float(match.group(1))) or float(match.group(1)) <= 0:
        raise CommandError(f"{option}: expected a size such as 8G, 512M or a number of bytes, got {text!r}")
    return int(float(match.group(1)) * _UNITS[unit])


def memory_limit(option: str | None) -> MemoryLimit:
    """The memory a command may use: ``--max-memory``, else `MEMORY_VARIABLE`, else what
    the machine has available (its free memory, the process's own included, within the
    limits of its cgroup and of ``ulimit -v``)."""
    if option is not None:
        return MemoryLimit(parse_size(option, "--max-memory"), "--max-memory allows")
    if os.environ.get(MEMORY_VARIABLE):
        return MemoryLimit(parse_size(os.environ[MEMORY_VARIABLE], MEMORY_VARIABLE), f"{MEMORY_VARIABLE} allows")
    own = _resident_bytes()
    limits = [MemoryLimit(available + own, "this machine has")
              for available in [_meminfo("MemAvailable")] if available is not None]  # fmt: skip
    cgroup = _cgroup_limit()
    if cgroup is not None:
        limits.append(MemoryLimit(cgroup, "the cgroup allows"))
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY:  # counts address space: less what is mapped but not resident
            limits.append(MemoryLimit(max(0, soft - (_virtual_bytes() - own)), "the address-space limit (ulimit -v) allows"))
    except (ImportError, OSError, ValueError):
        pass
    return min(limits, key=lambda limit: limit.bytes) if limits else MemoryLimit(2**62, "this machine has")


def limit_for(arguments) -> MemoryLimit:
    """The command's `memory_limit` (its ``--max-memory``), found once per command."""
    limit = getattr(arguments, "memory_limit", None)
    if limit is None:
        limit = memory_limit(getattr(arguments, "max_memory", None))
        arguments.memory_limit = limit
    return limit


def add_memory_argument(parser) -> None:
    """``--max-memory SIZE`` (of ``run``, ``sweep``, ``workspace`` and ``animate``)."""
    parser.add_argument("--max-memory", metavar="SIZE", help="the memory the command may use, e.g. 8G or 512M: "
                        "a larger run is refused before it starts (default: $" + MEMORY_VARIABLE + ", else the "
                        "memory this machine has available)")  # fmt: skip


def process_bytes() -> int:
    """The process's resident memory now, with the kernels' compilation to come."""
    return _resident_bytes() + COMPILE_BYTES


def model_bytes(n_coordinates: int, n_equations: int) -> int:
    """Memory of a model of these sizes while it is solved (beyond the process)."""
    return BYTES_PER_COORDINATE * n_coordinates + BYTES_PER_EXCESS_EQUATION * max(0, n_equations - n_coordinates)


def check_memory(parts: dict[str, int], limit: MemoryLimit, advice: str) -> int:
    """Refuse (a `CommandError`) when the `parts` (what, bytes) add up to more than `limit`;
    their sum otherwise."""
    needed = int(sum(parts.values()))
    if needed > limit.bytes:
        shown = "; ".join(f"{what}: {format_size(size)}" for what, size in parts.items() if size >= 0.01 * needed)
        raise CommandError(f"needs about {format_size(needed)} of memory ({shown}), {limit.source} "
                           f"{format_size(limit.bytes)}; {advice}")  # fmt: skip
    return needed


def format_size(size: float) -> str:
    """``74 GB``, ``1.5 GB``, ``310 MB`` (powers of 1024).

    >>> format_size(74 * 2**30), format_size(1.5 * 2**30), format_size(310 * 2**20)
    ('74 GB', '1.5 GB', '310 MB')
    """
    for unit, scale in (("TB", 2**40), ("GB", 2**30), ("MB", 2**20), ("kB", 2**10)):
        if size >= scale:
            value = size / scale
            return f"{value:.2g} {unit}" if value < 10 else f"{value:.0f} {unit}"
    return f"{int(size)} bytes"


def _meminfo(key: str) -> int | None:
    try:
        with open("/proc/meminfo", encoding="ascii") as file:
            for line in file:
                if line.startswith(f"{key}:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    if key == "MemAvailable" and hasattr(os, "sysconf"):  # elsewhere: the physical memory
        try:
            return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (OSError, ValueError):
            pass
    return None


def _cgroup_limit() -> int | None:
    """What the process's cgroup (v2) lets it have still: its limit less what it holds."""
    try:
        with open("/sys/fs/cgroup/memory.max", encoding="ascii") as file:
            text = file.read().strip()
        if text == "max":
            return None
        with open("/sys/fs/cgroup/memory.current", encoding="ascii") as file:
            current = int(file.read().strip())
        return int(text) - current + _resident_bytes()
    except (OSError, ValueError):
        return None


def _statm(field: int) -> int:
    try:
        with open("/proc/self/statm", encoding="ascii") as file:
            return int(file.read().split()[field]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError, AttributeError):
        return 0


def _resident_bytes() -> int:
    return _statm(1)


def _virtual_bytes() -> int:
    return _statm(0)


# --------------------------------------------------------------------------- what each command needs
def check_model_document(document: dict, limit: MemoryLimit) -> None:
    """Refuse a model whose elements (its own and its repeats' copies: `count` of a chain,
    ``ni × nj`` of a grid) would not fit in `limit` once built.  `document` is the parsed
    model file; what is not as the contract says is left to the reader to report."""
    units = document.get("units") if isinstance(document.get("units"), dict) else {}
    elements, copies = _elements(document), []
    for repeat in document.get("repeat", []) if isinstance(document.get("repeat"), list) else []:
        if not isinstance(repeat, dict) or not isinstance(units.get(repeat.get("unit")), dict):
            continue
        count = repeat.get("count")
        counts = count if isinstance(count, list) else [count]
        if not counts or not all(isinstance(n, int) and not isinstance(n, bool) and n > 0 for n in counts):
            continue
        n_copies = math.prod(counts)
        elements += n_copies * _elements(units[repeat["unit"]])
        copies.append(f"{' × '.join(map(str, counts))} copies of unit {repeat['unit']}")
    if copies:
        check_memory({"the process": process_bytes(), f"the model ({', '.join(copies)}), built": BYTES_PER_ELEMENT_BUILT
                      * elements}, limit, "give the repeats fewer copies, or run on a machine with more memory")  # fmt: skip


def _elements(table: dict) -> int:
    """Bodies, joints, drivers and loads declared in a model's (or a unit's) table."""
    bodies = table.get("bodies")
    count = len(bodies) if isinstance(bodies, dict) else 0
    return count + sum(len(table[kind]) for kind in ("joints", "drivers", "loads") if isinstance(table.get(kind), list))


def check_times(steps: int, limit: MemoryLimit) -> None:
    """Refuse a number of samples whose times alone would not fit (16 bytes each: the time
    and the count of Newton corrections)."""
    check_memory({"the process": process_bytes(), f"{steps} sample times": 16 * steps}, limit,
                 "give fewer --steps")  # fmt: skip


def run_parts(mechanism, settings, force_columns: int | None = None) -> dict[str, int]:
    """What ``run`` (and ``animate``) hold at their peak, bytes: the process, the model, the
    samples kept and the CSV rows while they are written."""
    n_times = settings.times.size
    points, joints = len(settings.point_names), len(settings.joint_indices)
    forces = 0
    if settings.forces is not None:
        elements = (mechanism.n_drivers + mechanism.n_joints) if settings.forces == "all" else len(settings.forces)
        forces = 2 * elements if force_columns is None else force_columns
    columns = 1 + 6 * points + 3 * joints + forces  # the CSV files' numbers per sample
    coordinates = 3 * mechanism.n_coordinates if settings.coordinates else 0
    per_sample = 8 * (1 + coordinates + (0 if settings.coordinates else columns))
    if settings.format == "zarr":
        kept = "a chunk of samples"
        samples = 3 * per_sample * min(n_times, max(1, 64 * 2**20 // per_sample))  # the chunk, and its copies
        rows = 0
    else:
        kept = f"{n_times} samples kept"
        samples = per_sample * n_times
        rows = (8 + BYTES_PER_CSV_VALUE) * n_times * max(1 + 6 * points, 1 + 3 * joints, 1 + forces)
    parts = {
        "the process": process_bytes(),
        f"a model of {mechanism.n_bodies} bodies": model_bytes(mechanism.n_coordinates, mechanism.n_equations),
        kept: samples,
    }
    if rows:
        parts["the CSV rows"] = rows
    return {what: int(size) for what, size in parts.items()}


RUN_ADVICE = ("write to Zarr with fewer outputs (--format zarr, --no-coordinates, --points, --joints), give fewer "
              "--steps, or --max-memory to allow more")  # fmt: skip


def animation_parts(frames: int, gif: bool, pixels: int) -> dict[str, int]:
    """What an animation holds besides the run: a GIF keeps every frame (a byte a pixel,
    and its frame in colour while it is made), an MP4 one frame."""
    return {f"{frames} frames": (frames if gif else 1) * pixels + 4 * pixels}


def workspace_parts(mechanism, n_points: int) -> dict[str, int]:
    """What ``workspace`` holds: the process, the model, and each grid point's coordinates,
    position and status."""
    return {
        "the process": process_bytes(),
        f"a model of {mechanism.n_bodies} bodies": model_bytes(mechanism.n_coordinates, mechanism.n_equations),
        f"{n_points} grid points": n_points * (8 * mechanism.n_coordinates + 16 + 4 * 16),
    }


def sweep_parts(mechanism, n_variants: int, n_columns: int) -> dict[str, int]:
    """What the process running ``sweep`` holds: the model, and each variant's values,
    status and stop times (the recorded motion goes to the store, task by task)."""
    return {
        "the process": process_bytes(),
        f"a model of {mechanism.n_bodies} bodies": model_bytes(mechanism.n_coordinates, mechanism.n_equations),
        f"{n_variants} variants": n_variants * (8 * n_columns + 4 * 14 + 16 + 100),
    }
