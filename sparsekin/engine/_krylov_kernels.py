"""numba kernels of flexible GMRES (`sparsekin.engine.krylov.fgmres`): the vector work.

Plain loops rather than BLAS calls: numpy's dot on vectors of 10^4–10^6 entries went
through a threaded BLAS that, on this project's busy 2-core machines, took 14 ms per
product of 3·10^4 entries (a profile of the lattice at 10^4 bodies) against about 30 µs
for these loops.
"""

from __future__ import annotations

import math

from numba import njit

from .._jit import JIT as _JIT


@njit(**_JIT)
def norm2(x):
    """The 2-norm of `x`."""
    total = 0.0
    for i in range(x.size):
        total += x[i] * x[i]
    return math.sqrt(total)


@njit(**_JIT)
def residual_into(rhs, product, out):
    """``out = rhs - product``; returns its 2-norm."""
    total = 0.0
    for i in range(rhs.size):
        r = rhs[i] - product[i]
        out[i] = r
        total += r * r
    return math.sqrt(total)


@njit(**_JIT)
def orthogonalize(basis, j, w, column):
    """Modified Gram–Schmidt of `w` against ``basis[:j + 1]``: the coefficients go to
    ``column[:j + 1]``, the norm of what is left to ``column[j + 1]``, and that rest,
    normalized, to ``basis[j + 1]`` (left as is if the norm is zero)."""
    n = w.size
    for i in range(j + 1):
        h = 0.0
        for k in range(n):
            h += basis[i, k] * w[k]
        column[i] = h
        for k in range(n):
            w[k] -= h * basis[i, k]
    rest = norm2(w)
    column[j + 1] = rest
    if rest > 0.0:
        for k in range(n):
            basis[j + 1, k] = w[k] / rest


@njit(**_JIT)
def combine(start, directions, y, out):
    """``out = start + directions[:y.size].T @ y``."""
    for k in range(out.size):
        total = start[k]
        for i in range(y.size):
            total += y[i] * directions[i, k]
        out[k] = total


@njit(**_JIT)
def largest_line_sum(indptr, indices, data, column_sums):
    """``max(||A||_1, ||A||_inf)`` of the CSR matrix ``(data, indices, indptr)``: its
    largest absolute column or row sum, in one pass (`column_sums` is work, shape (n_cols,))."""
    column_sums[:] = 0.0
    largest = 0.0
    for i in range(indptr.size - 1):
        row = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            magnitude = abs(data[p])
            row += magnitude
            column_sums[indices[p]] += magnitude
        largest = max(largest, row)
    for j in range(column_sums.size):
        largest = max(largest, column_sums[j])
    return largest
