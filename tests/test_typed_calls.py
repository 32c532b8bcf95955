"""`sparsekin.engine.typed_calls`: a kernel called through the entry point of the argument
types it was last typed for gives what the dispatcher gives, and goes back to the dispatcher
for arguments of another type (another dtype, dimension, layout, writeability, another
object where a NamedTuple was, None where an array was) instead of misreading them."""

from __future__ import annotations

import sys
from typing import NamedTuple

import numpy as np
import pytest
from numba import njit

from sparsekin.engine import typed_calls
from sparsekin.engine.typed_calls import TypedCall, TypedCalls


class Pair(NamedTuple):
    scale: np.ndarray
    shift: np.ndarray


@njit
def affine(pair, x, factor, out):
    """``out = factor · pair.scale · x + pair.shift``; returns the sum of `out`."""
    total = 0.0
    for i in range(x.size):
        out[i] = factor * pair.scale[i] * x[i] + pair.shift[i]
        total += out[i]
    return total


@njit
def first_entry(x):
    return x.flat[0] if x.size else -1.0


def _pair(size: int = 5) -> Pair:
    return Pair(np.linspace(1.0, 2.0, size), np.linspace(-1.0, 0.0, size))


def test_same_results_as_the_dispatcher():
    pair, call = _pair(), TypedCall(affine)
    rng = np.random.default_rng(0)
    for k in range(4):
        x = rng.standard_normal(5)
        out, expected = np.empty(5), np.empty(5)
        assert call(pair, x, 1.5 + k, out) == affine(pair, x, 1.5 + k, expected)
        np.testing.assert_array_equal(out, expected)
    assert call._entry is not None and call._misses == 1  # typed once, then its entry point


def test_other_types_go_through_the_dispatcher():
    call = TypedCall(first_entry)
    x = np.arange(6.0)
    assert call(x) == 0.0 and call._misses == 1
    assert call(np.arange(3, 9)) == 3  # int64: another specialization, not float64's code on its bytes
    assert call._misses == 2
    strided = np.arange(12.0)[1::2]  # not contiguous: its own layout
    assert call(strided) == 1.0 and call._misses == 3
    frozen = np.arange(2.0, 5.0)
    frozen.flags.writeable = False  # (numba types a read-only array apart)
    assert call(frozen) == 2.0 and call._misses == 4
    assert call(np.arange(4.0).reshape(2, 2)) == 0.0 and call._misses == 5
    assert call(np.arange(7.0, 9.0)) == 7.0 and call._misses == 6  # back to a 1-d float64: typed again
    assert call(np.arange(8.0, 9.0)) == 8.0 and call._misses == 6


def test_another_named_tuple_or_none_goes_through_the_dispatcher():
    call = TypedCall(affine)
    first, second, x, out = _pair(), _pair(), np.ones(5), np.empty(5)
    call(first, x, 1.0, out)
    second.shift[:] = 10.0
    assert call(second, x, 1.0, out) == pytest.approx(np.sum(second.scale + 10.0))
    assert call._misses == 2  # (compared by identity: typed again for `second`)
    with pytest.raises(Exception):  # noqa: B017 (numba's own typing error, not a misread)
        call(second, None, 1.0, out)


def test_arrays_are_not_held():
    call, x, out = TypedCall(affine), np.ones(5), np.empty(5)
    before = sys.getrefcount(x), sys.getrefcount(out)
    call(_pair(), x, 1.0, out)
    assert (sys.getrefcount(x), sys.getrefcount(out)) == before  # (the states' pool reuses arrays by this count)


def test_gives_up_after_max_misses(monkeypatch):
    monkeypatch.setattr(typed_calls, "MAX_MISSES", 2)
    call = TypedCall(first_entry)
    call(np.arange(2.0))
    call(np.arange(2))
    assert call._entry is None and call(np.arange(5.0, 6.0)) == 5.0 and call._misses == 3


def test_typed_calls_of_a_module():
    import types

    module = types.SimpleNamespace(first_entry=first_entry)
    calls = TypedCalls(module)
    assert calls.first_entry(np.arange(1.0, 3.0)) == 1.0
    assert calls.first_entry is calls.first_entry  # one per kernel, made once


def test_a_plain_function_is_called_as_it_is():
    """Under ``NUMBA_DISABLE_JIT=1`` the kernels are plain functions (CI runs the dynamics
    tests so): nothing to type, every call goes to the function."""
    call = TypedCall(first_entry.py_func)
    assert call(np.arange(3.0, 5.0)) == 3.0 and call(np.arange(2)) == 0
    assert call._entry is None and call._misses > typed_calls.MAX_MISSES
