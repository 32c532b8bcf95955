"""Forces on a known motion, the loads' side: masses, gravity and loads packed for the kernels.

For a kinematically driven mechanism the motion comes first; the forces follow from it at
almost no cost.  At each solved sample the Lagrange multipliers λ of the constraints solve

    Φqᵀ λ = Q − M q̈ − h

(gravity and loads, minus the inertial forces; `sparsekin.engine._force_kernels`) with the
transpose of the factorization already made at the converged position: one more
triangular solve, no factorization.  Three modules share the work, so that forward
dynamics, whose multipliers come from its own iteration, reuses the last two:

* here, `build_load_pattern` packs the masses and loads once (the right-hand side);
* `sparsekin.engine.multipliers` solves for λ at a sample (inverse dynamics only), the
  minimum-norm λ of a model with redundant equations included;
* `sparsekin.engine.force_columns` turns λ into the columns a run records: drivers'
  forces and powers, joints' reactions (`ForceOutputs`).

The drivers' powers and the loads' power then add up to the rate of change of kinetic
plus potential energy (tests/test_forces.py checks it).  With ``quasi_static`` the
inertial forces are left out: the forces that hold the mechanism still in each
configuration (a slow hydraulic machine).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.laws import LawTable, fill_laws
from ..model.loads import LoadArrays, MassArrays, pack_loads
from ..model.mechanism import Mechanism
from .actuators import ActuatorForces, build_actuators
from .columns import Resolver
from .force_columns import ForceOutputArrays  # noqa: F401 (compiled kernels cached before the split name it here)
from .pattern import element_columns, pack_element_laws, per_element

__all__ = ["LoadPattern", "build_load_pattern"]


@dataclass(frozen=True, eq=False)
class LoadPattern:
    """The masses of the bodies and the loads of a mechanism, packed for the kernels.

    Attributes
    ----------
    arrays : LoadArrays
    laws : LawTable
        The loads' built-in laws; their values fill an array of `n_laws` entries.
    other_laws : list of (int, Law)
        Laws that are not built in, evaluated in Python (the compiled loop refuses them).
    n_laws : int
    actuators : ActuatorForces or None
        The actuators along joints (`sparsekin.engine.actuators`), if any.
    """

    arrays: LoadArrays
    laws: LawTable
    other_laws: list
    n_laws: int
    actuators: ActuatorForces | None = None

    def evaluate(self, t: float, values: np.ndarray, rates: np.ndarray, accelerations: np.ndarray) -> None:
        """The value of every load law at time `t` (s) into `values` (N or N·m)."""
        fill_laws(self.laws, float(t), values, rates, accelerations)
        for k, law in self.other_laws:
            values[k], rates[k], accelerations[k] = law.evaluate(t, 0.0)


def build_load_pattern(mechanism: Mechanism, resolver: Resolver | None = None) -> LoadPattern:
    """Pack the bodies' masses, gravity and the loads of `mechanism` (linear in its size)."""
    resolver = Resolver(mechanism) if resolver is None else resolver
    counts = per_element(mechanism, "loads", lambda load: load.n_laws)
    first_law = np.zeros(counts.size + 1, dtype=np.int64)
    np.cumsum(counts, out=first_law[1:])
    blocks = []
    for kind, indices, columns in element_columns(mechanism, "loads", first_law[:-1], resolver):
        blocks += kind.loads(columns)
    table, others, n_laws = pack_element_laws(mechanism, "loads")
    arrays = pack_loads(blocks, _masses(mechanism, resolver), mechanism.gravity, resolver.frames, mechanism.shapes)
    return LoadPattern(arrays, table, others, n_laws, build_actuators(blocks, n_laws, resolver.frames))


def _masses(mechanism: Mechanism, resolver: Resolver) -> MassArrays:
    """Mass, inertia and centre of mass (in the body frame) of every body, copies tiled."""
    n = mechanism.n_bodies
    mass, inertia, com = np.zeros(n), np.zeros(n), resolver.frames[:n, :2].copy()
    own = mechanism.own("bodies")
    for b, body in enumerate(own):
        mass[b], inertia[b] = body.mass or 0.0, body.inertia or 0.0
        if body.com is not None:
            com[b] = mechanism.position(body.com)
    for copies in mechanism.copies:
        for body, (ks, starts) in zip(copies.unit.bodies, copies.placed("bodies")):
            bodies = copies.first_body + starts
            mass[bodies], inertia[bodies] = body.mass or 0.0, body.inertia or 0.0
            if body.com is not None:
                com[bodies] = copies.reference_positions([body.com], ks)[:, 0]
    return MassArrays(mass, inertia, np.ascontiguousarray(mechanism.local_points(np.arange(n), com, resolver.frames)))


