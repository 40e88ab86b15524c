"""Canonical signal names and their units.

Every quantity has one canonical column name with a fixed SI-ish unit (temperatures in °C,
powers in W, irradiances in W/m²). Some names take a numeric suffix for several signals of
the same kind, e.g. ``T_zon1``, ``T_zon2`` or ``Q_hea2``; a suffixed name has the unit of its
base name.
"""

from __future__ import annotations

import re

__all__ = ["SIGNALS", "CONSTANT", "signal_unit", "signal_base", "is_temperature"]

#: The input that is 1 at every sample: a virtual column of every dataset (no file holds it),
#: through which a model takes a constant heat input, such as the one that stands for a constant
#: offset of a temperature sensor (:func:`jaxbox.models.components.sensor_offset`).
CONSTANT = "one"

#: Canonical name -> (unit, description).
SIGNALS: dict[str, tuple[str, str]] = {
    "T_zon": ("°C", "zone air temperature (numbered variants T_zon1, T_zon2, ... accepted)"),
    "T_amb": ("°C", "ambient (outdoor) air temperature"),
    "T_bou": ("°C", "boundary temperature, e.g. attic or adjacent space (numbered variants)"),
    "T_cel": ("°C", "cellar air temperature"),
    "T_gro": ("°C", "ground temperature"),
    "T_sup": ("°C", "supply air temperature of the ventilation"),
    "I_glo_hor": ("W/m²", "global horizontal irradiance"),
    "I_dif_hor": ("W/m²", "diffuse horizontal irradiance"),
    "I_n": ("W/m²", "global irradiance on a vertical north-facing plane"),
    "I_e": ("W/m²", "global irradiance on a vertical east-facing plane"),
    "I_s": ("W/m²", "global irradiance on a vertical south-facing plane"),
    "I_w": ("W/m²", "global irradiance on a vertical west-facing plane"),
    "Q_hea": ("W", "heating power delivered to the zone (numbered variants Q_hea1, ...)"),
    "Q_ven": ("W", "ventilation thermal power"),
    "P_ele": ("W", "electricity use (internal gains)"),
}

_NUMBERED = re.compile(r"^(?P<base>[A-Za-z_]+?)(?P<num>\d+)$")


def signal_base(name: str) -> str | None:
    """Return the canonical base name of ``name`` (``"T_zon2"`` -> ``"T_zon"``), or ``None``."""
    if name in SIGNALS:
        return name
    match = _NUMBERED.match(name)
    if match is not None and match["base"] in SIGNALS:
        return match["base"]
    return None


def signal_unit(name: str) -> str | None:
    """Unit of a canonical signal name, numbered variants included.

    ``signal_unit("T_zon2") == "°C"``, ``signal_unit("Q_hea") == "W"``. Returns ``None`` for a
    name that is not canonical (such columns are allowed in a dataset and kept as they are).
    """
    base = signal_base(name)
    return None if base is None else SIGNALS[base][0]


def is_temperature(name: str) -> bool:
    """Whether ``name`` is a canonical temperature signal (unit °C)."""
    return signal_unit(name) == "°C"
