"""Argument checks of the validation API: each refuses a bad argument early, by its name, with
what to pass instead (a ``TypeError`` for the wrong kind of object, a ``ValueError`` for a value
out of range).

A leaf: it imports no module of :mod:`jaxbox.validate` (they all import it). Checks that need
the validation classes live in :mod:`jaxbox.validate._own`."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = [
    "check_fit",
    "check_dataset",
    "check_instance",
    "check_level",
    "check_interval",
    "check_positive",
    "check_fraction",
    "check_range",
    "check_flag",
]


def _kind(value: Any) -> str:
    return "None" if value is None else f"a {type(value).__name__}"


FIT_NEEDS = ("problem", "data", "params")
"""What every function of the validation API reads from a fit result (more where it says)."""


def _is_stochastic(result: Any) -> bool:
    # by name: importing jaxbox.stochastic here would run an import back up into validate
    return any(c.__name__ == "MLResult" for c in type(result).__mro__)


def check_fit(result: Any, what: str = "result", needs: tuple[str, ...] = FIT_NEEDS):
    """``result`` when it is an output-error fit: a :class:`~jaxbox.fit.FitResult` or any object
    with the attributes ``needs`` that the calling function reads (duck typing: a
    ``types.SimpleNamespace(problem=..., data=..., params=...)`` serves the sensitivities). A
    ``TypeError`` naming ``what`` otherwise; a stochastic fit gets the methods that serve it."""
    if _is_stochastic(result):
        raise TypeError(
            f"{what} is a stochastic fit (MLResult, jaxbox.fit_model(..., method='ml')); this "
            "function takes an output-error fit (method='oe'). For a stochastic fit use its own "
            "methods: intervals(), simulation_rmse(data), innovation_tests(), k_step_errors()"
        )
    missing = [name for name in needs if not hasattr(result, name)]
    if missing:
        raise TypeError(
            f"{what} must be a FitResult (the result of jaxbox.fit_model, or an object with "
            f"{', '.join(needs)}), got {_kind(result)} without {', '.join(missing)}"
        )
    return result


def check_dataset(data: Any, what: str):
    """``data`` when it is a :class:`~jaxbox.data.Dataset`; a ``TypeError`` naming ``what``
    otherwise (a DataFrame gets the way to wrap it)."""
    import pandas as pd

    from ..data import Dataset

    if isinstance(data, Dataset):
        return data
    hint = (
        "; wrap a DataFrame with a DatetimeIndex as jaxbox.data.Dataset(frame), or read a file "
        "with jaxbox.data.load"
        if isinstance(data, pd.DataFrame)
        else "; take it from Dataset.split() or Dataset.windows()"
    )
    raise TypeError(f"{what} must be a jaxbox.data.Dataset, got {_kind(data)}{hint}")


def check_instance(value: Any, cls: type, what: str, source: str):
    """``value`` when it is ``None`` or a ``cls``; a ``TypeError`` naming ``what`` and the
    function ``source`` that makes one otherwise."""
    if value is None or isinstance(value, cls):
        return value
    a = "an" if cls.__name__[0] in "AEIOU" else "a"
    raise TypeError(
        f"{what} must be {a} {cls.__name__} (from {source}) or None, got {_kind(value)}"
    )


def _real(value: Any, what: str) -> float:
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | float | np.number):
        raise TypeError(f"{what} must be a number, got {value!r}")
    value = float(value)
    if math.isnan(value):
        raise ValueError(f"{what} must be a number, got nan")
    return value


def check_level(value: Any, what: str = "level") -> float:
    """A confidence level strictly between 0 and 1."""
    level = _real(value, what)
    if not 0.0 < level < 1.0:
        raise ValueError(f"{what} must be a confidence level in (0, 1), e.g. 0.95; got {value}")
    return level


def check_interval(interval: Any) -> str:
    """The covariance a delta-method interval rests on: ``"white"`` or ``"hac"``."""
    if interval not in ("white", "hac"):
        raise ValueError(f"interval must be 'white' or 'hac', got {interval!r}")
    return interval


def check_positive(value: Any, what: str, unit: str = "", *, allow_inf: bool = False) -> float:
    """A number > 0 (finite unless ``allow_inf``: ``inf`` switches a limit off)."""
    x = _real(value, what)
    if not x > 0 or (math.isinf(x) and not allow_inf):
        rng = "> 0" if allow_inf else "finite and > 0"
        raise ValueError(f"{what} must be {rng}{f' [{unit}]' if unit else ''}, got {value}")
    return x


def check_fraction(value: Any, what: str, upper: float = 1.0) -> float:
    """A number in ``[0, upper)``."""
    x = _real(value, what)
    if not 0.0 <= x < upper:
        raise ValueError(f"{what} must be in [0, {upper:g}), got {value}")
    return x


def check_range(value: Any, what: str, unit: str = "", *, lower: float | None = None):
    """A pair ``(lo, hi)`` of numbers with ``lo < hi`` (``hi`` may be ``inf``, ``lo`` may be
    ``-inf`` unless ``lower`` bounds it from below)."""
    u = f" [{unit}]" if unit else ""
    try:
        lo, hi = value
    except (TypeError, ValueError):
        raise TypeError(f"{what} must be a pair (low, high){u}, got {value!r}") from None
    lo, hi = _real(lo, f"the low end of {what}"), _real(hi, f"the high end of {what}")
    if not lo < hi:
        raise ValueError(f"{what} must be (low, high) with low < high{u}, got {value!r}")
    if lower is not None and lo < lower:
        raise ValueError(f"the low end of {what} must be ≥ {lower:g}{u}, got {value!r}")
    return lo, hi


def check_flag(value: Any, what: str) -> bool:
    """A boolean switch (True or False)."""
    if not isinstance(value, bool | np.bool_):
        raise TypeError(f"{what} must be True or False, got {value!r}")
    return bool(value)
