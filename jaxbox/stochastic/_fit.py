"""Maximum-likelihood (and MAP) estimation of the stochastic form of an RC model.

Every start (the guess plus Latin-hypercube samples, :func:`jaxbox.fit.sample_starts`) of every
dataset runs BFGS (``optimistix.BFGS``) on the negative log-likelihood per observation, in the
bound transform's unbounded coordinates, under one ``vmap`` in one compiled call (kept in
:mod:`jaxbox._compiled`); a start ends when BFGS converges, when its objective stalls (not
lowered by 1e-8 of itself in 50 steps) or at ``max_steps`` (1000). The gradient is
reverse-mode autodiff through the Kalman filter's ``lax.scan``. The network, its noise
parameters and the bound transform enter the compiled solve as arrays padded to rounded sizes
(:mod:`jaxbox.stochastic._arrays`), so every model
structure of the same padded size, every free/fixed split and every set of bounds share one
program per data shape; a network with a node held at a constant temperature has a program of
its own.

At the best start, the exact Hessian of the NLL (plus the log prior) with respect to the
physical free parameters (``jax.hessian``) gives the covariance of the estimates, their
correlations, t-statistics and two-sided p-values (t distribution with ``N_obs − k`` degrees of
freedom), as CTSM reports them.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array

from .. import _compiled
from .._compiled import jit
from .._defaults import DEFAULT_CONCENTRATION
from .._derivatives import value_grad_hessian
from .._exported import compile_program
from .._x64 import require_x64
from ..fit._fit import bucket_samples
from ..fit._problem import FitError
from ..fit._result import StartReport
from ..fit._starts import sample_starts
from ..fit._transforms import Transform, to_physical_coded
from ..models import get_model
from ..simulate._extend import hold_rows
from ._arrays import KEYS, has_array_form, ml_arrays, padded_sizes, system_from_arrays
from ._checks import as_data, as_datasets, number
from ._kalman import kalman_scan
from ._problem import (
    StochasticProblem,
    make_stochastic_problem,
    neg_log_prior,
    stochastic_arrays,
    system,
)
from ._result import MLResult

__all__ = ["fit_ml", "fit_ml_many", "DEFAULT_ML_STARTS", "DEFAULT_ML_MAX_STEPS"]

DEFAULT_ML_STARTS = 16
"""Starts of a maximum-likelihood fit (the default guess, then Latin-hypercube samples)."""
DEFAULT_ML_MAX_STEPS = 1000
"""BFGS steps at most per maximum-likelihood start."""
#: a start whose objective has not fallen by ``ML_STALL_RTOL`` of itself for ``ML_STALL_WINDOW``
#: steps has converged (its coordinates may still creep towards a bound)
ML_STALL_WINDOW = 50
ML_STALL_RTOL = 1e-8
_CONVERGED, _MAX_STEPS, _NONFINITE = 0, 1, 2


class _StallState(eqx.Module):
    inner: Any
    f_ref: Array
    since: Array


class _Stalling(optx.AbstractMinimiser):
    """A minimiser that also ends when its objective stalls: not lowered by ``rtol · |f|`` for
    ``window`` steps. BFGS's own test (objective *and* coordinates settled) never ends a start
    whose coordinates creep towards a bound through the bound transform, each step lowering the
    objective by nothing that matters; with many starts under one ``vmap`` the slowest sets
    the time."""

    inner: optx.AbstractMinimiser
    window: int = ML_STALL_WINDOW
    stall_rtol: float = ML_STALL_RTOL

    @property
    def rtol(self) -> float:
        return self.inner.rtol

    @property
    def atol(self) -> float:
        return self.inner.atol

    @property
    def norm(self):
        return self.inner.norm

    def init(self, fn, y, args, options, f_struct, aux_struct, tags) -> _StallState:
        state = self.inner.init(fn, y, args, options, f_struct, aux_struct, tags)
        return _StallState(state, jnp.asarray(jnp.inf, f_struct.dtype), jnp.asarray(0))

    def step(self, fn, y, args, options, state: _StallState, tags):
        y, inner, aux = self.inner.step(fn, y, args, options, state.inner, tags)
        f = inner.f_info.f
        lower = f < state.f_ref - self.stall_rtol * jnp.abs(f)
        f_ref = jnp.where(lower | ~jnp.isfinite(state.f_ref), f, state.f_ref)
        since = jnp.where(lower, 0, state.since + 1)
        return y, _StallState(inner, f_ref, since), aux

    def terminate(self, fn, y, args, options, state: _StallState, tags):
        done, result = self.inner.terminate(fn, y, args, options, state.inner, tags)
        return done | (state.since >= self.window), result

    def postprocess(self, fn, y, aux, args, options, state: _StallState, tags, result):
        return self.inner.postprocess(fn, y, aux, args, options, state.inner, tags, result)


def _objective(full: Transform, model, hold: str):
    """Objective per observation over every parameter: free ones from the coordinates ``z``
    (through ``full``), fixed ones from ``values`` (their coordinates are ignored, so their
    gradient is zero and BFGS leaves them where they are)."""
    names = full.names

    def f(z, mask, values, lo, hi, sc, pm, ps, x0_std, dt, scale, u, y):
        p = jnp.where(mask, full.to_physical(z, lo, hi, sc), values)
        theta = {n: p[..., i] for i, n in enumerate(names)}
        mats, C, D, r, m0, P0 = system(model, theta, dt, hold, x0_std)
        nll = kalman_scan(mats, C, D, r, m0, P0, u, y)
        return (nll + neg_log_prior(p, pm, jnp.where(mask, ps, jnp.inf))) / scale

    return f


def _bfgs(obj, max_steps: int, rtol: float, atol: float, per_member: bool, n_args: int):
    """BFGS on ``obj(z, *args)`` from every start under one ``vmap`` over the ``n_args``
    arguments of ``(z0, *args)`` (the data, the last two, shared unless ``per_member``):
    ``(z, objective, code, steps)`` per start. A start also ends when its objective stalls
    (:class:`_Stalling`)."""
    solver = _Stalling(optx.BFGS(rtol=rtol, atol=atol))

    def one(z0, *args):
        def fn(z, _):
            v = obj(z, *args)
            return jnp.where(jnp.isfinite(v), v, jnp.inf)

        sol = optx.minimise(fn, solver, z0, max_steps=max_steps, throw=False)
        val = obj(sol.value, *args)
        steps = sol.stats["num_steps"]
        ok = sol.result == optx.RESULTS.successful
        code = jnp.where(
            ~jnp.isfinite(val),
            _NONFINITE,
            jnp.where(ok, _CONVERGED, jnp.where(steps >= max_steps, _MAX_STEPS, _NONFINITE)),
        )
        return sol.value, val, code.astype(jnp.int32), steps

    d = 0 if per_member else None
    return jit(jax.vmap(one, in_axes=(0,) * (n_args - 2) + (d, d)))


def _build(full, model, hold, max_steps: int, rtol: float, atol: float, per_member: bool):
    """The batched BFGS solve of one model structure (a network with a held node)."""
    return _bfgs(_objective(full, model, hold), max_steps, rtol, atol, per_member, 13)


def _nll_arrays(p, a: dict, dt, hold: str, u, y):
    """The negative log-likelihood of a problem in array form (``a``: the arrays of
    :func:`~jaxbox.stochastic._arrays.ml_arrays` by name) at the padded values ``p`` [P]."""
    v = jnp.concatenate([p, jnp.asarray([1.0, 0.0], dtype=p.dtype)])
    mats, C, D, r, m0, P0 = system_from_arrays(v, a, dt, hold)
    return kalman_scan(mats, C, D, r, m0, P0, u, y)


def _objective_arrays(style: str, hold: str):
    """:func:`_objective` for a problem in array form: ``f(z, arrays, dt, scale, u, y)`` with
    ``arrays`` the values of :func:`~jaxbox.stochastic._arrays.ml_arrays` in ``KEYS`` order."""

    def f(z, arrays, dt, scale, u, y):
        a = dict(zip(KEYS, arrays, strict=True))
        physical = to_physical_coded(z, a["lower"], a["upper"], a["scale"], a["kinds"], style)
        p = jnp.where(a["mask"], physical, a["values"])
        nll = _nll_arrays(p, a, dt, hold, u, y)
        ps = jnp.where(a["mask"], a["prior_sd"], jnp.inf)
        return (nll + neg_log_prior(p, a["prior_mean"], ps)) / scale

    return f


def _build_arrays(style, hold, max_steps: int, rtol: float, atol: float, per_member: bool):
    """The batched BFGS solve of problems in array form (one program per padded size)."""
    return _bfgs(_objective_arrays(style, hold), max_steps, rtol, atol, per_member, 6)


def _pad_columns(u: np.ndarray, width: int) -> np.ndarray:
    """Inputs [N, m] with zero columns up to ``width`` (padding inputs of the array form)."""
    return np.concatenate([u, np.zeros((u.shape[0], width - u.shape[1]))], axis=1)


def _pad_rows(u: np.ndarray, y: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(u [N, m], y [N, p])`` extended to ``n`` samples: the inputs hold their last values,
    the outputs are missing (NaN). The filter's missing samples add exactly nothing to the
    likelihood, its gradient and its Hessian, and the held inputs leave the drive of the last
    real sample as it was: a record padded so is the record itself, to the rounding of a
    longer sum."""
    u, y = np.asarray(u, dtype=float), np.asarray(y, dtype=float)
    extra = n - len(u)
    if extra <= 0:
        return u, y
    return hold_rows(u, n), np.concatenate([y, np.full((extra, y.shape[1]), np.nan)])


def _records(jobs) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each job's ``(u, y)`` as the solve takes it: as they are where every record has the same
    length, else each padded (:func:`_pad_rows`) to the longest rounded up to its bucket
    (:func:`jaxbox.fit._fit.bucket_samples`), so that later solves of neighbouring lengths
    share the program. Padding adds no finite output: the count of observations stays."""
    records = [(u, y) for _, _, (_, u, y) in jobs]
    lengths = {len(u) for u, _ in records}
    if len(lengths) == 1:
        return records
    n = bucket_samples(max(lengths))
    return [_pad_rows(u, y, n) for u, y in records]


def solve_ml(
    jobs: Sequence[tuple[StochasticProblem, np.ndarray, tuple]],
    *,
    max_steps: int = DEFAULT_ML_MAX_STEPS,
    rtol: float = 1e-8,
    atol: float = 1e-8,
) -> dict:
    """BFGS from every start of every job in one compiled, batched call.

    A job is ``(problem, starts [S, k] physical, (dt, u, y))``. Jobs must share the hold, the
    style of the bound transforms and the outputs; they may differ in model structure, data,
    record length (records of different lengths are padded to the bucket of the longest with
    missing samples, which add nothing to the likelihood: :func:`_pad_rows`), bounds, fixed
    values, priors and in which parameters are free. The
    compiled solve is kept per padded size (:mod:`jaxbox.stochastic._arrays`), hold, data
    shape and solver settings; a job whose network holds a node at a constant temperature
    needs jobs of its own structure and transform kinds, and a program of its own.

    Returns per member: ``job``, ``p`` [B, k] (each job's free parameters), ``objective`` [B]
    (NLL + prior per observation), ``code`` (0 converged, 1 step cap, 2 non-finite),
    ``steps``; and ``compile_s``, ``fit_s``.
    """
    if not jobs:
        raise FitError("no job to solve")
    if all(has_array_form(sp.model) for sp, _, _ in jobs):
        return _solve_arrays(jobs, max_steps, rtol, atol)
    fulls = [sp.full_transform() for sp, _, _ in jobs]
    keys = {
        (sp.model.structure, sp.hold, f[0].kinds, f[0].style)
        for (sp, _, _), f in zip(jobs, fulls, strict=True)
    }
    if len(keys) > 1:
        raise FitError(
            "jobs solved together need the same model structure, hold and bound transforms"
        )
    shapes = {(np.shape(a[1])[1:], np.shape(a[2])[1:]) for _, _, a in jobs}
    if len(shapes) > 1:
        raise FitError(
            f"datasets solved together need the same columns; got {sorted(shapes)} "
            "(inputs, outputs)"
        )
    sp0, full0 = jobs[0][0], fulls[0][0]
    n_all = len(full0.names)
    cols: list[list] = [[] for _ in range(12)]
    us, ys, counts, free_idx = [], [], [], []
    for (sp, starts, (dt, _, _)), (u, y), (full, mask, values) in zip(
        jobs, _records(jobs), fulls, strict=True
    ):
        starts = np.atleast_2d(np.asarray(starts, dtype=float))
        s = len(starts)
        idx = np.flatnonzero(mask)
        z0 = np.zeros((s, n_all))
        z0[:, idx] = np.where(np.isfinite(starts), sp.transform.to_internal(starts), np.nan)
        pm = np.zeros(n_all)
        ps = np.full(n_all, np.inf)
        pm[idx], ps[idx] = sp.prior_arrays()
        rows = (mask, values, full.lower, full.upper, full.scale, pm, ps, sp.x0_std)
        cols[0].append(z0)
        for c, a in zip(cols[1:9], rows, strict=True):
            a = np.asarray(a, dtype=float)
            c.append(np.broadcast_to(a, (s, len(a))))
        cols[9].append(np.full(s, float(dt)))
        cols[10].append(np.full(s, float(np.isfinite(y).sum())))
        us.append(u)
        ys.append(y)
        counts.append(s)
        free_idx.append(idx)
    members = [np.concatenate(c, axis=0) for c in cols[:11]]
    per_member = len(jobs) > 1
    u, y = _data(us, ys, counts)
    args = [jnp.asarray(a, dtype=float) for a in (*members, u, y)]
    args[1] = args[1].astype(bool)
    key = (
        "stochastic",
        "ml",
        sp0.model.structure,
        sp0.hold,
        full0.kinds,
        full0.style,
        tuple(a.shape for a in args),
        max_steps,
        rtol,
        atol,
    )
    build = lambda: _build(full0, sp0.model, sp0.hold, max_steps, rtol, atol, per_member)  # noqa: E731
    (z, *out), times = _compile_and_run(key, build, args)
    p_all = full0.to_physical(np.asarray(z, dtype=float), members[3], members[4], members[5])
    starts = np.cumsum([0, *counts])
    parts = [
        p_all[a:b][:, idx] for a, b, idx in zip(starts[:-1], starts[1:], free_idx, strict=True)
    ]
    return _outcome(counts, parts, out, times)


def _data(us, ys, counts) -> tuple:
    """``(u, y)`` of the solve: one series shared by every start, or with several jobs each
    start's own (a leading axis over the starts)."""
    if len(us) == 1:
        return us[0], ys[0]
    rep = lambda arrays: np.concatenate(  # noqa: E731
        [np.repeat(a[None], c, 0) for a, c in zip(arrays, counts, strict=True)]
    )
    return rep(us), rep(ys)


def _compile_and_run(key, build, args) -> tuple:
    """The compiled solve of ``key`` (built on a miss) run on ``args``: its outputs and
    ``(compile_s, fit_s)``."""
    t0 = time.perf_counter()
    # through a serialized export: a later process skips the tracing and lowering (most of a
    # warm ``jaxbox fit --method ml``), and XLA's persistent cache finds the executable
    compiled, built = _compiled.cached(
        key, lambda: compile_program("stochastic", key, build(), tuple(args))
    )
    compile_s = time.perf_counter() - t0 if built else 0.0
    t0 = time.perf_counter()
    out = jax.block_until_ready(compiled(*args))
    return out, (compile_s, time.perf_counter() - t0)


def _outcome(counts, parts, out, times) -> dict:
    """What :func:`solve_ml` returns, from each job's free parameters ``parts`` and the
    solve's ``(objective, code, steps)`` and ``(compile_s, fit_s)``."""
    val, code, steps = out
    width = {p.shape[1] for p in parts}
    return {
        "job": np.repeat(np.arange(len(parts)), counts),
        "p": np.concatenate(parts, axis=0) if len(width) == 1 else parts,
        "p_jobs": parts,
        "objective": np.asarray(val),
        "code": np.asarray(code),
        "steps": np.asarray(steps),
        "compile_s": times[0],
        "fit_s": times[1],
    }


def _solve_arrays(jobs, max_steps: int, rtol: float, atol: float) -> dict:
    """:func:`solve_ml` of jobs whose networks have an array form: one program per padded
    size, hold, data shape and solver settings, whatever their structures."""
    problems = [sp for sp, _, _ in jobs]
    if len({(sp.hold, sp.transform.style) for sp in problems}) > 1:
        raise FitError("jobs solved together need the same hold and bound-transform style")
    shapes = {np.shape(a[2])[1:] for _, _, a in jobs}
    if len(shapes) > 1:
        raise FitError(
            f"datasets solved together need the same outputs; got {sorted(shapes)} outputs"
        )
    sizes = padded_sizes(problems)
    z0s, members, dts, scales, us, ys, counts, free_idx = [], [], [], [], [], [], [], []
    for (sp, starts, (dt, _, _)), (u, y) in zip(jobs, _records(jobs), strict=True):
        starts = np.atleast_2d(np.asarray(starts, dtype=float))
        s = len(starts)
        idx = np.asarray([sp.param_names.index(n) for n in sp.free])
        z0 = np.zeros((s, sizes["params"]))
        z0[:, idx] = np.where(np.isfinite(starts), sp.transform.to_internal(starts), np.nan)
        arrays = ml_arrays(sp, sizes)
        z0s.append(z0)
        members.append([np.broadcast_to(arrays[k], (s, *np.shape(arrays[k]))) for k in KEYS])
        dts.append(np.full(s, float(dt)))
        scales.append(np.full(s, float(np.isfinite(y).sum())))
        us.append(_pad_columns(np.asarray(u, dtype=float), sizes["inputs"]))
        ys.append(np.asarray(y, dtype=float))
        counts.append(s)
        free_idx.append(idx)
    per_member = len(jobs) > 1
    u, y = _data(us, ys, counts)
    arrays = tuple(jnp.asarray(np.concatenate(c, axis=0)) for c in zip(*members, strict=True))
    z0 = jnp.asarray(np.concatenate(z0s), dtype=float)
    rest = tuple(jnp.asarray(np.concatenate(a), dtype=float) for a in (dts, scales))
    data = (jnp.asarray(u, dtype=float), jnp.asarray(y, dtype=float))
    args = (z0, arrays, *rest, *data)
    sp0 = problems[0]
    key = (
        "stochastic",
        "ml-arrays",
        sp0.hold,
        sp0.transform.style,
        tuple((a.shape, str(a.dtype)) for a in jax.tree_util.tree_leaves(args)),
        max_steps,
        rtol,
        atol,
    )
    build = lambda: _build_arrays(sp0.transform.style, sp0.hold, max_steps, rtol, atol, per_member)  # noqa: E731
    (z, *out), times = _compile_and_run(key, build, args)
    z = np.asarray(z, dtype=float)
    starts = np.cumsum([0, *counts])
    parts = [
        sp.transform.to_physical(z[a:b][:, idx])
        for (sp, _, _), a, b, idx in zip(jobs, starts[:-1], starts[1:], free_idx, strict=True)
    ]
    return _outcome(counts, parts, out, times)


def _hessian(sp: StochasticProblem, vec: np.ndarray, dt: float, u, y):
    """NLL, its gradient and its exact Hessian in every parameter (``param_names`` order) at
    the values ``vec``: one program per padded size, hold and data shape, the record padded to
    its bucket of samples (:func:`_pad_rows`; a network without an array form: per structure
    and length)."""
    if not has_array_form(sp.model):
        fn = _hessian_fn(sp, (np.shape(u), np.shape(y)))
        args = (vec, np.asarray(sp.x0_std), dt, u, y)
        return fn(*(jnp.asarray(a, dtype=float) for a in args))
    sizes = padded_sizes([sp])
    arrays = tuple(jnp.asarray(a) for a in (ml_arrays(sp, sizes)[k] for k in KEYS))
    pv = np.zeros(sizes["params"])
    pv[: len(vec)] = vec
    # the record padded to its bucket: a program for records of neighbouring lengths
    u, y = _pad_rows(u, y, bucket_samples(len(u)))
    data = (_pad_columns(u, sizes["inputs"]), y)
    args = (jnp.asarray(pv), arrays, jnp.asarray(float(dt)), *(jnp.asarray(a) for a in data))
    shapes = tuple((a.shape, str(a.dtype)) for a in jax.tree_util.tree_leaves(args))
    hold = sp.hold

    def build():
        def f(pv, arrays, dt, u, y):
            return _nll_arrays(pv, dict(zip(KEYS, arrays, strict=True)), dt, hold, u, y)

        return jit(value_grad_hessian(f), once=True)

    key = ("stochastic", "hessian-arrays", hold, shapes)
    fn = _compiled.cached(key, lambda: compile_program("stochastic-hessian", key, build(), args))[0]
    nll, grad, H = fn(*args)
    k = len(vec)
    return nll, np.asarray(grad)[:k], np.asarray(H)[:k, :k]


def _hessian_fn(sp: StochasticProblem, shapes):
    """NLL, its gradient and its exact Hessian in *every* parameter (physical and noise, in
    ``param_names`` order), compiled once per model structure, hold and data shape: fits with
    different free/fixed splits share it."""
    key = ("stochastic", "hessian", sp.model.structure, sp.hold, shapes)
    names = sp.param_names

    def build():
        def f(values, x0_std, dt, u, y):
            theta = {n: values[i] for i, n in enumerate(names)}
            mats, C, D, r, m0, P0 = system(sp.model, theta, dt, sp.hold, x0_std)
            return kalman_scan(mats, C, D, r, m0, P0, u, y)

        return jit(value_grad_hessian(f))

    return _compiled.cached(key, build)[0]


def _status(code: int, val: float, p) -> str:
    if not (np.isfinite(val) and np.all(np.isfinite(p))):
        return "nonfinite"
    return {_CONVERGED: "converged", _MAX_STEPS: "max_steps"}.get(int(code), "nonfinite")


def _result(sp, data, arrays, starts, out, sl, settings, timing) -> MLResult:
    job = int(out["job"][sl][0])
    p = out["p_jobs"][job]
    val, code, steps = out["objective"][sl], out["code"][sl], out["steps"][sl]
    status = tuple(_status(c, v, q) for c, v, q in zip(code, val, p, strict=True))
    report = StartReport(initial=starts, params=p, cost=val, steps=steps, status=status)
    best = report.best_index()
    if best is None:
        raise FitError(
            f"all {len(status)} maximum-likelihood starts failed for {sp.model.name} "
            f"({report.status_summary()}); check the data and bounds, or add starts"
        )
    dt, u, y = arrays
    pb = p[best]
    values = {**sp.fixed_dict, **dict(zip(sp.free, pb, strict=True))}
    vec = np.asarray([values[n] for n in sp.param_names], dtype=float)
    t0 = time.perf_counter()
    nll, grad, H = _hessian(sp, vec, dt, u, y)
    idx = np.asarray([sp.param_names.index(n) for n in sp.free])
    grad, H = np.asarray(grad)[idx], np.asarray(H)[np.ix_(idx, idx)]
    pm, ps = sp.prior_arrays()
    has = np.isfinite(ps)
    prior = 0.5 * float(np.sum(((pb - pm)[has] / ps[has]) ** 2))
    grad = grad + np.where(has, (pb - pm) / np.where(has, ps, 1.0) ** 2, 0.0)
    H = H + np.diag(np.where(has, 1.0 / np.where(has, ps, 1.0) ** 2, 0.0))
    timing = {**timing, "hessian_s": time.perf_counter() - t0}
    return MLResult.build(
        problem=sp,
        data=data,
        arrays=arrays,
        p_free=pb,
        nll=float(nll),
        objective=float(nll) + prior,
        grad=grad,
        hessian=H,
        starts=report,
        best=best,
        timing=timing,
        settings=settings,
    )


def _is_count(starts) -> bool:
    """Whether ``starts`` is a number of starts (an integer, not a bool) rather than an array
    of explicit starts."""
    return isinstance(starts, int | np.integer) and not isinstance(starts, bool | np.bool_)


def _check_settings(starts, seed, concentration, max_steps, rtol, atol) -> None:
    """The settings of :func:`fit_ml`, checked before anything is built: a number of starts
    ≥ 1 (or an array, :func:`_explicit_starts`), an integer seed or None, a concentration
    ≥ 0, an integer ``max_steps`` ≥ 1 and finite tolerances ≥ 0."""
    if _is_count(starts):
        if starts < 1:
            raise FitError(f"starts must be at least 1, got {starts}")
    elif isinstance(starts, bool | np.bool_ | str | bytes | float | np.floating) or (
        starts is None
    ):
        raise FitError(
            "starts must be a number of starts (an integer ≥ 1) or an array [S, k] of explicit "
            f"starts (physical values, one column per free parameter), got {starts!r}"
        )
    if seed is not None and (not isinstance(seed, int | np.integer) or isinstance(seed, bool)):
        raise FitError(f"seed must be an integer or None, got {seed!r}")
    kappa = number(concentration, "concentration")
    if not (np.isfinite(kappa) and kappa >= 0):
        raise FitError(
            f"concentration must be finite and ≥ 0 (0: uniform starts), got {concentration!r}"
        )
    if not isinstance(max_steps, int | np.integer) or isinstance(max_steps, bool):
        raise FitError(f"max_steps must be an integer ≥ 1, got {max_steps!r}")
    if max_steps < 1:
        raise FitError(f"max_steps must be at least 1, got {max_steps}")
    for name, tol in (("rtol", rtol), ("atol", atol)):
        v = number(tol, name)
        if not (np.isfinite(v) and v >= 0):
            raise FitError(f"{name} must be finite and ≥ 0, got {tol!r}")


def _explicit_starts(sp: StochasticProblem, starts) -> np.ndarray:
    """Explicit starts [S, k] (physical values, columns in ``sp.free`` order; one row may be
    given as a vector), checked: numbers, at least one row, one column per free parameter,
    every value finite and within its bounds (a start outside them has no coordinate in the
    bound transform, and would fail)."""
    try:
        x0s = np.asarray(starts, dtype=float)
    except (TypeError, ValueError):
        raise FitError(
            "explicit starts must be an array of numbers [S, k] (physical values, one column "
            f"per free parameter: {', '.join(sp.free)})"
        ) from None
    if x0s.ndim == 1:
        x0s = x0s[None, :]
    if x0s.ndim != 2 or x0s.shape[1] != len(sp.free):
        raise FitError(
            "explicit starts need one column per free parameter "
            f"({', '.join(sp.free)}), got shape {x0s.shape}"
        )
    if len(x0s) == 0:
        raise FitError("explicit starts hold no row; give at least one start, or a number")
    lo, hi = np.asarray(sp.transform.lower), np.asarray(sp.transform.upper)
    bad = ~np.isfinite(x0s) | (x0s < lo) | (x0s > hi)
    if bad.any():
        row, col = (int(i) for i in np.argwhere(bad)[0])
        raise FitError(
            f"explicit start {row}: {sp.free[col]} = {x0s[row, col]:g} is not a number within "
            f"its bounds [{lo[col]:g}, {hi[col]:g}]; move it inside or widen bounds="
        )
    return x0s


def fit_ml(
    model,
    data,
    *,
    free: Sequence[str] | None = None,
    fixed: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    guess: Mapping[str, float] | None = None,
    priors: Mapping[str, tuple[float, float]] | None = None,
    starts: int | np.ndarray = DEFAULT_ML_STARTS,
    seed: int | None = 0,
    concentration: float = DEFAULT_CONCENTRATION,
    hold: str = "foh",
    x0_std: float | Mapping[str, float] | None = None,
    max_steps: int = DEFAULT_ML_MAX_STEPS,
    rtol: float = 1e-8,
    atol: float = 1e-8,
) -> MLResult:
    """Maximum-likelihood (with ``priors``: MAP) estimate of the stochastic form of ``model``.

    Args:
        model: an :class:`~jaxbox.models.RCModel` or a library model name.
        data: the identification :class:`~jaxbox.data.Dataset`.
        free: parameters to estimate, physical and noise (default: all not ``fixed``).
        fixed: values held fixed (SI), e.g. ``{"sigma_wal": 0.0}`` for a state without
            diffusion.
        bounds: ``{name: (lower, upper)}`` (SI); noise parameters default to
            ``sigma_*`` ∈ [1e-7, 0.1] K/√s and ``sigma_y_*`` ∈ [1e-4, 5] K.
        guess: initial guesses (SI); physical ones default as for output error.
        priors: ``{name: (mean, sd)}`` Gaussian priors on free parameters (SI): a MAP estimate.
        starts: number of starts (the guess plus Latin-hypercube samples), or an array
            [S, k] of explicit starts in physical units (columns in ``problem.free`` order).
        seed, concentration: of the Latin hypercube (:func:`jaxbox.fit.sample_starts`).
        hold: ``"foh"`` (inputs linear between samples, as the output-error fit) or ``"zoh"``.
        x0_std: standard deviation [K] of the initial states around ``T_*0`` (one value, or
            per state name); default 1 K.
        max_steps: BFGS iterations per start.
        rtol, atol: BFGS tolerances on the NLL per observation and on the coordinates.

    Returns:
        :class:`MLResult`: estimates, intervals from the exact Hessian, log-likelihood, AIC,
        BIC, every start's outcome.
    """
    return fit_ml_many(
        model,
        [as_data(data)],
        free=free,
        fixed=fixed,
        bounds=bounds,
        guess=guess,
        priors=priors,
        starts=starts,
        seed=seed,
        concentration=concentration,
        hold=hold,
        x0_std=x0_std,
        max_steps=max_steps,
        rtol=rtol,
        atol=atol,
    )[0]


def fit_ml_many(
    model,
    datasets: Sequence,
    *,
    free: Sequence[str] | None = None,
    fixed: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    guess: Mapping[str, float] | None = None,
    priors: Mapping[str, tuple[float, float]] | None = None,
    starts: int | np.ndarray = DEFAULT_ML_STARTS,
    seed: int | None = 0,
    concentration: float = DEFAULT_CONCENTRATION,
    hold: str = "foh",
    x0_std: float | Mapping[str, float] | None = None,
    max_steps: int = DEFAULT_ML_MAX_STEPS,
    rtol: float = 1e-8,
    atol: float = 1e-8,
) -> list[MLResult]:
    """:func:`fit_ml` on several datasets in one compiled call (every start of every dataset
    under one ``vmap``). Datasets of different lengths are padded to the bucket of the longest
    with missing samples, which add nothing to the likelihood, so each result is its fit
    alone's to the optimiser's rounding. Returns one result per dataset."""
    require_x64()
    _check_settings(starts, seed, concentration, max_steps, rtol, atol)
    model = get_model(model)
    datasets = as_datasets(datasets)
    if not datasets:
        raise FitError("fit_ml_many needs at least one dataset")
    jobs, all_starts, arrays_list, problems = [], [], [], []
    for data in datasets:
        sp = make_stochastic_problem(
            model,
            data,
            free=free,
            fixed=fixed,
            bounds=bounds,
            guess=guess,
            priors=priors,
            hold=hold,
            x0_std=x0_std,
        )
        arrays = stochastic_arrays(model, data)
        if _is_count(starts):
            x0s = sample_starts(sp, data, int(starts), seed, concentration)
        else:
            x0s = _explicit_starts(sp, starts)
        jobs.append((sp, x0s, arrays))
        all_starts.append(x0s)
        arrays_list.append(arrays)
        problems.append(sp)
    out = solve_ml(jobs, max_steps=max_steps, rtol=rtol, atol=atol)
    settings = {
        "method": "ml" if not priors else "map",
        "max_steps": max_steps,
        "rtol": rtol,
        "atol": atol,
        "seed": seed,
        "hold": hold,
        "optimizer": "optimistix.BFGS",
    }
    timing = {"compile_s": out["compile_s"], "fit_s": out["fit_s"], "batch": len(jobs)}
    results = []
    for i, (sp, data) in enumerate(zip(problems, datasets, strict=True)):
        sl = out["job"] == i
        results.append(_result(sp, data, arrays_list[i], all_starts[i], out, sl, settings, timing))
    return results


def fit_ml_method(args: dict) -> MLResult:
    """``jaxbox.fit_model(..., method="ml")``: the output-error arguments that carry over to
    :func:`fit_ml`; output weights and simulator options do not apply to the likelihood."""
    from .._defaults import DEFAULT_MAX_STEPS

    for name, default in (("weights", None), ("sim_options", None), ("solver", None)):
        if args.get(name) is not default:
            raise FitError(f"{name} does not apply to method='ml'")
    if args.get("simulator", "exact") != "exact":
        raise FitError("simulator does not apply to method='ml' (the Kalman filter is exact)")
    opts = dict(args.get("ml_options") or {})
    bad = sorted(set(opts) - {"priors", "hold", "x0_std"})
    if bad:
        raise FitError(f"unknown argument(s) for method='ml': {', '.join(bad)}")
    starts = args["starts"]
    max_steps = args["max_steps"]
    return fit_ml(
        args["model"],
        args["data"],
        free=args["free"],
        fixed=args["fixed"],
        bounds=args["bounds"],
        guess=args["guess"],
        starts=starts,
        seed=args["seed"],
        concentration=args["concentration"],
        max_steps=DEFAULT_ML_MAX_STEPS if max_steps in (None, DEFAULT_MAX_STEPS) else max_steps,
        **opts,
    )
