"""The single error type raised for bad input data."""

from __future__ import annotations

__all__ = ["DataError", "DataWarning", "list_names"]


class DataError(ValueError):
    """Bad input data: a missing column, a bad timestamp, a gap, a wrong unit, ...

    The message names the offending column, row or timestamp and says how to fix it.
    """


class DataWarning(UserWarning):
    """Data that may be wrong but could be right (e.g. a heating power that may be in kW)."""


def list_names(names: object, limit: int = 20) -> str:
    """Comma-separated quoted names, cut after ``limit`` with a count of the rest."""
    names = [str(name) for name in names]  # type: ignore[union-attr]
    if not names:
        return "(none)"
    shown = ", ".join(repr(name) for name in names[:limit])
    rest = len(names) - limit
    return f"{shown}, ... ({rest} more)" if rest > 0 else shown
