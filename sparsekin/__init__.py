"""sparsekin: kinematic analysis of planar linkages in absolute coordinates.

Each body has coordinates ``(x, y, angle)``; joints and drivers are constraint equations
Phi(q, t) = 0.  At each time, Newton–Raphson solves the positions, then one sparse LU
factorization of the Jacobian Phi_q gives the velocities (Phi_q qd = -Phi_t) and the
accelerations (Phi_q qdd = gamma).

The subpackages follow the data flow, and imports point down this list (`errors` and
`_jit` are below all; docs/architecture.md has a sentence for every module):

=================  ===========================================================
`model`            the description: laws, primitives, loads, the element declarations
                   (`model.elements`), bodies, units and repeats, `Mechanism`, the file
`engine`           the equations made numbers: pattern (once), numba kernels that refill
                   residual, Jacobian and gamma, linear solvers, orderings, Newton, forces
`analysis`         numerical rank and null spaces, words for messages, failures, `check_model`
`results`          what a run keeps (memory or Zarr) and returns: `KinematicsResult`
`solve`            the time loop: `KinematicStepper`, the compiled loop, `solve_kinematics`
`studies`          `sweep` (`VariantSet`, `SweepResult`) on Dask, `workspace`
`plots`            figures and animations (matplotlib, imported inside the functions)
`cli`              the ``sparsekin`` command, a module per command
=================  ===========================================================

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

import os as _os
import signal as _signal
import sys as _sys


def _quiet_interrupt(signum, frame):
    """Ctrl-C while the command line loads the package (a second or more with cold caches):
    one line and exit status 130, as later, rather than a traceback of the imports.  The
    process ends at once (`os._exit`): an exception raised here could land inside a
    C extension's initialization (numpy's), which reports it as an ImportError with its
    traceback; nothing is solved or open yet.  The commands install their own handlers
    (`sparsekin.cli.signals`)."""
    _sys.stderr.write("sparsekin: interrupted: nothing solved yet, nothing written\n")
    _sys.stderr.flush()
    _os._exit(130)


# ``sparsekin ...`` (the console script) or ``python -m sparsekin`` (``-m`` while the package loads)
if (_sys.argv[:1] == ["-m"] or _os.path.basename(_sys.argv[0] if _sys.argv else "") in ("sparsekin", "sparsekin.exe")) \
        and _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler:  # fmt: skip
    _signal.signal(_signal.SIGINT, _quiet_interrupt)

from .errors import (
    AnalysisInterrupted,
    ConvergenceError,
    LimitWarning,
    ModelError,
    RedundantConstraintWarning,
    SingularConfigurationError,
    SingularJacobianError,
    SparsekinError,
    UnjoinedPointWarning,
)
from .model.composites import Cylinder
from .model.elements import (
    AbsoluteDriver,
    Actuator,
    DistanceDriver,
    Force,
    Gear,
    PathDriver,
    PinInSlot,
    RackPinion,
    Revolute,
    Rigid,
    RotationalDriver,
    RotationalSpring,
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
from .solve.dynamics import solve_dynamics
from .solve.kinematics import solve_kinematics
from .solve.stepper import KinematicStepper

__all__ = [
    "GROUND",
    "AbsoluteDriver",
    "Actuator",
    "AnalysisInterrupted",
    "Analysis",
    "Body",
    "ConvergenceError",
    "CoordinateMotion",
    "Cycle",
    "Cylinder",
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
    "RotationalSpring",
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
    "UnjoinedPointWarning",
    "analyse_jacobian",
    "check_model",
    "load_model",
    "pose_model",
    "save_model",
    "solve_dynamics",
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
_LAZY = {"sweep": "studies.sweeps", "VariantSet": "studies.variants", "SweepResult": "studies.stores",
         "workspace": "studies.workspaces", "Workspace": "studies.workspaces",
         "check_model": "analysis.check", "ModelReport": "analysis.check",
         "analyse_jacobian": "analysis.rank", "JacobianAnalysis": "analysis.rank",
         "pose_model": "solve.poses"}  # fmt: skip


def __getattr__(name: str):
    if name in _LAZY:
        from importlib import import_module

        value = getattr(import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
