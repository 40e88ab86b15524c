"""A structure name is built for the data's columns, in every command that reads one.

The structure search builds ``Zon+Wal`` without a solar aperture on data without ``I_glo_hor``
(an office with no irradiance sensor); ``jaxbox fit --model Zon+Wal``, ``fit_model``, the
forecast and the export of the fit build it the same way, and a forecast reads the JSON of
``jaxbox select --json`` as the accepted model's fit.
"""

from __future__ import annotations

import json

import pandas as pd
import pytest

import jaxbox
from jaxbox.models import get_model


@pytest.fixture(scope="module")
def office(tmp_path_factory):
    """Five days of N2, hourly, without irradiance: the columns of a building with no sun
    sensor, as a CSV."""
    data = jaxbox.datasets.twinhouse_exp1("N2").resample("1h")
    frame = data.frame[["T_zon", "T_amb", "Q_hea"]].iloc[:120]
    folder = tmp_path_factory.mktemp("office")
    csv = folder / "office.csv"
    frame.to_csv(csv, index_label="time")
    return folder, csv, jaxbox.load(csv)


def _cli(args, capsys):
    from jaxbox.cli._main import main

    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_get_model_builds_a_structure_for_the_columns():
    assert "gA" in get_model("Zon+Wal").param_names
    bare = get_model("Zon+Wal", ["T_zon", "T_amb", "Q_hea"])
    assert "gA" not in bare.param_names and bare.inputs == ("T_amb", "Q_hea")
    free = get_model("Zon+Wal", ["T_zon", "T_amb"])  # free-floating: no heating input
    assert free.inputs == ("T_amb",)
    sunny = ["T_zon", "T_amb", "Q_hea", "I_glo_hor"]
    assert get_model("Zon+Wal", sunny) == get_model("Zon+Wal")
    # a library model does not depend on the data; columns without a zone fall back
    assert get_model("ZonWal", ["T_zon", "T_amb"]) == get_model("ZonWal")
    assert get_model("Zon+Wal", ["x"]) == get_model("Zon+Wal")


def test_fit_forecast_and_export_of_a_structure_on_data_without_irradiance(office, capsys):
    folder, csv, data = office
    fit_file = folder / "fit.json"
    code, out, err = _cli(["fit", csv, "--model", "Zon+Wal", "--starts", "4", "--json"], capsys)
    assert code == 0, err
    doc = json.loads(out)
    assert "gA" not in doc["params"] and doc["model_columns"] == ["T_amb", "Q_hea", "T_zon"]
    fit_file.write_text(out)
    # the Python API builds it the same way
    ident, _ = data.split()
    res = jaxbox.fit_model("Zon+Wal", ident, starts=4)
    assert res.model.param_names == tuple(n for n in get_model("Zon+Wal").param_names if n != "gA")
    at = str(data.index[80])
    fc = folder / "fc.csv"
    args = ["forecast", csv, "--params", fit_file, "--at", at, "--horizon", "12h", "--out", fc]
    code, _, err = _cli(args, capsys)
    assert code == 0, err
    assert len(pd.read_csv(fc)) == 12
    # the JSON of `jaxbox select --json`: its accepted model's fit
    search = folder / "search.json"
    search.write_text(json.dumps({"table": [], "accepted": "Zon+Wal", "fit": doc}))
    fc2 = folder / "fc2.csv"
    args = ["forecast", csv, "--params", search, "--at", at, "--horizon", "12h", "--out", fc2]
    code, _, err = _cli(args, capsys)
    assert code == 0, err
    pd.testing.assert_frame_equal(pd.read_csv(fc), pd.read_csv(fc2))
    # a search that accepted the heat-demand form: its network, the zone's initial
    # temperature the measured one
    params = {n: v["value"] for n, v in doc["params"].items()}
    params["T_zon0"] = float(data["T_zon"][0])
    held = {k: v for k, v in params.items() if k != "T_zon0"}
    form = {"structure": "Zon+Wal", "params": held, "fixed": {}}
    demand = folder / "demand.json"
    demand.write_text(json.dumps({"table": [], "fit": None, "form_model": form}))
    plain = folder / "plain.json"
    plain.write_text(json.dumps({"model": "Zon+Wal", "params": params}))
    frames = []
    for path in (demand, plain):
        out_csv = folder / f"{path.stem}.csv"
        args = ["forecast", csv, "--params", path, "--at", at, "--horizon", "12h"]
        code, _, err = _cli([*args, "--out", out_csv], capsys)
        assert code == 0, err
        frames.append(pd.read_csv(out_csv))
    pd.testing.assert_frame_equal(*frames)
    none = folder / "none.json"
    none.write_text(json.dumps({"table": [], "accepted": None, "fit": None}))
    code, _, err = _cli(["forecast", csv, "--params", none, "--at", at, "--out", fc2], capsys)
    assert code == 2 and "accepted no model" in err and err.count("\n") == 1
    # the export rebuilds it from the columns the file records, with no data at hand
    code, out, err = _cli(
        ["export", fit_file, "--step", "15min", "--out", folder / "m.json"], capsys
    )
    assert code == 0, err
    exported = json.loads((folder / "m.json").read_text())
    assert "I_glo_hor" not in json.dumps(exported)


@pytest.mark.slow
def test_a_maximum_likelihood_fit_of_a_structure_on_data_without_irradiance(office, capsys):
    _, csv, _ = office
    args = ["fit", csv, "--model", "Zon+Wal", "--method", "ml", "--starts", "2", "--json"]
    code, out, err = _cli(args, capsys)
    assert code == 0, err
    assert "gA" not in json.loads(out)["params"]
