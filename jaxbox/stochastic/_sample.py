"""Synthetic data from the stochastic form of a model: exact samples of the discrete SDE."""

from __future__ import annotations

from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np

from .. import _compiled
from .._compiled import jit
from ..fit._problem import FitError
from ..models import get_model
from ._checks import as_data, regular_step, x0_stds
from ._kalman import HOLDS
from ._problem import DEFAULT_X0_STD, system
from ._states import _check_params

__all__ = ["simulate_sde"]


def simulate_sde(
    model,
    params: Mapping[str, float],
    data,
    *,
    seed: int | None = 0,
    hold: str = "foh",
    x0_std: float | Mapping[str, float] | None = None,
    replications: int | None = None,
):
    """Sample states and outputs of the SDE at the samples of ``data`` (its inputs).

    The transition from one sample to the next is drawn exactly (Φ, Γ, Q of
    :func:`~jaxbox.stochastic.discretize`), the initial state from ``N(T_*0, x0_std²)``
    (default: ``DEFAULT_X0_STD`` K; ``0`` starts exactly at ``T_*0``; one value or per state
    name). The inputs must be complete and the samples regularly spaced.

    Returns ``(y [N, p], x [N, n])`` [°C], or with ``replications`` arrays with a leading axis
    ``[R, N, …]`` of independent replications.
    """
    model = get_model(model)
    data = as_data(data)
    theta = _check_params(model, params)
    if hold not in HOLDS:
        raise FitError(f"unknown hold {hold!r}; choose one of {', '.join(HOLDS)}")
    if replications is not None and (
        not isinstance(replications, int | np.integer)
        or isinstance(replications, bool)
        or replications < 1
    ):
        raise FitError(f"replications must be an integer ≥ 1 or None, got {replications!r}")
    std = np.asarray(x0_stds(model, x0_std, DEFAULT_X0_STD, zero=True))
    u = np.asarray(data.array(list(model.inputs)), dtype=float)
    if not np.isfinite(u).all():
        row, col = (int(i) for i in np.argwhere(~np.isfinite(u))[0])
        raise FitError(
            f"input {model.inputs[col]} is missing (NaN) at row {row}; the simulation needs "
            "every input; fill or drop those rows"
        )
    dt = regular_step(data)
    fn = _compiled.cached(
        ("stochastic", "system", model.structure, hold),
        lambda: jit(lambda th, dt: system(model, th, dt, hold)),
    )[0]
    (Phi, G0, G1, Q), C, D, r, m0, _ = jax.tree_util.tree_map(
        np.asarray, fn({k: jnp.asarray(v) for k, v in theta.items()}, dt)
    )
    rng = np.random.default_rng(seed)
    R = 1 if replications is None else int(replications)
    n, N = len(m0), len(u)
    # Q may be singular (a diffusion fixed to 0): factor through its eigendecomposition
    w, V = np.linalg.eigh(0.5 * (Q + Q.T))
    LQ = V * np.sqrt(np.clip(w, 0.0, None))
    du = np.concatenate([u[1:] - u[:-1], np.zeros_like(u[:1])], axis=0)
    drive = u @ G0.T + du @ G1.T
    x = np.empty((R, N, n))
    x[:, 0] = m0 + std * rng.standard_normal((R, n))
    for k in range(N - 1):
        x[:, k + 1] = x[:, k] @ Phi.T + drive[k] + rng.standard_normal((R, n)) @ LQ.T
    y = x @ C.T + (u @ D.T)[None] + rng.standard_normal((R, N, len(r))) * r
    if replications is None:
        return y[0], x[0]
    return y, x
