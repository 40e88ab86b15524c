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


@pytest.mark.parametrize(
    ("plot", "words"),
    [
        (lambda res, v: plot_fit(res), ["validation must be a Validation", "FitResult"]),
        (lambda res, v: plot_residuals(None), ["validation must be a Validation"]),
        (lambda res, v: plot_residuals_vs_inputs(res), ["validation must be a Validation"]),
        (lambda res, v: plot_confidence_intervals(res), ["uncertainty must be an Uncertainty"]),
        (lambda res, v: plot_prediction(v), ["must be a PredictionPerformance"]),
        (lambda res, v: plot_multistart(None), ["result must be a fit"]),
    ],
)
def test_plots_of_the_wrong_object_say_what_they_take(fitted, plot, words):
    res, _, v = fitted
    with pytest.raises(TypeError) as err:
        plot(res, v)
    for word in words:
        assert word in str(err.value), str(err.value)


def test_plot_options_are_checked(fitted):
    """Unknown inputs were dropped silently (a name given as a string was read letter by letter:
    no input panel); which='bogus' or 'cross' without validation data said 'no data';
    max_rel_ci of -1 or NaN drew nonsense limits."""
    res, _, v = fitted
    with pytest.raises(ValueError, match="'T_out' are not inputs of Zon; its inputs: T_amb"):
        plot_fit(v, inputs=["T_out"])
    fig = plot_fit(v, inputs="T_amb")
    assert [ax.get_ylabel() for ax in fig.axes] == ["T_zon [°C]", "temperature [°C]"]
    with pytest.raises(ValueError, match="which must be 'auto', 'cross' or 'both'"):
        plot_residuals_vs_inputs(v, which="bogus")
    with pytest.raises(ValueError, match="which='cross': this Validation holds no validation data"):
        plot_residuals_vs_inputs(validate(res, method="exact"), which="cross")
    unc = uncertainty(res)
    for bad in (-1.0, float("nan")):
        with pytest.raises(ValueError, match="max_rel_ci"):
            plot_confidence_intervals(unc, max_rel_ci=bad)


def test_residual_band_with_output_gaps(fitted):
    """An output gap in the identification data (NaN residuals) made the ±2σ band NaN: not
    drawn at all."""
    _, _, v = fitted
    y = v.y_auto.copy()
    y[10:13, 0] = np.nan
    gappy = dataclasses.replace(v, y_auto=y)
    ax = plot_residuals(gappy).axes[0]
    band = [line.get_ydata()[0] for line in ax.lines[-3:-1]]
    e = v.residuals_auto[:, 0]
    expected = 2 * np.std(np.delete(e, [10, 11, 12]))
    assert band == pytest.approx([-expected, expected], rel=1e-12)


def test_save_plots_checks_its_options_before_writing(fitted, tmp_path):
    """A format matplotlib does not write failed at the first figure (matplotlib's message)
    after creating the folder; a Dataset in the validation slot raised AttributeError."""
    res, valid, v = fitted
    with pytest.raises(ValueError, match="fmt must be an image format"):
        save_plots(res, v, tmp_path / "a", fmt="bogus")
    assert not (tmp_path / "a").exists()
    with pytest.raises(ValueError, match="dpi"):
        save_plots(res, v, tmp_path / "b", dpi=0)
    with pytest.raises(TypeError, match="validation must be a Validation"):
        save_plots(res, valid, tmp_path / "c")
    with pytest.raises(TypeError, match="validation must be a Validation"):
        fit_report(res, valid, validation="cached")


def test_save_plots_replaces_earlier_plots_atomically(fitted, tmp_path, monkeypatch):
    """Saving again into the same folder replaces the plots (other files are left alone, no
    temporary file stays); a write that fails leaves the earlier plot whole (savefig wrote over
    it in place)."""
    import os

    res, _, v = fitted
    unc = uncertainty(res)
    out = tmp_path / "plots"
    out.mkdir()
    (out / "fit.png").write_bytes(b"an earlier plot")
    (out / "notes.txt").write_text("mine")
    paths = save_plots(res, v, out, uncertainty=unc, dpi=50)
    assert (out / "fit.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert save_plots(res, v, out, uncertainty=unc, dpi=50) == paths
    assert sorted(p.name for p in out.iterdir()) == sorted([p.name for p in paths] + ["notes.txt"])
    assert (out / "notes.txt").read_text() == "mine"

    (out / "fit.png").write_bytes(b"an earlier plot")

    def refused(src, dst):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(os, "replace", refused)
    with pytest.raises(PermissionError):
        save_plots(res, v, out, uncertainty=unc, dpi=50)
    monkeypatch.undo()
    assert (out / "fit.png").read_bytes() == b"an earlier plot"
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp")]


def test_save_plots_refuses_a_file_where_a_folder_is_needed(fitted, tmp_path):
    """A file given as the folder (or above it) raised FileExistsError from mkdir, naming no
    argument; now refused by name before anything is computed. A folder named like a plot is
    refused before any plot is written (it failed half-way, in savefig)."""
    res, _, v = fitted
    file = tmp_path / "plots.png"
    file.write_bytes(b"not a folder")
    with pytest.raises(NotADirectoryError, match="plots.png' is a file, not a folder"):
        save_plots(res, v, file)
    with pytest.raises(NotADirectoryError, match="lies under .*plots.png', which is a file"):
        save_plots(res, v, file / "sub")
    assert file.read_bytes() == b"not a folder"
    with pytest.raises(TypeError, match="directory must be a folder path"):
        save_plots(res, v, None)
    blocked = tmp_path / "blocked"
    (blocked / "residuals.png").mkdir(parents=True)
    with pytest.raises(IsADirectoryError, match="folders named residuals.png where the plots go"):
        save_plots(res, v, blocked, uncertainty=uncertainty(res), dpi=50)
    assert [p.name for p in blocked.iterdir()] == ["residuals.png"]
