"""The HLC referenced to the outdoor air: a measured boundary counted as it behaves in the data.

References: the analytic steady state of a zone between the outdoor air and one measured
boundary (``HLC = 1/R_wal + 1/R_bou``, the boundary's share ``R_wal/(R_wal+R_bou)``), a least
squares of the boundary's daily means by NumPy's ``polyfit``, and central differences of the
analytic formula for the interval.
"""

import numpy as np
import pytest

from jaxbox.data import Dataset
from jaxbox.fit import fit_model
from jaxbox.models import Grammar, parse_structure
from jaxbox.simulate import simulate_model
from jaxbox.validate import boundary_follow, outdoor_hlc, uncertainty
from jaxbox.validate._hlc_outdoor import MIN_DAYS

STEP = 3600.0
N = 24 * 12
TRUTH = {"C_zon": 4e6, "R_wal": 0.01, "R_bou": 0.02, "T_zon0": 20.0}
COLUMNS = ["T_zon", "T_amb", "T_bou", "Q_hea"]


def _model():
    return parse_structure("Zon+Bou").build(Grammar.from_columns(COLUMNS))


def _data(bou, seed=0, n=N):
    """The zone's response to random heating and weather with the boundary ``bou(t, T_amb)``
    (a measured temperature, an input), plus white noise of 0.05 K."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * STEP
    day = 2 * np.pi * t / 86400.0
    weeks = 2 * np.pi * t / (5 * 86400.0)
    t_amb = 6.0 + 4.0 * np.sin(day - 2.0) + 5.0 * np.sin(weeks) + rng.normal(0, 0.3, n)
    u = {"T_amb": t_amb, "T_bou": bou(t, t_amb), "Q_hea": 800.0 * (rng.random(n) > 0.4)}
    clean = Dataset.from_arrays(t, {**u, "T_zon": np.zeros(n)})
    y = simulate_model(_model(), TRUTH, clean).y[:, 0]
    return clean.with_columns(T_zon=y + rng.normal(0, 0.05, n))


def _fit(data):
    start = np.asarray([[TRUTH[n] * 1.05 for n in _model().param_names]])
    return fit_model(_model(), data, starts=start)


@pytest.fixture(scope="module")
def half_following():
    """A boundary half way between the outdoor air and a slowly varying inner temperature."""
    data = _data(lambda t, a: 0.5 * a + 0.5 * (18.0 + 2.0 * np.sin(2 * np.pi * t / 4e5)) + 1.0)
    return data, _fit(data)


def _analytic(theta, alpha):
    g_wal, g_bou = 1 / theta["R_wal"], 1 / theta["R_bou"]
    return g_wal + g_bou * (1 - alpha), g_wal + g_bou


def test_the_boundary_follow_is_a_least_squares_over_the_daily_means(half_following):
    data, _ = half_following
    (alpha, std) = boundary_follow(data, ["T_bou"])["T_bou"]
    days = data.frame.resample("1D").mean()
    x = (days["T_zon"] - days["T_amb"]).to_numpy()
    y = (days["T_bou"] - days["T_amb"]).to_numpy()
    slope, _ = np.polyfit(x, y, 1)
    assert alpha == pytest.approx(slope, rel=1e-10)
    assert 0 < std < 1


def test_outdoor_hlc_against_the_analytic_steady_state(half_following):
    data, result = half_following
    theta = {k: float(v) for k, v in result.params.items()}
    alpha, alpha_std = boundary_follow(data, ["T_bou"])["T_bou"]
    out = outdoor_hlc(result, interval="white")
    expected, held = _analytic(theta, alpha)
    assert out.value == pytest.approx(expected, rel=1e-9)
    assert out.hlc == pytest.approx(held, rel=1e-9)
    share = (1 / theta["R_bou"]) / held
    assert out.follow["T_bou"]["share"] == pytest.approx(share, rel=1e-9)
    assert out.follow["T_bou"]["alpha"] == pytest.approx(alpha, rel=1e-12)
    # the interval: central differences of the analytic formula over the free parameters, the
    # white covariance, and the boundary's regression variance
    unc = uncertainty(result)
    free = list(result.problem.free)
    grad = np.zeros(len(free))
    for i, name in enumerate(free):
        h = 1e-6 * abs(theta[name])
        up, dn = dict(theta), dict(theta)
        up[name] += h
        dn[name] -= h
        grad[i] = (_analytic(up, alpha)[0] - _analytic(dn, alpha)[0]) / (2 * h)
    var = grad @ np.asarray(unc.cov_free) @ grad + (held * share * alpha_std) ** 2
    assert out.std == pytest.approx(np.sqrt(var), rel=1e-5)
    assert out.ci95[0] < out.value < out.ci95[1]
    assert out.ci95[1] - out.value == pytest.approx(out.std * unc.t_quantile, rel=1e-9)
    # the truth's outdoor HLC (the same boundary behaviour) lies within it
    assert out.ci95[0] < _analytic(TRUTH, alpha)[0] < out.ci95[1]


def test_a_boundary_that_follows_the_outdoor_air_counts_fully_one_that_follows_the_zone_not():
    outdoor = _data(lambda t, a: a + 3.0, seed=1)
    r = _fit(outdoor)
    out = outdoor_hlc(r)
    assert abs(out.follow["T_bou"]["alpha"]) < 1e-9
    assert out.value == pytest.approx(out.hlc, rel=1e-9)
    # the measured zone temperature as the boundary (a heated neighbour): α = 1, only the
    # conductance to the outdoor air counts
    zone = outdoor.with_columns(T_bou=outdoor["T_zon"] + 0.5)
    out = outdoor_hlc(r, data=zone)
    assert out.follow["T_bou"]["alpha"] == pytest.approx(1.0, abs=1e-9)
    theta = {k: float(v) for k, v in r.params.items()}
    assert out.value == pytest.approx(1 / theta["R_wal"], rel=1e-6)


def test_without_a_boundary_it_is_the_hlc_and_where_it_does_not_apply_none(half_following):
    data, result = half_following
    short = Dataset.from_arrays(
        data.t[: 24 * (MIN_DAYS - 1)], {c: data[c][: 24 * (MIN_DAYS - 1)] for c in COLUMNS}
    )
    assert outdoor_hlc(result, data=short) is None  # too few days to tell the boundary
    cols = ["T_zon", "T_amb", "Q_hea"]
    plain = Dataset.from_arrays(data.t, {c: data[c] for c in cols})
    zon = fit_model(parse_structure("Zon").build(Grammar.from_columns(cols)), plain)
    out = outdoor_hlc(zon)
    assert out.follow == {} and out.value == pytest.approx(out.hlc, rel=1e-12)
    with pytest.raises(ValueError, match="interval"):
        outdoor_hlc(zon, interval="sandwich")  # refused even where the HLC is the held one
    with pytest.raises(TypeError):
        outdoor_hlc("not a fit")
    with pytest.raises(ValueError, match="level"):
        outdoor_hlc(result, level=1.5)
