"""The assembler: owns the constraint arrays and refills them in place.

An `Assembler` is built once per mechanism from its `ConstraintPattern`.  It owns the
residual, the CSR Jacobian (a ``scipy.sparse.csr_array`` whose pattern never changes), the
acceleration right-hand side and the driver targets, and refills their values with the
wiring of `sparsekin.engine._kernels`, the same functions the compiled time loop inlines.
Nothing is allocated per call.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from . import _kernels, _projection_kernels
from .discretization import Discretization, DriverLaws
from .typed_calls import TypedCall

if TYPE_CHECKING:
    from scipy.sparse import csr_array

__all__ = ["Assembler", "DriverLaws"]


class Assembler:
    """Residual, Jacobian and acceleration right-hand side of a mechanism, refilled in place.

    Parameters
    ----------
    discretization : Discretization
        The mechanism's arrays (`sparsekin.engine.discretization.discretize`): its
        constraint pattern and driver laws.

    Attributes
    ----------
    residual : ndarray, shape (n_equations,)
        Phi(q, t) = g(q) - target(t), after `fill_residual_jacobian`.
    jacobian : scipy.sparse.csr_array, shape (n_equations, n_coordinates)
        Phi_q, after `fill_residual_jacobian`.  Its pattern is fixed; only ``data`` changes.
        After `fill_in_order`, a copy made on each access (for diagnostics).
    values : ndarray, shape (nnz,)
        The values of the Jacobian as the kernels write them: ``jacobian.data`` itself,
        or after `fill_in_order` the same values in the order given there.
    weights : ndarray, shape (n_equations,)
        Weight of each row in the residual norm (`ConstraintPattern.residual_weights`).
    velocity_rhs : ndarray, shape (n_equations,)
        -Phi_t: the first time derivative of the targets, after `set_time`.
    acceleration_rhs : ndarray, shape (n_equations,)
        gamma plus the targets' second derivative, after `fill_acceleration_rhs`.
    driver_values : ndarray, shape (n_driven,)
        The laws' values at the last `set_time`, m or rad (one per driven row).
    """

    def __init__(self, discretization: Discretization) -> None:
        self.pattern = pattern = discretization.constraints
        n_coordinates, n_equations = pattern.n_coordinates, pattern.n_equations
        # Coordinates and velocities with the ground appended as a body of zeros.
        self._q = np.zeros(n_coordinates + 3)
        self._qd = np.zeros(n_coordinates + 3)
        # cos and sin of each body's angle in self._q (all angles 0 until the first fill)
        self._turns = np.zeros((pattern.n_bodies + 1, 2))
        self._turns[:, 0] = 1.0
        # The CSR values, with one discard slot past the end for the ground's columns.
        self._jac_buffer = np.zeros(pattern.nnz + 1)
        self.values = self._jac_buffer[: pattern.nnz]
        self._csr = None  # the CSR array over `values`, made when first asked for (`jacobian`)
        self._primitives = pattern.primitives
        self._fill_gamma_kernel = TypedCall(_kernels.fill_gamma)  # (the primitives' typing held: `typed_calls`)
        self._csr_position = None  # where each CSR value is in `values`, after fill_in_order
        self.weights = pattern.residual_weights
        self.residual = np.zeros(n_equations)
        self.acceleration_rhs = np.zeros(n_equations)
        # the pattern's own targets when no driver changes them (10^6 bodies: 24 MB fewer)
        self._target = pattern.target.copy() if pattern.driven_row.size else pattern.target
        self.velocity_rhs = np.zeros(n_equations)
        self._target_acceleration = np.zeros(n_equations)
        self.laws: DriverLaws = discretization.driver_laws
        n_driven = pattern.driven_row.size
        self.driver_values = np.zeros(n_driven)
        self._driver_rates = np.zeros(n_driven)
        self._driver_accelerations = np.zeros(n_driven)

    @property
    def jacobian(self) -> csr_array:
        from scipy.sparse import csr_array  # here: the compiled loop of a small model never needs it

        p = self.pattern
        shape = (p.n_equations, p.n_coordinates)
        if self._csr_position is not None:
            return csr_array((self.values[self._csr_position], p.indices, p.indptr), shape=shape)
        if self._csr is None:
            self._csr = csr_array((self.values, p.indices, p.indptr), shape=shape)
            if p.nnz and not np.shares_memory(self._csr.data, self._jac_buffer):
                raise RuntimeError("scipy copied the Jacobian values; the in-place refill would be lost")
        return self._csr

    @property
    def csr_positions(self) -> np.ndarray | None:
        """Where the k-th CSR value of the Jacobian is in `values` (None: `values` is in CSR order)."""
        return self._csr_position

    def fill_in_order(self, positions: np.ndarray | None) -> None:
        """Write the k-th CSR value of the Jacobian to ``values[positions[k]]`` from now on.

        A linear solver that reads the values in its own order (`RefactorSolver`'s
        ``value_positions``) then takes `values` as they are, without a gather; `jacobian`
        becomes a copy in CSR order.  ``None`` returns to the CSR order.  The values
        already there are moved to the new order, so that `values`, `csr_positions` and
        `jacobian` always describe the last fill.
        """
        p = self.pattern
        in_csr_order = self.values.copy() if self._csr_position is None else self.values[self._csr_position]
        if positions is None:
            self._primitives = p.primitives
            self._csr_position = None
            self.values[:] = in_csr_order
            return
        positions = np.asarray(positions, dtype=np.int64)
        if positions.shape != (p.nnz,) or (
            p.nnz and (positions.min() < 0 or positions.max() >= p.nnz or np.bincount(positions).min() != 1)
        ):
            raise ValueError(f"`positions` must be a permutation of range({p.nnz}).")
        # the ground's discard slot stays where it is
        self._primitives = p.primitives.with_slots(np.append(positions, p.nnz))
        self._csr_position = positions
        self.values[positions] = in_csr_order

    def set_time(self, t: float) -> None:
        """Evaluate the driver laws at time `t` (s) and update the targets."""
        self.laws.evaluate(t, self.driver_values, self._driver_rates, self._driver_accelerations)
        rows = self.pattern.driven_row
        self._target[rows] = self.driver_values
        self.velocity_rhs[rows] = self._driver_rates
        self._target_acceleration[rows] = self._driver_accelerations

    def fill_residual_jacobian(self, coordinates: np.ndarray) -> float:
        """Refill `residual` and the values of `jacobian` at `coordinates`.

        Returns
        -------
        float
            The weighted residual norm max |residual| · weights (NaN if not finite).
        """
        q = self._q
        q[:-3] = coordinates
        return _kernels.fill_residual_jacobian(
            self._primitives, q, self._turns, self._target, self.weights, self.residual, self._jac_buffer
        )

    def fill_arrays(self, coordinates: np.ndarray) -> tuple:
        """For a refill elsewhere (`DynamicSystem.fill_constraints_newton_rhs`): the kernels' q
        with `coordinates` copied in, the turns, the targets and the Jacobian's buffer (its
        values and the discard slot), to be filled as `fill_residual_jacobian` does, and the
        velocities with the ground appended and the targets' second derivative (for a γ made
        there as `fill_acceleration_rhs` does)."""
        self._q[:-3] = coordinates
        return self._q, self._turns, self._target, self._jac_buffer, self._qd, self._target_acceleration

    def filled_motion(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The coordinates and velocities of the last `fill_acceleration_rhs`, with the
        ground appended as a body of zeros, and ``(cos, sin)`` of every body's angle there
        (the kernels' ``q``, ``qd`` and ``turns``).  The arrays themselves, not copies: the
        next refill changes them."""
        return self._q, self._qd, self._turns

    def fill_acceleration_rhs(self, coordinates: np.ndarray, velocities: np.ndarray) -> None:
        """Refill `acceleration_rhs` (gamma plus the targets' second derivative)."""
        self._fill_gamma(coordinates, velocities)
        self.acceleration_rhs += self._target_acceleration

    def fill_acceleration_drift(self, coordinates: np.ndarray, velocities: np.ndarray, product: np.ndarray,
                                out: np.ndarray, weights: np.ndarray | None = None) -> float:  # fmt: skip
        """`fill_acceleration_rhs`, and ``out = product − acceleration_rhs`` in the same pass
        (the acceleration drift of every equation from ``product = jacobian @ qdd``; the same
        numbers as the two steps).  With `weights`, returns the weighted norm of the move of
        `out` (max |new − old| · weights, NaN if not finite), else 0."""
        self._fill_gamma(coordinates, velocities)
        return _projection_kernels.move_acceleration_drift(product, self.acceleration_rhs, self._target_acceleration,
                                                           out, self.weights if weights is None else weights,
                                                           weights is not None)  # fmt: skip

    def _fill_gamma(self, coordinates: np.ndarray, velocities: np.ndarray) -> None:
        """gamma at (coordinates, velocities) into `acceleration_rhs` (the targets' part not added)."""
        q, qd, turns = self._q, self._qd, self._turns
        _kernels.load_coordinates(coordinates, q, turns)  # (at the last refill's q: its turns, as they are)
        qd[:-3] = velocities
        self._fill_gamma_kernel(self._primitives, q, qd, turns, self.acceleration_rhs)
