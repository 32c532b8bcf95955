"""The one set of numba options, and a cache that follows every numba module of the package.

Every compiled function of sparsekin is declared with ``njit(**JIT)``: cached on disk, no
``fastmath`` (finiteness checks on results must keep working), ``nogil``, and numpy's
error model (a division by zero gives inf or NaN, which the callers check, instead of an
exception).

numba decides whether a cached compilation is fresh from a stamp of the one source file
that defines the function.  A compiled function also carries the code of every function
it calls from other files (the time loop of `sparsekin.solve._compiled` inlines the kernels of
`sparsekin.engine._kernels`, the laws and the dense LU), so an edit of a kernel would leave the
loop's cache stale.  `register_cache_locator` installs a cache locator for the functions
of this package whose stamp is a digest of *every* module of the package that compiles
code: a change to any of them is a cache miss for all, and nothing on disk is deleted.
If numba's caching internals ever change shape, the locator is not installed and numba's
own per-file stamps apply.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

#: Options of every `numba.njit` in the package.  ``_nrt=True`` (numba's reference counting,
#: its default) is written out so that no function inherits the one exception: the time
#: loop of `sparsekin.solve._compiled_dynamics._advance_samples` is compiled without it
#: (``{**JIT, "_nrt": False}``), and numba would compile a function it calls for the first
#: time with the caller's flag.
JIT = dict(cache=True, nogil=True, error_model="numpy", _nrt=True)

_PACKAGE = Path(__file__).resolve().parent
_stamp: str | None = None


def package_stamp() -> str:
    """SHA-256 of the sources of every module of the package that uses numba."""
    global _stamp
    if _stamp is None:
        digest = hashlib.sha256()
        for path in sorted(_PACKAGE.rglob("*.py")):
            source = path.read_bytes()
            if b"njit" in source:
                digest.update(path.relative_to(_PACKAGE).as_posix().encode() + b"\0" + source)
        _stamp = digest.hexdigest()
    return _stamp


def register_cache_locator() -> bool:
    """Put the package-wide stamp in front of numba's cache locators; True if installed."""
    try:
        from numba.core import caching

        user_provided = getattr(caching, "UserProvidedCacheLocator", None) or caching._UserProvidedCacheLocator
        in_tree = getattr(caching, "InTreeCacheLocator", None) or caching._InTreeCacheLocator
        user_wide = getattr(caching, "UserWideCacheLocator", None) or caching._UserWideCacheLocator
        implementation = getattr(caching, "CacheImpl", None) or caching._CacheImpl
        locators = implementation._locator_classes
    except AttributeError:
        return False

    def of_package(base):
        class PackageLocator(base):
            """numba's `base` locator for this package's functions, stamped by `package_stamp`."""

            def get_source_stamp(self):
                return package_stamp()

            @classmethod
            def from_function(cls, py_func, py_file):
                if _PACKAGE not in Path(py_file).resolve().parents:
                    return None
                return super().from_function(py_func, py_file)

        PackageLocator.__name__ = PackageLocator.__qualname__ = f"Sparsekin{base.__name__.lstrip('_')}"
        return PackageLocator

    if not any(getattr(locator, "__name__", "").startswith("Sparsekin") for locator in locators):
        # numba's order: NUMBA_CACHE_DIR if set, the package's own folder if writable, the
        # user-wide folder.
        locators[0:0] = [of_package(user_provided), of_package(in_tree), of_package(user_wide)]
    return True


register_cache_locator()
