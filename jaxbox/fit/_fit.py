"""Batched multistart Levenberg–Marquardt: every start of a problem in one compiled call.

The solve for all starts is ``jax.vmap`` of ``optimistix.least_squares`` (``throw=False``, so one
failing start does not stop the batch), jitted and compiled ahead of time once per problem
*structure* — model structure, free/fixed split, transform kinds, simulator, solver settings and
array shapes. Data, bounds, fixed values and starts are arguments, so a second dataset of the same
length, new bounds or new starts reuse the compiled executable (``compile_s == 0``).

The default simulator is the exact first-order-hold discretisation: for a linear model it has no
discretisation error, costs one small matrix exponential and a scan per residual evaluation, and
its forward-mode Jacobian is cheap. ``simulator="diffrax"`` fits through Kvaerno5 with one
fixed step per sample (or ``sim_options={"substeps": k}``) in forward mode.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .._x64 import require_x64
from ..models import get_model
from ._problem import FitError, Problem, make_problem, problem_arrays
from ._result import FitResult, StartReport
from ._starts import latin_hypercube

__all__ = ["fit", "solve_starts", "compile_cache_info", "clear_compile_cache"]

_CACHE: dict = {}
_STATS = {"compiles": 0, "hits": 0}

_CODES = {
    "successful": "converged",
    "nonlinear_max_steps_reached": "max_steps",
    "max_steps_reached": "max_steps",
}


def compile_cache_info() -> dict:
    """Number of compilations and cache hits of batched solves in this process."""
    return {"entries": len(_CACHE), **_STATS}


def clear_compile_cache() -> None:
    _CACHE.clear()
    _STATS.update(compiles=0, hits=0)


def _structure_key(problem: Problem, shapes, max_steps, rtol, atol):
    return (
        problem.model.structure,
        problem.free,
        tuple(n for n, _ in problem.fixed),
        problem.transform.kinds,
        problem.simulator,
        problem.sim_options,
        max_steps,
        rtol,
        atol,
        shapes,
    )


def _build_batched(problem: Problem, max_steps: int, rtol: float, atol: float):
    solver = optx.LevenbergMarquardt(rtol=rtol, atol=atol)

    def one(z0, args):
        sol = optx.least_squares(
            problem.residuals, solver, z0, args=args, max_steps=max_steps, throw=False
        )
        r = problem.residuals(sol.value, args)
        return sol.value, sol.result._value, sol.stats["num_steps"], jnp.sum(r * r)

    def batched(z0s, fixed_values, t, u, y, sqrt_w, lo, hi, sc):
        args = (fixed_values, t, u, y, sqrt_w, lo, hi, sc)
        return jax.vmap(one, in_axes=(0, None))(z0s, args)

    return jax.jit(batched)


def solve_starts(
    problem: Problem,
    starts: np.ndarray,
    arrays,
    *,
    max_steps: int = 200,
    rtol: float = 1e-8,
    atol: float = 1e-8,
):
    """Run LM from every start (physical values [S, p]) in one compiled, vmapped call.

    Returns a dict with ``z``, ``p`` [S, p], ``code`` [S] (optimistix result index), ``steps``,
    ``cost`` [S], ``compile_s`` and ``fit_s``.
    """
    t, u, y, sqrt_w = arrays
    tr = problem.transform
    z0 = tr.to_internal(starts)
    # a start that is not finite is passed through: it fails inside the batch and is reported
    z0 = np.where(np.isfinite(np.asarray(starts, float)), z0, np.nan)
    fixed_values = np.asarray([v for _, v in problem.fixed], dtype=float)
    args = (z0, fixed_values, t, u, y, sqrt_w, tr.lower, tr.upper, tr.scale)
    args = tuple(jnp.asarray(a, dtype=float) for a in args)
    shapes = tuple(a.shape for a in args)
    key = _structure_key(problem, shapes, max_steps, rtol, atol)
    compile_s = 0.0
    compiled = _CACHE.get(key)
    if compiled is None:
        t0 = time.perf_counter()
        compiled = _build_batched(problem, max_steps, rtol, atol).lower(*args).compile()
        compile_s = time.perf_counter() - t0
        _CACHE[key] = compiled
        _STATS["compiles"] += 1
    else:
        _STATS["hits"] += 1
    t0 = time.perf_counter()
    z, code, steps, cost = jax.block_until_ready(compiled(*args))
    fit_s = time.perf_counter() - t0
    z = np.asarray(z)
    p = np.asarray(tr.to_physical(jnp.asarray(z)))
    return {
        "z": z,
        "p": p,
        "code": np.asarray(code),
        "steps": np.asarray(steps),
        "cost": np.asarray(cost),
        "compile_s": compile_s,
        "fit_s": fit_s,
    }


def _status(code: int, cost: float, p: np.ndarray) -> str:
    if not (np.isfinite(cost) and np.all(np.isfinite(p))):
        return "nonfinite"
    key = list(optx.RESULTS._name_to_item)[int(code)]
    return _CODES.get(key, f"failed ({key})")


def fit(
    model,
    data,
    *,
    free: Sequence[str] | None = None,
    fixed: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    guess: Mapping[str, float] | None = None,
    starts: int | np.ndarray = 1,
    seed: int | None = 0,
    weights: Mapping[str, float] | Sequence[float] | None = None,
    simulator: str = "exact",
    sim_options: Mapping | None = None,
    max_steps: int = 200,
    rtol: float = 1e-8,
    atol: float = 1e-8,
    concentration: float = 4.0,
) -> FitResult:
    """Estimate the parameters of ``model`` from ``data`` by output-error least squares.

    Args:
        model: an :class:`~jaxbox.models.RCModel` or a library model name.
        data: the identification :class:`~jaxbox.data.Dataset` (inputs and outputs).
        free: parameters to estimate (default: all that are not ``fixed``; initial states
            included).
        fixed: parameter values held fixed (SI).
        bounds: ``{name: (lower, upper)}`` overriding the naming-convention bounds (SI).
        guess: initial guesses overriding the defaults (SI); initial states default to the
            data (see :func:`~jaxbox.fit.initial_guess`).
        starts: number of starts (the guess plus Latin-hypercube samples around it), or an
            array [S, n_free] of explicit starts in physical units.
        seed: seed of the Latin hypercube.
        weights: output weights q_j (per output name or in ``model.outputs`` order).
        simulator: ``"exact"`` (default, exact for linear models) or ``"diffrax"``.
        sim_options: diffrax options, e.g. ``{"substeps": 2}``.
        max_steps: Levenberg–Marquardt iteration cap per start.
        rtol, atol: Levenberg–Marquardt termination tolerances (on the unbounded coordinates
            and the cost).
        concentration: spread of the Latin hypercube around the guess (0: uniform).

    Returns:
        :class:`FitResult` with the best start's parameters, every start's outcome and timings.

    Raises:
        FitError: an ill-posed problem, or every start failed.
    """
    require_x64()
    model = get_model(model)
    problem = make_problem(
        model,
        data,
        free=free,
        fixed=fixed,
        bounds=bounds,
        guess=guess,
        weights=weights,
        simulator=simulator,
        sim_options=sim_options,
    )
    arrays = problem_arrays(problem, data)
    g = np.asarray([problem.guess_dict[n] for n in problem.free])
    if isinstance(starts, int | np.integer):
        if starts < 1:
            raise FitError(f"starts must be at least 1, got {starts}")
        x0s = g[None, :]
        if starts > 1:
            lhs = latin_hypercube(problem.transform, g, starts - 1, seed, concentration)
            x0s = np.concatenate([x0s, lhs], axis=0)
    else:
        x0s = np.atleast_2d(np.asarray(starts, dtype=float))
        if x0s.shape[1] != len(problem.free):
            raise FitError(
                "explicit starts must have one column per free parameter "
                f"({', '.join(problem.free)}), got shape {x0s.shape}"
            )
    out = solve_starts(problem, x0s, arrays, max_steps=max_steps, rtol=rtol, atol=atol)
    status = [_status(c, k, p) for c, k, p in zip(out["code"], out["cost"], out["p"], strict=True)]
    report = StartReport(
        initial=x0s,
        params=out["p"],
        cost=out["cost"],
        steps=out["steps"],
        status=tuple(status),
    )
    best = report.best_index()
    if best is None:
        raise FitError(
            f"all {len(status)} starts failed for model {model.name} "
            f"({report.status_summary()}); check the data and bounds, or add starts"
        )
    return FitResult.from_best(
        problem=problem,
        data=data,
        report=report,
        best=best,
        timing={"compile_s": out["compile_s"], "fit_s": out["fit_s"]},
        settings={"max_steps": max_steps, "rtol": rtol, "atol": atol, "seed": seed},
    )
