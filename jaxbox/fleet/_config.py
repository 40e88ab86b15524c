"""Settings of a fleet run, from keyword arguments or a TOML file.

A TOML file has up to four tables; every key is optional::

    [data]                      # how each building's file is read (see jaxbox.data.load)
    columns = { T_zon = "indoor", Q_hea = "heating_kW" }   # canonical name = your column
    time = "timestamp"          # time column (default "time"), or ["date", "clock"]
    time_unit = "s"             # unit of a numeric time column (s, ms, us, ns, min, h, D)
    epoch = "1970-01-01"        # time 0 of a numeric time column
    resample = "1h"             # average onto this grid
    scale = { Q_hea = 1000 }    # factors (after renaming), e.g. kW -> W
    counters = { Q_hea = "kWh" }  # cumulative energy meters (after renaming) and their unit
    units = { T_zon = "degF", T_amb = "degF" }  # columns logged in another unit (degF, K, kW…)
    tz = "Europe/Berlin"        # time zone of stamps without a UTC offset (local clock time)
    sep = ","
    decimal = "."
    # thousands = ","         # digits grouped in thousands (1,234.5); default none
    max_gap = "1h"              # input gaps up to this are interpolated; longer ones cut
    stuck_hours = 24            # a temperature unchanged this long is a stuck sensor ("none": off)

    [windows]                   # identification / validation periods of every building
    fraction = 0.5              # first share identifies, the rest validates (default halves)
    # or absolute periods, the same for every building:
    # train = ["2024-01-01", "2024-01-15 23:00"]
    # valid = ["2024-01-16", "2024-01-31 23:00"]

    [identify]
    models = "search"           # the structure search (default); one name: that model;
                                # several, a family or "all": forward selection among them
    starts = 16
    seed = 0
    max_steps = 200
    criterion = "se_cross"      # selection criterion (the validation simulation error)
    margin = 0.02               # improvement a selection step needs (default 0.02 for the
                                # search, 0 for a forward selection)
    patience = 1

    [run]
    partition_size = 16         # buildings per Dask task
    reports = false             # an HTML report per building (selection only)

Without a file the defaults of ``jaxbox select`` apply: the structure search of the component
grammar (:func:`jaxbox.structure_search`), the data split in halves.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import os
from collections.abc import Mapping
from pathlib import Path

from ..data._gaps import DEFAULT_MAX_GAP
from ..data._plausible import STUCK_HOURS

__all__ = ["FleetConfig", "FleetError", "load_config"]


class FleetError(ValueError):
    """A fleet run that cannot start: a bad setting, source or output folder."""


def _selection_default(name: str):
    from ..select import forward_selection

    return inspect.signature(forward_selection).parameters[name].default


#: the selection criteria understood (the forward selection ranks by validation SE)
CRITERIA = ("se_cross",)


@dataclasses.dataclass(frozen=True)
class FleetConfig:
    """Settings of a fleet run (see the module docstring for the TOML form).

    Attributes:
        columns: canonical name -> column name in the files.
        time: name of the time column (``None``: ``time``), or a date and a clock column.
        time_unit, epoch: unit and time 0 of a numeric time column (``None``: seconds since
            1970-01-01).
        resample: pandas frequency to average onto (``None``: as recorded).
        scale: canonical name -> factor.
        counters: canonical name -> energy unit of a cumulative meter (``"kWh"``…).
        units: canonical name -> the unit it is logged in (``"degF"``, ``"K"``, ``"kW"``…;
            :data:`jaxbox.data.UNITS`).
        tz: time zone of the time stamps (``None``: as written; see :func:`jaxbox.data.load`).
        sep, decimal, thousands: CSV separator, decimal mark and thousands separator.
        max_gap: the longest input gap [s] interpolated (a number, or text such as ``"2h"``);
            a longer one cuts the window into segments (:func:`jaxbox.data.prepare_window`),
            as ``jaxbox select --max-gap``.
        stuck_hours: a temperature that does not change for this many hours is refused as a
            stuck sensor (``None``, or ``"none"`` in a file: no such check), as ``jaxbox select
            --stuck-hours``.
        fraction: identification share of each building's data (without ``train``).
        train, valid: absolute (start, end) periods, the same for every building.
        models: ``"search"`` (the structure search, default), one model name (fitted as
            given), several names, a family or ``"all"`` (forward selection among them).
        starts, seed, max_steps: multistart settings per fit.
        continued: how many starts of each model (the first; in a search, of each grown
            candidate) also follow the continuation (``None``: all; ``1`` halves a search's
            fits, at the risk of a model only the other starts' continuation finds).
        polish: how many of each model's best starts are solved on to the full tolerance after
            every start was solved to a looser one (``None``: the search's default, 2, and
            every start to the full tolerance for a forward selection or a given model; ``0``:
            every start to the full tolerance).
        criterion: selection criterion (``"se_cross"``).
        margin: the relative improvement of the validation SE a selection step needs
            (``None``: 0.02 for the search, 0 for a forward selection).
        patience: forward-selection setting.
        partition_size: buildings per task.
        reports: write an HTML report per building (selection only).
    """

    columns: Mapping[str, str] = dataclasses.field(default_factory=dict)
    time: str | tuple[str, str] | None = None
    time_unit: str | None = None
    epoch: str | None = None
    resample: str | None = None
    scale: Mapping[str, float] = dataclasses.field(default_factory=dict)
    counters: Mapping[str, str] = dataclasses.field(default_factory=dict)
    units: Mapping[str, str] = dataclasses.field(default_factory=dict)
    tz: str | None = None
    sep: str | None = None
    decimal: str | None = None
    thousands: str | None = None
    max_gap: float | str = DEFAULT_MAX_GAP
    stuck_hours: float | str | None = STUCK_HOURS
    fraction: float = 0.5
    train: tuple[str, str] | None = None
    valid: tuple[str, str] | None = None
    models: str | tuple[str, ...] = "search"
    starts: int = dataclasses.field(default_factory=lambda: _selection_default("starts"))
    seed: int = 0
    max_steps: int | None = None
    continued: int | None = None
    polish: int | None = None
    criterion: str = "se_cross"
    margin: float | None = None
    patience: int = 1
    partition_size: int = 16
    reports: bool = False

    def __post_init__(self) -> None:
        if not 0.0 < _real("windows.fraction", self.fraction) < 1.0:
            raise FleetError(f"windows.fraction must be between 0 and 1, got {self.fraction}")
        if (self.train is None) != (self.valid is None):
            raise FleetError("windows: give both train and valid periods, or neither")
        for name in ("train", "valid"):
            v = getattr(self, name)
            if v is not None:
                if not isinstance(v, list | tuple) or len(v) != 2:
                    raise FleetError(f"windows.{name} must be [start, end], got {v!r}")
                object.__setattr__(self, name, (str(v[0]), str(v[1])))
        models = self.models
        if isinstance(models, list | tuple):
            if not models or not all(isinstance(m, str) and m for m in models):
                raise FleetError(f"identify.models must name models, got {models!r}")
            object.__setattr__(self, "models", tuple(models))
        elif not isinstance(models, str) or not models.strip():
            raise FleetError(
                f"identify.models must be 'search', a name, a list or 'all', got {models!r}"
            )
        for name in ("starts", "partition_size", "patience"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise FleetError(f"{name} must be a positive integer, got {v!r}")
        steps = self.max_steps
        if steps is not None and (
            not isinstance(steps, int) or isinstance(steps, bool) or steps < 1
        ):
            raise FleetError(f"identify.max_steps must be a positive integer, got {steps!r}")
        k = self.continued
        if k is not None and (not isinstance(k, int) or isinstance(k, bool) or k < 0):
            raise FleetError(f"identify.continued must be an integer ≥ 0, got {k!r}")
        k = self.polish
        if k is not None and (not isinstance(k, int) or isinstance(k, bool) or k < 0):
            raise FleetError(f"identify.polish must be an integer ≥ 0, got {k!r}")
        if self.criterion not in CRITERIA:
            raise FleetError(
                f"identify.criterion {self.criterion!r} is not known; use one of "
                f"{', '.join(CRITERIA)} (the validation simulation error)"
            )
        if self.margin is not None and not 0.0 <= _real("identify.margin", self.margin) < 1.0:
            raise FleetError(f"identify.margin must be in [0, 1), got {self.margin}")
        seed = self.seed
        if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
            raise FleetError(f"identify.seed must be an integer ≥ 0, got {seed!r}")
        if not isinstance(self.reports, bool):
            raise FleetError(f"run.reports must be true or false, got {self.reports!r}")
        self._check_models()
        object.__setattr__(self, "columns", _names_map("data.columns", self.columns))
        scale = _names_map("data.scale", self.scale, values=False)
        for k, v in scale.items():
            scale[k] = _real(f"data.scale.{k}", v)
            if not (math.isfinite(scale[k]) and scale[k] != 0):
                raise FleetError(f"data.scale.{k} must be a finite factor other than 0, got {v!r}")
        object.__setattr__(self, "scale", scale)
        if isinstance(self.time, list | tuple):
            if len(self.time) != 2 or not all(isinstance(t, str) and t for t in self.time):
                raise FleetError(f"data.time must be a column or [date, clock], got {self.time!r}")
            object.__setattr__(self, "time", tuple(self.time))
        from ..data._counters import COUNTER_UNITS

        counters = _names_map("data.counters", self.counters)
        for k, unit in counters.items():
            if unit.strip() not in COUNTER_UNITS:
                raise FleetError(
                    f"data.counters.{k}: unknown energy unit {unit!r}; use one of "
                    f"{', '.join(COUNTER_UNITS)}"
                )
        object.__setattr__(self, "counters", counters)
        from ..data._units import UNITS

        units = _names_map("data.units", self.units)
        known = sorted({u for table in UNITS.values() for u in table})
        for k, unit in units.items():
            if unit.strip() not in known:
                raise FleetError(
                    f"data.units.{k}: unknown unit {unit!r}; use one of {', '.join(known)}"
                )
        object.__setattr__(self, "units", units)
        if self.tz is not None and (not isinstance(self.tz, str) or not self.tz.strip()):
            raise FleetError(
                f"data.tz must name a time zone such as 'Europe/Berlin', got {self.tz!r}"
            )
        if self.thousands is not None:
            from ..data._load import THOUSANDS

            if self.thousands not in THOUSANDS or self.thousands == (self.decimal or "."):
                raise FleetError(
                    f"data.thousands must be one of {', '.join(map(repr, THOUSANDS))} and differ "
                    f"from the decimal mark ('.' with decimal = ','), got {self.thousands!r}"
                )
        self._check_reading()
        self._check_gaps()

    def _check_gaps(self) -> None:
        """``max_gap`` as seconds, ``stuck_hours`` as hours or ``None``."""
        from ..data import DataError
        from ..data._gaps import duration_seconds

        try:
            gap = duration_seconds(self.max_gap, "data.max_gap")
        except DataError as err:
            raise FleetError(str(err)) from None
        object.__setattr__(self, "max_gap", gap)
        hours = self.stuck_hours
        if isinstance(hours, str) and hours.strip().lower() in ("none", "off"):
            hours = None
        if hours is not None:
            if isinstance(hours, bool) or not isinstance(hours, int | float) or not hours > 0:
                raise FleetError(
                    f"data.stuck_hours must be a positive number of hours or 'none', got "
                    f"{self.stuck_hours!r}"
                )
            hours = float(hours)
        object.__setattr__(self, "stuck_hours", hours)

    def _check_models(self) -> None:
        """Every model name resolves: a library or structure name, a family, 'all', 'search'."""
        from ..models import ModelError, families, get_model

        names = self.models if isinstance(self.models, tuple) else (self.models,)
        for name in names:
            if name in ("all", "search") and not isinstance(self.models, tuple):
                continue
            if name in families() and not isinstance(self.models, tuple):
                continue
            try:
                get_model(name)
            except ModelError as err:
                raise FleetError(
                    f"identify.models: {err}; or a family ({', '.join(families())}), 'all' or "
                    "'search'"
                ) from None

    def _check_reading(self) -> None:
        """The options of reading each file, checked before any building is read."""
        import pandas as pd

        from ..data._checks import TIME_UNITS

        if self.sep is not None and (not isinstance(self.sep, str) or len(self.sep) != 1):
            raise FleetError(
                f"data.sep must be one character (e.g. ';' or '\\t'), got {self.sep!r}"
            )
        if self.decimal is not None and self.decimal not in (".", ","):
            raise FleetError(f"data.decimal must be '.' or ',', got {self.decimal!r}")
        if (self.sep or ",") == (self.decimal or "."):
            raise FleetError(
                "data.sep and data.decimal are the same; with decimal = ',' use sep = ';'"
            )
        if self.time_unit is not None and self.time_unit not in TIME_UNITS:
            raise FleetError(
                f"data.time_unit must be one of {', '.join(TIME_UNITS)}, got {self.time_unit!r}"
            )
        checks = [("data.epoch", self.epoch, lambda v: pd.Timestamp(v))]
        checks.append(("data.tz", self.tz, lambda v: pd.Timestamp("2000-01-01", tz=v)))
        for name, value, read in checks:
            if value is None:
                continue
            try:
                read(value)
            except (ValueError, TypeError, KeyError) as err:
                raise FleetError(f"{name} {value!r} cannot be read ({err})") from None
        if self.resample is not None:
            try:
                length = pd.Timedelta(pd.tseries.frequencies.to_offset(self.resample))
            except (ValueError, TypeError):
                length = None
            if length is None or not length.total_seconds() > 0:
                raise FleetError(
                    f"data.resample {self.resample!r} is not a positive fixed length of time; "
                    "give one such as '1h', '15min' or '1D'"
                )
        if self.train is not None:
            for name in ("train", "valid"):
                try:
                    start, end = (pd.Timestamp(v) for v in getattr(self, name))
                except (ValueError, TypeError) as err:
                    raise FleetError(f"windows.{name}: {err}") from None
                if not start < end:
                    raise FleetError(
                        f"windows.{name} must start before it ends, got {start}, {end}"
                    )

    @property
    def fixed_model(self) -> str | None:
        """The model name when exactly one model is given (fitted without selection)."""
        from ..models import families, list_models
        from ..models._grammar import is_structure_name

        m = self.models
        if isinstance(m, tuple) and len(m) == 1:
            return m[0]
        if (
            isinstance(m, str)
            and m not in ("all", "search")
            and m not in families()
            and (m in list_models() or is_structure_name(m))
        ):
            return m
        return None

    def load_options(self) -> dict:
        """Keyword arguments of :func:`jaxbox.data.load`."""
        out = {
            "columns": self.columns or None,
            "time": list(self.time) if isinstance(self.time, tuple) else self.time,
            "time_unit": self.time_unit,
            "epoch": self.epoch,
            "resample": self.resample,
            "scale": self.scale or None,
            "counters": self.counters or None,
            "units": self.units or None,
            "tz": self.tz,
            "sep": self.sep,
            "decimal": self.decimal,
            "thousands": self.thousands,
        }
        return {k: v for k, v in out.items() if v is not None}

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["models"] = list(self.models) if isinstance(self.models, tuple) else self.models
        return d


def _real(name: str, value) -> float:
    """A number setting as a float (a FleetError naming it otherwise)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise FleetError(f"{name} must be a number, got {value!r}")
    return float(value)


def _names_map(name: str, value, values: bool = True) -> dict:
    """A table of column names -> names (``values``) or -> anything, checked."""
    if not isinstance(value, Mapping):
        raise FleetError(f"{name} must be a table {{column = ...}}, got {value!r}")
    for k, v in value.items():
        if not isinstance(k, str) or (values and not (isinstance(v, str) and v)):
            raise FleetError(f"{name} must map column names to names, got {k!r} = {v!r}")
    return dict(value)


_TABLES = {
    "data": (
        "columns",
        "time",
        "time_unit",
        "epoch",
        "resample",
        "scale",
        "counters",
        "units",
        "tz",
        "sep",
        "decimal",
        "thousands",
        "max_gap",
        "stuck_hours",
    ),
    "windows": ("fraction", "train", "valid"),
    "identify": (
        "models",
        "starts",
        "seed",
        "max_steps",
        "continued",
        "polish",
        "criterion",
        "margin",
        "patience",
    ),
    "run": ("partition_size", "reports"),
}


def _read_toml(path: Path) -> dict:
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as err:
        raise FleetError(f"{path}: not valid TOML ({err})") from None


def load_config(path: str | os.PathLike | None = None, **overrides) -> FleetConfig:
    """The :class:`FleetConfig` of a TOML file (tables ``data``, ``windows``, ``identify``,
    ``run``), with ``overrides`` (attribute names) on top; defaults without a file.

    Raises:
        FleetError: an unknown table or key, or a bad value (naming it).
        OSError: the file cannot be read.
    """
    values: dict = {}
    if path is not None:
        doc = _read_toml(Path(path))
        for table, content in doc.items():
            if table not in _TABLES or not isinstance(content, dict):
                raise FleetError(
                    f"{path}: unknown table [{table}]; the tables are "
                    + ", ".join(f"[{t}]" for t in _TABLES)
                )
            for key, value in content.items():
                if key not in _TABLES[table]:
                    raise FleetError(
                        f"{path}: unknown key {key!r} in [{table}]; known: "
                        + ", ".join(_TABLES[table])
                    )
                values[key] = value
    values.update({k: v for k, v in overrides.items() if v is not None})
    try:
        return FleetConfig(**values)
    except TypeError as err:
        raise FleetError(str(err)) from None
