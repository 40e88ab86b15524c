"""Fleets in this process: sources, broken buildings, results, resume, config, command line.

A small synthetic fleet (one week of hourly data, ZonWal, 4 starts) fitted without Dask; the
Dask runs are in test_fleet_dask.py.
"""

import json

import numpy as np
import pandas as pd
import pytest

from jaxbox.cli._main import main
from jaxbox.datasets import make_fleet
from jaxbox.fleet import FleetError, load_config, read_results, run_fleet
from jaxbox.models import get_model
from jaxbox.validate import kpi_values
from jaxbox.validate._hlc_hac import HAC

N = 6
CFG = {"models": "ZonWal", "starts": 4, "partition_size": 3}


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """Six good buildings, and four broken ones: an infinite reading, a missing column, no heating
    (HLC not identifiable) and a zone temperature that is a random walk (no model reproduces it)."""
    folder = tmp_path_factory.mktemp("fleet") / "in"
    _, truth = make_fleet(N, folder, days=7, seed=5)
    rng = np.random.default_rng(0)
    f = pd.read_csv(folder / "b0.csv")
    f["T_zon"] = f["T_zon"].astype(float)
    f.loc[10, "T_zon"] = np.inf  # (a missing reading is masked, not bad data)
    f.to_csv(folder / "x_inf.csv", index=False)
    f = pd.read_csv(folder / "b1.csv")
    f.drop(columns=["Q_hea"]).to_csv(folder / "x_nocol.csv", index=False)
    f = pd.read_csv(folder / "b2.csv").assign(Q_hea=0.0)
    f.to_csv(folder / "x_noheat.csv", index=False)
    f = pd.read_csv(folder / "b3.csv")
    f["T_zon"] = 20 + np.cumsum(rng.normal(0, 1.5, len(f)))
    f.to_csv(folder / "x_walk.csv", index=False)
    return folder, truth


@pytest.fixture(scope="module")
def inline(fleet, tmp_path_factory):
    folder, _ = fleet
    out = tmp_path_factory.mktemp("out")
    summary = run_fleet(folder, out, load_config(**CFG), workers=0)
    return out, summary, read_results(out)


def test_make_fleet_truth_is_the_model_kpis(fleet):
    folder, truth = fleet
    assert sorted(p.name for p in folder.glob("b*.csv")) == [f"b{k}.csv" for k in range(N)]
    back = pd.read_csv(folder / "truth.csv", index_col="building")
    assert np.allclose(back["hlc"], truth["hlc"])
    assert np.allclose(truth["hlc"], 1 / truth["R_wal"], rtol=1e-10)
    row = truth.iloc[0]
    v = kpi_values("ZonWal", row[["C_zon", "C_wal", "R_wal", "gA", "T_zon0", "T_wal0"]])
    assert v["time_constants"] == pytest.approx(list(row[["tau1", "tau2"]]), rel=1e-12)
    again, truth2 = make_fleet(2, days=7, seed=5)
    assert truth2.iloc[0].equals(truth.iloc[0])


def test_every_building_is_a_row_with_its_status(inline, fleet):
    out, summary, rows = inline
    _, truth = fleet
    assert summary.processed == N + 4 and summary.workers == 0
    status = dict(zip(rows["building"], rows["status"], strict=True))
    assert status["x_inf"] == "bad_data" and status["x_nocol"] == "bad_data"
    assert status["x_noheat"] == "no_valid_model"
    assert status["x_walk"] == "no_valid_model"
    assert all(status[f"b{k}"] == "ok" for k in range(N))
    msg = dict(zip(rows["building"], rows["message"], strict=True))
    assert "T_zon" in msg["x_inf"] and "Q_hea" in msg["x_nocol"]
    assert "not identifiable" in msg["x_noheat"]
    assert summary.counts == {"ok": N, "no_valid_model": 2, "bad_data": 2, "failed": 0}


def test_rows_hold_params_intervals_kpis_and_timings(inline, fleet):
    out, _, rows = inline
    _, truth = fleet
    ok = rows[rows["status"] == "ok"].set_index("building")
    true = truth.loc[ok.index, "hlc"]
    assert np.all(ok["hlc_lo"] < ok["hlc"]) and np.all(ok["hlc"] < ok["hlc_hi"])
    assert np.allclose(ok["hlc"], true, rtol=0.05)  # 0.1 K noise, a week of data
    assert (ok["hlc_lo"] <= true).sum() + (true <= ok["hlc_hi"]).sum() >= 2 * N - 2
    first = ok.iloc[0]
    params = {p["name"]: p for p in first["params"]}
    assert set(params) == {"C_zon", "C_wal", "R_wal", "gA", "T_zon0", "T_wal0"}
    r = params["R_wal"]
    assert r["ci_lo"] < r["value"] < r["ci_hi"] and r["std"] > 0
    assert first["hlc"] == pytest.approx(1 / r["value"], rel=1e-10)
    assert np.isnan(params["T_zon0"]["std"])  # initial states get no interval
    assert len(first["tau_h"]) == 2 and first["tau_lo_h"][1] < first["tau_h"][1]
    assert np.all(ok["rmse_cross"] < 0.3) and np.all(ok["valid"])
    assert np.all(ok["total_s"] > 0) and np.all(ok["batch"] >= 1)
    doc = json.loads((out / "fits" / f"{first.name}.json").read_text())
    assert doc["status"] == "ok" and doc["model"] == "ZonWal"
    assert doc["kpis"]["hlc"]["value"] == pytest.approx(first["hlc"])
    # the HAC intervals of the fit document and of select, named in the row
    assert set(ok["kpi_interval"]) == {HAC}
    assert doc["kpis"]["hlc"]["method"] == HAC
    assert doc["kpis"]["hlc"]["ci95"] == pytest.approx([first["hlc_lo"], first["hlc_hi"]])
    assert pd.isna(rows.set_index("building").loc["x_inf", "kpi_interval"])  # no KPIs
    assert json.loads((out / "fits" / "x_inf.json").read_text())["status"] == "bad_data"
    meta = json.loads((out / "fleet.json").read_text())
    assert meta["status"] == "done" and meta["processed"] == N + 4


def test_buildings_of_neighbouring_lengths_share_one_batched_fit(tmp_path):
    """Three buildings whose records end 0, 3 and 5 hours apart: one batched fit (the shorter
    padded at their ends), where each length used to compile and run a batch of its own."""
    from jaxbox import _compiled
    from jaxbox.fit import clear_compile_cache

    folder = tmp_path / "in"
    _, truth = make_fleet(3, folder, days=7, seed=8)
    for name, cut in (("b1", 3), ("b2", 5)):
        f = pd.read_csv(folder / f"{name}.csv")
        f.iloc[: len(f) - cut].to_csv(folder / f"{name}.csv", index=False)
    clear_compile_cache()
    run_fleet(folder, tmp_path / "out", load_config(**CFG), workers=0)
    assert len(_compiled.entries("fit")) == 1
    rows = read_results(tmp_path / "out").set_index("building")
    assert list(rows["status"]) == ["ok"] * 3
    assert rows["n_train"].nunique() == 3
    assert np.allclose(rows["hlc"], truth.loc[rows.index, "hlc"], rtol=0.05)


def test_long_format_parquet_and_csv_give_the_same_rows(inline, fleet, tmp_path):
    folder, _ = fleet
    frames = [pd.read_csv(folder / f"b{k}.csv").assign(building=f"b{k}") for k in (0, 4)]
    long = pd.concat(frames, ignore_index=True)
    long.to_parquet(tmp_path / "long.parquet")
    long.to_csv(tmp_path / "long.csv", index=False)
    cfg = load_config(**CFG)
    base = inline[2].set_index("building")
    for name in ("long.parquet", "long.csv"):
        out = tmp_path / f"out-{name}"
        run_fleet(tmp_path / name, out, cfg, workers=0, fit_json=False)
        rows = read_results(out).set_index("building")
        assert list(rows.index) == ["b0", "b4"]
        assert np.allclose(rows["hlc"], base.loc[["b0", "b4"], "hlc"], rtol=1e-6)
    assert not (tmp_path / "out-long.csv" / "fits").exists()


def test_resume_after_a_crash_runs_only_the_rest(fleet, tmp_path):
    """A run that dies after its first partition is written; ``resume`` does the rest once."""
    folder, _ = fleet
    cfg = load_config(**CFG)

    def crash(index, rows):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_fleet(folder, tmp_path, cfg, workers=0, fit_json=False, on_partition=crash)
    first = read_results(tmp_path)
    assert list(first["building"]) == ["b0", "b1", "b2"]
    with pytest.raises(FleetError, match="resume"):
        run_fleet(folder, tmp_path, cfg, workers=0)
    summary = run_fleet(folder, tmp_path, cfg, workers=0, resume=True, fit_json=False)
    assert summary.skipped == 3 and summary.processed == N + 1
    rows = read_results(tmp_path)
    assert len(rows) == N + 4 and rows["building"].is_unique
    parts = sorted((tmp_path / "results.parquet").glob("part-*.parquet"))
    assert len(parts) == 1 + 3  # the crashed run's part, and the three of the resumed run
    again = run_fleet(folder, tmp_path, cfg, workers=0, resume=True)
    assert again.processed == 0 and again.skipped == N + 4


def test_config_from_toml(tmp_path):
    path = tmp_path / "fleet.toml"
    path.write_text(
        '[data]\ncolumns = { T_zon = "indoor" }\nresample = "1h"\n'
        '[windows]\nfraction = 0.6\n[identify]\nmodels = ["ZonWal"]\nstarts = 8\n'
        "[run]\npartition_size = 5\n",
        encoding="utf-8",
    )
    cfg = load_config(path, starts=3)
    assert cfg.fixed_model == "ZonWal" and cfg.starts == 3 and cfg.fraction == 0.6
    assert cfg.load_options() == {"columns": {"T_zon": "indoor"}, "resample": "1h"}
    assert load_config().fixed_model is None and load_config().models == "search"
    path.write_text(
        '[data]\ncounters = { Q_hea = "kWh" }\ntz = "Europe/Berlin"\nunits = { T_zon = "degF" }\n',
        encoding="utf-8",
    )
    cfg = load_config(path, time=["date", "clock"], time_unit="ms")
    assert cfg.load_options() == {
        "time": ["date", "clock"],
        "time_unit": "ms",
        "counters": {"Q_hea": "kWh"},
        "units": {"T_zon": "degF"},
        "tz": "Europe/Berlin",
    }
    with pytest.raises(FleetError, match="data.time must be a column or"):
        load_config(time=["date"])
    with pytest.raises(FleetError, match="data.tz must name a time zone"):
        load_config(tz=" ")
    cfg = load_config(thousands=".", decimal=",", sep=";")
    assert cfg.load_options() == {"sep": ";", "decimal": ",", "thousands": "."}
    with pytest.raises(FleetError, match="data.thousands must be one of"):
        load_config(thousands=".")
    assert load_config(models="Zon+Wal").fixed_model == "Zon+Wal"  # a structure name
    assert load_config(models="exp1").fixed_model is None  # a family: a selection

    path.write_text("[identify]\nstart = 3\n", encoding="utf-8")
    with pytest.raises(FleetError, match="unknown key 'start' in \\[identify\\]"):
        load_config(path)
    path.write_text("[identify]\ncontinued = 1\n", encoding="utf-8")
    assert load_config(path).continued == 1 and load_config().continued is None
    with pytest.raises(FleetError, match="identify.continued must be an integer ≥ 0"):
        load_config(continued=-1)
    path.write_text("[identify]\npolish = 0\n", encoding="utf-8")
    assert load_config(path).polish == 0 and load_config().polish is None
    with pytest.raises(FleetError, match="identify.polish must be an integer ≥ 0"):
        load_config(polish=-1)
    path.write_text("[identify]\ncriterion = 'aic'\n", encoding="utf-8")
    with pytest.raises(FleetError, match="criterion"):
        load_config(path)
    with pytest.raises(FleetError, match="fraction"):
        load_config(fraction=1.5)


@pytest.mark.parametrize(
    "setting, words",
    [
        ({"fraction": "half"}, "windows.fraction must be a number"),
        ({"margin": "x"}, "identify.margin must be a number"),
        ({"seed": -1}, "identify.seed must be an integer"),
        ({"reports": "yes"}, "run.reports must be true or false"),
        ({"models": ["ZonWall"]}, "identify.models: no library model named 'ZonWall'"),
        ({"models": "exp9"}, "identify.models: no library model named 'exp9'"),
        ({"columns": ["T_zon"]}, "data.columns must be a table"),
        ({"scale": {"Q_hea": "kW"}}, "data.scale.Q_hea must be a number"),
        ({"scale": {"Q_hea": 0}}, "data.scale.Q_hea must be a finite factor"),
        ({"counters": {"Q_hea": "kwh"}}, "data.counters.Q_hea: unknown energy unit"),
        ({"units": {"T_zon": "fahrenheit"}}, "data.units.T_zon: unknown unit 'fahrenheit'"),
        ({"sep": ";;"}, "data.sep must be one character"),
        ({"decimal": ";"}, "data.decimal must be"),
        ({"resample": "hourly"}, "data.resample 'hourly' is not a positive fixed length"),
        ({"time_unit": "weeks"}, "data.time_unit must be one of"),
        ({"epoch": "then"}, "data.epoch 'then' cannot be read"),
        ({"tz": "Mars/Olympus"}, "data.tz 'Mars/Olympus' cannot be read"),
        ({"train": ["2024-01-02", "2024-01-01"], "valid": ["2024-01-03", "2024-01-04"]}, "train"),
    ],
)
def test_fleet_settings_are_checked_before_any_building_is_read(setting, words):
    """A setting no building could be read or fitted with fails the run at once, naming the
    key, instead of failing every building in turn."""
    with pytest.raises(FleetError, match=words):
        load_config(**setting)


def test_cli_make_run_and_bad_input(tmp_path, capsys):
    fleet = tmp_path / "in"
    assert main(["fleet", "make", str(fleet), "--n", "2", "--days", "7"]) == 0
    assert (fleet / "truth.csv").exists() and "2 buildings" in capsys.readouterr().out
    out = tmp_path / "out"
    args = ["fleet", str(fleet), "--out", str(out), "--model", "ZonWal", "--starts", "4"]
    args += ["--partition-size", "3"]
    assert main([*args, "--workers", "0", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["processed"] == 2 and doc["counts"]["ok"] + doc["counts"]["no_valid_model"] == 2
    assert main([*args, "--workers", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and "resume" in err and "\n" not in err
    assert main([*args, "--scheduler", "localhost"]) == 2
    assert "tcp://HOST:PORT" in capsys.readouterr().err
    assert main(["fleet", str(tmp_path / "none"), "--out", str(tmp_path / "o2")]) == 2
    assert "no such file" in capsys.readouterr().err


@pytest.mark.slow
def test_the_default_is_the_structure_search(fleet, tmp_path):
    """Without models the fleet searches the grammar, as ``jaxbox select`` does: on a ZonWal
    building it accepts the envelope state, with the true heat-loss coefficient."""
    folder, truth = fleet
    sub = tmp_path / "in"
    sub.mkdir()
    (sub / "b4.csv").write_text((folder / "b4.csv").read_text())
    summary = run_fleet(sub, tmp_path / "out", load_config(starts=4, max_steps=60), workers=0)
    assert summary.counts.get("ok", 0) == 1
    rows = read_results(tmp_path / "out").set_index("building")
    assert rows.loc["b4", "model"] == "Zon+Wal"
    assert rows.loc["b4", "hlc"] == pytest.approx(truth.loc["b4", "hlc"], rel=0.05)


def test_local_workers_keep_the_xla_flags_of_the_process():
    """A local cluster's workers run one thread each and compile with the caller's XLA flags."""
    from jaxbox.fleet._run import worker_env

    env = worker_env({"XLA_FLAGS": " --xla_backend_optimization_level=0 "})
    assert env["XLA_FLAGS"].split() == [
        "--xla_backend_optimization_level=0",
        "--xla_cpu_multi_thread_eigen=false",
    ]
    assert worker_env({})["XLA_FLAGS"] == "--xla_cpu_multi_thread_eigen=false"
    assert env["OMP_NUM_THREADS"] == env["OPENBLAS_NUM_THREADS"] == "1"


def test_a_structure_name_is_built_for_each_buildings_columns(tmp_path):
    """``--model Zon+Wal`` on a fleet where one building has no irradiance sensor: that one is
    fitted without a solar aperture (the search's structure), not refused for a missing
    column."""
    folder = tmp_path / "in"
    make_fleet(2, folder, days=4, seed=3)
    f = pd.read_csv(folder / "b1.csv")
    f.drop(columns=["I_glo_hor"]).to_csv(folder / "b1.csv", index=False)
    out = tmp_path / "out"
    run_fleet(folder, out, load_config(models="Zon+Wal", starts=2, partition_size=2), workers=0)
    rows = read_results(out).set_index("building")
    assert "bad_data" not in set(rows["status"]), rows["status"]
    sunny, dark = (json.loads((out / "fits" / f"{b}.json").read_text()) for b in ("b0", "b1"))
    assert "gA" in sunny["params"] and "gA" not in dark["params"]


@pytest.fixture
def selections_seen(monkeypatch):
    """The fleet's selection step with the search and the forward selection replaced by
    recorders: ``(_selections, the keywords each call got)``."""
    import jaxbox.fleet._work as work
    import jaxbox.select as select

    seen = []
    monkeypatch.setattr(select, "structure_search", lambda gb, **kw: seen.append(kw))
    monkeypatch.setattr(
        select, "forward_selection_many", lambda boxes, names, **kw: seen.append(kw)
    )
    return work._selections, seen


def test_continued_reaches_the_search_and_the_selection(selections_seen):
    """``[identify] continued`` is passed to each building's structure search and to the
    forward selection (their fits' setting), and left out when not given."""
    selections, seen = selections_seen
    selections("search", ["house"], load_config(continued=1))
    selections("search", ["house"], load_config())
    selections([get_model("Zon")], ["house"], load_config(continued=2))
    assert seen[0]["continued"] == 1 and "continued" not in seen[1]
    assert seen[2]["continued"] == 2


def test_polish_reaches_the_search_and_the_selection(selections_seen):
    """``[identify] polish``: ``k`` is passed to the search and the forward selection, ``0``
    as ``None`` (every start to the full tolerance); left out when not given (the search's
    own default)."""
    selections, seen = selections_seen
    selections("search", ["house"], load_config(polish=3))
    selections("search", ["house"], load_config())
    selections([get_model("Zon")], ["house"], load_config(polish=0))
    assert seen[0]["polish"] == 3 and "polish" not in seen[1]
    assert "polish" in seen[2] and seen[2]["polish"] is None


def test_a_searched_buildings_hlc_interval_is_the_one_select_reports(monkeypatch, tmp_path):
    """The fleet's search reports the accepted model's HLC with the interval ``jaxbox select``
    gives (:func:`jaxbox.validate.hlc_interval`: near-best structures, coloured residuals, the
    record's conductance), not the model's own; the row says the form."""
    import jaxbox.validate as validate

    seen = []
    real = validate.hlc_interval

    def spy(sel, **kw):
        out = real(sel, **kw)
        seen.append(out)
        return out

    monkeypatch.setattr(validate, "hlc_interval", spy)
    folder = tmp_path / "in"
    make_fleet(1, folder, days=7, seed=5)
    run_fleet(folder, tmp_path / "out", load_config(starts=4, max_steps=60), workers=0)
    row = read_results(tmp_path / "out").iloc[0]
    (hi,) = seen
    assert row["status"] == "ok" and row["form"] == "temperature"
    assert (row["hlc"], row["hlc_lo"], row["hlc_hi"]) == (hi.value, *hi.ci95)
    assert row["kpi_interval"] == hi.method


@pytest.mark.slow
def test_a_held_zone_gets_the_heat_demand_form_and_the_hlc_select_reports(tmp_path, capsys):
    """A building held by its thermostat: the fleet's search accepts the heat-demand form, as
    ``jaxbox select`` does on the same file, with the same HLC and interval (before, the fleet
    read only the temperature form and reported "no valid model")."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from test_thermostat_form import simulate, truth_hlc

    folder = tmp_path / "in"
    folder.mkdir()
    csv = folder / "held.csv"
    simulate(10, control="held").to_csv(csv)
    run_fleet(folder, tmp_path / "out", load_config(starts=8), workers=0)
    row = read_results(tmp_path / "out").iloc[0]
    assert row["status"] == "ok" and row["form"] == "heat demand", row["message"]
    assert "in its heat-demand form" in row["message"]
    assert row["hlc_lo"] <= truth_hlc() <= row["hlc_hi"]
    assert np.isnan(row["rmse_cross"])  # the heating's error is in the message, in W
    assert main(["select", str(csv), "--json", "--starts", "8"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["form"] == "heat demand" and doc["form_model"]["structure"] == row["model"]
    assert doc["hlc"]["value"] == pytest.approx(row["hlc"], rel=1e-9)
    assert doc["hlc"]["ci95"] == pytest.approx([row["hlc_lo"], row["hlc_hi"]], rel=1e-9)
    assert doc["hlc"]["method"] == row["kpi_interval"]
    params = {p["name"]: p for p in row["params"]}
    assert params["R_wal"]["unit"] == "K/W" and params["R_wal"]["ci_lo"] > 0


def test_max_gap_and_stuck_hours_reach_every_building(tmp_path, capsys):
    """``[data] max_gap`` (``--max-gap``): a 3-h input gap cuts a building's window into two
    segments (initial states of their own) at 1 h, and is interpolated at 4 h, as ``jaxbox fit
    --max-gap`` does; ``stuck_hours`` reaches the data check; bad values are one line naming
    the option."""
    folder = tmp_path / "in"
    make_fleet(1, folder, days=7, seed=5)
    f = pd.read_csv(folder / "b0.csv")
    f.loc[40:42, "T_amb"] = np.nan
    f.loc[5:60, "T_zon"] = 20.0  # a sensor that stays put for 56 h
    f.to_csv(folder / "b0.csv", index=False)
    initial = {}
    for gap in ("1h", "4h"):
        out = tmp_path / gap
        cfg = load_config(models="ZonWal", starts=2, max_gap=gap, stuck_hours="none")
        run_fleet(folder, out, cfg, workers=0)
        assert read_results(out).iloc[0]["status"] != "bad_data"
        doc = json.loads((out / "fits" / "b0.json").read_text())
        initial[gap] = sorted(k for k in doc["params"] if k.startswith("T_"))
    assert initial["1h"] == ["T_wal0", "T_wal0_s2", "T_zon0", "T_zon0_s2"]
    assert initial["4h"] == ["T_wal0", "T_zon0"]
    run_fleet(folder, tmp_path / "stuck", load_config(models="ZonWal", starts=2), workers=0)
    row = read_results(tmp_path / "stuck").iloc[0]
    assert row["status"] == "bad_data" and "T_zon" in row["message"], row["message"]
    for option, value in (("--max-gap", "30x"), ("--stuck-hours", "-3")):
        code = main(["fleet", str(folder), "--out", str(tmp_path / "x"), option, value])
        err = capsys.readouterr().err
        assert code == 2 and err.count("error:") == 1 and option in err, err
