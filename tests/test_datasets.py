"""Tests of jaxbox.datasets: the shipped twin-house data and their derivation."""

from __future__ import annotations

import csv
import importlib.util
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jaxbox.data import DataError, Dataset
from jaxbox.datasets import CITATION, TWINHOUSE_EXP1_PHASES, twinhouse_exp1

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data" / "twinhouse_exp1"
COLUMNS = {
    "T_zon", "T_amb", "T_bou", "T_cel", "T_gro", "T_sup", "Q_hea", "Q_ven",
    "I_glo_hor", "I_dif_hor", "I_n", "I_e", "I_s", "I_w",
}  # fmt: skip
HOUSES = ("N2", "O5")
#: Rounding unit of the shipped files per column prefix.
UNIT = {"T": 1e-3, "Q": 0.1, "I": 0.1}


def phase(ds: Dataset, number: int) -> Dataset:
    start, end, _ = TWINHOUSE_EXP1_PHASES[number - 1]
    return ds.slice(start, end)


@pytest.mark.parametrize("house", HOUSES)
@pytest.mark.parametrize(("resolution", "n", "step"), [("1h", 984, 3600.0), ("10min", 5905, 600.0)])
def test_loads(house: str, resolution: str, n: int, step: float) -> None:
    ds = twinhouse_exp1(house, resolution)
    assert isinstance(ds, Dataset)
    assert set(ds.columns) == COLUMNS
    assert len(ds) == n
    assert ds.step == step
    assert ds.end == pd.Timestamp("2013-10-01 00:00")
    assert not np.isnan(ds.array(list(ds.columns))).any()


def test_hourly_time_base() -> None:
    ds = twinhouse_exp1()
    assert ds.start == pd.Timestamp("2013-08-21 01:00")
    assert ds.columns == twinhouse_exp1("O5").columns
    assert twinhouse_exp1("N2", "10min").start == pd.Timestamp("2013-08-21 00:00")


def test_bad_choices() -> None:
    with pytest.raises(DataError, match="unknown house 'N3'; choose one of 'N2', 'O5'"):
        twinhouse_exp1("N3")
    with pytest.raises(DataError, match="unknown resolution '15min'.*'1h', '10min'"):
        twinhouse_exp1("N2", "15min")
    assert twinhouse_exp1("o5").equals(twinhouse_exp1("O5"))


@pytest.mark.parametrize("house", HOUSES)
def test_plausible_values(house: str) -> None:
    ds = twinhouse_exp1(house, "10min")
    t_zon, q_hea = ds["T_zon"], ds["Q_hea"]
    assert (t_zon > 14.0).all() and (t_zon < 32.0).all()
    assert (q_hea >= 0.0).all() and (q_hea < 6000.0).all()  # six heaters
    assert (ds["T_amb"] > 0.0).all() and (ds["T_amb"] < 30.0).all()
    for name in ("I_glo_hor", "I_dif_hor", "I_n", "I_e", "I_s", "I_w"):
        assert (ds[name] >= 0.0).all() and (ds[name] < 1100.0).all()
    assert (ds["I_dif_hor"] <= ds["I_glo_hor"] + 5.0).all()  # within sensor noise

    one = phase(ds, 1)  # all rooms at 30 °C
    assert abs(one["T_zon"].mean() - 30.0) < 0.3
    assert (one["T_zon"] > 29.0).all() and (one["T_zon"] < 31.0).all()
    assert (one["Q_hea"] < 3000.0).all() and one["Q_hea"].mean() > 1000.0
    three = phase(ds, 3).slice("2013-09-15")  # 25 °C, after the first day of cooling down
    assert abs(three["T_zon"].mean() - 25.0) < 0.2
    four = phase(ds, 4)  # free float: heaters off (O5: a few W of standby)
    assert four["Q_hea"].max() < 100.0


@pytest.mark.parametrize("house", HOUSES)
def test_rolbs_pulses_in_phase_2(house: str) -> None:
    q = phase(twinhouse_exp1(house, "10min"), 2)["Q_hea"]
    on = (q > 450.0) & (q < 550.0)
    off = q < 100.0
    assert on.mean() > 0.3 and off.mean() > 0.3 and (on | off).mean() > 0.95
    switches = np.count_nonzero(np.diff(on.astype(int)) != 0)
    assert switches > 50  # many pulses of varied length
    hourly = phase(twinhouse_exp1(house, "1h"), 2)["Q_hea"]
    assert hourly.max() > 450.0 and hourly.min() < 100.0


def test_phases() -> None:
    assert len(TWINHOUSE_EXP1_PHASES) == 4
    fine = twinhouse_exp1("N2", "10min")
    assert TWINHOUSE_EXP1_PHASES[0][0] == fine.start
    assert TWINHOUSE_EXP1_PHASES[-1][1] == fine.end
    for (_, end, _), (start, _, _) in zip(
        TWINHOUSE_EXP1_PHASES[:-1], TWINHOUSE_EXP1_PHASES[1:], strict=True
    ):
        assert start - end == pd.Timedelta("10min")
    assert sum(len(phase(fine, i)) for i in range(1, 5)) == len(fine)
    hourly = twinhouse_exp1("N2", "1h")
    assert sum(len(phase(hourly, i)) for i in range(1, 5)) == len(hourly)


@pytest.mark.parametrize("house", HOUSES)
def test_hourly_file_is_mean_of_10min_file(house: str) -> None:
    # Independent of the resampler: the hour ending at hh:00 averages the six 10-min samples
    # stamped hh-1:10 ... hh:00; the single sample at 08-21 00:00 starts an incomplete hour.
    fine = twinhouse_exp1(house, "10min")
    hourly = twinhouse_exp1(house, "1h")
    names = list(hourly.columns)
    assert list(fine.columns) == names
    values = fine.array(names)[1:]
    expected = values.reshape(-1, 6, len(names)).mean(axis=1)
    assert (fine.index[1:][5::6] == hourly.index).all()
    # both files are rounded: their difference is at most one rounding unit
    atol = np.array([UNIT[name[0]] for name in names]) * (1.0 + 1e-6)
    assert (np.abs(hourly.array(names) - expected) <= atol).all()


def test_credit_and_license() -> None:
    assert "Annex 58" in CITATION and "Fraunhofer IBP" in CITATION and "BSD" in CITATION
    text = (resources.files("jaxbox.datasets") / "LICENSE_IDEAS.txt").read_text(encoding="utf-8")
    assert "Copyright (c) 1998-2025 Modelica Association, KU Leuven, 3E" in text
    assert "Annex 58" in text and "Fraunhofer IBP" in text


def test_shipped_files_are_small() -> None:
    files = resources.files("jaxbox.datasets") / "files"
    sizes = [entry.stat().st_size for entry in Path(str(files)).glob("*.csv.gz")]
    assert len(sizes) == 4
    assert sum(sizes) < 1_000_000


# -- derivation from the measured tables (only where they are available) -------------------------

needs_source = pytest.mark.skipif(not SHARED.is_dir(), reason=f"no source data in {SHARED}")


def _build_tool():
    spec = importlib.util.spec_from_file_location(
        "build_twinhouse", ROOT / "tools" / "build_twinhouse.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@needs_source
@pytest.mark.parametrize("house", HOUSES)
def test_shipped_files_match_fresh_derivation(house: str, tmp_path: Path) -> None:
    tool = _build_tool()
    derived = tool.derive(SHARED, house)
    for resolution, frame in derived.items():
        shipped = twinhouse_exp1(house, resolution).frame
        pd.testing.assert_index_equal(shipped.index, frame.index)
        assert list(shipped.columns) == list(frame.columns)
        np.testing.assert_array_equal(shipped.to_numpy(), frame.to_numpy())
        # writing is reproducible byte for byte
        path = tmp_path / f"{resolution}.csv.gz"
        tool.write(frame, path)
        assert path.read_bytes() == tool.output_file(house, resolution).read_bytes()


@needs_source
@pytest.mark.parametrize("house", HOUSES)
def test_lumping_by_hand(house: str) -> None:
    # Rebuild T_zon and Q_hea of a few rows straight from the source table with the csv module.
    with open(SHARED / f"twinhouse_{house}_exp1_10min.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    fine = twinhouse_exp1(house, "10min")
    p = f"{house}_"
    for i in (0, 1000, 2500, 5904):
        row = {key: float(value) for key, value in rows[i].items() if key != "datetime_utc+1"}
        living = (
            row[p + "living_AT_h67cm"] + row[p + "living_AT_h125cm"] + row[p + "living_AT_h187cm"]
        ) / 3
        others = [
            row[f"{p}{room}_AT"] for room in ("bath", "child", "kitchen", "doorway", "bedroom")
        ]
        heaters = ("living_room", "bath_room", "children_room", "kitchen", "doorway", "bedroom")
        assert fine.index[i] == pd.Timestamp(rows[i]["datetime_utc+1"])
        assert fine["T_zon"][i] == pytest.approx((living + sum(others)) / 6, abs=5e-4)
        assert fine["Q_hea"][i] == pytest.approx(
            sum(row[p + "heat_elP_" + h] for h in heaters), abs=0.05
        )
        assert fine["T_bou"][i] == pytest.approx(
            (row[p + "attic_east_AT"] + row[p + "attic_west_AT"]) / 2, abs=5e-4
        )
        assert fine["T_amb"][i] == pytest.approx(row["Ambient_temperature"], abs=5e-4)
        assert fine["I_s"][i] == pytest.approx(
            row["Solar_radiation_global_vertical_south"], abs=0.05
        )
        assert fine["Q_ven"][i] == pytest.approx(row[p + "vent_thP"], abs=0.05)
