"""Exceptions raised by sparsekin.

Every error derives from `SparsekinError`, except `AnalysisInterrupted`: a Ctrl-C during
an analysis, which is a `KeyboardInterrupt` so that it still stops a program that does
not look for it.  A mistake in a model (in Python or in a model file) is a `ModelError`
that names the element (``joints[3].bodies``) and, for a file, the file.  An analysis that
cannot go on raises a `ConvergenceError` (Newton did not converge), or a
`SingularConfigurationError` when the mechanism reached a singular configuration (a
lock-up, a dead centre); both carry the time, the driver values and the samples solved
before the failure (``result``), so nothing is lost.  So does `AnalysisInterrupted`, and
any `SparsekinError` raised by `sparsekin.solve_kinematics` once its time loop has begun.

Warnings: `RedundantConstraintWarning` when the analysis leaves out redundant equations;
`LimitWarning` when a joint or an actuator leaves the range its `limits` allow.
"""

from __future__ import annotations

import os
import sys
import warnings
from typing import Any

__all__ = [
    "SparsekinError",
    "ModelError",
    "ConvergenceError",
    "SingularJacobianError",
    "SingularConfigurationError",
    "RedundantConstraintWarning",
    "LimitWarning",
    "AnalysisInterrupted",
    "warn_caller",
]

_PACKAGE = os.path.dirname(os.path.abspath(__file__)) + os.sep


class SparsekinError(Exception):
    """Base class of every error raised by sparsekin (but `AnalysisInterrupted`)."""


class ModelError(SparsekinError, ValueError):
    """A mistake in a mechanism description.

    Parameters
    ----------
    reason : str
        What is wrong and what was expected.
    element : str
        Where: ``"joints[3].bodies"``, ``"drivers[0].law.amplitude"``; empty for the model
        as a whole.
    file : str or None
        The model file, when the mechanism came from one.

    Examples
    --------
    >>> str(ModelError('unknown body "c11"', element="joints[3].bodies", file="m.toml"))
    'm.toml: joints[3].bodies: unknown body "c11"'
    """

    def __init__(self, reason: str, *, element: str = "", file: str | None = None) -> None:
        self.reason = reason
        self.element = element
        self.file = file
        super().__init__(": ".join(part for part in (file, element, reason) if part))

    def within(self, prefix: str) -> ModelError:
        """The same error, located inside the element `prefix` (``"drivers[0].law"``)."""
        if not self.element:
            element = prefix
        elif self.element.startswith("["):
            element = prefix + self.element
        else:
            element = f"{prefix}.{self.element}"
        return ModelError(self.reason, element=element, file=self.file)

    def in_file(self, file: str) -> ModelError:
        """The same error, reported against the model file `file`."""
        return ModelError(self.reason, element=self.element, file=file)


class ConvergenceError(SparsekinError, RuntimeError):
    """The position analysis could not converge at some time.

    Attributes
    ----------
    time : float
        Time of the sample that failed, s.
    driver_values : dict[str, float]
        Value of every driver's law at `time` (m or rad), by driver label.
    result : KinematicsResult or None
        The samples solved before the failure (possibly none).
    """

    def __init__(
        self,
        message: str,
        *,
        time: float,
        driver_values: dict[str, float],
        result: Any = None,
    ) -> None:
        super().__init__(message)
        self.time = time
        self.driver_values = driver_values
        self.result = result


class SingularJacobianError(ConvergenceError):
    """The constraint Jacobian is singular: a locked or under-constrained mechanism."""


class SingularConfigurationError(SingularJacobianError):
    """The mechanism reached a singular configuration: a lock-up or a dead centre.

    The analysis stopped at the last configuration it could solve, where the Jacobian is
    (nearly) singular.  The message names the motion that the constraints no longer
    control and the constraints involved.

    Attributes
    ----------
    time : float
        The first time the analysis could not reach, s: the singular configuration lies
        between the last solved sample and this time (within a millionth of the step).
    driver_values : dict[str, float]
        Value of every driver's law at `time`.
    result : KinematicsResult or None
        The samples solved before the singular configuration.
    smallest_singular_value : float
        Smallest singular value of the scaled Jacobian at the last solved configuration,
        relative to its largest.
    """

    def __init__(
        self,
        message: str,
        *,
        time: float,
        driver_values: dict[str, float],
        result: Any = None,
        smallest_singular_value: float = 0.0,
    ) -> None:
        super().__init__(message, time=time, driver_values=driver_values, result=result)
        self.smallest_singular_value = smallest_singular_value


class RedundantConstraintWarning(UserWarning):
    """Some equations depend on the others and are left out of the analysis.

    Issued by `solve_kinematics` for a model with redundant but consistent joints (a
    parallelogram with a third parallel crank, say); the message names the equations.
    """


class LimitWarning(UserWarning):
    """A joint's own coordinate or a distance driver left its ``limits`` during a run.

    Issued once per element and run, naming the element, the first time outside and the
    value then.
    """


class UnjoinedPointWarning(UserWarning):
    """A point is carried by bodies that no joint connects at that point.

    Issued by `load_model` (and listed by `check_model`), naming the point and the bodies:
    nearly always a forgotten joint (`sparsekin.model.shared_points`).
    """


class AnalysisInterrupted(KeyboardInterrupt):
    """The user interrupted an analysis (Ctrl-C): the samples solved so far are in `result`.

    A `KeyboardInterrupt`, so that an interrupt still stops a program that does not look
    for it::

        try:
            result = solve_kinematics(mechanism, times)
        except AnalysisInterrupted as interrupt:
            result = interrupt.result  # every sample solved before the interrupt

    Attributes
    ----------
    result : KinematicsResult
    """

    def __init__(self, result: Any) -> None:
        super().__init__(f"interrupted after {result.n_times} samples")
        self.result = result


def warn_caller(message: str, category: type[Warning]) -> None:
    """Issue a warning attributed to the first caller outside sparsekin: the user's call
    of `sparsekin.solve_kinematics` (or of a stepper, a sweep), however deep inside the
    package the warning arises."""
    frame, level = sys._getframe(1), 2
    while frame is not None and frame.f_code.co_filename.startswith(_PACKAGE):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level)
