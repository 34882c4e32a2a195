"""Where numba keeps the compiled kernels, and whether this install has compiled them yet.

The kernels are compiled on their first call (``@njit(cache=True)``: 2-3 minutes of the first run
on two cores) and cached on disk, where numba's own cache locators put them: ``$NUMBA_CACHE_DIR``
if set, else the ``__pycache__`` folder beside each source file where it is writable, else
numba's user-wide cache (``~/.cache/numba``). Later runs load them in about a second.
"""

from __future__ import annotations

from pathlib import Path

from . import _kernels


def kernel_cache_folder() -> Path:
    """The folder numba caches the filter's kernels in (:mod:`emmi_gym.slam._kernels`), found as numba finds it."""
    from numba.core import caching

    source = _kernels.__file__
    for locator in (caching.UserProvidedCacheLocator, caching.InTreeCacheLocator, caching.UserWideCacheLocator):
        found = locator.from_function(_kernels.insert_scans.py_func, source)
        if found is not None:
            return Path(found.get_cache_path())
    return Path(source).parent / "__pycache__"


def kernels_compiled() -> bool:
    """Whether the filter's kernels have been compiled into the cache (an index file of numba's for them)."""
    return any(kernel_cache_folder().glob(f"{Path(_kernels.__file__).stem}.*.nbi"))


def first_run_note() -> str | None:
    """A line for a command that is about to compile the kernels (``None`` once they are cached)."""
    if kernels_compiled():
        return None
    return (f"first run: numba compiles the kernels (2-3 minutes on two cores; once), caching them in "
            f"{kernel_cache_folder()}")
