"""Checks of what a user passes to the stochastic API: datasets, numbers, initial covariances.

Every misuse raises a :class:`~jaxbox.fit.FitError` (a ``ValueError``) or a ``TypeError`` that
names the argument and says what to give instead, before anything is compiled.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

import numpy as np
import pandas as pd

from ..data import Dataset, as_dataset
from ..data._checks import fmt_seconds, irregular_position
from ..fit._problem import FitError, number

__all__ = ["as_data", "as_datasets", "regular_step", "number", "x0_stds"]


def as_data(data, what: str = "data") -> Dataset:
    """``data`` as a :class:`~jaxbox.data.Dataset` (a DataFrame or a CSV path is loaded, see
    :func:`jaxbox.data.as_dataset`); anything else is a ``TypeError`` naming ``what``."""
    return as_dataset(data, what=what)


def as_datasets(datasets, what: str = "datasets") -> list[Dataset]:
    """A sequence of datasets as a list of :class:`~jaxbox.data.Dataset`; one dataset given
    where several are expected is a ``TypeError`` (it is not a sequence of datasets)."""
    if isinstance(datasets, Dataset | pd.DataFrame | str | os.PathLike):
        raise TypeError(
            f"{what} must be a list of datasets, got one {type(datasets).__name__}; pass "
            f"[data], or use fit_ml for a single dataset"
        )
    try:
        items = list(datasets)
    except TypeError:
        raise TypeError(
            f"{what} must be a list of datasets, got {type(datasets).__name__}"
        ) from None
    return [as_data(d, f"{what}[{i}]") for i, d in enumerate(items)]


def regular_step(data: Dataset) -> float:
    """The sampling step [s] of ``data``, which must be regular: the filter discretises the
    model once for one step, so a series whose time stamps jump (segments joined by
    :func:`jaxbox.data.concat_periods`, gaps cut by :func:`jaxbox.data.prepare_window`, or an
    irregular grid) would be filtered as if they did not."""
    index = data.index
    i = irregular_position(index)
    if i is None:
        return float(data.step)
    this = (index[i] - index[i - 1]).total_seconds()
    raise FitError(
        f"the time step from {index[i - 1]} to {index[i]} (row {i}) is {fmt_seconds(this)}, "
        f"not the data's step of {fmt_seconds(data.step)}; the Kalman filter needs one regular "
        "series: use one segment (Dataset.segments lists them) or keep the gap as rows whose "
        "outputs are missing (NaN) and whose inputs are filled"
    )


def x0_stds(model, x0_std, default: float, zero: bool = False) -> tuple[float, ...]:
    """The standard deviation [K] of each initial state of ``model`` from ``x0_std``: ``None``
    (``default`` for every state), one number, or ``{state: K}`` (``default`` for the others).
    Each must be finite and > 0 (≥ 0 with ``zero``: an initial state known exactly), and its
    square (the initial variance [K²]) finite."""
    states = model.states
    if x0_std is None:
        x0 = (float(default),) * len(states)
    elif isinstance(x0_std, Mapping):
        bad = [k for k in x0_std if k not in states]
        if bad:
            raise FitError(
                f"x0_std: {model.name} has no state(s) {', '.join(map(str, bad))}; its states "
                f"are {', '.join(states)}"
            )
        x0 = tuple(
            number(x0_std[s], f"x0_std of {s}") if s in x0_std else float(default) for s in states
        )
    else:
        if not isinstance(x0_std, int | float | np.integer | np.floating) or isinstance(
            x0_std, bool
        ):
            raise FitError(
                f"x0_std must be a number [K] or a mapping {{state: K}} over the states "
                f"{', '.join(states)}, got {x0_std!r}"
            )
        x0 = (float(x0_std),) * len(states)
    low = (lambda v: v < 0) if zero else (lambda v: not v > 0)
    if any(not (np.isfinite(v) and np.isfinite(v * v)) or low(v) for v in x0):
        raise FitError(f"x0_std must be finite and {'≥' if zero else '>'} 0 [K], got {x0}")
    return x0
