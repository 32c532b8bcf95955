"""numba cores of the equations of motion, shared by `DynamicSystem` and the compiled dynamics loop.

`sparsekin.engine.saddle.DynamicSystem` (the Python stepper's system) and the compiled block
stepper of small models (`sparsekin.solve._compiled_dynamics`) call the same three
functions, so the two paths evaluate the same arithmetic in the same order:

* `fill_saddle_triplets` — every triplet of the saddle matrix (`fill_block_triplets` those
  of its leading block, which the matrix-free product of the large path uses alone)
  [[a M + b C_t + c K_t, Φqᵀ], [Φq, −r I]] (the kernels of
  `sparsekin.engine._dynamics_kernels`, in the order that fixes its pattern);
* `fill_motion_forces` — ``Q − M q̈ − h``: gravity, loads and actuators minus the
  inertial forces;
* `motion_powers` — the power of the loads, actuators and drivers, and that dissipated.

`newton_rhs_fused` (the Python stepper's only) is Newton's right-hand side in one call;
for a chain of joints `fill_coincidences_newton_rhs` is the constraints' refill and it in one
pass, and `fill_coincidences_drifts` the refill and the projections' targets.

Arguments as in `sparsekin.engine._dynamics_kernels` (``q``, ``qd``, ``qdd`` with the
ground appended, ``turns`` filled at ``q``).  ``actuators`` is the tuple ``(primitives,
indptr, indices, values, value, zeros, ones, rates)`` of
`sparsekin.engine.actuators.actuator_kernel_arrays` (no rows' entries for a model without
actuators: one signature for every model, compiled once for both paths).  They are
inlined into the compiled loop: a call passes the loads', primitives' and actuators' arrays,
whose reference counts at every call cost more than a small model's arithmetic.
"""

from __future__ import annotations

from numba import njit

from .._jit import JIT
from ._dynamics_kernels import (
    add_transposed_product,
    applied_power,
    damping_power,
    fill_diagonal_triplets,
    fill_inertia_triplets,
    fill_multiplier_triplets,
    fill_point_force_triplets,
    fill_primitive_hessians,
    fill_row_products,
    fill_spring_triplets,
    fill_torsion_triplets,
    load_shared,
)
from ._force_kernels import fill_applied_forces
from ._kernels import fill_body_turns, fill_coincidence_at, residual_jacobian, residual_norm
from ._projection_kernels import fill_inertia_values


@njit(inline="always", **JIT)
def fill_block_triplets(loads, primitives, actuators, q, qd, qdd, turns, law_values, multipliers, actuator_weights,
                        coefficients, scratch, rows, cols, vals):  # fmt: skip
    """The triplets of the leading block ``a M + b C_t + c K_t`` of the saddle matrix, from
    the first on (returns how many; arguments as for `fill_saddle_triplets`)."""
    a, b, c = coefficients
    e = fill_inertia_triplets(loads.masses, loads.gravity, qd, qdd, turns, a, b, c, rows, cols, vals, 0)
    return _fill_load_triplets(loads, primitives, actuators, q, qd, turns, law_values, multipliers, actuator_weights,
                               b, c, scratch, rows, cols, vals, e)  # fmt: skip


@njit(**JIT)
def fill_block_compact(loads, primitives, actuators, q, qd, qdd, turns, law_values, multipliers, actuator_weights,
                       coefficients, scratch, inertia, rows, cols, vals):  # fmt: skip
    """`fill_block_triplets` with each body's inertia block as its six values in `inertia`
    (`_projection_kernels.fill_inertia_values`: the same numbers, a third of the bytes)
    instead of its nine triplets: the triplets from ``9 · bodies`` on only, as
    `fill_block_triplets` writes them (returns how many, the same count)."""
    a, b, c = coefficients
    e = fill_inertia_values(loads.masses, loads.gravity, qd, qdd, turns, a, b, c, inertia)
    return _fill_load_triplets(loads, primitives, actuators, q, qd, turns, law_values, multipliers, actuator_weights,
                               b, c, scratch, rows, cols, vals, e)  # fmt: skip


@njit(inline="always", **JIT)
def _fill_load_triplets(loads, primitives, actuators, q, qd, turns, law_values, multipliers, actuator_weights, b, c,
                        scratch, rows, cols, vals, e):  # fmt: skip
    """The leading block's triplets after the bodies' inertia, from `e` on: point forces,
    springs, rotational springs, the constraints' and the actuators' Hessians."""
    gradient, rate_gradient, d, hessian, block = scratch
    e = fill_point_force_triplets(loads.force, turns, law_values, c, rows, cols, vals, e)
    e = fill_spring_triplets(loads.spring, q, qd, turns, b, c, gradient, rate_gradient, d, hessian, block,
                             rows, cols, vals, e)  # fmt: skip
    e = fill_torsion_triplets(loads.torsion, b, c, rows, cols, vals, e)
    e = fill_primitive_hessians(primitives, q, turns, multipliers, c, d, hessian, rows, cols, vals, e)
    for k in range(law_values.size):
        actuator_weights[k] = -law_values[k]  # f = −Q: −F ∇²s
    return fill_primitive_hessians(actuators[0], q, turns, actuator_weights, c, d, hessian, rows, cols, vals, e)


@njit(inline="always", **JIT)
def fill_saddle_triplets(loads, primitives, actuators, q, qd, qdd, turns, law_values, multipliers, actuator_weights,
                         jacobian, kept_row, n_kept, coefficients, regularization, scratch, rows, cols, vals):  # fmt: skip
    """The triplets of ``[[a M + b C_t + c K_t, Φqᵀ], [Φq, −regularization · I]]`` (returns
    how many: all of them, every call).

    `multipliers` has one entry per equation (0 on those left out).
    `jacobian` is ``(indptr, indices, values)`` of Φq; `kept_row` maps an equation to its
    index among the kept ones (−1: left out), `n_kept` counts them; `coefficients` is
    ``(a, b, c)``; `actuator_weights` (one per load law) is scratch for −F; `scratch`
    ``(gradient, rate_gradient, d, hessian, block)`` of shapes (6,), (6,), (2, 6), (6, 6),
    (6, 6)."""
    e = fill_block_triplets(loads, primitives, actuators, q, qd, qdd, turns, law_values, multipliers,
                            actuator_weights, coefficients, scratch, rows, cols, vals)  # fmt: skip
    indptr, indices, values = jacobian
    n_ground = q.size  # equations follow the coordinates and the ground's three
    e = fill_multiplier_triplets(indptr, indices, values, kept_row, n_ground, rows, cols, vals, e)
    e = fill_diagonal_triplets(n_ground, n_kept, -regularization, rows, cols, vals, e)
    return e


@njit(inline="always", **JIT)
def _actuator_gradients(actuators, q, turns):
    """∇s of every actuator at `q` (into ``actuators[3]``; `turns` made again at `q`).  Nothing
    without an actuator's entry: every caller's `turns` are at `q` already (the refill would
    write the same cos and sin, a pass over the bodies' angles for nothing)."""
    primitives, indptr, indices, values, value, zeros, ones, rates = actuators
    if indptr[indptr.size - 1] > 0:
        residual_jacobian(primitives, q, turns, zeros, ones, value, values)


@njit(inline="always", **JIT)
def fill_motion_forces(loads, actuators, q, qd, qdd, turns, law_values, applied, out):
    """``out`` (n_coordinates) = gravity, loads and actuators minus the inertial forces;
    `applied` (n_coordinates + 3) is scratch."""
    fill_applied_forces(loads, q, qd, qdd, turns, law_values, True, applied)
    for k in range(out.size):
        out[k] = applied[k]
    _actuator_gradients(actuators, q, turns)
    add_transposed_product(actuators[1], actuators[2], actuators[3], law_values, out)


@njit(inline="always", **JIT)
def motion_powers(loads, actuators, q, qd, turns, law_values, multipliers, driven_row, velocity_rhs):
    """``(power, dissipated)``: the power of the loads, actuators and drivers (a driver's
    force is −λ) and the power the dampers dissipate, W."""
    power = applied_power(loads, qd, turns, law_values)
    _actuator_gradients(actuators, q, turns)
    rates = actuators[7]
    fill_row_products(actuators[1], actuators[2], actuators[3], qd, rates)
    total = 0.0
    for k in range(rates.size):
        total += law_values[k] * rates[k]
    power += total
    drivers = 0.0
    for k in range(driven_row.size):
        drivers += multipliers[driven_row[k]] * velocity_rhs[driven_row[k]]
    power -= drivers
    return power, damping_power(loads.spring, loads.torsion, qd, q, turns)


@njit(**JIT)
def _add_transposed_pairs(indptr, indices, values, weights, out):
    """`add_transposed_product` (``out += Jᵀ weights``, columns sorted within rows) two rows at
    a time: a column in both rows takes the first row's term, then the second's, in registers
    (one load and one store instead of a store the next row waits on: a joint's x and y rows
    share their bodies' angle columns).  The same additions in the same order on every
    column: bit for bit; 0.7× its time on the 10^5-body chain's Φq."""
    rows, beyond = indptr.size - 1, out.size
    r = 0
    while r < rows:
        w0 = weights[r]
        if r + 1 < rows and w0 != 0.0 and weights[r + 1] != 0.0:
            w1 = weights[r + 1]
            a, a_end, b, b_end = indptr[r], indptr[r + 1], indptr[r + 1], indptr[r + 2]
            while a < a_end or b < b_end:
                column_a = indices[a] if a < a_end else beyond
                column_b = indices[b] if b < b_end else beyond
                if column_a == column_b:
                    out[column_a] = (out[column_a] + values[a] * w0) + values[b] * w1
                    a, b = a + 1, b + 1
                elif column_a < column_b:
                    out[column_a] += values[a] * w0
                    a += 1
                else:
                    out[column_b] += values[b] * w1
                    b += 1
            r += 2
        else:
            if w0 != 0.0:
                for s in range(indptr[r], indptr[r + 1]):
                    out[indices[s]] += values[s] * w0
            r += 1


@njit(**JIT)
def newton_rhs_fused(loads, actuators, motion, law_values, jacobian, multipliers, scale, residual, kept_rows,
                     all_kept, applied, direct, rhs):  # fmt: skip
    """Newton's right-hand side ``rhs = [scale · (M q̈ + h − Q + Φqᵀλ); −Φ of the kept
    rows]`` in one call; whether its first n entries are finite.

    The same operations in the same order as `DynamicSystem.residual` (`load_motion`,
    `fill_motion_forces`, the negation, Φqᵀλ) followed by `newton_rhs`, bit for bit, without
    the force array between them, and without copying q and the turns where the
    constraints' last fill was at q: the forces then read the fill's own (equal) arrays.
    `motion` is ``(coordinates, velocities, accelerations, q, qd, qdd, filled,
    filled_turns, turns)`` as for `load_motion`; `jacobian` ``(indptr, indices, values)``
    of Φq; `applied` (n_coordinates + 3) scratch, used only where `rhs` has fewer than
    n_coordinates + 3 entries (else the forces are made in ``rhs[:n + 3]``, whose last
    three the −Φ rows overwrite); `direct`: no load reads the ground's velocity or
    acceleration (no spring or rotational spring on it), so that the forces read
    `velocities` and `accelerations` themselves, not copies with the ground appended
    (`DynamicSystem`; two state-sized copies fewer a call)."""
    coordinates, velocities, accelerations, q, qd, qdd, filled, filled_turns, turns = motion
    n = coordinates.size
    if load_shared(coordinates, velocities, accelerations, q, qd, qdd, filled, filled_turns, turns, not direct):
        at, turned = filled, filled_turns
    else:
        at, turned = q, turns
    if direct:
        rates, second = velocities, accelerations
    else:
        rates, second = qd, qdd
    forces = rhs[: n + 3] if rhs.size >= n + 3 else applied
    fill_applied_forces(loads, at, rates, second, turned, law_values, True, forces)
    out = rhs[:n]
    if actuators[1][actuators[1].size - 1] > 0:  # actuators: Q gains F ∇s first, as in `fill_motion_forces`
        for k in range(n):
            out[k] = forces[k]
        _actuator_gradients(actuators, at, turned)
        add_transposed_product(actuators[1], actuators[2], actuators[3], law_values, out)
        for k in range(n):
            out[k] = -out[k]
    else:
        for k in range(n):
            out[k] = -forces[k]
    _add_transposed_pairs(jacobian[0], jacobian[1], jacobian[2], multipliers, out)
    finite = _scaled_finite(out, n, scale)
    for k in range(rhs.size - n):
        rhs[n + k] = -residual[k if all_kept else kept_rows[k]]
    return finite


@njit(inline="always", **JIT)
def _joint_products(i, j, n, ax, ay, bx, by, x):
    """Φq x on a joint's two rows (`_kernels.fill_coincidence_at`'s entries), each summed over its columns in
    ascending order from 0 (`_dynamics_kernels.fill_row_products`' sums; the ground's columns,
    from n on, are not in Φq)."""
    if j >= n:
        tx = (0.0 + 1.0 * x[i]) + -ay * x[i + 2]
        ty = (0.0 + 1.0 * x[i + 1]) + ax * x[i + 2]
    elif i >= n:
        tx = (0.0 + -1.0 * x[j]) + by * x[j + 2]
        ty = (0.0 + -1.0 * x[j + 1]) + -bx * x[j + 2]
    elif i < j:
        tx = (((0.0 + 1.0 * x[i]) + -ay * x[i + 2]) + -1.0 * x[j]) + by * x[j + 2]
        ty = (((0.0 + 1.0 * x[i + 1]) + ax * x[i + 2]) + -1.0 * x[j + 1]) + -bx * x[j + 2]
    else:
        tx = (((0.0 + -1.0 * x[j]) + by * x[j + 2]) + 1.0 * x[i]) + -ay * x[i + 2]
        ty = (((0.0 + -1.0 * x[j + 1]) + -bx * x[j + 2]) + 1.0 * x[i + 1]) + ax * x[i + 2]
    return tx, ty


@njit(**JIT)
def fill_coincidences_drifts(coincidence, q, qd, turns, target, weights, residual, jac_data, velocities, velocity_rhs,
                             velocity_drift, accelerations, acceleration_product, target_acceleration, acceleration_rhs,
                             acceleration_drift, constants):  # fmt: skip
    """`_kernels.fill_residual_jacobian` at `q` (equations as for
    `fill_coincidences_newton_rhs`), and with each joint's rows, in the same pass, the
    projections' targets (`_dynamics_kernels.fill_drift_pair`'s numbers): ``velocity_drift =
    Φq q̇ − velocity_rhs``, ``acceleration_product = Φq q̈``, the acceleration right-hand
    side γ + `target_acceleration` at (q, q̇) into `acceleration_rhs` (`_kernels.fill_gamma`
    and the sum of `Assembler.fill_acceleration_rhs`; `qd` the velocities with the ground
    appended, copied there) and ``acceleration_drift = Φq q̈ − acceleration_rhs``; returns
    the weighted norm of Φ.  Φq's constant entries are written only with `constants`
    (`fill_coincidence_at`)."""
    n = velocities.size
    fill_body_turns(q, turns)
    for k in range(n):
        qd[k] = velocities[k]
    c = coincidence
    for k in range(c.row.size):
        i, j, r, ax, ay, bx, by = fill_coincidence_at(c, k, q, turns, residual, jac_data, constants)
        vx, vy = _joint_products(i, j, n, ax, ay, bx, by, velocities)
        velocity_drift[r], velocity_drift[r + 1] = vx - velocity_rhs[r], vy - velocity_rhs[r + 1]
        px, py = _joint_products(i, j, n, ax, ay, bx, by, accelerations)
        acceleration_product[r], acceleration_product[r + 1] = px, py
        wi2, wj2 = qd[i + 2] ** 2, qd[j + 2] ** 2  # γ = a ω_i² − b ω_j², as `_kernels.fill_coincidence_gamma`
        gx = (ax * wi2 - bx * wj2) + target_acceleration[r]
        gy = (ay * wi2 - by * wj2) + target_acceleration[r + 1]
        acceleration_rhs[r], acceleration_rhs[r + 1] = gx, gy
        acceleration_drift[r], acceleration_drift[r + 1] = px - gx, py - gy
    return residual_norm(residual, target, weights)


@njit(**JIT)
def fill_coincidences_newton_rhs(loads, coincidence, q, turns, target, weights, residual, jac_data, velocities,
                                 accelerations, law_values, multipliers, scale, rhs, constants):  # fmt: skip
    """`_kernels.fill_residual_jacobian` at `q` (the coordinates with the ground appended)
    and then `newton_rhs_fused` (the state's velocities and accelerations read directly, no
    actuator, every equation kept) in one pass over the constraints: ``(weighted norm of Φ,
    whether the first n entries of rhs are finite)``.  For equations that are all point
    coincidences, their rows in the coincidences' order (`DynamicSystem`): each joint's
    Φqᵀλ terms are added as its Jacobian entries are made, the x row's then the y row's on
    each column, rows in order — the additions of `_add_transposed_pairs`, bit for bit,
    without reading Φq again.  Φq's constant entries are written only with `constants`
    (`fill_coincidence_at`)."""
    n = velocities.size
    fill_body_turns(q, turns)
    forces = rhs[: n + 3]  # (its last three: the first −Φ rows, written below)
    fill_applied_forces(loads, q, velocities, accelerations, turns, law_values, True, forces)
    out = rhs[:n]
    for k in range(n):
        out[k] = -forces[k]
    c = coincidence
    for k in range(c.row.size):  # `_kernels.fill_coincidence`, and Φqᵀλ of its two rows
        i, j, r, ax, ay, bx, by = fill_coincidence_at(c, k, q, turns, residual, jac_data, constants)
        w0, w1 = multipliers[r], multipliers[r + 1]
        if w0 != 0.0:  # (a row of λ = 0 adds nothing, as in `_add_transposed_pairs`)
            if i < n:
                out[i] += 1.0 * w0
                out[i + 2] += -ay * w0
            if j < n:
                out[j] += -1.0 * w0
                out[j + 2] += by * w0
        if w1 != 0.0:
            if i < n:
                out[i + 1] += 1.0 * w1
                out[i + 2] += ax * w1
            if j < n:
                out[j + 1] += -1.0 * w1
                out[j + 2] += -bx * w1
    norm = residual_norm(residual, target, weights)
    for r in range(residual.size):  # −Φ
        rhs[n + r] = -residual[r]
    finite = _scaled_finite(out, n, scale)
    return norm, finite


@njit(inline="always", **JIT)
def _scaled_finite(out, n, scale) -> bool:
    """``out[:n] *= scale``; whether every entry is finite (two lanes: a sum of zeros, NaN
    if any entry is not, in any order)."""
    p0 = p1 = 0.0
    for k in range(0, n - n % 2, 2):
        p0 += 0.0 * out[k]
        p1 += 0.0 * out[k + 1]
        out[k], out[k + 1] = out[k] * scale, out[k + 1] * scale
    for k in range(n - n % 2, n):
        p0 += 0.0 * out[k]
        out[k] = out[k] * scale
    return p0 + p1 == 0.0
