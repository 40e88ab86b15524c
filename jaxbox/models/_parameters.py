"""Parameters and the naming convention that gives them units, default guesses and bounds.

Every model parameter is named by a strict convention so that defaults, bounds and parent values
can be matched by name:

========== ======= ============================= =================================
prefix     unit    default guess                 default bounds
========== ======= ============================= =================================
``R_*``    K/W     1e-2 (per name, see below)    [1e-5, 10]
``C_*``    J/K     2e6 zone … 2e7 wall           [1e4, 1e10]
``gA*``    m²      2                             [0, 50]
``fra_*``  –       0.5                           [0, 1] (``fra_ele``: [0, 3])
``T_*0``   °C      20                            [-3, 37]
``Q_*``    W       0                             [-1e4, 1e4]
========== ======= ============================= =================================

The defaults and bounds of ``R_*``, ``C_*``, ``Q_*`` and ``gA*`` suit a building whose heat-loss
coefficient is up to about :data:`REFERENCE_HLC`; :func:`scaled_parameter` gives them for a
building ``s`` times as large (the structure search does so from its data, see
:attr:`jaxbox.models.Grammar.scale`).

``Q_*`` is a constant heat input (signed): a steady base load, or the heat that stands for a
constant offset of a temperature sensor (:func:`~jaxbox.models.components.sensor_offset`).

Whatever the bounds a spec is given (by a component, :meth:`RCNetwork.parameter`, an override of
:meth:`RCNetwork.build` or :meth:`RCModel.with_parameters`), they stay physical: a resistance
``R_*`` or a capacity ``C_*`` has a lower bound > 0 (at 0 a resistance joins two temperatures
into one, a capacity makes its state infinitely fast; below 0 the network makes heat), and a
fraction ``fra_*`` lies within [0, 1] (``fra_ele``, numbered ``fra_ele1``…, only ≥ 0: occupants'
body heat follows their electricity use, so it may exceed 1). :class:`Parameter` refuses other
bounds, naming the parameter.
"""

from __future__ import annotations

import dataclasses
import math
import re

__all__ = [
    "Parameter",
    "ModelError",
    "parameter_for",
    "scaled_parameter",
    "NAMING",
    "REFERENCE_HLC",
]


class ModelError(ValueError):
    """A model declaration or parameter specification is wrong; the message says how to fix it."""


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One model parameter: SI value space, default guess and bounds.

    Attributes:
        name: parameter name following the naming convention (``R_wal``, ``C_zon``, …).
        unit: SI unit string (``K/W``, ``J/K``, ``m²``, ``-``, ``°C``).
        default: default initial guess in ``unit``.
        lower: lower bound in ``unit`` (may be ``-inf``).
        upper: upper bound in ``unit`` (may be ``inf``).
        description: one-line physical meaning.
    """

    name: str
    unit: str
    default: float
    lower: float
    upper: float
    description: str = ""

    def __post_init__(self):
        if not isinstance(self.name, str):
            raise ModelError(f"a parameter name is text such as 'R_wal', got {self.name!r}")
        for field in ("default", "lower", "upper"):
            value = getattr(self, field)
            try:
                if isinstance(value, bool | str | bytes):
                    raise TypeError
                object.__setattr__(self, field, float(value))
            except (TypeError, ValueError):
                raise ModelError(
                    f"parameter {self.name!r}: {field} must be a number, got {value!r}"
                ) from None
        if math.isnan(self.default) or math.isnan(self.lower) or math.isnan(self.upper):
            raise ModelError(f"parameter {self.name!r}: default and bounds must not be NaN")
        if not self.lower < self.upper:
            raise ModelError(
                f"parameter {self.name!r}: lower bound {self.lower:g} must be below upper bound "
                f"{self.upper:g}"
            )
        if not self.lower <= self.default <= self.upper:
            raise ModelError(
                f"parameter {self.name!r}: default {self.default:g} lies outside its bounds "
                f"[{self.lower:g}, {self.upper:g}]; change the default or the bounds"
            )
        if _POSITIVE.fullmatch(self.name) and not self.lower > 0:
            if self.name[0] == "R":
                kind, floor = "resistance [K/W]", 1e-5
                why = "at 0 it joins two temperatures into one, below 0 heat flows uphill"
            else:
                kind, floor = "capacity [J/K]", 1e4
                why = "at 0 its temperature follows at once, below 0 it runs away"
            raise ModelError(
                f"parameter {self.name!r}: lower bound {self.lower:g} must be > 0, a {kind} is "
                f"positive ({why}); give a small positive lower bound such as {floor:g}"
            )
        if _FRACTION.fullmatch(self.name):
            top = math.inf if _FREE_FRACTION.fullmatch(self.name) else 1.0
            if not (0.0 <= self.lower and self.upper <= top):
                span = "[0, 1]" if top == 1.0 else "[0, ∞)"
                raise ModelError(
                    f"parameter {self.name!r}: bounds [{self.lower:g}, {self.upper:g}] leave "
                    f"{span}; a fraction fra_* lies within [0, 1] (fra_ele, a share of the "
                    f"electricity use, within [0, ∞)): give bounds within {span}"
                )

    @property
    def is_initial_state(self) -> bool:
        """True for initial-state parameters ``T_*0`` (and ``T_*0_s2``, ``T_*0_s3``… of the
        later segments of the data, see :meth:`RCModel.segmented`)."""
        return _T0.fullmatch(self.name) is not None

    def replace(self, **changes) -> Parameter:
        """Return a copy with fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


_T0 = re.compile(r"T_\w+0(_s\d+)?")
#: resistances [K/W] and capacities [J/K]: positive
_POSITIVE = re.compile(r"[RC]_\w+")
#: fractions [-]: within [0, 1], except the share of electricity use (and its numbered copies)
_FRACTION = re.compile(r"fra_\w+")
_FREE_FRACTION = re.compile(r"fra_ele\d*")

# Name-specific default guesses (SI), refined within a prefix. The capacities on the boundaries
# (C_bou, C_gro, and C_* of any other name) are chosen so that, with their resistances, no two of
# them nor the envelope (C_wal with R_wal) share a time constant C·R at the defaults: two
# capacities hanging off the zone with the same time constant leave a mode of the network that the
# zone temperature never sees, so their initial states could not be told apart from the data.
_DEFAULTS = {
    "C_zon": 2e6,
    "C_wal": 2e7,
    "C_int": 1e7,
    "C_bou": 6e6,
    "C_gro": 8e6,
    "C_emb": 5e6,
    "C_hea": 1e5,
    "C_sen": 1e5,
    "R_wal": 1e-2,
    "R_int": 2e-3,
    "R_inf": 3e-2,
    "R_bou": 2e-2,
    "R_gro": 2e-2,
    "R_emb": 2e-3,
}

# (regex, unit, default, lower, upper, description template)
NAMING: tuple[tuple[str, str, float, float, float, str], ...] = (
    (r"T_\w+0", "°C", 20.0, -3.0, 37.0, "initial temperature of state {}"),
    (r"R_\w+", "K/W", 1e-2, 1e-5, 10.0, "thermal resistance {}"),
    (r"C_\w+", "J/K", 1e7, 1e4, 1e10, "heat capacity {}"),
    (r"gA(_\w+)?", "m²", 2.0, 0.0, 50.0, "solar aperture {}"),
    (r"fra_ele", "-", 1.0, 0.0, 3.0, "fraction of electricity use released as internal gains"),
    (r"fra_\w+", "-", 0.5, 0.0, 1.0, "fraction {}"),
    (r"Q_\w+", "W", 0.0, -1e4, 1e4, "constant heat input {}"),
)


#: The heat-loss coefficient [W/K] of the largest building the naming defaults and bounds suit
#: (a large house, a small office: R_wal 1e-2 K/W is 100 W/K, and a capacity of 1e10 J/K with
#: it a time constant of 280 h). A larger building's parameters lie outside them (its
#: constant gains beyond 1e4 W, its masses beyond 1e10 J/K): see :func:`scaled_parameter`.
REFERENCE_HLC = 1000.0

_SCALES = (("R_", -1), ("C_", 1), ("Q_", 1), ("gA", 1))


def scaled_parameter(spec: Parameter, s: float) -> Parameter:
    """``spec`` for a building ``s`` times as large: conductances, capacities, constant heat
    inputs and solar apertures ``s`` times, so resistances ``R_*`` (default and bounds) divided
    by ``s``, capacities ``C_*``, heat inputs ``Q_*`` and apertures ``gA*`` multiplied by it;
    every other parameter (temperatures, fractions) unchanged.

    The same data with every heat input ``s`` times as large are then fitted by the same
    temperatures: the problem, in the fit's scaled coordinates, is the same.

    Raises:
        ModelError: ``s`` not a finite number > 0.
    """
    if not (isinstance(s, int | float) and math.isfinite(s) and s > 0):
        raise ModelError(f"scale of {spec.name!r} must be a finite number > 0, got {s!r}")
    power = next((k for prefix, k in _SCALES if spec.name.startswith(prefix)), 0)
    if power == 0 or s == 1.0:
        return spec
    f = float(s) ** power
    lo, hi = sorted((spec.lower * f, spec.upper * f))
    return spec.replace(default=spec.default * f, lower=lo, upper=hi)


def parameter_for(name: str, description: str | None = None) -> Parameter:
    """The default :class:`Parameter` for ``name`` by the naming convention.

    Raises:
        ModelError: when ``name`` follows none of the prefixes ``R_``, ``C_``, ``gA``, ``fra_``,
            ``T_*0``, ``Q_``.
    """
    for pattern, unit, default, lower, upper, text in NAMING:
        if re.fullmatch(pattern, name):
            default = _DEFAULTS.get(name, default)
            if pattern.startswith("T_"):
                text = text.format(name[2:-1])
            elif "{}" in text:
                text = text.format(name.split("_", 1)[1] if "_" in name else name)
            return Parameter(name, unit, default, lower, upper, description or text)
    raise ModelError(
        f"parameter name {name!r} follows no naming convention (R_* K/W, C_* J/K, gA* m², "
        "fra_* -, T_*0 °C, Q_* W); rename it or pass an explicit Parameter for it"
    )
