"""One bounded cache of compiled functions, shared by every room that compiles.

The batched fit, the sensitivities at an optimum, the uncertainty analysis and the collocation
reference each compile functions once per problem *structure* (model structure, free/fixed
split, solver settings, array shapes) and reuse them across starts, bounds and datasets. They
all keep them here, under a key that starts with the room's name, so that one call,
:func:`clear`, frees every compiled executable, and the number kept is bounded (least recently
used first out).
"""

from __future__ import annotations

import re
import threading
import weakref
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Any

__all__ = [
    "cached",
    "clear",
    "release",
    "entries",
    "info",
    "set_max_entries",
    "compiler_options",
    "jit",
    "options_of",
]

_LOCK = threading.Lock()
_ENTRIES: OrderedDict[Hashable, Any] = OrderedDict()
_STATS = {"compiles": 0, "hits": 0, "evictions": 0}
_MAX = [128]


#: keys being built, each with the event its builder sets when done
_BUILDING: dict[Hashable, threading.Event] = {}


def cached(key: Hashable, build: Callable[[], Any]) -> tuple[Any, bool]:
    """The value stored under ``key``, built by ``build()`` on a miss.

    Returns ``(value, built)``: ``built`` is True when this call built it (a compilation).
    ``key`` should start with the name of the room that owns the entry (``("fit", …)``).
    A key is built once: a call for a key another thread is building (a program compiled
    ahead, in the background) waits for it, and builds it itself only if that build failed.
    """
    while True:
        with _LOCK:
            if key in _ENTRIES:
                _ENTRIES.move_to_end(key)
                _STATS["hits"] += 1
                return _ENTRIES[key], False
            pending = _BUILDING.get(key)
            if pending is None:
                done = _BUILDING[key] = threading.Event()
                break
        pending.wait()  # then look again: stored, or (its build failed) ours to build
    try:
        value = build()  # outside the lock: compiling can take seconds
        with _LOCK:
            _ENTRIES[key] = value
            _ENTRIES.move_to_end(key)
            _STATS["compiles"] += 1
            while len(_ENTRIES) > _MAX[0]:
                _ENTRIES.popitem(last=False)
                _STATS["evictions"] += 1
    finally:
        with _LOCK:
            _BUILDING.pop(key, None)
        done.set()
    return value, True


#: XLA options of jaxbox's large programs on a CPU: the classic loop emitters compile the
#: batched fits about a third faster than the fusion emitters and run them as fast
_CPU_OPTIONS = {"xla_cpu_use_fusion_emitters": False}


def compiler_options() -> dict[str, Any] | None:
    """XLA options for jaxbox's compiled programs on the default backend (``None``: XLA's own).

    On a CPU the batched fit of a structure search compiles one program per step; with the
    classic emitters each takes about a third less time, and runs as fast (measured on the
    14-parameter fit: 2.8–3.1 s against 4.2–5.5 s, 0.47 s run either way).
    ``JAXBOX_XLA_DEFAULTS=1`` keeps XLA's defaults.
    """
    import os

    import jax

    if os.environ.get("JAXBOX_XLA_DEFAULTS", "0").strip().lower() in ("1", "yes", "on", "true"):
        return None
    if jax.default_backend() != "cpu" or not _supported():
        return None
    return dict(_CPU_OPTIONS)


_SUPPORTED: list[bool] = []


def _supported() -> bool:
    """Whether this jaxlib's CPU compiler knows :data:`_CPU_OPTIONS` (XLA renames and retires
    its flags: jaxlib 0.11 has no ``xla_cpu_use_fusion_emitters``). Probed once, on a trivial
    program."""
    if not _SUPPORTED:
        import jax
        import jax.numpy as jnp

        try:
            jax.jit(lambda x: x + 1.0, compiler_options=dict(_CPU_OPTIONS)).lower(
                jnp.zeros(())
            ).compile()
            ok = True
        except Exception:  # noqa: BLE001 - an unknown option is reported as a runtime error
            ok = False
        _SUPPORTED[:] = [ok]
    return _SUPPORTED[0]


#: XLA options of a program that runs once per result (an exact Hessian at the optimum): the
#: backend's optimisations off halve its compilation and cost little in its one run
_ONCE_OPTIONS = {"xla_backend_optimization_level": 0}


#: XLA options of the batched fit (a loop of small per-sample operations): the backend's
#: optimisation level 1 instead of 2
_LEAN_OPTIONS = {"xla_backend_optimization_level": 1}


def jit(fun: Callable, *, once: bool = False, lean: bool = False, **kwargs) -> Callable:
    """``jax.jit`` with :func:`compiler_options`.

    ``once``: a program evaluated once per result, compiled without the backend's optimisations
    (the exact Hessian of a maximum-likelihood fit: 3.3 s of XLA compilation instead of 7.4 s,
    0.10 s to run instead of 0.06 s; a fit's data sensitivities, 10 parameters: 2.2 s to the
    first result instead of 3.7 s). ``lean``: the backend's optimisation level 1, for the
    batched fit, whose time goes to loops of small operations that the more expensive
    optimisations do not speed up: on the 2-core CPU (shared, load 6), the 14-parameter
    64-start fit compiled in 2.4 s instead of 2.9–3.2 s and ran in 1.49 s against 1.51–1.56 s;
    a structure search's batch of eight 15–18-parameter variants 3.0 s instead of 3.6–3.9 s,
    5.45 s against 5.0–5.6 s; the same results to the last digit.
    """
    import jax

    options = _options(once=once, lean=lean)
    jitted = jax.jit(fun, compiler_options=options, **kwargs)
    _OPTIONS_OF[jitted] = options
    return jitted


#: the compiler options each function of :func:`jit` was made with (weakly: they go with it)
_OPTIONS_OF: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def options_of(jitted: Callable) -> dict[str, Any] | None:
    """The XLA compiler options a function of :func:`jit` was made with (``None``: XLA's own,
    or a function not made by :func:`jit`)."""
    return _OPTIONS_OF.get(jitted)


def _options(*, once: bool = False, lean: bool = False) -> dict[str, Any] | None:
    """The compiler options of :func:`jit`."""
    options = compiler_options()
    if once and options is not None:
        options = {**options, **_ONCE_OPTIONS}
    elif lean and options is not None and _flag_level() is None:
        options = {**options, **_LEAN_OPTIONS}
    return options


def _flag_level() -> int | None:
    """The backend optimisation level ``XLA_FLAGS`` sets for the whole process (``None``: none
    set). A program's own options override the flags, so ``lean`` defers to a level set there
    (the tests set 0 to compile their many small programs fast; level 1 would raise it)."""
    import os

    m = re.search(r"--xla_backend_optimization_level=(\d+)", os.environ.get("XLA_FLAGS", ""))
    return None if m is None else int(m.group(1))


def clear() -> None:
    """Drop every compiled function of every room and reset the counters."""
    with _LOCK:
        _ENTRIES.clear()
        _STATS.update(compiles=0, hits=0, evictions=0)


def release() -> None:
    """:func:`clear`, and JAX's own caches of compiled functions too.

    A long run that compiles ever new structures (a structure search per building) keeps every
    executable mapped otherwise, until the process runs out of memory maps; with the persistent
    compilation cache on, what is needed again comes back from disk.
    """
    import jax

    clear()
    jax.clear_caches()


def info(room: str | None = None) -> dict:
    """``entries`` (of ``room``, or of all rooms), and the process-wide ``compiles``, ``hits``
    and ``evictions``."""
    with _LOCK:
        if room is None:
            n = len(_ENTRIES)
        else:
            n = sum(1 for k in _ENTRIES if isinstance(k, tuple) and k and k[0] == room)
        return {"entries": n, "max_entries": _MAX[0], **_STATS}


def entries(room: str) -> list:
    """The compiled functions kept for ``room``, least recently used first."""
    with _LOCK:
        return [v for k, v in _ENTRIES.items() if isinstance(k, tuple) and k and k[0] == room]


def set_max_entries(n: int) -> None:
    """Keep at most ``n`` ≥ 1 compiled functions (the least recently used go first)."""
    if int(n) < 1:
        raise ValueError(f"the cache needs room for at least one entry, got {n}")
    with _LOCK:
        _MAX[0] = int(n)
        while len(_ENTRIES) > _MAX[0]:
            _ENTRIES.popitem(last=False)
            _STATS["evictions"] += 1
