"""Compiled functions cached on disk, where a damaged cache file is a cache miss rather than an error.

numba keeps each cached function in an index file (``.nbi``) and data files
(``.nbc``).  A write cut short (a killed process, a full disk) leaves a file
that no longer unpickles, and numba then raises ``EOFError`` or
``UnpicklingError`` from every call of the function, in every process, until
someone deletes the file.  :func:`cached_njit` compiles like ``numba.njit``
with ``cache=True`` and ``nogil=True``, and guards the load of a cached
version: a cache that cannot be read is set aside (its index removed), a
:class:`~hammerstein_ctrl.exceptions.CacheWarning` says which function it was,
and the function is compiled again and saved afresh.

Examples
--------
>>> @cached_njit(cache=False)
... def twice(x):
...     return 2.0 * x
>>> twice(1.5)
3.0
"""

from __future__ import annotations

import os
import warnings

import numba

from .exceptions import CacheWarning

__all__ = ["cached_njit", "tolerate_damaged_cache"]


def cached_njit(*, cache: bool = True, **options):
    """``numba.njit(cache=cache, nogil=True, **options)``, its cache made tolerant (:func:`tolerate_damaged_cache`).

    Parameters
    ----------
    cache : bool, default True
        Keep the compiled code on disk (numba's cache).
    **options
        Further options of ``numba.njit`` (``fastmath``, ``error_model``, ...).

    Returns
    -------
    callable
        A decorator.
    """
    def decorate(fn):
        return tolerate_damaged_cache(numba.njit(cache=cache, nogil=True, **options)(fn))
    return decorate


def tolerate_damaged_cache(dispatcher):
    """Make a cache file of ``dispatcher`` that cannot be read a cache miss: compiled again, with a warning.

    The guard wraps the one method numba calls to load a cached version (once
    per signature and process), so calls cost nothing more.  A dispatcher
    without a disk cache is returned unchanged.
    """
    cache = getattr(dispatcher, "_cache", None)
    load = getattr(cache, "load_overload", None)
    if load is None:
        return dispatcher

    def load_overload(sig, target_context):
        try:
            return load(sig, target_context)
        except Exception as exc:       # any failure to read back cached code: compile it again
            _set_aside(cache)
            warnings.warn(f"numba's cache of {dispatcher.py_func.__module__}.{dispatcher.py_func.__qualname__} "
                          f"could not be read ({type(exc).__name__}: {exc}); compiled again and saved afresh",
                          CacheWarning, stacklevel=2)
            return None

    cache.load_overload = load_overload
    return dispatcher


def _set_aside(cache):
    """Remove the cache's index file, so the next save writes a new index and data file instead of reading it."""
    index = getattr(getattr(cache, "_cache_file", None), "_index_path", None)
    if index:
        try:
            os.remove(index)
        except OSError:
            pass
