"""Exact discretisation of a linear model with inputs linear between samples (first-order hold).

For ``dx/dt = A x + B u(t)`` with ``u`` linear on ``[t_k, t_k + Δt]``::

    x_{k+1} = Φ x_k + Γ0 u_k + Γ1 (u_{k+1} − u_k)

with ``Φ = e^{AΔt}``, ``Γ0 = ∫_0^Δt e^{As} ds B`` and ``Γ1 = ∫_0^Δt e^{As} (1 − s/Δt) ds B``, all
read from one matrix exponential of the block matrix ``[[AΔt, BΔt, 0], [0, 0, I], [0, 0, 0]]``
(Van Loan). The recursion is a ``lax.scan`` whose input drive is computed up front, so the scan
carries only the state. This is exact up to round-off for regular sampling.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import lax

__all__ = ["discretize_foh", "simulate_exact"]


def discretize_foh(A, B, dt):
    """First-order-hold discretisation: returns (Φ, Γ0, Γ1) for the step ``dt`` [s]."""
    n, m = B.shape
    M = jnp.zeros((n + 2 * m, n + 2 * m), dtype=A.dtype)
    M = M.at[:n, :n].set(A * dt).at[:n, n : n + m].set(B * dt)
    M = M.at[n : n + m, n + m :].set(jnp.eye(m, dtype=A.dtype))
    E = jax.scipy.linalg.expm(M)
    return E[:n, :n], E[:n, n : n + m], E[:n, n + m :]


def simulate_exact(A, B, C, D, x0, u, dt):
    """Simulate at the samples: u [N, m] at a regular step dt [s]; returns (y [N, p], x [N, n]).

    ``x[0] = x0`` and ``y[k] = C x[k] + D u[k]``.
    """
    Phi, G0, G1 = discretize_foh(A, B, dt)
    drive = u[:-1] @ G0.T + (u[1:] - u[:-1]) @ G1.T

    def step(x, d):
        x = Phi @ x + d
        return x, x

    _, xs = lax.scan(step, x0, drive)
    xs = jnp.concatenate([x0[None, :], xs], axis=0)
    return xs @ C.T + u @ D.T, xs
