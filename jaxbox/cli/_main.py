"""The ``jaxbox`` command: argument parsing, error handling and dispatch.

Exit codes: 0 success; 2 bad input (one line ``error: …`` on stderr, no traceback); 1 an
unexpected internal error (set ``JAXBOX_DEBUG=1`` for the traceback).
"""

from __future__ import annotations

import argparse
import os
import sys

__all__ = ["main", "build_parser"]

_DESCRIPTION = """\
Identify and validate grey-box RC thermal models of buildings from monitoring data.

  jaxbox models                      list the model library
  jaxbox fit DATA --model NAME       fit one model, cross-validate, print the estimate
  jaxbox demo                        fit the bundled twin-house data end to end
"""

_DATA_HELP = (
    "CSV file with a 'time' column and canonical columns (T_zon, T_amb, Q_hea, I_glo_hor, …), "
    "or a bundled dataset: twinhouse_exp1:N2, twinhouse_exp1:O5 (add @10min for 10-minute data)"
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jaxbox",
        description=_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"jaxbox {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("models", help="list library models with their parameters")
    p.add_argument("--json", action="store_true", help="print one JSON object")

    p = sub.add_parser("fit", help="fit a model to data and cross-validate it")
    p.add_argument("data", metavar="DATA", help=_DATA_HELP)
    p.add_argument("--model", "-m", required=True, help="library model name (see `jaxbox models`)")
    p.add_argument(
        "--map",
        action="append",
        default=[],
        metavar="CANONICAL=COLUMN",
        help="take canonical signal CANONICAL from your column COLUMN (repeatable)",
    )
    p.add_argument("--time", metavar="COLUMN", help="name of the time column (default: time)")
    p.add_argument(
        "--resample", metavar="RULE", help="resample first, e.g. 1h (mean, right-closed)"
    )
    p.add_argument(
        "--train", metavar="START..END", help="identification period (default: 1st half)"
    )
    p.add_argument("--validate", metavar="START..END", help="validation period (default: the rest)")
    p.add_argument("--starts", type=int, default=16, help="number of starts (default 16)")
    p.add_argument("--seed", type=int, default=0, help="seed of the Latin hypercube (default 0)")
    p.add_argument(
        "--fix", action="append", default=[], metavar="P=VALUE", help="hold P at VALUE (SI)"
    )
    p.add_argument(
        "--bounds", action="append", default=[], metavar="P=LO:HI", help="bounds of P (SI)"
    )
    p.add_argument("--simulator", choices=("exact", "diffrax"), default="exact")
    p.add_argument("--max-steps", type=int, default=200, help="LM iterations per start")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--plots", metavar="DIR", help="write the validation plots (PNG) into DIR")

    p = sub.add_parser("demo", help="fit the bundled twin-house data and summarise")
    p.add_argument(
        "--out", metavar="DIR", help="output folder (default: a fresh jaxbox-out-* folder)"
    )
    p.add_argument("--house", choices=("N2", "O5"), default="N2")
    p.add_argument("--starts", type=int, default=16)
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    return parser


def _version() -> str:
    from .. import __version__

    return __version__


def _bad_input_errors() -> tuple[type[BaseException], ...]:
    from ..data import DataError
    from ..fit import FitError
    from ..models import ModelError
    from ..validate import ValidationError
    from ._commands import UsageError

    return (DataError, FitError, ModelError, ValidationError, UsageError, FileNotFoundError)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``jaxbox`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    from .. import enable_x64

    enable_x64()
    try:
        from ._commands import run

        return run(args)
    except _bad_input_errors() as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
    except Exception as err:  # pragma: no cover - last resort, keeps the one-line contract
        if os.environ.get("JAXBOX_DEBUG"):
            raise
        print(
            f"error: internal error ({type(err).__name__}: {err}); rerun with JAXBOX_DEBUG=1 "
            "for the traceback",
            file=sys.stderr,
        )
        return 1
