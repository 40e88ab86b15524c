"""TEMPORARY: the data layer's new checks, until jaxbox.data has them (then deleted)."""

from __future__ import annotations

import os
from collections.abc import Mapping

from .. import data as _data
from ..data import DataError

__all__ = ["as_dataset", "check_mapping", "check_plausibility"]


def as_dataset(obj, what: str = "data"):
    if hasattr(_data, "as_dataset"):
        return _data.as_dataset(obj, what=what)
    import pandas as pd

    if isinstance(obj, _data.Dataset):
        return obj
    if isinstance(obj, pd.DataFrame | str | os.PathLike):
        return _data.load(obj)
    raise TypeError(
        f"{what} takes a jaxbox Dataset, a pandas DataFrame with a time index or the path of a "
        f"CSV file, not {type(obj).__name__}"
    )


def check_mapping(value, name: str):
    if hasattr(_data, "check_mapping"):
        return _data.check_mapping(value, name)
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise TypeError(f"{name} must be a mapping {{name: value}}, not {type(value).__name__}")
    return dict(value)


def check_plausibility(dataset, what: str = "the data"):
    if hasattr(_data, "check_plausibility"):
        return _data.check_plausibility(dataset, what=what)
    import numpy as np

    for col in dataset.columns:
        x = dataset[col]
        if not np.all(np.isfinite(x)):
            raise DataError(f"column {col!r} has non-finite values in {what}")
        if np.max(np.abs(x)) > 1e7:
            raise DataError(f"column {col!r} has implausible values in {what}")
