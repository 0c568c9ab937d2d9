"""The one backend switch of the per-step hot path, and the package's one door to numba.

Every per-step rule (vision's nearest targets, input mapping, the controllers, the greedy
behaviours, the survival mechanics, the scheduler's bookkeeping) exists exactly twice, side by
side in the ``kernels`` module of the package that owns it: a compiled kernel (numba) and a
numpy reference with the same signature, which the parity tests compare
(``tests/test_kernel_parity.py``). Which of the two runs is decided once, when an owner object
is built (the runner, the survival world, a vision provider), by a ``backend`` argument that it
passes down to the objects it builds. Nothing checks a module flag inside a method.

Kernels take named buffers (``typing.NamedTuple`` of arrays and scalars, built once by the
object that owns the data) instead of long positional lists, so that a reordered producer
cannot bind the wrong array silently. :func:`bind` fixes a kernel's buffers once and returns a
call without arguments: for a compiled kernel it resolves the machine-code entry point for the
buffers' types at bind time, so a step pays neither numba's per-call type dispatch nor the
unboxing of dozens of separate arguments (see ``docs/design.md`` §3).
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal, TypeVar, cast

#: The packages whose ``kernels`` modules hold compiled code (found, not imported: the import
#: direction ``evolution -> behaviours -> cyber_rodent`` holds).
KERNEL_PACKAGES = ("cyber_rodent", "behaviours", "evolution")


def kernel_sources() -> list[Path]:
    """Every source file with compiled kernels: this module and each ``*kernels.py``."""
    files = [Path(__file__)]
    for name in KERNEL_PACKAGES:
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.origin is not None:
            files += sorted(Path(spec.origin).parent.rglob("*kernels.py"))
    return files


def compiled_cache_dir() -> Path:
    """Where numba caches this installation's compiled kernels.

    numba checks a cached function against its own source file only: a kernel that calls a
    kernel of another module would keep running the old callee after that module changed, and
    an index that names a renamed buffer type fails to load. The cache therefore lives in a
    directory named after a hash of every kernel source (and numba's version), so compiled code
    is reused only with exactly the sources it was compiled from. The base directory is
    ``$NUMBA_CACHE_DIR`` if set, else the user's cache directory.
    """
    digest = hashlib.sha256()
    for path in kernel_sources():
        digest.update(path.read_bytes())
    base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "cyber-rodent"
    )
    return Path(base) / f"numba-{numba_version}-{digest.hexdigest()[:16]}"


numba: Any
try:
    import numba

    numba_version = numba.__version__
    numba.config.CACHE_DIR = str(compiled_cache_dir())
except ImportError:  # pragma: no cover - numba is a dependency; backend="numpy" still works
    numba = None
    numba_version = ""

#: The two implementations of every per-step rule.
Backend = Literal["numba", "numpy"]
BACKENDS: tuple[Backend, ...] = ("numba", "numpy")
#: What every owner object uses unless told otherwise.
DEFAULT_BACKEND: Backend = "numba"

F = TypeVar("F", bound=Callable[..., Any])


def check_backend(backend: object) -> Backend:
    """Return ``backend`` if it is a usable backend name.

    Raises:
        ValueError: not one of :data:`BACKENDS` (the message lists them), or ``"numba"`` where
            numba cannot be imported.
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    if backend == "numba" and numba is None:  # pragma: no cover - numba is a dependency
        raise ValueError("backend 'numba' needs numba, which cannot be imported; use 'numpy'")
    return backend


def jit(function: F) -> F:
    """Compile ``function`` with ``numba.njit(cache=True, nogil=True)``.

    Compiled functions are cached on disk (:func:`compiled_cache_dir`), so a new process pays
    the compilation once per installation. Without numba the function is returned unchanged (the
    ``"numba"`` backend is then refused by :func:`check_backend`).
    """
    if numba is None:  # pragma: no cover
        return function
    return cast(F, numba.njit(cache=True, nogil=True)(function))


def jit_inline(function: F) -> F:
    """:func:`jit` for a helper of other kernels, inlined into every kernel that calls it.

    Named buffers are passed by value between compiled functions; a helper called per robot and
    target would copy them at every call, so it is inlined instead.
    """
    if numba is None:  # pragma: no cover
        return function
    return cast(F, numba.njit(cache=True, nogil=True, inline="always")(function))


def jit_built(function: F, *, inline: bool = False) -> F:
    """Compile a kernel that a factory builds at run time (a closure over other kernels, or a
    kernel's code rebuilt around other callees by :func:`with_callees`).

    Compiled in this process, never cached on disk: numba keys a closure's cache entry by its
    captured values, and a captured compiled function pickles differently in every process,
    so the entry would never be found again; a rebuilt kernel has the name, source file and
    code of the original it was built from, so it would find the original's entry and run the
    original's callees. With ``inline`` it is inlined into every kernel
    that calls it, as :func:`jit_inline`. Without numba the function is returned unchanged.
    """
    if numba is None:  # pragma: no cover
        return function
    options: dict[str, Any] = {"nogil": True}
    if inline:
        options["inline"] = "always"
    return cast(F, numba.njit(**options)(function))


def with_callees(function: F, **callees: Any) -> F:
    """``function``'s own code with some of the names it reads from its module bound to others.

    One source serves several builds: a fused kernel written once at module level (compiled
    with :func:`jit`, cached on disk) is built again around other callees, e.g. another
    controller's rule in place of the paper's. ``function`` is a compiled kernel or a plain
    function; the result is a plain function over a copy of its module's namespace in which each
    name of ``callees`` is bound to its value, to be compiled with :func:`jit_built`, never
    :func:`jit` (its cache entry would be the original's), or called as it is, for a numpy
    reference.

    Raises:
        ValueError: ``function`` reads no name of ``callees`` (a misspelling would otherwise
            build the original unchanged).
    """
    source = getattr(function, "py_func", function)
    code = source.__code__
    unread = sorted(set(callees) - set(code.co_names))
    if unread:
        raise ValueError(f"{source.__qualname__} reads no name {', '.join(unread)}")
    built = types.FunctionType(
        code, {**source.__globals__, **callees}, source.__name__, source.__defaults__,
        source.__closure__,
    )  # fmt: skip
    built.__qualname__ = source.__qualname__
    built.__doc__ = source.__doc__
    return cast(F, built)


def pick(backend: Backend, compiled: F, reference: F) -> F:
    """The compiled kernel for ``"numba"``, the numpy reference for ``"numpy"``."""
    return compiled if backend == "numba" else reference


def bind(kernel: Callable[..., Any], *buffers: Any) -> Callable[[], Any]:
    """``kernel`` with its arguments fixed: a call without arguments runs it on ``buffers``.

    For a compiled kernel the specialisation for the buffers' types is compiled (or loaded from
    the cache) now and its entry point is bound, skipping numba's per-call type dispatch. The
    buffers must keep their types for as long as the bound call is used: owners write into them
    in place and rebind whenever they replace one.
    """
    if numba is not None and isinstance(kernel, numba.core.registry.CPUDispatcher):
        purpose = numba.core.typing.typeof.Purpose.argument
        signature = tuple(numba.typeof(b, purpose) for b in buffers)
        return functools.partial(kernel.compile(signature), *buffers)
    return functools.partial(kernel, *buffers)


__all__ = [
    "BACKENDS",
    "DEFAULT_BACKEND",
    "KERNEL_PACKAGES",
    "Backend",
    "bind",
    "check_backend",
    "compiled_cache_dir",
    "jit",
    "jit_built",
    "jit_inline",
    "kernel_sources",
    "pick",
    "with_callees",
]
