"""Averaging a regular (or nearly regular) series onto a coarser regular grid.

Each sample at time ``t`` is the mean over the interval ``(t - step, t]`` (the convention of
monitoring systems that stamp the end of their averaging interval), so the mean over a coarser
interval ``(a, b]`` is the plain mean of the samples stamped in ``(a, b]``: right-closed intervals
labelled at their right edge. Intervals at either end that the data do not cover completely are
dropped; an interval without samples inside the data is a gap (NaN).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ._checks import JITTER, fmt_seconds, irregular_position, nominal_step
from ._errors import DataError

__all__ = ["resample_mean", "rule_seconds"]

_TOL = 1e-6


def rule_seconds(rule: str | pd.Timedelta | pd.DateOffset) -> tuple[pd.DateOffset, float]:
    """Parse a fixed-length pandas frequency (``"1h"``, ``"15min"``) into (offset, seconds)."""
    try:
        offset = pd.tseries.frequencies.to_offset(rule)
    except (ValueError, TypeError):
        raise DataError(
            f"cannot read resample rule {rule!r}; use a pandas frequency such as '1h' or '15min'."
        ) from None
    try:
        width = pd.Timedelta(offset)
    except (ValueError, TypeError):
        raise DataError(
            f"resample rule {rule!r} has no fixed length; use one such as '1h', '15min' or '1D'."
        ) from None
    seconds = float(width / pd.Timedelta(seconds=1))
    if seconds <= 0:
        raise DataError(f"resample rule {rule!r} must be a positive duration.")
    return offset, seconds


def resample_mean(
    frame: pd.DataFrame, rule: str | pd.Timedelta | pd.DateOffset, step: float
) -> pd.DataFrame:
    """Mean of ``frame`` over right-closed intervals of length ``rule`` labelled at the right edge.

    ``step`` [s] is the sampling step of ``frame`` (its median step; for irregular stamps the
    rule is checked against the logger's own step, :func:`~jaxbox.data._checks.nominal_step`,
    since rows missing from a jittered grid lift the median above it). Incomplete intervals at
    the start or end are dropped; an interval without any value of a column is a gap (NaN).
    """
    offset, width = rule_seconds(rule)
    regular = irregular_position(frame.index) is None
    # jittered stamps, rows missing: the logger's own step, give or take its jitter
    logged = step if regular else nominal_step(frame.index) / (1 + JITTER)
    if width < logged * (1 - _TOL):
        raise DataError(
            f"resample rule {rule!r} ({fmt_seconds(width)}) is shorter than the sampling step "
            f"({fmt_seconds(logged)}); resampling only averages onto a coarser grid."
        )
    ratio = width / step
    if regular and abs(ratio - round(ratio)) > _TOL * ratio:
        raise DataError(
            f"resample rule {rule!r} ({fmt_seconds(width)}) is not a whole multiple of the "
            f"sampling step ({fmt_seconds(step)}); choose a multiple so that every interval "
            "holds the same number of samples."
        )
    groups = frame.resample(offset, closed="right", label="right")
    means = groups.mean()
    counts = pd.Series(1, index=frame.index).resample(offset, closed="right", label="right").sum()
    counts = counts.reindex(means.index, fill_value=0)
    tol = pd.Timedelta(seconds=_TOL * step)
    span = pd.Timedelta(seconds=width)
    keep = np.ones(len(means), dtype=bool)
    if len(means) and frame.index[0] - pd.Timedelta(seconds=step) > means.index[0] - span + tol:
        keep[0] = False
    if len(means) and frame.index[-1] < means.index[-1] - tol:
        keep[-1] = False
    means, counts = means[keep], counts[keep]
    if means.empty:
        raise DataError(
            f"the data ({frame.index[0]} to {frame.index[-1]}) do not cover one complete "
            f"{rule!r} interval; use a shorter rule or more data."
        )
    # an interval without any sample, or without any value of a column, is a gap (NaN)
    return means.set_axis(pd.DatetimeIndex(means.index, freq=None, name="time"), axis=0)
