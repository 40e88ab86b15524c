"""The ground floor of the command line, shared by every command: bad-input errors in command-line
terms, option checks, DATA resolution and loading, output folders written all at once, Ctrl-C.

Nothing here imports another module of :mod:`jaxbox.cli`; the commands (``_commands``,
``_select``) import from here, and ``_main`` from all of them.

The contract of every command: all options are checked, and the output folders probed for
writing, before any computing; bad input raises :class:`UsageError` (or another ``ValueError`` of
the library: ``DataError``, ``ModelError``, ``FitError``…) whose message :func:`cli_message` puts
in command-line terms; outputs are written into a hidden staging folder and moved into place only
once everything is computed (:class:`Outputs`), so that an error or Ctrl-C leaves no partial file.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import signal
import socket
import sys
import tempfile
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path

from .._io import remove_stale_temporaries, temporary_prefix, to_jsonable

__all__ = [
    "DATA_HELP",
    "UsageError",
    "Outputs",
    "add_data_arguments",
    "check_folder",
    "cli_message",
    "fit_json",
    "load_all",
    "load_data",
    "print_json",
    "progress",
]


class UsageError(ValueError):
    """A command-line argument is malformed or out of range; the message names the option and
    says the expected form."""


# ---- Ctrl-C ------------------------------------------------------------------------------------

_INTERRUPTED = [False]


def _on_sigint(signum, frame) -> None:
    _INTERRUPTED[0] = True
    raise KeyboardInterrupt


def install_interrupt_handler() -> None:
    """Ctrl-C raises :class:`KeyboardInterrupt` and is remembered, so that one swallowed deep
    inside a library still stops the command at its next :func:`check_interrupted`."""
    _INTERRUPTED[0] = False
    try:
        signal.signal(signal.SIGINT, _on_sigint)
    except ValueError:  # not the main thread (an embedding application): leave it alone
        pass


def check_interrupted() -> None:
    """Raise :class:`KeyboardInterrupt` if Ctrl-C was pressed (and perhaps swallowed)."""
    if _INTERRUPTED[0]:
        raise KeyboardInterrupt


def interrupted() -> bool:
    return _INTERRUPTED[0]


@contextmanager
def _deferred_interrupt():
    """Hold Ctrl-C back while the block runs (moving finished files into place); raise it
    after."""
    try:
        previous = signal.signal(signal.SIGINT, lambda s, f: _INTERRUPTED.__setitem__(0, True))
    except ValueError:
        previous = None
    try:
        yield
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    check_interrupted()


# ---- messages in command-line terms -------------------------------------------------------------

#: (pattern, replacement) turning the library's Python advice into command-line options.
_ADVICE: list[tuple[re.Pattern, str | Callable]] = [
    # "pass sep=';' (command line: --sep ';')" -> "pass --sep ';'"
    (re.compile(r"\b[a-z_]+=(?:(?![;:.] )[^()])*?\s*\(command line: ([^)]*)\)"), r"\1"),
    (re.compile(r"\s*\(command line: [^)]*\)"), ""),
    # "overrides={'T_zon': (lo, hi)} (--range T_zon=LO:HI)" -> "--range T_zon=LO:HI"
    (re.compile(r"\b[a-z_]+=\{[^}]*\} \((--[^)]*)\)"), r"\1"),
    # "(columns=, --map)" -> "(--map)"; "scale=, --scale" -> "--scale"
    (re.compile(r"\b[a-z_]+=, (--[a-z-]+)"), r"\1"),
    (re.compile(r"; Dataset\.\w+\)"), ")"),
    (re.compile(r"\s*\(e\.g\. DataFrame\.\w+\)"), ""),
    (
        re.compile(r"map yours with columns=\{([^}]*)\} in jaxbox\.data\.load"),
        lambda m: (
            "map yours with "
            + " ".join(
                f"--map {k}=YOUR_COLUMN" for k in re.findall(r"'([^']+)': 'your_col'", m.group(1))
            )
        ),
    ),
    (re.compile(r"columns=\{'([^']+)': '([^']+)'\}"), r"--map \1=\2"),
    (re.compile(r"pass time='[^']*'"), "pass --time COLUMN"),
    (re.compile(r"pass time= with one of them"), "pass --time with one of them"),
    (re.compile(r"pass resample= \(e\.g\. resample='([^']*)'\)"), r"pass --resample \1"),
    (re.compile(r"resample='([^']*)'"), r"--resample \1"),
    (re.compile(r"scale=\{'([^']+)': ([^}]+)\}"), r"--scale \1=\2"),
    (re.compile(r"^scale (names|factor)"), r"--scale \1"),
    (re.compile(r"\bscale applies after columns="), "--scale applies after --map"),
    (
        re.compile(r"read it with pd\.read_csv\(\.\.\., encoding=\.\.\.\) and pass the DataFrame"),
        "save it as UTF-8 text",
    ),
    (re.compile(r",? or read it with pandas yourself and pass the DataFrame"), ""),
    (re.compile(r",? or parse the column yourself and pass a DataFrame with a DatetimeIndex"), ""),
    (re.compile(r"\(e\.g\. pd\.to_datetime\(\.\.\., utc=True\)\) and pass a DataFrame"), ""),
    (re.compile(r"\bcolumns=(?= \(canonical)"), "--map"),
    (re.compile(r"\(mapped by columns=\)"), "(mapped by --map)"),
    (re.compile(r"\bcolumns maps\b"), "--map maps"),
    (re.compile(r"\bpass time=\b"), "pass --time"),
    (re.compile(r"\bepoch="), "the epoch "),
]


def cli_message(message: str) -> str:
    """A library error message in command-line terms: options instead of keyword arguments."""
    text = " ".join(str(message).split())  # one line
    for pattern, replacement in _ADVICE:
        text = pattern.sub(replacement, text)
    return text


# ---- options -----------------------------------------------------------------------------------


def pairs(items: Sequence[str], option: str, example: str) -> dict[str, str]:
    """``KEY=VALUE`` items of a repeatable option; a key given twice is refused."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise UsageError(f"{option} {item!r} must look like {example}")
        key = key.strip()
        if key in out:
            raise UsageError(f"{option} gives {key!r} twice ({out[key]!r} and {value.strip()!r})")
        out[key] = value.strip()
    return out


def number(text: str, option: str) -> float:
    """A finite number."""
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"{option}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise UsageError(f"{option}: {text!r} is not a finite number")
    return value


def floats(items: Sequence[str], option: str, example: str) -> dict[str, float]:
    return {k: number(v, f"{option} {k}={v}") for k, v in pairs(items, option, example).items()}


def bounds(
    items: Sequence[str], option: str = "--bounds", example: str = "R_wal=0.001:0.1"
) -> dict[str, tuple[float, float]]:
    """``P=LO:HI`` items with ``LO < HI``, both finite."""
    out = {}
    for key, value in pairs(items, option, example).items():
        lo, sep, hi = value.partition(":")
        if not sep or not lo.strip() or not hi.strip():
            raise UsageError(f"{option} {key}={value!r} must look like {key}=LO:HI")
        where = f"{option} {key}={value}"
        low, high = number(lo, where), number(hi, where)
        if not low < high:
            raise UsageError(f"{where}: the lower bound {low:g} must be below the upper {high:g}")
        out[key] = (low, high)
    return out


def integer(value: int, option: str, lo: int, hi: int | None = None) -> int:
    """An integer option in ``[lo, hi]``."""
    if value < lo or (hi is not None and value > hi):
        span = f"at least {lo}" if hi is None else f"between {lo} and {hi}"
        raise UsageError(f"{option} must be {span}, got {value}")
    return value


def int_option(text: str) -> int:
    """argparse type of integer options: ``1e3`` is read as 1000, ``abc`` refused."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{text!r} is not an integer") from None
    if not math.isfinite(value) or value != int(value):
        raise ValueError(f"{text!r} is not an integer")
    return int(value)


int_option.__name__ = "integer"


def float_option(text: str) -> float:
    return float(text)


float_option.__name__ = "number"


def check_parameters(model, names, option: str) -> None:
    """Every name in ``names`` is a parameter of ``model``."""
    known = list(model.param_names)
    for name in names:
        if name not in known:
            import difflib

            close = difflib.get_close_matches(name, known, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise UsageError(
                f"{option} {name}: model {model.name} has no parameter {name!r}{hint}; its "
                f"parameters: {', '.join(known)}"
            )


def period(text: str | None, option: str):
    """``START..END`` (either side may be empty) as a pair of time stamps or ``None``."""
    if text is None:
        return None
    import pandas as pd

    start, sep, end = text.partition("..")
    if not sep:
        raise UsageError(
            f"{option} {text!r} must look like START..END (either side may be empty), e.g. "
            "2024-01-01..2024-01-15"
        )
    out = []
    for side in (start.strip(), end.strip()):
        if not side:
            out.append(None)
            continue
        try:
            stamp = pd.Timestamp(side)
        except (ValueError, TypeError, OverflowError):
            stamp = pd.NaT
        if stamp is pd.NaT:
            raise UsageError(f"{option} {text!r}: cannot read {side!r} as a date or time")
        out.append(stamp)
    if out[0] is not None and out[1] is not None and out[0] > out[1]:
        raise UsageError(f"{option} {text!r}: the start is after the end")
    return tuple(out)


def resample_rule(text: str | None) -> str | None:
    """A fixed-length pandas frequency such as ``1h`` or ``15min``."""
    if text is None:
        return None
    import pandas as pd

    try:
        seconds = pd.Timedelta(pd.tseries.frequencies.to_offset(text)).total_seconds()
    except (ValueError, TypeError):
        raise UsageError(
            f"--resample {text!r}: not a fixed length of time; give one such as 1h, 15min or 1D"
        ) from None
    if not seconds > 0:
        raise UsageError(f"--resample {text!r} must be a positive length of time")
    return text


def separator(text: str | None, option: str, allowed: str | None = None) -> str | None:
    """One character (``\\t`` or ``tab`` for a tab)."""
    if text is None:
        return None
    char = {"\\t": "\t", "tab": "\t", "TAB": "\t", "space": " "}.get(text, text)
    if len(char) != 1 or (allowed is not None and char not in allowed):
        what = f"one of {' '.join(repr(c) for c in allowed)}" if allowed else "one character"
        raise UsageError(f"{option} {text!r} must be {what} (\\t for a tab)")
    return char


def scale(items: Sequence[str]) -> dict[str, float]:
    out = floats(items, "--scale", "Q_hea=1000")
    for key, value in out.items():
        if value == 0:
            raise UsageError(f"--scale {key}=0: a factor must not be zero")
    return out


#: The most starts one command fits per model and dataset (beyond, the start sample alone
#: would fill the memory).
MAX_STARTS = 100_000
#: The most Levenberg–Marquardt iterations per start.
MAX_STEPS = 1_000_000


def check_run_options(args) -> None:
    """``--starts``, ``--seed``, ``--max-steps`` (and ``--margin``, ``--patience`` where the
    command has them) in range."""
    integer(args.starts, "--starts", 1, MAX_STARTS)
    integer(args.seed, "--seed", 0, 2**63 - 1)
    if args.max_steps is None:
        args.max_steps = fit_default("max_steps")
    integer(args.max_steps, "--max-steps", 1, MAX_STEPS)
    if getattr(args, "patience", None) is not None:
        integer(args.patience, "--patience", 1)
    margin = getattr(args, "margin", None)
    if margin is not None and not 0.0 <= margin < 1.0:  # nan fails too
        raise UsageError(
            f"--margin must be a fraction in [0, 1), e.g. 0.05 for 5 %, got {margin!r}"
        )


# ---- output folders ----------------------------------------------------------------------------


def check_folder(text: str | None, option: str) -> Path | None:
    """The output folder of ``option``, probed for writing before any computing: a file, a
    folder under a file, a place that cannot be written are refused (a probe file is created in
    it, and removed, together with any folder made for it)."""
    if text is None:
        return None
    if not text.strip():
        raise UsageError(f"{option} is empty; give a folder")
    path = Path(text)
    try:
        if path.exists() and not path.is_dir():
            raise UsageError(f"{option} {text!r} is a file, not a folder; give a folder")
        made = _make_folder(path)
    except UsageError as err:
        raise UsageError(f"{option} {text!r}: {err}") from None
    except (OSError, ValueError) as err:
        raise UsageError(f"{option} {text!r}: cannot make this folder ({_reason(err)})") from None
    try:
        fd, probe = tempfile.mkstemp(prefix=".jaxbox-probe-", dir=path)
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        raise UsageError(f"{option} {text!r}: cannot write into it ({_reason(err)})") from None
    finally:
        _remove_folders(made)
    return path


def _reason(err: BaseException) -> str:
    return getattr(err, "strerror", None) or str(err)


def _make_folder(path: Path) -> list[Path]:
    """``mkdir -p`` that returns the folders it made (deepest last)."""
    missing = []
    p = path
    while not p.exists():
        missing.append(p)
        if p.parent == p:
            break
        p = p.parent
    if p.exists() and not p.is_dir():
        raise UsageError(f"{p} is a file, so no folder can be made under it")
    made = []
    for folder in reversed(missing):
        folder.mkdir()
        made.append(folder)
    return made


def _remove_folders(made: list[Path]) -> None:
    for folder in reversed(made):
        try:
            folder.rmdir()
        except OSError:
            pass


class Outputs:
    """The files one command writes, all or nothing.

    :meth:`folder` gives a hidden staging folder inside a target folder (made if needed); once
    everything is computed, :meth:`commit` moves each staged file into place (``os.replace``:
    atomic per file, Ctrl-C held back meanwhile) and runs the ``after`` actions (saving
    GreyBoxes, themselves atomic). Leaving the ``with`` block by an error or Ctrl-C removes the
    staging folders and the target folders this run made. Staging folders of a run killed
    outright are removed by the next run writing there.
    """

    def __init__(self) -> None:
        self._staged: list[tuple[Path, Path]] = []
        self._made: list[Path] = []
        self._after: list[Callable[[], object]] = []
        self.committed = False

    def __enter__(self) -> Outputs:
        return self

    def __exit__(self, kind, err, tb) -> None:
        if not self.committed:
            self.discard()

    def folder(self, target: Path) -> Path:
        """A staging folder whose files :meth:`commit` moves into ``target``."""
        target = Path(target)
        self._made += _make_folder(target)
        remove_stale_temporaries(target)
        staging = Path(tempfile.mkdtemp(prefix=temporary_prefix("jaxbox-out"), dir=target))
        self._staged.append((staging, target))
        return staging

    def after(self, action: Callable[[], object]) -> None:
        """Run ``action`` at commit, after the staged files are in place."""
        self._after.append(action)

    def commit(self) -> None:
        check_interrupted()
        with _deferred_interrupt():
            for staging, target in self._staged:
                _move_tree(staging, target)
                shutil.rmtree(staging, ignore_errors=True)
            for action in self._after:
                action()
            self.committed = True

    def discard(self) -> None:
        for staging, _ in self._staged:
            shutil.rmtree(staging, ignore_errors=True)
        for folder in sorted(self._made, key=lambda p: len(p.parts), reverse=True):
            try:
                folder.rmdir()  # only if empty: what was there before stays
            except OSError:
                pass


def _move_tree(source: Path, target: Path) -> None:
    target.mkdir(parents=True, exist_ok=True)
    for item in sorted(source.iterdir()):
        if item.is_dir():
            _move_tree(item, target / item.name)
        else:
            os.replace(item, target / item.name)


def fresh_folder() -> Path:
    """A new ``jaxbox-out-<date>-<time>`` folder name in the current directory."""
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    path = Path(f"jaxbox-out-{stamp}")
    n = 1
    while path.exists():
        n += 1
        path = Path(f"jaxbox-out-{stamp}-{n}")
    return path


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


# ---- DATA --------------------------------------------------------------------------------------

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
        help=DATA_HELP + "; several DATA of the same length are fitted together in one batch",
    )
    p.add_argument(
        "--map",
        action="append",
        default=[],
        metavar="CANONICAL=COLUMN",
        help="take canonical signal CANONICAL from your column COLUMN (repeatable)",
    )
    p.add_argument(
        "--time",
        "--time-column",
        dest="time",
        metavar="COLUMN",
        help="name of the time column (default: time)",
    )
    p.add_argument("--sep", metavar="CHAR", help="column separator of the CSV (default ',')")
    p.add_argument(
        "--decimal", metavar="CHAR", help="decimal mark of the CSV: '.' (default) or ','"
    )
    p.add_argument(
        "--scale",
        action="append",
        default=[],
        metavar="COLUMN=FACTOR",
        help="multiply canonical column COLUMN by FACTOR, e.g. Q_hea=1000 for kW (repeatable)",
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
        "--resample", metavar="RULE", help="resample first, e.g. 1h (mean, right-closed)"
    )
    p.add_argument(
        "--train", metavar="START..END", help="identification period (default: first half)"
    )
    p.add_argument("--validate", metavar="START..END", help="validation period (default: the rest)")


class DataOptions:
    """The checked data options of a command line (before anything is loaded)."""

    def __init__(self, args) -> None:
        self.specs = list(args.data)
        self.columns = pairs(args.map, "--map", "T_zon=living_temp")
        self.time = args.time
        if self.time is not None and not self.time.strip():
            raise UsageError("--time is empty; give the name of the time column")
        self.sep = separator(args.sep, "--sep")
        self.decimal = separator(args.decimal, "--decimal", ".,")
        if self.sep is not None and self.sep == (self.decimal or "."):
            raise UsageError(
                f"--sep and --decimal are both {self.sep!r}; with --decimal ',' use --sep ';'"
            )
        self.scale = scale(args.scale)
        self.ranges = bounds(args.range, "--range", "T_zon=-10:60")
        self.resample = resample_rule(args.resample)
        self.train_text, self.valid_text = args.train, args.validate
        self.train = period(args.train, "--train")
        self.valid = period(args.validate, "--validate")
        self._check_specs()

    @property
    def csv_options(self) -> dict:
        return {
            "--map": self.columns,
            "--time": self.time,
            "--sep": self.sep,
            "--decimal": self.decimal,
            "--scale": self.scale,
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
                    raise UsageError(f"DATA {spec!r}: {_reason(err)}") from None
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
        scale=opts.scale or None,
    )


def split_periods(data, opts: DataOptions):
    """Identification and validation datasets from the ``--train`` and ``--validate`` periods."""
    from ..data import DataError

    train, valid = opts.train, opts.valid
    if train is None and valid is None:
        return data.split()

    def cut(span, option, text):
        try:
            return data.slice(*span)
        except DataError as err:
            raise UsageError(f"{option} {text}: {err}") from None

    val = cut(valid, "--validate", opts.valid_text) if valid is not None else None
    if train is not None:
        ident = cut(train, "--train", opts.train_text)
    else:
        before = data.index[data.index < val.start]
        if len(before) == 0:
            raise UsageError(
                f"--validate {opts.valid_text}: no data before the validation period to identify "
                f"on (the data start at {data.start}); give --train or start --validate later"
            )
        ident = data.slice(None, before[-1])
    if val is None:
        rest = data.index[data.index > ident.end]
        if len(rest) == 0:
            raise UsageError(
                "no data left after the identification period for validation (the data end at "
                f"{data.end}); shorten --train or give --validate"
            )
        val = data.slice(rest[0], None)
    if val.start <= ident.end:
        raise UsageError(
            f"the validation period ({val.start} .. {val.end}) must start after the "
            f"identification period ends ({ident.end}); adjust --train or --validate"
        )
    return ident, val


def check_windows(ident, valid, columns=None, ranges=None) -> None:
    """The physical plausibility of the signals (``columns``, default every canonical one) in
    the windows actually used (``ranges``: the ``--range`` overrides); warnings (uncertain
    findings) go to stderr."""
    from ..data import check_plausibility

    for data, what in ((ident, "identification data"), (valid, "validation data")):
        notes = check_plausibility(
            data, overrides=ranges or None, columns=columns, what=what, warn=False
        )
        for note in notes:
            print(f"warning: {cli_message(note)}", file=sys.stderr, flush=True)


def load_all(args, opts: DataOptions | None = None, *, model=None):
    """Every DATA of the command line, loaded, split and checked: ``[(spec, data, ident, valid),
    …]``. With ``model``, its inputs and outputs must be columns of each."""
    from ..data import DataError

    opts = opts or DataOptions(args)
    out = []
    for spec in opts.specs:
        try:
            data = load_data(spec, opts)
            ident, valid = split_periods(data, opts)
            columns = None
            if model is not None:
                columns = list(model.inputs) + list(model.outputs)
                ident.require(columns, what=f"model {model.name}")
            check_windows(ident, valid, columns, opts.ranges)
        except (DataError, UsageError) as err:
            if len(opts.specs) == 1:
                raise
            raise type(err)(f"{spec}: {err}") from None  # which of the files
        check_interrupted()
        out.append((spec, data, ident, valid))
    return out


# ---- output documents --------------------------------------------------------------------------


def print_json(obj) -> None:
    print(json.dumps(to_jsonable(obj), indent=2, allow_nan=False))


def progress(args) -> Callable[[str], None]:
    """The progress callback of a long computation: lines on stderr (never with ``--json``),
    and at each step a Ctrl-C that a library swallowed stops the command."""
    quiet = getattr(args, "json", False)

    def say(msg: str) -> None:
        check_interrupted()
        if not quiet:
            print(msg, file=sys.stderr, flush=True)

    return say


def fit_json(result, validation, *, timing, data_info, valid=None) -> dict:
    """The JSON document of one fit (schema in the README).

    The estimate with its uncertainty, residual analysis and validity verdict come from
    :func:`jaxbox.validate.fit_report`; this adds the multistart counts, timings and data.
    """
    from ..validate import fit_report

    doc = fit_report(result, valid, validation=validation)
    starts = result.starts
    status = list(starts.status)
    doc.update(
        model=result.model.name,
        starts={
            "n": starts.n,
            "converged": status.count("converged"),
            "max_steps": status.count("max_steps"),
            "failed": sum(s not in ("converged", "max_steps") for s in status),
            "at_best": starts.n_at_best(),
            "best": result.best,
        },
        simulator=result.problem.simulator,
        timing=timing,
        data=data_info,
    )
    return doc


def data_info(spec, ident, valid) -> dict:
    return {
        "source": spec,
        "step_s": ident.step,
        "train": [str(ident.start), str(ident.end)],
        "validate": [str(valid.start), str(valid.end)],
        "n_train": len(ident),
        "n_validate": len(valid),
    }


def fit_default(name: str):
    """A default of :func:`jaxbox.fit.fit_model` (the command line does not keep a copy)."""
    import inspect

    from ..fit import fit_model

    return inspect.signature(fit_model).parameters[name].default


def host_pid() -> str:
    return f"{socket.gethostname()}-{os.getpid()}"
