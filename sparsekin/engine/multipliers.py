"""The multipliers of inverse dynamics: λ from Φqᵀ λ = b at a solved sample.

At a `~sparsekin.engine.linearization.Linearization` (what a stepper publishes after a
sample) the factorization of the kept rows of Φq is at hand: λ costs one transposed
solve (`Multipliers.solve`).

A model with redundant equations has many λ: the equations left out carry none in the
solve; the answer given is the one of minimum norm, λ − W (WᵀW)⁻¹ Wᵀ λ with W the
dependencies of the equations at the sample (one more transposed solve per redundant
equation), up to `MAX_MIN_NORM_EQUATIONS` of them; beyond, the same λ by conjugate
gradients on the redundant equations' multipliers, two solves with the factorization
already held per iteration (`minimum_norm_multipliers`), or, if they converge too slowly,
one sparse LU per sample of the augmented system (`augmented_minimum_norm`).  That norm adds squares of newtons
(the multipliers of position equations) to squares of newton-metres (those of angle
equations, e.g. a rigid or translational joint's angle row), unweighted: when a
redundant set mixes both kinds, how the load is shared among them depends on the unit
of length (metres here: in millimetres the angle rows' multipliers would be a thousand
times larger and the split would differ).  Any of those answers holds the motion; only
their split among the redundant joints is a convention.
"""

from __future__ import annotations

import numpy as np

from .linearization import Linearization

__all__ = ["Multipliers", "MAX_MIN_NORM_EQUATIONS", "MIN_NORM_ITERATIONS", "minimum_norm_multipliers",
           "augmented_minimum_norm", "redundant_minimum_norm"]

#: The minimum-norm multipliers of a redundant model cost, through the dependencies, one
#: transposed solve per redundant equation and a dense (n_equations × n_redundant) matrix
#: per sample; above this many redundant equations conjugate gradients with the held
#: factorization (`minimum_norm_multipliers`) cost less, with a sparse LU of the augmented
#: system per sample (`augmented_minimum_norm`) where they do not converge.
MAX_MIN_NORM_EQUATIONS = 64
#: Conjugate gradients of `minimum_norm_multipliers`: relative residual and most
#: iterations.  The system's eigenvalues are 1 + the squared singular values of the
#: redundant rows written in the kept ones (C); 10^4-cell parallel-bar chain: 3 to 7
#: iterations per sample (docs/design-notes.md, "Redundant equations at scale").
MIN_NORM_TOLERANCE = 1e-12
MIN_NORM_ITERATIONS = 60
#: Iterative refinements of `augmented_minimum_norm`, the fallback when conjugate
#: gradients do not converge (100×100 rotating squares: not within 500 iterations; the
#: augmented LU then costs about 0.6 s per sample).
AUGMENTED_REFINEMENTS = 2


class Multipliers:
    """λ with Φqᵀ λ = rhs at each sample, minimum-norm for a redundant model.

    Parameters
    ----------
    n_equations : int
    min_norm_iterations : int
        Conjugate-gradient iterations before the augmented LU takes over (`MIN_NORM_ITERATIONS`).

    Attributes
    ----------
    values : ndarray, shape (n_equations,)
        The last λ (reused).
    """

    def __init__(self, n_equations: int, min_norm_iterations: int = MIN_NORM_ITERATIONS) -> None:
        self.values = np.zeros(n_equations)
        self.min_norm_iterations = int(min_norm_iterations)
        # conjugate gradients on the redundant multipliers failed once: the augmented LU from then on
        self._augmented = False

    def solve(self, lin: Linearization, rhs: np.ndarray) -> np.ndarray:
        """Φqᵀ λ = rhs with the factorization of `lin`; returns `values`."""
        solver, multipliers, kept = lin.factorization, self.values, lin.kept_rows
        if kept is None:
            solver.solve(rhs, out=multipliers, transposed=True)
            return multipliers
        multipliers[:] = 0.0
        multipliers[kept] = solver.solve(rhs, transposed=True)
        redundant = lin.redundant_rows
        jacobian = lin.jacobian()
        if redundant.size > MAX_MIN_NORM_EQUATIONS:
            parts = None
            if not self._augmented:
                parts = minimum_norm_multipliers(solver, jacobian[redundant], multipliers[kept].copy(),
                                                 self.min_norm_iterations)  # fmt: skip
            if parts is None:  # conjugate gradients too slow (then at every sample): one sparse LU of the augmented system
                self._augmented = True
                multipliers[:] = augmented_minimum_norm(jacobian, rhs)
            else:
                multipliers[kept], multipliers[redundant] = parts
            return multipliers
        # the dependencies w (W's columns): row r of Φq = Σ c_k · kept row k, c from Φ_keptᵀ c = Φ_rᵀ
        dependencies = np.zeros((multipliers.size, redundant.size))
        for c, r in enumerate(redundant.tolist()):
            dependencies[kept, c] = -solver.solve(jacobian[[r]].toarray().ravel(), transposed=True)
            dependencies[r, c] = 1.0
        return _without_dependencies(multipliers, dependencies)


def _without_dependencies(multipliers: np.ndarray, dependencies: np.ndarray) -> np.ndarray:
    """`multipliers` − W (WᵀW)⁻¹ Wᵀ `multipliers` in place (W: the dependencies as columns,
    a basis of the null space of Φqᵀ): the solution of Φqᵀ λ = Φqᵀ `multipliers` of minimum norm."""
    gram = dependencies.T @ dependencies
    multipliers -= dependencies @ np.linalg.solve(gram, dependencies.T @ multipliers)
    return multipliers


def redundant_minimum_norm(jacobian, kept_rows: np.ndarray, redundant_rows: np.ndarray,
                           multipliers: np.ndarray) -> np.ndarray:  # fmt: skip
    """The λ of minimum norm with Φqᵀ λ = Φqᵀ `multipliers` (a new array), for a Φq whose
    `redundant_rows` are combinations of its independent `kept_rows` (`multipliers` is 0 on
    the redundant rows: the integrator's λ of forward dynamics).

    Unlike `Multipliers.solve`, the kept rows B need not be square (forward dynamics keeps
    the degrees of freedom): the dependencies, row r = Σ c_k · kept row k, come from the
    normal equations (B Bᵀ) c = B a_rᵀ (one sparse LU of B Bᵀ per call, one solve and one
    refinement per redundant row; their condition is B's squared, fine away from a loss of
    rank), then W's columns are (−c on the kept rows, 1 on row r) as there.
    """
    from scipy.sparse.linalg import splu

    kept_block, redundant_block = jacobian[kept_rows], jacobian[redundant_rows]
    normal = splu((kept_block @ kept_block.T).tocsc(), permc_spec="MMD_AT_PLUS_A")
    target = (kept_block @ redundant_block.T).toarray()
    coefficients = normal.solve(target)
    coefficients += normal.solve(target - (kept_block @ (kept_block.T @ coefficients)))
    dependencies = np.zeros((multipliers.size, redundant_rows.size))
    dependencies[kept_rows] = -coefficients
    dependencies[redundant_rows, np.arange(redundant_rows.size)] = 1.0
    return _without_dependencies(multipliers.copy(), dependencies)


def minimum_norm_multipliers(solver, redundant_jacobian, particular: np.ndarray,
                             max_iterations: int = MIN_NORM_ITERATIONS) -> tuple[np.ndarray, np.ndarray] | None:  # fmt: skip
    """The multipliers of minimum norm, ``(λ_K, λ_R)``, from a particular solution.

    With B the kept rows of Φq (square, factored in `solver`) and A_R the redundant rows
    (`redundant_jacobian`), every solution of ``Bᵀ λ_K + A_Rᵀ λ_R = rhs`` is
    ``λ_K = particular − C λ_R`` with ``particular = B⁻ᵀ rhs`` and ``C = B⁻ᵀ A_Rᵀ``.  The
    one of minimum norm has ``(I + CᵀC) λ_R = Cᵀ particular``: a symmetric system with
    eigenvalues ≥ 1, solved by conjugate gradients, two solves with the factorization
    already held per iteration (`MIN_NORM_TOLERANCE`, at most `max_iterations`).

    Returns None if the iteration has not converged after `max_iterations`.
    """
    def operator(vector: np.ndarray) -> np.ndarray:
        image = solver.solve(redundant_jacobian.T @ vector, transposed=True)  # C v
        return vector + redundant_jacobian @ solver.solve(image)  # v + Cᵀ C v

    rhs = redundant_jacobian @ solver.solve(particular)  # Cᵀ particular
    solution = np.zeros_like(rhs)
    residual = rhs.copy()
    direction = residual.copy()
    squared = float(residual @ residual)
    target = MIN_NORM_TOLERANCE**2 * max(squared, np.finfo(float).tiny)
    for _ in range(max_iterations):
        if squared <= target:
            break
        image = operator(direction)
        step = squared / float(direction @ image)
        solution += step * direction
        residual -= step * image
        squared, previous = float(residual @ residual), squared
        direction = residual + (squared / previous) * direction
    else:
        if squared > target:
            return None
    kept = particular - solver.solve(redundant_jacobian.T @ solution, transposed=True)
    return kept, solution


def augmented_minimum_norm(jacobian, rhs: np.ndarray) -> np.ndarray:
    """The λ of minimum norm with ``Φqᵀ λ = rhs`` (Φq of full column rank) from one sparse LU
    of ``[[I, Φq], [Φqᵀ, 0]]`` (its solution ``(λ, −μ)`` has λ = Φq μ, in the range of Φq),
    refined `AUGMENTED_REFINEMENTS` times: its condition is that of Φq squared."""
    from scipy import sparse
    from scipy.sparse.linalg import splu

    m = jacobian.shape[0]
    augmented = sparse.block_array([[sparse.identity(m, format="csr"), jacobian], [jacobian.T, None]], format="csc")
    factor = splu(augmented, permc_spec="COLAMD")
    target = np.concatenate([np.zeros(m), rhs])
    solution = factor.solve(target)
    for _ in range(AUGMENTED_REFINEMENTS):
        solution += factor.solve(target - augmented @ solution)
    return solution[:m]
