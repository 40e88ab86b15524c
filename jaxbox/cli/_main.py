"""The ``jaxbox`` command: argument parsing, error handling and dispatch.

Compiled solves are kept in JAX's persistent compilation cache between runs (see
:func:`jaxbox.enable_compilation_cache`; ``JAXBOX_CACHE=0`` turns it off).

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
  jaxbox select DATA                 forward selection from simple to complex models
  jaxbox demo                        forward selection on the bundled twin-house data + report
"""


def build_parser() -> argparse.ArgumentParser:
    from ._commands import add_data_arguments
    from ._select import add_demo_arguments, add_select_arguments

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
    add_data_arguments(p)
    p.add_argument("--model", "-m", required=True, help="library model name (see `jaxbox models`)")
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

    p = sub.add_parser("select", help="forward selection over candidate models")
    add_select_arguments(p)

    p = sub.add_parser(
        "demo", help="forward selection on the bundled twin-house data, with an HTML report"
    )
    add_demo_arguments(p)
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


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``jaxbox`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    from .. import enable_x64

    enable_x64()
    _compilation_cache()
    try:
        from ._commands import run

        return run(args)
    except _bad_input_errors() as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into e.g. `head`, which closed early
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
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
