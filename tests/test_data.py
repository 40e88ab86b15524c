"""Tests of jaxbox.data: loading, checks, the Dataset value object."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from jaxbox.data import SIGNALS, DataError, Dataset, DataWarning, load, signal_unit

STEP = 600.0  # s


def frame(n: int = 13, step: float = STEP, start: str = "2020-01-01 00:00") -> pd.DataFrame:
    """A small regular DataFrame with a ``time`` column of ISO strings."""
    time = pd.Timestamp(start) + pd.to_timedelta(np.arange(n) * step, unit="s")
    return pd.DataFrame(
        {
            "time": time.strftime("%Y-%m-%d %H:%M:%S"),
            "T_zon": 20.0 + np.arange(n),
            "Q_hea": 100.0 * np.arange(n),
        }
    )


def synthetic(n: int = 37, step: float = STEP) -> Dataset:
    t = np.arange(n) * step
    return Dataset.from_arrays(t, {"T_zon": 20.0 + t / 3600.0, "Q_hea": 10.0 * np.arange(n)})


# -- signals --------------------------------------------------------------------------------------


def test_signal_units() -> None:
    assert signal_unit("T_zon") == "°C"
    assert signal_unit("T_zon2") == "°C"
    assert signal_unit("T_bou1") == "°C"
    assert signal_unit("Q_hea3") == "W"
    assert signal_unit("I_glo_hor") == "W/m²"
    assert signal_unit("P_ele") == "W"
    assert signal_unit("living_T") is None
    assert signal_unit("T_zonX") is None
    for name, (unit, description) in SIGNALS.items():
        assert signal_unit(name) == unit
        assert description


# -- load: sources and time -----------------------------------------------------------------------


def test_load_dataframe_with_time_column() -> None:
    ds = load(frame())
    assert ds.columns == ("T_zon", "Q_hea")
    assert ds.index.name == "time"
    assert ds.step == STEP
    assert len(ds) == 13
    assert ds.start == pd.Timestamp("2020-01-01 00:00")
    assert ds.end == pd.Timestamp("2020-01-01 02:00")
    np.testing.assert_array_equal(ds.t, np.arange(13) * STEP)
    assert ds.t.dtype == np.float64


def test_load_dataframe_with_datetime_index() -> None:
    df = frame()
    df.index = pd.DatetimeIndex(pd.to_datetime(df.pop("time")))
    ds = load(df)
    assert ds.columns == ("T_zon", "Q_hea")
    assert ds.step == STEP


def test_load_csv(tmp_path) -> None:
    path = tmp_path / "data.csv"
    frame().rename(columns={"T_zon": "living"}).to_csv(path, index=False)
    ds = load(path, columns={"T_zon": "living"})
    assert ds.columns == ("T_zon", "Q_hea")
    np.testing.assert_array_equal(ds["T_zon"], 20.0 + np.arange(13))
    assert load(str(path)).columns == ("living", "Q_hea")


def test_load_does_not_modify_the_input() -> None:
    df = frame()
    before = df.copy()
    load(df, columns={"T_zon1": "T_zon"})
    pd.testing.assert_frame_equal(df, before)


def test_numeric_time_is_seconds_since_1970() -> None:
    df = frame().assign(time=np.arange(13) * STEP + 86400.0)
    ds = load(df)
    assert ds.start == pd.Timestamp("1970-01-02 00:00")
    assert ds.step == STEP
    assert load(df, epoch="2013-01-01").start == pd.Timestamp("2013-01-02 00:00")


def test_named_time_column_is_dropped() -> None:
    df = frame().rename(columns={"time": "stamp"})
    ds = load(df, time="stamp")
    assert "stamp" not in ds.columns


def test_file_not_found(tmp_path) -> None:
    with pytest.raises(DataError, match="file not found.*nope.csv"):
        load(tmp_path / "nope.csv")


def test_no_time_column() -> None:
    df = frame().rename(columns={"time": "when"})
    with pytest.raises(
        DataError, match=r"no time column found \(tried 'time'.*time=.*columns: 'when'"
    ):
        load(df)
    with pytest.raises(DataError, match="no time column 'stamp'.*'when'"):
        load(df, time="stamp")


def test_no_time_column_suggests_likely_names() -> None:
    df = frame().rename(columns={"time": "Date_Time"})
    with pytest.raises(DataError, match=r"perhaps 'Date_Time'"):
        load(df)


def test_text_columns_are_dropped_with_a_warning() -> None:
    df = frame().assign(note="ok", stamp=pd.Timestamp("2020-01-01"))
    with pytest.warns(UserWarning, match="dropped column.*'note', 'stamp'"):
        ds = load(df)
    assert ds.columns == ("T_zon", "Q_hea")
    df = frame().assign(T_amb="cold")  # a canonical name must hold numbers
    with pytest.raises(DataError, match="column 'T_amb' has a non-numeric value 'cold' at row 0"):
        load(df)


def test_unparseable_time_stamp_names_row() -> None:
    df = frame()
    df.loc[4, "time"] = "yesterday"
    with pytest.raises(DataError, match="cannot parse the time stamp 'yesterday'.*row 4"):
        load(df)


def test_unparseable_time_stamp_names_csv_line(tmp_path) -> None:
    df = frame()
    df.loc[4, "time"] = "2020-13-45 00:00"
    path = tmp_path / "bad.csv"
    df.to_csv(path, index=False)
    with pytest.raises(DataError, match=r"row 4 \(line 6 of bad.csv\)"):
        load(path)


def test_non_iso_time_strings_are_inferred() -> None:
    df = frame()
    df["time"] = pd.to_datetime(df["time"]).dt.strftime("%d/%m/%Y %H:%M")
    assert load(df).step == STEP


def test_non_monotonic_time_stamps() -> None:
    df = frame()
    df.loc[[5, 6], "time"] = df.loc[[6, 5], "time"].to_numpy()
    with pytest.raises(
        DataError, match=r"not increasing: row 6 has 2020-01-01 00:50:00, earlier than .* at row 5"
    ):
        load(df)


def test_duplicate_time_stamps() -> None:
    df = frame()
    df.loc[7, "time"] = df.loc[6, "time"]
    df.loc[8:, "time"] = frame(n=13, start="2020-01-01 00:10")["time"].iloc[8:].to_numpy()
    with pytest.raises(
        DataError, match="duplicate time stamp 2020-01-01 01:00:00 at row 6 and row 7"
    ):
        load(df)


def test_irregular_sampling_suggests_resample() -> None:
    df = frame(n=20)
    df.loc[9, "time"] = "2020-01-01 01:35:00"  # 900 s and 300 s: not whole steps
    with pytest.raises(
        DataError, match=r"irregular sampling.*01:20:00 to .*01:35:00.*900 s.*resample="
    ):
        load(df)


@pytest.mark.parametrize(
    ("step", "rule"),
    [(600, "10min"), (900, "15min"), (120, "5min"), (3000, "1h"), (9000, "3h")],
)
def test_irregular_sampling_suggests_a_grid_as_fine_as_the_data(step, rule) -> None:
    """Jittered time stamps (a logger's clock) are told to resample onto the finest usual grid
    not finer than their step, not onto hours whatever the step."""
    rng = np.random.default_rng(0)
    t = pd.Timestamp("2020-01-01") + pd.to_timedelta(
        step * np.arange(40) + rng.integers(-step // 20, step // 20, 40), unit="s"
    )
    df = pd.DataFrame({"time": t, "T_zon": 20.0 + rng.normal(size=40)})
    with pytest.raises(DataError, match=rf"irregular sampling.*resample='{rule}'\)"):
        load(df)


def test_hourly_stamps_that_jitter_with_rows_missing_resample_hourly() -> None:
    """A logger that stamps hourly within ±5 minutes and loses a third of its rows: the
    median step (3829 s here) lies above the hour, but the logger's own step is the hour; the
    error suggests it, and resample='1h' averages onto it (lost rows become gaps)."""
    from jaxbox.data._checks import nominal_step

    rng = np.random.default_rng(0)
    n = 240
    kept = rng.random(n) > 0.35
    t = pd.Timestamp("2020-01-01") + pd.to_timedelta(
        3600 * np.arange(n) + rng.integers(-300, 300, n), unit="s"
    )
    df = pd.DataFrame({"time": t, "T_zon": 20.0 + np.sin(np.arange(n) / 5)})[kept]
    index = pd.DatetimeIndex(df["time"]).as_unit("ns")
    assert np.median(np.diff(index.asi8)) * 1e-9 > 3600 * 1.05
    assert nominal_step(index) == pytest.approx(3600, rel=0.05)
    with pytest.raises(DataError, match=r"irregular sampling.*resample='1h'\)"):
        load(df)
    ds = load(df, resample="1h")
    assert ds.step == 3600.0 and 0.2 < np.isnan(ds["T_zon"]).mean() < 0.5
    with pytest.raises(DataError, match="shorter than the sampling step"):
        load(df, resample="30min")  # half the logger's step: not an average


def test_local_time_with_utc_offsets_across_a_clock_change() -> None:
    """Local time stamps with their offsets (summer time +02:00, then +01:00) are instants: they
    are read onto one regular grid at the first offset, with a warning naming the offsets."""
    instants = pd.date_range("2013-10-26 22:00", periods=12, freq="h", tz="Europe/Berlin")
    df = pd.DataFrame(
        {"time": instants.strftime("%Y-%m-%d %H:%M:%S%z"), "T_zon": 20.0 + np.arange(12)}
    )
    assert df["time"].str[-5:].nunique() == 2  # +0200 before 03:00 on the 27th, +0100 after
    with pytest.warns(DataWarning, match=r"several UTC offsets \(\+01:00, \+02:00.*\+02:00"):
        ds = load(df)
    assert ds.step == 3600.0 and len(ds) == 12 and np.isfinite(ds["T_zon"]).all()
    np.testing.assert_array_equal(ds["T_zon"], 20.0 + np.arange(12))
    assert ds.index[0].utcoffset() == pd.Timedelta("2h")
    assert (ds.index.tz_convert("UTC") == instants.tz_convert("UTC")).all()
    half = df.assign(time=df["time"].where(df.index < 6, instants.strftime("%Y-%m-%d %H:%M:%S")))
    with pytest.raises(DataError, match="stamps with a UTC offset and stamps without one"):
        load(half)
    # the same clock without offsets repeats 02:00: refused, and the message says why
    naive = df.assign(time=instants.strftime("%Y-%m-%d %H:%M:%S"))
    with pytest.raises(DataError, match=r"duplicate time stamp 2013-10-27 02:00:00.*daylight"):
        load(naive)


def _local_clock(start: str, periods: int, freq: str) -> pd.DataFrame:
    """Naive local clock time in Berlin (as many loggers write it) from regular instants; the
    temperature counts the instants."""
    instants = pd.date_range(start, periods=periods, freq=freq, tz="Europe/Berlin")
    return pd.DataFrame(
        {"time": instants.strftime("%Y-%m-%d %H:%M:%S"), "T_zon": 20.0 + 0.01 * np.arange(periods)}
    )


@pytest.mark.parametrize("freq", ["10min", "1h"])
def test_local_clock_time_read_in_its_time_zone_across_the_end_of_summer_time(freq) -> None:
    """The hour repeated when the clocks go back is refused without a time zone (its stamps go
    back or repeat; the message names tz= and --tz) and read in order with one: a regular grid
    of instants, every sample kept, in that zone."""
    df = _local_clock("2013-10-27 00:00", 30, freq)
    with pytest.raises(DataError, match=r"daylight saving.*tz='Europe/Berlin' \(command line"):
        load(df)
    ds = load(df, tz="Europe/Berlin")
    step = pd.Timedelta(freq).total_seconds()
    assert ds.step == step and len(ds) == 30 and str(ds.index.tz) == "Europe/Berlin"
    np.testing.assert_array_equal(ds["T_zon"], df["T_zon"])
    assert np.all(np.diff(ds.index.asi8) == int(step * 1e9))
    assert ds.index[0].utcoffset() == pd.Timedelta("2h")
    assert ds.index[-1].utcoffset() == pd.Timedelta("1h")


def test_local_clock_time_across_the_start_of_summer_time(tmp_path) -> None:
    """The skipped hour is a gap in naive stamps, and the gap note says it is the clock change;
    with the time zone there is no gap. A stamp inside the skipped hour, an hour the clocks
    repeat that is logged once, and an unknown zone are refused, naming the row or the zone."""
    df = _local_clock("2013-03-31 00:00", 30, "10min")
    with pytest.warns(DataWarning, match=r"missing on Sunday 2013-03-31 is where the clocks go"):
        gappy = load(df)
    assert gappy["T_zon"].size == 36 and np.isnan(gappy["T_zon"]).sum() == 6
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ds = load(df, tz="Europe/Berlin")
    assert len(ds) == 30 and ds.step == 600.0 and not np.isnan(ds["T_zon"]).any()
    # a gap of the same hour on an ordinary day is only a gap
    plain = df.assign(time=df["time"].str.replace("2013-03-31", "2013-03-28"))
    plain = plain[~plain["time"].str.contains(" 02:")]
    with pytest.warns(DataWarning) as record:
        load(plain)
    assert not any("clocks" in str(w.message) for w in record)
    bad = df.iloc[:13].copy()
    bad.loc[12, "time"] = "2013-03-31 02:30:00"
    path = tmp_path / "local.csv"
    bad.to_csv(path, index=False)
    with pytest.raises(DataError, match=r"02:30:00.*row 12 \(line 14 of local.csv\) does not ex"):
        load(path, tz="Europe/Berlin")
    once = pd.DataFrame(
        {"time": ["2013-10-27 01:00", "2013-10-27 02:00", "2013-10-27 03:00"], "T_zon": 20.0}
    )
    with pytest.raises(DataError, match=r"02:00:00.*row 1 .*repeats in Europe/Berlin"):
        load(once, tz="Europe/Berlin")
    with pytest.raises(DataError, match=r"unknown time zone 'Mars/Base'"):
        load(df, tz="Mars/Base")


def test_stamps_with_offsets_are_converted_to_the_time_zone() -> None:
    utc = pd.date_range("2013-10-27", periods=5, freq="h", tz="UTC")
    ds = load(
        pd.DataFrame({"time": utc.strftime("%Y-%m-%dT%H:%M:%SZ"), "T_zon": 20.0}), tz="+01:00"
    )
    assert ds.index[0] == utc[0] and ds.index[0].utcoffset() == pd.Timedelta("1h")


def _seconds_frame(numbers) -> pd.DataFrame:
    return pd.DataFrame({"time": numbers, "T_zon": 20.0 + 0.01 * np.arange(len(numbers))})


STAMPS = pd.date_range("2024-01-30", periods=300, freq="10min")
UNIX_S = np.asarray((STAMPS - pd.Timestamp("1970-01-01")) // pd.Timedelta(seconds=1))


@pytest.mark.parametrize(("unit", "factor"), [("ms", 1000), ("us", 10**6)])
def test_epoch_numbers_in_a_finer_unit_are_refused_naming_it(unit, factor) -> None:
    """Milliseconds since 1970 read as seconds would be the year 55 000: a clear error that
    names time_unit= (no pandas overflow), and with it the stamps are right."""
    df = _seconds_frame(UNIX_S * factor)
    with pytest.raises(
        DataError, match=rf"reach the year \d+; they look like .*time_unit='{unit}'"
    ):
        load(df)
    ds = load(df, time_unit=unit)
    assert (ds.index == STAMPS).all() and ds.step == 600.0


def test_epoch_numbers_in_a_coarser_unit_or_spreadsheet_days_are_a_warning() -> None:
    """Numbers that read as seconds land in 1970 but make sense as minutes, or as spreadsheet
    serial days: a warning naming the reading; seconds since an experiment's start stay
    silent; an unknown unit is refused."""
    with pytest.warns(DataWarning, match=r"start in 1970; if they are minutes .*time_unit='min'"):
        load(_seconds_frame(UNIX_S // 60))
    serial = ((STAMPS - pd.Timestamp("1899-12-30")) / pd.Timedelta(days=1)).to_numpy()
    with pytest.warns(DataWarning, match=r"spreadsheet serial dates.*epoch='1899-12-30'"):
        load(_seconds_frame(serial))
    ds = load(_seconds_frame(serial), time_unit="D", epoch="1899-12-30")
    assert np.all(np.abs(ds.index - STAMPS) < pd.Timedelta("1ms")) and ds.step == 600.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ds = load(_seconds_frame(600.0 * np.arange(300)))
        # hours 8 to 12 of an experiment: read as days since 1899 they are 1982 … 2021, but
        # ten-minute steps are not 600 days
        late = load(_seconds_frame(30000.0 + 600.0 * np.arange(25)))
    assert ds.index[0] == pd.Timestamp("1970-01-01") and ds.step == 600.0
    assert late.step == 600.0
    with pytest.raises(DataError, match=r"unknown time_unit 'fortnight'"):
        load(_seconds_frame(UNIX_S), time_unit="fortnight")


@pytest.mark.parametrize("fmt", ["%d/%m/%Y %H:%M", "%d.%m.%Y %H:%M", "%m/%d/%Y %I:%M %p"])
def test_day_first_stamps_read_in_the_order_their_steps_say(fmt) -> None:
    """31/01/2024 and 01/02/2024 day first, 01/31/2024 month first: each read onto the regular
    grid it was written on (read month first, 02/01 would be a month after 01/01, the samples
    between missing)."""
    df = pd.DataFrame({"time": STAMPS.strftime(fmt), "T_zon": 20.0})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ds = load(df)
    assert (ds.index == STAMPS).all() and ds.step == 600.0


def test_dates_and_clock_times_in_two_columns() -> None:
    """A clock-only time column is refused naming the pair; the pair is joined; without a
    time column, the message suggests the pair; a signal mapped to the date column is
    refused."""
    df = pd.DataFrame(
        {"Date": STAMPS.strftime("%d.%m.%Y"), "time": STAMPS.strftime("%H:%M"), "T_zon": 20.0}
    )
    with pytest.raises(DataError, match=r"clock times without dates \('00:00'\).*time=\["):
        load(df)
    ds = load(df, time=["Date", "time"])
    assert (ds.index == STAMPS).all() and ds.columns == ("T_zon",)
    renamed = df.rename(columns={"time": "Time"})
    with pytest.raises(DataError, match=r"clock times.*time=\['Date', 'Time'\] \(command line"):
        load(renamed)
    with pytest.raises(DataError, match=r"which is the time column"):
        load(renamed, time=["Date", "Time"], columns={"T_amb": "Date"})
    with pytest.raises(DataError, match=r"time= takes one column name or two"):
        load(renamed, time=["Date", "Time", "T_zon"])
    german = renamed.rename(columns={"Date": "Datum", "Time": "Uhrzeit"})
    with pytest.raises(DataError, match=r"or time=\['Datum', 'Uhrzeit'\]"):
        load(german)


def test_export_quirks_of_csv_files(tmp_path) -> None:
    """Spaces around the names and a separator at the end of every line are tidied away; a
    header repeated inside the file, a summary row at its end and a spreadsheet workbook are
    refused, each saying what it is."""
    body = frame(n=6)
    text = body.to_csv(index=False)
    path = tmp_path / "export.csv"
    path.write_text(text.replace("time,T_zon,Q_hea", "time , T_zon,Q_hea ").replace("\n", ",\n"))
    ds = load(path)
    assert ds.columns == ("T_zon", "Q_hea") and len(ds) == 6
    path.write_text(text + text.replace("2020", "2021"))
    with pytest.raises(DataError, match=r"'time' .* \(line 8 of export.csv\): the header repeated"):
        load(path)
    path.write_text(text + "Total,120,3000\n")
    with pytest.raises(DataError, match=r"'Total' .*, the last row: a summary line\? drop it"):
        load(path)
    book = tmp_path / "data.xlsx"
    book.write_bytes(b"PK\x03\x04" + bytes(100))
    with pytest.raises(DataError, match=r"spreadsheet workbook, not a CSV.*pd.read_excel"):
        load(book)


def test_a_row_of_units_under_the_header_is_skipped(tmp_path) -> None:
    """Exports often put units under the names: that line is skipped with a warning, and the
    line numbers of later errors still point into the file. A first row that holds a number is
    data, not units."""
    body = frame(n=6)
    lines = ["time,T_zon,Q_hea", "-,degC,kW"]
    lines += [f"{r.time},{r.T_zon},{r.Q_hea}" for r in body.itertuples()]
    path = tmp_path / "units.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.warns(DataWarning, match=r"line 2 of units.csv holds units.*'degC', 'kW'"):
        ds = load(path)
    assert len(ds) == 6 and ds["T_zon"][0] == 20.0 and ds["Q_hea"][5] == 500.0
    lines[5] = lines[5].replace(",23.0,", ",x,")
    path.write_text("\n".join(lines) + "\n")
    with (
        pytest.warns(DataWarning, match="holds units"),
        pytest.raises(DataError, match=r"'x' at row 3 \(line 6 of units.csv\)"),
    ):
        load(path)
    lines[1] = "-,degC,0"  # a number: data (and an error), not a row of units
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"'-' .*at row 0 \(line 2 of units.csv\)"):
        load(path)


def test_missing_rows_are_gaps() -> None:
    df = frame(n=20).drop(index=[9, 10]).reset_index(drop=True)  # 01:30 and 01:40 missing
    with pytest.warns(
        DataWarning,
        match=r"gaps: missing samples in 'T_zon' \(2, the first at 2020-01-01 01:30:00\)",
    ):
        ds = load(df)
    assert len(ds) == 20 and ds.step == STEP
    assert np.isnan(ds["T_zon"][9:11]).all() and np.isfinite(ds["T_zon"][[8, 11]]).all()


def test_irregular_sampling_accepted_with_resample() -> None:
    df = frame(n=25).drop(index=9).reset_index(drop=True)  # 00:00 ... 04:00 without 01:30
    ds = load(df, resample="1h")
    assert ds.step == 3600.0
    assert list(ds.index) == list(pd.date_range("2020-01-01 01:00", periods=4, freq="1h"))
    # the second hour (01:00, 02:00] holds 01:10, 01:20, 01:40, 01:50, 02:00
    assert ds["T_zon"][1] == pytest.approx(np.mean(20.0 + np.array([7, 8, 10, 11, 12])))


def test_irregular_sampling_allowed_without_checks() -> None:
    df = frame(n=20).drop(index=9).reset_index(drop=True)
    assert load(df, check=False).step == STEP


def test_non_numeric_value() -> None:
    df = frame()
    df["Q_hea"] = df["Q_hea"].astype(object)
    df.loc[3, "Q_hea"] = "n/a"
    with pytest.raises(DataError, match="column 'Q_hea' has a non-numeric value 'n/a' at row 3"):
        load(df)


def test_decimal_comma_hint(tmp_path) -> None:
    path = tmp_path / "comma.csv"
    path.write_text('time,T_zon\n2020-01-01 00:00,"20,5"\n2020-01-01 00:10,"20,6"\n')
    with pytest.raises(DataError, match=r"'20,5' at row 0 \(line 2 of comma.csv\).*decimal"):
        load(path)


def test_missing_values_are_kept_and_noted(tmp_path) -> None:
    df = frame()
    df.loc[[3, 4, 9], "T_zon"] = np.nan
    with pytest.warns(
        DataWarning,
        match=r"missing samples in 'T_zon' \(3, the first at 2020-01-01 00:30:00\).*--max-gap",
    ):
        ds = load(df)
    assert np.isnan(ds["T_zon"][[3, 4, 9]]).all()
    path = tmp_path / "gap.csv"
    frame().to_csv(path, index=False)
    text = path.read_text().splitlines()
    text[3] = text[3].rsplit(",", 1)[0] + ","  # empty Q_hea in the third data row
    path.write_text("\n".join(text) + "\n")
    with pytest.warns(DataWarning, match=r"'Q_hea' \(1, the first at 2020-01-01 00:20:00\)"):
        assert np.isnan(load(path)["Q_hea"][2])


def test_kelvin_temperature() -> None:
    df = frame().assign(T_amb=np.full(13, 283.15))
    with pytest.raises(DataError, match=r"'T_amb' looks like kelvin.*subtract 273.15"):
        load(df)
    # a non-canonical column may hold anything
    assert "Tk" in load(frame().assign(Tk=np.full(13, 283.15))).columns


def test_mapping_to_missing_column_lists_available() -> None:
    with pytest.raises(
        DataError,
        match=r"maps 'T_zon' to 'living_T'.*no column 'living_T'.*available: 'T_zon', 'Q_hea'",
    ):
        load(frame(), columns={"T_zon": "living_T"})
    with pytest.raises(DataError, match=r"did you mean 'Q_hea'"):
        load(frame(), columns={"Q_hea1": "Q_heat"})


def test_mapping_written_backwards() -> None:
    df = frame().rename(columns={"T_zon": "living"})
    with pytest.raises(DataError, match=r"canonical -> yours: \{'T_zon': 'living'\}"):
        load(df, columns={"living": "T_zon"})


def test_mapping_collides_with_existing_column() -> None:
    df = frame().assign(living=1.0)
    with pytest.raises(DataError, match="two columns would be named 'T_zon'.*'living'"):
        load(df, columns={"T_zon": "living"})
    # swapping names is fine
    ds = load(df, columns={"T_zon": "living", "T_zon2": "T_zon"})
    assert ds["T_zon"][0] == 1.0 and ds["T_zon2"][0] == 20.0


def test_mapping_same_column_twice() -> None:
    with pytest.raises(DataError, match="'T_zon' is mapped twice"):
        load(frame(), columns={"T_zon1": "T_zon", "T_zon2": "T_zon"})


def test_duplicate_column_names() -> None:
    df = pd.concat([frame(), frame()[["T_zon"]]], axis=1)
    with pytest.raises(DataError, match="two columns are named 'T_zon'"):
        load(df)


def test_load_resample() -> None:
    ds = load(frame(n=13), resample="1h")
    assert ds.step == 3600.0
    assert len(ds) == 2  # (23:00, 00:00] is incomplete and dropped


# -- resample -------------------------------------------------------------------------------------


def test_resample_hand_computed() -> None:
    ds = synthetic(n=37)  # 00:00 ... 06:00 every 10 min
    hourly = ds.resample("1h")
    # (00:00, 01:00] averages the samples at 00:10 ... 01:00, i.e. numbers 1 ... 6
    expected = ds.array(["T_zon", "Q_hea"])[1:].reshape(6, 6, 2).mean(axis=1)
    np.testing.assert_allclose(hourly.array(["T_zon", "Q_hea"]), expected, rtol=0, atol=1e-12)
    assert list(hourly.index) == list(pd.date_range("2000-01-01 01:00", periods=6, freq="1h"))
    assert hourly["Q_hea"][0] == 35.0  # mean of 10, 20, ..., 60 W
    assert hourly.step == 3600.0


def test_resample_drops_incomplete_last_interval() -> None:
    ds = synthetic(n=40)  # ends at 06:30
    hourly = ds.resample("1h")
    assert hourly.end == pd.Timestamp("2000-01-01 06:00")
    assert len(hourly) == 6


def test_resample_keeps_complete_first_interval() -> None:
    ds = synthetic(n=37).slice("2000-01-01 00:10")  # 00:10 ... 06:00: six complete hours
    assert len(ds.resample("1h")) == 6


def test_resample_errors() -> None:
    ds = synthetic()
    with pytest.raises(DataError, match="shorter than the sampling step"):
        ds.resample("5min")
    with pytest.raises(DataError, match="not a whole multiple of the sampling step"):
        ds.resample("25min")
    with pytest.raises(DataError, match="no fixed length"):
        ds.resample("MS")
    with pytest.raises(DataError, match="cannot read resample rule"):
        ds.resample("often")
    with pytest.raises(DataError, match="do not cover one complete"):
        ds.slice(end="2000-01-01 00:30").resample("1h")


def test_resample_empty_interval_is_a_gap() -> None:
    df = frame(n=37)
    df = df.drop(index=range(13, 19)).reset_index(drop=True)  # no data in (02:00, 03:00]
    with pytest.warns(DataWarning, match="gaps"):
        ds = load(df, resample="1h")
    assert len(ds) == 6 and np.isnan(ds["T_zon"][2]) and np.isfinite(ds["T_zon"][[1, 3]]).all()


# -- Dataset --------------------------------------------------------------------------------------


def test_slice_is_inclusive() -> None:
    ds = synthetic()
    part = ds.slice("2000-01-01 01:00", pd.Timestamp("2000-01-01 02:00"))
    assert part.start == pd.Timestamp("2000-01-01 01:00")
    assert part.end == pd.Timestamp("2000-01-01 02:00")
    assert len(part) == 7
    assert len(ds.slice(start="2000-01-01 05:00")) == 7
    assert len(ds.slice(end="2000-01-01 00:10")) == 2


def test_slice_errors() -> None:
    ds = synthetic()
    with pytest.raises(DataError, match="no samples between .* the data span 2000-01-01 00:00:00"):
        ds.slice("2001-01-01")
    with pytest.raises(DataError, match="is after end"):
        ds.slice("2000-01-01 02:00", "2000-01-01 01:00")


def test_split_halves() -> None:
    ds = synthetic(n=40)
    ident, valid = ds.split()
    assert len(ident) == len(valid) == 20
    assert ident.end < valid.start
    np.testing.assert_array_equal(np.concatenate([ident.t, valid.t + 20 * STEP]), ds.t)
    assert [len(part) for part in synthetic(n=37).split()] == [18, 19]
    assert [len(part) for part in ds.split(fraction=0.75)] == [30, 10]


def test_split_at() -> None:
    ds = synthetic()
    ident, valid = ds.split(at="2000-01-01 01:00")
    assert ident.end == pd.Timestamp("2000-01-01 01:00")
    assert valid.start == pd.Timestamp("2000-01-01 01:10")
    assert len(ident) + len(valid) == len(ds)
    with pytest.raises(DataError, match="leaves one part empty"):
        ds.split(at="2000-01-01 06:00")
    with pytest.raises(DataError, match="fraction must be between 0 and 1"):
        ds.split(fraction=1.0)


def test_require_message() -> None:
    ds = synthetic()
    ds.require(["T_zon", "Q_hea"])
    with pytest.raises(
        DataError,
        match=r"no column 'T_amb' required by model 'TiTe'; available: 'T_zon', 'Q_hea'; "
        r"map yours with columns=\{'T_amb': 'your_col'\}",
    ):
        ds.require(["T_zon", "T_amb"], what="model 'TiTe'")
    with pytest.raises(DataError, match="no columns 'T_amb', 'I_s'"):
        ds.require(["T_amb", "I_s"])
    with pytest.raises(DataError, match="did you mean 'T_zon'"):
        ds.require("T_zon1")


def test_the_constant_one_is_a_virtual_column() -> None:
    """Every dataset has the input ``"one"`` (1 at every sample) for constant heat inputs; it
    is not a column of the frame, of the files written, or of the plausibility checks."""
    from jaxbox.data import CONSTANT, check_plausibility, prepare_window

    ds = synthetic()
    assert CONSTANT == "one" and "one" in ds and "one" not in ds.columns
    ds.require(["T_zon", "one"])
    a = ds.array(["Q_hea", "one", "T_zon"])
    assert a.shape == (len(ds), 3) and a.flags.c_contiguous
    np.testing.assert_array_equal(a[:, 1], 1.0)
    np.testing.assert_array_equal(a[:, [0, 2]], ds.array(["Q_hea", "T_zon"]))
    np.testing.assert_array_equal(ds["one"], np.ones(len(ds)))
    assert prepare_window(ds, ["Q_hea", "one"], ["T_zon"]) is ds
    check_plausibility(ds, columns=["T_zon", "one"])


def test_array_is_a_contiguous_copy() -> None:
    ds = synthetic()
    a = ds.array(["Q_hea", "T_zon"])
    assert a.shape == (len(ds), 2) and a.dtype == np.float64 and a.flags.c_contiguous
    np.testing.assert_array_equal(a[:, 0], 10.0 * np.arange(len(ds)))
    a[:] = -1.0
    assert ds.array("Q_hea")[1, 0] == 10.0
    with pytest.raises(DataError, match="no column 'T_amb'"):
        ds.array(["T_amb"])


def test_dataset_is_immutable() -> None:
    ds = synthetic()
    frame_copy = ds.frame
    frame_copy.iloc[:, :] = 0.0
    frame_copy["extra"] = 1.0
    assert ds["Q_hea"][1] == 10.0
    assert "extra" not in ds.columns
    ds["Q_hea"][1] = 0.0
    assert ds["Q_hea"][1] == 10.0
    with pytest.raises(AttributeError):
        ds.step = 1.0  # type: ignore[misc]


def test_pickle_and_copy() -> None:
    import copy
    import pickle

    ds = synthetic()
    for other in (pickle.loads(pickle.dumps(ds)), copy.copy(ds), copy.deepcopy(ds)):
        assert other.equals(ds) and other.step == ds.step


def test_repr_is_short() -> None:
    text = repr(synthetic())
    assert text.startswith("Dataset(37 samples, step 600 s")
    assert "T_zon, Q_hea" in text and "\n" not in text


def test_with_columns() -> None:
    ds = synthetic()
    new = ds.with_columns(T_amb=np.linspace(0.0, 10.0, len(ds)), P_ele=5.0)
    assert new.columns == ("T_zon", "Q_hea", "T_amb", "P_ele")
    assert ds.columns == ("T_zon", "Q_hea")
    np.testing.assert_array_equal(new["P_ele"], 5.0)
    replaced = ds.with_columns({"Q_hea": np.zeros(len(ds))})
    assert replaced.columns == ds.columns and not replaced["Q_hea"].any()
    with pytest.raises(DataError, match="column 'T_amb' has shape"):
        ds.with_columns(T_amb=np.zeros(3))
    with pytest.raises(DataError, match="looks like kelvin"):
        ds.with_columns(T_amb=np.full(len(ds), 290.0))


def test_with_columns_keeps_gaps_as_the_constructor_does() -> None:
    """NaN in a column added with with_columns is a gap, kept as Dataset(frame) keeps it (it
    was refused: 'missing values ... fill them before loading'); what the constructor refuses
    is still refused, naming the column."""
    ds = synthetic()
    gap = ds["T_zon"].copy()
    gap[[3, 4, 10]] = np.nan
    new = ds.with_columns(T_amb=gap)
    assert np.isnan(new["T_amb"][[3, 4, 10]]).all()
    assert np.count_nonzero(np.isnan(new["T_amb"])) == 3
    built = ds.frame
    built["T_amb"] = gap
    assert new.equals(Dataset(built))  # the same dataset, gap and all
    assert np.isnan(ds.with_columns(P_ele=float("nan"))["P_ele"]).all()  # a scalar gap too
    bad = gap.copy()
    bad[5] = np.inf
    with pytest.raises(DataError, match="column 'T_amb' has infinite values"):
        ds.with_columns(T_amb=bad)
    with pytest.raises(DataError, match="column 'T_amb' must hold numbers"):
        ds.with_columns(T_amb=["warm"] * len(ds))
    with pytest.raises(DataError, match="with_columns takes a mapping"):
        ds.with_columns(np.zeros(len(ds)))


def test_from_arrays() -> None:
    ds = Dataset.from_arrays(np.arange(5) * 3600.0, {"T_zon": np.ones(5)}, start="2020-06-01")
    assert ds.start == pd.Timestamp("2020-06-01") and ds.step == 3600.0
    index = pd.date_range("2020-06-01", periods=5, freq="15min")
    assert Dataset.from_arrays(index, {"T_zon": np.ones(5)}).step == 900.0
    with pytest.raises(DataError, match="signal 'T_zon' has shape"):
        Dataset.from_arrays(np.arange(5) * 3600.0, {"T_zon": np.ones(4)})
    with pytest.raises(DataError, match="irregular sampling"):
        Dataset.from_arrays(np.array([0.0, 1.0, 2.0, 3.5]) * 3600.0, {"T_zon": np.ones(4)})
    gappy = Dataset.from_arrays(np.array([0.0, 1.0, 2.0, 4.0]) * 3600.0, {"T_zon": np.ones(4)})
    assert len(gappy) == 5 and np.isnan(gappy["T_zon"][3])  # the missing row is a gap


def test_dataset_from_frame_needs_datetime_index() -> None:
    with pytest.raises(DataError, match="no DatetimeIndex.*time="):
        Dataset(frame())


def test_time_zone_aware_data() -> None:
    df = frame()
    df["time"] = pd.to_datetime(df["time"]).dt.tz_localize("UTC").astype(str)
    ds = load(df)
    assert str(ds.index.tz) == "UTC"
    assert len(ds.slice("2020-01-01 01:00")) == 7


def test_plot_returns_figure() -> None:
    from matplotlib.figure import Figure

    ds = synthetic().with_columns(I_s=1.0, other=2.0)
    figure = ds.plot()
    assert isinstance(figure, Figure)
    assert len(figure.axes) == 4
    assert figure.axes[0].get_ylabel() == "temperature [°C]"
    one = Figure().subplots()
    assert ds.plot(["T_zon"], ax=one) is one.figure


def test_first_values_skip_a_leading_gap_and_follow_new_columns():
    """The first finite value per column (a gap at the start skipped; a column missing or
    without a value left out); a new dataset from ``with_columns`` reads its own columns."""
    t = np.arange(4) * 3600.0
    ds = Dataset.from_arrays(
        t, {"T_zon": [np.nan, 20.5, 21.0, 21.5], "T_amb": [5.0, 6.0, 7.0, 8.0]}, check=False
    )
    assert ds.first_values(["T_zon", "T_amb", "T_bou"]) == {"T_zon": 20.5, "T_amb": 5.0}
    assert ds.first_values("T_zon") == {"T_zon": 20.5}  # read again: the same
    other = ds.with_columns(T_zon=np.array([19.0, 20.0, 21.0, 22.0]))
    assert other.first_values(["T_zon"]) == {"T_zon": 19.0}
    assert ds.first_values(["T_zon"]) == {"T_zon": 20.5}
    empty = ds.with_columns(T_bou=np.full(4, np.nan))
    assert empty.first_values(["T_bou"]) == {}


def test_time_column_by_another_case_or_an_unnamed_index(tmp_path) -> None:
    """'Time' (any case), 'timestamp', 'datetime', or the unnamed first column a DataFrame's
    index leaves in a CSV, read without time=; two candidates or unreadable stamps are not."""
    df = frame()
    assert list(load(df.rename(columns={"time": "Time"})).columns) == list(load(df).columns)
    assert len(load(df.rename(columns={"time": "TIMESTAMP"})).frame) == len(df)
    path = tmp_path / "indexed.csv"
    df.set_index("time").rename_axis(None).to_csv(path)
    assert pd.read_csv(path).columns[0] == "Unnamed: 0"
    pd.testing.assert_frame_equal(load(path).frame, load(df).frame, check_freq=False)
    numbered = tmp_path / "numbered.csv"
    df.to_csv(numbered)  # an integer index: not the time, and 'time' is found
    assert len(load(numbered).frame) == len(df)
    with pytest.raises(DataError, match="no time column found"):
        load(df.rename(columns={"time": "Time"}).assign(TIME=1.0))


def test_columns_in_other_units_are_converted_at_load(tmp_path) -> None:
    """units= converts °F, K, kW, Btu/h and kW/m² before the checks (°F and kelvin columns
    are refused otherwise, naming the option); a unit that does not fit the column, a column
    not there, a unit with a scale or a counter are refused."""
    df = frame().assign(T_amb=5.0, I_glo_hor=np.linspace(0.0, 400.0, 13))
    ref = load(df).frame
    logged = df.assign(
        T_zon=df["T_zon"] * 1.8 + 32,
        T_amb=df["T_amb"] + 273.15,
        Q_hea=df["Q_hea"] / 1000,
        I_glo_hor=df["I_glo_hor"] / 1000,
    )
    units = {"T_zon": "degF", "T_amb": "K", "Q_hea": "kW", "I_glo_hor": "kW/m2"}
    pd.testing.assert_frame_equal(load(logged, units=units).frame, ref, rtol=1e-12)
    btu = load(df.assign(Q_hea=df["Q_hea"] / 0.29307107), units={"Q_hea": "Btu/h"}).frame
    np.testing.assert_allclose(btu["Q_hea"], ref["Q_hea"], rtol=1e-12)
    with pytest.raises(DataError, match=r"looks like kelvin.*units=\{'T_amb': 'K'\}"):
        load(logged.drop(columns=["T_zon"]))
    for bad, words in (
        ({"Q_hea": "degF"}, "is a power .* 'kW'"),
        ({"T_zon": "kelvin"}, "is a temperature .* 'degF'"),
        ({"T_zonx": "K"}, "there is none.*did you mean 'T_zon'"),
    ):
        with pytest.raises(DataError, match=words):
            load(logged, units=bad)
    with pytest.raises(DataError, match="both a unit .* and a scale factor"):
        load(df, units={"Q_hea": "kW"}, scale={"Q_hea": 1000})
    with pytest.raises(DataError, match="both a unit and a counter") as info:
        load(df, units={"Q_hea": "kW"}, counters={"Q_hea": "kWh"})
    from jaxbox.cli._common import cli_message

    assert "(--counter Q_hea=kWh)" in cli_message(str(info.value))


def test_the_command_line_takes_units(tmp_path) -> None:
    from jaxbox.cli._common import cli_message
    from jaxbox.cli._data import DataOptions, load_data
    from jaxbox.cli._main import build_parser

    df = frame()
    path = tmp_path / "f.csv"
    df.assign(T_zon=df["T_zon"] * 1.8 + 32).to_csv(path, index=False)
    args = build_parser().parse_args(["fit", str(path), "--model", "Zon", "--unit", "T_zon=degF"])
    got = load_data(str(path), DataOptions(args)).frame
    np.testing.assert_allclose(got["T_zon"], load(df).frame["T_zon"], rtol=1e-12)
    with pytest.raises(DataError) as info:
        load(df.assign(T_zon=df["T_zon"] + 273.15))
    assert "--unit T_zon=K" in cli_message(str(info.value))
