"""Residual analysis: are the output errors white, and are they independent of the inputs?

A model that captures the dynamics leaves residuals ``e = y − ŷ`` that look like white noise and
are uncorrelated with every input. Structure that is left shows what to add next (a slow
state, a missing input). Per output this module computes

* residual statistics (mean, standard deviation, RMSE, extremes, skewness, excess kurtosis and
  the Jarque–Bera normality p-value);
* the autocorrelation function ``r_k`` with its white-noise band ``± z_{1−α/2} / √N``;
* the Ljung–Box portmanteau test ``Q = N (N + 2) Σ_{k=1}^{h} r_k² / (N − k)``, χ² with h
  degrees of freedom under whiteness;
* the cumulated periodogram test (Box & Jenkins): for white noise the normalised cumulated
  periodogram ordinates ``C_1 … C_{q−1}`` (q Fourier frequencies strictly between 0 and the
  Nyquist frequency) are distributed as uniform order statistics, so their Kolmogorov–Smirnov
  distance to the diagonal has the exact ``kstwo(q − 1)`` distribution;
* the cross-correlation of the residuals with each input at lags ``−L … L``
  (``corr(e_{t+k}, u_t)``: positive lags are residuals after the input), with the band
  ``± z_{1−α/2} / √N`` that holds when the residuals are white and independent of the input.

Missing samples (NaN: output gaps, and the rows :meth:`Validation.residual_analysis` puts
between the segments of the data so that no lagged pair spans a cut) are left out: the
correlations follow Parzen's (1963) estimator for amplitude-modulated series (see
:func:`autocorrelation`), ``N`` counts the measured samples, and the periodogram takes the
centred series with 0 at the missing samples.

Everything is returned as data (numpy arrays and JSON-ready summaries); the plots live in
:mod:`jaxbox.validate._plots`.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence

import numpy as np
from scipy import stats

__all__ = [
    "autocorrelation",
    "cross_correlation",
    "ljung_box",
    "cumulated_periodogram",
    "residual_stats",
    "LjungBox",
    "CumulatedPeriodogram",
    "OutputResiduals",
    "ResidualAnalysis",
    "analyse_residuals",
]


def _floats(e, what: str) -> np.ndarray:
    """``e`` as a float array; a ``TypeError`` naming ``what`` when it holds no numbers."""
    try:
        return np.asarray(e, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{what} must be numbers (an array), got {type(e).__name__}") from None


def _lags(value, what: str, default: int) -> int:
    """A number of lags: ``default`` for None, else a whole number (not 1.5, not a string)."""
    from ..data._args import check_count

    return default if value is None else check_count(value, what, minimum=0)


def _alpha(alpha) -> float:
    """A significance level in (0, 1)."""
    if isinstance(alpha, bool) or not isinstance(alpha, int | float | np.floating):
        raise ValueError(f"alpha must be a significance level in (0, 1), e.g. 0.05; got {alpha!r}")
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must be a significance level in (0, 1), e.g. 0.05; got {alpha}")
    return float(alpha)


def _vector(e, what="residuals") -> np.ndarray:
    """A 1-D float series; NaN marks a missing sample (a gap), infinities are refused."""
    e = _floats(e, what)
    if e.ndim != 1:
        raise ValueError(f"{what} must be one series (1-D), got shape {e.shape}")
    if np.isinf(e).any():
        raise ValueError(f"{what} contain inf; drop or fill those samples first")
    seen = int(np.isfinite(e).sum())
    if seen < 4:
        raise ValueError(f"{what} need at least 4 measured samples, got {seen}")
    return e


def _centred(e) -> tuple[np.ndarray, np.ndarray]:
    """``(d, seen)``: the series minus the mean of its measured samples, 0 where it is missing
    (the amplitude-modulated series of Parzen 1963), and the mask of measured samples."""
    seen = np.isfinite(e)
    d = np.where(seen, e - (e[seen].mean() if seen.any() else 0.0), 0.0)
    return d, seen


def _flat(e) -> bool:
    """No fluctuation: every measured sample of ``e`` the same (all 0 for a perfect fit).

    The tests below run on the series minus its mean, which is then 0 throughout: nothing is
    left to correlate, so the series is white by definition (statistics 0, p-values 1) rather
    than ``0 / 0``. A constant offset shows in :func:`residual_stats` (``mean``)."""
    seen = e[np.isfinite(e)]
    return bool(seen.size) and bool(np.all(seen == seen[0]))


def _flat_note(e) -> str:
    seen = e[np.isfinite(e)]
    what = (
        "every measured residual is 0 (a perfect fit)"
        if not seen.any()
        else f"every measured residual is {float(seen[0]):.6g} (a constant offset, no fluctuation)"
    )
    return f"{what}: white by definition (test statistics 0, p-values 1, correlations 0)"


def default_max_lag(n: int) -> int:
    """Lags shown by default: ``min(48, N // 4)`` (two days of hourly data)."""
    return int(max(1, min(48, n // 4)))


def default_lb_lags(n: int) -> int:
    """Ljung–Box lags by default: ``min(24, N // 5)`` (one day of hourly data)."""
    return int(max(1, min(24, n // 5)))


def autocorrelation(e, max_lag: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Sample autocorrelation ``r_k``, k = 0 … max_lag (biased estimator, ``r_0 = 1``).

    Missing samples (NaN, output gaps) are left out as in Parzen's (1963) estimator for
    amplitude-modulated series: with ``d`` the series minus the mean of its measured samples,
    ``n`` of them, and ``P_k`` the number of pairs ``(t, t + k)`` measured at both ends,
    ``r_k = [(Σ_pairs d_t d_{t+k}) / P_k] / [(Σ d_t²) / n] · (n − k) / n``; the last factor
    makes it the ordinary biased estimator when nothing is missing.

    Returns:
        (lags, r). ``r`` is ``nan`` for a constant series (and at a lag without any pair).
    """
    e = _vector(e)
    n = e.size
    L = _lags(max_lag, "max_lag", default_max_lag(n))
    if not 0 <= L < n:
        raise ValueError(f"max_lag must be in [0, {n - 1}] for {n} samples, got {max_lag}")
    d, seen = _centred(e)
    den = float(d @ d)
    lags = np.arange(L + 1)
    if den == 0:
        return lags, np.full(L + 1, np.nan)
    if seen.all():
        r = np.asarray([float(d[: n - k] @ d[k:]) for k in lags]) / den
        return lags, r
    m = int(seen.sum())
    w = seen.astype(float)
    pairs = np.asarray([float(w[: n - k] @ w[k:]) for k in lags])
    sums = np.asarray([float(d[: n - k] @ d[k:]) for k in lags])
    with np.errstate(invalid="ignore", divide="ignore"):
        r = (sums / pairs) / (den / m) * np.maximum(m - lags, 0) / m
    r[0] = 1.0
    return lags, r


def cross_correlation(e, u, max_lag: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Cross-correlation ``corr(e_{t+k}, u_t)`` for k = −max_lag … max_lag.

    Positive k: the residual *after* the input (an input effect the model misses shows there).
    ``nan`` when either series is constant.
    """
    e = _vector(e)
    u = _vector(u, "input")
    if u.size != e.size:
        raise ValueError(f"residuals ({e.size}) and input ({u.size}) differ in length")
    n = e.size
    L = _lags(max_lag, "max_lag", default_max_lag(n))
    if not 0 <= L < n:
        raise ValueError(f"max_lag must be in [0, {n - 1}] for {n} samples, got {max_lag}")
    de, _ = _centred(e)  # missing samples (NaN) count as 0 after centring: no pair
    du, _ = _centred(u)
    den = np.sqrt(float(de @ de) * float(du @ du))
    lags = np.arange(-L, L + 1)
    if den == 0:
        return lags, np.full(lags.size, np.nan)
    r = []
    for k in lags:
        if k >= 0:
            r.append(float(de[k:] @ du[: n - k]))
        else:
            r.append(float(de[: n + k] @ du[-k:]))
    return lags, np.asarray(r) / den


@dataclasses.dataclass(frozen=True, eq=False)
class LjungBox:
    """Ljung–Box test of whiteness.

    Attributes:
        statistic: Q.
        lags: number of autocorrelations h in Q (also the χ² degrees of freedom).
        p_value: P(χ²_h ≥ Q) under whiteness.
        alpha: significance level.
    """

    statistic: float
    lags: int
    p_value: float
    alpha: float = 0.05

    @property
    def white(self) -> bool:
        """Whiteness not rejected at level ``alpha``."""
        return bool(self.p_value > self.alpha)

    def to_dict(self) -> dict:
        return {
            "statistic": float(self.statistic),
            "lags": int(self.lags),
            "p_value": float(self.p_value),
            "white": self.white,
        }


def ljung_box(e, lags: int | None = None, alpha: float = 0.05) -> LjungBox:
    """Ljung–Box test on ``lags`` autocorrelations (default :func:`default_lb_lags`).

    With missing samples the autocorrelations are those of :func:`autocorrelation` and ``N``
    is the number of measured samples. A series without fluctuation (all 0: a perfect fit) is
    white by definition: ``Q = 0``, p-value 1.
    """
    e = _vector(e)
    alpha = _alpha(alpha)
    n = int(np.isfinite(e).sum())
    h = _lags(lags, "lags", default_lb_lags(n))
    if not 1 <= h < n:
        raise ValueError(f"lags must be in [1, {n - 1}] for {n} samples, got {lags}")
    if _flat(e):  # nothing left to correlate: white by definition (was nan, 'not white')
        return LjungBox(statistic=0.0, lags=h, p_value=1.0, alpha=alpha)
    _, r = autocorrelation(e, h)
    k = np.arange(1, h + 1)
    q = float(n * (n + 2) * np.sum(r[1:] ** 2 / (n - k)))
    p = float(stats.chi2.sf(q, h)) if np.isfinite(q) else float("nan")
    return LjungBox(statistic=q, lags=h, p_value=p, alpha=alpha)


@dataclasses.dataclass(frozen=True, eq=False)
class CumulatedPeriodogram:
    """Cumulated periodogram test of whiteness.

    Attributes:
        frequency: Fourier frequencies [cycles per sample], 1/N … q/N (below Nyquist).
        cumulated: normalised cumulated periodogram at those frequencies (ends at 1).
        statistic: Kolmogorov–Smirnov distance D of ``cumulated[:-1]`` to the diagonal.
        critical: critical distance at level ``alpha`` (the band half-width).
        p_value: P(D_{q−1} ≥ D) under whiteness.
        alpha: significance level.
    """

    frequency: np.ndarray
    cumulated: np.ndarray
    statistic: float
    critical: float
    p_value: float
    alpha: float = 0.05

    @property
    def white(self) -> bool:
        return bool(self.p_value > self.alpha)

    @property
    def expected(self) -> np.ndarray:
        """The white-noise line ``j / q``."""
        q = self.cumulated.size
        return np.arange(1, q + 1) / q

    def to_dict(self) -> dict:
        return {
            "statistic": float(self.statistic),
            "critical": float(self.critical),
            "p_value": float(self.p_value),
            "white": self.white,
        }


@functools.lru_cache(maxsize=256)
def _ks_critical(alpha: float, m: int) -> float:
    return float(stats.kstwo.ppf(1 - alpha, m))


def cumulated_periodogram(e, alpha: float = 0.05) -> CumulatedPeriodogram:
    """Cumulated periodogram test (exact Kolmogorov–Smirnov band for Gaussian white noise).

    Missing samples (NaN) are set to the mean of the measured ones (0 after centring), the
    periodogram of the amplitude-modulated series; a few percent of gaps barely change it.
    A series without fluctuation (all 0: a perfect fit) is white by definition: the cumulated
    periodogram is the diagonal, ``D = 0``, p-value 1.
    """
    e = _vector(e)
    alpha = _alpha(alpha)
    n = e.size
    d, _ = _centred(e)
    q = (n - 1) // 2  # Fourier frequencies strictly between 0 and Nyquist
    power = np.abs(np.fft.rfft(d)[1 : q + 1]) ** 2
    freq = np.arange(1, q + 1) / n
    total = float(power.sum())
    if _flat(e) and q >= 2:  # nothing left: white by definition (was nan, 'not white')
        diagonal = np.arange(1, q + 1) / q
        return CumulatedPeriodogram(freq, diagonal, 0.0, _ks_critical(alpha, q - 1), 1.0, alpha)
    if total == 0 or q < 2:
        nan = float("nan")
        return CumulatedPeriodogram(freq, np.full(q, nan), nan, nan, nan, alpha)
    c = np.cumsum(power) / total
    m = q - 1
    j = np.arange(1, m + 1)
    u = c[:-1]
    dist = float(max(np.max(j / m - u), np.max(u - (j - 1) / m)))
    return CumulatedPeriodogram(
        frequency=freq,
        cumulated=c,
        statistic=dist,
        critical=_ks_critical(alpha, m),
        p_value=float(stats.kstwo.sf(dist, m)),
        alpha=alpha,
    )


def residual_stats(e) -> dict[str, float]:
    """Summary statistics of a residual series [unit of the output, K for temperatures].

    Keys: ``n``, ``mean``, ``std`` (N − 1), ``rmse``, ``mae``, ``min``, ``max``, ``max_abs``,
    ``skewness``, ``kurtosis`` (excess), ``normality_p`` (Jarque–Bera; for a series without
    fluctuation, a perfect fit, skewness and kurtosis are 0 and normality_p 1); over the measured
    samples (NaN, an output gap, is left out; ``n`` counts the measured ones).
    """
    e = _vector(e)
    e = e[np.isfinite(e)]
    const = bool(np.ptp(e) == 0)
    return {
        "n": int(e.size),
        "mean": float(e.mean()),
        "std": float(e.std(ddof=1)),
        "rmse": float(np.sqrt(np.mean(e * e))),
        "mae": float(np.mean(np.abs(e))),
        "min": float(e.min()),
        "max": float(e.max()),
        "max_abs": float(np.max(np.abs(e))),
        "skewness": 0.0 if const else float(stats.skew(e)),
        "kurtosis": 0.0 if const else float(stats.kurtosis(e)),
        "normality_p": 1.0 if const else float(stats.jarque_bera(e).pvalue),
    }


@dataclasses.dataclass(frozen=True, eq=False)
class OutputResiduals:
    """Residual analysis of one output.

    Attributes:
        name: output name.
        residuals: measured minus simulated output [K], shape [N].
        stats: :func:`residual_stats`.
        lags, acf: autocorrelation at lags 0 … L.
        band: half-width of the white-noise band of ``acf`` and ``ccf``.
        ljung_box: :class:`LjungBox`.
        periodogram: :class:`CumulatedPeriodogram`.
        ccf_lags: lags −L … L of the cross-correlations.
        ccf: input name -> cross-correlation ``corr(e_{t+k}, u_t)``.
        alpha: significance level.
        note: why the tests are decided without data, or ``""``: a series without fluctuation
            (all 0, a perfect fit) is white by definition, its correlations 0.
    """

    name: str
    residuals: np.ndarray
    stats: dict
    lags: np.ndarray
    acf: np.ndarray
    band: float
    ljung_box: LjungBox
    periodogram: CumulatedPeriodogram
    ccf_lags: np.ndarray
    ccf: dict
    alpha: float
    note: str = ""

    @property
    def white(self) -> bool:
        """Both whiteness tests pass at level ``alpha``."""
        return self.ljung_box.white and self.periodogram.white

    def acf_outside(self) -> float:
        """Fraction of lags 1 … L whose autocorrelation lies outside the band."""
        r = self.acf[1:]
        return float(np.mean(np.abs(r) > self.band)) if r.size else 0.0

    def ccf_outside(self) -> dict[str, float]:
        """Per input: fraction of lags whose cross-correlation lies outside the band."""
        return {k: float(np.mean(np.abs(v) > self.band)) for k, v in self.ccf.items()}

    def to_dict(self) -> dict:
        """JSON-ready summary (no long arrays)."""
        ccf = {}
        for k, v in self.ccf.items():
            finite = np.isfinite(v)
            if finite.any():
                i = int(np.nanargmax(np.abs(v)))
                ccf[k] = {
                    "max_abs": float(abs(v[i])),
                    "at_lag": int(self.ccf_lags[i]),
                    "outside_band": float(np.mean(np.abs(v[finite]) > self.band)),
                }
            else:
                ccf[k] = {"max_abs": None, "at_lag": None, "outside_band": None}
        return {
            "stats": {k: (None if not np.isfinite(v) else v) for k, v in self.stats.items()},
            "white": self.white,
            "ljung_box": self.ljung_box.to_dict(),
            "cumulated_periodogram": self.periodogram.to_dict(),
            "acf": {
                "lag1": float(self.acf[1]) if self.acf.size > 1 else None,
                "band": float(self.band),
                "outside_band": self.acf_outside(),
                "max_lag": int(self.lags[-1]),
            },
            "ccf": ccf,
            **({"note": self.note} if self.note else {}),
        }


@dataclasses.dataclass(frozen=True, eq=False)
class ResidualAnalysis:
    """Residual analysis of every output (index by output name or position)."""

    outputs: tuple[OutputResiduals, ...]
    inputs: tuple[str, ...]
    alpha: float

    def __getitem__(self, key) -> OutputResiduals:
        if isinstance(key, str):
            for o in self.outputs:
                if o.name == key:
                    return o
            raise KeyError(f"no output {key!r}; outputs: {', '.join(self.names)}")
        return self.outputs[key]

    def __iter__(self):
        return iter(self.outputs)

    def __len__(self) -> int:
        return len(self.outputs)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(o.name for o in self.outputs)

    @property
    def white(self) -> bool:
        """Every output passes both whiteness tests."""
        return all(o.white for o in self.outputs)

    def to_dict(self) -> dict:
        return {o.name: o.to_dict() for o in self.outputs}


def analyse_residuals(
    residuals,
    inputs=None,
    *,
    output_names: Sequence[str] | None = None,
    input_names: Sequence[str] | None = None,
    max_lag: int | None = None,
    lb_lags: int | None = None,
    alpha: float = 0.05,
) -> ResidualAnalysis:
    """Residual analysis of every output.

    Args:
        residuals: measured minus simulated outputs, shape [N] or [N, outputs].
        inputs: inputs [N, m] for the cross-correlations (optional).
        output_names, input_names: column names (default ``y0, y1…``, ``u0, u1…``).
        max_lag: lags of the auto- and cross-correlations (default ``min(48, N // 4)``).
        lb_lags: autocorrelations in the Ljung–Box statistic (default ``min(24, N // 5)``).
        alpha: significance level of the tests and bands.

    Returns:
        :class:`ResidualAnalysis`. An output whose residuals do not fluctuate (all 0: a perfect
        fit) is white by definition: test statistics 0, p-values 1, correlations 0 at every
        lag but 0, with a ``note`` saying so (they were ``nan``, judged 'not white').
    """
    e = _floats(residuals, "residuals")
    if e.ndim == 1:
        e = e[:, None]
    if e.ndim != 2:
        raise ValueError(f"residuals must have shape [N] or [N, outputs], got {e.shape}")
    alpha = _alpha(alpha)
    n, p = e.shape
    if output_names is None:
        output_names = [f"y{j}" for j in range(p)]
    out_names = tuple(output_names)
    if len(out_names) != p:
        raise ValueError(f"{len(out_names)} output names for {p} residual columns")
    if inputs is None:
        u = np.zeros((n, 0))
    else:
        u = _floats(inputs, "inputs")
        if u.ndim == 1:
            u = u[:, None]
        if u.shape[0] != n:
            raise ValueError(f"inputs have {u.shape[0]} samples, the residuals {n}")
    in_names = (
        tuple(input_names) if input_names is not None else tuple(f"u{j}" for j in range(u.shape[1]))
    )
    if len(in_names) != u.shape[1]:
        raise ValueError(f"{len(in_names)} input names for {u.shape[1]} input columns")
    L = _lags(max_lag, "max_lag", default_max_lag(n))
    measured = int(np.isfinite(e).all(axis=1).sum()) if e.size else n
    band = float(stats.norm.ppf(1 - alpha / 2) / np.sqrt(max(measured, 1)))
    outs = []
    for j, name in enumerate(out_names):
        ej = e[:, j]
        lags, r = autocorrelation(ej, L)
        ccf = {}
        ccf_lags = np.arange(-L, L + 1)
        for i, un in enumerate(in_names):
            ccf_lags, ccf[un] = cross_correlation(ej, u[:, i], L)
        note = ""
        if _flat(_vector(ej)):  # a perfect fit: correlations 0 / 0, defined as none (white)
            note = _flat_note(ej)
            r = np.where(lags == 0, 1.0, 0.0)
            ccf = {un: np.zeros(ccf_lags.size) for un in ccf}
        outs.append(
            OutputResiduals(
                name=name,
                residuals=ej.copy(),
                stats=residual_stats(ej),
                lags=lags,
                acf=r,
                band=band,
                ljung_box=ljung_box(ej, lb_lags, alpha),
                periodogram=cumulated_periodogram(ej, alpha),
                ccf_lags=ccf_lags,
                ccf=ccf,
                alpha=alpha,
                note=note,
            )
        )
    return ResidualAnalysis(outputs=tuple(outs), inputs=in_names, alpha=alpha)
