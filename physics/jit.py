"""The compile decorators every kernel uses, defined once.

* ``jit``: a cached, GIL-free kernel with numpy's error model (no zero-division checks: the
  kernels guard their own divisions).
* ``jit_inline``: the same, inlined into its callers at numba level. Small kernels that take
  arrays are inlined because a call that passes arrays costs an atomic reference-count increment
  and decrement per array, which inlining lets numba prune (vector control env: +25% throughput,
  +4 s cold compile).
* ``jit_parallel``: the same, with ``numba.prange`` spread over threads (the batch kernels).
* ``jit_uncounted``: ``jit`` without numba's reference counting (its runtime, the NRT): arrays
  are borrowed from the caller, never counted. numba counts a reference (an atomic increment and
  decrement) for each array an inlined helper takes, and its pruning leaves many of those in
  loops: in the many-body event loop (``solvers.exact_many_element``) they were two thirds of
  the kernel's time. Such a kernel must not allocate (``np.empty`` needs the runtime), and the
  kernels it calls inherit the setting unless they set it themselves: a callee that allocates
  is compiled with ``jit_counted`` (``jit`` with the counting set explicitly, so it keeps it).

Every function compiled through them is cached by ``physics.cache`` (a per-user directory, and a
freshness stamp that covers every module the kernel's module imports), and processes that would
compile it for the same signature at once take turns (``cache.take_turns``); other numba code in
the process keeps numba's own cache behaviour.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

import numba
from numba import types
from numba.extending import overload

from spinstrike.physics.cache import KernelCache, take_turns

__all__ = ["MAX_STATIC_IF_ARGS", "jit", "jit_counted", "jit_inline", "jit_parallel",
           "jit_uncounted", "static_if"]


def _compiler(**options: Any) -> Callable[[Callable[..., Any]], Any]:
    def decorate(fn: Callable[..., Any]) -> Any:
        dispatcher = numba.njit(nogil=True, error_model="numpy", **options)(fn)
        try:
            dispatcher._cache = KernelCache(fn)  # what numba's enable_caching() sets
            take_turns(dispatcher)
        except RuntimeError as exc:  # no writable cache directory at all
            warnings.warn(f"spinstrike: kernels are not cached ({exc}); they compile in every "
                          "process", RuntimeWarning, stacklevel=2)
        return dispatcher

    return decorate


jit = _compiler()
jit_inline = _compiler(inline="always")
jit_parallel = _compiler(parallel=True)
jit_uncounted = _compiler(_nrt=False)
jit_counted = _compiler(_nrt=True)



#: arguments of a call that CPython still compiles as a plain call (its ``STACK_USE_GUIDELINE``);
#: more, and the call builds a tuple and passes ``*args``
MAX_STATIC_IF_ARGS = 30


def static_if(fn: Any, negate: bool = False, level: int = 1,
              otherwise: Any = None) -> Callable[..., Any]:
    """A kernel-callable ``g(flag, *args)`` that calls ``fn(*args)`` if ``flag >= level`` (if
    not, with ``negate``): a *static* if when ``flag`` is a compile-time literal, a boolean or
    an integer level (``kernels.FLAGS``), for then a call ruled out is never typed or compiled.
    numba's own branch pruning does not act on literal booleans, so ``if flag: fn(...)`` would
    compile ``fn`` for every scene; for a non-literal flag ``g`` is an ordinary run-time ``if``.
    (A literal that allows the call compiles the call alone.)

    With ``otherwise`` (a kernel of ``fn``'s parameters returning what ``fn`` returns), ``g``
    returns ``fn(*args)``, or ``otherwise(*args)`` where the flag rules ``fn`` out; without it
    ``g`` returns None.

    ``g`` is an ``overload`` inlined into its caller (no compiled layer of its own: each layer
    above the solver costs a compile of its own), which needs ``fn``'s exact parameter list, so
    ``g`` and its implementations are generated for that arity. ``fn`` takes at most
    :data:`MAX_STATIC_IF_ARGS` - 1 parameters: Python compiles a call of more than 30 arguments
    (``g``'s, the flag first) as a call with ``*args``, which numba cannot inline.
    """
    py_func = getattr(fn, "py_func", fn)  # a plain function under NUMBA_DISABLE_JIT
    if py_func.__code__.co_argcount + 1 > MAX_STATIC_IF_ARGS:
        raise TypeError(f"static_if({py_func.__name__}): {py_func.__code__.co_argcount} "
                        f"parameters, at most {MAX_STATIC_IF_ARGS - 1} (the call with the flag "
                        f"would have more than {MAX_STATIC_IF_ARGS} arguments, which numba "
                        "cannot inline)")
    params = ", ".join(f"a{i}" for i in range(py_func.__code__.co_argcount))
    test = f"not flag >= {int(level)}" if negate else f"flag >= {int(level)}"
    scope: dict[str, Any] = {"fn": fn, "otherwise": otherwise, "negate": negate,
                             "level": level, "types": types}
    if otherwise is None:
        run, skip = f"fn({params})", "None"
    else:
        run, skip = f"return fn({params})", f"otherwise({params})"
    exec(f"def g(flag, {params}):\n    if {test}:\n        {run}\n"  # noqa: S102
         f"    return {skip}\n"
         f"def call(flag, {params}):\n    {run}\n"
         f"def skip(flag, {params}):\n    return {skip}\n"
         f"def typed(flag, {params}):\n"
         f"    if isinstance(flag, (types.BooleanLiteral, types.IntegerLiteral)):\n"
         f"        return skip if (int(flag.literal_value) >= level) == negate else call\n"
         f"    return g\n", scope)
    g = scope["g"]
    overload(g, prefer_literal=True, inline="always")(scope["typed"])
    g.__name__ = g.__qualname__ = f"{'unless' if negate else 'if'}_{fn.__name__}"
    return g
