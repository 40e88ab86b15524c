"""A synthetic fleet: library models with random plausible parameters, driven by real weather.

Each building is a library model (``ZonWal`` by default, or ``Zon``) whose heat-loss
coefficient, capacities and solar aperture are drawn at random in plausible ranges (capacities
and aperture in proportion to the HLC), simulated
exactly over a window of the bundled twin-house weather (outdoor air and global horizontal
irradiance measured in Holzkirchen, 2013; each building its own start day), with random on/off
heating sized to its HLC and white measurement noise on the zone temperature. The true
parameters and KPIs (:func:`jaxbox.validate.kpi_values`) are known, so a fleet run can be
checked against them.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["make_fleet", "FLEET_MODELS", "TRUTH_FILE"]

#: library models the generator can draw
FLEET_MODELS = ("Zon", "ZonWal")
#: name of the answer key written beside the buildings
TRUTH_FILE = "truth.csv"


def _draw(model: str, rng: np.random.Generator) -> dict[str, float]:
    """Random plausible parameters (SI): HLC 60–400 W/K; per W/K of loss 10–30 kJ/K in the
    zone, 150–400 kJ/K in the envelope and a solar aperture of 0.004–0.02 m² (so that full sun
    would warm the zone by 3–16 K at steady state)."""
    hlc = float(np.exp(rng.uniform(np.log(60.0), np.log(400.0))))
    theta = {
        "R_wal": 1.0 / hlc,
        "C_zon": hlc * float(rng.uniform(1.0e4, 3.0e4)),
        "gA": hlc * float(rng.uniform(0.004, 0.02)),
        "T_zon0": float(rng.uniform(18.0, 24.0)),
    }
    if model == "ZonWal":
        theta["C_wal"] = hlc * float(rng.uniform(1.5e5, 4.0e5))
        theta["T_wal0"] = theta["T_zon0"] - float(rng.uniform(0.0, 4.0))
    return theta


def _heating(n: int, hlc: float, rng: np.random.Generator) -> np.ndarray:
    """On/off heating [W] in blocks of 1–8 h, on about half the time, 6–14 K worth of HLC."""
    q = np.zeros(n)
    level = hlc * float(rng.uniform(6.0, 14.0))
    i = 0
    on = bool(rng.random() < 0.5)
    while i < n:
        k = int(rng.integers(1, 9))
        q[i : i + k] = level if on else 0.0
        on = not on
        i += k
    return q


def make_fleet(
    n: int,
    directory: str | os.PathLike | None = None,
    *,
    model: str = "ZonWal",
    days: float = 31.0,
    noise: float = 0.1,
    seed: int = 0,
    prefix: str = "b",
) -> tuple[dict[str, object], pd.DataFrame]:
    """``n`` synthetic buildings with known parameters and KPIs.

    Args:
        n: number of buildings.
        directory: if given, write one CSV per building (``<prefix><k>.csv``, columns
            ``time, T_amb, Q_hea, I_glo_hor, T_zon``) and the answer key :data:`TRUTH_FILE`
            there (created if needed).
        model: library model of every building (see :data:`FLEET_MODELS`).
        days: length of each building's data [days] (hourly; at most the 41 days of weather).
        noise: standard deviation of the white noise on ``T_zon`` [K].
        seed: seed of every random draw.
        prefix: building names are ``prefix`` + a zero-padded number.

    Returns:
        (``{name: Dataset}``, truth table indexed by ``building`` with the model, its true
        parameters [SI], ``hlc`` [W/K], ``solar_aperture`` [m²], ``tau1``, ``tau2`` … [h]).

    Raises:
        ValueError: an unknown model, ``n < 1`` or more days than the weather holds.
    """
    from ..data import Dataset
    from ..data._args import check_count, check_real
    from ..models import get_model
    from ..simulate import simulate_model
    from ..validate import kpi_values
    from ._twinhouse import twinhouse_exp1

    if model not in FLEET_MODELS:
        raise ValueError(f"make_fleet draws {', '.join(FLEET_MODELS)}; got model {model!r}")
    n = check_count(n, "n (buildings)")
    days = check_real(days, "days", "days")
    noise = check_real(noise, "noise", "K")
    if noise < 0:
        raise ValueError(f"noise is a standard deviation [K] ≥ 0, got {noise}")
    seed = check_count(seed, "seed", 0)
    if directory is not None and Path(directory).exists() and not Path(directory).is_dir():
        raise ValueError(f"directory {str(directory)!r} is a file; give a folder")
    weather = twinhouse_exp1("N2", "1h")
    steps = int(round(days * 24))
    if steps < 48 or steps > len(weather):
        raise ValueError(
            f"days must give 2 days to {len(weather) // 24} days of hourly weather, got {days}"
        )
    rc = get_model(model)
    rng = np.random.default_rng(seed)
    t_amb, irr = weather["T_amb"], weather["I_glo_hor"]
    width = len(str(int(n) - 1))
    buildings: dict[str, object] = {}
    rows = []
    for k in range(int(n)):
        name = f"{prefix}{k:0{width}d}"
        theta = _draw(model, rng)
        first = int(rng.integers(0, len(weather) - steps + 1))
        index = weather.index[first : first + steps]
        cols = {
            "T_amb": t_amb[first : first + steps],
            "Q_hea": _heating(steps, 1.0 / theta["R_wal"], rng),
            "I_glo_hor": irr[first : first + steps],
        }
        clean = Dataset.from_arrays(index, {**cols, "T_zon": np.zeros(steps)})
        y = simulate_model(rc, theta, clean).y[:, 0] + rng.normal(0.0, noise, steps)
        buildings[name] = clean.with_columns(T_zon=np.round(y, 4))
        kpi = kpi_values(rc, theta)
        row = {"building": name, "model": model, "start": str(index[0]), **theta}
        row.update(hlc=kpi["hlc"], solar_aperture=kpi["solar_aperture"])
        row.update({f"tau{i + 1}": v for i, v in enumerate(kpi["time_constants"])})
        rows.append(row)
    truth = pd.DataFrame(rows).set_index("building")
    if directory is not None:
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        for name, data in buildings.items():
            frame = data.frame.copy()
            frame.index.name = "time"
            frame.to_csv(out / f"{name}.csv")
        truth.to_csv(out / TRUTH_FILE)
    return buildings, truth
