"""Input gaps in the series a Kalman filter runs over: bridged, and the filter reopened after
the long ones.

A logger drops samples, and a forecast from months of history should not fail for an hour of
missing weather a month before its origin. The filter needs an input at every sample, so
:func:`bridge_inputs` fills every missing input by linear interpolation in time (held at the
series' ends) and tells which rows it filled. A gap of at most ``max_gap`` seconds is bridged as
the fits bridge it (:func:`jaxbox.data.prepare_window`); after a longer one the filter does not
trust what it carried through the guessed inputs: the outputs inside such a gap are not used,
and at its first sample after it the filter *reopens*, the predicted state's covariance widened
by the initial state's (the filter goes on as it began). Forecasts whose horizon holds a filled
input are left out of the bands' calibration and of a backtest's scores.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..data._gaps import DEFAULT_MAX_GAP, _runs, duration_seconds
from ..fit._problem import FitError

__all__ = ["bridge_inputs", "DEFAULT_MAX_GAP"]


def bridge_inputs(
    u: np.ndarray,
    names: Sequence[str],
    index,
    dt: float,
    max_gap: float | str = DEFAULT_MAX_GAP,
) -> tuple[np.ndarray, np.ndarray, list[tuple[int, int]]]:
    """The inputs ``u`` [N, m] with every missing value filled, which rows were filled, and the
    long gaps.

    Args:
        u: inputs [N, m] (NaN: missing), at the regular step ``dt`` [s].
        names: the input columns (for the messages).
        index: the time stamps (for the messages).
        max_gap: the longest gap [s] (or ``"2h"``) bridged; a longer one reopens the filter.

    Returns:
        ``(filled_u, filled, long)``: ``filled_u`` [N, m] (each column linearly interpolated
        over the sample number, held before its first and after its last value), ``filled``
        [N] (a row with at least one input filled), ``long``: the rows ``[start, stop)`` of
        each run of filled rows longer than ``max_gap``, in order.

    Raises:
        FitError: an input with no value at all.
    """
    limit = duration_seconds(max_gap)
    u = np.array(u, dtype=float, copy=True)
    bad = ~np.isfinite(u)
    if not bad.any():
        return u, np.zeros(len(u), dtype=bool), []
    rows = np.arange(len(u))
    for j in range(u.shape[1]):
        ok = ~bad[:, j]
        if not ok.any():
            raise FitError(
                f"input {names[j]} has no value in the {len(u)} samples from {index[0]} to "
                f"{index[-1]}: the Kalman filter needs it; give the column's values"
            )
        if not ok.all():
            u[:, j] = np.interp(rows, rows[ok], u[ok, j])
    filled = bad.any(axis=1)
    long = [(a, b) for a, b in _runs(filled) if (b - a) * dt > limit * (1 + 1e-9)]
    return u, filled, long
