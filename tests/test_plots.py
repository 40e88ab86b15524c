"""Every validation plot renders headless; the fit report is strict JSON; plots save to files."""

import dataclasses
import io
import json

import numpy as np
import pytest
from matplotlib.figure import Figure

from jaxbox.data import Dataset
from jaxbox.fit import StartReport, fit_model
from jaxbox.simulate import simulate_model
from jaxbox.validate import (
    fit_report,
    plot_autocorrelation,
    plot_confidence_intervals,
    plot_cross_correlation,
    plot_fit,
    plot_multistart,
    plot_prediction,
    plot_residuals,
    plot_residuals_vs_inputs,
    prediction_performance,
    save_plots,
    uncertainty,
    validate,
)

N = 200
STEP = 3600.0
TRUTH = {"C_zon": 5e6, "R_wal": 0.01, "gA": 2.0, "T_zon0": 20.0}
FREE = ("C_zon", "R_wal", "gA", "T_zon0")


def _data(n, irradiance=True):
    rng = np.random.default_rng(0)
    t = np.arange(n) * STEP
    day = 2 * np.pi * t / 86400.0
    u = {
        "T_amb": 8.0 + 5.0 * np.sin(day - 2.0) + rng.normal(0, 0.5, n),
        "Q_hea": 1500.0 * (rng.random(n) > 0.5),
        "I_glo_hor": np.maximum(0.0, 600.0 * np.sin(day - 1.5)) * irradiance,
    }
    clean = Dataset.from_arrays(t, {**u, "T_zon": np.zeros(n)})
    y = simulate_model("Zon", TRUTH, clean).y[:, 0]
    return clean.with_columns(T_zon=y + rng.normal(0, 0.1, n))


def _several_starts(res):
    """The result with a multistart report of 5 starts (two local optima and a failure)."""
    p = res.starts.params[0]
    params = np.stack([p, p * 1.000001, p * [3.0, 0.5, 0.2, 1.0], p, p])
    cost = np.asarray([res.cost, res.cost, 4 * res.cost, res.cost, np.nan])
    report = StartReport(
        initial=params * 1.2,
        params=params,
        cost=cost,
        steps=np.full(5, 12),
        status=("converged",) * 4 + ("nonfinite",),
    )
    return dataclasses.replace(res, starts=report, best=0)


@pytest.fixture(scope="module")
def fitted():
    ident, valid = _data(2 * N).split()
    res = fit_model("Zon", ident, starts=np.asarray([[TRUTH[n] * 1.1 for n in FREE]]))
    res = _several_starts(res)
    v = validate(res, valid, method="exact")
    return res, valid, v


def _render(fig):
    assert isinstance(fig, Figure)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=50)
    assert buf.tell() > 1000


def test_every_plot_renders(fitted):
    res, valid, v = fitted
    unc = uncertainty(res)
    analysis = v.residual_analysis("auto")
    figures = [
        plot_fit(v),
        plot_fit(v, inputs=["Q_hea"], title="one input"),
        plot_residuals(v),
        plot_residuals_vs_inputs(v),
        plot_residuals_vs_inputs(v, which="cross"),
        plot_autocorrelation(analysis),
        plot_autocorrelation(v),
        plot_cross_correlation(analysis),
        plot_confidence_intervals(unc),
        plot_confidence_intervals(unc, max_rel_ci=None),
        plot_multistart(res),
        plot_prediction(prediction_performance(res, valid)),
    ]
    for fig in figures:
        _render(fig)
    assert len(figures[0].axes) == 1 + 3  # output, then °C, W, W/m² inputs
    assert len(figures[1].axes) == 2


def test_plots_of_auto_validation_only(fitted):
    res, _, _ = fitted
    v = validate(res, method="exact")
    for fig in (plot_fit(v), plot_residuals(v), plot_residuals_vs_inputs(v, which="auto")):
        _render(fig)
    _render(plot_prediction(prediction_performance(res)))
    with pytest.raises(ValueError, match="no data"):
        plot_residuals_vs_inputs(v, which="cross")


def test_confidence_interval_plot_marks_non_identifiable():
    start = np.asarray([[TRUTH[n] for n in FREE]])
    res = fit_model("Zon", _data(N, irradiance=False), starts=start)
    unc = uncertainty(res)
    assert unc.not_identifiable == ("gA",)
    fig = plot_confidence_intervals(unc)
    _render(fig)
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert "not identifiable" in texts


def test_fit_report_is_strict_json(fitted):
    res, valid, v = fitted
    rep = fit_report(res, valid, validation=v)
    text = json.dumps(rep, allow_nan=False)
    back = json.loads(text)
    for key in (
        "params",
        "correlation",
        "residuals",
        "valid",
        "reasons",
        "rmse_auto",
        "rmse_cross",
        "se_auto",
        "se_cross",
        "multistart",
        "prediction",
        "identifiability",
    ):
        assert key in back
    row = back["params"]["R_wal"]
    assert set(row) >= {"value", "unit", "lower", "upper", "at_bound", "std", "ci95", "rel_ci"}
    assert row["ci95"][0] < row["value"] < row["ci95"][1]
    assert row["rel_ci"] == pytest.approx(uncertainty(res).table()["R_wal"]["rel_ci"])
    assert back["params"]["T_zon0"]["std"] is None  # initial states: no interval by default
    assert set(back["correlation"]) == {"C_zon", "R_wal", "gA"}
    assert back["residuals"]["auto"]["T_zon"]["ljung_box"]["lags"] == 24
    assert back["residuals"]["cross"]["T_zon"]["stats"]["n"] == N
    assert isinstance(back["valid"], bool) and isinstance(back["reasons"], list)
    assert back["rmse_cross"]["T_zon"] == pytest.approx(v.rmse_cross["T_zon"])
    assert back["multistart"]["n_at_best"] == 3
    with_t0 = fit_report(res, valid, validation=v, include_initial_states=True)
    assert with_t0["params"]["T_zon0"]["std"] > 0


def test_save_plots_writes_every_figure(fitted, tmp_path):
    res, _, v = fitted
    paths = save_plots(res, v, tmp_path / "plots", dpi=50)
    names = {p.stem for p in paths}
    assert names >= {
        "fit",
        "residuals",
        "residuals_vs_inputs",
        "autocorrelation",
        "cross_correlation",
        "confidence_intervals",
        "multistart",
        "prediction",
        "autocorrelation_validation",
    }
    for p in paths:
        assert p.exists() and p.stat().st_size > 1000
