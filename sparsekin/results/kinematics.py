"""What a kinematic analysis returns: `KinematicsResult`, and the motions derived from it.

The result holds the coordinates of every body at every sample and their first two time
derivatives.  From them it derives, on request:

* `KinematicsResult.point`: the position, velocity and acceleration of a named point
  (`sparsekin.model.geometry.carried_motion`);
* `KinematicsResult.joint` and `~KinematicsResult.driver`: an element's own coordinate (a
  revolute's relative angle, a cylinder's stroke, a pin's slide) and its two derivatives,
  evaluated with the kernels of the constraint equations on the elements' output
  equations (`sparsekin.engine.pattern.build_output_pattern`);
* `KinematicsResult.driver_force` and `~KinematicsResult.reaction`: the forces a run
  recorded (`sparsekin.engine.forces`).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np

from ..engine.outputs import LimitState, element_index, limit_states, own_coordinates  # noqa: F401 (re-exported)
from ..engine.pattern import OutputPattern, PointMap, build_output_pattern
from ..model import _validate
from ..model.geometry import carried_motion
from ..model.mechanism import Mechanism

__all__ = ["KinematicsResult", "PointMotion", "CoordinateMotion", "DriverForce", "Reaction", "LimitState",
           "element_index", "own_coordinates", "limit_states"]


class PointMotion(NamedTuple):
    """Motion of a named point: each array has shape (n_times, 2), global x and y."""

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


class CoordinateMotion(NamedTuple):
    """An element's own coordinate (m or rad) and its time derivatives, each (n_times,)."""

    value: np.ndarray
    rate: np.ndarray
    acceleration: np.ndarray


class DriverForce(NamedTuple):
    """What a driver applies to hold the motion.

    Attributes
    ----------
    force : ndarray, shape (n_times,), or (n_times, 2) for a path driver
        N for a stroke, a distance or an x / y coordinate (positive when it pushes the two
        points apart, or along +x / +y); N·m for an angle (the torque on the driven body,
        counter-clockwise positive); a path driver's force on its body at the point, global
        (fx, fy).
    power : ndarray, shape (n_times,)
        Force times the rate of the driven quantity, W.
    """

    force: np.ndarray
    power: np.ndarray


class Reaction(NamedTuple):
    """The force of a joint on its ``bodies[0]`` from its ``bodies[1]``.

    Attributes
    ----------
    force : ndarray, shape (n_times, 2)
        Global x and y, N.
    torque : ndarray, shape (n_times,), or None
        About the joint's point, N·m, counter-clockwise positive; None for the kinds whose
        reaction has no torque (revolute, pin in slot).
    """

    force: np.ndarray
    torque: np.ndarray | None


@dataclass(frozen=True, eq=False)
class KinematicsResult:
    """Positions, velocities and accelerations of every body at every time.

    Attributes
    ----------
    times : ndarray, shape (n_times,)
        Sample times, s.
    coordinates, velocities, accelerations : array, shape (n_times, 3 * n_bodies), or None
        ``(x, y, angle)`` of each body frame, body order as in the model (m, rad), and
        their first and second time derivatives; None when the run did not keep them
        (``coordinates=False``).  Zarr arrays, read when sliced, for a run streamed to a
        store.
    newton_iterations : ndarray of int, shape (n_times,)
        Newton corrections at each time (over all its sub-steps when the step to it was
        subdivided).
    n_factorizations, n_solves : int
        Factorizations of the Jacobian and linear solves in the whole run.
    complete : bool
        False when the analysis stopped early: then only the samples solved are here.
    mechanism : Mechanism
        The mechanism analysed.
    n_subdivisions : int
        How many times a step was halved (a Newton failure, or a suspected jump to
        another assembly branch); 0 on a well-sampled run.
    redundant_equations : tuple of str
        The equations left out as redundant (empty for most models).
    n_refactorizations : int
        Numeric refactorizations on a fixed pattern (``linear_solver="refactor"``).
    linear_solver : str
        The path that solved the run: ``"compiled"`` (the compiled dense loop all the
        way), ``"compiled+dense"`` (the Python loop took over from it), ``"dense"``,
        ``"refactor"``, ``"reuse"`` (``"auto"`` found the refactorization's fill-in
        heavy at the first sample and reused its factorization across samples),
        ``"superlu"``, or ``"none"`` for a model with nothing to solve (no body, no equation).
    recorded_points : tuple of str
        Points whose motion the run recorded (`point_tracks`).
    point_tracks : array, shape (n_times, n_recorded_points, 6), or None
        x, y, vx, vy, ax, ay of each recorded point.
    recorded_joints : tuple of int
        Indices of the joints whose own coordinate the run recorded (`joint_tracks`).
    joint_tracks : array, shape (n_times, n_recorded_joints, 3), or None
        Value, rate and acceleration of each recorded joint's own coordinate.
    force_labels, force_units : tuple of str
        The force columns the run recorded (``forces.csv``'s names: ``D.force``,
        ``D.power``, ``J.fx``, …) and their units.
    force_tracks : array, shape (n_times, n_force_columns), or None
        Their values.
    quasi_static : bool
        Whether the forces leave out the inertial forces.
    store : str or None
        The Zarr store the run was streamed to.
    """

    times: np.ndarray
    coordinates: np.ndarray | None
    velocities: np.ndarray | None
    accelerations: np.ndarray | None
    newton_iterations: np.ndarray
    n_factorizations: int
    n_solves: int
    complete: bool
    point_map: PointMap = field(repr=False)
    mechanism: Mechanism = field(repr=False)
    n_subdivisions: int = 0
    redundant_equations: tuple[str, ...] = ()
    n_refactorizations: int = 0
    linear_solver: str = "superlu"
    recorded_points: tuple[str, ...] = ()
    point_tracks: np.ndarray | None = None
    recorded_joints: tuple[int, ...] = ()
    joint_tracks: np.ndarray | None = None
    force_labels: tuple[str, ...] = ()
    force_units: tuple[str, ...] = ()
    force_tracks: np.ndarray | None = None
    quasi_static: bool = False
    store: str | None = None

    @property
    def n_times(self) -> int:
        return len(self.times)

    def __repr__(self) -> str:
        """A summary, like xarray's: the model, the samples, the path and what was
        recorded with its shape (not the arrays themselves)."""
        times = np.asarray(self.times[:1]), np.asarray(self.times[-1:])
        span = f"t = {times[0][0]:g} … {times[1][0]:g} s" if self.n_times else "no sample"
        state = "complete" if self.complete else "stopped early"
        lines = [
            f"<KinematicsResult {self.mechanism.name!r}: {self.n_times} samples, {span}, {state}>",
            (f"  model:        {_count(self.mechanism.n_bodies, 'body', 'bodies')}, "
             f"{_count(len(self.mechanism.joints), 'joint')}, {_count(len(self.mechanism.drivers), 'driver')}"),
            (f"  path:         {self.linear_solver}: {self.n_factorizations} factorizations, {self.n_solves} solves, "
             f"{int(np.sum(self.newton_iterations))} Newton corrections, {self.n_subdivisions} halved steps"),
            "  recorded:",
        ]
        if self.coordinates is not None:
            shape = tuple(self.coordinates.shape)
            lines.append(f"    coordinates  {shape}  coordinates, velocities, accelerations (x, y, angle per body)")
        if self.recorded_points:
            lines.append(f"    points       {tuple(self.point_tracks.shape)}  {_listed(self.recorded_points)} "
                         f"× (x, y, vx, vy, ax, ay)")  # fmt: skip
        if self.recorded_joints:
            shown = [self.mechanism.joints[k].name or f"joints[{k}]" for k in self.recorded_joints[:LISTED_NAMES]]
            joints = _listed(shown, total=len(self.recorded_joints))  # a copy's joint is built on demand
            lines.append(f"    joints       {tuple(self.joint_tracks.shape)}  {joints} × (value, rate, accel)")
        if self.force_labels:
            forces = "quasi-static " * self.quasi_static
            lines.append(f"    forces       {tuple(self.force_tracks.shape)}  {forces}{_listed(self.force_labels)}")
        if lines[-1] == "  recorded:":
            lines[-1] += " nothing but the times"
        if self.redundant_equations:
            lines.append(f"  left out:     {_listed(self.redundant_equations)} (redundant)")
        if self.store is not None:
            lines.append(f"  store:        {self.store}")
        return "\n".join(lines)

    @property
    def body_names(self):
        """The name of every body, in coordinate order."""
        return self.mechanism.body_names

    @property
    def point_names(self) -> Sequence[str]:
        """Every named point of the model, in its order: a tuple, or for a model with
        repeated units a sequence that names its copies' points on demand."""
        names = self.point_map.names
        return names if self.mechanism.copies else tuple(names)

    def point(self, name: str) -> PointMotion:
        """Global position (m), velocity (m/s) and acceleration (m/s²) of point `name`.

        A recorded point, or any point when the coordinates were kept.
        """
        if name in self.recorded_points:
            tracks = np.asarray(self.point_tracks[:, self.recorded_points.index(name), :])
            return PointMotion(tracks[:, 0:2], tracks[:, 2:4], tracks[:, 4:6])
        if self.coordinates is None:
            raise KeyError(f'point "{name}" was not recorded: the run kept '
                           f"{', '.join(self.recorded_points) or 'no point'} and not the coordinates")  # fmt: skip
        try:
            body, local = self.point_map.locate(name)
        except KeyError:
            known = _validate.known_list(list(itertools.islice(self.point_map.names, 40)), limit=8)
            raise KeyError(f'unknown point "{name}"; the model has {known}') from None
        if body < 0:
            position = np.tile(local, (self.n_times, 1))
            return PointMotion(position, np.zeros_like(position), np.zeros_like(position))
        columns = slice(3 * body, 3 * body + 3)
        return PointMotion(
            *carried_motion(self.coordinates[:, columns], self.velocities[:, columns], self.accelerations[:, columns], local)
        )

    def joint(self, name: str | int) -> CoordinateMotion:
        """The own coordinate of joint `name` (its name, ``"joints[i]"`` or the index i) and
        its time derivatives.

        A revolute's relative angle ``angle(bodies[0]) - angle(bodies[1])`` (rad, not
        wrapped), a translational joint's stroke (m), a pin-in-slot's slide (m).

        Raises
        ------
        KeyError
            No such joint, or its kind has no own coordinate (a rigid joint, a gear).
        """
        return self._own_coordinate("joints", name)

    def driver(self, name: str | int) -> CoordinateMotion:
        """The quantity driver `name` (its name, ``"drivers[i]"`` or the index i) drives, as solved.

        A stroke or a distance (m), an angle (rad), a coordinate; it follows the driver's
        law to the solver's tolerance.
        """
        return self._own_coordinate("drivers", name)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Labels of the joints that have an own coordinate: the name, else ``joints[i]``."""
        outputs = self._outputs_pattern
        return tuple(
            joint.name or f"joints[{index}]"
            for index, joint in enumerate(self.mechanism.joints)
            if outputs.row_of_joint[index] >= 0
        )

    def _own_coordinate(self, kind: str, name: str) -> CoordinateMotion:
        index = element_index(self.mechanism, kind, name)
        if kind == "joints" and index in self.recorded_joints:
            tracks = np.asarray(self.joint_tracks[:, self.recorded_joints.index(index), :])
            return CoordinateMotion(tracks[:, 0], tracks[:, 1], tracks[:, 2])
        if self.coordinates is None:
            raise KeyError(f"{kind}[{index}] was not recorded, and the run did not keep the coordinates")
        rows = self._outputs_pattern.row_of_joint if kind == "joints" else self._outputs_pattern.row_of_driver
        row = int(rows[index])
        if row < 0:
            element = getattr(self.mechanism, kind)[index]
            raise KeyError(f"{kind}[{index}] is {element.type_name}, which has no coordinate of its own")
        value, rate, acceleration = self._outputs
        return CoordinateMotion(value[:, row], rate[:, row], acceleration[:, row])

    def driver_force(self, name: str | int) -> DriverForce:
        """The force (or torque) driver `name` applies to hold the motion, and its power.

        Raises
        ------
        KeyError
            No such driver, or the run did not record its force (``forces=``).
        """
        index = element_index(self.mechanism, "drivers", name)
        driver = self.mechanism.drivers[index]
        label = driver.name or f"drivers[{index}]"
        columns = self._force_columns(label, [*type(driver).force_names, "power"], "drivers", index)
        force = columns[:, :-1] if columns.shape[1] > 2 else columns[:, 0]
        return DriverForce(force, columns[:, -1])

    def reaction(self, name: str | int) -> Reaction:
        """The force of joint `name` on its ``bodies[0]`` from its ``bodies[1]`` (`Reaction`).

        Raises
        ------
        KeyError
            No such joint, or the run did not record its forces (``forces=``).
        """
        index = element_index(self.mechanism, "joints", name)
        joint = self.mechanism.joints[index]
        label = joint.name or f"joints[{index}]"
        names = ["fx", "fy", "torque"] if type(joint).reaction_torque else ["fx", "fy"]
        columns = self._force_columns(label, names, "joints", index)
        return Reaction(columns[:, :2], columns[:, 2] if columns.shape[1] == 3 else None)

    def _force_columns(self, label: str, names: list[str], kind: str, index: int) -> np.ndarray:
        position = self._force_position.get(f"{label}.{names[0]}")
        if position is None:
            why = "no forces" if not self.force_labels else "the forces of other elements"
            raise KeyError(f"{kind}[{index}] ({label}): the run recorded {why} (solve_kinematics(..., forces=...))")
        return np.asarray(self.force_tracks[:, position : position + len(names)])

    @cached_property
    def _force_position(self) -> dict[str, int]:
        return {label: k for k, label in enumerate(self.force_labels)}

    @cached_property
    def _outputs_pattern(self) -> OutputPattern:
        return build_output_pattern(self.mechanism)

    @cached_property
    def _outputs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every element's own coordinate at every sample, shape (n_times, n_rows) each."""
        return own_coordinates(self._outputs_pattern, self.coordinates, self.velocities, self.accelerations)

    def to_dataframe(self, points=None, joints=None):
        """The motion as a pandas DataFrame: one row per sample, one column per quantity.

        A wide table, as ``points.csv`` and ``joints.csv`` side by side: the index is the
        time ``t`` (s); the columns have three levels, ``kind`` (``"point"`` or
        ``"joint"``), ``name`` and ``quantity``: ``x, y, vx, vy, ax, ay`` for a point (m,
        m/s, m/s²), the joint's own coordinate and its two derivatives for a joint
        (``angle, rate, accel`` in rad for a revolute, ``stroke, speed, accel`` in m for a
        translational joint, ...).  ``df["point", "K"]`` is the table of point K,
        ``df["joint", "actuator1", "stroke"]`` one column, and
        ``df["point"].stack("name", future_stack=True)`` the tidy table of the points
        (one row per time and point).  pandas is an optional dependency:
        ``pip install "sparsekin[pandas]"``.

        Parameters
        ----------
        points : sequence of str, optional
            The points (default: every named point; the recorded points of a run that did
            not keep the coordinates).
        joints : sequence of str or int, optional
            The joints, by name, ``"joints[i]"`` or index (default: every joint that has an
            own coordinate; the recorded joints of a run that did not keep the coordinates).

        Returns
        -------
        pandas.DataFrame
            Shape (n_times, 6 · n_points + 3 · n_joints).

        Examples
        --------
        >>> import numpy as np
        >>> from sparsekin import solve_kinematics
        >>> from sparsekin.testset import task5
        >>> result = solve_kinematics(task5(), np.linspace(0.0, 1.0, 11))
        >>> table = result.to_dataframe(points=["K"], joints=["actuator1"])
        >>> table.columns.tolist()[:2], table.shape
        ([('point', 'K', 'x'), ('point', 'K', 'y')], (11, 9))
        >>> float(table["point", "K", "x"].iloc[0])  # K as drawn
        -1.2
        """
        try:
            import pandas as pd
        except ImportError:
            raise ImportError('to_dataframe needs pandas: pip install "sparsekin[pandas]"') from None
        kept = self.coordinates is not None
        if points is None:
            point_names = tuple(self.point_names) if kept else self.recorded_points
        else:
            point_names = tuple(points)
        if joints is None and not kept:
            joint_indices = list(self.recorded_joints)
        elif joints is None:
            joint_indices = [index for index in range(len(self.mechanism.joints))
                             if self._outputs_pattern.row_of_joint[index] >= 0]  # fmt: skip
        else:
            joint_indices = [element_index(self.mechanism, "joints", name) for name in joints]
        columns, labels = [], []
        for name in point_names:
            columns.extend(array.T for array in self.point(name))  # (2, n_times) each: x, y
            labels.extend(("point", name, quantity) for quantity in ("x", "y", "vx", "vy", "ax", "ay"))
        for index in joint_indices:
            joint = self.mechanism.joints[index]
            columns.append(np.stack(self.joint(index)))
            labels.extend(("joint", joint.name or f"joints[{index}]", suffix) for suffix in type(joint).output_names)
        values = np.vstack(columns).T if columns else np.empty((self.n_times, 0))
        return pd.DataFrame(values, index=pd.Index(self.times, name="t"), columns=_sorted_columns(pd, labels))

    def to_xarray(self):
        """The results as an `xarray.Dataset` (the layout of `sparsekin.results.recording`).

        A run streamed to a store opens it lazily; an in-memory run is copied.
        """
        try:
            import xarray as xr
        except ImportError:
            raise ImportError('to_xarray needs xarray: pip install "sparsekin[zarr]"') from None
        if self.store is not None:
            return xr.open_zarr(self.store)
        from . import schema

        arrays = {name: np.asarray(array) for name, array in schema.result_arrays(self).items()}
        layout = _Layout(self.mechanism, self.coordinates is not None, self.recorded_points, self.recorded_joints,
                         self.force_labels, self.force_units)  # fmt: skip
        coords = {schema.TIME: ("time", np.asarray(self.times))} | schema.dataset_labels(layout)
        return xr.Dataset(schema.dataset_variables(arrays), coords=coords)


class _Layout(NamedTuple):
    """What a result recorded, as `sparsekin.results.schema` reads it."""

    mechanism: Mechanism
    coordinates: bool
    point_names: tuple
    joint_indices: tuple
    force_labels: tuple
    force_units: tuple


#: Most names listed in `KinematicsResult`'s summary per kind of record: a line each, whatever the model's size.
LISTED_NAMES = 4


def _count(number: int, word: str, plural: str | None = None) -> str:
    return f"{number} {word if number == 1 else plural or word + 's'}"


def _listed(names, total: int | None = None) -> str:
    """``A, B, C, D … (12)``: the first `LISTED_NAMES` names, and how many there are
    (`total`, when `names` holds the first ones only)."""
    names = list(names)
    total = len(names) if total is None else total
    shown = ", ".join(names[:LISTED_NAMES])
    return shown if total <= LISTED_NAMES else f"{shown} … ({total})"


def _sorted_columns(pd, labels):
    """A MultiIndex of `labels` whose level values are ordered so that its codes follow the
    columns' order: pandas then knows it is sorted (lexsorted), and selecting by all three
    levels neither copies nor warns, while every column keeps its place."""
    from graphlib import CycleError, TopologicalSorter
    from itertools import pairwise

    levels = []
    for depth in range(3):
        if depth < 2:
            levels.append(list(dict.fromkeys(label[depth] for label in labels)))
            continue
        before: dict[str, set[str]] = {label[2]: set() for label in labels}  # quantity -> those before it
        for previous, label in pairwise(labels):
            if previous[:2] == label[:2]:
                before[label[2]].add(previous[2])
        try:
            levels.append(list(TopologicalSorter(before).static_order()))
        except CycleError:  # no order fits every element: pandas will say it is not sorted
            levels.append(list(dict.fromkeys(label[2] for label in labels)))
    codes = [[level.index(label[depth]) for label in labels] for depth, level in enumerate(levels)]
    return pd.MultiIndex(levels=levels, codes=codes, names=["kind", "name", "quantity"])
