"""Exact discretisation of the stochastic form and the continuous–discrete Kalman filter.

Between two samples ``t_k`` and ``t_{k+1} = t_k + Δt`` the SDE ``dx = (A x + B u) dt + σ dω``
integrates exactly to ::

    x_{k+1} = Φ x_k + Γ0 u_k + Γ1 (u_{k+1} − u_k) + w_k,   w_k ~ N(0, Q)

with ``Φ = e^{AΔt}``, the input matrices of a zero-order hold (``Γ1 = 0``) or a first-order hold
(:func:`~jaxbox.simulate._exact.discretize_foh_rc`) and the process-noise covariance
``Q = ∫_0^Δt e^{As} σσᵀ e^{Aᵀs} ds`` from one matrix exponential (Van Loan 1978)::

    expm([[−A, σσᵀ], [0, Aᵀ]] Δt) = [[·, F12], [0, F22]],   Q = F22ᵀ F12.

The noise does not depend on the hold of the inputs, so Q is the same for both.

The filter (:func:`kalman_scan`) runs in ``lax.scan``: at each sample the innovation
``ε_k = y_k − C x̂_{k|k−1} − D u_k`` with covariance ``S_k = C P_{k|k−1} Cᵀ + R`` (Cholesky
factor), the update in Joseph form ``P = (I − KC) P (I − KC)ᵀ + K R Kᵀ`` (symmetric positive
definite by construction), and the prediction ``P_{k+1|k} = Φ P Φᵀ + Q``, symmetrised. A missing
output (NaN) gets a zero row of ``C`` and a unit variance, so it neither updates the state nor
counts in the likelihood. The negative log-likelihood is

    NLL = ½ Σ_k (log det S_k + ε_kᵀ S_k⁻¹ ε_k + p_k log 2π)

(natural log; ``p_k`` outputs observed at sample ``k``).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
from jax import lax

from ..simulate._exact import discretize_foh_rc

__all__ = ["process_noise", "process_noise_van_loan", "discretize", "kalman_scan", "HOLDS"]

HOLDS = ("zoh", "foh")
_LOG2PI = math.log(2.0 * math.pi)


def process_noise_van_loan(A, sigma, dt):
    """Van Loan: ``Q = ∫_0^dt e^{As} diag(σ²) e^{Aᵀs} ds`` [K²] for diffusions σ [K/√s], from
    one matrix exponential of the block matrix ``[[−A, σσᵀ], [0, Aᵀ]] dt``."""
    n = A.shape[-1]
    Sig = jnp.diag(sigma**2)
    M = jnp.zeros((2 * n, 2 * n), dtype=A.dtype)
    M = M.at[:n, :n].set(-A * dt).at[:n, n:].set(Sig * dt).at[n:, n:].set(A.T * dt)
    F = jax.scipy.linalg.expm(M)
    Q = F[n:, n:].T @ F[:n, n:]
    return 0.5 * (Q + Q.T)


def process_noise(A, sigma, dt, Phi, held=None):
    """The Van Loan integral ``Q = ∫_0^dt e^{As} diag(σ²) e^{Aᵀs} ds`` [K²], through the
    Lyapunov identity ``A Q + Q Aᵀ = Φ Σ Φᵀ − Σ`` (``Φ = e^{A dt}``, ``Σ = diag(σ²)``).

    The identity follows from integrating ``d/ds (e^{As} Σ e^{Aᵀs})`` over the step; it is
    solved on the nodes that are not held at a constant temperature (their block of ``A`` is
    stable, so the Kronecker-sum operator is invertible; held nodes have no diffusion and their
    rows of Q are zero). Same value as :func:`process_noise_van_loan` but a small linear solve
    instead of a matrix exponential: far cheaper to differentiate twice (the exact Hessian).
    """
    n = A.shape[-1]
    held = tuple(bool(h) for h in (held or (False,) * n))
    free = [i for i in range(n) if not held[i]]
    k = len(free)
    if k == 0:
        return jnp.zeros((n, n), dtype=A.dtype)
    fi = jnp.asarray(free)
    Af, Pf, s2 = A[fi][:, fi], Phi[fi][:, fi], sigma[fi] ** 2
    rhs = (Pf * s2[None, :]) @ Pf.T - jnp.diag(s2)
    eye = jnp.eye(k, dtype=A.dtype)
    K = jnp.kron(Af, eye) + jnp.kron(eye, Af)
    Qf = jnp.linalg.solve(K, rhs.reshape(-1)).reshape(k, k)
    Qf = 0.5 * (Qf + Qf.T)
    if k == n:
        return Qf
    return jnp.zeros((n, n), dtype=A.dtype).at[jnp.ix_(fi, fi)].set(Qf)


def discretize(A, B, caps, held, sigma, dt, hold: str = "foh"):
    """``(Φ, Γ0, Γ1, Q)`` of the stochastic model for the step ``dt`` [s]; ``Γ1 = 0`` for a
    zero-order hold."""
    Phi, G0, G1 = discretize_foh_rc(A, B, caps, dt, held)
    if hold == "zoh":
        # a constant input over the step: Γ0 is the same integral ∫ e^{As} ds B
        G1 = jnp.zeros_like(G1)
    elif hold != "foh":
        raise ValueError(f"unknown hold {hold!r}; choose one of {HOLDS}")
    return Phi, G0, G1, process_noise(A, sigma, dt, Phi, held)


def _sym(P):
    return 0.5 * (P + P.T)


#: up to this many states the filter's products are written as broadcast multiplications and
#: sums (fused loops); beyond, as matrix products
SMALL_STATES = 6


def _product(small: bool):
    """``a @ b`` for vectors and matrices; with ``small``, as a broadcast product summed over
    the shared axis. On a CPU, XLA emits the matrix products of the filter's step (4 × 4 and
    up) as calls to a matrix-multiplication routine, each with an overhead far above its
    arithmetic; the broadcast form fuses into the step's loops: a filter of 4–6 states with its
    gradient runs 4–6 times faster this way (3 states and fewer: the same)."""
    if not small:
        return jnp.matmul

    def mm(a, b):
        if a.ndim == 1:
            return jnp.sum(a[:, None] * b, axis=0)
        if b.ndim == 1:
            return jnp.sum(a * b[None, :], axis=1)
        return jnp.sum(a[:, :, None] * b[None, :, :], axis=1)

    return mm


def kalman_scan(mats, Cm, D, r, m0, P0, u, y, *, full: bool = False):
    """Run the filter over one series.

    Args:
        mats: ``(Φ [n,n], Γ0 [n,m], Γ1 [n,m], Q [n,n])``.
        Cm, D: output matrices [p,n], [p,m].
        r: measurement-noise standard deviations [p] (K).
        m0, P0: mean [n] and covariance [n,n] of the initial state.
        u: inputs [N, m]; y: outputs [N, p], NaN where missing.
        full: also return the per-sample quantities (else only the NLL).

    Returns:
        ``nll`` (a scalar), or with ``full`` a dict: ``nll``, ``innov`` [N,p] (NaN where
        missing), ``S`` [N,p,p], ``m_pred``, ``P_pred`` (before the update at each sample),
        ``m_filt``, ``P_filt`` (after it).
    """
    Phi, G0, G1, Q = mats
    n = Phi.shape[0]
    eye = jnp.eye(n, dtype=Phi.dtype)
    single = Cm.shape[0] == 1
    mm = _product(n <= SMALL_STATES)
    ok = jnp.isfinite(y)
    y0 = jnp.where(ok, y, 0.0)
    du = jnp.concatenate([u[1:] - u[:-1], jnp.zeros_like(u[:1])], axis=0)
    drive = u @ G0.T + du @ G1.T  # drive[k]: from sample k to k+1
    r2 = r**2

    def step(carry, data):
        m, P = carry
        yk, okk, uk, dk = data
        okf = okk.astype(m.dtype)
        Ck = Cm * okf[:, None]
        e = jnp.where(okk, yk - mm(Cm, m) - mm(D, uk), 0.0)
        Rk = jnp.diag(jnp.where(okk, r2, 0.0))
        PCt = mm(P, Ck.T)
        S = _sym(mm(Ck, PCt) + Rk + jnp.diag(1.0 - okf))
        if single:  # one output: scalar innovation variance, no factorisation
            s = S[0, 0]
            K = PCt / s
            quad = e[0] * e[0] / s
            logdet = jnp.log(s)
        else:
            L = jnp.linalg.cholesky(S)
            K = jax.scipy.linalg.cho_solve((L, True), PCt.T).T
            a = jax.scipy.linalg.solve_triangular(L, e, lower=True)
            quad = a @ a
            logdet = 2.0 * jnp.sum(jnp.log(jnp.diag(L)))
        nll = 0.5 * (logdet + quad + _LOG2PI * jnp.sum(okf))
        mf = m + mm(K, e)
        IKC = eye - mm(K, Ck)
        Pf = _sym(mm(mm(IKC, P), IKC.T) + mm(mm(K, Rk), K.T))
        mn = mm(Phi, mf) + dk
        Pn = _sym(mm(mm(Phi, Pf), Phi.T) + Q)
        if full:
            out = (nll, jnp.where(okk, e, jnp.nan), S, m, P, mf, Pf)
        else:
            out = nll
        return (mn, Pn), out

    _, outs = lax.scan(step, (m0, _sym(P0)), (y0, ok, u, drive))
    if not full:
        return jnp.sum(outs)
    nll, e, S, mp, Pp, mf, Pf = outs
    return dict(
        nll=jnp.sum(nll),
        nll_k=nll,
        innov=e,
        S=S,
        m_pred=mp,
        P_pred=Pp,
        m_filt=mf,
        P_filt=Pf,
    )


def _smoother_gain(PhiPf, Pp1):
    """``G = Pf Φᵀ Pp1⁻¹`` through a Cholesky solve of the symmetric ``Pp1``. A singular
    ``Pp1`` (states without diffusion whose initial spread has vanished, or was 0: known
    exactly) has no Cholesky factor; there the pseudo-inverse (eigenvalues below ``n·ε`` of
    the largest dropped) gives the gain, zero in the directions that carry no uncertainty,
    instead of NaN."""
    n = Pp1.shape[0]
    L = jnp.linalg.cholesky(Pp1)
    ok = jnp.all(jnp.isfinite(L))
    eye = jnp.eye(n, dtype=Pp1.dtype)
    G = jax.scipy.linalg.cho_solve((jnp.where(ok, L, eye), True), PhiPf).T
    w, V = jnp.linalg.eigh(Pp1)
    keep = w > n * jnp.finfo(Pp1.dtype).eps * jnp.maximum(jnp.max(w), 0.0)
    winv = jnp.where(keep, 1.0 / jnp.where(keep, w, 1.0), 0.0)
    G_pinv = ((V * winv[None, :]) @ V.T @ PhiPf).T
    return jnp.where(ok, G, G_pinv)


def rts_scan(Phi, drive, m_pred, P_pred, m_filt, P_filt):
    """Rauch–Tung–Striebel smoother over the outputs of :func:`kalman_scan` (``full``).

    ``G_k = P_{k|k} Φᵀ P_{k+1|k}⁻¹``, ``x̂_{k|N} = x̂_{k|k} + G_k (x̂_{k+1|N} − x̂_{k+1|k})``,
    ``P_{k|N} = P_{k|k} + G_k (P_{k+1|N} − P_{k+1|k}) G_kᵀ`` (a singular ``P_{k+1|k}``: its
    pseudo-inverse, :func:`_smoother_gain`). ``drive`` is unused (the predicted
    means carry it) and kept for symmetry with the filter's arguments.
    """
    del drive

    def step(carry, data):
        ms, Ps = carry
        mf, Pf, mp1, Pp1 = data
        G = _smoother_gain(Phi @ Pf, Pp1)
        m = mf + G @ (ms - mp1)
        P = _sym(Pf + G @ (Ps - Pp1) @ G.T)
        return (m, P), (m, P)

    last = (m_filt[-1], P_filt[-1])
    data = (m_filt[:-1], P_filt[:-1], m_pred[1:], P_pred[1:])
    _, (ms, Ps) = lax.scan(step, last, data, reverse=True)
    ms = jnp.concatenate([ms, m_filt[-1:]], axis=0)
    Ps = jnp.concatenate([Ps, P_filt[-1:]], axis=0)
    return ms, Ps
