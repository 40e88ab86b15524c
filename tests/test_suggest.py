"""Which column is which, from the names loggers give them: the suggested mapping of the
errors that ask for one (jaxbox.data._suggest), in Python and on the command line."""

from __future__ import annotations

import shlex

import numpy as np
import pytest

from jaxbox.data._suggest import name_unit, suggest_columns, suggestion_text

#: the headers of real monitoring files (the Purdue house's, DarkGreyBox's office)
PURDUE = [
    "Time",
    "Setpoint_C_",
    "Rounded Setpoints",
    "Mode",
    "Indoor Temp [C]",
    "OutdoorTemp_C_",
    "WindSpeed_m_s_",
    "SolarIrradiation_W_m_2_",
    "HeatSupply_kW_",
    "Outdoor Unit [W]",
    "AHU and AUX1 [W]",
    "AUX2  [W]",
]
OFFICE = ["Ph", "Ti", "Ta", "Th"]


def test_the_headers_of_real_files_map_to_their_signals_with_the_units_they_state():
    assert suggest_columns(PURDUE) == (
        {
            "T_zon": "Indoor Temp [C]",
            "T_amb": "OutdoorTemp_C_",
            "I_glo_hor": "SolarIrradiation_W_m_2_",
            "Q_hea": "HeatSupply_kW_",
        },
        {"Q_hea": "kW"},
    )
    assert suggest_columns(OFFICE) == ({"T_zon": "Ti", "T_amb": "Ta", "Q_hea": "Ph"}, {})


@pytest.mark.parametrize(
    "name, unit",
    [
        ("HeatSupply_kW_", ("kW", "power")),
        ("Heating power (kW)", ("kW", "power")),
        ("P_heat [W]", (None, "power")),
        ("Boiler [MW]", ("MW", "power")),
        ("Heat [Btu/h]", ("Btu/h", "power")),
        ("SolarIrradiation_W_m_2_", (None, "irradiance")),
        ("GHI [W/m²]", (None, "irradiance")),
        ("I_sol (kW/m2)", ("kW/m2", "irradiance")),
        ("Indoor Temp [C]", (None, "temperature")),
        ("T_out [degF]", ("degF", "temperature")),
        ("oat_F", ("degF", "temperature")),
        ("T_room_K", ("K", "temperature")),
        ("heat_energy_kWh", (None, None)),  # an energy counter: no unit of a signal
        ("Mode", (None, None)),
    ],
)
def test_the_unit_a_name_states(name, unit):
    assert name_unit(name) == unit


@pytest.mark.parametrize(
    "name, signal",
    [
        ("Room temp", "T_zon"),
        ("Zone1 Temp", "T_zon"),
        ("T_in", "T_zon"),
        ("yTi", "T_zon"),
        ("Outside air temperature", "T_amb"),
        ("OAT", "T_amb"),
        ("T_out [degF]", "T_amb"),
        ("GHI [W/m²]", "I_glo_hor"),
        ("I_sol (kW/m2)", "I_glo_hor"),
        ("Boiler_kW", "Q_hea"),
        # ruled out: a setpoint, a supply temperature, an electric unit outdoors, a heat flux,
        # an energy counter, a facade's irradiance, a temperature without a word for one
        ("Setpoint_C_", None),
        ("Supply temp", None),
        ("Outdoor Unit [W]", None),
        ("Heat flux wall", None),
        ("heat_energy_kWh", None),
        ("Solar vertical south [W/m2]", None),
        ("Living room humidity", None),
        ("Temperature (°C)", None),
    ],
)
def test_which_signal_a_name_says(name, signal):
    got = suggest_columns([name])[0]
    assert got == ({} if signal is None else {signal: name})


def test_a_signal_two_columns_fit_is_not_suggested_nor_a_column_two_signals_claim():
    rooms = ["Room 1 temp", "Room 2 temp", "Outdoor temp"]
    assert suggest_columns(rooms)[0] == {"T_amb": "Outdoor temp"}
    # "indoor" and "outdoor" in one name: which is it? neither
    assert suggest_columns(["Indoor outdoor temp diff"])[0] == {}
    # nothing to say: no clause
    assert suggestion_text(["T_zon"], ["a", "b"]) == ""
    # columns named as jaxbox names them are no suggestion
    assert (
        suggestion_text(["T_zon"], ["T_zon_old", "Ti"])
        == "; by their names, perhaps columns={'T_zon': 'Ti'}"
    )


def test_the_search_and_the_dataset_errors_suggest_the_mapping():
    import jaxbox
    from jaxbox.data import DataError
    from jaxbox.models import Grammar, ModelError

    with pytest.raises(ModelError) as err:
        Grammar.from_columns(PURDUE[1:])
    text = str(err.value)
    assert text.endswith(
        "by their names, perhaps columns={'T_amb': 'OutdoorTemp_C_', 'T_zon': 'Indoor Temp [C]', "
        "'Q_hea': 'HeatSupply_kW_', 'I_glo_hor': 'SolarIrradiation_W_m_2_'} with "
        "units={'Q_hea': 'kW'}"
    ), text
    t = np.arange(24) * 3600.0
    d = jaxbox.Dataset.from_arrays(t, {"Ti": np.full(24, 20.0), "Ta": np.zeros(24)})
    with pytest.raises(DataError, match=r"perhaps columns=\{'T_zon': 'Ti'\}\.$"):
        d.require(["T_zon"])


def test_the_command_line_gives_the_suggestion_as_options_that_run(tmp_path, capsys, monkeypatch):
    """The header of a heat-pump house's logger: the options the error suggests, pasted as
    they are, map every signal and convert the heating from kW."""
    from test_hostile import frame as tiny

    import jaxbox.select
    from jaxbox.cli._main import main

    names = {
        "T_zon": "Indoor Temp [C]",
        "T_amb": "OutdoorTemp_C_",
        "Q_hea": "HeatSupply_kW_",
        "I_glo_hor": "SolarIrradiation_W_m_2_",
    }
    data = tiny(72).rename(columns=names)
    data["HeatSupply_kW_"] /= 1000.0
    path = tmp_path / "logger.csv"
    data.to_csv(path, index=False)
    assert main(["select", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    said = err.split("by their names, perhaps ")[1]
    assert said == (
        "--map T_amb=OutdoorTemp_C_ --map 'T_zon=Indoor Temp [C]' --map Q_hea=HeatSupply_kW_ "
        "--map I_glo_hor=SolarIrradiation_W_m_2_ --unit Q_hea=kW"
    ), said
    seen = {}
    search = jaxbox.select.structure_search

    def roots(gb, **kw):  # the roots alone: a short search; what it was given is kept
        seen["columns"] = list(gb.data.columns)
        seen["Q_hea"] = float(np.nanmax(gb.data.frame["Q_hea"]))
        return search(gb, max_depth=0, lookahead=0, **kw)

    monkeypatch.setattr(jaxbox.select, "structure_search", roots)
    fast = ["--starts", "1", "--max-steps", "20", "--patience", "1", "--out", str(tmp_path / "o")]
    assert main(["select", str(path), *shlex.split(said), *fast]) in (0, 1)
    assert {"T_zon", "T_amb", "Q_hea", "I_glo_hor"} <= set(seen["columns"])
    assert seen["Q_hea"] == pytest.approx(800.0)  # kW read as kW: watts inside


def test_the_no_heat_verdict_suggests_the_heating_column(tmp_path):
    from jaxbox.select._cases import idle_heat_inputs

    class _Case:  # what the verdict reads of a case: its model's inputs and its data
        def __init__(self, columns):
            import pandas as pd

            import jaxbox

            frame = pd.DataFrame(
                {c: np.ones(4) for c in columns},
                index=pd.date_range("2024-01-01", periods=4, freq="h"),
            )
            self.ident = jaxbox.data.as_dataset(frame)
            self.model = type("M", (), {"inputs": ("T_amb",), "outputs": ("T_zon",)})()

    (text,) = idle_heat_inputs([_Case(["T_zon", "T_amb", "HeatSupply_kW_", "Mode"])])
    assert "perhaps columns={'Q_hea': 'HeatSupply_kW_'} with units={'Q_hea': 'kW'})" in text


def test_a_mapped_column_whose_name_states_another_unit_is_warned_at_load(tmp_path):
    """Mapped without its unit, a column whose name says kW is named at load with the option
    that reads it so; given the unit or a scale factor, nothing is said; mapped onto a signal
    of another kind (a power onto a temperature), the mapping is named."""
    import warnings

    from test_hostile import frame as tiny

    import jaxbox
    from jaxbox.data import DataWarning

    data = tiny(48).rename(columns={"Q_hea": "HeatSupply_kW_", "T_amb": "Outdoor [W]"})
    data["HeatSupply_kW_"] /= 1000.0
    path = tmp_path / "logger.csv"
    data.to_csv(path, index=False)

    def notes(**kw):
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            jaxbox.load(path, check=False, **kw)
        return [str(w.message) for w in seen if issubclass(w.category, DataWarning)]

    heat = {"Q_hea": "HeatSupply_kW_"}
    (said,) = notes(columns=heat)
    assert "'HeatSupply_kW_' (mapped to 'Q_hea') states kW in its name" in said, said
    assert "units={'Q_hea': 'kW'} (command line: --unit Q_hea=kW)" in said, said
    assert notes(columns=heat, units={"Q_hea": "kW"}) == []
    assert notes(columns=heat, scale={"Q_hea": 1000}) == []
    (said,) = notes(columns={"T_amb": "Outdoor [W]"})
    assert "mapped to 'T_amb' (a temperature), but its name states a power" in said, said


def test_several_columns_make_one_signal_the_mean_of_rooms_the_sum_of_heaters(tmp_path, capsys):
    """A house logged room by room: the zone the mean of the rooms, the heating the sum of
    the heaters, a row missing in one room missing; on the command line by repeating --map."""
    import pandas as pd
    from test_hostile import frame as tiny

    import jaxbox
    from jaxbox.cli._main import main
    from jaxbox.data import DataError

    f = tiny(48)
    f["room_a"], f["room_b"] = f.pop("T_zon") + 1.0, f["T_amb"] + 15.0
    f["heater_1"], f["heater_2"] = f["Q_hea"] * 0.25, f.pop("Q_hea") * 0.75
    f.loc[5, "room_b"] = np.nan
    d = jaxbox.load(
        f,
        time="time",
        columns={"T_zon": ["room_a", "room_b"], "Q_hea": ["heater_1", "heater_2"]},
        scale={"Q_hea": 2.0},  # the canonical signal's options apply to it after combining
    )
    frame = d.frame
    want = (frame["room_a"] + frame["room_b"]) / 2
    np.testing.assert_allclose(frame["T_zon"], want)
    assert np.isnan(frame["T_zon"].iloc[5]) and not np.isnan(frame["room_a"].iloc[5])
    np.testing.assert_allclose(frame["Q_hea"], 2.0 * (frame["heater_1"] + frame["heater_2"]))
    with pytest.raises(DataError, match=r"is mapped twice"):
        jaxbox.load(f, columns={"T_zon": ["room_a", "room_b"], "T_zon2": "room_b"})
    with pytest.raises(DataError, match=r"no column 'room_c'"):
        jaxbox.load(f, columns={"T_zon": ["room_a", "room_c"]})
    with pytest.raises(DataError, match=r"'Mode' is no signal jaxbox knows how to combine"):
        jaxbox.load(f.assign(m=1.0), columns={"Mode": ["m", "room_a"]})
    text = f.astype({"room_a": object})
    text.loc[3, "room_a"] = "n/a"
    with pytest.raises(DataError, match=r"'room_a'.*row 3"):  # a source's text cell is named
        jaxbox.load(text, columns={"T_zon": ["room_a", "room_b"]})
    path = tmp_path / "rooms.csv"
    pd.DataFrame(f).to_csv(path, index=False)
    argv = ["fit", str(path), "--model", "Zon", "--starts", "1", "--json", "--validate", "none"]
    rooms = ["--map", "T_zon=room_a", "--map", "T_zon=room_b"]
    heaters = ["--map", "Q_hea=heater_1", "--map", "Q_hea=heater_2"]
    assert main([*argv, *rooms, *heaters]) == 0, capsys.readouterr().err
    capsys.readouterr()
    assert main([*argv, *rooms, "--map", "T_zon=room_a", *heaters]) == 2
    assert "--map gives T_zon=room_a twice" in capsys.readouterr().err


def test_rooms_and_heaters_that_all_fit_are_listed_with_the_mapping_that_combines_them():
    from jaxbox.cli._common import cli_message

    cols = ["Room 1 temp", "Room 2 temp", "Outdoor temp", "Heater 1 [W]", "Heater 2 [W]"]
    text = suggestion_text(["T_zon", "T_amb"], cols, also=["Q_hea"])
    assert text == (
        "; by their names, perhaps columns={'T_amb': 'Outdoor temp'}"
        "; several columns could be T_zon: one of them, or all: "
        "columns={'T_zon': ['Room 1 temp', 'Room 2 temp']} for their mean"
        "; several columns could be Q_hea: one of them, or all: "
        "columns={'Q_hea': ['Heater 1 [W]', 'Heater 2 [W]']} for their sum"
    ), text
    assert cli_message("x" + text) == (
        "x; by their names, perhaps --map 'T_amb=Outdoor temp'"
        "; several columns could be T_zon: one of them, or all: "
        "--map 'T_zon=Room 1 temp' --map 'T_zon=Room 2 temp' for their mean"
        "; several columns could be Q_hea: one of them, or all: "
        "--map 'Q_hea=Heater 1 [W]' --map 'Q_hea=Heater 2 [W]' for their sum"
    )


def test_a_raw_twin_house_header_gives_the_living_room_and_the_heaters():
    """The raw header of a twin house (IEA EBC Annex 58): the living room's air temperature
    at three heights (``AT``) listed for their mean, the heaters for their sum; the facades'
    and the diffuse and longwave irradiances, the ground and the humidity left out."""
    cols = [
        "N2_attic_east_AT",
        "N2_cellar_AT",
        "N2_living_AT_h67cm",
        "N2_living_AT_h125cm",
        "N2_living_AT_h187cm",
        "N2_kitchen_AT",
        "N2_living_rH_h125cm",
        "N2_westfacade_S_IS_T",
        "N2_heat_elP_living_room",
        "N2_heat_elP_kitchen",
        "N2_vent_ODA_AT",
        "Ambient_temperature",
        "Solar_radiation_global_horizontal",
        "Solar_radiation_diffuse_horizontal",
        "Solar_radiation_global_vertical_south",
        "Longwave_radiation_horizontal",
        "Relative_humidity",
        "Ground_temperature_50cm",
    ]
    assert suggestion_text(["T_zon", "T_amb"], cols, also=["Q_hea", "I_glo_hor"]) == (
        "; by their names, perhaps columns={'T_amb': 'Ambient_temperature', "
        "'I_glo_hor': 'Solar_radiation_global_horizontal'}"
        "; several columns could be T_zon: one of them, or all: columns={'T_zon': "
        "['N2_living_AT_h67cm', 'N2_living_AT_h125cm', 'N2_living_AT_h187cm']} for their mean"
        "; several columns could be Q_hea: one of them, or all: columns={'Q_hea': "
        "['N2_heat_elP_living_room', 'N2_heat_elP_kitchen']} for their sum"
    )
