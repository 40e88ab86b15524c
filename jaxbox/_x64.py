"""float64 for JAX: every jaxbox computation runs in double precision.

jaxbox does not flip JAX's global precision switch as an import side effect. The command-line
entry point and the test suite enable it; in Python call :func:`enable_x64` once, before creating
any JAX array (or set the environment variable ``JAX_ENABLE_X64=1``). Public numerical entry
points refuse to run in float32, where parameter recovery degrades to about 0.2 %.
"""

from __future__ import annotations

import jax

__all__ = ["enable_x64", "require_x64", "PrecisionError"]


class PrecisionError(RuntimeError):
    """JAX is running in float32; jaxbox needs float64."""


def enable_x64() -> None:
    """Switch JAX to float64 (``jax_enable_x64``). Call before creating any JAX array."""
    jax.config.update("jax_enable_x64", True)


def require_x64() -> None:
    """Raise :class:`PrecisionError` unless JAX runs in float64."""
    if not jax.config.jax_enable_x64:
        raise PrecisionError(
            "jaxbox needs float64: call jaxbox.enable_x64() right after importing jaxbox "
            "(before creating JAX arrays), or set the environment variable JAX_ENABLE_X64=1"
        )
