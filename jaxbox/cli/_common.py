"""The ground floor of the command line, shared by every command: bad-input errors and their
messages in command-line terms, option checks, Ctrl-C, the JSON documents.

Nothing here imports another module of :mod:`jaxbox.cli`; ``_outputs`` and ``_data`` build on
it, the commands (``_commands``, ``_select``) on all three, and ``_main`` on the commands.

The contract of every command: all options are checked, and the output folders probed for
writing, before any computing; bad input raises :class:`UsageError` (or another ``ValueError`` of
the library: ``DataError``, ``ModelError``, ``FitError``…) whose message :func:`cli_message` puts
in command-line terms; outputs are written into a hidden staging folder and moved into place only
once everything is computed (:class:`~jaxbox.cli._outputs.Outputs`), so that an error or Ctrl-C
leaves no partial file.
"""

from __future__ import annotations

import ast
import json
import math
import os
import re
import shlex
import signal
import sys
from collections.abc import Callable, Sequence
from contextlib import contextmanager

from .._io import to_jsonable

__all__ = [
    "UsageError",
    "check_interrupted",
    "check_run_options",
    "cli_message",
    "deferred_interrupt",
    "fit_default",
    "fit_json",
    "forget_interrupt",
    "install_interrupt_handler",
    "on_interrupt",
    "print_json",
    "progress",
]


class UsageError(ValueError):
    """A command-line argument is malformed or out of range; the message names the option and
    says the expected form."""


# ---- Ctrl-C ------------------------------------------------------------------------------------

_INTERRUPTED = [False]
#: end the process in the handler itself (the console script) instead of raising
_EXIT_AT_ONCE = [False]
#: what to undo when the process ends in the handler (partial outputs), newest last
_CLEANUPS: list[Callable[[], None]] = []


def _on_sigint(signum, frame) -> None:
    """Ctrl-C. In the console script the process ends here and now: the partial outputs are
    removed, one line is printed, exit 130. Raising :class:`KeyboardInterrupt` instead would
    surface wherever the main thread happens to be, and JAX runs Python inside its C++ (garbage
    collection callbacks that swallow it with a printed traceback, callbacks whose C++ caller
    aborts the process on it). Called in-process, it raises :class:`KeyboardInterrupt`."""
    _INTERRUPTED[0] = True
    if not _EXIT_AT_ONCE[0]:
        raise KeyboardInterrupt
    for cleanup in reversed(_CLEANUPS):
        cleanup()
    try:
        sys.stderr.write("error: interrupted\n")
        sys.stderr.flush()
    except (OSError, ValueError):
        pass
    os._exit(130)


def install_interrupt_handler(exit_at_once: bool = False) -> None:
    """Take over Ctrl-C for a command (see :func:`_on_sigint`); a Ctrl-C is also remembered, so
    that one swallowed deep inside a library still stops the command at its next
    :func:`check_interrupted`."""
    _INTERRUPTED[0] = False
    _EXIT_AT_ONCE[0] = exit_at_once
    try:
        signal.signal(signal.SIGINT, _on_sigint)
    except ValueError:  # not the main thread (an embedding application): leave it alone
        pass


def on_interrupt(cleanup: Callable[[], None]) -> None:
    """Run ``cleanup`` if the process ends on Ctrl-C (until :func:`forget_interrupt`)."""
    _CLEANUPS.append(cleanup)


def forget_interrupt(cleanup: Callable[[], None]) -> None:
    if cleanup in _CLEANUPS:
        _CLEANUPS.remove(cleanup)


def check_interrupted() -> None:
    """Raise :class:`KeyboardInterrupt` if Ctrl-C was pressed (and perhaps swallowed)."""
    if _INTERRUPTED[0]:
        raise KeyboardInterrupt


@contextmanager
def deferred_interrupt():
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


def _suggested_options(m: re.Match) -> str:
    """A suggested mapping (:func:`jaxbox.data._suggest.suggestion_text`) as ``--map`` and
    ``--unit`` options, each name quoted for the shell."""
    try:
        columns = ast.literal_eval(m.group(1))
        units = ast.literal_eval(m.group(2)) if m.group(2) else {}
    except (ValueError, SyntaxError):  # a name the pattern cut: the Python form stays
        return m.group(0)
    return "by their names, perhaps " + _map_options(columns, units)


def _map_options(columns: dict, units: dict | None = None) -> str:
    """``--map`` options of a mapping (a list of columns: the option once for each), then the
    ``--unit`` options; each item quoted for the shell."""
    maps = [
        f"--map {shlex.quote(f'{k}={c}')}"
        for k, v in columns.items()
        for c in (v if isinstance(v, list) else [v])
    ]
    return " ".join(maps + [f"--unit {shlex.quote(f'{k}={v}')}" for k, v in (units or {}).items()])


def _several_options(m: re.Match) -> str:
    """ "all: columns={'T_zon': [...]} for their mean" as repeated ``--map`` options."""
    try:
        columns = ast.literal_eval(m.group(1))
    except (ValueError, SyntaxError):
        return m.group(0)
    return f"all: {_map_options(columns)} for their"


#: (pattern, replacement) turning the library's Python advice into command-line options.
_ADVICE: list[tuple[re.Pattern, str | Callable]] = [
    # "all: columns={'T_zon': ['a', 'b']} for their mean" -> "--map T_zon=a --map T_zon=b"
    (re.compile(r"all: columns=(\{'[^']+': \[.*?\]\}) for their"), _several_options),
    # "by their names, perhaps columns={'T_zon': 'Ti'} with units={'Q_hea': 'kW'}"
    (
        re.compile(
            r"by their names, perhaps columns=(\{.*?\})(?: with units=(\{.*?\}))?(?=\.?$|\)|;)"
        ),
        _suggested_options,
    ),
    # "units={'T_zon': 'degF'} (command line: --unit T_zon=degF)" -> "--unit T_zon=degF"
    (
        re.compile(r"\b(?:units|counters)=\{'[^']+': '[^']+'\}\s*\(command line: ([^)]*)\)"),
        r"\1",
    ),
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
    (re.compile(r"^resample rule\b"), "--resample"),
    (re.compile(r"\bscale applies after columns="), "--scale applies after --map"),
    (re.compile(r"^counters names column"), "--counter names column"),
    (re.compile(r"\(counters apply after columns=\)"), "(--counter applies after --map)"),
    (
        re.compile(r"read it with pd\.read_csv\(\.\.\., encoding=\.\.\.\) and pass the DataFrame"),
        "save it as UTF-8 text",
    ),
    (re.compile(r",? or read it with pandas yourself and pass the DataFrame"), ""),
    (re.compile(r",? or read it with pd\.read_excel\(\.\.\.\) and pass the DataFrame"), ""),
    (re.compile(r",? or parse the column yourself and pass a DataFrame with a DatetimeIndex"), ""),
    (re.compile(r"\(e\.g\. pd\.to_datetime\(\.\.\., utc=True\)\) and pass a DataFrame"), ""),
    (re.compile(r"\bcolumns=(?= \(canonical)"), "--map"),
    (re.compile(r"\(mapped by columns=\)"), "(mapped by --map)"),
    (re.compile(r"\bcolumns maps\b"), "--map maps"),
    (re.compile(r"\bpass time=\b"), "pass --time"),
    (re.compile(r"\bepoch="), "the epoch "),
    (re.compile(r"\b(start|end|at)=(?=')"), r"\1 "),
]


#: what the warnings given now are about (a DATA argument, among several), their prefix
_ABOUT = [""]


@contextmanager
def about(spec: str | None):
    """Warnings given inside name ``spec`` (``None``: as they are), for commands on several
    DATA."""
    before = _ABOUT[0]
    _ABOUT[0] = f"{spec}: " if spec else ""
    try:
        yield
    finally:
        _ABOUT[0] = before


def warning_line(message: object) -> str:
    """A warning as the command line gives it: one line, in its terms, naming the DATA it is
    about (see :func:`about`)."""
    return f"warning: {_ABOUT[0]}{cli_message(str(message))}"


_LINE_BREAKS = re.compile(r"[ \t]*[\r\n]+[ \t]*")


def _advice(text: str) -> str:
    """``text`` with the library's Python advice replaced by command-line options."""
    for pattern, replacement in _ADVICE:
        text = pattern.sub(replacement, text)
    return text


def cli_message(message: str) -> str:
    """A library error message in command-line terms: options instead of keyword arguments."""
    # One line; runs of spaces inside a quoted name (a column 'AUX2  [W]') are kept.
    return _advice(_LINE_BREAKS.sub(" ", str(message)).strip())


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


def check_fixed_in_range(model, fixed: dict) -> None:
    """A ``--fix`` value inside the parameter's range (its naming-convention bounds): beyond
    it, the simulations would only fail (a capacity of 1e-30 J/K)."""
    for name, value in fixed.items():
        p = model.parameter(name)
        if not p.lower <= value <= p.upper:
            raise UsageError(
                f"--fix {name}={value:g} lies outside the range of {name}, [{p.lower:g}, "
                f"{p.upper:g}] {p.unit}"
            )


def check_positive(fixed: dict, limits: dict) -> None:
    """Resistances ``R_*`` and capacities ``C_*`` are positive: a ``--fix`` value or a
    ``--bounds`` lower bound at or below zero is refused (the fit would only fail)."""
    for option, values in (("--fix", fixed), ("--bounds", limits)):
        for name, value in values.items():
            low = value[0] if isinstance(value, tuple) else value
            if name.startswith(("R_", "C_")) and not low > 0:
                kind = "resistance" if name.startswith("R_") else "capacity"
                what = "value" if option == "--fix" else "lower bound"
                raise UsageError(
                    f"{option} {name}: a {kind} is positive; the {what} {low:g} is not"
                )


def period(text: str | None, option: str):
    """``START..END`` (either side may be empty): the pair of its sides (``None`` for an empty
    one), each checked to be a date or time; ``None`` without the option."""
    if text is None:
        return None
    import pandas as pd

    start, sep, end = text.partition("..")
    if not sep:
        raise UsageError(
            f"{option} {text!r} must look like START..END (either side may be empty), e.g. "
            "2024-01-01..2024-01-15"
        )
    sides, stamps = [], []
    for side in (start.strip(), end.strip()):
        if not side:
            sides.append(None)
            continue
        try:
            stamp = pd.Timestamp(side)
        except (ValueError, TypeError, OverflowError):
            stamp = pd.NaT
        if stamp is pd.NaT:
            raise UsageError(f"{option} {text!r}: cannot read {side!r} as a date or time")
        sides.append(side)
        stamps.append(stamp)
    if len(stamps) == 2:
        try:
            reversed_ = stamps[0] > stamps[1]
        except TypeError:  # one with a time zone, one without
            raise UsageError(
                f"{option} {text!r}: give both sides with a time zone or neither"
            ) from None
        if reversed_:
            raise UsageError(f"{option} {text!r}: the start is after the end")
    return tuple(sides)


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


def homotopy_option(text: str | None) -> tuple[float, ...]:
    """``--homotopy``: observer gains ``0.9,0.5,0.2,0.05`` (the default when absent) or
    ``none``, checked as the fit checks them."""
    from ..fit import DEFAULT_HOMOTOPY, FitError
    from ..fit._fit import check_homotopy

    if text is None:
        return DEFAULT_HOMOTOPY
    if text.strip().lower() == "none":
        return ()
    example = ",".join(f"{g:g}" for g in DEFAULT_HOMOTOPY)
    gains = [number(item, "--homotopy") for item in text.split(",")]
    try:
        return check_homotopy(gains)
    except FitError:
        raise UsageError(
            f"--homotopy takes observer gains in (0, 1] that strictly decrease, e.g. {example}, "
            f"or none; got {text!r}"
        ) from None


def check_run_options(args) -> None:
    """``--starts``, ``--seed``, ``--max-steps`` (and ``--margin``, ``--patience``, ``--beam``,
    ``--continued``, ``--polish`` where the command has them) in range."""
    integer(args.starts, "--starts", 1, MAX_STARTS)
    integer(args.seed, "--seed", 0, 2**63 - 1)
    if args.max_steps is None:
        args.max_steps = fit_default("max_steps")
    integer(args.max_steps, "--max-steps", 1, MAX_STEPS)
    if hasattr(args, "homotopy"):
        args.homotopy = homotopy_option(args.homotopy)
    if getattr(args, "patience", None) is not None:
        integer(args.patience, "--patience", 1)
    if getattr(args, "beam", None) is not None:
        integer(args.beam, "--beam", 1, 64)
    if getattr(args, "continued", None) is not None:
        integer(args.continued, "--continued", 0)
    if getattr(args, "polish", None) is not None:
        integer(args.polish, "--polish", 0)
    margin = getattr(args, "margin", None)
    if margin is not None and not 0.0 <= margin < 1.0:  # nan fails too
        raise UsageError(
            f"--margin must be a fraction in [0, 1), e.g. 0.05 for 5 %, got {margin!r}"
        )


# ---- output documents --------------------------------------------------------------------------


def print_json(obj) -> None:
    print(json.dumps(to_jsonable(obj), indent=2, allow_nan=False))


def progress(args) -> Callable[[str], None]:
    """The progress callback of a long computation: lines on stderr (never with ``--json``),
    and at each step a Ctrl-C that a library swallowed stops the command."""
    quiet = getattr(args, "json", False)

    def say(msg: str) -> None:
        check_interrupted()
        if not quiet:  # the library's advice in command-line terms, line by line
            lines = str(msg).split("\n")
            print("\n".join(_advice(line) for line in lines), file=sys.stderr, flush=True)

    return say


def fit_json(result, validation, *, timing, data_info, valid=None, data_checks=None) -> dict:
    """The JSON document of one fit (schema in the README).

    The estimate with its uncertainty, residual analysis and validity verdict come from
    :func:`jaxbox.validate.fit_report` (its data check with ``data_checks``: the ``--range``
    and ``--stuck-hours`` the data were loaded with); this adds the multistart counts, timings
    and data.
    """
    from ..validate import fit_report

    doc = fit_report(result, valid, validation=validation, verdict_options=data_checks or None)
    starts = result.starts
    status = list(starts.status)
    doc.update(
        model=result.model.name,
        # the columns the model reads: a structure name is rebuilt for them (forecast, export)
        model_columns=[*result.model.inputs, *result.model.outputs],
        starts={
            "n": starts.n,
            "converged": status.count("converged"),
            "max_steps": status.count("max_steps"),
            "failed": sum(s not in ("converged", "max_steps") for s in status),
            "at_best": starts.n_at_best(),
            "best": result.best,
            "homotopy": list(result.settings.get("homotopy", ())),
        },
        simulator=result.problem.simulator,
        timing=timing,
        data={
            **data_info,
            # the identification samples fitted: gaps longer than --max-gap cut out
            "segments": [
                [str(result.data.index[a]), str(result.data.index[b - 1])]
                for a, b in result.data.segments
            ],
        },
    )
    return doc


def data_info(spec, ident, valid) -> dict:
    """The data part of a document: source, step, windows and their lengths (``validate``
    ``None`` with ``--validate none``), and the segments of the identification window."""
    return {
        "source": spec,
        "step_s": ident.step,
        "train": [str(ident.start), str(ident.end)],
        "validate": None if valid is None else [str(valid.start), str(valid.end)],
        "n_train": len(ident),
        "n_validate": 0 if valid is None else len(valid),
    }


def fit_default(name: str):
    """A default of :func:`jaxbox.fit.fit_model` (``starts``, ``max_steps``, ``homotopy``).

    The command line keeps no copy: it reads the one :mod:`jaxbox._defaults` holds, which
    ``fit_model`` takes its defaults from, without importing the fit, so that building the
    parser (``jaxbox --help``, a mistyped option) loads no JAX."""
    from .. import _defaults

    return getattr(_defaults, f"DEFAULT_{name.upper()}")
