"""The result of a forward-dynamics run: a `Motion` with its run's statistics, energy and drift."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .kinematics import run_summary
from .motion import Motion
from .schema import DRIFT_TERMS, DRIFT_UNITS, ENERGY_TERMS
from .stats import RunStatsFields

__all__ = ["Energy", "DynamicsResult", "ENERGY_COLUMNS"]

#: The columns of ``energy.csv`` after ``t``, in order, with their units: the recorded
#: variables ``energy`` and ``drift`` of `sparsekin.results.schema`.
ENERGY_COLUMNS = (*((term, "J") for term in ENERGY_TERMS),
                  *((f"drift_{term}", unit) for term, unit in zip(DRIFT_TERMS, DRIFT_UNITS)))  # fmt: skip


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
class DynamicsResult(Motion, RunStatsFields):
    """A motion integrated under forces: `Motion`'s accessors, the run's statistics
    (`RunStatsFields`, as `KinematicsResult`), and `energy`.

    Attributes
    ----------
    energy_tracks : ndarray, shape (n_times, 6), or None
        The recorded variable ``energy`` (`sparsekin.results.schema.ENERGY_TERMS`, J).
    drift_tracks : ndarray, shape (n_times, 2), or None
        The recorded variable ``drift`` (position, velocity).
    n_steps : int
        Integration steps taken (accepted).
    rho_inf : float
        The generalized-α method's spectral radius at infinite frequency (1: no
        numerical damping).
    """

    energy_tracks: np.ndarray | None = field(default=None, kw_only=True)
    drift_tracks: np.ndarray | None = field(default=None, kw_only=True)
    n_steps: int = field(default=0, kw_only=True)
    rho_inf: float = field(default=1.0, kw_only=True)

    @property
    def energy(self) -> Energy | None:
        """The energy balance and drift, one array per term (`Energy`); None if not recorded."""
        if self.energy_tracks is None or self.drift_tracks is None:
            return None
        energy, drift = np.asarray(self.energy_tracks), np.asarray(self.drift_tracks)
        return Energy(*(np.ascontiguousarray(energy[:, c]) for c in range(len(ENERGY_TERMS))),
                      *(np.ascontiguousarray(drift[:, c]) for c in range(len(DRIFT_TERMS))))  # fmt: skip

    def __repr__(self) -> str:
        text = run_summary(self)
        energy = self.energy
        if energy is not None and energy.balance.size:
            worst = float(np.max(np.abs(energy.balance)))
            text += (f"\nintegrated in {self.n_steps} steps (rho_inf = {self.rho_inf:g}); "
                     f"largest energy error {worst:.3g} J")
        return text
