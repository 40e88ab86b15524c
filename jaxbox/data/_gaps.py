"""Gaps in monitoring data: missing rows, missing values, and the segments they leave.

A :class:`~jaxbox.data.Dataset` keeps its gaps: rows missing from a regular grid are put back as
rows of NaN when the data are loaded, and NaN values stay NaN. They are judged only in the
windows actually used, by :func:`prepare_window`:

* an **output** gap (a measured output is NaN) is kept: the sample is masked (weight 0) in the
  cost, the error metrics and the residual tests, whatever its length (the simulation does not
  need the outputs);
* an **input** gap of at most ``max_gap`` seconds (default one hour; the duration of a gap is its
  number of missing samples times the step) is filled by linear interpolation in time, with a
  :class:`~jaxbox.data.DataWarning` that names the column and the time span;
* a longer input gap (and an input gap at either end of the window, which cannot be
  interpolated) is cut out: the window splits into **segments**. The prepared dataset holds the
  segments one after the other; its time stamps jump over each cut. The segments share the
  model parameters and each starts from initial states of its own (several experiments in one
  estimation).

:func:`concat_periods` joins separate periods of one building the same way.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence

import numpy as np
import pandas as pd

from ._checks import fill_missing_rows, segment_slices
from ._errors import DataError, DataWarning
from ._signals import signal_base

__all__ = [
    "DEFAULT_MAX_GAP",
    "MAX_CUTS",
    "MIN_SEGMENT",
    "concat_periods",
    "duration_seconds",
    "fill_missing_rows",
    "gap_note",
    "prepare_window",
    "segment_slices",
]

#: Input gaps up to this duration [s] are interpolated; longer ones split the window.
DEFAULT_MAX_GAP = 3600.0
#: The fewest samples of a segment; shorter pieces between gaps are dropped with a warning.
MIN_SEGMENT = 4
#: More interpolated gaps than this in the same input(s) are reported in one summary note.
MAX_GAP_NOTES = 5
#: More cuts than this in one window are refused: each segment's initial states are estimated
#: on their own, so a record with a sample lost every few hours (a wireless sensor) would be
#: fitted as dozens of short experiments, slowly and poorly determined.
MAX_CUTS = 20
_TOL = 1e-6


def duration_seconds(value, what: str = "max_gap") -> float:
    """Seconds of a duration given as seconds (a number), a ``pandas.Timedelta`` or text such
    as ``"2h"``, ``"90min"``; must be ≥ 0."""
    if isinstance(value, bool):
        raise DataError(f"{what} must be a duration such as 3600 (seconds) or '1h', got {value!r}")
    if isinstance(value, int | float | np.integer | np.floating):
        seconds = float(value)
    else:
        try:
            seconds = float(pd.Timedelta(value) / pd.Timedelta(seconds=1))
        except (ValueError, TypeError):
            raise DataError(
                f"cannot read {what}={value!r} as a duration; give seconds or text such as '1h' "
                "or '30min'."
            ) from None
    if not math.isfinite(seconds) or seconds < 0:
        raise DataError(f"{what} must be a finite duration ≥ 0, got {value!r}.")
    return seconds


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop), …]`` of the runs of True in a 1-D boolean array."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _duration(n: int, step: float) -> str:
    """``n`` samples of ``step`` seconds as ``"2 h"`` or ``"30 min"``."""
    minutes = n * step / 60
    return f"{minutes / 60:g} h" if minutes >= 60 else f"{minutes:g} min"


def _span(index: pd.DatetimeIndex, a: int, b: int, step: float) -> str:
    """``"from A to B (n samples, 2 h)"`` or ``"at A (1 sample, 1 h)"``."""
    n = b - a
    where = f"at {index[a]}" if n == 1 else f"from {index[a]} to {index[b - 1]}"
    return f"{where} ({n} sample{'s' if n > 1 else ''}, {_duration(n, step)})"


def _filled_summary(
    what: str, names: tuple[str, ...], runs: list[tuple[int, int]], index, step: float
) -> str:
    """One note for many interpolated gaps of the same input(s): how many, how long, where."""
    runs = sorted(runs)
    lengths = [b - a for a, b in runs]
    which = f"input{'s' if len(names) > 1 else ''} {', '.join(map(repr, names))}"
    shortest, longest = _duration(min(lengths), step), _duration(max(lengths), step)
    size = shortest if shortest == longest else f"{shortest} to {longest}"
    return (
        f"{what}: interpolated {which} in {len(runs)} gaps of {size} ({sum(lengths)} samples in "
        f"all), the first at {index[runs[0][0]]}, the last at {index[runs[-1][0]]}"
    )


def gap_note(data, columns: Sequence[str] | None = None) -> str | None:
    """One line noting the gaps of ``data`` (NaN values, per column), or ``None``."""
    frame = data._frame if columns is None else data._frame[list(columns)]
    holes = frame.isna()
    counts = holes.sum()
    bad = [str(c) for c in frame.columns if counts[c] > 0]
    if not bad:
        return None
    # The signals the models read (canonical names) first; other columns only counted.
    known = [c for c in bad if signal_base(c) is not None]
    named = known if known else bad
    others = len(bad) - len(named)
    listed = ", ".join(
        f"{c!r} ({int(counts[c])}, the first at {frame.index[holes[c].to_numpy()][0]})"
        for c in named[:6]
    )
    more = f", … ({len(named) - 6} more)" if len(named) > 6 else ""
    if others:
        more += f" (and {others} other column{'s' if others > 1 else ''} no model reads)"
    note = (
        f"the data have gaps: missing samples in {listed}{more}; in the windows used, input gaps "
        "are interpolated up to max_gap (command line --max-gap) and split the window into "
        "segments beyond, output gaps are masked."
    )
    skipped = _skipped_hour(frame.index, holes.all(axis=1).to_numpy())
    if skipped is not None:
        note += (
            f" The hour missing on Sunday {skipped} is where the clocks go forward to daylight "
            "saving time: if the stamps are local clock time, pass the time zone, e.g. "
            "tz='Europe/Berlin' (command line: --tz Europe/Berlin)."
        )
    return note


def _skipped_hour(index, empty: np.ndarray) -> str | None:
    """The first Sunday of March, April, September or October on which the rows missing from
    naive time stamps ``index`` (``empty``: every column missing) are exactly one clock hour
    before 04:00, the hour local clocks skip at the start of daylight saving time; else
    ``None``."""
    if index.tz is not None or not empty.any():
        return None
    days = index.normalize()
    hours = np.asarray(index.hour)
    for day in pd.unique(days[empty]):
        if day.day_of_week != 6 or day.month not in (3, 4, 9, 10):
            continue
        on = np.asarray(days == day)
        missing = on & empty
        hour = hours[missing]
        if hour.max() != hour.min() or hour[0] > 3:
            continue
        clock = on & (hours == hour[0])
        around = on & ~empty & ((hours == hour[0] - 1) | (hours == hour[0] + 1))
        if np.array_equal(missing, clock) and around.sum() >= 2:
            return str(day.date())
    return None


def prepare_window(
    data,
    inputs: Sequence[str],
    outputs: Sequence[str],
    *,
    max_gap: float | str = DEFAULT_MAX_GAP,
    what: str = "the data",
    warn: bool = True,
):
    """The window ``data`` ready for simulation: short input gaps interpolated, long ones cut
    out (segments), output gaps left as NaN (masked downstream).

    Args:
        data: a :class:`~jaxbox.data.Dataset` (a window of the data, possibly already holding
            segments).
        inputs, outputs: the model's input and output columns.
        max_gap: the longest input gap [s] (or text such as ``"2h"``) filled by linear
            interpolation; the duration of a gap is its number of missing samples times the step.
        what: what the window is, for the messages (``"identification data"``…).
        warn: issue a :class:`~jaxbox.data.DataWarning` per interpolated gap and cut.

    Returns:
        A new Dataset (the same object when there is nothing to do) whose time stamps jump over
        each cut; its segments are :attr:`Dataset.segments`.

    Raises:
        DataError: no segment of at least :data:`MIN_SEGMENT` samples is left, an output is
            missing in every sample of the window, or more than :data:`MAX_CUTS` input gaps
            are longer than ``max_gap`` (the message names the ``max_gap`` that interpolates
            most of them).
    """
    from ._dataset import Dataset

    limit = duration_seconds(max_gap)
    data.require(list(inputs) + list(outputs))
    inputs = [name for name in inputs if name in data.columns]  # not the virtual constant
    step = data.step
    frame = data._frame
    keep = np.ones(len(frame), dtype=bool)
    filled = {}
    found: dict[tuple[str, int, int], list[str]] = {}  # (what, start, stop) -> columns
    for a0, b0 in segment_slices(frame.index, step):
        for name in inputs:
            values = frame[name].to_numpy()[a0:b0]
            missing = np.isnan(values)
            if not missing.any():
                continue
            column = values.copy()
            for a, b in _runs(missing):
                if a == 0 or b == len(values):
                    keep[a0 + a : a0 + b] = False
                    kind = "edge"
                elif (b - a) * step <= limit * (1 + _TOL):
                    x = np.arange(len(values))
                    ok = ~missing
                    column[a:b] = np.interp(x[a:b], x[ok], values[ok])
                    kind = "filled"
                else:
                    keep[a0 + a : a0 + b] = False
                    kind = "cut"
                found.setdefault((kind, a0 + a, a0 + b), []).append(name)
            if name not in filled:
                filled[name] = frame[name].to_numpy().copy()
            filled[name][a0:b0] = column
    notes = []
    filled_runs: dict[tuple[str, ...], list[tuple[int, int]]] = {}
    for (kind, a, b), names in found.items():
        if kind == "filled":
            filled_runs.setdefault(tuple(names), []).append((a, b))
    summarised = {key for key, runs in filled_runs.items() if len(runs) > MAX_GAP_NOTES}
    for key in summarised:
        notes.append(_filled_summary(what, key, filled_runs[key], frame.index, step))
    for (kind, a, b), names in sorted(found.items(), key=lambda item: item[0][1:]):
        which = f"input{'s' if len(names) > 1 else ''} {', '.join(map(repr, names))}"
        span = _span(frame.index, a, b, step)
        if kind == "filled":
            if tuple(names) not in summarised:
                notes.append(f"{what}: interpolated {which} {span}")
        elif kind == "edge":
            notes.append(f"{what}: {which} missing at an end of the window {span}: cut off")
        else:
            notes.append(
                f"{what}: {which} missing {span}, longer than max_gap ({limit / 3600:g} h): "
                "the window splits into segments there"
            )
    cuts = sorted((b - a) * step for (kind, a, b) in found if kind == "cut")
    if len(cuts) > MAX_CUTS:
        raise DataError(_too_many_cuts(what, cuts, limit, step))
    if not filled and keep.all():
        out = data
    else:
        new = frame.copy()
        for name, column in filled.items():
            new[name] = column
        new = new[keep]
        if new.empty:
            empty = [n for n in inputs if not np.isfinite(frame[n].to_numpy(float)).any()]
            if empty:
                raise DataError(
                    f"input{'s' if len(empty) > 1 else ''} {', '.join(map(repr, empty))} "
                    f"{'have' if len(empty) > 1 else 'has'} no value in {what} ({data.start} .. "
                    f"{data.end}): give the values, choose another window, or leave the column "
                    "out of the data (a --map of a column without values: drop it) so that "
                    "no model reads it."
                )
            raise DataError(
                f"{what} ({data.start} .. {data.end}) holds no sample with every input of the "
                f"model ({', '.join(map(repr, inputs))}); choose another window."
            )
        out = Dataset._new(new, step)
    # drop segments too short to use, and segments without any measured output
    pieces = segment_slices(out.index, step)
    ys = out._frame[list(outputs)].to_numpy()
    drop = np.zeros(len(out), dtype=bool)
    for a, b in pieces:
        short = b - a < MIN_SEGMENT
        blind = not np.isfinite(ys[a:b]).any()
        if short or blind:
            drop[a:b] = True
            why = f"fewer than {MIN_SEGMENT} samples" if short else "no measured output in it"
            notes.append(f"{what}: dropped the segment {_span(out.index, a, b, step)} ({why})")
    if drop.any():
        if drop.all():
            raise DataError(
                f"{what} ({data.start} .. {data.end}) leaves no segment of at least "
                f"{MIN_SEGMENT} samples with measured outputs between its gaps; choose another "
                "window or a longer max_gap (command line --max-gap)."
            )
        out = Dataset._new(out._frame[~drop].copy(), step)
    for name in outputs:
        if not np.isfinite(out._frame[name].to_numpy()).any():
            raise DataError(
                f"output {name!r} is missing in every sample of {what} ({data.start} .. "
                f"{data.end}); choose another window."
            )
    if warn:
        for note in notes:
            warnings.warn(note + ".", DataWarning, stacklevel=3)
    return out


def _too_many_cuts(what: str, cuts: list[float], limit: float, step: float) -> str:
    """Why a window with more than :data:`MAX_CUTS` input gaps longer than ``max_gap`` is
    refused, and the ``max_gap`` that would interpolate all but a few of them."""
    keep = MAX_CUTS // 2  # gaps left to cut at the suggested max_gap
    longest = cuts[-keep - 1]  # the longest gap that it interpolates
    hours = longest / 3600.0
    text = f"{hours:g}h" if hours == int(hours) else f"{round(longest / 60):d}min"
    return (
        f"{what} would split into {len(cuts) + 1} segments at {len(cuts)} input gaps longer "
        f"than max_gap ({limit / 3600:g} h; {_duration(round(cuts[0] / step), step)} to "
        f"{_duration(round(cuts[-1] / step), step)}), each segment with initial states of its "
        f"own: interpolate the short gaps, max_gap='{text}' (command line --max-gap {text}: "
        f"{len(cuts) - keep} of the {len(cuts)} gaps are that short), or average onto a "
        "coarser grid (resample=, --resample)"
    )


def concat_periods(periods: Sequence) -> object:
    """Separate periods of one building (Datasets at the same step, in time order, not
    overlapping) as one Dataset whose time stamps jump between them: each period is a segment
    of its own (unless it follows the previous one by exactly one step)."""
    from ._dataset import Dataset

    items = list(periods)
    if not items:
        raise DataError("no period given; pass a list of Datasets.")
    for i, item in enumerate(items):
        if not isinstance(item, Dataset):
            raise TypeError(
                f"period {i} must be a jaxbox Dataset, got {type(item).__name__}; load it with "
                "jaxbox.data.load first"
            )
    step = items[0].step
    for i, item in enumerate(items[1:], start=1):
        if abs(item.step - step) > 1e-6 * step:
            raise DataError(
                f"period {i} has a step of {item.step:g} s but period 0 {step:g} s; resample "
                "them to the same step."
            )
        if item.start <= items[i - 1].end:
            raise DataError(
                f"period {i} starts at {item.start}, not after period {i - 1} ends "
                f"({items[i - 1].end}); give the periods in time order, without overlap."
            )
    names = list(items[0].columns)
    for i, item in enumerate(items[1:], start=1):
        if list(item.columns) != names:
            missing = [c for c in names if c not in item.columns]
            if missing:
                raise DataError(
                    f"period {i} has no column(s) {', '.join(map(repr, missing))} that period 0 "
                    "has; give every period the same columns."
                )
    frame = pd.concat([item._frame[names] for item in items])
    return Dataset._new(frame, step)
