"""The parameter covariance under autocorrelated output errors (HAC), for the KPI intervals.

The delta-method interval of :func:`~jaxbox.validate.kpis` rests on the covariance
``σ̂² (JᵀJ)⁻¹`` of :func:`~jaxbox.validate.uncertainty`, which assumes white output errors and
the right structure. The output errors of a grey-box model are seldom white: what the structure
misses shows up as slow, strongly autocorrelated residuals, and the white covariance then
understates the uncertainty several times over. :func:`robust_covariance` takes the sandwich

    ``cov(θ̂) = B Ω B``,    ``B = (JᵀJ)⁺``,    ``Ω = Σ_l k(l/b) Γ_l``,

with ``s_t = Σ_j J_tj e_tj`` the score of sample t (weighted sensitivities times weighted
errors, summed over the outputs), ``Γ_l = Σ_t s_t s_{t−l}ᵀ`` (``Γ_{−l} = Γ_lᵀ``), the
Bartlett kernel ``k(x) = 1 − |x|`` and the bandwidth ``b`` chosen from the data (Andrews 1991,
AR(1) plug-in). Because output-error residuals are so persistent, the scores are prewhitened
first (Andrews & Monahan 1992): each score series is filtered by its own AR(1) coefficient
``ρ_k`` (at most :data:`MAX_RHO`), ``s̃_t = s_t − R s_{t−1}``, the kernel estimate is taken of
``s̃`` and recoloured, ``Ω = (I − R)⁻¹ Ω̃ (I − R)⁻¹``. A factor ``N/(N − p)`` corrects for the
fitted parameters. With white residuals ``R ≈ 0``, ``b`` is small and the sandwich is the
white covariance to sampling error; ``B`` is the pseudo-inverse the white covariance uses, so
a direction the data do not determine stays without a standard error.

Residuals of finely sampled data are white noise (the sensor's, its quantisation) on top of
the slow error of the structure. At the sample's own scale the noise dominates the lag-one
correlation, the AR(1) prewhitening models the fast part, and the kernel, a few samples
wide, misses the slow one: on the same building the interval came out four times narrower
from 10-minute data than from their hourly means, for the same HLC. So the long-run
covariance is also estimated from the scores summed over blocks of 2, 4, 8 … samples (the
blocking of Flyvbjerg & Petersen 1989; a sum over a block is the block's contribution to
``Ω``, whatever the correlation inside it), the same prewhitened kernel estimate over the
block sums, while at least :data:`MIN_BLOCKS` (and four per parameter) remain; the level with
the largest standard errors (median over the parameters) is taken. Where the level of the
samples already holds the correlation, the coarser levels agree with it to their sampling
error.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = [
    "RobustCovariance",
    "robust_covariance",
    "MAX_RHO",
    "MIN_BLOCKS",
    "WHITE",
    "HAC",
    "HIGH_LAG1",
]

#: the largest AR(1) coefficient of the prewhitening (above it the recolouring factor
#: ``1/(1 − ρ)`` explodes on a short record)
MAX_RHO = 0.97
#: method names of the intervals
WHITE = "delta (white residuals)"
HAC = "delta (HAC: prewhitened Newey-West, at least the white)"
#: lag-1 autocorrelation of the residuals above which they are not called white
HIGH_LAG1 = 0.5
#: the fewest blocks of summed scores a blocking level keeps (and at least four per parameter)
MIN_BLOCKS = 48


@dataclasses.dataclass(frozen=True, eq=False)
class RobustCovariance:
    """The parameter covariance under autocorrelated output errors (HAC sandwich).

    Attributes:
        free: the free parameters (rows and columns of ``cov_free``).
        cov_free: the covariance [SI²]; ``nan`` where the white one has none.
        bandwidth: the Bartlett bandwidth ``b`` [samples] of the prewhitened scores (of the
            chosen blocking level: in samples, the bandwidth in blocks times ``block``).
        rho: the prewhitening AR(1) coefficient of each score series (after capping), at the
            chosen blocking level.
        lag1: the lag-1 autocorrelation of the residuals (pooled over the outputs).
        ljung_box_p: the smallest Ljung–Box p-value over the outputs' residuals.
        inflation: median over the parameters of the ratio of HAC to white standard errors.
        block: the samples summed per block at the chosen blocking level (1: the samples).
    """

    free: tuple[str, ...]
    cov_free: np.ndarray
    bandwidth: float
    rho: np.ndarray
    lag1: float
    ljung_box_p: float
    inflation: float
    block: int = 1

    @property
    def white(self) -> bool:
        """Whether the residuals pass as white (Ljung–Box p ≥ 0.05 and lag-1 ≤ 0.5)."""
        p = self.ljung_box_p
        return (not math.isfinite(p) or p >= 0.05) and not self.lag1 > HIGH_LAG1


def _errors(result, uncertainty=None):
    """(weighted errors e [N, m] in K, weighted sensitivities J [N, m, p] in K per SI unit) in
    time order, 0 where an output is not measured (m: the outputs with a weight). The
    sensitivities are those ``uncertainty`` holds when it was computed on this fit, else
    computed anew."""
    from ..fit import problem_arrays
    from ._uncertainty import optimum_sensitivities

    problem = result.problem
    t, u, y, sqrt_w = problem_arrays(problem, result.data)
    ysim, J = optimum_sensitivities(result, uncertainty, t, u)
    q = np.asarray(problem.weights, dtype=float)
    rows = q > 0
    sq = np.sqrt(q[rows])
    e = (np.asarray(y)[:, rows] - ysim[:, rows]) * sq
    Jw = J[:, rows, :] * sq[None, :, None]
    if np.ndim(sqrt_w) == 2:
        seen = (np.asarray(sqrt_w) > 0)[:, rows]
        e = np.where(seen, e, 0.0)
        Jw = np.where(seen[..., None], Jw, 0.0)
    return e, Jw


def _ar1(x: np.ndarray) -> np.ndarray:
    """Lag-1 autocorrelation coefficient of each column of ``x`` [N, k] (0 for a flat one)."""
    den = np.sum(x[:-1] * x[:-1], axis=0)
    num = np.sum(x[1:] * x[:-1], axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(den > 0, num / den, 0.0)
    return np.nan_to_num(r)


def _bandwidth(s: np.ndarray) -> float:
    """Andrews' (1991) AR(1) plug-in bandwidth of the Bartlett kernel for the score series
    ``s`` [N, k] (each series weighted by its inverse variance, so units do not matter)."""
    n = len(s)
    r = np.clip(_ar1(s), -0.97, 0.97)
    var = np.var(s, axis=0)
    live = var > 0
    if not live.any():
        return 0.0
    r, v = r[live], var[live] / np.max(var[live])
    s2 = v * (1 - r * r)  # innovation variances, relative
    w = 1.0 / (v * v)  # inverse-variance weights
    num = np.sum(w * 4 * r * r * s2 * s2 / ((1 - r) ** 6 * (1 + r) ** 2))
    den = np.sum(w * s2 * s2 / (1 - r) ** 4)
    alpha = num / den if den > 0 else 0.0
    return float(min(1.1447 * (alpha * n) ** (1.0 / 3.0), n - 1))


def _long_run(s: np.ndarray, b: float) -> np.ndarray:
    """Bartlett kernel estimate ``Σ_l (1 − |l|/(b+1)) Γ_l`` of the scores ``s`` [N, k]."""
    omega = s.T @ s
    for lag in range(1, int(math.floor(b)) + 1):
        w = 1.0 - lag / (b + 1.0)
        g = s[lag:].T @ s[:-lag]
        omega += w * (g + g.T)
    return omega


def _sandwich(scores: np.ndarray, bread: np.ndarray, max_rho: float):
    """``(B Ω B, bandwidth, ρ)``: the prewhitened Newey–West sandwich of the parameter scores
    ``s`` [N, p] with bread ``B`` [p, p] (unscaled: the caller applies its degrees of freedom).
    Each score series is prewhitened by its AR(1) coefficient ρ (clipped to ``max_rho``), its
    long-run covariance taken with the Bartlett kernel at Andrews' bandwidth, and recoloured."""
    rho = np.clip(_ar1(scores), -max_rho, max_rho)
    white = scores[1:] - rho * scores[:-1]
    b = _bandwidth(white)
    omega = _long_run(white, b)
    recolour = 1.0 / (1.0 - rho)
    omega = omega * recolour[:, None] * recolour[None, :]
    return bread @ omega @ bread, b, rho


def _blocked_sandwich(scores: np.ndarray, bread: np.ndarray, max_rho: float):
    """``(B Ω B, bandwidth [samples], ρ, block)``: :func:`_sandwich` at the blocking level whose
    standard errors are largest (median over the parameters), the scores summed over blocks of
    ``block`` = 1, 2, 4 … samples while at least :data:`MIN_BLOCKS` blocks (and four per
    parameter) remain. The samples after the last whole block are left out of a level and its
    ``Ω`` scaled up by their share."""
    n, p = scores.shape
    fewest = max(MIN_BLOCKS, 4 * p)
    best = None
    m = 1
    while m == 1 or n // m >= fewest:
        k = n // m
        sums = scores[: k * m].reshape(k, m, p).sum(axis=1)
        cov, b, rho = _sandwich(sums, bread, max_rho)
        cov = cov * (n / (k * m))
        with np.errstate(invalid="ignore"):
            se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        if best is None:
            base = np.where(se > 0, se, np.nan)
            size = 1.0
        else:
            with np.errstate(invalid="ignore", divide="ignore"):
                ratio = se / base
            ratio = ratio[np.isfinite(ratio)]
            size = float(np.median(ratio)) if ratio.size else 0.0
        if best is None or size > best[0]:
            best = (size, cov, b * m, rho, m)
        m *= 2
    return best[1:]


def robust_covariance(result, uncertainty=None, *, max_rho: float = MAX_RHO) -> RobustCovariance:
    """The HAC (prewhitened Newey–West) covariance of a fit's free parameters.

    Args:
        result: a :class:`~jaxbox.fit.FitResult`.
        uncertainty: its :class:`~jaxbox.validate.Uncertainty` (computed when ``None``); its
            pseudo-inverse ``(JᵀJ)⁺`` is the sandwich's bread, and the exact sensitivities it
            was computed from are reused (computed again only for an uncertainty of other
            parameter values or data).
        max_rho: the largest prewhitening AR(1) coefficient.

    Returns:
        :class:`RobustCovariance` (definitions in :mod:`jaxbox.validate._hlc`).
    """
    from ._args import check_fit, check_fraction
    from ._own import check_own
    from ._residuals import ljung_box
    from ._uncertainty import uncertainty as _uncertainty

    problem = check_fit(result).problem
    uncertainty = check_own(result, uncertainty, None)[0]
    max_rho = check_fraction(max_rho, "max_rho (largest prewhitening coefficient)")
    if uncertainty is None:
        uncertainty = _uncertainty(result)
    free = tuple(problem.free)
    e, J = _errors(result, uncertainty)
    n, p = len(e), len(free)
    s = np.einsum("tm,tmp->tp", e, J)  # scores [N, p]
    ok = np.all(np.isfinite(uncertainty.cov_free), axis=1)
    bread = np.zeros((p, p))
    sigma2 = float(uncertainty.sigma2)
    if sigma2 > 0:
        bread[np.ix_(ok, ok)] = uncertainty.cov_free[np.ix_(ok, ok)] / sigma2
    sandwich, b, rho, block = _blocked_sandwich(s, bread, max_rho)
    dof = max(uncertainty.dof, 1)
    cov = sandwich * (n * e.shape[1] / dof)
    cov = np.where(ok[:, None] & ok[None, :], cov, np.nan)
    cov = 0.5 * (cov + cov.T)
    pooled = e[np.any(e != 0, axis=1)]
    lag1 = float(np.mean(_ar1(pooled))) if len(pooled) > 2 else float("nan")
    pvals = []
    for j in range(e.shape[1]):
        col = e[:, j][e[:, j] != 0]
        if len(col) > 10:
            pvals.append(ljung_box(col).p_value)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.sqrt(np.diag(cov) / np.diag(uncertainty.cov_free))
    ratio = ratio[np.isfinite(ratio)]
    return RobustCovariance(
        free=free,
        cov_free=cov,
        bandwidth=b,
        rho=rho,
        lag1=lag1,
        ljung_box_p=float(min(pvals)) if pvals else float("nan"),
        inflation=float(np.median(ratio)) if ratio.size else float("nan"),
        block=int(block),
    )
