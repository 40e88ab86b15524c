"""Energy meters: cumulative counters turned into the mean power of each sampling interval.

A heat or electricity meter logs the energy delivered since it was installed (kWh, MWh, J …),
not a power. The power of the interval that ends at ``t_k`` (time stamps end their intervals) is

    P_k = (E_k − E_{k−1}) / (t_k − t_{k−1}) · (joules per unit)   [W],

NaN for the first sample, next to a missing reading and where the counter falls (a reset or a
replaced meter): such samples become gaps, judged like any other
(:func:`jaxbox.data.prepare_window`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from ._args import check_mapping
from ._errors import DataError

__all__ = ["COUNTER_UNITS", "counters_to_power", "rising_share"]

#: A power column is an energy counter when it never falls (at this share of its steps: a
#: reset or two allowed) and rises at this share of them, and at least this many times: the
#: meter of a heating that runs a tenth of the time still rises at a tenth of its steps
#: (an office's, off at night and at weekends: 40 % of its hours), and no power logged as it
#: is holds still or climbs through a whole record without falling once.
COUNTER_MONOTONE = 0.99
COUNTER_RISING = 0.1
COUNTER_RISES = 6


def rising_share(values: np.ndarray) -> float | None:
    """The share of the steps of ``values`` (finite ones, in order) that rise, when the series
    looks like a cumulative counter (it never falls: :data:`COUNTER_MONOTONE`; it rises:
    :data:`COUNTER_RISING`); else ``None``."""
    x = np.asarray(values, dtype=float)
    steps = np.diff(x[np.isfinite(x)])
    if steps.size < 2:
        return None
    rising = float(np.mean(steps > 0))
    if np.mean(steps >= 0) < COUNTER_MONOTONE or rising < COUNTER_RISING:
        return None
    if np.count_nonzero(steps > 0) < COUNTER_RISES:
        return None
    return rising


#: Joules per unit of an energy counter.
COUNTER_UNITS: dict[str, float] = {
    "J": 1.0,
    "kJ": 1e3,
    "MJ": 1e6,
    "GJ": 1e9,
    "Wh": 3600.0,
    "kWh": 3.6e6,
    "MWh": 3.6e9,
}


def check_counters(counters: Mapping[str, str] | None, names: list[str]) -> dict[str, float]:
    """``counters`` (column -> unit) checked against the columns; column -> joules per unit."""
    given = check_mapping(counters, "counters", "{'Q_hea': 'kWh'}")
    out = {}
    for name, unit in given.items():
        if name not in names:
            raise DataError(
                f"counters names column {name!r}, but there is none; columns: "
                f"{', '.join(map(repr, names))} (counters apply after columns=)."
            )
        factor = COUNTER_UNITS.get(str(unit).strip())
        if factor is None:
            raise DataError(
                f"unknown energy unit {unit!r} for counter {name!r}; use one of "
                f"{', '.join(COUNTER_UNITS)}."
            )
        out[str(name)] = factor
    return out


def counters_to_power(
    frame: pd.DataFrame, joules: Mapping[str, float], *, longest: float | None = None
) -> pd.DataFrame:
    """``frame`` (float columns, DatetimeIndex) with each counter column of ``joules``
    (column -> joules per unit) replaced by the mean power of each interval [W]; an interval
    longer than ``longest`` [s] (rows missing from a regular grid) gives a gap."""
    if not joules:
        return frame
    out = frame.copy()
    seconds = np.diff(out.index.asi8) * 1e-9
    for name, factor in joules.items():
        energy = out[name].to_numpy(dtype=float)
        delta = np.diff(energy)
        power = np.full(len(energy), np.nan)
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(delta) & (delta >= 0) & (seconds > 0)
        if longest is not None:
            ok &= seconds <= longest * (1 + 1e-6)
        power[1:][ok] = delta[ok] * factor / seconds[ok]
        out[name] = power
    return out
