"""``jaxbox fit --method ml`` and ``jaxbox estimate``: JSON shape, the states CSV, one-line
errors."""

import json

import numpy as np
import pandas as pd
import pytest
from test_stochastic import _dataset
from test_stochastic_ml import STARTS, TI

import jaxbox
from jaxbox.cli._main import main


@pytest.fixture(scope="module")
def csv_file(tmp_path_factory):
    data = _dataset(jaxbox.get_model("BM_Ti"), TI, 300, seed=7, x0_std=1.0)
    path = tmp_path_factory.mktemp("ml") / "building.csv"
    data.frame.to_csv(path, index_label="time")
    return path


@pytest.fixture(scope="module")
def fit_doc(csv_file, tmp_path_factory):
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(
            ["fit", str(csv_file), "--model", "BM_Ti", "--method", "ml"]
            + ["--starts", str(STARTS), "--json"]
        )
    assert code == 0
    path = tmp_path_factory.mktemp("fit") / "fit.json"
    path.write_text(out.getvalue())
    return json.loads(out.getvalue()), path


def test_fit_method_ml_json(fit_doc):
    doc, _ = fit_doc
    assert doc["method"] == "ml"
    assert {"loglik", "aic", "bic", "residuals", "k_step_rmse", "simulation_rmse"} <= set(doc)
    assert {"sigma_zon", "sigma_y_zon", "C_zon"} <= set(doc["params"])
    assert doc["aic"] == pytest.approx(2 * doc["n_free"] - 2 * doc["loglik"])
    lb = doc["residuals"]["outputs"]["T_zon"]["ljung_box"]
    assert 0 <= lb["p_value"] <= 1
    assert doc["table"]["R_wal"]["sd"] > 0
    assert doc["data"]["n_train"] == 150


def test_estimate_writes_states(fit_doc, csv_file, tmp_path, capsys):
    _, path = fit_doc
    out = tmp_path / "states.csv"
    code = main(
        ["estimate", str(csv_file), "--model", "BM_Ti", "--params", str(path), "--out", str(out)]
        + ["--json"]
    )
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    frame = pd.read_csv(out, index_col="time")
    assert len(frame) == 300
    assert {"T_zon_filtered", "T_zon_filtered_sd", "T_zon_smoothed", "T_zon_innovation"} <= set(
        frame.columns
    )
    assert summary["current"]["states"]["T_zon"] == pytest.approx(frame["T_zon_filtered"].iloc[-1])
    # smoothing never increases the uncertainty of the filter
    assert np.all(frame["T_zon_smoothed_sd"] <= frame["T_zon_filtered_sd"] + 1e-12)


def test_fit_method_ml_text(csv_file, capsys):
    code = main(["fit", str(csv_file), "--model", "BM_Ti", "--method", "ml", "--starts", "4"])
    assert code == 0
    out = capsys.readouterr().out
    assert "log-likelihood" in out and "Ljung–Box" in out and "k-step RMSE" in out


def test_bad_input_is_one_line(csv_file, tmp_path, capsys):
    code = main(["fit", str(csv_file), "--model", "BM_Ti", "--method", "ml", "--fix", "sigma_x=1"])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "sigma_x" in err[0]
    bad = tmp_path / "p.json"
    bad.write_text(json.dumps({"params": {"C_zon": 5e6}}))
    code = main(
        ["estimate", str(csv_file), "--model", "BM_Ti", "--params", str(bad)]
        + ["--out", str(tmp_path / "s.csv")]
    )
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "sigma_y_zon" in err[0]


def test_select_method_ml_by_likelihood_ratio(csv_file, capsys):
    """Data of a one-state SDE: the two-state model is no significant improvement."""
    argv = ["select", str(csv_file), "--models", "BM_Ti,BM_TiTe", "--method", "ml"]
    code = main([*argv, "--starts", "4", "--json"])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["method"] == "ml" and [r["model"] for r in doc["table"]] == ["BM_Ti", "BM_TiTe"]
    two = doc["table"][1]
    assert two["df"] == two["n_free"] - doc["table"][0]["n_free"] and 0 <= two["pvalue"] <= 1
    assert doc["accepted"] == "BM_Ti"
    code = main([*argv, "--starts", "4"])
    assert code == 0
    assert "accepted: BM_Ti" in capsys.readouterr().out
    code = main([*argv, "--out", "somewhere"])
    assert code == 2 and "--out" in capsys.readouterr().err


def test_estimate_with_initial_spreads_of_another_model_is_one_line(csv_file, tmp_path, capsys):
    """A fit document whose x0_std has one value per state of another model was zipped
    against the states and failed with zip()'s message; it names the counts now."""
    doc = tmp_path / "p.json"
    doc.write_text(json.dumps({"params": dict(TI), "x0_std": [1.0, 1.0]}))
    code = main(
        ["estimate", str(csv_file), "--model", "BM_Ti", "--params", str(doc)]
        + ["--out", str(tmp_path / "s.csv")]
    )
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "x0_std holds 2 value(s) but BM_Ti has 1 state(s)" in err[0]


@pytest.mark.parametrize("json_out", [True, False], ids=["json", "text"])
@pytest.mark.slow
def test_fit_method_ml_without_validation(csv_file, capsys, json_out):
    """``--validate none`` with ``--method ml``: no validation period, so its entries are null
    (once an internal error reading the length of a validation that does not exist)."""
    argv = ["fit", str(csv_file), "--model", "BM_Ti", "--method", "ml", "--validate", "none"]
    code = main([*argv, "--starts", "2", *(["--json"] if json_out else [])])
    out = capsys.readouterr()
    assert code == 0, out.err
    if json_out:
        doc = json.loads(out.out)
        assert doc["validation"] is None and doc["residuals"]["validation"] is None
        assert doc["simulation_rmse"]["validation"] is None
        assert doc["data"]["n_validate"] == 0 and doc["data"]["n_train"] == 300
        assert set(doc["simulation_rmse"]["identification"]) == {"T_zon"}
    else:
        assert "validation: none" in out.out


def test_input_gaps_are_interpolated_up_to_max_gap_and_a_longer_one_named(
    fit_doc, csv_file, tmp_path, capsys
):
    """A one-hour gap of T_amb in the identification half is interpolated, as the output-error
    fit does (the fit is the one of the same data filled by pandas); a three-hour gap is refused
    in one line naming it and the --max-gap that bridges it, for the fit and for estimate."""
    frame = pd.read_csv(csv_file, index_col="time")
    short, long = frame.copy(), frame.copy()
    short.iloc[40, short.columns.get_loc("T_amb")] = np.nan
    long.iloc[40:43, long.columns.get_loc("T_amb")] = np.nan
    paths = {}
    for name, f in (("short", short), ("long", long), ("filled", short.interpolate())):
        paths[name] = tmp_path / f"{name}.csv"
        f.to_csv(paths[name], index_label="time")

    def fit(path, *extra):
        args = ["fit", str(path), "--model", "BM_Ti", "--method", "ml", "--starts", "4"]
        code = main([*args, "--json", *extra])
        out = capsys.readouterr()
        return code, out.out, out.err

    code, out, err = fit(paths["short"])
    assert code == 0, err
    code, ref, err = fit(paths["filled"])
    assert code == 0, err
    assert json.loads(out)["loglik"] == pytest.approx(json.loads(ref)["loglik"], rel=1e-9)
    code, _, err = fit(paths["long"])
    assert code == 2 and err.count("error:") == 1
    t = pd.DatetimeIndex(frame.index)
    need = f"{int(np.ceil(3 * (t[1] - t[0]).total_seconds() / 3600))}h"  # three samples
    assert f"identification data: the inputs are missing from {t[40]} to {t[42]}" in err
    assert f"--max-gap {need} to interpolate it" in err
    code, out, err = fit(paths["long"], "--max-gap", need)
    assert code == 0, err
    _, params = fit_doc
    est = ["estimate", str(paths["long"]), "--model", "BM_Ti", "--params", str(params)]
    code = main([*est, "--out", str(tmp_path / "s.csv")])
    err = capsys.readouterr().err
    assert code == 2 and "the data: the inputs are missing" in err and f"--max-gap {need}" in err
    assert main([*est, "--out", str(tmp_path / "s.csv"), "--max-gap", need]) == 0
