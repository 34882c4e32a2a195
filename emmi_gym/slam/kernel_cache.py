"""Where numba keeps the compiled kernels, and whether this install has compiled them yet.

The kernels are compiled on their first call (``@njit(cache=True)``: 2-3 minutes of the first run
on two cores) and cached on disk, where numba's own cache locators put them: ``$NUMBA_CACHE_DIR``
if set, else the ``__pycache__`` folder beside each source file where it is writable, else
numba's user-wide cache (``~/.cache/numba``). Later runs load them in about a second.
"""

from __future__ import annotations

import inspect
from pathlib import Path

from . import _kernels


def cache_folder(function) -> Path:
    """The folder numba caches the kernel ``function`` (a plain Python function) in, found as numba finds it."""
    from numba.core import caching

    source = inspect.getfile(function)
    for locator in (caching.UserProvidedCacheLocator, caching.InTreeCacheLocator, caching.UserWideCacheLocator):
        found = locator.from_function(function, source)
        if found is not None:
            return Path(found.get_cache_path())
    return Path(source).parent / "__pycache__"


def kernel_cache_folder() -> Path:
    """The folder numba caches the filter's kernels in (:mod:`emmi_gym.slam._kernels`)."""
    return cache_folder(_kernels.insert_scans.py_func)


def cached_kernels(modules) -> tuple[int, int]:
    """(cached, all) of the numba kernels in ``modules`` (the project compiles every kernel with ``cache=True``;
    those inlined into others, ``inline="always"``, are no kernels of their own): how many of them have an index
    file in numba's cache (compiled by this or any other process, worker processes included)."""
    from numba.core.dispatcher import Dispatcher

    kernels = {id(value): value for module in modules for value in vars(module).values()
               if isinstance(value, Dispatcher) and value.targetoptions.get("inline") != "always"}
    cached = 0
    for kernel in kernels.values():
        function = kernel.py_func
        stem = Path(inspect.getfile(function)).stem
        cached += any(cache_folder(function).glob(f"{stem}.{function.__qualname__}-*.nbi"))
    return cached, len(kernels)


def kernels_compiled() -> bool:
    """Whether the filter's kernels have been compiled into the cache (an index file of numba's for them)."""
    return any(kernel_cache_folder().glob(f"{Path(_kernels.__file__).stem}.*.nbi"))


def first_run_note() -> str | None:
    """A line for a command that is about to compile the kernels (``None`` once they are cached)."""
    if kernels_compiled():
        return None
    return (f"first run: numba compiles the kernels (2-3 minutes on two cores; once), caching them in "
            f"{kernel_cache_folder()}")
