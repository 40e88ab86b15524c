"""Physical plausibility of the signals in the periods actually used for identification and
validation.

:func:`check_plausibility` looks at every canonical column of a dataset (or of a slice of it)
and refuses values that no building produces or that betray a unit or sensor problem:

* ``infinite`` / ``absurd`` — an infinity or a magnitude beyond :data:`~jaxbox.data._checks.ABSURD`
  (logger error codes such as ``1e300``);
* ``kelvin`` — temperatures about 273 K above the plausible range, in the whole column or only
  in part of it (a logger that switched units);
* ``fahrenheit`` — a column mostly above the plausible range but plausible in °F, or a zone
  temperature whose median is above 40 °C (°F in part of a column is a ``range`` error that
  says so);
* ``range`` — values outside the plausible range of their kind (:data:`PLAUSIBLE_RANGES`,
  overridable per column with ``overrides={column: (lo, hi)}``);
* ``jump`` — a temperature whose median over 11 samples changes by more than 20 K from one
  sample to the next, one-sided at the first and last samples: a change of unit (an offset
  near 273.15 K: ``kelvin``; a factor near 1.8: ``fahrenheit``) or of sensor is an error; an
  outdoor temperature that stays within its plausible range is weather (a front), a warning;
* ``spike`` — isolated samples far from their neighbours: for a temperature, farther than
  ``max(5 K, spike_k · σ)`` from the median of the 5 samples around it (a Hampel filter; σ is
  the robust standard deviation ``1.4826 · MAD`` of the sample-to-sample differences); for a
  power, more than 20 times the 99th percentile of its magnitudes;
* ``stuck`` — a temperature that does not change at all for ``stuck_hours`` (24 h) or more;
* ``counter`` — a power column that never falls and rises in most samples over at least half
  a day: a cumulative energy meter (kWh…) rather than a power (load it with ``counters=``);
* ``kilowatt`` — heating power that looks like kW (see below);
* ``sign`` — a heating column negative at almost every non-zero sample: heat taken out of the
  zone (cooling), or heating logged with the opposite sign? (a warning: ``scale=-1`` flips it).

**The kW heuristic.** A heating column ``Q_hea*`` that is not zero but peaks below 50 W cannot
heat a building. When the data also hold a zone temperature ``T_zon*`` and ``T_amb`` whose mean
difference is at least 3 K, the mean heating power per kelvin of that difference, a lower
bound of the heat-loss coefficient when the heating covers the losses (solar and internal gains
only add to it), is computed: below 1 W/K (no building loses so little) the column is refused
as kW; otherwise, or without those temperatures, a warning is given. A column peaking between
50 W and 1 kW is refused as kW too when that mean is below 5 W/K (a large building logged in
kW: an office whose boiler peaks at 158 kW and averages 1.7 kW per K). Declaring the range of the
column with ``overrides`` (e.g. ``{"Q_hea": (0, 40)}`` for a small test cell) turns the
heuristic off. Irradiance that peaks below 1.5 W/m² over at least a day gives a warning
(kW/m²?).

Every refusal raises :class:`~jaxbox.data.DataError` naming the column, the first time stamps
and their count, and what to do (with the Python keyword and the command-line option). Every
judgement of plausibility (:data:`ALLOWABLE`) can be overridden where the data are right:
``allow={"T_zon": "jump"}`` (command line ``--allow T_zon=jump``) turns that refusal into a
warning.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import math
import warnings
from collections.abc import Callable, Iterable, Mapping
from typing import NamedTuple

import numpy as np
import pandas as pd

from ._args import check_mapping
from ._checks import ABSURD, ABSURD_OTHER, rows_text
from ._counters import rising_share
from ._errors import DataError, DataWarning, list_names
from ._signals import CONSTANT, is_temperature, signal_base, signal_unit

__all__ = [
    "ALLOWABLE",
    "PLAUSIBLE_RANGES",
    "STUCK_HOURS",
    "Finding",
    "allowing",
    "check_plausibility",
    "edge_samples",
    "trim_edges",
    "find_implausible",
    "plausible_range",
]

#: Plausible range (lo, hi) per canonical base name, in the canonical unit (°C, W, W/m²).
PLAUSIBLE_RANGES: dict[str, tuple[float, float]] = {
    "T_zon": (-30.0, 60.0),
    "T_amb": (-60.0, 60.0),
    "T_bou": (-50.0, 80.0),
    "T_cel": (-30.0, 50.0),
    "T_gro": (-40.0, 60.0),
    "T_sup": (-50.0, 80.0),
    "I_glo_hor": (-50.0, 1600.0),
    "I_dif_hor": (-50.0, 1000.0),
    "I_n": (-50.0, 1600.0),
    "I_e": (-50.0, 1600.0),
    "I_s": (-50.0, 1600.0),
    "I_w": (-50.0, 1600.0),
    "Q_hea": (-1e7, 1e7),
    "Q_ven": (-1e7, 1e7),
    "P_ele": (-1e7, 1e7),
}

_KELVIN = 273.15
#: A zone temperature whose median is above this [°C] is taken to be in °F.
_ZONE_MEDIAN_MAX = 40.0
#: A temperature changing level by more than this [K] from one sample to the next has jumped.
_JUMP_K = 20.0
#: A jump within this [K] of 273.15 K, or of the °C/°F conversion, is a change of unit.
_UNIT_TOLERANCE_K = 3.0
#: ... as the medians of this many samples before and after.
_JUMP_SAMPLES = 11
#: Smallest deviation [K] of a temperature from its neighbours that counts as a spike.
_SPIKE_FLOOR_K = 5.0
#: A power sample above this multiple of the 99th percentile of the magnitudes is a spike.
_POWER_SPIKE_FACTOR = 20.0
#: A heating column peaking below this [W] may be in kW.
_KW_PEAK = 50.0
#: A temperature that does not change for this many hours is a stuck sensor (default).
STUCK_HOURS = 24.0
#: Below this heat-loss coefficient [W/K] (mean heating / mean T_zon - T_amb) it is in kW.
_KW_UA = 1.0
#: A heating column peaking below this [W] (but above ``_KW_PEAK``) whose mean per K of
#: zone-ambient difference is below ``_KW_UA_MEAN`` [W/K] is in kW too.
_KW_PEAK_MEAN = 1000.0
_KW_UA_MEAN = 5.0
#: Heating above this peak [W], or above this mean per K of zone-ambient difference [W/K], is
#: more than a building zone takes (mW?).
_MW_PEAK = 1e6
_MW_UA = 2e4
#: An irradiance whose peak changes by a factor within this range at a sample, with at least
#: this many samples and hours on each side, may have changed unit (W/m² and kW/m²).
_SCALE_FACTOR = (300.0, 3000.0)
_SCALE_MIN_SAMPLES = 12
_SCALE_MIN_HOURS = 24.0
#: An outdoor temperature this much [K] warmer than the heated zone on average may be in °F.
_WARM_OUTSIDE_K = 5.0
#: ... judged on at least this many samples (and a tenth of them) with the heating on.
_WARM_MIN_SAMPLES = 12
#: Smallest mean zone-ambient difference [K] for the kW test.
_KW_DELTA_T = 3.0
#: An irradiance peaking below this [W/m²] over a day or more may be in kW/m².
_KW_IRRADIANCE = 1.5
#: A power column is judged as an energy counter (:func:`._counters.rising_share`) when it
#: spans this many hours and samples.
_COUNTER_HOURS = 12.0
_COUNTER_MIN_SAMPLES = 12
#: A first or last temperature sample off the straight line through its two neighbours by more
#: than max(_EDGE_FLOOR_K, _EDGE_K · σ) [K] (σ: the robust scatter of the same deviation over
#: the other samples) is a partial interval.
_EDGE_FLOOR_K = 0.2
_EDGE_K = 8.0
_EDGE_MIN_SAMPLES = 8
#: A heating column negative at this share of at least this many non-zero samples is flagged.
_SIGN_SHARE = 0.95
_SIGN_MIN_SAMPLES = 10

_WINDOWS = "choose periods without them (--train/--validate; Dataset.slice)"


@dataclasses.dataclass(frozen=True)
class Finding:
    """One implausible observation in one column.

    Attributes:
        column: the column concerned.
        kind: ``infinite``, ``absurd``, ``kelvin``, ``fahrenheit``, ``range``, ``jump``,
            ``spike``, ``stuck``, ``kilowatt`` (see :mod:`jaxbox.data._plausible`).
        message: the problem, where, and what to do, in one line.
        severe: True for an error, False for a warning.
    """

    column: str
    kind: str
    message: str
    severe: bool = True


def _overrides(overrides: object, names: Iterable[str]) -> dict[str, tuple[float, float]]:
    """Validate ``overrides`` (column or canonical base name -> (lo, hi))."""
    given = check_mapping(overrides, "overrides", "{'T_zon': (-10, 90)}")
    names = list(names)
    out = {}
    for key, pair in given.items():
        key = str(key)
        if key not in names and key not in PLAUSIBLE_RANGES:
            raise DataError(
                f"overrides names {key!r}, which is neither a column nor a canonical name; "
                f"columns: {list_names(names)}."
            )
        try:
            lo, hi = (float(v) for v in pair)
        except (TypeError, ValueError):
            lo = hi = float("nan")
        if not lo < hi:
            raise DataError(
                f"overrides[{key!r}] must be a pair (lo, hi) with lo < hi, got {pair!r}."
            )
        out[key] = (lo, hi)
    return out


def plausible_range(
    name: str, overrides: Mapping[str, tuple[float, float]] | None = None
) -> tuple[float, float] | None:
    """Plausible (lo, hi) of column ``name`` in its canonical unit: ``overrides[name]``, else
    ``overrides`` of its base name (``"T_zon"`` for ``"T_zon2"``), else
    :data:`PLAUSIBLE_RANGES`; ``None`` for a column that is not canonical."""
    overrides = overrides or {}
    if name in overrides:
        return tuple(overrides[name])  # type: ignore[return-value]
    base = signal_base(name)
    if base is None:
        return None
    return tuple(overrides.get(base, PLAUSIBLE_RANGES[base]))  # type: ignore[return-value]


#: The refusals that ``allow`` (``--allow``) turns into warnings: every judgement of
#: plausibility. Infinite and absurd values (logger error codes) are not data: set them to NaN.
ALLOWABLE = ("kelvin", "fahrenheit", "range", "jump", "spike", "stuck", "counter", "kilowatt")

#: the allowances of the checks run in this context (:func:`allowing`)
_ALLOWED: contextvars.ContextVar[frozenset] = contextvars.ContextVar(
    "jaxbox_allowed", default=frozenset()
)


def _allow_hint(column: str, kind: str) -> str:
    return f"if the data are right, pass allow={{{column!r}: {kind!r}}} (--allow {column}={kind})"


def parse_allow(allow: object) -> frozenset[tuple[str | None, str]]:
    """``allow`` as a set of ``(column or None for every column, kind)``. It takes a kind
    (``"jump"``), ``"COLUMN=KIND"`` (``"T_zon=jump"``), a sequence of those, or a mapping
    ``{column: kind or kinds}``; kinds are those of :data:`ALLOWABLE`."""
    if allow is None:
        return frozenset()
    if isinstance(allow, str):
        items: list[tuple[str | None, str]] = [_allow_item(allow)]
    elif isinstance(allow, Mapping):
        items = []
        for column, kinds in allow.items():
            for kind in [kinds] if isinstance(kinds, str) else list(kinds):
                items.append(_allow_item(f"{column}={kind}"))
    elif isinstance(allow, Iterable):
        items = [_allow_item(a) for a in allow]
    else:
        raise TypeError(
            f"allow takes a kind, 'COLUMN=KIND', a list of those or {{column: kind}}, got "
            f"{type(allow).__name__}"
        )
    return frozenset(items)


def _allow_item(text: object) -> tuple[str | None, str]:
    if isinstance(text, tuple) and len(text) == 2:  # (column or None, kind): parsed already
        column, kind = text
        if column is not None and not isinstance(column, str):
            raise TypeError(f"allow: expected a kind or 'COLUMN=KIND', got {text!r}")
        text = f"{column or ''}={kind}"
    if not isinstance(text, str):
        raise TypeError(f"allow: expected a kind or 'COLUMN=KIND', got {text!r}")
    column, _, kind = text.rpartition("=")
    kind = kind.strip()
    if kind not in ALLOWABLE:
        raise DataError(
            f"allow: {kind!r} is not a check that can be allowed; give one of "
            f"{', '.join(ALLOWABLE)} (command line: --allow KIND or --allow COLUMN=KIND)."
        )
    return (column.strip() or None, kind)


@contextlib.contextmanager
def allowing(allow: object):
    """Within the block, :func:`check_plausibility` also allows ``allow`` (as its argument
    ``allow``), e.g. for the checks a :class:`~jaxbox.select.GreyBox` runs."""
    token = _ALLOWED.set(_ALLOWED.get() | parse_allow(allow))
    try:
        yield
    finally:
        _ALLOWED.reset(token)


def _allowed(finding: Finding, allowed: frozenset) -> bool:
    return (
        (None, finding.kind) in allowed
        or (finding.column, finding.kind) in allowed
        or (
            signal_base(finding.column),
            finding.kind,
        )
        in allowed
    )


# -- one small function per check; each returns the findings of one column -----------------------


@dataclasses.dataclass(frozen=True)
class _Column:
    """What every check needs to know about one column."""

    name: str
    x: np.ndarray
    index: pd.DatetimeIndex
    lo: float
    hi: float
    unit: str
    overridden: bool

    @property
    def temperature(self) -> bool:
        return self.unit == "°C"

    @property
    def power(self) -> bool:
        return self.unit == "W"

    def rows(self, mask: np.ndarray) -> str:
        return rows_text(self.index, mask)

    def override_hint(self) -> str:
        return f"overrides={{{self.name!r}: (lo, hi)}} (--range {self.name}=LO:HI)"


class _Options(NamedTuple):
    """The tolerances of :func:`check_plausibility`."""

    stuck_hours: float | None
    spike_k: float


def _infinite(c: _Column, frame: pd.DataFrame, opts: _Options) -> list[Finding]:
    bad = np.isinf(c.x)
    if not bad.any():
        return []
    return [
        Finding(
            c.name,
            "infinite",
            f"column {c.name!r} has infinite values {c.rows(bad)}; set them to NaN and fill the "
            f"gap, or {_WINDOWS}.",
        )
    ]


def _absurd(c: _Column, frame: pd.DataFrame, opts: _Options) -> list[Finding]:
    limit = ABSURD if signal_base(c.name) is not None else ABSURD_OTHER
    with np.errstate(invalid="ignore"):
        bad = np.abs(c.x) > limit
    if not bad.any():
        return []
    first = float(c.x[np.flatnonzero(bad)[0]])
    return [
        Finding(
            c.name,
            "absurd",
            f"column {c.name!r} has absurd values (e.g. {first:.3g}) {c.rows(bad)}: a logger "
            f"error code? set them to NaN and fill the gap, or {_WINDOWS}.",
        )
    ]


def _in(values: np.ndarray, lo: float, hi: float) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        return (values >= lo) & (values <= hi)


def _kelvin(c: _Column, frame: pd.DataFrame, opts: _Options) -> list[Finding]:
    if not c.temperature:
        return []
    with np.errstate(invalid="ignore"):
        bad = (c.x > c.hi) & _in(c.x - _KELVIN, c.lo, c.hi)
    if not bad.any():
        return []
    finite = np.isfinite(c.x)
    part = "" if bad.sum() == finite.sum() else f"{int(bad.sum())} of {int(finite.sum())} "
    return [
        Finding(
            c.name,
            "kelvin",
            f"{part}values of {c.name!r} look like kelvin (about 273 above °C) {c.rows(bad)}; "
            f"convert them to °C (subtract 273.15) before loading, or {_WINDOWS}; "
            f"{_allow_hint(c.name, 'kelvin')}.",
        )
    ]


def _fahrenheit_like(c: _Column) -> np.ndarray:
    """Samples above the range that would be in range read as °F."""
    with np.errstate(invalid="ignore"):
        return (c.x > c.hi) & _in((c.x - 32.0) / 1.8, c.lo, c.hi)


def _fahrenheit(c: _Column, frame: pd.DataFrame, opts: _Options) -> list[Finding]:
    """The whole column in °F: most samples too warm but plausible in °F, or a zone median
    above 40 °C."""
    if not c.temperature:
        return []
    finite = c.x[np.isfinite(c.x)]
    if finite.size == 0:
        return []
    median = float(np.median(finite))
    most = _fahrenheit_like(c).sum() > finite.size / 2
    zone_hot = signal_base(c.name) == "T_zon" and not c.overridden and median > _ZONE_MEDIAN_MAX
    if not most and not zone_hot:
        return []
    return [
        Finding(
            c.name,
            "fahrenheit",
            f"{c.name!r} looks like °F (median {median:.4g}, too warm for °C); load it with "
            f"units={{{c.name!r}: 'degF'}} (command line: --unit {c.name}=degF), or declare its "
            f"range with {c.override_hint()}.",
        )
    ]


def _factor_into_range(c: _Column) -> float | None:
    """The power of 1000 (1e-3, 1e-6, 1e3, 1e6) that brings every finite sample of a power or
    irradiance into its plausible range with a peak above a tenth of the range's top (W/m²
    logged ×1000, heating in mW…), or ``None``."""
    if c.unit not in ("W", "W/m²"):
        return None
    finite = c.x[np.isfinite(c.x)]
    if finite.size == 0:
        return None
    for factor in (1e-3, 1e-6, 1e3, 1e6):
        scaled = finite * factor
        if np.all(_in(scaled, c.lo, c.hi)) and np.max(np.abs(scaled)) > 0.1 * _typical_peak(c):
            return factor
    return None


def _typical_peak(c: _Column) -> float:
    """A peak a column of its kind reaches in a building's data (W/m² of sun, W of heating)."""
    return 1000.0 if c.unit == "W/m²" else 2000.0


def _range(c: _Column, frame: pd.DataFrame, opts: _Options) -> list[Finding]:
    with np.errstate(invalid="ignore"):
        bad = (c.x < c.lo) | (c.x > c.hi)
    if not bad.any():
        return []
    hits = c.x[bad]
    factor = _factor_into_range(c)
    if factor is not None:
        hint = (
            f" (a unit off by {1 / factor:g}? then pass scale={{{c.name!r}: {factor:g}}} "
            f"(--scale {c.name}={factor:g}))"
        )
    elif c.unit != "°C":
        hint = " (a unit off by a factor? scale=, --scale)"
    elif np.all(_fahrenheit_like(c)[bad]):
        hint = " (°F in part of it? convert those to °C)"
    else:
        hint = ""
    return [
        Finding(
            c.name,
            "range",
            f"{c.name!r} leaves its plausible range {c.lo:g} … {c.hi:g} {c.unit} (min "
            f"{np.min(hits):.4g}, max {np.max(hits):.4g}) {c.rows(bad)}{hint}; check the "
            f"mapping (columns=, --map), fix those samples or {_WINDOWS}; if right, widen it: "
            f"{c.override_hint()}.",
        )
    ]


def _unit_change(before: float, after: float) -> str | None:
    """What turns the level ``before`` into ``after`` [°C or whatever was logged], if it is a
    change of unit: ``"kelvin"`` (an offset near ±273.15 K), ``"fahrenheit"`` (``after`` near
    ``1.8 · before + 32`` or the reverse), else ``None``."""
    if abs(abs(after - before) - _KELVIN) < _UNIT_TOLERANCE_K:
        return "kelvin"
    for a, b in ((before, after), (after, before)):
        if abs(b - (1.8 * a + 32.0)) < max(_UNIT_TOLERANCE_K, 0.05 * abs(b)):
            return "fahrenheit"
    return None


def _local_step(x: np.ndarray, i: int) -> float:
    """The mean of the (up to) 3 samples from ``i`` less that of the 3 before: where exactly
    a level changes (the medians over 11 samples see it at several boundaries around)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all NaN on one side
        step = float(np.nanmean(x[i : i + 3]) - np.nanmean(x[max(0, i - 3) : i]))
    return step if math.isfinite(step) else 0.0


def _jump(c: _Column, frame: pd.DataFrame, opts: _Options) -> list[Finding]:
    """Level changes of a temperature: the median of the (up to) 11 samples after a sample
    boundary against that of the 11 before, one-sided at the ends (a first or last sample off
    its neighbours is a jump of one sample). A change of unit (an offset near 273.15 K, a
    factor near 1.8) is an error; an outdoor temperature that changes steeply but stays within
    its plausible range (the range check ran first) is weather: a warning; a jump of any other
    temperature is an error (a change of sensor?) that ``allow`` can keep."""
    if not c.temperature or len(c.x) < 6:
        return []
    s = pd.Series(c.x)
    w = _JUMP_SAMPLES
    before = s.rolling(w, min_periods=1).median().to_numpy()  # median of x[i-w+1..i]
    after = s[::-1].rolling(w, min_periods=1).median().to_numpy()[::-1]  # of x[i..i+w-1]
    step = np.full(len(c.x), np.nan)
    step[1:] = after[1:] - before[:-1]
    with np.errstate(invalid="ignore"):
        bad = np.abs(step) > _JUMP_K
    if not bad.any():
        return []
    # one boundary per run of neighbouring boundaries: where the step is largest
    runs = np.split(np.flatnonzero(bad), np.flatnonzero(np.diff(np.flatnonzero(bad)) > 1) + 1)
    weather = []
    n = len(c.x)
    for run in runs:
        i = int(run[np.argmax([abs(_local_step(c.x, k)) for k in run])])
        if i < 3:
            where = f"between {c.index[i - 1]} and {c.index[i]} (its first {i} sample(s))"
        elif n - i < 3:
            where = f"between {c.index[i - 1]} and {c.index[i]} (its last {n - i} sample(s))"
        else:
            where = f"between {c.index[i - 1]} and {c.index[i]} and stays there"
        # the unit is judged on the two samples either side (the level of the weather moves
        # less between them than over 11)
        unit = _unit_change(float(c.x[i - 1]), float(c.x[i])) or _unit_change(
            float(before[i - 1]), float(after[i])
        )
        if unit is not None:
            what = "°C to K or back" if unit == "kelvin" else "°C to °F or back"
            return [
                Finding(
                    c.name,
                    unit,
                    f"{c.name!r} jumps by {step[i]:+.3g} K {where}: a change of unit ({what}); "
                    "convert that part before loading, or use the periods on one side of it "
                    f"(--train/--validate; Dataset.slice); {_allow_hint(c.name, unit)}.",
                )
            ]
        if signal_base(c.name) != "T_amb" or i < 3 or n - i < 3:
            return [
                Finding(
                    c.name,
                    "jump",
                    f"{c.name!r} jumps by {step[i]:+.3g} K {where}: a change of sensor? fix the "
                    "data before loading, or use the periods on one side of it "
                    f"(--train/--validate; Dataset.slice); {_allow_hint(c.name, 'jump')}.",
                )
            ]
        weather.append(
            Finding(
                c.name,
                "jump",
                f"{c.name!r} changes by {step[i]:+.3g} K {where} (medians of {w} samples), "
                "within its plausible range: kept as weather (a front); if it is a change of "
                "sensor, use the periods on one side of it (--train/--validate).",
                severe=False,
            )
        )
    return weather[:1]


def _robust_sigma(values: np.ndarray) -> float:
    values = values[np.isfinite(values)]
    if values.size == 0:
        return 0.0
    return 1.4826 * float(np.median(np.abs(values - np.median(values))))


def _spike(c: _Column, frame: pd.DataFrame, opts: _Options) -> list[Finding]:
    if len(c.x) < 5:
        return []
    if c.temperature:
        median = pd.Series(c.x).rolling(5, center=True, min_periods=3).median().to_numpy()
        threshold = max(_SPIKE_FLOOR_K, opts.spike_k * _robust_sigma(np.diff(c.x)))
        with np.errstate(invalid="ignore"):
            bad = np.abs(c.x - median) > threshold
        size = f"more than {threshold:.3g} K from their neighbours"
    elif c.power:
        magnitude = np.abs(c.x[np.isfinite(c.x)])
        level = float(np.quantile(magnitude, 0.99)) if magnitude.size else 0.0
        if level <= 0:
            return []
        with np.errstate(invalid="ignore"):
            bad = np.abs(c.x) > _POWER_SPIKE_FACTOR * level
        if bad.sum() > 0.01 * len(c.x):
            return []
        size = f"above {_POWER_SPIKE_FACTOR:g}× its 99th percentile {level:.4g} W"
    else:
        return []
    if not bad.any():
        return []
    first = float(c.x[np.flatnonzero(bad)[0]])
    return [
        Finding(
            c.name,
            "spike",
            f"{c.name!r} has isolated spikes {size} (e.g. {first:.4g}) {c.rows(bad)}; set them "
            f"to NaN and interpolate before loading, or {_WINDOWS}; "
            f"{_allow_hint(c.name, 'spike')}.",
        )
    ]


def _stuck(c: _Column, frame: pd.DataFrame, opts: _Options) -> list[Finding]:
    if not c.temperature or opts.stuck_hours is None or len(c.x) < 3:
        return []
    same = np.diff(c.x) == 0.0
    if not same.any():
        return []
    # runs of equal neighbours: start/end positions of each run of True in ``same``
    edges = np.diff(np.concatenate([[0], same.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # samples s..e
    hours = np.asarray((c.index[ends] - c.index[starts]) / pd.Timedelta(hours=1), dtype=float)
    long = np.flatnonzero((hours >= opts.stuck_hours) & (ends - starts >= 2))
    if long.size == 0:
        return []
    k = int(long[np.argmax(hours[long])])
    s, e = int(starts[k]), int(ends[k])
    return [
        Finding(
            c.name,
            "stuck",
            f"{c.name!r} stays exactly at {c.x[s]:.4g} °C for {hours[k]:.3g} h, from "
            f"{c.index[s]} to {c.index[e]}: a stuck or disconnected sensor? choose periods where "
            "it moves (--train/--validate; Dataset.slice) or, if the sensor is right (a coarse "
            "one in a steady room), raise the tolerance (stuck_hours=, --stuck-hours H; none "
            "turns the check off).",
        )
    ]


def _counter(c: _Column, frame: pd.DataFrame, opts: _Options) -> list[Finding]:
    """A power that never falls and rises at most samples: a cumulative energy meter."""
    if not c.power or c.overridden:
        return []
    ok = np.isfinite(c.x)
    x = c.x[ok]
    if x.size < _COUNTER_MIN_SAMPLES:
        return []
    hours = (c.index[ok][-1] - c.index[ok][0]) / pd.Timedelta(hours=1)
    rising = rising_share(x)
    if hours < _COUNTER_HOURS or rising is None:
        return []
    return [
        Finding(
            c.name,
            "counter",
            f"{c.name!r} never falls and rises in {100 * rising:.0f} % of its samples (from "
            f"{x[0]:.6g} at {c.index[ok][0]} to {x[-1]:.6g} at {c.index[ok][-1]}): a cumulative "
            "energy meter, not a power? load it with counters={"
            f"{c.name!r}: 'kWh'}} (--counter {c.name}=kWh; or MWh, Wh, J, MJ) to turn it into "
            f"the mean power of each interval; if it is a power, declare its range with "
            f"{c.override_hint()}.",
        )
    ]


def _zone_ambient_delta(frame: pd.DataFrame) -> float | None:
    """Mean difference [K] of the zones' mean temperature over ``T_amb``, or ``None`` without
    a zone or ``T_amb``."""
    zones = [n for n in frame.columns if signal_base(str(n)) == "T_zon"]
    if not zones or "T_amb" not in frame.columns:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a sample with no zone temperature
        zone = np.nanmean(frame[zones].to_numpy(dtype=float), axis=1)
        delta = float(np.nanmean(zone - frame["T_amb"].to_numpy(dtype=float)))
    return delta if math.isfinite(delta) else None


def _kilowatt(c: _Column, frame: pd.DataFrame, opts: _Options) -> list[Finding]:
    if c.overridden:
        return []
    base = signal_base(c.name)
    finite = c.x[np.isfinite(c.x)]
    if finite.size == 0:
        return []
    peak = float(np.max(np.abs(finite)))
    if base and base.startswith("I_"):
        span = (c.index[-1] - c.index[0]) / pd.Timedelta(hours=1)
        if 0 < peak < _KW_IRRADIANCE and span >= 24:
            return [
                Finding(
                    c.name,
                    "kilowatt",
                    f"{c.name!r} peaks at {peak:.3g} W/m² over {span:.3g} h: in kW/m²? then "
                    f"pass units={{{c.name!r}: 'kW/m2'}} (command line: --unit {c.name}=kW/m2) "
                    f"or scale={{{c.name!r}: 1000}} (--scale {c.name}=1000).",
                    severe=False,
                )
            ]
        return []
    if base != "Q_hea" or peak == 0:
        return []
    delta = _zone_ambient_delta(frame)
    ua = None
    if delta is not None and delta >= _KW_DELTA_T:
        ua = float(np.nanmean(finite)) / delta
    if peak >= _KW_PEAK:
        # A large building logged in kW peaks above 50 "W" (an office's boiler at 158 kW);
        # below 1 kW the mean per K still tells: no zone a heater of that size serves loses
        # under 5 W/K.
        if not (peak < _KW_PEAK_MEAN and ua is not None and ua < _KW_UA_MEAN):
            return _milliwatt(c, frame, peak)
        factor, limit = 1000, _KW_UA_MEAN
    else:
        factor = 1000 if peak * 1000 >= _KW_PEAK else 1_000_000
        limit = _KW_UA
    unit = "kW" if factor == 1000 else "MW"
    fix = (
        f"pass units={{{c.name!r}: {unit!r}}} (command line: --unit {c.name}={unit}) or "
        f"scale={{{c.name!r}: {factor}}} (--scale {c.name}={factor})"
    )
    if ua is not None and ua < limit:
        return [
            Finding(
                c.name,
                "kilowatt",
                f"{c.name!r} looks like {unit}, not W: it peaks at {peak:.3g} and its mean per "
                f"K of zone-ambient difference is {ua:.3g} W/K, below any building's heat loss; "
                f"{fix}, or declare its range with {c.override_hint()}.",
            )
        ]
    return [
        Finding(
            c.name,
            "kilowatt",
            f"{c.name!r} peaks at only {peak:.3g} W: in {unit}? then {fix}.",
            severe=False,
        )
    ]


def _scale_change(c: _Column, frame: pd.DataFrame, opts: _Options) -> list[Finding]:
    """An irradiance whose peak before a sample and after it differ by a factor near 1000
    (300–3000), each side a day or more and at least 12 samples: logged in kW/m² in one part
    and W/m² in the other? A warning. Not for heating: heating that stops for good (the end of
    a season, a free-floating test) looks the same."""
    if c.overridden or c.unit != "W/m²" or len(c.x) < 2 * _SCALE_MIN_SAMPLES:
        return []
    magnitude = np.where(np.isfinite(c.x), np.abs(c.x), 0.0)
    before = np.maximum.accumulate(magnitude)[:-1]  # peak of x[:k + 1]
    after = np.maximum.accumulate(magnitude[::-1])[::-1][1:]  # peak of x[k + 1:]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = after / before  # ratio[k]: x[k + 1:] against x[:k + 1]
    # each side at least a day (a day and a night of sun) and _SCALE_MIN_SAMPLES samples
    hours = np.asarray((c.index - c.index[0]) / pd.Timedelta(hours=1), dtype=float)
    step = float(np.median(np.diff(hours)))  # each sample stands for an interval
    span_before = hours[:-1] - hours[0] + step
    span_after = hours[-1] - hours[1:] + step
    k_all = np.arange(len(ratio))
    sides = (
        (span_before >= _SCALE_MIN_HOURS)
        & (span_after >= _SCALE_MIN_HOURS)
        & (k_all + 1 >= _SCALE_MIN_SAMPLES)
        & (len(c.x) - k_all - 1 >= _SCALE_MIN_SAMPLES)
    )
    lo, hi = _SCALE_FACTOR
    scaled = ((ratio > lo) & (ratio < hi)) | ((ratio > 1 / hi) & (ratio < 1 / lo))
    hits = np.flatnonzero(scaled & sides)
    if hits.size == 0:
        return []
    k = int(hits[0]) + 1  # the first sample of the part after
    up = ratio[hits[0]] > 1
    fix = 0.001 if up else 1000
    return [
        Finding(
            c.name,
            "kilowatt",
            f"{c.name!r} peaks {'1000 times higher' if up else '1000 times lower'} from "
            f"{c.index[k]} on than before: a change of unit (W/m² and kW/m²)? scale that part "
            f"by {fix:g} before loading, or use the periods on one side of it "
            "(--train/--validate; Dataset.slice).",
            severe=False,
        )
    ]


def _milliwatt(c: _Column, frame: pd.DataFrame, peak: float) -> list[Finding]:
    """Heating that no single zone takes: a peak above 1 MW, or a mean above 20 kW per K of
    zone-ambient difference (mW, or W logged ×1000?): a warning."""
    delta = _zone_ambient_delta(frame)
    per_k = None
    if delta is not None and delta >= _KW_DELTA_T:
        per_k = float(np.nanmean(c.x)) / delta
    if peak <= _MW_PEAK and (per_k is None or per_k <= _MW_UA):
        return []
    why = f"peaks at {peak:.3g} W" + (
        f" and averages {per_k:.3g} W per K of zone-ambient difference" if per_k else ""
    )
    return [
        Finding(
            c.name,
            "kilowatt",
            f"{c.name!r} {why}, more than a building zone takes: in mW (or W logged ×1000)? "
            f"then pass scale={{{c.name!r}: 0.001}} (--scale {c.name}=0.001); if it is right, "
            f"declare its range with {c.override_hint()}.",
            severe=False,
        )
    ]


def _warm_outside(c: _Column, frame: pd.DataFrame, opts: _Options) -> list[Finding]:
    """An outdoor temperature warmer than the heated zone on average: °F read as °C? (a
    warning; winter °F values such as 20–45 lie within the plausible range of °C)."""
    if c.overridden or signal_base(c.name) != "T_amb":
        return []
    heating = [n for n in frame.columns if signal_base(str(n)) == "Q_hea"]
    zones = [n for n in frame.columns if signal_base(str(n)) == "T_zon"]
    if not heating or not zones:
        return []
    # judged where the heating runs (an office's nights and holidays are off)
    on = np.nansum(frame[heating].to_numpy(dtype=float), axis=1) > 0
    if on.sum() < max(_WARM_MIN_SAMPLES, 0.1 * on.size):
        return []
    delta = _zone_ambient_delta(frame[on])
    if delta is None or delta > -_WARM_OUTSIDE_K:
        return []
    return [
        Finding(
            c.name,
            "fahrenheit",
            f"{c.name!r} is on average {-delta:.3g} K warmer than the zone while the heating "
            f"runs: in °F? then load it with units={{{c.name!r}: 'degF'}} (command line: --unit "
            f"{c.name}=degF); or are the zone and outdoor columns swapped (check columns=, "
            f"--map)? If it is right, "
            f"declare its range with {c.override_hint()}.",
            severe=False,
        )
    ]


def _sign(c: _Column, frame: pd.DataFrame, opts: _Options) -> list[Finding]:
    """A heating power negative at almost every non-zero sample: cooling, or the wrong sign?"""
    if c.overridden or signal_base(c.name) != "Q_hea":
        return []
    x = c.x[np.isfinite(c.x) & (c.x != 0)]
    if x.size < _SIGN_MIN_SAMPLES:
        return []
    negative = float(np.mean(x < 0))
    if negative < _SIGN_SHARE:
        return []
    warmer = ""
    delta = _zone_ambient_delta(frame)
    if delta is not None and delta >= _KW_DELTA_T:
        warmer = f", while the zone is {delta:.3g} K warmer than outside on average"
    return [
        Finding(
            c.name,
            "sign",
            f"{c.name!r} is negative at {100 * negative:.0f} % of its non-zero samples (down to "
            f"{float(np.min(x)):.4g} W){warmer}: the models take it as heat put into the zone, so "
            f"this is cooling; if it is heating logged with the opposite sign, pass scale="
            f"{{{c.name!r}: -1}} (--scale {c.name}=-1).",
            severe=False,
        )
    ]


#: The checks in the order they run; after a column's first error its later checks are skipped.
_CHECKS: tuple[Callable[..., list[Finding]], ...] = (
    _infinite,
    _counter,
    _absurd,
    _kelvin,
    _fahrenheit,
    _range,
    _jump,
    _spike,
    _stuck,
    _kilowatt,
    _scale_change,
    _warm_outside,
    _sign,
)


def _frame_of(data: object) -> pd.DataFrame:
    frame = getattr(data, "_frame", None)
    if isinstance(frame, pd.DataFrame):
        return frame
    if isinstance(data, pd.DataFrame) and isinstance(data.index, pd.DatetimeIndex):
        return data
    raise TypeError(
        "check_plausibility takes a jaxbox Dataset (or a DataFrame with a DatetimeIndex), got "
        f"{type(data).__name__}; load the data with jaxbox.data.load first."
    )


def find_implausible(
    data: object,
    *,
    overrides: Mapping[str, tuple[float, float]] | None = None,
    columns: Iterable[str] | None = None,
    stuck_hours: float | None = STUCK_HOURS,
    spike_k: float = 10.0,
    allow: object = None,
) -> tuple[Finding, ...]:
    """Every implausible finding (errors and warnings) in ``data``, without raising.

    Arguments as in :func:`check_plausibility`. At most one error per column (its first); an
    allowed one is a warning beginning ``allowed:``; the later checks of the column are
    skipped after either.
    """
    allowed = parse_allow(allow) | _ALLOWED.get()
    frame = _frame_of(data)
    names = [str(n) for n in frame.columns]
    ranges = _overrides(overrides, names)
    if columns is None:
        chosen = [n for n in names if signal_base(n) is not None]
    else:
        chosen = [columns] if isinstance(columns, str) else [str(n) for n in columns]
        chosen = [n for n in chosen if n != CONSTANT or n in names]  # the virtual constant
        missing = [n for n in chosen if n not in names]
        if missing:
            raise DataError(
                f"no column {list_names(missing)} to check; available: {list_names(names)}."
            )
    index = pd.DatetimeIndex(frame.index).as_unit("ns")  # a DataFrame's may be in µs
    opts = _Options(stuck_hours=stuck_hours, spike_k=float(spike_k))
    findings: list[Finding] = []
    for name in chosen:
        rng = plausible_range(name, ranges)
        lo, hi = rng if rng is not None else (-math.inf, math.inf)
        column = _Column(
            name=name,
            x=frame[name].to_numpy(dtype=np.float64),
            index=index,
            lo=lo,
            hi=hi,
            unit=signal_unit(name) or "",
            overridden=name in ranges or signal_base(name) in ranges,
        )
        for check in _CHECKS:
            found = [
                dataclasses.replace(f, severe=False, message=f"allowed: {f.message}")
                if f.severe and _allowed(f, allowed)
                else f
                for f in check(column, frame, opts)
            ]
            findings += found
            # after a refusal, or a refusal allowed, the column's later checks are skipped
            if any(f.severe or f.message.startswith("allowed: ") for f in found):
                break
    return tuple(findings)


def check_plausibility(
    data: object,
    *,
    overrides: Mapping[str, tuple[float, float]] | None = None,
    columns: Iterable[str] | None = None,
    what: str | None = None,
    stuck_hours: float | None = STUCK_HOURS,
    spike_k: float = 10.0,
    warn: bool = True,
    allow: object = None,
) -> tuple[str, ...]:
    """Refuse physically implausible signals in ``data``; return the warnings.

    Call it on the data actually used: the identification window and the validation window
    (e.g. ``check_plausibility(ident, columns=model.inputs + model.outputs, what="identification
    data")``). The checks are listed in :mod:`jaxbox.data._plausible`: infinite and absurd
    values, temperatures in kelvin or °F (in all or part of a column), values outside the
    plausible range of their kind, jumps, spikes, stuck temperature sensors, heating power in
    kW.

    Args:
        data: a :class:`~jaxbox.data.Dataset` (or a slice of one).
        overrides: plausible range per column or canonical base name, ``{"T_zon": (-10, 90)}``
            (canonical units); replaces :data:`PLAUSIBLE_RANGES` for it and turns off the
            range-based unit heuristics (zone median in °F, heating in kW) for it.
        columns: the columns to check (default: every canonical column).
        what: names the data in the messages, e.g. ``"validation data"``.
        stuck_hours: a temperature constant for this long [h] is a stuck sensor (``None``: no
            check).
        spike_k: a temperature farther than ``max(5 K, spike_k · σ)`` from the median of its 5
            neighbours is a spike (σ: robust standard deviation of the sample differences).
        warn: also issue the warnings with :func:`warnings.warn` (:class:`DataWarning`).
        allow: refusals to turn into warnings, where the data are right though they look
            wrong: a kind of :data:`ALLOWABLE` (``"jump"``) for every column, ``"COLUMN=KIND"``,
            a list of those, or ``{column: kind}`` (command line: ``--allow``); also those of
            an enclosing :func:`allowing` block.

    Returns:
        The warnings (uncertain findings, such as a heating power that may be in kW), in words.

    Raises:
        DataError: the first implausible column, naming it, the first time stamps and their
            count, and what to do (Python keyword and command-line option); more problems are
            counted at the end of the message.
        TypeError: ``data`` is not a Dataset, or ``overrides`` is not a mapping.
    """
    findings = find_implausible(
        data,
        overrides=overrides,
        columns=columns,
        stuck_hours=stuck_hours,
        spike_k=spike_k,
        allow=allow,
    )
    prefix = f"{what}: " if what else ""
    errors = [f for f in findings if f.severe]
    if errors:
        others = sorted({f.column for f in errors[1:]})
        more = f" ({len(errors) - 1} more problem(s) in {list_names(others, 5)})" if others else ""
        raise DataError(prefix + errors[0].message + more)
    notes = tuple(prefix + f.message for f in findings if not f.severe)
    if warn:
        for note in notes:
            warnings.warn(note, DataWarning, stacklevel=2)
    return notes


# -- the first and last samples ------------------------------------------------------------------

#: what ``trim`` (``--trim``) takes
TRIM = ("auto", "none", "first", "last", "both")


def _edge_offset(x: np.ndarray, end: str) -> tuple[float, float] | None:
    """(deviation [K] of the ``end`` sample from the straight line through its two neighbours,
    the robust scatter σ [K] of that deviation over the other samples), or ``None`` where it
    cannot be judged (too few samples, a missing one at the edge)."""
    y = x if end == "last" else x[::-1]
    if len(y) < _EDGE_MIN_SAMPLES or not np.all(np.isfinite(y[-3:])):
        return None
    r = y[2:] - (2 * y[1:-1] - y[:-2])  # r[k]: the deviation of y[k + 2]
    sigma = _robust_sigma(r[:-1])
    return float(r[-1]), sigma


def edge_samples(
    data: object, columns: Iterable[str] | None = None
) -> dict[str, tuple[Finding, ...]]:
    """The first and last samples that look like partial intervals (a logger that wrote a mean
    over part of the interval, or a reading taken mid-interval): a temperature (of
    ``columns``, default every canonical temperature column) whose first or last sample lies
    off the straight line through its two neighbours by more than ``max(0.2 K, 8 σ)``, σ the
    robust scatter of the same deviation over the other samples (a one-sided rule: the spike
    and jump checks compare a sample with neighbours on both sides).

    Returns:
        ``{"first": findings, "last": findings}`` (kind ``edge``, warnings), each naming the
        column, the time stamp, the deviation and what to do.
    """
    frame = _frame_of(data)
    names = [str(n) for n in frame.columns]
    chosen = names if columns is None else [str(n) for n in columns if str(n) in names]
    out: dict[str, tuple[Finding, ...]] = {}
    for end in ("first", "last"):
        found = []
        for name in chosen:
            if not is_temperature(name):
                continue
            judged = _edge_offset(frame[name].to_numpy(dtype=np.float64), end)
            if judged is None:
                continue
            offset, sigma = judged
            limit = max(_EDGE_FLOOR_K, _EDGE_K * sigma)
            if abs(offset) <= limit:
                continue
            stamp = frame.index[-1 if end == "last" else 0]
            side = "before" if end == "last" else "after"
            found.append(
                Finding(
                    name,
                    "edge",
                    f"{name!r} at its {end} sample ({stamp}) is {offset:+.3g} K off the trend of "
                    f"the samples {side} it (more than {limit:.2g} K): a partial {end} interval "
                    "(a logger writing mid-interval)? drop it with trim='auto' or "
                    f"trim={end!r} (command line: --trim {end}; fit and select drop it by "
                    "default, --trim none keeps it), or --train/--validate.",
                    severe=False,
                )
            )
        out[end] = tuple(found)
    return out


def trim_edges(data, trim: str = "auto", columns: Iterable[str] | None = None):
    """``data`` without its partial first or last sample: ``trim="auto"`` drops those that
    :func:`edge_samples` flags, ``"first"``, ``"last"`` or ``"both"`` drop them anyway,
    ``"none"`` keeps everything.

    Returns:
        (the dataset, the notes on what was dropped and why).

    Raises:
        DataError: ``trim`` is not one of :data:`TRIM`.
    """
    if trim not in TRIM:
        raise DataError(
            f"trim must be one of {', '.join(TRIM)}, got {trim!r} (command line: --trim)."
        )
    if trim == "none" or len(data) < _EDGE_MIN_SAMPLES:
        return data, ()
    flagged = edge_samples(data, columns) if trim == "auto" else {}
    index = data.index
    drop_first = trim in ("first", "both") or bool(flagged.get("first"))
    drop_last = trim in ("last", "both") or bool(flagged.get("last"))
    notes = []
    for end, drop in (("first", drop_first), ("last", drop_last)):
        if not drop:
            continue
        stamp = index[0] if end == "first" else index[-1]
        why = flagged.get(end)
        if why:
            reason = why[0].message.split(": a partial")[0]
            notes.append(
                f"dropped the {end} sample ({stamp}): {reason}, a partial {end} interval? "
                "(--trim none keeps it)"
            )
    start = index[1] if drop_first else None
    end = index[-2] if drop_last else None
    return (data.slice(start, end) if drop_first or drop_last else data), tuple(notes)
