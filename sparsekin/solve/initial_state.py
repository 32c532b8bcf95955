"""How far a forward-dynamics run moves the initial state its model gives.

A run starts from the drawing assembled at the first time (moved onto Φ(q, t) = 0 by the
smallest weighted change) and from the bodies' ``velocity`` made consistent with the
constraints by the smallest mass-weighted change: q̇ minimises (q̇ − q̇₀)ᵀ M (q̇ − q̇₀)
subject to Φq q̇ = −Φt (`sparsekin.solve.dynamics.GeneralizedAlphaStepper.start`).
`initial_state_change` measures both changes on that very state; ``sparsekin check``
prints them (`initial_state_lines`), one line each.

The mass-weighted size of the velocity change is ‖Δq̇‖_M = √(Δq̇ᵀ M Δq̇), kg^½·m/s; half
its square is the kinetic energy of the change, J.  With a singular M (a point mass on a
massless link) a change of the coordinates' rates can cost no energy at all: the line
also names the largest change of one body's (vx, vy, ω).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..analysis.assemble import point_moves
from ..model.mechanism import Mechanism
from ._dynamics_start import initial_velocities
from .dynamics import GeneralizedAlphaStepper

__all__ = ["InitialStateChange", "initial_state_change", "initial_state_lines", "VELOCITY_NAMES"]

#: The components of a body's ``velocity`` in the model file, with their units.
VELOCITY_NAMES = (("vx", "m/s"), ("vy", "m/s"), ("omega", "rad/s"))
#: Largest change of a velocity component, relative to the largest given (at least 1), that
#: is rounding: the velocities are then consistent as given.
UNCHANGED = 1e-12


class InitialStateChange(NamedTuple):
    """The initial state of a forward-dynamics run against the one its model gives.

    Attributes
    ----------
    time : float
        The first time, s.
    drawn, coordinates : ndarray, shape (3 * n_bodies,)
        The drawing's coordinates and the assembled ones (m, rad).
    given, velocities : ndarray, shape (3 * n_bodies,)
        The bodies' ``velocity`` as given (zero where not) and the consistent ones.
    moves : list of (str, float) or None
        The named points the assembly moved, the largest first (`point_moves`), m; None
        for a model with too many points to locate.
    n_moved : int
        How many named points moved (-1 when not located).
    velocity_change : float
        ‖Δq̇‖_M = √(Δq̇ᵀ M Δq̇), kg^½·m/s.
    kinetic_given, kinetic : float
        The kinetic energy of the given and of the consistent velocities, J.
    """

    time: float
    drawn: np.ndarray
    coordinates: np.ndarray
    given: np.ndarray
    velocities: np.ndarray
    moves: list | None
    n_moved: int
    velocity_change: float
    kinetic_given: float
    kinetic: float

    @property
    def energy_of_change(self) -> float:
        """½ Δq̇ᵀ M Δq̇, J."""
        return 0.5 * self.velocity_change**2


def initial_state_change(mechanism: Mechanism, time: float = 0.0) -> InitialStateChange:
    """The initial state a forward-dynamics run of `mechanism` starts from at `time` (s),
    against the drawing and the given velocities.

    Raises
    ------
    ModelError
        As `sparsekin.solve_dynamics`: the drawing cannot be assembled, or the motion is
        not determined.

    Examples
    --------
    A 1 kg point mass on a massless 1 m link pinned at O, its link's frame given the
    velocity (0.6, 0.4) m/s at the pin: the pin holds, the mass keeps its vertical speed.

    >>> import sparsekin as sk
    >>> from sparsekin.solve.initial_state import initial_state_change
    >>> pendulum = sk.Mechanism(
    ...     points={"O": (0.0, 0.0), "P": (1.0, 0.0)},
    ...     bodies=[sk.Body("link", origin="O", points=("O", "P"), mass=1.0, com="P", velocity=(0.6, 0.4, 0.0))],
    ...     joints=[sk.Revolute(("link", "ground"), at="O")])
    >>> change = initial_state_change(pendulum)
    >>> change.velocities.round(12).tolist(), round(change.velocity_change, 12)
    ([0.0, 0.0, 0.4], 0.6)
    """
    stepper = GeneralizedAlphaStepper(mechanism, max_step=1.0)  # no step is taken
    stepper.start(float(time))
    state, system = stepper.state, stepper.system
    drawn = stepper.pattern.initial_coordinates
    given = initial_velocities(mechanism, drawn.size)
    kinetic_change = system.energies(state.coordinates, state.velocities - given)[0]
    located = point_moves(mechanism, drawn, state.coordinates)
    moves, n_moved = located if located is not None else (None, -1)
    return InitialStateChange(
        float(time), drawn.copy(), state.coordinates.copy(), given, state.velocities.copy(), moves, n_moved,
        float(np.sqrt(max(2.0 * kinetic_change, 0.0))), system.energies(state.coordinates, given)[0],
        system.energies(state.coordinates, state.velocities)[0],
    )  # fmt: skip


def initial_state_lines(change: InitialStateChange, mechanism: Mechanism) -> tuple[str, str]:
    """The two lines of ``sparsekin check`` on a forward-dynamics model: the drawing's
    change, then the velocities'."""
    at = f"t = {change.time:g} s"
    if change.moves is None:
        moved = "too many points to list"
    elif not change.moves:
        moved = "no point moved"
    else:
        shown = ", ".join(f"{name} {distance:.3g} m" for name, distance in change.moves[:3])
        more = f" … ({change.n_moved - 3} more)" if change.n_moved > 3 else ""
        moved = f"{change.n_moved} point{'s' * (change.n_moved != 1)} moved, the largest first: {shown}{more}"
    positions = f"initial positions (dynamics): the drawing assembled at {at} by the smallest change: {moved}"
    delta = change.velocities - change.given
    if np.max(np.abs(delta), initial=0.0) <= UNCHANGED * max(1.0, float(np.max(np.abs(change.given), initial=0.0))):
        return positions, f"initial velocities (dynamics): consistent at {at} as given (kinetic energy {change.kinetic:.6g} J)"
    column = int(np.argmax(np.abs(delta)))
    name, unit = VELOCITY_NAMES[column % 3]
    velocities = (
        f"initial velocities (dynamics): made consistent at {at} by the smallest mass-weighted change, "
        f"√(Δq̇ᵀMΔq̇) = {change.velocity_change:.6g} kg^½·m/s (kinetic energy {change.kinetic_given:.6g} J given, "
        f"{change.kinetic:.6g} J consistent, {change.energy_of_change:.6g} J in the change); largest change: "
        f"{mechanism.bodies[column // 3].name}.{name} by {delta[column]:+.6g} {unit}"
    )
    return positions, velocities
