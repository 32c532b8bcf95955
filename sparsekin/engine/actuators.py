"""Actuators along joints: a force (or torque) F along a joint's own coordinate s(q).

The generalized force is ``F ∇s``; ∇s comes from the constraint kernels applied to the
coordinate's primitive (the joint kind's `outputs`), so an actuator needs no kernel of its
own.  `build_actuators` packs them once; `ActuatorForces` evaluates ∇s at a configuration
and adds ``F ∇s`` to a generalized-force vector (inverse dynamics in
`sparsekin.engine.forces`, forward dynamics in `sparsekin.engine.saddle`), and ``ds/dt``
for their power.
"""

from __future__ import annotations

import numpy as np

from ..model.loads import actuator_blocks
from ..model.primitives import pack
from . import _dynamics_kernels, _kernels

__all__ = ["ActuatorForces", "actuator_kernel_arrays", "build_actuators"]


def build_actuators(blocks, n_laws: int, frames: np.ndarray) -> ActuatorForces | None:
    """The joint actuators among a mechanism's load blocks (row r of their packed
    coordinates is load law r; rows of other laws are empty), or None without actuators.

    Parameters
    ----------
    blocks : list
        Every load block of the mechanism (`sparsekin.engine.forces.build_load_pattern`).
    n_laws : int
        The load laws.
    frames : ndarray, shape (n_bodies + 1, 3)
        Drawn frames, the ground last.
    """
    coordinates = actuator_blocks(blocks)
    return ActuatorForces(pack(coordinates, n_laws, frames)) if coordinates else None


def actuator_kernel_arrays(actuators: ActuatorForces | None, n_laws: int, n_bodies: int) -> tuple:
    """`ActuatorForces.kernel_arrays` of `actuators`, or of none (rows for the `n_laws` load
    laws, no entries) for a model without: one type for the numba cores either way."""
    if actuators is None:
        actuators = ActuatorForces(pack([], n_laws, np.zeros((n_bodies + 1, 3))))
    return actuators.kernel_arrays()


class ActuatorForces:
    """``F ∇s`` of every actuator, ∇s refilled at each configuration.

    Attributes
    ----------
    equations : PackedEquations
        The actuators' coordinates s, one row per load law.
    values : ndarray
        ∇s (the rows' Jacobian values, CSR) at the last `fill`, one discard slot past the end.
    """

    def __init__(self, equations) -> None:
        self.equations = equations
        n_rows = equations.indptr.size - 1
        self.values = np.zeros(int(equations.indptr[-1]) + 1)
        self._value, self._ones = np.zeros(n_rows), np.ones(n_rows)
        self.rates = np.zeros(n_rows)

    def kernel_arrays(self) -> tuple:
        """The actuators as the numba cores of `sparsekin.engine._motion_kernels` take them:
        ``(primitives, indptr, indices, values, value, zeros, ones, rates)`` (`values` and
        `rates` are this object's own, refilled there)."""
        e = self.equations
        return (e.primitives, e.indptr, e.indices, self.values, self._value, np.zeros(self._value.size), self._ones,
                self.rates)  # fmt: skip

    def fill(self, q: np.ndarray, turns: np.ndarray) -> None:
        """∇s at `q` (the ground appended; `turns` filled there)."""
        _kernels.fill_residual_jacobian(self.equations.primitives, q, turns, np.zeros(self._value.size), self._ones,
                                        self._value, self.values)  # fmt: skip

    def add_forces(self, law_values: np.ndarray, out: np.ndarray) -> None:
        """``out += Σ F ∇s`` (out over the coordinates, the ground's optional), after `fill`."""
        e = self.equations
        _dynamics_kernels.add_transposed_product(e.indptr, e.indices, self.values, law_values, out)

    def power(self, law_values: np.ndarray, velocities: np.ndarray) -> float:
        """``Σ F ds/dt``, W, after `fill`."""
        e = self.equations
        _dynamics_kernels.fill_row_products(e.indptr, e.indices, self.values, velocities, self.rates)
        return float(law_values @ self.rates)
