"""The ``jaxbox`` command-line interface."""

from ._main import build_parser as build_parser
from ._main import main as _main


def main(argv: list[str] | None = None) -> int:
    """Console-script entry point."""
    raise SystemExit(_main(argv))
