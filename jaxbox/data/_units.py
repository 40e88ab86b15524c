"""Columns logged in other units, converted at load: ``units={"T_zon": "degF"}``.

jaxbox works in °C, W and W/m² (:data:`~jaxbox.data.SIGNALS`). A column logged in another unit
is named with its unit and converted before any check, as ``value · factor + offset``:

============ ================================================== ==========================
kind         units                                              to
============ ================================================== ==========================
temperature  ``degC`` (``C``, ``°C``), ``degF`` (``F``, ``°F``), ``K``  °C
power        ``W``, ``kW``, ``MW``, ``Btu/h``, ``kBtu/h``                  W
irradiance   ``W/m2`` (``W/m²``), ``kW/m2`` (``kW/m²``)                    W/m²
============ ================================================== ==========================

A unit that does not fit the column (``degF`` for ``Q_hea``), an unknown unit, or a column
given both a unit and a ``scale`` factor is refused, naming the units the column takes.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping

from ._args import check_mapping
from ._errors import DataError, list_names
from ._signals import signal_unit

__all__ = ["UNITS", "unit_conversions"]

_F = 5.0 / 9.0
#: unit of the data (per kind: the unit jaxbox uses) -> (factor, offset) onto that unit
UNITS: dict[str, dict[str, tuple[float, float]]] = {
    "°C": {
        "degC": (1.0, 0.0),
        "C": (1.0, 0.0),
        "°C": (1.0, 0.0),
        "degF": (_F, -32.0 * _F),
        "F": (_F, -32.0 * _F),
        "°F": (_F, -32.0 * _F),
        "K": (1.0, -273.15),
    },
    "W": {
        "W": (1.0, 0.0),
        "kW": (1e3, 0.0),
        "MW": (1e6, 0.0),
        "Btu/h": (0.29307107, 0.0),
        "kBtu/h": (293.07107, 0.0),
    },
    "W/m²": {
        "W/m2": (1.0, 0.0),
        "W/m²": (1.0, 0.0),
        "kW/m2": (1e3, 0.0),
        "kW/m²": (1e3, 0.0),
    },
}


_EXAMPLE = {"°C": "degF", "W": "kW", "W/m²": "kW/m2"}
_KIND = {"°C": "temperature", "W": "power", "W/m²": "irradiance"}


def unit_conversions(
    units: Mapping[str, str] | None,
    names: list[str],
    scale: Mapping[str, float],
    counters: Mapping[str, float],
) -> tuple[dict[str, float], dict[str, float]]:
    """``(factors, offsets)`` per column from ``units`` (canonical column -> the unit it is
    logged in), for columns ``names`` (after mapping); ``scale`` and ``counters`` must not
    name them too.

    Raises:
        DataError: a column that is not there, is not a temperature, power or irradiance, a
            unit it does not take, or a column in ``units`` and ``scale`` or ``counters``.
    """
    given = check_mapping(units, "units", "{'T_zon': 'degF'}")
    factors: dict[str, float] = {}
    offsets: dict[str, float] = {}
    for name, unit in given.items():
        name = str(name)
        if name not in names:
            close = difflib.get_close_matches(name, names, n=3, cutoff=0.6)
            hint = f" (did you mean {list_names(close)}?)" if close else ""
            raise DataError(
                f"units names column {name!r}, but there is none{hint}; units apply after "
                f"columns= (canonical names, command line: --map); available: "
                f"{list_names(names)}."
            )
        ours = signal_unit(name)
        table = UNITS.get(ours or "")
        if table is None:
            raise DataError(
                f"units: {name!r} is not a canonical temperature (T_…), power (Q_…, P_…) or "
                "irradiance (I_…) column; convert it before loading, or use scale= "
                "(command line --scale) for a factor."
            )
        if name in counters:
            raise DataError(
                f"{name!r} is given both a unit and a counter: a counter's unit is its energy "
                f"(counters={{{name!r}: 'kWh'}} (command line: --counter {name}=kWh)); drop "
                "its unit."
            )
        if name in scale:
            raise DataError(
                f"{name!r} has both a unit ({unit!r}) and a scale factor; give one of them "
                f"(units={{{name!r}: {unit!r}}} (command line: --unit {name}={unit}))."
            )
        if not isinstance(unit, str) or unit.strip() not in table:
            raise DataError(
                f"units: {name!r} is a {_KIND[ours]} (jaxbox's unit {ours}); give the unit it "
                f"is logged in as one of {list_names(table)}, got {unit!r}; e.g. "
                f"units={{{name!r}: {_EXAMPLE[ours]!r}}} (command line: --unit "
                f"{name}={_EXAMPLE[ours]})."
            )
        factor, offset = table[unit.strip()]
        if (factor, offset) != (1.0, 0.0):
            factors[name], offsets[name] = factor, offset
    return factors, offsets
