"""The equations of motion as numbers: their residual and the saddle-point iteration matrix.

Forward dynamics solves, at each time,

    f(q, qd, qdd, lam) = M(q) qdd + h(q, qd) - Q(q, qd, t) + Phi_q^T lam = 0,
    Phi(q, t) = 0,

with Q gravity and the loads (actuators along joints included) and h the centripetal
terms.  An implicit step linearises them into the *saddle* matrix

    S = [[a M + b C_t + c K_t, Phi_q^T], [Phi_q, -r I]],   C_t = df/dqd,  K_t = df/dq,

whose pattern is known before the first step: every body's 3×3 mass block, a 6×6 block
for each pair of bodies that a constraint primitive or a spring couples, and the
Jacobian's entries twice.  `DynamicSystem` builds that pattern once (`SaddlePattern`, from
one run of the kernels of `sparsekin.engine._dynamics_kernels`, which write their entries
in an order fixed by the model) and refills its values in place: a numba scatter of the
kernels' triplets into the CSR values, no allocation per call.  ``(a, b, c) = (1, 0, 0)``
gives [[M, Phi_q^T], [Phi_q, 0]] (initial accelerations and multipliers, velocity
projection); generalized-alpha takes ``(1, gamma'/beta', 1/beta')``, its scaled form
(`sparsekin.solve.dynamics`).

Redundant equations are left out of the saddle (``kept_rows``): their multipliers are 0.
A small ``r`` (only in an iteration matrix: the residual stays exact) keeps S regular where
Φq loses rank for an instant (a chain of parallelograms with its bars aligned): Newton's
multiplier updates there stay bounded, as in a least-squares step.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from . import _dynamics_kernels as kernels
from . import _motion_kernels, _projection_kernels, _saddle_pattern_kernels
from .actuators import actuator_kernel_arrays
from .assembly import Assembler
from .typed_calls import TypedCalls
from .discretization import Discretization

__all__ = ["SaddlePattern", "DynamicSystem"]


@dataclass(frozen=True, eq=False)
class SaddlePattern:
    """The CSR pattern of the saddle matrix and where each kernel triplet goes.

    Attributes
    ----------
    size : int
        n_coordinates + number of kept equations.
    indptr, indices : ndarray
        CSR pattern, columns sorted within rows.
    slots : ndarray of int, shape (n_triplets,), or None
        The position of each triplet in the CSR values; ``nnz`` (a discard slot) for the
        ground's coordinates and left-out equations.  None in `DynamicSystem.saddle` when
        the system holds only the slots it cannot derive (`DynamicSystem.triplet_slots`
        gives them all).
    """

    size: int
    indptr: np.ndarray
    indices: np.ndarray
    slots: np.ndarray | None

    @property
    def nnz(self) -> int:
        return int(self.indptr[-1])

    @classmethod
    def from_triplets(cls, rows: np.ndarray, cols: np.ndarray, n: int, size: int) -> SaddlePattern:
        """The pattern of triplets whose indices are coordinates (the ground's three,
        ``n .. n + 2``, discarded) or ``n + 3 + k`` for the k-th kept equation (negative:
        left out, discarded); indices and slots 32-bit where they fit."""
        dtype = _index_dtype(max(size, rows.size))
        indptr = np.zeros(size + 1, dtype=np.int64)
        slots = np.empty(rows.size, dtype=dtype)
        indices = kernels.saddle_pattern(rows, cols, n, indptr, slots)
        index = _index_dtype(max(size, indices.size))  # one dtype for both: scipy keeps them as they are
        return cls(size, indptr.astype(index), indices.astype(index), slots)


def _is_every_row(kept_rows: np.ndarray, m: int) -> bool:
    """Whether `kept_rows` is ``0, 1, …, m − 1`` (every equation kept, in order)."""
    if kept_rows.size != m:
        return False
    return m == 0 or (int(kept_rows[0]) == 0 and bool(np.all(np.diff(kept_rows) == 1)))


def _index_dtype(largest: int) -> type:
    """int32 when every index fits (half the memory), int64 otherwise."""
    return np.int32 if largest < np.iinfo(np.int32).max - 1 else np.int64


def _untouched_zeros(shape) -> np.ndarray:
    """float64 zeros in an anonymous mapping of their own, resident only where written
    (``np.zeros`` of a chunk glibc reuses clears it, which makes every page resident at once:
    at 10^6 bodies 40 MB for the kernels' q and turns, which the chain's steps never write)."""
    import mmap

    size = int(np.prod(shape))
    return np.frombuffer(mmap.mmap(-1, max(8 * size, 1)), dtype=np.float64, count=size).reshape(shape)


class DynamicSystem:
    """Residual of the equations of motion and the saddle matrix of a mechanism, in place.

    Parameters
    ----------
    discretization : Discretization
        The mechanism's arrays (`sparsekin.engine.discretization.discretize`).
    kept_rows : ndarray of int, optional
        The equations in the saddle (default all); the others are redundant.
    assembler : Assembler, optional
        The constraints' assembler, if already made.

    Attributes
    ----------
    assembler : Assembler
        The constraints: residual Phi, Jacobian, velocity and acceleration right-hand sides.
    loads : LoadPattern
    law_values : ndarray
        The load laws' values at the last `set_time`.
    matrix : scipy.sparse.csr_array, shape (size, size)
        S after `fill_matrix`; its pattern is fixed.
    n, size : int
        Coordinates; coordinates plus kept equations.
    """

    def __init__(self, discretization: Discretization, kept_rows: np.ndarray | None = None,
                 assembler: Assembler | None = None) -> None:  # fmt: skip
        from scipy.sparse import csr_array

        self.pattern = pattern = discretization.constraints
        self.assembler = Assembler(discretization) if assembler is None else assembler
        self.loads = discretization.loads
        self.actuators = self.loads.actuators
        n, m = pattern.n_coordinates, pattern.n_equations
        self.n = n
        row = _index_dtype(m)  # (int32 for any chain: read by every pass over Φq; 12 MB fewer at 10^6 bodies)
        self.kept_rows = np.arange(m, dtype=row) if kept_rows is None else np.asarray(kept_rows).astype(row)
        if _is_every_row(self.kept_rows, m):  # then each row's index among the kept is its own: one array
            self.kept_row = self.kept_rows
        else:
            self.kept_row = np.full(m, -1, dtype=row)
            self.kept_row[self.kept_rows] = np.arange(self.kept_rows.size)
        self.size = n + self.kept_rows.size
        n_laws = self.loads.n_laws
        self.law_values, self._law_rates, self._law_accelerations = np.zeros(n_laws), np.zeros(n_laws), np.zeros(n_laws)
        # the kernels' q, qd, qdd with the ground appended; qd is the assembler's own (each side
        # writes the velocities into it before every read, the ground's entries stay 0): one array fewer
        # q and the turns are written only where a call is not at the constraints' last refill
        # (`_shared`): in the chain's steps never, so they are kept out of the resident memory
        self._q, self._qd, self._qdd = _untouched_zeros(n + 3), self.assembler.filled_motion()[1], np.zeros(n + 3)
        self._turns = _untouched_zeros((pattern.n_bodies + 1, 2))
        self._applied = np.zeros(n + 3)
        self._actuator_weights = np.zeros(n_laws)
        self._actuator_arrays = actuator_kernel_arrays(self.actuators, n_laws, pattern.n_bodies)
        # the kernels that take the model's NamedTuples, their typing held (`typed_calls`: ~40 µs a step at 10^3 bodies)
        self._motion, self._kernels = TypedCalls(_motion_kernels), TypedCalls(kernels)
        arrays = self.loads.arrays
        # whether the loads read no velocity or acceleration of the ground (body n_bodies): Newton's
        # right-hand side then reads the state's, not copies with the ground appended
        pairs = (arrays.spring.body_i, arrays.spring.body_j, arrays.torsion.body_i, arrays.torsion.body_j)
        self._direct_motion = arrays.masses.mass.size <= pattern.n_bodies and all(
            bool(np.all(bodies < pattern.n_bodies)) for bodies in pairs)  # fmt: skip
        # whether the refill of the constraints and Newton's right-hand side can be one pass
        # (`fill_constraints_newton_rhs`): every equation a kept row of a point coincidence, in their order
        primitives, c = pattern.primitives, pattern.primitives.coincidence
        self._coincidence_rows = (self._direct_motion and self.actuators is None and m == 2 * c.row.size
                                  and self.kept_rows.size == m and bool(np.array_equal(c.row, np.arange(0, m, 2)))
                                  and primitives.projection.row.size == primitives.distance.row.size == 0
                                  and primitives.combination.row.size == 0)  # fmt: skip
        count = (9 * pattern.n_bodies + arrays.force.body.size + 36 * arrays.spring.body_i.size
                 + 4 * arrays.torsion.body_i.size + kernels.hessian_entries(pattern.primitives)
                 + 2 * pattern.nnz + self.kept_rows.size)  # fmt: skip
        if self.actuators is not None:
            count += kernels.hessian_entries(self.actuators.equations.primitives)
        index = _index_dtype(n + 3 + m)
        block_count = count - 2 * pattern.nnz - self.kept_rows.size  # the coordinate block's
        self._rows = np.zeros(block_count, dtype=index)
        self._cols = np.zeros(block_count, dtype=index)
        self._vals = np.zeros(block_count)
        self._block_count = 0  # triplets of the coordinate block at the last `product` or `residuals`
        self._block_compact = False  # the last of them `residuals`'s: the bodies' inertia in `_inertia`
        self._constants_in = None  # the buffer in which a fused refill wrote Φq's constant entries (`_constants`)
        self._scratch = (np.zeros(6), np.zeros(6), np.zeros((2, 6)), np.zeros((6, 6)), np.zeros((6, 6)))
        # one run at the drawing fixes the pattern
        drawn = pattern.initial_coordinates
        self.assembler.set_time(0.0)
        self.assembler.fill_residual_jacobian(drawn)
        block = self._fill_block_triplets(drawn, np.zeros(n), np.zeros(n), np.zeros(m), 1.0, 1.0, 1.0)
        if not self._pattern_from_parts(block, _index_dtype(max(self.size, count))):
            self._pattern_from_triplets(block, count, index)
        # `residuals`' inertia blocks, six values a body (`_projection_kernels.fill_inertia_values`), in
        # the values of their nine triplets (no memory of their own; `_block_compact` says which)
        bodies = arrays.masses.mass.size
        self._inertia = self._vals[: 6 * bodies].reshape(bodies, 6)
        self._data = np.zeros(self.saddle.nnz + 1)
        self.matrix = csr_array((self._data[:-1], self.saddle.indices, self.saddle.indptr), shape=(self.size, self.size))

    def _pattern_from_parts(self, block: int, slot_dtype: type) -> bool:
        """S's pattern from the block's first `block` triplets and the Jacobian's rows
        (`sparsekin.engine._saddle_pattern_kernels`: the same pattern and slots as sorting
        every triplet, without Φq's): `saddle` and `_slots`, Φq's and the diagonal's slots
        derived from the row pointers; False (nothing set) where the Jacobian's rows or the
        kept equations are not in order."""
        p, n = self.pattern, self.n
        ok, block_start, block_columns = _saddle_pattern_kernels.coordinate_block_rows(self._rows, self._cols, block, n)
        saddle_indptr = np.zeros(self.size + 1, dtype=np.int64)
        if not (ok and _saddle_pattern_kernels.saddle_rows(block_start, p.indptr, p.indices, self.kept_row, n,
                                                           saddle_indptr)):  # fmt: skip
            return False
        nnz = int(saddle_indptr[-1])
        index = _index_dtype(max(self.size, nnz))
        indices = np.empty(nnz, dtype=index)
        block_slots, transposed_slots = np.empty(block, dtype=slot_dtype), np.empty(p.nnz, dtype=slot_dtype)
        _saddle_pattern_kernels.fill_saddle_pattern((self._rows, self._cols), block_start, block_columns,
                                                    (p.indptr, p.indices, self.kept_row), n, saddle_indptr, indices,
                                                    block_slots, transposed_slots)  # fmt: skip
        del block_start, block_columns
        self.saddle = SaddlePattern(self.size, saddle_indptr.astype(index), indices, None)
        if block < self._rows.size:  # (the count is exact without spring or actuator entries: no copy then)
            self._rows, self._cols, self._vals = (array[:block].copy() for array in (self._rows, self._cols, self._vals))
        self._slots = (block_slots, transposed_slots, None)
        self._jacobian_rows = (p.indptr, p.indices, self.kept_row, n, self.saddle.indptr)
        return True

    def _pattern_from_triplets(self, block: int, count: int, index: type) -> None:
        """S's pattern from every triplet (`SaddlePattern.from_triplets`): `saddle` and
        `_slots`, Φq's and the diagonal's derived where the pattern's agree."""
        p, n, m = self.pattern, self.n, self.pattern.n_equations
        rows, cols, vals = np.zeros(count, dtype=index), np.zeros(count, dtype=index), np.zeros(count)
        self._rows, self._cols, self._vals = rows, cols, vals
        drawn = p.initial_coordinates
        self._fill_triplets(drawn, np.zeros(n), np.zeros(n), np.zeros(m), 1.0, 1.0, 1.0)
        self.saddle = SaddlePattern.from_triplets(rows, cols, n, self.size)
        # From now on only the coordinate block goes through triplets: Φq, Φqᵀ and the (2, 2)
        # diagonal are scattered from the Jacobian's values straight into their slots
        # (`kernels.scatter_saddle`), which saves 16 bytes for each of 2 nnz(Φq) + m triplets.
        self._rows, self._cols, self._vals = (array[:block].copy() for array in (rows, cols, vals))
        del rows, cols, vals
        slots = self.saddle.slots
        self._slots = (slots[:block], slots[block : block + 2 * p.nnz], slots[block + 2 * p.nnz :])
        # Φq's slots and the diagonal's follow from the row pointers when each kept equation's
        # row of S is its Jacobian row in order: then only the block's and Φqᵀ's are held
        # (10^6 bodies: 52 MB fewer), checked here against the pattern's
        self._jacobian_rows = (p.indptr, p.indices, self.kept_row, n, self.saddle.indptr)
        lower = np.empty(p.nnz, dtype=slots.dtype)
        diagonal = np.empty(self.kept_rows.size, dtype=slots.dtype)
        kernels.derived_multiplier_slots(self._jacobian_rows, self.saddle.nnz, lower, diagonal)
        if np.array_equal(lower, self._slots[1][0::2]) and np.array_equal(diagonal, self._slots[2]):
            self._slots = (self._slots[0].copy(), self._slots[1][1::2].copy(), None)
            self.saddle = replace(self.saddle, slots=None)

    # ------------------------------------------------------------------ time and constraints
    def set_time(self, t: float) -> None:
        """Driver targets and load laws at time `t` (s)."""
        self.assembler.set_time(t)
        self.loads.evaluate(t, self.law_values, self._law_rates, self._law_accelerations)

    def fill_constraints(self, coordinates: np.ndarray) -> float:
        """Phi and Phi_q at `coordinates` (`assembler.residual`, `assembler.values`); returns
        the weighted norm of Phi on the kept rows (the fill's own norm when all are kept)."""
        norm = self.assembler.fill_residual_jacobian(coordinates)
        if self.kept_rows.size == self.pattern.n_equations:
            return norm
        return kernels.weighted_norm(self.kept(self.assembler.residual), self.kept(self.assembler.weights))

    def kept(self, values: np.ndarray) -> np.ndarray:
        """`values` of every equation on the kept rows only: itself when all are kept (no copy)."""
        return values if self.kept_rows.size == self.pattern.n_equations else values[self.kept_rows]

    def velocity_drift(self, velocities: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Phi_q qd + Phi_t of every equation, at the last `fill_constraints` (into `out`,
        shape (n_equations,), if given)."""
        return self.jacobian_product(velocities, self.assembler.velocity_rhs, out)

    def jacobian_product(self, x: np.ndarray, minus: np.ndarray | None = None,
                         out: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
        """``Phi_q x − minus`` of every equation (Phi_q of the last `fill_constraints`), into
        `out` (shape (n_equations,)) if given: no temporaries on the large path."""
        out = np.empty(self.pattern.n_equations) if out is None else out
        p = self.pattern
        kernels.fill_row_products(p.indptr, p.indices, self.assembler.values, x, out)
        if minus is not None:
            np.subtract(out, minus, out=out)
        return out

    # ------------------------------------------------------------------ motion
    def _shared(self, coordinates, velocities, accelerations) -> tuple[np.ndarray, np.ndarray]:
        """The kernels' qd, qdd loaded, and their q and turns: the constraints' own arrays when
        their last refill was at these coordinates (no copy; `kernels.load_shared`), else ours,
        loaded (`kernels.load_motion`'s numbers either way; ours are then never written in a
        run whose every call is at the refilled coordinates: not resident)."""
        filled, _, turns = self.assembler.filled_motion()
        if kernels.load_shared(coordinates, velocities, accelerations, self._q, self._qd, self._qdd, filled, turns,
                               self._turns):  # fmt: skip
            return filled, turns
        return self._q, self._turns

    def applied_forces(self, coordinates, velocities, accelerations, out: np.ndarray) -> np.ndarray:
        """``out = Q − M qdd − h``: gravity, loads and actuators minus the inertial forces."""
        q, turns = self._shared(coordinates, velocities, accelerations)
        _motion_kernels.fill_motion_forces(self.loads.arrays, self._actuator_arrays, q, self._qd, self._qdd, turns,
                                           self.law_values, self._applied, out)  # fmt: skip
        return out

    def residual(self, coordinates, velocities, accelerations, multipliers, out: np.ndarray) -> np.ndarray:
        """``out = M qdd + h − Q + Phi_qᵀ lam`` (N, N·m), Phi_q from the last `fill_constraints`.

        `multipliers` has one entry per equation (0 on those left out)."""
        self.applied_forces(coordinates, velocities, accelerations, out)
        np.negative(out, out=out)
        p = self.pattern
        values = self.assembler.values
        kernels.add_transposed_product(p.indptr, p.indices, values, multipliers, out)
        return out

    def newton_rhs(self, coordinates, velocities, accelerations, multipliers, scale: float, rhs: np.ndarray) -> bool:
        """``rhs = [scale · residual; −Phi of the kept rows]`` (`residual`; Phi and Phi_q from
        the last `fill_constraints`) in one call (`_motion_kernels.newton_rhs_fused`: the
        same numbers, no force array between); whether its first n entries are finite."""
        filled, _, turns = self.assembler.filled_motion()
        motion = (coordinates, velocities, accelerations, self._q, self._qd, self._qdd, filled, turns, self._turns)
        p, kept = self.pattern, self.kept_rows
        return self._motion.newton_rhs_fused(self.loads.arrays, self._actuator_arrays, motion, self.law_values,
                                                (p.indptr, p.indices, self.assembler.values), multipliers, scale,
                                                self.assembler.residual, kept, kept.size == p.n_equations,
                                                self._applied, self._direct_motion, rhs)  # fmt: skip

    def fill_constraints_newton_rhs(self, coordinates, velocities, accelerations, multipliers, scale: float,
                                    rhs: np.ndarray) -> tuple[float, bool] | None:  # fmt: skip
        """`fill_constraints` and then `newton_rhs` at one state, in one pass over the
        constraints where every equation is a point coincidence's (a chain of joints:
        `_motion_kernels.fill_coincidences_newton_rhs`, the same numbers): ``(the weighted
        norm of Phi, whether rhs is finite)``; None (nothing done) for other models."""
        if not self._coincidence_rows:
            return None
        assembler = self.assembler
        q, turns, target, jacobian, _, _ = assembler.fill_arrays(coordinates)
        made = self._motion.fill_coincidences_newton_rhs(self.loads.arrays, self.pattern.primitives.coincidence,
                                                            q, turns, target, assembler.weights, assembler.residual,
                                                            jacobian, velocities, accelerations, self.law_values,
                                                            multipliers, scale, rhs, self._constants(jacobian))  # fmt: skip
        self._constants_in = jacobian
        return made

    def fill_constraints_drifts(self, coordinates, velocities, accelerations, velocity_drift: np.ndarray,
                                acceleration_product: np.ndarray, acceleration_drift: np.ndarray) -> float | None:  # fmt: skip
        """`fill_constraints`, and (every equation) ``velocity_drift = Phi_q qd + Phi_t``,
        ``acceleration_product = Phi_q qdd``, the assembler's acceleration right-hand side at
        (q, qd) (`Assembler.fill_acceleration_rhs`) and ``acceleration_drift = Phi_q qdd −
        it`` (the numbers of `velocity_drift`, `jacobian_product` and the subtraction) in the
        same pass, for the models of `fill_constraints_newton_rhs`: the weighted norm of Phi;
        None (nothing done) for other models."""
        if not self._coincidence_rows:
            return None
        assembler = self.assembler
        q, turns, target, jacobian, qd, target_acceleration = assembler.fill_arrays(coordinates)
        norm = self._motion.fill_coincidences_drifts(self.pattern.primitives.coincidence, q, qd, turns, target,
                                                        assembler.weights, assembler.residual, jacobian, velocities,
                                                        assembler.velocity_rhs, velocity_drift, accelerations,
                                                        acceleration_product, target_acceleration,
                                                        assembler.acceleration_rhs, acceleration_drift,
                                                        self._constants(jacobian))  # fmt: skip
        self._constants_in = jacobian
        return norm

    def _constants(self, jacobian: np.ndarray) -> bool:
        """Whether the fused refills must write Φq's constant entries (a joint's ±1) into
        `jacobian`, the assembler's buffer: unless one of them filled this buffer already, in
        CSR order (every fill writes the same constants there; the refill is bound by memory,
        and these are 4 of a joint's 8 entries and of the slots read)."""
        return self._constants_in is not jacobian or self.assembler.csr_positions is not None

    def _fill_block_triplets(self, coordinates, velocities, accelerations, multipliers, a, b, c) -> int:
        """The triplets of ``a M + b C_t + c K_t`` (from the first on); returns their count."""
        q, turns = self._shared(coordinates, velocities, accelerations)
        self._block_compact = False  # (`residuals` fills its own again)
        return self._motion.fill_block_triplets(self.loads.arrays, self.pattern.primitives, self._actuator_arrays,
                                                q, self._qd, self._qdd, turns, self.law_values, multipliers,
                                                self._actuator_weights, (a, b, c), self._scratch, self._rows,
                                                self._cols, self._vals)  # fmt: skip

    def _fill_triplets(self, coordinates, velocities, accelerations, multipliers, a, b, c) -> int:
        """Every triplet of S (the pattern's run): the block's, Φq's and Φqᵀ's, the (2, 2)
        diagonal's; returns the block's count."""
        rows, cols, vals, p = self._rows, self._cols, self._vals, self.pattern
        block = self._fill_block_triplets(coordinates, velocities, accelerations, multipliers, a, b, c)
        e = kernels.fill_multiplier_triplets(p.indptr, p.indices, self.assembler.values, self.kept_row, self.n + 3,
                                             rows, cols, vals, block)  # fmt: skip
        kernels.fill_diagonal_triplets(self.n + 3, self.kept_rows.size, 0.0, rows, cols, vals, e)
        return block

    def fill_matrix(self, coordinates, velocities, accelerations, multipliers, a: float, b: float, c: float,
                    regularization: float = 0.0):  # fmt: skip
        """S = [[a M + b C_t + c K_t, Phi_qᵀ], [Phi_q, −regularization · I]] at the state
        given, Phi_q from the last `fill_constraints` (at the same coordinates); returns
        `matrix`."""
        self._fill_block_triplets(coordinates, velocities, accelerations, multipliers, a, b, c)
        block_slots, jacobian_slots, diagonal_slots = self._slots
        if diagonal_slots is None:  # Φq's and the diagonal's derived
            kernels.scatter_saddle_derived(self._vals, self.assembler.values, -regularization, block_slots,
                                           jacobian_slots, self._jacobian_rows, self._data)  # fmt: skip
        else:
            kernels.scatter_saddle(self._vals, self.assembler.values, -regularization, block_slots, jacobian_slots,
                                   diagonal_slots, self._data)  # fmt: skip
        return self.matrix

    def triplet_slots(self) -> np.ndarray:
        """The position of each triplet of S in the CSR values (`SaddlePattern.slots`: the
        block's, then Φq's and Φqᵀ's of each Jacobian entry, then the diagonal's), derived
        again where the system does not hold them (a new array then)."""
        block_slots, jacobian_slots, diagonal_slots = self._slots
        if diagonal_slots is not None:
            return self.saddle.slots
        lower = np.empty_like(jacobian_slots)
        diagonal = np.empty(self.kept_rows.size, dtype=jacobian_slots.dtype)
        kernels.derived_multiplier_slots(self._jacobian_rows, self.saddle.nnz, lower, diagonal)
        pairs = np.empty(2 * lower.size, dtype=lower.dtype)
        pairs[0::2], pairs[1::2] = lower, jacobian_slots
        return np.concatenate([block_slots, pairs, diagonal])

    def product(self, coordinates, velocities, accelerations, multipliers, a: float, b: float, c: float,
                x: np.ndarray, out: np.ndarray, *, same_state: bool = False) -> np.ndarray:  # fmt: skip
        """``out = S x`` for S of `fill_matrix` (no regularization) at the state given, without
        assembling S: the triplets of ``a M + b C_t + c K_t`` times x's coordinates, and Φq of
        the last `fill_constraints`; returns `out` (shape (size,)).  (The velocity projection's
        residual: a third of the work of filling S and multiplying.)  `same_state`: the state
        and coefficients of the last call, and no fill since: its triplets are reused."""
        if not same_state or self._block_compact:
            self._block_count = self._fill_block_triplets(coordinates, velocities, accelerations, multipliers, a, b, c)
        count = self._block_count
        p = self.pattern
        kernels.saddle_product(self._rows, self._cols, self._vals, count, self.n, p.indptr, p.indices,
                               self.assembler.values, self.kept_row, x, out)  # fmt: skip
        return out

    def residuals(self, coordinates, velocities, accelerations, multipliers, a: float, b: float, c: float,
                  first: tuple, second: tuple | None = None, *, same_state: bool = False) -> None:  # fmt: skip
        """``out = [0; drift] − S x`` for ``first = (x, drift, out)`` and, if given, `second`
        (`drift` of the kept equations), S as in `product`, both in one pass over S: the
        residuals of iterative refinement for the projections.  (``-(0 − v) = v`` exactly:
        the same numbers as `product` followed by the two subtractions.)  The bodies' inertia
        blocks are held as six values each, not as triplets (`fill_block_compact`)."""
        if not same_state or not self._block_compact:
            q, turns = self._shared(coordinates, velocities, accelerations)
            self._block_count = self._motion.fill_block_compact(
                self.loads.arrays, self.pattern.primitives, self._actuator_arrays, q, self._qd, self._qdd,
                turns, self.law_values, multipliers, self._actuator_weights, (a, b, c), self._scratch,
                self._inertia, self._rows, self._cols, self._vals)  # fmt: skip
            self._block_compact = True
        p, start = self.pattern, 9 * self._inertia.shape[0]
        x1, drift1, out1 = first if second is None else second
        _projection_kernels.saddle_residuals(self._inertia, self._rows, self._cols, self._vals, start,
                                             self._block_count, self.n, p.indptr, p.indices, self.assembler.values,
                                             self.kept_row, *first, x1, drift1, out1, second is not None)  # fmt: skip

    # ------------------------------------------------------------------ energy
    def energies(self, coordinates, velocities) -> tuple[float, float, float]:
        """Kinetic, gravitational potential and elastic energy, J."""
        q, turns = self._shared(coordinates, velocities, self._qdd[:-3])
        arrays = self.loads.arrays
        return self._kernels.kinetic_potential_elastic(arrays.masses, arrays.gravity, arrays.spring, arrays.torsion, q,
                                                 self._qd, turns)  # fmt: skip

    def powers(self, coordinates, velocities, multipliers) -> tuple[float, float]:
        """Power put in by the loads, actuators and drivers, and power dissipated by the
        dampers, W; Phi_q and the drivers' rates from the last `fill_constraints` /
        `set_time`."""
        q, turns = self._shared(coordinates, velocities, self._qdd[:-3])
        power, dissipated = self._motion.motion_powers(
            self.loads.arrays, self._actuator_arrays, q, self._qd, turns, self.law_values, multipliers,
            self.pattern.driven_row, self.assembler.velocity_rhs,
        )  # fmt: skip
        return power, dissipated

    def powers_and_energies(self, coordinates, velocities, multipliers) -> tuple[tuple, tuple]:
        """`powers` and `energies` at one state, its motion loaded once: ``((power,
        dissipated), (kinetic, potential, elastic))``, each bit for bit its own call."""
        q, turns = self._shared(coordinates, velocities, self._qdd[:-3])
        arrays = self.loads.arrays
        powers = self._motion.motion_powers(arrays, self._actuator_arrays, q, self._qd, turns, self.law_values,
                                               multipliers, self.pattern.driven_row, self.assembler.velocity_rhs)  # fmt: skip
        return powers, self._kernels.kinetic_potential_elastic(arrays.masses, arrays.gravity, arrays.spring, arrays.torsion,
                                                         q, self._qd, turns)  # fmt: skip
