"""Checks of the types of keyword arguments at the public boundary."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = ["check_count", "check_mapping", "check_real"]


def check_mapping(value: Any, name: str, example: str | None = None) -> dict:
    """Return ``value`` as a new dict, or ``{}`` for ``None``; refuse anything but a mapping.

    Args:
        value: the argument as given.
        name: the argument's name, for the message (``"columns"``, ``"bounds"``...).
        example: an example of a valid value for the message, e.g. ``"{'Q_hea': 1000}"``.

    Raises:
        TypeError: ``value`` is a list, a string, a number... and not a mapping. The message
            names the argument, what it got and what it takes.
    """
    if value is None:
        return {}
    if isinstance(value, Mapping):
        return dict(value)
    got = f"a {type(value).__name__}"
    if isinstance(value, str):
        got = f"the string {value!r}"
    elif isinstance(value, (list, tuple, set)):
        got = f"{got} of {len(value)} item(s)"
    hint = f" such as {name}={example}" if example else ""
    raise TypeError(f"{name} must be a mapping (a dict{hint}), got {got}.")


def check_count(value: Any, name: str, minimum: int = 1) -> int:
    """An integer argument ``≥ minimum`` (a bool, a float or a string is a ``TypeError``, a
    smaller one a ``ValueError``, each naming ``name``)."""
    import numpy as np

    if isinstance(value, bool | np.bool_) or not isinstance(value, int | np.integer):
        raise TypeError(f"{name} must be an integer ≥ {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be an integer ≥ {minimum}, got {value}")
    return int(value)


def check_real(value: Any, name: str, unit: str = "") -> float:
    """A finite real number argument (a ``TypeError`` or ``ValueError`` naming ``name``)."""
    import math

    import numpy as np

    if isinstance(value, bool | np.bool_) or not isinstance(value, int | float | np.number):
        raise TypeError(f"{name} must be a number{f' [{unit}]' if unit else ''}, got {value!r}")
    if not math.isfinite(float(value)):
        raise ValueError(f"{name} must be finite, got {value}")
    return float(value)
