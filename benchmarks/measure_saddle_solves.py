"""What bounds a solve of the N-four-bar chain's saddle matrix: kernel variants, one process.

Issue 25: the large path of forward dynamics spends ~40 % of a step in solves of its held
LU (`RefactorSolver`, `_lu_kernels.solve_lu_transposed`).  The chain's iteration matrix
(captured from `GeneralizedAlphaStepper` on `n_four_bar`) is factored once; then, called
in turn in one process, caches flushed (a 64 MB write) before each call, the median of 15
calls per round, the median over rounds:

* ``structural`` — main's solve: the structural factors, their exact zeros included;
* ``compact`` — the same factors without their exact zeros, rows as one-byte offsets
  (`_compact_lu_kernels`, what `RefactorSolver` solves with after a few solves);
* ``pair_structural``, ``pair_compact`` — two right-hand sides in one pass;
* ``split`` — the columns ordered part 1, part 2, separator (breadth-first levels of the
  column intersection graph, the middle level the separator, each part from its outer end
  in; SuperLU's partial pivoting on that order, the parts' columns then moved before the
  separator's), so that L and U are block triangular, and a kernel that walks the two
  parts' columns interleaved: two independent chains of dependent additions;
* ``split_plain`` — those factors with the plain kernel;
* ``no_dependency`` — the plain kernel with every dot product reading another array than
  the one it writes: no chain of dependent additions at all, the bound of any reordering
  that only breaks dependencies;
* ``empty_columns`` — the plain kernel with every column empty: the permutations and the
  per-column work alone;
* ``stream`` — a sum over the structural factors' values and indices: reading them from
  memory, no solve.

Command::

    python3 benchmarks/measure_saddle_solves.py --bodies 10001 100001

prints one JSON line per size (times in ms, the load).
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
from numba import njit

_wide = np.int64


def chain_saddle_matrix(bodies: int):
    """The iteration matrix the dynamics of the (bodies - 1) / 2 four-bar chain factors first."""
    from sparsekin.solve.dynamics import GeneralizedAlphaStepper
    from sparsekin.testset import n_four_bar

    stepper = GeneralizedAlphaStepper(n_four_bar((bodies - 1) // 2), 1e-3)
    stepper.start(0.0)
    matrices = []
    factor = stepper.solver.factor
    stepper.solver.factor = lambda matrix: (matrices.append(matrix.copy()), factor(matrix))
    k = 0
    while not matrices:
        k += 1
        stepper.advance(k * 1e-3)
    return matrices[0]


@njit(cache=True)
def _levels(col_indptr, col_rows, row_indptr, row_cols, start, level, queue):
    """Breadth-first levels of A's columns through its rows; returns the columns reached."""
    level[:] = -1
    row_seen = np.zeros(row_indptr.size - 1, dtype=np.bool_)
    level[start], queue[0] = 0, start
    head, tail = 0, 1
    while head < tail:
        c = queue[head]
        head += 1
        for p in range(col_indptr[c], col_indptr[c + 1]):
            r = col_rows[p]
            if not row_seen[r]:
                row_seen[r] = True
                for q in range(row_indptr[r], row_indptr[r + 1]):
                    d = row_cols[q]
                    if level[d] < 0:
                        level[d] = level[c] + 1
                        queue[tail] = d
                        tail += 1
    return tail


def split_column_order(matrix):
    """(order, n1, n2): part 1, part 2 (from its far end), the separator level last."""
    n = matrix.shape[1]
    rows = matrix.tocsr()
    level, queue = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    _levels(matrix.indptr, matrix.indices, rows.indptr, rows.indices, 0, level, queue)
    assert _levels(matrix.indptr, matrix.indices, rows.indptr, rows.indices, int(queue[-1]), level, queue) == n
    counts = np.bincount(level)
    before = np.cumsum(counts) - counts
    middle = int(np.argmax(np.minimum(before, n - before - counts)))
    levels = level[queue]
    first, second = queue[levels < middle], queue[levels > middle][::-1]
    return np.concatenate([first, second, queue[levels == middle]]), first.size, second.size


def split_solver(jacobian):
    """A `RefactorSolver` on the split order (its suggested pivots) and the parts' sizes."""
    from sparsekin.engine.linalg import RefactorSolver, _splu

    matrix = jacobian.T.tocsc()
    order, n1, n2 = split_column_order(matrix)
    lu = _splu(matrix[:, order], "NATURAL", pivots_only=True)
    perm_c = np.empty(order.size, dtype=np.int64)
    perm_c[order] = lu.perm_c  # SuperLU postorders its elimination tree: the parts come apart again
    part = np.empty(order.size, dtype=np.int64)
    part[order] = np.repeat([0, 1, 2], [n1, n2, order.size - n1 - n2])
    part_at_step = np.empty_like(part)
    part_at_step[perm_c] = part
    moved = np.empty_like(part)
    moved[np.argsort(part_at_step, kind="stable")] = np.arange(part.size)  # parts first, in their order
    solver = RefactorSolver(lean=True)
    solver.suggest(moved[lu.perm_r], moved[perm_c])
    solver.factor(jacobian)
    return solver, n1, n2


@njit(cache=True, inline="always")
def _upper_dot(j, work, u_indptr, u_indices, u_values, u_inverse):
    total = work[j]
    for p in range(_wide(u_indptr[j]), _wide(u_indptr[j + 1])):
        total -= u_values[p] * work[u_indices[p]]
    work[j] = total * u_inverse[j]


@njit(cache=True, inline="always")
def _lower_dot(j, work, l_indptr, l_indices, l_values):
    total = work[j]
    for p in range(_wide(l_indptr[j]), _wide(l_indptr[j + 1])):
        total -= l_values[p] * work[l_indices[p]]
    work[j] = total


@njit(cache=True)
def solve_split_transposed(factors, n1, n2, rhs, work, out):
    """`solve_lu_transposed` on block triangular factors, the two parts interleaved."""
    perm_r, perm_c, (l_indptr, l_indices, l_values), (u_indptr, u_indices, u_values, u_inverse) = factors
    n, both = rhs.size, min(n1, n2)
    for i in range(n):
        work[perm_c[i]] = rhs[i]
    for t in range(both):
        _upper_dot(t, work, u_indptr, u_indices, u_values, u_inverse)
        _upper_dot(n1 + t, work, u_indptr, u_indices, u_values, u_inverse)
    for j in range(both, n1):
        _upper_dot(j, work, u_indptr, u_indices, u_values, u_inverse)
    for j in range(n1 + both, n):
        _upper_dot(j, work, u_indptr, u_indices, u_values, u_inverse)
    for j in range(n - 1, n1 + both - 1, -1):
        _lower_dot(j, work, l_indptr, l_indices, l_values)
    for j in range(n1 - 1, both - 1, -1):
        _lower_dot(j, work, l_indptr, l_indices, l_values)
    for t in range(both - 1, -1, -1):
        _lower_dot(t, work, l_indptr, l_indices, l_values)
        _lower_dot(n1 + t, work, l_indptr, l_indices, l_values)
    for i in range(n):
        out[i] = work[perm_r[i]]


@njit(cache=True)
def solve_without_dependency(factors, rhs, work, other, out):
    """The plain transposed solve's work, its dot products reading `other`."""
    perm_r, perm_c, (l_indptr, l_indices, l_values), (u_indptr, u_indices, u_values, u_inverse) = factors
    n = rhs.size
    for i in range(n):
        work[perm_c[i]] = rhs[i]
    for j in range(n):
        total = work[j]
        for p in range(_wide(u_indptr[j]), _wide(u_indptr[j + 1])):
            total -= u_values[p] * other[u_indices[p]]
        work[j] = total * u_inverse[j]
    for j in range(n - 1, -1, -1):
        total = work[j]
        for p in range(_wide(l_indptr[j]), _wide(l_indptr[j + 1])):
            total -= l_values[p] * other[l_indices[p]]
        work[j] = total
    for i in range(n):
        out[i] = work[perm_r[i]]


@njit(cache=True)
def stream(factors):
    """Every value and index of L and U read once, in order."""
    total, rows = 0.0, 0
    for indices, values in ((factors[2][1], factors[2][2]), (factors[3][1], factors[3][2])):
        for p in range(values.size):
            total += values[p]
            rows += indices[p]
    return total + rows


def measure(bodies: int, rounds: int = 5, calls: int = 15) -> dict:
    from scipy.sparse import csr_array

    from sparsekin.engine import _compact_lu_kernels, _lu_kernels, compact_factors, linalg

    jacobian = csr_array(chain_saddle_matrix(bodies))
    n = jacobian.shape[0]
    structural = linalg.RefactorSolver(lean=True)
    structural.factor(jacobian)
    plain = structural._solve_factors(0)[1]  # before any compaction: the structural factors
    compact_solver = linalg.RefactorSolver(lean=True)
    compact_solver.factor(jacobian)
    kernels, compact = compact_solver._solve_factors(compact_factors.COMPACT_AFTER_SOLVES + 1)
    assert kernels is _compact_lu_kernels
    split, n1, n2 = split_solver(jacobian)
    split_factors = split._solve_factors(0)[1]
    empty = (plain[0], plain[1], (np.zeros_like(plain[2][0]), *plain[2][1:]), (np.zeros_like(plain[3][0]), *plain[3][1:]))
    rng = np.random.default_rng(0)
    b, c = rng.standard_normal(n), rng.standard_normal(n)
    work, out, probe, other = np.zeros(n), np.empty(n), np.zeros(1), np.ones(n)
    reference = np.empty(n)
    _lu_kernels.solve_lu_transposed(plain, b, work, reference, probe)
    x0, x1 = b.copy(), c.copy()
    variants = {
        "structural": lambda: _lu_kernels.solve_lu_transposed(plain, b, work, out, probe),
        "compact": lambda: _compact_lu_kernels.solve_lu_transposed(compact, b, work, out, probe),
        "pair_structural": lambda: _lu_kernels.solve_lu_transposed_pair(plain, x0, x1, work, probe),
        "pair_compact": lambda: _compact_lu_kernels.solve_lu_transposed_pair(compact, x0, x1, work, probe),
        "split": lambda: solve_split_transposed(split_factors, n1, n2, b, work, out),
        "split_plain": lambda: _lu_kernels.solve_lu_transposed(split_factors, b, work, out, probe),
        "no_dependency": lambda: solve_without_dependency(plain, b, work, other, out),
        "empty_columns": lambda: _lu_kernels.solve_lu_transposed(empty, b, work, out, probe),
        "stream": lambda: stream(plain),
    }
    agreement = {}
    for name in ("compact", "split"):
        variants[name]()
        agreement[name] = float(np.abs(out - reference).max() / np.abs(reference).max())
    flush = np.zeros(8_000_000)
    medians = {name: [] for name in variants}
    for _ in range(rounds):
        for name, call in variants.items():
            times = []
            for _ in range(calls):
                flush += 1.0
                start = time.perf_counter()
                call()
                times.append(time.perf_counter() - start)
            medians[name].append(float(np.median(times)))
    return {"bodies": bodies, "unknowns": n, "entries_structural": int(plain[2][0][-1] + plain[3][0][-1]),
            "entries_compact": int(compact[2][0].sum(dtype=np.int64) + compact[3][0].sum(dtype=np.int64)),
            "entries_split": int(split_factors[2][0][-1] + split_factors[3][0][-1]), "parts": [n1, n2, n - n1 - n2],
            "ms": {name: round(1e3 * float(np.median(v)), 4) for name, v in medians.items()},
            "relative_difference": agreement, "load_average": os.getloadavg()[0],
            "utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime())}  # fmt: skip


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--bodies", type=int, nargs="+", default=[10001, 100001])
    parser.add_argument("--rounds", type=int, default=5)
    arguments = parser.parse_args(argv)
    for bodies in arguments.bodies:
        print(json.dumps(measure(bodies, arguments.rounds)), flush=True)


if __name__ == "__main__":
    main()
