"""A record extended past its last sample, so that records of neighbouring lengths share one
compiled program.

The fit (samples of weight 0), the maximum-likelihood solve (missing outputs), the diffrax
post-simulation and the interval Jacobians all extend a record the same way: the times go on at
the data's step and the inputs hold their last values. Every simulation here runs forward in
time, so no state at a real sample depends on what comes after it; the callers drop, or weigh by
zero, the samples beyond the record.
"""

from __future__ import annotations

import numpy as np

__all__ = ["extend_times", "hold_rows"]


def extend_times(t: np.ndarray, n: int) -> np.ndarray:
    """Sample times ``t`` [N] (s) extended to ``n`` samples at the data's step ``t[1] − t[0]``
    (1 s for a single sample); ``t`` itself where it has ``n`` or more."""
    t = np.asarray(t, dtype=float)
    extra = int(n) - len(t)
    if extra <= 0:
        return t
    step = t[1] - t[0] if len(t) > 1 else 1.0
    return np.concatenate([t, t[-1] + step * np.arange(1, extra + 1)])


def hold_rows(a: np.ndarray, n: int, axis: int = 0) -> np.ndarray:
    """``a`` extended to ``n`` entries along ``axis`` (the time axis) by repeating its last
    entry; ``a`` itself where it has ``n`` or more."""
    a = np.asarray(a)
    extra = int(n) - a.shape[axis]
    if extra <= 0:
        return a
    last = np.take(a, [-1], axis=axis)
    return np.concatenate([a, np.repeat(last, extra, axis=axis)], axis=axis)
