"""Real buildings for the search benchmarks, prepared in several reasonable ways.

* :func:`twinhouse_variant` — a twin house of IEA EBC Annex 58 experiment 1 from the measured
  10-minute tables in ``../shared/data/twinhouse_exp1``: the zone as the mean of the six heated
  rooms with their total heating (as shipped), or the living room alone with its own heater and
  the mean of the five other heated rooms as a measured neighbour ``T_adj``; with or without
  the supply-air and cellar columns, at 10 minutes or hourly;
* :func:`darkgreybox_office` — DarkGreyBox's demo office (hourly, boiler-heated), with that
  tool's own split (train to 2020-01-19 23:00, test the last five days);
* :func:`purdue_house` — the Purdue DC Nanogrid house under its thermostat (hourly, a month).

Each returns a :class:`jaxbox.GreyBox` with the periods it is judged on. The raw files are not
shipped; they are read from ``../shared/data`` beside the repository (or ``JAXBOX_SHARED``).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("JAXBOX_SHARED", ROOT.parent / "shared")) / "data"

__all__ = ["twinhouse_variant", "darkgreybox_office", "purdue_house", "VARIANTS"]

#: the twin-house preparations of the variant table: (zone, supply air and cellar, step)
VARIANTS = [
    (zone, columns, step)
    for zone in ("mean", "living")
    for columns in ("all", "no T_sup, T_cel")
    for step in ("1h", "10min")
]


def twinhouse_variant(house: str, zone: str = "mean", columns: str = "all", step: str = "1h"):
    """A twin house prepared one way (see the module); a GreyBox with the default halves."""
    import jaxbox
    from jaxbox.data import load

    sys.path.insert(0, str(ROOT / "tools"))
    from build_twinhouse import HEATED_ROOMS, derive_10min, source_file

    frame = derive_10min(SHARED / "twinhouse_exp1", house)
    if zone == "living":  # the living room, its own heater, its heated neighbours measured
        raw = load(source_file(SHARED / "twinhouse_exp1", house), time="datetime_utc+1").frame
        heights = [f"{house}_living_AT_h{h}" for h in ("67cm", "125cm", "187cm")]
        frame["T_zon"] = raw[heights].mean(axis=1).reindex(frame.index)
        frame["Q_hea"] = raw[f"{house}_heat_elP_living_room"].reindex(frame.index)
        rooms = [f"{house}_{room}_AT" for room in HEATED_ROOMS]
        frame["T_adj"] = raw[rooms].mean(axis=1).reindex(frame.index)
    elif zone != "mean":
        raise ValueError(f"zone is 'mean' or 'living', got {zone!r}")
    if columns != "all":
        frame = frame.drop(columns=["T_sup", "T_cel"])
    data = load(frame)
    if step != "10min":
        data = data.resample(step)
    name = f"{house} {zone} {columns} {step}"
    return jaxbox.GreyBox(data, name=name)


def darkgreybox_office():
    """DarkGreyBox's demo office with that tool's split; ``Q_hea`` in W from ``Ph`` in kW."""
    import jaxbox

    df = pd.read_csv(SHARED / "darkgreybox_office" / "demo_data.csv", index_col=0, parse_dates=True)
    d = pd.DataFrame({"T_zon": df["Ti"], "T_amb": df["Ta"], "Q_hea": df["Ph"] * 1000.0})
    d.index = df.index.tz_convert("UTC").tz_localize(None)
    d.index.name = "time"
    return jaxbox.GreyBox(
        d,
        name="darkgreybox office",
        train=("2019-12-23 00:00", "2020-01-19 23:00"),
        valid=("2020-01-20 00:00", "2020-01-24 23:00"),
    )


def purdue_house():
    """The Purdue house under its thermostat: ``T_zon``, ``T_amb``, ``I_glo_hor``, ``Q_hea`` [W]
    from the heat pump's thermal power (auxiliary heat included); default halves."""
    import jaxbox

    df = pd.read_csv(SHARED / "purdue_dc_house" / "DC_House_Nov_April.csv", encoding="utf-8-sig")
    d = pd.DataFrame(
        {
            "T_zon": df["Indoor Temp [C]"],
            "T_amb": df["OutdoorTemp_C_"],
            "I_glo_hor": df["SolarIrradiation_W_m_2_"],
            "Q_hea": df["HeatSupply_kW_"] * 1000.0,
        }
    )
    d.index = pd.to_datetime(df["Time"], format="%m/%d/%Y %H:%M")
    d.index.name = "time"
    return jaxbox.GreyBox(d, name="purdue house")
