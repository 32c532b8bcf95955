"""Motion laws of drivers: the driven quantity as a function of time.

A law gives, at a time ``t`` (s), the value of the driven quantity (m or rad) and its first
and second time derivatives.  ``initial`` is the value of the driven quantity in the
initial configuration of the model; laws use it as the default offset, so that a driver
starts where the model was drawn.  Any object with an `evaluate` method of the same form
is a law (see `Law`); it runs in the Python time loop.

The built-in laws (`BUILT_IN_LAWS`) are evaluated by one set of numba functions, whatever
asks: `Law.evaluate` here, the assembler at every time, and the compiled time loop of
`sparsekin.solve._compiled`.  Each law packs its parameters into a flat array (`parameters`),
and a `LawTable` holds the packed laws of all drivers, grouped by kind.

>>> value, rate, acceleration = Harmonic(amplitude=0.05, omega=1.5).evaluate(0.0, initial=0.8)
>>> [round(float(v), 12) + 0.0 for v in (value, rate, acceleration)]  # at t = 0
[0.8, 0.075, 0.0]
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np
from numba import njit

from .._jit import JIT
from ..errors import ModelError
from . import _validate
from ._validate import FileKeys

__all__ = ["Law", "Harmonic", "Linear", "Polynomial", "Spline", "BUILT_IN_LAWS", "LawTable", "LawPacker", "pack_laws"]


@runtime_checkable
class Law(Protocol):
    """What a driver needs of a motion law."""

    def evaluate(self, t: float, initial: float) -> tuple[float, float, float]:
        """Value, first and second time derivative of the driven quantity at time `t`."""
        ...


class _BuiltIn:
    """What the built-in laws share: evaluation through the numba kernels of this module."""

    __slots__ = ()

    def evaluate(self, t, initial):
        """Value, first and second time derivative at `t` (a number or an array of times, s)."""
        table, _ = pack_laws([self], np.array([float(initial)]))
        times = np.asarray(t, dtype=float)
        value, rate, acceleration = (np.empty(times.size) for _ in range(3))
        _evaluate_at_times(table, times.ravel(), value, rate, acceleration)
        if times.ndim == 0:
            return float(value[0]), float(rate[0]), float(acceleration[0])
        return value.reshape(times.shape), rate.reshape(times.shape), acceleration.reshape(times.shape)


@dataclass(frozen=True, slots=True)
class Harmonic(_BuiltIn):
    """``offset + amplitude * sin(omega * t + phase)``; `offset` defaults to the initial value."""

    amplitude: float
    omega: float
    phase: float = 0.0
    offset: float | None = None

    type_name = "harmonic"
    file_keys = FileKeys(required=("amplitude", "omega"), optional=("phase", "offset"))

    def __post_init__(self) -> None:
        for field_name in ("amplitude", "omega", "phase"):
            _set(self, field_name, _validate.finite_float(getattr(self, field_name), field_name))
        if self.offset is not None:
            _set(self, "offset", _validate.finite_float(self.offset, "offset"))

    def parameters(self, initial: float) -> np.ndarray:
        """``offset, amplitude, omega, phase``."""
        offset = initial if self.offset is None else self.offset
        return np.array([offset, self.amplitude, self.omega, self.phase], dtype=float)


@dataclass(frozen=True, slots=True)
class Linear(_BuiltIn):
    """``start + rate * t``; `start` defaults to the initial value."""

    rate: float
    start: float | None = None

    type_name = "linear"
    file_keys = FileKeys(required=("rate",), optional=("start",))

    def __post_init__(self) -> None:
        _set(self, "rate", _validate.finite_float(self.rate, "rate"))
        if self.start is not None:
            _set(self, "start", _validate.finite_float(self.start, "start"))

    def parameters(self, initial: float) -> np.ndarray:
        """``start, rate``."""
        return np.array([initial if self.start is None else self.start, self.rate], dtype=float)


@dataclass(frozen=True)
class Polynomial(_BuiltIn):
    """``c0 + c1 t + c2 t² + …``; a `c0` of None means the initial value."""

    coefficients: tuple[float | None, ...]

    type_name = "polynomial"
    file_keys = FileKeys(required=("coefficients",))

    def __post_init__(self) -> None:
        coefficients = self.coefficients
        if isinstance(coefficients, (str, bytes)) or not _validate.is_sequence(coefficients) or not len(coefficients):
            raise ModelError(
                f"expected a non-empty list of numbers, got {coefficients!r}", element="coefficients"
            )
        first = None if coefficients[0] is None else _validate.finite_float(coefficients[0], "coefficients[0]")
        rest = (
            _validate.finite_float(c, f"coefficients[{k}]") for k, c in enumerate(coefficients[1:], start=1)
        )
        _set(self, "coefficients", (first, *rest))

    def parameters(self, initial: float) -> np.ndarray:
        """The m coefficients (ascending powers, c0 resolved), then those of the first and
        second derivatives, each padded with zeros to m."""
        first = initial if self.coefficients[0] is None else self.coefficients[0]
        c = np.array([first, *self.coefficients[1:]], dtype=float)
        padded = np.zeros((3, c.size))
        padded[0] = c
        for order in (1, 2):
            derivative = np.polynomial.polynomial.polyder(c, order)
            padded[order, : derivative.size] = derivative
        return padded.ravel()


#: The closest two samples of a spline may be, relative to its span: closer ones give
#: derivatives that overflow (``[0, 1e-300, 10]``).
MIN_SPLINE_STEP = 1e-9


@dataclass(frozen=True)
class Spline(_BuiltIn):
    """``offset`` plus a C² cubic spline (not-a-knot ends) through the samples ``(times, values)``.

    `offset` defaults to 0: the values are those of the driven quantity.  An `offset` of
    None (``offset = "initial"`` in a file) is the initial value: the values are then
    displacements from the drawing, as the default offsets of the other laws.  The law is
    defined on ``[times[0], times[-1]]``; an analysis outside that range is refused before
    it starts.
    """

    times: tuple[float, ...]
    values: tuple[float, ...]
    offset: float | None = 0.0
    _curve: object = field(init=False, repr=False, compare=False)  # scipy's CubicSpline

    type_name = "spline"
    file_keys = FileKeys(optional=("offset",), forms=(("times", "values"), ("file",)))

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
        steps = np.diff(times)
        if np.any(steps <= 0.0):
            raise ModelError("expected strictly increasing times", element="times")
        closest = int(np.argmin(steps))
        if steps[closest] < MIN_SPLINE_STEP * (times[-1] - times[0]):  # issue 28: overflow, then NaN
            raise ModelError(f"times[{closest}] = {times[closest]!r} and times[{closest + 1}] = {times[closest + 1]!r} "
                             f"are {steps[closest]:.3g} s apart: expected samples at least {MIN_SPLINE_STEP:g} of the "
                             "span apart (the spline's accelerations would overflow)", element="times")  # fmt: skip
        _set(self, "times", times)
        _set(self, "values", values)
        if self.offset is not None:
            _set(self, "offset", _validate.finite_float(self.offset, "offset"))
        from scipy.interpolate import CubicSpline  # here: importing it costs every run a quarter second

        _set(self, "_curve", CubicSpline(times, values))

    @property
    def time_range(self) -> tuple[float, float]:
        """First and last sample time, s."""
        return self.times[0], self.times[-1]

    def parameters(self, initial: float) -> np.ndarray:
        """The m + 1 breakpoints, then the (4, m) polynomial coefficients row by row
        (scipy's ``PPoly`` layout: row 0 multiplies s³; the offset added to row 3)."""
        coefficients = self._curve.c.copy()
        coefficients[3] += initial if self.offset is None else self.offset
        return np.concatenate([self._curve.x, coefficients.ravel()])


#: The laws evaluated by the numba kernels, in the order of `LawTable.kind_first`.
BUILT_IN_LAWS = (Harmonic, Linear, Polynomial, Spline)


class LawTable(NamedTuple):
    """Packed built-in laws, grouped by kind.

    Attributes
    ----------
    kind_first : ndarray of int64, shape (len(BUILT_IN_LAWS) + 1,)
        Entries ``kind_first[c] .. kind_first[c + 1] - 1`` are the laws of kind c.
    target : ndarray of int64, shape (n_entries,)
        Where each entry's value goes in the output arrays of `evaluate_laws`.
    start : ndarray of int64, shape (n_entries + 1,)
        Entry e's parameters are ``data[start[e] : start[e + 1]]`` (see each law's
        `parameters`).
    data : ndarray of float64
    """

    kind_first: np.ndarray
    target: np.ndarray
    start: np.ndarray
    data: np.ndarray


def pack_laws(laws, initial: np.ndarray) -> tuple[LawTable, list[tuple[int, Law]]]:
    """The `LawTable` of the built-in laws among `laws`, and the others as ``(index, law)``.

    Parameters
    ----------
    laws : sequence of Law
        Law k fills entry k of the outputs of `evaluate_laws`.
    initial : ndarray, shape (len(laws),)
        The drawn value of each driven quantity (the default offsets).
    """
    packer = LawPacker()
    for k, law in enumerate(laws):
        packer.add(law, np.array([k]), np.array([float(initial[k])]))
    return packer.table(), packer.others


class LawPacker:
    """Builds a `LawTable` from laws given one by one or as a law repeated over many targets.

    `add` takes one law object for several targets (a unit's law over its copies), with
    per-target values of some of its parameters (`varied`): the parameters of every target
    are computed as arrays, without a law object per target.
    """

    def __init__(self) -> None:
        self._groups: list[list[tuple[np.ndarray, np.ndarray]]] = [[] for _ in BUILT_IN_LAWS]
        self.others: list[tuple[int, Law]] = []

    def add(self, law, targets: np.ndarray, initial: np.ndarray, varied: dict | None = None) -> None:
        """`law` for each of `targets`, whose drawn values are `initial`; `varied` maps a
        parameter name to its value for each target."""
        varied = varied or {}
        if type(law) not in BUILT_IN_LAWS:  # not a subclass either: its evaluate may differ
            for k, target in enumerate(targets.tolist()):
                changed = dataclasses.replace(law, **{key: float(v[k]) for key, v in varied.items()}) if varied else law
                self.others.append((target, changed))
            return
        if type(law) in (Harmonic, Linear):  # parameters are the fields, and the offset may be `initial`
            fields = {Harmonic: ("offset", "amplitude", "omega", "phase"), Linear: ("start", "rate")}[type(law)]
            columns = []
            for name in fields:
                value = getattr(law, name)
                column = varied.get(name)
                if column is None:
                    column = initial if value is None else np.full(targets.size, value)
                columns.append(np.asarray(column, dtype=float))
            parameters = np.stack(columns, axis=1)
        elif varied:  # a polynomial or a spline whose parameters vary: one law object per target
            parameters = np.stack([
                dataclasses.replace(law, **{key: v[k] for key, v in varied.items()}).parameters(float(initial[k]))
                for k in range(targets.size)
            ])  # fmt: skip
        else:
            parameters = np.repeat(law.parameters(0.0)[None], targets.size, axis=0)
            if type(law) is Polynomial and law.coefficients[0] is None:
                parameters[:, 0] = initial  # c0 is the drawn value
            elif type(law) is Spline and law.offset is None:
                parameters[:, 4 * (len(law.times) - 1) + 1 :] += initial[:, None]  # row 3: the constant terms
        self._groups[BUILT_IN_LAWS.index(type(law))].append((np.asarray(targets, dtype=np.int64), parameters))

    def table(self) -> LawTable:
        targets, sizes, data, counts = [], [], [], []
        for groups in self._groups:
            counts.append(sum(t.size for t, _ in groups))
            for group_targets, parameters in groups:
                targets.append(group_targets)
                sizes.append(np.full(group_targets.size, parameters.shape[1], dtype=np.int64))
                data.append(parameters.ravel())
        sizes_all = np.concatenate(sizes) if sizes else np.zeros(0, dtype=np.int64)
        start = np.zeros(sizes_all.size + 1, dtype=np.int64)
        np.cumsum(sizes_all, out=start[1:])
        return LawTable(
            kind_first=np.cumsum([0] + counts).astype(np.int64),
            target=np.concatenate(targets) if targets else np.zeros(0, dtype=np.int64),
            start=start,
            data=np.concatenate(data) if data else np.zeros(0),
        )


# ---------------------------------------------------------------------- the kernels
@njit(inline="always", **JIT)
def _harmonic(p, t):
    offset, amplitude, omega, phase = p[0], p[1], p[2], p[3]
    angle = omega * t + phase
    sine = math.sin(angle)
    return offset + amplitude * sine, amplitude * omega * math.cos(angle), -amplitude * omega**2 * sine


@njit(inline="always", **JIT)
def _linear(p, t):
    return p[0] + p[1] * t, p[1], 0.0


@njit(inline="always", **JIT)
def _horner(c, t):
    """numpy's ``polyval(t, c)``, same operation order."""
    total = c[c.size - 1]
    for i in range(c.size - 2, -1, -1):
        total = c[i] + total * t
    return total


@njit(inline="always", **JIT)
def _polynomial(p, t):
    m = p.size // 3
    return _horner(p[:m], t), _horner(p[m : 2 * m], t), _horner(p[2 * m :], t)


@njit(inline="always", **JIT)
def _spline(p, t):
    """scipy's ``PPoly`` evaluation, the end pieces extended beyond the range."""
    m = (p.size - 1) // 5  # intervals
    x = p[: m + 1]
    c = p[m + 1 :]  # (4, m) row by row; row 0 multiplies s³
    low, high = 0, m - 1  # the interval i with x[i] <= t < x[i + 1]
    while low < high:
        middle = (low + high + 1) // 2
        if t >= x[middle]:
            low = middle
        else:
            high = middle - 1
    s = t - x[low]
    c3, c2, c1, c0 = c[low], c[m + low], c[2 * m + low], c[3 * m + low]  # c0 + c1 s + c2 s² + c3 s³
    return c0 + c1 * s + c2 * (s * s) + c3 * (s * s * s), c1 + 2.0 * c2 * s + 3.0 * c3 * (s * s), 2.0 * c2 + 6.0 * c3 * s


@njit(inline="always", **JIT)
def evaluate_laws(table, t, value, rate, acceleration):
    """Value, first and second time derivative of every law of `table` at time t (s)."""
    k, data, start, target = table.kind_first, table.data, table.start, table.target
    for e in range(k[0], k[1]):
        value[target[e]], rate[target[e]], acceleration[target[e]] = _harmonic(data[start[e] : start[e + 1]], t)
    for e in range(k[1], k[2]):
        value[target[e]], rate[target[e]], acceleration[target[e]] = _linear(data[start[e] : start[e + 1]], t)
    for e in range(k[2], k[3]):
        value[target[e]], rate[target[e]], acceleration[target[e]] = _polynomial(data[start[e] : start[e + 1]], t)
    for e in range(k[3], k[4]):
        value[target[e]], rate[target[e]], acceleration[target[e]] = _spline(data[start[e] : start[e + 1]], t)


@njit(**JIT)
def fill_laws(table, t, value, rate, acceleration):
    """`evaluate_laws`, called from Python."""
    evaluate_laws(table, t, value, rate, acceleration)


@njit(**JIT)
def _evaluate_at_times(table, times, value, rate, acceleration):
    """The one law of `table` at each of `times`."""
    buffer = np.empty((3, 1))
    for k in range(times.size):
        evaluate_laws(table, times[k], buffer[0], buffer[1], buffer[2])
        value[k], rate[k], acceleration[k] = buffer[0, 0], buffer[1, 0], buffer[2, 0]


def _set(law: object, field_name: str, value: object) -> None:
    """Store the canonical form of a field of a frozen law (floats, tuples)."""
    object.__setattr__(law, field_name, value)
