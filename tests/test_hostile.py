"""Hostile input: the command line never dies with a traceback, the Python API refuses what it
cannot take with a message that says what it takes.

Each command-line case runs in-process (``jaxbox.cli._main.main``) on tiny CSV files in a fresh
folder and must fail in the checks before anything is fitted: exit 2, exactly one ``error:`` line
on stderr naming what is wrong (the option, column, parameter or file), no traceback, and no file
left behind. Ctrl-C is tested in a subprocess.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jaxbox.cli._main import main

N = 48  # hourly samples of the tiny building


def frame(n: int = N) -> pd.DataFrame:
    """A plausible small building, hourly, canonical names."""
    t = np.arange(n)
    day = 2 * np.pi * t / 24
    return pd.DataFrame(
        {
            "time": pd.date_range("2024-01-01 01:00", periods=n, freq="h"),
            "T_zon": 20 + 1.5 * np.sin(day) + 0.01 * t,
            "T_amb": 5 + 4 * np.sin(day - 1),
            "Q_hea": 500.0 + 300 * (t % 5 > 2),
            "I_glo_hor": np.maximum(0.0, 300 * np.sin(day)),
        }
    )


def csv(path: Path, f: pd.DataFrame | None = None, **kw) -> Path:
    (f if f is not None else frame()).to_csv(path, index=False, **kw)
    return path


def changed(**columns):
    """A frame with some values replaced: ``column=(rows, value)`` or ``column=array``."""

    def make(folder: Path) -> Path:
        f = frame()
        for name, change in columns.items():
            if isinstance(change, tuple):
                rows, value = change
                f[name] = f[name].astype(object if isinstance(value, str) else float)
                f.loc[rows, name] = value
            else:
                f[name] = change
        return csv(folder / "data.csv", f)

    return make


def text(content: str | bytes, name: str = "data.csv"):
    def make(folder: Path) -> Path:
        path = folder / name
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")
        return path

    return make


def good(folder: Path) -> Path:
    return csv(folder / "data.csv")


def renamed(**names):
    def make(folder: Path) -> Path:
        return csv(folder / "data.csv", frame().rename(columns=names))

    return make


def stuck(folder: Path) -> Path:
    """Four days whose outdoor temperature never changes."""
    f = frame(96)
    f["T_amb"] = 5.0
    return csv(folder / "data.csv", f)


def dropped(*names):
    def make(folder: Path) -> Path:
        return csv(folder / "data.csv", frame().drop(columns=list(names)))

    return make


def with_rows(rows):
    def make(folder: Path) -> Path:
        return csv(folder / "data.csv", frame().iloc[rows])

    return make


def semicolons(decimal_comma: bool):
    def make(folder: Path) -> Path:
        return csv(folder / "data.csv", frame(), sep=";", decimal="," if decimal_comma else ".")

    return make


def grouped(folder: Path) -> Path:
    """Heating power written with a thousands separator, as spreadsheets export it."""
    f = frame()
    f["Q_hea"] = [f"{q:,.1f}" for q in f["Q_hea"] + 1000]
    return csv(folder / "data.csv", f)


def folder_as_data(folder: Path) -> Path:
    (folder / "data.csv").mkdir()
    return folder / "data.csv"


def prefix_file(folder: Path) -> Path:
    """A file named like a bundled dataset, with only a header: must be read, not replaced."""
    (folder / "twinhouse_exp1_myhouse.csv").write_text("time,T_zon,T_amb,Q_hea,I_glo_hor\n")
    return folder / "twinhouse_exp1_myhouse.csv"


def slug_taken(folder: Path) -> Path:
    """Two datasets whose plots go to ./1-data and ./2-data, the second a file already."""
    for sub in ("a", "b"):
        (folder / sub).mkdir()
        csv(folder / sub / "data.csv")
    (folder / "2-data").write_text("taken")
    return folder


def a_file(folder: Path) -> Path:
    (folder / "taken").write_text("a file, not a folder")
    return folder / "taken"


FIT = ["fit", "{data}", "--model", "Zon"]
SEL = ["select", "{data}", "--models", "Zon"]
HALF = "2024-01-01..2024-01-02"  # identification: the first day

# (id, make the DATA file, command line, words the one error line must contain)
CASES = [
    # -- DATA: files that cannot be read as data
    ("nonexistent file", None, ["fit", "nope.csv", "--model", "Zon"], ["nope.csv", "not found"]),
    ("folder as DATA", folder_as_data, FIT, ["data.csv", "folder"]),
    ("empty file", text(""), FIT, ["empty"]),
    ("header only", text("time,T_zon,T_amb,Q_hea,I_glo_hor\n"), FIT, ["sample"]),
    ("one row", with_rows([0]), FIT, ["sample"]),
    ("two rows", with_rows([0, 1]), FIT, ["sample(s)", "more data"]),
    ("seven rows: halves too short", with_rows(list(range(7))), FIT, ["3 sample(s)"]),
    ("binary garbage", text(bytes(range(256)) * 8), FIT, ["data.csv"]),
    (
        "latin-1 file",
        text("time,T_zon,T_amb,Q_hea,I_glo_hor,Pièce\n".encode("latin-1")),
        FIT,
        ["UTF-8"],
    ),
    ("dataset name prefix is a file", prefix_file, FIT, ["sample"]),
    (
        "bundled name without variant",
        None,
        ["fit", "twinhouse_exp1", "--model", "Zon"],
        ["twinhouse_exp1:N2"],
    ),
    (
        "bundled name with unknown variant",
        None,
        ["fit", "twinhouse_exp1:N3", "--model", "Zon"],
        ["twinhouse_exp1:N3", "twinhouse_exp1:O5"],
    ),
    ("same DATA twice", good, ["fit", "{data}", "{data}", "--model", "Zon"], ["twice"]),
    (
        "same file under two names",
        good,
        ["fit", "{data}", "{folder}/./data.csv", "--model", "Zon"],
        ["twice"],
    ),
    (
        "--map on a bundled dataset",
        None,
        ["fit", "twinhouse_exp1:N2", "--model", "Zon", "--map", "T_zon=x"],
        ["--map"],
    ),
    (
        "--sep on a bundled dataset",
        None,
        ["fit", "twinhouse_exp1:N2", "--model", "Zon", "--sep", ";"],
        ["--sep"],
    ),
    # -- columns
    ("missing column", renamed(T_zon="indoor"), FIT, ["'T_zon'", "--map"]),
    (
        "--map to a missing column",
        renamed(T_zon="indoor"),
        [*FIT, "--map", "T_zon=living"],
        ["living"],
    ),
    ("--map without =", renamed(T_zon="indoor"), [*FIT, "--map", "T_zon"], ["--map"]),
    (  # (two columns for one signal are their mean: tests/test_suggest.py)
        "--map one column twice for one signal",
        renamed(T_zon="indoor"),
        [*FIT, "--map", "T_zon=indoor", "--map", "T_zon=indoor"],
        ["--map", "T_zon=indoor twice"],
    ),
    (
        "--map several columns for a signal that cannot combine them",
        renamed(T_zon="indoor"),
        [*FIT, "--map", "T_zon=indoor", "--map", "flag=T_amb", "--map", "flag=Q_hea"],
        ["'flag' is no signal jaxbox knows how to combine"],
    ),
    (
        "duplicate column names",
        text("time,T_zon,T_zon\n2024-01-01,1,2\n2024-01-01 01:00,1,2\n"),
        FIT,
        ["T_zon"],
    ),
    (
        "a text column dropped, columns missing",
        changed(note=np.full(N, "abc"), Q_hea=(0, np.nan)),
        [*FIT, "--map", "Q_hea=nothere"],
        ["nothere"],
    ),
    ("kelvin column", changed(T_zon=frame()["T_zon"] + 273.15), FIT, ["T_zon", "kelvin"]),
    ("text in a number column", changed(T_amb=(5, "oops")), FIT, ["T_amb", "oops"]),
    (
        "an input missing in the whole identification window",
        changed(Q_hea=(list(range(24)), np.nan)),
        FIT,
        ["Q_hea"],
    ),
    ("--max-gap not a duration", good, [*FIT, "--max-gap", "soon"], ["--max-gap", "soon"]),
    ("--max-gap negative", good, [*FIT, "--max-gap", "-1h"], ["--max-gap"]),
    ("inf in the validation window", changed(T_amb=(40, np.inf)), FIT, ["T_amb"]),
    ("inf in the identification window", changed(T_zon=(3, np.inf)), FIT, ["T_zon"]),
    ("1e300 in the validation window", changed(I_glo_hor=(45, 1e300)), FIT, ["I_glo_hor"]),
    ("-1e300 in the identification window", changed(T_amb=(2, -1e300)), FIT, ["T_amb"]),
    ("spike in the validation window", changed(T_zon=(30, 95.0)), FIT, ["T_zon"]),
    ("spike inside the plausible range", changed(T_zon=(30, 38.0)), FIT, ["T_zon", "spike"]),
    ("stuck outdoor sensor", stuck, FIT, ["T_amb", "stuck", "--stuck-hours H"]),
    ("stuck outdoor sensor, tolerance too short", stuck, [*FIT, "--stuck-hours", "30"], ["stuck"]),
    ("--stuck-hours 0", good, [*FIT, "--stuck-hours", "0"], ["--stuck-hours", "positive"]),
    ("--stuck-hours text", good, [*FIT, "--stuck-hours", "long"], ["--stuck-hours"]),
    ("heating power in kW", changed(Q_hea=frame()["Q_hea"] / 1000), FIT, ["Q_hea"]),
    ("semicolon file", semicolons(False), FIT, ["--sep"]),
    ("semicolons and decimal commas", semicolons(True), [*FIT, "--sep", ";"], ["--decimal"]),
    ("--sep of two characters", good, [*FIT, "--sep", "ab"], ["--sep"]),
    ("--decimal not . or ,", good, [*FIT, "--decimal", "x"], ["--decimal"]),
    ("digits grouped in thousands", grouped, FIT, ["Q_hea", "'1,500.0'", "--thousands ','"]),
    ("--thousands the decimal mark", good, [*FIT, "--thousands", "."], ["--thousands"]),
    ("--thousands not a separator", good, [*FIT, "--thousands", "x"], ["--thousands"]),
    ("--sep and --decimal the same", good, [*FIT, "--sep", ",", "--decimal", ","], ["--sep"]),
    ("--scale without =", good, [*FIT, "--scale", "Q_hea"], ["--scale"]),
    ("--scale not a number", good, [*FIT, "--scale", "Q_hea=abc"], ["--scale", "abc"]),
    ("--scale zero", good, [*FIT, "--scale", "Q_hea=0"], ["--scale"]),
    ("--scale nan", good, [*FIT, "--scale", "Q_hea=nan"], ["--scale"]),
    ("--scale of a missing column", good, [*FIT, "--scale", "nothere=2"], ["nothere", "--scale"]),
    ("--range without colon", good, [*FIT, "--range", "T_zon=50"], ["--range", "LO:HI"]),
    ("--range reversed", good, [*FIT, "--range", "T_zon=60:-10"], ["--range", "T_zon"]),
    ("--time of a missing column", good, [*FIT, "--time", "stamp"], ["stamp", "--time"]),
    ("no time column", renamed(time="when"), FIT, ["--time"]),
    ("unparseable time stamp", changed(time=(4, "not a date")), FIT, ["not a date"]),
    ("duplicate time stamps", with_rows([0, 1, 1, 2, 3, 4, 5]), FIT, ["duplicate"]),
    ("time stamps out of order", with_rows([0, 2, 1, 3, 4, 5]), FIT, ["sort"]),
    (
        "irregular sampling",
        lambda folder: csv(
            folder / "data.csv",
            frame().assign(
                time=lambda f: f["time"].where(f.index != 10, f["time"][10] + pd.Timedelta("20min"))
            ),
        ),
        FIT,
        ["--resample"],
    ),
    # -- model and parameters
    ("unknown model", good, ["fit", "{data}", "--model", "Nope"], ["Nope"]),
    ("--model typo", good, ["fit", "{data}", "--model", "ZonWall"], ["ZonWall"]),
    ("no --model", good, ["fit", "{data}"], ["--model"]),
    ("--fix of an unknown parameter", good, [*FIT, "--fix", "R_x=1"], ["R_x", "--fix"]),
    ("--fix without =", good, [*FIT, "--fix", "gA"], ["--fix", "gA"]),
    ("--fix not a number", good, [*FIT, "--fix", "gA=big"], ["--fix", "big"]),
    ("--fix nan", good, [*FIT, "--fix", "gA=nan"], ["--fix"]),
    ("--bounds lo > hi", good, [*FIT, "--bounds", "R_wal=1:0.1"], ["--bounds", "R_wal"]),
    ("--bounds lo = hi", good, [*FIT, "--bounds", "R_wal=1:1"], ["--bounds", "R_wal"]),
    ("--bounds not numbers", good, [*FIT, "--bounds", "R_wal=a:b"], ["--bounds"]),
    ("--bounds without colon", good, [*FIT, "--bounds", "R_wal=0.1"], ["--bounds", "LO:HI"]),
    ("--bounds inf", good, [*FIT, "--bounds", "R_wal=0:inf"], ["--bounds"]),
    ("--bounds of an unknown parameter", good, [*FIT, "--bounds", "C_x=1:2"], ["C_x"]),
    (
        "--fix and --bounds of one parameter",
        good,
        [*FIT, "--fix", "gA=1", "--bounds", "gA=0:2"],
        ["gA"],
    ),
    ("--bounds of a capacity below 0", good, [*FIT, "--bounds", "C_zon=-5:-1"], ["C_zon"]),
    ("--bounds of a resistance from 0", good, [*FIT, "--bounds", "R_wal=0:1"], ["R_wal"]),
    ("--fix a resistance at 0", good, [*FIT, "--fix", "R_wal=0"], ["R_wal", "--fix"]),
    ("--fix outside the range", good, [*FIT, "--fix", "C_zon=1e-30"], ["C_zon", "range"]),
    ("--train of 3 samples", good, [*FIT, "--train", "..2024-01-01 03:00"], ["--train"]),
    ("--validate of 2 samples", good, [*FIT, "--validate", "2024-01-02 23:00.."], ["--validate"]),
    # -- run options
    ("--starts 0", good, [*FIT, "--starts", "0"], ["--starts"]),
    ("--starts -3", good, [*FIT, "--starts", "-3"], ["--starts"]),
    ("--starts 1e9", good, [*FIT, "--starts", "1e9"], ["--starts"]),
    ("--starts abc", good, [*FIT, "--starts", "abc"], ["--starts"]),
    ("--starts 2.5", good, [*FIT, "--starts", "2.5"], ["--starts"]),
    ("--seed -1", good, [*FIT, "--seed", "-1"], ["--seed"]),
    ("--max-steps 0", good, [*FIT, "--max-steps", "0"], ["--max-steps"]),
    ("--homotopy rising", good, [*FIT, "--homotopy", "0.2,0.5"], ["--homotopy", "decrease"]),
    ("--homotopy above 1", good, [*FIT, "--homotopy", "2"], ["--homotopy", "(0, 1]"]),
    ("--homotopy text", good, [*FIT, "--homotopy", "strong"], ["--homotopy", "strong"]),
    ("--simulator unknown", good, [*FIT, "--simulator", "euler"], ["--simulator"]),
    ("unknown option", good, [*FIT, "--fast"], ["--fast"]),
    ("unknown command", None, ["fitt"], ["fitt"]),
    ("--margin nan", good, [*SEL, "--margin", "nan"], ["--margin"]),
    ("--margin -1", good, [*SEL, "--margin", "-1"], ["--margin"]),
    ("--margin 1", good, [*SEL, "--margin", "1"], ["--margin"]),
    ("--margin abc", good, [*SEL, "--margin", "abc"], ["--margin"]),
    ("--patience 0", good, [*SEL, "--patience", "0"], ["--patience"]),
    ("--models unknown", good, ["select", "{data}", "--models", "Zon,Nope"], ["Nope"]),
    ("--models empty", good, ["select", "{data}", "--models", ",,"], ["--models"]),
    (
        "--models the data cannot feed",
        good,
        ["select", "{data}", "--models", "ZonIntBou"],
        ["--models"],
    ),
    ("demo --starts 0", None, ["demo", "--starts", "0", "--out", "{folder}/out"], ["--starts"]),
    ("demo --house unknown", None, ["demo", "--house", "X3"], ["--house"]),
    # -- periods
    ("--resample not a rule", good, [*FIT, "--resample", "fortnightly"], ["--resample"]),
    ("--resample zero", good, [*FIT, "--resample", "0h"], ["--resample"]),
    ("--resample finer than the data", good, [*FIT, "--resample", "10min"], ["--resample"]),
    ("--train without ..", good, [*FIT, "--train", "2024-01-01"], ["--train", "START..END"]),
    ("--train not a date", good, [*FIT, "--train", "monday..friday"], ["--train", "monday"]),
    ("--train reversed", good, [*FIT, "--train", "2024-01-02..2024-01-01"], ["--train"]),
    ("--train outside the data", good, [*FIT, "--train", "2030-01-01..2030-02-01"], ["--train"]),
    ("--train all the data", good, [*FIT, "--train", ".."], ["--validate"]),
    (
        "--validate before the data",
        good,
        [*FIT, "--validate", "2020-01-01..2020-02-01"],
        ["--validate"],
    ),
    (
        "--validate from the first sample",
        good,
        [*FIT, "--validate", "2024-01-01.."],
        ["--validate"],
    ),
    (
        "--validate inside --train",
        good,
        [*FIT, "--train", HALF, "--validate", "2024-01-01 12:00.."],
        ["--validate"],
    ),
    (
        "--train with a time zone",
        good,
        [*FIT, "--train", "2024-01-01T00:00+02:00.."],
        ["--train", "time zone"],
    ),
    (
        "--train mixing time zones",
        good,
        [*FIT, "--train", "2024-01-01T00:00+02:00..2024-01-02"],
        ["--train", "time zone"],
    ),
    (
        "--validate overlapping --train",
        good,
        [*FIT, "--train", HALF, "--validate", ".."],
        ["--validate"],
    ),
    (
        "--map to the time column",
        renamed(T_zon="indoor"),
        [*FIT, "--map", "T_zon=time"],
        ["time column"],
    ),
    ("--map without a canonical name", good, [*FIT, "--map", "=T_zon"], ["--map"]),
    ("empty --model", good, ["fit", "{data}", "--model", ""], ["no library model"]),
    ("search: --beam 0", good, ["select", "{data}", "--beam", "0"], ["--beam"]),
    (
        "search: no T_amb for the grammar",
        dropped("T_amb"),
        ["select", "{data}"],
        ["T_amb"],
    ),
    (
        "select --method ml --out",
        good,
        ["select", "{data}", "--method", "ml", "--models", "BM_Ti", "--out", "{data}.out"],
        ["--out"],
    ),
    (
        "fit: no irradiance for the model",
        dropped("I_glo_hor"),
        FIT,
        ["'I_glo_hor'", "--map I_glo_hor=", "jaxbox select DATA", "structure search"],
    ),
    (
        "select a family: no irradiance",
        dropped("I_glo_hor"),
        ["select", "{data}", "--models", "exp1"],
        ["--models", "'I_glo_hor'", "jaxbox select DATA"],
    ),
    (
        "--models all, none fed",
        dropped("Q_hea", "I_glo_hor"),
        ["select", "{data}", "--models", "all"],
        ["--models"],
    ),
    ("--starts above the limit", good, [*FIT, "--starts", "100001"], ["--starts"]),
    ("--seed 1e30", good, [*FIT, "--seed", "1e30"], ["--seed"]),
    ("--max-steps 1e7", good, [*FIT, "--max-steps", "1e7"], ["--max-steps"]),
    ("bad input with --json", good, [*FIT, "--json", "--starts", "0"], ["--starts"]),
    ("--plots name too long", good, [*FIT, "--plots", "p" * 300], ["--plots"]),
    ("DATA is an empty string", None, ["fit", "", "--model", "Zon"], ["DATA"]),
    # -- output folders
    ("--plots is a file", a_file, [*FIT, "--plots", "{data}"], ["--plots", "file"]),
    ("--plots under a file", a_file, [*FIT, "--plots", "{data}/plots"], ["--plots"]),
    ("--plots unwritable", good, [*FIT, "--plots", "/proc/jaxbox-plots"], ["--plots"]),
    ("--plots empty", good, [*FIT, "--plots", ""], ["--plots"]),
    (
        "select --out is a file",
        a_file,
        ["select", "twinhouse_exp1:N2", "--out", "{data}"],
        ["--out", "file"],
    ),
    (
        "select --out under a file",
        a_file,
        ["select", "twinhouse_exp1:N2", "--out", "{data}/x/y"],
        ["--out"],
    ),
    (
        "select --out unwritable",
        None,
        ["select", "twinhouse_exp1:N2", "--out", "/proc/x"],
        ["--out"],
    ),
    ("demo --out is a file", a_file, ["demo", "--out", "{data}"], ["--out"]),
    (
        "a dataset's --plots folder is a file",
        slug_taken,
        ["fit", "{folder}/a/data.csv", "{folder}/b/data.csv", "--model", "Zon", "--plots", "."],
        ["--plots", "2-data"],
    ),
]


@pytest.mark.parametrize("make, argv, words", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_hostile_command_line(make, argv, words, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    data = make(tmp_path) if make is not None else None
    argv = [a.format(data=data, folder=tmp_path) for a in argv]
    before = _tree(tmp_path)
    t0 = time.perf_counter()
    code = main(argv)
    elapsed = time.perf_counter() - t0
    out = capsys.readouterr()
    lines = out.err.strip().splitlines()
    assert code == 2, out.err
    errors = [line for line in lines if line.startswith("error: ")]
    assert len(errors) == 1 and lines[-1] == errors[0], out.err
    assert all(line.startswith("warning: ") for line in lines[:-1]), out.err  # one line each
    for word in words:
        assert word in errors[0], (word, errors[0])
    assert "Traceback" not in out.err and "internal error" not in out.err
    assert _python_advice(out.err) == [], out.err
    assert out.out == ""
    assert _tree(tmp_path) == before  # nothing written, nothing left behind
    assert elapsed < 20, "refused before any fitting"


def test_enough_cases():
    assert len(CASES) >= 60


def _tree(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _python_advice(line: str) -> list[str]:
    """Python keyword advice (``columns=``, ``time=``…) or DataFrame advice in a message."""
    import re

    found = re.findall(r"\b(?:columns|time|resample|sep|decimal|scale|overrides)=", line)
    found += [w for w in ("DataFrame", "pd.read_csv", "jaxbox.data") if w in line]
    return found


# -- what the checks let through ------------------------------------------------------------------


def test_a_file_named_like_a_bundled_dataset_is_read_as_that_file(tmp_path, monkeypatch):
    from jaxbox.cli._data import load_data

    monkeypatch.chdir(tmp_path)
    csv(tmp_path / "twinhouse_exp1_myhouse.csv")
    csv(tmp_path / "twinhouse_exp1")  # even the bare name is a path when no variant is given
    assert len(load_data("twinhouse_exp1_myhouse.csv")) == N
    assert len(load_data("twinhouse_exp1")) == N
    assert len(load_data("twinhouse_exp1:N2")) == 984  # the exact name: the bundled data


def test_semicolons_decimal_commas_and_kilowatts_read_with_options(tmp_path, monkeypatch):
    from jaxbox.cli._data import DataOptions, load_data

    f = frame()
    f["Q_hea"] = f["Q_hea"] / 1000
    path = csv(tmp_path / "data.csv", f, sep=";", decimal=",")
    args = _args(data=[str(path)], sep=";", decimal=",", scale=["Q_hea=1000"])
    data = load_data(str(path), DataOptions(args))
    np.testing.assert_allclose(data["Q_hea"], frame()["Q_hea"])
    args = _args(data=[str(path)], sep="\\t")
    assert DataOptions(args).sep == "\t"


def test_thousands_separators_read_with_thousands(tmp_path):
    """Digits grouped in thousands, as exported with ',' (quoted) or '.' beside a decimal
    comma, with a row of units: refused naming the option, read with it."""
    from jaxbox.cli._data import DataOptions, load_data
    from jaxbox.data import DataError, load

    power = np.asarray(frame()["Q_hea"] + 1000.25)
    us = frame()
    us["Q_hea"] = [f"{q:,.2f}" for q in power]
    path = csv(tmp_path / "us.csv", us)
    with pytest.raises(DataError, match="thousands=','"):
        load(path)
    np.testing.assert_allclose(load(path, thousands=",")["Q_hea"], power)
    options = DataOptions(_args(data=[str(path)], thousands=","))
    np.testing.assert_allclose(load_data(str(path), options)["Q_hea"], power)

    de = frame().astype(object)
    for name in ("T_zon", "T_amb", "I_glo_hor"):
        de[name] = [f"{v:.6f}".replace(".", ",") for v in frame()[name]]
    de["Q_hea"] = [f"{q:,.2f}".replace(",", " ").replace(".", ",").replace(" ", ".") for q in power]
    units = {"time": "", "T_zon": "°C", "T_amb": "°C", "Q_hea": "W", "I_glo_hor": "W/m²"}
    path = csv(tmp_path / "de.csv", pd.concat([pd.DataFrame([units]), de]), sep=";")
    with pytest.raises(DataError, match="thousands='.', decimal=','"), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the row of units
        load(path, sep=";", decimal=",")
    with pytest.warns(UserWarning, match="units"):
        data = load(path, sep=";", decimal=",", thousands=".")
    np.testing.assert_allclose(data["Q_hea"], power)
    np.testing.assert_allclose(data["T_zon"], frame()["T_zon"], atol=1e-6)
    with pytest.raises(DataError, match="decimal mark are both '.'"):
        load(path, sep=";", thousands=".")


def test_an_energy_meter_read_with_counter(tmp_path):
    """A heat meter in kWh is refused with the option that reads it, and read with it."""
    from jaxbox.cli._common import cli_message
    from jaxbox.cli._data import DataOptions, load_data
    from jaxbox.data import DataError

    f = frame()
    power = f["Q_hea"].to_numpy()
    f["Q_hea"] = 100.0 + np.cumsum(power * 3600 / 3.6e6)
    path = csv(tmp_path / "meter.csv", f)
    with pytest.raises(DataError) as info:
        load_data(str(path), DataOptions(_args(data=[str(path)]))).check_plausible()
    assert "--counter Q_hea=kWh" in cli_message(str(info.value))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no gap to speak of: the first row is dropped
        data = load_data(str(path), DataOptions(_args(data=[str(path)], counter=["Q_hea=kWh"])))
    np.testing.assert_allclose(data["Q_hea"], power[1:], rtol=1e-9)


def test_local_clock_time_read_with_tz(tmp_path):
    """Naive local time across the end of summer time: refused with the option that reads it,
    read with it (an empty zone is a usage error), and the bundled data take no --tz."""
    from jaxbox.cli._common import UsageError, cli_message
    from jaxbox.cli._data import DataOptions, load_data
    from jaxbox.data import DataError

    f = frame()
    instants = pd.date_range("2013-10-26 20:00", periods=len(f), freq="h", tz="Europe/Berlin")
    f["time"] = instants.strftime("%Y-%m-%d %H:%M:%S")
    path = csv(tmp_path / "local.csv", f)
    with pytest.raises(DataError) as info:
        load_data(str(path), DataOptions(_args(data=[str(path)])))
    assert "pass the data's time zone, e.g. --tz Europe/Berlin," in cli_message(str(info.value))
    data = load_data(str(path), DataOptions(_args(data=[str(path)], tz=" Europe/Berlin")))
    assert data.step == 3600.0 and len(data) == len(f) and str(data.index.tz) == "Europe/Berlin"
    with pytest.raises(UsageError, match="--tz is empty"):
        DataOptions(_args(data=[str(path)], tz=" "))
    with pytest.raises(UsageError, match="--tz applies to CSV files"):
        DataOptions(_args(data=["twinhouse_exp1:N2"], tz="UTC"))


def test_time_options_of_the_command_line(tmp_path):
    """--time DATE,CLOCK joins two columns, --time-unit and --epoch read numeric stamps; bad
    values are usage errors before anything is loaded."""
    from jaxbox.cli._common import UsageError
    from jaxbox.cli._data import DataOptions, load_data

    f = frame()
    stamps = pd.DatetimeIndex(f.pop("time"))
    f.insert(0, "clock", stamps.strftime("%H:%M"))
    f.insert(0, "day", stamps.strftime("%d.%m.%Y"))
    path = csv(tmp_path / "two.csv", f)
    opts = DataOptions(_args(data=[str(path)], time="day, clock"))
    assert opts.time == ["day", "clock"]
    assert (load_data(str(path), opts).index == stamps).all()
    g = frame()
    g["time"] = (stamps - pd.Timestamp("1899-12-30")) / pd.Timedelta(days=1)
    path = csv(tmp_path / "serial.csv", g)
    opts = DataOptions(_args(data=[str(path)], time_unit="D", epoch="1899-12-30"))
    data = load_data(str(path), opts)
    assert np.all(np.abs(data.index - stamps) < pd.Timedelta("1ms"))
    for bad, match in [
        (dict(time="a,b,c"), "give one column, or two as DATE,CLOCK"),
        (dict(time_unit="weeks"), "--time-unit 'weeks' is not one of s, ms"),
        (dict(epoch="yesterday-ish"), "--epoch 'yesterday-ish' is not a time stamp"),
    ]:
        with pytest.raises(UsageError, match=match):
            DataOptions(_args(data=[str(path)], **bad))


def _args(**kw):
    import argparse

    base = dict(
        data=[],
        map=[],
        range=[],
        time=None,
        tz=None,
        sep=None,
        decimal=None,
        thousands=None,
        scale=[],
        counter=[],
        resample=None,
        train=None,
        validate=None,
    )
    return argparse.Namespace(**{**base, **kw})


def test_cli_messages_in_command_line_terms():
    from jaxbox.cli._common import cli_message

    msg = cli_message(
        "the data has no column 'T_zon' required by model Zon; available: 'a'; map yours with "
        "columns={'T_zon': 'your_col'} in jaxbox.data.load."
    )
    assert "--map T_zon=" in msg and "columns=" not in msg
    msg = cli_message(
        "x.csv separates its columns with semicolons: pass sep=';' (command line: --sep ';')."
    )
    assert msg == "x.csv separates its columns with semicolons: pass --sep ';'."
    msg = cli_message("irregular sampling …; pass resample= (e.g. resample='1h') to average")
    assert "--resample 1h" in msg and "resample=" not in msg


# -- Ctrl-C ----------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def import_s():
    """How long importing what the command line uses takes in a fresh process here [s]
    (``import jaxbox`` alone is lazy)."""
    t0 = time.perf_counter()
    code = "import jaxbox.cli._main, jaxbox.select, jaxbox.validate"
    subprocess.run([sys.executable, "-c", code], check=True, timeout=300)
    return time.perf_counter() - t0


#: Ctrl-C delays [s]: (after the process starts, after `import jaxbox` is done)
DELAYS = [(0.3, None), (1.0, None), (3.0, None)]
DELAYS += [(None, 0.2), (None, 2.0), (None, 4.0), (None, 6.0)]


@pytest.mark.slow
@pytest.mark.parametrize("delay", DELAYS, ids=lambda d: f"{d[0]}s" if d[0] else f"import+{d[1]}s")
def test_ctrl_c_exits_130_with_one_line_and_no_partial_file(delay, import_s, tmp_path):
    """SIGINT at any moment (importing, loading, compiling, fitting, validating, plotting,
    writing): exit 130, one line, no partial file; or, when it came too late, the complete
    outputs and exit 0."""
    plots = tmp_path / "plots"
    cmd = ["fit", "twinhouse_exp1:N2", "--model", "ZonWal", "--starts", "4", "--plots", "plots"]
    _interrupt([*cmd, "--json"], tmp_path, delay[0] if delay[0] else import_s + delay[1])
    assert not plots.exists() or not any(plots.iterdir()), list(plots.rglob("*"))


@pytest.mark.slow
def test_ctrl_c_during_a_selection_leaves_no_output_folder(import_s, tmp_path):
    cmd = ["select", "twinhouse_exp1:N2", "--models", "Zon,ZonWal", "--starts", "2"]
    _interrupt([*cmd, "--out", "out", "--json"], tmp_path, import_s + 4.0)
    assert not (tmp_path / "out").exists()


def _interrupt(argv, folder, delay):
    """Run ``python -m jaxbox argv`` in ``folder``, press Ctrl-C after ``delay`` seconds, check
    the exit: 130 with one line and nothing in ``folder`` (or 0 when it had finished)."""
    # no compilation cache: the command compiles, as on a first run, and is still busy
    env = {k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}
    env["JAXBOX_CACHE"] = "0"
    proc = subprocess.Popen(
        [sys.executable, "-m", "jaxbox", *argv],
        env=env,
        cwd=folder,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=300)
    # finished before the signal, or the signal came while the interpreter shut down after the
    # command had finished (Python restores the default handler then; a shell reports 130
    # either way): the outputs are complete
    if proc.returncode in (0, -signal.SIGINT):
        assert json.loads(out)
        pytest.skip("the command finished before Ctrl-C")
    assert proc.returncode == 130, err
    assert err.strip().splitlines() == ["error: interrupted"], err
    assert out == ""
    assert all(p.name == "plots" and p.is_dir() for p in folder.iterdir())


# -- the Python API -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def dataset():
    from jaxbox.data import load

    return load(frame().set_index("time"))


@pytest.mark.parametrize(
    "bad", [np.zeros((4, 3)), [1, 2, 3], None, {"T_zon": [1, 2]}, 3.5], ids=type
)
def test_greybox_refuses_what_is_not_data(bad):
    from jaxbox.select import GreyBox

    with pytest.raises(TypeError, match="Dataset.*DataFrame.*path"):
        GreyBox(bad)


def test_greybox_takes_a_dataset_a_dataframe_or_a_path(dataset, tmp_path):
    from jaxbox.select import GreyBox

    path = csv(tmp_path / "data.csv")
    for data in (dataset, frame().set_index("time"), path, str(path)):
        gb = GreyBox(data)
        assert len(gb.data) == N and gb.valid_period is not None


@pytest.mark.parametrize("ranges", [[("T_zon", 0, 50)], "T_zon=0:50", {"T_zon": 5}])
def test_greybox_refuses_malformed_ranges(dataset, ranges):
    from jaxbox.select import GreyBox

    with pytest.raises(TypeError, match="ranges"):
        GreyBox(dataset, ranges=ranges)


def test_greybox_refuses_implausible_windows(dataset):
    from jaxbox.data import DataError
    from jaxbox.select import GreyBox

    f = frame()
    f.loc[40, "T_zon"] = 95.0
    with pytest.raises(DataError, match="T_zon"):
        GreyBox(f.set_index("time"))


@pytest.mark.parametrize(
    "kw, words",
    [
        ({"fixed": ["gA", 1.0]}, "fixed"),
        ({"fixed": "gA=1"}, "fixed"),
        ({"bounds": [(0, 1)]}, "bounds"),
        ({"guess": [1.0, 2.0]}, "guess"),
        ({"free": "R_wal"}, "free"),
        ({"train": "2024-01-01..2024-01-02"}, "train"),
    ],
)
def test_add_case_refuses_lists_and_strings_for_mappings(dataset, kw, words):
    from jaxbox.select import GreyBox

    with pytest.raises(TypeError, match=words):
        GreyBox(dataset).add_case("Zon", **kw)


@pytest.mark.parametrize("bad", [np.zeros(3), 42, None], ids=type)
def test_forward_selection_refuses_what_is_not_a_building(bad):
    from jaxbox.select import forward_selection, forward_selection_many

    with pytest.raises(TypeError, match="GreyBox.*Dataset.*DataFrame.*path"):
        forward_selection(bad, ["Zon"])
    with pytest.raises(TypeError, match="GreyBox"):
        forward_selection_many([bad], ["Zon"])


def test_forward_selection_many_takes_a_list(dataset):
    from jaxbox.select import GreyBox, forward_selection_many

    with pytest.raises(TypeError, match="list"):
        forward_selection_many(GreyBox(dataset), ["Zon"])
    with pytest.raises(TypeError, match="list"):
        forward_selection_many("data.csv", ["Zon"])


def test_a_sensor_taken_with_stuck_hours_is_not_refused_by_the_verdict(
    tmp_path, monkeypatch, capsys
):
    """``--stuck-hours none`` takes a steady column; the fit's verdict in the JSON then checks
    the data as they were loaded, instead of refusing the column again."""
    import json

    monkeypatch.chdir(tmp_path)
    data = stuck(tmp_path)
    argv = ["fit", str(data), "--model", "Zon", "--starts", "2", "--stuck-hours", "none"]
    code = main([*argv, "--json"])
    out = capsys.readouterr()
    assert code == 0, out.err
    doc = json.loads(out.out)
    said = [*doc["reasons"], *doc["warnings"]]
    assert said and not [r for r in said if "stays exactly" in r], said


def test_the_command_line_keeps_a_column_name_as_it_is_and_names_the_signals_in_gaps():
    """A column 'AUX2  [W]' (two spaces) is quoted as it is, so it can be copied into --map;
    the gap warning names the signals the models read and only counts the other columns."""
    from jaxbox.cli._common import cli_message
    from jaxbox.data import DataWarning, load

    assert cli_message("columns: 'AUX2  [W]',\n  'Ph'.") == "columns: 'AUX2  [W]', 'Ph'."
    stamps = pd.date_range("2024-01-01", periods=48, freq="h")
    frame = pd.DataFrame(
        {"time": stamps, "T_zon": 20.0, "T_amb": 5.0, "Setpoint": 20.0, "Mode": 0.0}
    )
    frame.loc[10:12, ["T_zon", "Setpoint", "Mode"]] = np.nan
    with pytest.warns(DataWarning, match="the data have gaps") as seen:
        load(frame)
    (note,) = [str(w.message) for w in seen if "the data have gaps" in str(w.message)]
    assert "'T_zon' (3, the first at 2024-01-01 10:00:00)" in note
    assert "Setpoint" not in note and "(and 2 other columns no model reads)" in note
