"""The ``jaxbox`` command-line interface."""

import os
import sys

from ._main import build_parser as build_parser
from ._main import main as _main


def main(argv: list[str] | None = None) -> int:
    """Console-script entry point.

    After Ctrl-C (exit 130) the process ends at once, without the interpreter's clean-up: JAX's
    compiler threads may still be running, and tearing the interpreter down under them can
    crash it (the signal handler itself ends it; see ``jaxbox.cli._common._on_sigint``).
    """
    code = _main(argv, exit_at_once=True)
    # what the command printed reaches its reader before the interpreter shuts down (a Ctrl-C
    # during the shutdown, when Python has restored the default handler, ends the process
    # before the buffers would be flushed)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    if code == 130:
        os._exit(130)
    raise SystemExit(code)
