"""The ``jaxbox`` command: argument parsing, error handling and dispatch.

Compiled solves are kept in JAX's persistent compilation cache between runs (see
:func:`jaxbox.enable_compilation_cache`; ``JAXBOX_CACHE=0`` turns it off).

Exit codes:

* 0 success;
* 1 ``select`` found no valid model (its last line says why);
* 2 bad input: one line ``error: …`` on stderr naming the option, column, row or parameter and
  the fix, no traceback, no output file;
* 3 an internal error (a fault of jaxbox, not of the input): one line ``error: internal error
  (…)`` on stderr saying where the traceback went — a log file ``jaxbox-error-*.log`` in the
  temporary folder, or stderr itself with ``JAXBOX_DEBUG=1`` — and no partial output file;
* 130 Ctrl-C: one line, no partial output file.

Data that are plausible but suspicious give ``warning: …`` lines and the command goes on; each
names the option that removes the doubt: a unit that looks wrong (``--scale``, ``--counter``),
a steep change of the outdoor temperature (kept as weather), a partial first or last sample
(dropped by ``fit`` and ``select``; ``--trim none`` keeps it), a long gap (``--max-gap``). Every
refusal of the plausibility checks can be overridden where the data are right:
``--allow [COLUMN=]CHECK`` (or ``--range``, ``--stuck-hours`` for their checks).
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import warnings

from ._commands import add_fit_arguments, fit_command, models_command
from ._common import (
    UsageError,
    check_interrupted,
    cli_message,
    install_interrupt_handler,
    warning_line,
)
from ._design import add_design_arguments, design_command
from ._estimate import add_estimate_arguments, estimate_command
from ._export import add_export_arguments, export_command
from ._fleet import add_fleet_arguments, fleet_command
from ._forecast import add_forecast_arguments, forecast_command
from ._select import add_demo_arguments, add_select_arguments, demo_command, select_command

__all__ = ["main", "build_parser"]

_DESCRIPTION = """\
Identify and validate grey-box RC thermal models of buildings from monitoring data.

  jaxbox models                      list the model library
  jaxbox fit DATA --model NAME       fit one model, cross-validate, print the estimate
  jaxbox select DATA                 forward selection from simple to complex models
  jaxbox demo                        forward selection on the bundled twin-house data + report
  jaxbox estimate DATA --model NAME --params FIT.json --out STATES.csv
                                     states of a stochastic (--method ml) fit, to a CSV
  jaxbox fleet DIR --out OUT         every building of a fleet on Dask: models, KPIs, Parquet
  jaxbox design --model NAME --out CSV   plan the heating of an identification experiment
  jaxbox forecast DATA --params FIT.json --at TIME --horizon 24h --out CSV
                                     forecast with 50 % and 95 % bands (a backtest without
                                     --inputs FUTURE.csv)
  jaxbox export FIT.json --step 15min --out MODEL.json|.npz|.mo|.py
                                     discrete state space, Modelica or python-control
"""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: a malformed command line raises :class:`UsageError`
    (exit 2 with one ``error:`` line) instead of printing the usage block."""

    def error(self, message: str):
        raise UsageError(f"{message} (see {self.prog} --help)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="jaxbox",
        description=_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"jaxbox {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("models", help="list library models with their parameters")
    p.add_argument("--json", action="store_true", help="print one JSON object")

    p = sub.add_parser("fit", help="fit a model to data and cross-validate it")
    add_fit_arguments(p)

    p = sub.add_parser("select", help="forward selection over candidate models")
    add_select_arguments(p)

    p = sub.add_parser(
        "demo", help="forward selection on the bundled twin-house data, with an HTML report"
    )
    add_demo_arguments(p)

    p = sub.add_parser("estimate", help="filtered and smoothed states from an ML fit, to a CSV")
    add_estimate_arguments(p)
    p = sub.add_parser("fleet", help="a fleet of buildings on Dask (or: fleet make DIR --n N)")
    add_fleet_arguments(p)
    add_design_arguments(sub.add_parser("design", help="plan an identification experiment"))
    add_forecast_arguments(sub.add_parser("forecast", help="forecast with bands from a fit file"))
    add_export_arguments(sub.add_parser("export", help="a fit as a state space or Modelica model"))
    return parser


def _version() -> str:
    from .. import __version__

    return __version__


def _bad_input_errors() -> tuple[type[BaseException], ...]:
    """Errors that mean bad input (exit 2): the library's ``ValueError`` subclasses that name
    what to fix, a file that cannot be read or written, a problem too big for the memory (a
    malformed command line, :class:`UsageError`, is told before these are imported)."""
    from .._x64 import PrecisionError
    from ..data import DataError
    from ..fit import FitError
    from ..models import ModelError
    from ..select import PersistError
    from ..validate import ValidationError

    return (
        DataError,
        FitError,
        ModelError,
        ValidationError,
        PersistError,
        PrecisionError,
        OSError,
        MemoryError,
    )


def _compilation_cache() -> None:
    """Reuse compiled solves across runs (JAX's persistent cache in ``$JAXBOX_CACHE_DIR`` or
    ``~/.cache/jaxbox/jax``); ``JAXBOX_CACHE=0`` turns it off. A folder that cannot be
    written only costs the reuse."""
    if os.environ.get("JAXBOX_CACHE", "1").strip().lower() in ("0", "no", "off", "false"):
        return
    from .._cache import enable_compilation_cache

    try:
        enable_compilation_cache()
    except OSError:
        pass


_COMMANDS = {
    "models": models_command,
    "fit": fit_command,
    "select": select_command,
    "demo": demo_command,
    "estimate": estimate_command,
    "fleet": fleet_command,
    "design": design_command,
    "forecast": forecast_command,
    "export": export_command,
}


def _run(argv: list[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    from .. import enable_x64

    _SHOWN.clear()
    with warnings.catch_warnings():
        warnings.showwarning = _one_line_warning
        enable_x64()
        _compilation_cache()
        code = _COMMANDS[args.command](args)
    check_interrupted()  # a Ctrl-C some library swallowed still stops with 130
    return code


#: the warnings of this command given so far (each is given once)
_SHOWN: set[str] = set()


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings as one line ``warning: …`` in command-line terms (no file, line, source), each
    once per command (a window prepared twice warns twice)."""
    text = warning_line(message)
    if text not in _SHOWN:
        _SHOWN.add(text)
        print(text, file=sys.stderr, flush=True)


#: what diffrax says when an adaptive simulation runs out of steps
_SOLVER_STEPS = "maximum number of solver steps was reached"


def _error(text: str) -> None:
    print(f"error: {text}", file=sys.stderr, flush=True)


def _os_error(err: OSError) -> str:
    if isinstance(err, FileNotFoundError | PermissionError | IsADirectoryError) or err.filename:
        where = f"{err.filename}: " if err.filename else ""
        return f"{where}{err.strerror or err}"
    return str(err)


def main(argv: list[str] | None = None, *, exit_at_once: bool = False) -> int:
    """Entry point of the ``jaxbox`` console script; returns the exit code.

    0 success; 1 no valid model (``select``); 2 bad input, with one line ``error: …`` on
    stderr (no traceback); 3 an internal error, with one line saying where the traceback went
    (:func:`_internal_error`); 130 Ctrl-C, with one line and no partial output file. With
    ``exit_at_once`` (the console script) Ctrl-C ends the process in the signal handler, after
    removing the partial outputs.
    """
    previous = signal.getsignal(signal.SIGINT)
    install_interrupt_handler(exit_at_once)
    # a failed simulation inside a compiled call is logged by JAX with a traceback before it
    # is raised; the command reports it in one line
    logging.getLogger("jax._src.callback").setLevel(logging.CRITICAL)
    try:
        return _run(argv)
    except KeyboardInterrupt:
        _error("interrupted")
        return 130
    except BrokenPipeError:  # output piped into e.g. `head`, which closed early
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except SystemExit:  # --help, --version: argparse's own exit, before anything heavy loads
        raise
    except UsageError as err:  # a malformed command line: told without loading the library
        _error(cli_message(str(err)))
        return 2
    except _bad_input_errors() as err:
        if isinstance(err, OSError):
            _error(cli_message(_os_error(err)))
        elif isinstance(err, MemoryError):
            _error("out of memory; give fewer --starts or shorter periods")
        else:
            _error(cli_message(str(err)))
        return 2
    except Exception as err:  # last resort, keeps the one-line contract
        if _SOLVER_STEPS in str(err):  # an adaptive simulation gave up (a stiff model)
            _error(
                "a simulation needed more solver steps than allowed: the model is too stiff for "
                "the data (very small capacities or resistances); narrow --bounds or --fix"
            )
            return 2
        return _internal_error(err)
    finally:
        try:
            signal.signal(signal.SIGINT, previous)
        except (ValueError, TypeError):
            pass


#: exit code of an internal error (a fault of jaxbox, not of the input)
INTERNAL_ERROR = 3


def _internal_error(err: BaseException) -> int:
    """Report an unexpected exception: one line on stderr saying where its traceback went, exit
    :data:`INTERNAL_ERROR`. The traceback goes to stderr with ``JAXBOX_DEBUG=1``, otherwise to a
    new log file ``jaxbox-error-<time>-<random>.log`` in the temporary folder (stderr if even that
    cannot be written). The outputs were staged and are already discarded (``Outputs``)."""
    import tempfile
    import traceback
    from datetime import datetime

    trace = "".join(traceback.format_exception(type(err), err, err.__traceback__))
    first = str(err).splitlines()[0] if str(err).strip() else ""
    what = f"internal error ({type(err).__name__}: {cli_message(first)})"
    where = None
    if not os.environ.get("JAXBOX_DEBUG"):
        stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
        try:
            fd, where = tempfile.mkstemp(prefix=f"jaxbox-error-{stamp}-", suffix=".log")
            with os.fdopen(fd, "w", encoding="utf-8") as log:
                log.write(f"jaxbox {_version()}\n{trace}")
        except OSError:
            where = None
    if where is None:
        print(trace, end="", file=sys.stderr, flush=True)
        _error(f"{what}; the traceback is above; please report it")
    else:
        _error(f"{what}; traceback in {where}; please report it")
    return INTERNAL_ERROR
