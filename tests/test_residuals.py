"""Residual analysis: autocorrelation, whiteness tests, cross-correlation with inputs."""

import json

import numpy as np
import pytest
from scipy import stats

from jaxbox.validate import (
    analyse_residuals,
    autocorrelation,
    cross_correlation,
    cumulated_periodogram,
    ljung_box,
    residual_stats,
)


def _ar1(phi, n, seed):
    rng = np.random.default_rng(seed)
    w = rng.standard_normal(n)
    x = np.empty(n)
    x[0] = w[0]
    for i in range(1, n):
        x[i] = phi * x[i - 1] + w[i]
    return x


def test_autocorrelation_against_direct_formula():
    e = np.random.default_rng(0).standard_normal(300)
    lags, r = autocorrelation(e, 10)
    d = e - e.mean()
    direct = [np.sum(d[: 300 - k] * d[k:]) / np.sum(d * d) for k in range(11)]
    np.testing.assert_allclose(r, direct)
    assert list(lags) == list(range(11)) and r[0] == pytest.approx(1.0)


def test_autocorrelation_of_ar1_decays_geometrically():
    _, r = autocorrelation(_ar1(0.7, 20000, 1), 3)
    np.testing.assert_allclose(r[1:], [0.7, 0.49, 0.343], atol=0.03)


def test_ljung_box_statistic():
    e = np.random.default_rng(2).standard_normal(250)
    lb = ljung_box(e, 12)
    _, r = autocorrelation(e, 12)
    q = 250 * 252 * sum(r[k] ** 2 / (250 - k) for k in range(1, 13))
    assert lb.statistic == pytest.approx(q)
    assert lb.p_value == pytest.approx(stats.chi2.sf(q, 12))
    assert lb.lags == 12


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_white_noise_passes(seed):
    e = np.random.default_rng(seed).normal(0.0, 0.2, 400)
    a = analyse_residuals(e)
    assert a.white
    assert a[0].ljung_box.white and a[0].periodogram.white


def test_whiteness_tests_hold_their_level():
    """Over 400 seeded white-noise series each test rejects at close to its 5 % level.

    Binomial 99.9 % bounds for 400 trials at 5 %: 8 … 35 rejections.
    """
    rng = np.random.default_rng(11)
    lb = cp = 0
    for _ in range(400):
        e = rng.standard_normal(240)
        lb += not ljung_box(e).white
        cp += not cumulated_periodogram(e).white
    lo, hi = stats.binom.interval(0.999, 400, 0.05)
    assert lo <= lb <= hi and lo <= cp <= hi, (lb, cp)


@pytest.mark.parametrize(
    "make",
    [
        lambda rng, n: _ar1(0.5, n, 6),  # a missing slow state
        lambda rng, n: np.sin(2 * np.pi * np.arange(n) / 24) + 0.5 * rng.standard_normal(n),
        lambda rng, n: np.cumsum(rng.standard_normal(n)),  # drift
    ],
    ids=["ar1", "daily", "random_walk"],
)
def test_structured_residuals_fail(make):
    e = make(np.random.default_rng(8), 400)
    a = analyse_residuals(e)
    o = a[0]
    assert not a.white
    assert o.ljung_box.p_value < 1e-6
    assert o.periodogram.p_value < 1e-3
    assert o.acf_outside() > 0.1


def test_cumulated_periodogram_band_is_exact_ks():
    e = np.random.default_rng(9).standard_normal(201)
    cp = cumulated_periodogram(e)
    q = 100  # Fourier frequencies strictly below Nyquist
    assert cp.frequency.size == q and cp.cumulated[-1] == pytest.approx(1.0)
    assert cp.critical == pytest.approx(stats.kstwo.ppf(0.95, q - 1))
    assert np.all(np.diff(cp.cumulated) >= 0)


def test_cross_correlation_finds_a_lagged_input():
    rng = np.random.default_rng(10)
    n = 500
    u = rng.standard_normal(n)
    e = 0.1 * rng.standard_normal(n)
    e[3:] += 0.8 * u[:-3]  # residual follows the input 3 samples later
    lags, r = cross_correlation(e, u, 10)
    assert lags[np.argmax(np.abs(r))] == 3
    a = analyse_residuals(e, u[:, None], input_names=["Q_hea"], max_lag=10)
    summary = a.to_dict()["y0"]["ccf"]["Q_hea"]
    assert summary["at_lag"] == 3 and summary["max_abs"] > 5 * a[0].band
    # a white residual independent of the input stays mostly inside the band
    a0 = analyse_residuals(rng.standard_normal(n), u, input_names=["Q_hea"], max_lag=10)
    assert a0[0].ccf_outside()["Q_hea"] < 0.2


def test_residual_stats():
    e = np.random.default_rng(12).normal(0.5, 2.0, 5000)
    s = residual_stats(e)
    assert s["n"] == 5000
    assert s["mean"] == pytest.approx(0.5, abs=0.1)
    assert s["std"] == pytest.approx(2.0, rel=0.05)
    assert s["rmse"] == pytest.approx(np.sqrt(np.mean(e**2)))
    assert abs(s["skewness"]) < 0.15 and abs(s["kurtosis"]) < 0.3
    assert s["max_abs"] == pytest.approx(np.max(np.abs(e)))


def test_multi_output_analysis_and_json():
    rng = np.random.default_rng(13)
    e = np.column_stack([rng.standard_normal(300), _ar1(0.8, 300, 14)])
    u = rng.standard_normal((300, 2))
    a = analyse_residuals(e, u, output_names=["T_zon", "T_int"], input_names=["T_amb", "Q_hea"])
    assert a.names == ("T_zon", "T_int")
    assert a["T_zon"].white and not a["T_int"].white and not a.white
    d = a.to_dict()
    json.dumps(d, allow_nan=False)
    assert set(d["T_int"]["ccf"]) == {"T_amb", "Q_hea"}
    with pytest.raises(KeyError, match="T_zon"):
        a["T_x"]


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="inf"):
        analyse_residuals(np.array([0.1, np.inf, 0.2, 0.3, 0.1]))
    with pytest.raises(ValueError, match="4 measured samples"):  # NaN: missing samples
        analyse_residuals(np.array([0.1, np.nan, np.nan, 0.3, 0.1]))
    with pytest.raises(ValueError, match="max_lag"):
        autocorrelation(np.zeros(10) + np.arange(10), 20)
    with pytest.raises(ValueError, match="samples"):
        analyse_residuals(np.zeros((10, 1)), np.zeros((9, 1)))
    e = np.random.default_rng(0).standard_normal(40)
    for alpha in (0.0, 1.0, -0.05, 5, float("nan"), "0.05", True):
        with pytest.raises(ValueError, match="alpha must be a significance level"):
            analyse_residuals(e, alpha=alpha)


def test_the_single_tests_check_alpha_and_lags_too():
    """ljung_box and cumulated_periodogram took alpha = 2 or NaN and answered 'not white';
    lags of 1.5 were cut to 1, a string raised int()'s message."""
    e = np.random.default_rng(0).standard_normal(40)
    for test in (ljung_box, cumulated_periodogram):
        for alpha in (2.0, float("nan")):
            with pytest.raises(ValueError, match="alpha must be a significance level"):
                test(e, alpha=alpha)
    with pytest.raises(TypeError, match="lags must be an integer"):
        ljung_box(e, lags=1.5)
    with pytest.raises(TypeError, match="max_lag must be an integer"):
        autocorrelation(e, "5")
    with pytest.raises(TypeError, match="max_lag must be an integer"):
        analyse_residuals(e, max_lag=2.5)
    with pytest.raises(TypeError, match="residuals must be numbers"):
        analyse_residuals("residuals")


def test_a_perfect_fit_is_white_by_definition():
    """All-zero residuals (a perfect fit) gave nan test statistics, p-values and correlations
    (0 / 0), judged 'not white'; now white by definition with a note saying why."""
    rng = np.random.default_rng(3)
    e = np.zeros((60, 2))
    e[:, 1] = rng.standard_normal(60)  # a noisy output beside it keeps its ordinary tests
    e[7, 0] = np.nan  # an output gap changes nothing
    u = rng.standard_normal((60, 1))
    a = analyse_residuals(e, u, output_names=["T_zon", "T_int"], input_names=["T_amb"])
    o = a["T_zon"]
    assert o.white and a["T_int"].white and a.white
    assert (o.ljung_box.statistic, o.ljung_box.p_value) == (0.0, 1.0)
    assert (o.periodogram.statistic, o.periodogram.p_value) == (0.0, 1.0)
    assert o.periodogram.critical > 0
    np.testing.assert_array_equal(o.periodogram.cumulated, o.periodogram.expected)
    np.testing.assert_array_equal(o.acf, np.r_[1.0, np.zeros(o.lags.size - 1)])
    np.testing.assert_array_equal(o.ccf["T_amb"], np.zeros(o.ccf_lags.size))
    assert o.acf_outside() == 0.0 and o.ccf_outside() == {"T_amb": 0.0}
    assert "perfect fit" in o.note and a["T_int"].note == ""
    assert o.stats["std"] == 0.0 and o.stats["skewness"] == 0.0 and o.stats["kurtosis"] == 0.0
    assert o.stats["normality_p"] == 1.0
    d = a.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["T_zon"]["white"] and "perfect fit" in d["T_zon"]["note"]
    assert "note" not in d["T_int"]
    assert d["T_zon"]["acf"]["lag1"] == 0.0
    # the single tests too; a constant offset has nothing left to test either (its mean shows it)
    for series in (np.zeros(30), np.full(30, 0.4)):
        assert ljung_box(series).white and cumulated_periodogram(series).white
    assert "constant offset" in analyse_residuals(np.full(30, 0.4))[0].note
