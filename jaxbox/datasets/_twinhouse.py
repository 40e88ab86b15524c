"""Twin houses N2 and O5 in Holzkirchen (IEA EBC Annex 58, experiment 1, summer 2013).

Measured 10-minute data of two identical, unoccupied test houses of Fraunhofer IBP, as
redistributed with the IDEAS Modelica library (3-clause BSD license, see ``LICENSE_IDEAS.txt``),
reduced to one zone per house: the ground floor's heated rooms lumped together.
"""

from __future__ import annotations

from functools import cache
from importlib import resources

import pandas as pd

from jaxbox.data import DataError, Dataset, load

__all__ = ["CITATION", "TWINHOUSE_EXP1_PHASES", "twinhouse_exp1"]

HOUSES = ("N2", "O5")
RESOLUTIONS = ("1h", "10min")

#: The four phases of experiment 1 (both houses): (first, last time stamp, description).
#: Time stamps are UTC+1 and mark the end of each 10-minute interval; with hourly data the
#: first sample of a phase is the first full hour after its start.
TWINHOUSE_EXP1_PHASES: list[tuple[pd.Timestamp, pd.Timestamp, str]] = [
    (
        pd.Timestamp("2013-08-21 00:00"),
        pd.Timestamp("2013-08-30 00:00"),
        "1: all heated rooms held at 30 °C",
    ),
    (
        pd.Timestamp("2013-08-30 00:10"),
        pd.Timestamp("2013-09-14 00:00"),
        "2: ROLBS heat input (0 / 500 W) in the living room only, other heaters off",
    ),
    (
        pd.Timestamp("2013-09-14 00:10"),
        pd.Timestamp("2013-09-20 00:00"),
        "3: all heated rooms held at 25 °C",
    ),
    (
        pd.Timestamp("2013-09-20 00:10"),
        pd.Timestamp("2013-10-01 00:00"),
        "4: free float",
    ),
]

#: Credit for the twin-house data.
CITATION = (
    "Twin houses N2 and O5, Holzkirchen: measurements of IEA EBC Annex 58 (experiment 1, "
    "2013) by Fraunhofer IBP, as redistributed with the IDEAS Modelica library "
    "(https://github.com/open-ideas/IDEAS, 3-clause BSD license, Copyright (c) 1998-2025 "
    "Modelica Association, KU Leuven, 3E and contributors). Single-zone use as in "
    "R. De Coninck, F. Magnusson, J. Åkesson, L. Helsen (2016), Toolbox for development and "
    "validation of grey-box building models for forecasting and control, J. Build. Perf. Sim. "
    "9(3):288-303, doi:10.1080/19401493.2015.1046933."
)


def _choose(value: str, choices: tuple[str, ...], name: str) -> str:
    for choice in choices:
        if str(value).lower() == choice.lower():
            return choice
    raise DataError(
        f"unknown {name} {value!r}; choose one of {', '.join(repr(c) for c in choices)}."
    )


@cache
def _load(house: str, resolution: str) -> Dataset:
    name = f"twinhouse_exp1_{house}_{resolution}.csv.gz"
    with resources.as_file(resources.files("jaxbox.datasets") / "files" / name) as path:
        return load(path)


def twinhouse_exp1(house: str = "N2", resolution: str = "1h") -> Dataset:
    """Measured data of twin house ``house`` ("N2" or "O5") at ``resolution`` ("1h", "10min").

    One zone per house, 2013-08-21 to 2013-10-01 (UTC+1; each time stamp ends its averaging
    interval; hourly: 984 samples from 08-21 01:00, 10-minute: 5905 from 08-21 00:00):

    - ``T_zon`` [°C]: mean air temperature of the six rooms with an electric heater (living
      room, three heights averaged first; bath, child, kitchen, doorway, bedroom),
    - ``Q_hea`` [W]: total electric heater power of those rooms,
    - ``T_bou`` [°C]: attic air (mean east/west), ``T_cel`` [°C]: cellar air,
    - ``T_amb`` [°C]: outdoor air, ``T_gro`` [°C]: ground surface (0 cm),
    - ``T_sup`` [°C]: ventilation supply air (corrected), ``Q_ven`` [W]: ventilation thermal
      power as measured (negative while the supply air is colder than the exhaust air),
    - ``I_glo_hor``, ``I_dif_hor`` [W/m²]: global and diffuse horizontal irradiance,
    - ``I_n``, ``I_e``, ``I_s``, ``I_w`` [W/m²]: global irradiance on the vertical facades.

    Values are rounded to 0.001 °C, 0.1 W and 0.1 W/m². See :data:`TWINHOUSE_EXP1_PHASES` for
    the heating phases and :data:`CITATION` for the credit.
    """
    return _load(_choose(house, HOUSES, "house"), _choose(resolution, RESOLUTIONS, "resolution"))
