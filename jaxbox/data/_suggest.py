"""Which column is which, read from the names a logger gave them: a suggested mapping.

Monitoring files name their columns as their loggers do (``Indoor Temp [C]``,
``OutdoorTemp_C_``, ``HeatSupply_kW_``, ``Ti``, ``Ph``), and often write the unit into the
name. Where a search or a model asks for a canonical signal the data do not have, the error
suggests the columns whose names say they are that signal, with the unit their names state:
``suggest_columns(['Indoor Temp [C]', 'OutdoorTemp_C_', 'HeatSupply_kW_'])`` gives
``{'T_zon': 'Indoor Temp [C]', 'T_amb': 'OutdoorTemp_C_', 'Q_hea': 'HeatSupply_kW_'}`` and
``{'Q_hea': 'kW'}``. Nothing is mapped or converted without the user: a column is suggested
only where it alone fits a signal, and the user passes it (``columns=``, ``units=``; on the
command line ``--map``, ``--unit``); where several fit one (the rooms of a house, its
heaters), they are listed with the mapping that takes them all (their mean, of powers their
sum). :func:`stated_unit_notes` warns where a mapped column's name states a unit the column is
not read in.

The words read (in English, lower case; a name is cut at every non-alphanumeric character,
between a word and a capitalised one and before digits):

* the zone's air ``T_zon``: *indoor, inside, interior, internal, room, zone, living* with a
  word for a temperature (*temp*, *air*, *AT*) or its unit, or a code ``Ti``, ``Tin``,
  ``Tz``, ``Tzone``, ``Tint``, ``yTi``;
* the outdoor air ``T_amb``: *outdoor, outside, ambient, exterior, external, weather*, or a code
  ``Ta``, ``Tamb``, ``Tout``, ``Text``, ``To``, ``Toa``, ``OAT``;
* the global horizontal irradiance ``I_glo_hor``: *solar, irradiance, irradiation, radiation,
  pyranometer, GHI*, or a code ``Ps``, ``Gv``, ``Isol``;
* the heating power ``Q_hea``: *heat, heating, heater, thermal, boiler, radiator*, or a code
  ``Ph``, ``Qh``, ``Phea``, ``Qhea``;

a column whose name states a unit of another kind (a power for a temperature), or a word that
rules the signal out (a *setpoint*, a *supply* or *return* temperature, an *energy* counter, an
electric *unit*), is not suggested.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Sequence

from ._units import _KIND as _KIND_OF_UNIT

__all__ = ["suggest_columns", "name_unit", "suggestion_text", "stated_unit_notes"]

#: signal -> (words naming it, code names that are the whole name, kind of unit it takes)
_SIGNALS: dict[str, tuple[frozenset, frozenset, str]] = {
    "T_zon": (
        frozenset({"indoor", "inside", "interior", "internal", "room", "zone", "living"}),
        frozenset({"ti", "tin", "tz", "tzone", "tint", "yti", "tindoor"}),
        "temperature",
    ),
    "T_amb": (
        frozenset({"outdoor", "outside", "ambient", "exterior", "external", "weather"}),
        frozenset({"ta", "tamb", "tout", "text", "to", "toa", "oat", "toutdoor"}),
        "temperature",
    ),
    "I_glo_hor": (
        frozenset({"solar", "irradiance", "irradiation", "radiation", "pyranometer", "ghi"}),
        frozenset({"ps", "gv", "isol", "ghi", "igh"}),
        "irradiance",
    ),
    "Q_hea": (
        frozenset({"heat", "heating", "heater", "thermal", "boiler", "radiator"}),
        frozenset({"ph", "qh", "phea", "qhea", "qheat", "pheat"}),
        "power",
    ),
}
#: words that rule a signal out whatever else the name says
_NOT = {
    "T_zon": frozenset(
        {"setpoint", "set", "sp", "target", "supply", "return", "flow", "humidity", "rh"}
    ),
    "T_amb": frozenset({"setpoint", "unit", "humidity", "rh", "wind", "speed", "dew"}),
    "I_glo_hor": frozenset(
        {"direct", "diffuse", "dni", "dhi", "vertical", "facade", "beam", "longwave", "infrared"}
    ),
    "Q_hea": frozenset(
        {"setpoint", "temp", "temperature", "energy", "kwh", "wh", "cop", "status", "mode", "flux"}
    ),
}
#: words that name a temperature (a name with a zone word and no unit also needs one of these;
#: ``at``: air temperature, as loggers abbreviate it, ``N2_living_AT_h67cm``)
_TEMPERATURE_WORDS = frozenset({"temp", "temperature", "tmp", "t", "air", "at"})
#: unit spelled in a name -> (the unit as ``units=`` takes it, its kind); ``None``: jaxbox's own
_POWER_UNITS = {"w": (None, "power"), "kw": ("kW", "power"), "mw": ("MW", "power")}
_TEMPERATURE_UNITS = {
    "c": (None, "temperature"),
    "degc": (None, "temperature"),
    "°c": (None, "temperature"),
    "f": ("degF", "temperature"),
    "degf": ("degF", "temperature"),
    "°f": ("degF", "temperature"),
    "k": ("K", "temperature"),
    "kelvin": ("K", "temperature"),
}
_IRRADIANCE = re.compile(
    r"(?<![a-z])(k?)w[\W_]*(?:per[\W_]*)?m[\W_]*(?:2|²|\^2)(?![0-9])", re.IGNORECASE
)
_BTU = re.compile(r"(?<![a-z])(k?)btu[\W_]*(?:per[\W_]*)?h(?:r|our)?(?![a-z])", re.IGNORECASE)


def _tokens(name: str) -> list[str]:
    """Lower-case words of a column name (cut at non-alphanumerics and camel case)."""
    spaced = re.sub(r"([a-z]{2,}|[0-9])([A-Z][a-z])", r"\1 \2", str(name))
    spaced = re.sub(r"([A-Za-z])([0-9])", r"\1 \2", spaced)  # "Zone1" -> "Zone 1"
    return [t for t in re.split(r"[^0-9a-z°²]+", spaced.lower()) if t]


def name_unit(name: str) -> tuple[str | None, str | None]:
    """The unit a column's name states: ``(unit for units=, kind)``; the unit ``None`` where it
    is jaxbox's own (°C, W, W/m²), the kind ``None`` where the name states none.

    >>> name_unit("HeatSupply_kW_"), name_unit("SolarIrradiation_W_m_2_")
    (('kW', 'power'), (None, 'irradiance'))
    """
    text = str(name)
    m = _IRRADIANCE.search(text)
    if m:
        return ("kW/m2" if m.group(1) else None), "irradiance"
    m = _BTU.search(text)
    if m:
        return ("kBtu/h" if m.group(1) else "Btu/h"), "power"
    words = _tokens(text)
    for word in reversed(words):  # a unit is written last, as a rule
        if word in _POWER_UNITS:
            return _POWER_UNITS[word]
        if word in _TEMPERATURE_UNITS and len(words) > 1:
            return _TEMPERATURE_UNITS[word]
    return None, None


def _fits(signal: str, name: str) -> bool:
    words, codes, kind = _SIGNALS[signal]
    tokens = _tokens(name)
    if not tokens or _NOT[signal] & set(tokens):
        return False
    _, stated = name_unit(name)
    if stated is not None and stated != kind:
        return False
    # a code is the whole name, or the name but its unit ("Ti", "T_in", "Ti_C", "Ph [kW]")
    cut = _BTU.sub(" ", _IRRADIANCE.sub(" ", str(name)))
    bare = [t for t in _tokens(cut) if t not in _POWER_UNITS and t not in _TEMPERATURE_UNITS]
    if "".join(bare) in codes or "".join(tokens) in codes:
        return True
    if not words & set(tokens):
        return False
    if kind == "temperature" and stated is None:
        return bool(_TEMPERATURE_WORDS & set(tokens))
    return True


def _fitting(columns: Iterable[str], signals: Sequence[str] | None) -> dict[str, list[str]]:
    """The columns whose names fit each signal, a column that two signals claim left out."""
    columns = [str(c) for c in columns]
    signals = list(_SIGNALS) if signals is None else [s for s in signals if s in _SIGNALS]
    fits = {s: [c for c in columns if _fits(s, c)] for s in signals}
    claimed: dict[str, int] = {}
    for found in fits.values():
        for c in found:
            claimed[c] = claimed.get(c, 0) + 1
    return {s: [c for c in f if claimed[c] == 1] for s, f in fits.items()}


def suggest_columns(
    columns: Iterable[str], signals: Sequence[str] | None = None
) -> tuple[dict[str, str], dict[str, str]]:
    """The columns whose names say they are ``signals`` (default: the zone and outdoor
    temperatures, the irradiance and the heating), one per signal where exactly one column fits
    it and no other signal claims that column; and the units their names state where these are
    not jaxbox's own. Returns ``(columns, units)``: ``{signal: column}``, ``{signal: unit}``
    (ready for ``jaxbox.data.load(..., columns=…, units=…)``, keyed by the canonical names)."""
    return _unique(_fitting(columns, signals))


def _unique(fits: dict[str, list[str]]) -> tuple[dict[str, str], dict[str, str]]:
    """``(signal -> its one fitting column, signal -> the unit that column's name states)``
    of :func:`_fitting`'s answer (the units only where they are not jaxbox's own)."""
    mapping = {s: f[0] for s, f in fits.items() if len(f) == 1}
    units = {}
    for s, c in mapping.items():
        unit, _ = name_unit(c)
        if unit is not None:
            units[s] = unit
    return mapping, units


def suggestion_text(
    missing: Iterable[str], columns: Iterable[str], also: Iterable[str] = ()
) -> str:
    """``"; by their names, perhaps columns={…} with units={…}"`` for the ``missing`` signals
    (and those of ``also`` the data lack, which a model would read), or ``""`` where no name
    says which of ``columns`` they are."""
    columns = list(columns)
    missing = list(missing)
    wanted = list(dict.fromkeys([*missing, *(s for s in also if s not in columns)]))
    own = [c for c in columns if c not in wanted and c not in _SIGNALS]
    fits = _fitting(own, wanted)
    mapping, units = _unique(fits)
    text = ""
    if any(s in mapping for s in missing):
        text = f"; by their names, perhaps columns={mapping!r}"
        units = {s: u for s, u in units.items() if s in mapping}
        text += f" with units={units!r}" if units else ""
    for signal, found in fits.items():
        # rooms, heaters: one of them, or all of them together
        if signal not in mapping and 1 < len(found) <= _MAX_SEVERAL:
            how = "sum" if _SIGNALS[signal][2] == "power" else "mean"
            text += (
                f"; several columns could be {signal}: one of them, or all: "
                f"columns={ {signal: found}!r} for their {how}"
            )
    return text


#: the most columns that fit one signal listed as its candidates (more: no suggestion)
_MAX_SEVERAL = 12


def stated_unit_notes(
    mapped: Iterable[tuple[str, str]],
    converted: Iterable[str],
    unit_of: Callable[[str], str | None],
) -> list[str]:
    """Warnings for columns mapped onto a signal whose names state another unit than the one
    they are read in: ``mapped`` the pairs (your column, canonical name), ``converted`` the
    canonical names given a unit or a scale factor, ``unit_of`` the unit jaxbox reads a
    canonical name in (``"°C"``, ``"W"``, ``"W/m²"``, ``None``). A name that states a unit of
    another kind (a power mapped onto a temperature) is named too."""
    converted = set(converted)
    notes = []
    for user, canonical in mapped:
        kind = _KIND_OF_UNIT.get(unit_of(canonical) or "")
        unit, stated = name_unit(user)
        if kind is None or stated is None or canonical in converted:
            continue
        if stated != kind:
            notes.append(
                f"column {user!r} is mapped to {canonical!r} (a {kind}), but its name states a "
                f"{stated}: check the mapping (columns=, --map)"
            )
        elif unit is not None:
            notes.append(
                f"column {user!r} (mapped to {canonical!r}) states {unit} in its name, but no "
                f"unit was given: it is read in {unit_of(canonical)}; if it is logged in "
                f"{unit}, pass units={{{canonical!r}: {unit!r}}} (command line: --unit "
                f"{canonical}={unit})"
            )
    return notes
