"""Missing inputs in a forecast's history: short gaps bridged as the fits bridge them, the filter
reopened after a long one, the noise of an output-error fit taken before it, and forecasts over
filled inputs left out of calibration and backtest scores. Checked against a Kalman filter
written out here and against the same filter over data filled by pandas."""

import numpy as np
import pandas as pd
import pytest
from test_forecast import STEP, TRUE, _inputs

import jaxbox
from jaxbox.fit import FitError
from jaxbox.forecast import StochasticForm, backtest, forecast
from jaxbox.forecast._bridge import bridge_inputs
from jaxbox.forecast._form import noise_from_residuals
from jaxbox.stochastic import simulate_sde

#: the history's long gap: Q_hea and T_amb missing at these rows (6 h, longer than 1 h)
LONG = slice(100, 106)
#: a short gap: T_amb missing at one row (1 h, bridged)
SHORT = 60


@pytest.fixture(scope="module")
def data():
    """Eight days of hourly data of ZonWal's stochastic form with the parameters TRUE."""
    n = 8 * 24 + 1
    u = _inputs(n)
    t = np.arange(n) * STEP
    base = jaxbox.data.Dataset.from_arrays(t, {**u, "T_zon": np.zeros(n)})
    y, _ = simulate_sde("ZonWal", TRUE, base, seed=3, x0_std=0.0)
    return base.with_columns(T_zon=y[:, 0])


@pytest.fixture(scope="module")
def gappy(data):
    frame = data.frame.copy()
    frame.iloc[LONG, frame.columns.get_loc("Q_hea")] = np.nan
    frame.iloc[LONG, frame.columns.get_loc("T_amb")] = np.nan
    frame.iloc[SHORT, frame.columns.get_loc("T_amb")] = np.nan
    return jaxbox.data.Dataset(frame, check=False)


def _form() -> StochasticForm:
    model = jaxbox.get_model("ZonWal")
    return StochasticForm(
        model=model,
        params=dict(TRUE),
        hold="foh",
        x0_std=(1.0,) * model.n_states,
        source="ml",
        note="given",
        step=STEP,
    )


def _kalman(sysm, m, P, u, y, reopen=()):
    """The filter written out: update at each sample, predict to the next; at a row of
    ``reopen`` the predicted covariance widened by P0."""
    ms, Ps = [], []
    for k in range(len(u)):
        if k in reopen:
            P = P + sysm.P0
        yk = y[k]
        ok = np.isfinite(yk)
        if ok.any():
            C, D = sysm.C[ok], sysm.D[ok]
            S = C @ P @ C.T + np.diag(sysm.r[ok] ** 2)
            K = P @ C.T @ np.linalg.inv(S)
            m = m + K @ (yk[ok] - C @ m - D @ u[k])
            P = P - K @ S @ K.T
        ms.append(m)
        Ps.append(P)
        if k + 1 < len(u):
            m = sysm.Phi @ m + sysm.G0 @ u[k] + sysm.G1 @ (u[k + 1] - u[k])
            P = sysm.Phi @ P @ sysm.Phi.T + sysm.Q
    return np.array(ms), np.array(Ps)


def test_bridge_fills_by_interpolation_and_names_the_long_gaps(data, gappy):
    names = ["T_amb", "Q_hea"]
    u = gappy.frame[names].to_numpy()
    filled_u, filled, long = bridge_inputs(u, names, gappy.index, STEP, "1h")
    expected = gappy.frame[names].interpolate(method="linear").to_numpy()  # pandas, independent
    np.testing.assert_allclose(filled_u, expected, rtol=0, atol=1e-12)
    assert long == [(LONG.start, LONG.stop)]
    assert filled.sum() == (LONG.stop - LONG.start) + 1 and filled[SHORT]
    assert bridge_inputs(u, names, gappy.index, STEP, "6h")[2] == []  # a 6-h gap is bridged
    # held before the first and after the last value
    edge = u.copy()
    edge[:3, 0] = np.nan
    assert np.all(bridge_inputs(edge, names, gappy.index, STEP)[0][:3, 0] == u[3, 0])
    with pytest.raises(FitError, match=r"input Q_hea has no value in the 193 samples"):
        bridge_inputs(np.column_stack([u[:, 0], np.full(len(u), np.nan)]), names, gappy.index, STEP)


def test_the_filter_bridges_short_gaps_and_reopens_after_long_ones(data, gappy):
    form = _form()
    model = form.model
    bridged = form.filter(gappy, max_gap="6h")
    filled = gappy.frame.interpolate(method="linear")
    assert bridged.reopened == () and bridged.filled.sum() == 7
    same = form.filter(jaxbox.data.Dataset(filled, check=False))
    np.testing.assert_allclose(bridged.m, same.m, rtol=1e-12, atol=1e-10)
    run = form.filter(gappy)  # max_gap 1 h: the 6-h gap reopens the filter
    assert run.reopened == (LONG.stop,)
    assert np.all(np.isnan(run.y[LONG]))  # outputs with guessed inputs are not used
    u = filled[list(model.inputs)].to_numpy()
    y = gappy.frame[list(model.outputs)].to_numpy().copy()
    y[LONG] = np.nan
    sysm = run.system
    m, P = _kalman(sysm, sysm.m0, sysm.P0, u, y, reopen={LONG.stop})
    np.testing.assert_allclose(run.m, m, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(run.P, P, rtol=1e-9, atol=1e-12)
    # reopened: the wall's variance after the gap is the widened one, larger than bridged
    assert run.P[LONG.stop, 1, 1] > bridged.P[LONG.stop, 1, 1]


def test_a_forecast_after_a_long_gap_says_so_and_covers(data, gappy):
    form = _form()
    history = gappy.slice(None, data.index[130])
    out = forecast(form, history, data, horizon="24h")
    assert "reopened after 1 gap(s) longer than max_gap (1 h)" in out.attrs["bridged"]
    assert str(data.index[LONG.stop]) in out.attrs["bridged"]
    z = (out["T_zon_measured"] - out["T_zon_mean"]) / out["T_zon_sd"]
    assert np.mean(np.abs(z) < 1.96) >= 0.8
    # nothing missing: nothing said, the forecast as before
    clean = forecast(form, data.slice(None, data.index[130]), data, horizon="24h")
    assert clean.attrs["bridged"] is None
    # the history's last input missing: the filter's filled value starts the horizon
    last = gappy.frame.copy()
    last.iloc[130, last.columns.get_loc("Q_hea")] = np.nan
    held = forecast(
        form, jaxbox.data.Dataset(last, check=False).slice(None, data.index[130]), data, horizon=4
    )
    assert np.all(np.isfinite(held["T_zon_mean"]))


def test_a_backtest_scores_no_forecast_over_a_missing_input(data, gappy):
    form = _form()
    steps = 6
    table = backtest(form, gappy, horizon=steps, calibrate=False)
    n = len(data)
    bad = set()
    for row in [SHORT, *range(LONG.start, LONG.stop)]:
        bad.update(range(max(0, row - steps), row + 1))  # origins whose rows o … o+H hold it
    expected = len([o for o in range(n - steps) if o not in bad])
    assert table.attrs["origins"] == expected
    assert backtest(form, data, horizon=steps, calibrate=False).attrs["origins"] == n - steps
    calibrated = backtest(form, gappy, horizon=steps)
    assert np.all(np.isfinite(calibrated["rmse"]))


def test_the_noise_of_an_output_error_fit_is_taken_before_the_first_long_gap(data, gappy):
    model = jaxbox.get_model("ZonWal")
    params = {k: v for k, v in TRUE.items() if not k.startswith("sigma")}
    form = noise_from_residuals(model, params, gappy)
    before = gappy.slice(None, data.index[LONG.start - 1]).frame.interpolate(method="linear")
    ref = noise_from_residuals(model, params, jaxbox.data.Dataset(before, check=False))
    for k in ("sigma_zon", "sigma_wal", "sigma_y_zon"):
        assert form.params[k] == pytest.approx(ref.params[k], rel=1e-9)
    early = gappy.frame.copy()
    early.iloc[10:20, early.columns.get_loc("Q_hea")] = np.nan
    with pytest.raises(FitError, match=r"leaves 10 samples, fewer than 24.*--max-gap"):
        noise_from_residuals(model, params, jaxbox.data.Dataset(early, check=False))
    bridged = noise_from_residuals(
        model, params, jaxbox.data.Dataset(early, check=False), max_gap="12h"
    )
    assert bridged.source == "oe"


def test_cli_forecast_over_a_history_with_a_long_gap(tmp_path, data, gappy, capsys):
    """An output-error fit file (its noise estimated from the history up to the gap) and a
    history with a long input gap: the forecast is written and says what was done."""
    import json

    from jaxbox.cli._main import main

    csv = tmp_path / "gappy.csv"
    gappy.frame.to_csv(csv, index_label="time")
    oe = tmp_path / "oe.json"
    phys = {n: {"value": v, "unit": "?"} for n, v in TRUE.items() if not n.startswith("sigma")}
    oe.write_text(json.dumps({"model": "ZonWal", "params": phys}))
    out = tmp_path / "fc.csv"
    args = ["forecast", csv, "--params", oe, "--at", data.index[130], "--out", out]
    code = main([str(a) for a in [*args, "--horizon", "12h"]])
    text = capsys.readouterr()
    assert code == 0, text.err
    assert "missing inputs: 7 sample(s) of the history" in text.out
    assert f"reopened after 1 gap(s) longer than max_gap (1 h), at {data.index[LONG.stop]}" in (
        text.out
    )
    assert len(pd.read_csv(out)) == 12
    code = main([str(a) for a in [*args, "--horizon", "12h", "--max-gap", "6h"]])
    text = capsys.readouterr()
    assert code == 0, text.err
    assert "missing inputs: 7 sample(s)" in text.out and "reopened" not in text.out
