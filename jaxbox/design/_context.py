"""A design problem with its data: prior samples, weather, step, noise; and what a schedule
predicts (standard deviations of every parameter and of the HLC, comfort, energy)."""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from .._compiled import cached, jit
from ..data import DataError, Dataset
from ..models import ModelError
from ._fisher import CRITERIA, Setup
from ._prior import Prior

__all__ = ["Context", "make_context", "default_weather", "weather_arrays"]


def default_weather(step: float) -> Dataset:
    """The bundled twin-house weather (house N2, from 2013-08-21) at ``step`` [s]."""
    from ..datasets import twinhouse_exp1

    if step >= 3600 and step % 3600 == 0:
        data = twinhouse_exp1("N2", "1h")
        return data if step == 3600 else data.resample(pd.Timedelta(seconds=step))
    if step % 600 == 0:
        data = twinhouse_exp1("N2", "10min")
        return data if step == 600 else data.resample(pd.Timedelta(seconds=step))
    raise DataError(
        f"the bundled weather comes every 10 min and 1 h; a step of {step:g} s needs your own "
        "weather (a multiple of 600 s otherwise)"
    )


def weather_arrays(weather: Dataset, names, n: int, step: float):
    """The first ``n`` samples of the weather inputs ``names`` [n, len(names)] and their times."""
    if not isinstance(weather, Dataset):
        raise TypeError(
            f"weather must be a jaxbox Dataset, got {type(weather).__name__}; load it with "
            "jaxbox.data.load (a file or a DataFrame)"
        )
    if abs(weather.step - step) > 1e-6 * step:
        if step > weather.step and abs(step / weather.step - round(step / weather.step)) < 1e-9:
            weather = weather.resample(pd.Timedelta(seconds=step))
        else:
            raise DataError(
                f"the weather comes every {weather.step:g} s, the schedule every {step:g} s; give "
                "weather at the schedule's step (or a step that divides it)"
            )
    weather.require(list(names), what="the design's weather")
    if len(weather) < n:
        raise DataError(
            f"the weather has {len(weather)} samples of {step:g} s, the horizon needs {n}; give "
            "a longer weather file or a shorter horizon"
        )
    values = weather.array(list(names))[:n] if names else np.zeros((n, 0))
    _check_gaps(values, names, weather.index[:n])
    return values, weather.index[:n]


def _check_gaps(values: np.ndarray, names, index: pd.DatetimeIndex) -> None:
    """Refuse missing weather [n, len(names)] within the horizon, naming the column and when."""
    for j, name in enumerate(names):
        missing = np.flatnonzero(~np.isfinite(values[:, j]))
        if len(missing):
            raise DataError(
                f"the weather column {name!r} has {len(missing)} missing value(s) within the "
                f"horizon, the first at {index[missing[0]]}; fill them (e.g. "
                "DataFrame.interpolate) or give weather without gaps"
            )


@dataclasses.dataclass(frozen=True, eq=False)
class Context:
    """A design problem with its data.

    Attributes:
        setup: the static side (:class:`~jaxbox.design._fisher.Setup`).
        fixed: values [SI] of the parameters that are not estimated.
        phis: design coordinates of the free parameters per prior sample [S, p]; row 0 is the
            nominal prior, the initial states are the preconditioned start.
        inputs: every model input over the horizon [N, m], the heating column zero.
        index: the time stamps of the schedule.
        step: the sample step [s].
        sigma: the output noise standard deviation [K].
        linear: per prior sample, what does not depend on the inputs
            (:meth:`~jaxbox.design._fisher.Setup.linearise`): ``(mats, tangents, c, hlc)``.
    """

    setup: Setup
    fixed: dict
    phis: np.ndarray
    inputs: np.ndarray
    index: pd.DatetimeIndex
    step: float
    sigma: float
    linear: tuple

    @property
    def n(self) -> int:
        return self.inputs.shape[0]

    def theta(self, sample: int = 0) -> dict[str, float]:
        """Parameter values [SI] of a prior sample (the nominal one by default)."""
        th = self.setup.theta(jnp.asarray(self.phis[sample]), self.fixed)
        return {k: float(v) for k, v in th.items()}

    def args(self):
        """``(mats, tangents, c, inputs, sigma)`` as JAX arrays: the data of the compiled
        functions."""
        mats, tangents, c, _ = self.linear
        return (
            mats,
            tangents,
            c,
            jnp.asarray(self.inputs),
            jnp.asarray(self.sigma, dtype=float),
        )

    def report(self, power) -> dict:
        """What the schedule ``power`` [W] per sample predicts, at the nominal prior.

        Returns a dict: ``loss`` (every criterion, see :mod:`~jaxbox.design._fisher`; robust
        designs average it over the prior samples), ``std`` and ``rel_std`` of every free
        parameter [SI and fraction], ``hlc`` [W/K] and ``hlc_std`` [W/K], ``energy_kwh``,
        ``mean_power`` [W], ``t_min``/``t_max`` of the predicted outputs [°C], the outputs, and
        ``unidentifiable``: the free parameters the schedule leaves unidentifiable (its Fisher
        information is singular along them, at the nominal prior). Their standard deviations
        are ``inf``, and so is every criterion they enter (for every prior sample where that
        holds): a singular design is never silently NaN, nor compared as a finite one.
        """
        power = np.asarray(power, dtype=float)
        if power.shape != (self.n,):
            raise ValueError(f"a schedule of {self.n} samples is needed, got shape {power.shape}")
        bad = np.flatnonzero(~np.isfinite(power))
        if len(bad):
            raise ModelError(
                f"the power has {len(bad)} non-finite value(s) (NaN or inf), the first at sample "
                f"{bad[0]}; give a finite heating power [W] for every sample"
            )
        fn = _report_fn(self.setup)
        losses, Fs, y = fn(*self.args(), jnp.asarray(power))
        losses, Fs, y = np.array(losses), np.asarray(Fs), np.asarray(y)
        if not (np.all(np.isfinite(Fs)) and np.all(np.isfinite(y))):
            raise ModelError(
                f"the predicted outputs of {self.setup.model.name} are not finite for this "
                "schedule; check the prior values, the power and the weather"
            )
        c_all = np.asarray(self.linear[2])
        inverses = [_Inverse.of(F) for F in Fs]
        for s, inv in enumerate(inverses):  # the criteria of a singular sample, exactly
            if inv.singular:
                losses[s] = [inv.criterion(k, self.setup.interest, c_all[s]) for k in CRITERIA]
        inv, c, hlc = inverses[0], c_all[0], float(self.linear[3][0])
        th = self.theta(0)
        std, rel = {}, {}
        for i, (name, lg) in enumerate(zip(self.setup.free, self.setup.log, strict=True)):
            sd = float(np.sqrt(inv.variance(np.eye(len(self.setup.free))[i])))
            std[name] = float(th[name] * sd) if lg else sd
            rel[name] = sd if lg else float(sd / abs(th[name]) if th[name] else np.inf)
        return {
            "loss": {k: float(v) for k, v in zip(CRITERIA, losses.mean(axis=0), strict=True)},
            "std": std,
            "rel_std": rel,
            "hlc": float(hlc),
            "hlc_std": float(hlc) * float(np.sqrt(inv.variance(c))),
            "unidentifiable": [n for n, u in zip(self.setup.free, inv.unseen, strict=True) if u],
            "energy_kwh": float(np.sum(power) * self.step / 3.6e6),
            "mean_power": float(np.mean(power)),
            "t_min": float(np.min(y)),
            "t_max": float(np.max(y)),
            "outputs": y,
        }


#: eigenvalues of the Jacobi-scaled Fisher information (unit diagonal) below this fraction of
#: the largest are taken as zero: directions of the parameters that the outputs do not see
_RCOND = 1e-10
#: a linear function of the parameters whose (scaled) weight along such a direction exceeds
#: this fraction of its norm has an infinite variance
_NULL_WEIGHT = 1e-3


@dataclasses.dataclass(frozen=True)
class _Inverse:
    """The covariance ``F⁻¹`` of the design coordinates from a Fisher information that may be
    singular: on the directions the outputs see, the pseudo-inverse; along the others, an
    infinite variance.

    Attributes:
        d: ``√F_ii`` of the parameters the outputs see, 0 for the others [p].
        pinv: pseudo-inverse of the Jacobi-scaled information ``F_ij / (d_i d_j)`` [p, p].
        null: the directions it does not see, in scaled coordinates [p, k].
        unseen: per parameter, True when its variance is infinite.
    """

    d: np.ndarray
    pinv: np.ndarray
    null: np.ndarray
    unseen: np.ndarray

    @property
    def singular(self) -> bool:
        return bool(self.unseen.any() or self.null.shape[1])

    @classmethod
    def of(cls, F: np.ndarray) -> _Inverse:
        F = 0.5 * (F + F.T)
        p = F.shape[0]
        diag = np.diag(F)
        seen = diag > 1e-20 * max(float(diag.max()), 0.0)
        d = np.where(seen, np.sqrt(np.where(seen, diag, 1.0)), 0.0)
        ix = np.flatnonzero(seen)
        pinv, null = np.zeros((p, p)), np.zeros((p, 0))
        if len(ix):
            lam, V = np.linalg.eigh(F[np.ix_(ix, ix)] / np.outer(d[ix], d[ix]))
            zero = lam <= _RCOND * lam.max()
            W = V[:, ~zero]
            pinv[np.ix_(ix, ix)] = (W / lam[~zero]) @ W.T
            null = np.zeros((p, int(zero.sum())))
            null[ix] = V[:, zero]
        unseen = ~seen | (np.abs(null) > _NULL_WEIGHT).any(axis=1)
        return cls(d=d, pinv=pinv, null=null, unseen=unseen)

    def variance(self, w) -> float:
        """Variance of ``wᵀφ`` (w [p] in design coordinates): ``inf`` when the information
        does not see it."""
        w = np.asarray(w, dtype=float)
        if np.any((self.d == 0) & (w != 0)):
            return math.inf
        ws = np.divide(w, self.d, out=np.zeros_like(w), where=self.d > 0)
        norm = float(np.linalg.norm(ws))
        if norm == 0.0:
            return 0.0
        if np.any(np.abs(ws @ self.null) > _NULL_WEIGHT * norm):
            return math.inf
        return max(float(ws @ self.pinv @ ws), 0.0)

    def criterion(self, name: str, interest, c) -> float:
        """A design loss as :meth:`~jaxbox.design._fisher.Setup.criterion` computes it, ``inf``
        where the information does not see what it measures."""
        if name == "hlc":
            var = self.variance(c)
            return math.log(var) if var > 0 else -math.inf
        idx = np.asarray(interest)
        if self.unseen[idx].any():
            return math.inf
        s = np.divide(1.0, self.d[idx], out=np.zeros(len(idx)), where=self.d[idx] > 0)
        sub = self.pinv[np.ix_(idx, idx)] * np.outer(s, s)
        if name == "D":
            return float(np.linalg.slogdet(sub)[1])
        return math.log(float(np.trace(sub)))


def _report_fn(setup: Setup):
    def build():
        def fn(mats, tangents, c, U0, sigma, power):
            U = U0.at[:, setup.heat_index].set(power)
            F = setup.information(mats, tangents, U, sigma)
            losses = jax.vmap(
                lambda f, cc: jnp.stack([setup.criterion(k, f, cc) for k in CRITERIA])
            )(F, c)
            nominal = jax.tree_util.tree_map(lambda a: a[0], mats)
            return losses, F, setup.simulate(nominal, U)

        return jit(fn)

    return cached(("design", "report", setup.key), build)[0]


def _linearise_fn(setup: Setup):
    return cached(("design", "linearise", setup.key), lambda: jit(setup.linearise))[0]


def _precondition_fn(setup: Setup):
    """x0 of the nominal sample: steady state under the mean weather of the first day, with the
    constant heating that holds the zone at the start temperature."""

    def build():
        def fn(phi, fixed, u_mean, t_start):
            th = setup.theta(phi, fixed)
            e = jnp.zeros_like(u_mean).at[setup.heat_index].set(1.0)
            xa = setup.steady_state(th, u_mean)
            gain = setup.steady_state(th, u_mean + e) - xa
            s = setup.output_states[setup.hlc_output]
            q = (t_start - xa[s]) / gain[s]
            return xa + q * gain, q

        return jit(fn)

    return cached(("design", "precondition", setup.key), build)[0]


def make_context(
    prior: Prior,
    setup: Setup,
    weather: Dataset,
    n: int,
    step: float,
    sigma: float,
    start_temperature: float,
    log_samples: np.ndarray | None = None,
    sample_names: tuple[str, ...] = (),
) -> Context:
    """Assemble a :class:`Context`: weather over ``n`` samples, the initial state of every
    prior sample preconditioned at ``start_temperature`` [°C]."""
    model = setup.model
    w, index = weather_arrays(weather, setup.weather_inputs, n, step)
    U0 = np.zeros((n, len(model.inputs)))
    for j, name in enumerate(setup.weather_inputs):
        U0[:, model.inputs.index(name)] = w[:, j]
    fixed = {k: float(v) for k, v in prior.theta.items() if k not in setup.free}
    base = dict(prior.theta)
    samples = [base]
    if log_samples is not None:
        samples = []
        for row in log_samples:
            th = dict(base)
            th.update({k: float(np.exp(v)) for k, v in zip(sample_names, row, strict=True)})
            samples.append(th)
    per_day = max(1, int(round(86400 / step)))
    u_mean = jnp.asarray(U0[: min(n, per_day)].mean(axis=0))
    pre = _precondition_fn(setup)
    nodes = model.network.nodes
    phis = []
    for th in samples:
        phi = setup.to_coords(th)
        x0, _ = pre(jnp.asarray(phi), fixed, u_mean, jnp.asarray(float(start_temperature)))
        x0 = np.asarray(x0)
        if not np.all(np.isfinite(x0)):
            raise ModelError(
                f"the steady state of {model.name} at the prior parameters is not finite; check "
                "the prior values (resistances and capacities > 0)"
            )
        for i, node in enumerate(nodes):
            if not node.constant and node.T0 in setup.free:
                phi[setup.free.index(node.T0)] = x0[i]
            elif not node.constant and not phis:  # a fixed initial state: the nominal start
                fixed[node.T0] = float(x0[i])
        phis.append(phi)
    phis = np.asarray(phis)
    jfixed = {k: jnp.asarray(v, dtype=float) for k, v in fixed.items()}
    linear = _linearise_fn(setup)(jnp.asarray(phis), jfixed, jnp.asarray(float(step)))
    if not all(bool(jnp.all(jnp.isfinite(a))) for a in jax.tree_util.tree_leaves(linear)):
        raise ModelError(
            f"the discrete matrices of {model.name} at the prior parameters are not finite; "
            "check the prior values"
        )
    return Context(
        setup=setup,
        fixed=fixed,
        phis=phis,
        inputs=U0,
        index=index,
        step=float(step),
        sigma=float(sigma),
        linear=linear,
    )
