"""The whole time loop of a small model in one numba call, with a dense LU.

For models of a few dozen coordinates the Python loop of `sparsekin.solvers` spends its
time in call overhead, not in arithmetic.  `solve_compiled` runs the same analysis —
Taylor predictor, Newton on the positions, then velocities and accelerations with the
Jacobian factored at the converged position — inside one compiled function, on a dense
copy of the Jacobian with an LU factorization with partial pivoting.

Symbols (as in `sparsekin._kernels`): ``q``, ``qd``, ``qdd`` coordinates, velocities and
accelerations; ``Phi(q, t) = g(q) - target(t)`` the residual; ``Phi_q`` the Jacobian;
``gamma`` the acceleration right-hand side.

Newton
------
The first sample runs plain Newton from the initial configuration, exactly as
`sparsekin.solvers` does.  Every later sample first tries a *chord* Newton: corrections
solved with the factorization of the Jacobian at the previous converged position (already
at hand, it served that sample's velocities and accelerations), as long as each correction
divides the residual by at least ``1 / CHORD_CONTRACTION``.  When the residual drops below
the tolerance the Jacobian at the converged position is factored afresh, so velocities and
accelerations are solved exactly as in the Python path.  If the chord stalls, or anything
else goes wrong, the sample restarts from the predictor with plain Newton — the algorithm
of `sparsekin.solvers._solve_positions`, with its stall and iteration limits — so a sample
fails here exactly when it fails there.

Velocities and accelerations could instead reuse the old factorization with iterative
refinement, saving the factorization at the converged position; measured on Task 5 at
1 ms steps, refinement to full accuracy cost about 14 extra solves and residuals per
sample and made the loop 2.7 times slower, so it was not kept.

Contract with the caller
------------------------
The loop stops at the first sample it cannot solve and returns its index as
``n_solved``: rows ``0 .. n_solved - 1`` of the output arrays are filled and final, the
rest are not meaningful.  ``status`` says why it stopped (`LoopStatus`); the loop raises
nothing and builds no message.  The caller re-runs from sample ``n_solved`` with the
Python path (from the solved sample ``n_solved - 1``), which fails there again and
produces the detailed error.

Driver laws
-----------
`Harmonic`, `Linear`, `Polynomial` and `Spline` laws are packed into one `LawTable`
(four flat arrays) and evaluated inside the loop, one small function per kind over the
drivers of that kind.  A mechanism with any other law object is not supported:
check `supports_compiled` first.

Caching: numba's on-disk cache of `_run_time_loop` is invalidated when this file changes,
not when a kernel it calls (in `sparsekin._kernels` and `sparsekin._lu_kernels`) does.
`_drop_stale_cache` therefore clears this module's cache files whenever those two files
change, before the loop is first compiled or loaded.
"""

from __future__ import annotations

import math
from enum import IntEnum
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numba import njit

from . import _kernels
from ._lu_kernels import dense_lu_factor, dense_lu_solve
from .laws import Harmonic, Linear, Polynomial, Spline
from .model import Mechanism
from .pattern import ConstraintPattern

__all__ = [
    "CHORD_CONTRACTION",
    "CompiledOutcome",
    "LawTable",
    "LoopStatus",
    "pack_laws",
    "solve_compiled",
    "supports_compiled",
]

#: The one set of jit options of this module, as in `sparsekin._kernels`.
_JIT = dict(cache=True, nogil=True, error_model="numpy")


def _drop_stale_cache() -> None:
    """Delete this module's numba cache files if a kernel module they inline has changed.

    The kernel files' sizes and modification times are kept in a stamp file beside the
    cache (numba's default location, ``__pycache__`` next to this file).  A read-only
    installation keeps whatever cache it shipped with.
    """
    here = Path(__file__).resolve()
    cache = here.parent / "__pycache__"
    stamp = " ".join(
        f"{path.name}:{path.stat().st_size}:{path.stat().st_mtime_ns}"
        for path in (here.with_name("_kernels.py"), here.with_name("_lu_kernels.py"))
    )
    stamp_file = cache / f"{here.stem}.kernels-stamp"
    try:
        if stamp_file.exists() and stamp_file.read_text() == stamp:
            return
        for stale in (*cache.glob(f"{here.stem}.*.nbi"), *cache.glob(f"{here.stem}.*.nbc")):
            stale.unlink()
        cache.mkdir(exist_ok=True)
        stamp_file.write_text(stamp)
    except OSError:
        pass


_drop_stale_cache()

#: Chord Newton ends with one Newton correction with the factorization at the converged
#: position, unless the residual is already this fraction of the tolerance (at the
#: default tolerance, a few rounding errors), where that correction would change nothing.
#: Shared with the Python loop of `sparsekin.solvers`.
POLISH_BELOW = 1e-3
#: A chord correction must divide the residual by at least 1 / CHORD_CONTRACTION, or the
#: sample restarts with plain Newton.
CHORD_CONTRACTION = 0.1

#: Plain Newton stalls when, from its third correction on, a correction leaves more than
#: this fraction of the residual (as in `sparsekin.solvers._solve_positions`).
_STALL_RATIO = 0.5

# Status codes of the loop (numba sees plain integers; `LoopStatus` names them).
_SOLVED, _RESIDUAL_NOT_FINITE, _STALLED, _NOT_CONVERGED, _SINGULAR, _CHORD_REJECTED = range(6)


class LoopStatus(IntEnum):
    """Why the compiled loop stopped."""

    #: every sample solved
    SOLVED = _SOLVED
    #: the residual at a Newton iterate is NaN or infinite
    RESIDUAL_NOT_FINITE = _RESIDUAL_NOT_FINITE
    #: from the third correction on, a Newton correction left more than half the residual
    STALLED = _STALLED
    #: `max_iterations` Newton corrections did not reach the tolerance
    NOT_CONVERGED = _NOT_CONVERGED
    #: a zero or non-finite pivot, or a non-finite solution of a linear system
    SINGULAR = _SINGULAR


class CompiledOutcome(NamedTuple):
    """What `solve_compiled` did.

    Attributes
    ----------
    n_solved : int
        Samples solved; equal to the number of times unless the loop stopped early.
    status : LoopStatus
        `LoopStatus.SOLVED`, or why sample ``n_solved`` failed.
    n_factorizations, n_solves : int
        Dense LU factorizations and triangular solves, counted like the Python path's.
    n_restarts : int
        Samples whose chord Newton was abandoned for plain Newton from the predictor.
    """

    n_solved: int
    status: LoopStatus
    n_factorizations: int
    n_solves: int
    n_restarts: int

    @property
    def complete(self) -> bool:
        return self.status == LoopStatus.SOLVED


# ---------------------------------------------------------------------- driver laws
#: Law kinds, in the order of `LawTable.kind_first`.
_LAW_KINDS = (Harmonic, Linear, Polynomial, Spline)


class LawTable(NamedTuple):
    """The laws of all drivers in four flat arrays, drivers grouped by kind.

    Attributes
    ----------
    kind_first : ndarray of int64, shape (5,)
        Entries ``kind_first[c] .. kind_first[c + 1] - 1`` of `driver` are the drivers
        whose law is of kind c: `Harmonic`, `Linear`, `Polynomial`, `Spline`.
    driver : ndarray of int64, shape (n_drivers,)
        Driver index of each entry (the driver's position in ``mechanism.drivers``).
    start : ndarray of int64, shape (n_drivers + 1,)
        Entry e's parameters are ``data[start[e] : start[e + 1]]``:

        * harmonic: ``offset, amplitude, omega, phase``;
        * linear: ``start, rate``;
        * polynomial of m coefficients: c, then c' and c'' padded with zeros to m
          (ascending powers, c0 resolved against the driver's initial value);
        * cubic spline of m intervals: its m + 1 breakpoints, then its scipy ``PPoly``
          coefficients ``c`` of shape (4, m), row by row.
    data : ndarray of float64
    """

    kind_first: np.ndarray
    driver: np.ndarray
    start: np.ndarray
    data: np.ndarray


def supports_compiled(mechanism: Mechanism) -> bool:
    """Whether every driver law is one `solve_compiled` evaluates inside the loop.

    Subclasses and other law objects are refused: their `evaluate` may differ.
    """
    return all(type(driver.law) in _LAW_KINDS for driver in mechanism.drivers)


def pack_laws(mechanism: Mechanism, initial: np.ndarray) -> LawTable:
    """The `LawTable` of `mechanism`'s drivers; `initial` is ``pattern.driver_initial``."""
    groups: list[list[int]] = [[] for _ in _LAW_KINDS]
    for k, driver in enumerate(mechanism.drivers):
        if type(driver.law) not in _LAW_KINDS:
            raise ValueError(
                f"`drivers[{k}].law` must be one of {', '.join(kind.__name__ for kind in _LAW_KINDS)} "
                f"for the compiled loop, got {type(driver.law).__name__}."
            )
        groups[_LAW_KINDS.index(type(driver.law))].append(k)
    order = [k for group in groups for k in group]
    chunks = [_law_parameters(mechanism.drivers[k].law, float(initial[k])) for k in order]
    sizes = [chunk.size for chunk in chunks]
    return LawTable(
        kind_first=np.cumsum([0] + [len(group) for group in groups]).astype(np.int64),
        driver=np.array(order, dtype=np.int64),
        start=np.cumsum([0] + sizes).astype(np.int64),
        data=np.concatenate(chunks) if chunks else np.zeros(0),
    )


def _law_parameters(law, initial: float) -> np.ndarray:
    """One law's entry of `LawTable.data`."""
    if type(law) is Harmonic:
        offset = initial if law.offset is None else law.offset
        return np.array([offset, law.amplitude, law.omega, law.phase], dtype=float)
    if type(law) is Linear:
        return np.array([initial if law.start is None else law.start, law.rate], dtype=float)
    if type(law) is Polynomial:
        first = initial if law.coefficients[0] is None else law.coefficients[0]
        c = np.array([first, *law.coefficients[1:]], dtype=float)
        padded = np.zeros((3, c.size))
        padded[0] = c
        for order in (1, 2):
            derivative = np.polynomial.polynomial.polyder(c, order)
            padded[order, : derivative.size] = derivative
        return padded.ravel()
    # Spline: the very curve the Python path evaluates (`Spline` builds it once).
    curve = law._curve
    return np.concatenate([curve.x, curve.c.ravel()])


@njit(inline="always", **_JIT)
def _evaluate_harmonic(laws, first, stop, t, value, rate, acceleration):
    for e in range(first, stop):
        s = laws.start[e]
        offset, amplitude, omega, phase = laws.data[s], laws.data[s + 1], laws.data[s + 2], laws.data[s + 3]
        d = laws.driver[e]
        angle = omega * t + phase
        sine = math.sin(angle)
        value[d] = offset + amplitude * sine
        rate[d] = amplitude * omega * math.cos(angle)
        acceleration[d] = -amplitude * omega**2 * sine


@njit(inline="always", **_JIT)
def _evaluate_linear(laws, first, stop, t, value, rate, acceleration):
    for e in range(first, stop):
        start, slope = laws.data[laws.start[e]], laws.data[laws.start[e] + 1]
        d = laws.driver[e]
        value[d] = start + slope * t
        rate[d] = slope
        acceleration[d] = 0.0


@njit(inline="always", **_JIT)
def _horner(c, t):
    """numpy's ``polyval(t, c)``, same operation order."""
    total = c[c.size - 1]
    for i in range(c.size - 2, -1, -1):
        total = c[i] + total * t
    return total


@njit(inline="always", **_JIT)
def _evaluate_polynomial(laws, first, stop, t, value, rate, acceleration):
    for e in range(first, stop):
        start = laws.start[e]
        m = (laws.start[e + 1] - start) // 3
        d = laws.driver[e]
        value[d] = _horner(laws.data[start : start + m], t)
        rate[d] = _horner(laws.data[start + m : start + 2 * m], t)
        acceleration[d] = _horner(laws.data[start + 2 * m : start + 3 * m], t)


@njit(inline="always", **_JIT)
def _evaluate_spline(laws, first, stop, t, value, rate, acceleration):
    """scipy's ``PPoly`` evaluation (`_ppoly.evaluate_poly1`), same operation order."""
    for e in range(first, stop):
        start = laws.start[e]
        m = (laws.start[e + 1] - start - 1) // 5  # intervals
        x = laws.data[start : start + m + 1]
        c = laws.data[start + m + 1 : start + 5 * m + 1]  # (4, m) row by row
        # the interval i with x[i] <= t < x[i + 1]; the end ones beyond the range
        low, high = 0, m - 1
        while low < high:
            middle = (low + high + 1) // 2
            if t >= x[middle]:
                low = middle
            else:
                high = middle - 1
        s = t - x[low]
        c3, c2, c1, c0 = c[3 * m + low], c[2 * m + low], c[m + low], c[low]  # c_k multiplies s^k
        d = laws.driver[e]
        value[d] = c3 + c2 * s + c1 * (s * s) + c0 * (s * s * s)
        rate[d] = c2 * 1.0 * 1.0 + c1 * s * 2.0 + c0 * (s * s) * 3.0
        acceleration[d] = c1 * 1.0 * 2.0 + c0 * s * 6.0


@njit(inline="always", **_JIT)
def _evaluate_laws(laws, t, value, rate, acceleration):
    """Value, first and second time derivative of every driver's law at time t."""
    k = laws.kind_first
    _evaluate_harmonic(laws, k[0], k[1], t, value, rate, acceleration)
    _evaluate_linear(laws, k[1], k[2], t, value, rate, acceleration)
    _evaluate_polynomial(laws, k[2], k[3], t, value, rate, acceleration)
    _evaluate_spline(laws, k[3], k[4], t, value, rate, acceleration)


# ---------------------------------------------------------------------- the loop
class _Geometry(NamedTuple):
    """The arrays of a `ConstraintPattern` the loop reads, with the weights of the rows."""

    coincidence_body_i: np.ndarray
    coincidence_body_j: np.ndarray
    coincidence_local_i: np.ndarray
    coincidence_local_j: np.ndarray
    coincidence_row: np.ndarray
    coincidence_slots: np.ndarray
    projection_body_i: np.ndarray
    projection_body_j: np.ndarray
    projection_local_i: np.ndarray
    projection_local_j: np.ndarray
    projection_direction: np.ndarray
    projection_row: np.ndarray
    projection_slots: np.ndarray
    difference_plus: np.ndarray
    difference_minus: np.ndarray
    difference_row: np.ndarray
    difference_slots: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray
    target: np.ndarray
    driver_row: np.ndarray
    weights: np.ndarray
    initial_coordinates: np.ndarray


def _pack_geometry(pattern: ConstraintPattern, weights: np.ndarray) -> _Geometry:
    """Contiguous arrays of fixed dtypes, so that one compiled loop serves every model."""
    integer = lambda array: np.ascontiguousarray(array, dtype=np.int64)  # noqa: E731
    real = lambda array: np.ascontiguousarray(array, dtype=np.float64)  # noqa: E731
    p = pattern
    return _Geometry(
        integer(p.coincidence_body_i), integer(p.coincidence_body_j),
        real(p.coincidence_local_i.reshape(-1, 2)), real(p.coincidence_local_j.reshape(-1, 2)),
        integer(p.coincidence_row), integer(p.coincidence_slots.reshape(-1, 8)),
        integer(p.projection_body_i), integer(p.projection_body_j),
        real(p.projection_local_i.reshape(-1, 2)), real(p.projection_local_j.reshape(-1, 2)),
        real(p.projection_direction.reshape(-1, 2)), integer(p.projection_row),
        integer(p.projection_slots.reshape(-1, 6)),
        integer(p.difference_plus), integer(p.difference_minus), integer(p.difference_row),
        integer(p.difference_slots.reshape(-1, 2)),
        integer(p.indptr), integer(p.indices), real(p.target), integer(p.driver_row), real(weights),
        real(p.initial_coordinates),
    )  # fmt: skip


@njit(inline="always", **_JIT)
def _fill_residual_jacobian(g, q, turns, target, residual, jac_data):
    """Residual and CSR Jacobian values at q (ground appended); returns the weighted norm.

    The norm is NaN when any residual entry is not finite.  `turns` receives the cos and
    sin of every body's angle at q.
    """
    _kernels.fill_body_turns(q, turns)
    _kernels.fill_point_coincidence(
        q, turns, g.coincidence_body_i, g.coincidence_body_j, g.coincidence_local_i, g.coincidence_local_j,
        g.coincidence_row, g.coincidence_slots, residual, jac_data,
    )  # fmt: skip
    _kernels.fill_projected_distance(
        q, turns, g.projection_body_i, g.projection_body_j, g.projection_local_i, g.projection_local_j,
        g.projection_direction, g.projection_row, g.projection_slots, residual, jac_data,
    )  # fmt: skip
    _kernels.fill_coordinate_difference(
        q, g.difference_plus, g.difference_minus, g.difference_row, g.difference_slots, residual, jac_data
    )
    norm = 0.0
    for r in range(residual.size):
        residual[r] -= target[r]
        weighted = abs(residual[r]) * g.weights[r]
        if not math.isfinite(weighted):
            return np.nan
        if weighted > norm:
            norm = weighted
    return norm


@njit(inline="always", **_JIT)
def _factor_jacobian(g, jac_data, lu, pivots):
    """Scatter the CSR values into the dense `lu` and factor it; False if singular."""
    lu[:] = 0.0
    for r in range(lu.shape[0]):
        for s in range(g.indptr[r], g.indptr[r + 1]):
            lu[r, g.indices[s]] = jac_data[s]
    return dense_lu_factor(lu, pivots)


@njit(inline="always", **_JIT)
def _solved(lu, pivots, b):
    """Solve in place; False if the solution is not finite."""
    dense_lu_solve(lu, pivots, b)
    for value in b:
        if not math.isfinite(value):
            return False
    return True


@njit(inline="always", **_JIT)
def _solve_positions(g, q, turns, target, tolerance, max_iterations, chord, residual, jac_data, lu, pivots, counts):
    """Newton from q (ground appended), refined in place; returns (corrections, status).

    Plain Newton (``chord`` False) follows `sparsekin.solvers._solve_positions` step for
    step.  Chord Newton solves with the factorization already in `lu` and gives up
    (`_CHORD_REJECTED`, or any failure) when a correction contracts too little; once it
    converges, one last Newton correction with the fresh factorization polishes q unless
    the residual is already below ``POLISH_BELOW * tolerance``.  On
    success `lu` holds the factorization of the Jacobian at the converged q (before that
    last correction, which moves q by less than the tolerance).
    ``counts`` accumulates (factorizations, solves).
    """
    n = lu.shape[0]
    previous_norm = np.inf
    for iteration in range(max_iterations + 1):
        norm = _fill_residual_jacobian(g, q, turns, target, residual, jac_data)
        if not math.isfinite(norm):
            return iteration, _RESIDUAL_NOT_FINITE
        converged = norm <= tolerance
        if chord and not converged and iteration > 0 and norm > CHORD_CONTRACTION * previous_norm:
            return iteration, _CHORD_REJECTED
        if converged or not chord:
            counts[0] += 1
            if not _factor_jacobian(g, jac_data, lu, pivots):
                return iteration, _SINGULAR
        if converged:
            if chord and iteration > 0 and norm > POLISH_BELOW * tolerance:
                # Chord corrections converge linearly and stop anywhere below the tolerance:
                # one Newton correction with the fresh factorization takes q to full accuracy,
                # as plain Newton's quadratic convergence does.
                counts[1] += 1
                if not _solved(lu, pivots, residual):
                    return iteration, _SINGULAR
                for c in range(n):
                    q[c] -= residual[c]
                return iteration + 1, _SOLVED
            return iteration, _SOLVED
        if iteration == max_iterations:
            break
        if iteration >= 3 and norm > _STALL_RATIO * previous_norm:
            return iteration, _STALLED
        previous_norm = norm
        counts[1] += 1
        if not _solved(lu, pivots, residual):
            return iteration, _SINGULAR
        for c in range(n):
            q[c] -= residual[c]
    return max_iterations, _NOT_CONVERGED


@njit(**_JIT)
def _run_time_loop(
    g, laws, times, tolerance, max_iterations, chord, coordinates, velocities, accelerations, iterations
):
    """Every sample in turn; returns (n_solved, status, n_factorizations, n_solves, n_restarts)."""
    n = g.initial_coordinates.size
    n_drivers = g.driver_row.size
    q = np.zeros(n + 3)  # the ground appended as a body of zeros
    qd = np.zeros(n + 3)
    turns = np.zeros((n // 3 + 1, 2))  # cos and sin of each body's angle, the ground last
    predictor = np.empty(n)
    residual = np.empty(n)
    jac_data = np.zeros(g.indptr[n] + 1)  # one discard slot for the ground's columns
    lu = np.empty((n, n))
    pivots = np.zeros(n, dtype=np.int64)
    target = g.target.copy()
    velocity_rhs = np.zeros(n)
    target_acceleration = np.zeros(n)
    gamma = np.zeros(n)  # rows of coordinate differences stay zero
    rhs = np.empty(n)
    value = np.empty(n_drivers)
    rate = np.empty(n_drivers)
    acceleration = np.empty(n_drivers)
    counts = np.zeros(2, dtype=np.int64)  # factorizations, solves
    n_restarts = 0
    for k in range(times.size):
        t = times[k]
        if k == 0:
            for c in range(n):
                predictor[c] = g.initial_coordinates[c]
        else:  # Taylor predictor, same operation order as the Python path
            h = t - times[k - 1]
            half_h2 = 0.5 * h * h
            for c in range(n):
                predictor[c] = (velocities[k - 1, c] * h + coordinates[k - 1, c]) + (
                    half_h2 * accelerations[k - 1, c]
                )
        _evaluate_laws(laws, t, value, rate, acceleration)
        for d in range(n_drivers):
            r = g.driver_row[d]
            target[r] = value[d]
            velocity_rhs[r] = rate[d]
            target_acceleration[r] = acceleration[d]

        # Chord Newton first (not at the first sample: no factorization yet), and on any
        # failure plain Newton from the predictor again.
        corrections, status = 0, _CHORD_REJECTED
        for attempt in range(1 if k == 0 or not chord else 2):
            for c in range(n):
                q[c] = predictor[c]
            use_chord = attempt == 0 and chord and k > 0
            corrections, status = _solve_positions(
                g, q, turns, target, tolerance, max_iterations, use_chord, residual, jac_data, lu, pivots, counts
            )
            if status == _SOLVED:
                break
            n_restarts += use_chord
        if status != _SOLVED:
            return k, status, counts[0], counts[1], n_restarts

        # Phi_q qd = -Phi_t, then Phi_q qdd = gamma + target'', with the factorization at q.
        for r in range(n):
            rhs[r] = velocity_rhs[r]
        counts[1] += 1
        if not _solved(lu, pivots, rhs):
            return k, _SINGULAR, counts[0], counts[1], n_restarts
        for c in range(n):
            qd[c] = rhs[c]
        _kernels.fill_body_turns(q, turns)  # q moved by the last correction
        _kernels.fill_point_coincidence_gamma(
            q, qd, turns, g.coincidence_body_i, g.coincidence_body_j, g.coincidence_local_i, g.coincidence_local_j,
            g.coincidence_row, gamma,
        )  # fmt: skip
        _kernels.fill_projected_distance_gamma(
            q, qd, turns, g.projection_body_i, g.projection_body_j, g.projection_local_i, g.projection_local_j,
            g.projection_direction, g.projection_row, gamma,
        )  # fmt: skip
        for r in range(n):
            rhs[r] = gamma[r] + target_acceleration[r]
        counts[1] += 1
        if not _solved(lu, pivots, rhs):
            return k, _SINGULAR, counts[0], counts[1], n_restarts
        for c in range(n):
            coordinates[k, c] = q[c]
            velocities[k, c] = qd[c]
            accelerations[k, c] = rhs[c]
        iterations[k] = corrections
    return times.size, _SOLVED, counts[0], counts[1], n_restarts


def solve_compiled(
    mechanism: Mechanism,
    pattern: ConstraintPattern,
    times: np.ndarray,
    tolerance: float,
    max_iterations: int,
    weights: np.ndarray,
    coordinates: np.ndarray,
    velocities: np.ndarray,
    accelerations: np.ndarray,
    iterations: np.ndarray,
    *,
    chord: bool = True,
) -> CompiledOutcome:
    """Positions, velocities and accelerations at every time, in one compiled loop.

    The semantics are those of `sparsekin.solve_kinematics`; the caller validates
    `times`, `tolerance` and `max_iterations` as it does, and owns the output arrays,
    which are filled in place.  See the module docstring for what happens at a sample
    that cannot be solved.

    Parameters
    ----------
    mechanism : Mechanism
        Its laws must pass `supports_compiled`.
    pattern : ConstraintPattern
        ``build_pattern(mechanism)``, with as many equations as coordinates.
    times : ndarray, shape (n_times,)
        Strictly increasing sample times, s.
    tolerance : float
        Largest accepted weighted residual.
    max_iterations : int
        Most Newton corrections at one time.
    weights : ndarray, shape (n_equations,)
        Weight of each residual row in the convergence test: 1 on angle rows,
        ``1 / pattern.length_scale`` on the others.
    coordinates, velocities, accelerations : ndarray of float64, shape (n_times, n_coordinates)
        Filled with q, qd and qdd, C-contiguous.
    iterations : ndarray of int64, shape (n_times,)
        Filled with the Newton corrections at each time (those of the attempt that
        converged: chord corrections, or plain Newton's after a restart).
    chord : bool
        Try chord Newton first (see the module docstring); False runs plain Newton at
        every sample, with the Python path's iterates and counts.

    Returns
    -------
    CompiledOutcome

    Examples
    --------
    >>> import numpy as np
    >>> from sparsekin.pattern import build_pattern
    >>> from sparsekin.testset import task5
    >>> mechanism = task5()
    >>> pattern = build_pattern(mechanism)
    >>> times = np.linspace(0.0, 1.0, 101)
    >>> q, qd, qdd = (np.empty((times.size, pattern.n_coordinates)) for _ in range(3))
    >>> counts = np.empty(times.size, dtype=np.int64)
    >>> weights = np.where(pattern.row_is_angle, 1.0, 1.0 / pattern.length_scale)
    >>> outcome = solve_compiled(mechanism, pattern, times, 1e-12, 12, weights, q, qd, qdd, counts)
    >>> outcome.n_solved, outcome.status.name
    (101, 'SOLVED')
    """
    if not supports_compiled(mechanism):
        pack_laws(mechanism, pattern.driver_initial)  # raises, naming the driver
    n_times, n_coordinates = np.shape(times)[0], pattern.n_coordinates
    if pattern.n_equations != n_coordinates:
        raise ValueError(
            f"`pattern` must have as many equations as coordinates ({n_coordinates}), "
            f"got {pattern.n_equations}."
        )
    _check_array(times, "times", (n_times,), np.float64)
    _check_array(weights, "weights", (n_coordinates,), np.float64)
    outputs = {"coordinates": coordinates, "velocities": velocities, "accelerations": accelerations}
    for name, array in outputs.items():
        _check_array(array, name, (n_times, n_coordinates), np.float64)
    _check_array(iterations, "iterations", (n_times,), np.int64)
    n_solved, status, n_factorizations, n_solves, n_restarts = _run_time_loop(
        _pack_geometry(pattern, weights), pack_laws(mechanism, pattern.driver_initial), times,
        float(tolerance), int(max_iterations), bool(chord),
        coordinates, velocities, accelerations, iterations,
    )  # fmt: skip
    return CompiledOutcome(
        int(n_solved), LoopStatus(status), int(n_factorizations), int(n_solves), int(n_restarts)
    )


def _check_array(array, name: str, shape: tuple[int, ...], dtype) -> None:
    if not isinstance(array, np.ndarray) or array.shape != shape or array.dtype != dtype:
        got = f"{array.dtype} {array.shape}" if isinstance(array, np.ndarray) else type(array).__name__
        raise ValueError(f"`{name}` must be a {np.dtype(dtype)} array of shape {shape}, got {got}.")
    if not array.flags.c_contiguous or not array.flags.writeable:
        raise ValueError(f"`{name}` must be C-contiguous and writeable.")
