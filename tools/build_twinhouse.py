"""Derive the shipped twin-house data files from the measured 10-minute tables.

Reads ``twinhouse_{N2,O5}_exp1_10min.csv`` (IEA EBC Annex 58 experiment 1, as redistributed
with the IDEAS Modelica library) and writes, for each house, a 10-minute and an hourly gzip CSV
with canonical column names to ``jaxbox/datasets/files/``:

- ``T_zon`` [°C]: mean of the air temperatures of the six rooms with an electric heater
  (living room, its three heights averaged first; bath, child, kitchen, doorway, bedroom),
- ``Q_hea`` [W]: sum of the six heater powers,
- ``T_bou`` [°C]: attic air temperature (mean of east and west), ``T_cel`` [°C]: cellar,
- ``T_amb`` [°C], ``T_gro`` [°C] (ground at 0 cm), ``T_sup`` [°C] (corrected supply air),
- ``Q_ven`` [W]: ventilation thermal power as measured,
- ``I_glo_hor``, ``I_dif_hor``, ``I_n``, ``I_e``, ``I_s``, ``I_w`` [W/m²].

Time stamps (UTC+1, naive) mark the end of each averaging interval; the hourly file is the mean
over right-closed hours labelled at their end, the incomplete first hour dropped. Values are
rounded to 0.001 °C, 0.1 W and 0.1 W/m².

Usage: ``python tools/build_twinhouse.py [SOURCE_DIR]`` (default: ``../shared/data/
twinhouse_exp1`` next to the repository root).
"""

from __future__ import annotations

import argparse
import gzip
import sys
from pathlib import Path

import pandas as pd

from jaxbox.data import load

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_SOURCE = ROOT.parent / "shared" / "data" / "twinhouse_exp1"
OUTPUT = ROOT / "jaxbox" / "datasets" / "files"
HOUSES = ("N2", "O5")
RESOLUTIONS = ("10min", "1h")
HEATED_ROOMS = ("bath", "child", "kitchen", "doorway", "bedroom")
HEATERS = ("living_room", "bath_room", "children_room", "kitchen", "doorway", "bedroom")
COLUMNS = (
    "T_zon", "T_amb", "T_bou", "T_cel", "T_gro", "T_sup", "Q_hea", "Q_ven",
    "I_glo_hor", "I_dif_hor", "I_n", "I_e", "I_s", "I_w",
)  # fmt: skip
#: Decimal places kept per unit prefix: T_* 0.001 °C, Q_* 0.1 W, I_* 0.1 W/m².
DECIMALS = {"T": 3, "Q": 1, "I": 1}


def source_file(source: Path, house: str) -> Path:
    """Path of the measured 10-minute table of ``house``."""
    return Path(source) / f"twinhouse_{house}_exp1_10min.csv"


def output_file(house: str, resolution: str, directory: Path = OUTPUT) -> Path:
    """Path of a shipped file."""
    return Path(directory) / f"twinhouse_exp1_{house}_{resolution}.csv.gz"


def derive_10min(source: Path, house: str) -> pd.DataFrame:
    """Canonical 10-minute signals of ``house``, unrounded (DatetimeIndex ``time``)."""
    raw = load(source_file(source, house), time="datetime_utc+1").frame
    p = f"{house}_"
    living = raw[[f"{p}living_AT_h67cm", f"{p}living_AT_h125cm", f"{p}living_AT_h187cm"]]
    rooms = [living.mean(axis=1)] + [raw[f"{p}{room}_AT"] for room in HEATED_ROOMS]
    out = pd.DataFrame(index=raw.index)
    out["T_zon"] = pd.concat(rooms, axis=1).mean(axis=1)
    out["T_amb"] = raw["Ambient_temperature"]
    out["T_bou"] = raw[[f"{p}attic_east_AT", f"{p}attic_west_AT"]].mean(axis=1)
    out["T_cel"] = raw[f"{p}cellar_AT"]
    out["T_gro"] = raw["Ground_temperature_0cm"]
    out["T_sup"] = raw[f"{p}vent_SUA_corr_AT"]
    out["Q_hea"] = raw[[f"{p}heat_elP_{heater}" for heater in HEATERS]].sum(axis=1)
    out["Q_ven"] = raw[f"{p}vent_thP"]
    out["I_glo_hor"] = raw["Solar_radiation_global_horizontal"]
    out["I_dif_hor"] = raw["Solar_radiation_diffuse_horizontal"]
    for facade, name in zip("nesw", ("north", "east", "south", "west"), strict=True):
        out[f"I_{facade}"] = raw[f"Solar_radiation_global_vertical_{name}"]
    return out[list(COLUMNS)]


def rounded(frame: pd.DataFrame) -> pd.DataFrame:
    """Round each column to its shipped precision (and turn -0.0 into 0.0)."""
    return pd.DataFrame(
        {name: frame[name].round(DECIMALS[name[0]]) + 0.0 for name in frame.columns},
        index=frame.index,
    )


def derive(source: Path, house: str) -> dict[str, pd.DataFrame]:
    """Both shipped tables of ``house``, rounded: ``{"10min": ..., "1h": ...}``."""
    fine = derive_10min(source, house)
    hourly = load(fine).resample("1h").frame
    return {"10min": rounded(fine), "1h": rounded(hourly)}


def write(frame: pd.DataFrame, path: Path) -> None:
    """Write a table as a reproducible gzip CSV (no name or time stamp in the gzip header)."""
    text = frame.to_csv(index_label="time", date_format="%Y-%m-%d %H:%M:%S", lineterminator="\n")
    Path(path).write_bytes(gzip.compress(text.encode("utf-8"), compresslevel=9, mtime=0))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source", nargs="?", type=Path, default=DEFAULT_SOURCE)
    parser.add_argument("--output", type=Path, default=OUTPUT)
    args = parser.parse_args(argv)
    if not args.source.is_dir():
        parser.error(f"no such folder: {args.source}")
    args.output.mkdir(parents=True, exist_ok=True)
    for house in HOUSES:
        for resolution, frame in derive(args.source, house).items():
            path = output_file(house, resolution, args.output)
            write(frame, path)
            print(
                f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}: "
                f"{len(frame)} rows, {path.stat().st_size / 1024:.0f} KiB"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
