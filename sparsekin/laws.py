"""Motion laws of drivers: the driven quantity as a function of time.

A law gives, at a time ``t`` (s), the value of the driven quantity (m or rad) and its first
and second time derivatives.  ``initial`` is the value of the driven quantity in the
initial configuration of the model; laws use it as the default offset, so that a driver
starts where the model was drawn.  Any object with an `evaluate` method of the same form
is a law (see `Law`).

>>> value, rate, acceleration = Harmonic(amplitude=0.05, omega=1.5).evaluate(0.0, initial=0.8)
>>> [round(float(v), 12) + 0.0 for v in (value, rate, acceleration)]  # at t = 0
[0.8, 0.075, 0.0]
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
from scipy.interpolate import CubicSpline

from . import _validate
from .errors import ModelError

__all__ = ["Law", "Harmonic", "Linear", "Polynomial", "Spline"]


@runtime_checkable
class Law(Protocol):
    """What a driver needs of a motion law."""

    def evaluate(self, t: float, initial: float) -> tuple[float, float, float]:
        """Value, first and second time derivative of the driven quantity at time `t`."""
        ...


@dataclass(frozen=True, slots=True)
class Harmonic:
    """``offset + amplitude * sin(omega * t + phase)``; `offset` defaults to the initial value."""

    amplitude: float
    omega: float
    phase: float = 0.0
    offset: float | None = None

    def __post_init__(self) -> None:
        for field_name in ("amplitude", "omega", "phase"):
            _set(self, field_name, _validate.finite_float(getattr(self, field_name), field_name))
        if self.offset is not None:
            _set(self, "offset", _validate.finite_float(self.offset, "offset"))

    def evaluate(self, t, initial):
        offset = initial if self.offset is None else self.offset
        angle = self.omega * t + self.phase
        sine, cosine = np.sin(angle), np.cos(angle)
        return (
            offset + self.amplitude * sine,
            self.amplitude * self.omega * cosine,
            -self.amplitude * self.omega**2 * sine,
        )


@dataclass(frozen=True, slots=True)
class Linear:
    """``start + rate * t``; `start` defaults to the initial value."""

    rate: float
    start: float | None = None

    def __post_init__(self) -> None:
        _set(self, "rate", _validate.finite_float(self.rate, "rate"))
        if self.start is not None:
            _set(self, "start", _validate.finite_float(self.start, "start"))

    def evaluate(self, t, initial):
        start = initial if self.start is None else self.start
        return start + self.rate * t, self.rate + 0.0 * t, 0.0 * t


@dataclass(frozen=True)
class Polynomial:
    """``c0 + c1 t + c2 t² + …``; a `c0` of None means the initial value."""

    coefficients: tuple[float | None, ...]

    def __post_init__(self) -> None:
        coefficients = self.coefficients
        if isinstance(coefficients, (str, bytes)) or not _validate.is_sequence(coefficients) or not len(coefficients):
            raise ModelError(
                f"expected a non-empty list of numbers, got {coefficients!r}", element="coefficients"
            )
        first = None if coefficients[0] is None else _validate.finite_float(coefficients[0], "coefficients[0]")
        rest = _validate.number_list(tuple(coefficients[1:]), "coefficients")
        _set(self, "coefficients", (first, *rest))

    def evaluate(self, t, initial):
        c = np.array(
            [initial if self.coefficients[0] is None else self.coefficients[0], *self.coefficients[1:]],
            dtype=float,
        )
        value = np.polynomial.polynomial.polyval(t, c)
        first = np.polynomial.polynomial.polyval(t, np.polynomial.polynomial.polyder(c, 1))
        second = np.polynomial.polynomial.polyval(t, np.polynomial.polynomial.polyder(c, 2))
        return value, first, second


@dataclass(frozen=True)
class Spline:
    """A C² cubic spline (not-a-knot ends) through the samples ``(times, values)``.

    The law is defined on ``[times[0], times[-1]]``; an analysis outside that range is
    refused before it starts.
    """

    times: tuple[float, ...]
    values: tuple[float, ...]
    _curve: CubicSpline = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        times = _validate.number_list(self.times, "times")
        values = _validate.number_list(self.values, "values")
        if len(times) < 2:
            raise ModelError(f"expected at least 2 samples, got {len(times)}", element="times")
        if len(values) != len(times):
            raise ModelError(
                f"expected as many values as times ({len(times)}), got {len(values)}",
                element="values",
            )
        if np.any(np.diff(times) <= 0.0):
            raise ModelError("expected strictly increasing times", element="times")
        _set(self, "times", times)
        _set(self, "values", values)
        _set(self, "_curve", CubicSpline(times, values))

    @property
    def time_range(self) -> tuple[float, float]:
        """First and last sample time, s."""
        return self.times[0], self.times[-1]

    def evaluate(self, t, initial):
        return self._curve(t), self._curve(t, 1), self._curve(t, 2)


def _set(law: object, field_name: str, value: object) -> None:
    """Store the canonical form of a field of a frozen law (floats, tuples)."""
    object.__setattr__(law, field_name, value)
