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

The fit's normal equations have the same form (:func:`normal_equations_parallel`): the state,
then its sensitivities, each an affine recursion with the observer's pull and the restarts of
segments folded into the per-sample maps. On an H100 they make one start of the 14-parameter
fit 9× faster and 64 starts 8× (``benchmarks/GPU.md``); :func:`prefer_parallel` picks them on an
accelerator for batches of up to 1024 members whose sensitivities fit in 256 MB.
"""

from __future__ import annotations

import os

import jax
import jax.numpy as jnp
from jax import lax

from ._exact import (
    _drive,
    _spread,
    _take,
    discretize_foh,
    normal_equations,
    segment_index,
)

__all__ = [
    "linear_recurrence",
    "simulate_parallel",
    "simulate_foh_parallel",
    "normal_equations_parallel",
    "normal_equations_auto",
    "prefer_parallel",
]


def _compose(first, second):
    """The affine map ``first`` then ``second``: ``(A₂A₁, A₂b₁ + b₂)`` for A [..., n, n] and
    b [..., n, r] (any leading axes)."""
    A1, b1 = first
    A2, b2 = second
    return A2 @ A1, A2 @ b1 + b2


def linear_recurrence(Phi, drive, x0):
    """All states of ``x_{k+1} = Φ x_k + d_k``: returns ``[x_0, …, x_K]``, shape [K+1, n, …].

    Args:
        Phi: the transition matrix [n, n] (the same at every step).
        drive: ``d_k``, shape [K, n, …] (trailing axes, e.g. sensitivities, ride along).
        x0: the initial state [n, …].
    """
    K, n = drive.shape[0], Phi.shape[0]
    mats = jnp.broadcast_to(Phi, (K, n, n))
    A, b = lax.associative_scan(_compose, (mats, drive.reshape(K, n, -1)))
    xs = (A @ x0.reshape(n, -1) + b).reshape(drive.shape)
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


#: most bytes of sensitivities [N, B, n, q] that :func:`normal_equations_parallel` holds at once
_PARALLEL_BYTES = 1 << 28
#: widest batch run parallel in time: on an H100 it wins at 1024 members (1.4–2×) and loses at
#: 4096 (0.74×), where the sequential scan already fills the device (``benchmarks/GPU.md``)
_PARALLEL_BATCH = 1024


def prefer_parallel(n_samples: int, batch: int, n: int, q: int, platform: str | None = None):
    """Whether the fit's normal equations should run parallel in time.

    On an accelerator the sequential scan costs about the same few microseconds a sample for 1
    or 10³ members (``benchmarks/GPU.md``), so a narrow batch leaves the device idle; the
    associative scan runs ~2 log₂ N wide steps instead. It holds every sample's sensitivities at
    once, so only up to :data:`_PARALLEL_BYTES` of them, and only for up to
    :data:`_PARALLEL_BATCH` members (wider batches already fill the device).
    Never on a CPU, where the associative scan's extra work is not free.
    ``JAXBOX_PARALLEL_IN_TIME=1`` (or ``0``) forces the choice, read when a fit is compiled.
    """
    forced = os.environ.get("JAXBOX_PARALLEL_IN_TIME", "").strip().lower()
    if forced in ("1", "yes", "on", "true"):
        return True
    if forced in ("0", "no", "off", "false"):
        return False
    platform = jax.default_backend() if platform is None else platform
    return (
        platform != "cpu"
        and batch <= _PARALLEL_BATCH
        and 8 * n_samples * batch * n * (q + 1) <= _PARALLEL_BYTES
    )


def _affine_scan(A, b):
    """Prefix compositions of ``s_k = A_k s_{k−1} + b_k`` for A [N, B, n, n], b [N, B, n, …]
    with ``A_0 = 0``: every ``s_k``, shape of ``b``."""
    flat = b.reshape(b.shape[:3] + (-1,))
    return lax.associative_scan(_compose, (A, flat))[1].reshape(b.shape)


def normal_equations_parallel(mats, tangents, outputs, u, y, w, *, t=None, gain=None, chunk=None):
    """:func:`~jaxbox.simulate._exact.normal_equations`, parallel in time (same arguments and
    results; ``chunk`` is ignored: every sample's sensitivities are held at once).

    The state, then its sensitivities, follow from two associative scans over the samples: a
    sample's map ``s ↦ Φ (I − P_k) s + c_k`` (``P_k`` the observer's pull of the measured states
    at sample ``k``, zero without a gain) composes associatively, and a segment's first sample
    is the constant map to its initial state. The products ``Σ r²``, ``Jᵀr`` and ``JᵀJ`` are then
    one contraction over the samples.
    """
    Phi, G0, G1, x0 = mats
    dPhi, dG0, dG1, dx0 = tangents
    outputs = tuple(int(o) for o in outputs)
    n_samples = u.shape[0]
    batch, n = Phi.shape[:2]
    du = jnp.concatenate([u[1:] - u[:-1], jnp.zeros_like(u[:1])], axis=0)
    d = _drive(u, du, G0, G1)[:-1]  # [N−1, B, n]
    if gain is None:
        M = jnp.broadcast_to(Phi, (n_samples - 1,) + Phi.shape)
        c = d
    else:  # the pull x ← x − P_k (x − y_k) on the measured rows: the map Φ (I − P_k), Φ P_k y_k
        P = jax.vmap(lambda p: _spread(p, outputs, n))(gain[None, :, None] * (w > 0))  # [N, B, n]
        Py = P * jax.vmap(lambda v: _spread(v, outputs, n))(
            jnp.broadcast_to(y, (n_samples, batch, len(outputs)))
        )
        M = Phi[None] * (1.0 - P[:-1])[:, :, None, :]  # [N−1, B, n, n]
        c = jnp.einsum("bij,kbj->kbi", Phi, Py[:-1]) + d
    # the first sample is the constant map to the initial state (A = 0)
    A = jnp.concatenate([jnp.zeros((1, batch, n, n), Phi.dtype), M], axis=0)
    segmented = x0.ndim == 3
    if segmented:  # and so is every segment's first sample, to that segment's initial state
        first, index = segment_index(t, x0.shape[1])  # [N, Bt]
        first = jnp.broadcast_to(first, (n_samples, batch))
        rows = jnp.arange(batch)[None, :]
        index = jnp.broadcast_to(index, (n_samples, batch))
        starts, dstarts = x0[rows, index], dx0[rows, index]  # [N, B, n], [N, B, n, q]
        A = jnp.where(first[..., None, None], 0.0, A)
        x0, dx0 = starts[0], dstarts[0]
    b = jnp.concatenate([x0[None], c], axis=0)
    if segmented:
        b = jnp.where(first[..., None], starts, b)
    x = _affine_scan(A, b)  # [N, B, n]: the state at each sample, before the pull
    # the sensitivities: X_{k+1} = Φ (I − P_k) X_k + ∂Φ xc_k + ∂Γ0 u_k + ∂Γ1 Δu_k
    xc = x if gain is None else x - P * x + Py  # the state after the pull
    e = jnp.einsum("bijq,kbj->kbiq", dPhi, xc[:-1]) + _drive(u, du, dG0, dG1)[:-1]
    bX = jnp.concatenate([dx0[None], e], axis=0)
    if segmented:
        bX = jnp.where(first[..., None, None], dstarts, bX)
    X = _affine_scan(A, bX)  # [N, B, n, q]
    r = w * (_take(x, outputs, axis=2) - y)  # [N, B, p]
    Jw = w[..., None] * _take(X, outputs, axis=2)  # [N, B, p, q]
    cost = jnp.einsum("kbo,kbo->b", r, r)
    g = jnp.einsum("kbo,kboq->bq", r, Jw)
    H = jnp.einsum("kboq,kbol->bql", Jw, Jw)
    return cost, g, H


def normal_equations_auto(mats, tangents, outputs, u, y, w, **kwargs):
    """:func:`~jaxbox.simulate._exact.normal_equations` in time order, or
    :func:`normal_equations_parallel` where :func:`prefer_parallel` says it pays (an
    accelerator, a batch of up to 1024 members); the same arguments and results."""
    batch, n = mats[0].shape[:2]
    fast = prefer_parallel(u.shape[0], batch, n, tangents[0].shape[-1])
    return (normal_equations_parallel if fast else normal_equations)(
        mats, tangents, outputs, u, y, w, **kwargs
    )
