"""Every derivative jaxbox uses, checked against finite differences in float64.

``jax.test_util.check_grads`` compares forward- (JVP) and reverse-mode (VJP) derivatives with
central differences along random directions; full Jacobians are compared with central
differences of an independent implementation where one exists.
"""

from __future__ import annotations

import types

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _reference import van_loan_outputs
from jax.test_util import check_grads

from jaxbox.data import Dataset
from jaxbox.fit import make_problem, make_transform, problem_arrays
from jaxbox.models import get_model
from jaxbox.simulate import simulate_arrays
from jaxbox.simulate._exact import discretize_foh_rc
from jaxbox.validate import sensitivities

N = 48
ZONWAL = {"C_zon": 2e6, "C_wal": 2e7, "R_wal": 0.01, "gA": 3.0, "T_zon0": 20.0, "T_wal0": 17.0}
RATIO = ("C_zon", "C_wal", "R_wal", "gA")  # scaled by their value in the checks


@pytest.fixture(scope="module")
def data() -> Dataset:
    rng = np.random.default_rng(0)
    t = np.arange(N) * 3600.0
    day = 2 * np.pi * t / 86400.0
    return Dataset.from_arrays(
        t,
        {
            "T_amb": 8.0 + 4.0 * np.sin(day - 2.0) + 0.2 * np.cumsum(rng.standard_normal(N)),
            "Q_hea": np.repeat(np.arange(N) % 2, rng.integers(3, 10, size=N))[:N] * 800.0,
            "I_glo_hor": np.maximum(0.0, 450.0 * np.sin(day - np.pi / 2)),
            "T_zon": 20.0 + rng.standard_normal(N),
        },
    )


def relative_theta(s, x0):
    """θ from relative factors s (for R, C, gA) and initial states x0 [°C]: all O(1)."""
    theta = {k: ZONWAL[k] * s[i] for i, k in enumerate(RATIO)}
    theta.update(T_zon0=x0[0], T_wal0=x0[1])
    return theta


S0 = jnp.asarray([1.0, 1.0, 1.0, 1.0])
X0 = jnp.asarray([20.0, 17.0])


# ---- simulation outputs w.r.t. parameters and initial states -------------------------------------


def test_exact_simulation_derivatives(data) -> None:
    model = get_model("ZonWal")
    t, u = jnp.asarray(data.t), jnp.asarray(data.array(list(model.inputs)))

    def f(s, x0):
        return simulate_arrays(model, relative_theta(s, x0), t, u, method="exact")[0]

    # the full forward-mode Jacobian against central differences of the independent oracle
    Js, Jx = jax.jit(jax.jacfwd(f, argnums=(0, 1)))(S0, X0)
    J = np.concatenate([np.asarray(Js), np.asarray(Jx)], axis=-1)[:, 0, :]
    base = np.concatenate([np.asarray(S0), np.asarray(X0)])
    fd = np.empty_like(J)
    for i in range(6):
        h = 1e-5 if i < 4 else 1e-4
        plus, minus = base.copy(), base.copy()
        plus[i] += h
        minus[i] -= h
        yp = van_loan_outputs(model, relative_theta(plus[:4], plus[4:]), data)[:, 0]
        ym = van_loan_outputs(model, relative_theta(minus[:4], minus[4:]), data)[:, 0]
        fd[:, i] = (yp - ym) / (2 * h)
    np.testing.assert_allclose(J, fd, rtol=1e-6, atol=1e-7)
    # reverse mode (second order forward is checked through the estimation cost's Hessian in
    # test_sensitivity.py)
    check_grads(jax.jit(f), (S0, X0), order=1, modes=("rev",))


@pytest.mark.parametrize("mode", ["fwd", "rev"])
@pytest.mark.slow
def test_diffrax_fixed_step_derivatives(data, mode: str) -> None:
    """The diffrax route of the fit (one Kvaerno5 step per sample): forward mode through
    ``ForwardMode``, reverse mode through the default checkpointed adjoint."""
    model = get_model("ZonWal")
    t, u = jnp.asarray(data.t), jnp.asarray(data.array(list(model.inputs)))
    adjoint = diffrax.ForwardMode() if mode == "fwd" else diffrax.RecursiveCheckpointAdjoint()

    @jax.jit
    def f(s, x0):
        theta = relative_theta(s, x0)
        opts = dict(adaptive=False, rtol=1e-12, atol=1e-12, adjoint=adjoint)
        return simulate_arrays(model, theta, t, u, method="diffrax", **opts)[0]

    check_grads(f, (S0, X0), order=1, modes=(mode,), rtol=1e-6)


# ---- parameter transforms ------------------------------------------------------------------------

TRANSFORMS = {
    "log": ([1e4], [1e10], [2e6]),
    "linear": ([-3.0], [37.0], [20.0]),
    "lower": ([0.0], [np.inf], [3.0]),
    "free": ([-np.inf], [np.inf], [-4.0]),
}


@pytest.mark.parametrize("kind", TRANSFORMS)
def test_transform_derivatives(kind: str) -> None:
    lo, hi, g = TRANSFORMS[kind]
    tr = make_transform(("p",), lo, hi, g)
    assert tr.kind_names() == [kind]
    z = np.asarray([0.3])
    check_grads(lambda zz: tr.to_physical(zz), (jnp.asarray(z),), order=2, modes=("fwd", "rev"))
    # the inverse is numpy: its derivative must be the reciprocal of the forward one
    p = float(tr.to_physical(jnp.asarray(z))[0])
    dp_dz = float(jax.grad(lambda zz: tr.to_physical(zz)[0])(jnp.asarray(z))[0])
    h = 1e-6 * max(abs(p), 1.0)
    dz_dp = (tr.to_internal([p + h])[0] - tr.to_internal([p - h])[0]) / (2 * h)
    assert dz_dp * dp_dz == pytest.approx(1.0, rel=1e-6)
    assert tr.to_internal([p])[0] == pytest.approx(z[0], abs=1e-12)


def test_transforms_with_bounds_as_arguments() -> None:
    """Bounds and scales passed as (traced) arrays, as the compiled fit does."""
    tr = make_transform(("R", "T", "f"), [1e-5, -3.0, 0.0], [10.0, 37.0, np.inf], [0.01, 20, 1])
    z = jnp.asarray([0.1, -0.2, 0.4])
    lo, hi, sc = (jnp.asarray(a) for a in (tr.lower, tr.upper, tr.scale))
    f = jax.jit(lambda zz: tr.to_physical(zz, lo, hi, sc))
    np.testing.assert_allclose(f(z), tr.to_physical(z), rtol=1e-15)
    check_grads(f, (z,), order=2, modes=("fwd", "rev"))


# ---- residuals of the estimation problem and the sensitivities of the intervals ------------------


@pytest.fixture(scope="module")
def problem(data):
    return make_problem(get_model("ZonWal"), data, guess=ZONWAL)


@pytest.fixture(scope="module")
def residual_fns(problem):
    """The residuals of the problem and their forward-mode Jacobian, compiled once."""
    return jax.jit(problem.residuals), jax.jit(jax.jacfwd(problem.residuals))


def _args(problem, data, z):
    t, u, y, sqrt_w = problem_arrays(problem, data)
    tr = problem.transform
    fixed = np.asarray([v for _, v in problem.fixed], dtype=float)
    return tuple(jnp.asarray(a) for a in (fixed, t, u, y, sqrt_w, tr.lower, tr.upper, tr.scale))


def test_residual_jacobian(problem, data, residual_fns) -> None:
    """The Jacobian of the Levenberg–Marquardt residuals in the internal coordinates."""
    z = jnp.asarray(problem.transform.to_internal([ZONWAL[n] for n in problem.free]))
    args = _args(problem, data, z)
    res, jac = residual_fns
    J = np.asarray(jac(z, args))
    fd = np.empty_like(J)
    for i in range(len(z)):
        dz = np.zeros(len(z))
        dz[i] = 1e-6
        fd[:, i] = (np.asarray(res(z + dz, args)) - np.asarray(res(z - dz, args))) / 2e-6
    np.testing.assert_allclose(J, fd, rtol=1e-6, atol=1e-9 * np.abs(J).max())


def test_interval_sensitivities(data) -> None:
    """``jaxbox.validate.sensitivities`` (the J of the confidence intervals) against central
    differences in the physical parameters (forward mode through diffrax is checked above)."""
    model = get_model("ZonWal")
    problem = make_problem(model, data, guess=ZONWAL)
    result = types.SimpleNamespace(problem=problem, data=data, params=dict(ZONWAL))
    ysim, J = sensitivities(result)
    assert J.shape == (N, 1, len(problem.free))
    t, u, _, _ = problem_arrays(problem, data)
    fixed = jnp.asarray([v for _, v in problem.fixed], dtype=float)
    sim = jax.jit(lambda p: problem.simulate(p, fixed, jnp.asarray(t), jnp.asarray(u)))
    p0 = np.asarray([ZONWAL[n] for n in problem.free])
    np.testing.assert_allclose(ysim, sim(jnp.asarray(p0)), rtol=1e-12)
    np.testing.assert_allclose(ysim, van_loan_outputs(model, ZONWAL, data), atol=1e-9)
    for i in range(len(p0)):
        h = 1e-5 * abs(p0[i]) if p0[i] != 0 else 1e-5
        dp = np.zeros(len(p0))
        dp[i] = h
        fd = (np.asarray(sim(jnp.asarray(p0 + dp))) - np.asarray(sim(jnp.asarray(p0 - dp)))) / (
            2 * h
        )
        scale = np.abs(J[:, :, i]).max()
        np.testing.assert_allclose(J[:, :, i], fd, rtol=1e-5, atol=1e-7 * scale)


# ---- the collocation NLP (the reference route) ---------------------------------------------------


@pytest.mark.parametrize("objective", ["samples", "quadrature"])
def test_collocation_derivatives(data, objective: str) -> None:
    """Sparse constraint and residual Jacobians (assembled from per-element blocks) and the
    Hessian-vector products of the Lagrangian, against central differences, at an infeasible
    point of a small problem (2 states, 2 points per element, 2 elements per sample)."""
    from jaxbox.reference._collocation import _assemble, _initial_point, _jargs, _transcribe

    small = Dataset.from_arrays(data.t[:6], {k: data[k][:6] for k in data.columns})
    problem = make_problem(get_model("ZonWal"), small, guess=ZONWAL)
    tx = _transcribe(problem, small, 2, 2, objective)
    rng = np.random.default_rng(1)
    w = _initial_point(tx)
    w = jnp.asarray(w + 1e-2 * rng.standard_normal(w.size))
    jargs = _jargs(tx.args)
    evaluate = tx.fns["evaluate"]

    def values(ww):
        c, r = evaluate(jnp.asarray(ww), jargs)[:2]
        return np.asarray(c), np.asarray(r)

    c, r, gx, jx, gz, jz = (np.asarray(a) for a in evaluate(w, jargs))
    GX, JX = _assemble(tx.sparsity, gx, jx)
    G = np.hstack([GX.toarray(), gz])
    J = np.hstack([JX.toarray(), jz])
    assert G.shape == (tx.sparsity.n_c, w.size) and J.shape == (len(r), w.size)
    fd_G, fd_J = np.empty_like(G), np.empty_like(J)
    h = 1e-6
    for i in range(w.size):
        e = np.zeros(w.size)
        e[i] = h
        (cp, rp), (cm, rm) = values(w + e), values(w - e)
        fd_G[:, i] = (cp - cm) / (2 * h)
        fd_J[:, i] = (rp - rm) / (2 * h)
    np.testing.assert_allclose(G, fd_G, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(J, fd_J, rtol=1e-6, atol=1e-8 * np.abs(J).max())
    # Hessian of the Lagrangian ½‖r‖² + λᵀc along random directions
    lam = rng.standard_normal(len(c))
    dirs = rng.standard_normal((3, w.size))
    Hd = np.asarray(tx.fns["hvp"](w, jnp.asarray(lam), jnp.asarray(dirs), jargs))

    def gradient(ww):
        cc, rr, gx_, jx_, gz_, jz_ = (np.asarray(a) for a in evaluate(jnp.asarray(ww), jargs))
        GX_, JX_ = _assemble(tx.sparsity, gx_, jx_)
        return np.concatenate([JX_.T @ rr + GX_.T @ lam, jz_.T @ rr + gz_.T @ lam])

    for d, hd in zip(dirs, Hd, strict=True):
        fd = (gradient(w + 1e-5 * d) - gradient(w - 1e-5 * d)) / 2e-5
        np.testing.assert_allclose(hd, fd, rtol=1e-6, atol=1e-8 * np.abs(fd).max())


# ---- the symmetric (RC) discretisation and the normal equations of the fit ---------------------

_rc = discretize_foh_rc


def _rc_inputs(s):
    model = get_model("ZonWal")
    theta = relative_theta(s, X0)
    A, B, _, _ = model.state_space(theta)
    return A, B, jnp.stack([theta["C_zon"], theta["C_wal"]])


def test_rc_discretisation_values_and_derivatives() -> None:
    """Closed-form (Daleckii–Krein) derivatives of the eigendecomposition route, against finite
    differences and against autodiff of the Van Loan matrix exponential."""
    from jaxbox.simulate import discretize_foh

    def rc(s):
        A, B, caps = _rc_inputs(s)
        return _rc(A, B, caps, 3600.0)

    def van_loan(s):
        A, B, _ = _rc_inputs(s)
        return discretize_foh(A, B, 3600.0)

    for a, b in zip(jax.jit(rc)(S0), jax.jit(van_loan)(S0), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * float(jnp.abs(b).max()))
    check_grads(jax.jit(rc), (S0,), order=1, modes=("fwd", "rev"))
    jac = jax.jit(lambda s: (jax.jacfwd(rc)(s), jax.jacfwd(van_loan)(s)))
    for a, b in zip(*jac(S0), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12 * float(jnp.abs(b).max()))


def test_rc_discretisation_derivative_in_the_step() -> None:
    """The step Δt is differentiable too (e.g. for a sampling-time study): d/dΔt of the
    eigendecomposition route equals autodiff of the Van Loan matrix exponential."""
    from jaxbox.simulate import discretize_foh

    A, B, caps = _rc_inputs(S0)
    rc = jax.jit(jax.jacfwd(lambda dt: _rc(A, B, caps, dt)))
    van_loan = jax.jit(jax.jacfwd(lambda dt: discretize_foh(A, B, dt)))
    for a, b in zip(rc(3600.0), van_loan(3600.0), strict=True):
        assert float(jnp.abs(b).max()) > 0
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12 * float(jnp.abs(b).max()))
    check_grads(lambda dt: _rc(A, B, caps, dt), (3600.0,), order=1, modes=("fwd", "rev"))


_CLOSE_B = jnp.asarray([[1e-4, 2e-4], [3e-4, 1e-4]])


def _close_A(v):
    a = 1e-4 * v
    return jnp.asarray([[-a[0], a[2]], [a[2], -a[1]]])


@jax.jit
def _close_rc(v):
    return _rc(_close_A(v), _CLOSE_B, jnp.ones(2), 3600.0)


@jax.jit
def _close_jacobians(v):
    from jaxbox.simulate import discretize_foh

    rc = jax.jacfwd(lambda vv: _rc(_close_A(vv), _CLOSE_B, jnp.ones(2), 3600.0))(v)
    van_loan = jax.jacfwd(lambda vv: discretize_foh(_close_A(vv), _CLOSE_B, 3600.0))(v)
    return rc, van_loan


@pytest.mark.parametrize("gap", [0.0, 1e-9, 1e-6, 1e-3])
def test_rc_discretisation_with_close_eigenvalues(gap: float) -> None:
    """Two nodes with (nearly) equal time constants: the divided differences of the JVP switch
    to derivatives at the midpoint."""
    v0 = jnp.asarray([1.0, 1.0 + gap, 0.0])
    check_grads(_close_rc, (v0,), order=1, modes=("fwd", "rev"), eps=1e-6)
    rc, van_loan = _close_jacobians(v0)
    for a, b in zip(rc, van_loan, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-10)


def test_normal_equations_of_the_fit(problem, data, residual_fns) -> None:
    """Cost, ``Jᵀr`` and ``JᵀJ`` of the fit's Levenberg–Marquardt step (state and sensitivities
    propagated together, chunk by chunk) against autodiff of the residuals (checked against
    central differences above), for a batch of two parameter sets."""
    z1 = problem.transform.to_internal([ZONWAL[n] for n in problem.free])
    Z = jnp.asarray(np.stack([z1, z1 + 0.05 * np.arange(len(z1))]))
    t, u, y, sqrt_w = problem_arrays(problem, data)
    tr = problem.transform
    fixed = np.asarray([v for _, v in problem.fixed], dtype=float)
    B = Z.shape[0]
    members = tuple(
        jnp.asarray(np.broadcast_to(a, (B,) + np.shape(a)))
        for a in (fixed, tr.lower, tr.upper, tr.scale, data.step)
    )
    w = np.broadcast_to(sqrt_w, y.shape)
    shared = tuple(jnp.asarray(a)[:, None] for a in (t, u, y, w))
    # chunks of 7 samples: 48 is not a multiple, so the padding of the last chunk is exercised
    cost, g, H = jax.jit(problem.normal_equations, static_argnums=3)(Z, members, shared, 7)
    args = _args(problem, data, Z[0])
    for b in range(B):
        r = np.asarray(residual_fns[0](Z[b], args))
        J = np.asarray(residual_fns[1](Z[b], args))
        np.testing.assert_allclose(cost[b], r @ r, rtol=1e-10)
        np.testing.assert_allclose(g[b], J.T @ r, rtol=1e-7, atol=1e-10 * np.abs(J.T @ r).max())
        np.testing.assert_allclose(H[b], J.T @ J, rtol=1e-8, atol=1e-12 * np.abs(J.T @ J).max())
