"""How the estimates depend on the data: implicit differentiation through the optimum.

At the optimum θ̂ of the fit's cost ``C(θ, y) = Σ_k Σ_j (q_j / N) (ŷ_jk(θ) − y_jk)²`` the gradient
vanishes, ``∇_θ C(θ̂(y), y) = 0``. Differentiating this identity in the data (implicit function
theorem) gives the first-order change of every estimate per unit change of every measurement::

    dθ̂/dy = −(∂²C/∂θ²)⁻¹ ∂²C/∂θ∂y,      ∂²C/∂θ∂y_jk = −2 (q_j / N) ∂ŷ_jk/∂θ.

``∂²C/∂θ²`` is the exact Hessian of the cost in the free physical parameters (forward-over-forward
autodiff through the fit's own simulator), or on request its Gauss–Newton part
``2 Σ (q_j/N) ∂ŷᵀ/∂θ ∂ŷ/∂θ`` (the two differ by the residual-curvature terms; the exact one is
what re-fits reproduce). The derivatives with respect to the measured inputs (``inputs=True``)
follow the same way with ``∂²C/∂θ∂u``.

These numbers say which measurements an estimate rests on, how a sensor offset or a single bad
sample moves it (:meth:`FitSensitivity.predicted_change`), and, summed over samples with a noise
variance, its sandwich covariance (:meth:`FitSensitivity.covariance`; with the Gauss–Newton
Hessian and uniform weights it equals ``σ² (JᵀJ)⁻¹``) — the basis for designing experiments that
pin the parameters down better.

Parameters that ended on a bound (an active constraint: see :meth:`FitResult.at_bound`) are held
there: their derivatives are zero and they are left out of the Hessian.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float

from .._compiled import cached, jit
from .._derivatives import value_and_jacfwd
from .._x64 import require_x64
from ._problem import FitError, Problem, problem_arrays
from ._result import BOUND_TOLERANCE

__all__ = ["FitSensitivity", "fit_sensitivity"]

HESSIANS = ("exact", "gauss-newton")


@dataclasses.dataclass(frozen=True, eq=False)
class FitSensitivity:
    """Derivatives of the estimates with respect to the measurements.

    Attributes:
        names: the free parameters (rows of ``values``).
        units: their units.
        params: the estimates θ̂ [SI].
        outputs: the measured outputs (last axis of ``values``).
        t: sample times [s] since the first sample, [N].
        values: ``dθ̂_i / dy_jk`` [n_free, N, n_outputs], in the parameter's unit per kelvin.
        inputs: the model inputs (last axis of ``input_values``); empty unless asked for.
        input_values: ``dθ̂_i / du_lk`` [n_free, N, n_inputs] in the parameter's unit per unit of
            the input (°C, W, W/m²), or ``None``.
        held: parameters held on a bound (zero derivatives).
        hessian: ``"exact"`` or ``"gauss-newton"``.
        hessian_matrix: ∂²C/∂θ² of the free parameters [K² per SI unit²] (rows and columns of
            held parameters included, though unused).
        condition: condition number of the Hessian of the parameters not held, after scaling
            each parameter by its magnitude.
        positive_definite: whether that Hessian is positive definite (False: θ̂ is not a strict
            local minimum, and the derivatives are not meaningful).
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    params: Float[np.ndarray, " free"]
    outputs: tuple[str, ...]
    t: Float[np.ndarray, " samples"]
    values: Float[np.ndarray, "free samples outputs"]
    inputs: tuple[str, ...]
    input_values: Float[np.ndarray, "free samples inputs"] | None
    held: tuple[str, ...]
    hessian: str
    hessian_matrix: Float[np.ndarray, "free free"]
    condition: float
    positive_definite: bool

    def __getitem__(self, name: str) -> Float[np.ndarray, "samples outputs"]:
        """``dθ̂/dy`` [N, n_outputs] of one parameter."""
        try:
            return self.values[self.names.index(name)]
        except ValueError:
            raise KeyError(
                f"{name!r} is not a free parameter; free parameters: {', '.join(self.names)}"
            ) from None

    def relative(self) -> Float[np.ndarray, "free samples outputs"]:
        """``(dθ̂_i/dy_jk) / |θ̂_i|`` [n_free, N, n_outputs] in 1/K (``nan`` where θ̂_i = 0)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return (
                self.values / np.where(self.params != 0, np.abs(self.params), np.nan)[:, None, None]
            )

    def predicted_change(
        self,
        dy: Float[ArrayLike, "samples outputs"] | Float[ArrayLike, " samples"],
        du: Float[ArrayLike, "samples inputs"] | None = None,
    ) -> dict[str, float]:
        """First-order change of each estimate for a change of the data.

        Args:
            dy: change of the measured outputs [K], shape [N, n_outputs] (or [N] for one output).
            du: change of the inputs, shape [N, n_inputs] (needs ``inputs=True``).
        """
        dy = np.asarray(dy, dtype=float)
        if dy.ndim == 1:
            dy = dy[:, None]
        if dy.shape != self.values.shape[1:]:
            raise ValueError(f"dy must have shape {self.values.shape[1:]}, got {dy.shape}")
        out = np.einsum("ikj,kj->i", self.values, dy)
        if du is not None:
            if self.input_values is None:
                raise ValueError("input derivatives were not computed; pass inputs=True")
            du = np.asarray(du, dtype=float)
            if du.shape != self.input_values.shape[1:]:
                raise ValueError(
                    f"du must have shape {self.input_values.shape[1:]}, got {du.shape}"
                )
            out = out + np.einsum("ikl,kl->i", self.input_values, du)
        return {n: float(v) for n, v in zip(self.names, out, strict=True)}

    def covariance(
        self, sigma2: float | Float[ArrayLike, " outputs"]
    ) -> Float[np.ndarray, "free free"]:
        """Covariance of the estimates for independent measurement noise of variance ``sigma2``.

        ``Σ_k Σ_j σ_j² (dθ̂/dy_jk)(dθ̂/dy_jk)ᵀ`` [SI²]; ``sigma2`` is one variance [K²] or one per
        output.
        """
        s2 = np.broadcast_to(np.asarray(sigma2, dtype=float), (len(self.outputs),))
        return np.einsum("ikj,lkj,j->il", self.values, self.values, s2)

    def to_dict(self) -> dict:
        """JSON-ready: per parameter the derivatives per output as lists (one value per sample)."""
        return {
            "hessian": self.hessian,
            "held": list(self.held),
            "condition": float(self.condition),
            "positive_definite": self.positive_definite,
            "t": self.t.tolist(),
            "params": {
                n: {
                    "value": float(self.params[i]),
                    "unit": self.units[i],
                    "d_dy": {o: self.values[i, :, j].tolist() for j, o in enumerate(self.outputs)},
                }
                for i, n in enumerate(self.names)
            },
        }

    def __repr__(self) -> str:
        return (
            f"FitSensitivity(params={list(self.names)}, outputs={list(self.outputs)}, "
            f"samples={len(self.t)}, hessian={self.hessian!r}, held={list(self.held)})"
        )


def _functions(problem: Problem, n_samples: int) -> dict:
    """The compiled derivatives of ``problem``'s structure over ``n_samples`` samples, kept in
    the ``"sensitivity"`` room of :mod:`jaxbox._compiled` (built on a miss)."""
    key = ("sensitivity", *problem.simulation_key, n_samples)
    return cached(key, lambda: _build_functions(problem))[0]


def _build_functions(problem: Problem) -> dict:
    """``derivatives`` (∂ŷ/∂q and the exact Hessian of the cost) and ``inputs`` (∂²C/∂u∂q)."""

    def cost(q, scale, fixed_values, t, u, y, sqrt_w):
        e = (problem.simulate(q * scale, fixed_values, t, u) - y) * sqrt_w
        return jnp.sum(e * e)

    def outputs(q, scale, fixed_values, t, u):
        return problem.simulate(q * scale, fixed_values, t, u)

    def derivatives(q, scale, fixed_values, t, u, y, sqrt_w):
        """∂ŷ/∂q [N, p_out, n] and the exact Hessian of the cost [n, n] (nested forward mode)."""

        def sim(qq):
            return outputs(qq, scale, fixed_values, t, u)

        def first(qq):
            yq, Jq = value_and_jacfwd(sim)(qq)
            return Jq, (Jq, yq)

        d2, (J, yhat) = jax.jacfwd(first, has_aux=True)(q)  # d2: [N, p_out, n, n]
        w2 = jnp.broadcast_to(sqrt_w**2, y.shape)  # 0 at the samples of an output gap
        H = 2.0 * (
            jnp.einsum("kji,kjl,kj->il", J, J, w2) + jnp.einsum("kj,kjil->il", (yhat - y) * w2, d2)
        )
        return J, H

    def mixed_inputs(q, scale, fixed_values, t, u, y, sqrt_w):
        grad_u = jax.grad(cost, argnums=4)
        return jax.jacfwd(grad_u)(q, scale, fixed_values, t, u, y, sqrt_w)  # [N, m, n]

    return {"derivatives": jit(derivatives, once=True), "inputs": jit(mixed_inputs, once=True)}


def fit_sensitivity(result, *, hessian: str = "exact", inputs: bool = False) -> FitSensitivity:
    """Derivatives of a fit's estimates with respect to its data (implicit differentiation).

    Args:
        result: a :class:`~jaxbox.fit.FitResult` (or any result with ``problem``, ``params`` and
            ``data``, e.g. a collocation result).
        hessian: ``"exact"`` (default; what re-fits reproduce) or ``"gauss-newton"``.
        inputs: also differentiate with respect to the measured inputs (needs a simulator that
            supports reverse-mode autodiff: the exact one).

    Returns:
        :class:`FitSensitivity` with ``values[i, k, j] = dθ̂_i / dy_jk``.

    Raises:
        FitError: an unknown ``hessian``, or input derivatives with the diffrax simulator.
    """
    require_x64()
    if hessian not in HESSIANS:
        raise FitError(f"unknown hessian {hessian!r}; choose one of {HESSIANS}")
    problem: Problem = result.problem
    if inputs and problem.simulator != "exact":
        raise FitError(
            "input derivatives need reverse-mode autodiff through the simulator; refit with "
            "simulator='exact' or pass inputs=False"
        )
    model = problem.model
    t, u, y, sqrt_w = problem_arrays(problem, result.data)
    free = problem.free
    p_hat = np.asarray([result.params[n] for n in free], dtype=float)
    scale = np.where(p_hat != 0, np.abs(p_hat), 1.0)
    fixed_values = np.asarray([v for _, v in problem.fixed], dtype=float)
    args = tuple(
        jnp.asarray(a, dtype=float) for a in (p_hat / scale, scale, fixed_values, t, u, y, sqrt_w)
    )
    fns = _functions(problem, len(t))
    J, H = (np.asarray(a) for a in fns["derivatives"](*args))
    # q_j / N_j per sample and output (0 at the samples of an output gap)
    w2 = np.broadcast_to(np.asarray(sqrt_w) ** 2, np.shape(y))
    if hessian == "gauss-newton":
        H = 2.0 * np.einsum("kji,kjl,kj->il", J, J, w2)
    H = 0.5 * (H + H.T)
    # parameters on a bound are held there (active constraint)
    pos = problem.transform.relative_position(p_hat)
    held_mask = np.isfinite(pos) & ((pos < BOUND_TOLERANCE) | (pos > 1 - BOUND_TOLERANCE))
    act = np.flatnonzero(~held_mask)
    Ha = H[np.ix_(act, act)]
    eig = np.linalg.eigvalsh(Ha) if act.size else np.ones(1)
    positive_definite = bool(eig[0] > 0)
    condition = float(np.abs(eig).max() / np.abs(eig).min()) if np.all(eig != 0) else np.inf
    # d q / d y_jk = H⁻¹ · 2 (q_j/N) ∂ŷ_jk/∂q, then back to physical units
    rhs = 2.0 * (J * w2[:, :, None])[:, :, act]  # [N, p_out, n_act]
    n_free, n_samples, n_out = len(free), J.shape[0], J.shape[1]
    S = np.zeros((n_free, n_samples, n_out))
    if act.size:
        sol = _solve(Ha, rhs.reshape(-1, act.size).T)  # [n_act, N * p_out]
        S[act] = sol.reshape(act.size, n_samples, n_out) * scale[act, None, None]
    input_values = None
    if inputs:
        Mu = np.asarray(fns["inputs"](*args))  # ∂²C/∂u∂q [N, m, n]
        Su = np.zeros((n_free, n_samples, Mu.shape[1]))
        if act.size:
            sol = _solve(Ha, -Mu[:, :, act].reshape(-1, act.size).T)
            Su[act] = sol.reshape(act.size, n_samples, Mu.shape[1]) * scale[act, None, None]
        input_values = Su
    return FitSensitivity(
        names=tuple(free),
        units=tuple(model.parameter(n).unit for n in free),
        params=p_hat,
        outputs=tuple(model.outputs),
        t=np.asarray(t, dtype=float),
        values=S,
        inputs=tuple(model.inputs) if inputs else (),
        input_values=input_values,
        held=tuple(n for n, h in zip(free, held_mask, strict=True) if h),
        hessian=hessian,
        hessian_matrix=H / np.outer(scale, scale),
        condition=condition,
        positive_definite=positive_definite,
    )


def _solve(H, B):
    try:
        return np.linalg.solve(H, B)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(H, B, rcond=None)[0]
