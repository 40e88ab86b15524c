"""A value with its derivatives in one pass (jaxbox._derivatives): the same numbers as
``jax.jacfwd`` / ``jax.grad`` / ``jax.hessian`` taken apart, the function traced once."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxbox._derivatives import value_and_jacfwd, value_grad_hessian


def _matrices(p, dt, scale):
    """A pytree of outputs (as a model's discretisation): a matrix (the exponential's series to
    third order, a matrix product and a solve, as the discretisations have), a vector."""
    A = jnp.array([[-p[0], p[1]], [p[1], -p[0] - p[2]]]) * dt
    Phi = jnp.eye(2) + A + A @ A / 2 + A @ A @ A / 6
    return Phi, scale * jnp.linalg.solve(jnp.eye(2) - A, jnp.sin(p[:2])) * p[2]


def _nll(p, y):
    r = y - jnp.exp(-p[0] * jnp.arange(5.0)) * p[1] - p[2] ** 2
    return 0.5 * jnp.sum(r * r) + jnp.log1p(p[0] ** 2)


P = jnp.array([0.7, 0.2, 1.3])


def test_value_and_jacfwd_equals_the_two_apart():
    y, J = jax.jit(value_and_jacfwd(_matrices))(P, 0.5, 2.0)
    y0 = jax.jit(_matrices)(P, 0.5, 2.0)
    J0 = jax.jit(jax.jacfwd(_matrices))(P, 0.5, 2.0)
    for a, b in zip(jax.tree.leaves((y, J)), jax.tree.leaves((y0, J0)), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-15)
    # against central differences, independently of JAX's forward mode
    h = 1e-6
    for k in range(3):
        e = jnp.zeros(3).at[k].set(h)
        up, down = jax.jit(_matrices)(P + e, 0.5, 2.0), jax.jit(_matrices)(P - e, 0.5, 2.0)
        for jk, u, d in zip(
            jax.tree.leaves(J), jax.tree.leaves(up), jax.tree.leaves(down), strict=True
        ):
            np.testing.assert_allclose(jk[..., k], (u - d) / (2 * h), rtol=1e-7, atol=1e-9)


def test_value_grad_hessian_equals_the_three_apart():
    y = jnp.linspace(1.0, 2.0, 5)
    v, g, H = jax.jit(value_grad_hessian(_nll))(P, y)
    assert float(v) == pytest.approx(float(jax.jit(_nll)(P, y)), rel=1e-15)
    np.testing.assert_allclose(g, jax.jit(jax.grad(_nll))(P, y), rtol=1e-14)
    np.testing.assert_allclose(H, jax.jit(jax.hessian(_nll))(P, y), rtol=1e-13, atol=1e-15)
    # against central differences of the gradient, independently of JAX's forward mode
    h = 1e-6
    for k in range(3):
        e = jnp.zeros(3).at[k].set(h)
        fd = (jax.jit(jax.grad(_nll))(P + e, y) - jax.jit(jax.grad(_nll))(P - e, y)) / (2 * h)
        np.testing.assert_allclose(H[:, k], fd, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(H, H.T, atol=1e-14)


@pytest.mark.parametrize("make", [value_and_jacfwd, value_grad_hessian])
def test_the_function_is_traced_once(make):
    calls = []

    def f(p, y):
        calls.append(1)  # runs once per trace
        return _nll(p, y)

    jax.jit(make(f)).lower(P, jnp.ones(5))
    assert len(calls) == 1
    calls.clear()
    jax.jit(lambda p, y: (f(p, y), jax.jacfwd(f)(p, y))).lower(P, jnp.ones(5))
    assert len(calls) == 2  # what the one pass saves
