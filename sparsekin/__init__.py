"""sparsekin: kinematic analysis of planar linkages in absolute coordinates.

Each body has coordinates ``(x, y, angle)``; joints and drivers are constraint equations
Phi(q, t) = 0.  At each time, Newton–Raphson solves the positions, then one sparse LU
factorization of the Jacobian Phi_q gives the velocities (Phi_q qd = -Phi_t) and the
accelerations (Phi_q qdd = gamma).

The modules follow the data flow:

=================  ===========================================================
`laws`             motion laws of drivers: `Harmonic`, `Linear`, ... (and their kernels)
`primitives`       the four primitive equations every element is made of
`loads`            the three primitive loads, and the bodies' masses, packed
`elements`         every kind of joint, driver and load, declared once (the registry)
`units`            units repeated into chains: `Unit`, `Repeat`, resolved by arithmetic
`model`            frozen description: `Mechanism`, `Body`
`modelfile`        the TOML model file: `load_model`, `save_model`
`columns`          elements as arrays for the equation builders (tiled over copies)
`pattern`          Mechanism -> packed equations, CSR pattern and slots (once)
`_kernels`         numba kernels that refill residual, Jacobian and gamma
`assembly`         `Assembler`: owns the arrays and calls the kernels
`_force_kernels`   numba kernels of the applied and inertial forces and the element forces
`dynamics`         forces that hold the motion: multipliers, driver forces, reactions
`_lu_kernels`      numba LU: refactorization on fixed L/U patterns, solves, dense LU
`linalg`           linear solvers behind one interface: SuperLU, refactorization, dense
`rank`             numerical rank, null spaces and conditioning of a sparse Jacobian
`newton`           Newton–Raphson: the rules (shared with the compiled loop), the loop
`reduced`          square systems without redundant equations, or with coordinates held
`describe`         words for messages: equations, coordinates, motions
`failures`         what went wrong: model errors, lock-up and convergence errors
`ordering`         a long chain's first pivot order, tiled from a short chain
`stepper`          `KinematicStepper`: the time loop, one sample at a time
`_compiled`        the whole time loop of a small model in one numba call
`results`          `KinematicsResult`: points, joint and driver coordinates, forces
`recording`        what a run keeps, in chunks, in memory or in a Zarr store
`solvers`          `solve_kinematics`: validate, run the loop, return the result
`check`            `check_model`: degrees of freedom, rank, redundancy, free motions
`sweeps`           `sweep`: many variants on Dask (`VariantSet`, `SweepResult`)
`workspaces`       `workspace`: a point's reachable region over two drivers' values
`cli`              the ``sparsekin`` command; `plotting` its figures
=================  ===========================================================

Imports point down this list (`geometry`, `errors` and `_validate` are below all).

A slider-crank, from description to the motion of its slider:

>>> import numpy as np
>>> import sparsekin as sk
>>> mechanism = sk.Mechanism(
...     points={"O": (0.0, 0.0), "A": (0.1, 0.0), "B": (0.4, 0.0)},
...     bodies=[
...         sk.Body("crank", origin="O", points=("O", "A")),
...         sk.Body("rod", origin="A", points=("A", "B")),
...         sk.Body("slider", origin="B", points=("B",)),
...     ],
...     joints=[
...         sk.Revolute(("crank", "ground"), at="O"),
...         sk.Revolute(("crank", "rod"), at="A"),
...         sk.Revolute(("rod", "slider"), at="B"),
...         sk.Translational(("ground", "slider"), axis=("O", "B"), name="guide"),
...     ],
...     drivers=[sk.RotationalDriver(("crank", "ground"), law=sk.Linear(rate=2 * np.pi))],
... )
>>> result = sk.solve_kinematics(mechanism, times=np.linspace(0.0, 0.5, 51))
>>> result.coordinates.shape  # 51 samples × (x, y, angle) of 3 bodies
(51, 9)
>>> bool(np.allclose(result.point("B").position[-1], [0.2, 0.0]))  # crank at 180°: 0.4 - 0.1 - 0.1
True
"""

from .errors import (
    AnalysisInterrupted,
    ConvergenceError,
    LimitWarning,
    ModelError,
    RedundantConstraintWarning,
    SingularConfigurationError,
    SingularJacobianError,
    SparsekinError,
)
from .model.elements import (
    AbsoluteDriver,
    DistanceDriver,
    Force,
    Gear,
    PathDriver,
    PinInSlot,
    RackPinion,
    Revolute,
    Rigid,
    RotationalDriver,
    Spring,
    Torque,
    Translational,
    TranslationalDriver,
)
from .model.laws import Harmonic, Law, Linear, Polynomial, Spline
from .model.mechanism import GROUND, Analysis, Body, Mechanism
from .model.modelfile import load_model, save_model
from .model.units import Cycle, OnCopies, Repeat, Step, Unit
from .results.kinematics import CoordinateMotion, DriverForce, KinematicsResult, PointMotion, Reaction
from .solve.kinematics import solve_kinematics
from .solve.stepper import KinematicStepper

__all__ = [
    "GROUND",
    "AbsoluteDriver",
    "AnalysisInterrupted",
    "Analysis",
    "Body",
    "ConvergenceError",
    "CoordinateMotion",
    "Cycle",
    "DistanceDriver",
    "DriverForce",
    "Force",
    "Gear",
    "Harmonic",
    "JacobianAnalysis",
    "KinematicStepper",
    "KinematicsResult",
    "Law",
    "LimitWarning",
    "Linear",
    "Mechanism",
    "ModelError",
    "ModelReport",
    "OnCopies",
    "PathDriver",
    "PinInSlot",
    "PointMotion",
    "Polynomial",
    "RackPinion",
    "Reaction",
    "RedundantConstraintWarning",
    "Repeat",
    "Revolute",
    "Rigid",
    "RotationalDriver",
    "SingularConfigurationError",
    "SingularJacobianError",
    "SparsekinError",
    "Spline",
    "Spring",
    "Step",
    "Torque",
    "Translational",
    "TranslationalDriver",
    "Unit",
    "analyse_jacobian",
    "check_model",
    "load_model",
    "save_model",
    "solve_kinematics",
    "SweepResult",
    "VariantSet",
    "Workspace",
    "sweep",
    "workspace",
]
__version__ = "0.1.0"

#: Names imported on first use, so that ``import sparsekin`` loads neither Dask nor the
#: sweep machinery, nor the rank analysis and its scipy modules that a run does not need
#: (every ``sparsekin run`` pays for what ``import sparsekin`` imports): name -> module.
_LAZY = {"sweep": "studies.sweeps", "VariantSet": "studies.sweeps", "SweepResult": "studies.sweeps",
         "workspace": "studies.workspaces", "Workspace": "studies.workspaces",
         "check_model": "analysis.check", "ModelReport": "analysis.check",
         "analyse_jacobian": "analysis.rank", "JacobianAnalysis": "analysis.rank"}  # fmt: skip


def __getattr__(name: str):
    if name in _LAZY:
        from importlib import import_module

        value = getattr(import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
