"""Checks shared by the model, the laws and the model-file reader.

Each check returns the value in its canonical Python form or raises a `ModelError` that
names the element and what was expected.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence

from ..errors import ModelError

#: Largest magnitude accepted for any number in a model: beyond it, products of two
#: coordinates overflow or lose every significant digit.
MAX_MAGNITUDE = 1e15


def finite_float(value: object, element: str) -> float:
    """`value` as a float, if it is a real, finite number of sensible magnitude."""
    if type(value) is float and -MAX_MAGNITUDE <= value <= MAX_MAGNITUDE:  # the common case, fast
        return value
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ModelError(f"expected a number, got {_shown(value)}", element=element)
    number = float(value)
    if not math.isfinite(number):
        raise ModelError(f"expected a finite number, got {number!r}", element=element)
    if abs(number) > MAX_MAGNITUDE:
        raise ModelError(
            f"expected a number of magnitude at most {MAX_MAGNITUDE:g}, got {number!r}",
            element=element,
        )
    return number


def positive_int(value: object, element: str, minimum: int = 1) -> int:
    """`value` as an int, if it is a whole number >= `minimum`."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ModelError(f"expected a whole number, got {_shown(value)}", element=element)
    if value < minimum:
        raise ModelError(f"expected a whole number >= {minimum}, got {value}", element=element)
    return int(value)


def name(value: object, element: str) -> str:
    """`value`, if it is a non-empty string."""
    if not isinstance(value, str) or not value.strip():
        raise ModelError(f"expected a non-empty name, got {_shown(value)}", element=element)
    return value


def pair(value: object, element: str) -> tuple[float, float]:
    """`value` as ``(x, y)``, if it is a sequence of two finite numbers."""
    if isinstance(value, (str, bytes)) or not is_sequence(value) or len(value) != 2:
        raise ModelError(f"expected [x, y], got {_shown(value)}", element=element)
    return (finite_float(value[0], f"{element}[0]"), finite_float(value[1], f"{element}[1]"))


def point_reference(value: object, element: str) -> str | tuple[float, float]:
    """A point name, or coordinates ``(x, y)``."""
    if isinstance(value, str):
        return name(value, element)
    if not is_sequence(value):
        raise ModelError(
            f"expected a point name or [x, y], got {_shown(value)}", element=element
        )
    return pair(value, element)


def two_names(value: object, element: str) -> tuple[str, str]:
    """`value` as a pair of names, ``[i, j]``."""
    if type(value) in (tuple, list) and len(value) == 2 and type(value[0]) is type(value[1]) is str:
        if value[0].strip() and value[1].strip():  # the common case, fast
            return (value[0], value[1])
    if isinstance(value, str) or not is_sequence(value) or len(value) != 2:
        raise ModelError(f"expected two body names [i, j], got {_shown(value)}", element=element)
    return (name(value[0], f"{element}[0]"), name(value[1], f"{element}[1]"))


def names(value: object, element: str) -> tuple[str, ...]:
    """`value` as a tuple of names."""
    if type(value) in (tuple, list) and all(type(item) is str and item.strip() for item in value):
        return tuple(value)  # the common case, fast
    if isinstance(value, str) or not is_sequence(value):
        raise ModelError(f"expected a list of names, got {_shown(value)}", element=element)
    return tuple(name(item, f"{element}[{index}]") for index, item in enumerate(value))


def choice(value: object, element: str, allowed: Sequence[str]) -> str:
    """`value`, if it is one of `allowed`."""
    if not isinstance(value, str) or value not in allowed:
        expected = ", ".join(f'"{item}"' for item in allowed)
        raise ModelError(f"expected one of {expected}, got {_shown(value)}", element=element)
    return value


def number_list(value: object, element: str) -> tuple[float, ...]:
    """`value` as a tuple of finite numbers."""
    if isinstance(value, (str, bytes)) or not is_sequence(value):
        raise ModelError(f"expected a list of numbers, got {_shown(value)}", element=element)
    return tuple(finite_float(item, f"{element}[{index}]") for index, item in enumerate(value))


def non_negative_float(value: object, element: str) -> float:
    """`value` as a float, if it is a finite number >= 0."""
    number = finite_float(value, element)
    if number < 0.0:
        raise ModelError(f"expected a number >= 0, got {number!r}", element=element)
    return number


def known_list(known: Sequence[str], limit: int = 6) -> str:
    """Up to `limit` names for an error message, eliding the middle of long lists."""
    if len(known) <= limit:
        return ", ".join(known)
    return f"{', '.join(known[: limit - 2])} … {', '.join(known[-2:])}"


def is_sequence(value: object) -> bool:
    """A list-like value (a tuple, a list, an array), not a string or a mapping."""
    return type(value) in (tuple, list) or isinstance(value, Sequence) or (
        hasattr(value, "__len__") and hasattr(value, "__getitem__") and not isinstance(value, dict)
    )


def _shown(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


class FileKeys:
    """The keys a kind of element accepts in a model file.

    Parameters
    ----------
    required, optional : tuple of str
        Keys that must be given, and keys that may be given.
    forms : tuple of tuple of str
        Alternative groups of keys, exactly one of which must be given in full, e.g.
        ``(("axis",), ("at", "direction"))``.
    """

    __slots__ = ("required", "optional", "forms")

    def __init__(self, required: tuple[str, ...] = (), optional: tuple[str, ...] = (),
                 forms: tuple[tuple[str, ...], ...] = ()) -> None:  # fmt: skip
        self.required, self.optional, self.forms = tuple(required), tuple(optional), tuple(forms)

    @property
    def keys(self) -> tuple[str, ...]:
        """Every key, in the order they are listed and written."""
        return (*self.required, *(key for form in self.forms for key in form), *self.optional)

    def __repr__(self) -> str:
        return f"FileKeys(required={self.required}, optional={self.optional}, forms={self.forms})"


def limits(value: object, element: str) -> tuple[float, float]:
    """`value` as ``(minimum, maximum)``, two finite numbers with minimum < maximum."""
    if isinstance(value, (str, bytes)) or not is_sequence(value) or len(value) != 2:
        raise ModelError(f"expected [min, max], got {_shown(value)}", element=element)
    low, high = finite_float(value[0], f"{element}[0]"), finite_float(value[1], f"{element}[1]")
    if not low < high:
        raise ModelError(f"expected [min, max] with min < max, got [{low!r}, {high!r}]", element=element)
    return low, high


class ReadOnlyDict(dict):
    """A dict that cannot be changed: the tables of a built mechanism (its points, a unit's
    points, a repeat's attachments), which were checked when it was built.  Still a dict
    (``json.dumps``, ``dict(...)``, ``|`` giving a new dict) and picklable; to change one,
    build a new mechanism (``dataclasses.replace(mechanism, points={...})``).

    >>> points = ReadOnlyDict({"O": (0.0, 0.0)})
    >>> points["A"] = (1.0, 0.0)
    Traceback (most recent call last):
    ...
    TypeError: a built mechanism cannot be changed: build a new one, e.g. dataclasses.replace(mechanism, points={...})
    """

    __slots__ = ()

    def _refuse(self, *_, **__):
        raise TypeError("a built mechanism cannot be changed: build a new one, e.g. "
                        "dataclasses.replace(mechanism, points={...})")  # fmt: skip

    __setitem__ = __delitem__ = __ior__ = clear = pop = popitem = setdefault = update = _refuse

    def __reduce__(self):
        return (type(self), (dict(self),))
