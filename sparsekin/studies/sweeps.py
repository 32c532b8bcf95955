"""Design sweeps on Dask: many variants of one mechanism, each an independent analysis.

The data flow:

1. `VariantSet` describes the variants: a grid of parameter values by path (the
   cartesian product of its axes; several paths on one axis take the same values
   together) and, for a tolerance study, random samples in which every point's drawn
   position moves by a normal deviation.  It is the one description both
   `sparsekin.sweep` and ``sparsekin sweep`` use (`VariantSet.from_arguments` reads the
   command-line spelling).
2. `VariantSet.bind` checks it against a mechanism (`VariantDesign`): every path names a
   parameter, every value is allowed, and variant k's mechanism is a copy of the nominal
   one with its values (`VariantDesign.variant`).
3. The variants go to Dask in tasks of consecutive variants (`task_ranges`).  A task
   solves its variants one after the other with `sparsekin.solve_kinematics`; variants
   that only change law parameters share one constraint pattern, and every task after a
   worker's first finds the numba code compiled.  A variant that locks up is a result:
   status ``singular`` and its times.
4. The client writes each task's block of variants into the output as the task finishes
   (memory, or the Zarr store ``sweep.zarr``, region by region), so that no process holds
   more than a few tasks' results.  `SweepResult` is what comes back.

Steps 1 and 2 live in `sparsekin.studies.variants`, the outputs and `SweepResult` in
`sparsekin.studies.stores`; this module runs the tasks (step 3) and exports all of them.

Parameter paths (`PATH_FORMS`), relative to the model:

=====================================  ================================================
``drivers[i].law.KEY``                 parameter KEY of the law of the model's driver i
``drivers.NAME.law.KEY``               the same, driver by name (``law_x``, ``law_y``
                                       for a path driver)
``points.NAME``                        drawn position of a point, (x, y), m
``points.NAME.x``, ``points.NAME.y``   one coordinate of it, m
``bodies.NAME.mass``, ``.inertia``     a body's mass (kg) and inertia (kg·m²)
``bodies.NAME.velocity.vx`` (``vy``,   a component of its initial velocity (forward
``omega``)                             dynamics), m/s or rad/s
``loads[i].KEY``, ``loads.NAME.KEY``   a number of load i (``stiffness``, ``damping``,
                                       ``free_angle``, a number ``value`` …)
``loads[i].value.KEY``                 parameter KEY of the law of load i's value
``units.UNIT.drivers[i].law.KEY``      a repeated unit's parameter: every copy takes it
``units.UNIT.points.NAME`` (``.x``,    (a repeat's own ``vary`` still applies on top)
``.y``)
=====================================  ================================================

>>> import numpy as np
>>> import sparsekin as sk
>>> design = sk.VariantSet({("drivers[0].law.amplitude", "drivers[1].law.amplitude"): np.linspace(0.03, 0.07, 9)})
>>> design.n_variants, design.columns
(9, ('drivers[0].law.amplitude', 'drivers[1].law.amplitude'))
>>> sk.VariantSet.from_arguments(["drivers[0].law.amplitude=0.04:0.06:3", "points.M.x=0.18:0.22:5"]).n_variants
15
"""


from __future__ import annotations

import math
import os
import time
import warnings

import numpy as np

from ..errors import ConvergenceError, ModelError, SingularJacobianError
from ..model.mechanism import Mechanism
from ..results.motion import Motion
from ..results.schema import COORDINATE_VARIABLES, result_arrays, result_fields
from .stores import (
    STATUS_DTYPE,
    STATUSES,
    SweepResult,
    _layout,
    _MemoryOutput,
    _ZarrOutput,
    write_variants_csv,
)
from .variants import PATH_FORMS, VariantDesign, VariantSet, resolve_path

__all__ = [
    "VariantSet",
    "VariantDesign",
    "SweepResult",
    "sweep",
    "write_variants_csv",
    "task_ranges",
    "STATUSES",
    "DISTRIBUTED_EXTRA",
    "PATH_FORMS",
    "resolve_path",
]

#: What to install for sweeps, and the one line that says so.
DISTRIBUTED_EXTRA = 'sweeps need dask and distributed: pip install "sparsekin[distributed]"'
#: Tasks per worker thread when the size of a task is not given: enough for the load to
#: balance and for a lost worker to cost little, few enough that each task amortises its
#: pattern and its Dask overhead (about a millisecond) over many variants.
TASKS_PER_THREAD = 4
#: Most bytes of results one task returns (its variants' arrays together).
TASK_BYTES = 256 * 2**20
#: Tasks submitted but not yet written, per worker thread: one running, one waiting.
PENDING_PER_THREAD = 2
#: What a sweep's variants can be: kinematic runs, or forward-dynamics runs.
ANALYSES = ("kinematics", "dynamics")


def task_ranges(
    n_variants: int, n_threads: int, bytes_per_variant: int, variants_per_task: int | None = None
):
    """``(first, stop)`` of each task's variants.

    Without `variants_per_task`: `TASKS_PER_THREAD` tasks per worker thread, each at most
    `TASK_BYTES` of results.

    >>> task_ranges(10, 1, 1000)
    [(0, 3), (3, 6), (6, 9), (9, 10)]
    """
    if variants_per_task is None:
        variants_per_task = math.ceil(n_variants / (TASKS_PER_THREAD * max(1, n_threads)))
        variants_per_task = max(1, min(variants_per_task, TASK_BYTES // max(1, bytes_per_variant)))
    return [
        (first, min(first + variants_per_task, n_variants))
        for first in range(0, n_variants, variants_per_task)
    ]


def solve_variants(design: VariantDesign, first: int, stop: int, times: np.ndarray, options: dict) -> dict:
    """Solve variants ``first … stop - 1`` one after the other: a task's work.

    `options` are the keywords of each variant's run, and ``analysis``: ``"kinematics"``
    (`sparsekin.solve_kinematics`) or ``"dynamics"`` (`sparsekin.solve_dynamics`).
    Returns a dict: ``status`` (str array), ``t_stop``, ``t_failure`` (s, NaN when not
    applicable), ``messages`` (list of str) and the recorded arrays (``q``, ``qd``,
    ``qdd``, ``points``, ``joints``, ``forces``, and for dynamics ``energy`` and
    ``drift``), each of shape (stop - first, n_times, ...), NaN after a variant's last
    solved sample.
    """
    from ..engine.discretization import discretize
    from ..results.recording import Selection

    n, n_times = stop - first, times.size
    mechanism = design.mechanism
    nominal = discretize(mechanism)
    solve, dynamic = _variant_solver(options)
    selection = Selection(nominal, options["coordinates"], options["points"], options["joints"], options["forces"],
                          energy=dynamic)  # fmt: skip
    shapes = selection.sample_shapes()
    arrays = {key: np.full((n, n_times, *shape), np.nan) for key, shape in shapes.items()}
    status = np.full(n, "", dtype=STATUS_DTYPE)
    t_stop, t_failure = np.full(n, np.nan), np.full(n, np.nan)
    messages = [""] * n
    shared = None if design.geometry_varies else nominal.constraints
    for row, k in enumerate(range(first, stop)):
        result, notes = None, []
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                variant = design.variant(k)
                result = solve(variant, times, shared)
                status[row] = "complete"
            except SingularJacobianError as error:
                status[row], result, t_failure[row] = "singular", error.result, error.time
                notes.append(str(error))
            except ConvergenceError as error:
                status[row], result, t_failure[row] = "no_convergence", error.result, error.time
                notes.append(str(error))
            except ModelError as error:
                status[row] = "invalid"
                notes.append(str(error))
        notes += [str(warning.message) for warning in caught]
        messages[row] = " | ".join(" ".join(note.split()) for note in notes)
        if result is not None and result.n_times:
            m = result.n_times
            t_stop[row] = result.times[-1]
            for name, source in result_arrays(result).items():
                if name in arrays:
                    arrays[name][row, :m] = source
    return {"status": status, "t_stop": t_stop, "t_failure": t_failure, "messages": messages, **arrays}


def _variant_solver(options: dict):
    """``(solve, dynamic)``: ``solve(variant, times, pattern)`` runs one variant's analysis
    with the run's keywords of `options` (its ``analysis`` names the analysis; `pattern`, a
    constraint pattern the variants share or None, serves the kinematics)."""
    keywords = dict(options)
    if keywords.pop("analysis", "kinematics") == "dynamics":
        from ..solve.dynamics import solve_dynamics

        return (lambda variant, times, pattern: solve_dynamics(variant, times, **keywords)), True
    from ..solve.kinematics import solve_kinematics

    return (lambda variant, times, pattern: solve_kinematics(variant, times, pattern=pattern, **keywords)), False


def sweep(
    mechanism: Mechanism,
    vary,
    times,
    client=None,
    *,
    workers: int | None = None,
    store=None,
    coordinates: bool = True,
    points=None,
    joints=None,
    forces="auto",
    quasi_static: bool = False,
    variants_per_task: int | None = None,
    tolerance: float | None = None,
    max_iterations: int | None = None,
    linear_solver: str = "auto",
    progress=None,
    analysis: str | None = None,
    max_step: float | None = None,
    rho_inf: float | None = None,
    rtol: float | None = None,
) -> SweepResult:
    """Solve every variant of `mechanism` that `vary` describes, on Dask.

    Each variant is an independent `sparsekin.solve_kinematics` run at `times` (or, for
    forward dynamics, a `sparsekin.solve_dynamics` run: see `analysis`).  The
    variants are split into tasks of consecutive variants (`task_ranges`); the client
    writes each task's results as it arrives, into memory or into the Zarr store `store`,
    so no process holds every variant's results when there is a store.  A variant that
    locks up is a result (status ``singular``), not a failure of the sweep.

    Parameters
    ----------
    mechanism : Mechanism
        The nominal mechanism.
    vary : VariantSet or mapping
        The variants; a mapping is ``VariantSet(grid=vary)``: path (or tuple of paths
        varied together) -> values.
    times : array_like, shape (n_times,)
        Sample times of every variant, s.
    client : distributed.Client or str, optional
        The Dask client, or a scheduler's address (``"tcp://host:8786"``).  Default: a
        local cluster of `workers` processes, started here and closed at the end.
    workers : int, optional
        Worker processes of the local cluster (default: one per core).
    store : str or path-like, optional
        Write the results to this Zarr store (replaced if it exists): variables
        ``q``, ``qd``, ``qdd`` (variant, time, coordinate), ``points`` (variant, time,
        point, component), ``joints`` (variant, time, joint, derivative), and per variant
        ``parameters`` (variant, parameter), ``status``, ``t_stop``, ``t_failure``; for
        forward dynamics also ``energy`` (variant, time, energy_term) and ``drift``
        (variant, time, drift_term), and the attributes ``analysis``, ``max_step``,
        ``rho_inf`` and ``rtol`` (None for fixed steps).  Default: in memory.
    coordinates, points, joints, forces, quasi_static
        What each variant records, as in `solve_kinematics` (variable ``forces``
        (variant, time, force) in the store).
    variants_per_task : int, optional
        Variants per Dask task (default: `TASKS_PER_THREAD` tasks per worker thread).
    tolerance, max_iterations, linear_solver
        As in `solve_kinematics` (`tolerance` and `linear_solver` as in `solve_dynamics`
        for forward dynamics; `max_iterations` and `quasi_static` are the kinematics').
    progress : callable, optional
        Called as ``progress(variants_done, n_variants)`` as results arrive.
    analysis : {"kinematics", "dynamics"}, optional
        What each variant's run is; default: the model's ``[analysis] type``.
    max_step, rho_inf, rtol : float, optional
        Forward dynamics only: as in `solve_dynamics` (defaults: the model's
        ``analysis.max_step``, else the shortest interval of `times`; 0.9; the model's
        ``analysis.rtol``, else fixed steps).  A variant whose step fails after halving is
        a result (status ``no_convergence``).

    Returns
    -------
    SweepResult

    Raises
    ------
    ModelError
        For a path that names no parameter, or a value it does not take.
    ValueError
        For an argument `solve_kinematics` (`solve_dynamics`) would refuse (times outside a spline law's
        range, an unknown point, a bad tolerance ...): raised before any task is
        submitted.  An exception raised later comes from a task that failed (not a
        variant: those are results) and stops the sweep.
    ImportError
        Without dask and distributed (``pip install "sparsekin[distributed]"``).

    Examples
    --------
    >>> import numpy as np, sparsekin as sk
    >>> task5 = sk.load_model("examples/task5.toml")
    >>> amplitudes = {("drivers[0].law.amplitude", "drivers[1].law.amplitude"): [0.05, 0.06]}
    >>> result = sk.sweep(task5, amplitudes, np.linspace(0.0, 1.0, 101), workers=1, coordinates=False,
    ...                   points=["K"])  # doctest: +SKIP
    >>> result.status.tolist(), result.t_stop.tolist()  # doctest: +SKIP
    (['complete', 'singular'], [1.0, 0.75])
    """
    try:
        import distributed
    except ImportError:
        raise ImportError(DISTRIBUTED_EXTRA) from None
    from ..engine.discretization import discretize
    from ..solve.options import Request, check_times

    if not isinstance(mechanism, Mechanism):
        raise TypeError(f"`mechanism` must be a Mechanism, got {type(mechanism).__name__}.")
    variants = vary if isinstance(vary, VariantSet) else VariantSet(vary)
    design = variants.bind(mechanism)
    times = check_times(times, mechanism)
    if progress is not None and not callable(progress):
        raise ValueError(f"`progress` must be a callable (done, total), got {progress!r}.")
    if variants_per_task is not None and (isinstance(variants_per_task, bool) or int(variants_per_task) < 1):
        raise ValueError(f"`variants_per_task` must be a whole number >= 1, got {variants_per_task!r}.")
    # every argument a task would refuse is refused here, before a cluster starts
    options, attrs = _run_options(mechanism, times, analysis, tolerance, max_iterations, linear_solver, quasi_static,
                                  max_step, rho_inf, rtol)  # fmt: skip
    dynamic = options["analysis"] == "dynamics"
    selection = Request(coordinates, points, joints, forces, quasi_static, energy=dynamic).selection(discretize(mechanism))
    chosen = selection.forces
    options |= dict(coordinates=bool(coordinates), points=selection.point_names or None,
                    joints=list(selection.joint_indices) or None,
                    forces=None if chosen is None else [*(f"drivers[{d}]" for d in chosen.driver_indices),
                                                        *(f"joints[{j}]" for j in chosen.joint_indices)])  # fmt: skip
    layout = _layout(design, times, selection)
    own_cluster = None
    if client is None:
        own_cluster = _local_cluster(workers)
        client = distributed.Client(own_cluster)
    elif isinstance(client, str):
        client = own_cluster = distributed.Client(client)
    try:
        # Client.nthreads asks the scheduler for every worker (scheduler_info()["workers"]
        # lists at most five in distributed 2025.4 … 2026.6: dask/distributed#9045)
        n_threads = sum(client.nthreads().values()) or 1
        bytes_per_variant = 8 * times.size * sum(int(np.prod(shape)) for shape in layout.shapes.values())
        ranges = task_ranges(design.n_variants, n_threads, bytes_per_variant, variants_per_task)
        size = ranges[0][1] - ranges[0][0]
        attrs = {"model": mechanism.name, "grid": list(variants.paths), "samples": variants.samples,
                 "perturb_points": -1.0 if variants.perturb_points is None else variants.perturb_points,
                 "seed": str(variants.seed), **attrs}  # fmt: skip
        output = _ZarrOutput(store, layout, size, attrs) if store is not None else _MemoryOutput(layout)
        status = np.full(design.n_variants, "", dtype=STATUS_DTYPE)
        t_stop, t_failure = np.full(design.n_variants, np.nan), np.full(design.n_variants, np.nan)
        messages = [""] * design.n_variants
        start = time.perf_counter()
        for first, stop, block in _run_tasks(client, design, ranges, times, options, n_threads):
            output.write(first, stop, block)
            status[first:stop], t_stop[first:stop], t_failure[first:stop] = (block["status"], block["t_stop"],
                                                                             block["t_failure"])  # fmt: skip
            messages[first:stop] = block["messages"]
            if progress is not None:
                progress(int(np.count_nonzero(status)), design.n_variants)
        wall_time = time.perf_counter() - start
    finally:
        if own_cluster is not None:
            client.close()
            own_cluster.close()
    arrays = output.close()
    return SweepResult(
        variants=variants, columns=layout.columns, parameters=layout.parameters, status=status, t_stop=t_stop,
        t_failure=t_failure, messages=tuple(messages), times=times, **result_fields(arrays, options["analysis"]),
        analysis=options["analysis"],
        recorded_points=selection.point_names, recorded_joints=selection.joint_labels,
        force_labels=selection.force_labels, force_units=selection.force_units,
        store=output.path, n_tasks=len(ranges), wall_time=wall_time,
        coordinate_labels=tuple(layout.labels.get("coordinate", ())), labels=layout.labels,
        motion=_sweep_motion(selection, times, arrays, status, design.geometry_varies),
    )  # fmt: skip


def _run_options(mechanism: Mechanism, times: np.ndarray, analysis, tolerance, max_iterations, linear_solver,
                 quasi_static, max_step, rho_inf, rtol=None) -> tuple[dict, dict]:  # fmt: skip
    """``(options, attrs)``: each variant's checked run keywords (with ``analysis``, as
    `solve_variants` takes them) and what the store's attributes say of the analysis; a
    ValueError for an argument that the analysis would refuse or does not take."""
    from ..engine.newton import DEFAULT_TOLERANCE, NEWTON_MAXITER
    from ..solve.dynamics import DEFAULT_TOLERANCE as DYNAMICS_TOLERANCE
    from ..solve.dynamics import MAX_ITERATIONS
    from ..solve.options import DynamicsOptions, SolveOptions

    if analysis is None:
        analysis = mechanism.analysis.type
    if analysis not in ANALYSES:
        raise ValueError(f"`analysis` must be one of {', '.join(map(repr, ANALYSES))}, got {analysis!r}.")
    if analysis == "kinematics":
        if max_step is not None or rho_inf is not None or rtol is not None:
            raise ValueError('`max_step`, `rho_inf` and `rtol` are for forward dynamics: give analysis="dynamics" (or a '
                             'model with [analysis] type = "dynamics").')  # fmt: skip
        checked = SolveOptions(DEFAULT_TOLERANCE if tolerance is None else tolerance,
                               NEWTON_MAXITER if max_iterations is None else max_iterations, linear_solver)  # fmt: skip
        return dict(analysis=analysis, linear_solver=linear_solver, quasi_static=bool(quasi_static),
                    tolerance=checked.tolerance, max_iterations=checked.max_iterations), {"analysis": analysis}  # fmt: skip
    for name, value in (("max_iterations", max_iterations), ("quasi_static", quasi_static or None)):
        if value is not None:
            raise ValueError(f"`{name}` is for kinematic sweeps; forward dynamics takes `max_step`, `rho_inf`, `rtol` "
                             "and `tolerance`.")  # fmt: skip
    checked = SolveOptions(DYNAMICS_TOLERANCE if tolerance is None else tolerance, MAX_ITERATIONS, linear_solver)
    dynamics = DynamicsOptions(max_step, *(() if rho_inf is None else (rho_inf,)), rtol=rtol)
    options = dict(analysis=analysis, linear_solver=linear_solver, tolerance=checked.tolerance,
                   max_step=dynamics.max_step, rho_inf=dynamics.rho_inf, rtol=dynamics.rtol)  # fmt: skip
    chosen = dynamics.for_run(times, mechanism)
    return options, {"analysis": analysis, "max_step": chosen.max_step, "rho_inf": dynamics.rho_inf,
                     "rtol": chosen.rtol}  # fmt: skip


def _sweep_motion(selection, times: np.ndarray, arrays: dict, status: np.ndarray, geometry_varies: bool) -> Motion:
    """The sweep's recorded motion with the variant first (see `SweepResult.motion`)."""
    fields = result_fields(arrays)
    if geometry_varies:  # each variant has its own drawing: nothing derived from the coordinates
        fields |= {v.attribute: None for v in COORDINATE_VARIABLES}
    return Motion(times=times, complete=bool(np.all(status == "complete")), point_map=selection.discretization.points,
                  mechanism=selection.mechanism, recorded_points=selection.point_names,
                  recorded_joints=selection.joint_indices, force_labels=selection.force_labels,
                  force_units=selection.force_units, **fields)  # fmt: skip


def default_worker_count() -> int:
    """Worker processes of a local cluster when none is given: one per core this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _local_cluster(workers: int | None):
    """A local cluster: the scheduler in this process, `workers` single-threaded worker processes."""
    import logging

    from distributed import LocalCluster

    if workers is None:
        workers = default_worker_count()
    if isinstance(workers, bool) or int(workers) < 1:
        raise ValueError(f"`workers` must be a whole number >= 1, got {workers!r}.")
    return LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True, dashboard_address=":0",
                        silence_logs=logging.ERROR)  # fmt: skip


def _run_tasks(client, design: VariantDesign, ranges, times, options, n_threads: int):
    """Submit the tasks a few at a time and yield ``(first, stop, block)`` as they finish.

    At most `PENDING_PER_THREAD` tasks per worker thread are submitted and not yet
    written: the workers' memory holds a few tasks' results, never the sweep's.  A task
    whose worker dies is run again by the scheduler on another worker.
    """
    from distributed import as_completed

    pending_limit = PENDING_PER_THREAD * n_threads + 1
    queue = list(ranges)
    queue.reverse()
    completed = as_completed()
    futures: dict = {}  # key -> (future, first, stop)
    token = f"{os.getpid():x}-{time.monotonic_ns():x}"

    def submit() -> None:
        first, stop = queue.pop()
        future = client.submit(solve_variants, design, first, stop, times, options, pure=False,
                               key=f"sparsekin-variants-{first}-{stop}-{token}")  # fmt: skip
        futures[future.key] = (future, first, stop)
        completed.add(future)

    try:
        while queue and len(futures) < pending_limit:
            submit()
        for future in completed:
            _, first, stop = futures.pop(future.key)
            block = future.result()  # a task that failed (not a variant: those are results) stops the sweep
            future.release()
            yield first, stop, block
            while queue and len(futures) < pending_limit:
                submit()
    finally:
        if futures:  # stopped early (an error, Ctrl-C): the remaining tasks are not wanted
            client.cancel([future for future, _, _ in futures.values()])
