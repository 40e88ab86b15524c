"""Test configuration: float64 everywhere, headless matplotlib, no persistent cache."""

import os

os.environ.setdefault("MPLBACKEND", "Agg")
# the command line keeps a persistent compilation cache; tests stay hermetic (one test turns
# it on in a folder of its own)
os.environ["JAXBOX_CACHE"] = "0"

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)
