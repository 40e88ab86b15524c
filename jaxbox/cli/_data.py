"""DATA on the command line: the options that read and split it, checked before anything is
loaded (:class:`DataOptions`); bundled datasets by their exact names, anything else a path;
loading, splitting into the ``--train``/``--validate`` windows and checking them
(:func:`load_all`)."""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from pathlib import Path

from ._common import (
    UsageError,
    about,
    bounds,
    check_interrupted,
    number,
    pairs,
    period,
    resample_rule,
    scale,
    separator,
    warning_line,
)
from ._outputs import check_folder, reason

__all__ = [
    "DATA_HELP",
    "DataOptions",
    "add_data_arguments",
    "check_output_folders",
    "load_all",
    "load_for_model",
    "load_data",
    "slug",
]


#: The fewest samples of an identification or validation period (the residual tests of
#: :mod:`jaxbox.validate` need 4).
MIN_SAMPLES = 4

DATA_HELP = (
    "CSV file with a 'time' column and canonical columns (T_zon, T_amb, Q_hea, I_glo_hor, …), "
    "or a bundled dataset by its exact name: twinhouse_exp1:N2, twinhouse_exp1:O5 (add @10min "
    "for 10-minute data)"
)


def add_data_arguments(p) -> None:
    """DATA and the options that read and split it (shared by ``fit`` and ``select``)."""
    p.add_argument(
        "data",
        metavar="DATA",
        nargs="+",
        help=DATA_HELP
        + "; several DATA of the same or neighbouring lengths are fitted together in one batch",
    )
    p.add_argument(
        "--map",
        action="append",
        default=[],
        metavar="CANONICAL=COLUMN",
        help="take canonical signal CANONICAL from your column COLUMN (repeatable; a "
        "CANONICAL given several columns takes their mean, of powers their sum)",
    )
    p.add_argument(
        "--time",
        "--time-column",
        dest="time",
        metavar="COLUMN",
        help="name of the time column (default: time), or DATE,CLOCK for a date column and a "
        "clock column",
    )
    p.add_argument(
        "--time-unit",
        metavar="UNIT",
        help="unit of a numeric time column: s (default), ms, us, ns, min, h or D",
    )
    p.add_argument(
        "--epoch",
        metavar="STAMP",
        help="time of 0 of a numeric time column (default 1970-01-01; 1899-12-30 with "
        "--time-unit D for spreadsheet serial dates)",
    )
    p.add_argument(
        "--tz",
        metavar="ZONE",
        help="time zone of the time stamps, e.g. Europe/Berlin: stamps without a UTC offset are "
        "local clock time there, across daylight-saving changes",
    )
    p.add_argument("--sep", metavar="CHAR", help="column separator of the CSV (default ',')")
    p.add_argument(
        "--decimal", metavar="CHAR", help="decimal mark of the CSV: '.' (default) or ','"
    )
    p.add_argument(
        "--thousands",
        metavar="CHAR",
        help="thousands separator of the CSV's numbers: ',' (1,234.5), '.' with --decimal ',' "
        '(1.234,5), "\'" or space (default none)',
    )
    p.add_argument(
        "--scale",
        action="append",
        default=[],
        metavar="COLUMN=FACTOR",
        help="multiply canonical column COLUMN by FACTOR, e.g. Q_hea=1000 for kW (repeatable)",
    )
    p.add_argument(
        "--unit",
        action="append",
        default=[],
        metavar="COLUMN=UNIT",
        help="canonical column COLUMN is logged in UNIT, converted at load: degF or K for a "
        "temperature, kW, MW or Btu/h for a power, kW/m2 for irradiance (repeatable)",
    )
    p.add_argument(
        "--counter",
        action="append",
        default=[],
        metavar="COLUMN=UNIT",
        help="canonical column COLUMN is a cumulative energy meter in UNIT (kWh, MWh, Wh, J, kJ, "
        "MJ, GJ): use the mean power of each interval (repeatable)",
    )
    p.add_argument(
        "--range",
        action="append",
        default=[],
        metavar="COLUMN=LO:HI",
        help="plausible range of COLUMN where the default does not fit, e.g. T_zon=-10:60 "
        "(repeatable)",
    )
    p.add_argument(
        "--allow",
        action="append",
        default=[],
        metavar="[COLUMN=]CHECK",
        help="keep data a plausibility check refuses, with a warning, where they are right: "
        "CHECK is one of kelvin, fahrenheit, range, jump, spike, stuck, counter, kilowatt, for "
        "COLUMN or every column, e.g. T_zon=jump (repeatable)",
    )
    p.add_argument(
        "--stuck-hours",
        metavar="H",
        help="a temperature that does not change for H hours is refused as a stuck sensor "
        "(default 24; 'none' turns the check off, e.g. for a coarse sensor in a steady cellar)",
    )
    p.add_argument(
        "--resample", metavar="RULE", help="resample first, e.g. 1h (mean, right-closed)"
    )
    p.add_argument(
        "--trim",
        metavar="auto|none|first|last|both",
        help="drop a partial first or last sample: auto (the default) drops one whose "
        "temperature strays off the trend of its neighbours, with a warning; none keeps every "
        "sample; first, last, both drop those anyway",
    )
    p.add_argument(
        "--train", metavar="START..END", help="identification period (default: first half)"
    )
    p.add_argument(
        "--validate",
        metavar="START..END|none",
        help="validation period (default: the rest); a time stamp shared with --train belongs "
        "to the identification period; 'none' fits all of --train (default the whole data) "
        "and reports residual tests and intervals only",
    )
    p.add_argument(
        "--max-gap",
        metavar="DURATION",
        default="1h",
        help="input gaps up to DURATION (e.g. 30min, 2h) are interpolated, with a warning; "
        "longer ones split a window into segments with their own initial states; output gaps "
        "are masked (default 1h)",
    )


def _stuck_hours(text) -> float | None:
    """``--stuck-hours``: a positive number of hours, or ``none`` (no stuck-sensor check);
    not given: the default of :func:`jaxbox.data.check_plausibility`."""
    if text is None:
        from ..data._plausible import STUCK_HOURS

        return STUCK_HOURS
    if str(text).strip().lower() in ("none", "off"):
        return None
    value = number(str(text), "--stuck-hours")
    if value <= 0:
        raise UsageError(f"--stuck-hours {text}: give a positive number of hours, or none")
    return value


def _trim(text) -> str:
    """``--trim``: one of :data:`jaxbox.data._plausible.TRIM` (default ``auto``)."""
    from ..data._plausible import TRIM

    if text is None:
        return "auto"
    value = str(text).strip().lower()
    if value not in TRIM:
        raise UsageError(f"--trim {text!r}: give one of {', '.join(TRIM)}")
    return value


def _allow(items) -> frozenset:
    """``--allow [COLUMN=]CHECK``, repeatable: the refusals kept as warnings."""
    from ..data import DataError
    from ..data._plausible import parse_allow

    for item in items:
        if not str(item).strip() or str(item).strip().endswith("="):
            raise UsageError(f"--allow {item!r}: give CHECK or COLUMN=CHECK, e.g. T_zon=jump")
    try:
        return parse_allow(list(items))
    except DataError as err:
        raise UsageError(str(err).replace("allow: ", f"--allow {items[-1]}: ", 1)) from None


def _max_gap(text) -> float:
    """``--max-gap``: a duration such as ``30min`` or ``2h`` (a bare number is seconds)."""
    from ..data import DataError
    from ..data._gaps import duration_seconds

    try:
        value = float(text)
    except (TypeError, ValueError):
        value = text
    try:
        return duration_seconds(value, "--max-gap")
    except DataError as err:
        raise UsageError(str(err).replace("--max-gap=", "--max-gap ")) from None


def _mapping(items) -> dict[str, str | list[str]]:
    """``--map CANONICAL=COLUMN`` items; a canonical name given several columns takes them all
    (``--map T_zon=room1 --map T_zon=room2``: their mean; powers their sum), a column given
    twice for one name is refused."""
    out: dict[str, str | list[str]] = {}
    for item in items:
        ((key, value),) = pairs([item], "--map", "T_zon=living_temp").items()
        if key not in out:
            out[key] = value
            continue
        got = out[key] if isinstance(out[key], list) else [out[key]]
        if value in got:
            raise UsageError(f"--map gives {key}={value} twice")
        out[key] = [*got, value]
    return out


class DataOptions:
    """The checked data options of a command line (before anything is loaded)."""

    def __init__(self, args) -> None:
        self.specs = list(args.data)
        self.columns = _mapping(args.map)
        self.time = args.time
        if self.time is not None and not self.time.strip():
            raise UsageError("--time is empty; give the name of the time column")
        if self.time is not None and "," in self.time:
            parts = [part.strip() for part in self.time.split(",")]
            if len(parts) != 2 or not all(parts):
                raise UsageError(
                    f"--time {self.time!r}: give one column, or two as DATE,CLOCK (e.g. "
                    "--time date,time)"
                )
            self.time = parts
        self.time_unit = getattr(args, "time_unit", None)
        if self.time_unit is not None:
            from ..data._checks import TIME_UNITS

            self.time_unit = self.time_unit.strip()
            if self.time_unit not in TIME_UNITS:
                raise UsageError(
                    f"--time-unit {self.time_unit!r} is not one of {', '.join(TIME_UNITS)}"
                )
        self.epoch = getattr(args, "epoch", None)
        if self.epoch is not None:
            import pandas as pd

            try:
                pd.Timestamp(self.epoch)
            except (ValueError, TypeError):
                raise UsageError(f"--epoch {self.epoch!r} is not a time stamp") from None
        self.tz = getattr(args, "tz", None)
        if self.tz is not None and not self.tz.strip():
            raise UsageError("--tz is empty; give a time zone such as Europe/Berlin or UTC")
        self.tz = None if self.tz is None else self.tz.strip()
        self.sep = separator(args.sep, "--sep")
        self.decimal = separator(args.decimal, "--decimal", ".,")
        if self.sep is not None and self.sep == (self.decimal or "."):
            raise UsageError(
                f"--sep and --decimal are both {self.sep!r}; with --decimal ',' use --sep ';'"
            )
        from ..data._load import THOUSANDS

        self.thousands = separator(getattr(args, "thousands", None), "--thousands", THOUSANDS)
        if self.thousands is not None and self.thousands == (self.decimal or "."):
            raise UsageError(
                f"--thousands and --decimal are both {self.thousands!r}; with --thousands '.' "
                "use --decimal ','"
            )
        self.scale = scale(args.scale)
        self.counters = pairs(args.counter, "--counter", "Q_hea=kWh")
        self.units = pairs(getattr(args, "unit", []), "--unit", "T_zon=degF")
        self.ranges = bounds(args.range, "--range", "T_zon=-10:60")
        self.stuck_hours = _stuck_hours(getattr(args, "stuck_hours", None))
        self.allow = _allow(getattr(args, "allow", []))
        self.resample = resample_rule(args.resample)
        self.trim = _trim(getattr(args, "trim", None))
        self.train_text, self.valid_text = args.train, args.validate
        self.train = period(args.train, "--train")
        none = args.validate is not None and args.validate.strip().lower() == "none"
        self.valid = False if none else period(args.validate, "--validate")
        self.max_gap = _max_gap(getattr(args, "max_gap", "1h"))
        self._check_specs()

    @property
    def csv_options(self) -> dict:
        return {
            "--map": self.columns,
            "--time": self.time,
            "--time-unit": self.time_unit,
            "--epoch": self.epoch,
            "--tz": self.tz,
            "--sep": self.sep,
            "--decimal": self.decimal,
            "--thousands": self.thousands,
            "--scale": self.scale,
            "--unit": self.units,
            "--counter": self.counters,
        }

    def _check_specs(self) -> None:
        from ..datasets import NAMES, is_bundled

        seen: dict[object, str] = {}
        for spec in self.specs:
            if not spec.strip():
                raise UsageError("a DATA argument is empty; give a CSV file or a bundled name")
            if is_bundled(spec):
                used = [k for k, v in self.csv_options.items() if v]
                if used:
                    raise UsageError(
                        f"{used[0]} applies to CSV files, not to the bundled dataset {spec}"
                    )
                key: object = spec
            else:
                path = Path(spec)
                try:
                    exists, is_dir = path.exists(), path.is_dir()
                except (OSError, ValueError) as err:
                    raise UsageError(f"DATA {spec!r}: {reason(err)}") from None
                if not exists:
                    hint = ""
                    if spec.split(":")[0].split("@")[0] in {n.split(":")[0] for n in NAMES}:
                        hint = f"; bundled datasets are named exactly {', '.join(NAMES)}"
                    raise UsageError(
                        f"DATA {spec!r}: file not found (relative paths are taken from "
                        f"{os.getcwd()!r}){hint}"
                    )
                if is_dir:
                    raise UsageError(f"DATA {spec!r} is a folder; give the path of a CSV file")
                if not os.access(path, os.R_OK):
                    raise UsageError(f"DATA {spec!r}: the file cannot be read (permissions)")
                st = path.stat()
                key = (st.st_dev, st.st_ino)
            if key in seen:
                same = "" if seen[key] == spec else f" (as {seen[key]!r} and {spec!r})"
                raise UsageError(f"the same DATA is given twice{same}; give each dataset once")
            seen[key] = spec


#: Appended where a named model needs a signal the data lack.
SEARCH_HINT = (
    "; or name a structure of the component grammar (--model Zon+Wal+Int: built for the "
    "signals your data hold), or let 'jaxbox select DATA' (the structure search, its default) "
    "choose one"
)


def require_model_columns(data, model) -> None:
    """``data`` must hold the inputs and outputs of ``model``; the error also points to the
    structure search, which needs no signal the data lack."""
    from ..data import DataError

    try:
        data.require(list(model.inputs) + list(model.outputs), what=f"model {model.name}")
    except DataError as err:
        raise DataError(f"{str(err).rstrip('.')}{SEARCH_HINT}.") from None


def load_data(spec: str, opts: DataOptions | None = None):
    """A dataset from a CSV path or a bundled name (exactly ``twinhouse_exp1:N2[@10min]``)."""
    from ..data import load
    from ..datasets import bundled, is_bundled

    if is_bundled(spec):
        data = bundled(spec)
        rule = opts.resample if opts else None
        return data.resample(rule) if rule else data
    if opts is None:
        return load(spec)
    return load(
        spec,
        time=opts.time,
        columns=opts.columns or None,
        resample=opts.resample,
        sep=opts.sep,
        decimal=opts.decimal,
        thousands=opts.thousands,
        scale=opts.scale or None,
        counters=opts.counters or None,
        units=opts.units or None,
        tz=opts.tz,
        **({"time_unit": opts.time_unit} if opts.time_unit else {}),
        **({"epoch": opts.epoch} if opts.epoch else {}),
    )


def split_periods(data, opts: DataOptions):
    """Identification and validation datasets from the ``--train`` and ``--validate`` periods
    (:meth:`jaxbox.data.Dataset.windows`: default the halves, a shared edge belongs to the
    identification period; ``--validate none``: no validation dataset, ``None``), each of at
    least :data:`MIN_SAMPLES`."""
    from ..data import DataError

    try:
        ident, val = data.windows(opts.train, opts.valid, names=("--train", "--validate"))
    except DataError as err:
        raise UsageError(str(err)) from None
    windows = ((ident, "identification", "--train"), (val, "validation", "--validate"))
    for window, what, option in windows:
        if window is not None and len(window) < MIN_SAMPLES:
            fix = f"widen {option}" if _option_given(opts, option) else "give more data"
            raise UsageError(
                f"the {what} period ({window.start} .. {window.end}) holds {len(window)} "
                f"sample(s); at least {MIN_SAMPLES} are needed: {fix}"
            )
    return ident, val


def _option_given(opts: DataOptions, option: str) -> bool:
    return (opts.train if option == "--train" else opts.valid) is not None


def check_windows(
    ident, valid, columns, ranges, stuck_hours: float | None, allow: frozenset = frozenset()
) -> None:
    """The physical plausibility of the signals (``columns``, default every canonical one) in
    the windows actually used (``ranges``: the ``--range`` overrides; ``stuck_hours``:
    ``--stuck-hours``; ``allow``: ``--allow``); warnings (uncertain findings) go to stderr."""
    from ..data import check_plausibility

    for data, what in ((ident, "identification data"), (valid, "validation data")):
        if data is None:
            continue
        notes = check_plausibility(
            data,
            overrides=ranges or None,
            columns=columns,
            what=what,
            warn=False,
            stuck_hours=stuck_hours,
            allow=allow,
        )
        for note in notes:
            print(warning_line(note), file=sys.stderr, flush=True)


def _trimmed(data, opts: DataOptions, columns):
    """``data`` without a partial first or last sample (``--trim``), with a warning for each
    one dropped."""
    from ..data import trim_edges

    data, notes = trim_edges(data, getattr(opts, "trim", "auto"), columns)
    for note in notes:
        print(warning_line(note), file=sys.stderr, flush=True)
    return data


def load_all(args, opts: DataOptions | None = None, *, model=None, model_for=None):
    """Every DATA of the command line, loaded, split and checked: ``[(spec, data, ident, valid),
    …]``. With ``model``, its inputs and outputs must be columns of each; ``model_for(columns)``
    gives the model for each DATA's columns instead (a structure name built for the data)."""
    from ..data import DataError

    opts = opts or DataOptions(args)
    out = []
    for spec in opts.specs:
        try:
            with about(spec if len(opts.specs) > 1 else None):
                data = load_data(spec, opts)
                if model_for is not None:
                    model = model_for(data.columns)
                columns = None
                if model is not None:
                    columns = list(model.inputs) + list(model.outputs)
                data = _trimmed(data, opts, columns)
                ident, valid = split_periods(data, opts)
                if model is not None:
                    require_model_columns(ident, model)
                check_windows(ident, valid, columns, opts.ranges, opts.stuck_hours, opts.allow)
        except (DataError, UsageError) as err:
            if len(opts.specs) == 1:
                raise
            raise type(err)(f"{spec}: {err}") from None  # which of the files
        check_interrupted()
        out.append((spec, data, ident, valid))
    return out


def load_for_model(args, opts: DataOptions, name: str, model):
    """:func:`load_all` for ``--model name`` (``model``: as built without data): ``(sets,
    model)``. A structure of the grammar (``Zon+Wal+Int``) is built for the data's columns, as
    the structure search builds it (no solar aperture without ``I_glo_hor``); every DATA must
    then give the same model. With one DATA the model, a structure's or the library's, is sized
    for its building (:func:`jaxbox.select._scale.sized_model`) as the search sizes its own."""
    from ..models import get_model, list_models
    from ..models._grammar import is_structure_name
    from ..select._scale import sized_model

    if not (is_structure_name(name) and name not in list_models()):
        sets = load_all(args, opts, model=model)
    else:
        sets = load_all(args, opts, model_for=lambda columns: get_model(name, columns))
        built = {get_model(name, data.columns).param_names for _, data, _, _ in sets}
        if len(built) > 1:
            raise UsageError(
                f"--model {name} reads other columns in each DATA (its parameters differ: "
                f"{' / '.join(', '.join(b) for b in sorted(built))}); fit them one at a time"
            )
        model = get_model(name, sets[0][1].columns)
    if len(sets) == 1:
        model = sized_model(model, sets[0][2])
    return sets, model


def slug(spec: str, specs: Sequence[str] = ()) -> str:
    """A folder name for a DATA argument, unique among ``specs`` (the numbered position is
    prefixed when two share a name)."""
    from ..datasets import is_bundled

    def name(x: str) -> str:
        base = x if is_bundled(x) else Path(x).stem
        return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in base) or "data"

    out = name(spec)
    if [name(x) for x in specs].count(out) > 1:
        out = f"{list(specs).index(spec) + 1}-{out}"
    return out


def check_output_folders(text: str | None, option: str, specs: Sequence[str]) -> Path | None:
    """The output folder of ``option`` probed for writing, and with several DATA the folder of
    each inside it (one per dataset, named by :func:`slug`)."""
    folder = check_folder(text, option)
    if folder is not None and len(specs) > 1:
        for spec in specs:
            check_folder(str(folder / slug(spec, specs)), option)
    return folder
