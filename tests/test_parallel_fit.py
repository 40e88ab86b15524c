"""The fit's normal equations parallel in time (an associative scan over the samples, the route
on an accelerator) equal the sequential pass: with and without the observer's pull, masked
samples, segments, shared and per-member inputs; and a whole fit through them reaches the same
optimum from the same starts."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _reference import synthetic_building

from jaxbox.fit import fit_model
from jaxbox.fit._fit import clear_compile_cache
from jaxbox.models import get_model
from jaxbox.simulate._exact import normal_equations
from jaxbox.simulate._parallel import (
    _PARALLEL_BATCH,
    _PARALLEL_BYTES,
    normal_equations_parallel,
    prefer_parallel,
)

B, N_STATES, M, Q, N = 3, 4, 3, 5, 37


def _problem(segments, members_u, seed=0):
    rng = np.random.default_rng(seed)

    def rnd(*s):
        return jnp.asarray(rng.normal(size=s))

    Phi = jnp.asarray(
        np.stack(
            [np.eye(N_STATES) * 0.9 + 0.02 * rng.normal(size=(N_STATES,) * 2) for _ in range(B)]
        )
    )
    mats = [Phi, rnd(B, N_STATES, M) * 0.1, rnd(B, N_STATES, M) * 0.1]
    tangents = [
        rnd(B, N_STATES, N_STATES, Q) * 0.01,
        rnd(B, N_STATES, M, Q) * 0.1,
        rnd(B, N_STATES, M, Q) * 0.1,
    ]
    t = None
    if segments == 1:
        mats.append(rnd(B, N_STATES))
        tangents.append(rnd(B, N_STATES, Q))
    else:  # three segments: gaps after samples 15 and 30
        mats.append(rnd(B, segments, N_STATES))
        tangents.append(rnd(B, segments, N_STATES, Q))
        tt = np.arange(N, dtype=float)
        tt[15:] += 5.0
        tt[30:] += 7.0
        t = jnp.asarray(tt)[:, None]
    u = rnd(N, members_u, M)
    y = rnd(N, 1, 2)
    w = jnp.asarray(rng.uniform(size=(N, 1, 2)) > 0.2) * 0.3  # a fifth of the samples masked
    return tuple(mats), tuple(tangents), u, y, w, t


# each option both ways: segments, per-member inputs, the observer's pull, two measured states
CASES = [
    (1, 1, None, (0, 2)),
    (1, B, (0.9, 0.5, 0.0), (1,)),
    (3, 1, (0.9, 0.5, 0.0), (0, 2)),
    (3, B, None, (1,)),
]


@pytest.mark.parametrize("segments, members_u, gain, outputs", CASES)
def test_parallel_normal_equations_equal_the_sequential_pass(segments, members_u, gain, outputs):
    mats, tangents, u, y, w, t = _problem(segments, members_u)
    y, w = y[..., : len(outputs)], w[..., : len(outputs)]
    g = None if gain is None else jnp.asarray(gain)
    # compiled, as in a fit (op by op, the associative scan's levels dispatch one at a time)
    seq = jax.jit(
        lambda m, tg, u, y, w, t, g: normal_equations(m, tg, outputs, u, y, w, t=t, gain=g, chunk=8)
    )(mats, tangents, u, y, w, t, g)
    par = jax.jit(
        lambda m, tg, u, y, w, t, g: normal_equations_parallel(m, tg, outputs, u, y, w, t=t, gain=g)
    )(mats, tangents, u, y, w, t, g)
    for name, a, b in zip(("cost", "Jᵀr", "JᵀJ"), seq, par, strict=True):
        assert np.all(np.isfinite(b)), name
        np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-14 * float(jnp.max(jnp.abs(a))))


def test_parallel_in_time_only_on_an_accelerator_and_for_a_narrow_batch(monkeypatch):
    monkeypatch.delenv("JAXBOX_PARALLEL_IN_TIME", raising=False)
    assert not prefer_parallel(492, 64, 4, 14, platform="cpu")
    assert prefer_parallel(492, 64, 4, 14, platform="gpu")
    assert prefer_parallel(52560, 1, 6, 20, platform="gpu")
    assert prefer_parallel(492, _PARALLEL_BATCH, 4, 14, platform="gpu")
    assert not prefer_parallel(492, _PARALLEL_BATCH + 1, 4, 14, platform="gpu")
    too_long = _PARALLEL_BYTES // (8 * 64 * 4 * 15) + 1  # samples
    assert not prefer_parallel(too_long, 64, 4, 14, platform="gpu")
    monkeypatch.setenv("JAXBOX_PARALLEL_IN_TIME", "1")
    assert prefer_parallel(492, 64, 4, 14, platform="cpu")
    monkeypatch.setenv("JAXBOX_PARALLEL_IN_TIME", "0")
    assert not prefer_parallel(492, 64, 4, 14, platform="gpu")


TRUTH = {"C_zon": 3.0e6, "C_wal": 4.0e7, "R_wal": 0.012, "gA": 2.5, "T_zon0": 26.0, "T_wal0": 19.0}


@pytest.mark.slow
def test_a_fit_parallel_in_time_reaches_the_same_optimum(monkeypatch):
    data = synthetic_building(get_model("ZonWal"), TRUTH, n=150, seed=3, noise=0.02, step=3600.0)
    runs = {}
    try:
        for mode in ("0", "1"):
            monkeypatch.setenv("JAXBOX_PARALLEL_IN_TIME", mode)
            clear_compile_cache()  # the route is chosen when the fit is compiled
            runs[mode] = fit_model("ZonWal", data, starts=6, seed=0)
    finally:
        clear_compile_cache()
    seq, par = runs["0"], runs["1"]
    assert par.cost == pytest.approx(seq.cost, rel=1e-9)
    np.testing.assert_allclose(par.starts.cost, seq.starts.cost, rtol=1e-7)
    for name, value in seq.params.items():
        assert par.params[name] == pytest.approx(value, rel=1e-6), name


def test_parallel_normal_equations_differentiate_like_the_sequential_pass():
    """Experiment design differentiates JᵀJ through the pass with respect to the inputs."""
    mats, tangents, u, y, w, _ = _problem(1, 1)

    def information(fn, inputs):
        _, _, H = fn(mats, tangents, (0, 2), inputs, y, w)
        return jnp.sum(jnp.log(jnp.diagonal(H, axis1=1, axis2=2)))

    seq = jax.jit(jax.grad(lambda v: information(normal_equations, v)))(u)
    par = jax.jit(jax.grad(lambda v: information(normal_equations_parallel, v)))(u)
    np.testing.assert_allclose(par, seq, rtol=1e-10, atol=1e-12 * float(jnp.max(jnp.abs(seq))))
