"""The result of a maximum-likelihood fit: estimates, intervals, information criteria."""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import stats

from ..fit._result import StartReport
from ..fit._uses import ModelUses
from ._checks import as_data
from ._problem import StochasticProblem

__all__ = ["MLResult", "likelihood_ratio_test"]


def _covariance(H: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``H⁻¹`` through the Hessian scaled by the parameter magnitudes (capacities of 1e7 J/K and
    resistances of 1e-2 K/W side by side); NaN when it is not positive definite."""
    s = np.where(np.abs(p) > 0, np.abs(p), 1.0)
    Hs = H * s[:, None] * s[None, :]
    Hs = 0.5 * (Hs + Hs.T)
    try:
        L = np.linalg.cholesky(Hs)
    except np.linalg.LinAlgError:
        return np.full_like(H, np.nan)
    Li = np.linalg.inv(L)
    return (Li.T @ Li) * s[:, None] * s[None, :]


@dataclasses.dataclass(frozen=True, eq=False)
class MLResult(ModelUses):
    """A maximum-likelihood (or MAP) estimate of a stochastic grey-box model.

    Attributes:
        problem: the :class:`StochasticProblem`.
        data: the identification dataset.
        params: every parameter (SI): physical, then noise (``sigma_*`` [K/√s],
            ``sigma_y_*`` [K]).
        nll: negative log-likelihood at the estimate (natural log, with the 2π constant).
        objective: NLL plus the negative log prior (equals ``nll`` without priors).
        n_obs: number of observed output values.
        gradient, hessian: of the objective in the physical free parameters, at the estimate.
        cov: covariance of the free estimates, ``hessian⁻¹`` (NaN if not positive definite).
        converged, best, starts: as :class:`jaxbox.fit.FitResult` (``starts.cost`` holds the
            objective per observation).
        timing: ``compile_s``, ``fit_s``, ``hessian_s`` [s]; settings: the solver settings.
    """

    problem: StochasticProblem
    data: object
    arrays: tuple
    params: dict
    nll: float
    objective: float
    n_obs: int
    gradient: np.ndarray
    hessian: np.ndarray
    cov: np.ndarray
    converged: bool
    best: int
    starts: StartReport
    timing: dict
    settings: dict

    @classmethod
    def build(
        cls,
        *,
        problem,
        data,
        arrays,
        p_free,
        nll,
        objective,
        grad,
        hessian,
        starts,
        best,
        timing,
        settings,
    ) -> MLResult:
        params = dict(problem.fixed)
        params.update({n: float(v) for n, v in zip(problem.free, p_free, strict=True)})
        params = {n: float(params[n]) for n in problem.param_names}
        y = arrays[2]
        return cls(
            problem=problem,
            data=data,
            arrays=arrays,
            params=params,
            nll=float(nll),
            objective=float(objective),
            n_obs=int(np.isfinite(y).sum()),
            gradient=grad,
            hessian=hessian,
            cov=_covariance(hessian, np.asarray(p_free, dtype=float)),
            converged=starts.status[best] == "converged",
            best=best,
            starts=starts,
            timing=dict(timing),
            settings=dict(settings),
        )

    # ---- basic views -----------------------------------------------------------------------
    @property
    def model(self):
        return self.problem.model

    def n_at_best(self, rtol: float = 1e-6) -> int:
        """Usable starts whose objective is within ``rtol · max(1, |best|)`` of the best (the
        objective per observation, which may be negative)."""
        best = self.starts.cost[self.best]
        tol = rtol * max(1.0, abs(best))
        return int(np.sum(self.starts.usable & (self.starts.cost <= best + tol)))

    @property
    def free(self) -> tuple[str, ...]:
        return self.problem.free

    @property
    def method(self) -> str:
        return self.settings.get("method", "ml")

    @property
    def n_free(self) -> int:
        return len(self.free)

    @property
    def loglik(self) -> float:
        """Log-likelihood (natural log, with the 2π constant)."""
        return -self.nll

    @property
    def aic(self) -> float:
        return 2.0 * self.n_free + 2.0 * self.nll

    @property
    def bic(self) -> float:
        return self.n_free * float(np.log(self.n_obs)) + 2.0 * self.nll

    @property
    def dof(self) -> int:
        """Degrees of freedom of the t-statistics: observations minus free parameters."""
        return max(1, self.n_obs - self.n_free)

    @property
    def sd(self) -> dict[str, float]:
        """Standard deviation of each free estimate (SI), from the exact Hessian."""
        d = np.sqrt(np.diag(self.cov))
        return {n: float(v) for n, v in zip(self.free, d, strict=True)}

    @property
    def correlation(self) -> np.ndarray:
        """Correlation matrix of the free estimates (``free`` order)."""
        d = np.sqrt(np.diag(self.cov))
        return self.cov / d[:, None] / d[None, :]

    def tstat(self) -> dict[str, float]:
        """Estimate over its standard deviation."""
        sd = self.sd
        return {n: self.params[n] / sd[n] for n in self.free}

    def pvalue(self) -> dict[str, float]:
        """Two-sided p-value of ``parameter = 0`` (t distribution, :attr:`dof`)."""
        return {n: float(2 * stats.t.sf(abs(t), self.dof)) for n, t in self.tstat().items()}

    def intervals(self, level: float = 0.95) -> dict[str, tuple[float, float]]:
        """``level`` confidence interval of each free estimate: ``θ ± t_{(1+level)/2} sd``."""
        if not 0 < level < 1:
            raise ValueError(f"level must be in (0, 1) (e.g. 0.95), got {level}")
        q = stats.t.ppf(0.5 + level / 2, self.dof)
        sd = self.sd
        return {n: (self.params[n] - q * sd[n], self.params[n] + q * sd[n]) for n in self.free}

    def params_table(self) -> dict[str, dict]:
        """Per parameter: value, unit, free, sd, t, p, 95 % interval, bounds, at_bound."""
        sd, t, pv, ci = self.sd, self.tstat(), self.pvalue(), self.intervals()
        pos = self.problem.transform.relative_position(
            np.asarray([self.params[n] for n in self.free])
        )
        at = {
            n: bool(np.isfinite(x) and (x < 1e-3 or x > 1 - 1e-3))
            for n, x in zip(self.free, pos, strict=True)
        }
        bounds = self.problem.bounds
        table = {}
        for n in self.problem.param_names:
            spec = self.problem.spec(n)
            free = n in self.free
            lo, hi = bounds.get(n, (spec.lower, spec.upper))
            table[n] = {
                "value": self.params[n],
                "unit": spec.unit,
                "free": free,
                "sd": sd.get(n, float("nan")) if free else 0.0,
                "t": t.get(n, float("nan")),
                "p": pv.get(n, float("nan")),
                "ci95": list(ci[n]) if free else [self.params[n], self.params[n]],
                "lower": lo,
                "upper": hi,
                "at_bound": at.get(n, False),
            }
        return table

    def summary(self) -> str:
        lines = [
            f"model {self.model.name} ({self.method.upper()}, Kalman filter): {self.n_free} free "
            f"parameters, {self.n_obs} observations "
            f"({'converged' if self.converged else 'NOT converged'})",
            f"log-likelihood {self.loglik:.3f}, AIC {self.aic:.2f}, BIC {self.bic:.2f}",
            f"starts: {self.starts.n} ({self.starts.status_summary()}), "
            f"{self.n_at_best()} reached the best",
            f"{'parameter':<14} {'value':>12} {'sd':>10} {'t':>8} {'p':>9} {'unit':<5} note",
        ]
        for n, row in self.params_table().items():
            note = "fixed" if not row["free"] else ("AT BOUND" if row["at_bound"] else "")
            lines.append(
                f"{n:<14} {row['value']:>12.5g} {row['sd']:>10.3g} {row['t']:>8.2f} "
                f"{row['p']:>9.2g} {row['unit']:<5} {note}"
            )
        return "\n".join(lines)

    # ---- states and validation ---------------------------------------------------------------
    def states(self, data=None):
        """Filtered and smoothed states over ``data`` (default: the identification data)."""
        from ._states import estimate_states

        return estimate_states(
            self.model,
            self.params,
            self.data if data is None else data,
            hold=self.problem.hold,
            x0_std=dict(zip(self.model.states, self.problem.x0_std, strict=True)),
        )

    def innovation_tests(self, data=None, alpha: float = 0.05):
        """Whiteness of the standardised one-step innovations: autocorrelation, Ljung–Box,
        cumulated periodogram (:func:`jaxbox.validate.analyse_residuals`)."""
        return innovation_tests(self.states(data), alpha=alpha)

    def k_step_errors(self, k=(1, 2, 4, 8), data=None) -> dict:
        """k-step-ahead prediction errors with filtering (see :func:`k_step_errors`)."""
        return self.states(data).k_step_errors(k)

    def simulation_rmse(self, data=None) -> dict[str, float]:
        """Open-loop simulation RMSE [K] per output (no filtering), comparable to output error."""
        from ..simulate import simulate_model

        data = self.data if data is None else as_data(data)
        phys = {n: self.params[n] for n in self.model.param_names}
        sim = simulate_model(self.model, phys, data)
        e = data.array(list(self.model.outputs)) - sim.y
        return {
            o: float(np.sqrt(np.nanmean(e[:, j] ** 2))) for j, o in enumerate(self.model.outputs)
        }

    def to_dict(self) -> dict:
        """JSON-ready: method, params (with noise), loglik, aic, bic, intervals, correlation."""
        return {
            "method": self.method,
            "model": self.model.name,
            "params": dict(self.params),
            "table": self.params_table(),
            "loglik": self.loglik,
            "aic": self.aic,
            "bic": self.bic,
            "n_obs": self.n_obs,
            "n_free": self.n_free,
            "converged": self.converged,
            "hold": self.problem.hold,
            "x0_std": list(self.problem.x0_std),
            "correlation": {"names": list(self.free), "matrix": self.correlation.tolist()},
            "starts": {
                "n": self.starts.n,
                "status": self.starts.status_summary(),
                "at_best": self.n_at_best(),
            },
            "timing": dict(self.timing),
        }

    def __repr__(self) -> str:
        return (
            f"MLResult(model={self.model.name!r}, loglik={self.loglik:.6g}, "
            f"converged={self.converged}, starts={self.starts.n})"
        )


def innovation_tests(est, alpha: float = 0.05):
    """Residual analysis (:func:`jaxbox.validate.analyse_residuals`) of the standardised
    innovations of a :class:`StateEstimate`, missing samples left out, with the inputs."""
    from ..validate._residuals import analyse_residuals

    if not 0 < alpha < 1:
        raise ValueError(f"alpha must be in (0, 1) (e.g. 0.05), got {alpha}")
    e = est.standardized_innovations
    keep = np.all(np.isfinite(e), axis=1)
    return analyse_residuals(
        e[keep],
        est.inputs[keep],
        output_names=est.outputs,
        input_names=est.model.inputs,
        alpha=alpha,
    )


def likelihood_ratio_test(small: MLResult, large: MLResult) -> dict:
    """Likelihood-ratio test of a model ``small`` nested in ``large`` (same data).

    ``2 (ℓ_large − ℓ_small)`` is χ² with ``k_large − k_small`` degrees of freedom when the
    extra parameters of ``large`` are not needed. Returns ``statistic``, ``df``, ``pvalue``
    (small ``pvalue``: the larger model is significantly better).
    """
    for name, fit in (("small", small), ("large", large)):
        if not isinstance(fit, MLResult):
            raise TypeError(
                f"{name} must be an MLResult (a fit_ml result), got {type(fit).__name__}"
            )
    if small.n_obs != large.n_obs:
        raise ValueError(
            f"the two fits use {small.n_obs} and {large.n_obs} observations; a likelihood-ratio "
            "test compares fits of the same data"
        )
    df = large.n_free - small.n_free
    if df < 1:
        raise ValueError(
            f"{large.model.name} has {large.n_free} free parameters, not more than "
            f"{small.model.name} ({small.n_free}); pass the nested (smaller) model first"
        )
    stat = 2.0 * (large.loglik - small.loglik)
    return {
        "small": small.model.name,
        "large": large.model.name,
        "statistic": float(stat),
        "df": int(df),
        "pvalue": float(stats.chi2.sf(max(stat, 0.0), df)),
    }
