"""The steady-state form: daily means of the zone's energy balance, for data that determine
nothing but it (a co-heating test: the zone held constant by heaters for weeks).

Over whole days the heat stored in the building is small next to what flows through it, and
the energy balance of the zone reads, day by day ``d``::

    Q̄_d = HLC · (T̄_zon,d − T̄_amb,d) − gA · Ī_d                                          [W]

with ``Q̄`` the heating, ``T̄`` the temperatures [°C] and ``Ī`` the irradiance [W/m²] (the sum
of the data's irradiance columns) averaged over the day. :func:`steady_fit` fits it by least
squares through the origin over the complete days (95 % intervals from Student's t); a solar
aperture whose interval spans zero is dropped (``Q̄ = HLC · ΔT̄``). The model is valid when the
HLC is positive and determined (half-width at most :data:`~jaxbox.validate.MAX_REL_CI` of it);
the dynamics (every capacity) are reported as undetermined, which is not a reason to reject:
the form does not claim them. Its error is the leave-one-day-out RMSE of the daily heating.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import stats

from ..validate import MAX_REL_CI

__all__ = ["SteadyFit", "steady_fit", "MIN_DAYS"]

#: fewest complete days a steady-state fit is posed on
MIN_DAYS = 5


@dataclasses.dataclass(frozen=True)
class SteadyFit:
    """The steady-state form identified from daily means.

    Attributes:
        hlc: heat-loss coefficient [W/K]; ``hlc_interval`` its 95 % interval.
        gA: solar aperture [m²] (0 when dropped); ``gA_interval`` its 95 % interval.
        days: complete days used.
        rmse_loo: leave-one-day-out RMSE of the daily mean heating [W]; ``q_std`` the std of
            the daily mean heating [W].
        valid: the verdict; ``reasons`` why not.
        undetermined: what the form does not determine (the dynamics).
        dropped: terms dropped because their interval spans zero.
        form: ``"steady state"``.
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
    form: str = "steady state"

    @property
    def structure(self) -> str:
        return "HLC" if "gA" in self.dropped else "HLC+gA"

    @property
    def relative(self) -> float:
        """Leave-one-day-out RMSE over the std of the daily heating."""
        return self.rmse_loo / max(self.q_std, 1e-9)

    def summary(self) -> str:
        lo, hi = self.hlc_interval
        text = (
            f"steady-state form on {self.days} daily means: HLC {self.hlc:.4g} W/K "
            f"[{lo:.4g}, {hi:.4g}]"
        )
        if "gA" in self.dropped:
            text += ", solar aperture dropped (its interval spans zero)"
        else:
            text += f", gA {self.gA:.3g} m² [{self.gA_interval[0]:.3g}, {self.gA_interval[1]:.3g}]"
        text += (
            f"; daily heating RMSE {self.rmse_loo:.4g} W leaving one day out "
            f"({self.relative:.3g} of its std); undetermined: {', '.join(self.undetermined)}; "
        )
        return text + ("valid" if self.valid else "not valid: " + "; ".join(self.reasons))

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d.update(
            structure=self.structure,
            relative=self.relative,
            hlc_interval=list(self.hlc_interval),
            gA_interval=list(self.gA_interval),
            reasons=list(self.reasons),
            undetermined=list(self.undetermined),
            dropped=list(self.dropped),
        )
        return d


def daily_means(data, zone: str = "T_zon", heating: str = "Q_hea"):
    """``(ΔT̄ [K], Ī [W/m²], Q̄ [W])`` over the complete days of ``data`` (every sample of the
    day present)."""
    frame = data.frame
    irr = [c for c in frame.columns if c.startswith("I_")]
    d = frame[[zone, "T_amb", heating]].copy()
    d["I"] = frame[irr].sum(axis=1, min_count=len(irr)) if irr else 0.0
    per_day = round(86400.0 / float(data.step))
    groups = d.groupby(d.index.normalize())
    complete = groups.count().min(axis=1) >= per_day
    m = groups.mean()[complete]
    return (
        (m[zone] - m["T_amb"]).to_numpy(float),
        m["I"].to_numpy(float),
        m[heating].to_numpy(float),
    )


def steady_fit(data, zone: str = "T_zon", heating: str = "Q_hea") -> SteadyFit:
    """Fit the steady-state form on the complete days of ``data`` (see the module).

    Args:
        data: a Dataset with ``zone``, ``T_amb``, ``heating`` [W] and any ``I_*`` columns.
        zone, heating: the zone temperature and heating columns.

    Returns:
        :class:`SteadyFit` (not valid, with the reason, on fewer than :data:`MIN_DAYS` days).
    """
    dT, irr, q = daily_means(data, zone, heating)
    n = q.size
    nan = (float("nan"), float("nan"))
    if n < MIN_DAYS:
        return SteadyFit(
            float("nan"),
            nan,
            0.0,
            nan,
            n,
            float("nan"),
            float("nan"),
            False,
            (f"{n} complete days, fewer than {MIN_DAYS}",),
        )
    solar = bool(np.ptp(irr) > 0)
    X = np.stack([dT, -irr], axis=1) if solar else dT[:, None]
    beta, se, dof = _ols(X, q)
    dropped: tuple = ()
    t = stats.t.ppf(0.975, max(dof, 1))
    if solar and abs(beta[1]) <= t * se[1]:  # the aperture's interval spans zero: dropped
        X = dT[:, None]
        beta, se, dof = _ols(X, q)
        t = stats.t.ppf(0.975, max(dof, 1))
        dropped = ("gA",)
    elif not solar:
        dropped = ("gA",)
    hlc, gA = float(beta[0]), float(beta[1]) if X.shape[1] > 1 else 0.0
    hlc_int = (hlc - t * se[0], hlc + t * se[0])
    gA_int = (gA - t * se[1], gA + t * se[1]) if X.shape[1] > 1 else (0.0, 0.0)
    loo = _loo(X, q)
    reasons = []
    if not hlc > 0:
        reasons.append(f"HLC {hlc:.3g} W/K not positive")
    elif not t * se[0] <= MAX_REL_CI * hlc:
        reasons.append(f"HLC undetermined (95 % interval {hlc_int[0]:.3g} to {hlc_int[1]:.3g})")
    return SteadyFit(
        hlc=hlc,
        hlc_interval=hlc_int,
        gA=gA,
        gA_interval=gA_int,
        days=n,
        rmse_loo=loo,
        q_std=float(np.std(q)),
        valid=not reasons,
        reasons=tuple(reasons),
        dropped=dropped,
    )


def _ols(X, y):
    """Least squares through the origin: ``(β, standard errors, degrees of freedom)``."""
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    dof = X.shape[0] - X.shape[1]
    s2 = float(np.sum((y - X @ beta) ** 2)) / max(dof, 1)
    cov = s2 * np.linalg.pinv(X.T @ X)
    return beta, np.sqrt(np.maximum(np.diag(cov), 0.0)), dof


def _loo(X, y) -> float:
    """Leave-one-out RMSE of a least-squares fit (PRESS residuals)."""
    H = X @ np.linalg.pinv(X.T @ X) @ X.T
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    e = (y - X @ beta) / np.maximum(1.0 - np.diag(H), 1e-9)
    return float(np.sqrt(np.mean(e**2)))
