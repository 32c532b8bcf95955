"""Forces that hold a known motion: masses and loads, the multipliers, drivers and reactions.

For a kinematically driven mechanism the motion comes first; the forces follow from it at
almost no cost.  At each solved sample the Lagrange multipliers λ of the constraints solve

    Φqᵀ λ = Q − M q̈ − h

(gravity and loads, minus the inertial forces; `sparsekin.engine._force_kernels`) with the
transpose of the factorization already made at the converged position: one more
triangular solve, no factorization.  The constraints apply −Φqᵀ λ to the bodies, so

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

The drivers' powers and the loads' power then add up to the rate of change of kinetic
plus potential energy (tests/test_forces.py checks it).  With ``quasi_static`` the
inertial forces are left out: the forces that hold the mechanism still in each
configuration (a slow hydraulic machine).

A model with redundant equations has many λ: the equations left out carry none in the
solve; the answer given is the one of minimum norm, λ − W (WᵀW)⁻¹ Wᵀ λ with W the
dependencies of the equations at the sample (one more transposed solve per redundant
equation), up to `MAX_MIN_NORM_EQUATIONS` of them; beyond, the same λ by conjugate
gradients on the redundant equations' multipliers, two solves with the factorization
already held per iteration (`minimum_norm_multipliers`), or, if they converge too slowly,
one sparse LU per sample of the augmented system (`augmented_minimum_norm`).  That norm adds squares of newtons
(the multipliers of position equations) to squares of newton-metres (those of angle
equations, e.g. a rigid or translational joint's angle row), unweighted: when a
redundant set mixes both kinds, how the load is shared among them depends on the unit
of length (metres here: in millimetres the angle rows' multipliers would be a thousand
times larger and the split would differ).  Any of those answers holds the motion; only
their split among the redundant joints is a convention.

`build_load_pattern` packs the masses and loads once; `ForceOutputs` says which columns
a run records and how each is made; `ForceSolver` evaluates them after each sample of the
Python time loop (the compiled loop of `sparsekin.solve._compiled` runs the same kernels inline).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..model.geometry import to_local
from ..model.laws import LawPacker, LawTable, fill_laws
from ..model.loads import LoadArrays, MassArrays, pack_loads
from ..model.mechanism import Mechanism
from . import _force_kernels
from .actuators import ActuatorForces, build_actuators
from .columns import Resolver
from .pattern import ConstraintPattern, element_columns, pack_element_laws, per_element

__all__ = [
    "LoadPattern",
    "ForceOutputArrays",
    "ForceOutputs",
    "ForceSolver",
    "build_load_pattern",
    "no_forces",
    "MAX_MIN_NORM_EQUATIONS",
    "minimum_norm_multipliers",
    "augmented_minimum_norm",
]

#: The minimum-norm multipliers of a redundant model cost, through the dependencies, one
#: transposed solve per redundant equation and a dense (n_equations × n_redundant) matrix
#: per sample; above this many redundant equations conjugate gradients with the held
#: factorization (`minimum_norm_multipliers`) cost less, with a sparse LU of the augmented
#: system per sample (`augmented_minimum_norm`) where they do not converge.
MAX_MIN_NORM_EQUATIONS = 64
#: Conjugate gradients of `minimum_norm_multipliers`: relative residual and most
#: iterations.  The system's eigenvalues are 1 + the squared singular values of the
#: redundant rows written in the kept ones (C); 10^4-cell parallel-bar chain: 3 to 7
#: iterations per sample (docs/design-notes.md, "Redundant equations at scale").
MIN_NORM_TOLERANCE = 1e-12
MIN_NORM_ITERATIONS = 60
#: Iterative refinements of `augmented_minimum_norm`, the fallback when conjugate
#: gradients do not converge (100×100 rotating squares: not within 500 iterations; the
#: augmented LU then costs about 0.6 s per sample).
AUGMENTED_REFINEMENTS = 2


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
    arrays = pack_loads(blocks, _masses(mechanism, resolver), mechanism.gravity, resolver.frames)
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
    return MassArrays(mass, inertia, np.ascontiguousarray(to_local(resolver.frames[:n], com)))


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
    mechanism : Mechanism
    pattern : ConstraintPattern
    drivers, joints : sequence of int
        Indices of the drivers and joints whose forces are recorded.

    Attributes
    ----------
    labels, units : tuple of str
        The column names and their units (N, N·m, W).
    driver_indices, joint_indices : tuple of int
    """

    def __init__(self, mechanism: Mechanism, pattern: ConstraintPattern, drivers: Sequence[int],
                 joints: Sequence[int]) -> None:  # fmt: skip
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
        side, side_is_first, point_body, point_local = _reaction_geometry(mechanism, pattern, self.joint_indices)
        entries = _reaction_entries(pattern, np.array(self.joint_indices, dtype=np.int64), side, side_is_first)
        self._csr_arrays = ForceOutputArrays(
            _ints(driver_row), _ints(driver_rows), _ints(driver_column), *entries, side, side_is_first, point_body,
            point_local, _ints(joint_column), np.array(joint_torque, dtype=bool),
        )  # fmt: skip
        self._ordered: tuple[object, ForceOutputArrays] | None = None

    @property
    def n_columns(self) -> int:
        return len(self.labels)

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


def _reaction_geometry(mechanism: Mechanism, pattern: ConstraintPattern, joints: tuple[int, ...]):
    """For each chosen joint: the side body (bodies[0], or bodies[1] when bodies[0] is the
    ground), whether it is bodies[0], and the joint's point (carrier body, local position)."""
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
        point_local[where] = to_local(resolver.frames[carrier_body], point[chosen])
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


class ForceSolver:
    """The force columns of each sample of the Python time loop, from its stepper.

    Parameters
    ----------
    pattern : ConstraintPattern
    loads : LoadPattern
    outputs : ForceOutputs
    quasi_static : bool
        Leave out the inertial forces.
    """

    def __init__(self, pattern: ConstraintPattern, loads: LoadPattern, outputs: ForceOutputs,
                 quasi_static: bool = False) -> None:  # fmt: skip
        self.loads, self.outputs, self.inertial = loads, outputs, not quasi_static
        n = pattern.n_coordinates
        self._qdd, self._b = np.zeros(n + 3), np.zeros(n + 3)
        self._laws = [np.zeros(loads.n_laws) for _ in range(3)]
        self.multipliers = np.zeros(pattern.n_equations)
        self._work = np.zeros((len(outputs.joint_indices), 3))
        self.row = np.zeros(outputs.n_columns)
        # conjugate gradients on the redundant multipliers failed once: the augmented LU from then on
        self._augmented = False

    def evaluate(self, stepper) -> np.ndarray:
        """The force columns at the stepper's current sample (`row`, reused), right after its
        `start` or `advance`: the assembler's arrays (Jacobian values, the coordinates and
        velocities of its last acceleration refill) are then those of that sample."""
        assembler = stepper.assembler
        q, qd, turns = assembler.filled_motion()
        qdd = self._qdd
        qdd[:-3] = stepper.accelerations
        self.loads.evaluate(stepper.time, *self._laws)
        _force_kernels.fill_applied_forces(self.loads.arrays, q, qd, qdd, turns, self._laws[0], self.inertial,
                                           self._b)  # fmt: skip
        if self.loads.actuators is not None:  # actuators along joints (forward-dynamics loads)
            self.loads.actuators.fill(q, turns)
            self.loads.actuators.add_forces(self._laws[0], self._b)
        self._solve_multipliers(stepper, self._b[:-3])
        _force_kernels.fill_force_outputs(
            self.outputs.arrays(assembler.csr_positions), assembler.values, self.multipliers, q, turns,
            assembler.velocity_rhs, self._work, self.row,
        )  # fmt: skip
        return self.row

    def _solve_multipliers(self, stepper, rhs: np.ndarray) -> None:
        """Φqᵀ λ = rhs with the stepper's factorization; minimum norm for a redundant model."""
        solver, system, multipliers = stepper.linear_solver, stepper.system, self.multipliers
        if system is stepper.assembler:
            solver.solve(rhs, out=multipliers, transposed=True)
            return
        kept = system.rows
        multipliers[:] = 0.0
        multipliers[kept] = solver.solve(rhs, transposed=True)
        redundant = stepper.redundant_rows
        if redundant.size > MAX_MIN_NORM_EQUATIONS:
            jacobian = stepper.assembler.jacobian
            parts = None if self._augmented else minimum_norm_multipliers(solver, jacobian[redundant], multipliers[kept].copy())
            if parts is None:  # conjugate gradients too slow (then at every sample): one sparse LU of the augmented system
                self._augmented = True
                multipliers[:] = augmented_minimum_norm(jacobian, rhs)
            else:
                multipliers[kept], multipliers[redundant] = parts
            return
        # the dependencies w (W's columns): row r of Φq = Σ c_k · kept row k, c from Φ_keptᵀ c = Φ_rᵀ
        jacobian = stepper.assembler.jacobian
        dependencies = np.zeros((multipliers.size, redundant.size))
        for c, r in enumerate(redundant.tolist()):
            dependencies[kept, c] = -solver.solve(jacobian[[r]].toarray().ravel(), transposed=True)
            dependencies[r, c] = 1.0
        gram = dependencies.T @ dependencies
        multipliers -= dependencies @ np.linalg.solve(gram, dependencies.T @ multipliers)


def minimum_norm_multipliers(solver, redundant_jacobian, particular: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The multipliers of minimum norm, ``(λ_K, λ_R)``, from a particular solution.

    With B the kept rows of Φq (square, factored in `solver`) and A_R the redundant rows
    (`redundant_jacobian`), every solution of ``Bᵀ λ_K + A_Rᵀ λ_R = rhs`` is
    ``λ_K = particular − C λ_R`` with ``particular = B⁻ᵀ rhs`` and ``C = B⁻ᵀ A_Rᵀ``.  The
    one of minimum norm has ``(I + CᵀC) λ_R = Cᵀ particular``: a symmetric system with
    eigenvalues ≥ 1, solved by conjugate gradients, two solves with the factorization
    already held per iteration (`MIN_NORM_TOLERANCE`, at most `MIN_NORM_ITERATIONS`).

    Returns None if the iteration has not converged after `MIN_NORM_ITERATIONS`.
    """
    def operator(vector: np.ndarray) -> np.ndarray:
        image = solver.solve(redundant_jacobian.T @ vector, transposed=True)  # C v
        return vector + redundant_jacobian @ solver.solve(image)  # v + Cᵀ C v

    rhs = redundant_jacobian @ solver.solve(particular)  # Cᵀ particular
    solution = np.zeros_like(rhs)
    residual = rhs.copy()
    direction = residual.copy()
    squared = float(residual @ residual)
    target = MIN_NORM_TOLERANCE**2 * max(squared, np.finfo(float).tiny)
    for _ in range(MIN_NORM_ITERATIONS):
        if squared <= target:
            break
        image = operator(direction)
        step = squared / float(direction @ image)
        solution += step * direction
        residual -= step * image
        squared, previous = float(residual @ residual), squared
        direction = residual + (squared / previous) * direction
    else:
        if squared > target:
            return None
    kept = particular - solver.solve(redundant_jacobian.T @ solution, transposed=True)
    return kept, solution


def augmented_minimum_norm(jacobian, rhs: np.ndarray) -> np.ndarray:
    """The λ of minimum norm with ``Φqᵀ λ = rhs`` (Φq of full column rank) from one sparse LU
    of ``[[I, Φq], [Φqᵀ, 0]]`` (its solution ``(λ, −μ)`` has λ = Φq μ, in the range of Φq),
    refined `AUGMENTED_REFINEMENTS` times: its condition is that of Φq squared."""
    from scipy import sparse
    from scipy.sparse.linalg import splu

    m = jacobian.shape[0]
    augmented = sparse.block_array([[sparse.identity(m, format="csr"), jacobian], [jacobian.T, None]], format="csc")
    factor = splu(augmented, permc_spec="COLAMD")
    target = np.concatenate([np.zeros(m), rhs])
    solution = factor.solve(target)
    for _ in range(AUGMENTED_REFINEMENTS):
        solution += factor.solve(target - augmented @ solution)
    return solution[:m]


def no_forces() -> tuple[LoadArrays, LawTable, ForceOutputArrays]:
    """Empty loads, load laws and force columns: what the compiled loop takes when a run
    records no forces (the same types, so the same compiled code)."""
    masses = MassArrays(np.zeros(0), np.zeros(0), np.zeros((0, 2)))
    loads = pack_loads([], masses, (0.0, 0.0), np.zeros((1, 3)))
    none = np.zeros(0, dtype=np.int64)
    outputs = ForceOutputArrays(none, none, none, none, none, none, none, none, np.zeros(0, dtype=bool), none,
                                np.zeros((0, 2)), none, np.zeros(0, dtype=bool))  # fmt: skip
    return loads, LawPacker().table(), outputs


def _ints(values) -> np.ndarray:
    return np.ascontiguousarray(values, dtype=np.int64)
