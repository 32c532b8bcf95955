"""The options of a run, validated once: `SolveOptions` (how), `Request` (what to keep), `check_times`.

Each is checked where it is made, with the message a user of `sparsekin.solve_kinematics`
reads (the argument's name in backticks and what was expected); the layers below take
the values as they are.

>>> SolveOptions(tolerance=1e-10).max_iterations
12
>>> SolveOptions(linear_solver="fast")
Traceback (most recent call last):
...
ValueError: `linear_solver` must be one of 'auto', 'superlu', 'refactor', 'dense', got 'fast'.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..engine.discretization import Discretization
from ..engine.newton import DEFAULT_TOLERANCE, NEWTON_MAXITER
from ..model.laws import Spline
from ..model.mechanism import Mechanism
from ..results.recording import Selection
from .branch_guard import BranchGuard
from .error_control import RTOL_RANGE
from .policy import LINEAR_SOLVERS, Thresholds

__all__ = ["SolveOptions", "Request", "DynamicsOptions", "BranchGuard", "TOLERANCE_RANGE", "RTOL_RANGE", "check_times",
           "checked_tolerance", "checked_rtol", "checked_max_iterations", "checked_rho_inf", "check_progress"]

#: Smallest and largest accepted `tolerance`: below about 4 eps the residual cannot be
#: reached in floating point; above 1 % of the model size a "solution" is not one.
TOLERANCE_RANGE = (4 * np.finfo(float).eps, 1e-2)
def _checked_number(name: str, value, bounds: tuple[float, float], expected: str = "a positive number") -> float:
    """`value` as a float within `bounds`, else a ValueError naming `name`."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f"`{name}` must be {expected}, got {value!r}.")
    low, high = bounds
    if not (math.isfinite(value) and low <= value <= high):
        raise ValueError(f"`{name}` must be a number in [{low:.3g}, {high:g}], got {value!r}.")
    return float(value)


def checked_tolerance(value) -> float:
    """`value` as a float within `TOLERANCE_RANGE`, else a ValueError."""
    return _checked_number("tolerance", value, TOLERANCE_RANGE)


def checked_rtol(value) -> float | None:
    """`value` as a float within `RTOL_RANGE` (None stays None), else a ValueError."""
    return None if value is None else _checked_number("rtol", value, RTOL_RANGE, "None or a positive number")


def checked_max_iterations(value) -> int:
    """`value` as an int >= 1, else a ValueError."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"`max_iterations` must be a whole number >= 1, got {value!r}.")
    return int(value)


@dataclass(frozen=True)
class SolveOptions:
    """How a run solves: checked when made.

    Attributes
    ----------
    tolerance : float
        Largest accepted residual: lengths relative to the size of the model, angles in
        rad; within `TOLERANCE_RANGE`.
    max_iterations : int
        Most Newton corrections at one time, at least 1.
    linear_solver : {"auto", "dense", "refactor", "superlu"}
        See `sparsekin.solve_kinematics` and `sparsekin.solve.policy`.
    thresholds : Thresholds
        The sizes at which ``"auto"`` changes path.
    guard : BranchGuard
        The branch guard's thresholds.
    """

    tolerance: float = DEFAULT_TOLERANCE
    max_iterations: int = NEWTON_MAXITER
    linear_solver: str = "auto"
    thresholds: Thresholds = field(default_factory=Thresholds)
    guard: BranchGuard = field(default_factory=BranchGuard)

    def __post_init__(self) -> None:
        object.__setattr__(self, "tolerance", checked_tolerance(self.tolerance))
        object.__setattr__(self, "max_iterations", checked_max_iterations(self.max_iterations))
        if not isinstance(self.linear_solver, str) or self.linear_solver not in LINEAR_SOLVERS:
            raise ValueError(f"`linear_solver` must be one of {', '.join(map(repr, LINEAR_SOLVERS))}, "
                             f"got {self.linear_solver!r}.")  # fmt: skip


@dataclass(frozen=True)
class Request:
    """What a run keeps (see `sparsekin.solve_kinematics`): checked when made, resolved
    against a model by `selection`.

    Attributes
    ----------
    coordinates : bool
    points, joints : None, "all" or sequence of str
    forces : "auto", None, "all" or sequence of str
    quasi_static : bool
    chunk_samples : int or None
        Samples per chunk of the recorder (default: as many as 64 MiB hold, at most
        `sparsekin.results.recording.MAX_CHUNK_SAMPLES`).
    """

    coordinates: bool = True
    points: object = None
    joints: object = None
    forces: object = "auto"
    quasi_static: bool = False
    chunk_samples: int | None = None
    energy: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.coordinates, (bool, np.bool_)):  # issue 28: "no" was true
            raise ValueError(f"`coordinates` must be True or False, got {self.coordinates!r}.")
        points = self.points
        if isinstance(points, Sequence) and not isinstance(points, str) and not all(isinstance(n, str) for n in points):
            # issue 28: [["K"]] was a bare TypeError (the names themselves are checked by `selection`)
            raise ValueError(f'`points` must be None, "all" or a list of point names, got {points!r}.')
        if not isinstance(self.quasi_static, (bool, np.bool_)):
            raise ValueError(f"`quasi_static` must be True or False, got {self.quasi_static!r}.")
        if self.chunk_samples is not None and (isinstance(self.chunk_samples, bool) or int(self.chunk_samples) < 1):
            raise ValueError(f"`chunk_samples` must be a whole number >= 1, got {self.chunk_samples!r}.")

    def selection(self, discretization: Discretization) -> Selection:
        """The variables this request records for `discretization` (names checked there)."""
        return Selection(discretization, self.coordinates, self.points, self.joints, self.forces, energy=self.energy)


@dataclass(frozen=True)
class DynamicsOptions:
    """How a forward-dynamics run integrates (`sparsekin.solve_dynamics`): checked when made.

    Attributes
    ----------
    max_step : float or None
        Largest integration step, s; None: chosen by `for_run` from the model and times.
    rho_inf : float
        Numerical damping of generalized-α, in [0, 1] (1: none).
    rtol : float or None
        Local error of one step relative to the model size (angles: rad), in
        `RTOL_RANGE`: the steps are chosen by their error estimate
        (`sparsekin.solve.error_control`), never above `max_step`; None: steps of
        `max_step`, halved only on a failure (`for_run` takes the model's
        ``analysis.rtol`` then).
    """

    max_step: float | None = None
    rho_inf: float = 0.9
    rtol: float | None = None

    def __post_init__(self) -> None:
        if self.max_step is not None:
            object.__setattr__(self, "max_step", checked_positive(self.max_step, "max_step"))
        object.__setattr__(self, "rho_inf", checked_rho_inf(self.rho_inf))
        object.__setattr__(self, "rtol", checked_rtol(self.rtol))

    def for_run(self, times: np.ndarray, mechanism: Mechanism) -> DynamicsOptions:
        """These options with `max_step` chosen when not given: the model's
        ``analysis.max_step``, else the shortest interval of `times` (1 s for one sample);
        and `rtol`, when not given, the model's ``analysis.rtol``."""
        analysis = mechanism.analysis
        rtol = analysis.rtol if self.rtol is None else self.rtol
        max_step = analysis.max_step if self.max_step is None else self.max_step
        if max_step is None:
            max_step = float(np.min(np.diff(times))) if times.size > 1 else 1.0
        return DynamicsOptions(max_step, self.rho_inf, rtol)


def checked_positive(value, name: str) -> float:
    """`value` as a positive finite float, else a ValueError naming `name`."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not value > 0.0 \
            or not math.isfinite(value):  # fmt: skip
        raise ValueError(f"`{name}` must be a positive number, got {value!r}.")
    return float(value)


def checked_rho_inf(value) -> float:
    """`value` as a float in [0, 1], else a ValueError."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not 0.0 <= value <= 1.0:  # fmt: skip
        raise ValueError(f"`rho_inf` must be a number in [0, 1], got {value!r}.")
    return float(value)


def check_progress(progress) -> None:
    """A ValueError unless `progress` is None or a callable ``(done, total)``."""
    if progress is not None and not callable(progress):
        raise ValueError(f"`progress` must be a callable (done, total), got {progress!r}.")


def check_times(times, mechanism: Mechanism) -> np.ndarray:
    """`times` as a new C-contiguous float array: non-empty, 1-D, finite, strictly
    increasing and within the time range of every spline law of `mechanism`; else a
    ValueError naming the argument."""
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
