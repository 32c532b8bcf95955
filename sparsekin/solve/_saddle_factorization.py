"""The compiled dynamics loop's factorization of the saddle matrix: dense, or banded.

`sparsekin.solve._compiled_dynamics` holds one factorization of the saddle matrix and
calls two functions on it, `factor_saddle` and `solve_saddle`; which LU they run is
fixed once per run by `compiled_factorization`, from the plan
`sparsekin.solve.policy.plan_compiled_factorization`:

* ``"dense"``: the dense LU with partial pivoting of `sparsekin.engine._lu_kernels`, the
  matrix column-major (small models: A01, A03, Task 5);
* ``"banded"``: the unknowns in reverse Cuthill–McKee order of the saddle pattern
  (computed once), and the banded LU with partial pivoting of
  `sparsekin.engine._banded_kernels` refilled in place on that fixed band at each
  factorization (chain-like models: the IFToMM N-four-bar at N = 40, 485 unknowns,
  bandwidths 9 and 9; its factorization 10 times faster than the dense one).

The factorization is a tuple ``(matrix, order, band_slot, bandwidths, scratch, extent,
factors)``: ``matrix`` the dense (size, size) or band (2 kl + ku + 1, size) storage, both
Fortran-ordered; ``order`` the banded order (empty: dense); ``band_slot`` where each CSR
entry goes in the band; ``bandwidths`` ``[kl, ku]``; ``scratch`` a vector of the size;
``extent`` the reach of L's and U's columns and ``factors`` their nonzero entries
compressed, which the solves run over (`sparsekin.engine._banded_kernels`).  Both kinds
share this one tuple type, the dense one with empty placeholders, and the two functions
branch on ``order.size``: the loop's state is a single numba type, so the loop compiles
once for both LUs (two specializations chosen by a literal flag would compile it twice).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.sparse import csr_array
from scipy.sparse.csgraph import reverse_cuthill_mckee

from .._jit import JIT
from ..engine._banded_kernels import factor_band_held, solve_band
from ..engine._lu_kernels import dense_lu_solve
from ._compiled import _factor
from .policy import Thresholds, plan_compiled_factorization

#: The banded LU holds its pivots (`sparsekin.engine._banded_kernels.refactor_band`: only the
#: operations on entries that can be nonzero) up to this bound on its updates, size · kl · (kl + ku)
#: (three int64 each: 12 MB here; A02: 78 570).
MAX_SCHEDULED_UPDATES = 500_000

__all__ = ["MAX_SCHEDULED_UPDATES", "band_slots", "bandwidths", "compiled_factorization", "factor_saddle", "saddle_band_order", "solve_saddle"]


def bandwidths(indptr: np.ndarray, indices: np.ndarray, order: np.ndarray) -> tuple[int, int]:
    """``(kl, ku)``: the largest distance below and above the diagonal of any entry of the
    CSR pattern ``(indptr, indices)`` with its rows and columns in `order`."""
    rows, columns = _ordered_entries(indptr, indices, order)
    if rows.size == 0:
        return 0, 0
    return int(max(0, (rows - columns).max())), int(max(0, (columns - rows).max()))


def band_slots(indptr: np.ndarray, indices: np.ndarray, order: np.ndarray, lower: int, upper: int) -> np.ndarray:
    """Where each CSR entry of the pattern ``(indptr, indices)``, rows and columns in `order`,
    goes in the band storage of `lower` and `upper` bandwidths: shape (2, nnz), its row
    and column there."""
    rows, columns = _ordered_entries(indptr, indices, order)
    if rows.size and ((rows - columns).max() > lower or (columns - rows).max() > upper):
        raise ValueError(f"the pattern does not fit a band of {lower} below and {upper} above the diagonal")
    return np.stack((lower + upper + rows - columns, columns))


def _ordered_entries(indptr: np.ndarray, indices: np.ndarray, order: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The row and column of each CSR entry once the rows and columns are put in `order`."""
    position = np.empty(order.size, dtype=np.int64)
    position[order] = np.arange(order.size)
    rows = position[np.repeat(np.arange(indptr.size - 1), np.diff(indptr))]
    return rows, position[np.asarray(indices, dtype=np.int64)]


def saddle_band_order(indptr: np.ndarray, indices: np.ndarray) -> tuple[np.ndarray, int, int]:
    """The reverse Cuthill–McKee order of a square CSR pattern (made symmetric) and the
    bandwidths ``(kl, ku)`` below and above the diagonal it gives."""
    size = indptr.size - 1
    pattern = csr_array((np.ones(indices.size), indices, indptr), shape=(size, size))
    order = reverse_cuthill_mckee((pattern + pattern.T).tocsr(), symmetric_mode=True).astype(np.int64)
    lower, upper = bandwidths(indptr, indices, order)
    return order, lower, upper


def compiled_factorization(indptr: np.ndarray, indices: np.ndarray, thresholds: Thresholds | None = None,
                           banded: bool = True):  # fmt: skip
    """The held factorization of the saddle matrix of CSR pattern ``(indptr, indices)``
    that `plan_compiled_factorization` plans (module docstring), zeros; None when the plan
    is the Python stepper (too large for the dense LU and not banded enough).  Not
    `banded`: the dense LU or None (``linear_solver="dense"``)."""
    size = indptr.size - 1
    thresholds = Thresholds() if thresholds is None else thresholds
    order, lower, upper = np.zeros(0, dtype=np.int64), None, None
    if banded and thresholds.min_banded_saddle_size <= size <= thresholds.compiled_banded_max_size:
        order, lower, upper = saddle_band_order(indptr, indices)
    kind = plan_compiled_factorization(size, lower, upper, thresholds)
    if kind is None:
        return None
    if kind == "dense":
        no_order, none = np.zeros(0, dtype=np.int64), np.zeros((2, 0), dtype=np.int64)
        return (np.zeros((size, size), order="F"), no_order, none, np.zeros(2, dtype=np.int64), np.zeros(size), none,
                (none, none, np.zeros((2, 0))), _schedule(np.zeros(0), 0, 0, 0, 0))  # fmt: skip
    capacity = size * (lower + upper)
    factors = (np.zeros((2, size + 1), dtype=np.int64), np.zeros((2, capacity), dtype=np.int64),
               np.zeros((2, capacity)))  # fmt: skip
    band = np.zeros((2 * lower + upper + 1, size), order="F")
    held = size * lower * (lower + upper) <= MAX_SCHEDULED_UPDATES
    return (band, order, band_slots(indptr, indices, order, lower, upper), np.array([lower, upper], dtype=np.int64),
            np.zeros(size), np.zeros((2, size), dtype=np.int64), factors,
            _schedule(band.ravel(order="F"), size, lower, upper, held))  # fmt: skip


def _schedule(flat: np.ndarray, size: int, lower: int, upper: int, held: bool) -> tuple:
    """The held pivots' schedule of a band of `size` columns (`sparsekin.engine._banded_kernels`,
    ``schedule``; `flat` a view of the band), its lists empty unless `held`."""
    width = lower + upper
    capacity = (size * (width + 1), size * lower, size * lower * width, size * width) if held else (0, 0, 0, 0)
    pointers = np.zeros((4, size + 1), dtype=np.int64)
    pointers[3, 0] = -1
    return (flat, pointers, np.zeros(size, dtype=np.int64), np.zeros((2, capacity[0]), dtype=np.int64),
            np.zeros(capacity[1], dtype=np.int64), np.zeros((3, capacity[2]), dtype=np.int64),
            np.zeros(capacity[3], dtype=np.int64), np.zeros((size if held else 0, 2 * lower + upper + 1), dtype=bool),
            np.zeros(size if held else 0))  # fmt: skip


@njit(**JIT)
def factor_saddle(indptr, indices, values, factorization, pivots):
    """Refill the held `factorization` from the saddle matrix's CSR values and factor it;
    False if a pivot fails (singular, or not finite)."""
    matrix, order, band_slot, widths, _, extent, factors, schedule = factorization
    if order.size:
        return factor_band_held(values, band_slot, matrix, widths[0], widths[1], pivots, extent, factors, schedule)
    return _factor(indptr, indices, values, matrix, pivots)


@njit(inline="always", **JIT)
def solve_saddle(factorization, pivots, b):
    """Solve the saddle matrix's system in place in `b` with the held `factorization`."""
    matrix, order, _, widths, scratch, _, factors, schedule = factorization
    if order.size and schedule[1][3, 0] >= 0:  # held pivots: U's diagonal inverted
        solve_band(matrix, widths[0], widths[1], pivots, factors, order, scratch, b, schedule[8])
    elif order.size:
        solve_band(matrix, widths[0], widths[1], pivots, factors, order, scratch, b)
    else:
        dense_lu_solve(matrix, pivots, b)
