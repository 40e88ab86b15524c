"""Error metrics: RMSE per output and the weighted simulation error SE = Σ q_j RMSE_j (output
gaps, NaN in the measurements, are left out)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["rmse", "simulation_error"]


def rmse(y_sim, y_meas) -> np.ndarray:
    """Root-mean-square error per output column [same unit as y, K for temperatures].

    A missing measurement (NaN, an output gap) is left out: the mean runs over the measured
    samples of each column (``nan`` for a column without any).
    """
    y_sim, y_meas = np.asarray(y_sim, dtype=float), np.asarray(y_meas, dtype=float)
    if y_sim.shape != y_meas.shape:
        raise ValueError(
            f"y_sim has shape {y_sim.shape} but y_meas {y_meas.shape}; give one simulated value "
            "per measured one (samples × outputs)"
        )
    e = y_sim - y_meas
    if e.ndim == 1:
        e = e[:, None]
    seen = np.isfinite(e)
    count = seen.sum(axis=0)
    total = np.where(seen, e * e, 0.0).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sqrt(np.where(count > 0, total / np.maximum(count, 1), np.nan))


def simulation_error(rmse_per_output: Sequence[float], weights: Sequence[float]) -> float:
    """SE = Σ q_j RMSE_j [K], the reference study's weighted simulation error."""
    r = np.asarray(rmse_per_output, dtype=float)
    q = np.asarray(weights, dtype=float)
    if r.shape != q.shape:
        raise ValueError(f"{r.size} RMSE values for {q.size} weights; give one weight per output")
    return float(np.sum(q * r))
