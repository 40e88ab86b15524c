"""The :class:`Dataset` value object: measured signals on a regular time grid."""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ._checks import (
    Where,
    check_finite,
    check_kelvin,
    check_order,
    check_regular,
    fill_missing_rows,
    fmt_seconds,
    irregular_position,
    median_step,
    segment_slices,
    to_float,
)
from ._counters import counters_to_power
from ._errors import DataError, list_names
from ._plausible import STUCK_HOURS, check_plausibility
from ._resample import resample_mean
from ._signals import CONSTANT
from ._suggest import suggestion_text

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["Dataset"]

TimeLike = str | pd.Timestamp | np.datetime64


def _position(i: int) -> str:
    return f"row {i}"


def _names(names: str | Iterable[str]) -> list[str]:
    return [names] if isinstance(names, str) else list(names)


def validated_frame(
    frame: pd.DataFrame,
    *,
    check: bool,
    regular: bool = True,
    where: Where = _position,
    scale: Mapping[str, float] | None = None,
    counters: Mapping[str, float] | None = None,
    offsets: Mapping[str, float] | None = None,
) -> pd.DataFrame:
    """A fresh float64 copy of ``frame`` (DatetimeIndex named ``time``) after the checks.

    Always: unique string column names, strictly increasing time stamps, numeric values, at
    least two samples, no infinite value or absurd magnitude. With ``check``: no temperature in
    kelvin and, with ``regular``, a constant sampling step; rows missing from that step's grid
    (every step a whole multiple of the median step) are put back as rows of NaN. NaN values
    are gaps, kept (see :mod:`jaxbox.data._gaps`). ``scale`` (column -> factor) multiplies
    columns before the value checks, and ``offsets`` (column -> value) is added after it (a
    unit converted: °F to °C, :mod:`jaxbox.data._units`); ``counters`` (column -> joules per
    unit) turns cumulative energy meters into the mean power of each interval
    (:mod:`jaxbox.data._counters`; on a regular grid, an interval over missing rows is a gap)
    and drops the first row, which only gives their starting readings.
    """
    if not isinstance(frame, pd.DataFrame):
        raise DataError(
            f"expected a pandas DataFrame, got {type(frame).__name__}; use jaxbox.data.load "
            "for files or Dataset.from_arrays for numpy arrays."
        )
    if not isinstance(frame.index, pd.DatetimeIndex):
        raise DataError(
            "the DataFrame has no DatetimeIndex; use jaxbox.data.load(frame, time='your_column') "
            "to take the time stamps from a column."
        )
    columns = [str(name) for name in frame.columns]
    seen: set[str] = set()
    for name in columns:
        if name in seen:
            raise DataError(f"two columns are named {name!r}; rename or drop one of them.")
        seen.add(name)
    if len(frame) < 2:
        raise DataError(
            f"the data have {len(frame)} sample(s); at least two are needed to know the step."
        )
    index = pd.DatetimeIndex(frame.index, freq=None, name="time").as_unit("ns")
    check_order(index, where)
    grid = None
    if check and regular and irregular_position(index) is not None:
        grid = fill_missing_rows(index, median_step(index))
        if grid is None:
            check_regular(index, where)
    values = to_float(frame.set_axis(columns, axis=1).set_axis(index, axis=0), where)
    for name, factor in (scale or {}).items():
        values[name] = values[name] * factor
    for name, offset in (offsets or {}).items():
        values[name] = values[name] + offset
    if counters:
        longest = median_step(index) if grid is not None else None
        values = counters_to_power(values, counters, longest=longest)
    check_finite(values)
    if check:
        check_kelvin(values)
    if grid is not None:  # rows missing from the regular grid: gaps of NaN
        values = values.reindex(grid)
    if counters:  # the first row only gives the counters' starting readings
        values = values.iloc[1:]
    return values


class Dataset:
    """Measured signals on a regular time grid: an immutable wrapper around a DataFrame.

    The index is a DatetimeIndex named ``time``; every column is float64 in the unit of its
    canonical name (see :data:`jaxbox.data.SIGNALS`: °C, W, W/m²). Other columns are kept as
    they are. Build one with :func:`jaxbox.data.load`, :meth:`from_arrays` or
    ``Dataset(frame)`` for a DataFrame that already has a DatetimeIndex. Every method returns a
    new Dataset; ``frame`` and ``array`` return copies.

    Gaps are kept: NaN values, and rows missing from the grid put back as rows of NaN. A window
    prepared for a fit (:func:`jaxbox.data.prepare_window`) or separate periods joined
    (:func:`jaxbox.data.concat_periods`) hold :attr:`segments`: their time stamps jump over the
    cuts.
    """

    __slots__ = ("_frame", "_step", "_memo")
    _frame: pd.DataFrame
    _step: float
    _memo: dict  # values derived from the frame, computed once (see first_values)

    def __init__(self, frame: pd.DataFrame, *, check: bool = True) -> None:
        values = validated_frame(frame, check=check)
        object.__setattr__(self, "_frame", values)
        object.__setattr__(self, "_step", median_step(values.index))
        object.__setattr__(self, "_memo", {})

    @classmethod
    def _new(cls, frame: pd.DataFrame, step: float | None = None) -> Dataset:
        """Wrap an already validated frame without checking it again."""
        self = object.__new__(cls)
        object.__setattr__(self, "_frame", frame)
        object.__setattr__(
            self, "_step", median_step(frame.index) if len(frame) > 1 or step is None else step
        )
        object.__setattr__(self, "_memo", {})
        return self

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError("a Dataset is immutable; with_columns, slice, ... return new ones")

    def __delattr__(self, name: str) -> None:
        raise AttributeError("a Dataset is immutable")

    def __reduce__(self) -> tuple[Any, ...]:
        return (Dataset._new, (self._frame, self._step))

    # -- construction ---------------------------------------------------------------------------

    @classmethod
    def from_arrays(
        cls,
        time: Any,
        signals: Mapping[str, Any],
        start: TimeLike = "2000-01-01",
        *,
        check: bool = True,
    ) -> Dataset:
        """Build a dataset from numpy arrays (handy for synthetic data).

        Args:
            time: seconds since ``start`` (1-D array, regular step), or a DatetimeIndex.
            signals: name -> 1-D array of the same length (units of the canonical names: °C,
                W, W/m²).
            start: time stamp of ``time == 0`` when ``time`` is in seconds.
            check: run the checks of :func:`jaxbox.data.load` (regular step, rows missing from
                it put back as NaN, no kelvin, ...).
        """
        if isinstance(time, pd.DatetimeIndex):
            index = time
        else:
            seconds = np.asarray(time, dtype=np.float64)
            if seconds.ndim != 1:
                raise DataError(f"time must be a 1-D array of seconds, got shape {seconds.shape}.")
            index = pd.Timestamp(start) + pd.to_timedelta(seconds, unit="s")
        data = {}
        for name, values in signals.items():
            array = np.asarray(values, dtype=np.float64)
            if array.ndim == 0:
                array = np.full(len(index), float(array))
            if array.shape != (len(index),):
                raise DataError(
                    f"signal {name!r} has shape {array.shape} but there are {len(index)} time "
                    "stamps; give one value per time stamp."
                )
            data[name] = array
        return cls(pd.DataFrame(data, index=pd.DatetimeIndex(index, name="time")), check=check)

    def with_columns(self, columns: Mapping[str, Any] | None = None, /, **arrays: Any) -> Dataset:
        """A new dataset with columns added or replaced.

        Give a mapping and/or keywords ``name=values``; values are 1-D arrays with one value
        per sample, or scalars (repeated). Units are those of the canonical names. The values
        are checked as ``Dataset(frame)`` checks them: NaN is a gap, kept (as the constructor
        keeps it); infinite or absurd values, text and temperatures in kelvin are refused,
        naming the column.
        """
        if columns is not None and not isinstance(columns, Mapping):
            raise DataError(
                f"with_columns takes a mapping {{name: values}} and/or keywords name=values, got "
                f"{type(columns).__name__}"
            )
        new = {**(columns or {}), **arrays}
        frame = self._frame.copy()
        for name, values in new.items():
            try:
                array = np.asarray(values, dtype=np.float64)
            except (TypeError, ValueError) as err:
                raise DataError(
                    f"column {str(name)!r} must hold numbers (NaN for a gap), one per sample: {err}"
                ) from None
            if array.ndim == 0:
                array = np.full(len(frame), float(array))
            if array.shape != (len(frame),):
                raise DataError(
                    f"column {name!r} has shape {array.shape} but the data have {len(frame)} "
                    "samples; give one value per sample."
                )
            frame[str(name)] = array
        added = frame[[str(name) for name in new]]
        check_finite(added)  # as the constructor: NaN values are gaps, kept
        check_kelvin(added)
        return Dataset._new(frame, self._step)

    # -- views ----------------------------------------------------------------------------------

    @property
    def frame(self) -> pd.DataFrame:
        """A copy of the data (DatetimeIndex ``time``, float64 columns)."""
        return self._frame.copy(deep=True)

    @property
    def index(self) -> pd.DatetimeIndex:
        """The time stamps (DatetimeIndex named ``time``)."""
        return self._frame.index  # type: ignore[return-value]

    @property
    def columns(self) -> tuple[str, ...]:
        """Column names."""
        return tuple(str(name) for name in self._frame.columns)

    def __len__(self) -> int:
        return len(self._frame)

    def __contains__(self, name: object) -> bool:
        return name == CONSTANT or name in self._frame.columns

    def __getitem__(self, name: str) -> np.ndarray:
        """One column as a new 1-D float64 array (``"one"``: the constant 1, see
        :data:`~jaxbox.data.CONSTANT`)."""
        self.require([name])
        if name == CONSTANT and name not in self._frame.columns:
            return np.ones(len(self._frame))
        return self._frame[name].to_numpy(dtype=np.float64, copy=True)

    @property
    def step(self) -> float:
        """Sampling step [s] (the median step when the data are not regular)."""
        return self._step

    @property
    def t(self) -> np.ndarray:
        """Time [s] since the first sample, float64, shape (N,)."""
        ns = self._frame.index.asi8
        return (ns - ns[0]).astype(np.float64) / 1e9

    @property
    def start(self) -> pd.Timestamp:
        """First time stamp."""
        return self._frame.index[0]

    @property
    def end(self) -> pd.Timestamp:
        """Last time stamp."""
        return self._frame.index[-1]

    def __repr__(self) -> str:
        names = self.columns
        shown = ", ".join(names[:8]) + (f", ... ({len(names) - 8} more)" if len(names) > 8 else "")
        span = self.end - self.start
        return (
            f"Dataset({len(self)} samples, step {fmt_seconds(self._step)}, "
            f"{self.start} to {self.end} ({span}), columns: {shown or '(none)'})"
        )

    def equals(self, other: object) -> bool:
        """Same time stamps, columns and values (NaN equal to NaN)."""
        return isinstance(other, Dataset) and self._frame.equals(other._frame)

    # -- access ---------------------------------------------------------------------------------

    def require(self, names: str | Iterable[str], what: str | None = None) -> None:
        """Raise :class:`DataError` unless every column in ``names`` is present.

        ``what`` completes the message, e.g. ``what="model 'TiTe'"`` gives "required by model
        'TiTe'".
        """
        missing = [n for n in _names(names) if n != CONSTANT and n not in self._frame.columns]
        if not missing:
            return
        plural = "s" if len(missing) > 1 else ""
        listed = ", ".join(repr(name) for name in missing)
        close = [
            match
            for name in missing
            for match in difflib.get_close_matches(name, self.columns, n=1, cutoff=0.7)
        ]
        hint = f" (did you mean {list_names(close)}?)" if close else ""
        mapping = ", ".join(f"{name!r}: 'your_col'" for name in missing)
        raise DataError(
            f"the data has no column{plural} {listed}"
            f"{f' required by {what}' if what else ''}{hint}; available: "
            f"{list_names(self.columns)}; map yours with columns={{{mapping}}} in "
            f"jaxbox.data.load{suggestion_text(missing, self.columns)}."
        )

    def array(self, names: str | Iterable[str]) -> np.ndarray:
        """Columns ``names`` as a new C-contiguous float64 array of shape (N, len(names)); the
        name ``"one"`` (:data:`~jaxbox.data.CONSTANT`) gives a column of ones."""
        names = _names(names)
        self.require(names)
        if CONSTANT in names and CONSTANT not in self._frame.columns:
            out = np.ones((len(self._frame), len(names)), dtype=np.float64)
            real = [i for i, n in enumerate(names) if n != CONSTANT]
            if real:
                out[:, real] = self._frame[[names[i] for i in real]].to_numpy(dtype=np.float64)
            return out
        return np.array(self._frame[names].to_numpy(dtype=np.float64), dtype=np.float64, order="C")

    def first_values(self, names: str | Iterable[str]) -> dict[str, float]:
        """The first finite value of each column of ``names`` (a column missing, or without a
        finite value, is left out), each column read once: a Dataset does not change."""
        out = {}
        for name in _names(names):
            key = ("first", name)
            if key not in self._memo:
                value = None
                if name in self._frame.columns:
                    values = self._frame[name].to_numpy(dtype=np.float64)
                    ok = np.flatnonzero(np.isfinite(values))
                    value = float(values[ok[0]]) if ok.size else None
                self._memo[key] = value
            if self._memo[key] is not None:
                out[name] = self._memo[key]
        return out

    # -- new datasets ---------------------------------------------------------------------------

    def resample(self, rule: str | pd.Timedelta) -> Dataset:
        """Average onto a coarser regular grid (``rule`` such as ``"1h"``).

        Mean over right-closed intervals labelled at their right edge (each sample stamps the
        end of its averaging interval); an incomplete interval at the start or end is dropped,
        an interval without any value of a column is a gap (NaN).
        """
        return Dataset._new(resample_mean(self._frame, rule, self._step))

    def _bound(self, value: TimeLike, name: str) -> pd.Timestamp:
        try:
            stamp = pd.Timestamp(value)
        except (ValueError, TypeError):
            raise DataError(f"cannot read {name}={value!r} as a time stamp.") from None
        tz = self._frame.index.tz
        if tz is not None and stamp.tzinfo is None:
            stamp = stamp.tz_localize(tz)
        elif tz is None and stamp.tzinfo is not None:
            raise DataError(f"{name}={value!r} has a time zone but the data have none; drop it.")
        return stamp

    def slice(self, start: TimeLike | None = None, end: TimeLike | None = None) -> Dataset:
        """Samples with ``start <= time <= end`` (both inclusive; ``None`` = open).

        A date without a time means midnight at the start of that day.
        """
        keep = np.ones(len(self), dtype=bool)
        lo = hi = None
        if start is not None:
            lo = self._bound(start, "start")
            keep &= self._frame.index >= lo
        if end is not None:
            hi = self._bound(end, "end")
            keep &= self._frame.index <= hi
        if lo is not None and hi is not None and lo > hi:
            raise DataError(f"start {lo} is after end {hi}.")
        if not keep.any():
            raise DataError(
                f"no samples between {lo if lo is not None else 'the start'} and "
                f"{hi if hi is not None else 'the end'}; the data span {self.start} to "
                f"{self.end}."
            )
        return Dataset._new(self._frame[keep].copy(), self._step)

    def split(self, at: TimeLike | None = None, fraction: float = 0.5) -> tuple[Dataset, Dataset]:
        """Split into (identification, validation) parts.

        With ``at``: identification ``time <= at``, validation ``time > at``. Otherwise the first
        ``floor(N * fraction)`` samples and the rest (two equal halves by default).
        """
        n = len(self)
        if at is not None:
            stamp = self._bound(at, "at")
            first = int(np.searchsorted(self._frame.index.asi8, stamp.as_unit("ns").value, "right"))
        else:
            if not 0.0 < fraction < 1.0:
                raise DataError(f"fraction must be between 0 and 1 (exclusive), got {fraction}.")
            first = int(np.floor(n * fraction))
        if first == 0 or first == n:
            where = f"at {at}" if at is not None else f"with fraction {fraction}"
            raise DataError(
                f"splitting {where} leaves one part empty; the data span {self.start} to "
                f"{self.end} ({n} samples)."
            )
        frame = self._frame
        return (
            Dataset._new(frame.iloc[:first].copy(), self._step),
            Dataset._new(frame.iloc[first:].copy(), self._step),
        )

    @property
    def segments(self) -> tuple[tuple[int, int], ...]:
        """``((start, stop), …)``: runs of samples at the regular step. A dataset holds one
        segment unless gaps were cut out of it (:func:`jaxbox.data.prepare_window`) or periods
        joined (:func:`jaxbox.data.concat_periods`): its time stamps then jump between them."""
        return segment_slices(self._frame.index, self._step)

    def windows(
        self,
        train: tuple | None = None,
        valid: tuple | bool | None = None,
        *,
        names: tuple[str, str] = ("train", "valid"),
    ) -> tuple[Dataset, Dataset | None]:
        """The identification and validation windows, ``(ident, valid)``.

        Args:
            train: ``(start, end)`` of the identification window (inclusive; a ``None`` side is
                open); default the first half of the data, everything before ``valid``, or all
                of the data with ``valid=False``.
            valid: ``(start, end)`` of the validation window; default everything after the
                identification window; ``False`` for none (``valid`` is then ``None``).
            names: how the two arguments are called in messages (the command line passes
                ``("--train", "--validate")``).

        A time stamp shared by both windows (``--train A..B --validate B..C``) belongs to the
        first one: the validation window starts at the next sample.

        Raises:
            DataError: an empty window, a validation window that does not start after the
                identification window or leaves nothing after the shared edge.
        """

        def cut(span, name):
            try:
                return self.slice(*span)
            except DataError as err:
                raise DataError(f"{name} {_span_text(span)}: {err}") from None

        if train is None and valid is None:
            return self.split()
        if train is None and valid is False:
            return self, None
        val = cut(valid, names[1]) if valid is not None and valid is not False else None
        if train is not None:
            ident = cut(train, names[0])
        else:
            before = self.index[self.index < val.start]
            if len(before) == 0:
                raise DataError(
                    f"{names[1]} {_span_text(valid)}: no data before the validation window to "
                    f"identify on (the data start at {self.start}); give {names[0]} or start "
                    f"{names[1]} later."
                )
            ident = self.slice(None, before[-1])
        if valid is False:
            return ident, None
        if val is None:
            rest = self.index[self.index > ident.end]
            if len(rest) == 0:
                raise DataError(
                    f"no data left after the identification window for validation (the data "
                    f"end at {self.end}); shorten {names[0]} or give {names[1]}."
                )
            return ident, self.slice(rest[0], None)
        if val.start == ident.end:  # the shared edge belongs to the first window
            if len(val) == 1:
                raise DataError(
                    f"{names[1]} {_span_text(valid)} holds only the last sample of the "
                    f"identification window ({ident.end}); a shared edge belongs to the first "
                    f"window: extend {names[1]}."
                )
            val = self.slice(val.index[1], val.end)
        if val.start < ident.end:
            raise DataError(
                f"the validation window ({val.start} .. {val.end}) must start after the "
                f"identification window ends ({ident.end}); adjust {names[0]} or {names[1]}."
            )
        return ident, val

    def check_plausible(
        self,
        *,
        overrides: Mapping[str, tuple[float, float]] | None = None,
        columns: str | Iterable[str] | None = None,
        what: str | None = None,
        stuck_hours: float | None = STUCK_HOURS,
        spike_k: float = 10.0,
        warn: bool = True,
        allow: object = None,
    ) -> tuple[str, ...]:
        """Refuse physically implausible signals; return the warnings.

        See :func:`jaxbox.data.check_plausibility` (ranges per kind of signal with
        ``overrides={column: (lo, hi)}``, kelvin/°F/kW mix-ups, spikes, jumps, stuck sensors).
        Apply it to the windows actually used, e.g. ``ident.check_plausible()``.

        Raises:
            DataError: naming the column, the time stamps and what to do.
        """
        return check_plausibility(
            self,
            overrides=overrides,
            columns=columns,
            what=what,
            stuck_hours=stuck_hours,
            spike_k=spike_k,
            warn=warn,
            allow=allow,
        )

    def plot(self, columns: str | Iterable[str] | None = None, ax: Axes | None = None) -> Figure:
        """Plot the signals against time; returns a matplotlib Figure.

        Temperatures (°C), powers (W) and irradiances (W/m²) go on separate stacked axes,
        other columns on a last one. With ``ax``, everything goes on that one axes.
        """
        from ._plot import plot_dataset

        names = list(self.columns) if columns is None else _names(columns)
        self.require(names)
        return plot_dataset(self._frame, names, ax)


def _span_text(span) -> str:
    start, end = span
    return f"{'' if start is None else start}..{'' if end is None else end}"
