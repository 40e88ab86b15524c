"""Loading monitoring data from a CSV file or a DataFrame into a checked :class:`Dataset`."""

from __future__ import annotations

import bz2
import difflib
import gzip
import itertools
import lzma
import math
import os
import re
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd

from ._args import check_mapping
from ._checks import localize, parse_time
from ._counters import check_counters
from ._dataset import Dataset, validated_frame
from ._errors import DataError, DataWarning, list_names
from ._gaps import gap_note
from ._signals import signal_base, signal_unit
from ._suggest import stated_unit_notes
from ._units import unit_conversions

__all__ = ["as_dataset", "load"]

_TIME_NAMES = ("time",)
#: Words in the names of time and date columns (English, German, Dutch, French, Spanish
#: exports), for the hint when no time column is found.
_TIME_WORDS = ("time", "stamp", "zeit", "tijd", "heure", "hora", "clock")
_DATE_WORDS = ("date", "datum", "fecha", "dato")


def _head_lines(path: Path, n: int = 20) -> list[str]:
    """The first ``n`` lines of a text file (decompressed by extension); [] if unreadable."""
    opener = {".gz": gzip.open, ".bz2": bz2.open, ".xz": lzma.open, ".lzma": lzma.open}.get(
        path.suffix.lower()
    )
    if path.suffix.lower() in (".zip", ".zst", ".tar"):
        return []
    try:
        handle = (
            opener(path, "rt", encoding="utf-8", errors="replace")
            if opener is not None
            else open(path, encoding="utf-8", errors="replace")  # noqa: SIM115
        )
        with handle as f:
            return [line.rstrip("\r\n") for line in itertools.islice(f, n)]
    except (OSError, EOFError, ValueError):
        return []


_DECIMAL_COMMA = re.compile(r"^\s*[-+]?\d+,\d+\s*$")


def _sniff(path: Path, sep: str | None, decimal: str | None) -> None:
    """Refuse semicolon/tab files read with the default separator, and decimal commas in a
    comma-separated file, saying which option reads them."""
    lines = [line for line in _head_lines(path) if line.strip()]
    if not lines:
        return
    header, rows = lines[0], lines[1:]
    name = path.name
    if sep is None and "," not in header:
        for char, text, option in ((";", "semicolons", "';'"), ("\t", "tabs", "'\\t'")):
            if char in header:
                comma = any(
                    _DECIMAL_COMMA.match(field) for row in rows for field in row.split(char)
                )
                both = " and decimal commas" if comma else ""
                extra = " --decimal ','" if comma else ""
                keyword = ", decimal=','" if comma else ""
                raise DataError(
                    f"{name!r} separates its columns with {text}{both}, not commas: pass "
                    f"sep={option}{keyword} (command line: --sep {option}{extra})."
                )
    if (sep or ",") == "," and '"' not in header:
        width = header.count(",")
        wider = [i for i, row in enumerate(rows) if '"' not in row and row.count(",") > width]
        if wider and all(rows[i].rstrip(", ").count(",") <= width for i in wider):
            raise DataError(
                f"{name!r}: line {wider[0] + 2} ends with more separators than the header has "
                "columns (trailing commas); remove them from the file."
            )
        if wider and len(wider) >= max(1, len(rows) // 2):
            fields = rows[wider[0]].count(",") + 1
            raise DataError(
                f"{name!r}: line {wider[0] + 2} has {fields} comma-separated fields but the "
                f"header has {width + 1}: decimal commas in a comma-separated file cannot be "
                "read; export with ';' between columns and pass sep=';', decimal=',' (command "
                "line: --sep ';' --decimal ',')."
            )
    if (decimal or ".") == "." and sep not in (None, ","):
        for row in rows:
            if any(_DECIMAL_COMMA.match(field) for field in row.split(sep)):
                raise DataError(
                    f"{name!r} writes numbers with a decimal comma: pass decimal=',' (command "
                    "line: --decimal ',')."
                )


#: Thousands separators a CSV file may group its digits with (one byte each, as pandas reads).
THOUSANDS = (",", ".", "'", " ", "_")


def _check_thousands(thousands: str | None, sep: str, decimal: str) -> None:
    """Refuse a thousands separator that cannot be told from the decimal mark or a column."""
    if thousands is None:
        return
    if thousands not in THOUSANDS:
        raise DataError(
            f"thousands={thousands!r} is not a thousands separator; give one of "
            f"{', '.join(map(repr, THOUSANDS))} (command line: --thousands)."
        )
    if thousands == decimal:
        raise DataError(
            f"the thousands separator and the decimal mark are both {decimal!r}: with "
            "thousands='.' pass decimal=',' (command line: --thousands '.' --decimal ',')."
        )
    if thousands == sep and sep != ",":
        raise DataError(
            f"the thousands separator and the column separator are both {sep!r}; give the "
            "file's column separator with sep= (command line: --sep)."
        )


def _read_csv(
    path: Path, sep: str | None = None, decimal: str | None = None, thousands: str | None = None
) -> tuple[pd.DataFrame, int]:
    """The CSV at ``path`` and the number of lines skipped below its header (a row of units).
    A thousands separator equal to the comma between columns groups the digits of quoted
    fields (``"1,234.5"``)."""
    if not path.exists():
        raise DataError(
            f"file not found: {str(path)!r} (relative paths are taken from the current "
            f"directory {os.getcwd()!r}); check the path."
        )
    if path.is_dir():
        raise DataError(f"{str(path)!r} is a directory; give the path of a CSV file.")
    options = {"sep": sep or ",", "decimal": decimal or "."}
    if options["sep"] == options["decimal"]:
        raise DataError(
            f"the column separator and the decimal mark are both {options['sep']!r}; with "
            "decimal=',' pass sep=';' (command line: --sep ';' --decimal ',')."
        )
    _check_thousands(thousands, options["sep"], options["decimal"])
    if thousands is not None:
        options["thousands"] = thousands
    _refuse_spreadsheet(path)
    _sniff(path, sep, decimal)
    try:
        names = pd.read_csv(path, header=None, nrows=1, dtype=str, **options)
        frame = pd.read_csv(path, **options)
    except pd.errors.EmptyDataError:
        raise DataError(f"the file {str(path)!r} is empty; give a CSV with a header.") from None
    except pd.errors.ParserError as error:
        first = str(error).strip().splitlines()[0]
        raise DataError(
            f"cannot read {str(path)!r} as CSV ({first}); check the separator (sep=, command "
            "line --sep) and quoting, or read it with pandas yourself and pass the DataFrame."
        ) from None
    except UnicodeDecodeError:
        raise DataError(
            f"{str(path)!r} is not UTF-8 text; read it with pd.read_csv(..., encoding=...) and "
            "pass the DataFrame."
        ) from None
    header = [str(name) for name in names.iloc[0].tolist()] if len(names) else []
    seen: set[str] = set()
    for column in header:
        if column in seen:
            raise DataError(
                f"two columns are named {column!r} in {path.name}; rename or drop one of them "
                "in the file."
            )
        seen.add(column)
    units = _units_row(frame, options["decimal"], thousands)
    if units is None:
        return frame, 0
    warnings.warn(
        f"line 2 of {path.name} holds units, not values ({', '.join(map(repr, units[:6]))}"
        f"{', …' if len(units) > 6 else ''}): skipped. Signals are read in the units of their "
        "canonical names (°C, W, W/m²); convert others with scale= (command line: --scale).",
        DataWarning,
        stacklevel=3,
    )
    return pd.read_csv(path, skiprows=[1], **options), 1


#: The first bytes of spreadsheet workbooks: a zip archive (.xlsx, .ods) or an OLE2 file (.xls).
_WORKBOOK_MAGIC = (b"PK\x03\x04", b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1")


def _refuse_spreadsheet(path: Path) -> None:
    """A spreadsheet workbook given as the data is refused, saying how to read it."""
    try:
        with open(path, "rb") as f:
            head = f.read(8)
    except OSError:
        return
    if path.suffix.lower() in (".xlsx", ".xlsm", ".xls", ".ods") or head.startswith(
        _WORKBOOK_MAGIC
    ):
        if path.suffix.lower() in (".gz", ".zip", ".bz2", ".xz") and head.startswith(b"PK"):
            return  # a zipped CSV, which pandas reads
        raise DataError(
            f"{str(path)!r} is a spreadsheet workbook, not a CSV file; save the sheet as CSV "
            "(UTF-8), or read it with pd.read_excel(...) and pass the DataFrame."
        )


def _tidy_header(raw: pd.DataFrame) -> pd.DataFrame:
    """Column names of a CSV without the spaces around them (``time, T_zon``), and without the
    empty columns of a separator at the end of every line (``Unnamed: 3``)."""
    empty = [
        name
        for name in raw.columns
        if re.fullmatch(r"Unnamed: \d+", str(name)) and raw[name].isna().all()
    ]
    return raw.drop(columns=empty).rename(columns=lambda name: str(name).strip())


def _is_number(text: object, decimal: str, thousands: str | None = None) -> bool:
    text = str(text).strip()
    if thousands:
        text = text.replace(thousands, "")
    try:
        float(text.replace(decimal, "."))
    except ValueError:
        return False
    return True


def _units_row(frame: pd.DataFrame, decimal: str, thousands: str | None = None) -> list[str] | None:
    """The cells of the first row when it names units rather than values: no cell of it is a
    number, some are text, and at least half the cells of each of the next rows are numbers."""
    if len(frame) < 3:
        return None
    first = frame.iloc[0].tolist()
    text = [str(v).strip() for v in first if isinstance(v, str) and str(v).strip()]
    if not text or any(_is_number(v, decimal, thousands) for v in first if isinstance(v, str)):
        return None
    if any(isinstance(v, int | float) and not pd.isna(v) for v in first):
        return None
    for _, row in frame.iloc[1:3].iterrows():
        cells = row.tolist()
        numbers = sum(
            _is_number(v, decimal, thousands) if isinstance(v, str) else not pd.isna(v)
            for v in cells
        )
        if numbers < len(cells) / 2:
            return None
    return text


#: Column names taken as the time without time= (any case): 'Time', 'TIMESTAMP', 'DateTime'.
_TIME_NAMES_ANY_CASE = ("time", "timestamp", "datetime")
#: How pandas names a CSV's unnamed first column (an index written by ``DataFrame.to_csv``).
_UNNAMED_INDEX = ("Unnamed: 0", "")


def _implied_time_column(raw: pd.DataFrame, names: list[str]) -> str | None:
    """The column that is the time without being called ``time``: the only one named 'time',
    'timestamp' or 'datetime' in any case, or an unnamed first column (a DataFrame's index
    written to CSV) whose values read as time stamps; ``None`` otherwise."""
    named = [n for n in names if n.strip().lower() in _TIME_NAMES_ANY_CASE]
    if len(named) == 1:
        return named[0]
    if names and names[0] in _UNNAMED_INDEX:
        head = raw[raw.columns[0]].dropna().head(5)
        if len(head) and head.map(lambda v: isinstance(v, str)).all():
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # pandas' 'could not infer format'
                    pd.to_datetime(head, utc=True)
            except (ValueError, TypeError, OverflowError):
                return None
            return names[0]
    return None


def _time_values(
    raw: pd.DataFrame, time: str | Sequence[str] | None, from_frame: bool
) -> tuple[pd.Series | pd.Index, str, str | list[str] | None]:
    """Return (time values, their name, the column(s) to drop or None when from the index).
    ``time`` may name a date column and a clock column, joined with a space."""
    names = [str(name) for name in raw.columns]
    if isinstance(time, (list, tuple)):
        if len(time) != 2 or not all(isinstance(t, str) for t in time):
            raise DataError(
                f"time= takes one column name or two, a date and a clock column, e.g. "
                f"time=['date', 'time']; got {time!r}."
            )
        absent = [t for t in time if t not in names]
        if absent:
            raise DataError(
                f"no time column {absent[0]!r}; columns: {list_names(names)}; pass time= with "
                "the date and clock columns among them."
            )
        date, clock = time
        joined = raw[date].astype("string").str.strip() + " " + raw[clock].astype("string")
        return joined, f"{date} + {clock}", list(time)
    if time is not None:
        if time in names:
            return raw[time], time, time
        if from_frame and raw.index.name == time:
            return raw.index, time, None
        raise DataError(
            f"no time column {time!r}; columns: {list_names(names)}; pass time= with one of them."
        )
    for name in _TIME_NAMES:
        if name in names:
            return raw[name], name, name
    if from_frame and isinstance(raw.index, pd.DatetimeIndex):
        return raw.index, str(raw.index.name or "index"), None
    found = _implied_time_column(raw, names)
    if found is not None:
        return raw[found], found, found
    tried = ", ".join(repr(name) for name in _TIME_NAMES) + (
        f" in any case, {', '.join(repr(n) for n in _TIME_NAMES_ANY_CASE[1:])}, an unnamed first "
        "column of time stamps"
    )
    extra = " and the DataFrame index (not a DatetimeIndex)" if from_frame else ""
    likely = [name for name in names if any(k in name.lower() for k in _TIME_WORDS + _DATE_WORDS)]
    hint = f" (perhaps {list_names(likely, 5)}?)" if likely else ""
    for char, option in ((";", "';'"), ("\t", "'\\t'")):
        if len(names) == 1 and char in names[0]:
            raise DataError(
                f"the data have one column {names[0][:60]!r}: a file separated by {option}? "
                f"read it with sep={option} (command line: --sep {option})."
            )
    dates = [n for n in likely if any(k in n.lower() for k in _DATE_WORDS)]
    clocks = [n for n in likely if n not in dates]
    pair = ""
    if dates and clocks:  # the date and the clock in two columns
        pair = (
            f", or time=[{dates[0]!r}, {clocks[0]!r}] (command line: --time "
            f"{dates[0]},{clocks[0]}) for a date and a clock column"
        )
    raise DataError(
        f"no time column found (tried {tried}{extra}); pass time='your_time_column'{hint}"
        f"{pair}; columns: {list_names(names)}."
    )


def _renaming(
    columns: Mapping[str, str | Sequence[str]] | None,
    signals: list[str],
    time_names: Sequence[str],
) -> tuple[dict[str, str], dict[str, list[str]]]:
    """Validate ``columns`` (canonical -> your column, or a list of your columns) and return
    ``(user -> canonical, canonical -> [user, …])``: the columns renamed, and the canonical
    signals combined from several of yours (:func:`_combined`)."""
    if not columns:
        return {}, {}
    if not isinstance(columns, Mapping):
        raise DataError(
            "columns must map canonical names to your column names, e.g. "
            "columns={'T_zon': 'living_T'}."
        )
    renaming: dict[str, str] = {}
    combine: dict[str, list[str]] = {}
    used: dict[str, str] = {}
    for canonical, given in columns.items():
        several = not isinstance(given, (str, bytes)) and hasattr(given, "__iter__")
        users = list(dict.fromkeys(given)) if several else [given]
        if several and not users:
            raise DataError(f"columns maps {canonical!r} to no column; name one or more.")
        for user in users:
            _check_mapped(canonical, user, signals, time_names, used)
            used[user] = str(canonical)
        if len(users) > 1:
            if _COMBINE.get(signal_unit(str(canonical)) or "") is None:
                raise DataError(
                    f"columns maps {canonical!r} to several columns ({list_names(users)}), but "
                    f"{canonical!r} is no signal jaxbox knows how to combine: temperatures (°C) "
                    "and irradiances (W/m²) are averaged, powers (W) summed; map one column."
                )
            combine[str(canonical)] = [str(u) for u in users]
        else:
            renaming[users[0]] = str(canonical)
    targets = [(u, c) for u, c in renaming.items()] + [(cols[0], c) for c, cols in combine.items()]
    for user, canonical in targets:
        if canonical in signals and canonical not in renaming:
            raise DataError(
                f"two columns would be named {canonical!r}: yours {user!r} (mapped by columns=) "
                f"and the existing {canonical!r}; drop one or map to a numbered variant "
                f"such as {canonical + '2'!r}."
            )
    return renaming, combine


def _check_mapped(canonical, user, signals, time_names, used: dict[str, str]) -> None:
    """Refuse a mapping of ``canonical`` onto ``user`` that is the time column, no column, or
    a column mapped already (``used``: yours -> canonical)."""
    if user in time_names:
        raise DataError(
            f"columns maps {canonical!r} to {user!r}, which is the time column; map a "
            "signal column instead."
        )
    if user not in signals:
        close = difflib.get_close_matches(str(user), signals, n=3, cutoff=0.6)
        if canonical in signals and signal_base(str(user)) is not None:
            hint = f" (the mapping goes canonical -> yours: {{{user!r}: {canonical!r}}}?)"
        elif close:
            hint = f" (did you mean {list_names(close)}?)"
        else:
            hint = ""
        raise DataError(
            f"columns maps {canonical!r} to {user!r}, but there is no column {user!r}{hint}; "
            f"available: {list_names(signals)}."
        )
    if user in used:
        raise DataError(
            f"column {user!r} is mapped twice (to {used[user]!r} and {canonical!r}); map "
            "each of your columns to one canonical name."
        )


#: how several of your columns make one canonical signal, by the signal's unit
_COMBINE = {"°C": "mean", "W/m²": "mean", "W": "sum"}


def _combined(frame: pd.DataFrame, combine: Mapping[str, list[str]], where) -> pd.DataFrame:
    """``frame`` with each canonical signal of ``combine`` added from several of your columns:
    the mean of temperatures and irradiances, the sum of powers (:data:`_COMBINE`); a row
    missing in any of them is missing (a gap), so that the mean of the others does not stand
    in for it. Your columns are kept as they are."""
    if not combine:
        return frame
    sources = list(dict.fromkeys(c for cols in combine.values() for c in cols))
    values = validated_frame(frame[sources], check=False, regular=False, where=where)
    out = frame.copy()
    for canonical, cols in combine.items():
        block = values[cols].to_numpy(dtype=float)
        how = _COMBINE[signal_unit(canonical)]
        out[canonical] = block.sum(axis=1) if how == "sum" else block.mean(axis=1)
    return out


def _factors(scale: Mapping[str, float] | None, names: list[str]) -> dict[str, float]:
    """Validate ``scale`` (column -> factor) against the column names after mapping."""
    factors = check_mapping(scale, "scale", "{'Q_hea': 1000}")
    out = {}
    for name, factor in factors.items():
        if name not in names:
            close = difflib.get_close_matches(str(name), names, n=3, cutoff=0.6)
            hint = f" (did you mean {list_names(close)}?)" if close else ""
            raise DataError(
                f"scale names column {name!r}, but there is none{hint}; scale applies after "
                f"columns= (canonical names); available: {list_names(names)}."
            )
        try:
            value = float(factor)
        except (TypeError, ValueError):
            value = float("nan")
        if isinstance(factor, bool) or not math.isfinite(value) or value == 0.0:
            raise DataError(
                f"scale factor of {name!r} must be a finite non-zero number, got {factor!r}; "
                "e.g. scale={'Q_hea': 1000} (command line: --scale Q_hea=1000) for kW to W."
            )
        out[str(name)] = value
    return out


def load(
    source: str | os.PathLike[str] | pd.DataFrame,
    *,
    time: str | Sequence[str] | None = None,
    columns: Mapping[str, str] | None = None,
    resample: str | None = None,
    check: bool = True,
    epoch: str | pd.Timestamp = "1970-01-01",
    time_unit: str = "s",
    sep: str | None = None,
    decimal: str | None = None,
    thousands: str | None = None,
    scale: Mapping[str, float] | None = None,
    counters: Mapping[str, str] | None = None,
    tz: str | None = None,
    units: Mapping[str, str] | None = None,
) -> Dataset:
    """Load monitoring data into a checked :class:`Dataset`.

    Args:
        source: path of a CSV file (with a header; ``.gz`` etc. decompressed by extension) or a
            pandas DataFrame.
        time: name of the time column, or the names of a date column and a clock column
            (``["date", "time"]``, joined). By default the column ``time``, or else the
            DatetimeIndex of a DataFrame. Date-time strings are parsed (ISO 8601 preferred;
            31/01/2024 read day first where the order of the stamps says so); numbers are
            ``time_unit`` since ``epoch`` (default **seconds** since 1970-01-01 00:00; numbers
            that cannot be seconds are refused naming the unit they look like). Each time stamp
            should mark the end of its averaging interval.
        columns: canonical name -> your column name, e.g. ``{"T_zon": "living_T"}``; those
            columns are renamed, all others are kept as they are. A list of your columns
            makes one signal of them all (``{"T_zon": ["living_T", "kitchen_T"], "Q_hea":
            ["heater_1", "heater_2"]}``): the mean of temperatures and irradiances, the sum of
            powers, a row missing in any of them missing; your columns are kept beside it.
            Units must be those of the canonical names (°C, W, W/m²; see :data:`SIGNALS`).
        resample: a pandas frequency such as ``"1h"``: after the checks, average onto that grid
            (see :meth:`Dataset.resample`); irregular sampling is then allowed.
        check: also require a regular step (rows missing from the grid become rows of NaN)
            and no temperature in kelvin. Parseable, strictly increasing time stamps and numeric
            values are always required. Gaps (NaN) are kept and noted with a
            :class:`DataWarning`; they are judged in the windows used
            (:func:`jaxbox.data.prepare_window`).
        epoch: time of ``0`` for a numeric time column (``"1899-12-30"`` with
            ``time_unit="D"`` for spreadsheet serial dates).
        time_unit: unit of a numeric time column: ``"s"``, ``"ms"``, ``"us"``, ``"ns"``,
            ``"min"``, ``"h"`` or ``"D"``.
        sep: column separator of a CSV file (default ``","``; e.g. ``";"`` or ``"\\t"``). A
            file separated by semicolons or tabs read without it is refused with this advice.
        decimal: decimal mark of a CSV file (default ``"."``; ``","`` with ``sep=";"``).
        thousands: thousands separator of a CSV file's numbers (default none): ``","`` for
            ``1,234.5`` (quoted in a comma-separated file), ``"."`` with ``decimal=","`` for
            ``1.234,5``, ``"'"`` or ``" "``.
        scale: canonical column name (after ``columns``) -> factor multiplying its values,
            e.g. ``{"Q_hea": 1000}`` for heating power logged in kW. Applied before the checks.
        counters: canonical column name (after ``columns``) -> energy unit (``"kWh"``, ``"MWh"``,
            ``"Wh"``, ``"J"``, ``"kJ"``, ``"MJ"``, ``"GJ"``) of a column that holds a cumulative
            energy meter instead of a power: it becomes the mean power [W] of each sampling
            interval (the first row, the starting readings, is dropped; a gap where the counter
            falls or is missing).
        tz: time zone of the time stamps, e.g. ``"Europe/Berlin"`` (or ``"UTC"``, ``"+01:00"``).
            Stamps without a UTC offset are then read as local clock time there, across
            daylight-saving changes (the hour repeated at the end of summer time told apart by
            its order); stamps with offsets are converted to it. The data keep that zone.
            Without ``tz`` naive stamps stay naive (a repeated hour is a duplicate).
        units: canonical column name (after ``columns``) -> the unit it is logged in, converted
            to jaxbox's before the checks: ``{"T_zon": "degF", "T_amb": "degF"}`` (or ``"K"``),
            ``{"Q_hea": "kW"}`` (``"MW"``, ``"Btu/h"``), ``{"I_glo_hor": "kW/m2"}``; see
            :mod:`jaxbox.data._units`. A column takes a unit or a ``scale``, not both.

    Always refused (whatever ``check``): duplicate column names, infinite values and absurd
    magnitudes (see :func:`jaxbox.data.check_finite`). The physical plausibility of the
    signals in the periods actually used is checked by
    :func:`jaxbox.data.check_plausibility`.

    Raises:
        DataError: for any problem with the input; the message names the column, row or
            time stamp at fault and the fix.

    Example:
        ```python
        data = jaxbox.load("building.csv", columns={"T_zon": "living_temp", "T_amb": "outdoor"},
                           resample="1h")
        ```
    """
    from_frame = isinstance(source, pd.DataFrame)
    if from_frame:
        raw = source
        label = "the DataFrame"

        def where(i: int) -> str:
            return f"row {i}"

    elif isinstance(source, (str, os.PathLike)):
        path = Path(source)
        raw, skipped = _read_csv(path, sep, decimal, thousands)
        raw = _tidy_header(raw)
        label = path.name

        def where(i: int) -> str:
            return f"row {i} (line {i + 2 + skipped} of {label})"

    else:
        raise DataError(
            f"source must be a CSV path or a pandas DataFrame, got {type(source).__name__}."
        )
    if raw.columns.has_duplicates:
        name = raw.columns[raw.columns.duplicated()][0]
        raise DataError(f"two columns are named {name!r} in {label}; rename or drop one of them.")

    values, time_name, time_column = _time_values(raw, time, from_frame)
    dropped = [time_column] if isinstance(time_column, str) else list(time_column or [])
    signals = [str(name) for name in raw.columns if name not in dropped]
    renaming, combine = _renaming(columns, signals, dropped or [time_name])
    try:
        origin = pd.Timestamp(epoch)
    except (ValueError, TypeError):
        raise DataError(f"cannot read epoch={epoch!r} as a time stamp.") from None
    try:
        index = parse_time(pd.Series(values), time_name, epoch=origin, where=where, unit=time_unit)
    except DataError as error:  # clock times only: name the date column when one is there
        dates = [n for n in signals if any(k in n.lower() for k in _DATE_WORDS)]
        if "clock times without dates" not in str(error) or not dates:
            raise
        raise DataError(str(error).replace("your_date_column", dates[0])) from None
    if tz is not None:
        index = localize(index, tz, time_name, where)

    frame = raw.drop(columns=dropped) if dropped else raw
    frame = frame.set_axis([renaming.get(str(name), str(name)) for name in frame.columns], axis=1)
    frame = _combined(frame.set_axis(index, axis=0), combine, where)
    names = [str(name) for name in frame.columns]
    factors = _factors(scale, names)
    joules = check_counters(counters, names)
    by_unit, offsets = unit_conversions(units, names, factors, joules)
    mapped = [*renaming.items(), *((u, c) for c, cols in combine.items() for u in cols)]
    for note in stated_unit_notes(mapped, [*factors, *by_unit, *joules], signal_unit):
        warnings.warn(note, DataWarning, stacklevel=2)
    factors = {**factors, **by_unit}
    dataset = Dataset._new(
        validated_frame(
            frame,
            check=check,
            regular=resample is None,
            where=where,
            scale=factors,
            counters=joules,
            offsets=offsets,
        )
    )
    dataset = dataset if resample is None else dataset.resample(resample)
    note = gap_note(dataset) if check else None
    if note is not None:
        warnings.warn(note, DataWarning, stacklevel=2)
    return dataset


def as_dataset(obj: object, *, what: str = "data", **load_kwargs: object) -> Dataset:
    """The :class:`Dataset` for what a user passed as data.

    Accepts a :class:`Dataset` (returned as it is, or passed through :func:`load` when
    ``load_kwargs`` are given), a pandas DataFrame with a DatetimeIndex or a ``time`` column,
    or the path of a CSV file (``str`` or ``os.PathLike``), both read with :func:`load`.

    Args:
        obj: the data.
        what: what the argument is, for the messages (``"data"``, ``"valid"``...).
        load_kwargs: keyword arguments of :func:`load` (``columns``, ``resample``, ``sep``...).

    Raises:
        TypeError: ``obj`` is something else (a numpy array, ``None``, a list, a dict...); the
            message says what it takes.
        DataError: from :func:`load`.
    """
    if isinstance(obj, Dataset):
        return load(obj.frame, **load_kwargs) if load_kwargs else obj  # type: ignore[arg-type]
    if isinstance(obj, (pd.DataFrame, str, os.PathLike)):
        return load(obj, **load_kwargs)  # type: ignore[arg-type]
    got = "None" if obj is None else f"a {type(obj).__module__}.{type(obj).__qualname__}"
    got = got.replace("builtins.", "")
    hint = ""
    if hasattr(obj, "shape") and hasattr(obj, "dtype"):
        hint = "; for arrays use jaxbox.data.Dataset.from_arrays(time_s, {'T_zon': ..., ...})"
    elif isinstance(obj, Mapping):
        hint = "; for a dict of columns use jaxbox.data.Dataset.from_arrays(time_s, columns)"
    raise TypeError(
        f"{what} must be a jaxbox Dataset, a pandas DataFrame with a DatetimeIndex or a 'time' "
        f"column, or the path of a CSV file; got {got}{hint}."
    )
