"""k-step-ahead prediction performance, next to the (stricter) simulation performance.

A model predictive controller re-initialises its model from measurements at every step and
predicts k steps ahead with known (forecast) inputs. Here, at every sample i the state is set
to the measured outputs for the measured states and to the open-loop simulated state for the
others, then propagated k steps with the measured inputs by the exact first-order-hold
discretisation (:func:`~jaxbox.simulate.discretize_foh`); the k-step errors at ``i + k`` give
an RMSE per horizon and output. The simulation (open-loop, from the initial state) RMSE is
reported alongside: the reference study argues it is the stricter criterion, since a model that
only predicts well a few steps ahead may owe that to the re-initialisation. As k grows the
k-step error tends to the simulation error when no state is measured; with measured states it
tends to the error of a simulation that forgets its initial state.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from .._x64 import require_x64
from ._metrics import rmse, simulation_error

__all__ = ["PredictionPerformance", "prediction_performance"]

DEFAULT_HORIZONS = (1, 2, 3, 6, 12, 24)


@dataclasses.dataclass(frozen=True, eq=False)
class PredictionPerformance:
    """RMSE of k-step-ahead predictions and of the simulation.

    Attributes:
        outputs: output names (columns of the RMSE arrays).
        weights: output weights q_j.
        horizons: prediction horizons k [samples].
        step: sampling step [s].
        measured_states: states re-initialised from the measurements (the others from the
            simulation).
        rmse_auto: k-step RMSE [K] on the identification data, shape [len(horizons), outputs].
        se_auto: weighted k-step error Σ q_j RMSE_j [K] per horizon.
        sim_rmse_auto, sim_se_auto: simulation RMSE per output [K] and SE on the same data.
        rmse_cross, se_cross, sim_rmse_cross, sim_se_cross: the same on validation data (the
            simulation runs on from the identification period), or ``None``.
    """

    outputs: tuple[str, ...]
    weights: tuple[float, ...]
    horizons: np.ndarray
    step: float
    measured_states: tuple[str, ...]
    rmse_auto: np.ndarray
    se_auto: np.ndarray
    sim_rmse_auto: np.ndarray
    sim_se_auto: float
    rmse_cross: np.ndarray | None = None
    se_cross: np.ndarray | None = None
    sim_rmse_cross: np.ndarray | None = None
    sim_se_cross: float | None = None

    def to_dict(self) -> dict:
        """JSON-ready: per period, SE and RMSE per output by horizon, and the simulation's."""

        def period(rmse, se, sim_rmse, sim_se):
            if rmse is None:
                return None
            return {
                "se": {int(k): float(s) for k, s in zip(self.horizons, se, strict=True)},
                "rmse": {
                    name: {int(k): float(r) for k, r in zip(self.horizons, rmse[:, j], strict=True)}
                    for j, name in enumerate(self.outputs)
                },
                "simulation_se": float(sim_se),
                "simulation_rmse": {
                    n: float(r) for n, r in zip(self.outputs, sim_rmse, strict=True)
                },
            }

        return {
            "horizons": [int(k) for k in self.horizons],
            "step_s": float(self.step),
            "measured_states": list(self.measured_states),
            "auto": period(self.rmse_auto, self.se_auto, self.sim_rmse_auto, self.sim_se_auto),
            "cross": period(self.rmse_cross, self.se_cross, self.sim_rmse_cross, self.sim_se_cross),
        }


def _k_step(Phi, G0, G1, Cm, Dm, xhat, u, kmax):
    """Predictions ŷ_k for k = 1 … kmax from every origin: list of arrays [N − k, outputs]."""
    n = len(u)
    drive = u[:-1] @ G0.T + (u[1:] - u[:-1]) @ G1.T  # [N − 1, n_states]
    X = xhat
    out = []
    for k in range(1, kmax + 1):
        X = X[: n - k] @ Phi.T + drive[k - 1 : n - 1]
        out.append(X @ Cm.T + u[k:] @ Dm.T)
    return out


def _discrete(model, params, dt: float):
    """``(Φ, Γ0, Γ1, C, D, x0)`` of the exact discretisation at ``params`` in NumPy (Van Loan's
    augmented exponential): no compilation for a new structure."""
    from ..simulate._exact import discretize_foh_numpy

    theta = {k: float(v) for k, v in params.items()}
    A, B, C, D = model.state_space_numpy(theta)
    x0 = np.asarray([theta[m.T0] for m in model.network.nodes])
    return (*discretize_foh_numpy(A, B, dt), C, D, x0)


def _horizons(horizons) -> list[int]:
    """``horizons`` as whole numbers of samples ≥ 1 (one number is one horizon)."""
    from ..data._args import check_count

    if isinstance(horizons, int | np.integer) and not isinstance(horizons, bool):
        horizons = [horizons]
    if isinstance(horizons, str) or not hasattr(horizons, "__iter__"):
        raise TypeError(
            f"horizons must be whole numbers of samples, e.g. [1, 6, 24]; got {horizons!r}"
        )
    return [check_count(k, "each of horizons (whole samples)") for k in horizons]


def prediction_performance(
    result,
    valid=None,
    *,
    horizons: Sequence[int] | None = None,
) -> PredictionPerformance:
    """k-step-ahead prediction RMSE on the identification (and validation) data.

    Args:
        result: a :class:`~jaxbox.fit.FitResult`.
        valid: validation :class:`~jaxbox.data.Dataset` directly following the identification
            data (optional).
        horizons: horizons k in samples (default 1, 2, 3, 6, 12, 24, capped by the data length).

    Returns:
        :class:`PredictionPerformance`.
    """

    from ._args import check_fit
    from ._postsim import joined_arrays

    require_x64()
    needs = ("problem", "model", "data", "params")
    result = check_fit(result, needs=needs if valid is None else (*needs, "settings"))
    model = result.model
    ident = result.data
    names_out = list(model.outputs)
    if result.model.segments > 1 or len(ident.segments) > 1:
        raise ValueError(
            f"the identification data hold {len(ident.segments)} segments (gaps cut out or "
            "separate periods); k-step prediction needs one: pass a window without long gaps"
        )
    if valid is not None:
        from ._postsim import validation_window

        valid = validation_window(result, valid)
        if len(valid.segments) > 1 or (valid.start - ident.end).total_seconds() > ident.step * 1.5:
            raise ValueError(
                "the validation data hold gaps longer than max_gap or do not follow the "
                "identification data directly; k-step prediction needs one segment"
            )
    u, y, n_id = joined_arrays(result, valid)
    n_all = len(u)
    ks = np.asarray(sorted(set(DEFAULT_HORIZONS if horizons is None else _horizons(horizons))))
    ks = ks.astype(int)
    shortest = min(n_id, n_all - n_id) if valid is not None else n_id
    if horizons is None:
        ks = ks[ks < shortest]
    if ks.size == 0 or ks[0] < 1 or ks[-1] >= shortest:
        raise ValueError(
            f"horizons must be whole numbers of samples in [1, {shortest - 1}], got "
            f"{list(map(int, ks))}"
        )
    Phi, G0, G1, Cm, Dm, x0 = _discrete(model, result.params, float(ident.step))
    # open-loop simulation over both periods (exact discretisation)
    drive = u[:-1] @ G0.T + (u[1:] - u[:-1]) @ G1.T
    xs = np.empty((n_all, len(x0)))
    xs[0] = x0
    for i in range(n_all - 1):
        xs[i + 1] = Phi @ xs[i] + drive[i]
    ysim = xs @ Cm.T + u @ Dm.T
    # measured states: output rows of C that select one state
    xhat = xs.copy()
    measured = []
    for j in range(Cm.shape[0]):
        row = Cm[j]
        nz = np.flatnonzero(row)
        if nz.size == 1 and row[nz[0]] == 1.0 and not np.any(Dm[j]):
            xhat[:, nz[0]] = y[:, j]
            measured.append(model.states[nz[0]])
    preds = _k_step(Phi, G0, G1, Cm, Dm, xhat, u, int(ks[-1]))
    q = np.asarray(result.problem.weights, dtype=float)

    def period(lo, hi):
        rm = []
        for k in ks:
            pk = preds[k - 1]  # origin i ↦ row i, target i + k
            origins = np.arange(lo, hi - k)
            rm.append(rmse(pk[origins], y[origins + k]))  # output gaps left out
        rm = np.asarray(rm)
        se = np.asarray([simulation_error(r, q) for r in rm])
        srm = rmse(ysim[lo:hi], y[lo:hi])
        return rm, se, srm, simulation_error(srm, q)

    auto = period(0, n_id)
    cross = period(n_id, n_all) if valid is not None else (None, None, None, None)
    return PredictionPerformance(
        outputs=tuple(names_out),
        weights=tuple(float(w) for w in q),
        horizons=ks,
        step=float(ident.step),
        measured_states=tuple(measured),
        rmse_auto=auto[0],
        se_auto=auto[1],
        sim_rmse_auto=auto[2],
        sim_se_auto=float(auto[3]),
        rmse_cross=cross[0],
        se_cross=cross[1],
        sim_rmse_cross=cross[2],
        sim_se_cross=None if cross[3] is None else float(cross[3]),
    )
