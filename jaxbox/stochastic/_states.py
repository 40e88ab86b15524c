"""State estimation with a fitted stochastic model: filtered and smoothed states, innovations,
k-step-ahead prediction errors.

:func:`estimate_states` runs the Kalman filter (:func:`~jaxbox.stochastic._kalman.kalman_scan`)
and the Rauch–Tung–Striebel smoother over a dataset, for given parameters (physical and noise,
SI). The filtered state at the last sample, with its covariance, is what a model-predictive
controller starts from.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import jax.numpy as jnp
import numpy as np
import pandas as pd

from .. import _compiled
from .._compiled import jit
from ..fit._problem import FitError
from ..models import RCModel, get_model
from ._checks import as_data, number, x0_stds
from ._kalman import HOLDS, kalman_scan, rts_scan
from ._noise import noise_names
from ._problem import DEFAULT_X0_STD, stochastic_arrays, system

__all__ = ["StateEstimate", "estimate_states", "k_step_errors"]


#: the estimates a :class:`StateEstimate` holds, each with its covariance
_VIEWS = ("predicted", "filtered", "smoothed")


@dataclasses.dataclass(frozen=True, eq=False)
class StateEstimate:
    """Filtered and smoothed states of a stochastic model over a dataset.

    Attributes:
        model: the RC model.
        index: time stamps of the samples.
        states, outputs: names.
        predicted, predicted_cov: one-step predictions ``x̂_{k|k−1}`` [°C], shape [N, n], and
            their covariances [K²], shape [N, n, n].
        filtered, filtered_cov: ``x̂_{k|k}`` and covariances.
        smoothed, smoothed_cov: ``x̂_{k|N}`` and covariances (RTS).
        innovations: ``y_k − ŷ_{k|k−1}`` [K], shape [N, p] (NaN where the output is missing).
        innovation_cov: their covariances ``S_k`` [K²], shape [N, p, p].
        nll: negative log-likelihood (natural log, with the 2π constant).
        matrices: ``(Φ, Γ0, Γ1, Q, C, D)`` of the discrete model (numpy).
    """

    model: RCModel
    index: pd.DatetimeIndex
    states: tuple[str, ...]
    outputs: tuple[str, ...]
    predicted: np.ndarray
    predicted_cov: np.ndarray
    filtered: np.ndarray
    filtered_cov: np.ndarray
    smoothed: np.ndarray
    smoothed_cov: np.ndarray
    innovations: np.ndarray
    innovation_cov: np.ndarray
    nll: float
    matrices: tuple
    inputs: np.ndarray
    measured: np.ndarray

    @property
    def loglik(self) -> float:
        return -self.nll

    @property
    def standardized_innovations(self) -> np.ndarray:
        """Innovations divided by their standard deviations ``sqrt(S_jj)`` [-]."""
        return self.innovations / np.sqrt(np.diagonal(self.innovation_cov, axis1=1, axis2=2))

    def to_frame(self, which: Sequence[str] = ("filtered", "smoothed")) -> pd.DataFrame:
        """A table per sample: each state's estimate and standard deviation [K] for ``which``
        (``predicted``, ``filtered``, ``smoothed``), and each output's innovation."""
        which = [which] if isinstance(which, str) else list(which)
        bad = [w for w in which if w not in _VIEWS]
        if bad:
            raise ValueError(
                f"which: no estimate {', '.join(map(repr, bad))}; choose from {', '.join(_VIEWS)}"
            )
        cols = {}
        for w in which:
            mean, cov = getattr(self, w), getattr(self, f"{w}_cov")
            sd = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))
            for i, s in enumerate(self.states):
                cols[f"{s}_{w}"] = mean[:, i]
                cols[f"{s}_{w}_sd"] = sd[:, i]
        for j, o in enumerate(self.outputs):
            cols[f"{o}_innovation"] = self.innovations[:, j]
        return pd.DataFrame(cols, index=self.index)

    def current(self) -> dict:
        """The filtered state at the last sample and its covariance: where a controller starts."""
        return {
            "time": str(self.index[-1]),
            "states": {s: float(v) for s, v in zip(self.states, self.filtered[-1], strict=True)},
            "covariance": self.filtered_cov[-1].tolist(),
        }

    def k_step_errors(self, k: int | Sequence[int] = (1, 2, 4, 8)) -> dict:
        """k-step-ahead prediction errors (:func:`k_step_errors`) from the filtered states."""
        return k_step_errors(self, k)


def _check_params(model: RCModel, params: Mapping) -> dict:
    """Every physical and noise parameter of the stochastic form of ``model`` from ``params``
    (SI), checked: a mapping with every name and no other, finite numbers, resistances and
    capacities > 0, ``sigma_* ≥ 0`` and ``sigma_y_* > 0``."""
    names = model.param_names + noise_names(model)
    if not isinstance(params, Mapping):
        raise TypeError(
            f"params must be a mapping {{name: value}} (SI) over {', '.join(names)}, e.g. "
            f"MLResult.params; got {type(params).__name__}"
        )
    missing = [n for n in names if n not in params]
    if missing:
        raise FitError(
            f"parameters of the stochastic form of {model.name} missing: {', '.join(missing)} "
            "(give every physical and noise parameter, e.g. from an ML fit)"
        )
    extra = [str(n) for n in params if n not in names]
    if extra:
        raise FitError(
            f"params: the stochastic form of {model.name} has no parameter(s) "
            f"{', '.join(extra)}; its parameters are {', '.join(names)} (were they estimated "
            "with another model?)"
        )
    out = {}
    for n in names:
        v = number(params[n], f"parameter {n}")
        if not np.isfinite(v):
            raise FitError(f"parameter {n} is {v}; give a finite number")
        if n.startswith(("R_", "C_")) and not v > 0:
            raise FitError(f"parameter {n} is {v:g}; resistances and capacities must be > 0")
        out[n] = v
    for n in noise_names(model):
        if out[n] < 0 or (n.startswith("sigma_y_") and out[n] <= 0):
            raise FitError(f"noise parameter {n} = {out[n]:g}; sigma_* ≥ 0 and sigma_y_* > 0")
    return out


def _check_finite(out: dict, index, theta: dict) -> None:
    """A likelihood that is not finite (parameters finite but so extreme that the discretised
    model or the filter overflows) is named with the first sample where it is not."""
    bad = ~np.isfinite(out["nll_k"])
    if not bad.any():
        return
    k = int(np.flatnonzero(bad)[0])
    values = ", ".join(f"{n}={v:.4g}" for n, v in theta.items())
    raise FitError(
        f"the Kalman filter's likelihood is not finite from row {k} ({index[k]}) on: the "
        f"parameters ({values}) make the discrete model degenerate; check their values "
        "(e.g. against the bounds of fit_ml)"
    )


def _filter_fn(model: RCModel, hold: str, shapes):
    key = ("stochastic", "states", model.structure, hold, shapes)

    def build():
        def run(theta, x0_std, dt, u, y):
            mats, C, D, r, m0, P0 = system(model, theta, dt, hold, x0_std)
            out = kalman_scan(mats, C, D, r, m0, P0, u, y, full=True)
            ms, Ps = rts_scan(
                mats[0], None, out["m_pred"], out["P_pred"], out["m_filt"], out["P_filt"]
            )
            return out, ms, Ps, (*mats, C, D)

        return jit(run)

    return _compiled.cached(key, build)[0]


def estimate_states(
    model,
    params: Mapping[str, float],
    data,
    *,
    hold: str = "foh",
    x0_std: float | Mapping[str, float] | None = None,
) -> StateEstimate:
    """Filter and smooth the states of ``model`` over ``data`` for parameters ``params``.

    Args:
        model: an :class:`~jaxbox.models.RCModel` or library name.
        params: every physical and noise parameter (SI), e.g. :attr:`MLResult.params`.
        data: a :class:`~jaxbox.data.Dataset` with the model's inputs and outputs (outputs may
            be NaN where missing when the dataset allows it).
        hold: ``"foh"`` or ``"zoh"``, as in the fit.
        x0_std: standard deviation [K] of the initial states (default 1 K; 0: known exactly),
            one value or per state name.
    """
    model = get_model(model)
    data = as_data(data)
    theta = _check_params(model, params)
    if hold not in HOLDS:
        raise FitError(f"unknown hold {hold!r}; choose one of {', '.join(HOLDS)}")
    x0 = x0_stds(model, x0_std, DEFAULT_X0_STD, zero=True)
    dt, u, y = stochastic_arrays(model, data)
    fn = _filter_fn(model, hold, (u.shape, y.shape))
    th = {k: jnp.asarray(v) for k, v in theta.items()}
    out, ms, Ps, mats = fn(th, jnp.asarray(x0), dt, jnp.asarray(u), jnp.asarray(y))
    out = {k: np.asarray(v) for k, v in out.items()}
    _check_finite(out, data.index, theta)
    return StateEstimate(
        model=model,
        index=data.index,
        states=model.states,
        outputs=model.outputs,
        predicted=out["m_pred"],
        predicted_cov=out["P_pred"],
        filtered=out["m_filt"],
        filtered_cov=out["P_filt"],
        smoothed=np.asarray(ms),
        smoothed_cov=np.asarray(Ps),
        innovations=out["innov"],
        innovation_cov=out["S"],
        nll=float(out["nll"]),
        matrices=tuple(np.asarray(m) for m in mats),
        inputs=u,
        measured=y,
    )


def _horizons(k) -> list[int]:
    """``k`` of :func:`k_step_errors` as a list of whole numbers of samples: one integer or a
    sequence of them (a float, a string or a bool is named, not iterated or truncated)."""

    def whole(h) -> bool:
        return isinstance(h, int | np.integer) and not isinstance(h, bool | np.bool_)

    items = [k] if whole(k) else k
    if isinstance(items, str | bytes) or not isinstance(items, Sequence | np.ndarray):
        items = None
    if items is None or not all(whole(h) for h in items):
        raise ValueError(f"k must be a whole number of samples ≥ 1 or a list of them, got {k!r}")
    return [int(h) for h in items]


def k_step_errors(est: StateEstimate, k: int | Sequence[int] = (1, 2, 4, 8)) -> dict:
    """k-step-ahead prediction errors: from the filtered state at each sample ``i``, the model
    predicts the outputs at ``i + k`` with the measured inputs and no measurement in between —
    what a model-predictive controller relies on.

    Returns ``{k: {"errors": [N−k, p] (y − ŷ, K), "rmse": {output: K}}}``. For ``k = 1`` the
    errors are the innovations from the second sample on.
    """
    ks = _horizons(k)
    Phi, G0, G1, _, C, D = est.matrices
    u, y = est.inputs, est.measured
    n_samples = len(u)
    du = np.concatenate([u[1:] - u[:-1], np.zeros_like(u[:1])], axis=0)
    drive = u @ G0.T + du @ G1.T
    out = {}
    for h in ks:
        if not 1 <= h < n_samples:
            raise ValueError(f"k = {h} must be between 1 and {n_samples - 1} samples")
        m = est.filtered[: n_samples - h].copy()
        for j in range(h):
            m = m @ Phi.T + drive[j : n_samples - h + j]
        err = y[h:] - (m @ C.T + u[h:] @ D.T)
        out[h] = {
            "errors": err,
            "rmse": {
                o: float(np.sqrt(np.nanmean(err[:, j] ** 2))) for j, o in enumerate(est.outputs)
            },
        }
    return out
