"""Parameter uncertainty from the exact output sensitivities at the optimum.

With ``J`` the sensitivities ``∂ŷ/∂θ`` of the simulated outputs to the free parameters (physical
units, forward-mode autodiff through the estimation's own simulator) and ``e = y − ŷ`` the output
errors at the optimum θ̂, the linearised covariance is::

    cov(θ̂) = σ̂² (JᵀJ)⁻¹,        σ̂² = SSE / (N − p),

with N the number of measured output samples (the samples of an output gap are left out) and p
the number of free parameters (initial states included, those of every segment of the data: they
are estimated too). With several outputs both J and e are weighted row-wise by
``√q_j`` (the fit's output weights, without the 1/N of the fit's residuals), which is weighted
least squares under the assumption that the noise variance of output j is ``σ²/q_j``; with one
output of weight 1 it is ordinary least squares. Because J is taken with respect to the physical
parameters, the covariance needs no mapping back through the bound transforms, and a parameter
near its bound keeps a finite sensitivity (the verdict flags it separately).

Confidence intervals are ``θ̂ ± t_{N−p, 0.975} · std`` (Student-t); ``rel_ci`` is that half-width
as a fraction of ``|θ̂|``. Intervals for the initial states are computed only on request (the
reference study shows none), but the initial states are always part of J, so the reported
covariance of the other parameters is their marginal covariance. The temperature of a node held
constant (``RCNetwork.constant``) is a parameter, not an initial state, and always gets one.

**Identifiability.** J is analysed after scaling each column to unit norm (so that units do not
matter) by a singular value decomposition ``J_n = U S Vᵀ``. ``1/s_k`` is the collinearity index
of direction ``v_k`` (Brun, Reichert & Künsch 2001): the parameters can move along ``v_k`` and
change the outputs by only ``s_k`` times what a unit move of one parameter alone would. A
direction with ``s_k ≤ rcond · s_1`` is numerically singular: the parameters loading on it are
*not identifiable* and get no standard error (``nan``), only the estimable rest of the covariance
is kept (pseudo-inverse). A direction with ``1/s_k > max_collinearity`` is *poorly
identifiable*: its parameters keep their (wide, but computed) intervals and are flagged. A
parameter the outputs do not depend on at all (a zero column, e.g. a solar aperture without
irradiance in the data) is not identifiable either. Each flagged direction is described in words
by the parameter changes that leave the outputs unchanged to first order.
"""

from __future__ import annotations

import dataclasses
import hashlib

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Bool, Float
from scipy import stats

from .._compiled import cached, jit
from .._derivatives import value_and_jacfwd
from .._exported import compile_program
from .._x64 import require_x64
from ._args import check_fit

__all__ = ["Uncertainty", "Combination", "uncertainty", "sensitivities"]

_TEMPERATURE_UNITS = ("°C", "K")


@dataclasses.dataclass(frozen=True, eq=False)
class Combination:
    """A direction in parameter space that the data do not determine.

    Attributes:
        parameters: the parameters that move along the direction (largest share first).
        changes: the first-order change of each of them along the direction, normalised so the
            largest is 1: relative [%] for ratio-scale parameters (R, C, gA, fractions),
            absolute [K] for temperatures.
        collinearity: collinearity index ``1/s_k`` of the column-normalised sensitivities
            (``inf`` for a parameter with zero sensitivity).
        singular: True when numerically singular (not identifiable at all); False when only
            poorly identifiable.
        text: the same in words.
    """

    parameters: tuple[str, ...]
    changes: tuple[float, ...]
    collinearity: float
    singular: bool
    text: str

    def to_dict(self) -> dict:
        return {
            "parameters": list(self.parameters),
            "changes": [float(c) for c in self.changes],
            "collinearity": _finite_or_none(self.collinearity),
            "singular": self.singular,
            "text": self.text,
        }


@dataclasses.dataclass(frozen=True, eq=False)
class _Optimum:
    """The exact sensitivities an :class:`Uncertainty` was computed from, kept for
    :func:`~jaxbox.validate.robust_covariance` (which needs them in time order).

    Attributes:
        key: what they depend on (:func:`_optimum_key`).
        ysim: simulated outputs ŷ [N, outputs] in °C.
        J: sensitivities ∂ŷ/∂θ [N, outputs, free] in °C per SI unit.
    """

    key: tuple
    ysim: np.ndarray
    J: np.ndarray


def _digest(*arrays) -> str:
    """A hash of the float64 contents (and shapes) of ``arrays``."""
    h = hashlib.blake2b(digest_size=20)
    for a in arrays:
        a = np.ascontiguousarray(a, dtype=float)
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _optimum_key(problem, theta, t, u) -> tuple:
    """What the sensitivities of :func:`sensitivities` depend on: the problem's simulation
    (structure, free/fixed split, simulator), the fixed values, the free values ``theta`` [SI]
    and the data's times ``t`` [s] and inputs ``u``."""
    return (problem.simulation_key, problem.fixed, _digest(theta, t, u))


def optimum_sensitivities(result, uncertainty, t, u) -> tuple[np.ndarray, np.ndarray]:
    """``(ŷ, J)`` of :func:`sensitivities` at ``result``'s optimum: those ``uncertainty`` was
    computed from when it was computed on the same fit (same simulation, parameter values,
    times ``t`` [s] and inputs ``u`` of the data), else computed anew.

    Returns:
        (ŷ [N, outputs] in °C, J [N, outputs, free] in °C per SI unit), numpy.
    """
    kept = None if uncertainty is None else uncertainty._optimum
    if kept is not None:
        problem = result.problem
        theta = np.asarray([result.params[n] for n in problem.free], dtype=float)
        if kept.key == _optimum_key(problem, theta, t, u):
            return kept.ysim, kept.J
    return sensitivities(result)


@dataclasses.dataclass(frozen=True, eq=False)
class Uncertainty:
    """Linearised uncertainty of a fit's parameters (lmfit-style error bars).

    Attributes:
        names: parameters with intervals (free ones; initial states only on request).
        units: their units.
        values: estimates θ̂ [SI].
        std: standard errors [SI]; ``nan`` where a parameter is not identifiable.
        ci95: (lower, upper) of the confidence interval [SI], shape [p, 2] (level ``level``).
        rel_ci: half-width of the interval as a fraction of ``|θ̂|`` (``inf`` at θ̂ = 0).
        cov: covariance matrix [SI²] of ``names``; rows of non-identifiable parameters ``nan``.
        correlation: correlation matrix of ``names``.
        identifiable: per name, False when it loads on a flagged direction.
        level: confidence level of ``ci95`` (0.95).
        t_quantile: Student-t quantile used for the intervals.
        dof: degrees of freedom N − p.
        n_obs: number of output samples N (outputs with zero weight are left out).
        sigma2: residual variance σ̂² [K²] (weighted by q_j with several outputs).
        condition: condition number ``s_1/s_min`` of the column-normalised sensitivities.
        collinearity: collinearity index ``1/s_min`` of the same (all free parameters).
        combinations: flagged directions (not or poorly identifiable).
        free: every free parameter (columns of ``jacobian`` and of ``cov_free``).
        cov_free: covariance of every free parameter, initial states included.
        jacobian: weighted sensitivities ``√q_j ∂ŷ/∂θ`` [N·outputs, len(free)].
        singular_values: of the column-normalised sensitivities, descending.
        _optimum: the sensitivities in time order it was computed from (private: reused by
            :func:`~jaxbox.validate.robust_covariance` on the same fit).
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    values: Float[np.ndarray, " params"]
    std: Float[np.ndarray, " params"]
    ci95: Float[np.ndarray, "params 2"]
    rel_ci: Float[np.ndarray, " params"]
    cov: Float[np.ndarray, "params params"]
    correlation: Float[np.ndarray, "params params"]
    identifiable: Bool[np.ndarray, " params"]
    level: float
    t_quantile: float
    dof: int
    n_obs: int
    sigma2: float
    condition: float
    collinearity: float
    combinations: tuple[Combination, ...]
    free: tuple[str, ...]
    cov_free: Float[np.ndarray, "free free"]
    jacobian: Float[np.ndarray, "rows free"]
    singular_values: Float[np.ndarray, " free"]
    _optimum: _Optimum | None = dataclasses.field(default=None, repr=False)

    @property
    def flagged(self) -> tuple[str, ...]:
        """Free parameters (initial states included) on a not or poorly identifiable direction."""
        out: dict[str, None] = {}
        for c in self.combinations:
            for n in c.parameters:
                out.setdefault(n, None)
        return tuple(n for n in self.free if n in out)

    @property
    def not_identifiable(self) -> tuple[str, ...]:
        """Free parameters on a numerically singular direction (no standard error)."""
        out = {n for c in self.combinations if c.singular for n in c.parameters}
        return tuple(n for n in self.free if n in out)

    def table(self) -> dict[str, dict]:
        """Per parameter: value, unit, std, ci95, rel_ci, identifiable (``nan`` kept)."""
        return {
            n: {
                "value": float(self.values[i]),
                "unit": self.units[i],
                "std": float(self.std[i]),
                "ci95": (float(self.ci95[i, 0]), float(self.ci95[i, 1])),
                "rel_ci": float(self.rel_ci[i]),
                "identifiable": bool(self.identifiable[i]),
            }
            for i, n in enumerate(self.names)
        }

    def correlation_dict(self) -> dict[str, dict[str, float | None]]:
        """The correlation matrix as nested dicts (JSON-ready: ``None`` for undefined)."""
        return {
            a: {b: _finite_or_none(self.correlation[i, j]) for j, b in enumerate(self.names)}
            for i, a in enumerate(self.names)
        }

    def to_dict(self) -> dict:
        """JSON-ready summary (``nan``/``inf`` written as ``None``)."""
        return {
            "params": {
                n: {
                    "value": row["value"],
                    "unit": row["unit"],
                    "std": _finite_or_none(row["std"]),
                    "ci95": _pair_or_none(row["ci95"]),
                    "rel_ci": _finite_or_none(row["rel_ci"]),
                    "identifiable": row["identifiable"],
                }
                for n, row in self.table().items()
            },
            "correlation": self.correlation_dict(),
            "dof": self.dof,
            "n_obs": self.n_obs,
            "sigma2": self.sigma2,
            "level": self.level,
            "condition": _finite_or_none(self.condition),
            "collinearity": _finite_or_none(self.collinearity),
            "non_identifiable": [c.to_dict() for c in self.combinations],
        }

    def summary(self) -> str:
        """A readable table of estimates, standard errors and intervals."""
        pct = round(100 * self.level)
        lines = [
            f"σ̂ = {np.sqrt(self.sigma2):.4g} K, N = {self.n_obs}, dof = {self.dof}, "
            f"collinearity index {self.collinearity:.3g}",
            f"{'parameter':<10} {'value':>12} {'std':>11} {f'{pct}% interval':>25} "
            f"{'±rel':>8}  unit",
        ]
        for i, n in enumerate(self.names):
            if np.isfinite(self.std[i]):
                lo, hi = self.ci95[i]
                ci = f"[{lo:.4g}, {hi:.4g}]"
                rel = f"{100 * self.rel_ci[i]:.3g}%"
                std = f"{self.std[i]:.4g}"
            else:
                ci, rel, std = "not identifiable", "", "-"
            lines.append(
                f"{n:<10} {self.values[i]:>12.5g} {std:>11} {ci:>25} {rel:>8}  {self.units[i]}"
            )
        for c in self.combinations:
            lines.append("  " + c.text)
        return "\n".join(lines)


def _finite_or_none(x):
    x = float(x)
    return x if np.isfinite(x) else None


def _pair_or_none(pair):
    lo, hi = (float(v) for v in pair)
    return [lo, hi] if np.isfinite(lo) and np.isfinite(hi) else None


def _rc_jacobian(problem, t, u, p, fixed_values):
    """``(ŷ, ∂ŷ/∂θ)`` through one compiled program shared by every structure of the same padded
    size (the network as arrays, :meth:`~jaxbox.models.RCModel.rc_arrays`), so that a structure
    search compiles a handful of programs instead of one per candidate; ``None`` where the
    problem has no such form (the diffrax simulator, a node held at a constant temperature).

    Sizes are rounded up (states, inputs and heat sources to multiples of 8, free parameters to
    24…; the sources as the fit's programs round them) so that the structures of a search share
    one or two programs (one simulation each: the padding
    costs little); padding states are inert and padding parameters are referenced by nothing,
    so their Jacobian columns are zero and dropped. The record is extended to its bucket of
    samples (:func:`~jaxbox.fit._fit.bucket_samples`), so that records of neighbouring lengths
    (a fleet's buildings, the periods of a selection) share the program too.
    """
    from ..fit._fit import _RC_KEYS, _round_up, bucket_samples
    from ..models._network import ModelError
    from ..simulate._extend import extend_times, hold_rows

    model = problem.model
    if problem.simulator != "exact" or any(node.constant for node in model.network.nodes):
        return None
    sizes = model.array_sizes()
    sizes = {
        "states": _round_up(sizes["states"], 8),
        "edges": _round_up(sizes["edges"], 8),
        "sources": _round_up(sizes["sources"], 8),
        "factors": _round_up(sizes["factors"], 2),
    }
    n_free, n_fixed, m = len(problem.free), len(problem.fixed), len(model.inputs)
    width, fixed_width, m_pad = _round_up(n_free, 24), _round_up(n_fixed, 8), _round_up(m, 8)
    slots = list(problem.free) + [f"\0p{i}" for i in range(width - n_free)]
    slots += [n for n, _ in problem.fixed] + [f"\0q{i}" for i in range(fixed_width - n_fixed)]
    inputs = list(model.inputs) + [f"\0u{i}" for i in range(m_pad - m)]
    try:
        arrays = model.rc_arrays([*slots, "1", "0"], inputs=inputs, **sizes)
    except ModelError:
        return None
    # host arrays throughout: an eager jnp operation on them compiles a program of its own for
    # every shape, in every process (tens of ms each)
    arrays = tuple(np.asarray(arrays[k]) for k in _RC_KEYS)
    segmented = model.segments > 1
    # the record extended to its bucket of samples (the times at the data's step, the inputs
    # held): records of neighbouring lengths share the program, and the samples beyond the
    # record, which no earlier state depends on, are dropped
    n_samples = len(t)
    n_run = bucket_samples(n_samples)
    key = ("uncertainty", "rc", segmented, n_run, width, fixed_width, m_pad, *sizes.values())
    key += (len(problem.output_states), model.segments)
    p_pad = np.concatenate([np.asarray(p, dtype=float), np.ones(width - n_free)])
    q_pad = np.concatenate([np.asarray(fixed_values, dtype=float), np.ones(fixed_width - n_fixed)])
    u_pad = hold_rows(np.pad(np.asarray(u, dtype=float), ((0, 0), (0, m_pad - m))), n_run)
    out_idx = np.asarray(problem.output_states)
    args = (p_pad, q_pad, extend_times(t, n_run), u_pad, arrays, out_idx)
    key += tuple((a.shape, str(a.dtype)) for a in jax.tree_util.tree_leaves(args))

    def build():  # compiled for these shapes, kept for later processes (jaxbox._exported)
        return compile_program("uncertainty", key, _build_rc_jacobian(segmented), args)

    ysim, J = cached(key, build)[0](*args)
    return np.asarray(ysim)[:n_samples], np.asarray(J)[:n_samples, ..., :n_free]


def _build_rc_jacobian(segmented: bool):
    from ..fit._fit import _RC_KEYS
    from ..models._network import rc_from_arrays
    from ..simulate._exact import discretize_foh_rc, simulate_foh, simulate_foh_segments

    def f(p, fixed_values, t, u, arrays, out_idx):
        v = jnp.concatenate([p, fixed_values, jnp.asarray([1.0, 0.0], dtype=p.dtype)])
        A, B, caps, x0 = rc_from_arrays(v, dict(zip(_RC_KEYS, arrays, strict=True)))
        Phi, G0, G1 = discretize_foh_rc(A, B, caps, t[1] - t[0])
        C = jax.nn.one_hot(out_idx, A.shape[0], dtype=A.dtype)
        D = jnp.zeros((C.shape[0], u.shape[1]), dtype=A.dtype)
        if segmented:
            return simulate_foh_segments(Phi, G0, G1, C, D, x0, u, t)[0]
        return simulate_foh(Phi, G0, G1, C, D, x0, u)[0]

    return jit(value_and_jacfwd(f))


def _jacobian_fn(problem, n_samples: int):
    """Jitted (p_free, fixed, t, u) -> (ŷ [N, p_out], ∂ŷ/∂θ [N, p_out, n_free]) for N =
    ``n_samples``, kept in the ``"uncertainty"`` room of :mod:`jaxbox._compiled`."""
    key = ("uncertainty", *problem.simulation_key, n_samples)
    return cached(key, lambda: _build_jacobian_fn(problem))[0]


def _build_jacobian_fn(problem):
    def f(p, fixed_values, t, u):
        return problem.simulate(p, fixed_values, t, u)

    return jit(value_and_jacfwd(f))


def sensitivities(
    result, params: Float[ArrayLike, " free"] | None = None
) -> tuple[Float[np.ndarray, "samples outputs"], Float[np.ndarray, "samples outputs free"]]:
    """Exact sensitivities of the simulated outputs to the free parameters.

    Forward-mode autodiff through the fit's own simulator (``result.problem.simulate``) on the
    identification data.

    Args:
        result: a :class:`~jaxbox.fit.FitResult`.
        params: free parameter values [SI] in ``result.free`` order (default: the optimum).

    Returns:
        (ŷ [N, outputs] in °C, J [N, outputs, len(result.free)] in °C per SI unit), numpy.
    """
    require_x64()
    problem = check_fit(result, needs=_SENSITIVITY_NEEDS[params is None]).problem
    if params is None:
        params = [result.params[n] for n in problem.free]
    t, u, p, fixed_values = _arrays(problem, result.data, params)
    shared = _rc_jacobian(problem, t, u, p, fixed_values)
    if shared is not None:
        ysim, J = shared
    else:
        ysim, J = _jacobian_fn(problem, len(t))(
            p, fixed_values, np.asarray(t, dtype=float), np.asarray(u, dtype=float)
        )
    return np.asarray(ysim), np.asarray(J)


def prepare_sensitivities(problem, data) -> bool:
    """Compile (and keep) the program :func:`sensitivities` will run for ``problem`` on
    ``data``, before any fit: the one shared by every structure of its padded size
    (:func:`_rc_jacobian`), evaluated once at the guess. A structure search does it in a thread
    while its first fit compiles. Returns whether the problem has that shared program."""
    guess = problem.guess_dict
    arrays = _arrays(problem, data, [guess[n] for n in problem.free])
    return _rc_jacobian(problem, *arrays) is not None


def _arrays(problem, data, params) -> tuple:
    """``(t, u, p, fixed_values)`` of ``problem`` on ``data`` at the free values ``params``:
    the arguments of its sensitivity programs."""
    from ..fit import problem_arrays

    t, u, _, _ = problem_arrays(problem, data)
    fixed_values = np.asarray([v for _, v in problem.fixed], dtype=float)
    return t, u, _free_values(params, problem.free), fixed_values


_SENSITIVITY_NEEDS = {True: ("problem", "data", "params"), False: ("problem", "data")}
"""What :func:`sensitivities` reads of its result: without ``params``, the optimum too."""


def _free_values(params, free) -> np.ndarray:
    """``params`` as one finite value [SI] per free parameter, in ``free`` order."""
    try:
        p = np.asarray(params, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(
            f"params must be {len(free)} numbers in result.free order ({', '.join(free)}), "
            f"got {params!r}"
        ) from None
    if p.shape != (len(free),):
        raise ValueError(
            f"params must be {len(free)} values in result.free order ({', '.join(free)}), "
            f"got shape {p.shape}"
        )
    bad = [n for n, v in zip(free, p, strict=True) if not np.isfinite(v)]
    if bad:
        raise ValueError(f"params of {', '.join(bad)} are not finite; give finite values [SI]")
    return p


def _is_temperature(unit: str) -> bool:
    return unit in _TEMPERATURE_UNITS


def _describe(names, units, values, direction, collinearity, singular, share=0.05):
    """Readable description of a direction (per-parameter physical changes)."""
    scaled = []
    for unit, v, d in zip(units, values, direction, strict=True):
        if _is_temperature(unit) or v == 0:
            scaled.append(d)  # K (or the unit itself when the value is 0)
        else:
            scaled.append(100 * d / abs(v))  # %
    scaled = np.asarray(scaled)
    big = np.max(np.abs(scaled))
    scaled = scaled / big
    ranked = np.argsort(-np.round(np.abs(scaled), 6), kind="stable")
    order = [i for i in ranked if abs(scaled[i]) >= share]
    if scaled[order[0]] < 0:
        scaled = -scaled
    params = tuple(names[i] for i in order)
    changes = tuple(float(scaled[i]) for i in order)

    def one(i):
        unit = units[i]
        if _is_temperature(unit):
            return f"{names[i]} by {scaled[i]:+.2f} K"
        if values[i] == 0:
            return f"{names[i]} by {scaled[i]:+.2f} {unit}"
        return f"{names[i]} by {scaled[i]:+.2f} %"

    if len(order) == 1:
        n = params[0]
        if singular:
            text = (
                f"{n} is not identifiable: the outputs do not depend on it (to first order) with "
                "these data; fix it, or use data that excite it"
            )
        else:
            text = (
                f"{n} is poorly identifiable (collinearity index {collinearity:.3g}): the outputs "
                "hardly depend on it with these data"
            )
        return params, changes, text
    moves = ", ".join(one(i) for i in order)
    who = ", ".join(params)
    if singular:
        text = (
            f"{who} are not identifiable separately: changing {moves} leaves the outputs "
            "unchanged (to first order); only a combination of them is determined by the data — "
            "fix one of them or change the model structure"
        )
    else:
        text = (
            f"{who} are poorly identifiable together (collinearity index {collinearity:.3g}): "
            f"changing {moves} hardly changes the outputs"
        )
    return params, changes, text


def uncertainty(
    result,
    *,
    include_initial_states: bool = False,
    level: float = 0.95,
    rcond: float = 1e-9,
    max_collinearity: float = 1e3,
    loading: float = 1e-3,
) -> Uncertainty:
    """Standard errors, confidence intervals and identifiability of a fit's parameters.

    Args:
        result: a :class:`~jaxbox.fit.FitResult`.
        include_initial_states: also give intervals for the initial states ``T_*0`` (those of
            constant nodes always get one).
        level: confidence level of the intervals.
        rcond: singular values of the column-normalised sensitivities below ``rcond`` times the
            largest are treated as zero (not identifiable, no standard error).
        max_collinearity: directions whose collinearity index ``1/s_k`` exceeds this are flagged
            as poorly identifiable (standard errors still given).
        loading: a parameter belongs to a flagged direction when its component in the unit
            direction vector exceeds this.

    Returns:
        :class:`Uncertainty`.

    Raises:
        TypeError: ``result`` is not a FitResult (a stochastic fit has ``result.intervals()``),
            or an option of the wrong type.
        ValueError: fewer output samples than free parameters (no degrees of freedom left), an
            optimum that is not finite, or an option out of range (``level`` in (0, 1),
            ``rcond`` and ``loading`` in [0, 1), ``max_collinearity`` > 0).

    Example:
        ```python
        unc = uncertainty(result)
        print(unc.summary())                 # std, 95 % intervals, non-identifiable combinations
        ```
    """
    from ..fit import problem_arrays
    from ..fit._problem import _positive
    from ._args import check_flag, check_fraction, check_level, check_positive

    problem = check_fit(result).problem
    level = check_level(level)
    rcond = check_fraction(rcond, "rcond (relative singular-value cut-off)")
    max_collinearity = check_positive(max_collinearity, "max_collinearity", allow_inf=True)
    loading = check_fraction(loading, "loading (share of a direction)")
    include_initial_states = check_flag(include_initial_states, "include_initial_states")
    free = tuple(problem.free)
    specs = {s.name: s for s in problem.model.parameters}
    units = tuple(specs[n].unit for n in free)
    theta = np.asarray([result.params[n] for n in free], dtype=float)
    t, u, y, sqrt_w = problem_arrays(problem, result.data)
    # samples of an output gap (weight 0) are no observations
    seen = np.broadcast_to(np.asarray(sqrt_w) > 0, y.shape) if np.ndim(sqrt_w) == 2 else None
    if not np.all(np.isfinite(theta)):
        raise ValueError("the fit has no finite optimum; there is nothing to attach intervals to")
    ysim, J = sensitivities(result)
    if not (np.all(np.isfinite(ysim)) and np.all(np.isfinite(J))):
        raise ValueError(
            "the simulation or its sensitivities are not finite at the optimum; the parameters "
            "are not usable"
        )

    q = np.asarray(problem.weights, dtype=float)
    rows = q > 0
    sq = np.sqrt(q[rows])
    e = (y[:, rows] - ysim[:, rows]) * sq
    Jw = J[:, rows, :] * sq[None, :, None]
    if seen is None:
        e, Jw = e.ravel(), Jw.reshape(-1, len(free))
    else:
        e, Jw = e[seen[:, rows]], Jw[seen[:, rows]]
    n_obs = e.size
    p = len(free)
    dof = n_obs - p
    if dof <= 0:
        raise ValueError(
            f"{n_obs} output samples for {p} free parameters leave no degrees of freedom; "
            "use more data or fewer free parameters"
        )
    sigma2 = float(np.sum(e * e) / dof)

    norms = np.linalg.norm(Jw, axis=0)
    # a column counts as zero against the others per relative change of a resistance or a
    # capacity (always > 0), per unit of the others: in SI units a large building's
    # capacities (1e10 J/K) and resistances (1e-5 K/W) have sensitivities 1e15 apart
    positive = np.array([_positive(n) for n in free])
    rel = norms * np.where(positive, np.abs(theta), 1.0)
    scale_ref = np.max(rel) if np.any(rel > 0) else 1.0
    zero = ~(rel > 1e-14 * scale_ref)  # also catches nan
    live = np.flatnonzero(~zero)
    combos: list[Combination] = []
    affected = zero.copy()
    flagged = zero.copy()
    for i in np.flatnonzero(zero):
        combos.append(
            Combination(
                parameters=(free[i],),
                changes=(1.0,),
                collinearity=float("inf"),
                singular=True,
                text=(
                    f"{free[i]} is not identifiable: the outputs do not depend on it with these "
                    "data (zero sensitivity, e.g. its input is zero); fix it, or use data that "
                    "excite it"
                ),
            )
        )
    cov = np.full((p, p), np.nan)
    s = np.zeros(0)
    if live.size:
        Jn = Jw[:, live] / norms[live]
        _, s, Vt = np.linalg.svd(Jn, full_matrices=False)
        V = Vt.T
        sing = s <= rcond * s[0]
        poor = ~sing & (s < 1.0 / max_collinearity)
        keep = ~sing
        covn = (V[:, keep] / s[keep] ** 2) @ V[:, keep].T * sigma2
        d = 1.0 / norms[live]
        cov[np.ix_(live, live)] = covn * d[:, None] * d[None, :]
        for k in np.flatnonzero(sing | poor):
            v = V[:, k]
            members = np.abs(v) > loading
            phys = v * d  # physical change per parameter along the direction
            idx = live[members]
            names_k, changes, text = _describe(
                [free[i] for i in idx],
                [units[i] for i in idx],
                theta[idx],
                phys[members],
                1.0 / s[k] if s[k] > 0 else float("inf"),
                bool(sing[k]),
            )
            combos.append(
                Combination(
                    parameters=names_k,
                    changes=changes,
                    collinearity=float(1.0 / s[k]) if s[k] > 0 else float("inf"),
                    singular=bool(sing[k]),
                    text=text,
                )
            )
            flagged[idx] = True
            if sing[k]:
                affected[idx] = True
    cov[affected, :] = np.nan
    cov[:, affected] = np.nan
    if s.size:
        condition = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
        collinearity = float(1.0 / s[-1]) if s[-1] > 0 else float("inf")
    else:
        condition = collinearity = float("inf")
    if zero.any():
        condition = collinearity = float("inf")

    held = {m.T0 for m in problem.model.network.nodes if getattr(m, "constant", False)}
    show = [
        i
        for i, n in enumerate(free)
        if include_initial_states or not specs[n].is_initial_state or n in held
    ]
    sub = cov[np.ix_(show, show)]
    std = np.sqrt(np.where(np.diag(sub) >= 0, np.diag(sub), np.nan))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = sub / np.outer(std, std)
        np.fill_diagonal(corr, np.where(np.isfinite(std), 1.0, np.nan))
        tq = float(stats.t.ppf(0.5 + level / 2, dof))
        vals = theta[show]
        half = tq * std
        ci = np.stack([vals - half, vals + half], axis=1)
        rel = np.where(vals != 0, half / np.abs(vals), np.where(np.isnan(half), np.nan, np.inf))
    return Uncertainty(
        names=tuple(free[i] for i in show),
        units=tuple(units[i] for i in show),
        values=vals,
        std=std,
        ci95=ci,
        rel_ci=rel,
        cov=sub,
        correlation=np.clip(corr, -1.0, 1.0),
        identifiable=~flagged[show],
        level=level,
        t_quantile=tq,
        dof=int(dof),
        n_obs=int(n_obs),
        sigma2=sigma2,
        condition=condition,
        collinearity=collinearity,
        combinations=tuple(combos),
        free=free,
        cov_free=cov,
        jacobian=Jw,
        singular_values=s,
        _optimum=_Optimum(_optimum_key(problem, theta, t, u), _frozen(ysim), _frozen(J)),
    )


def _frozen(a: np.ndarray) -> np.ndarray:
    """``a`` as a read-only array (kept in an :class:`Uncertainty`, shared by its users)."""
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a
