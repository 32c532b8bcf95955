"""`DenseSolver`: LAPACK's LU on a dense copy of the Jacobian, for small models.

The third linear solver behind the interface of `sparsekin.engine.linalg` (same methods,
counters and errors as `~sparsekin.engine.linalg.SuperLUSolver`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .linalg import _NOT_FACTORED, SingularMatrix, _checked_rhs, _checked_square

if TYPE_CHECKING:
    from scipy.sparse import csr_array

__all__ = ["DenseSolver"]


class DenseSolver:
    """LAPACK's LU with partial pivoting (``getrf``/``getrs``) on a dense copy, for small models.

    The Jacobian is scattered into a preallocated C-ordered array, whose Fortran view is
    ``A = jacobian.T``: LAPACK factors it in place, without a copy.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.sparse import csr_array
    >>> solver = DenseSolver()
    >>> solver.factor(csr_array(np.array([[2.0, 1.0], [0.0, 4.0]])))
    >>> solver.solve(np.array([3.0, 4.0])).tolist()
    [1.0, 1.0]
    """

    name = "dense"

    def __init__(self) -> None:
        self.n_factorizations = 0
        self.n_refactorizations = 0
        self.n_solves = 0
        self._n = -1
        self._factored = False
        self._getrf = self._getrs = None  # LAPACK's, looked up at the first factorization

    def factor(self, jacobian: csr_array) -> None:
        """Factor `jacobian` (square CSR); raise `SingularMatrix` if a pivot is exactly zero."""
        n = _checked_square(jacobian)
        self._factored = False
        if self._getrf is None:
            import scipy.linalg

            self._getrf, self._getrs = scipy.linalg.lapack.get_lapack_funcs(("getrf", "getrs"), dtype=np.float64)
        if n != self._n:
            self._n = n
            self._dense = np.zeros((n, n))  # C order: its Fortran view ``.T`` is jacobian.T
        self.n_factorizations += 1
        dense = self._dense
        dense.fill(0.0)
        jacobian.toarray(out=dense)  # adds the values into `out`
        lu, pivots, info = self._getrf(dense.T, overwrite_a=True)
        if info > 0:
            raise SingularMatrix(f"exactly zero pivot at step {info}")
        if not np.all(np.isfinite(lu.diagonal())):
            raise SingularMatrix("non-finite pivot: the Jacobian holds non-finite values")
        self._lu, self._pivots = lu, pivots
        self._factored = True

    def solve(
        self, rhs: np.ndarray, out: np.ndarray | None = None, *, transposed: bool = False
    ) -> np.ndarray:
        """Solve ``jacobian @ x = rhs``, or ``jacobian.T @ x = rhs`` if `transposed`.

        Parameters and returns as `~sparsekin.engine.linalg.RefactorSolver.solve`.
        """
        if not self._factored:
            raise RuntimeError(_NOT_FACTORED)
        rhs = np.asarray(rhs, dtype=float)
        if out is not None or rhs.ndim not in (1, 2) or rhs.shape[0] != self._n:
            _checked_rhs(rhs, self._n, out)
        # The factors are those of A = jacobian.T: jacobian @ x = rhs is LAPACK's trans=1.
        solution, info = self._getrs(self._lu, self._pivots, rhs, trans=0 if transposed else 1)
        if out is not None:
            out[...] = solution
            solution = out
        self.n_solves += 1 if rhs.ndim == 1 else rhs.shape[1]
        if not np.all(np.isfinite(solution)):
            raise SingularMatrix("the solution is not finite")
        return solution
