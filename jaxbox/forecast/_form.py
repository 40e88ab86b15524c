"""The stochastic form of a fitted model: what a forecast, a heat demand or a controller runs on.

A maximum-likelihood fit (:class:`~jaxbox.stochastic.MLResult`) *is* a stochastic model: its
physical and noise parameters are taken as they are. An output-error fit
(:class:`~jaxbox.fit.FitResult`) estimated the physical parameters only; its stochastic form keeps
them and estimates the noise from the fit's residual process: the diffusion ``sigma_<node>``
[K/√s] of every state and the measurement noise ``sigma_y_<output>`` [K] that maximise the Kalman
filter's likelihood of the identification data with the physical parameters held at the
output-error estimate (L-BFGS-B in the logarithms of the noise parameters, within the bounds of
:mod:`jaxbox.stochastic._noise`). The form says which of the two it is (:attr:`StochasticForm.
source`, :attr:`StochasticForm.note`).

:meth:`StochasticForm.system` gives the exact discrete matrices (Van Loan, the fit's hold),
:meth:`StochasticForm.filter` runs the Kalman filter of :mod:`jaxbox.stochastic._kalman` over a
dataset (one compiled program per state/input/output count and padded length).
"""

from __future__ import annotations

import dataclasses
import weakref
from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np

from .. import _compiled
from .._compiled import jit
from ..fit._problem import FitError
from ..models import RCModel
from ..stochastic._checks import as_data, regular_step, x0_stds
from ..stochastic._kalman import kalman_scan
from ..stochastic._noise import (
    SIGMA_BOUNDS,
    SIGMA_Y_BOUNDS,
    diffusion_names,
    measurement_names,
    noise_names,
)
from ..stochastic._problem import DEFAULT_X0_STD, system
from ._bridge import DEFAULT_MAX_GAP, bridge_inputs

__all__ = ["StochasticForm", "DiscreteSystem", "FilterRun", "stochastic_form"]

#: the filter runs over series padded to a multiple of this many samples (one compiled program
#: per padded length, not per length)
PAD = 512

#: standard deviation [K] of the initial state of an output-error fit's stochastic form
OE_X0_STD = DEFAULT_X0_STD


@dataclasses.dataclass(frozen=True, eq=False)
class DiscreteSystem:
    """``x_{k+1} = Φ x_k + Γ0 u_k + Γ1 (u_{k+1} − u_k) + w_k``, ``w_k ~ N(0, Q)``,
    ``y_k = C x_k + D u_k + e_k``, ``e_k ~ N(0, diag(r²))`` for one step ``dt`` [s].

    States and outputs in °C, inputs in the data's units (°C, W, W/m²); ``Q`` [K²], ``r`` [K].
    ``Γ1 = 0`` for a zero-order hold. ``m0`` [°C], ``P0`` [K²]: the initial state's mean and
    covariance.
    """

    dt: float
    hold: str
    Phi: np.ndarray
    G0: np.ndarray
    G1: np.ndarray
    Q: np.ndarray
    C: np.ndarray
    D: np.ndarray
    r: np.ndarray
    m0: np.ndarray
    P0: np.ndarray

    @property
    def R(self) -> np.ndarray:
        """Measurement-noise covariance ``diag(r²)`` [K²]."""
        return np.diag(self.r**2)

    def drive(self, u: np.ndarray) -> np.ndarray:
        """``Γ0 u_k + Γ1 (u_{k+1} − u_k)`` [K] for ``k = 0 … N−2`` of inputs ``u`` [N, m]."""
        u = np.asarray(u, float)
        return u[:-1] @ self.G0.T + (u[1:] - u[:-1]) @ self.G1.T


@dataclasses.dataclass(frozen=True, eq=False)
class FilterRun:
    """The Kalman filter over a dataset: filtered means ``m`` [N, n] [°C] and covariances
    ``P`` [N, n, n] [K²] after the update at each sample, with the inputs ``u`` [N, m] (missing
    ones filled) and the outputs ``y`` [N, p] the filter used (NaN where missing or in a long
    input gap). ``filled`` [N]: the rows with an input filled (``None``: none); ``reopened``:
    the rows where the filter reopened after a long input gap."""

    index: object
    m: np.ndarray
    P: np.ndarray
    u: np.ndarray
    y: np.ndarray
    system: DiscreteSystem
    filled: np.ndarray | None = None
    reopened: tuple[int, ...] = ()


@dataclasses.dataclass(frozen=True, eq=False)
class StochasticForm:
    """A fitted model as a stochastic state-space model.

    Attributes:
        model: the RC model.
        params: every physical and noise parameter (SI): ``sigma_<node>`` [K/√s],
            ``sigma_y_<output>`` [K].
        hold: ``"foh"`` or ``"zoh"``, the hold of the inputs in the fit.
        x0_std: standard deviation [K] of each initial state around ``T_*0``.
        source: ``"ml"`` (the noise of a maximum-likelihood fit) or ``"oe"`` (an output-error
            fit whose noise was estimated from its residuals).
        note: one sentence saying where the noise comes from.
        step: the sampling step [s] of the fit's data.
    """

    model: RCModel
    params: dict
    hold: str
    x0_std: tuple[float, ...]
    source: str
    note: str
    step: float

    def system(self, dt: float | None = None) -> DiscreteSystem:
        """The exact discrete model for the step ``dt`` [s] (default: the fit's step)."""
        dt = float(self.step if dt is None else dt)
        fn = _compiled.cached(
            ("stochastic", "system", self.model.structure, self.hold),
            lambda: jit(lambda th, dt: system(self.model, th, dt, self.hold)),
        )[0]
        theta = {k: jnp.asarray(v) for k, v in self.params.items()}
        (Phi, G0, G1, Q), C, D, r, m0, _ = jax.tree_util.tree_map(np.asarray, fn(theta, dt))
        P0 = np.diag(np.asarray(self.x0_std, float) ** 2)
        return DiscreteSystem(dt, self.hold, Phi, G0, G1, Q, C, D, r, m0, P0)

    def filter(
        self,
        data,
        *,
        x0: Mapping[str, float] | None = None,
        max_gap: float | str = DEFAULT_MAX_GAP,
    ) -> FilterRun:
        """The Kalman filter over ``data`` (regular samples, outputs may be NaN), starting from
        ``T_*0`` (or ``x0`` [°C] per state name) with covariance ``diag(x0_std²)``.

        Missing inputs are interpolated (:mod:`jaxbox.forecast._bridge`); after a gap longer
        than ``max_gap`` [s] (or ``"2h"``) the filter reopens: the outputs inside the gap are
        not used, and the state's covariance at its first sample after it is widened by
        ``diag(x0_std²)``. The run's ``filled`` and ``reopened`` say where.
        """
        data = as_data(data)
        model = self.model
        data.require(list(model.inputs) + list(model.outputs), what=f"model {model.name}")
        dt = regular_step(data)
        sysm = self.system(dt)
        u = np.asarray(data.array(list(model.inputs)), float)
        y = np.array(data.array(list(model.outputs)), dtype=float, copy=True)
        u, filled, long = bridge_inputs(u, model.inputs, data.index, dt, max_gap)
        for a, b in long:
            y[a:b] = np.nan  # their inputs are guesses: the filter does not update on them
        m0 = sysm.m0.copy()
        if x0 is not None:
            for i, s in enumerate(model.states):
                if s in x0:
                    m0[i] = float(x0[s])
        n = len(u)
        ms, Ps = [], []
        start, prior, cov = 0, m0, sysm.P0
        for stop in [b for _, b in long if b < n] + [n]:
            m, P = run_filter(sysm, prior, cov, u[start:stop], y[start:stop])
            ms.append(m)
            Ps.append(P)
            if stop < n:  # reopen: the prediction to `stop`, its covariance widened
                k = stop - 1
                prior = sysm.Phi @ m[-1] + sysm.G0 @ u[k] + sysm.G1 @ (u[k + 1] - u[k])
                cov = sysm.Phi @ P[-1] @ sysm.Phi.T + sysm.Q + sysm.P0
            start = stop
        reopened = tuple(b for _, b in long if b < n)
        return FilterRun(
            data.index,
            np.concatenate(ms),
            np.concatenate(Ps),
            u,
            y,
            sysm,
            filled=filled,
            reopened=reopened,
        )


def _filter_program(shapes):
    def run(Phi, G0, G1, Q, C, D, r, m0, P0, u, y):
        out = kalman_scan((Phi, G0, G1, Q), C, D, r, m0, P0, u, y, full=True)
        return out["m_filt"], out["P_filt"]

    return _compiled.cached(("forecast", "filter", shapes), lambda: jit(run))[0]


def run_filter(sysm: DiscreteSystem, m0, P0, u, y) -> tuple[np.ndarray, np.ndarray]:
    """Filtered means [N, n] and covariances [N, n, n] of :func:`~jaxbox.stochastic.kalman_scan`
    over inputs ``u`` [N, m] and outputs ``y`` [N, p] (NaN: missing). The series is padded at
    its end to a multiple of :data:`PAD` samples (outputs missing, the last input held), which
    leaves the first ``N`` results unchanged."""
    n_samples = len(u)
    total = -(-n_samples // PAD) * PAD
    up = np.concatenate([u, np.repeat(u[-1:], total - n_samples, axis=0)], axis=0)
    yp = np.concatenate([y, np.full((total - n_samples, y.shape[1]), np.nan)], axis=0)
    fn = _filter_program((sysm.Phi.shape, sysm.G0.shape, sysm.C.shape, total))
    m, P = fn(sysm.Phi, sysm.G0, sysm.G1, sysm.Q, sysm.C, sysm.D, sysm.r, m0, P0, up, yp)
    return np.asarray(m)[:n_samples], np.asarray(P)[:n_samples]


# ---- the stochastic form of a fit ---------------------------------------------------------------

#: output-error fits whose noise has been estimated, so that a second forecast reuses it
_OE_FORMS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def stochastic_form(result) -> StochasticForm:
    """The stochastic form of a fit: an :class:`~jaxbox.stochastic.MLResult` as it is; a
    :class:`~jaxbox.fit.FitResult` with its noise estimated from its residuals (see the module
    docstring; computed once per result). A :class:`StochasticForm` is returned unchanged."""
    if isinstance(result, StochasticForm):
        return result
    problem = getattr(result, "problem", None)
    if hasattr(problem, "hold") and hasattr(result, "nll"):  # a maximum-likelihood fit
        return StochasticForm(
            model=result.model,
            params=dict(result.params),
            hold=problem.hold,
            x0_std=tuple(float(v) for v in problem.x0_std),
            source="ml",
            note="noise parameters estimated by maximum likelihood with the physical ones",
            step=float(result.data.step),
        )
    if problem is not None and hasattr(result, "cost") and hasattr(result, "starts"):
        form = _OE_FORMS.get(result)
        if form is None:
            form = _oe_form(result)
            _OE_FORMS[result] = form
        return form
    raise TypeError(
        "expected a fit: a FitResult (jaxbox.fit_model), an MLResult (method='ml') or a "
        f"StochasticForm; got {type(result).__name__}"
    )


def _first_segment(data):
    a, b = data.segments[0]
    if len(data.segments) == 1:
        return data
    return data.slice(data.index[a], data.index[b - 1])


def _noise_program(model: RCModel, hold: str, names: tuple[str, ...], shapes):
    key = ("forecast", "noise", model.structure, hold, names, shapes)

    def build():
        def nll(z, phys, x0_std, dt, u, y):
            theta = dict(phys)
            theta.update({n: jnp.exp(z[i]) for i, n in enumerate(names)})
            mats, C, D, r, m0, P0 = system(model, theta, dt, hold, x0_std)
            return kalman_scan(mats, C, D, r, m0, P0, u, y)

        return jit(jax.value_and_grad(nll))

    return _compiled.cached(key, build)[0]


def _oe_form(result) -> StochasticForm:
    """Noise of an output-error fit from its residuals on its identification data."""
    form = noise_from_residuals(result.model, result.params, _first_segment(result.data))
    return dataclasses.replace(form, step=float(result.data.step))


#: the fewest samples the noise of an output-error fit is estimated from
NOISE_MIN_SAMPLES = 24


def noise_from_residuals(
    model: RCModel,
    params: Mapping[str, float],
    data,
    *,
    max_gap: float | str = DEFAULT_MAX_GAP,
) -> StochasticForm:
    """The stochastic form of a model whose physical parameters ``params`` (SI) were estimated
    by output error: the diffusions and measurement noises that maximise the Kalman filter's
    likelihood of ``data`` (one regular series starting at the fit's initial state ``T_*0``)
    with the physical parameters held (L-BFGS-B in the logarithms of the noise parameters,
    within their bounds, from three starts).

    Input gaps of at most ``max_gap`` [s] (or ``"2h"``) are interpolated; the likelihood is
    taken up to the first longer one (after it where the series begins with one), which must
    leave :data:`NOISE_MIN_SAMPLES` samples."""
    import scipy.optimize

    data = as_data(data)
    data.require(list(model.inputs) + list(model.outputs), what=f"model {model.name}")
    dt = regular_step(data)
    u = np.asarray(data.array(list(model.inputs)), float)
    y = np.asarray(data.array(list(model.outputs)), float)
    u, _, long = bridge_inputs(u, model.inputs, data.index, dt, max_gap)
    a = long[0][1] if long and long[0][0] == 0 else 0
    b = next((g for g, _ in long if g > a), len(u))
    if b - a < NOISE_MIN_SAMPLES:
        gaps = ", ".join(f"{data.index[g]} to {data.index[h - 1]}" for g, h in long[:3])
        raise FitError(
            f"the noise of the stochastic form is estimated by the Kalman filter over the data "
            f"up to their first input gap longer than max_gap ({gaps}), which leaves {b - a} "
            f"samples, fewer than {NOISE_MIN_SAMPLES}: fill the gap, give a larger max_gap "
            "(command line --max-gap), or data that start after it"
        )
    u, y = u[a:b], y[a:b]
    missing = [n for n in model.param_names if n not in params]
    if missing:
        raise FitError(
            f"parameters of {model.name} missing: {', '.join(missing)} (was it fitted with "
            "another model?)"
        )
    phys = {n: float(params[n]) for n in model.param_names}
    names = tuple(n for n in diffusion_names(model) if n) + measurement_names(model)
    n_diff = len(names) - len(model.outputs)
    x0 = x0_stds(model, None, OE_X0_STD)
    fn = _noise_program(model, "foh", names, (u.shape, y.shape))
    args = (
        {k: jnp.asarray(v) for k, v in phys.items()},
        jnp.asarray(x0),
        dt,
        jnp.asarray(u),
        jnp.asarray(y),
    )
    sim = _open_loop_rms(model, phys, dt, u, y)
    rms = max(sim, 1e-4)
    lo = np.log([SIGMA_BOUNDS[0]] * n_diff + [SIGMA_Y_BOUNDS[0]] * len(model.outputs))
    hi = np.log([SIGMA_BOUNDS[1]] * n_diff + [SIGMA_Y_BOUNDS[1]] * len(model.outputs))

    def fun(z):
        v, g = fn(jnp.asarray(z), *args)
        v, g = float(v), np.asarray(g, float)
        if not np.isfinite(v) or not np.all(np.isfinite(g)):
            return 1e30, np.zeros_like(g)
        return v, g

    best = None
    # starts: a quiet, a moderate and a noisy process, the measurement noise near the residuals
    for level, share in ((1e-5, 0.9), (1e-4, 0.5), (1e-3, 0.2)):
        z0 = np.log([level] * n_diff + [max(share * rms, 2e-4)] * len(model.outputs))
        z0 = np.clip(z0, lo, hi)
        opt = scipy.optimize.minimize(
            fun, z0, jac=True, method="L-BFGS-B", bounds=list(zip(lo, hi, strict=True))
        )
        if best is None or opt.fun < best.fun:
            best = opt
    if best is None or not np.isfinite(best.fun) or best.fun >= 1e30:
        raise FitError(
            f"the noise of {model.name}'s stochastic form could not be estimated from the "
            "output-error residuals (the Kalman filter's likelihood is not finite)"
        )
    params = dict(phys)
    params.update({n: float(np.exp(best.x[i])) for i, n in enumerate(names)})
    for n in noise_names(model):
        params.setdefault(n, 0.0)
    return StochasticForm(
        model=model,
        params={n: params[n] for n in model.param_names + noise_names(model)},
        hold="foh",
        x0_std=x0,
        source="oe",
        note=(
            "output-error fit: noise estimated from its residuals (maximum likelihood of the "
            "diffusions and measurement noise with the physical parameters held)"
        ),
        step=dt,
    )


def _open_loop_rms(model: RCModel, phys: dict, dt: float, u, y) -> float:
    """RMS [K] of the open-loop simulation's output errors (the starts' noise level)."""
    from ..simulate._exact import discretize_foh_numpy

    A, B, C, D = model.state_space_numpy(phys)
    Phi, G0, G1 = discretize_foh_numpy(A, B, dt)
    x = np.asarray([phys[node.T0] for node in model.network.nodes], float)
    drive = u[:-1] @ G0.T + (u[1:] - u[:-1]) @ G1.T
    xs = [x]
    for d in drive:
        x = Phi @ x + d
        xs.append(x)
    e = y - (np.asarray(xs) @ C.T + u @ D.T)
    return float(np.sqrt(np.nanmean(e**2)))
