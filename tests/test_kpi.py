"""Physical KPIs (HLC, solar aperture, time constants) and their delta-method intervals.

References: closed-form values for the one- and two-state models, the analytic gradient of the
one-state model, and a Monte Carlo of the parameter covariance through an independent numpy
computation of the steady-state gain and the eigenvalues.
"""

import dataclasses

import numpy as np
import pytest

from jaxbox.data import Dataset
from jaxbox.fit import fit_model
from jaxbox.models import get_model
from jaxbox.simulate import simulate_model
from jaxbox.validate import _uncertainty, fit_report, kpi_values, kpis, uncertainty

STEP = 3600.0
N = 168


def _data(model, theta, seed=0, sigma=0.05, n=N):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * STEP
    day = 2 * np.pi * t / 86400.0
    u = {
        "T_amb": 8.0 + 5.0 * np.sin(day - 2.0) + rng.normal(0, 0.5, n),
        "Q_hea": 1500.0 * (rng.random(n) > 0.5),
        "I_glo_hor": np.maximum(0.0, 600.0 * np.sin(day - 1.5)),
    }
    clean = Dataset.from_arrays(t, {**u, "T_zon": np.zeros(n)})
    y = simulate_model(model, theta, clean).y[:, 0]
    return clean.with_columns(T_zon=y + rng.normal(0.0, sigma, n))


ZON = {"C_zon": 5e6, "R_wal": 0.01, "gA": 2.0, "T_zon0": 20.0}
ZONWAL = {"C_zon": 2e6, "C_wal": 3e7, "R_wal": 0.008, "gA": 3.0, "T_zon0": 20.0, "T_wal0": 15.0}


@pytest.fixture(scope="module")
def zon_fit():
    free = list(ZON)
    return fit_model("Zon", _data("Zon", ZON), starts=np.asarray([[ZON[n] * 1.1 for n in free]]))


@pytest.fixture(scope="module")
def zonwal_fit():
    free = list(ZONWAL)
    start = np.asarray([[ZONWAL[n] * 1.1 for n in free]])
    return fit_model("ZonWal", _data("ZonWal", ZONWAL, seed=3), starts=start)


def _two_state_taus(C_zon, C_wal, R_wal):
    """τ [h] of ZonWal from the trace and determinant of its 2×2 state matrix."""
    r = R_wal / 2
    a = np.array([[-1 / (r * C_zon), 1 / (r * C_zon)], [1 / (r * C_wal), -2 / (r * C_wal)]])
    tr, det = np.trace(a), np.linalg.det(a)
    disc = np.sqrt(tr * tr / 4 - det)
    lam = np.array([tr / 2 - disc, tr / 2 + disc])
    return np.sort(-1 / lam) / 3600


def test_values_match_closed_forms():
    one = kpi_values("Zon", ZON)
    assert one["hlc"] == pytest.approx(1 / ZON["R_wal"], rel=1e-12)
    assert one["solar_aperture"] == pytest.approx(ZON["gA"], rel=1e-12)
    assert one["time_constants"] == pytest.approx([ZON["R_wal"] * ZON["C_zon"] / 3600], rel=1e-12)
    two = kpi_values("ZonWal", ZONWAL)
    assert two["hlc"] == pytest.approx(1 / ZONWAL["R_wal"], rel=1e-12)
    assert two["apertures"] == {"I_glo_hor": pytest.approx(3.0, rel=1e-12)}
    taus = _two_state_taus(ZONWAL["C_zon"], ZONWAL["C_wal"], ZONWAL["R_wal"])
    assert two["time_constants"] == pytest.approx(taus, rel=1e-10)


def test_two_zones_hlc_is_the_sum_of_the_envelopes():
    """Two zones, each with its own heater, coupled by R_bou: holding both 1 K above ambient
    loses 1/R_wal1 + 1/R_wal2 (no flow through R_bou), and 1 W/m² is worth gA1 + gA2 watts."""
    m = get_model("Zon2IntBou")
    theta = m.defaults()
    theta.update(R_wal1=0.01, R_wal2=0.02, R_bou=0.05, gA1=2.0, gA2=5.0)
    v = kpi_values(m, theta)
    assert v["hlc"] == pytest.approx(100.0 + 50.0, rel=1e-10)
    assert v["solar_aperture"] == pytest.approx(7.0, rel=1e-10)
    assert len(v["time_constants"]) == 4


def test_one_state_intervals_match_the_analytic_gradient(zon_fit):
    unc = uncertainty(zon_fit)
    k = kpis(zon_fit, unc)
    i = {n: j for j, n in enumerate(unc.free)}
    cov = unc.cov_free
    R, C = zon_fit.params["R_wal"], zon_fit.params["C_zon"]
    assert k.hlc.value == pytest.approx(1 / R, rel=1e-12)
    assert k.hlc.std == pytest.approx(np.sqrt(cov[i["R_wal"], i["R_wal"]]) / R**2, rel=1e-9)
    assert k.solar_aperture.std == pytest.approx(np.sqrt(cov[i["gA"], i["gA"]]), rel=1e-9)
    g = np.zeros(len(unc.free))
    g[i["R_wal"]], g[i["C_zon"]] = C / 3600, R / 3600
    assert k.time_constants[0].std == pytest.approx(np.sqrt(g @ cov @ g), rel=1e-9)
    lo, hi = k.hlc.ci95
    assert (lo + hi) / 2 == pytest.approx(k.hlc.value, rel=1e-12)
    assert (hi - lo) / 2 == pytest.approx(unc.t_quantile * k.hlc.std, rel=1e-12)
    assert lo < 1 / ZON["R_wal"] < hi


def _numpy_kpis(draws, free):
    """Independent, for ZonWal: its state matrices written out by hand for every draw, the
    steady state by a linear solve and a general eigensolver (numpy, batched)."""
    p = {n: draws[:, i] for i, n in enumerate(free)}
    g = 2 / p["R_wal"]  # each half of R_wal
    cz, cw = p["C_zon"], p["C_wal"]
    A = np.stack([np.stack([-g / cz, g / cz], -1), np.stack([g / cw, -2 * g / cw], -1)], -2)
    bq = np.stack([1 / cz, 0 * cz], -1)[..., None]
    bs = np.stack([p["gA"] / cz, 0 * cz], -1)[..., None]
    xq = np.linalg.solve(-A, bq)[:, 0, 0]
    xs = np.linalg.solve(-A, bs)[:, 0, 0]
    tau = np.sort(-1 / np.linalg.eigvals(A).real, axis=1) / 3600
    return np.column_stack([1 / xq, xs / xq, tau])


def test_two_state_intervals_match_monte_carlo(zonwal_fit):
    """Delta-method std of every KPI within 10 % of the spread of 4000 parameter draws from
    the fit's covariance (a relative uncertainty of a few percent, so nearly linear)."""
    unc = uncertainty(zonwal_fit)
    k = kpis(zonwal_fit, unc)
    theta = np.asarray([zonwal_fit.params[n] for n in unc.free])
    rng = np.random.default_rng(1)
    draws = rng.multivariate_normal(theta, unc.cov_free, size=4000)
    values = _numpy_kpis(draws, unc.free)
    ours = [k.hlc, k.solar_aperture, *k.time_constants]
    assert np.allclose([x.value for x in ours], _numpy_kpis(theta[None], unc.free)[0], rtol=1e-9)
    mc_std = values.std(axis=0, ddof=1)
    assert np.all(np.isfinite([x.std for x in ours]))
    assert np.allclose([x.std for x in ours], mc_std, rtol=0.1), ([x.std for x in ours], mc_std)
    # the true HLC and aperture inside their intervals
    assert k.hlc.ci95[0] < 1 / ZONWAL["R_wal"] < k.hlc.ci95[1]
    assert k.solar_aperture.ci95[0] < ZONWAL["gA"] < k.solar_aperture.ci95[1]


def test_kpis_in_the_fit_report(zon_fit):
    doc = fit_report(zon_fit)
    hlc = doc["kpis"]["hlc"]
    assert hlc["unit"] == "W/K"
    assert hlc["value"] == pytest.approx(1 / zon_fit.params["R_wal"])
    assert hlc["ci95"][0] < hlc["value"] < hlc["ci95"][1]
    assert len(doc["kpis"]["time_constants"]) == 1


def test_bad_level_or_uncertainty_is_refused(zon_fit, zonwal_fit):
    """A level of 2 gave every indicator an undefined interval (written as None) silently; a
    string for the uncertainty raised AttributeError; another fit's was used as this one's."""
    with pytest.raises(ValueError, match="level must be a confidence level"):
        kpis(zon_fit, level=2.0)
    with pytest.raises(TypeError, match="uncertainty must be an Uncertainty"):
        kpis(zon_fit, "wide")
    with pytest.raises(ValueError, match="uncertainty is of a fit"):
        kpis(zon_fit, uncertainty(zonwal_fit))


def _numbers(k) -> np.ndarray:
    """Every indicator's value, std and interval, and the residual statistics, as one array."""
    rows = [[x.value, x.std, *x.ci95] for x in k.all()]
    res = [k.residuals[n] for n in ("lag1", "ljung_box_p", "bandwidth", "inflation")]
    return np.concatenate([np.ravel(rows), res])


@pytest.mark.parametrize("interval", ["white", "hac"])
def test_kpis_reuse_the_sensitivities_of_the_uncertainty(zonwal_fit, interval, monkeypatch):
    """The HAC covariance (computed for the intervals and for the warning about non-white
    residuals) recomputed the sensitivities the uncertainty already held: now they are computed
    once, with the same numbers as a recomputation."""
    calls = []
    real = _uncertainty.sensitivities
    monkeypatch.setattr(
        _uncertainty, "sensitivities", lambda *a, **k: calls.append(1) or real(*a, **k)
    )
    unc = uncertainty(zonwal_fit)
    reused = kpis(zonwal_fit, unc, interval=interval)
    assert len(calls) == 1
    kpis(zonwal_fit, interval=interval)  # the uncertainty computed inside: reused as well
    assert len(calls) == 2
    bare = dataclasses.replace(unc, _optimum=None)  # an uncertainty without them: recomputed
    again = kpis(zonwal_fit, bare, interval=interval)
    assert len(calls) == 3
    np.testing.assert_allclose(_numbers(reused), _numbers(again), rtol=1e-12, atol=0)
    assert reused.warnings == again.warnings and reused.method == again.method
    # the kept sensitivities are not those of other parameter values: recomputed there
    moved = dict(zonwal_fit.params, R_wal=zonwal_fit.params["R_wal"] * 1.01)
    other = dataclasses.replace(zonwal_fit, params=moved)
    kpis(other, unc, interval=interval)
    assert len(calls) == 4
