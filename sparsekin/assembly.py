"""The assembler: owns the constraint arrays and refills them in place.

An `Assembler` is built once per mechanism from its `ConstraintPattern`.  It owns the
residual, the CSR Jacobian (a ``scipy.sparse.csr_array`` whose pattern never changes), the
acceleration right-hand side and the driver targets, and refills their values with the
kernels of `sparsekin._kernels`.  Nothing is allocated per call but the small arrays of
the driver laws.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_array

from . import _kernels
from .laws import Harmonic, Linear
from .model import Mechanism
from .pattern import ConstraintPattern

__all__ = ["Assembler", "DriverLaws"]


class DriverLaws:
    """The laws of all drivers, evaluated together at one time.

    Harmonic and linear laws are evaluated as arrays, so that a model with 10^5 drivers
    costs a few numpy calls per time; other laws are called one by one.
    """

    def __init__(self, mechanism: Mechanism, initial: np.ndarray) -> None:
        laws = [driver.law for driver in mechanism.drivers]
        self.n_drivers = len(laws)
        self._initial = initial
        harmonic = [k for k, law in enumerate(laws) if type(law) is Harmonic]
        linear = [k for k, law in enumerate(laws) if type(law) is Linear]
        self._harmonic = np.array(harmonic, dtype=np.int64)
        self._harmonic_parameters = np.array(
            [
                [
                    initial[k] if laws[k].offset is None else laws[k].offset,
                    laws[k].amplitude,
                    laws[k].omega,
                    laws[k].phase,
                ]
                for k in harmonic
            ],
            dtype=float,
        ).reshape(-1, 4).T.copy()
        self._linear = np.array(linear, dtype=np.int64)
        self._linear_parameters = np.array(
            [[initial[k] if laws[k].start is None else laws[k].start, laws[k].rate] for k in linear],
            dtype=float,
        ).reshape(-1, 2).T.copy()
        grouped = set(harmonic) | set(linear)
        self._others = [(k, laws[k]) for k in range(len(laws)) if k not in grouped]

    def evaluate(self, t: float, value: np.ndarray, first: np.ndarray, second: np.ndarray) -> None:
        """Fill the value and time derivatives of every driver's law at time `t`."""
        offset, amplitude, omega, phase = self._harmonic_parameters
        angle = omega * t + phase
        sine = np.sin(angle)
        value[self._harmonic] = offset + amplitude * sine
        first[self._harmonic] = amplitude * omega * np.cos(angle)
        second[self._harmonic] = -amplitude * omega**2 * sine
        start, rate = self._linear_parameters
        value[self._linear] = start + rate * t
        first[self._linear] = rate
        second[self._linear] = 0.0
        for k, law in self._others:
            value[k], first[k], second[k] = law.evaluate(t, float(self._initial[k]))


class Assembler:
    """Residual, Jacobian and acceleration right-hand side of a mechanism, refilled in place.

    Parameters
    ----------
    mechanism : Mechanism
    pattern : ConstraintPattern
        From `sparsekin.pattern.build_pattern`.

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
    velocity_rhs : ndarray, shape (n_equations,)
        -Phi_t: the first time derivative of the targets, after `set_time`.
    acceleration_rhs : ndarray, shape (n_equations,)
        gamma, after `fill_acceleration_rhs`.
    driver_values : ndarray, shape (n_drivers,)
        The laws' values at the last `set_time`, m or rad.
    """

    def __init__(self, mechanism: Mechanism, pattern: ConstraintPattern) -> None:
        self.pattern = pattern
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
        self._csr = csr_array((self.values, pattern.indices, pattern.indptr), shape=(n_equations, n_coordinates))
        if pattern.nnz and not np.shares_memory(self._csr.data, self._jac_buffer):
            raise RuntimeError("scipy copied the Jacobian values; the in-place refill would be lost")
        self._slots = (pattern.coincidence_slots, pattern.projection_slots, pattern.difference_slots)
        self._csr_position = None  # where each CSR value is in `values`, after fill_in_order
        self.residual = np.zeros(n_equations)
        self.acceleration_rhs = np.zeros(n_equations)
        self._gamma = np.zeros(n_equations)
        self._target = pattern.target.copy()
        self.velocity_rhs = np.zeros(n_equations)
        self._target_acceleration = np.zeros(n_equations)
        self.laws = DriverLaws(mechanism, pattern.driver_initial)
        n_drivers = self.laws.n_drivers
        self.driver_values = np.zeros(n_drivers)
        self._driver_rates = np.zeros(n_drivers)
        self._driver_accelerations = np.zeros(n_drivers)

    @property
    def jacobian(self) -> csr_array:
        if self._csr_position is None:
            return self._csr
        return csr_array((self.values[self._csr_position], self.pattern.indices, self.pattern.indptr),
                         shape=self._csr.shape)  # fmt: skip

    def fill_in_order(self, positions: np.ndarray | None) -> None:
        """Write the k-th CSR value of the Jacobian to ``values[positions[k]]`` from now on.

        A linear solver that reads the values in its own order (`RefactorSolver`'s
        ``value_positions``) then takes `values` as they are, without a gather; `jacobian`
        becomes a copy in CSR order.  ``None`` returns to the CSR order.
        """
        p = self.pattern
        if positions is None:
            self._slots = (p.coincidence_slots, p.projection_slots, p.difference_slots)
            self._csr_position = None
            return
        positions = np.asarray(positions, dtype=np.int64)
        if positions.shape != (p.nnz,) or (
            p.nnz and (positions.min() < 0 or positions.max() >= p.nnz or np.bincount(positions).min() != 1)
        ):
            raise ValueError(f"`positions` must be a permutation of range({p.nnz}).")
        composed = np.append(positions, p.nnz)  # the ground's discard slot stays where it is
        self._slots = tuple(composed[slots] for slots in (p.coincidence_slots, p.projection_slots, p.difference_slots))
        self._csr_position = positions

    def set_time(self, t: float) -> None:
        """Evaluate the driver laws at time `t` (s) and update the targets."""
        self.laws.evaluate(t, self.driver_values, self._driver_rates, self._driver_accelerations)
        rows = self.pattern.driver_row
        self._target[rows] = self.driver_values
        self.velocity_rhs[rows] = self._driver_rates
        self._target_acceleration[rows] = self._driver_accelerations

    def fill_residual_jacobian(self, coordinates: np.ndarray) -> None:
        """Refill `residual` and the values of `jacobian` at `coordinates`."""
        p, q, turns = self.pattern, self._q, self._turns
        q[:-3] = coordinates
        _kernels.fill_body_turns(q, turns)
        _kernels.fill_point_coincidence(
            q, turns, p.coincidence_body_i, p.coincidence_body_j, p.coincidence_local_i, p.coincidence_local_j,
            p.coincidence_row, self._slots[0], self.residual, self._jac_buffer,
        )  # fmt: skip
        _kernels.fill_projected_distance(
            q, turns, p.projection_body_i, p.projection_body_j, p.projection_local_i, p.projection_local_j,
            p.projection_direction, p.projection_row, self._slots[1], self.residual, self._jac_buffer,
        )  # fmt: skip
        _kernels.fill_coordinate_difference(
            q, p.difference_plus, p.difference_minus, p.difference_row, self._slots[2],
            self.residual, self._jac_buffer,
        )  # fmt: skip
        self.residual -= self._target

    def fill_acceleration_rhs(self, coordinates: np.ndarray, velocities: np.ndarray) -> None:
        """Refill `acceleration_rhs` (gamma plus the targets' second derivative)."""
        p, q, qd, turns = self.pattern, self._q, self._qd, self._turns
        if not np.array_equal(q[:-3], coordinates):  # else `turns` is that of the last refill
            q[:-3] = coordinates
            _kernels.fill_body_turns(q, turns)
        qd[:-3] = velocities
        _kernels.fill_point_coincidence_gamma(
            q, qd, turns, p.coincidence_body_i, p.coincidence_body_j, p.coincidence_local_i, p.coincidence_local_j,
            p.coincidence_row, self._gamma,
        )  # fmt: skip
        _kernels.fill_projected_distance_gamma(
            q, qd, turns, p.projection_body_i, p.projection_body_j, p.projection_local_i, p.projection_local_j,
            p.projection_direction, p.projection_row, self._gamma,
        )  # fmt: skip
        # Coordinate differences have no gamma: their rows of self._gamma stay zero.
        np.add(self._gamma, self._target_acceleration, out=self.acceleration_rhs)
