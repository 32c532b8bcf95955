"""The result of a forward-dynamics run: the kinematic result, plus energy and drift."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .kinematics import KinematicsResult

__all__ = ["Energy", "DynamicsResult", "ENERGY_COLUMNS"]

#: The columns of ``energy.csv`` after ``t``, in order, with their units.
ENERGY_COLUMNS = (("kinetic", "J"), ("potential", "J"), ("elastic", "J"), ("dissipated", "J"), ("work", "J"),
                  ("balance", "J"), ("drift_position", "1"), ("drift_velocity", "1/s"))  # fmt: skip


class Energy(NamedTuple):
    """Energy and constraint drift at every sample, arrays of shape (n_times,).

    Attributes
    ----------
    kinetic : ½ q̇ᵀ M q̇, J.
    potential : the gravitational potential −Σ m g · r_com, J.
    elastic : springs' ½ k (L − L0)² and rotational springs' ½ k (Δθ − θ0)², J.
    dissipated : energy taken by the dampers since the first sample, J.
    work : work done by the loads, actuators and drivers since the first sample, J.
    balance : kinetic + potential + elastic + dissipated − work, minus its first value:
        zero for the exact motion; the integrator's energy error, J.
    drift_position : ‖Φ‖, the largest constraint residual (lengths relative to the
        model size, angles in rad).
    drift_velocity : ‖Φq q̇ + Φt‖ weighted the same way, 1/s.
    """

    kinetic: np.ndarray
    potential: np.ndarray
    elastic: np.ndarray
    dissipated: np.ndarray
    work: np.ndarray
    balance: np.ndarray
    drift_position: np.ndarray
    drift_velocity: np.ndarray


@dataclass(frozen=True, eq=False)
class DynamicsResult(KinematicsResult):
    """`KinematicsResult`'s accessors on a motion integrated under forces, with `energy`.

    Attributes
    ----------
    energy : Energy
    n_steps : int
        Integration steps taken (accepted).
    rho_inf : float
        The generalized-α method's spectral radius at infinite frequency (1: no
        numerical damping).
    """

    energy: Energy | None = None
    n_steps: int = 0
    rho_inf: float = 1.0

    def __repr__(self) -> str:
        text = super().__repr__()
        if self.energy is not None and self.energy.balance.size:
            worst = float(np.max(np.abs(self.energy.balance)))
            text += f"\nintegrated in {self.n_steps} steps (rho_inf = {self.rho_inf:g}); largest energy error {worst:.3g} J"
        return text
