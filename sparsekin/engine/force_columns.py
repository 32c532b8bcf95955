"""From multipliers to the forces a run records: drivers' forces and powers, joints' reactions.

Whatever gave the Lagrange multipliers λ (inverse dynamics, `sparsekin.engine.multipliers`,
or a forward-dynamics step), the constraints apply −Φqᵀ λ to the bodies, so

* a driver's force (or torque) is −λ on each of its rows: positive when it pushes along
  the quantity it drives (a stroke or distance apart, a relative angle
  counter-clockwise), and its power is that force times the quantity's rate;
* a joint's reaction on ``bodies[0]`` from ``bodies[1]`` is −Φqᵀ λ restricted to the
  joint's rows and to the columns of ``bodies[0]``, with the moment taken about the
  joint's point (`~sparsekin.model.elements.Joint.reaction_point`).  When ``bodies[0]`` is the
  ground, which has no columns, it is minus the sum of what those rows apply to every
  other body they involve: the joint's equations depend only on the relative positions
  of its bodies, so the forces of its rows on all of them, the ground included, balance.
  For a two-body joint that is −(the force on ``bodies[1]``); a gear's rows also act on
  its carrier (``angle(ground) − angle(k) = −ratio · (angle(j) − angle(k))`` puts
  −ratio·λ on the planet j and (1 + ratio)·λ on the carrier k), so its torque on the
  ground is −λ, as for a gear whose ``bodies[0]`` moves.

`ForceOutputs` says which columns a run records and how each is made;
`ForceOutputs.fill` makes them at a sample (`sparsekin.engine._force_kernels`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from ..model.mechanism import Mechanism
from . import _force_kernels
from .columns import Resolver
from .linearization import Linearization
from .pattern import ConstraintPattern, element_columns

__all__ = ["ForceOutputArrays", "ForceOutputs"]


class ForceOutputArrays(NamedTuple):
    """How `sparsekin.engine._force_kernels.fill_force_outputs` makes each column."""

    driver_row: np.ndarray  # int64 (n_drivers,): the driver's first row
    driver_rows: np.ndarray  # int64 (n_drivers,): its number of rows (force columns)
    driver_column: np.ndarray  # int64 (n_drivers,): its first column; its power follows its forces
    entry_position: np.ndarray  # int64 (E,): where each Jacobian entry of a reaction is in the values
    entry_row: np.ndarray  # int64 (E,)
    entry_joint: np.ndarray  # int64 (E,): which selected joint
    entry_component: np.ndarray  # int64 (E,): 0, 1, 2 for the side body's x, y, angle
    joint_side: np.ndarray  # int64 (n_joints,): the body whose columns give the reaction
    joint_side_is_first: np.ndarray  # bool (n_joints,): that body is bodies[0]
    joint_point_body: np.ndarray  # int64 (n_joints,): the body carrying the joint's point
    joint_point_local: np.ndarray  # float64 (n_joints, 2): the point in that body's frame
    joint_column: np.ndarray  # int64 (n_joints,)
    joint_torque: np.ndarray  # bool (n_joints,): whether the torque is a column


class ForceOutputs:
    """The force columns of a run, for chosen drivers and joints, and how to make them.

    Columns: for each driver (model order) ``D.force`` — or ``D.fx, D.fy`` for a path
    driver — then ``D.power``; then for each joint ``J.fx, J.fy`` and, for the kinds that
    declare ``reaction_torque``, ``J.torque``.  ``D`` and ``J`` are the element's name, or
    ``drivers[i]`` / ``joints[i]``.

    Parameters
    ----------
    discretization : Discretization
        The mechanism's arrays (`sparsekin.engine.discretization.discretize`).
    drivers, joints : sequence of int
        Indices of the drivers and joints whose forces are recorded.

    Attributes
    ----------
    labels, units : tuple of str
        The column names and their units (N, N·m, W).
    driver_indices, joint_indices : tuple of int
    """

    def __init__(self, discretization, drivers: Sequence[int], joints: Sequence[int]) -> None:
        mechanism, pattern = discretization.mechanism, discretization.constraints
        self.driver_indices, self.joint_indices = tuple(drivers), tuple(joints)
        first_row, n_joints = pattern.element_first_row, mechanism.n_joints
        labels: list[str] = []
        units: list[str] = []
        driver_row, driver_rows, driver_column = [], [], []
        for d in self.driver_indices:
            label, kind = _label_and_kind(mechanism, "drivers", d)
            row = int(first_row[n_joints + d])
            driver_row.append(row)
            driver_rows.append(kind.n_equations)
            driver_column.append(len(labels))
            unit = "N·m" if pattern.row_is_angle[row] else "N"
            labels += [f"{label}.{name}" for name in kind.force_names] + [f"{label}.power"]
            units += [unit] * kind.n_equations + ["W"]
        joint_column, joint_torque = [], []
        for k in self.joint_indices:
            label, kind = _label_and_kind(mechanism, "joints", k)
            joint_column.append(len(labels))
            joint_torque.append(kind.reaction_torque)
            names = ("fx", "fy", "torque") if kind.reaction_torque else ("fx", "fy")
            labels += [f"{label}.{name}" for name in names]
            units += ["N", "N", "N·m"][: len(names)]
        self.labels, self.units = tuple(labels), tuple(units)
        side, side_is_first, point_body, point_local = _reaction_geometry(discretization, self.joint_indices)
        entries = _reaction_entries(pattern, np.array(self.joint_indices, dtype=np.int64), side, side_is_first)
        self._csr_arrays = ForceOutputArrays(
            _ints(driver_row), _ints(driver_rows), _ints(driver_column), *entries, side, side_is_first, point_body,
            point_local, _ints(joint_column), np.array(joint_torque, dtype=bool),
        )  # fmt: skip
        self._ordered: tuple[object, ForceOutputArrays] | None = None

    @property
    def n_columns(self) -> int:
        return len(self.labels)

    def fill(self, lin: Linearization, multipliers: np.ndarray, work: np.ndarray, out: np.ndarray) -> np.ndarray:
        """The columns at the sample of `lin` from its `multipliers` into `out` (returned);
        `work` is scratch of shape (len(joint_indices), 3)."""
        q, _, turns = lin.motion
        _force_kernels.fill_force_outputs(self.arrays(lin.csr_positions), lin.jacobian_values, multipliers, q, turns,
                                          lin.velocity_rhs, work, out)  # fmt: skip
        return out

    def arrays(self, csr_positions: np.ndarray | None = None) -> ForceOutputArrays:
        """The kernel's arrays for Jacobian values in CSR order, or with the k-th CSR value
        at ``csr_positions[k]`` (`sparsekin.engine.assembly.Assembler.csr_positions`)."""
        if csr_positions is None:
            return self._csr_arrays
        if self._ordered is None or self._ordered[0] is not csr_positions:
            positions = np.ascontiguousarray(csr_positions[self._csr_arrays.entry_position], dtype=np.int64)
            self._ordered = (csr_positions, self._csr_arrays._replace(entry_position=positions))
        return self._ordered[1]


def _label_and_kind(mechanism: Mechanism, kind: str, index: int) -> tuple[str, type]:
    """The label (name, else ``kind[i]``) and the kind of joint or driver `index`, a copy's
    read from its unit without building the copy."""
    own = mechanism.own(kind)
    if index < len(own):
        element = own[index]
    else:
        for copies in mechanism.copies:
            if 0 <= index - copies.first[kind] < copies.total(kind):
                k, e = copies.locate(kind, index - copies.first[kind])
                unit_element = getattr(copies.unit, kind)[e]
                name = copies.name(k, unit_element.name) if unit_element.name else None
                return name or f"{kind}[{index}]", type(unit_element)
        raise IndexError(f"{kind}[{index}] out of range")
    return element.name or f"{kind}[{index}]", type(element)


def _reaction_geometry(discretization, joints: tuple[int, ...]):
    """For each chosen joint: the side body (bodies[0], or bodies[1] when bodies[0] is the
    ground), whether it is bodies[0], and the joint's point (carrier body, local position)."""
    mechanism, pattern = discretization.mechanism, discretization.constraints
    n = len(joints)
    side, side_is_first = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=bool)
    point_body, point_local = np.zeros(n, dtype=np.int64), np.zeros((n, 2))
    if not n:
        return side, side_is_first, point_body, point_local
    resolver = Resolver(mechanism)
    slot = np.full(mechanism.n_joints, -1, dtype=np.int64)
    slot[list(joints)] = np.arange(n)
    rows = pattern.element_first_row[: mechanism.n_joints]
    for kind, indices, columns in element_columns(mechanism, "joints", rows, resolver):
        chosen = slot[indices] >= 0
        if not chosen.any():
            continue
        where = slot[indices][chosen]
        first, second = (body[chosen] for body in columns.pair())
        carrier, point = kind.reaction_point(columns)
        ground = resolver.ground
        side[where] = np.where(first == ground, second, first)
        side_is_first[where] = first != ground
        carrier_body = (first if carrier == 0 else second)
        point_body[where] = carrier_body
        point_local[where] = mechanism.local_points(carrier_body, point[chosen], resolver.frames)
    return side, side_is_first, point_body, point_local


def _reaction_entries(pattern: ConstraintPattern, joints: np.ndarray, side: np.ndarray, side_is_first: np.ndarray):
    """The Jacobian entries of each chosen joint's rows that make its reaction:
    (CSR position, row, joint slot, component).

    Those in the columns of its side body; when ``bodies[0]`` is the ground, also those in
    the angle columns of any third body the rows involve (a gear's carrier), counted as
    angle entries of the side body: the reaction on the ground is minus the sum over
    every other body (see the module docstring), and a torque needs no arm.
    """
    first_row = pattern.element_first_row
    starts, ends = first_row[joints], first_row[joints + 1]
    n_rows = ends - starts
    row_joint = np.repeat(np.arange(joints.size, dtype=np.int64), n_rows)
    rows = np.repeat(starts - np.cumsum(n_rows) + n_rows, n_rows) + np.arange(int(n_rows.sum()), dtype=np.int64)
    indptr = pattern.indptr.astype(np.int64)
    counts = indptr[rows + 1] - indptr[rows]
    entry_row = np.repeat(rows, counts)
    entry_joint = np.repeat(row_joint, counts)
    positions = np.repeat(indptr[rows] - np.cumsum(counts) + counts, counts) + np.arange(int(counts.sum()), dtype=np.int64)
    columns = pattern.indices[positions].astype(np.int64)
    component = columns - 3 * side[entry_joint]
    own = (component >= 0) & (component < 3)
    third = ~own & ~side_is_first[entry_joint]  # bodies[0] is the ground: another body's share counts
    if np.any(third & (columns % 3 != 2)):
        joint = int(joints[entry_joint[np.flatnonzero(third & (columns % 3 != 2))[0]]])
        raise NotImplementedError(
            f"joints[{joint}]: bodies[0] is the ground and the joint's equations push a third body; its reaction "
            "would need that body's forces moved to the joint's point (only a third body's torque is counted)"
        )
    keep = own | third
    component = np.where(own, component, 2)
    return _ints(positions[keep]), _ints(entry_row[keep]), _ints(entry_joint[keep]), _ints(component[keep])


def _ints(values) -> np.ndarray:
    return np.ascontiguousarray(values, dtype=np.int64)
