"""The command line: JSON shape, exit codes, one-line errors."""

import json
import os

import numpy as np
import pandas as pd
import pytest

from jaxbox.cli._main import main


@pytest.fixture(scope="module")
def csv_file(tmp_path_factory):
    """A small synthetic building in a CSV with user column names (one-state truth)."""
    n = 240
    t = np.arange(n) * 3600.0
    rng = np.random.default_rng(0)
    day = 2 * np.pi * t / 86400
    t_amb = 10 + 5 * np.sin(day)
    q = 800.0 * (rng.random(n) > 0.5)
    irr = np.maximum(0, 400 * np.sin(day))
    R, C, gA = 0.01, 5e6, 2.0
    T = np.empty(n)
    T[0] = 22.0
    for k in range(n - 1):  # fine explicit Euler reference, 60 substeps
        x = T[k]
        for s in range(60):
            f = s / 60
            ua = t_amb[k] + f * (t_amb[k + 1] - t_amb[k])
            uq = q[k] + f * (q[k + 1] - q[k])
            ui = irr[k] + f * (irr[k + 1] - irr[k])
            x += 60.0 * ((ua - x) / R + uq + gA * ui) / C
        T[k + 1] = x
    frame = pd.DataFrame(
        {
            "time": pd.date_range("2024-01-01", periods=n, freq="h"),
            "indoor": T,
            "outdoor": t_amb,
            "heater": q,
            "sun": irr,
        }
    )
    path = tmp_path_factory.mktemp("cli") / "building.csv"
    frame.to_csv(path, index=False)
    return path


MAP = ["--map", "T_zon=indoor", "--map", "T_amb=outdoor", "--map", "Q_hea=heater"]
MAP += ["--map", "I_glo_hor=sun"]


@pytest.mark.slow
@pytest.mark.parametrize("command", ["fit", "select"])
@pytest.mark.parametrize("name", ["Zon+Wal", "Zon"])
def test_a_model_named_for_a_large_building_is_sized_as_the_search_does(
    csv_file, capsys, command, name
):
    """A structure or a library model named for one building larger than the naming
    defaults' reference (``fit --model``, ``select --models``) is built for that building, as
    the structure search builds its own: its resistances' bounds divided and its capacities'
    multiplied by the same scale (here the heating ×100: a 10 kW/K building, R_wal 1e-4 K/W)."""
    from jaxbox.models import parameter_for

    which = ["--model", name] if command == "fit" else ["--models", name]
    args = [command, str(csv_file), *which, "--starts", "2", "--json", *MAP]
    code = main([*args, "--scale", "Q_hea=100", "--validate", "none"])
    out = capsys.readouterr()
    assert code == 0, out.err
    doc = json.loads(out.out)
    params = (doc if command == "fit" else doc["fit"])["params"]
    scale = params["C_zon"]["upper"] / parameter_for("C_zon").upper
    assert scale > 1.0
    assert parameter_for("R_wal").lower / params["R_wal"]["lower"] == pytest.approx(scale)
    assert params["T_zon0"]["lower"] == parameter_for("T_zon0").lower
    np.testing.assert_allclose(params["R_wal"]["value"], 0.01 / 100, rtol=0.1)


def test_models_json(capsys):
    assert main(["models", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    names = [m["name"] for m in doc["models"]]
    assert "Zon" in names and "ZonWal" in names
    zon = doc["models"][names.index("Zon")]
    p = {q["name"]: q for q in zon["parameters"]}
    assert p["R_wal"]["unit"] == "K/W" and p["R_wal"]["lower"] > 0
    assert set(zon) >= {"name", "states", "inputs", "outputs", "parameters"}


def test_fit_json_shape(csv_file, capsys, tmp_path):
    plots = tmp_path / "plots"
    code = main(
        [
            "fit",
            str(csv_file),
            "--model",
            "Zon",
            "--starts",
            "4",
            "--homotopy",
            "0.8,0.1",
            "--json",
            *MAP,
            "--plots",
            str(plots),
        ]
    )
    out = capsys.readouterr()
    assert code == 0, out.err
    doc = json.loads(out.out)
    assert doc["model"] == "Zon"
    assert set(doc["params"]) == {"C_zon", "R_wal", "gA", "T_zon0"}
    for row in doc["params"].values():
        assert {"value", "lower", "upper", "at_bound", "std", "ci95", "rel_ci"} <= set(row)
    lo, hi = doc["params"]["R_wal"]["ci95"]
    assert lo < doc["params"]["R_wal"]["value"] < hi
    assert doc["params"]["T_zon0"]["std"] is None  # no interval for initial states by default
    assert isinstance(doc["valid"], bool) and isinstance(doc["reasons"], list)
    assert {"auto", "cross"} <= set(doc["residuals"])
    assert "correlation" in doc
    assert doc["params"]["R_wal"]["value"] == pytest.approx(0.01, rel=1e-3)
    # the CSV comes from an explicit-Euler reference (60 s steps): close, not exact
    assert doc["params"]["C_zon"]["value"] == pytest.approx(5e6, rel=5e-3)
    assert set(doc["rmse_auto"]) == {"T_zon"} and set(doc["rmse_cross"]) == {"T_zon"}
    assert doc["rmse_cross"]["T_zon"] < 0.01
    assert doc["se_auto"] >= 0 and doc["se_cross"] >= 0
    assert doc["starts"]["n"] == 4
    assert doc["starts"]["homotopy"] == [0.8, 0.1]
    assert doc["starts"]["converged"] + doc["starts"]["failed"] + doc["starts"]["max_steps"] == 4
    assert {"compile_s", "fit_s"} <= set(doc["timing"])
    assert doc["data"]["n_train"] == 120 and doc["data"]["n_validate"] == 120
    pngs = sorted(p.name for p in plots.glob("*.png"))
    assert "fit.png" in pngs and "residuals.png" in pngs and len(doc["plots"]) == len(pngs)
    assert all((plots / n).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for n in pngs)


def test_fit_with_periods_fix_and_bounds(csv_file, capsys):
    code = main(
        [
            "fit",
            str(csv_file),
            "--model",
            "Zon",
            "--starts",
            "2",
            "--json",
            *MAP,
            "--train",
            "2024-01-01..2024-01-06",
            "--fix",
            "gA=2.0",
            "--bounds",
            "R_wal=0.001:0.1",
        ]
    )
    out = capsys.readouterr()
    assert code == 0, out.err
    doc = json.loads(out.out)
    assert doc["params"]["gA"] == {**doc["params"]["gA"], "value": 2.0, "free": False}
    assert doc["params"]["R_wal"]["lower"] == 0.001
    assert doc["data"]["train"][1].startswith("2024-01-06")


@pytest.mark.parametrize(
    "args, words",
    [
        (["fit", "nope.csv", "--model", "Zon"], "file not found"),
        (["fit", "{csv}", "--model", "Zon"], "T_zon"),  # columns not mapped
        (["fit", "{csv}", "--model", "Nope", *MAP], "no library model named 'Nope'"),
        (["fit", "{csv}", "--model", "Zon", *MAP, "--fix", "gA"], "must look like"),
        (["fit", "{csv}", "--model", "Zon", *MAP, "--fix", "R_x=1"], "no parameter"),
        (["fit", "{csv}", "--model", "Zon", *MAP, "--bounds", "R_wal=1:0.1"], "below"),
        (["fit", "{csv}", "--model", "Zon", *MAP, "--train", "2024-01-01"], "START..END"),
        (["fit", "{csv}", "--model", "Zon", "--map", "T_zon=nothere"], "nothere"),
        (["select", "{csv}", *MAP, "--continued", "-1"], "--continued must be at least 0"),
        (["select", "{csv}", *MAP, "--method", "ml", "--continued", "1"], "output-error fits"),
        (["select", "{csv}", *MAP, "--polish", "-1"], "--polish must be at least 0"),
        (["select", "{csv}", *MAP, "--method", "ml", "--polish", "1"], "output-error fits"),
    ],
)
def test_bad_input_exits_2_with_one_line(csv_file, capsys, args, words):
    args = [str(csv_file) if a == "{csv}" else a for a in args]
    assert main(args) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert words in lines[0]
    assert "Traceback" not in err


@pytest.mark.slow
def test_fit_several_files_in_one_batch(csv_file, capsys, tmp_path):
    """Two buildings of the same length: one compiled call, each result the one fitted alone."""
    frame = pd.read_csv(csv_file)
    frame["indoor"] += 0.05 * np.random.default_rng(1).standard_normal(len(frame))
    second = tmp_path / "building.csv"  # the same file name in another folder
    frame.to_csv(second, index=False)
    plots = tmp_path / "plots"
    common = ["--model", "Zon", "--starts", "3", "--json", *MAP]
    code = main(["fit", str(csv_file), str(second), *common, "--plots", str(plots)])
    out = capsys.readouterr()
    assert code == 0, out.err
    doc = json.loads(out.out)
    assert doc["model"] == "Zon" and len(doc["fits"]) == 2
    assert [f["data"]["source"] for f in doc["fits"]] == [str(csv_file), str(second)]
    assert all(f["timing"]["batch"] == 2 for f in doc["fits"])
    # plots of each building in a folder of its own, even with the same file name
    assert sorted(p.name for p in plots.iterdir()) == ["1-building", "2-building"]
    assert main(["fit", str(second), *common]) == 0  # the second building alone
    alone = json.loads(capsys.readouterr().out)
    # to the fit's tolerance: a batch of two is vectorised differently from one building, and the
    # last digits of an optimum in a flat valley carry ~1e-8 of it (see test_performance)
    assert doc["fits"][1]["se_auto"] == pytest.approx(alone["se_auto"], rel=1e-6)
    assert doc["fits"][1]["params"]["R_wal"]["value"] == pytest.approx(
        alone["params"]["R_wal"]["value"], rel=1e-7
    )
    assert main(["fit", str(csv_file), str(csv_file), *common]) == 2
    assert "the same DATA is given twice" in capsys.readouterr().err
    frame.loc[7, "indoor"] = np.nan
    gappy = tmp_path / "gappy.csv"
    frame.to_csv(gappy, index=False)
    assert main(["fit", str(csv_file), str(gappy), *common]) == 0  # an output gap is masked
    err = capsys.readouterr().err
    # the warnings of several DATA name the file they are about
    assert (
        err.startswith(f"warning: {gappy}: the data have gaps") and "'T_zon' (1, the first" in err
    )
    assert all(line.startswith(f"warning: {gappy}: ") for line in err.splitlines()), err


@pytest.mark.slow
def test_command_line_keeps_a_persistent_compilation_cache(tmp_path):
    """The command line writes its compiled solves to the cache folder for the next process;
    a folder it cannot create costs the reuse, never the run."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "JAXBOX_CACHE": "1", "JAXBOX_CACHE_DIR": str(tmp_path / "cache")}
    cmd = [sys.executable, "-m", "jaxbox", "fit", "twinhouse_exp1:N2", "--model", "Zon"]
    cmd += ["--starts", "1", "--json"]
    (tmp_path / "unwritable").write_text("a file where a folder should be")
    unwritable = {**env, "JAXBOX_CACHE_DIR": str(tmp_path / "unwritable" / "x")}
    # the two processes are independent: they run side by side
    pipes = dict(stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    fit = subprocess.Popen(cmd, env=env, **pipes)
    models = subprocess.Popen(
        [sys.executable, "-m", "jaxbox", "models", "--json"], env=unwritable, **pipes
    )
    out, err = fit.communicate(timeout=300)
    assert fit.returncode == 0, err
    assert any((tmp_path / "cache").iterdir())
    out, err = models.communicate(timeout=300)
    assert models.returncode == 0, err
    assert json.loads(out)["models"]


def test_select_writes_its_outputs_at_once(csv_file, capsys, tmp_path):
    """select --out: the selection document, the report and the saved GreyBox in place, no
    staging folder left; the GreyBox loads with the same cases."""
    from jaxbox.select import GreyBox

    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")  # what was there stays
    code = main(
        ["select", str(csv_file), "--models", "Zon", "--starts", "2", *MAP, "--out", str(out)]
    )
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert sorted(p.name for p in out.iterdir()) == [
        "greybox",
        "notes.txt",
        "report.html",
        "selection.json",
    ]
    doc = json.loads((out / "selection.json").read_text())
    assert doc["files"]["report"] == str(out / "report.html")
    back = GreyBox.load(out / "greybox")
    assert list(back.cases) == [row["case"] for row in doc["table"]]


def test_select_continued_reaches_every_case(csv_file, capsys, tmp_path):
    """select --continued K: each model's first K starts also follow the continuation (a
    setting of every case of a forward selection, kept in the saved GreyBox)."""
    from jaxbox.select import GreyBox

    out = tmp_path / "out"
    args = ["select", str(csv_file), "--models", "Zon", "--starts", "2", "--continued", "1"]
    code = main([*args, *MAP, "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    back = GreyBox.load(out / "greybox")
    assert [c.settings["continued"] for c in back.cases.values()] == [1]
    assert back.cases["Zon"].result.settings["continued"] == 1


@pytest.mark.parametrize(("value", "polish"), [("1", 1), ("0", None)])
def test_select_polish_reaches_every_case(csv_file, capsys, tmp_path, value, polish):
    """select --polish K: each model's K best starts are solved on to the full tolerance (a
    setting of every case, kept in the saved GreyBox); 0: every start to it."""
    from jaxbox.select import GreyBox

    out = tmp_path / "out"
    args = ["select", str(csv_file), "--models", "Zon", "--starts", "2", "--polish", value]
    code = main([*args, *MAP, "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    back = GreyBox.load(out / "greybox")
    assert [c.settings["polish"] for c in back.cases.values()] == [polish]
    assert back.cases["Zon"].result.settings["polish"] == polish


def test_a_warning_is_given_once_per_command(capsys):
    """The same warning raised twice in one command (a window prepared twice) is one line."""
    import importlib
    import warnings

    _main = importlib.import_module("jaxbox.cli._main")
    _main._SHOWN.clear()
    for _ in range(2):
        _main._one_line_warning(UserWarning("gaps in 'T_amb'"), UserWarning, "x.py", 1)
    _main._one_line_warning(UserWarning("gaps in 'T_zon'"), UserWarning, "x.py", 1)
    assert capsys.readouterr().err.splitlines() == [
        "warning: gaps in 'T_amb'",
        "warning: gaps in 'T_zon'",
    ]
    with warnings.catch_warnings():  # a new command starts afresh
        assert main(["models", "--json"]) == 0
    assert not _main._SHOWN


def test_a_staging_folder_is_recorded_before_it_is_made(tmp_path, monkeypatch):
    """Ctrl-C the moment a command's staging folder is made leaves nothing behind (the folder
    is in the list its clean-up removes before it exists), and a staging folder of a process
    killed outright is removed by the next command writing there."""
    from pathlib import Path

    from jaxbox.cli._outputs import Outputs

    made = Path.mkdir

    def mkdir_then_ctrl_c(self, *args, **kwargs):
        made(self, *args, **kwargs)
        raise KeyboardInterrupt

    target = tmp_path / "plots"
    target.mkdir()
    monkeypatch.setattr(Path, "mkdir", mkdir_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt), Outputs() as outputs:
        outputs.folder(target)
    monkeypatch.setattr(Path, "mkdir", made)
    assert list(target.iterdir()) == []
    # a dead process's staging folder (its pid in the name, the ".tmp" suffix)
    import subprocess
    import sys

    from jaxbox._io import temporary_prefix

    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    stale = target / temporary_prefix("jaxbox-out").replace(f"-{os.getpid()}.", f"-{dead}.")
    stale = stale.with_name(stale.name + "abc123.tmp")
    stale.mkdir()
    (stale / "fit.png").write_bytes(b"half")
    with Outputs() as outputs:
        staging = outputs.folder(target)
        assert staging.name.endswith(".tmp") and not stale.exists()
    assert list(target.iterdir()) == []
