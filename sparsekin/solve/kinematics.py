"""Kinematic analysis: `solve_kinematics` validates, runs the time loop, returns the result.

At each time t the positions q solve Phi(q, t) = 0 by Newton–Raphson from a Taylor
predictor built on the previous sample.  The factorization of the Jacobian Phi_q at the
converged position then serves two more solves:

    Phi_q · qd  = -Phi_t        (velocities)
    Phi_q · qdd = gamma         (accelerations)

When the model has masses or loads (or when asked, ``forces=``), the same factorization
serves one more, transposed, solve for the forces that hold the motion
(`sparsekin.engine.forces`):

    Phi_q^T · lam = Q - M qdd - h   (Lagrange multipliers: driver forces, joint reactions)

Convergence is judged on the residual, lengths relative to the size of the model (so a
chain 10^4 m long converges as surely as a 1 m linkage) and angles in radians.  The loop
itself is `sparsekin.solve.stepper.KinematicStepper` (predictor, Newton, branch guard, step
halving, lock-up diagnosis); for small models `sparsekin.solve._compiled` runs the same loop in
one numba call first and hands over to the stepper at any sample it cannot solve.

Linear solvers (the `linear_solver` argument; ``"auto"`` picks the fastest):

* ``"dense"`` — for small models, the whole time loop compiled with numba on a dense LU;
  a model it cannot run (a law of another kind, redundant equations) and any sample it
  cannot solve go to the Python loop with `DenseSolver`.
* ``"refactor"`` — `RefactorSolver`: the ordering and the L and U patterns are fixed by a
  first SuperLU factorization, every later factorization is a numeric refactorization.
* ``"superlu"`` — a fresh SuperLU factorization at every Newton iteration.

With ``"refactor"`` and ``"dense"`` the Newton corrections are *chord* corrections (see
`sparsekin.engine.newton`).  Every path factors the Jacobian at the converged position, so
velocities and accelerations are solved with the Jacobian there, to the same accuracy.
"""

from __future__ import annotations

import numpy as np

from ..engine.forces import ForceSolver, build_load_pattern
from ..engine.newton import DEFAULT_TOLERANCE, NEWTON_MAXITER
from ..engine.pattern import ConstraintPattern, build_pattern, build_point_map, per_element
from ..errors import AnalysisInterrupted, LimitWarning, SparsekinError, warn_caller
from ..model.laws import Spline
from ..model.mechanism import Mechanism
from ..results.kinematics import KinematicsResult, PointMotion
from ..results.recording import MemorySink, Recorder, Selection, ZarrSink
from ._compiled import CompiledForces, solve_compiled, supports_compiled
from .stepper import (
    COMPILED_MAX_COORDINATES,
    LINEAR_SOLVERS,
    KinematicStepper,
    checked_max_iterations,
    checked_tolerance,
    first_branch_jump,
)

__all__ = ["KinematicsResult", "PointMotion", "solve_kinematics"]


def solve_kinematics(
    mechanism: Mechanism,
    times,
    *,
    tolerance: float = DEFAULT_TOLERANCE,
    max_iterations: int = NEWTON_MAXITER,
    linear_solver: str = "auto",
    coordinates: bool = True,
    points=None,
    joints=None,
    forces="auto",
    quasi_static: bool = False,
    store=None,
    progress=None,
    pattern: ConstraintPattern | None = None,
) -> KinematicsResult:
    """Positions, velocities and accelerations of `mechanism` at `times`.

    Parameters
    ----------
    mechanism : Mechanism
        A mechanism whose equations (joints and drivers) control every coordinate.  It
        may have more equations than coordinates if the surplus are redundant and
        consistent: they are left out, with a `RedundantConstraintWarning`.
    times : array_like, shape (n_times,)
        Strictly increasing, finite sample times, s.  The first sample starts Newton
        from the initial configuration of the model.
    tolerance : float
        Largest accepted residual: lengths relative to the size of the model, angles in
        rad; within `sparsekin.solve.stepper.TOLERANCE_RANGE`.
    max_iterations : int
        Most Newton corrections at one time before it converges, at least 1 (a chord
        Newton's final polishing correction, `sparsekin.engine.newton`, comes on top).
    linear_solver : {"auto", "dense", "refactor", "superlu"}
        How the linear systems are solved (see the module docstring).  ``"auto"`` takes
        ``"dense"`` (the compiled loop) up to `COMPILED_MAX_COORDINATES` coordinates and
        ``"refactor"`` above, unless the refactorization's fill-in exceeds
        `~sparsekin.solve.stepper.MAX_REFACTOR_FILL`: then SuperLU with chord Newton.  Every
        choice gives the same results to rounding.
    coordinates : bool
        Keep every body's coordinates, velocities and accelerations (the default); then
        any point's motion and any joint's coordinate can be derived from the result.
    points : None, "all" or sequence of str
        Points whose motion is recorded while the run goes on (needed when `coordinates`
        is False: a long run of a large model keeps only what it needs).
    joints : None, "all" or sequence of str
        Joints whose own coordinate (angle, stroke, slide) is recorded while the run goes on.
    forces : "auto", None, "all" or sequence of str
        Drivers and joints whose forces are computed and recorded: each driver's force (or
        torque) and power, each joint's reaction (`KinematicsResult.driver_force`,
        `~KinematicsResult.reaction`).  "auto" (the default): all of them when the model
        has a mass or a load (`Mechanism.has_forces`), none otherwise.
    quasi_static : bool
        Forces without the inertial forces: what holds the mechanism still in each
        configuration (gravity and loads only).
    store : str or path-like, optional
        Stream what is recorded to this Zarr store, chunk by chunk (``pip install
        "sparsekin[zarr]"``): memory then holds a chunk, not the run.  The result reads
        from the store; ``result.to_xarray()`` opens it lazily.
    progress : callable, optional
        Called as ``progress(samples_done, n_times)`` while the run goes on.
    pattern : ConstraintPattern, optional
        ``build_pattern(m)`` of a mechanism ``m`` with the same bodies, joints, drivers and
        drawing as `mechanism` (only the parameters of driver laws may differ): a sweep
        over law parameters builds it once for many variants.  Default: built here.
        Checked against `mechanism`: the same numbers of bodies and of equations per joint
        and driver, and the same drawn body frames.

    Returns
    -------
    KinematicsResult

    Raises
    ------
    TypeError, ValueError
        If an argument is not of the expected type, shape or range.
    AnalysisInterrupted
        On Ctrl-C (a `KeyboardInterrupt`): ``interrupt.result`` holds the samples solved,
        all written to the store if there is one.
    ModelError
        If the mechanism's equations do not control every coordinate at the first sample
        (free motions, a driver that the joints already fix, a drawing at a singular
        configuration), or its redundant equations contradict each other or involve
        drivers.
    SingularConfigurationError
        If the mechanism reaches a singular configuration (a lock-up, a dead centre):
        ``error.result`` holds the samples before it.
    ConvergenceError
        If a sample cannot be solved for another reason; ``error.result`` holds the
        samples before it.

    Warns
    -----
    RedundantConstraintWarning
        When redundant equations are left out (with forces: the reactions of a redundant
        set are not unique; the minimum-norm ones are given).
    LimitWarning
        Once for each element with ``limits`` whose own coordinate leaves them, at the
        first sample outside.

    Notes
    -----
    Any error raised once the time loop has begun leaves the samples solved before it in
    the store (if there is one); a `SparsekinError` also carries them in ``error.result``.

    Examples
    --------
    >>> from sparsekin import Body, Mechanism, Revolute, RotationalDriver, Linear
    >>> crank = Mechanism(
    ...     points={"O": (0.0, 0.0), "A": (0.1, 0.0)},
    ...     bodies=[Body("crank", origin="O", points=("O", "A"))],
    ...     joints=[Revolute(("crank", "ground"), at="O")],
    ...     drivers=[RotationalDriver(("crank", "ground"), law=Linear(rate=2.0))],
    ... )
    >>> result = solve_kinematics(crank, times=[0.0, 0.5])
    >>> result.point("A").velocity[1].round(6).tolist()  # 0.2 m/s, perpendicular to the crank at 1 rad
    [-0.168294, 0.10806]
    """
    if not isinstance(mechanism, Mechanism):
        raise TypeError(f"`mechanism` must be a Mechanism, got {type(mechanism).__name__}.")
    times = _checked_times(times, mechanism)
    tolerance = checked_tolerance(tolerance)
    max_iterations = checked_max_iterations(max_iterations)
    if linear_solver not in LINEAR_SOLVERS:
        raise ValueError(f"`linear_solver` must be one of {', '.join(map(repr, LINEAR_SOLVERS))}, got {linear_solver!r}.")
    if progress is not None and not callable(progress):
        raise ValueError(f"`progress` must be a callable (done, total), got {progress!r}.")
    if not isinstance(quasi_static, (bool, np.bool_)):
        raise ValueError(f"`quasi_static` must be True or False, got {quasi_static!r}.")
    if pattern is None:
        pattern = build_pattern(mechanism)
    else:
        _check_pattern(pattern, mechanism)
    selection = Selection(mechanism, coordinates, points, joints, forces, pattern=pattern)
    n = pattern.n_coordinates
    if pattern.n_equations == 0 and n == 0:  # nothing to solve: every sample is the empty configuration
        stepper = None
    else:
        stepper = KinematicStepper(
            mechanism, linear_solver=linear_solver, tolerance=tolerance, max_iterations=max_iterations, pattern=pattern,
            forces=selection.forces is not None,
        )  # fmt: skip
    sink = ZarrSink(store, selection, times.size) if store is not None else MemorySink(selection, times.size)
    force_solver = None
    if selection.forces is not None and stepper is not None:
        force_solver = ForceSolver(pattern, build_load_pattern(mechanism), selection.forces, bool(quasi_static))
    run = _Run(mechanism, stepper, times, Recorder(selection, sink), progress, force_solver)
    compiled = (
        stepper is not None
        and (linear_solver == "dense" or (linear_solver == "auto" and n <= COMPILED_MAX_COORDINATES))
        and pattern.n_equations == n
        and supports_compiled(mechanism)
    )
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # non-finite values are checked
            result = run.solve(compiled)
    finally:
        for state in run.recorder.limit_crossings:
            warn_caller(f"{state.label} left its limits: {state.quantity} {state.value:.6g} {state.unit} at "
                        f"t = {state.time:.6g} s, outside [{state.limits[0]:g}, {state.limits[1]:g}]",
                        LimitWarning)  # fmt: skip
    return result


class _Run:
    """One run: the stepper (or the compiled loop, chunk by chunk) feeding a recorder."""

    def __init__(self, mechanism, stepper: KinematicStepper | None, times: np.ndarray, recorder: Recorder,
                 progress, force_solver: ForceSolver | None = None) -> None:  # fmt: skip
        self.mechanism, self.stepper, self.times, self.recorder = mechanism, stepper, times, recorder
        self.progress, self.force_solver = progress, force_solver
        self.iterations = np.zeros(times.size, dtype=np.int64)
        self.compiled_counts = np.zeros(2, dtype=np.int64)  # factorizations and solves of the compiled loop
        self.path = stepper.path if stepper is not None else "none"
        self._first = None  # (t, q) of the first sample: the reference of the lock-up diagnosis
        self._last = None  # (t, q, qd, qdd) of the last sample solved by the compiled loop
        self._result = None

    def solve(self, compiled: bool) -> KinematicsResult:
        """Solve every sample; on any error the samples recorded so far are kept (in the
        store too) and become the ``result`` of the error (`AnalysisInterrupted` on Ctrl-C)."""
        stepper, times = self.stepper, self.times
        try:
            if stepper is None:
                empty = np.zeros(0)
                no_forces = np.zeros(self.recorder.selection.n_force_columns)
                for k in range(times.size):
                    self.recorder.add(times[k], empty, empty, empty, no_forces)
                return self.result()
            k = self._solve_compiled() if compiled else 0
            if k == 0:
                self.iterations[0] = stepper.start(times[0])
                self._record(0)
                k = 1
            elif k < times.size:
                stepper.resume(*self._last, first=self._first)
            for k in range(k, times.size):
                self.iterations[k] = stepper.advance(times[k])
                self._record(k)
        except BaseException as error:
            result = self._result_after(error)
            if isinstance(error, KeyboardInterrupt) and result is not None:
                raise AnalysisInterrupted(result) from None
            if isinstance(error, SparsekinError):
                error.result = result
            raise
        return self.result()

    def _result_after(self, error: BaseException) -> KinematicsResult | None:
        """The samples recorded before `error`, or None (with a note on `error`) if they
        cannot be written: the error that stopped the run is the one raised."""
        try:
            return self.result()
        except Exception as failure:  # best effort: `error` is the one raised
            error.add_note(f"the samples solved before this error could not be kept: {failure!r}")
            return None

    def _record(self, k: int) -> None:
        stepper = self.stepper
        forces = None if self.force_solver is None else self.force_solver.evaluate(stepper)
        self.recorder.add(self.times[k], stepper.coordinates, stepper.velocities, stepper.accelerations, forces)
        if self.progress is not None:
            self.progress(k + 1, self.times.size)

    def _solve_compiled(self) -> int:
        """Run the compiled loop chunk by chunk; the samples it solved that pass the branch guard.

        Each chunk starts from the last sample of the one before (row 0 of its arrays), so
        that the progress is reported and an interrupt is taken between chunks.
        """
        stepper, times = self.stepper, self.times
        size = min(self.recorder.size, times.size)
        n = stepper.pattern.n_coordinates
        rows = [np.empty((size + 1, n)) for _ in range(3)]
        iterations = np.zeros(size + 1, dtype=np.int64)
        chunk_times = np.empty(size + 1)
        forces = None
        if self.force_solver is not None:
            solver = self.force_solver
            forces = CompiledForces(solver.loads.arrays, solver.loads.laws, solver.loads.n_laws, solver.outputs.arrays(),
                                    solver.inertial, np.zeros((size + 1, solver.outputs.n_columns)))  # fmt: skip
        done = 0
        while done < times.size:
            start = 0 if done == 0 else 1  # row 0: the previous sample
            m = min(size + 1 - start, times.size - done)
            chunk_times[start : start + m] = times[done : done + m]
            if start:
                chunk_times[0] = self._last[0]
                for array, state in zip(rows, self._last[1:]):
                    array[0] = state
            stop = start + m
            outcome = solve_compiled(
                stepper.mechanism, stepper.pattern, chunk_times[:stop], stepper.tolerance, stepper.max_iterations,
                rows[0][:stop], rows[1][:stop], rows[2][:stop], iterations[:stop], start=start,
                forces=None if forces is None else forces._replace(rows=forces.rows[:stop]),
                laws=stepper.assembler.laws.table,
            )  # fmt: skip
            self.compiled_counts += (outcome.n_factorizations, outcome.n_solves)
            solved = first_branch_jump(chunk_times, *rows, stepper.pattern.coordinate_weights, outcome.n_solved)
            new = solved - start
            if new > 0:
                self.iterations[done : done + new] = iterations[start:solved]
                self.recorder.add_block(chunk_times[start:solved], *(array[start:solved] for array in rows),
                                        None if forces is None else forces.rows[start:solved])  # fmt: skip
                if done == 0:
                    self._first = (chunk_times[0], rows[0][0].copy())
                self._last = (chunk_times[solved - 1], *(array[solved - 1].copy() for array in rows))
                done += new
                if self.progress is not None:
                    self.progress(done, times.size)
            if solved < stop:  # the Python loop takes over (and diagnoses)
                self.path = "compiled+dense"
                return done
        self.path = "compiled"
        return done

    def result(self) -> KinematicsResult:
        """The result of the samples recorded (once: it closes the recorder)."""
        if self._result is not None:
            return self._result
        arrays = self.recorder.finish()
        n_solved = arrays["t"].shape[0]  # every sample recorded has its iterations
        stepper, mechanism = self.stepper, self.mechanism
        selection = self.recorder.selection
        counts = (0, 0, 0) if stepper is None else (stepper.n_factorizations, stepper.n_solves, stepper.n_refactorizations)
        path = self.path if self.path.startswith("compiled") or stepper is None else stepper.path
        self._result = KinematicsResult(
            times=np.asarray(arrays["t"]),
            coordinates=arrays.get("q"),
            velocities=arrays.get("qd"),
            accelerations=arrays.get("qdd"),
            newton_iterations=self.iterations[:n_solved],
            n_factorizations=counts[0] + int(self.compiled_counts[0]),
            n_solves=counts[1] + int(self.compiled_counts[1]),
            complete=n_solved == self.times.size,
            point_map=build_point_map(mechanism),
            mechanism=mechanism,
            n_subdivisions=0 if stepper is None else stepper.n_subdivisions,
            redundant_equations=() if stepper is None else tuple(stepper.diagnosis.label(r) for r in stepper.redundant_rows),
            n_refactorizations=counts[2],
            linear_solver=path,
            recorded_points=selection.point_names,
            point_tracks=arrays.get("points"),
            recorded_joints=selection.joint_indices,
            joint_tracks=arrays.get("joints"),
            force_labels=() if selection.forces is None else selection.forces.labels,
            force_units=() if selection.forces is None else selection.forces.units,
            force_tracks=arrays.get("forces"),
            quasi_static=self.force_solver is not None and not self.force_solver.inertial,
            store=getattr(self.recorder.sink, "path", None),
        )
        return self._result


def _checked_times(times, mechanism: Mechanism) -> np.ndarray:
    try:  # issue 28: complex, text and bool times were cast to floats
        dtype = np.asarray(times).dtype if not isinstance(times, (str, bytes)) else np.dtype(str)
    except (TypeError, ValueError):
        dtype = np.dtype(object)  # ragged: refused below
    if dtype.kind in "bcSUV":
        raise ValueError(f"`times` must be an array of numbers, got {type(times).__name__} of {dtype} values.")
    try:
        array = np.array(times, dtype=float)  # a copy, C-contiguous: the compiled loop reads it
    except (TypeError, ValueError):
        raise ValueError(f"`times` must be an array of numbers, got {type(times).__name__}.") from None
    if array.ndim != 1 or array.size == 0:
        raise ValueError(f"`times` must be a non-empty 1-D array, got shape {array.shape}.")
    if not np.all(np.isfinite(array)):
        raise ValueError("`times` must be finite.")
    if np.any(np.diff(array) <= 0.0):
        raise ValueError("`times` must be strictly increasing.")
    for kind in ("drivers", "loads"):
        for element in mechanism.declared(kind):
            laws = element.laws()
            if kind == "drivers":
                names = element.law_fields
            else:  # a load's components: its value, or value[c] of a force's (fx, fy)
                names = ("value",) if len(laws) == 1 else tuple(f"value[{c}]" for c in range(len(laws)))
            for name, law in zip(names, laws):
                if isinstance(law, Spline):
                    first, last = law.time_range
                    if array[0] < first or array[-1] > last:
                        raise ValueError(
                            f"`times` span [{array[0]:g}, {array[-1]:g}] s but the {name} of {kind[:-1]} "
                            f"{element.describe()!r}, a spline, is defined on [{first:g}, {last:g}] s."
                        )
    return array


def _check_pattern(pattern, mechanism: Mechanism) -> None:
    """`pattern` must be that of a mechanism with the bodies, equations and drawing of `mechanism`."""
    if not isinstance(pattern, ConstraintPattern):
        got = type(pattern).__name__
        raise ValueError(f"`pattern` must be a ConstraintPattern (build_pattern), got {got}.")
    if (pattern.n_bodies, pattern.n_equations) != (mechanism.n_bodies, mechanism.n_equations):
        why = (f"it has {pattern.n_bodies} bodies and {pattern.n_equations} equations, `mechanism` "
               f"{mechanism.n_bodies} and {mechanism.n_equations}")  # fmt: skip
    else:
        counts = np.concatenate([per_element(mechanism, kind, lambda element: element.n_equations)
                                 for kind in ("joints", "drivers")])  # fmt: skip
        if counts.size + 1 != pattern.element_first_row.size or not np.array_equal(
            np.diff(pattern.element_first_row), counts
        ):  # fmt: skip
            why = "its joints and drivers have other numbers of equations"
        elif not np.array_equal(pattern.initial_coordinates, mechanism.frames().ravel()):
            why = "its bodies are drawn elsewhere"
        else:
            return
    raise ValueError(f"`pattern` must be the ConstraintPattern of a mechanism like `mechanism`: {why}.")
