"""Forecasts with uncertainty from a fitted model.

From the data up to a time ``t`` (the *history*) the Kalman filter of the fit's stochastic form
(:mod:`jaxbox.forecast._form`) gives the state at ``t``, ``x̂_{t|t}`` with covariance ``P_{t|t}``.
Over the horizon the mean and the covariance are propagated with the future inputs (a weather
forecast, planned heating) and no measurement::

    x̂_{k+1} = Φ x̂_k + Γ0 u_k + Γ1 (u_{k+1} − u_k),     P_{k+1} = Φ P_k Φᵀ + Q,
    ŷ_k = C x̂_k + D u_k,                               S_k = C P_k Cᵀ + diag(r²),

so that ``y_k ~ N(ŷ_k, S_k)`` for a measured output (``sd = √diag S``); the 50 % and 95 % bands
are the Gaussian quantiles ``ŷ ± 0.674 sd`` and ``ŷ ± 1.960 sd``. These bands hold the
measured temperatures (measurement noise included). With ``parameters=True`` they also hold the
uncertainty of the estimated parameters, to first order: the forecast mean's sensitivities
``J = ∂ŷ/∂θ`` (central differences through the filter and the propagation) add
``diag(J Σ_θ Jᵀ)`` to the variance, ``Σ_θ`` the covariance of the estimate (the inverse Hessian
of a maximum-likelihood fit; for an output-error fit pass ``parameters=uncertainty(fit)``, its
``σ²(JᵀJ)⁻¹`` from :func:`jaxbox.validate.uncertainty`).

**Calibration on the history** (``calibrate=True``, the default). The stochastic form's noise
explains the one-step errors; a model's error over many hours (a solar gain it places wrongly,
a slow state it lacks, parameters that do not carry over to new weather) grows faster than its
process noise says, and the bands would hold too few measurements. So the history itself is
forecast from its own samples, and at each horizon step ``k`` and output the variance is scaled
by ``c_k = max(m_k, r_k, 1/4)``: ``m_k`` the mean squared standardised error ``e²/S`` of the
``k``-step forecasts over the whole history (at most :data:`CALIBRATION_ORIGINS` origins, evenly
spread), ``r_k`` the same over the last :data:`CALIBRATION_RECENT` seconds of origins (the
model's errors of the last day: a model whose error has grown since the fit gets wider bands at
once, not after weeks). Only forecasts whose target lies within the history count, so a
forecast at ``t`` uses nothing after ``t``. The bands are as wide as the model's own recent and
long-run errors, never narrower than half the model's sd. ``frame.attrs["calibration"]`` gives
the factors (of the sd) per output at the last step, or says why there was none (fewer than
:data:`CALIBRATION_MIN` whole horizons in the history). :func:`backtest` calibrates each origin
on the data before it, as :func:`forecast` would at that origin (from all its origins rather
than ≤ 400 spread ones).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from scipy import stats

from ..data._gaps import _duration, duration_seconds
from ..fit._problem import FitError
from ..stochastic._checks import as_data, regular_step
from ._bridge import DEFAULT_MAX_GAP
from ._form import DiscreteSystem, StochasticForm, stochastic_form

__all__ = [
    "forecast",
    "backtest",
    "propagate",
    "parameter_covariance",
    "horizon_steps",
    "future_inputs",
    "BANDS",
    "CALIBRATION_ORIGINS",
    "CALIBRATION_MIN",
    "CALIBRATION_RECENT",
    "CALIBRATION_FLOOR",
    "calibration",
]

#: the central bands reported, as fractions
BANDS = (0.5, 0.95)
_Z = {b: float(stats.norm.ppf(0.5 + b / 2)) for b in BANDS}
#: at most this many in-sample forecasts calibrate the bands (evenly spread over the history)
CALIBRATION_ORIGINS = 400
#: no calibration from fewer in-sample forecasts (whole horizons within the history) than this
CALIBRATION_MIN = 24
#: the recent window of the calibration [s]: the origins of the history's last day
CALIBRATION_RECENT = 86400.0
#: the calibration never scales the sd below this fraction
CALIBRATION_FLOOR = 0.5
#: in-sample forecasts are propagated this many origins at a time (bounded memory)
_CHUNK = 256


def horizon_steps(horizon, dt: float) -> int:
    """The horizon as a whole number of samples of ``dt`` [s]: an integer (samples) or a
    duration (``"24h"``, a :class:`pandas.Timedelta`)."""
    if isinstance(horizon, int | np.integer) and not isinstance(horizon, bool):
        steps = int(horizon)
    else:
        try:
            seconds = pd.Timedelta(horizon).total_seconds()
        except (TypeError, ValueError):
            seconds = float("nan")
        if not np.isfinite(seconds) or seconds <= 0:
            raise FitError(
                f"horizon must be a number of samples or a positive duration such as '24h', "
                f"got {horizon!r}"
            )
        steps = int(round(seconds / dt))
        if steps < 1 or abs(steps * dt - seconds) > 1e-6 * dt:
            raise FitError(
                f"horizon {horizon!r} is not a whole number of samples of the data's step "
                f"({dt:g} s)"
            )
    if steps < 1:
        raise FitError(f"horizon must be at least one sample, got {horizon!r}")
    return steps


def future_inputs(model, history, future, steps: int, last=None) -> np.ndarray:
    """The inputs ``u_t, u_{t+1}, …, u_{t+steps}`` [steps + 1, m]: the last row of ``history``
    (time ``t``; ``last`` [m] instead, the filter's where it filled a missing one) and the rows
    of ``future`` after ``t``, which must continue the history at its step and cover the
    horizon."""
    future.require(list(model.inputs), what=f"the future inputs of model {model.name}")
    dt = history.step
    after = future.index > history.index[-1]
    times = future.index[after]
    u = np.asarray(future.array(list(model.inputs)), float)[after]
    first = history.index[-1] + pd.Timedelta(seconds=dt)
    if len(times) == 0 or times[0] != first:
        got = "nothing after it" if len(times) == 0 else f"its first row after it at {times[0]}"
        raise FitError(
            f"the future inputs must continue the history at its step: the history ends at "
            f"{history.index[-1]}, the next sample is {first}, the future inputs hold {got}"
        )
    if len(times) < steps:
        last = history.index[-1] + pd.Timedelta(seconds=dt * steps)
        raise FitError(
            f"the horizon reaches {last} but the future inputs end at {times[-1]} "
            f"({len(times)} of {steps} samples): give inputs up to {last} or a shorter horizon"
        )
    steps_ok = np.diff(times[: steps + 1].asi8) / 1e9 if steps > 1 else np.asarray([dt])
    if np.any(np.abs(steps_ok - dt) > 1e-6 * dt):
        raise FitError(
            f"the future inputs are not sampled at the history's step ({dt:g} s) over the horizon"
        )
    u = u[:steps]
    bad = ~np.isfinite(u)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise FitError(
            f"future input {model.inputs[col]} is missing (NaN) at {times[row]}; a forecast "
            "needs every input over the horizon"
        )
    if last is None:
        hist_u = np.asarray(history.array(list(model.inputs)), float)[-1:]
    else:
        hist_u = np.asarray(last, float).reshape(1, -1)
    return np.concatenate([hist_u, u], axis=0)


def propagate(sysm: DiscreteSystem, m, P, u) -> dict[str, np.ndarray]:
    """Mean and covariance over a horizon from state(s) ``m`` [..., n] with covariance(s)
    ``P`` [..., n, n] and inputs ``u`` [..., H + 1, m] (``u[..., 0]`` at the origin).

    Returns ``x`` [..., H, n], ``Px`` [..., H, n, n] (the states), ``y`` [..., H, p] and
    ``var`` [..., H, p] (the measured outputs, measurement noise included), at the samples
    ``1 … H`` after the origin.
    """
    u = np.asarray(u, float)
    m = np.asarray(m, float)
    P = np.asarray(P, float)
    H = u.shape[-2] - 1
    drive = u[..., :-1, :] @ sysm.G0.T + (u[..., 1:, :] - u[..., :-1, :]) @ sysm.G1.T
    xs, Ps = [], []
    for k in range(H):
        m = m @ sysm.Phi.T + drive[..., k, :]
        P = sysm.Phi @ P @ sysm.Phi.T + sysm.Q
        P = 0.5 * (P + np.swapaxes(P, -1, -2))
        xs.append(m)
        Ps.append(P)
    x = np.stack(xs, axis=-2)
    Px = np.stack(Ps, axis=-3)
    y = x @ sysm.C.T + u[..., 1:, :] @ sysm.D.T
    var = np.einsum("ij,...jk,ik->...i", sysm.C, Px, sysm.C) + sysm.r**2
    return {"x": x, "Px": Px, "y": y, "var": var}


def _standardised(run, origins: np.ndarray, steps: int) -> np.ndarray:
    """``e²/S`` [O, H, p] of the forecasts of ``run``'s own data from ``origins``: NaN where the
    target lies beyond the data or is not measured."""
    n = len(run.y)
    out = []
    for lo in range(0, origins.size, _CHUNK):
        o = origins[lo : lo + _CHUNK]
        idx = o[:, None] + np.arange(steps + 1)[None, :]
        within = idx[:, 1:] < n
        idx = np.minimum(idx, n - 1)
        f = propagate(run.system, run.m[o], run.P[o], run.u[idx])
        within &= _measured_inputs(run, o, steps)
        meas = np.where(within[..., None], run.y[idx[:, 1:]], np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            z2 = (meas - f["y"]) ** 2 / np.clip(f["var"], 1e-300, None)
        out.append(np.where(np.isfinite(z2), z2, np.nan))
    if not out:
        return np.full((0, steps, run.y.shape[1]), np.nan)
    return np.concatenate(out, axis=0)


def _measured_inputs(run, origins: np.ndarray, steps: int) -> np.ndarray:
    """[O, H]: whether the inputs of the forecast from each origin to each step ``1 … steps``
    were all measured (none filled by the filter, :mod:`jaxbox.forecast._bridge`)."""
    ok = np.ones((origins.size, steps), dtype=bool)
    filled = getattr(run, "filled", None)
    if filled is None or not filled.any():
        return ok
    cum = np.concatenate([[0], np.cumsum(filled)])
    n = len(filled)
    ends = np.minimum(origins[:, None] + np.arange(1, steps + 1)[None, :] + 1, n)
    return (cum[ends] - cum[np.minimum(origins, n)][:, None]) == 0


def _recent(dt: float) -> int:
    """The recent window in origins: :data:`CALIBRATION_RECENT` at the step ``dt`` [s]."""
    return max(CALIBRATION_MIN, int(round(CALIBRATION_RECENT / dt)))


def _combine(m: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The factor from the long-run and recent means (NaN: no forecast known, factor 1)."""
    f = np.fmax(np.where(np.isfinite(m), m, 1.0), r)
    return np.maximum(f, CALIBRATION_FLOOR**2)


def _too_short(n: int, steps: int) -> str | None:
    whole = n - steps
    if whole < CALIBRATION_MIN:
        return (
            f"none: {max(whole, 0)} in-sample forecasts of {steps} steps fit in the "
            f"history, fewer than {CALIBRATION_MIN}"
        )
    return None


def calibration(run, steps: int) -> tuple[np.ndarray | None, str]:
    """Variance factors ``[steps, p]`` for a forecast from the last sample of the filtered data
    ``run``, from forecasts of that data, and a line that says what they rest on (see the module
    docstring).

    ``None`` (and the reason) where fewer than :data:`CALIBRATION_MIN` origins leave a whole
    horizon within the history.
    """
    n = len(run.y)
    short = _too_short(n, steps)
    if short:
        return None, short
    h = np.arange(1, steps + 1)
    spread = np.arange(0, n - 1)
    if spread.size > CALIBRATION_ORIGINS:
        spread = np.unique(np.linspace(0, n - 2, CALIBRATION_ORIGINS).round().astype(int))
    window = _recent(_dt(run))
    recent = np.arange(max(0, n - steps - window), n - 1)
    z_all = _standardised(run, spread, steps)
    z_rec = _standardised(run, recent, steps)
    # the k-step forecasts of the last `window` origins whose target lies within the history
    keep = recent[:, None] >= (n - 1 - h - window + 1)[None, :]
    z_rec = np.where(keep[..., None], z_rec, np.nan)
    with warnings.catch_warnings():  # an all-NaN column: no forecast known there (factor 1)
        warnings.simplefilter("ignore", RuntimeWarning)
        factor = _combine(np.nanmean(z_all, axis=0), np.nanmean(z_rec, axis=0))
    return factor, (
        f"from {spread.size} in-sample forecasts of the history and those of its last "
        f"{window} samples"
    )


def _per_origin(run, origins: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Factors ``[O, H, p]`` for forecasts from ``origins`` of ``run``, each from the data up to
    its origin (as :func:`calibration` there, from all its origins), and which were calibrated."""
    z2 = _standardised(run, np.arange(0, max(int(origins.max()), 1)), steps)  # [K, H, p]
    ok = np.isfinite(z2)
    cs = np.concatenate([np.zeros((1,) + z2.shape[1:]), np.cumsum(np.where(ok, z2, 0.0), 0)])
    cn = np.concatenate([np.zeros((1,) + z2.shape[1:]), np.cumsum(ok, 0)])
    h = np.arange(1, steps + 1)
    last = np.clip(origins[:, None] - h[None, :], -1, None)  # [O, H]: the last k with k + h <= o
    lo = np.clip(last - _recent(_dt(run)) + 1, 0, None)
    col = np.arange(steps)[None, :]
    with np.errstate(invalid="ignore", divide="ignore"):
        m = cs[last + 1, col] / cn[last + 1, col]
        r = (cs[last + 1, col] - cs[lo, col]) / (cn[last + 1, col] - cn[lo, col])
    factor = _combine(m, r)
    calibrated = origins + 1 - steps >= CALIBRATION_MIN
    factor = np.where(calibrated[:, None, None], factor, 1.0)
    return factor, calibrated


def _dt(run) -> float:
    """The step [s] of a filter run (its index is regular)."""
    return float(pd.Timedelta(run.index[1] - run.index[0]).total_seconds())


def _calibrated(out: dict, run, steps: int, calibrate: bool) -> str:
    """Scale ``out["var"]`` in place by the history's calibration; the line for ``attrs``."""
    if not calibrate:
        return "none (calibrate=False)"
    factor, note = calibration(run, steps)
    if factor is None:
        return note
    out["var"] = out["var"] * factor
    last = ", ".join(f"{float(np.sqrt(f)):.2f}" for f in factor[-1])
    return f"{note}: sd × {last} at the last step"


def _frame(outputs: Sequence[str], index, y, var, measured=None) -> pd.DataFrame:
    sd = np.sqrt(np.clip(var, 0.0, None))
    cols: dict[str, np.ndarray] = {"step": np.arange(1, len(index) + 1)}
    for j, o in enumerate(outputs):
        cols[f"{o}_mean"] = y[:, j]
        cols[f"{o}_sd"] = sd[:, j]
        for b in BANDS:
            pct = int(round(100 * b))
            cols[f"{o}_lo{pct}"] = y[:, j] - _Z[b] * sd[:, j]
            cols[f"{o}_hi{pct}"] = y[:, j] + _Z[b] * sd[:, j]
        if measured is not None:
            cols[f"{o}_measured"] = measured[:, j]
    frame = pd.DataFrame(cols, index=index)
    frame.index.name = "time"
    return frame


def parameter_covariance(result) -> tuple[tuple[str, ...], np.ndarray]:
    """``(names, Σ_θ)``: the covariance [SI²] of the estimated physical parameters of a
    maximum-likelihood fit (the inverse of the exact Hessian; noise parameters left out), or
    of an output-error fit's :func:`jaxbox.validate.uncertainty` (``Uncertainty.free`` and
    ``cov_free``, initial states included), or a pair ``(names, covariance)`` as it is."""
    if isinstance(result, tuple | list) and len(result) == 2:
        names, cov = tuple(result[0]), np.asarray(result[1], float)
    elif hasattr(result, "cov_free") and hasattr(result, "free"):  # an Uncertainty
        names, cov = tuple(result.free), np.asarray(result.cov_free, float)
    elif hasattr(getattr(result, "problem", None), "hold") and hasattr(result, "cov"):
        names = tuple(n for n in result.free if n in result.model.param_names)
        idx = [result.free.index(n) for n in names]
        cov = np.asarray(result.cov, float)[np.ix_(idx, idx)]
    elif hasattr(result, "cost") and hasattr(result, "problem"):
        raise FitError(
            "the covariance of an output-error fit's parameters comes from "
            "jaxbox.validate.uncertainty(result): pass parameters=uncertainty(result)"
        )
    else:
        raise FitError(
            "parameters=True needs a maximum-likelihood fit for the covariance of its "
            "parameters; else pass parameters=jaxbox.validate.uncertainty(fit) or "
            "(names, covariance)"
        )
    if cov.shape != (len(names), len(names)):
        raise FitError(f"parameters: a covariance of {len(names)} names must be square")
    if not np.all(np.isfinite(cov)):
        raise FitError(
            "the covariance of the fit's parameters is not finite (a parameter is not "
            "identifiable); forecast without the parameters' uncertainty"
        )
    return names, cov


def _parameter_variance(form: StochasticForm, parameters, mean_of) -> np.ndarray:
    """``diag(J Σ Jᵀ)`` of the outputs ``mean_of(form)`` [..., p] for the parameter covariance
    ``parameters = (names, Σ)``, ``J`` by central differences (steps of 1e-4 of each value)."""
    names, cov = parameters
    bad = [n for n in names if n not in form.model.param_names]
    if bad:
        raise FitError(f"parameters: {', '.join(bad)} not parameters of {form.model.name}")
    cols = []
    for n in names:
        v = form.params[n]
        h = 1e-4 * max(abs(v), 1e-8)
        plus = dataclasses.replace(form, params={**form.params, n: v + h})
        minus = dataclasses.replace(form, params={**form.params, n: v - h})
        cols.append((mean_of(plus) - mean_of(minus)) / (2 * h))
    J = np.stack(cols, axis=-1)  # [..., p, k]
    return np.einsum("...i,ij,...j->...", J, cov, J)


def _covariance_of(result, parameters):
    if parameters is False or parameters is None:
        return None
    return parameter_covariance(result if parameters is True else parameters)


def forecast(
    result,
    history,
    future,
    *,
    horizon: int | str | pd.Timedelta = "24h",
    x0: Mapping[str, float] | None = None,
    parameters: bool | tuple = False,
    calibrate: bool = True,
    max_gap: float | str = DEFAULT_MAX_GAP,
) -> pd.DataFrame:
    """Forecast the outputs of a fitted model with their uncertainty.

    Args:
        result: a fit (:class:`~jaxbox.fit.FitResult`, :class:`~jaxbox.stochastic.MLResult`)
            or its :class:`~jaxbox.forecast.StochasticForm`. An output-error fit's noise is
            estimated from its residuals (once per result; ``frame.attrs["noise"]`` says so).
        history: the data up to the forecast's origin ``t`` (its last sample): inputs and
            outputs at one regular step, outputs may be missing. The filter starts at the fit's
            initial state ``T_*0`` (or ``x0`` [°C] per state), so the history should start
            where the fit's data start, or be long enough to forget the start.
        future: the inputs after ``t`` (°C, W, W/m²), continuing the history at its step, at
            least up to ``t + horizon``; outputs in it, if any, are reported as ``*_measured``.
        horizon: samples, or a duration (``"24h"``).
        x0: initial state [°C] per state name, instead of the fit's ``T_*0``.
        parameters: also the uncertainty of the estimated parameters in the bands (see the
            module docstring): ``True`` (a maximum-likelihood fit's covariance), an
            :class:`~jaxbox.validate.Uncertainty` (``jaxbox.validate.uncertainty(fit)``), or
            ``(names, covariance)`` [SI²].
        calibrate: scale the bands to the model's own multi-step errors over the history
            (see the module docstring); ``False``: the stochastic form's bands as they are.
        max_gap: the longest gap of the history's inputs [s] (or ``"2h"``) the filter bridges
            without reopening (:meth:`StochasticForm.filter`); missing inputs are interpolated
            either way.

    Returns:
        A DataFrame indexed by time (``t + step`` … ``t + horizon``): ``step`` (samples after
        ``t``) and per output ``<output>_mean``, ``_sd``, ``_lo50``, ``_hi50``, ``_lo95``,
        ``_hi95`` [°C, K] (and ``_measured`` where ``future`` holds the output). ``attrs``:
        ``model``, ``origin``, ``noise`` (where the noise comes from), ``state`` and
        ``state_cov`` (the filtered state at ``t`` [°C] and its covariance [K²]),
        ``calibration`` (what scaled the bands).
    """
    _check_flag(calibrate, "calibrate")
    form = stochastic_form(result)
    model = form.model
    history = as_data(history, "history")
    future = as_data(future, "future")
    run = form.filter(history, x0=x0, max_gap=max_gap)
    dt = regular_step(history)
    steps = horizon_steps(horizon, dt)
    u = future_inputs(model, history, future, steps, last=run.u[-1])
    out = propagate(run.system, run.m[-1], run.P[-1], u)
    note = _calibrated(out, run, steps, calibrate)
    cov = _covariance_of(result, parameters)
    if cov is not None:

        def mean_of(f):
            r = f.filter(history, x0=x0, max_gap=max_gap)
            return propagate(r.system, r.m[-1], r.P[-1], u)["y"]

        out["var"] = out["var"] + _parameter_variance(form, cov, mean_of)
    index = history.index[-1] + pd.to_timedelta(np.arange(1, steps + 1) * dt, unit="s")
    measured = None
    if all(o in future.columns for o in model.outputs):
        meas = future.frame[list(model.outputs)].reindex(index)
        measured = meas.to_numpy(dtype=float)
    frame = _frame(model.outputs, index, out["y"], out["var"], measured)
    frame.attrs.update(_attrs(form, history.index[-1], run.m[-1], run.P[-1]))
    frame.attrs["parameters"] = cov is not None
    frame.attrs["calibration"] = note
    frame.attrs["bridged"] = _bridged(run, max_gap)
    return frame


def _bridged(run, max_gap) -> str | None:
    """What the filter did with the history's missing inputs, in a line (``None``: none)."""
    filled = run.filled
    if filled is None or not filled.any():
        return None
    line = f"{int(filled.sum())} sample(s) of the history with a missing input interpolated"
    if run.reopened:
        when = ", ".join(str(run.index[k]) for k in run.reopened[-3:])
        line += (
            f"; the filter reopened after {len(run.reopened)} gap(s) longer than max_gap "
            f"({_duration(1, duration_seconds(max_gap))}), at {when}"
        )
    return line


def _attrs(form: StochasticForm, origin, m, P) -> dict:
    return {
        "model": form.model.name,
        "outputs": list(form.model.outputs),
        "origin": str(origin),
        "noise": form.note,
        "source": form.source,
        "states": list(form.model.states),
        "state": [float(v) for v in m],
        "state_cov": np.asarray(P, float).tolist(),
    }


def backtest(
    result,
    data,
    *,
    start=None,
    horizon: int | str | pd.Timedelta = "24h",
    every: int = 1,
    parameters: bool | tuple = False,
    calibrate: bool = True,
    max_gap: float | str = DEFAULT_MAX_GAP,
) -> pd.DataFrame:
    """Forecasts from many origins over measured data, scored against the measurements.

    The filter runs once over ``data``; from every ``every``-th sample at or after ``start``
    (default: the first) whose horizon lies within the data, the measured inputs drive a
    forecast (:func:`forecast`), which is compared with the measured outputs. ``parameters``:
    as in :func:`forecast`. ``calibrate``: each origin's bands calibrated on the data before
    it, as :func:`forecast` would calibrate them there (module docstring); origins with fewer
    than :data:`CALIBRATION_MIN` whole horizons before them keep the raw bands.

    Missing inputs are bridged by the filter (``max_gap`` as in :func:`forecast`); an origin
    whose horizon holds a missing input is not scored (a forecast takes measured inputs).

    Returns:
        One row per horizon step and output: ``step``, ``hours``, ``output``, ``n`` (scored
        forecasts), ``rmse`` [K], ``bias`` [K], ``cover50``, ``cover95`` (fraction of the
        measurements inside the 50 % and 95 % bands), ``sd`` [K] (mean forecast sd).
    """
    form = stochastic_form(result)
    model = form.model
    data = as_data(data)
    run = form.filter(data, max_gap=max_gap)
    dt = regular_step(data)
    steps = horizon_steps(horizon, dt)
    n = len(data)
    first = 0 if start is None else int(np.searchsorted(data.index, pd.Timestamp(start)))
    if not isinstance(every, int | np.integer) or isinstance(every, bool) or every < 1:
        raise FitError(f"every must be a whole number of samples ≥ 1, got {every!r}")
    origins = np.arange(first, n - steps, int(every))
    if origins.size == 0:
        raise FitError(
            f"no origin at or after {start} leaves a horizon of {steps} samples within the data "
            f"(which end at {data.index[-1]})"
        )
    measured = _measured_inputs(run, origins, steps)[:, -1]
    if not measured.all():
        origins = origins[measured]
        if origins.size == 0:
            raise FitError(
                f"every origin at or after {start} has a missing input within its horizon of "
                f"{steps} samples: a backtest scores forecasts from measured inputs"
            )
    u = np.stack([run.u[o : o + steps + 1] for o in origins])
    out = propagate(run.system, run.m[origins], run.P[origins], u)
    _check_flag(calibrate, "calibrate")
    if calibrate:
        factor, calibrated = _per_origin(run, origins, steps)
        out["var"] = out["var"] * factor
        note = (
            f"per origin, from the forecasts of the data before it (all of it and its last "
            f"{_recent(dt)} samples): {int(calibrated.sum())} of {origins.size} origins "
            f"calibrated (the others have fewer than {CALIBRATION_MIN} whole horizons before them)"
        )
    else:
        note = "none (calibrate=False)"
    cov = _covariance_of(result, parameters)
    if cov is not None:

        def mean_of(f):
            r = f.filter(data, max_gap=max_gap)
            return propagate(r.system, r.m[origins], r.P[origins], u)["y"]

        out["var"] = out["var"] + _parameter_variance(form, cov, mean_of)
    meas = np.stack([run.y[o + 1 : o + steps + 1] for o in origins])  # [O, H, p]
    sd = np.sqrt(out["var"])
    rows = []
    for j, o in enumerate(model.outputs):
        err = meas[..., j] - out["y"][..., j]
        ok = np.isfinite(err)
        z = np.abs(err) / sd[..., j]
        for h in range(steps):
            k = ok[:, h]
            e = err[k, h]
            rows.append(
                {
                    "step": h + 1,
                    "hours": (h + 1) * dt / 3600.0,
                    "output": o,
                    "n": int(k.sum()),
                    "rmse": float(np.sqrt(np.mean(e**2))) if e.size else np.nan,
                    "bias": float(np.mean(e)) if e.size else np.nan,
                    "cover50": float(np.mean(z[k, h] <= _Z[0.5])) if e.size else np.nan,
                    "cover95": float(np.mean(z[k, h] <= _Z[0.95])) if e.size else np.nan,
                    "sd": float(np.mean(sd[k, h, j])) if e.size else np.nan,
                }
            )
    table = pd.DataFrame(rows)
    table.attrs.update(
        {
            "model": model.name,
            "noise": form.note,
            "origins": int(origins.size),
            "parameters": cov is not None,
            "calibration": note,
        }
    )
    return table


def _check_flag(value, name: str) -> None:
    if not isinstance(value, bool | np.bool_):
        raise FitError(f"{name} must be True or False, got {value!r}")
