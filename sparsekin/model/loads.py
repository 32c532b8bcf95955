"""The three primitive loads that every load kind is made of, and the masses of the bodies.

A load kind (`sparsekin.model.elements.LOAD_KINDS`) says which primitives it is made of by
returning *blocks*, as the joints and drivers do with the constraint primitives of
`sparsekin.model.primitives`: arrays of parameters, one entry per load, in the global
coordinates of the drawn configuration.  `pack_loads` turns the blocks of a mechanism
and its bodies' masses into the body-local arrays the kernels of
`sparsekin.engine._force_kernels` read.

=================  ==========================================================
primitive          generalized force on the bodies
=================  ==========================================================
`PointForce`       a force (global components, two laws) at a point of a body
`BodyTorque`       a torque (one law) on a body, counter-clockwise positive
`SpringDamper`     tension k (L - L0) + c L' along the line from a point of
                   body i to a point of body j, pulling the two together
`TorsionSpring`    torque k (θi - θj - θ0) + c (θi' - θj') resisting the relative
                   turn of body i against body j (a rotational spring-damper)
`JointActuator`    a force (one law) along a joint's own coordinate s(q): the
                   generalized force F ∇s (a stroke pushed apart, a relative
                   angle turned counter-clockwise)
=================  ==========================================================

The laws of the loads are numbered by the loads, in model order (a force's x and y laws,
a torque's law); the law values at a time fill one array that the kernels index.  As for
the constraints, the ground is body ``n_bodies``: loads on it are computed and discarded.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .lengths import NO_SHAPES

__all__ = [
    "PointForce",
    "BodyTorque",
    "SpringDamper",
    "TorsionSpring",
    "JointActuator",
    "MassArrays",
    "PointForceArrays",
    "TorqueArrays",
    "SpringArrays",
    "TorsionArrays",
    "LoadArrays",
    "pack_loads",
]


# ---------------------------------------------------------------------- blocks (what kinds emit)
class PointForce(NamedTuple):
    """A force at the point of `body` that starts at `point` (k, 2); its global x and y
    components are the laws ``law`` and ``law + 1`` (N)."""

    law: np.ndarray
    body: np.ndarray
    point: np.ndarray


class BodyTorque(NamedTuple):
    """A torque on `body`, the law ``law`` (N·m, counter-clockwise positive)."""

    law: np.ndarray
    body: np.ndarray


class SpringDamper(NamedTuple):
    """A spring-damper from the point of `body_i` that starts at `point_i` to the point of
    `body_j` that starts at `point_j`: tension ``stiffness · (L - free_length) + damping ·
    L'`` (N), with L the distance between the points (m).  A NaN `free_length` is the drawn
    distance."""

    body_i: np.ndarray
    body_j: np.ndarray
    point_i: np.ndarray
    point_j: np.ndarray
    stiffness: np.ndarray
    free_length: np.ndarray
    damping: np.ndarray


class TorsionSpring(NamedTuple):
    """A rotational spring-damper between `body_i` and `body_j`: the torque ``stiffness ·
    (angle_i - angle_j - free_angle) + damping · (angle_i' - angle_j')`` (N·m) acts
    clockwise on body i and counter-clockwise on body j.  A NaN `free_angle` is the drawn
    relative angle."""

    body_i: np.ndarray
    body_j: np.ndarray
    stiffness: np.ndarray
    free_angle: np.ndarray
    damping: np.ndarray


class JointActuator(NamedTuple):
    """A force (N) or torque (N·m), the law ``law``, along the own coordinate s(q) of a
    joint: `coordinate` is the constraint-primitive block that measures s, one entry per
    actuator, whose ``row`` is the actuator's law.  The generalized force is ``F ∇s``."""

    law: np.ndarray
    coordinate: tuple


# ---------------------------------------------------------------------- packed (what kernels read)
class MassArrays(NamedTuple):
    mass: np.ndarray  # float64 (n_bodies,), kg
    inertia: np.ndarray  # float64 (n_bodies,), kg·m² about the centre of mass
    com: np.ndarray  # float64 (n_bodies, 2): the centre of mass in the body frame, m


class PointForceArrays(NamedTuple):
    body: np.ndarray  # int64 (k,)
    local: np.ndarray  # float64 (k, 2): the point in the body frame
    law: np.ndarray  # int64 (k,): the x component's law; y is law + 1


class TorqueArrays(NamedTuple):
    body: np.ndarray
    law: np.ndarray


class SpringArrays(NamedTuple):
    body_i: np.ndarray
    body_j: np.ndarray
    local_i: np.ndarray
    local_j: np.ndarray
    stiffness: np.ndarray  # N/m
    free_length: np.ndarray  # m
    damping: np.ndarray  # N·s/m


class TorsionArrays(NamedTuple):
    body_i: np.ndarray
    body_j: np.ndarray
    stiffness: np.ndarray  # N·m/rad
    free_angle: np.ndarray  # rad
    damping: np.ndarray  # N·m·s/rad


class LoadArrays(NamedTuple):
    """Everything that loads the bodies: the one argument of the force kernels.

    The joint actuators are not here: their coordinates are constraint primitives, packed
    by `actuator_blocks` for `sparsekin.engine.saddle`."""

    masses: MassArrays
    gravity: np.ndarray  # float64 (2,), m/s²
    force: PointForceArrays
    torque: TorqueArrays
    spring: SpringArrays
    torsion: TorsionArrays


_KINDS = (PointForce, BodyTorque, SpringDamper, TorsionSpring)


def actuator_blocks(blocks) -> list:
    """The coordinate blocks (constraint primitives, rows = laws) of the joint actuators."""
    return [block.coordinate for block in blocks if type(block) is JointActuator]


def pack_loads(blocks, masses: MassArrays, gravity, frames: np.ndarray, shapes=None) -> LoadArrays:
    """Pack the load blocks of a mechanism, with its masses and gravity, for the kernels.

    Parameters
    ----------
    blocks : iterable of PointForce, BodyTorque, SpringDamper
    masses : MassArrays
    gravity : (gx, gy)
        m/s².
    frames : ndarray, shape (n_bodies + 1, 3)
        Drawn frames of the bodies, the ground last.
    shapes : BodyShapes, optional
        The bodies with `lengths`: their points sit where their shape puts them
        (`sparsekin.model.lengths`).
    """
    blocks = list(blocks)
    merged = {kind: _merged([b for b in blocks if type(b) is kind], kind) for kind in _KINDS}
    f, t, s, r = merged[PointForce], merged[BodyTorque], merged[SpringDamper], merged[TorsionSpring]
    free_length = np.where(np.isnan(s.free_length), np.hypot(*(s.point_j - s.point_i).T), s.free_length)
    body_i, body_j = _ints(r.body_i), _ints(r.body_j)
    free_angle = np.where(np.isnan(r.free_angle), frames[body_i, 2] - frames[body_j, 2], r.free_angle)
    return LoadArrays(
        masses=masses,
        gravity=np.asarray(gravity, dtype=float).reshape(2),
        force=PointForceArrays(_ints(f.body), _local(frames, f.body, f.point, shapes), _ints(f.law)),
        torque=TorqueArrays(_ints(t.body), _ints(t.law)),
        spring=SpringArrays(
            _ints(s.body_i), _ints(s.body_j), _local(frames, s.body_i, s.point_i, shapes),
            _local(frames, s.body_j, s.point_j, shapes),
            _floats(s.stiffness), _floats(free_length), _floats(s.damping),
        ),
        torsion=TorsionArrays(body_i, body_j, _floats(r.stiffness), _floats(free_angle), _floats(r.damping)),
    )  # fmt: skip


def _local(frames: np.ndarray, body: np.ndarray, points: np.ndarray, shapes=None) -> np.ndarray:
    """The points in the drawn frames of their bodies (their shapes' places on bodies with
    lengths), shape (k, 2)."""
    return np.ascontiguousarray((shapes or NO_SHAPES).local_points(frames, body, points))


_INDEX_FIELDS = ("law", "body", "body_i", "body_j")


def _merged(blocks, kind):
    if not blocks:
        return kind(*(np.zeros((0, 2)) if name.startswith("point") else
                      np.zeros(0, dtype=np.int64 if name in _INDEX_FIELDS else float) for name in kind._fields))  # fmt: skip
    return kind(*(np.concatenate([getattr(block, name) for block in blocks]) for name in kind._fields))


def _ints(array) -> np.ndarray:
    return np.ascontiguousarray(array, dtype=np.int64)


def _floats(array) -> np.ndarray:
    return np.ascontiguousarray(array, dtype=np.float64)
