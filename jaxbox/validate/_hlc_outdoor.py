"""The heat-loss coefficient referenced to the outdoor air, with measured boundaries as they behave.

The HLC of :func:`~jaxbox.validate.kpis` is the heating per kelvin of steady zone rise with
*every* temperature input held: the zone's conductance to all of its measured surroundings.
When a model couples the zone to measured temperatures other than the outdoor air (an attic, a
cellar, the ground, the supply air, neighbouring rooms), that number depends on which of them
the data carry and the search took: the same house prepared with and without its supply-air
column gives HLCs 20 % apart, each right for its own inputs.

The *outdoor HLC* asks what an analyst asks of a whole building: the heating per kelvin of
zone–outdoor difference when each measured boundary ``b`` responds as it does in the data.
With ``k_b`` the steady-state gain of the zone temperature on ``T_b`` (its share of the zone's
conductance) and ``α_b`` how far ``T_b`` follows the zone rather than the outdoor air,

    ``T_b − T_amb ≈ a_b + α_b (T_zon − T_amb)``   (least squares over the daily means),

substituting in the steady state ``T_zon = Σ k_i T_i + Q / HLC`` gives

    ``HLC_outdoor = HLC · (1 − Σ_b k_b α_b)``:

a boundary that follows the outdoor air (``α_b = 0``: a ventilated attic) counts fully, one that
follows the zone (``α_b = 1``: a heated neighbour) not at all, the supply air behind a heat
recovery of efficiency η as ``1 − η``. Without other measured boundaries it is the HLC itself.

**Interval.** The delta method over the free parameters (the covariance of
:func:`~jaxbox.validate.kpis`, white or HAC), plus the least-squares variance of each ``α_b``
(daily means: ``(HLC k_b)² var α_b``), independent of it; the same t quantile.
"""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp
import numpy as np

from .._compiled import cached

__all__ = ["OutdoorHLC", "outdoor_hlc", "boundary_follow", "AMBIENT"]

#: the outdoor air temperature's column
AMBIENT = "T_amb"
#: daily means needed to tell how a boundary follows the zone
MIN_DAYS = 3


@dataclasses.dataclass(frozen=True)
class OutdoorHLC:
    """The HLC referenced to the outdoor air (see the module).

    Attributes:
        value: HLC_outdoor [W/K].
        std: its standard error [W/K].
        ci95: (lower, upper) [W/K] at ``level``.
        level: confidence level.
        hlc: the HLC with every temperature input held [W/K].
        follow: per measured boundary, ``{"share": k_b, "alpha": α_b, "alpha_std": …}``.
        method: the parameter covariance the interval rests on.
    """

    value: float
    std: float
    ci95: tuple[float, float]
    level: float
    hlc: float
    follow: dict
    method: str

    def to_dict(self) -> dict:
        fin = lambda v: float(v) if math.isfinite(v) else None  # noqa: E731
        return {
            "value": self.value,
            "std": fin(self.std),
            "ci95": [fin(v) for v in self.ci95],
            "level": self.level,
            "hlc_held": self.hlc,
            "boundaries": self.follow,
            "method": self.method + " + the boundaries' regression on the daily means",
        }


def boundary_follow(data, boundaries, zone: str = "T_zon") -> dict[str, tuple[float, float]]:
    """``{b: (α_b, std α_b)}``: how far each boundary temperature follows ``zone`` rather than
    the outdoor air, by least squares over the daily means of ``data`` (``T_b − T_amb`` on
    ``T_zon − T_amb`` with an intercept). A boundary with fewer than :data:`MIN_DAYS` daily
    means, or whose zone–outdoor difference does not vary, is left out."""
    frame = data.frame if hasattr(data, "frame") else data
    days = frame.resample("1D").mean()
    out = {}
    for b in boundaries:
        if b not in days or zone not in days or AMBIENT not in days:
            continue
        x = (days[zone] - days[AMBIENT]).to_numpy(float)
        y = (days[b] - days[AMBIENT]).to_numpy(float)
        ok = np.isfinite(x) & np.isfinite(y)
        n = int(ok.sum())
        if n < MIN_DAYS or np.ptp(x[ok]) <= 0:
            continue
        X = np.c_[np.ones(n), x[ok]]
        coef, *_ = np.linalg.lstsq(X, y[ok], rcond=None)
        resid = y[ok] - X @ coef
        s2 = float(resid @ resid) / (n - 2) if n > 2 else math.nan
        var = s2 * np.linalg.inv(X.T @ X)[1, 1]
        out[b] = (float(coef[1]), math.sqrt(var) if var >= 0 else math.nan)
    return out


def _function(model, free: tuple[str, ...], fixed: tuple[str, ...], jq: int, jb: tuple[int, ...]):
    """Compiled (p_free, fixed_values, α [len jb]) -> ((HLC_outdoor, HLC, k_b…), gradient in
    p), float64 arrays of those sizes; kept, as an exported program, for later processes too
    (:func:`jaxbox._exported.compile_program`, as the KPIs' program)."""

    from ._kpi import _steady_state, _value_and_jacobian_program

    def build():
        def g(p, fv, alpha):
            theta = {n: p[i] for i, n in enumerate(free)}
            theta.update({n: fv[i] for i, n in enumerate(fixed)})
            gain = _steady_state(model, theta)[0]
            hlc = 1.0 / gain[0, jq]
            k = jnp.stack([gain[0, j] for j in jb]) if jb else jnp.zeros(0)
            return jnp.concatenate([jnp.stack([hlc * (1.0 - k @ alpha), hlc]), k])

        key = ("kpi_outdoor", model.structure, free, fixed, jq, jb)
        return _value_and_jacobian_program(key, g, len(free), len(fixed), len(jb))

    return cached(("kpi_outdoor", model, free, fixed, jq, jb), build)[0]


def outdoor_hlc(
    result, uncertainty=None, *, data=None, interval: str = "hac", level: float | None = None
) -> OutdoorHLC | None:
    """The HLC of a fit referenced to the outdoor air (see the module), with its interval.

    Args:
        result: a :class:`~jaxbox.fit.FitResult` of a one-zone model with one heat input and
            the outdoor air ``T_amb`` among its inputs.
        uncertainty: its :class:`~jaxbox.validate.Uncertainty` (computed when ``None``).
        data: the data the boundaries' behaviour is read from (default: the fit's own; the whole
            record tells it better).
        interval: ``"hac"`` (default) or ``"white"``: the parameter covariance, as
            :func:`~jaxbox.validate.kpis`.
        level: confidence level (default: that of ``uncertainty``).

    Returns:
        :class:`OutdoorHLC`, or ``None`` for a model of several zones or heat inputs, without
        ``T_amb``, or with a boundary whose behaviour the data do not tell (fewer than
        :data:`MIN_DAYS` days).
    """
    from ._args import check_fit, check_interval
    from ._hlc_hac import HAC, WHITE, robust_covariance
    from ._kpi import _delta_std, _prepared, kpi_inputs

    check_interval(interval)
    model = check_fit(result).problem.model
    heat, _ = kpi_inputs(model)
    temps = [u for u in model.inputs if u.startswith("T_")]
    one_zone = len(model.outputs) == 1 and model.outputs[0].startswith("T_")
    if not one_zone or len(heat) != 1 or AMBIENT not in temps:
        return None
    boundaries = tuple(u for u in temps if u != AMBIENT)
    follow = boundary_follow(result.data if data is None else data, boundaries)
    if set(follow) != set(boundaries):
        return None
    fit = _prepared(result, uncertainty, level, interval)
    uncertainty, (free, fixed, p, fv) = fit.uncertainty, fit.arrays
    alpha = np.asarray([follow[b][0] for b in boundaries], dtype=float)
    jq = model.inputs.index(heat[0])
    jb = tuple(model.inputs.index(b) for b in boundaries)
    values, grad = _function(model, free, fixed, jq, jb)(
        np.asarray(p, dtype=float), np.asarray(fv, dtype=float), alpha
    )
    values, grad = np.asarray(values), np.asarray(grad)
    if interval == "hac":
        cov, method = np.asarray(robust_covariance(result, uncertainty).cov_free, float), HAC
    else:
        cov, method = np.asarray(uncertainty.cov_free, dtype=float), WHITE
    var = float(_delta_std(grad[:1], cov, uncertainty, interval)[0]) ** 2
    hlc, shares = float(values[1]), values[2:]
    var += sum((hlc * k * follow[b][1]) ** 2 for k, b in zip(shares, boundaries, strict=True))
    std = math.sqrt(var) if math.isfinite(var) and var >= 0 else math.nan
    level, tq = fit.level, fit.t_quantile
    v = float(values[0])
    return OutdoorHLC(
        value=v,
        std=std,
        ci95=(v - tq * std, v + tq * std),
        level=level,
        hlc=hlc,
        follow={
            b: {"share": float(k), "alpha": follow[b][0], "alpha_std": follow[b][1]}
            for k, b in zip(shares, boundaries, strict=True)
        },
        method=method,
    )
