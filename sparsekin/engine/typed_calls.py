"""Calls of a numba kernel that skip the dispatcher's typing of arguments seen before.

numba's dispatcher types every argument at every call.  An array, a number or a plain tuple
of them is typed in C (about 0.05 µs an array); a NamedTuple is not: it goes through
numba's Python ``typeof``, field by field, 1–4.6 µs for the model's `LoadArrays`,
`Primitives` and actuator arrays (NamedTuples of NamedTuples of arrays).  A forward-dynamics
step of the N-four-bar chain passes them to about seven kernels: at 10^3 bodies ~40 µs of a
0.57 ms step (docs/design-notes.md, "Python between the kernels").

`TypedCall` calls the kernel's compiled entry point for the argument types of its last
call through the dispatcher when every argument is, for an array, a number or a tuple of
numbers, of the same numba type (dtype, dimensions, contiguity, writeability: `_key`), and
otherwise the very object it was then; anything else goes through the dispatcher (which
compiles a new specialization if it must), whose types are held for the next call.  The
same compiled code runs on the same arguments: the results are the same bits.  Arrays are
held by weak references only (`sparsekin.solve._state_arrays` reuses a state's arrays by
their reference count): the array of the last typing is not looked at again.  After
`MAX_MISSES` calls through the dispatcher every call goes there.
"""

from __future__ import annotations

import weakref

import numpy as np

__all__ = ["TypedCall", "TypedCalls"]

#: The flags of an array that its numba type depends on (`numpy.ndarray.flags.num`):
#: C_CONTIGUOUS, F_CONTIGUOUS, ALIGNED, WRITEABLE (not OWNDATA: a view and its base are typed alike).
_LAYOUT = 0x1 | 0x2 | 0x100 | 0x400
_NUMBERS = (float, int, bool, np.float64, np.int64, np.bool_)
#: Calls through the dispatcher (the first included) after which a `TypedCall` holds nothing.
MAX_MISSES = 8


def _key(value):
    """What numba's type of `value` depends on, for an array, a number or a tuple of numbers;
    None for anything else (held as the object itself)."""
    kind = type(value)
    if kind is np.ndarray:
        return value.dtype, value.ndim, value.flags.num & _LAYOUT
    if kind in _NUMBERS:
        return kind
    if kind is tuple and all(type(item) in _NUMBERS for item in value):
        return tuple(type(item) for item in value)
    return None


class TypedCall:
    """`kernel` (a numba dispatcher), called as the kernel itself, its typing held between calls.

    Parameters
    ----------
    kernel : numba.core.registry.CPUDispatcher

    Notes
    -----
    The arguments of the last call through the dispatcher that are not arrays, numbers or
    tuples of numbers are held and compared by identity (a model's NamedTuples, which its
    system holds anyway); its arrays by weak references (the same array is not typed again).
    """

    __slots__ = ("kernel", "_entry", "_held", "_keys", "_misses")

    def __init__(self, kernel) -> None:
        self.kernel = kernel
        self._entry, self._held, self._keys = None, (), ()
        # a plain function (``NUMBA_DISABLE_JIT=1``) or a dispatcher without what `_bind` reads:
        # always called as it is
        self._misses = 0 if hasattr(kernel, "overloads") and hasattr(kernel, "typeof_pyval") else MAX_MISSES

    def __call__(self, *args):
        entry = self._entry
        if entry is not None and len(args) == len(self._held):
            for value, held, key in zip(args, self._held, self._keys):  # (`_key`, inline for arrays)
                if key is None:
                    if value is not held:
                        break
                elif type(value) is np.ndarray:
                    if held() is not value and (value.dtype, value.ndim, value.flags.num & _LAYOUT) != key:
                        break
                elif _key(value) != key:
                    break
            else:
                return entry(*args)
        result = self.kernel(*args)
        self._misses += 1
        if self._misses < MAX_MISSES:
            self._bind(args)
        else:
            self._entry, self._held = None, ()
        return result

    def _bind(self, args: tuple) -> None:
        """Hold the entry point of `args`' types (compiled by the call just made)."""
        kernel = self.kernel
        try:
            signature = tuple(kernel.typeof_pyval(value) for value in args)
            compiled = kernel.overloads.get(signature)
            entry = None if compiled is None else compiled.entry_point
        except (AttributeError, TypeError, ValueError):  # numba's internals changed: the dispatcher from now on
            compiled, entry, self._misses = None, None, MAX_MISSES
        if entry is None:  # (a conversion numba made on the way: always through the dispatcher)
            self._entry = None
            return
        keys = tuple(_key(value) for value in args)
        self._held = tuple(value if key is None else weakref.ref(value) if type(value) is np.ndarray else None
                           for value, key in zip(args, keys))  # fmt: skip
        self._entry, self._keys = entry, keys


class TypedCalls:
    """A `TypedCall` of each kernel of `module`, made at its first use: ``calls.name(*args)``
    (one per holder: a system's own, whose NamedTuples are its model's)."""

    def __init__(self, module) -> None:
        self._module = module

    def __getattr__(self, name: str) -> TypedCall:
        call = TypedCall(getattr(self._module, name))
        setattr(self, name, call)
        return call
