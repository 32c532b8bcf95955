"""The forward-dynamics benchmarks of issue 25 built in Exudyn, a peer for comparison only.

Exudyn (``pip install "sparsekin[peers]"``, pinned at 1.13.6) is not used by sparsekin or by its
tests: this module is imported lazily and only by hand (benchmarks/peers/README.md has the
commands and the figures).  Each model is the one of examples/dynamics/*.toml, in Exudyn's
planar elements: ``NodeRigidBody2D`` + ``ObjectRigidBody2D`` with the node at the centre of
mass (so that its mass matrix is diagonal), ``ObjectJointRevolute2D`` between
``MarkerBodyPosition`` markers, gravity as a ``LoadForceVector`` at each centre of mass, and
Exudyn's implicit generalized-alpha integrator (index 3, its default spectral radius 0.9, its
modified Newton) with the Eigen sparse LU (``LinearSolverType.EigenSparse``).  The pendulum's
point mass is ``NodePoint2D`` + ``ObjectMassPoint2D`` held by ``ObjectConnectorDistance``.

Errors are measured against tests/dynamics_reference.py (exact or published answers).

Command line (one measurement per process, printed as one JSON line)::

    python3 benchmarks/peers/exudyn_models.py accuracy a02 --step 1e-3
    python3 benchmarks/peers/exudyn_models.py timing chain --bodies 1001 --steps 20
    python3 benchmarks/peers/exudyn_models.py table   # every figure of the README, ~12 min

``timing`` reports the time per step (the median over ``--repeat`` solves) and the process's
peak resident memory (``resource.getrusage``), which is why ``table`` runs each measurement in
its own subprocess.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
GRAVITY = 9.81


def import_exudyn():
    """exudyn and its item interface, or one line saying how to install them."""
    try:
        import exudyn
        import exudyn.itemInterface as items
    except ImportError:
        raise SystemExit('the peer benchmarks need Exudyn: pip install "sparsekin[peers]"') from None
    return exudyn, items


def import_reference():
    sys.path.insert(0, str(ROOT / "tests"))
    import dynamics_reference

    return dynamics_reference


@dataclass
class PeerModel:
    """An assembled Exudyn system and the sensors that read the benchmark's outputs.

    ``sensors`` maps an output name to an Exudyn sensor index; ``angle_offsets`` maps an
    angle output to its reference angle (a 2D node's coordinate is relative to it).
    """

    container: object
    system: object
    n_bodies: int
    sensors: dict = field(default_factory=dict)
    angle_offsets: dict = field(default_factory=dict)


class PlanarBuilder:
    """Rigid bodies at their centres of mass, revolutes at global points, gravity, outputs."""

    def __init__(self, gravity: float = GRAVITY):
        self.exudyn, self.items = import_exudyn()
        self.container = self.exudyn.SystemContainer()
        self.system = self.container.AddSystem()
        self.ground = self.system.AddObject(self.items.ObjectGround(referencePosition=[0.0, 0.0, 0.0]))
        self.gravity = gravity
        self.frames: list[tuple[np.ndarray, float]] = []
        self.bodies: list[int] = []
        self.nodes: list[int] = []
        self.model = PeerModel(self.container, self.system, 0)

    def body(self, com, angle: float, mass: float, inertia: float, velocity=(0.0, 0.0, 0.0)) -> int:
        """A rigid body with its centre of mass at `com` (global, m), turned by `angle` (rad),
        moving at `velocity` = (vx, vy) of the centre of mass and the angular velocity."""
        node = self.system.AddNode(
            self.items.NodeRigidBody2D(
                referenceCoordinates=[com[0], com[1], angle], initialVelocities=list(velocity)
            )
        )
        body = self.system.AddObject(
            self.items.ObjectRigidBody2D(mass=mass, inertia=inertia, nodeNumber=node)
        )
        if self.gravity and mass:
            centre = self.system.AddMarker(
                self.items.MarkerBodyPosition(bodyNumber=body, localPosition=[0, 0, 0])
            )
            self.system.AddLoad(
                self.items.LoadForceVector(markerNumber=centre, loadVector=[0, -mass * self.gravity, 0])
            )
        self.frames.append((np.asarray(com, dtype=float), angle))
        self.bodies.append(body)
        self.nodes.append(node)
        self.model.n_bodies += 1
        return len(self.bodies) - 1

    def marker(self, body: int | None, point) -> int:
        """A position marker at the global point `point` (initial configuration) of `body`
        (None: the ground)."""
        if body is None:
            return self.system.AddMarker(
                self.items.MarkerBodyPosition(bodyNumber=self.ground, localPosition=[point[0], point[1], 0.0])
            )
        return self.system.AddMarker(
            self.items.MarkerBodyPosition(
                bodyNumber=self.bodies[body], localPosition=[*self.local(body, point), 0.0]
            )
        )

    def local(self, body: int, point) -> np.ndarray:
        com, angle = self.frames[body]
        c, s = np.cos(angle), np.sin(angle)
        return np.array([[c, s], [-s, c]]) @ (np.asarray(point, dtype=float) - com)

    def revolute(self, body_i: int, body_j: int | None, point) -> None:
        self.system.AddObject(
            self.items.ObjectJointRevolute2D(
                markerNumbers=[self.marker(body_i, point), self.marker(body_j, point)]
            )
        )

    def point_output(self, name: str, body: int, point) -> None:
        """Sensors for the position and velocity of a body's point."""
        for suffix, variable in (("position", "Position"), ("velocity", "Velocity")):
            self.model.sensors[f"{name}.{suffix}"] = self.system.AddSensor(
                self.items.SensorBody(
                    bodyNumber=self.bodies[body],
                    localPosition=[*self.local(body, point), 0.0],
                    storeInternal=True,
                    writeToFile=False,
                    outputVariableType=getattr(self.exudyn.OutputVariableType, variable),
                )
            )

    def angle_output(self, name: str, body: int) -> None:
        self.model.sensors[name] = self.system.AddSensor(
            self.items.SensorNode(
                nodeNumber=self.nodes[body],
                storeInternal=True,
                writeToFile=False,
                outputVariableType=self.exudyn.OutputVariableType.Coordinates,
            )
        )
        self.model.angle_offsets[name] = self.frames[body][1]

    def assembled(self) -> PeerModel:
        self.system.Assemble()
        return self.model


def build_pendulum(length: float = 1.0, mass: float = 1.0) -> PeerModel:
    """A01: a point mass at (L, 0) held at distance L from the origin, released from rest."""
    builder = PlanarBuilder()
    exudyn, items, system = builder.exudyn, builder.items, builder.system
    node = system.AddNode(items.NodePoint2D(referenceCoordinates=[length, 0.0]))
    point = system.AddObject(items.ObjectMassPoint2D(physicsMass=mass, nodeNumber=node))
    on_mass = system.AddMarker(items.MarkerBodyPosition(bodyNumber=point, localPosition=[0, 0, 0]))
    system.AddLoad(items.LoadForceVector(markerNumber=on_mass, loadVector=[0, -mass * GRAVITY, 0]))
    system.AddObject(
        items.ObjectConnectorDistance(
            markerNumbers=[builder.marker(None, (0.0, 0.0)), on_mass], distance=length
        )
    )
    for suffix, variable in (("position", "Position"), ("velocity", "Velocity")):
        builder.model.sensors[f"P.{suffix}"] = system.AddSensor(
            items.SensorNode(
                nodeNumber=node,
                storeInternal=True,
                writeToFile=False,
                outputVariableType=getattr(exudyn.OutputVariableType, variable),
            )
        )
    builder.model.n_bodies = 1
    return builder.assembled()


def build_n_four_bar(n_loops: int = 40) -> PeerModel:
    """A02 (and the chain at scale): N + 1 cranks pinned at (k, 0), N couplers, uniform bars of
    1 m and 1 kg, cranks vertical, B0 at (1, 0) m/s; outputs B0 (the tip of crank 0)."""
    builder = PlanarBuilder()
    inertia = 1.0 / 12.0
    cranks = [builder.body((k, 0.5), np.pi / 2, 1.0, inertia, (0.5, 0.0, -1.0)) for k in range(n_loops + 1)]
    for k, crank in enumerate(cranks):
        builder.revolute(crank, None, (k, 0.0))
    for k in range(1, n_loops + 1):
        coupler = builder.body((k - 0.5, 1.0), 0.0, 1.0, inertia, (1.0, 0.0, 0.0))
        builder.revolute(coupler, cranks[k - 1], (k - 1, 1.0))
        builder.revolute(coupler, cranks[k], (k, 1.0))
    builder.point_output("B0", cranks[0], (0.0, 1.0))
    return builder.assembled()


def build_andrews() -> PeerModel:
    """A03 from the reference geometry (tests/dynamics_reference.py, ``andrews_geometry``): the
    same points, centres of mass, masses, inertias, revolutes, spring and torque as
    examples/dynamics/andrews.toml; outputs the seven body angles."""
    reference = import_reference()
    geometry = reference.andrews_geometry()
    builder = PlanarBuilder(gravity=0.0)
    items, system = builder.items, builder.system
    index = {}
    for name, body in geometry["bodies"].items():
        index[name] = builder.body(body["com"], body["angle"], body["mass"], body["inertia"])
        builder.angle_output(name, index[name])
    for body_i, body_j, point in geometry["joints"]:
        builder.revolute(
            index[body_i], None if body_j == "ground" else index[body_j], geometry["points"][point]
        )
    spring = geometry["spring"]
    ends = [
        builder.marker(None if body == "ground" else index[body], geometry["points"][point])
        for body, point in zip(spring["bodies"], spring["points"])
    ]
    system.AddObject(
        items.ObjectConnectorSpringDamper(
            markerNumbers=ends,
            stiffness=spring["stiffness"],
            referenceLength=spring["free_length"],
            damping=0.0,
        )
    )
    crank = builder.bodies[index[geometry["torque"]["body"]]]
    rigid = system.AddMarker(items.MarkerBodyRigid(bodyNumber=crank, localPosition=[0, 0, 0]))
    system.AddLoad(items.LoadTorqueVector(markerNumber=rigid, loadVector=[0, 0, geometry["torque"]["value"]]))
    return builder.assembled()


#: Task 5 round trip: horizon (s) and the sampling of the inverse-dynamics forces (s).
TASK5_HORIZON, TASK5_FORCE_SAMPLING = 0.5, 1e-3


def task5_inverse_dynamics():
    """sparsekin's kinematic run of examples/task5_dynamics.toml over TASK5_HORIZON: the
    driver forces that hold the prescribed strokes (inverse dynamics), and the motion."""
    from sparsekin import load_model, solve_kinematics

    mechanism = load_model(ROOT / "examples" / "task5_dynamics.toml")
    times = np.arange(0.0, TASK5_HORIZON + TASK5_FORCE_SAMPLING / 2, TASK5_FORCE_SAMPLING)
    return solve_kinematics(mechanism, times)


def build_task5(kinematics=None) -> PeerModel:
    """Task 5 with masses (examples/task5_dynamics.toml, read with tomllib) with its two drivers
    removed and each replaced by an actuator force along its cylinder (N on the cylinder to M on
    the rod, and H to G): sparsekin's inverse-dynamics driver force, a C2 cubic spline through
    its 1 ms samples, applied by a spring-damper of zero stiffness whose force user function
    returns -F(t) (Exudyn's force is positive in tension; the driver's pushes the points apart).
    The initial velocities are the kinematic run's at t = 0.  Outputs K, the tool point.
    The forward motion must come back to the kinematic one within the integrator's error.
    """
    import tomllib

    from scipy.interpolate import CubicSpline

    kinematics = task5_inverse_dynamics() if kinematics is None else kinematics
    document = tomllib.loads((ROOT / "examples" / "task5_dynamics.toml").read_text())
    points = {name: np.asarray(xy, dtype=float) for name, xy in document["points"].items()}
    builder = PlanarBuilder(gravity=-document["gravity"][1])
    items, system = builder.items, builder.system
    index = {}
    names = list(kinematics.body_names)
    for name, body in document["bodies"].items():
        k = names.index(name)
        origin, rate = kinematics.coordinates[0, 3 * k : 3 * k + 2], kinematics.velocities[0, 3 * k + 2]
        com = np.asarray(points[body["com"]] if isinstance(body["com"], str) else body["com"], dtype=float)
        lever = com - origin
        velocity = kinematics.velocities[0, 3 * k : 3 * k + 2] + rate * np.array([-lever[1], lever[0]])
        index[name] = builder.body(
            com, body.get("angle", 0.0), body["mass"], body["inertia"], (*velocity, rate)
        )
    for joint in document["joints"]:
        body_i, body_j = (None if name == "ground" else index[name] for name in joint["bodies"])
        if joint["type"] == "revolute":
            builder.revolute(body_i, body_j, points[joint["at"]])
            continue
        start, end = (points[name] for name in joint["axis"])  # translational: axis from P (on i) to Q (on j)
        axis = (end - start) / np.hypot(*(end - start))
        rigid = [
            system.AddMarker(
                items.MarkerBodyRigid(
                    bodyNumber=builder.bodies[body], localPosition=[*builder.local(body, point), 0.0]
                )
            )
            for body, point in ((body_i, start), (body_j, end))
        ]
        local_axis, local_normal = (
            builder.local(body, builder.frames[body][0] + vector)
            for body, vector in ((body_i, axis), (body_j, np.array([-axis[1], axis[0]])))
        )
        system.AddObject(
            items.ObjectJointPrismatic2D(
                markerNumbers=rigid,
                axisMarker0=[*local_axis, 0.0],
                normalMarker1=[*local_normal, 0.0],
                constrainRotation=True,
            )
        )
        driver = next(d for d in document["drivers"] if d["joint"] == joint["name"])
        force = CubicSpline(kinematics.times, kinematics.driver_force(driver["name"]).force)

        def actuator(_system, t, _item, _stretch, _rate, _stiffness, _damping, _force, law=force):
            return -float(law(t))

        system.AddObject(
            items.ObjectConnectorSpringDamper(
                markerNumbers=[builder.marker(body_i, start), builder.marker(body_j, end)],
                referenceLength=float(np.hypot(*(end - start))),
                springForceUserFunction=actuator,
            )
        )
    for load in document.get("loads", ()):
        marker = builder.marker(index[load["body"]], points[load["at"]])
        system.AddLoad(items.LoadForceVector(markerNumber=marker, loadVector=[*load["value"], 0.0]))
    builder.point_output("K", index["c1"], points["K"])
    return builder.assembled()


BUILDERS = {"a01": build_pendulum, "a02": build_n_four_bar, "a03": build_andrews, "task5": build_task5}


@dataclass
class PeerRun:
    """One Exudyn solve: outputs at the sensor samples, wall time, and whether it finished."""

    times: np.ndarray
    outputs: dict
    seconds: float
    n_steps: int
    finished: bool
    message: str = ""


def simulate(
    model: PeerModel,
    step: float,
    t_end: float,
    output_period: float | None = None,
    spectral_radius: float = 0.9,
    adaptive: bool = True,
    verbose: bool = False,
) -> PeerRun:
    """Integrate `model` to `t_end` at the largest step `step` (Exudyn reduces it after a Newton
    failure and recovers it when `adaptive`), sampling the sensors every `output_period`;
    `verbose` lets Exudyn print its progress and why a step failed."""
    exudyn, _ = import_exudyn()
    settings = exudyn.SimulationSettings()
    integration = settings.timeIntegration
    n_steps = round(t_end / step)
    integration.numberOfSteps = n_steps
    integration.endTime = t_end
    integration.verboseMode = 1 if verbose else 0  # 1: progress, and why a step failed
    integration.adaptiveStep = adaptive
    integration.generalizedAlpha.spectralRadius = spectral_radius
    integration.newton.useModifiedNewton = True
    settings.linearSolver.solverType = exudyn.LinearSolverType.EigenSparse
    settings.solution.file.write = False
    settings.solution.sensors.writePeriod = output_period if output_period else step
    settings.displayComputationTime = False
    settings.displayStatistics = False
    start = time.perf_counter()
    message = ""
    try:
        finished = bool(model.system.SolveDynamic(settings))
    except Exception as error:  # noqa: BLE001 - Exudyn raises on a failed step: a result, not a crash
        finished, message = False, str(error).splitlines()[0] if str(error) else type(error).__name__
    seconds = time.perf_counter() - start
    outputs, times = {}, None
    for name, sensor in model.sensors.items():
        data = np.asarray(model.system.GetSensorStoredData(sensor))
        times = data[:, 0]
        outputs[name] = (
            data[:, 1:3] if name not in model.angle_offsets else data[:, 3] + model.angle_offsets[name]
        )
    return PeerRun(times, outputs, seconds, n_steps, finished, message)


def model_maker(benchmark: str, n_bodies: int | None = None):
    """A function building a fresh system of `benchmark` ("chain": the N-four-bar of `n_bodies`
    = 2N + 1 bodies); Task 5's inverse dynamics is run once, not per system."""
    if benchmark == "chain":
        return lambda: build_n_four_bar((n_bodies - 1) // 2)
    if benchmark == "task5":
        kinematics = task5_inverse_dynamics()
        return lambda: build_task5(kinematics)
    return BUILDERS[benchmark]


def accuracy(
    benchmark: str, step: float, spectral_radius: float = 0.9, adaptive: bool = True, verbose: bool = False
) -> dict:
    """Run one benchmark over its whole horizon and compare with the reference (`verbose`:
    Exudyn prints its progress and, on a failure, the step, time and Newton error)."""
    reference = import_reference()
    horizon = {
        "a01": (10.0, 0.01),
        "a02": (20.0, 0.05),
        "a03": (reference.ANDREWS_REFERENCE_TIME, 1e-3),
        "task5": (TASK5_HORIZON, TASK5_FORCE_SAMPLING),
    }
    t_end, period = horizon[benchmark]
    if benchmark == "task5":
        kinematics = task5_inverse_dynamics()
        model = build_task5(kinematics)
    else:
        model = BUILDERS[benchmark]()
    run = simulate(model, step, t_end, period, spectral_radius, adaptive, verbose)
    result = {
        "benchmark": benchmark,
        "step": step,
        "spectral_radius": spectral_radius,
        "adaptive": adaptive,
        "finished": run.finished,
        "message": run.message,
        "seconds": run.seconds,
        "t_last": float(run.times[-1]),
        "samples": len(run.times),
    }
    if benchmark == "a01":
        exact, _ = reference.pendulum_point(run.times)
        result["path_error_m"] = float(np.abs(run.outputs["P.position"] - exact).max())
    elif benchmark == "a02":
        position, velocity = reference.n_four_bar_b0(run.times)
        result["position_error_m"] = float(np.abs(run.outputs["B0.position"] - position).max())
        result["velocity_error_m_s"] = float(np.abs(run.outputs["B0.velocity"] - velocity).max())
    elif benchmark == "task5":  # against the prescribed (kinematic) motion at the same samples
        prescribed = np.asarray(kinematics.point("K").position)[: len(run.times)]
        result["path_error_m"] = float(np.abs(run.outputs["K.position"] - prescribed).max())
    else:
        angles = np.array([run.outputs[f"b{k}"] for k in range(1, 8)]).T
        published = reference.andrews_angles_from_bodies(angles[-1])
        result["angle_error_rad"] = float(np.abs(published - reference.ANDREWS_REFERENCE_ANGLES).max())
    return result


def timing(benchmark: str, n_bodies: int | None, n_steps: int, step: float, repeat: int) -> dict:
    """Wall time per step of fixed steps (no step reduction), and the peak memory of this process.

    A pre-step user function stamps the clock at the start of every step: the time per step is
    the mean over the steps after the first, (last stamp - first stamp) / (n_steps - 1), so
    the solver's start-up (first Jacobian, factorization, initial accelerations) is left out;
    modified Newton refactors only on some steps, which is why a mean over steps, not a
    median, is the cost per step.  The figure is the median over `repeat` fresh systems.  The
    start-up is reported too (`start_seconds`: from the call to the first stamp), and for the
    chain the largest error of B0 against the exact answer.  For the small models, whose steps
    take microseconds, `seconds_per_step_unclocked` is the whole solve of another fresh system
    without the callback, divided by `n_steps` (start-up included, negligible over 10^2-10^3
    steps).
    """
    reference = import_reference()
    n_loops = (n_bodies - 1) // 2 if benchmark == "chain" else None
    make = model_maker(benchmark, n_bodies)
    per_step, cpu_per_step, start_seconds, build_seconds, unclocked, error = [], [], [], [], [], None
    for _ in range(repeat):
        start = time.perf_counter()
        model = make()
        build_seconds.append(time.perf_counter() - start)
        stamps, cpu_stamps = [], []

        def stamp(_system, _time, stamps=stamps, cpu_stamps=cpu_stamps):
            stamps.append(time.perf_counter())
            cpu_stamps.append(time.process_time())  # the process's CPU time (all its threads)
            return True

        model.system.SetPreStepUserFunction(stamp)
        start = time.perf_counter()
        run = simulate(model, step, n_steps * step, step, adaptive=False)
        per_step.append((stamps[-1] - stamps[0]) / (len(stamps) - 1))
        cpu_per_step.append((cpu_stamps[-1] - cpu_stamps[0]) / (len(stamps) - 1))
        start_seconds.append(stamps[0] - start)
        if benchmark == "chain":
            position, _ = reference.n_four_bar_b0(run.times, n_loops=n_loops)
            error = float(np.abs(run.outputs["B0.position"] - position).max())
        size, finished = model.n_bodies, run.finished and len(stamps) == n_steps
        del model, run
        if benchmark != "chain":  # small models: also the whole solve without the clock's callback
            unclocked.append(simulate(make(), step, n_steps * step, step, adaptive=False).seconds)
    return {
        "benchmark": benchmark,
        "n_bodies": size,
        "n_steps": n_steps,
        "step": step,
        "finished": finished,
        "seconds_per_step": statistics.median(per_step),
        "cpu_seconds_per_step": statistics.median(cpu_per_step),
        "start_seconds": statistics.median(start_seconds),
        "seconds_per_step_unclocked": statistics.median(unclocked) / n_steps if unclocked else None,
        "repeat": repeat,
        "build_seconds": statistics.median(build_seconds),
        "b0_error_m": error,
        "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def in_subprocess(*arguments: str) -> dict:
    """One measurement in a fresh interpreter (its own peak memory), parsed from its JSON line;
    what Exudyn printed before it (a solver's reason to stop) is kept as `exudyn_says`."""
    output = subprocess.run(
        [sys.executable, "-W", "ignore", __file__, *arguments], check=True, capture_output=True, text=True
    )
    lines = [line.strip() for line in output.stdout.splitlines() if line.strip()]
    result = {**json.loads(lines[-1]), "load_average": os.getloadavg()[0]}
    if lines[:-1]:
        result["exudyn_says"] = " / ".join(lines[:-1][-4:])
    return result


#: Every measurement of benchmarks/peers/README.md: (command-line arguments) in order.
TABLE = (
    *(("accuracy", "a01", "--step", step) for step in ("1e-3", "5e-4", "2.5e-4")),
    *(("accuracy", "a02", "--step", step) for step in ("1e-3", "5e-4", "2.5e-4")),
    *(("accuracy", "a02", "--step", step, "--fixed") for step in ("1e-3", "5e-4", "2.5e-4")),
    *(("accuracy", "a03", "--step", step) for step in ("2e-5", "1e-5", "5e-6", "2.5e-6")),
    *(("accuracy", "task5", "--step", step) for step in ("1e-3", "5e-4", "2.5e-4")),
    ("timing", "a01", "--steps", "1000", "--step", "1e-3"),
    ("timing", "a02", "--steps", "200", "--step", "1e-3"),
    ("timing", "a03", "--steps", "300", "--step", "1e-5"),
    ("timing", "task5", "--steps", "500", "--step", "1e-3"),
    ("timing", "chain", "--bodies", "1001", "--steps", "20"),
    ("timing", "chain", "--bodies", "10001", "--steps", "10"),
    ("timing", "chain", "--bodies", "100001", "--steps", "4", "--repeat", "1"),
    ("imports",),
)


def table(path: Path, only: str | None = None) -> None:
    """Run every measurement of TABLE, each in a fresh interpreter, one after the other (the
    machine is shared: nothing in parallel), and write them to `path` as JSON lines in TABLE's
    order.  With `only`, run just the entries whose arguments contain it and keep the others'
    lines from `path`."""
    kept = {}
    if only and path.exists():
        kept = {row["arguments"]: row for row in map(json.loads, path.read_text().splitlines())}
    for arguments in TABLE:
        name = " ".join(arguments)
        if only is None or only in name:
            kept[name] = {"arguments": name, **in_subprocess(*arguments)}
            print(name, "done", file=sys.stderr)
        path.write_text("".join(json.dumps(kept[" ".join(a)]) + "\n" for a in TABLE if " ".join(a) in kept))


def report(path: Path) -> str:
    """The README's tables (Markdown) from the JSON lines that `table` wrote."""
    rows = [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]
    lines = [
        "| run | finished (else: the last output sample) | error (up to there) | wall time |",
        "|---|---|---|---|",
    ]
    for row in rows:
        if "path_error_m" in row:
            error = f"path {row['path_error_m']:.2e} m"
        elif "position_error_m" in row:
            error = (
                f"B0 position {row['position_error_m']:.2e} m, velocity {row['velocity_error_m_s']:.2e} m/s"
            )
        elif "angle_error_rad" in row:
            error = f"angles {row['angle_error_rad']:.2e} rad"
        else:
            continue
        status = "yes" if row["finished"] else f"no, stopped at {row['t_last']:.3f} s"
        lines.append(f"| `{row['arguments']}` | {status} | {error} | {row['seconds']:.2f} s |")
    lines += [
        "",
        "| run | bodies | time per step | start-up | B0 error | peak memory |",
        "|---|---|---|---|---|---|",
    ]
    for row in rows:
        if "seconds_per_step" not in row:
            continue
        unclocked = row.get("seconds_per_step_unclocked")
        per_step = f"{row['seconds_per_step'] * 1e3:.4g} ms" + (
            f" ({unclocked * 1e3:.4g} ms without the clock)" if unclocked else ""
        )
        error = f"{row['b0_error_m']:.1e} m" if row["b0_error_m"] is not None else ""
        lines.append(
            f"| `{row['arguments']}` | {row['n_bodies']} | {per_step} | {row['start_seconds']:.3g} s "
            f"| {error} | {row['peak_memory_mb']:.0f} MB |"
        )
    lines += [
        f"| `imports` (Python, NumPy, Exudyn only) | | | | | {row['peak_memory_mb']:.0f} MB |"
        for row in rows
        if row["arguments"] == "imports"
    ]
    loads = [row["load_average"] for row in rows if "load_average" in row]
    if loads:
        lines += ["", f"Load average (1 min) during the runs: {min(loads):.1f} to {max(loads):.1f}."]
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    run_accuracy = commands.add_parser(
        "accuracy", help="one benchmark over its horizon against the reference"
    )
    run_accuracy.add_argument("benchmark", choices=sorted(BUILDERS))
    run_accuracy.add_argument("--step", type=float, default=1e-3)
    run_accuracy.add_argument("--spectral-radius", type=float, default=0.9)
    run_accuracy.add_argument("--fixed", action="store_true", help="no step reduction after a Newton failure")
    run_accuracy.add_argument("--verbose", action="store_true", help="Exudyn's progress and reason to stop")
    run_timing = commands.add_parser("timing", help="time per step and peak memory")
    run_timing.add_argument("benchmark", choices=sorted([*BUILDERS, "chain"]))
    run_timing.add_argument("--bodies", type=int, default=1001, help="chain: 2N + 1 bodies")
    run_timing.add_argument("--steps", type=int, default=20)
    run_timing.add_argument("--step", type=float, default=1e-3)
    run_timing.add_argument("--repeat", type=int, default=3)
    commands.add_parser("imports", help="peak memory of the interpreter with numpy and exudyn imported")
    run_table = commands.add_parser("table", help="every measurement of the README, into a JSON-lines file")
    run_table.add_argument("--out", type=Path, default=Path(__file__).with_name("exudyn_results.jsonl"))
    run_table.add_argument("--only", help="rerun only the entries whose arguments contain this")
    run_report = commands.add_parser("report", help="the README's tables from the JSON-lines file")
    run_report.add_argument(
        "results", type=Path, nargs="?", default=Path(__file__).with_name("exudyn_results.jsonl")
    )
    arguments = parser.parse_args(argv)
    if arguments.command == "table":
        table(arguments.out, arguments.only)
        return
    if arguments.command == "report":
        print(report(arguments.results))
        return
    if arguments.command == "accuracy":
        result = accuracy(
            arguments.benchmark,
            arguments.step,
            arguments.spectral_radius,
            not arguments.fixed,
            arguments.verbose,
        )
    elif arguments.command == "timing":
        result = timing(
            arguments.benchmark, arguments.bodies, arguments.steps, arguments.step, arguments.repeat
        )
    else:
        import_exudyn()
        result = {"peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}
    print(json.dumps({**result, "exudyn": import_exudyn()[0].__version__}))


if __name__ == "__main__":
    main()
