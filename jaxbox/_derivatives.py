"""A function's value with its derivatives, in one pass.

``lambda p: (f(p), jax.jacfwd(f)(p))`` traces ``f`` twice: once for the value, once inside the
forward-mode Jacobian, whose primal computes the same value again. The program is larger than
it needs to be, and XLA compiles (and, where it does not merge the two, runs) the simulation
twice. The functions here take the value from the Jacobian's own primal (``has_aux``), so that
``f`` is traced once: a program of the same results with less to compile.
"""

from __future__ import annotations

from collections.abc import Callable

import jax

__all__ = ["value_and_jacfwd", "value_grad_hessian"]


def value_and_jacfwd(f: Callable) -> Callable:
    """``(p, *args) -> (f(p, *args), ∂f/∂p)``: the forward-mode Jacobian in its first argument
    (as ``jax.jacfwd(f)``), the value from the same pass."""

    def with_value(p, *args):
        y = f(p, *args)
        return y, y

    def both(p, *args):
        J, y = jax.jacfwd(with_value, has_aux=True)(p, *args)
        return y, J

    return both


def value_grad_hessian(f: Callable) -> Callable:
    """``(p, *args) -> (f, ∇f, ∇²f)`` of a scalar ``f`` in its first argument: the Hessian
    forward-over-reverse (as ``jax.hessian(f)``), the value and the gradient from the same
    pass."""

    def grad_with_value(p, *args):
        value, g = jax.value_and_grad(f)(p, *args)
        return g, (value, g)

    def all_three(p, *args):
        H, (value, g) = jax.jacfwd(grad_with_value, has_aux=True)(p, *args)
        return value, g, H

    return all_three
