"""Parallel-in-time simulation: the first-order-hold recursion as an associative scan.

The recursion ``x_{k+1} = Φ x_k + d_k`` composes affine maps ``x ↦ Φ x + d``; composition is
associative, ``(Φ₂, d₂) ∘ (Φ₁, d₁) = (Φ₂Φ₁, Φ₂d₁ + d₂)``, so all states follow from a prefix
scan (``jax.lax.associative_scan``) in ``O(log N)`` sequential levels instead of ``N`` steps, at
``O(N n³)`` work instead of ``O(N n²)``. Where that wins:

* on a GPU, for long series: the sequential scan launches one tiny step per sample and leaves the
  device idle, the associative scan runs ~2 log₂ N wide batched matrix products;
* on a CPU, only for a few states and long series, and not under a wide batch of starts, where
  the sequential scan already fills the vector units (``benchmarks/RESULTS.md`` has the numbers).

Results agree with :func:`~jaxbox.simulate.simulate_exact` to round-off (the products are
summed in a different order).
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import lax

from ._exact import discretize_foh

__all__ = ["linear_recurrence", "simulate_parallel", "simulate_foh_parallel"]


def linear_recurrence(Phi, drive, x0):
    """All states of ``x_{k+1} = Φ x_k + d_k``: returns ``[x_0, …, x_K]``, shape [K+1, n, …].

    Args:
        Phi: the transition matrix [n, n] (the same at every step).
        drive: ``d_k``, shape [K, n, …] (trailing axes, e.g. sensitivities, ride along).
        x0: the initial state [n, …].
    """
    K, n = drive.shape[0], Phi.shape[0]
    mats = jnp.broadcast_to(Phi, (K, n, n))

    def compose(first, second):
        # apply `first`, then `second`
        A1, b1 = first
        A2, b2 = second
        return A2 @ A1, jnp.einsum("kij,kj...->ki...", A2, b1) + b2

    A, b = lax.associative_scan(compose, (mats, drive))
    xs = jnp.einsum("kij,j...->ki...", A, x0) + b
    return jnp.concatenate([x0[None], xs], axis=0)


def simulate_foh_parallel(Phi, G0, G1, C, D, x0, u):
    """:func:`~jaxbox.simulate._exact.simulate_foh` by associative scan: (y [N, p], x [N, n])."""
    drive = u[:-1] @ G0.T + (u[1:] - u[:-1]) @ G1.T
    xs = linear_recurrence(Phi, drive, x0)
    return xs @ C.T + u @ D.T, xs


def simulate_parallel(A, B, C, D, x0, u, dt):
    """Same as :func:`~jaxbox.simulate.simulate_exact`, parallel in time.

    ``u`` [N, m] at a regular step ``dt`` [s]; returns (y [N, p], x [N, n]) with ``x[0] = x0``.
    """
    Phi, G0, G1 = discretize_foh(A, B, dt)
    return simulate_foh_parallel(Phi, G0, G1, C, D, x0, u)
