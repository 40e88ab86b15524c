"""Forecasts with uncertainty: the mean against an independent simulation, the bands against a
Monte Carlo of the stochastic model, an output-error fit's noise, coverage, bad input."""

import numpy as np
import pandas as pd
import pytest
import scipy.integrate
import scipy.signal

import jaxbox
from jaxbox.fit import FitError
from jaxbox.forecast import (
    StochasticForm,
    backtest,
    forecast,
    plot_forecast,
    propagate,
    stochastic_form,
)
from jaxbox.stochastic import simulate_sde
from jaxbox.validate import uncertainty

STEP = 3600.0
TRUE = {
    "C_zon": 4.0e6,
    "C_wal": 3.0e7,
    "R_wal": 0.008,
    "gA": 2.0,
    "T_zon0": 20.0,
    "T_wal0": 15.0,
    "sigma_zon": 4e-4,
    "sigma_wal": 1e-4,
    "sigma_y_zon": 0.05,
}


def _inputs(n: int, seed: int = 1) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * STEP
    day = 2 * np.pi * t / 86400.0
    return {
        "T_amb": 5.0 + 4.0 * np.sin(day - 2.0) + rng.normal(0, 0.3, n),
        "I_glo_hor": np.clip(400.0 * np.sin(day - np.pi / 2), 0.0, None),
        "Q_hea": np.where(rng.random(n) < 0.5, 0.0, 1500.0),
    }


@pytest.fixture(scope="module")
def data():
    """Eight days of hourly data of ZonWal's stochastic form with the parameters TRUE."""
    n = 8 * 24 + 1
    u = _inputs(n)
    base = jaxbox.data.Dataset.from_arrays(np.arange(n) * STEP, {**u, "T_zon": np.zeros(n)})
    y, _ = simulate_sde("ZonWal", TRUE, base, seed=3, x0_std=0.0)
    return base.with_columns(T_zon=y[:, 0])


def _form(params: dict, x0_std: float = 0.0) -> StochasticForm:
    model = jaxbox.get_model("ZonWal")
    return StochasticForm(
        model=model,
        params=dict(params),
        hold="foh",
        x0_std=(x0_std,) * model.n_states,
        source="ml",
        note="given",
        step=STEP,
    )


def test_mean_is_the_simulation_when_the_state_is_known(data):
    """No diffusion and an exactly known initial state: the filter's state is the simulated
    one whatever the measurements say, so the forecast mean is the open-loop simulation
    (here scipy's, linear inputs between samples) and its sd is the measurement noise."""
    params = {**TRUE, "sigma_zon": 0.0, "sigma_wal": 0.0}
    form = _form(params)
    garbage = data.with_columns(T_zon=np.full(len(data), 35.0))
    history = garbage.slice(None, data.index[100])
    out = forecast(form, history, data, horizon="30h", calibrate=False)
    model = form.model
    A, B, C, D = model.state_space_numpy(params)
    u = data.array(list(model.inputs))
    t = np.arange(len(data)) * STEP
    _, ysim, _ = scipy.signal.lsim((A, B, C, D), u, t, X0=[20.0, 15.0], interp=True)
    np.testing.assert_allclose(out["T_zon_mean"], ysim[101:131], rtol=0, atol=1e-8)
    np.testing.assert_allclose(out["T_zon_sd"], 0.05, rtol=1e-12)
    assert list(out["step"]) == list(range(1, 31))
    assert out.index[0] == data.index[101]
    lo, hi = out["T_zon_lo95"], out["T_zon_hi95"]
    np.testing.assert_allclose(hi - lo, 2 * 1.959963984540054 * 0.05, rtol=1e-9)


def _monte_carlo(form, m, P, u, steps, n_paths=20000, sub=120, seed=0):
    """Euler–Maruyama of ``dx = (A x + B u(t)) dt + σ dω`` with inputs linear between samples,
    ``sub`` substeps per sample, from ``x ~ N(m, P)``; the measured outputs at the samples."""
    rng = np.random.default_rng(seed)
    model = form.model
    A, B, C, _ = model.state_space_numpy(form.params)
    sig = np.asarray([form.params["sigma_zon"], form.params["sigma_wal"]])
    L = np.linalg.cholesky(P + 1e-15 * np.eye(len(m)))
    x = m + rng.standard_normal((n_paths, len(m))) @ L.T
    h = STEP / sub
    out = []
    for k in range(steps):
        for j in range(sub):
            a = (j + 0.5) / sub
            uk = (1 - a) * u[k] + a * u[k + 1]
            x = x + h * (x @ A.T + uk @ B.T) + np.sqrt(h) * sig * rng.standard_normal(x.shape)
        out.append(x @ C.T + form.params["sigma_y_zon"] * rng.standard_normal((n_paths, 1)))
    return np.stack(out, axis=1)[..., 0]  # [paths, steps]


def test_bands_match_a_monte_carlo_of_the_stochastic_model(data):
    form = _form(TRUE, x0_std=1.0)
    history = data.slice(None, data.index[60])
    steps = 12
    out = forecast(form, history, data, horizon=steps, calibrate=False)
    m = np.asarray(out.attrs["state"])
    P = np.asarray(out.attrs["state_cov"])
    u = data.array(list(form.model.inputs))[60 : 60 + steps + 1]
    y = _monte_carlo(form, m, P, u, steps)
    mean, sd = out["T_zon_mean"].to_numpy(), out["T_zon_sd"].to_numpy()
    # the Monte Carlo's mean within 4 standard errors plus the Euler scheme's O(h) drift
    se = sd / np.sqrt(len(y))
    assert np.all(np.abs(y.mean(axis=0) - mean) < 4 * se + 2e-3)
    np.testing.assert_allclose(y.std(axis=0), sd, rtol=0.03)
    inside95 = np.mean((y >= out["T_zon_lo95"].to_numpy()) & (y <= out["T_zon_hi95"].to_numpy()), 0)
    inside50 = np.mean((y >= out["T_zon_lo50"].to_numpy()) & (y <= out["T_zon_hi50"].to_numpy()), 0)
    assert np.all(np.abs(inside95 - 0.95) < 0.01)
    assert np.all(np.abs(inside50 - 0.50) < 0.02)
    # the uncertainty grows with the horizon (diffusion, no measurement)
    assert np.all(np.diff(sd) > 0)


def test_backtest_of_the_true_model_covers_at_its_nominal_levels(data):
    """Forecasts of data drawn from the model itself: the 95 % band holds about 95 % of the
    measurements at every horizon, the 50 % band about half."""
    table = backtest(_form(TRUE, x0_std=1.0), data, start=data.index[24], horizon="12h")
    assert set(table["step"]) == set(range(1, 13))
    assert table["n"].min() > 100
    assert table["cover95"].mean() == pytest.approx(0.95, abs=0.03)
    assert table["cover50"].mean() == pytest.approx(0.50, abs=0.08)
    # the forecast sd at 1 h is near the measurement noise plus one hour of diffusion
    assert table["sd"].iloc[0] == pytest.approx(np.hypot(0.05, 4e-4 * 60), rel=0.25)


def test_calibration_equals_the_standardised_errors_of_forecasts_over_the_history(data):
    """The factors against forecasts made one origin at a time by :func:`forecast` (uncalibrated):
    per horizon step, the larger of the mean squared standardised error over the whole history
    and over its last day of origins, counting only targets within the history, at least 1/4."""
    wrong = _form({**TRUE, "gA": 0.0, "R_wal": 0.7 * TRUE["R_wal"]}, x0_std=1.0)
    history = data.slice(None, data.index[80])
    steps = 6
    z2 = []
    for o in range(0, 80):
        f = forecast(wrong, data.slice(None, data.index[o]), data, horizon=steps, calibrate=False)
        e = (f["T_zon_measured"] - f["T_zon_mean"]).where(f.index <= history.index[-1])
        z2.append((e / f["T_zon_sd"]).to_numpy() ** 2)
    z2 = np.asarray(z2)  # [origin, step]: NaN where the target lies after the history
    assert np.isnan(z2[79, 1]) and np.isfinite(z2[79, 0]) and np.isfinite(z2[78, 1])
    expected = np.array(
        [
            max(np.nanmean(z2[: 81 - h, h - 1]), np.nanmean(z2[81 - h - 24 : 81 - h, h - 1]), 0.25)
            for h in range(1, steps + 1)
        ]
    )
    out = forecast(wrong, history, data, horizon=steps)
    raw = forecast(wrong, history, data, horizon=steps, calibrate=False)
    np.testing.assert_allclose(out["T_zon_sd"] / raw["T_zon_sd"], np.sqrt(expected), rtol=1e-8)
    np.testing.assert_allclose(out["T_zon_mean"], raw["T_zon_mean"], rtol=0)
    assert expected[-1] > 2.0 and "80 in-sample forecasts" in out.attrs["calibration"]
    assert raw.attrs["calibration"] == "none (calibrate=False)"
    short = forecast(wrong, data.slice(None, data.index[20]), data, horizon=steps)
    assert short.attrs["calibration"].startswith("none: 15 in-sample forecasts")
    with pytest.raises(FitError, match="calibrate must be True or False, got 'yes'"):
        forecast(wrong, history, data, horizon=steps, calibrate="yes")


def test_a_backtest_calibrates_each_origin_as_a_forecast_there_would(data):
    """Each origin of a backtest gets the bands :func:`forecast` gives with the data up to it;
    origins with too little history before them keep the raw bands."""
    wrong = _form({**TRUE, "gA": 0.0, "R_wal": 0.7 * TRUE["R_wal"]}, x0_std=1.0)
    steps = 6
    table = backtest(wrong, data, start=data.index[20], horizon=steps, every=40)
    assert "4 of 5 origins calibrated" in table.attrs["calibration"]
    for o in (100, 140):
        f = forecast(wrong, data.slice(None, data.index[o]), data, horizon=steps)
        g = forecast(wrong, data.slice(None, data.index[o]), data, horizon=steps, calibrate=False)
        one = backtest(wrong, data, start=data.index[o], horizon=steps, every=1000)
        np.testing.assert_allclose(one["sd"], f["T_zon_sd"], rtol=1e-8)
        assert np.all(f["T_zon_sd"] > g["T_zon_sd"])
    early = backtest(wrong, data, start=data.index[20], horizon=steps, every=1000)
    raw = backtest(wrong, data, start=data.index[20], horizon=steps, every=1000, calibrate=False)
    np.testing.assert_allclose(early["sd"], raw["sd"], rtol=1e-12)
    assert "0 of 1 origins calibrated" in early.attrs["calibration"]


def test_calibrated_bands_of_a_wrong_model_cover_and_of_the_true_model_stay(data):
    """A model without its solar gain and with a wrong loss: its own bands hold far fewer than
    95 % of the later measurements; calibrated on the data before the scored forecasts they hold
    about as many as they should. The true model's bands barely move."""
    wrong = _form({**TRUE, "gA": 0.0, "R_wal": 0.7 * TRUE["R_wal"]}, x0_std=1.0)
    start = data.index[96]
    raw = backtest(wrong, data, start=start, horizon="12h", calibrate=False)
    cal = backtest(wrong, data, start=start, horizon="12h")
    assert raw["cover95"].mean() < 0.7
    assert cal["cover95"].mean() > 0.85
    assert "85 of 85 origins calibrated" in cal.attrs["calibration"]
    true = backtest(_form(TRUE, x0_std=1.0), data, start=start, horizon="12h")
    true_raw = backtest(_form(TRUE, x0_std=1.0), data, start=start, horizon="12h", calibrate=False)
    assert np.all(true["sd"] <= 1.25 * true_raw["sd"])
    assert true["cover95"].mean() == pytest.approx(0.95, abs=0.04)


@pytest.fixture(scope="module")
def oe_fit(data):
    ident = data.slice(None, data.index[24 * 6])
    return jaxbox.fit_model("ZonWal", ident, starts=2)


def test_output_error_fit_gets_noise_from_its_residuals_and_says_so(oe_fit, data):
    form = stochastic_form(oe_fit)
    assert form.source == "oe" and "residuals" in form.note
    assert stochastic_form(oe_fit) is form  # estimated once per result
    assert set(form.params) == set(TRUE)
    # the innovations' level: measurement noise plus an hour of diffusion, within 30 %
    one_step = np.hypot(form.params["sigma_y_zon"], form.params["sigma_zon"] * 60)
    assert one_step == pytest.approx(np.hypot(0.05, 4e-4 * 60), rel=0.3)
    history = data.slice(None, data.index[24 * 6])
    out = oe_fit.forecast(history, data, horizon="24h")
    assert out.attrs["source"] == "oe" and "residuals" in out.attrs["noise"]
    assert "T_zon_measured" in out
    z = (out["T_zon_measured"] - out["T_zon_mean"]) / out["T_zon_sd"]
    assert np.mean(np.abs(z) < 1.96) >= 0.8  # 24 correlated values: a loose check
    with pytest.raises(FitError, match=r"pass parameters=uncertainty\(result\)"):
        oe_fit.forecast(history, data, horizon="24h", parameters=True)
    wide = oe_fit.forecast(history, data, horizon="24h", parameters=uncertainty(oe_fit))
    assert wide.attrs["parameters"] and np.all(wide["T_zon_sd"] >= out["T_zon_sd"])
    np.testing.assert_allclose(wide["T_zon_mean"], out["T_zon_mean"], rtol=0)


def test_bad_input_gets_one_clear_line(data):
    form = _form(TRUE, x0_std=1.0)
    history = data.slice(None, data.index[150])
    with pytest.raises(FitError, match=r"horizon reaches .* but the future inputs end at"):
        forecast(form, history, data, horizon="72h")
    with pytest.raises(FitError, match="continue the history"):
        forecast(form, history, data.slice(data.index[160], None), horizon=2)
    with pytest.raises(FitError, match="whole number of samples"):
        forecast(form, history, data, horizon="90min")
    with pytest.raises(TypeError, match="expected a fit"):
        forecast({"C_zon": 1.0}, history, data, horizon=2)
    gap = data.frame.copy()
    gap.loc[data.index[152], "Q_hea"] = np.nan
    with pytest.raises(FitError, match="future input Q_hea is missing"):
        forecast(form, history, jaxbox.data.Dataset(gap, check=False), horizon=5)


def test_plot_forecast_draws_one_panel_per_output(data):
    form = _form(TRUE, x0_std=1.0)
    history = data.slice(None, data.index[100])
    out = forecast(form, history, data, horizon=24)
    fig = plot_forecast(out, history)
    assert len(fig.axes) == 1
    assert fig.axes[0].get_ylabel() == "T_zon [°C]"
    with pytest.raises(TypeError, match="DataFrame of a forecast"):
        plot_forecast(pd.DataFrame({"a": [1]}))


# ---- jaxbox forecast ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def files(data, tmp_path_factory):
    """The data as a CSV, an ML-like fit file (noise given) and an output-error one."""
    import json

    folder = tmp_path_factory.mktemp("forecast")
    csv = folder / "building.csv"
    data.frame.to_csv(csv, index_label="time")
    ml = folder / "ml.json"
    ml.write_text(json.dumps({"model": "ZonWal", "params": TRUE, "x0_std": [1.0, 1.0]}))
    oe = folder / "oe.json"
    phys = {n: {"value": v, "unit": "?"} for n, v in TRUE.items() if not n.startswith("sigma")}
    oe.write_text(json.dumps({"model": "ZonWal", "params": phys}))
    return folder, csv, ml, oe


def _cli(args, capsys):
    from jaxbox.cli._main import main

    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_cli_backtest_prints_rmse_and_coverage_and_writes_the_csv(files, data, capsys):
    folder, csv, ml, _ = files
    out, png = folder / "f.csv", folder / "f.png"
    at = str(data.index[120])
    code, stdout, err = _cli(
        ["forecast", csv, "--params", ml, "--at", at, "--horizon", "24h", "--out", out]
        + ["--plot", png],
        capsys,
    )
    assert code == 0, err
    assert "backtest T_zon: RMSE" in stdout and "95 % band holds" in stdout
    frame = pd.read_csv(out, index_col="time", parse_dates=True)
    assert len(frame) == 24 and frame.index[0] == data.index[121]
    assert {"T_zon_mean", "T_zon_sd", "T_zon_lo95", "T_zon_hi95", "T_zon_measured"} <= set(frame)
    # the same numbers as the library's forecast
    ref = forecast(_form(TRUE, 1.0), data.slice(None, at), data, horizon="24h")
    np.testing.assert_allclose(frame["T_zon_mean"], ref["T_zon_mean"], rtol=1e-10)
    err_ = frame["T_zon_measured"] - frame["T_zon_mean"]
    rmse = float(np.sqrt(np.mean(err_**2)))
    assert f"RMSE {rmse:.3f} K" in stdout
    assert png.stat().st_size > 1000


def test_cli_future_inputs_and_the_output_error_noise(files, data, capsys):
    folder, csv, _, oe = files
    future = folder / "future.csv"
    data.frame[["T_amb", "Q_hea", "I_glo_hor"]].iloc[101:113].to_csv(future, index_label="time")
    out = folder / "g.csv"
    args = ["forecast", csv, "--params", oe, "--at", data.index[100], "--out", out]
    code, stdout, err = _cli([*args, "--inputs", future, "--horizon", "12h"], capsys)
    assert code == 0, err
    assert "noise estimated from its residuals" in stdout and "backtest" not in stdout
    assert len(pd.read_csv(out)) == 12
    # a horizon beyond the future inputs: one line
    code, _, err = _cli([*args, "--inputs", future, "--horizon", "24h"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert "horizon reaches" in err and "future inputs end at" in err


def test_cli_fit_file_of_another_model(files, data, capsys):
    folder, csv, ml, _ = files
    args = ["forecast", csv, "--at", data.index[100], "--out", folder / "h.csv"]
    code, _, err = _cli([*args, "--params", ml, "--model", "Zon"], capsys)
    assert code == 2 and "is a fit of ZonWal, not of --model Zon" in err
    other = folder / "other.json"
    other.write_text('{"params": {"C_zon": 1e6, "R_wal": 0.01, "gA": 1, "T_zon0": 20}}')
    code, _, err = _cli([*args, "--params", other, "--model", "ZonWal"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert "was it fitted with another model?" in err


# ---- heat demand for a setpoint -----------------------------------------------------------------


@pytest.fixture(scope="module")
def zoo_building():
    from jaxbox.datasets import make_zoo

    (b,) = make_zoo(
        1,
        seed=11,
        structure="Zon+Wal",
        step="60min",
        days=10,
        gaps=0.0,
        offset=0.0,
        heating="prbs",
        noise=0.05,
    )
    return b


def _true_response(b, x0, origin: int, q, steps: int):
    """The true building (its continuous model, scipy's integrator) from state ``x0`` at sample
    ``origin``: the weather linear between samples, the heater's power constant over each
    interval (``q[k]`` over the k-th); the zone temperature at the samples after ``origin``."""
    model = jaxbox.get_model(b.structure)
    A, B, C, _ = model.state_space_numpy(b.params)
    u = b.data.array(list(model.inputs))[origin : origin + steps + 1].copy()
    j = model.inputs.index("Q_hea")
    dt = b.data.step
    out = []
    x = np.asarray(x0, float)
    for k in range(steps):

        def f(s, xx, k=k):
            uk = u[k] + (u[k + 1] - u[k]) * s / dt
            uk[j] = q[k]
            return A @ xx + B @ uk

        sol = scipy.integrate.solve_ivp(f, (0, dt), x, method="LSODA", rtol=1e-11, atol=1e-9)
        x = sol.y[:, -1]
        out.append(C @ x)
    return np.asarray(out)[:, 0]


def _true_state(b, origin: int):
    """The true state at sample ``origin``: the noise-free simulation of the truth."""
    model = jaxbox.get_model(b.structure)
    A, B, C, D = model.state_space_numpy(b.params)
    u = b.data.array(list(model.inputs))[: origin + 1]
    t = np.arange(origin + 1) * b.data.step
    x0 = [b.params[n.T0] for n in model.network.nodes]
    _, _, x = scipy.signal.lsim((A, B, C, D), u, t, X0=x0, interp=True)
    return x[-1]


def test_heat_demand_of_the_true_model_holds_the_true_building(zoo_building):
    """With the true model told the state, the planned power drives the true building (scipy)
    exactly to the setpoint where the heater can, and to the forecast float where it cannot
    (a warning says when)."""
    from jaxbox.forecast import SetpointWarning, heat_demand
    from jaxbox.stochastic import noise_names

    b = zoo_building
    model = jaxbox.get_model(b.structure)
    params = dict(b.params)
    params.update({n: 0.0 if not n.startswith("sigma_y") else 0.05 for n in noise_names(model)})
    form = StochasticForm(model, params, "foh", (0.0,) * model.n_states, "ml", "true", STEP)
    origin = 150
    history = b.data.slice(None, b.data.index[origin])
    with pytest.warns(SetpointWarning, match="cannot hold T_zon at the setpoint from"):
        hd = heat_demand(
            form,
            history,
            b.data,
            setpoint=21.0,
            setback="17@22:00-06:00",
            q_max=2000.0,
            horizon="36h",
            samples=50,
        )
    q = hd["Q_hea"].to_numpy()
    assert q.min() >= 0 and q.max() <= 2000.0
    np.testing.assert_allclose(form.filter(history).m[-1], _true_state(b, origin), atol=1e-8)
    true = _true_response(b, _true_state(b, origin), origin, q, len(hd))
    np.testing.assert_allclose(hd["T_zon"], true, atol=1e-6)  # held or floating alike
    held = (q > 0) & (q < 2000.0)
    assert held.sum() > 10 and hd["saturated"].any() and (q == 0).any()
    np.testing.assert_allclose(true[held], hd["setpoint"][held], atol=1e-6)
    assert hd.attrs["energy_kwh"] == pytest.approx(q.sum() * STEP / 3.6e6)
    sat = hd["saturated"].to_numpy()
    assert np.all(true[sat] < hd["setpoint"].to_numpy()[sat] - 0.05)


def test_heat_demand_of_an_identified_model_on_the_true_building(zoo_building):
    """A model identified from the building's noisy data: its plan holds the true building
    within 0.2 K of the setpoint, for an energy within 3 % of the true model's plan, and the
    true model's energy lies in its 95 % band widened by that error."""
    from jaxbox.forecast import heat_demand

    b = zoo_building
    ident = b.data.slice(None, b.data.index[120])
    fit = jaxbox.fit_model(b.structure, ident, starts=2)
    origin = 150
    history = b.data.slice(None, b.data.index[origin])
    opts = dict(setpoint=20.0, q_max=5000.0, horizon="24h", samples=200)
    hd = fit.heat_demand(history, b.data, **opts)
    model = fit.model
    params = dict(b.params)
    params.update({"sigma_zon": 0.0, "sigma_wal": 0.0, "sigma_y_zon": 0.05})
    truth = heat_demand(
        StochasticForm(model, params, "foh", (0.0, 0.0), "ml", "true", STEP),
        history,
        b.data,
        **opts,
    )
    assert not hd["saturated"].any() and hd["Q_hea"].min() > 0
    true = _true_response(b, _true_state(b, origin), origin, hd["Q_hea"].to_numpy(), len(hd))
    assert np.max(np.abs(true - 20.0)) < 0.2
    assert hd.attrs["energy_kwh"] == pytest.approx(truth.attrs["energy_kwh"], rel=0.03)
    lo, hi = hd.attrs["energy_kwh_lo95"], hd.attrs["energy_kwh_hi95"]
    assert lo < hd.attrs["energy_kwh"] < hi


def test_setback_schedule_and_bad_setpoints():
    from jaxbox.forecast import parse_setback, setpoint_schedule

    index = pd.date_range("2024-01-01 20:00", periods=12, freq="h")
    sp = setpoint_schedule(index, 21.0, "17@22:00-06:00")
    assert list(sp) == [21, 21, 17, 17, 17, 17, 17, 17, 17, 17, 21, 21]
    assert parse_setback("16.5@23:30-05:00") == (16.5, "23:30", "05:00")
    with pytest.raises(FitError, match="TEMPERATURE@HH:MM-HH:MM"):
        parse_setback("17 from 22")
    with pytest.raises(FitError, match="not a clock time"):
        parse_setback("17@25:00-06:00")


def test_cli_heat_demand(files, data, capsys):
    from jaxbox.forecast import SetpointWarning, heat_demand

    folder, csv, ml, _ = files
    out = folder / "demand.csv"
    at = data.index[100]
    args = ["forecast", csv, "--params", ml, "--at", at, "--horizon", "24h", "--out", out]
    code, stdout, err = _cli(
        [
            *args,
            "--setpoint",
            21,
            "--setback",
            "17@22:00-06:00",
            "--q-max",
            400,
            "--plot",
            folder / "d.png",
        ],
        capsys,
    )
    assert code == 0, err
    with pytest.warns(SetpointWarning):
        ref = heat_demand(
            _form(TRUE, 1.0),
            data.slice(None, at),
            data,
            setpoint=21.0,
            setback="17@22:00-06:00",
            q_max=400.0,
            horizon="24h",
        )
    frame = pd.read_csv(out, index_col="time", parse_dates=True)
    np.testing.assert_allclose(frame["Q_hea"], ref["Q_hea"], rtol=1e-9)
    assert f"{ref.attrs['energy_kwh']:.2f} kWh" in stdout
    # 400 W cannot hold this house: one warning line, and the forecast goes on
    assert err.count("\n") == 1 and "cannot hold T_zon at the setpoint" in err
    code, _, err = _cli([*args, "--setpoint", 21], capsys)
    assert code == 2 and "--setpoint needs the heater's maximum power --q-max" in err
    code, _, err = _cli([*args, "--setpoint", 21, "--q-max", 900, "--setback", "17"], capsys)
    assert code == 2 and "TEMPERATURE@HH:MM-HH:MM" in err


def test_parameter_uncertainty_matches_a_monte_carlo_over_the_parameters(data):
    """The variance the estimate's covariance adds to the bands (first order) against the
    spread of the forecast means over parameters drawn from that covariance."""
    names = ("C_zon", "R_wal", "gA")
    sd = np.asarray([0.02 * TRUE["C_zon"], 0.02 * TRUE["R_wal"], 0.03 * TRUE["gA"]])
    corr = np.asarray([[1.0, -0.5, 0.2], [-0.5, 1.0, 0.1], [0.2, 0.1, 1.0]])
    cov = corr * sd[:, None] * sd[None, :]
    form = _form(TRUE, x0_std=1.0)
    history = data.slice(None, data.index[60])
    plain = forecast(form, history, data, horizon=12)
    wide = forecast(form, history, data, horizon=12, parameters=(names, cov))
    assert wide.attrs["parameters"] and not plain.attrs["parameters"]
    added = wide["T_zon_sd"].to_numpy() ** 2 - plain["T_zon_sd"].to_numpy() ** 2
    rng = np.random.default_rng(7)
    u = data.array(list(form.model.inputs))[60:73]
    means = []
    for theta in rng.multivariate_normal([TRUE[n] for n in names], cov, 400):
        f = _form({**TRUE, **dict(zip(names, theta, strict=True))}, x0_std=1.0)
        run = f.filter(history)
        means.append(propagate(run.system, run.m[-1], run.P[-1], u)["y"][:, 0])
    np.testing.assert_allclose(np.var(means, axis=0, ddof=1), added, rtol=0.2)
    np.testing.assert_allclose(wide["T_zon_mean"], plain["T_zon_mean"], rtol=0)
    with pytest.raises(FitError, match="needs a maximum-likelihood fit"):
        forecast(form, history, data, horizon=12, parameters=True)


def test_cli_parameters_from_the_fit_files_covariance(files, data, capsys):
    import json

    folder, csv, _, _ = files
    names = ["C_zon", "R_wal", "gA"]
    sd = {"C_zon": 8e4, "R_wal": 2e-4, "gA": 0.05}
    corr = [[1.0, -0.4, 0.1], [-0.4, 1.0, 0.0], [0.1, 0.0, 1.0]]
    doc = {
        "model": "ZonWal",
        "params": TRUE,
        "x0_std": [1.0, 1.0],
        "table": {n: {"sd": sd[n]} for n in names},
        "correlation": {"names": names, "matrix": corr},
    }
    path = folder / "ml_cov.json"
    path.write_text(json.dumps(doc))
    out = folder / "p.csv"
    at = data.index[100]
    args = ["forecast", csv, "--params", path, "--at", at, "--horizon", "12h", "--out", out]
    code, stdout, err = _cli([*args, "--parameters"], capsys)
    assert code == 0, err
    assert "the bands hold the parameters' uncertainty" in stdout
    s = np.asarray([sd[n] for n in names])
    cov = np.asarray(corr) * s[:, None] * s[None, :]
    ref = forecast(
        _form(TRUE, 1.0), data.slice(None, at), data, horizon="12h", parameters=(names, cov)
    )
    frame = pd.read_csv(out, index_col="time", parse_dates=True)
    np.testing.assert_allclose(frame["T_zon_sd"], ref["T_zon_sd"], rtol=1e-9)
    _, _, ml, _ = files
    code, _, err = _cli(
        ["forecast", csv, "--params", ml, "--at", at, "--out", out, "--parameters"], capsys
    )
    assert code == 2 and "holds no covariance of its parameters" in err


def test_cli_future_inputs_are_read_as_the_data_are(files, data, capsys):
    """A logger's own column names and kW: --map and --unit apply to --inputs FUTURE.csv as to
    DATA (a file of future inputs need not hold the zone temperature), and the forecast is the
    one from the same inputs in canonical names."""
    folder, _, _, oe = files
    names = {"T_amb": "outdoor", "Q_hea": "heat_kW", "I_glo_hor": "sun", "T_zon": "indoor"}
    logger = data.frame.rename(columns=names)
    logger["heat_kW"] = logger["heat_kW"] / 1000.0
    csv, future = folder / "logger.csv", folder / "logger_future.csv"
    logger.to_csv(csv, index_label="time")
    logger.drop(columns=["indoor"]).iloc[101:113].to_csv(future, index_label="time")
    maps = [a for k, v in names.items() for a in ("--map", f"{k}={v}")]
    out, ref = folder / "logger_fc.csv", folder / "canonical_fc.csv"
    args = ["forecast", csv, "--params", oe, "--at", data.index[100], "--horizon", "12h"]
    code, _, err = _cli(
        [*args, *maps, "--unit", "Q_hea=kW", "--inputs", future, "--out", out], capsys
    )
    assert code == 0, err
    canonical = folder / "canonical_future.csv"
    data.frame[["T_amb", "Q_hea", "I_glo_hor"]].iloc[101:113].to_csv(canonical, index_label="time")
    code, _, err = _cli(
        ["forecast", folder / "building.csv", "--params", oe, "--at", data.index[100]]
        + ["--horizon", "12h", "--inputs", canonical, "--out", ref],
        capsys,
    )
    assert code == 0, err
    a, b = pd.read_csv(out), pd.read_csv(ref)
    np.testing.assert_allclose(a["T_zon_mean"], b["T_zon_mean"], rtol=1e-9)


def test_cli_at_after_the_data_is_one_line(files, data, capsys):
    """--at after the last sample: one line naming the data's end (before, the forecast started
    silently from the last sample, or failed on the future inputs)."""
    folder, csv, ml, _ = files
    late = data.index[-1] + pd.Timedelta("5D")
    code, _, err = _cli(
        [
            "forecast",
            csv,
            "--params",
            ml,
            "--at",
            late,
            "--horizon",
            "6h",
            "--out",
            folder / "l.csv",
        ],
        capsys,
    )
    assert code == 2 and err.count("\n") == 1
    assert f"after the data's last sample ({data.index[-1]})" in err
