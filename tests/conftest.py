"""Test configuration: float64 everywhere, headless matplotlib, one compilation cache per run.

The command line keeps a persistent compilation cache in the user's folder; the tests never
touch it (``JAXBOX_CACHE=0``; one test turns it on in a folder of its own). Instead, the
processes of one test run (``pytest -n``: the xdist workers) share a persistent cache in a fresh
temporary folder, so that a program compiled by one worker is loaded, not compiled again, by
the others; the folder starts empty and is removed at the end of the run, so every run is
hermetic. ``JAXBOX_TEST_CACHE=0`` turns the shared cache off.
"""

import os
import shutil
import tempfile
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ["JAXBOX_CACHE"] = "0"
# the fit programs are compiled directly, not through kept exports (tests/test_exported.py
# turns them on in a folder of its own)
os.environ.setdefault("JAXBOX_EXPORTED", "0")
if os.environ.get("PYTEST_XDIST_WORKER"):  # a worker per core: one thread each
    os.environ.setdefault("JAXBOX_THREADS", "1")

# the tests compile hundreds of small programs and run each briefly: XLA's backend optimisations
# cost more compile time than they save (the benchmarks and the command line keep them)
os.environ["XLA_FLAGS"] = " ".join(
    [os.environ.get("XLA_FLAGS", ""), "--xla_backend_optimization_level=0"]
).strip()

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

# one folder per run: named after the controlling process (an xdist worker's parent)
_RUN = os.getppid() if os.environ.get("PYTEST_XDIST_WORKER") else os.getpid()
_SHARED = Path(tempfile.gettempdir()) / f"jaxbox-tests-{_RUN}" / "jax"
if os.environ.get("JAXBOX_TEST_CACHE", "1").strip().lower() not in ("0", "no", "off", "false"):
    from jaxbox import enable_compilation_cache  # noqa: E402

    enable_compilation_cache(_SHARED)
    # the tests compile many programs of 0.1–0.5 s (at the lowest optimisation level) that
    # several workers need: shared too
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.1)
    # the processes the tests start (notebook kernels, the command line, cluster workers)
    # share it too
    os.environ["JAX_COMPILATION_CACHE_DIR"] = str(_SHARED)
    os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"] = "0.1"
    os.environ["JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES"] = "0"


def pytest_sessionfinish(session, exitstatus):
    """The controlling process (not an xdist worker) removes the run's cache folder."""
    if not hasattr(session.config, "workerinput"):
        shutil.rmtree(_SHARED.parent, ignore_errors=True)


# ``JAXBOX_TEST_CPU=FILE``: append each test's CPU seconds (its process and the processes it
# waited for: the command line, notebook kernels), a line per test, to FILE. CPU time, unlike
# wall time, hardly depends on what else the machine runs: it is how the tiers are sized.
_CPU_LOG = os.environ.get("JAXBOX_TEST_CPU")
if _CPU_LOG:
    import resource

    import pytest

    def _cpu() -> float:
        own = resource.getrusage(resource.RUSAGE_SELF)
        kids = resource.getrusage(resource.RUSAGE_CHILDREN)
        return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(item, nextitem):
        start = _cpu()
        yield
        with open(_CPU_LOG, "a", encoding="utf-8") as log:
            log.write(f"{_cpu() - start:.3f}\t{item.nodeid}\n")
