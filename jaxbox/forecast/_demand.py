"""The heating power that holds a zone at a setpoint: the fitted model inverted.

From the Kalman state at the origin ``t`` (:func:`~jaxbox.forecast.forecast`), the heater holds
its power constant over each sample interval; the power ``q_k`` over ``(t_k, t_{k+1}]`` is the one
that brings the zone to the setpoint at ``t_{k+1}``::

    x_{k+1} = Φ x_k + d_k + g q_k,    c·x_{k+1} = T_set(t_{k+1})
    ⇒ q_k = (T_set − c·(Φ x_k + d_k)) / (c·g),

where ``d_k`` is the drive of the other inputs (the fit's hold), ``g = ∫_0^Δt e^{As} ds b`` the
response to a constant unit power of the heater input ``b`` and ``c`` the zone's output row. The
power is clipped to ``[q_min, q_max]``: where the heater is saturated (or off), the zone floats,
and the recursion goes on with the clipped power.

The mean path uses the filtered mean; the band comes from a Monte Carlo of the stochastic form
(initial state drawn from the filter's ``N(x̂, P)``, process noise each step), each draw
controlled by the same law: the power, the zone temperature and the energy over the horizon are
reported with their 2.5 % and 97.5 % quantiles.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Mapping

import numpy as np
import pandas as pd

from ..fit._problem import FitError
from ..stochastic._checks import as_data, regular_step
from ._bridge import DEFAULT_MAX_GAP
from ._forecast import future_inputs, horizon_steps
from ._form import stochastic_form

__all__ = ["heat_demand", "setpoint_schedule", "parse_setback", "SetpointWarning"]

#: a zone more than this below its setpoint with the heater at its maximum is "not reached" [K]
REACH_TOLERANCE = 0.05


class SetpointWarning(UserWarning):
    """The heater cannot hold the zone at the setpoint over part of the horizon."""


def parse_setback(text: str) -> tuple[float, str, str]:
    """``"17@22:00-06:00"`` → ``(17.0, "22:00", "06:00")``: a setpoint [°C] from a clock time
    to another (across midnight when the second is earlier)."""
    m = re.fullmatch(
        r"\s*([-+]?\d+(?:\.\d*)?)\s*@\s*(\d{1,2}:\d{2})\s*-\s*(\d{1,2}:\d{2})\s*", text
    )
    if not m:
        raise FitError(
            f"setback must be TEMPERATURE@HH:MM-HH:MM, e.g. 17@22:00-06:00; got {text!r}"
        )
    for clock in m[2], m[3]:
        h, mi = (int(v) for v in clock.split(":"))
        if not (0 <= h < 24 and 0 <= mi < 60):
            raise FitError(f"setback: {clock} is not a clock time (HH:MM)")
    return float(m[1]), m[2], m[3]


def setpoint_schedule(
    index: pd.DatetimeIndex, setpoint: float, setback: str | tuple | None = None
) -> np.ndarray:
    """The setpoint [°C] at each time of ``index``: ``setpoint``, or the setback temperature
    (``"17@22:00-06:00"`` or ``(17, "22:00", "06:00")``) from its first clock time (inclusive)
    to its second (exclusive), local time of the index."""
    out = np.full(len(index), float(setpoint))
    if setback is None:
        return out
    temp, a, b = parse_setback(setback) if isinstance(setback, str) else setback
    minutes = index.hour * 60 + index.minute
    ha, ma = (int(v) for v in str(a).split(":"))
    hb, mb = (int(v) for v in str(b).split(":"))
    lo, hi = ha * 60 + ma, hb * 60 + mb
    inside = (minutes >= lo) & (minutes < hi) if lo <= hi else (minutes >= lo) | (minutes < hi)
    out[np.asarray(inside)] = float(temp)
    return out


def _control(sysm, j: int, row: int, x, drive, sp, q_min, q_max):
    """The inversion law over the horizon for states ``x`` [..., n]: powers [..., H] [W] and
    the zone temperatures [..., H] [°C] it gives; ``drive`` [..., H, n] without the heater."""
    g = sysm.G0[:, j]
    c = sysm.C[row]
    cg = float(c @ g)
    if not cg > 0:
        raise FitError(
            "the heater input does not warm the zone within one sample in this model "
            f"(c·g = {cg:.3g} K/W); it cannot be inverted for a setpoint"
        )
    H = sp.shape[-1]
    qs, ts = [], []
    for k in range(H):
        free = x @ sysm.Phi.T + drive[..., k, :]
        q = np.clip((sp[k] - free @ c) / cg, q_min, q_max)
        x = free + q[..., None] * g
        qs.append(q)
        ts.append(x @ c)
    return np.stack(qs, -1), np.stack(ts, -1), x


def heat_demand(
    result,
    history,
    future,
    *,
    setpoint: float | np.ndarray | pd.Series,
    q_max: float,
    q_min: float = 0.0,
    setback: str | tuple | None = None,
    horizon: int | str | pd.Timedelta = "24h",
    heater: str | None = None,
    zone: str | None = None,
    samples: int = 400,
    seed: int | None = 0,
    x0: Mapping[str, float] | None = None,
    max_gap: float | str = DEFAULT_MAX_GAP,
) -> pd.DataFrame:
    """The heating power that holds the zone at a setpoint over a horizon, with its band.

    Args:
        result: a fit or its :class:`~jaxbox.forecast.StochasticForm`.
        history: data up to the origin ``t`` (as :func:`~jaxbox.forecast.forecast`).
        future: the other inputs after ``t`` (the heater's column, if any, is ignored).
        setpoint: zone setpoint [°C]: a number, or one value per forecast sample (an array or
            a Series on the forecast's times).
        q_max, q_min: the heater's range [W].
        setback: a lower setpoint at night, ``"17@22:00-06:00"`` (with a number ``setpoint``).
        horizon: samples or a duration (``"24h"``).
        heater: the heater's input column (default ``Q_hea``, or the model's only ``Q_hea*``).
        zone: the controlled output (default the model's first).
        samples: Monte Carlo draws of the band; seed: their seed.
        x0: initial state [°C] of the filter per state name.
        max_gap: the longest gap of the history's inputs [s] the filter bridges without
            reopening (as :func:`~jaxbox.forecast.forecast`).

    Returns:
        A DataFrame on the forecast's times ``t + step … t + horizon``: ``setpoint`` [°C];
        ``<heater>`` [W], the constant power over the interval that ends at that time, with
        ``<heater>_lo95``, ``<heater>_hi95``; ``<zone>`` [°C] (at the setpoint, or floating
        where the heater is saturated or off) with ``_lo95``, ``_hi95``; ``saturated`` (heater
        at ``q_max`` and the zone more than 0.05 K below the setpoint). ``attrs``:
        ``energy_kwh`` and its band ``energy_kwh_lo95``, ``energy_kwh_hi95``,
        ``unreached`` (the saturated stretches) and ``noise``. A setpoint the heater cannot
        reach is said by a :class:`SetpointWarning`; the zone's float is forecast there.
    """
    form = stochastic_form(result)
    model = form.model
    heater = heater or _default_heater(model)
    if heater not in model.inputs:
        raise FitError(
            f"{model.name} has no heater input {heater!r}; its inputs are {', '.join(model.inputs)}"
        )
    zone = zone or model.outputs[0]
    if zone not in model.outputs:
        raise FitError(f"{model.name} has no output {zone!r}; its outputs are {model.outputs}")
    q_max, q_min = float(q_max), float(q_min)
    if not (np.isfinite(q_max) and np.isfinite(q_min) and q_max > q_min):
        raise FitError(f"the heater's range needs q_min < q_max [W], got {q_min:g}, {q_max:g}")
    history = as_data(history, "history")
    future = as_data(future, "future")
    dt = regular_step(history)
    steps = horizon_steps(horizon, dt)
    j, row = model.inputs.index(heater), model.outputs.index(zone)
    if heater not in future.columns:
        future = future.with_columns({heater: np.zeros(len(future))})
    run = form.filter(history, x0=x0, max_gap=max_gap)
    u = future_inputs(model, history, future, steps, last=run.u[-1])
    u[:, j] = 0.0
    sysm = run.system
    index = history.index[-1] + pd.to_timedelta(np.arange(1, steps + 1) * dt, unit="s")
    sp = _setpoints(setpoint, setback, index)
    drive = u[:-1] @ sysm.G0.T + (u[1:] - u[:-1]) @ sysm.G1.T  # [H, n]
    q, temp, _ = _control(sysm, j, row, run.m[-1], drive, sp, q_min, q_max)
    # Monte Carlo of the stochastic form under the same law
    rng = np.random.default_rng(seed)
    n = len(run.m[-1])
    L0 = _factor(run.P[-1])
    LQ = _factor(sysm.Q)
    xs = run.m[-1] + rng.standard_normal((samples, n)) @ L0.T
    noise = rng.standard_normal((samples, steps, n)) @ LQ.T
    qmc, tmc, _ = _control(sysm, j, row, xs, drive[None] + noise, sp, q_min, q_max)
    energy = q.sum() * dt / 3.6e6
    emc = qmc.sum(axis=1) * dt / 3.6e6
    saturated = (q >= q_max) & (temp < sp - REACH_TOLERANCE)
    frame = pd.DataFrame(
        {
            "setpoint": sp,
            heater: q,
            f"{heater}_lo95": np.quantile(qmc, 0.025, axis=0),
            f"{heater}_hi95": np.quantile(qmc, 0.975, axis=0),
            zone: temp,
            f"{zone}_lo95": np.quantile(tmc, 0.025, axis=0),
            f"{zone}_hi95": np.quantile(tmc, 0.975, axis=0),
            "saturated": saturated,
        },
        index=index,
    )
    frame.index.name = "time"
    unreached = _stretches(index, saturated, dt)
    frame.attrs.update(
        {
            "model": model.name,
            "origin": str(history.index[-1]),
            "heater": heater,
            "zone": zone,
            "q_max": q_max,
            "q_min": q_min,
            "energy_kwh": float(energy),
            "energy_kwh_lo95": float(np.quantile(emc, 0.025)),
            "energy_kwh_hi95": float(np.quantile(emc, 0.975)),
            "unreached": unreached,
            "noise": form.note,
        }
    )
    if unreached:
        worst = float(np.max(sp[saturated] - temp[saturated]))
        spans = ", ".join(f"{a} to {b}" for a, b in unreached)
        warnings.warn(
            f"the heater ({q_max:g} W) cannot hold {zone} at the setpoint from {spans} (up to "
            f"{worst:.1f} K below it); there the forecast is the zone's float",
            SetpointWarning,
            stacklevel=2,
        )
    return frame


def _default_heater(model) -> str:
    if "Q_hea" in model.inputs:
        return "Q_hea"
    heaters = [i for i in model.inputs if i.startswith("Q_hea")]
    if len(heaters) == 1:
        return heaters[0]
    raise FitError(
        f"{model.name} has {'no' if not heaters else 'several'} heater inputs Q_hea*"
        f"{'' if not heaters else ' (' + ', '.join(heaters) + ')'}; name one with heater="
    )


def _setpoints(setpoint, setback, index) -> np.ndarray:
    if isinstance(setpoint, pd.Series):
        sp = setpoint.reindex(index).to_numpy(dtype=float)
        if np.isnan(sp).any():
            raise FitError(
                f"the setpoint Series must hold a value at every forecast time ({index[0]} to "
                f"{index[-1]})"
            )
        return sp
    if np.ndim(setpoint) == 0:
        try:
            value = float(setpoint)
        except (TypeError, ValueError):
            raise FitError(f"setpoint must be a temperature [°C], got {setpoint!r}") from None
        if not np.isfinite(value):
            raise FitError(f"setpoint must be a finite temperature [°C], got {setpoint!r}")
        return setpoint_schedule(index, value, setback)
    sp = np.asarray(setpoint, dtype=float)
    if sp.shape != (len(index),) or not np.all(np.isfinite(sp)):
        raise FitError(
            f"setpoint must be one temperature or {len(index)} finite values (one per forecast "
            f"sample), got shape {sp.shape}"
        )
    if setback is not None:
        raise FitError("give setback with one setpoint temperature, not with a schedule")
    return sp


def _factor(S) -> np.ndarray:
    """A square root ``L Lᵀ = S`` of a covariance (eigendecomposition: ``S`` may be singular)."""
    w, V = np.linalg.eigh(0.5 * (S + S.T))
    return V * np.sqrt(np.clip(w, 0.0, None))


def _stretches(index, mask, dt: float) -> list[tuple[str, str]]:
    """``(first, last)`` times of each run of True in ``mask`` (the intervals ending there)."""
    out = []
    idx = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    for a, b in zip(idx[::2], idx[1::2], strict=True):
        start = index[a] - pd.Timedelta(seconds=dt)
        out.append((str(start), str(index[b - 1])))
    return out
