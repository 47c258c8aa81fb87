"""``cached_njit``: numba's ``njit`` with its compiled kernels kept on disk between runs.

``cache=True`` keeps each compiled kernel in a ``__pycache__`` beside its source (or numba's
user-wide cache folder, or ``NUMBA_CACHE_DIR``), so only a first run compiles (the cpu renderer
and the fast encoder: about half a minute on 2 cores, a later run loads them in about a second).
Where none of those folders can be written, numba refuses ``cache=True`` when the kernel is
defined (a RuntimeError at import); ``cached_njit`` then compiles the kernel without a disk cache,
silently: every run compiles it again, nothing fails.
"""

from __future__ import annotations

from typing import Callable


def cached_njit(**options) -> Callable:
    """A decorator: ``numba.njit(cache=True, **options)``, or ``numba.njit(**options)`` when no
    cache folder is writable (module docstring)."""
    import numba

    def decorate(func):
        try:
            return numba.njit(cache=True, **options)(func)
        except RuntimeError:  # "cannot cache function ...: no locator available"
            return numba.njit(**options)(func)

    return decorate
