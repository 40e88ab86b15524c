"""Error metrics: RMSE per output and the weighted simulation error SE = Σ q_j RMSE_j."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["rmse", "simulation_error"]


def rmse(y_sim, y_meas) -> np.ndarray:
    """Root-mean-square error per output column [same unit as y, K for temperatures]."""
    e = np.asarray(y_sim, dtype=float) - np.asarray(y_meas, dtype=float)
    if e.ndim == 1:
        e = e[:, None]
    return np.sqrt(np.mean(e * e, axis=0))


def simulation_error(rmse_per_output: Sequence[float], weights: Sequence[float]) -> float:
    """SE = Σ q_j RMSE_j [K], the reference study's weighted simulation error."""
    r = np.asarray(rmse_per_output, dtype=float)
    q = np.asarray(weights, dtype=float)
    return float(np.sum(q * r))
