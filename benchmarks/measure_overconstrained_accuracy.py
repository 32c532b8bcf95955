"""Errors of overconstrained models against their closed forms, on every linear-solver path.

Usage: ``python3 benchmarks/measure_overconstrained_accuracy.py [FAMILY [SIZES...]]``
(``--paths auto,superlu`` to choose the paths).  Families (`FAMILIES`):

* ``squares N`` — `testset.rotating_squares` (N × N unit squares);
* ``rectangles N`` — `testset.rotating_rectangles` (N × N rectangles of 1 m × 0.6 m);
* ``rectangles_wide N`` — the same, N × (N // 2 + 1) rectangles;
* ``motif_file N`` — `testset.rotating_rectangles_motif` (N × N rectangles of 1 m × 0.6 m
  in 2 × 2 motifs, N even) written to a grid file and read back;
* ``motif_flat N`` — the same model written flat, element by element (`Mechanism.expanded`).

Each model is solved at `TIMES` (one period of the driver's sine, 7 samples) by
`solve_kinematics` with each linear solver, and the largest error of the positions,
velocities and accelerations against `testset.rotating_lattice_motion` is printed relative
to the largest value of that quantity (x, y in m and the angles in rad together), one
line of Markdown per model and path.  Without arguments: every size of the issue 26 table
(squares 3…100, rectangles 3…60), the dense path up to `DENSE_MAX_COORDINATES`.
"""

from __future__ import annotations

import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

_HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(_HERE.parent)]  # sparsekin when not installed

from sparsekin import RedundantConstraintWarning, load_model, save_model, solve_kinematics, testset  # noqa: E402

#: The samples: a period of the driver (θ = 0.3 + 0.2 sin t).
TIMES = np.linspace(0.0, 2 * np.pi, 7)
PATHS = ("auto", "refactor", "superlu", "dense")
#: The dense path (a dense LU of the reduced system at every solve, as no compiled loop
#: takes redundant equations) only up to this many coordinates: 24 s at 4 800.
DENSE_MAX_COORDINATES = 1200
RECTANGLE = (1.0, 0.6)


def _motif_file(n: int):
    mechanism = testset.rotating_rectangles_motif(n // 2, n // 2, *RECTANGLE)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "motif.toml"
        save_model(mechanism, path)
        return load_model(path)


#: family -> (builder of size N, (ni, nj, width, height), name of body (i, j))
FAMILIES = {
    "squares": (testset.rotating_squares, lambda n: (n, n, 1.0, 1.0), lambda i, j: f"s{i}_{j}.sq"),
    "rectangles": (lambda n: testset.rotating_rectangles(n, n, *RECTANGLE), lambda n: (n, n, *RECTANGLE),
                   lambda i, j: f"r{i}_{j}.rect"),
    "rectangles_wide": (lambda n: testset.rotating_rectangles(n, n // 2 + 1, *RECTANGLE),
                        lambda n: (n, n // 2 + 1, *RECTANGLE), lambda i, j: f"r{i}_{j}.rect"),
    "motif_file": (_motif_file, lambda n: (n, n, *RECTANGLE), lambda i, j: f"m{i // 2}_{j // 2}." + "abcd"[i % 2 + 2 * (j % 2)]),
    "motif_flat": (lambda n: _motif_file(n).expanded(), lambda n: (n, n, *RECTANGLE),
                   lambda i, j: f"m{i // 2}_{j // 2}." + "abcd"[i % 2 + 2 * (j % 2)]),
}  # fmt: skip
#: Sizes measured without arguments.
DEFAULT_SIZES = {"squares": range(3, 101), "rectangles": range(3, 61), "motif_file": range(4, 61, 4),
                 "motif_flat": range(4, 61, 4), "rectangles_wide": range(4, 61, 4)}  # fmt: skip


def errors(family: str, n: int, paths=PATHS) -> list[dict]:
    """One row per path: the relative errors of positions, velocities, accelerations."""
    build, shape, name = FAMILIES[family]
    ni, nj, width, height = shape(n)
    mechanism = build(n)
    columns = np.array([[[3 * mechanism.body_index(name(i, j)) + k for k in range(3)] for j in range(nj)]
                        for i in range(ni)])  # fmt: skip
    exact = testset.rotating_lattice_motion(ni, nj, TIMES, width, height)
    rows = []
    for path in paths:
        if path == "dense" and mechanism.n_coordinates > DENSE_MAX_COORDINATES:
            continue
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RedundantConstraintWarning)
            result = solve_kinematics(mechanism, TIMES, linear_solver=path)
        seconds = time.perf_counter() - start
        row = {"family": family, "size": f"{ni}×{nj}", "coordinates": mechanism.n_coordinates, "path": path,
               "taken": result.linear_solver, "seconds": seconds}  # fmt: skip
        for label, solved, expected in zip(("positions", "velocities", "accelerations"),
                                           (result.coordinates, result.velocities, result.accelerations), exact):  # fmt: skip
            row[label] = float(np.abs(solved[:, columns] - expected).max() / np.abs(expected).max())
        rows.append(row)
    return rows


def main(argv: list[str]) -> None:
    paths = PATHS
    if argv and argv[0].startswith("--paths"):
        paths = tuple(argv[0].split("=", 1)[1].split(","))
        argv = argv[1:]
    cases = ([(argv[0], int(size)) for size in argv[1:]] if argv else
             [(family, size) for family, sizes in DEFAULT_SIZES.items() for size in sizes])  # fmt: skip
    print("| model | size | coordinates | path | positions | velocities | accelerations | seconds |")
    print("|---|---|---|---|---|---|---|---|")
    worst = {}
    for family, size in cases:
        for row in errors(family, size, paths):
            print(f"| {row['family']} | {row['size']} | {row['coordinates']} | {row['path']} ({row['taken']}) | "
                  f"{row['positions']:.1e} | {row['velocities']:.1e} | {row['accelerations']:.1e} | "
                  f"{row['seconds']:.2f} |", flush=True)  # fmt: skip
            for label in ("positions", "velocities", "accelerations"):
                worst[family, label] = max(worst.get((family, label), 0.0), row[label])
    print()
    for (family, label), value in sorted(worst.items()):
        print(f"largest {label} error, {family}: {value:.1e}")


if __name__ == "__main__":
    main(sys.argv[1:])
