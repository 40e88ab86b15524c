"""Simulation by numerical integration with diffrax and implicit, L-stable ESDIRK solvers.

Inputs are linearly interpolated between samples (the same assumption as the exact route). Two
step-size strategies:

* ``adaptive`` (default, for validation): Kvaerno3 under PID control of the local error, with
  the step ends clipped to the sample instants, where the interpolated inputs have kinks; the
  error is controllable by ``rtol``/``atol``. Kvaerno5 was used here first: under this sampled
  forcing its embedded estimate misjudges its error (order reduction), and at ``rtol = 1e-8``
  it took up to 4 accepted and 2 rejected steps per 10-minute sample and still ended 2e-6 to
  2e-5 K from the exact solution. Kvaerno3 at the default ``1e-6`` ends 5e-8 to 1e-5 K from it
  (its error follows its tolerance) in 1.6 to 7 times fewer, cheaper steps on six of seven
  measured cases; a fast mode (a heater node of 20 minutes in hourly data) costs it 1.3× the
  steps (`benchmarks/NOTES.md`).
* fixed: ``substeps`` equal Kvaerno5 steps per sample interval, landing exactly on the samples.
  Cheaper, differentiable in forward mode at a fixed cost; used when fitting with diffrax. Under
  sampled forcing at |hλ| ~ 0.1–1 its error falls as h², not h⁵ — validate with the adaptive
  route.
"""

from __future__ import annotations

import contextlib
import functools
import math
from typing import TYPE_CHECKING

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, Float

from ._extend import extend_times, hold_rows

if TYPE_CHECKING:  # imported where it integrates: the exact route never loads it (0.2 s)
    import diffrax

__all__ = [
    "ADAPTIVE_ATOL",
    "ADAPTIVE_RTOL",
    "RMSOver",
    "diffrax_runs_numpy",
    "integrate_diffrax",
    "simulate_diffrax",
]

#: Default tolerances of the adaptive route (relative, and absolute in °C).
ADAPTIVE_RTOL = 1e-6
ADAPTIVE_ATOL = 1e-6


class RMSOver(eqx.Module):
    """Root mean square over the first ``count`` components of a state vector: the step
    control's norm of a system padded with states that stay exactly zero (their scaled errors
    are zero), so that it takes the steps the unpadded system would (``count``: traced)."""

    count: Float[Array, ""]

    def __call__(self, x):
        return jnp.sqrt(jnp.sum(x * x) / self.count)


@contextlib.contextmanager
def _errors_as_nan(active: bool):
    """While tracing, make equinox's runtime checks (e.g. lineax's non-finite-input check in the
    implicit stage solves) return NaN instead of raising, so that one diverging batch member
    under ``vmap`` yields NaN outputs (reported as a failed start) rather than stopping the
    whole batch."""
    if not active:
        yield
        return
    import equinox._errors as eqx_errors

    saved = eqx_errors.EQX_ON_ERROR
    eqx_errors.EQX_ON_ERROR = "nan"
    try:
        yield
    finally:
        eqx_errors.EQX_ON_ERROR = saved


def simulate_diffrax(A, B, C, D, x0, t, u, **options):
    """Integrate ``dx/dt = A x + B u(t)`` from ``x0`` [°C] over the sample times ``t`` [s].

    Args:
        A, B, C, D: state-space matrices (SI, per second).
        x0, t, u, options: as in :func:`integrate_diffrax`.

    Returns:
        (y [N, p], x [N, n]) at the sample times.
    """
    xs = integrate_diffrax(A, B, x0, t, u, **options)
    return xs @ C.T + u @ D.T, xs


def integrate_diffrax(
    A: Float[Array, "n n"],
    B: Float[Array, "n m"],
    x0: Float[Array, " n"],
    t: Float[Array, " N"],
    u: Float[Array, "N m"],
    *,
    adaptive: bool = True,
    rtol: float = ADAPTIVE_RTOL,
    atol: float = ADAPTIVE_ATOL,
    substeps: int = 1,
    max_steps: int | None = None,
    adjoint: diffrax.AbstractAdjoint | None = None,
    throw: bool = True,
    norm=None,
) -> Float[Array, "N n"]:
    """The states [°C] at the sample times of ``dx/dt = A x + B u(t)`` integrated from ``x0``.

    Args:
        A, B: state-space matrices (SI, per second).
        x0: initial state [°C] at ``t[0]``.
        t: sample times [s], increasing, shape [N].
        u: inputs at the samples, shape [N, m].
        adaptive: PID step control (True) or ``substeps`` constant steps per interval.
        rtol, atol: tolerances of the step control and of the implicit stage solves.
        substeps: fixed steps per sample interval when ``adaptive=False``.
        max_steps: solver step cap (default from N, and from the tolerances when they are
            finer than the defaults).
        adjoint: diffrax adjoint; ``diffrax.ForwardMode()`` for forward-mode Jacobians.
        throw: raise on solver failure (set False under ``vmap``; the states are then NaN).
        norm: the step control's error norm (default diffrax's RMS norm; :class:`RMSOver` for a
            system padded with states that stay zero).

    Returns:
        x [N, n] at the sample times.
    """
    import diffrax

    n_samples = t.shape[0]
    interp = diffrax.LinearInterpolation(ts=t, ys=u)

    def rhs(s, x, args):
        return A @ x + B @ interp.evaluate(s)

    root = diffrax.VeryChord(rtol=rtol, atol=atol, norm=optx.max_norm)
    solver = (diffrax.Kvaerno3 if adaptive else diffrax.Kvaerno5)(root_finder=root)
    if adaptive:
        pid = dict(rtol=rtol, atol=atol, pcoeff=0.3, icoeff=0.4)
        if norm is not None:
            pid["norm"] = norm
        controller = diffrax.ClipStepSizeController(diffrax.PIDController(**pid), step_ts=t)
        dt0 = None
        # a third-order method: steps grow as tolerance^(-1/3) below the default tolerances
        finer = max(1.0, (ADAPTIVE_RTOL / max(min(rtol, atol), 1e-15)) ** (1 / 3))
        steps = max_steps or int(math.ceil(128 * finer)) * n_samples + 4096
    else:
        # steps exactly on the sample instants (and equal sub-steps between them), where the
        # interpolated inputs have kinks
        frac = jnp.arange(substeps) / substeps
        grid = (t[:-1, None] + (t[1:] - t[:-1])[:, None] * frac[None, :]).ravel()
        controller = diffrax.StepTo(ts=jnp.concatenate([grid, t[-1:]]))
        dt0 = None
        steps = max_steps or substeps * (n_samples - 1) + 16
    with _errors_as_nan(not throw):
        sol = diffrax.diffeqsolve(
            diffrax.ODETerm(rhs),
            solver,
            t0=t[0],
            t1=t[-1],
            dt0=dt0,
            y0=x0,
            saveat=diffrax.SaveAt(ts=t),
            stepsize_controller=controller,
            max_steps=steps,
            adjoint=adjoint if adjoint is not None else diffrax.RecursiveCheckpointAdjoint(),
            throw=throw,
        )
    xs = sol.ys
    if not throw:
        xs = jnp.where(sol.result == diffrax.RESULTS.successful, xs, jnp.nan)
    return xs


#: state and input counts of :func:`diffrax_runs_numpy` are padded to multiples of this
PAD = 4


def _padded(size: int) -> int:
    return max(PAD, -(-size // PAD) * PAD)


def run_length(n: int) -> int:
    """Samples of :func:`diffrax_runs_numpy`'s compiled program for a record of ``n``: the next
    power of two up to 1024 (at least 32), above that ``n`` rounded up to an eighth of an octave
    (at most 12.5 % more). Records of neighbouring lengths (a fleet's buildings, the periods
    of a selection, a user's slices) share one program; the samples beyond ``n`` are
    integrated and dropped, a few milliseconds on the short records where the rounding is
    coarse."""
    n = int(n)
    if n <= 1024:
        return max(32, 1 << max(0, n - 1).bit_length())
    step = 1 << (n.bit_length() - 4)
    return step * -(-n // step)


def diffrax_runs_numpy(
    A: np.ndarray,
    B: np.ndarray,
    t: np.ndarray,
    u: np.ndarray,
    x0: np.ndarray,
    *,
    rtol: float = ADAPTIVE_RTOL,
    atol: float = ADAPTIVE_ATOL,
) -> np.ndarray:
    """States [S, N, n] of S runs of ``dx/dt = A x + B u(t)`` (adaptive Kvaerno3, as
    :func:`simulate_diffrax`): inputs ``u`` [S, N, m] at the sample times ``t`` [s], shape [N], from
    ``x0`` [°C], shape [S, n]; NumPy in and out. A run that fails is NaN.

    The matrices are padded with zeros to multiples of :data:`PAD` states and inputs, and one
    compiled program (kept in the bounded cache of compiled functions) serves every system of a
    padded size, run count, run length (:func:`run_length`) and tolerances: the models of a
    selection, and records of neighbouring lengths, share it instead of compiling one each.
    The padded states stay zero, and the step control's norm runs over the real states only
    (:class:`RMSOver`), so the steps and the tolerance are those of the unpadded system.
    """
    from .._compiled import cached, jit
    from .._exported import compile_program

    A, B, u = np.asarray(A, float), np.asarray(B, float), np.asarray(u, float)
    n, m = B.shape
    n_pad, m_pad = _padded(n), _padded(m)
    Ap = np.zeros((n_pad, n_pad))
    Ap[:n, :n] = A
    Bp = np.zeros((n_pad, m_pad))
    Bp[:n, :m] = B
    Up = np.zeros(u.shape[:2] + (m_pad,))
    Up[..., :m] = u
    X0 = np.zeros((len(x0), n_pad))
    X0[:, :n] = np.asarray(x0, float)
    # the record extended to its run length: the times go on at the last step, the inputs hold
    # their last values (the interpolation up to the last real sample is unchanged, and so
    # are the steps, clipped at every sample, and the states there)
    t = np.asarray(t, float)
    n_samples = len(t)
    n_run = run_length(n_samples)
    t, Up = extend_times(t, n_run), hold_rows(Up, n_run, axis=1)
    options = (("atol", float(atol)), ("rtol", float(rtol)))
    key = ("diffrax-runs", n_pad, m_pad, Up.shape[0], Up.shape[1], options)
    args = (Ap, Bp, t, Up, X0, np.float64(n))
    # through a serialized export: a later process skips the tracing (about 4 s on a 2-core
    # CPU, most of a warm ``jaxbox fit``), and XLA's persistent cache finds the executable
    fn = cached(
        key,
        lambda: compile_program(
            "diffrax-runs", key, jit(functools.partial(_runs, **dict(options))), args
        ),
    )[0]
    return np.asarray(fn(*args))[:, :n_samples, :n]


def _runs(A, B, t, U, X0, count, **options):
    """:func:`integrate_diffrax` of every run under ``vmap``, the norm over ``count`` states."""
    norm = RMSOver(count)

    def one(u, x0):
        return integrate_diffrax(A, B, x0, t, u, throw=False, norm=norm, **options)

    return jax.vmap(one)(U, X0)
