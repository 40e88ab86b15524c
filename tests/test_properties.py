"""Property-based tests of the loader and the plausibility checks (Hypothesis).

Random small buildings are written as CSV files in many dialects (separators, decimal marks,
time formats and zones) and read back, with or without a fault (a gap, an infinity, a duplicate
time stamp, a unit scaled by 1e-3 or 1e3 or offset by 273.15, a spike anywhere including the
first and last rows, a stuck sensor). The property each time: the data are loaded with the
right values, or refused with one error naming the column (and the row), or the fault is
named in a finding — never a wrong value silently.

Bounded in time and deterministic: few examples, no deadline, derandomised (the same examples
on every run, so CI does not flake).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from jaxbox.data import DataError, check_plausibility, edge_samples, find_implausible, load  # noqa: E402

SETTINGS = settings(
    max_examples=20,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

#: (separator, decimal mark) of the CSV dialects
DIALECTS = [(",", "."), (";", ","), ("\t", "."), (";", ".")]
#: how time stamps are written: (name, formatter of a naive UTC DatetimeIndex, load options)
TIMES = ["iso", "iso-t", "offset", "epoch-s", "epoch-min", "day-first", "dotted"]


@st.composite
def buildings(draw):
    """A plausible building: hourly, 2–4 days, canonical columns in canonical units."""
    n = draw(st.integers(48, 96))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    day = 2 * np.pi * t / 24
    t_amb = draw(st.floats(-15, 15)) + draw(st.floats(1, 6)) * np.sin(day - 1)
    frame = pd.DataFrame(
        {
            "T_zon": 20 + draw(st.floats(0.3, 2)) * np.sin(day) + 0.05 * rng.standard_normal(n),
            "T_amb": t_amb + 0.1 * rng.standard_normal(n),
            "Q_hea": rng.choice([0.0, 800.0, 1500.0], size=n),
            "I_glo_hor": np.maximum(0.0, draw(st.floats(100, 800)) * np.sin(day - np.pi / 2)),
        },
        index=pd.date_range(
            draw(st.sampled_from(["2024-01-01", "2023-03-25"])), periods=n, freq="h", name="time"
        ),
    )
    frame["Q_hea"] += 1.0  # never all zero
    return frame.round(4)


def _write(frame: pd.DataFrame, path, dialect, timefmt) -> dict:
    """Write ``frame`` as a CSV in ``dialect`` with time stamps as ``timefmt``; return the
    options that read it back."""
    sep, decimal = dialect
    out = frame.copy()
    index = out.index
    options: dict = {"sep": sep, "decimal": decimal}
    if timefmt == "iso":
        stamps = index.strftime("%Y-%m-%d %H:%M:%S")
    elif timefmt == "iso-t":
        stamps = index.strftime("%Y-%m-%dT%H:%M")
    elif timefmt == "offset":
        stamps = (index.tz_localize("UTC").tz_convert("Europe/Berlin")).strftime(
            "%Y-%m-%d %H:%M:%S%z"
        )
        options["tz"] = "UTC"
    elif timefmt == "day-first":  # 01/02/2024 13:00 is the 1st of February: from the order
        stamps = index.strftime("%d/%m/%Y %H:%M")
    elif timefmt == "dotted":  # as a German spreadsheet writes it
        stamps = index.strftime("%d.%m.%Y %H:%M")
    elif timefmt == "epoch-s":
        stamps = (index - pd.Timestamp("1970-01-01")) // pd.Timedelta(seconds=1)
    else:  # minutes since an epoch
        stamps = (index - pd.Timestamp("2000-01-01")) // pd.Timedelta(minutes=1)
        options.update(time_unit="min", epoch="2000-01-01")
    out.insert(0, "time", np.asarray(stamps))
    out.to_csv(path, sep=sep, decimal=decimal, index=False)
    return options


def _same_stamps(loaded, frame) -> bool:
    index = loaded.index
    if index.tz is not None:
        index = index.tz_convert("UTC").tz_localize(None)
    return bool(np.all(index.as_unit("ns") == frame.index.as_unit("ns")))


@SETTINGS
@given(frame=buildings(), dialect=st.sampled_from(DIALECTS), timefmt=st.sampled_from(TIMES))
def test_a_clean_file_in_any_dialect_is_read_with_its_values(tmp_path, frame, dialect, timefmt):
    path = tmp_path / "building.csv"
    options = _write(frame, path, dialect, timefmt)
    data = load(path, **options)
    assert _same_stamps(data, frame)
    for name in frame.columns:
        np.testing.assert_allclose(
            data.array(name).ravel(), frame[name].to_numpy(), rtol=0, atol=1e-9
        )
    check_plausibility(data, warn=False)  # a plausible building passes the checks


@SETTINGS
@given(
    frame=buildings(),
    dialect=st.sampled_from([(";", ",", "."), ("\t", ".", ","), (";", ".", "'"), (";", ",", " ")]),
    timefmt=st.sampled_from(TIMES),
)
def test_thousands_separators_are_read_with_their_values(tmp_path, frame, dialect, timefmt):
    """Every number written with a thousands separator (1.501,25 / 1,501.25 / 1'501.25 /
    1 501,25) and read back with ``thousands=``."""
    sep, decimal, thousands = dialect
    frame = frame.assign(Q_hea=frame["Q_hea"] * 3.0)  # powers above 1000 W
    path = tmp_path / "building.csv"
    options = _write(frame, path, (sep, decimal), timefmt)
    table = pd.read_csv(path, sep=sep, dtype=str)
    for name in frame.columns:
        text = [f"{v:,.4f}" for v in frame[name]]  # 1,501.2500
        table[name] = [
            t.replace(",", "\0").replace(".", decimal).replace("\0", thousands) for t in text
        ]
    table.to_csv(path, sep=sep, index=False)
    data = load(path, **options, thousands=thousands)
    assert _same_stamps(data, frame)
    for name in frame.columns:
        np.testing.assert_allclose(
            data.array(name).ravel(), frame[name].to_numpy(), rtol=0, atol=1e-9
        )


@SETTINGS
@given(
    frame=buildings(),
    dialect=st.sampled_from(DIALECTS),
    column=st.sampled_from(["T_zon", "T_amb", "Q_hea", "I_glo_hor"]),
    where=st.floats(0, 1),
    fault=st.sampled_from(["nan", "inf", "duplicate"]),
)
def test_a_gap_is_kept_an_infinity_and_a_duplicate_stamp_refused(
    tmp_path, frame, dialect, column, where, fault
):
    k = int(where * (len(frame) - 1))
    path = tmp_path / "building.csv"
    if fault == "duplicate":
        frame = pd.concat([frame.iloc[: k + 1], frame.iloc[k:]])
    else:
        frame = frame.copy()
        frame.iloc[k, frame.columns.get_loc(column)] = np.nan if fault == "nan" else np.inf
    options = _write(frame, path, dialect, "iso")
    if fault == "nan":
        data = load(path, **options)
        got = data.array(column).ravel()
        assert np.isnan(got[k]) and np.sum(np.isnan(got)) == 1
        np.testing.assert_allclose(np.delete(got, k), np.delete(frame[column].to_numpy(), k))
        return
    with pytest.raises(DataError) as err:
        load(path, **options)
    message = str(err.value)
    assert "\n" not in message
    stamp = str(frame.index[k])[:13]  # the row, to the hour
    if fault == "inf":
        assert column in message and stamp in message, message
    else:
        assert "duplicate" in message and stamp[:10] in message, message


#: faults of the unit of a column: (column, name, change)
UNITS = [
    ("Q_hea", "kW", lambda x: x / 1000),
    ("Q_hea", "mW", lambda x: x * 1000),
    ("I_glo_hor", "kW/m2", lambda x: x / 1000),
    ("I_glo_hor", "x1000", lambda x: x * 1000),
    ("T_zon", "K", lambda x: x + 273.15),
    ("T_amb", "K", lambda x: x + 273.15),
    ("T_zon", "°F", lambda x: 1.8 * x + 32),
]


@SETTINGS
@given(frame=buildings(), unit=st.sampled_from(UNITS), part=st.sampled_from([1.0, 0.5]))
def test_a_unit_that_lies_is_named(frame, unit, part):
    """A column in another unit, in whole or from the middle on, never passes unnamed."""
    column, name, change = unit
    if part < 1 and name == "kW":
        return  # heating in kW from the middle on looks like heating that stops: not judged
    k = int(len(frame) * (1 - part))
    values = frame[column].to_numpy().copy()
    values[k:] = change(values[k:])
    frame = frame.assign(**{column: values})
    try:
        findings = find_implausible(frame)
    except DataError as err:  # pragma: no cover - find_implausible does not raise on data
        pytest.fail(str(err))
    named = [f for f in findings if f.column == column]
    assert named, (unit, part, findings)
    fix = {"kW": "scale", "mW": "scale", "kW/m2": "scale", "x1000": "scale"}.get(unit[1])
    if fix is not None and part == 1.0:
        assert any(fix in f.message for f in named), named


@SETTINGS
@given(
    frame=buildings(),
    column=st.sampled_from(["T_zon", "T_amb"]),
    where=st.one_of(st.just(0.0), st.just(1.0), st.floats(0, 1)),
    size=st.floats(25, 40),
    sign=st.sampled_from([-1, 1]),
)
def test_a_spike_anywhere_even_first_or_last_is_refused_naming_column_and_row(
    frame, column, where, size, sign
):
    k = int(where * (len(frame) - 1))
    values = frame[column].to_numpy().copy()
    values[k] += sign * size
    with pytest.raises(DataError) as err:
        check_plausibility(frame.assign(**{column: values}), warn=False)
    message = str(err.value)
    assert repr(column) in message and str(frame.index[k]) in message, message


@SETTINGS
@given(frame=buildings(), end=st.sampled_from(["first", "last"]), size=st.floats(1.0, 4.0))
def test_a_partial_first_or_last_sample_is_flagged(frame, end, size):
    frame = frame.assign(T_zon=20 + 0.5 * np.sin(2 * np.pi * np.arange(len(frame)) / 24))
    values = frame["T_zon"].to_numpy().copy()
    values[0 if end == "first" else -1] += size
    found = edge_samples(frame.assign(T_zon=values), ["T_zon"])
    assert [f.column for f in found[end]] == ["T_zon"]
    assert edge_samples(frame, ["T_zon"]) == {"first": (), "last": ()}


@SETTINGS
@given(frame=buildings(), start=st.floats(0, 0.4), hours=st.integers(25, 40))
def test_a_stuck_sensor_is_refused(frame, start, hours):
    k = int(start * len(frame))
    values = frame["T_zon"].to_numpy().copy()
    end = min(len(frame), k + hours + 1)
    if end - k - 1 < 24:
        return
    values[k:end] = values[k]
    with pytest.raises(DataError, match="'T_zon' stays exactly"):
        check_plausibility(frame.assign(T_zon=values), warn=False)
