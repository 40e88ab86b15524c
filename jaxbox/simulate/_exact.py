"""Exact discretisation of a linear model with inputs linear between samples (first-order hold).

For ``dx/dt = A x + B u(t)`` with ``u`` linear on ``[t_k, t_k + Δt]``::

    x_{k+1} = Φ x_k + Γ0 u_k + Γ1 (u_{k+1} − u_k)

with ``Φ = e^{AΔt}``, ``Γ0 = ∫_0^Δt e^{As} ds B = Δt φ1(AΔt) B`` and
``Γ1 = ∫_0^Δt e^{As} (1 − s/Δt) ds B = Δt φ2(AΔt) B``. This is exact up to round-off for regular
sampling.

Two ways to the matrices:

* :func:`discretize_foh` — any ``A``: one matrix exponential of the block matrix
  ``[[AΔt, BΔt, 0], [0, 0, I], [0, 0, 0]]`` (Van Loan);
* :func:`discretize_foh_rc` — RC networks, where ``A = C⁻¹G`` with ``G`` symmetric (conductances)
  and ``C`` the diagonal of heat capacities: ``S = C^{1/2} A C^{-1/2}`` is symmetric, so one
  eigendecomposition of the small ``S`` gives ``e^{SΔt}``, ``φ1`` and ``φ2`` at once, and their
  derivatives follow in closed form (Daleckii–Krein: divided differences of the scalar functions
  at pairs of eigenvalues, computed stably also for close or equal eigenvalues). Under ``vmap``
  and forward-mode autodiff this costs a fraction of the block-matrix exponential, whose
  scaling-and-squaring branches all run when batched. Nodes held at a constant temperature are
  handled as a constant input of the others.

:func:`normal_equations` runs the recursion for a batch of parameter sets together with the
forward sensitivities of the states (the tangents batched as a matrix next to the state) and
accumulates, chunk by chunk over time, the cost ``Σ r²``, the gradient ``Jᵀr`` and the Gram
matrix ``JᵀJ`` of the weighted output residuals — what a Gauss–Newton or Levenberg–Marquardt step
needs, without ever holding the Jacobian of a long series in memory.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

__all__ = [
    "discretize_foh",
    "discretize_foh_rc",
    "phi_functions",
    "simulate_exact",
    "simulate_foh",
    "simulate_foh_segments",
    "segment_index",
    "normal_equations",
]

_SERIES_TERMS = 20


def discretize_foh(A, B, dt):
    """First-order-hold discretisation: returns (Φ, Γ0, Γ1) for the step ``dt`` [s]."""
    n, m = B.shape
    M = jnp.zeros((n + 2 * m, n + 2 * m), dtype=A.dtype)
    M = M.at[:n, :n].set(A * dt).at[:n, n : n + m].set(B * dt)
    M = M.at[n : n + m, n + m :].set(jnp.eye(m, dtype=A.dtype))
    E = jax.scipy.linalg.expm(M)
    return E[:n, :n], E[:n, n : n + m], E[:n, n + m :]


def discretize_foh_numpy(A, B, dt):
    """:func:`discretize_foh` in NumPy/SciPy (Van Loan's augmented exponential), without a
    compilation per matrix size: ``(Φ, Γ0, Γ1)`` for the step ``dt`` [s], NaN where ``A·dt`` or
    ``B·dt`` is not finite."""
    import numpy as np
    import scipy.linalg

    A, B = np.asarray(A, float), np.asarray(B, float)
    n, m = B.shape
    M = np.zeros((n + 2 * m, n + 2 * m))
    M[:n, :n], M[:n, n : n + m] = A * dt, B * dt
    M[n : n + m, n + m :] = np.eye(m)
    E = scipy.linalg.expm(M) if np.all(np.isfinite(M)) else np.full(M.shape, np.nan)
    return E[:n, :n], E[:n, n : n + m], E[:n, n + m :]


def exact_runs_numpy(A, B, C, D, dt, u, x0):
    """Outputs [S, N, p] and states [S, N, n] of S runs of the exact first-order-hold recursion
    from ``x0`` [S, n] with inputs ``u`` [S, N, m] at the step ``dt`` [s] (NumPy: post-simulating
    a structure costs no compilation; the recursion is a loop over the samples)."""
    Phi, G0, G1 = discretize_foh_numpy(A, B, dt)
    u = np.asarray(u, float)
    drive = u[:, :-1] @ G0.T + (u[:, 1:] - u[:, :-1]) @ G1.T  # [S, N-1, n]
    S, N = u.shape[:2]
    xs = np.empty((S, N, Phi.shape[0]))
    x = np.asarray(x0, float)
    xs[:, 0] = x
    PhiT = Phi.T
    for k in range(N - 1):
        x = x @ PhiT + drive[:, k]
        xs[:, k + 1] = x
    return xs @ np.asarray(C, float).T + u @ np.asarray(D, float).T, xs


def phi_functions(x):
    """``(φ0, φ1, φ2, φ3)`` of ``x`` elementwise: ``φ0 = eˣ``, ``φ_{k+1}(x) = (φ_k(x) − 1/k!)/x``.

    A Taylor series for ``|x| < 1`` and the recurrence from ``expm1`` beyond, so every value is
    accurate to a few ulps (``x`` above 700 is clipped).
    """
    small = jnp.abs(x) < 1.0
    xs = jnp.where(small, x, 0.0)
    xl = jnp.where(small, 1.0, jnp.minimum(x, 700.0))
    out = []
    for k in range(4):
        acc = jnp.zeros_like(xs)
        for j in range(_SERIES_TERMS, -1, -1):
            acc = acc * xs + 1.0 / math.factorial(j + k)
        out.append(acc)
    e = jnp.exp(xl)
    p1 = jnp.expm1(xl) / xl
    p2 = (p1 - 1.0) / xl
    p3 = (p2 - 0.5) / xl
    return tuple(jnp.where(small, s, b) for s, b in zip(out, (e, p1, p2, p3), strict=True))


def _scaled(V, d):
    return (V * d[..., None, :]) @ jnp.swapaxes(V, -1, -2)


def _sym_phi(S, dt):
    """``(e^{SΔt}, Δt φ1(SΔt), Δt φ2(SΔt))`` for a symmetric matrix ``S`` and a step ``Δt``
    (differentiable in both)."""
    E, Q1, Q2 = _sym_phis(S * dt)
    return E, dt * Q1, dt * Q2


@jax.custom_jvp
def _sym_phis(X):
    """``(φ0(X), φ1(X), φ2(X))`` of a symmetric matrix ``X`` from one eigendecomposition."""
    w, V = jnp.linalg.eigh(X)
    p0, p1, p2, _ = phi_functions(w)
    return _scaled(V, p0), _scaled(V, p1), _scaled(V, p2)


@_sym_phis.defjvp
def _sym_phis_jvp(primals, tangents):
    # Daleckii–Krein: for f applied to X = V diag(x) Vᵀ, df = V (F ∘ (Vᵀ dX V)) Vᵀ with
    # F_ij = (f(x_i) − f(x_j)) / (x_i − x_j), or f'(x_i) when the two are (nearly) equal.
    (X,), (dX,) = primals, tangents
    x, V = jnp.linalg.eigh(X)
    p = phi_functions(x)
    xi, xj = x[..., :, None], x[..., None, :]
    gap = xi - xj
    # below this gap the quotient loses more digits than the midpoint derivative's O(gap²) error
    close = jnp.abs(gap) <= 1e-5 * jnp.maximum(1.0, jnp.maximum(jnp.abs(xi), jnp.abs(xj)))
    safe = jnp.where(close, 1.0, gap)
    pm = phi_functions(0.5 * (xi + xj))
    # φ0' = φ0, φ1' = φ1 − φ2, φ2' = φ2 − 2 φ3
    dmid = (pm[0], pm[1] - pm[2], pm[2] - 2.0 * pm[3])
    T = jnp.swapaxes(V, -1, -2) @ dX @ V
    T = 0.5 * (T + jnp.swapaxes(T, -1, -2))
    outs, douts = [], []
    for k in range(3):
        pk = p[k]
        F = jnp.where(close, dmid[k], (pk[..., :, None] - pk[..., None, :]) / safe)
        outs.append(_scaled(V, pk))
        douts.append(V @ (F * T) @ jnp.swapaxes(V, -1, -2))
    return tuple(outs), tuple(douts)


def discretize_foh_rc(A, B, caps, dt, held=None):
    """First-order-hold discretisation of an RC network: (Φ, Γ0, Γ1) for the step ``dt`` [s].

    Args:
        A, B: state-space matrices with ``A = C⁻¹G``, ``G`` symmetric on the nodes that are not
            held, ``B = C⁻¹H``.
        caps: heat capacities [J/K] per state (any positive value for held nodes).
        dt: the step [s].
        held: static tuple of bools, True for a node held at a constant temperature (its row of
            ``A`` and ``B`` is zero).

    Same result as :func:`discretize_foh` for such ``A``; differentiable (forward and reverse) at
    the cost of one symmetric eigendecomposition of the free block.
    """
    n = A.shape[-1]
    held = tuple(bool(h) for h in (held or (False,) * n))
    free = [i for i in range(n) if not held[i]]
    fixed = [i for i in range(n) if held[i]]
    if fixed:
        fi, hi = jnp.asarray(free), jnp.asarray(fixed)
        Aff, Afh = A[fi][:, fi], A[fi][:, hi]
        # the held temperatures drive the free nodes as constant inputs
        Phi_f, G0_f, G1_f = discretize_foh_rc(
            Aff, jnp.concatenate([Afh, B[fi]], axis=1), caps[fi], dt
        )
        nh = len(fixed)
        Phi = jnp.zeros((n, n), dtype=A.dtype)
        Phi = Phi.at[jnp.ix_(fi, fi)].set(Phi_f).at[jnp.ix_(fi, hi)].set(G0_f[:, :nh])
        Phi = Phi.at[hi, hi].set(1.0)
        m = B.shape[1]
        G0 = jnp.zeros((n, m), dtype=A.dtype).at[fi].set(G0_f[:, nh:])
        G1 = jnp.zeros((n, m), dtype=A.dtype).at[fi].set(G1_f[:, nh:])
        return Phi, G0, G1
    r = jnp.sqrt(caps)
    S = A * r[:, None] / r[None, :]
    S = 0.5 * (S + S.T)
    E, P1, P2 = _sym_phi(S, dt)
    Bs = B * r[:, None]
    return E / r[:, None] * r[None, :], (P1 @ Bs) / r[:, None], (P2 @ Bs) / r[:, None]


def simulate_exact(A, B, C, D, x0, u, dt):
    """Simulate at the samples: u [N, m] at a regular step dt [s]; returns (y [N, p], x [N, n]).

    ``x[0] = x0`` and ``y[k] = C x[k] + D u[k]``.
    """
    Phi, G0, G1 = discretize_foh(A, B, dt)
    return simulate_foh(Phi, G0, G1, C, D, x0, u)


def simulate_foh(Phi, G0, G1, C, D, x0, u):
    """The recursion for given discrete matrices: returns (y [N, p], x [N, n])."""
    drive = u[:-1] @ G0.T + (u[1:] - u[:-1]) @ G1.T

    def step(x, d):
        x = Phi @ x + d
        return x, x

    _, xs = lax.scan(step, x0, drive)
    xs = jnp.concatenate([x0[None, :], xs], axis=0)
    return xs @ C.T + u @ D.T, xs


def segment_index(t, n_segments: int):
    """Where each segment starts and which segment each sample belongs to, from the sample
    times ``t`` [N] (or [N, B]): a time step longer than the first one starts a new segment.

    Returns ``(first [N…] bool, index [N…] int)``, the index clipped to ``n_segments − 1``.
    Traceable: the segments of the data are arguments, not part of a compiled function.
    """
    t = jnp.asarray(t)
    dt = t[1] - t[0]
    jump = jnp.diff(t, axis=0) > dt * (1 + 1e-6) + 1e-6
    first = jnp.concatenate([jnp.ones_like(jump[:1]), jump], axis=0)
    index = jnp.clip(jnp.cumsum(first, axis=0) - 1, 0, n_segments - 1)
    return first, index


def simulate_foh_segments(Phi, G0, G1, C, D, X0, u, t):
    """:func:`simulate_foh` over data in segments: the state restarts from ``X0[s]`` [S, n] at
    the first sample of segment ``s`` (see :func:`segment_index`); the step across a cut is
    computed and discarded. Returns (y [N, p], x [N, n])."""
    first, index = segment_index(t, X0.shape[0])
    drive = u[:-1] @ G0.T + (u[1:] - u[:-1]) @ G1.T
    drive = jnp.concatenate([drive, jnp.zeros_like(drive[:1])], axis=0)

    def step(x, a):
        d, f, i = a
        x = jnp.where(f, X0[i], x)
        return Phi @ x + d, x

    _, xs = lax.scan(step, X0[0], (drive, first, index))
    return xs @ C.T + u @ D.T, xs


def chunk_length(n_samples: int, n_batch: int, n_states: int, n_tangents: int) -> int:
    """Samples per chunk of :func:`normal_equations`: about 16 MB of tangents per chunk."""
    per_sample = max(1, n_batch * n_states * (n_tangents + 1))
    length = max(32, (1 << 21) // per_sample)
    n_chunks = -(-n_samples // length)
    return -(-n_samples // n_chunks)


def _pad_time(a, total):
    extra = total - a.shape[0]
    if extra == 0:
        return a
    return jnp.concatenate([a, jnp.zeros((extra,) + a.shape[1:], a.dtype)], axis=0)


def _matvec(M, x):
    """``M @ x`` per batch member, M [B, n, n], x [B, n, …], as fused elementwise terms."""
    n = M.shape[-1]
    extra = x.ndim - 2
    out = 0.0
    for j in range(n):
        out = out + M[:, :, j].reshape(M.shape[:2] + (1,) * extra) * x[:, None, j]
    return out


def _take(a, outputs: tuple[int, ...], axis: int = 1):
    """``a`` at the static state indices ``outputs`` along ``axis``, by slices (no gather)."""
    lo = outputs[0]
    if outputs == tuple(range(lo, lo + len(outputs))):
        return lax.slice_in_dim(a, lo, lo + len(outputs), axis=axis)
    return jnp.concatenate([lax.slice_in_dim(a, o, o + 1, axis=axis) for o in outputs], axis=axis)


def _spread(v, outputs: tuple[int, ...], n: int):
    """[B, p] values at the static state indices ``outputs`` → [B, n], zero elsewhere (no
    scatter)."""
    out = 0.0
    for j, o in enumerate(outputs):
        onehot = np.zeros(n)
        onehot[o] = 1.0
        out = out + v[:, j, None] * jnp.asarray(onehot, v.dtype)
    return out


def _drive(u, du, G0, G1):
    """``Γ0 u_k + Γ1 Δu_k`` for u [L, Bu, m] (Bu 1 or B) and G [B, n, m, …] → [L, B, n, …]."""
    G = jnp.concatenate([G0, G1], axis=2)
    ud = jnp.concatenate([u, du], axis=-1)
    if ud.shape[1] == 1:  # shared inputs: one plain matrix product
        return jnp.einsum("lm,bim...->lbi...", ud[:, 0], G)
    return jnp.einsum("lbm,bim...->lbi...", ud, G)


def normal_equations(
    mats, tangents, outputs, u, y, w, *, chunk: int | None = None, t=None, gain=None
):
    """Cost, gradient and Gram matrix of weighted output residuals for a batch of models.

    For each batch member the outputs are states (``y_k = x_k[outputs]``, the node temperatures
    of an RC network), the residuals ``r_k = w_k ∘ (y_k(θ) − y_k)`` with the first-order-hold
    recursion from ``x_0``. The tangents are derivatives of the matrices with respect to ``q``
    coordinates (a trailing axis); the state's sensitivities to them are propagated with the
    state, chunk by chunk over time, and only their products are kept.

    Args:
        mats: ``(Φ [B,n,n], Γ0 [B,n,m], Γ1 [B,n,m], x0 [B,n])``.
        tangents: their derivatives, each with a trailing axis of length ``q``.
        outputs: static tuple of the state indices that are measured.
        u: inputs [N, Bu, m], ``Bu`` 1 (shared by all members) or B.
        y: measured outputs [N, By, p], ``By`` 1 or B.
        w: residual weights [N, Bw, p] (0 masks a sample), ``Bw`` 1 or B.
        chunk: samples per chunk (default from :func:`chunk_length`); memory is O(chunk).
        t: sample times [N, Bt] (``Bt`` 1 or B), needed when ``x0`` holds the initial states of
            several segments, ``[B, S, n]``: the state and its sensitivities restart from those
            of segment ``s`` at its first sample (see :func:`segment_index`).
        gain: observer gain per member [B] (``None``: none, the plain simulation). After each
            sample with a measurement the measured states are pulled towards it,
            ``x[outputs] ← x[outputs] − gain (x[outputs] − y)``, before the next step; the
            residual is that of the state before the pull (the one-step prediction at gain 1).

    Returns:
        ``(cost [B], g [B, q], H [B, q, q])``: ``Σ r²``, ``Jᵀr`` and ``JᵀJ``.
    """
    Phi, G0, G1, x0 = mats
    dPhi, dG0, dG1, dx0 = tangents
    outputs = tuple(int(o) for o in outputs)
    n_samples = u.shape[0]
    segmented = x0.ndim == 3
    if segmented:
        X0s, dX0s = x0, dx0  # [B, S, n], [B, S, n, q]
        x0, dx0 = x0[:, 0], dx0[:, 0]
        first, index = segment_index(t, X0s.shape[1])  # [N, Bt]
    else:
        first = jnp.zeros((n_samples, 1), bool)
        index = jnp.zeros((n_samples, 1), jnp.int32)
    batch, n = x0.shape
    q = dx0.shape[-1]
    du = jnp.concatenate([u[1:] - u[:-1], jnp.zeros_like(u[:1])], axis=0)
    L = chunk or chunk_length(n_samples, batch, n, q)
    n_chunks = -(-n_samples // L)
    total = n_chunks * L
    u, du, y, w, first, index = (_pad_time(a, total) for a in (u, du, y, w, first, index))
    split = lambda a: a.reshape((n_chunks, L) + a.shape[1:])  # noqa: E731
    rows = jnp.arange(batch)

    def restart(state, f, i, initial):
        """The state (or its tangents) restarted at the first sample of a segment."""
        if not segmented:
            return state
        f = jnp.broadcast_to(f, (batch,))
        i = jnp.broadcast_to(i, (batch,))
        mask = f.reshape((batch,) + (1,) * (state.ndim - 1))
        return jnp.where(mask, initial[rows, i], state)

    def one_chunk(carry, data):
        x, X, cost, g, H = carry
        uc, duc, yc, wc, fc, ic = data

        def sample(carry, a):
            # the state and its tangents in one pass: x_{k+1} = Φ x_k + Γ0 u_k + Γ1 Δu_k and
            # X_{k+1} = Φ X_k + ∂Φ x_k + ∂Γ0 u_k + ∂Γ1 Δu_k; only the measured rows leave
            x, X = carry
            d, e, f, i, yk, wk = a
            x = restart(x, f, i, X0s if segmented else None)
            X = restart(X, f, i, dX0s if segmented else None)
            yhat, out = _take(x, outputs), _take(X, outputs)  # the prediction of sample k
            if gain is None:
                xc = x
            else:  # the measured states pulled towards their measurements
                pull = gain[:, None] * (wk > 0)
                xc = x - _spread(pull * (yhat - yk), outputs, n)
                X = X * (1.0 - _spread(pull, outputs, n))[..., None]
            for j in range(n):
                e = e + dPhi[:, :, j, :] * xc[:, None, j, None]
            return (_matvec(Phi, xc) + d, _matvec(Phi, X) + e), (yhat, out)

        (x_next, X_next), (yhats, Js) = lax.scan(
            sample, (x, X), (_drive(uc, duc, G0, G1), _drive(uc, duc, dG0, dG1), fc, ic, yc, wc)
        )
        r = wc * (yhats - yc)  # [L, B, p]
        Jw = wc[..., None] * Js  # [L, B, p, q]
        Jb = jnp.transpose(Jw, (1, 0, 2, 3)).reshape(batch, -1, q)  # member-major for the products
        rb = jnp.transpose(r, (1, 0, 2)).reshape(batch, -1)
        cost = cost + jnp.einsum("bk,bk->b", rb, rb)
        g = g + jnp.einsum("bk,bkq->bq", rb, Jb)
        H = H + jnp.einsum("bkq,bkp->bqp", Jb, Jb)
        return (x_next, X_next, cost, g, H), None

    dtype = x0.dtype
    init = (
        x0,
        dx0,
        jnp.zeros((batch,), dtype),
        jnp.zeros((batch, q), dtype),
        jnp.zeros((batch, q, q), dtype),
    )
    (_, _, cost, g, H), _ = lax.scan(
        one_chunk, init, tuple(split(a) for a in (u, du, y, w, first, index))
    )
    return cost, g, H


def weighted_cost(mats, outputs, u, y, w):
    """``Σ r²`` per batch member (the residuals of :func:`normal_equations`), no tangents."""
    Phi, G0, G1, x0 = mats
    du = jnp.concatenate([u[1:] - u[:-1], jnp.zeros_like(u[:1])], axis=0)

    def primal(x, d):
        return _matvec(Phi, x) + d, x

    _, xs = lax.scan(primal, x0, _drive(u, du, G0, G1))
    r = w * (xs[:, :, jnp.asarray(tuple(outputs))] - y)
    return jnp.einsum("lbo,lbo->b", r, r)
