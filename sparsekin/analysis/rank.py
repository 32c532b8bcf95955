"""The numerical rank of a sparse Jacobian, its null spaces and its conditioning.

`analyse_jacobian` finds the numerical rank of a sparse Jacobian Phi_q (m equations, n
coordinates), a basis of its null space (the free motions, which no equation controls)
and of its left null space (the redundant equations, each a combination of the others).
It knows nothing of mechanisms: `sparsekin.analysis.check` and the time loop put its findings into
words (`sparsekin.analysis.describe`).

The rank-revealing factorization
--------------------------------
scipy has no sparse QR, and a sparse LU breaks down on an exactly singular matrix (and is
not rank-revealing in general).  The analysis works on the Jacobian scaled by powers of 2
so that every row and every column has a largest entry of 1, ``A = D_r Phi_q D_c`` (its
decisions do not depend on units), and confirms every decision by a least-squares
residual ``||A v||`` of unit vectors v:

* **Square and nonsingular** (the common case): SuperLU factors A (COLAMD ordering,
  partial pivoting) and inverse subspace iteration ``X <- A^-1 A^-T X`` draws the right
  singular vectors of the smallest singular values.  A Rayleigh–Ritz step with A (the SVD
  of the small dense matrix ``A Q``, Q an orthonormal basis of the block) gives their
  singular values; if the smallest is above the tolerance, the rank is full.
* **Otherwise** (rectangular, exactly singular, or a Ritz value within the tolerance),
  SuperLU factors the symmetric augmented matrix ``M = [[delta I, A^T], [A, -delta I]]``,
  which is never singular.  ``M^2 = diag(delta² + A^T A, delta² + A A^T)``: the
  eigenvalues of M are ``±sqrt(delta² + sigma_i²)``, and ``±delta`` exactly on the null
  spaces — (x, 0) for a right null vector x, (0, y) for a left null vector y.  Inverse
  subspace iteration with M thus converges to both null spaces at once, at the rate
  ``delta / sigma`` per sweep, with delta a tenth of the rank tolerance.  The condition
  of M is ``sigma_max / delta``: unlike the normal equations ``A A^T``, nothing is
  squared.  Rayleigh–Ritz steps with A and A^T keep the directions whose residual is
  within the tolerance; with those deflated, a second block finds the smallest nonzero
  singular values (the condition number).

**Tall** (more equations than coordinates, at least `SMALLEST_TALL_LU` coordinates: an
overconstrained mechanism), `sparsekin.analysis.tall_lu.TallLU` first: a sparse LU that
offers the rows in turn and names redundant those that are combinations of the rows kept
before them, its kept block certified by its smallest singular value; near-linear in the
size, where the augmented matrix's blocks grow with the nullity.  If a coordinate is left
without a pivot or the certificate fails, the augmented matrix decides.  Its dependencies
are computed one at a time when a message needs them (`JacobianAnalysis.dependency`).

The rank tolerance is NumPy's ``matrix_rank`` convention on the scaled matrix,
``max(m, n) · eps · sigma_max`` (at least ``100 · eps · sigma_max``).  Column-pivoted QR of
the null bases then chooses one coordinate per free motion and one equation per
dependency (later joints first, drivers last), and the bases are rewritten with the
identity on those: each free motion moves its own coordinate, each redundant equation is
written in terms of the others.  The cost is one or two sparse LU factorizations and a
few block solves: about a second at 10^5 bodies with full rank, a few seconds otherwise.
It grows with the nullity, which is expected to be small (blocks of up to `MAX_NULLITY`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
from scipy import sparse
from scipy.sparse.csgraph import structural_rank
from scipy.sparse.linalg import splu

from ..errors import ModelError
from .tall_lu import CERTIFICATE_MARGIN, INVOLVEMENT, TallLU

__all__ = ["JacobianAnalysis", "RankUndetermined", "analyse_jacobian", "independent_rows", "SMALLEST_TALL_LU"]

#: Tall Jacobians with at least this many coordinates are analysed by `TallLU` first (its
#: answer certified, the dense analysis otherwise); smaller ones by the dense analysis,
#: which also gives the smallest nonzero singular values exactly and takes a fraction of a
#: second there (0.24 s at 432 coordinates, 12×12 rotating squares; one run).
SMALLEST_TALL_LU = 300

#: Regularization delta of the augmented matrix: a tenth of the rank tolerance, so that
#: inverse iteration separates the null spaces from the smallest nonzero singular values,
#: but at least this much relative to sigma_max, above the rounding of the elimination.
SMALLEST_REGULARIZATION = 1e-13
#: Extra directions drawn beyond the estimated nullity.
OVERSAMPLING = 6
#: Sweeps of inverse subspace iteration: ``X <- A^-1 A^-T X`` for a square nonsingular
#: Jacobian, ``X <- M^-1 X`` with the augmented matrix M for the smallest nonzero
#: singular values, and ``NULL_SWEEPS`` of them for the null spaces.
SWEEPS = 3
NULL_SWEEPS = 2
#: Largest number of directions drawn on one side.
MAX_NULLITY = 4096

_EPS = np.finfo(float).eps


class RankUndetermined(ModelError):
    """The rank of a Jacobian cannot be told: more null vectors on one side than the dense
    analysis finds (`MAX_NULLITY`), where the sparse LU could not decide.  Raised before
    the dense analysis allocates its blocks ((m + n) × `MAX_NULLITY` numbers), whose result
    would be incomplete."""


@dataclass(frozen=True, eq=False)
class JacobianAnalysis:
    """Numerical rank, null spaces and conditioning of a constraint Jacobian.

    Vectors are given for the scaled Jacobian ``A = D_r Phi_q D_c`` (``D_r`` and ``D_c``
    diagonal, `row_scale` and `column_scale`), where every row and column has a largest
    entry of 1: a coordinate of a free motion is then the displacement it causes at the
    farthest equation it enters (m), and the weight of an equation in a dependency is
    comparable between equations.  The free motions are also given unscaled, in the
    coordinates of the mechanism.

    Attributes
    ----------
    shape : tuple of int
        ``(m, n)``: equations, coordinates.
    rank : int
        Numerical rank: singular values above ``tolerance · sigma_max`` (scaled).
    tolerance : float
        Relative rank tolerance, ``max(m, n, 100) · eps`` unless given.
    sigma_max : float
        Largest singular value of the scaled Jacobian.
    sigma_min : float
        Smallest singular value above the tolerance that was found (an estimate from
        above of the smallest nonzero one); ``nan`` if the Jacobian has rank 0.
    free_coordinates : ndarray of int, shape (n_free,)
        One coordinate per free motion, which that motion moves and the others do not.
    free_motions : ndarray, shape (n, n_free)
        Basis of the null space of Phi_q, in coordinates (m, rad): motion k moves
        ``free_coordinates[k]`` by its scaled unit.
    scaled_free_motions : ndarray, shape (n, n_free)
        The same basis for A: ``free_motions = column_scale[:, None] * scaled_free_motions``,
        with the identity on the rows `free_coordinates`.
    redundant_rows : ndarray of int, shape (n_redundant,)
        Equations to leave out so that the others are independent: later joints first,
        drivers last.
    dependency_source : object
        What gives the dependencies on demand (`dependency`, `rows_in_dependencies`,
        `dependencies`): a dense basis of the left null space for the dense analysis, the
        factors of `sparsekin.analysis.tall_lu.TallLU` for a tall Jacobian of full rank.
    smallest_singular_value : float
        Smallest singular value found, relative to `sigma_max` (0 to rounding for a
        rank-deficient Jacobian).
    smallest_motion, smallest_equations : ndarray, shapes (n,) and (m,)
        Unit right and left singular vectors of the smallest singular value (scaled):
        the motion the constraints control least and the combination of equations that
        is closest to dependent.
    row_scale, column_scale : ndarray, shapes (m,) and (n,)
        The powers of 2 of the scaling.
    """

    shape: tuple[int, int]
    rank: int
    tolerance: float
    sigma_max: float
    sigma_min: float
    free_coordinates: np.ndarray
    free_motions: np.ndarray
    scaled_free_motions: np.ndarray
    redundant_rows: np.ndarray
    dependency_source: _DenseDependencies | TallLU
    smallest_singular_value: float
    smallest_motion: np.ndarray
    smallest_equations: np.ndarray
    row_scale: np.ndarray
    column_scale: np.ndarray
    _involvement: dict = field(default_factory=dict, init=False, repr=False)

    @property
    def n_free(self) -> int:
        """Number of free motions, ``n - rank``."""
        return int(self.free_coordinates.size)

    @property
    def n_redundant(self) -> int:
        """Number of redundant equations, ``m - rank`` (up to rounding at the threshold)."""
        return int(self.redundant_rows.size)

    def dependency(self, k: int) -> np.ndarray:
        """Dependency k, shape (m,): 1 at ``redundant_rows[k]``, 0 at the other redundant
        rows, and the weights that express that row of A as a combination of the kept ones
        (``row_scale * dependency(k)`` does the same for Phi_q).  One triangular solve for
        a tall Jacobian analysed by its LU."""
        return self.dependency_source.dependency(int(k))

    def rows_in_dependencies(self, rows):
        """The weights of the equations `rows` in every dependency, shape (len(rows),
        n_redundant): a dense array, or a sparse one holding the dependencies that
        involve them (for a tall Jacobian analysed by its LU)."""
        return self.dependency_source.rows_in_dependencies(np.asarray(rows, dtype=np.int64))

    def involvement(self, rows) -> tuple[np.ndarray, int]:
        """Which dependencies the equations `rows` take part in, and how many independent
        ones: decided once per set of rows (kept), with one threshold, `INVOLVEMENT`.

        A dependency involves `rows` if one of their weights is at least `INVOLVEMENT`
        relative to the redundant equation's own 1; the count is the rank of their
        weights in those dependencies, singular values below `INVOLVEMENT` times the
        largest weight counting as zero.
        """
        rows = np.asarray(rows, dtype=np.int64)
        key = rows.tobytes()
        if key not in self._involvement:
            weights = self.rows_in_dependencies(rows)
            if not weights.shape[0] or not weights.shape[1]:
                found = (np.zeros(self.n_redundant, dtype=bool), 0)
            else:
                if sparse.issparse(weights):
                    weights = sparse.csc_array(weights)
                largest = abs(weights).max(axis=0)
                involved = np.asarray(largest.toarray() if hasattr(largest, "toarray") else largest).ravel() >= INVOLVEMENT
                taking_part = weights[:, np.flatnonzero(involved)]
                taking_part = taking_part.toarray() if sparse.issparse(taking_part) else taking_part
                scale = max(1.0, float(np.abs(taking_part).max(initial=0.0)))  # each dependency has 1 at its own row
                count = int(np.linalg.matrix_rank(taking_part, tol=INVOLVEMENT * scale)) if taking_part.size else 0
                found = (involved, count)
            self._involvement[key] = found
        return self._involvement[key]

    def involve(self, rows) -> np.ndarray:
        """For each dependency, whether one of the equations `rows` takes part in it
        (a weight of at least `INVOLVEMENT` relative to the redundant equation's own 1)."""
        return self.involvement(rows)[0]

    def dependency_rank(self, rows) -> int:
        """The rank of the weights of the equations `rows` in the dependencies: how many
        independent dependencies they take part in (`involvement`)."""
        return self.involvement(rows)[1]

    @property
    def dependencies(self) -> np.ndarray:
        """Every dependency, shape (m, n_redundant): a basis of the left null space of A.
        Dense: for small models; `dependency` gives one."""
        return np.column_stack([self.dependency(k) for k in range(self.n_redundant)]) if self.n_redundant else (
            np.zeros((self.shape[0], 0)))  # fmt: skip

    @property
    def condition(self) -> float:
        """2-norm condition number of the scaled Jacobian, restricted to its rank."""
        return self.sigma_max / self.sigma_min if self.sigma_min > 0 else math.inf


def analyse_jacobian(
    jacobian,
    *,
    tolerance: float | None = None,
    row_preference: np.ndarray | None = None,
    seed: int = 0,
    tall_lu_from: int = SMALLEST_TALL_LU,
) -> JacobianAnalysis:
    """Numerical rank, free motions and redundant equations of a sparse Jacobian.

    Parameters
    ----------
    jacobian : sparse array, shape (m, n)
        Phi_q: one row per equation, one column per coordinate.
    tolerance : float, optional
        Singular values of the scaled Jacobian at most ``tolerance · sigma_max`` count
        as zero.  Default ``max(m, n, 100) · eps``, NumPy's convention.
    row_preference : ndarray, shape (m,), optional
        Positive weights: among equally suitable equations, those with larger weights
        are named redundant first.  Default: later rows first.
    seed : int
        Seed of the random start blocks (the result does not depend on it, beyond
        rounding).
    tall_lu_from : int
        A tall Jacobian (more rows than columns) of at least this many columns is
        analysed by a sparse LU first (`SMALLEST_TALL_LU`).

    Returns
    -------
    JacobianAnalysis

    Examples
    --------
    Two identical rows and a column that no equation touches:

    >>> import numpy as np
    >>> from scipy.sparse import csr_array
    >>> jacobian = csr_array(np.array([[1.0, 2.0, 0.0], [1.0, 2.0, 0.0]]))
    >>> analysis = analyse_jacobian(jacobian)
    >>> analysis.rank, analysis.redundant_rows.tolist(), analysis.free_coordinates.size
    (1, [1], 2)
    """
    shape = getattr(jacobian, "shape", np.shape(jacobian))
    if len(shape) != 2:
        raise ValueError(f"`jacobian` must be a 2-D matrix, got shape {tuple(shape)}.")
    jacobian = sparse.csr_array(jacobian, dtype=float)
    if not np.all(np.isfinite(jacobian.data)):
        raise ValueError("`jacobian` must have finite entries.")
    m, n = jacobian.shape
    if tolerance is None:
        tolerance = max(m, n, 100) * _EPS
    rng = np.random.default_rng(seed)
    if m == 0 or n == 0 or jacobian.count_nonzero() == 0:
        ones = {"row_scale": np.ones(m), "column_scale": np.ones(n)}
        return _analysis_of_zero(shape=(m, n), tolerance=tolerance, **ones)
    scaled, row_scale, column_scale = _equilibrate(jacobian)
    common = {"shape": (m, n), "tolerance": tolerance, "row_scale": row_scale, "column_scale": column_scale}
    sigma_max = _largest_singular_value(scaled, rng)
    absolute_tolerance = tolerance * sigma_max
    if row_preference is None:
        row_preference = 1.0 + np.arange(m) / m

    if m == n:  # the common case: square, and usually of full rank
        lu = _square_lu(scaled)
        if lu is not None:
            values, right = _smallest_singular_triplets(lu, scaled, rng)
            if values[0] > absolute_tolerance:
                image = scaled @ right[:, 0]
                return JacobianAnalysis(
                    **common,
                    rank=n,
                    sigma_max=sigma_max,
                    sigma_min=float(values[0]),
                    free_coordinates=np.zeros(0, dtype=np.int64),
                    free_motions=np.zeros((n, 0)),
                    scaled_free_motions=np.zeros((n, 0)),
                    redundant_rows=np.zeros(0, dtype=np.int64),
                    dependency_source=_DenseDependencies(np.zeros((m, 0))),
                    smallest_singular_value=float(values[0]) / sigma_max,
                    smallest_motion=right[:, 0],
                    smallest_equations=image / np.linalg.norm(image),
                )

    if m > n >= tall_lu_from:  # the common overconstrained case: full column rank
        found = _analysis_by_tall_lu(scaled, row_preference, absolute_tolerance, sigma_max, rng, common)
        if found is not None:
            return found

    if abs(m - n) > MAX_NULLITY:  # at least that many null vectors: more than the dense analysis draws, in
        raise RankUndetermined(_too_many_null_vectors(m, n, tall_lu_from))  # blocks of (m + n) × MAX_NULLITY
    augmented = _AugmentedFactor(scaled, max(0.1 * tolerance, SMALLEST_REGULARIZATION) * sigma_max)
    spaces = augmented.near_null(scaled, absolute_tolerance, rng)
    null_right, null_left = spaces.right, spaces.left
    free_coordinates = _select(null_right, None)
    redundant_rows = _select(null_left, row_preference)
    scaled_motions = _basic(null_right, free_coordinates)
    nonnull = spaces.nonnull_values[spaces.nonnull_values > absolute_tolerance]
    if null_right.shape[1]:
        smallest_motion = null_right[:, 0]
        smallest_value = float(np.linalg.norm(scaled @ smallest_motion))
    else:
        smallest_motion, smallest_value = spaces.vectors_right[:, 0], float(spaces.values_right[0])
    if null_left.shape[1]:
        smallest_equations = null_left[:, 0]
    else:
        image = scaled @ smallest_motion
        smallest_equations = image / max(float(np.linalg.norm(image)), np.finfo(float).tiny)
    return JacobianAnalysis(
        **common,
        rank=n - null_right.shape[1],
        sigma_max=sigma_max,
        sigma_min=float(nonnull.min()) if nonnull.size else math.nan,
        free_coordinates=free_coordinates,
        free_motions=column_scale[:, None] * scaled_motions,
        scaled_free_motions=scaled_motions,
        redundant_rows=redundant_rows,
        dependency_source=_DenseDependencies(_basic(null_left, redundant_rows)),
        smallest_singular_value=smallest_value / sigma_max,
        smallest_motion=smallest_motion,
        smallest_equations=smallest_equations,
    )


#: `independent_rows` decides by a dense SVD up to this many coordinates and equations
#: (microseconds for a few bodies, tens of milliseconds at this size).
DENSE_INDEPENDENCE_MAX_SIZE = 400
#: ... and certifies rows independent only above this multiple of the rank tolerance, far
#: beyond `analyse_jacobian`'s own estimates (sigma_max to < 1 %).
INDEPENDENCE_MARGIN = 100.0


def independent_rows(jacobian, *, tolerance: float | None = None) -> bool:
    """Whether the rows of a small Jacobian are clearly independent, so that
    `analyse_jacobian` would name no redundant row: the smallest singular value of the
    Jacobian scaled as there is above `INDEPENDENCE_MARGIN` times its rank tolerance
    (``tolerance`` as there).  False when that is not clear, or the Jacobian has more rows
    than columns or more than `DENSE_INDEPENDENCE_MAX_SIZE` of either: ask
    `analyse_jacobian`.

    >>> import numpy as np
    >>> from scipy.sparse import csr_array
    >>> independent_rows(csr_array(np.array([[1.0, 2.0, 0.0], [0.0, 1e-3, 1.0]])))
    True
    >>> independent_rows(csr_array(np.array([[1.0, 2.0, 0.0], [1.0, 2.0, 0.0]])))
    False
    """
    jacobian = sparse.csr_array(jacobian, dtype=float)
    m, n = jacobian.shape
    if m == 0 or m > n or n > DENSE_INDEPENDENCE_MAX_SIZE or not np.all(np.isfinite(jacobian.data)):
        return False
    if tolerance is None:
        tolerance = max(m, n, 100) * _EPS
    dense = jacobian.toarray()  # scaled as `_equilibrate` scales (its sparse products cost more here)
    dense *= _power_of_two_inverse(np.abs(dense).max(axis=1))[:, None]
    dense *= _power_of_two_inverse(np.abs(dense).max(axis=0))[None, :]
    values = np.linalg.svd(dense, compute_uv=False)
    return bool(values[-1] > INDEPENDENCE_MARGIN * tolerance * values[0])


def _too_many_null_vectors(m: int, n: int, tall_lu_from: int) -> str:
    """Why a Jacobian with more than `MAX_NULLITY` null vectors on one side is not analysed."""
    if m > n:
        why = ("its sparse LU could not certify the rank (the kept equations are too close to dependent)"
               if n >= tall_lu_from else f"it has fewer than {tall_lu_from} coordinates (the sparse LU's threshold)")  # fmt: skip
        found = f"at least {m - n} redundant equations"
    else:
        why, found = "only the dense analysis finds free motions", f"at least {n - m} free motions"
    return (f"the rank of the {m} × {n} constraint Jacobian cannot be told: {found}, more than the dense analysis "
            f"finds ({MAX_NULLITY}; its memory grows as equations × them), and {why}")  # fmt: skip


def _analysis_by_tall_lu(scaled, preference, absolute_tolerance, sigma_max, rng, common):
    """The analysis of a tall Jacobian of full column rank by `TallLU`, or None if a
    coordinate is left without a pivot or its certificate fails."""
    m, n = scaled.shape
    for fill_reducing in (False, True):  # the rows' own order, then a nested dissection
        factor = TallLU(scaled, preference, fill_reducing)
        if not factor.complete:
            if factor.over_budget:
                continue
            return None
        values, right = factor.smallest_singular_triplets(rng)
        if values[0] >= CERTIFICATE_MARGIN * absolute_tolerance:
            break
    else:
        return None
    # the rows left out are combinations of B's: A's smallest singular value is at least
    # B's, and a Rayleigh–Ritz step with A on B's smallest directions estimates it from above
    image = np.linalg.qr(np.asfortranarray(scaled @ right), mode="r")
    _, values_tall, vectors = np.linalg.svd(image)
    motion = right @ vectors[-1]
    equations = scaled @ motion
    return JacobianAnalysis(
        **common,
        rank=n,
        sigma_max=sigma_max,
        sigma_min=float(values_tall[-1]),
        free_coordinates=np.zeros(0, dtype=np.int64),
        free_motions=np.zeros((n, 0)),
        scaled_free_motions=np.zeros((n, 0)),
        redundant_rows=factor.redundant_rows,
        dependency_source=factor,
        smallest_singular_value=float(values_tall[-1]) / sigma_max,
        smallest_motion=motion,
        smallest_equations=equations / np.linalg.norm(equations),
    )


class _DenseDependencies:
    """A dense basis of the left null space, with `TallLU`'s interface."""

    def __init__(self, basis: np.ndarray) -> None:
        self.basis = basis

    def dependency(self, k: int) -> np.ndarray:
        return self.basis[:, k]

    def rows_in_dependencies(self, rows: np.ndarray) -> np.ndarray:
        return self.basis[rows]


def _analysis_of_zero(*, shape, tolerance, row_scale, column_scale) -> JacobianAnalysis:
    """A Jacobian without a nonzero entry: every coordinate is free, every equation redundant."""
    m, n = shape
    return JacobianAnalysis(
        shape=shape,
        rank=0,
        tolerance=tolerance,
        sigma_max=0.0,
        sigma_min=math.nan,
        free_coordinates=np.arange(n),
        free_motions=np.diag(column_scale),
        scaled_free_motions=np.eye(n),
        redundant_rows=np.arange(m),
        dependency_source=_DenseDependencies(np.eye(m)),
        smallest_singular_value=0.0,
        smallest_motion=np.eye(n)[:, 0] if n else np.zeros(0),
        smallest_equations=np.eye(m)[:, 0] if m else np.zeros(0),
        row_scale=row_scale,
        column_scale=column_scale,
    )


def _equilibrate(jacobian: sparse.csr_array):
    """``D_r J D_c`` with powers of 2 making each row's, then each column's, largest entry 1."""
    row_scale = _power_of_two_inverse(_dense(abs(jacobian).max(axis=1)))
    scaled = sparse.csr_array(sparse.diags_array(row_scale) @ jacobian)
    column_scale = _power_of_two_inverse(_dense(abs(scaled).max(axis=0)))
    scaled = sparse.csr_array(scaled @ sparse.diags_array(column_scale))
    return scaled, row_scale, column_scale


def _dense(array) -> np.ndarray:
    return np.asarray(array.toarray() if hasattr(array, "toarray") else array, dtype=float).ravel()


def _power_of_two_inverse(maximum: np.ndarray) -> np.ndarray:
    scale = np.ones_like(maximum)
    positive = maximum > 0
    scale[positive] = np.exp2(-np.round(np.log2(maximum[positive])))
    return scale


def _largest_singular_value(matrix, rng, sweeps: int = 10, block: int = 4) -> float:
    """Block power iteration on A^T A with a Rayleigh–Ritz step: sigma_max to < 1 %."""
    basis = _orthonormal(rng.standard_normal((matrix.shape[1], min(block, matrix.shape[1]))))
    for _ in range(sweeps):
        basis = _orthonormal(matrix.T @ (matrix @ basis), keep_width=True, rng=rng)
    return float(_rayleigh_ritz(matrix, basis)[0][-1])


def _square_lu(scaled: sparse.csr_array):
    """SuperLU of a square A, or None if A is singular to SuperLU: structurally (fewer than n
    entries can be matched one per row and column — then never handed to SuperLU, which
    reads past the end of a column left without a candidate pivot row and crashes the
    process now and then: 10 of 10 processes factoring a 36×36 parallelogram tower's
    Jacobian 300 times) or by an exactly zero pivot."""
    square = sparse.csc_array(scaled)
    square.eliminate_zeros()  # the structure SuperLU sees is that of the entries stored
    if structural_rank(sparse.csr_matrix(square)) < square.shape[1]:
        return None
    try:
        return splu(square, permc_spec="COLAMD")
    except RuntimeError:  # an exactly zero pivot (among candidate rows): rank deficient
        return None


def _smallest_singular_triplets(lu, scaled, rng, block: int = OVERSAMPLING):
    """Ritz values (ascending) and right vectors of the smallest singular values of a
    square nonsingular A, by inverse subspace iteration ``X <- A^-1 A^-T X``."""
    n = scaled.shape[1]
    drawn = _orthonormal(rng.standard_normal((n, min(block, n))))
    for _ in range(SWEEPS):
        drawn = _orthonormal(lu.solve(drawn, trans="T"), keep_width=True, rng=rng)
        drawn = _orthonormal(lu.solve(drawn), keep_width=True, rng=rng)
    return _rayleigh_ritz(scaled, drawn)


class _AugmentedFactor:
    """SuperLU of the augmented matrix ``M = [[delta I, A^T], [A, -delta I]]``.

    M is symmetric and never singular.  Its square is ``diag(delta² + A^T A, delta² +
    A A^T)``, so its eigenvalues are ``±sqrt(delta² + sigma_i²)`` and, on the null spaces,
    ``±delta``: a right null vector x of A gives the eigenvector (x, 0), a left null
    vector y gives (0, y), exactly.  Inverse subspace iteration with M therefore
    converges to the null spaces of A at the rate ``delta / sigma`` per sweep, and its
    condition is ``sigma_max / delta`` — not squared, as the normal equations
    ``A A^T`` would make it.
    """

    def __init__(self, scaled: sparse.csr_array, delta: float) -> None:
        m, n = scaled.shape
        coo = scaled.tocoo()
        diagonal = np.arange(n + m)
        rows = np.concatenate([coo.col, coo.row + n, diagonal])
        columns = np.concatenate([coo.row + n, coo.col, diagonal])
        for attempt in range(3):
            regularization = np.where(diagonal < n, delta, -delta) * 100.0**attempt
            values = np.concatenate([coo.data, coo.data, regularization])
            matrix = sparse.csc_array((values, (rows, columns)), shape=(n + m, n + m))
            try:
                self.lu = splu(matrix, permc_spec="COLAMD")
                break
            except RuntimeError:  # an exactly zero pivot after rounding: regularize more
                continue
        else:  # pragma: no cover
            raise RuntimeError("the augmented Jacobian could not be factored")
        self.shape = (m, n)
        pivots = np.abs(self.lu.U.diagonal())
        self.hint = int(np.count_nonzero(pivots <= math.sqrt(delta)))

    def near_null(self, scaled, tolerance: float, rng) -> _NullSpaces:
        """Null spaces of A (right and left) and its smallest nonzero singular values.

        First, inverse subspace iteration with M draws the null spaces; the directions of
        the drawn block whose Ritz value (``||A v||``) is within `tolerance` are null
        vectors, refined by one more sweep of their own.  If every direction drawn is
        null, the block may be too small and is doubled.  Then, with the null vectors
        projected out after every solve, a second block finds the smallest nonzero
        singular values (for the condition number).
        """
        m, n = self.shape
        size = n + m
        block = min(self.hint + OVERSAMPLING, size, MAX_NULLITY)
        while True:
            drawn = _orthonormal(rng.standard_normal((size, block)))
            for _ in range(NULL_SWEEPS):
                drawn = _orthonormal(self.lu.solve(drawn), keep_width=True, rng=rng)
            right = _null_part(scaled, drawn[:n], tolerance)
            left = _null_part(scaled.T, drawn[n:], tolerance)
            saturated = right.shape[1] + left.shape[1] >= block
            disagree = n - right.shape[1] != m - left.shape[1]  # the two sides imply different ranks
            if (saturated or disagree) and block < min(size, MAX_NULLITY):
                block = min(2 * block, size, MAX_NULLITY)  # draw more
                continue
            break
        # One more sweep on the null vectors alone: nothing else in the block to pollute them.
        locked = _stack_parts(right, left, n, m)
        if locked.shape[1]:
            refined = _orthonormal(self.lu.solve(locked), rtol=1e-12)
            right = _null_part(scaled, refined[:n], tolerance)
            left = _null_part(scaled.T, refined[n:], tolerance)
            locked = _stack_parts(right, left, n, m)
        # The smallest nonzero singular values, the null spaces deflated.
        width = min(OVERSAMPLING, size - locked.shape[1])
        others = _deflated(rng.standard_normal((size, width)), locked)
        for _ in range(2 * SWEEPS):  # M is indefinite: its eigenvalues ±sigma converge no faster than sigma
            others = _orthonormal(_deflated(self.lu.solve(_orthonormal(others)), locked), keep_width=False)
            if others.shape[1] == 0:
                break
        values_right, vectors_right = _rayleigh_ritz(scaled, _orthonormal(_deflated(others[:n], right)))
        values_left, _ = _rayleigh_ritz(scaled.T, _orthonormal(_deflated(others[n:], left)))
        nonnull = np.concatenate([values_right, values_left])
        return _NullSpaces(right, left, nonnull, values_right, vectors_right)


@dataclass
class _NullSpaces:
    right: np.ndarray  # orthonormal basis of the right null space of A, (n, k_right)
    left: np.ndarray  # orthonormal basis of the left null space, (m, k_left)
    nonnull_values: np.ndarray  # Ritz values of the smallest nonzero singular values
    values_right: np.ndarray  # the right ones, ascending, and their vectors
    vectors_right: np.ndarray


def _null_part(operator, block: np.ndarray, tolerance: float) -> np.ndarray:
    """The Ritz vectors of ``operator`` in the range of `block` whose Ritz value is within `tolerance`."""
    values, vectors = _rayleigh_ritz(operator, _orthonormal(block))
    return vectors[:, values <= tolerance]


def _stack_parts(right: np.ndarray, left: np.ndarray, n: int, m: int) -> np.ndarray:
    """The eigenvectors (x, 0) and (0, y) of M for right and left null vectors x and y."""
    locked = np.zeros((n + m, right.shape[1] + left.shape[1]))
    locked[:n, : right.shape[1]] = right
    locked[n:, right.shape[1] :] = left
    return locked


def _deflated(block: np.ndarray, locked: np.ndarray) -> np.ndarray:
    """`block` with its components along the orthonormal columns of `locked` removed (twice)."""
    if locked.shape[1] == 0:
        return block
    for _ in range(2):
        block = block - _times(locked, locked.T @ block)
    return block


def _times(tall: np.ndarray, small: np.ndarray) -> np.ndarray:
    """``tall @ small`` for a tall (N, k) block and a small (k, j) matrix.

    Written as ``(small^T tall^T)^T``: OpenBLAS is an order of magnitude slower on the
    direct product, whose inner and outer dimensions are tiny, when it runs threaded.
    """
    return (small.T @ tall.T).T


def _orthonormal(block: np.ndarray, rtol: float = 1e-7, *, keep_width: bool = False, rng=None) -> np.ndarray:
    """An orthonormal basis of the range of a tall `block`, without directions below `rtol`.

    The columns are scaled to unit length, then two passes of Gram–Cholesky QR (the
    Gram matrix is small and cheap to form): the first through the eigenvectors of the
    Gram matrix, dropping directions below `rtol` relative to the largest; the second
    to restore orthogonality.  With
    `keep_width`, dropped directions are replaced by random ones orthogonal to the
    others, as subspace iteration needs a block of constant width.
    """
    width = block.shape[1]
    if width == 0:
        return block
    norms = np.sqrt(np.einsum("ij,ij->j", block, block))
    block = block[:, norms > 0] / norms[norms > 0]  # each column to unit length first: a
    # column amplified 10^13 times more than another must not hide it in the Gram matrix
    gram = block.T @ block
    values, vectors = np.linalg.eigh(0.5 * (gram + gram.T))
    if values[-1] <= 0:
        kept = np.zeros(0, dtype=bool)
        basis = block[:, :0]
    else:
        kept = values > (rtol * rtol) * values[-1]
        basis = _times(block, vectors[:, kept] / np.sqrt(values[kept]))
        basis = _cholesky_qr(basis)
    if keep_width and basis.shape[1] < width:
        extra = rng.standard_normal((block.shape[0], width - basis.shape[1]))
        for _ in range(2):
            extra -= _times(basis, basis.T @ extra)
        extra = _cholesky_qr(np.linalg.qr(extra)[0])
        basis = np.hstack([basis, extra])
    return np.asfortranarray(basis)


def _cholesky_qr(block: np.ndarray) -> np.ndarray:
    """The Q of ``block = Q R``, for a well-conditioned tall block (condition < 1e7)."""
    if block.shape[1] == 0:
        return block
    upper = np.linalg.cholesky(block.T @ block).T
    # R⁻¹ by LAPACK's dtrtri (the diagonal is positive: cholesky raised otherwise) times the
    # block: scipy.linalg.solve_triangular (and solve) took 3–15 ms per call on these tiny
    # matrices, whatever their size, on a loaded machine (scipy 1.17, threaded OpenBLAS) —
    # 0.3 s of a one-body model's start.  LAPACK's own routines take microseconds.
    inverse = scipy.linalg.lapack.dtrtri(upper)[0]
    return _times(block, inverse)


def _rayleigh_ritz(operator, basis: np.ndarray):
    """Singular values (ascending) of ``operator @ basis`` and the Ritz vectors.

    A Householder QR of the image keeps the small singular values accurate to rounding
    of the largest, which is what the rank decision needs.
    """
    if basis.shape[1] == 0:
        return np.zeros(0), basis
    image = np.linalg.qr(np.asfortranarray(operator @ basis), mode="r")
    _, values, right = np.linalg.svd(image)
    values = np.concatenate([values, np.zeros(basis.shape[1] - values.size)])
    order = np.argsort(values, kind="stable")
    return values[order], _times(basis, right[order].T)


def _select(basis: np.ndarray, preference: np.ndarray | None) -> np.ndarray:
    """``basis.shape[1]`` rows of `basis` forming a well-conditioned square block, sorted.

    Column-pivoted QR of the (weighted) transpose: the rows with the largest weighted
    share first, each made independent of those before.
    """
    k = basis.shape[1]
    if k == 0:
        return np.zeros(0, dtype=np.int64)
    weighted = basis if preference is None else basis * preference[:, None]
    norms = np.linalg.norm(weighted, axis=1)
    candidates = np.flatnonzero(norms > 1e-10 * norms.max())
    _, pivots = scipy.linalg.qr(weighted[candidates].T, mode="r", pivoting=True)
    return np.sort(candidates[pivots[:k]]).astype(np.int64)


def _basic(basis: np.ndarray, chosen: np.ndarray) -> np.ndarray:
    """``basis @ inv(basis[chosen])``: the same span, with the identity on the chosen rows
    (numpy's solve: scipy's is slow on small matrices, `_cholesky_qr`)."""
    if basis.shape[1] == 0:
        return basis
    return np.linalg.solve(basis[chosen].T, basis.T).T
