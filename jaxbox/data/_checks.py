"""Checks of time stamps and values; each failure raises a :class:`DataError` that names the
offending column, row or time stamp and says what to do.

Row positions are described by a ``where(i)`` callable supplied by the caller (for a CSV file it
gives the line number, for a DataFrame the position).
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable

import numpy as np
import pandas as pd

from ._counters import rising_share
from ._errors import DataError, DataWarning
from ._signals import is_temperature, signal_base, signal_unit

__all__ = [
    "Where",
    "check_finite",
    "check_kelvin",
    "check_order",
    "localize",
    "check_regular",
    "fill_missing_rows",
    "segment_slices",
    "irregular_position",
    "median_step",
    "parse_time",
    "rows_text",
    "to_float",
]

Where = Callable[[int], str]

_COMMA_NUMBER = re.compile(r"^\s*[-+]?\d*,\d+\s*$")
#: A number with its digits grouped in thousands (``1,234.5``, ``1.234,5``, ``1'234``).
_GROUPED_NUMBER = re.compile(r"^\s*[-+]?\d{1,3}(?:([,.' _])\d{3})+(?:([.,])\d+)?\s*$")

#: Relative tolerance on the sampling step (float seconds round to the nanosecond).
_STEP_RTOL = 1e-6
#: Relative tolerance of a whole number of steps (rows missing from a grid, a segment's cut).
_GRID_TOL = 1e-6
#: Absolute tolerance on the sampling step [s].
_STEP_ATOL = 1e-6
#: A temperature column with a median above this [°C] is taken to be in kelvin.
_KELVIN_MEDIAN = 150.0
#: Magnitude above which a value of a canonical signal (°C, W, W/m²) is absurd.
ABSURD = 1e9
#: Magnitude above which a value of any other column is absurd.
ABSURD_OTHER = 1e30


def _position(i: int) -> str:
    return f"row {i}"


def _seconds(delta: pd.Timedelta | np.timedelta64) -> float:
    return float(pd.Timedelta(delta) / pd.Timedelta(seconds=1))


def fmt_seconds(seconds: float) -> str:
    """Short human form of a duration given in seconds."""
    if seconds == int(seconds):
        seconds = int(seconds)
    return f"{seconds} s"


#: Units of a numeric time column: their length [s].
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "min": 60.0, "h": 3600.0, "D": 86400.0}
_UNIT_NAMES = {
    "s": "seconds",
    "ms": "milliseconds",
    "us": "microseconds",
    "ns": "nanoseconds",
    "min": "minutes",
    "h": "hours",
    "D": "days",
}
#: Years in which monitoring data plausibly lie, for guessing the unit of numeric time stamps.
_PLAUSIBLE_YEARS = (1980, 2070)
#: The epoch of spreadsheet serial dates (days since 1899-12-30).
SPREADSHEET_EPOCH = pd.Timestamp("1899-12-30")


def _years(first: float, last: float, unit: str, epoch: pd.Timestamp) -> tuple[float, float]:
    """The years (fractional) of the first and last numbers read in ``unit`` since ``epoch``."""
    base = epoch.year + (epoch.day_of_year - 1) / 365.25
    scale = TIME_UNITS[unit] / (365.25 * 86400.0)
    return base + first * scale, base + last * scale


def _unit_guess(first: float, last: float, step: float) -> str | None:
    """The option text of the first reading of numbers (``step``: their median difference) that
    puts them in plausible years with a plausible sampling step (0.1 s to a day)."""
    lo, hi = _PLAUSIBLE_YEARS
    candidates = [("D", SPREADSHEET_EPOCH)] + [
        (u, pd.Timestamp("1970-01-01")) for u in ("ms", "us", "ns", "min", "h")
    ]
    for unit, epoch in candidates:
        a, b = _years(first, last, unit, epoch)
        seconds = step * TIME_UNITS[unit]
        if lo <= a <= hi and lo <= b <= hi and (np.isnan(seconds) or 0.1 <= seconds <= 86400):
            if epoch == SPREADSHEET_EPOCH:
                return (
                    "days since 1899-12-30 (spreadsheet serial dates): pass time_unit='D', "
                    "epoch='1899-12-30' (command line: --time-unit D --epoch 1899-12-30)"
                )
            return (
                f"{_UNIT_NAMES[unit]} since 1970-01-01: pass time_unit='{unit}' (command line: "
                f"--time-unit {unit})"
            )
    return None


def _numeric_time(
    values: pd.Series, name: str, epoch: pd.Timestamp, unit: str, where: Where
) -> pd.Series:
    """Numbers of ``unit`` since ``epoch`` as time stamps; numbers that cannot be in that unit
    (beyond the years pandas holds, or past 2200) are refused and a suspicious reading (before
    1980 from the default epoch, where another unit gives plausible years) is a warning, both
    naming the unit the numbers look like."""
    if unit not in TIME_UNITS:
        raise DataError(
            f"unknown time_unit {unit!r}; use one of {', '.join(map(repr, TIME_UNITS))}."
        )
    numbers = values.to_numpy(dtype=np.float64, na_value=np.nan)
    bad = np.flatnonzero(~np.isfinite(numbers))
    if bad.size:
        i = int(bad[0])
        raise DataError(
            f"the time column {name!r} has no valid value at {where(i)} ({values.iloc[i]!r}); "
            "fill or drop that row."
        )
    first, last = float(np.min(numbers)), float(np.max(numbers))
    years = _years(first, last, unit, epoch)
    read = f"the numbers in the time column {name!r} read as {_UNIT_NAMES[unit]} since {epoch}"
    step = float(np.median(np.diff(numbers))) if numbers.size > 1 else float("nan")
    guess = _unit_guess(first, last, step)
    if max(years) > 2200 or min(years) < 1678:
        raise DataError(
            f"{read} reach the year {int(max(years) if max(years) > 2200 else min(years))}"
            + (f"; they look like {guess}." if guess else "; give the right time_unit= or epoch=.")
        )
    if years[0] < _PLAUSIBLE_YEARS[0] and epoch == pd.Timestamp("1970-01-01") and guess:
        warnings.warn(
            f"{read} start in {int(years[0])}; if they are {guess}.",
            DataWarning,
            stacklevel=5,
        )
    return pd.Series(epoch + pd.to_timedelta(numbers * TIME_UNITS[unit], unit="s"))


def parse_time(
    values: pd.Series,
    name: str,
    *,
    epoch: pd.Timestamp,
    where: Where = _position,
    unit: str = "s",
) -> pd.DatetimeIndex:
    """Turn a column of time stamps into a DatetimeIndex named ``time`` (nanosecond unit).

    Date-time strings (ISO 8601 or any format pandas can infer, day first where the order of
    the stamps says so) and datetime values are parsed as they are; numbers are ``unit`` (a key
    of :data:`TIME_UNITS`, default seconds) since ``epoch``.
    """
    if isinstance(values.dtype, pd.DatetimeTZDtype) or pd.api.types.is_datetime64_dtype(values):
        parsed = pd.Series(pd.DatetimeIndex(values))
    elif pd.api.types.is_bool_dtype(values):
        raise DataError(
            f"the time column {name!r} holds booleans; give date-time strings or seconds."
        )
    elif pd.api.types.is_numeric_dtype(values):
        parsed = _numeric_time(values, name, epoch, unit, where)
    else:
        parsed = _parse_strings(values, name)
    missing = np.flatnonzero(parsed.isna().to_numpy())
    if missing.size:
        i = int(missing[0])
        text = f"cannot parse the time stamp {values.iloc[i]!r} in column {name!r} at {where(i)}"
        text += f" ({missing.size} unparseable in all)" if missing.size > 1 else ""
        if str(values.iloc[i]).strip() == name:
            raise DataError(f"{text}: the header repeated (files joined?); drop those lines.")
        if missing.size == 1 and i == len(values) - 1 and len(values) > 2:
            raise DataError(f"{text}, the last row: a summary line? drop it.")
        raise DataError(
            f"{text}; use ISO 8601 ('2013-08-21 00:10:00') or parse the column yourself and pass "
            "a DataFrame with a DatetimeIndex."
        )
    index = pd.DatetimeIndex(parsed, name="time")
    return index.as_unit("ns")


def _parse_strings(values: pd.Series, name: str) -> pd.Series:
    text = values.astype("string")
    try:
        iso = pd.to_datetime(text, format="ISO8601", errors="coerce")
    except (ValueError, TypeError):
        iso = _one_offset(text, name)
    if not iso.isna().any():
        return iso
    clock = text.str.strip().str.fullmatch(r"\d{1,2}:\d\d(:\d\d(\.\d*)?)?\s*([aApP][mM])?")
    if clock.fillna(False).all():
        raise DataError(
            f"the time column {name!r} holds clock times without dates ({text.iloc[0]!r}); "
            f"join the column of dates to it: time=['your_date_column', {name!r}] (command "
            f"line: --time your_date_column,{name})."
        )
    # day first (31/01/2024) where that reading is the one whose order and steps make sense:
    # read month first, 02/01 is a month after 01/01 and the samples between are missing
    readings = []
    for dayfirst in (False, True):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                readings.append(pd.to_datetime(text, errors="coerce", dayfirst=dayfirst))
        except (ValueError, TypeError):
            continue
        if _disorder(readings[-1]) == (0, 0, 0):  # a regular series: no reading does better
            break
    if not readings:
        return iso
    inferred = min(readings, key=_disorder)
    return inferred if inferred.isna().sum() < iso.isna().sum() else iso


def _disorder(stamps: pd.Series) -> tuple[int, int, int]:
    """How badly parsed time stamps fit a time series: unparsed stamps, steps back, and steps
    other than the median step."""
    given = stamps.dropna()
    steps = np.diff(pd.DatetimeIndex(given).as_unit("ns").asi8)
    if steps.size == 0:
        return int(stamps.isna().sum()), 0, 0
    usual = np.median(steps)
    return int(stamps.isna().sum()), int(np.sum(steps <= 0)), int(np.sum(steps != usual))


def _one_offset(text: pd.Series, name: str) -> pd.Series:
    """Time stamps with several UTC offsets (local time across a daylight-saving change,
    ``…+02:00`` then ``…+01:00``), each an unambiguous instant: all at the offset of the first,
    so that the grid stays regular, with a :class:`DataWarning` naming the offsets."""
    given = text.dropna()
    suffix = given.str.strip().str.extract(_OFFSET, expand=False)
    if given.empty or suffix.isna().any():
        raise DataError(
            f"the time stamps in column {name!r} mix stamps with a UTC offset and stamps without "
            "one; give every stamp its offset (e.g. 2013-10-27 02:00:00+01:00) or none."
        )
    try:
        utc = pd.to_datetime(text, format="ISO8601", utc=True, errors="coerce")
        first = pd.Timestamp(str(given.iloc[0]).strip())
    except (ValueError, TypeError) as error:
        raise DataError(
            f"cannot read the time stamps in column {name!r} with their UTC offsets ({error}); "
            "convert them to one time zone (e.g. pd.to_datetime(..., utc=True)) and pass a "
            "DataFrame."
        ) from None
    shown = ", ".join(
        sorted({"+00:00" if o == "Z" else f"{o[:3]}:{o[-2:]}" for o in suffix.unique()})
    )
    warnings.warn(
        f"the time stamps in column {name!r} carry several UTC offsets ({shown}: a change to or "
        f"from daylight saving time?); they are taken at the offset of the first, "
        f"{offset_text(first.utcoffset())} (to keep local time, pass the time zone, e.g. "
        "tz='Europe/Berlin' (command line: --tz Europe/Berlin)).",
        DataWarning,
        stacklevel=5,
    )
    return utc.dt.tz_convert(first.tzinfo)


#: The UTC offset at the end of an ISO 8601 time stamp.
_OFFSET = r"((?:[+-]\d\d:?\d\d)|Z)$"


def localize(
    index: pd.DatetimeIndex, tz: str, name: str, where: Where = _position
) -> pd.DatetimeIndex:
    """Time stamps in the time zone ``tz``: an IANA name (``"Europe/Berlin"``), ``"UTC"`` or a
    fixed offset (``"+01:00"``).

    Stamps without a UTC offset are the local clock time of ``tz``: across the end of daylight
    saving time the repeated hour is told apart by its order (the first pass in summer time),
    and a stamp in the hour the clocks skip at its start is refused. Stamps with an offset are
    converted to ``tz``.
    """
    try:
        pd.Timestamp("2000-01-01", tz=tz)
    except (KeyError, ValueError, TypeError, LookupError):
        raise DataError(
            f"unknown time zone {tz!r}; give a name such as 'Europe/Berlin' or 'UTC', or a fixed "
            "offset such as '+01:00'."
        ) from None
    if index.tz is not None:
        return index.tz_convert(tz)
    try:
        return index.tz_localize(tz, ambiguous="infer", nonexistent="raise")
    except (ValueError, TypeError):  # pytz's errors derive from these
        pass
    skipped = np.flatnonzero(index.tz_localize(tz, ambiguous="NaT", nonexistent="NaT").isna())
    if skipped.size:
        i = int(skipped[0])
        try:
            index[i : i + 1].tz_localize(tz, ambiguous=True, nonexistent="raise")
        except (ValueError, TypeError):  # the clocks skip it
            raise DataError(
                f"the time stamp {index[i]} in column {name!r} at {where(i)} does not exist in "
                f"{tz} (the clocks skip that hour at the start of daylight saving time); are the "
                f"stamps local time in {tz}?"
            ) from None
        raise DataError(
            f"the time stamp {index[i]} in column {name!r} at {where(i)} is in the hour that "
            f"the end of daylight saving time repeats in {tz}, and its order does not tell which "
            "pass it belongs to (the hour is not logged twice); drop that hour or give the "
            "stamps their UTC offsets."
        )
    raise DataError(f"cannot read the time stamps in column {name!r} as local time in {tz}.")


def offset_text(offset) -> str:
    """A UTC offset (``datetime.timedelta``) as ``"+02:00"``."""
    minutes = int(round(offset.total_seconds() / 60))
    sign = "+" if minutes >= 0 else "-"
    return f"{sign}{abs(minutes) // 60:02d}:{abs(minutes) % 60:02d}"


def check_order(index: pd.DatetimeIndex, where: Where = _position) -> None:
    """Time stamps must strictly increase: name the first step back and the first duplicate."""
    values = index.asi8
    steps = np.diff(values)
    back = np.flatnonzero(steps < 0)
    if back.size:
        i = int(back[0]) + 1
        text = (
            f"time stamps are not increasing: {where(i)} has {index[i]}, earlier than "
            f"{index[i - 1]} at {where(i - 1)}"
        )
        if _clock_back(index, i, steps[i - 1]):
            raise DataError(f"{text}: {_CLOCK_BACK}")
        raise DataError(f"{text}; sort the data by time first.")
    same = np.flatnonzero(steps == 0)
    if same.size:
        i = int(same[0]) + 1
        stamp = f"duplicate time stamp {index[i]} at {where(i - 1)} and {where(i)}"
        stamp += f" ({same.size} duplicates in all)" if same.size > 1 else ""
        if _clock_back(index, i, 0):
            raise DataError(f"{stamp}: {_CLOCK_BACK}")
        raise DataError(f"{stamp}; drop or average the duplicates first.")


_CLOCK_BACK = (
    "the end of daylight saving time repeats an hour of local clock time; pass the data's time "
    "zone, e.g. tz='Europe/Berlin' (command line: --tz Europe/Berlin), to read the stamps as "
    "local time there, or log in UTC."
)


def _clock_back(index: pd.DatetimeIndex, i: int, step_ns: int) -> bool:
    """Whether naive stamps going back (or repeating) at ``i`` by at most an hour, early on a
    night of March, April or September to November, look like clocks set back."""
    hour_ns = 3600 * 10**9
    return (
        index.tz is None
        and -hour_ns <= int(step_ns) <= 0
        and 0 <= index[i].hour <= 3
        and index[i].month in (3, 4, 9, 10, 11)
    )


def median_step(index: pd.DatetimeIndex) -> float:
    """Median time step [s] (``nan`` for fewer than two samples)."""
    if len(index) < 2:
        return float("nan")
    return float(np.median(np.diff(index.asi8))) * 1e-9


#: How far [share] jittered time stamps may lift the logger's own step above its grid's: a
#: grid that much finer than :func:`nominal_step` is still the logger's.
JITTER = 0.1


def nominal_step(index: pd.DatetimeIndex) -> float:
    """The logger's own step [s]: the median of the steps in the shortest cluster (those up to
    1.5 times the 10th percentile of the steps). The median step itself for a regular index;
    for stamps that jitter around a grid with rows missing (steps of one, two, three grid
    steps), the grid's step, where the median of all steps lies above it."""
    if len(index) < 2:
        return float("nan")
    steps = np.diff(index.asi8) * 1e-9
    steps = steps[steps > 0]
    if not steps.size:
        return float("nan")
    short = steps[steps <= 1.5 * np.percentile(steps, 10)]
    return float(np.median(short))


def irregular_position(index: pd.DatetimeIndex) -> int | None:
    """Position of the first sample whose step from the previous one differs from the median."""
    if len(index) < 3:
        return None
    steps = np.diff(index.asi8) * 1e-9
    step = float(np.median(steps))
    off = np.flatnonzero(np.abs(steps - step) > _STEP_ATOL + _STEP_RTOL * step)
    return int(off[0]) + 1 if off.size else None


def fill_missing_rows(index: pd.DatetimeIndex, step: float) -> pd.DatetimeIndex | None:
    """The regular grid from the first to the last time stamp when every step of ``index`` is
    a whole multiple of ``step`` [s] (rows missing from a regular grid); ``None`` otherwise."""
    steps = np.diff(index.asi8) * 1e-9
    ratio = steps / step
    if np.any(np.abs(ratio - np.round(ratio)) > _GRID_TOL * np.maximum(ratio, 1.0)):
        return None
    return pd.date_range(index[0], index[-1], periods=int(round((steps.sum()) / step)) + 1).rename(
        "time"
    )


def segment_slices(index: pd.DatetimeIndex, step: float) -> tuple[tuple[int, int], ...]:
    """``((start, stop), …)``: the runs of samples at the regular ``step`` [s]; a time step
    longer than ``step`` starts a new segment."""
    if len(index) < 2:
        return ((0, len(index)),)
    steps = np.diff(index.asi8) * 1e-9
    cuts = np.flatnonzero(steps > step * (1 + _GRID_TOL) + _GRID_TOL) + 1
    edges = [0, *cuts.tolist(), len(index)]
    return tuple((edges[i], edges[i + 1]) for i in range(len(edges) - 1))


def check_regular(index: pd.DatetimeIndex, where: Where = _position) -> None:
    """The sampling step must be constant; name the first place where it is not."""
    i = irregular_position(index)
    if i is None:
        return
    step = median_step(index)
    this = _seconds(index[i] - index[i - 1])
    raise DataError(
        f"irregular sampling: the step from {index[i - 1]} to {index[i]} ({where(i)}) is "
        f"{fmt_seconds(this)} but the median step is {fmt_seconds(step)}; pass resample= "
        f"(e.g. resample='{_rule_hint(nominal_step(index))}') to average onto a regular grid."
    )


def _rule_hint(step: float) -> str:
    """The finest usual grid not finer than ``step`` [s], give or take :data:`JITTER`
    (``"15min"`` for 15-minute data with jittered time stamps, ``"1h"`` for hourly stamps
    that jitter by minutes), so that resampling keeps the data's resolution."""
    for seconds, rule in (
        (60, "1min"),
        (300, "5min"),
        (600, "10min"),
        (900, "15min"),
        (1800, "30min"),
        (3600, "1h"),
    ):
        if step <= seconds * (1 + JITTER):
            return rule
    return f"{int(np.ceil(step / 3600 / (1 + JITTER)))}h"


def to_float(frame: pd.DataFrame, where: Where = _position) -> pd.DataFrame:
    """Convert every column to float64; name the first value that is not a number.

    A column without a single number (dates, comments, ...) whose name is not canonical is not
    a signal: it is dropped with a warning. Any other non-numeric value is an error.
    """
    out = {}
    dropped = []
    for name in frame.columns:
        column = frame[name]
        kind = column.dtype
        if pd.api.types.is_numeric_dtype(kind) and not pd.api.types.is_complex_dtype(kind):
            out[name] = column.to_numpy(dtype=np.float64, na_value=np.nan)
            continue
        if pd.api.types.is_datetime64_any_dtype(kind) or pd.api.types.is_timedelta64_dtype(kind):
            numbers = pd.Series(np.nan, index=column.index)
        else:
            numbers = pd.to_numeric(column, errors="coerce")
        blank = column.isna() | column.astype("string").str.strip().eq("").fillna(True)
        blank = blank.to_numpy(dtype=bool, na_value=True)
        bad = np.flatnonzero(numbers.isna().to_numpy() & ~blank)
        if bad.size and bad.size == np.count_nonzero(~blank) and signal_base(str(name)) is None:
            dropped.append(str(name))
            continue
        if bad.size:
            i = int(bad[0])
            value = column.iloc[i]
            hint = _number_hint(value)
            raise DataError(
                f"column {name!r} has a non-numeric value {value!r} at {where(i)}{hint}; fix or "
                "drop that value, or drop the column before loading."
            )
        out[name] = numbers.to_numpy(dtype=np.float64, na_value=np.nan)
    if dropped:
        warnings.warn(
            f"dropped column(s) without any number: {', '.join(map(repr, dropped))}.",
            UserWarning,
            stacklevel=4,
        )
    return pd.DataFrame(out, index=frame.index, columns=[n for n in frame.columns if n in out])


def _number_hint(value: object) -> str:
    """What a text cell that looks like a number asks for: a decimal comma, or thousands."""
    if not isinstance(value, str):
        return ""
    if _COMMA_NUMBER.match(value):
        either = (
            "; or, if the comma groups thousands, thousands=',' / --thousands ','"
            if _GROUPED_NUMBER.match(value)
            else ""
        )
        return (
            " (a decimal comma? pass decimal=',', on the command line --decimal ',', with "
            f"sep=';' / --sep ';' when commas also separate the columns{either})"
        )
    grouped = _GROUPED_NUMBER.match(value)
    if grouped is None or grouped.group(1) == grouped.group(2):
        return ""
    mark, point = grouped.group(1), grouped.group(2) or ("," if grouped.group(1) == "." else ".")
    if point == ",":
        return (
            f" (digits grouped in thousands? pass thousands={mark!r}, decimal=',', on the "
            f"command line --thousands {mark!r} --decimal ',')"
        )
    return (
        f" (digits grouped in thousands? pass thousands={mark!r}, on the command line "
        f"--thousands {mark!r})"
    )


def check_kelvin(frame: pd.DataFrame) -> None:
    """Canonical temperature columns must be in °C, not kelvin."""
    for name in frame.columns:
        if not is_temperature(name):
            continue
        values = frame[name].to_numpy()
        seen = values[np.isfinite(values)]
        median = float(np.median(seen)) if seen.size else np.nan
        if median > _KELVIN_MEDIAN:
            raise DataError(
                f"column {name!r} looks like kelvin (median {median:.1f}); load it with "
                f"units={{{name!r}: 'K'}} (command line: --unit {name}=K), or convert it to °C "
                "(subtract 273.15)."
            )


def rows_text(index: pd.Index, mask: np.ndarray, limit: int = 3) -> str:
    """``"at 2013-08-21 03:00:00, ... (12 samples in all)"``: the first ``limit`` time stamps
    where ``mask`` is true, and their count."""
    hits = np.flatnonzero(np.asarray(mask, dtype=bool))
    shown = ", ".join(str(index[i]) for i in hits[:limit])
    more = f", ... ({hits.size} samples in all)" if hits.size > limit else ""
    return f"at {shown}{more}"


def check_finite(frame: pd.DataFrame) -> None:
    """No infinite value and no absurd magnitude (above :data:`ABSURD` for a canonical signal,
    :data:`ABSURD_OTHER` for another column), whatever the other checks: name the column and
    the time stamps."""
    for name in frame.columns:
        values = frame[name].to_numpy(dtype=np.float64)
        infinite = np.isinf(values)
        if infinite.any():
            raise DataError(
                f"column {name!r} has infinite values {rows_text(frame.index, infinite)}; an "
                "infinity is not a measurement: set those samples to NaN and fill the gap or "
                "slice it away."
            )
        limit = ABSURD if signal_base(str(name)) is not None else ABSURD_OTHER
        with np.errstate(invalid="ignore"):
            huge = np.abs(values) > limit
        if huge.any():
            first = float(values[np.flatnonzero(huge)[0]])
            counter = signal_unit(str(name)) == "W" and rising_share(values) is not None
            why = (
                "a cumulative energy meter (in J?) rather than a power? load it with counters="
                f"{{{str(name)!r}: 'J'}} (--counter {name}=J; or kJ, MJ, kWh)"
                if counter
                else "an error code of the logger? set them to NaN and fill or slice them away "
                "(a unit off by a factor: scale=, --scale)"
            )
            raise DataError(
                f"column {name!r} has absurd values (e.g. {first:.3g}, beyond ±{limit:.0e}) "
                f"{rows_text(frame.index, huge)}; {why}."
            )
