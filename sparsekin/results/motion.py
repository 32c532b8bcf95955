"""The motion a run recorded, and what is derived from it: `Motion`.

A motion holds the coordinates of every body at every sample and their first two time
derivatives.  From them it derives, on request:

* `Motion.point`: the position, velocity and acceleration of a named point
  (`sparsekin.model.geometry.carried_motion`);
* `Motion.joint` and `~Motion.driver`: an element's own coordinate (a
  revolute's relative angle, a cylinder's stroke, a pin's slide) and its two derivatives,
  evaluated with the kernels of the constraint equations on the elements' output
  equations (`sparsekin.engine.pattern.build_output_pattern`);
* `Motion.driver_force` and `~Motion.reaction`: the forces a run
  recorded (`sparsekin.engine.forces`).

Every analysis returns one (`sparsekin.results.kinematics.KinematicsResult` is a `Motion`
with the run's statistics, `sparsekin.results.stats.RunStats`); the plots and the files
read only this part.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np

from ..engine.outputs import element_index, own_coordinates
from ..engine.pattern import OutputPattern, PointMap, build_output_pattern
from ..model import _validate
from ..model.geometry import carried_motion
from ..model.mechanism import Mechanism

__all__ = ["Motion", "PointMotion", "CoordinateMotion", "DriverForce", "Reaction"]


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
class Motion:
    """What a run recorded: the motion of every body, or of chosen points and joints, and forces.

    Attributes
    ----------
    times : ndarray, shape (n_times,)
        Sample times, s.
    coordinates, velocities, accelerations : array, shape (n_times, 3 * n_bodies), or None
        ``(x, y, angle)`` of each body frame, body order as in the model (m, rad), and
        their first and second time derivatives; None when the run did not keep them
        (``coordinates=False``).  Zarr arrays, read when sliced, for a run streamed to a
        store.
    complete : bool
        False when the analysis stopped early: then only the samples solved are here.
    point_map : PointMap
        Where each named point rides.
    mechanism : Mechanism
        The mechanism analysed.
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
    complete: bool
    point_map: PointMap = field(repr=False)
    mechanism: Mechanism = field(repr=False)
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
            tracks = np.asarray(self.point_tracks[..., self.recorded_points.index(name), :])
            return PointMotion(tracks[..., 0:2], tracks[..., 2:4], tracks[..., 4:6])
        if self.coordinates is None:
            raise KeyError(f'point "{name}" was not recorded: the run kept '
                           f"{', '.join(self.recorded_points) or 'no point'} and not the coordinates")  # fmt: skip
        try:
            body, local = self.point_map.locate(name)
        except KeyError:
            known = _validate.known_list(list(itertools.islice(self.point_map.names, 40)), limit=8)
            raise KeyError(f'unknown point "{name}"; the model has {known}') from None
        if body < 0:
            position = np.broadcast_to(np.asarray(local, dtype=float), (*self.coordinates.shape[:-1], 2)).copy()
            return PointMotion(position, np.zeros_like(position), np.zeros_like(position))
        columns = slice(3 * body, 3 * body + 3)
        frames = (np.asarray(array[..., columns]) for array in (self.coordinates, self.velocities, self.accelerations))
        return PointMotion(*carried_motion(*frames, local))

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
            tracks = np.asarray(self.joint_tracks[..., self.recorded_joints.index(index), :])
            return CoordinateMotion(tracks[..., 0], tracks[..., 1], tracks[..., 2])
        if self.coordinates is None:
            raise KeyError(f"{kind}[{index}] was not recorded, and the run did not keep the coordinates")
        rows = self._outputs_pattern.row_of_joint if kind == "joints" else self._outputs_pattern.row_of_driver
        row = int(rows[index])
        if row < 0:
            element = getattr(self.mechanism, kind)[index]
            raise KeyError(f"{kind}[{index}] is {element.type_name}, which has no coordinate of its own")
        value, rate, acceleration = self._outputs
        return CoordinateMotion(value[..., row], rate[..., row], acceleration[..., row])

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
        force = columns[..., :-1] if columns.shape[-1] > 2 else columns[..., 0]
        return DriverForce(force, columns[..., -1])

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
        return Reaction(columns[..., :2], columns[..., 2] if columns.shape[-1] == 3 else None)

    def _force_columns(self, label: str, names: list[str], kind: str, index: int) -> np.ndarray:
        position = self._force_position.get(f"{label}.{names[0]}")
        if position is None:
            why = "no forces" if not self.force_labels else "the forces of other elements"
            raise KeyError(f"{kind}[{index}] ({label}): the run recorded {why} (solve_kinematics(..., forces=...))")
        return np.asarray(self.force_tracks[..., position : position + len(names)])

    @cached_property
    def _force_position(self) -> dict[str, int]:
        return {label: k for k, label in enumerate(self.force_labels)}

    @cached_property
    def _outputs_pattern(self) -> OutputPattern:
        return build_output_pattern(self.mechanism)

    @cached_property
    def _outputs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every element's own coordinate at every sample, shape (n_times, n_rows) each
        (after any leading dimension of the coordinates, a sweep's variants)."""
        states = [np.asarray(array) for array in (self.coordinates, self.velocities, self.accelerations)]
        leading = states[0].shape[:-1]
        rows = own_coordinates(self._outputs_pattern, *(state.reshape(-1, state.shape[-1]) for state in states))
        return tuple(row.reshape(*leading, row.shape[-1]) for row in rows)

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
                         self.force_labels, self.force_units, schema.ENERGY in arrays)  # fmt: skip
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
    records_energy: bool = False


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

