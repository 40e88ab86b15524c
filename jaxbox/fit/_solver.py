"""Levenberg–Marquardt as an optimistix least-squares solver.

:class:`LevenbergMarquardt` is an :class:`optimistix.AbstractLeastSquaresSolver`: it honours
optimistix's ``init / step / terminate / postprocess`` contract, so
``optx.least_squares(fn, jaxbox.LevenbergMarquardt(rtol=…, atol=…), y0)`` solves any residual
function. It is assembled from optimistix's own parts:

* a *descent*, :class:`ScaledDampedNewton` (an :class:`optimistix.AbstractDescent`): the damped
  Gauss–Newton step of Moré (1978), ``(Hₛ + λ Dₛ) δₛ = −gₛ`` in coordinates scaled by the running
  maximum of the column norms of ``J``, solved by Cholesky, with a cap on the largest change of
  a coordinate per step;
* a *search*, :class:`NielsenDamping` (an :class:`optimistix.AbstractSearch`): accepts a trial
  when the actual reduction of the cost is at least 10⁻⁴ of the reduction the linear model
  predicted, and updates the damping λ from the gain ratio as Nielsen (1999) does; the step size
  it hands the descent is ``1/λ``;
* function information of the kind :class:`optimistix.FunctionInfo.EvalGradHessian`: the cost
  ``½ Σ r²``, the gradient ``g = Jᵀr`` and the Gauss–Newton matrix ``H = JᵀJ``.

Where that information comes from is the one thing that differs between callers. A plain
residual function gets it from ``jax.jacfwd`` (any pytree ``y``, any pytree of residuals). A
caller that can compute ``(½ Σ r², Jᵀr, JᵀJ)`` without forming ``J`` — jaxbox's batched fit
propagates the sensitivities with the state in one pass over the data — passes that function as
``options["normal_equations"]``: ``normal_equations(y, args) -> (f, g, H)``.

Termination (MINPACK's ``ftol`` test): an accepted step whose actual and predicted reductions of
``Σ r²`` are both at most ``rtol · Σ r² + atol``; or a damping beyond 10¹⁶ (the cost cannot be
reduced at machine precision). A first point that cannot be evaluated ends the solve with
``RESULTS.nonlinear_divergence``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import optimistix as optx
from jax.flatten_util import ravel_pytree
from jaxtyping import Array, Bool, Float, Int, PyTree, Scalar

__all__ = ["LevenbergMarquardt", "ScaledDampedNewton", "NielsenDamping", "LMState"]

#: a trial is accepted when the actual reduction is at least this fraction of the predicted one
_ACCEPT = 1e-4
#: beyond this damping the cost cannot be reduced at machine precision
_LAMBDA_MAX = 1e16
#: a coordinate whose column norm of J is below this fraction of the largest is saturated
_SATURATED = 1e-8

_Info = optx.FunctionInfo.EvalGradHessian


def _gram(info) -> Float[Array, "p p"]:
    return info.hessian.as_matrix()


def _info(f, g, H) -> _Info:
    return _Info(f, g, lx.MatrixLinearOperator(H, lx.positive_semidefinite_tag))


def _finite(*arrays) -> Bool[Array, ""]:
    ok = jnp.array(True)
    for a in arrays:
        ok = ok & jnp.all(jnp.isfinite(a))
    return ok


def _column_norms(H, fallback) -> Float[Array, " p"]:
    diag = jnp.sqrt(jnp.clip(jnp.diagonal(H), 0.0))
    return jnp.where(jnp.isfinite(diag) & (diag > 0), diag, fallback)


# ---- the descent -----------------------------------------------------------------------------


class _DescentState(eqx.Module):
    fresh: Bool[Array, ""]
    grad: Float[Array, " p"]
    gram: Float[Array, "p p"]
    scale: Float[Array, " p"]
    result: optx.RESULTS


class ScaledDampedNewton(optx.AbstractDescent):
    """The damped Gauss–Newton step in Moré's scaled coordinates.

    ``δ = D⁻¹ δₛ`` with ``(D⁻¹ H D⁻¹ + λ I) δₛ = −D⁻¹ g``, ``D`` the running maximum of the
    column norms of ``J`` (so the step does not depend on how each coordinate is scaled) and
    ``λ = 1/step_size``. The step is shortened as a whole (its direction kept) so that no
    coordinate moves by more than ``step_cap``; a saturated coordinate (its column of ``J``
    vanishes, as for a parameter resting on a bound) is clipped on its own instead, so that it
    cannot freeze the others. ``step_cap=None`` turns the cap off.
    """

    step_cap: float | None = 2.0

    def init(self, y, f_info_struct) -> _DescentState:
        p = f_info_struct.grad.shape[0]
        dtype = f_info_struct.grad.dtype
        return _DescentState(
            jnp.array(True),
            jnp.zeros((p,), dtype),
            jnp.eye(p, dtype=dtype),
            jnp.ones((p,), dtype),
            optx.RESULTS.successful,
        )

    def query(self, y, f_info, state: _DescentState) -> _DescentState:
        H = _gram(f_info)
        # Moré's scaling: the running maximum of the column norms of J (the first: their value)
        scale = jnp.where(
            state.fresh, _column_norms(H, 1.0), jnp.maximum(state.scale, _column_norms(H, 0.0))
        )
        return _DescentState(jnp.array(False), f_info.grad, H, scale, state.result)

    def step(self, step_size: Scalar, state: _DescentState) -> tuple[Array, optx.RESULTS]:
        d, g, H = state.scale, state.grad, state.gram
        lam = 1.0 / step_size
        M = H / (d[:, None] * d[None, :]) + lam * jnp.eye(d.shape[0], dtype=d.dtype)
        L = jnp.linalg.cholesky(M)
        step = -jax.scipy.linalg.cho_solve((L, True), g / d) / d
        if self.step_cap is not None:
            limit = self.step_cap
            col = jnp.sqrt(jnp.clip(jnp.diagonal(H), 0.0))
            sat = col < _SATURATED * jnp.max(col)
            big = jnp.max(jnp.where(sat, 0.0, jnp.abs(step)))
            shrink = jnp.minimum(1.0, limit / jnp.where(big > 0, big, 1.0))
            step = jnp.where(sat, jnp.clip(step, -limit, limit), step * shrink)
        return step, state.result


# ---- the search ------------------------------------------------------------------------------


class _SearchState(eqx.Module):
    damping: Scalar
    nu: Scalar
    actual: Scalar  # actual reduction of Σ r² by the last trial
    predicted: Scalar  # reduction of Σ r² the linear model predicted for it
    accepted: Bool[Array, ""]


class NielsenDamping(optx.AbstractSearch):
    """Levenberg–Marquardt damping from the gain ratio ρ (Nielsen 1999).

    A trial with ``ρ = actual / predicted > 10⁻⁴`` is accepted and λ is multiplied by
    ``max(1/3, 1 − (2ρ − 1)³)``; a rejected trial multiplies λ by ν, and ν doubles. Returns the
    step size ``1/λ`` for :class:`ScaledDampedNewton`.
    """

    damping0: float = 1e-2

    def init(self, y, f_info_struct) -> _SearchState:
        dtype = f_info_struct.f.dtype
        zero = jnp.zeros((), dtype)
        return _SearchState(
            jnp.asarray(self.damping0, dtype),
            jnp.asarray(2.0, dtype),
            zero,
            zero,
            jnp.array(False),
        )

    def step(self, first_step, y, y_eval, f_info, f_eval_info, state: _SearchState):
        s = y_eval - y
        H = _gram(f_info)
        # reductions of Σ r² = 2 f
        predicted = -(2.0 * jnp.dot(f_info.grad, s) + s @ H @ s)
        actual = 2.0 * (f_info.f - f_eval_info.f)
        ok = (
            _finite(f_eval_info.f, f_eval_info.grad, _gram(f_eval_info))
            & (predicted > 0)
            & (actual > _ACCEPT * predicted)
        )
        rho = jnp.where(ok, actual / jnp.where(predicted > 0, predicted, 1.0), 0.0)
        lam = jnp.where(
            ok,
            state.damping * jnp.maximum(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3),
            state.damping * state.nu,
        )
        nu = jnp.where(ok, 2.0, 2.0 * state.nu)
        lam = jnp.where(first_step, self.damping0, lam)
        nu = jnp.where(first_step, 2.0, nu)
        accept = first_step | ok
        new = _SearchState(lam, nu, actual, predicted, ok & ~first_step)
        return 1.0 / lam, accept, optx.RESULTS.successful, new


# ---- the solver ------------------------------------------------------------------------------


class LMState(eqx.Module):
    """State of :class:`LevenbergMarquardt` between steps (one start)."""

    first_step: Bool[Array, ""]
    y_eval: Any
    f_info: _Info
    aux: Any
    search_state: _SearchState
    descent_state: _DescentState
    terminate: Bool[Array, ""]
    result: optx.RESULTS
    num_steps: Int[Array, ""]
    num_accepted_steps: Int[Array, ""]


def _jacfwd_normal_equations(fn, y, args):
    """``(½ Σ r², Jᵀr, JᵀJ)``, ``aux`` and the unravel function of a residual function."""
    flat, unravel = ravel_pytree(y)

    def residuals(v):
        r, aux = fn(unravel(v), args)
        return ravel_pytree(r)[0], aux

    def with_value(v):
        r, aux = residuals(v)
        return r, (r, aux)

    # the residuals from the Jacobian's own primal: the model is traced and run once
    J, (r, aux) = jax.jacfwd(with_value, has_aux=True)(flat)
    return (0.5 * jnp.dot(r, r), J.T @ r, J.T @ J), aux


class LevenbergMarquardt(optx.AbstractLeastSquaresSolver):
    """Levenberg–Marquardt with Moré scaling and Nielsen damping, as an optimistix solver.

    Args:
        rtol, atol: a solve has converged when an accepted step reduced ``Σ r²``, and the linear
            model predicted it to reduce, by at most ``rtol · Σ r² + atol``.
        norm: kept for optimistix's interface (the test above does not use it).
        descent: the step; :class:`ScaledDampedNewton` by default.
        search: the damping; :class:`NielsenDamping` by default.

    Options (``options`` of ``optx.least_squares`` or of :meth:`step`):
        ``normal_equations``: ``(y, args) -> (½ Σ r², Jᵀr, JᵀJ)`` for a flat ``y`` [p], used
        instead of differentiating ``fn`` (which is then not called).
    """

    rtol: float = 1e-6
    atol: float = 1e-16
    norm: Callable[[PyTree], Scalar] = optx.max_norm
    descent: ScaledDampedNewton = ScaledDampedNewton()
    search: NielsenDamping = NielsenDamping()

    def _evaluate(self, fn, y, args, options):
        lin = options.get("normal_equations")
        if lin is not None:
            return lin(y, args), None
        return _jacfwd_normal_equations(fn, y, args)

    def init(self, fn, y, args, options, f_struct, aux_struct, tags) -> LMState:
        flat = ravel_pytree(y)[0]
        p, dtype = flat.shape[0], flat.dtype
        info = _info(jnp.zeros((), dtype), jnp.zeros((p,), dtype), jnp.zeros((p, p), dtype))
        info_struct = jax.eval_shape(lambda: info)
        aux = None if options.get("normal_equations") is not None else aux_struct
        return LMState(
            first_step=jnp.array(True),
            y_eval=y,
            f_info=info,
            aux=jax.tree_util.tree_map(lambda s: jnp.zeros(s.shape, s.dtype), aux),
            search_state=self.search.init(flat, info_struct),
            descent_state=self.descent.init(flat, info_struct),
            terminate=jnp.array(False),
            result=optx.RESULTS.successful,
            num_steps=jnp.array(0),
            num_accepted_steps=jnp.array(0),
        )

    def step(self, fn, y, args, options, state: LMState, tags):
        flat, unravel = ravel_pytree(y)
        flat_eval = ravel_pytree(state.y_eval)[0]
        (f, g, H), aux_eval = self._evaluate(fn, state.y_eval, args, options)
        eval_info = _info(f, g, H)
        step_size, accept, search_result, search_state = self.search.step(
            state.first_step, flat, flat_eval, state.f_info, eval_info, state.search_state
        )
        finite = _finite(flat_eval, f, g, H)
        descent_state = jax.lax.cond(
            accept & finite,
            lambda s: self.descent.query(flat_eval, eval_info, s),
            lambda s: s,
            state.descent_state,
        )
        keep = accept & finite
        new_flat = jnp.where(keep, flat_eval, flat)
        f_info = jax.tree_util.tree_map(lambda a, b: jnp.where(keep, a, b), eval_info, state.f_info)
        aux = (
            None
            if state.aux is None
            else jax.tree_util.tree_map(lambda a, b: jnp.where(keep, a, b), aux_eval, state.aux)
        )
        # termination: MINPACK's ftol test on an accepted step, or a damping that cannot grow
        cost = 2.0 * state.f_info.f
        tol = self.rtol * cost + self.atol
        small = (
            search_state.accepted & (search_state.actual <= tol) & (search_state.predicted <= tol)
        )
        stalled = search_state.damping > _LAMBDA_MAX
        diverged = state.first_step & ~finite
        terminate = diverged | (~state.first_step & (small | stalled))
        result = optx.RESULTS.where(diverged, optx.RESULTS.nonlinear_divergence, search_result)
        step, descent_result = self.descent.step(step_size, descent_state)
        result = optx.RESULTS.where(result == optx.RESULTS.successful, descent_result, result)
        new_state = LMState(
            first_step=jnp.array(False),
            y_eval=unravel(new_flat + step),
            f_info=f_info,
            aux=aux,
            search_state=search_state,
            descent_state=descent_state,
            terminate=terminate,
            result=result,
            num_steps=state.num_steps + jnp.where(state.first_step, 0, 1),
            num_accepted_steps=state.num_accepted_steps + jnp.where(search_state.accepted, 1, 0),
        )
        # on a diverged first point, report it (not the placeholder) as the iterate
        out = unravel(jnp.where(diverged, flat_eval, new_flat))
        return out, new_state, aux

    def terminate(self, fn, y, args, options, state: LMState, tags):
        return state.terminate, state.result

    def postprocess(self, fn, y, aux, args, options, state: LMState, tags, result):
        return y, aux, {"cost": 2.0 * state.f_info.f, "steps": state.num_steps}
