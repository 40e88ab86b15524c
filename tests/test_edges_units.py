"""Data at its edges and units that lie: the jump check tells a change of unit from weather,
spikes and jumps of the first and last samples are seen (one-sided), every refusal of the
plausibility checks can be allowed by name."""

from __future__ import annotations

import json
import os
import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jaxbox.data import ALLOWABLE, DataError, allowing, check_plausibility, find_implausible

N = 96  # hourly samples, four days


def frame(n: int = N, **columns) -> pd.DataFrame:
    """A plausible building, hourly, with ``columns`` replaced."""
    t = np.arange(n)
    day = 2 * np.pi * t / 24
    f = pd.DataFrame(
        {
            "T_zon": 20 + 1.5 * np.sin(day) + 0.01 * t,
            "T_amb": 5 + 4 * np.sin(day - 1),
            "Q_hea": 500.0 + 300 * (t % 5 > 2),
            "I_glo_hor": np.maximum(0.0, 300 * np.sin(day)),
        },
        index=pd.date_range("2024-01-01 01:00", periods=n, freq="h"),
    )
    for name, values in columns.items():
        f[name] = values
    return f


def _front(n: int = N, at: int = 50, drop: float = 22.0) -> np.ndarray:
    """An outdoor temperature that falls by ``drop`` K over ten hours from sample ``at``."""
    t = np.arange(n)
    ramp = np.clip((t - at) / 10.0, 0.0, 1.0)
    return 1.0 + np.sin(2 * np.pi * t / 24) - drop * ramp


def test_a_cold_front_is_weather_a_warning_not_a_refusal():
    notes = check_plausibility(frame(T_amb=_front()), warn=False)
    assert any("'T_amb' changes by" in n and "weather" in n for n in notes), notes


@pytest.mark.parametrize(
    "convert, kind",
    [(lambda x: 1.8 * x + 32, "°F"), (lambda x: x + 273.15, "kelvin")],
    ids=["fahrenheit", "kelvin"],
)
def test_a_change_of_unit_mid_column_is_refused_naming_it(convert, kind):
    t_amb = 5 + 4 * np.sin(2 * np.pi * np.arange(N) / 24 - 1)
    t_amb[60:] = convert(t_amb[60:])
    with pytest.raises(DataError, match="T_amb") as err:
        check_plausibility(frame(T_amb=t_amb), warn=False)
    assert kind in str(err.value)


def test_a_plausible_jump_of_the_zone_is_refused_and_can_be_allowed():
    t_zon = frame()["T_zon"].to_numpy().copy()
    t_zon[50:] -= 25.0  # still within -30 … 60 °C: a sensor moved outdoors?
    data = frame(T_zon=t_zon)
    with pytest.raises(DataError, match="'T_zon' jumps by") as err:
        check_plausibility(data, warn=False)
    assert "allow={'T_zon': 'jump'}" in str(err.value)
    for allow in ("jump", "T_zon=jump", ["T_zon=jump"], {"T_zon": "jump"}, {"T_zon": ["jump"]}):
        notes = check_plausibility(data, warn=False, allow=allow)
        assert any(n.startswith("allowed: 'T_zon' jumps") for n in notes), (allow, notes)
    with allowing("T_zon=jump"):
        assert check_plausibility(data, warn=False)
    with pytest.raises(DataError):  # the block is over
        check_plausibility(data, warn=False)
    with pytest.raises(DataError):  # another column's allowance does not apply
        check_plausibility(data, warn=False, allow="T_amb=jump")


@pytest.mark.parametrize("bad", ["wobble", "T_zon=wobble", ["jump", "infinite"]])
def test_allow_refuses_what_it_cannot_allow_naming_the_checks(bad):
    with pytest.raises(DataError, match="kelvin, fahrenheit, range, jump"):
        check_plausibility(frame(), allow=bad)


def test_allow_refuses_what_is_not_a_kind():
    with pytest.raises(TypeError, match="allow"):
        check_plausibility(frame(), allow=3)


def test_every_allowable_refusal_becomes_a_warning():
    """One column per kind of refusal; each allowed by name gives a warning instead."""
    t = frame()
    hot = t["T_zon"].to_numpy().copy()
    hot[40] += 30.0
    cases = {
        "spike": frame(T_zon=hot),
        "range": frame(T_amb=t["T_amb"] - 70.0),
        "kelvin": frame(T_amb=t["T_amb"] + 273.15),
        "stuck": frame(T_amb=np.r_[np.full(N - 2, 3.0), 3.5, 4.0]),
        "counter": frame(Q_hea=np.cumsum(np.full(N, 0.5))),
        "kilowatt": frame(Q_hea=t["Q_hea"] / 1000.0),
    }
    for kind, data in cases.items():
        found = [f for f in find_implausible(data) if f.severe]
        assert [f.kind for f in found] == [kind], (kind, found)
        assert kind in ALLOWABLE
        allowed = find_implausible(data, allow=kind)
        assert not any(f.severe for f in allowed), (kind, allowed)
        assert any(f.message.startswith("allowed: ") for f in allowed), kind


@pytest.mark.parametrize("where", [0, -1], ids=["first", "last"])
def test_a_jump_of_the_first_or_last_samples_is_seen(where):
    t_zon = frame()["T_zon"].to_numpy().copy()
    if where == 0:
        t_zon[:2] += 24.0
    else:
        t_zon[-2:] += 24.0
    with pytest.raises(DataError, match="first 2|last 2"):
        check_plausibility(frame(T_zon=t_zon), warn=False)


def test_the_python_warning_of_a_front_names_the_column():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_plausibility(frame(T_amb=_front()))
    assert any("'T_amb' changes by" in str(w.message) for w in caught)


def _cooling(n: int = 144, last: float = 0.0, first: float = 0.0) -> pd.DataFrame:
    """Three days every 30 minutes of a zone cooling down without heating under a falling
    outdoor temperature; the first and last zone samples moved by ``first`` and ``last`` K."""
    t = np.arange(n) / 2.0  # hours
    t_amb = 6 - 0.05 * t + 2 * np.sin(2 * np.pi * t / 24)
    rng = np.random.default_rng(3)
    t_zon = 8 + 12 * np.exp(-t / 40) + 0.01 * rng.standard_normal(n)
    t_zon[-1] += last
    t_zon[0] += first
    return pd.DataFrame(
        {
            "T_zon": t_zon,
            "T_amb": t_amb,
            "Q_hea": np.zeros(n),
            "I_glo_hor": np.maximum(0.0, 200 * np.sin(2 * np.pi * (t - 6) / 24)),
        },
        index=pd.date_range("2024-01-01 00:30", periods=n, freq="30min", name="time"),
    )


@pytest.mark.parametrize("end", ["first", "last"])
def test_a_partial_edge_interval_is_flagged_and_trimmed(end):
    from jaxbox.data import Dataset, edge_samples, trim_edges

    data = Dataset(_cooling(**{end: 0.84}))
    found = edge_samples(data)
    assert [f.column for f in found[end]] == ["T_zon"]
    other = "last" if end == "first" else "first"
    assert found[other] == ()
    import re

    offset = float(re.search(r"is ([+-][\d.]+) K off the trend", found[end][0].message)[1])
    assert offset == pytest.approx(0.84, abs=0.1)  # the noise and the curvature aside
    trimmed, notes = trim_edges(data)
    assert len(trimmed) == len(data) - 1 and len(notes) == 1 and end in notes[0]
    assert (trimmed.start, trimmed.end) == (
        (data.index[1], data.end) if end == "first" else (data.start, data.index[-2])
    )
    kept, none = trim_edges(data, "none")
    assert kept is data and none == ()


def test_clean_edges_are_kept_and_trim_can_drop_them_anyway():
    from jaxbox.data import Dataset, edge_samples, trim_edges

    data = Dataset(_cooling())
    assert edge_samples(data) == {"first": (), "last": ()}
    assert trim_edges(data)[0] is data
    both, notes = trim_edges(data, "both")
    assert len(both) == len(data) - 2 and notes == ()
    with pytest.raises(DataError, match="trim must be one of auto, none"):
        trim_edges(data, "middle")


@pytest.mark.slow
def test_fit_drops_a_partial_last_sample_with_a_warning(tmp_path, capsys):
    import json

    from jaxbox.cli._main import main

    path = tmp_path / "cooling.csv"
    _cooling(last=0.84).to_csv(path)
    argv = ["fit", str(path), "--model", "Zon", "--starts", "1", "--max-steps", "2", "--json"]
    assert main(argv) == 0
    out = capsys.readouterr()
    assert any(
        line.startswith("warning: dropped the last sample") and "'T_zon'" in line
        for line in out.err.splitlines()
    ), out.err
    data = json.loads(out.out)["data"]
    assert data["n_train"] + data["n_validate"] == 143
    assert main([*argv, "--trim", "none"]) == 0
    out = capsys.readouterr()
    assert "dropped" not in out.err
    data = json.loads(out.out)["data"]
    assert data["n_train"] + data["n_validate"] == 144
    assert main([*argv, "--trim", "middle"]) == 2
    assert "--trim 'middle'" in capsys.readouterr().err


def _findings(data, column):
    return [f for f in find_implausible(data) if f.column == column]


@pytest.mark.parametrize(
    "column, factor, severe, fix, unit",
    [
        ("I_glo_hor", 1e-3, False, "--scale I_glo_hor=1000", "kW/m2"),  # kW/m²
        ("I_glo_hor", 1e3, True, "--scale I_glo_hor=0.001", None),  # W/m² logged ×1000
        ("Q_hea", 1e-3, True, "--scale Q_hea=1000)", "kW"),  # kW
        ("Q_hea", 1e-6, True, "--scale Q_hea=1000000", "MW"),  # MW
        ("Q_hea", 1e3, False, "--scale Q_hea=0.001", None),  # mW
    ],
    ids=["irradiance-kW", "irradiance-x1000", "heating-kW", "heating-MW", "heating-mW"],
)
def test_a_power_or_irradiance_in_another_unit_names_the_scale_that_fixes_it(
    column, factor, severe, fix, unit
):
    from jaxbox.cli._common import cli_message
    from jaxbox.data import load

    data = frame()
    data[column] = data[column] * factor
    found = _findings(data, column)
    assert len(found) == 1 and found[0].severe == severe, found
    assert fix in found[0].message, found[0].message
    if unit is not None:  # the unit named as well, in each interface's terms, and it fixes it
        assert f"units={{'{column}': '{unit}'}}" in found[0].message, found[0].message
        assert f"pass --unit {column}={unit} or --scale" in cli_message(found[0].message)
        fixed = load(data, units={column: unit})
        assert not [f for f in fixed.check_plausible() if f.column == column]


def test_an_outdoor_temperature_in_fahrenheit_in_winter_is_named():
    """20–45 °F lies within the plausible range of °C: only its warmth against the heated zone
    gives it away."""
    data = frame()
    data["T_amb"] = 1.8 * data["T_amb"] + 32
    found = _findings(data, "T_amb")
    assert [(f.kind, f.severe) for f in found] == [("fahrenheit", False)]
    assert "°F" in found[0].message and "--range T_amb=LO:HI" in found[0].message
    assert _findings(frame(), "T_amb") == []


def test_a_swapped_zone_and_outdoor_column_is_named_where_the_heating_runs():
    """An office whose heating runs a third of the hours, its zone and outdoor columns
    swapped: judged on the hours with the heating on, the warning names both readings."""
    data = frame()
    data["T_zon"], data["T_amb"] = data["T_amb"].to_numpy(), data["T_zon"].to_numpy()
    data["Q_hea"] = np.where(np.arange(len(data)) % 3 == 0, data["Q_hea"].abs() + 100.0, 0.0)
    found = _findings(data, "T_amb")
    assert [(f.kind, f.severe) for f in found] == [("fahrenheit", False)]
    assert "swapped" in found[0].message and "°F" in found[0].message


@pytest.mark.parametrize(
    "convert, kind",
    [(lambda x: x + 273.15, "kelvin"), (lambda x: 1.8 * x + 32, "fahrenheit")],
    ids=["kelvin", "fahrenheit"],
)
def test_a_zone_temperature_in_another_unit_is_refused(convert, kind):
    data = frame()
    data["T_zon"] = convert(data["T_zon"])
    assert [(f.kind, f.severe) for f in _findings(data, "T_zon")] == [(kind, True)]


def test_a_meter_given_as_power_names_counter():
    data = frame(Q_hea=1000 + np.cumsum(np.full(N, 0.4)))
    (found,) = _findings(data, "Q_hea")
    assert found.kind == "counter" and "--counter Q_hea=kWh" in found.message


def test_the_meter_of_a_heating_that_runs_a_fifth_of_the_time_is_a_counter():
    """An office's heat meter rises only while the heating runs (here 5 of 24 hours); held
    still the rest of the time it still never falls. A power that rises less often than
    :data:`COUNTER_RISING` of its steps, or fewer than :data:`COUNTER_RISES` times, is not
    taken for one."""
    from jaxbox.data._counters import COUNTER_RISES, COUNTER_RISING, rising_share

    on = (np.arange(N) % 24 >= 7) & (np.arange(N) % 24 < 12)
    meter = 120.0 + np.cumsum(np.where(on, 3.2, 0.0))  # kWh
    (found,) = _findings(frame(Q_hea=meter), "Q_hea")
    assert found.kind == "counter" and "rises in 21 %" in found.message, found.message
    assert rising_share(meter) == pytest.approx(np.mean(np.diff(meter) > 0))
    rare = 120.0 + np.cumsum(np.arange(N) % 24 == 7)  # rises once a day: 4 times
    assert 0 < np.count_nonzero(np.diff(rare)) < COUNTER_RISES and rising_share(rare) is None
    few = 120.0 + np.cumsum(np.arange(N) % 24 == 7) + np.cumsum(np.arange(N) % 24 == 19)
    assert np.mean(np.diff(few) > 0) < COUNTER_RISING and rising_share(few) is None


def test_the_gain_of_an_input_is_found_from_the_state_space():
    import jaxbox
    from jaxbox.select._cases import _gain_inputs

    zon = jaxbox.get_model("Zon")
    theta = zon.defaults()
    assert _gain_inputs(zon, theta, "gA") == ("I_glo_hor",)
    assert _gain_inputs(zon, theta, "C_zon") == ()  # it moves A too
    assert _gain_inputs(zon, theta, "R_wal") == ()


@pytest.mark.parametrize("kilo", [True, False], ids=["kW/m2", "W/m2"])
def test_no_valid_model_names_a_doubtful_unit_first(kilo, tmp_path, capsys):
    """Irradiance in kW/m² pushes the aperture to its bound: the last line says so before it
    speaks of the data's length."""
    from test_hostile import frame as tiny

    import jaxbox
    from jaxbox.cli._main import main

    data = tiny(72)
    if kilo:
        data["I_glo_hor"] = data["I_glo_hor"] / 1000.0
    path = tmp_path / "office.csv"
    data.to_csv(path, index=False)
    argv = ["select", str(path), "--models", "Zon", "--starts", "1", "--max-steps", "30"]
    code = main([*argv, "--out", str(tmp_path / "out")])
    last = capsys.readouterr().err.strip().splitlines()[-1]
    said: list[str] = []  # the selection's own verdict (verdict_text) in Python
    gb = jaxbox.GreyBox(path)
    jaxbox.forward_selection(gb, ["Zon"], starts=1, max_steps=30, progress=said.append)
    (verdict,) = [m for m in said if m.startswith("accepted: ")]
    assert verdict.startswith("accepted: none (no valid model")
    assert ("; 'I_glo_hor' peaks at" in verdict) == kilo, verdict
    assert code == 1 and last.startswith("no valid model: "), last
    assert "span only" in last
    if kilo:
        doubt = last.index("'I_glo_hor' peaks at")
        assert doubt < last.index("span only")
        assert "--scale I_glo_hor=1000" in last and "(gA on a bound)" in last
        assert "scale={" not in last  # in command-line terms
    else:
        assert "I_glo_hor" not in last


def test_allow_takes_its_own_parsed_form():
    """The command line parses --allow once and passes the result on (once an internal error
    the option matrix found)."""
    from jaxbox.data._plausible import parse_allow

    parsed = parse_allow(["T_zon=jump", "spike"])
    assert parsed == {("T_zon", "jump"), (None, "spike")}
    assert parse_allow(parsed) == parsed


#: the measured buildings beside the repository (not shipped), as the benchmarks read them
SHARED = Path(os.environ.get("JAXBOX_SHARED", Path(__file__).resolve().parents[2] / "shared"))
SHARED = SHARED / "data"


@pytest.mark.skipif(
    not (SHARED / "purdue_dc_house").is_dir(), reason="the Purdue house data are not beside"
)
def test_the_purdue_cold_front_is_kept_as_weather():
    """+1 °C to −21 °C in ten hours on 2022-12-22: refused once as a change of unit."""
    import jaxbox
    from jaxbox.data import load

    data = load(
        SHARED / "purdue_dc_house" / "DC_House_Nov_April.csv",
        time="Time",
        columns={
            "T_zon": "Indoor Temp [C]",
            "T_amb": "OutdoorTemp_C_",
            "I_glo_hor": "SolarIrradiation_W_m_2_",
            "Q_hea": "HeatSupply_kW_",
        },
        scale={"Q_hea": 1000.0},
    )
    notes = check_plausibility(data, columns=["T_zon", "T_amb", "I_glo_hor", "Q_hea"], warn=False)
    front = [n for n in notes if "'T_amb' changes by" in n]
    assert len(front) == 1 and "2022-12-22" in front[0] and "weather" in front[0], notes
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        jaxbox.GreyBox(data, name="purdue house")  # the search's entry takes it


@pytest.mark.parametrize(
    "extra, code, words",
    [
        ([], 2, ["'T_zon' jumps by", "--allow T_zon=jump"]),
        (["--allow", "wobble"], 2, ["--allow wobble", "kelvin, fahrenheit"]),
        (["--allow", "T_zon="], 2, ["--allow 'T_zon='"]),
        (["--allow", "T_zon=jump", "--validate", "none"], 0, ["allowed: 'T_zon' jumps by"]),
    ],
    ids=["refused", "unknown-check", "empty-check", "allowed"],
)
def test_the_command_line_allows_a_refusal_by_name(extra, code, words, tmp_path, capsys):
    from test_hostile import frame as tiny

    from jaxbox.cli._main import main

    data = tiny(48)
    data.loc[30:, "T_zon"] -= 25.0
    path = tmp_path / "moved.csv"
    data.to_csv(path, index=False)
    argv = ["fit", str(path), "--model", "Zon", "--starts", "1", "--max-steps", "2", *extra]
    assert main(argv) == code
    err = capsys.readouterr().err
    for word in words:
        assert word in err, err
    assert "allow={" not in err  # in command-line terms


@pytest.mark.parametrize("heat", [0.0, 500.0], ids=["heating off", "heating constant"])
def test_no_valid_model_names_a_heat_input_that_is_zero_first(heat, tmp_path, capsys, monkeypatch):
    """With the heating off throughout the identification data, the scale of every model is
    undetermined (capacities × k, resistances / k, apertures × k: the same temperatures):
    the verdict and the command's last line say so first. A constant heat input that is not
    zero sets the scale (the mean temperature it holds): nothing to say then."""
    from test_hostile import frame as tiny

    import jaxbox
    from jaxbox.cli._main import main
    from jaxbox.select import _cases

    data = tiny(72)
    # heat == 0: the heating off over the identification half (the first), on in the other
    data.loc[: 35 if heat == 0.0 else None, "Q_hea"] = heat
    path = tmp_path / "house.csv"
    data.to_csv(path, index=False)
    monkeypatch.setattr(_cases.Case, "is_valid", property(lambda self: False))
    argv = ["select", str(path), "--models", "Zon", "--starts", "1", "--max-steps", "5"]
    assert main(argv) == 1
    last = capsys.readouterr().err.strip().splitlines()[-1]
    said: list[str] = []
    gb = jaxbox.GreyBox(path)
    jaxbox.forward_selection(gb, ["Zon"], starts=1, max_steps=5, progress=said.append)
    (verdict,) = [m for m in said if m.startswith("accepted: ")]
    hint = "'Q_hea' is 0 W throughout the identification data"
    assert last.startswith("no valid model: ") and verdict.startswith("accepted: none (no valid")
    if heat == 0.0:
        assert last.startswith(f"no valid model: {hint}"), last
        assert f"none (no valid model; {hint}" in verdict, verdict
        assert "not the heat-loss coefficient or the capacities" in last
        # where the heating runs: the validation half, and the options that identify on it
        (options,) = re.findall(r"identify on it, (--train '[^']+' --validate none)\)", last)
        train = re.search(r"--train '([^']+)'", options)[1]
        assert train == f"{gb.valid_period[0]}..{gb.valid_period[1]}"
        assert main([*argv, "--json"]) == 1
        assert json.loads(capsys.readouterr().out)["verdict"].startswith(
            f"none (no valid model; {hint}"
        )
        monkeypatch.undo()
        assert main([*argv, "--train", train, "--validate", "none", "--json"]) in (0, 1)
    else:
        assert "0 W throughout" not in last and "0 W throughout" not in verdict


def test_no_heat_input_measured_is_named(tmp_path, monkeypatch):
    """Data with no heat input at all (a free-floating building, no 'Q_hea'): the same
    scale left undetermined, and the verdict says so."""
    from test_hostile import frame as tiny

    import jaxbox
    from jaxbox.select import _cases, structure_search

    path = tmp_path / "free.csv"
    tiny(72).drop(columns=["Q_hea"]).to_csv(path, index=False)
    monkeypatch.setattr(_cases.Case, "is_valid", property(lambda self: False))
    said: list[str] = []
    gb = jaxbox.GreyBox(path)
    structure_search(gb, starts=1, max_steps=5, max_depth=0, lookahead=0, progress=said.append)
    (verdict,) = [m for m in said if m.startswith("accepted: ")]
    assert verdict.startswith("accepted: none (no valid model; no heat input is measured"), verdict


@pytest.mark.parametrize(
    "columns, inputs, outputs, said",
    [
        ({"Q_hea": 0.0}, ("T_amb", "Q_hea"), ("T_zon",), "'Q_hea' is 0 W throughout"),
        ({"Q_hea": 0.0, "P_ele": 0.0}, ("Q_hea", "P_ele"), ("T_zon",), "'Q_hea' and 'P_ele' are"),
        ({"Q_hea": 0.0, "P_ele": 80.0}, ("Q_hea", "P_ele"), ("T_zon",), None),
        ({"Q_hea": 500.0}, ("T_amb", "Q_hea"), ("T_zon",), None),
        ({}, ("T_amb",), ("T_zon",), "no heat input is measured"),
        ({"Q_hea": 300.0}, ("T_amb",), ("T_zon",), "none of the models takes a heat input"),
        ({"Heizung [kW]": 1.5}, ("T_amb",), ("T_zon",), "also have 'Heizung [kW]', under names"),
        ({"Q_hea": 0.0}, ("T_amb", "T_zon"), ("Q_hea",), None),  # the heat demand form
    ],
)
def test_which_heat_inputs_leave_the_scale_undetermined(columns, inputs, outputs, said):
    import types

    from jaxbox.select._cases import idle_heat_inputs

    n = 24
    frame = pd.DataFrame(
        {"T_zon": np.full(n, 20.0), "T_amb": np.linspace(0, 5, n)}
        | {k: np.full(n, v) for k, v in columns.items()}
    )
    frame.iloc[3] = np.nan  # a gap: left out, never read as a heat input
    case = types.SimpleNamespace(
        model=types.SimpleNamespace(inputs=inputs, outputs=outputs), ident=frame
    )
    got = idle_heat_inputs([case])
    if said is None:
        assert got == []
    else:
        (text,) = got
        assert said in text and "not the heat-loss coefficient or the capacities" in text


def test_a_search_without_its_required_columns_names_them_all_and_the_mapping(
    tmp_path, capsys, monkeypatch
):
    """Columns under the names of a German logger: the search names both signals it needs
    at once, the columns the data have, and the mapping in each interface's terms; where the
    heating is left unmapped, the verdict names the columns no model reads."""
    from test_hostile import frame as tiny

    import jaxbox.select
    from jaxbox.cli._main import main
    from jaxbox.models import Grammar, ModelError
    from jaxbox.select import _cases

    names = {"T_zon": "Raumtemperatur", "T_amb": "Aussen", "Q_hea": "Heizung [kW]"}
    with pytest.raises(ModelError) as err:
        Grammar.from_columns(["Raumtemperatur", "Aussen", "I_glo_hor"])
    text = str(err.value)
    assert "needs the ambient temperature T_amb and a zone temperature T_zon" in text, text
    assert "'Raumtemperatur', 'Aussen', 'I_glo_hor'" in text
    assert "columns={'T_amb': 'your_col', 'T_zon': 'your_col'} in jaxbox.data.load" in text
    with pytest.raises(ModelError, match=r"needs the ambient temperature T_amb \(did you mean"):
        Grammar.from_columns(["T_zon", "T_amb_"])
    data = tiny(72).rename(columns=names)
    data["Heizung [kW]"] /= 1000.0
    path = tmp_path / "logger.csv"
    data.to_csv(path, index=False)
    assert main(["select", str(path)]) == 2
    err = capsys.readouterr().err
    assert "--map T_amb=YOUR_COLUMN --map T_zon=YOUR_COLUMN" in err, err
    argv = ["select", str(path), "--map", "T_zon=Raumtemperatur", "--map", "T_amb=Aussen"]
    monkeypatch.setattr(_cases.Case, "is_valid", property(lambda self: False))
    search = jaxbox.select.structure_search
    monkeypatch.setattr(  # the roots alone: a short search
        jaxbox.select,
        "structure_search",
        lambda gb, **kw: search(gb, max_depth=0, lookahead=0, **kw),
    )
    assert main([*argv, "--starts", "1", "--max-steps", "20", "--patience", "1"]) == 1
    err = capsys.readouterr().err
    # the progress lines in command-line terms as the last one is
    (verdict,) = [line for line in err.splitlines() if line.startswith("accepted: ")]
    for line in (verdict, err.strip().splitlines()[-1]):
        assert "also have 'Heizung [kW]', under names no model reads" in line, line
        assert "map yours with --map Q_hea=YOUR_COLUMN" in line, line
        assert "jaxbox.data.load" not in line


def test_no_valid_model_repeats_the_data_checks_doubt_of_swapped_columns(tmp_path, capsys):
    """The zone and outdoor columns swapped: the data check's warning (given at the start)
    is the last line's first cause when no model is valid."""
    from test_hostile import frame as tiny

    from jaxbox.cli._main import main

    data = tiny(72)
    data["T_zon"], data["T_amb"] = data["T_amb"].to_numpy(), data["T_zon"].to_numpy()
    path = tmp_path / "swapped.csv"
    data.to_csv(path, index=False)
    argv = ["select", str(path), "--models", "Zon", "--starts", "1", "--max-steps", "30"]
    code = main([*argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert any(line.startswith("warning:") and "swapped" in line for line in err), err
    assert code == 1 and err[-1].startswith("no valid model: the data check warned: 'T_amb'")
    assert "swapped" in err[-1] and err[-1].index("swapped") < err[-1].index("none of the")
