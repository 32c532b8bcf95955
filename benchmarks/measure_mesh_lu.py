"""Time every sparse LU option on one Jacobian of a test-set model, in a fresh process.

Usage: ``python3 benchmarks/measure_mesh_lu.py FAMILY BODIES [OPTION ...]``.  Builds the
model (`families.build`), fills its Jacobian at t = 0 at the drawing, and for each option
times the first factorization (everything a first `factor` of a new pattern does:
ordering, analysis, numeric factorization), a refactorization with the same values where
the option has one, and a solve (median of three); it checks each solution by its backward error
``||J x - b||_inf / (||J||_inf ||x||_inf + ||b||_inf)``.  Prints one JSON object per
option on its own line.  Options (default: all that are installed):

* ``superlu`` — scipy's SuperLU with COLAMD (`SuperLUSolver`);
* ``superlu-metis`` — `SuperLUSolver(ordering="metis")`: SuperLU on J's columns in METIS's
  order of the bodies (``permc_spec="NATURAL"``); its "refactorization" is a fresh SuperLU
  factorization in the order it holds, and ``ordering_s`` times that order alone;
* ``dissection`` — `DissectionSolver`: SuperLU on J's columns in a geometric nested
  dissection of the bodies, solves by numba kernels on its factors; its
  "refactorization" is a fresh SuperLU factorization in the order it holds, and
  ``ordering_s`` times that order alone;
* ``refactor-metis`` — `RefactorSolver(ordering="metis")`;
* ``supernodal`` — `SupernodalSolver`: the multifrontal LU in numba kernels (BLAS for the
  fronts' updates) in the same dissection, rows by a matching; its refactorization is the
  numeric factorization on its held analysis (``ordering_s``: the order alone);
* ``pardiso`` — MKL Pardiso through `pypardiso` (not a dependency; skipped when missing).

``--generic`` takes the Jacobian at a generic configuration instead of the drawing (the
drawn coordinates plus 0.05 times standard normal numbers, seed 0: no entry exactly zero,
as at a refactorization later in a run); ``--run=LABEL`` adds ``run`` (the label and the
load average) to each line.  ``solve_two_s`` times one call with two right-hand sides.
Run it with ``OPENBLAS_NUM_THREADS=1`` (one thread, as the others; on a loaded machine
OpenBLAS's threads made `SupernodalSolver`'s fronts several times slower).

The solves are of ``J x = b``; the factorizations of ``A = J.T`` (the CSC view of the CSR
Jacobian), except ``superlu-metis``'s, of J's CSC copy.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np

_HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(_HERE), str(_HERE.parent)]  # the families, and sparsekin when not installed

from families import build  # noqa: E402

from sparsekin.engine.assembly import Assembler  # noqa: E402
from sparsekin.engine.discretization import Discretization  # noqa: E402
from sparsekin.engine.pattern import build_pattern  # noqa: E402

OPTIONS = ("superlu", "dissection", "supernodal", "superlu-metis", "refactor-metis", "pardiso")


def _peak_rss_bytes() -> int:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    return 0


def jacobian_at_drawing(family: str, bodies: int, perturbation: float = 0.0):
    """The CSR Jacobian of the model at t = 0 at its drawing (moved by `perturbation` times
    standard normal numbers, seed 0, if given), the model's size, and where its bodies are
    drawn (their origins, shape (bodies, 2))."""
    mechanism = build(family, bodies)
    pattern = build_pattern(mechanism)
    assembler = Assembler(Discretization(mechanism, pattern))
    assembler.set_time(0.0)
    coordinates = pattern.initial_coordinates
    if perturbation:
        coordinates = coordinates + perturbation * np.random.default_rng(0).standard_normal(coordinates.size)
    assembler.fill_residual_jacobian(coordinates)
    return assembler.jacobian, mechanism.n_bodies, pattern.initial_coordinates.reshape(-1, 3)[:, :2].copy()


def backward_error(jacobian, x: np.ndarray, b: np.ndarray) -> float:
    norm = float(abs(jacobian).sum(axis=1).max())
    return float(np.abs(jacobian @ x - b).max() / (norm * np.abs(x).max() + np.abs(b).max()))


def _timed(function, *args):
    start = time.perf_counter()
    result = function(*args)
    return time.perf_counter() - start, result


def _median_time(function, *args, repeats: int = 3):
    """The median time of `repeats` calls, and the last call's result."""
    times, result = [], None
    for _ in range(repeats):
        seconds, result = _timed(function, *args)
        times.append(seconds)
    return float(np.median(times)), result


def _solver_option(solver, jacobian, b, refactor: bool = True) -> dict:
    first, _ = _timed(solver.factor, jacobian)
    row = {"first_factorization_s": first}
    if refactor:
        row["refactorization_s"], _ = _timed(solver.factor, jacobian)
    row["solve_s"], x = _median_time(solver.solve, b)
    row["backward_error"] = backward_error(jacobian, x, b)
    two = np.stack([b, b[::-1]], axis=1)
    row["solve_two_s"], x2 = _median_time(solver.solve, two)
    errors = [backward_error(jacobian, x2[:, c], two[:, c]) for c in (0, 1)]
    row["backward_error"] = max(row["backward_error"], *errors)
    if hasattr(solver, "nnz_factors"):
        row["nnz_factors"] = solver.nnz_factors
    for counter in ("n_factorizations", "n_refactorizations", "n_fallbacks"):
        if hasattr(solver, counter):
            row[counter] = getattr(solver, counter)
    return row


def measure(option: str, jacobian, b: np.ndarray, points: np.ndarray) -> dict | None:
    from sparsekin.engine import linalg

    if option == "superlu":
        return _solver_option(linalg.SuperLUSolver(), jacobian, b, refactor=False)
    if option in ("dissection", "supernodal"):
        from sparsekin.engine.dissection import DissectionSolver
        from sparsekin.engine.ordering import geometric_column_order
        from sparsekin.engine.supernodal import SupernodalSolver

        ordering_s, _ = _timed(lambda: geometric_column_order(jacobian, points, block=linalg.COORDINATES_PER_BODY))
        solver = DissectionSolver(points) if option == "dissection" else SupernodalSolver(points)
        return dict(_solver_option(solver, jacobian, b), ordering_s=ordering_s)
    if option == "refactor-metis":
        return _solver_option(linalg.RefactorSolver(ordering="metis"), jacobian, b)
    if option == "superlu-metis":
        from sparsekin.engine.ordering import fill_reducing_column_order

        block = linalg.COORDINATES_PER_BODY if jacobian.shape[1] % linalg.COORDINATES_PER_BODY == 0 else 1
        ordering_s, _ = _timed(lambda: fill_reducing_column_order(jacobian, method="metis", block=block))
        solver = linalg.SuperLUSolver(ordering="metis")
        row = _solver_option(solver, jacobian, b)  # its refactorization: SuperLU again, in the held order
        return dict(row, ordering_s=ordering_s)
    if option == "pardiso":
        os.environ.setdefault("MKL_NUM_THREADS", "1")  # single thread, as the others
        try:
            import pypardiso
        except ImportError:
            return None
        solver = pypardiso.PyPardisoSolver()
        matrix = jacobian.tocsr()
        factor_s, _ = _timed(solver.factorize, matrix)
        solve_s, x = _median_time(solver.solve, matrix, b)
        return {"first_factorization_s": factor_s, "solve_s": solve_s, "backward_error": backward_error(jacobian, x, b)}
    raise ValueError(f"unknown option {option!r}; expected one of {', '.join(OPTIONS)}")


def main(argv: list[str]) -> None:
    flags = [a for a in argv if a.startswith("--")]
    argv = [a for a in argv if not a.startswith("--")]
    perturbation = 0.05 if "--generic" in flags else 0.0
    labels = [f.split("=", 1)[1] for f in flags if f.startswith("--run=")]
    family, bodies = argv[0], int(argv[1])
    options = argv[2:] or OPTIONS
    small, _, small_points = jacobian_at_drawing(family, 100)  # compile the kernels outside the timings
    for option in options:
        measure(option, small, np.ones(small.shape[0]), small_points)
    jacobian, n_bodies, points = jacobian_at_drawing(family, bodies, perturbation)
    b = np.random.default_rng(0).standard_normal(jacobian.shape[0])
    for option in options:
        row = measure(option, jacobian, b, points)
        if row is None:
            continue
        row.update(family=family, bodies=n_bodies, unknowns=jacobian.shape[0], nnz=int(jacobian.nnz), option=option,
                   pose="generic" if perturbation else "drawing", peak_rss_bytes=_peak_rss_bytes())  # fmt: skip
        if labels:
            row = {"run": f"{labels[0]}, load {os.getloadavg()[0]:.2f}", **row}
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
