"""Bundled datasets by name: ``twinhouse_exp1:N2``, ``twinhouse_exp1:O5`` (``@10min`` appended for
10-minute data).

Only the exact spellings in :data:`NAMES` address a bundled dataset; anything else is a path (a
file ``twinhouse_exp1_myhouse.csv`` is read as that file, never replaced by bundled data).
"""

from __future__ import annotations

from ._twinhouse import HOUSES, twinhouse_exp1

__all__ = ["NAMES", "bundled", "is_bundled"]

#: Every name of a bundled dataset, mapped to (house, resolution).
_SPELLINGS: dict[str, tuple[str, str]] = {
    f"twinhouse_exp1:{house}{suffix}": (house, resolution)
    for house in HOUSES
    for suffix, resolution in (("", "1h"), ("@1h", "1h"), ("@10min", "10min"))
}

#: The names of the bundled datasets, as written in messages and help texts.
NAMES: tuple[str, ...] = tuple(name for name in _SPELLINGS if not name.endswith("@1h"))


def is_bundled(name: str) -> bool:
    """Whether ``name`` is exactly the name of a bundled dataset (see :data:`NAMES`)."""
    return name in _SPELLINGS


def bundled(name: str):
    """The bundled :class:`~jaxbox.data.Dataset` named exactly ``name`` (see :data:`NAMES`).

    Raises:
        KeyError: ``name`` is not one of them; the message lists the names.
    """
    try:
        house, resolution = _SPELLINGS[name]
    except KeyError:
        raise KeyError(
            f"no bundled dataset {name!r}; bundled datasets: {', '.join(NAMES)}"
        ) from None
    return twinhouse_exp1(house, resolution)
