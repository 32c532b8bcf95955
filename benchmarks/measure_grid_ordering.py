"""Does a tiled first pivot order serve a grid?  SuperLU's COLAMD against the copies' own order.

Usage: ``python3 benchmarks/measure_grid_ordering.py SIDE [SIDE ...]`` (e.g. ``30 70 200``)

For `sparsekin.testset.lattice(SIDE, SIDE)` at its drawing, factor ``jacobian.T`` with
SuperLU twice: with COLAMD (what `RefactorSolver`'s first factorization uses) and with the
natural order — the equations and coordinates copy by copy, row by row, which is what a
tiled order (`sparsekin.engine.ordering`, built for chains) repeats.  Prints the median
time of 3 factorizations and the fill, nnz(L + U) / nnz(A), of each (docs/design-notes.md,
"Grids").
"""

from __future__ import annotations

import sys
import time

import numpy as np
from scipy.sparse.linalg import splu

from sparsekin.engine.discretization import Discretization
from sparsekin import testset
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.pattern import build_pattern

#: Factorizations per measurement (the median is printed).
ROUNDS = 3


def main(sides: list[int]) -> None:
    for side in sides:
        mechanism = testset.lattice(side, side)
        pattern = build_pattern(mechanism)
        assembler = Assembler(Discretization(mechanism, pattern))
        assembler.set_time(0.0)
        assembler.fill_residual_jacobian(pattern.initial_coordinates)
        matrix = assembler.jacobian.T.tocsc()
        for order in ("COLAMD", "NATURAL"):
            seconds = []
            for _ in range(ROUNDS):
                start = time.perf_counter()
                lu = splu(matrix, permc_spec=order)
                seconds.append(time.perf_counter() - start)
            fill = (lu.L.nnz + lu.U.nnz) / matrix.nnz
            print(f"lattice {side}x{side} ({mechanism.n_bodies} bodies): {order:8s} "
                  f"{np.median(seconds) * 1e3:9.1f} ms  nnz(L+U)/nnz(A) {fill:5.1f}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main([int(side) for side in sys.argv[1:]] or [30, 70])
