"""The steady-state form: daily means of the zone's energy balance, for data that determine
nothing but it (a co-heating test: the zone held constant by heaters for weeks).

Over whole days the heat stored in the building is small next to what flows through it, and
the energy balance of the zone reads, day by day ``d``::

    Q̄_d = H₀ · ΔT̄_d + H₁ · ΔT̄_d−1 − gA · Ī_d − Q₀,    HLC = H₀ + H₁                  [W]

with ``Q̄`` the heating, ``ΔT̄`` the zone's excess over the ambient [K] and ``Ī`` the
irradiance [W/m²] (the sum of the data's irradiance columns) averaged over the day. The
previous day's term takes the heat the envelope stores from one day to the next (a change of
weather reaches the heating a day late); ``Q₀`` is a constant heat gain (occupants,
appliances: heat the heating need not supply). Each is dropped, the least significant first,
while its interval spans zero. :func:`steady_fit` fits it by least squares through the
origin over the complete days (95 % intervals from Student's t). The solar aperture is kept
even where its interval spans zero (reported as undetermined): the sun and the temperature
difference vary together, and leaving it out would bias the HLC. The model is valid when the
HLC is positive and determined (half-width at most :data:`~jaxbox.validate.MAX_REL_CI` of it);
the dynamics (every capacity) are reported as undetermined, which is not a reason to reject:
the form does not claim them. Its error is the leave-one-day-out RMSE of the daily heating.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import stats

from ..validate import MAX_REL_CI

__all__ = ["SteadyFit", "steady_fit", "MIN_DAYS"]

#: fewest complete days a steady-state fit is posed on
MIN_DAYS = 5


#: the steady-state form's interval: least squares on the daily means, Student's t
STEADY_METHOD = "least squares on the daily means (Student's t)"


@dataclasses.dataclass(frozen=True)
class SteadyFit:
    """The steady-state form identified from daily means.

    Attributes:
        hlc: heat-loss coefficient [W/K]; ``hlc_interval`` its 95 % interval.
        gA: solar aperture [m²] (0 without irradiance); ``gA_interval`` its 95 % interval.
        days: complete days used.
        rmse_loo: leave-one-day-out RMSE of the daily mean heating [W]; ``q_std`` the std of
            the daily mean heating [W].
        valid: the verdict; ``reasons`` why not.
        undetermined: what the form does not determine (the dynamics).
        q0: constant heat gain [W] (0 when dropped).
        dropped: terms left out: ``H1`` (the previous day's share: its interval spans zero or too
            few consecutive days), ``gA`` (no irradiance), ``Q0`` (its interval spans zero).
        form: ``"steady state"``.
        hlc_method: how the HLC's interval was made; ``warnings`` where it may be too narrow
            (daily residuals correlated from one day to the next, which Student's interval
            takes as independent).
    """

    hlc: float
    hlc_interval: tuple
    gA: float
    gA_interval: tuple
    days: int
    rmse_loo: float
    q_std: float
    valid: bool
    reasons: tuple = ()
    undetermined: tuple = ("the dynamics (every capacity)",)
    dropped: tuple = ()
    q0: float = 0.0
    form: str = "steady state"
    hlc_method: str = STEADY_METHOD
    warnings: tuple = ()

    @property
    def structure(self) -> str:
        """The terms kept: ``HLC`` (with ``lag`` when the previous day's share is kept) and
        ``gA``."""
        kept = ["HLC"] + (["lag"] if "H1" not in self.dropped else [])
        kept += [] if "gA" in self.dropped else ["gA"]
        return "+".join(kept + ([] if "Q0" in self.dropped else ["Q0"]))

    @property
    def relative(self) -> float:
        """Leave-one-day-out RMSE over the std of the daily heating."""
        return self.rmse_loo / max(self.q_std, 1e-9)

    def summary(self) -> str:
        """The HLC, the aperture, the error and the verdict on one line."""
        if not np.isfinite(self.hlc):
            return f"steady-state form: not valid: {'; '.join(self.reasons)}"
        lo, hi = self.hlc_interval
        text = (
            f"steady-state form on {self.days} daily means: HLC {self.hlc:.4g} W/K "
            f"[{lo:.4g}, {hi:.4g}] ({self.hlc_method})"
        )
        if "H1" not in self.dropped:
            text += " (a share a day late: the envelope's storage)"
        if "Q0" not in self.dropped:
            text += f", constant gains {self.q0:.4g} W"
        if "gA" in self.dropped:
            text += ", no irradiance"
        else:
            text += f", gA {self.gA:.3g} m² [{self.gA_interval[0]:.3g}, {self.gA_interval[1]:.3g}]"
        text += (
            f"; daily heating RMSE {self.rmse_loo:.4g} W leaving one day out "
            f"({self.relative:.3g} of its std); undetermined: {', '.join(self.undetermined)}; "
        )
        text += "valid" if self.valid else "not valid: " + "; ".join(self.reasons)
        return text + "".join(f"; warning: {w}" for w in self.warnings)

    def to_dict(self) -> dict:
        """JSON-ready fields (SI units)."""
        d = dataclasses.asdict(self)
        d.update(
            structure=self.structure,
            relative=self.relative,
            hlc_interval=list(self.hlc_interval),
            gA_interval=list(self.gA_interval),
            reasons=list(self.reasons),
            undetermined=list(self.undetermined),
            dropped=list(self.dropped),
            warnings=list(self.warnings),
        )
        return d


def daily_means(data, zone: str = "T_zon", heating: str = "Q_hea"):
    """``(ΔT̄ [K], Ī [W/m²], Q̄ [W], previous)`` over the complete days of ``data`` (every
    sample of the day present); ``previous`` [bool] marks the days whose previous day is
    complete too."""
    frame = data.frame
    irr = [c for c in frame.columns if c.startswith("I_")]
    d = frame[[zone, "T_amb", heating]].copy()
    d["I"] = frame[irr].sum(axis=1, min_count=len(irr)) if irr else 0.0
    per_day = round(86400.0 / float(data.step))
    groups = d.groupby(d.index.normalize())
    complete = groups.count().min(axis=1) >= per_day
    m = groups.mean()[complete]
    days = m.index
    previous = np.asarray(
        [i > 0 and (days[i] - days[i - 1]).days == 1 for i in range(len(days))], dtype=bool
    )
    return (
        (m[zone] - m["T_amb"]).to_numpy(float),
        m["I"].to_numpy(float),
        m[heating].to_numpy(float),
        previous,
    )


def steady_fit(data, zone: str = "T_zon", heating: str = "Q_hea") -> SteadyFit:
    """Fit the steady-state form on the complete days of ``data`` (see the module).

    Args:
        data: a Dataset with ``zone``, ``T_amb``, ``heating`` [W] and any ``I_*`` columns.
        zone, heating: the zone temperature and heating columns.

    Returns:
        :class:`SteadyFit` (not valid, with the reason, on fewer than :data:`MIN_DAYS` days).
    """
    dT, irr, q, previous = daily_means(data, zone, heating)
    nan = (float("nan"), float("nan"))
    if q.size < MIN_DAYS:
        return SteadyFit(
            float("nan"),
            nan,
            0.0,
            nan,
            q.size,
            float("nan"),
            float("nan"),
            False,
            (f"{q.size} complete days, fewer than {MIN_DAYS}",),
        )
    lagged = np.concatenate([[np.nan], dT[:-1]])
    terms = {"H0": dT, "H1": lagged, "gA": -irr, "Q0": -np.ones(q.size)}
    dropped = [] if np.ptp(irr) > 0 else ["gA"]
    if previous.sum() < MIN_DAYS:
        dropped.append("H1")
    while True:  # the lag and the constant gain dropped while their interval spans zero
        names = [k for k in terms if k not in dropped]
        rows = previous if "H1" in names else np.ones(q.size, dtype=bool)
        X = np.stack([terms[k][rows] for k in names], axis=1)
        y = q[rows]
        beta, cov, dof = _ols(X, y)
        t = float(stats.t.ppf(0.975, max(dof, 1)))
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        ratio = {
            k: abs(beta[i]) / max(se[i], 1e-300) for i, k in enumerate(names) if k in ("H1", "Q0")
        }
        weakest = min(ratio, key=ratio.get, default=None)
        if weakest is None or ratio[weakest] > t:
            break
        dropped.append(weakest)
    c = np.asarray([k in ("H0", "H1") for k in names], dtype=float)
    hlc, hlc_se = float(c @ beta), float(np.sqrt(max(c @ cov @ c, 0.0)))
    hlc_int = (hlc - t * hlc_se, hlc + t * hlc_se)
    if "gA" in names:
        i = names.index("gA")
        gA, gA_int = float(beta[i]), (float(beta[i] - t * se[i]), float(beta[i] + t * se[i]))
    else:
        gA, gA_int = 0.0, (0.0, 0.0)
    undetermined = ["the dynamics (every capacity)"]
    if "gA" in names and abs(gA) <= t * se[names.index("gA")]:
        undetermined.append("gA (its interval spans zero)")
    reasons = []
    if not hlc > 0:
        reasons.append(f"HLC {hlc:.3g} W/K not positive")
    elif not t * hlc_se <= MAX_REL_CI * hlc:
        reasons.append(f"HLC undetermined (95 % interval {hlc_int[0]:.3g} to {hlc_int[1]:.3g})")
    return SteadyFit(
        hlc=hlc,
        hlc_interval=hlc_int,
        gA=gA,
        gA_interval=gA_int,
        days=int(y.size),
        rmse_loo=_loo(X, y),
        q_std=float(np.std(y)),
        valid=not reasons,
        reasons=tuple(reasons),
        undetermined=tuple(undetermined),
        dropped=tuple(dropped),
        q0=float(beta[names.index("Q0")]) if "Q0" in names else 0.0,
        warnings=_day_to_day(y - X @ beta, np.flatnonzero(rows), previous),
    )


def _day_to_day(e: np.ndarray, days: np.ndarray, previous: np.ndarray) -> tuple[str, ...]:
    """A warning where the residuals ``e`` of consecutive days (``days``: their positions
    among the complete days) are correlated beyond chance (lag-1 correlation above 2/√pairs):
    Student's interval takes the days as independent and is then too narrow."""
    pair = (np.diff(days) == 1) & previous[days[1:]]  # day k+1 follows day k
    n = int(pair.sum())
    if n < MIN_DAYS:
        return ()
    x, z = e[:-1][pair], e[1:][pair]
    rho = float(np.sum(x * z) / max(np.sqrt(np.sum(x * x) * np.sum(z * z)), 1e-300))
    if not rho > 2.0 / math.sqrt(n):
        return ()
    return (
        f"the daily residuals are correlated from one day to the next (lag-1 correlation "
        f"{rho:.2f} over {n} pairs of days): the interval, which takes the days as "
        "independent, may be too narrow",
    )


def _ols(X, y):
    """Least squares through the origin: ``(β, covariance, degrees of freedom)``."""
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    dof = X.shape[0] - X.shape[1]
    s2 = float(np.sum((y - X @ beta) ** 2)) / max(dof, 1)
    return beta, s2 * np.linalg.pinv(X.T @ X), dof


def _loo(X, y) -> float:
    """Leave-one-out RMSE of a least-squares fit (PRESS residuals)."""
    H = X @ np.linalg.pinv(X.T @ X) @ X.T
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    e = (y - X @ beta) / np.maximum(1.0 - np.diag(H), 1e-9)
    return float(np.sqrt(np.mean(e**2)))
