"""Hostile inputs: implausible data never passes.

Each case corrupts a small hourly dataset (the first 10 days of the bundled twin house N2) the way
real monitoring data goes wrong, and asserts the exception type and that the message names the
column and the option (Python keyword or command-line flag) that fixes it.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

import jaxbox
from jaxbox.data import (
    PLAUSIBLE_RANGES,
    DataError,
    Dataset,
    DataWarning,
    as_dataset,
    check_mapping,
    check_plausibility,
    find_implausible,
    load,
    plausible_range,
)
from jaxbox.validate import check_validity

N = 240  # ten days, hourly


@pytest.fixture(scope="module")
def base() -> pd.DataFrame:
    """Hourly measured data: T_zon, T_amb, T_bou, Q_hea, I_glo_hor (DatetimeIndex ``time``)."""
    data = jaxbox.datasets.twinhouse_exp1("N2")
    return data.frame[["T_zon", "T_amb", "T_bou", "Q_hea", "I_glo_hor"]].iloc[:N].copy()


def _half(frame, name, fn):
    """Apply ``fn`` to the second half of column ``name``."""
    x = frame[name].to_numpy(copy=True)
    x[N // 2 :] = fn(x[N // 2 :])
    frame[name] = x


def _at(frame, name, rows, value=None, add=None):
    x = frame[name].to_numpy(copy=True)
    x[rows] = value if add is None else x[rows] + add
    frame[name] = x


def _rename(frame, old, new, factor=1.0):
    frame[new] = frame.pop(old) * factor


# -- the window check: (id, corruption, keywords, words the message must hold) -------------------

WINDOW_CASES = [
    (
        "half zone in K",
        lambda f: _half(f, "T_zon", lambda x: x + 273.15),
        {},
        ["'T_zon'", "kelvin", "273.15"],
    ),
    (
        "half ambient in K",
        lambda f: _half(f, "T_amb", lambda x: x + 273.15),
        {},
        ["'T_amb'", "kelvin", "--train/--validate"],
    ),
    (
        "boundary in K at one sample",
        lambda f: _at(f, "T_bou", [5], add=273.15),
        {},
        ["'T_bou'", "kelvin"],
    ),
    (
        "zone in °F",
        lambda f: f.__setitem__("T_zon", f["T_zon"] * 1.8 + 32),
        {},
        ["'T_zon'", "°F", "--range T_zon=LO:HI"],
    ),
    (
        "half ambient in °F",
        lambda f: _half(f, "T_amb", lambda x: x * 1.8 + 32),
        {},
        ["'T_amb'", "°F", "--map"],
    ),
    (
        "heating in kW",
        lambda f: f.__setitem__("Q_hea", f["Q_hea"] / 1000),
        {},
        ["'Q_hea'", "kW", "scale={'Q_hea': 1000}", "--scale Q_hea=1000"],
    ),
    (
        "heating as a kWh meter",
        lambda f: f.__setitem__("Q_hea", 1234.0 + (f["Q_hea"] * 3600 / 3.6e6).cumsum()),
        {},
        ["'Q_hea'", "energy meter", "counters={'Q_hea': 'kWh'}", "--counter Q_hea=kWh"],
    ),
    (
        "numbered heating in kW",
        lambda f: _rename(f, "Q_hea", "Q_hea1", 1e-3),
        {},
        ["'Q_hea1'", "--scale Q_hea1=1000"],
    ),
    (
        "zone spike",
        lambda f: _at(f, "T_zon", [150], add=15.0),
        {},
        ["'T_zon'", "spike", "--train/--validate"],
    ),
    (
        "ambient spike down",
        lambda f: _at(f, "T_amb", [40], add=-25.0),
        {},
        ["'T_amb'", "spike", "Dataset.slice"],
    ),
    (
        "two-sample zone spike",
        lambda f: _at(f, "T_zon", [150, 151], add=12.0),
        {},
        ["'T_zon'", "spike", "2013-08-27 08:00:00"],
    ),
    (
        "heating spike",
        lambda f: _at(f, "Q_hea", [100], 2e6),
        {},
        ["'Q_hea'", "spike", "--train/--validate"],
    ),
    (
        "stuck zone sensor",
        lambda f: _at(f, "T_zon", slice(50, 80), 21.5),
        {},
        ["'T_zon'", "stuck", "29 h", "stuck_hours="],
    ),
    (
        "stuck ambient sensor",
        lambda f: _at(f, "T_amb", slice(0, 30), 12.0),
        {},
        ["'T_amb'", "stuck"],
    ),
    (
        "hot zone",
        lambda f: _at(f, "T_zon", [10, 11, 12], 70.0),
        {},
        ["'T_zon'", "plausible range", "--map", "--range T_zon=LO:HI", "overrides={'T_zon'"],
    ),
    ("arctic ambient", lambda f: _at(f, "T_amb", [3], -80.0), {}, ["'T_amb'", "-60", "--map"]),
    (
        "irradiance in mW/m²",
        lambda f: f.__setitem__("I_glo_hor", f["I_glo_hor"] * 1000),
        {},
        ["'I_glo_hor'", "--scale"],
    ),
    (
        "heating in mW",
        lambda f: f.__setitem__("Q_hea", f["Q_hea"] * 1e4),
        {},
        ["'Q_hea'", "--scale"],
    ),
    (
        "jump of a sensor",
        lambda f: _half(f, "T_bou", lambda x: x + 25.0),
        {},
        # the boundary where the change was made: sample N // 2 (one-sided medians located
        # it five samples early before)
        ["'T_bou'", "jumps by +2", "and 2013-08-26 01:00:00"],
    ),
    (
        "narrow override",
        lambda f: None,
        {"overrides": {"T_zon": (0.0, 20.0)}},
        ["'T_zon'", "0 … 20"],
    ),
    (
        "override by base name",
        lambda f: _rename(f, "T_zon", "T_zon2"),
        {"overrides": {"T_zon": (0.0, 20.0)}},
        ["'T_zon2'", "0 … 20"],
    ),
    (
        "several problems",
        lambda f: (_at(f, "T_zon", [150], add=15.0), _at(f, "T_amb", [3], -80.0)),
        {},
        ["'T_zon'", "1 more problem(s) in 'T_amb'"],
    ),
    (
        "named window",
        lambda f: _at(f, "T_zon", [150], add=15.0),
        {"what": "validation data"},
        ["validation data: 'T_zon'"],
    ),
]


@pytest.mark.parametrize(
    ("corrupt", "keywords", "words"),
    [case[1:] for case in WINDOW_CASES],
    ids=[case[0] for case in WINDOW_CASES],
)
def test_window_check_refuses(base, corrupt, keywords, words):
    frame = base.copy()
    corrupt(frame)
    data = Dataset(frame, check=False)
    with pytest.raises(DataError) as info:
        check_plausibility(data, **keywords)
    message = str(info.value)
    for word in words:
        assert word in message, message
    assert len(message) < 500 and "\n" not in message


# -- at load: (id, frame corruption or CSV text, keywords, exception, words) ---------------------


def _csv(rows: int = 6, sep: str = ",", decimal: str = ".", header: str | None = None) -> str:
    names = header or sep.join(["time", "T_zon", "T_amb", "Q_hea"])
    lines = [names]
    for h in range(rows):
        values = [f"{20 + h / 10:.1f}", f"{5 - h / 10:.1f}", "500.5"]
        lines.append(
            sep.join([f"2020-01-01 {h:02d}:00", *(v.replace(".", decimal) for v in values)])
        )
    return "\n".join(lines) + "\n"


LOAD_CASES = [
    (
        "inf in a temperature",
        lambda f: _at(f, "T_zon", [7], np.inf),
        {},
        DataError,
        ["'T_zon'", "infinite", "2013-08-21 08:00:00"],
    ),
    (
        "-inf in an irradiance",
        lambda f: _at(f, "I_glo_hor", [3, 4, 5, 6], -np.inf),
        {},
        DataError,
        ["'I_glo_hor'", "infinite", "4 samples in all"],
    ),
    (
        "1e300 in the heating",
        lambda f: _at(f, "Q_hea", [9], 1e300),
        {},
        DataError,
        ["'Q_hea'", "absurd", "1e+300", "--scale"],
    ),
    (
        "1e300 in another column",
        lambda f: f.__setitem__("note", np.where(np.arange(N) == 2, 1e300, 1.0)),
        {},
        DataError,
        ["'note'", "absurd"],
    ),
    ("1e12 W", lambda f: _at(f, "Q_hea", [9], -1e12), {}, DataError, ["'Q_hea'", "absurd"]),
    (
        "scale of an unknown column",
        lambda f: None,
        {"scale": {"Q": 1000}},
        DataError,
        ["scale", "'Q'", "'Q_hea'"],
    ),
    (
        "scale factor zero",
        lambda f: None,
        {"scale": {"Q_hea": 0}},
        DataError,
        ["'Q_hea'", "--scale Q_hea=1000"],
    ),
    (
        "scale as a list",
        lambda f: None,
        {"scale": [("Q_hea", 1000)]},
        TypeError,
        ["scale must be a mapping", "list"],
    ),
    ("columns as a string", lambda f: None, {"columns": "T_zon=living"}, DataError, ["columns"]),
]


@pytest.mark.parametrize(
    ("corrupt", "keywords", "error", "words"),
    [case[1:] for case in LOAD_CASES],
    ids=[case[0] for case in LOAD_CASES],
)
def test_load_refuses(base, corrupt, keywords, error, words):
    frame = base.copy()
    corrupt(frame)
    with pytest.raises(error) as info:
        load(frame, **keywords)
    for word in words:
        assert word in str(info.value), str(info.value)


CSV_CASES = [
    (
        "duplicate column",
        _csv(header="time,T_zon,T_zon,Q_hea"),
        {},
        ["two columns are named 'T_zon'"],
    ),
    ("semicolons", _csv(sep=";"), {}, ["semicolons", "sep=';'", "--sep ';'"]),
    (
        "semicolons and decimal commas",
        _csv(sep=";", decimal=","),
        {},
        ["sep=';', decimal=','", "--sep ';' --decimal ','"],
    ),
    (
        "decimal commas with sep given",
        _csv(sep=";", decimal=","),
        {"sep": ";"},
        ["decimal=','", "--decimal ','"],
    ),
    (
        "decimal commas between commas",
        _csv(decimal=","),
        {},
        ["decimal commas", "--sep ';' --decimal ','"],
    ),
    ("tabs", _csv(sep="\t"), {}, ["tabs", "--sep"]),
    (
        "trailing commas",
        "time,T_zon\n2020-01-01 00:00,20.5,\n2020-01-01 01:00,20.6,\n",
        {},
        ["line 2", "trailing commas"],
    ),
    ("same separator and decimal mark", _csv(), {"decimal": ","}, ["--sep ';' --decimal ','"]),
    (
        "a quoted decimal comma",
        'time,T_zon\n2020-01-01 00:00,"20,5"\n2020-01-01 01:00,"20,6"\n',
        {},
        ["'T_zon'", "'20,5'", "--decimal ','"],
    ),
]


@pytest.mark.parametrize(
    ("text", "keywords", "words"),
    [case[1:] for case in CSV_CASES],
    ids=[case[0] for case in CSV_CASES],
)
def test_csv_refused_with_the_option_that_reads_it(tmp_path, text, keywords, words):
    path = tmp_path / "data.csv"
    path.write_text(text)
    with pytest.raises(DataError) as info:
        load(path, **keywords)
    message = str(info.value)
    for word in words:
        assert word in message, message
    assert "no time column" not in message


def test_a_frame_read_with_the_wrong_separator(tmp_path):
    path = tmp_path / "data.csv"
    path.write_text(_csv(sep=";"))
    with pytest.raises(DataError, match=r"one column 'time;T_zon;T_amb;Q_hea'.*--sep ';'"):
        load(pd.read_csv(path))


@pytest.mark.parametrize(
    ("sep", "decimal"), [(";", ","), (";", "."), ("\t", "."), ("\t", ","), (",", ".")]
)
def test_csv_read_with_sep_and_decimal(tmp_path, sep, decimal):
    path = tmp_path / "data.csv"
    path.write_text(_csv(sep=sep, decimal=decimal))
    data = load(path, sep=sep, decimal=decimal, scale={"Q_hea": 2})
    np.testing.assert_allclose(data["T_zon"], 20 + np.arange(6) / 10)
    np.testing.assert_allclose(data["Q_hea"], 1001.0)


# -- what the Python API takes as data ------------------------------------------------------------

NOT_DATA = [
    ("ndarray", np.zeros((10, 3)), ["numpy.ndarray", "Dataset.from_arrays"]),
    ("None", None, ["got None"]),
    ("list", [1.0, 2.0], ["got a list"]),
    ("dict", {"T_zon": [1.0, 2.0]}, ["got a dict", "from_arrays"]),
    ("number", 3.0, ["got a float"]),
    ("Series", pd.Series([1.0, 2.0]), ["pandas"]),
]


@pytest.mark.parametrize(
    ("obj", "words"), [case[1:] for case in NOT_DATA], ids=[case[0] for case in NOT_DATA]
)
def test_as_dataset_refuses_what_is_not_data(obj, words):
    with pytest.raises(TypeError) as info:
        as_dataset(obj, what="valid")
    message = str(info.value)
    assert message.startswith("valid must be a jaxbox Dataset, a pandas DataFrame")
    assert "path of a CSV file" in message
    for word in words:
        assert word in message, message


def test_as_dataset_takes_datasets_frames_and_paths(base, tmp_path):
    data = Dataset(base)
    assert as_dataset(data) is data
    assert as_dataset(base).equals(data)
    assert as_dataset(base.reset_index()).equals(data)
    path = tmp_path / "data.csv"
    base.to_csv(path)
    assert np.allclose(as_dataset(path).array(data.columns), data.array(data.columns))
    assert len(as_dataset(str(path), resample="2h")) == N // 2
    scaled = as_dataset(data, scale={"Q_hea": 1e-3})
    np.testing.assert_allclose(scaled["Q_hea"], data["Q_hea"] / 1000)


@pytest.mark.parametrize(
    ("value", "words"),
    [
        ([("R_wal", (0, 1))], ["bounds must be a mapping", "a list of 1 item(s)"]),
        ("R_wal=0:1", ["the string 'R_wal=0:1'"]),
        (3, ["a int"]),
    ],
)
def test_check_mapping_refuses_other_types(value, words):
    with pytest.raises(TypeError) as info:
        check_mapping(value, "bounds", "{'R_wal': (0.001, 1)}")
    for word in words:
        assert word in str(info.value)
    assert "bounds={'R_wal': (0.001, 1)}" in str(info.value)


def test_check_mapping_accepts_mappings():
    assert check_mapping(None, "x") == {}
    given = {"a": 1}
    out = check_mapping(given, "x")
    assert out == given and out is not given


def test_overrides_must_be_a_mapping_of_pairs(base):
    data = Dataset(base)
    with pytest.raises(TypeError, match="overrides must be a mapping"):
        check_plausibility(data, overrides=[("T_zon", (0, 1))])
    with pytest.raises(DataError, match=r"overrides\['T_zon'\] must be a pair"):
        check_plausibility(data, overrides={"T_zon": (5, 1)})
    with pytest.raises(DataError, match="overrides names 'living'"):
        check_plausibility(data, overrides={"living": (5, 10)})


# -- what passes ----------------------------------------------------------------------------------


def test_measured_data_pass_in_every_window():
    for house in ("N2", "O5"):
        for resolution in ("1h", "10min"):
            data = jaxbox.datasets.twinhouse_exp1(house, resolution)
            for window in (data, *data.split()):
                assert check_plausibility(window) == ()
                assert window.check_plausible() == ()


@pytest.mark.parametrize(
    ("corrupt", "keywords"),
    [
        (lambda f: f.__setitem__("T_zon", f["T_zon"] + 30), {"overrides": {"T_zon": (0, 100)}}),
        (lambda f: f.__setitem__("T_amb", f["T_amb"] - 75), {"overrides": {"T_amb": (-90, 60)}}),
        (lambda f: _at(f, "T_zon", slice(50, 80), 21.5), {"stuck_hours": None}),
        (lambda f: _at(f, "T_zon", slice(50, 80), 21.5), {"stuck_hours": 48}),
        (lambda f: _at(f, "T_zon", [150], add=15.0), {"spike_k": 10.0, "columns": ["T_amb"]}),
        (lambda f: f.__setitem__("Q_hea", f["Q_hea"] / 1000), {"overrides": {"Q_hea": (0, 10)}}),
    ],
    ids=["sauna", "siberia", "no stuck check", "stuck shorter", "other columns", "tiny heater"],
)
def test_overrides_and_options_let_data_pass(base, corrupt, keywords):
    frame = base.copy()
    corrupt(frame)
    assert check_plausibility(Dataset(frame, check=False), **keywords) == ()


def test_scale_at_load_repairs_kilowatts(base):
    frame = base.copy()
    frame["Q_hea"] = frame["Q_hea"] / 1000
    with pytest.raises(DataError, match="--scale Q_hea=1000"):
        load(frame).check_plausible()
    assert load(frame, scale={"Q_hea": 1000}).check_plausible() == ()


def test_a_greybox_keeps_its_stuck_sensor_tolerance(base, tmp_path):
    """A coarse sensor that is right may stay put for days: ``stuck_hours`` lets a GreyBox take
    it, and a saved GreyBox is read back with the same tolerance (not refused on reload)."""
    frame = base.copy()
    _at(frame, "T_bou", slice(50, 110), 21.5)  # 60 h without a change
    with pytest.raises(DataError, match=r"'T_bou' stays exactly.*stuck_hours="):
        jaxbox.GreyBox(Dataset(frame))
    for hours in (None, 72):
        gb = jaxbox.GreyBox(Dataset(frame), stuck_hours=hours)
        assert gb.stuck_hours == hours
        gb.save(tmp_path / f"gb{hours}")
        assert jaxbox.GreyBox.load(tmp_path / f"gb{hours}").stuck_hours == hours
    for bad, error in ((0, DataError), (-3.0, DataError), ("24", TypeError), (True, TypeError)):
        with pytest.raises(error, match="stuck_hours"):
            jaxbox.GreyBox(Dataset(frame), stuck_hours=bad)


def _stuck_reasons(verdict) -> list[str]:
    return [r for r in (*verdict.reasons, *verdict.warnings) if "stays exactly" in r]


def test_the_verdict_takes_the_greybox_stuck_sensor_tolerance(base, tmp_path):
    """Data a GreyBox took with its ``stuck_hours`` are not refused again by the verdict of its
    cases (the data check of :func:`~jaxbox.validate.check_validity`), nor when it is read back;
    ``check_validity`` alone keeps the default and takes the option."""
    frame = base.copy()
    _at(frame, "T_bou", slice(20, 80), 21.5)  # 60 h without a change, in the first half
    gb = jaxbox.GreyBox(Dataset(frame), stuck_hours=None)
    case = gb.identify("Zon+Bou", starts=2)
    assert case.data_checks["stuck_hours"] is None
    assert _stuck_reasons(case.verdict) == []
    assert _stuck_reasons(check_validity(case.result, validation=case.validation))  # default 24
    assert _stuck_reasons(check_validity(case.result, stuck_hours=72)) == []
    with pytest.raises(ValueError, match="stuck_hours"):
        check_validity(case.result, stuck_hours=0)
    gb.save(tmp_path / "gb")
    back = jaxbox.GreyBox.load(tmp_path / "gb")
    assert _stuck_reasons(back.cases[case.name].verdict) == []


@pytest.mark.filterwarnings("ignore::jaxbox.data.DataWarning")  # the gaps made on purpose
def test_counters_at_load_give_the_power_of_each_interval(base):
    """A kWh meter (with a reset and a missing reading) becomes the mean power of each hour:
    the power itself where both readings exist, a gap at the reset and the two intervals around
    the missing reading; the first row (the starting readings) is dropped. A steady or stepped
    heating is no counter."""
    frame = base.copy()
    power = frame["Q_hea"].to_numpy()
    energy = 500.0 + np.cumsum(power * 3600.0 / 3.6e6)  # kWh at the end of each hour
    energy[100:] -= energy[99]  # the meter replaced after sample 99: starts again at 0
    energy[150] = np.nan
    frame["Q_hea"] = energy
    with pytest.raises(DataError, match="energy meter"):
        load(frame).check_plausible()
    got = load(frame, counters={"Q_hea": "kWh"})
    q = got["Q_hea"]
    assert len(got) == N - 1 and got.index[0] == frame.index[1]
    gaps = np.flatnonzero(np.isnan(q)) + 1  # rows of the frame
    assert gaps.tolist() == [100, 150, 151]
    ok = np.isfinite(q)
    np.testing.assert_allclose(q[ok], power[1:][ok], rtol=1e-9, atol=1e-6)
    assert got.check_plausible() == ()
    # in joules the readings pass 1e9 (absurd for a power): turned into power before that check,
    # and without counters= the absurd values are named as a likely meter, unlike an error code
    with pytest.raises(DataError, match=r"absurd.*energy meter.*counters=\{'Q_hea': 'J'\}"):
        load(frame.assign(Q_hea=frame["Q_hea"] * 3.6e6))
    with pytest.raises(DataError, match=r"absurd.*error code of the logger") as info:
        load(base.assign(Q_hea=np.where(np.arange(N) == 7, 9.9e9, base["Q_hea"])))
    assert "meter" not in str(info.value)
    in_joules = load(frame.assign(Q_hea=frame["Q_hea"] * 3.6e6), counters={"Q_hea": "J"})
    np.testing.assert_allclose(in_joules["Q_hea"][ok], power[1:][ok], rtol=1e-9, atol=1e-6)
    # a row missing from the grid: the interval over it is a gap too
    holed = load(frame.drop(index=frame.index[60]), counters={"Q_hea": "kWh"})
    assert np.isnan(holed["Q_hea"][[59, 60]]).all() and np.isfinite(holed["Q_hea"][61])
    with pytest.raises(DataError, match="unknown energy unit 'kWx'.*kWh"):
        load(frame, counters={"Q_hea": "kWx"})
    with pytest.raises(DataError, match="counters names column 'Q_he'"):
        load(frame, counters={"Q_he": "kWh"})
    for steady in (np.full(N, 800.0), np.where(np.arange(N) < N // 2, 0.0, 1500.0)):
        assert check_plausibility(Dataset(base.assign(Q_hea=steady))) == ()


def test_heating_of_the_wrong_sign_is_a_warning(base):
    """Heating logged as negative (or a cooling power): a warning naming the flip, which
    scale=-1 applies at load; a cooled zone is not refused."""
    frame = base.assign(Q_hea=-base["Q_hea"])
    with pytest.warns(DataWarning, match=r"'Q_hea' is negative at 100 %.*warmer than outside"):
        notes = check_plausibility(Dataset(frame))
    assert len(notes) == 1 and "--scale Q_hea=-1" in notes[0]
    kinds = [(f.column, f.kind, f.severe) for f in find_implausible(Dataset(frame))]
    assert kinds == [("Q_hea", "sign", False)]
    assert load(frame, scale={"Q_hea": -1}).check_plausible() == ()
    assert check_plausibility(Dataset(base)) == ()  # the right sign: nothing to say


def test_uncertain_kilowatts_are_a_warning(base):
    """A small heater where zone and ambient are close: may be right, so only a warning."""
    frame = base.copy()
    frame["Q_hea"] = frame["Q_hea"] / 1000
    frame["T_amb"] = frame["T_zon"] - 1.0
    with pytest.warns(
        DataWarning, match=r"'Q_hea' peaks at only .* W: in kW\?.*--scale Q_hea=1000"
    ):
        notes = check_plausibility(Dataset(frame))
    assert len(notes) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert check_plausibility(Dataset(frame), warn=False) == notes
    kinds = [(f.column, f.kind, f.severe) for f in find_implausible(Dataset(frame))]
    assert kinds == [("Q_hea", "kilowatt", False)]


def test_ranges_and_overrides():
    assert plausible_range("T_zon3") == PLAUSIBLE_RANGES["T_zon"]
    assert plausible_range("T_zon3", {"T_zon": (0, 1)}) == (0, 1)
    assert plausible_range("T_zon3", {"T_zon3": (2, 3), "T_zon": (0, 1)}) == (2, 3)
    assert plausible_range("living_T") is None
    assert plausible_range("living_T", {"living_T": (0, 1)}) == (0, 1)


def test_window_check_takes_only_datasets():
    with pytest.raises(TypeError, match="takes a jaxbox Dataset"):
        check_plausibility(np.zeros((3, 2)))


def test_every_way_into_a_dataset_refuses_infinities(base):
    data = Dataset(base)
    bad = data["T_zon"]
    bad[3] = np.inf
    with pytest.raises(DataError, match="column 'T_zon' has infinite values"):
        data.with_columns(T_zon=bad)
    with pytest.raises(DataError, match="column 'T_amb' has absurd values"):
        Dataset.from_arrays(data.t, {"T_amb": np.full(N, 1e300)}, check=False)
    frame = base.copy()
    frame.iloc[5, 0] = -np.inf
    with pytest.raises(DataError, match="'T_zon' has infinite"):
        Dataset(frame, check=False)


def test_a_large_building_in_kilowatts_is_refused(base):
    """An office logged in kW peaks above 50 "W" (its boiler at 158 kW) but averages under
    5 W per K of zone-ambient difference: refused as kW, and the declared range keeps it."""
    frame = base.copy()
    frame["T_amb"] = frame["T_zon"] - 12.0
    on = np.arange(len(frame)) % 24 < 12
    frame["Q_hea"] = np.where(on, 40.0, 0.0)
    frame.iloc[5, frame.columns.get_loc("Q_hea")] = 158.0
    kinds = [(f.column, f.kind, f.severe) for f in find_implausible(Dataset(frame))]
    assert kinds == [("Q_hea", "kilowatt", True)]
    with pytest.raises(DataError, match=r"'Q_hea' looks like kW.*--scale Q_hea=1000"):
        check_plausibility(Dataset(frame))
    assert load(frame, scale={"Q_hea": 1000}).check_plausible() == ()
    assert find_implausible(Dataset(frame), overrides={"Q_hea": (0, 200)}) == ()
    # a heater of the same size serving a zone that loses 10 W/K is kept
    frame["Q_hea"] = frame["Q_hea"] * 6
    assert not [f for f in find_implausible(Dataset(frame)) if f.kind == "kilowatt"]
