"""The recorded variables, in one table: what a run can keep, its dimensions, unit and labels.

Every consumer of recorded arrays derives from `VARIABLES`: the shapes a `Selection` asks
the sinks for, the Zarr store's layout and its labels, ``to_xarray`` of a result and of a
sweep, the sweep's arrays, the fields of `~sparsekin.results.kinematics.KinematicsResult`
and of `~sparsekin.studies.stores.SweepResult` that hold them, and ``coordinates.npz``.
A new recorded quantity (a dynamics run's multipliers, its energy) is one more row here,
plus the code that fills it.

The functions take a *layout*: any object with the attributes ``mechanism``,
``coordinates`` (bool), ``point_names``, ``joint_indices``, ``force_labels`` and
``force_units`` (a `~sparsekin.results.recording.Selection` before a run, a result after).

=============  ==============================  ===========================================
variable       dimensions                      content
=============  ==============================  ===========================================
``t``          (time)                          sample times, s (a coordinate)
``q``,         (time, coordinate)              x, y, angle of every body (m, rad) and their
``qd``, ``qdd``                                derivatives; labels ``c1.x``, ``c1.angle``
``points``     (time, point, component)        x, y, vx, vy, ax, ay of each recorded point
``joints``     (time, joint, derivative)       value, rate, accel of each recorded joint's
                                               own coordinate; ``joint_quantity`` (angle,
                                               stroke, slide) and ``joint_unit`` per joint
``forces``     (time, force)                   the columns of ``forces.csv`` (drivers'
                                               forces and powers, joints' reactions),
                                               labelled like them; ``force_unit`` per
                                               column (N, N·m, W)
``energy``     (time, energy_term)             forward dynamics: kinetic, potential,
                                               elastic, dissipated, work and balance, J
``drift``      (time, drift_term)              forward dynamics: ‖Φ‖ (position, 1) and
                                               ‖Φq q̇ + Φt‖ (velocity, 1/s); ``drift_unit``
=============  ==============================  ===========================================

The layout's ``records_energy`` (False when it has none) says whether the last two are
recorded; they are fields of a dynamics result only (`Variable.analyses`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from ..model.elements import COORDINATE_NAMES

__all__ = ["Variable", "VARIABLES", "TIME", "Q", "QD", "QDD", "POINTS", "JOINTS", "FORCES", "ENERGY", "DRIFT",
           "ENERGY_TERMS", "DRIFT_TERMS", "DRIFT_UNITS", "POINT_COMPONENTS", "JOINT_DERIVATIVES", "COORDINATE_VARIABLES",
           "variable", "sample_shapes", "dataset_labels", "dataset_variables", "result_arrays", "result_fields"]

#: The time: the first dimension of every variable, and its coordinate.
TIME = "t"
#: The components of a recorded point, in the order they are stored.
POINT_COMPONENTS = ("x", "y", "vx", "vy", "ax", "ay")
#: The derivatives of a recorded joint coordinate.
JOINT_DERIVATIVES = ("value", "rate", "accel")
#: The terms of a dynamics run's energy balance, J (`sparsekin.results.dynamics.Energy`).
ENERGY_TERMS = ("kinetic", "potential", "elastic", "dissipated", "work", "balance")
#: Its constraint drift: position (relative lengths, rad) and velocity, with their units.
DRIFT_TERMS = ("position", "velocity")
DRIFT_UNITS = ("1", "1/s")


@dataclass(frozen=True)
class Variable:
    """One recorded variable.

    Attributes
    ----------
    name : str
        Its name in a store, a Dataset and the arrays a run hands over.
    attribute : str
        The field of a result (`KinematicsResult`, `SweepResult`) that holds it.
    dims : tuple of str
        Its dimensions after ``time`` (and a sweep's ``variant`` before it).
    unit : str
        Its unit, or where the units are labelled.
    shape : callable
        ``shape(layout)``: the shape of one sample, or None when the layout does not record it.
    labels : callable
        ``labels(layout)``: the Dataset coordinates of its dimensions.
    analyses : tuple of str
        The analyses whose results have a field for it (`result_fields`).
    """

    name: str
    attribute: str
    dims: tuple[str, ...]
    unit: str
    shape: Callable
    labels: Callable
    analyses: tuple[str, ...] = ("kinematics", "dynamics")


def _coordinate_shape(layout):
    return (layout.mechanism.n_coordinates,) if layout.coordinates else None


def _coordinate_labels(layout) -> dict:
    return {"coordinate": [f"{name}.{c}" for name in layout.mechanism.body_names for c in COORDINATE_NAMES]}


def _point_shape(layout):
    return (len(layout.point_names), len(POINT_COMPONENTS)) if layout.point_names else None


def _point_labels(layout) -> dict:
    return {"point": list(layout.point_names), "component": list(POINT_COMPONENTS)}


def _joint_shape(layout):
    return (len(layout.joint_indices), len(JOINT_DERIVATIVES)) if layout.joint_indices else None


def _joint_labels(layout) -> dict:
    from ..engine.pattern import build_output_pattern

    mechanism, indices = layout.mechanism, layout.joint_indices
    kinds = [type(mechanism.joints[k]) for k in indices]
    outputs = build_output_pattern(mechanism, joints=indices)
    return {
        "joint": [mechanism.joints[k].name or f"joints[{k}]" for k in indices],
        "derivative": list(JOINT_DERIVATIVES),
        "joint_quantity": ("joint", [kind.output_names[0] for kind in kinds]),
        "joint_unit": ("joint", ["rad" if angle else "m" for angle in outputs.row_is_angle]),
    }


def _force_shape(layout):
    return (len(layout.force_labels),) if layout.force_labels else None


def _force_labels(layout) -> dict:
    return {"force": list(layout.force_labels), "force_unit": ("force", list(layout.force_units))}


def _energy_shape(layout):
    return (len(ENERGY_TERMS),) if getattr(layout, "records_energy", False) else None


def _energy_labels(layout) -> dict:
    return {"energy_term": list(ENERGY_TERMS)}


def _drift_shape(layout):
    return (len(DRIFT_TERMS),) if getattr(layout, "records_energy", False) else None


def _drift_labels(layout) -> dict:
    return {"drift_term": list(DRIFT_TERMS), "drift_unit": ("drift_term", list(DRIFT_UNITS))}


#: Every variable a run can record, in the order it is stored.
VARIABLES = (
    Variable("q", "coordinates", ("coordinate",), "m, rad", _coordinate_shape, _coordinate_labels),
    Variable("qd", "velocities", ("coordinate",), "m/s, rad/s", _coordinate_shape, _coordinate_labels),
    Variable("qdd", "accelerations", ("coordinate",), "m/s², rad/s²", _coordinate_shape, _coordinate_labels),
    Variable("points", "point_tracks", ("point", "component"), "m, m/s, m/s²", _point_shape, _point_labels),
    Variable("joints", "joint_tracks", ("joint", "derivative"), "joint_unit", _joint_shape, _joint_labels),
    Variable("forces", "force_tracks", ("force",), "force_unit", _force_shape, _force_labels),
    Variable("energy", "energy_tracks", ("energy_term",), "J", _energy_shape, _energy_labels, ("dynamics",)),
    Variable("drift", "drift_tracks", ("drift_term",), "drift_unit", _drift_shape, _drift_labels, ("dynamics",)),
)
#: The body coordinates and their two time derivatives (the state of a kinematic sample).
COORDINATE_VARIABLES = VARIABLES[:3]
#: The names, for the code that fills them.
Q, QD, QDD, POINTS, JOINTS, FORCES, ENERGY, DRIFT = (v.name for v in VARIABLES)
_BY_NAME = {v.name: v for v in VARIABLES}


def variable(name: str) -> Variable:
    """The variable called `name`."""
    return _BY_NAME[name]


def sample_shapes(layout) -> dict[str, tuple[int, ...]]:
    """The shape of one sample of each variable `layout` records (the time aside)."""
    shapes = {v.name: v.shape(layout) for v in VARIABLES}
    return {name: shape for name, shape in shapes.items() if shape is not None}


def dataset_labels(layout) -> dict:
    """The Dataset coordinates (labels) of the variables `layout` records: the same for a
    Zarr store, a result's ``to_xarray`` and a sweep's."""
    labels = {}
    for v in VARIABLES:
        if v.shape(layout) is not None:
            labels |= v.labels(layout)
    return labels


def dataset_variables(arrays: dict, leading: tuple[str, ...] = ("time",)) -> dict:
    """``{name: (dims, array)}`` for an `xarray.Dataset` of the recorded `arrays` (by name;
    the time and anything not in the table are left out)."""
    return {name: ((*leading, *_BY_NAME[name].dims), array) for name, array in arrays.items() if name in _BY_NAME}


def result_arrays(result) -> dict:
    """The recorded arrays of a result (any object with the variables' attributes), by name."""
    arrays = {v.name: getattr(result, v.attribute, None) for v in VARIABLES}
    return {name: array for name, array in arrays.items() if array is not None}


def result_fields(arrays: dict, analysis: str = "kinematics") -> dict:
    """The keyword arguments of the fields of an `analysis`'s result for the recorded
    `arrays` (by name): None for a variable not recorded."""
    return {v.attribute: arrays.get(v.name) for v in VARIABLES if analysis in v.analyses}
