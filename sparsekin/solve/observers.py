"""What a run makes of each solved sample besides the motion: the recorded variables and the limits.

The steppers hand over states (time, coordinates, velocities, accelerations, and the force
columns when a run computes them) and publish a `Linearization` after each sample;
`InverseDynamics` makes the force columns from it; `RecordedVariables` turns a block of
states into the variables of `sparsekin.results.schema` the selection records (the motion of points
carried by bodies, the own coordinates of joints), which a `Recorder` stores;
`LimitWatch` notes the first sample at which an element with ``limits`` leaves them.
"""

from __future__ import annotations

import numpy as np

from ..engine._force_kernels import fill_applied_forces
from ..engine.force_columns import ForceOutputs
from ..engine.linearization import Linearization
from ..engine.multipliers import MIN_NORM_ITERATIONS, Multipliers
from ..engine.outputs import LimitState, own_coordinates
from ..engine.pattern import limited_elements
from ..model.geometry import carried_motion
from ..results import schema
from ..results.recording import Selection
from ._compiled import CompiledForces

__all__ = ["InverseDynamics", "RecordedVariables", "LimitWatch"]


class InverseDynamics:
    """The force columns of a sample from its `Linearization`: Q − M q̈ − h (the loads),
    the multipliers by a transposed solve (`sparsekin.engine.multipliers`), then the
    columns (`sparsekin.engine.force_columns`).

    Parameters
    ----------
    discretization : Discretization
    outputs : ForceOutputs
        The columns to make.
    quasi_static : bool
        Leave out the inertial forces.
    min_norm_iterations : int
        See `sparsekin.engine.multipliers.Multipliers`.
    """

    def __init__(self, discretization, outputs: ForceOutputs, quasi_static: bool = False,
                 min_norm_iterations: int = MIN_NORM_ITERATIONS) -> None:  # fmt: skip
        self.loads, self.outputs, self.inertial = discretization.loads, outputs, not quasi_static
        pattern = discretization.constraints
        self._qdd, self._b = np.zeros(pattern.n_coordinates + 3), np.zeros(pattern.n_coordinates + 3)
        self._laws = [np.zeros(self.loads.n_laws) for _ in range(3)]
        self.multipliers = Multipliers(pattern.n_equations, min_norm_iterations)
        self._work = np.zeros((len(outputs.joint_indices), 3))
        self.row = np.zeros(outputs.n_columns)

    def __call__(self, lin: Linearization) -> np.ndarray:
        """The force columns at the sample of `lin` (`row`, reused)."""
        q, qd, turns = lin.motion
        qdd = self._qdd
        qdd[:-3] = lin.accelerations
        self.loads.evaluate(lin.time, *self._laws)
        fill_applied_forces(self.loads.arrays, q, qd, qdd, turns, self._laws[0], self.inertial, self._b)
        if self.loads.actuators is not None:  # actuators along joints (forward-dynamics loads)
            self.loads.actuators.fill(q, turns)
            self.loads.actuators.add_forces(self._laws[0], self._b)
        multipliers = self.multipliers.solve(lin, self._b[:-3])
        return self.outputs.fill(lin, multipliers, self._work, self.row)

    def compiled(self) -> CompiledForces:
        """What the compiled loop takes to make the same columns inline (`CompiledForces`;
        its rows, none here, are allocated by the loop)."""
        loads = self.loads
        return CompiledForces(loads.arrays, loads.laws, loads.n_laws, self.outputs.arrays(), self.inertial,
                              np.zeros((0, self.outputs.n_columns)))  # fmt: skip


class RecordedVariables:
    """The recorded variables of blocks of solved samples.

    Parameters
    ----------
    selection : Selection
    """

    def __init__(self, selection: Selection) -> None:
        self.selection = selection
        discretization = selection.discretization
        self._points = [discretization.points.locate(name) for name in selection.point_names]
        self._joints = discretization.output_rows(joints=selection.joint_indices) if selection.joint_indices else None

    def block(self, coordinates, velocities, accelerations, forces=None) -> dict:
        """The variables of the samples whose states are the rows of the arrays (forces:
        their force columns, when the selection records some)."""
        selection, states = self.selection, (coordinates, velocities, accelerations)
        arrays = {}
        if selection.coordinates:
            arrays |= {v.name: state for v, state in zip(schema.COORDINATE_VARIABLES, states)}
        if self._points:
            arrays[schema.POINTS] = self._point_tracks(*states)
        if self._joints is not None:
            arrays[schema.JOINTS] = np.stack(own_coordinates(self._joints, *states), axis=2)
        if selection.forces is not None:
            arrays[schema.FORCES] = forces
        return arrays

    def _point_tracks(self, coordinates, velocities, accelerations) -> np.ndarray:
        m = coordinates.shape[0]
        out = np.empty((m, len(self._points), len(schema.POINT_COMPONENTS)))
        for p, (body, local) in enumerate(self._points):
            if body < 0:  # a ground point
                out[:, p, :2] = local
                out[:, p, 2:] = 0.0
                continue
            columns = slice(3 * body, 3 * body + 3)
            frames = (coordinates[:, columns], velocities[:, columns], accelerations[:, columns])
            out[:, p, 0:2], out[:, p, 2:4], out[:, p, 4:6] = carried_motion(*frames, local)
        return out


class LimitWatch:
    """The elements with ``limits``: their own coordinates checked at every sample recorded.

    Parameters
    ----------
    discretization : Discretization
    """

    def __init__(self, discretization) -> None:
        self.crossings: list[LimitState] = []
        mechanism = discretization.mechanism
        self.active = any(getattr(e, "limits", None) is not None
                          for kind in ("joints", "drivers") for e in mechanism.declared(kind))  # fmt: skip
        if not self.active:
            return
        self._mechanism = mechanism
        limited = limited_elements(mechanism)
        self._outputs = discretization.output_rows(joints=limited["joints"], drivers=limited["drivers"])
        self._elements = [(kind, k) for kind in ("joints", "drivers") for k in limited[kind]]
        limits = np.array([getattr(mechanism, kind)[k].limits for kind, k in self._elements], dtype=float)
        self._low, self._high = limits[:, 0], limits[:, 1]
        self._open = np.ones(len(self._elements), dtype=bool)  # not yet outside

    def watch(self, times, coordinates) -> None:
        """Samples at `times` (s) with `coordinates` (one row each): each element still
        within its limits that leaves them is recorded at its first sample outside."""
        if not self.active or not self._open.any():
            return
        rest = np.zeros_like(coordinates)
        values = own_coordinates(self._outputs, coordinates, rest, rest)[0]
        outside = self._open & ((values < self._low) | (values > self._high))
        crossed = np.flatnonzero(outside.any(axis=0))
        first = outside[:, crossed].argmax(axis=0)
        for e, k in sorted(zip(crossed.tolist(), first.tolist()), key=lambda pair: pair[1]):  # in time order
            kind, index = self._elements[e]
            element = getattr(self._mechanism, kind)[index]
            quantity = type(element).output_names[0] if kind == "joints" else element.type_name
            unit = "rad" if self._outputs.row_is_angle[e] else "m"
            self.crossings.append(LimitState(self._mechanism.element_label(kind, index), quantity, unit,
                                             float(values[k, e]), element.limits, float(times[k]), False))  # fmt: skip
        self._open[crossed] = False
