"""Diagnostics: the rank of the constraint Jacobian, redundant equations and free motions.

`analyse_jacobian` finds the numerical rank of a sparse Jacobian Phi_q (m equations, n
coordinates), a basis of its null space (the free motions, which no equation controls)
and of its left null space (the redundant equations, each a combination of the others).
`check_model` assembles a mechanism and reports, in words, what is wrong with it;
``sparsekin check MODEL.toml`` prints that report.  The solvers use the same analysis to
leave redundant equations out and to describe a lock-up.

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
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy import sparse
from scipy.sparse.linalg import splu

from .assembly import Assembler
from .model import COORDINATE_NAMES, Mechanism
from .pattern import EQUATION_NAMES, ConstraintPattern, build_pattern, build_point_map

__all__ = [
    "JacobianAnalysis",
    "ModelReport",
    "analyse_jacobian",
    "check_model",
    "coordinate_label",
    "describe_motion",
    "equation_label",
]

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
#: Shares of a motion or of a dependency below this are not listed.
LISTED_SHARE = 0.01
#: How many coordinates, bodies or equations a line of a report lists at most.
LISTED = 6

_EPS = np.finfo(float).eps


# ---------------------------------------------------------------------- labels
def equation_label(mechanism: Mechanism, pattern: ConstraintPattern, row: int) -> str:
    """``joints[2] (revolute c4–c1 at A), equation y``: the element and equation of a row."""
    element = int(np.searchsorted(pattern.element_first_row, row, side="right")) - 1
    within = row - int(pattern.element_first_row[element])
    n_joints = len(mechanism.joints)
    if element < n_joints:
        label = mechanism.element_label("joints", element)
        equation = EQUATION_NAMES[mechanism.joints[element].type_name][within]
    else:
        label = mechanism.element_label("drivers", element - n_joints)
        equation = "driven value"
    return f"{label}, equation {equation}"


def coordinate_label(mechanism: Mechanism, column: int) -> str:
    """``c3.angle``: the body and coordinate of a column."""
    return f"{mechanism.bodies[column // 3].name}.{COORDINATE_NAMES[column % 3]}"


# ---------------------------------------------------------------------- the analysis
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
    dependencies : ndarray, shape (m, n_redundant)
        Basis of the left null space of A: column k has 1 at ``redundant_rows[k]``, 0 at
        the other redundant rows, and expresses that row of A as a combination of the
        kept ones (``row_scale[:, None] * dependencies`` does the same for Phi_q).
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
    dependencies: np.ndarray
    smallest_singular_value: float
    smallest_motion: np.ndarray
    smallest_equations: np.ndarray
    row_scale: np.ndarray
    column_scale: np.ndarray

    @property
    def n_free(self) -> int:
        """Number of free motions, ``n - rank``."""
        return int(self.free_coordinates.size)

    @property
    def n_redundant(self) -> int:
        """Number of redundant equations, ``m - rank`` (up to rounding at the threshold)."""
        return int(self.redundant_rows.size)

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
        try:
            lu = splu(sparse.csc_array(scaled), permc_spec="COLAMD")
        except RuntimeError:  # an exactly zero pivot: rank deficient
            lu = None
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
                    dependencies=np.zeros((m, 0)),
                    smallest_singular_value=float(values[0]) / sigma_max,
                    smallest_motion=right[:, 0],
                    smallest_equations=image / np.linalg.norm(image),
                )

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
        dependencies=_basic(null_left, redundant_rows),
        smallest_singular_value=smallest_value / sigma_max,
        smallest_motion=smallest_motion,
        smallest_equations=smallest_equations,
    )


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
        dependencies=np.eye(m),
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
    return scipy.linalg.solve_triangular(upper, block.T, trans="T").T


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
    """``basis @ inv(basis[chosen])``: the same span, with the identity on the chosen rows."""
    if basis.shape[1] == 0:
        return basis
    return scipy.linalg.solve(basis[chosen].T, basis.T).T


# ---------------------------------------------------------------------- words
def shares(vector: np.ndarray) -> np.ndarray:
    """Each entry's share of the squared norm of `vector` (they sum to 1)."""
    squared = np.square(vector)
    total = squared.sum()
    return squared / total if total > 0 else squared


def motion_summary(mechanism: Mechanism, scaled_motion: np.ndarray, limit: int = LISTED) -> str:
    """``c3.angle 31%, c4.angle 25%, c1.x 12%``: the coordinates a motion moves most.

    `scaled_motion` is in the scaled coordinates of a `JacobianAnalysis` (a rotation
    counts as the displacement it causes at the body's farthest joint point), so that
    the shares compare translations and rotations fairly.
    """
    share = shares(scaled_motion)
    listed = [int(c) for c in np.argsort(-share, kind="stable")[:limit] if share[c] >= LISTED_SHARE]
    text = ", ".join(f"{coordinate_label(mechanism, c)} {_percent(share[c])}" for c in listed)
    rest = int(np.count_nonzero(share >= LISTED_SHARE)) - len(listed)
    return text + (f", … ({rest} more)" if rest > 0 else "")


def equations_summary(
    mechanism: Mechanism,
    pattern: ConstraintPattern,
    scaled_weights: np.ndarray,
    rows: np.ndarray | None = None,
    limit: int = LISTED,
    exclude: int | None = None,
) -> str:
    """``joints[2] (revolute c4–c1 at A), equation y 40%; …``: equations by their share.

    `scaled_weights` weigh the rows `rows` (all rows when None) of the scaled Jacobian.
    """
    rows = np.arange(scaled_weights.size) if rows is None else np.asarray(rows)
    if exclude is not None:  # the shares of the other equations of a dependency
        scaled_weights = np.where(rows == exclude, 0.0, scaled_weights)
    share = shares(scaled_weights)
    order = [int(k) for k in np.argsort(-share, kind="stable") if share[k] >= LISTED_SHARE]
    text = "; ".join(
        f"{equation_label(mechanism, pattern, int(rows[k]))} {_percent(share[k])}" for k in order[:limit]
    )
    return text + (f"; … ({len(order) - limit} more)" if len(order) > limit else "")


def _percent(share: float) -> str:
    return f"{100 * share:.0f}%" if share >= 0.005 else "<1%"


def describe_motion(
    mechanism: Mechanism,
    pattern: ConstraintPattern,
    coordinates: np.ndarray,
    motion: np.ndarray,
    scaled_motion: np.ndarray,
    limit: int = LISTED,
) -> str:
    """How the bodies move in a motion: ``c6 rotates about D (-0.2, 0.5)``.

    Parameters
    ----------
    mechanism, pattern
    coordinates : ndarray, shape (n,)
        The configuration, m and rad.
    motion : ndarray, shape (n,)
        A velocity of the coordinates (m, rad), up to a factor.
    scaled_motion : ndarray, shape (n,)
        The same in scaled coordinates: it decides which bodies move noticeably.
    limit : int
        Most bodies described.

    Returns
    -------
    str
        Each body that takes a share of at least 1 % of the motion, largest first:
        ``rotates about`` its instantaneous centre (named when it is a named point), or
        ``translates along`` a unit direction.
    """
    share = shares(scaled_motion).reshape(-1, 3).sum(axis=1)
    moving = [int(b) for b in np.argsort(-share, kind="stable") if share[b] >= LISTED_SHARE]
    points = _current_points(mechanism, coordinates)
    parts = []
    for body in moving[:limit]:
        x, y, _ = coordinates[3 * body : 3 * body + 3]
        vx, vy, omega = motion[3 * body : 3 * body + 3]
        speed = math.hypot(vx, vy)
        name = mechanism.bodies[body].name
        if abs(omega) * pattern.length_scale <= 1e-9 * speed:
            parts.append(f"{name} translates along ({_shown(vx / speed, 1.0)}, {_shown(vy / speed, 1.0)})")
            continue
        centre = (x - vy / omega, y + vx / omega)
        label = _named_point(points, centre, pattern.length_scale)
        shown = f"({_shown(centre[0], pattern.length_scale)}, {_shown(centre[1], pattern.length_scale)})"
        where = f"{label} {shown}" if label else shown
        parts.append(f"{name} rotates about {where}")
    if len(moving) > limit:
        parts.append(f"… ({len(moving)} bodies move)")
    return ", ".join(parts) if parts else "nothing moves noticeably"


def _shown(value: float, scale: float) -> str:
    """`value` to 4 digits, and 0 when it is rounding noise against `scale`."""
    return f"{value:.4g}" if abs(value) > 1e-9 * scale else "0"


def _current_points(mechanism: Mechanism, coordinates: np.ndarray) -> dict[str, tuple[float, float]]:
    """Global position of every named point in the configuration `coordinates`."""
    point_map = build_point_map(mechanism)
    positions = {}
    for k, name in enumerate(point_map.names):
        body = int(point_map.body[k])
        local = point_map.local[k]
        if body < 0:
            positions[name] = (float(local[0]), float(local[1]))
            continue
        x, y, angle = coordinates[3 * body : 3 * body + 3]
        cosine, sine = math.cos(angle), math.sin(angle)
        positions[name] = (x + cosine * local[0] - sine * local[1], y + sine * local[0] + cosine * local[1])
    return positions


def _named_point(points: dict[str, tuple[float, float]], where: tuple[float, float], scale: float):
    """The named point nearest to `where`, if within a millionth of `scale`."""
    best, distance = None, 1e-6 * scale
    for name, (x, y) in points.items():
        gap = math.hypot(x - where[0], y - where[1])
        if gap <= distance:
            best, distance = name, gap
    return best


# ---------------------------------------------------------------------- check_model
#: Newton corrections allowed when assembling the model in `check_model`.
ASSEMBLY_MAXITER = 20
#: Convergence tolerance of the assembly: lengths relative to the model size, angles in rad.
ASSEMBLY_TOLERANCE = 1e-12
#: A redundant equation is consistent when its residual at the assembled configuration is
#: below this (lengths relative to the model size, angles in rad).
CONSISTENCY_TOLERANCE = 1e-9


@dataclass(frozen=True)
class RedundantEquation:
    """An equation that depends on the others at the analysed configuration.

    Attributes
    ----------
    row : int
        Its row in the Jacobian.
    label : str
        ``joints[5] (revolute coupler–crank2 at T2), equation x``.
    residual : float
        Its residual at the configuration, in `unit`: zero when the redundancy is
        consistent.
    unit : str
        ``"m"`` or ``"rad"``.
    consistent : bool
        Whether `residual` is within `CONSISTENCY_TOLERANCE`.
    depends_on : str
        The other equations of the dependency, with their shares.
    involves_drivers : bool
        Whether a driver takes part in the dependency (the drivers then prescribe a
        motion that the joints already fix).
    """

    row: int
    label: str
    residual: float
    unit: str
    consistent: bool
    depends_on: str
    involves_drivers: bool


@dataclass(frozen=True)
class FreeMotion:
    """A motion that no equation controls (one vector of a basis of the null space).

    Attributes
    ----------
    coordinate : str
        The coordinate this motion moves and the other free motions do not (``c6.angle``).
    bodies : str
        How the bodies move: ``c6 rotates about D (-0.2, 0.5)``.
    coordinates : str
        The coordinates it moves, with their shares of the motion.
    """

    coordinate: str
    bodies: str
    coordinates: str


@dataclass(frozen=True, eq=False)
class ModelReport:
    """What `check_model` found: counts, rank, redundant equations and free motions.

    Attributes
    ----------
    name : str
    time : float
        The time of the analysis, s.
    n_bodies, n_coordinates, n_joints, n_joint_equations, n_drivers, n_equations : int
    assembled : bool
        Whether Newton–Raphson reached a configuration satisfying the equations (the
        redundant ones left out, the free coordinates held) from the model's drawing.
    assembly : str
        How the assembly went, in words.
    rank : int
        Numerical rank of the Jacobian at the assembled configuration (at the drawn one
        if the assembly failed).
    analysis : JacobianAnalysis
        The details of that rank analysis.
    redundant : tuple of RedundantEquation
    free_motions : tuple of FreeMotion
    """

    name: str
    time: float
    n_bodies: int
    n_coordinates: int
    n_joints: int
    n_joint_equations: int
    n_drivers: int
    n_equations: int
    assembled: bool
    assembly: str
    rank: int
    redundant: tuple[RedundantEquation, ...]
    free_motions: tuple[FreeMotion, ...]
    analysis: JacobianAnalysis

    @property
    def dof_by_count(self) -> tuple[int, int]:
        """Grübler's count, 3 per body minus the equations: without and with the drivers."""
        return self.n_coordinates - self.n_joint_equations, self.n_coordinates - self.n_equations

    @property
    def dof_by_rank(self) -> tuple[int, int]:
        """Degrees of freedom from the numerical rank: without and with the drivers.

        Without the drivers, the rank of the joints' rows is ``rank - n_drivers + d``
        where d is the number of independent dependencies that involve drivers.
        """
        n_free = self.n_coordinates - self.rank
        dependencies = self.analysis.dependencies
        involved = dependencies[self.n_joint_equations :]
        if involved.size:
            scale = float(np.abs(dependencies).max())
            driver_dependencies = int(np.linalg.matrix_rank(involved, tol=1e-8 * scale))
        else:
            driver_dependencies = 0
        return n_free + self.n_drivers - driver_dependencies, n_free

    @property
    def problems(self) -> tuple[str, ...]:
        """One line per problem; empty when the model is sound."""
        problems = []
        if not self.assembled:
            problems.append(f"cannot assemble at t = {self.time:g} s")
        if self.redundant:
            inconsistent = sum(not equation.consistent for equation in self.redundant)
            drivers = any(equation.involves_drivers for equation in self.redundant)
            text = f"{len(self.redundant)} redundant equation{'s' * (len(self.redundant) != 1)}"
            if inconsistent:
                text += f", {inconsistent} of them not satisfied (the joints contradict each other)"
            if drivers:
                text += (", drivers among them (the drivers prescribe a motion that the joints fix, or the "
                         "configuration is a dead centre)")
            problems.append(text)
        if self.free_motions:
            problems.append(f"{len(self.free_motions)} free motion{'s' * (len(self.free_motions) != 1)}")
        return tuple(problems)

    @property
    def sound(self) -> bool:
        """No problem: assembled, no redundant equation, no free motion."""
        return not self.problems

    def __str__(self) -> str:
        return format_report(self)


def check_model(mechanism: Mechanism, time: float = 0.0) -> ModelReport:
    """Assemble `mechanism` at `time` and report its rank, redundant equations and free motions.

    Newton–Raphson first brings the drawn configuration onto the constraints (leaving out
    the redundant equations and holding the free coordinates, both found at the drawn
    configuration), then `analyse_jacobian` studies the Jacobian there.

    Parameters
    ----------
    mechanism : Mechanism
    time : float
        Time of the analysis, s (the drivers' values at that time are used).

    Returns
    -------
    ModelReport
        ``str(report)`` is a readable report; ``report.sound`` says whether anything is
        wrong.

    Examples
    --------
    >>> from sparsekin import Body, Linear, Mechanism, Revolute, RotationalDriver
    >>> crank = Mechanism(
    ...     points={"O": (0.0, 0.0), "A": (0.1, 0.0)},
    ...     bodies=[Body("crank", origin="O", points=("O", "A"))],
    ...     joints=[Revolute(("crank", "ground"), at="O")],
    ...     drivers=[RotationalDriver(("crank", "ground"), law=Linear(rate=2.0))],
    ... )
    >>> report = check_model(crank)
    >>> report.sound, report.rank, report.dof_by_count, report.dof_by_rank
    (True, 3, (1, 0), (1, 0))
    >>> unpinned = Mechanism(points=crank.points, bodies=crank.bodies, drivers=crank.drivers)
    >>> report = check_model(unpinned)
    >>> report.problems
    ('2 free motions',)
    >>> [motion.bodies for motion in report.free_motions]
    ['crank translates along (1, 0)', 'crank translates along (0, 1)']
    """
    if not isinstance(mechanism, Mechanism):
        raise TypeError(f"`mechanism` must be a Mechanism, got {type(mechanism).__name__}.")
    is_number = isinstance(time, (int, float, np.integer, np.floating)) and not isinstance(time, bool)
    if not (is_number and math.isfinite(time)):
        raise ValueError(f"`time` must be a finite number (s), got {time!r}.")
    pattern = build_pattern(mechanism)
    weights = residual_weights(pattern)
    preference = row_preference(mechanism, pattern)
    drawn = pattern.initial_coordinates.copy()
    if pattern.n_equations == 0:  # nothing to assemble: every coordinate is free
        analysis = analyse_jacobian(sparse.csr_array((0, pattern.n_coordinates)))
        assembled, coordinates, assembly = True, drawn, f"nothing to assemble at t = {time:g} s: no equation"
        residual = raw_residual = np.zeros(0)
    else:
        assembler = Assembler(mechanism, pattern)
        assembler.set_time(float(time))
        assembler.fill_residual_jacobian(drawn)
        first = analyse_jacobian(assembler.jacobian, row_preference=preference)
        assembled, coordinates, assembly = _assemble(
            mechanism, pattern, assembler, float(time), drawn, first, weights
        )
        assembler.fill_residual_jacobian(coordinates)
        analysis = analyse_jacobian(assembler.jacobian, row_preference=preference) if assembled else first
        raw_residual = assembler.residual
        residual = raw_residual * weights
    n_joint_equations = int(pattern.element_first_row[len(mechanism.joints)])
    redundant = tuple(
        RedundantEquation(
            row=int(row),
            label=equation_label(mechanism, pattern, int(row)),
            residual=float(abs(raw_residual[row])),
            unit="rad" if pattern.row_is_angle[row] else "m",
            consistent=bool(abs(residual[row]) <= CONSISTENCY_TOLERANCE),
            depends_on=equations_summary(mechanism, pattern, analysis.dependencies[:, k], exclude=int(row)),
            involves_drivers=bool(np.any(shares(analysis.dependencies[:, k])[n_joint_equations:] >= 1e-12)),
        )
        for k, row in enumerate(analysis.redundant_rows)
    )
    free_motions = tuple(
        FreeMotion(
            coordinate=coordinate_label(mechanism, int(column)),
            bodies=describe_motion(
                mechanism, pattern, coordinates,
                analysis.free_motions[:, k], analysis.scaled_free_motions[:, k],
            ),
            coordinates=motion_summary(mechanism, analysis.scaled_free_motions[:, k]),
        )
        for k, column in enumerate(analysis.free_coordinates)
    )
    return ModelReport(
        name=mechanism.name,
        time=float(time),
        n_bodies=mechanism.n_bodies,
        n_coordinates=pattern.n_coordinates,
        n_joints=len(mechanism.joints),
        n_joint_equations=n_joint_equations,
        n_drivers=len(mechanism.drivers),
        n_equations=pattern.n_equations,
        assembled=assembled,
        assembly=assembly,
        rank=analysis.rank,
        redundant=redundant,
        free_motions=free_motions,
        analysis=analysis,
    )


def residual_weights(pattern: ConstraintPattern) -> np.ndarray:
    """Weights that make residuals comparable: 1 for angles (rad), 1 / model size for lengths."""
    return np.where(pattern.row_is_angle, 1.0, 1.0 / pattern.length_scale)


def row_preference(mechanism: Mechanism, pattern: ConstraintPattern) -> np.ndarray:
    """Which equations to name redundant first: later joints, and drivers only as a last resort."""
    m = pattern.n_equations
    preference = 1.0 + np.arange(m) / max(m, 1)
    preference[int(pattern.element_first_row[len(mechanism.joints)]) :] *= 1e-3
    return preference


def _assemble(mechanism, pattern, assembler, time, drawn, analysis, weights):
    """Newton–Raphson on the equations that are not redundant, the free coordinates held.

    Returns (converged, coordinates, words).  After convergence, up to two more
    corrections bring the residual to the rounding floor, so that the rank analysis at
    the result is not blurred by a residual just below the tolerance.
    """
    m, n = pattern.n_equations, pattern.n_coordinates
    kept = np.setdiff1d(np.arange(m), analysis.redundant_rows)
    held = analysis.free_coordinates
    selector = sparse.csr_array((np.ones(held.size), (np.arange(held.size), held)), shape=(held.size, n))
    coordinates = drawn.copy()
    best, best_norm, corrections = coordinates.copy(), math.inf, 0
    polishing = 0
    worst = 0
    for iteration in range(ASSEMBLY_MAXITER + 1):
        assembler.fill_residual_jacobian(coordinates)
        residual = assembler.residual[kept] * weights[kept]
        norm = float(np.max(np.abs(residual), initial=0.0))
        if not math.isfinite(norm):
            break
        if norm < best_norm:
            best, best_norm, corrections = coordinates.copy(), norm, iteration
            worst = int(kept[np.argmax(np.abs(residual))]) if residual.size else 0
        elif best_norm <= ASSEMBLY_TOLERANCE:
            break  # at the rounding floor
        if best_norm <= ASSEMBLY_TOLERANCE:
            polishing += 1
            if polishing > 2 or norm == 0.0:
                break
        if iteration == ASSEMBLY_MAXITER or kept.size + held.size == 0:
            break
        square = sparse.vstack([assembler.jacobian[kept], selector]).tocsc()
        try:
            step = splu(square, permc_spec="COLAMD").solve(
                np.concatenate([assembler.residual[kept], coordinates[held] - drawn[held]])
            )
        except RuntimeError:
            return False, best, (
                f"cannot assemble at t = {time:g} s: the Jacobian is singular after "
                f"{iteration} Newton corrections"
            )
        if not np.all(np.isfinite(step)):
            break
        coordinates = coordinates - step
    if best_norm <= ASSEMBLY_TOLERANCE:
        moved = float(np.max(np.abs(best - drawn) * _coordinate_weights(pattern), initial=0.0))
        return True, best, (
            f"assembled at t = {time:g} s in {corrections} Newton correction{'s' * (corrections != 1)} "
            f"from the drawing: largest residual {best_norm:.2g}, largest change of a coordinate "
            f"{moved:.2g} (lengths relative to the model size, {pattern.length_scale:.4g} m; angles in rad)"
        )
    where = equation_label(mechanism, pattern, worst) if m else "no equation"
    return False, drawn, (
        f"cannot assemble at t = {time:g} s: Newton–Raphson did not converge from the drawing "
        f"(smallest residual reached {best_norm:.3g}, relative to the model size; largest in {where})"
    )


def _coordinate_weights(pattern: ConstraintPattern) -> np.ndarray:
    weights = np.full(pattern.n_coordinates, 1.0 / pattern.length_scale)
    weights[2::3] = 1.0
    return weights


def format_report(report: ModelReport) -> str:
    """The report of ``sparsekin check``: a few lines, then one block per problem."""
    analysis = report.analysis
    joints_text = f"{report.n_joint_equations} from {report.n_joints} joint{'s' * (report.n_joints != 1)}"
    drivers_text = f"{report.n_equations - report.n_joint_equations} from {report.n_drivers} driver" + (
        "s" * (report.n_drivers != 1)
    )
    count_without, count_with = report.dof_by_count
    rank_without, rank_with = report.dof_by_rank
    where = "assembled" if report.assembled else "drawn"
    lines = [
        f"model {report.name}: {report.n_bodies} bodies, {report.n_coordinates} coordinates, "
        f"{report.n_equations} equations ({joints_text}, {drivers_text})",
        f"degrees of freedom by count (3 per body minus equations): {count_without} without the drivers, "
        f"{count_with} with them",
        report.assembly,
        f"rank of the Jacobian at the {where} configuration: {report.rank} for {report.n_equations} "
        f"equations and {report.n_coordinates} coordinates (singular values of the row- and "
        f"column-scaled Jacobian above {analysis.tolerance:.2g} × the largest)",
        f"degrees of freedom by rank: {rank_without} without the drivers, {rank_with} with them",
        f"condition number of the scaled Jacobian (on its rank): {_number(analysis.condition)}",
    ]
    if report.redundant:
        lines.append(f"redundant equations ({len(report.redundant)}):")
        for equation in report.redundant:
            state = "consistent" if equation.consistent else "NOT satisfied"
            lines.append(f"  {equation.label}: residual {equation.residual:.3g} {equation.unit}, {state}")
            lines.append(f"      depends on {equation.depends_on or 'nothing else (a zero equation)'}")
    else:
        lines.append("redundant equations: none")
    if report.free_motions:
        lines.append(f"free motions ({len(report.free_motions)}):")
        for k, motion in enumerate(report.free_motions, start=1):
            lines.append(f"  {k}. {motion.bodies}")
            lines.append(f"      moves {motion.coordinates}")
    else:
        lines.append("free motions: none")
    lines.append("verdict: " + ("sound" if report.sound else "; ".join(report.problems)))
    return "\n".join(lines)


def _number(value: float) -> str:
    return "infinite" if not math.isfinite(value) else f"{value:.4g}"
