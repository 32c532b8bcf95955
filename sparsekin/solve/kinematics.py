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
one numba call first and hands over to the stepper at any sample it cannot solve.  The run
driver of `sparsekin.solve.run` drives either (`sparsekin.solve.steppers`);
`run_kinematics` below is the layer under the facade, on arguments checked once
(`sparsekin.solve.options`), with the linear solver planned once (`sparsekin.solve.policy`).

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

from ..analysis.assemble import start_discretization
from ..engine.discretization import Discretization, discretize
from ..engine.newton import DEFAULT_TOLERANCE, NEWTON_MAXITER
from ..engine.pattern import ConstraintPattern
from ..errors import LimitWarning, warn_caller
from ..model.mechanism import Mechanism
from ..results.kinematics import KinematicsResult, PointMotion
from ..results.recording import MemorySink, Recorder, ZarrSink
from ..results.schema import FORCES, TIME, result_fields
from ._compiled import CompiledKinematicLoop
from .observers import InverseDynamics, LimitWatch, RecordedVariables
from .options import Request, SolveOptions, check_times
from .policy import plan_linear_solver
from .run import run
from .stepper import KinematicStepper
from .steppers import FallbackStepper, SampleBlock, SampleSteps, StillStepper

__all__ = ["KinematicsResult", "PointMotion", "solve_kinematics", "run_kinematics"]


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
        rad; within `sparsekin.solve.options.TOLERANCE_RANGE`.
    max_iterations : int
        Most Newton corrections at one time before it converges, at least 1 (a chord
        Newton's final polishing correction, `sparsekin.engine.newton`, comes on top).
    linear_solver : {"auto", "dense", "refactor", "superlu"}
        How the linear systems are solved (see the module docstring).  ``"auto"`` takes
        ``"dense"`` (the compiled loop) up to `COMPILED_MAX_COORDINATES` coordinates and
        ``"refactor"`` above, unless the refactorization's fill-in exceeds
        `~sparsekin.solve.policy.MAX_REFACTOR_FILL`: then SuperLU with chord Newton.  Every
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
    times = check_times(times, mechanism)
    options = SolveOptions(tolerance, max_iterations, linear_solver)
    if progress is not None and not callable(progress):
        raise ValueError(f"`progress` must be a callable (done, total), got {progress!r}.")
    request = Request(coordinates, points, joints, forces, quasi_static)
    return run_kinematics(discretize(mechanism, pattern), times, options, request, store=store, progress=progress)


def run_kinematics(discretization: Discretization, times: np.ndarray, options: SolveOptions = SolveOptions(),
                   request: Request = Request(), *, store=None, progress=None) -> KinematicsResult:  # fmt: skip
    """`solve_kinematics` on arguments checked already: the layer under the facade.

    Parameters
    ----------
    discretization : Discretization
        The mechanism's arrays (`sparsekin.engine.discretization.discretize`).
    times : ndarray
        From `sparsekin.solve.options.check_times`.
    options : SolveOptions
        How to solve: tolerance, Newton corrections, linear solver, the thresholds of
        ``"auto"`` (`sparsekin.solve.policy.Thresholds`) and the branch guard.
    request : Request
        What to record.
    store, progress
        As for `solve_kinematics`.

    Returns
    -------
    KinematicsResult
    """
    # Start from the drawing assembled at the first time, on its branch (issue 27: rough
    # drawings with exact lengths, copies drawn at another phase of their driver).
    discretization = start_discretization(discretization, float(times[0]))
    selection = request.selection(discretization)
    plan = plan_linear_solver(discretization, options.linear_solver, options.thresholds)
    sink = ZarrSink(store, selection, times.size) if store is not None else MemorySink(selection, times.size)
    recorder = Recorder(selection, sink, request.chunk_samples)
    pattern = discretization.constraints
    observer = None
    if pattern.n_equations == 0 and pattern.n_coordinates == 0:  # nothing to solve
        stepper = StillStepper()
    else:
        python = KinematicStepper(discretization, options=options, forces=selection.forces is not None)
        if selection.forces is not None:
            observer = InverseDynamics(discretization, selection.forces, bool(request.quasi_static),
                                       options.thresholds.min_norm_iterations)  # fmt: skip
        if plan.loop == "compiled":
            compiled_forces = None if observer is None else observer.compiled()
            stepper = FallbackStepper(CompiledKinematicLoop(discretization, options, recorder.size, compiled_forces),
                                      python)  # fmt: skip
        else:
            stepper = SampleSteps(python)
    variables, limits = RecordedVariables(selection), LimitWatch(discretization)

    def record(block: SampleBlock) -> None:
        forces = block.recorded.get(FORCES)
        if observer is not None and forces is None:
            forces = observer(block.linearization)[None]
        limits.watch(block.times, block.coordinates)
        recorder.add_block(block.times, variables.block(block.coordinates, block.velocities, block.accelerations, forces))

    def finish(state) -> KinematicsResult:
        return _result(discretization, recorder, stepper.stats(), state.iterations, times.size,
                       observer is not None and not observer.inertial)  # fmt: skip

    try:
        return run(stepper, times, record, finish, progress=progress, chunk=recorder.size)
    finally:
        for state in limits.crossings:
            warn_caller(f"{state.label} left its limits: {state.quantity} {state.value:.6g} {state.unit} at "
                        f"t = {state.time:.6g} s, outside [{state.limits[0]:g}, {state.limits[1]:g}]",
                        LimitWarning)  # fmt: skip


def _result(discretization, recorder: Recorder, stats, iterations, n_times: int, quasi_static: bool) -> KinematicsResult:
    """The result of the samples recorded (it closes the recorder)."""
    arrays = recorder.finish()
    n_solved = arrays[TIME].shape[0]  # every sample recorded has its iterations
    selection = recorder.selection
    return KinematicsResult(
        times=np.asarray(arrays[TIME]),
        **result_fields(arrays),
        newton_iterations=iterations[:n_solved],
        n_factorizations=stats.n_factorizations,
        n_solves=stats.n_solves,
        complete=n_solved == n_times,
        point_map=discretization.points,
        mechanism=discretization.mechanism,
        n_subdivisions=stats.n_subdivisions,
        redundant_equations=stats.redundant_equations,
        n_refactorizations=stats.n_refactorizations,
        linear_solver=stats.path,
        recorded_points=selection.point_names,
        recorded_joints=selection.joint_indices,
        force_labels=selection.force_labels,
        force_units=selection.force_units,
        quasi_static=quasi_static,
        store=getattr(recorder.sink, "path", None),
    )

