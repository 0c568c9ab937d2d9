"""The package's one door to numba: the decorator every compiled kernel uses.

The per-step hot path (geometric vision, behaviours, controller, input mapping, contact scan)
is compiled with numba where it is installed (it is a dependency); each kernel module keeps a
numpy reference implementation that is used if numba cannot be imported, and that the tests
compare the kernels with. Compiled functions are cached on disk next to their source, so a new
process pays the compilation once per installation.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

try:
    import numba
except ImportError:  # pragma: no cover - numba is a dependency; this keeps numpy working
    numba = None

#: numba can be imported, so the kernels are compiled.
AVAILABLE = numba is not None


def jit(function: Callable[..., Any] | None = None, *, cache: bool = True) -> Any:
    """``numba.njit(cache=cache, nogil=True)``; without numba, the plain Python function.

    Usable bare (``@jit``) or with arguments (``@jit(cache=False)``).
    """
    if function is None:
        return lambda f: jit(f, cache=cache)
    if numba is None:  # pragma: no cover
        return function
    return numba.njit(cache=cache, nogil=True)(function)
