"""One bounded cache of compiled functions: rooms, hits, clear() and least-recently-used eviction.

A tiny problem (a one-state model over two days of hourly samples) evaluated at the true
parameters, so that no fit has to be compiled: the sensitivities and the uncertainty analysis
take any result with ``problem``, ``params`` and ``data``. The verbs are run once per room; the
eviction tests fetch the rooms' entries through the same getters the verbs use, which build the
jitted functions without compiling them.
"""

from __future__ import annotations

import types

import jax
import numpy as np
import pytest
from _reference import synthetic_building

from jaxbox import _compiled
from jaxbox.fit import fit_sensitivity, make_problem
from jaxbox.fit._sensitivity import _functions as sensitivity_functions
from jaxbox.models import get_model
from jaxbox.reference import collocation_fit
from jaxbox.reference._transcription import _functions as collocation_functions
from jaxbox.validate import sensitivities
from jaxbox.validate._uncertainty import _jacobian_fn

TRUTH = {"C_zon": 5e6, "R_wal": 0.01, "gA": 3.0, "T_zon0": 20.0}
N = 48
ROOMS = ("sensitivity", "uncertainty", "collocation")


@pytest.fixture(scope="module")
def result():
    """A stand-in for a fit result at the true parameters (48 hourly samples)."""
    data = synthetic_building(get_model("Zon"), TRUTH, n=N, seed=4, noise=0.02)
    return types.SimpleNamespace(
        problem=make_problem(get_model("Zon"), data), params=TRUTH, data=data
    )


@pytest.fixture(autouse=True)
def empty_cache():
    """Every test starts from an empty cache; the maximum size is restored afterwards."""
    before = _compiled.info()["max_entries"]
    _compiled.clear()
    yield
    _compiled.set_max_entries(before)
    _compiled.clear()


def _entries(room: str | None = None) -> int:
    return _compiled.info(room)["entries"]


def _compiles() -> int:
    return _compiled.info()["compiles"]


# getters of one entry per room (no compilation: jax.jit compiles on the first call)
def _sensitivity(result):
    return sensitivity_functions(result.problem, N)


def _uncertainty(result):
    return _jacobian_fn(result.problem, N)


def _collocation(result, n_c: int = 3):
    return collocation_functions(result.problem, n_c, ((N,),))


def test_sensitivity_compiles_once(result) -> None:
    first = fit_sensitivity(result)
    assert _entries("sensitivity") == 1 and _compiles() == 1
    second = fit_sensitivity(result)
    info = _compiled.info()
    assert info["compiles"] == 1 and info["hits"] == 1 and _entries() == 1
    np.testing.assert_array_equal(first.values, second.values)
    # the cached function traced and compiled once for both calls
    assert _sensitivity(result)["derivatives"]._cache_size() == 1


def test_uncertainty_compiles_once(result) -> None:
    _, J1 = sensitivities(result)
    assert _entries("uncertainty") == 1 and _compiles() == 1
    _, J2 = sensitivities(result)
    assert _compiles() == 1 and _compiled.info()["hits"] == 1
    np.testing.assert_array_equal(J1, J2)
    # the shared program of the network in array form, compiled once for its padded shapes
    # (an executable: a call with other shapes could not retrace it)
    assert isinstance(_compiled.entries("uncertainty")[0], jax.stages.Compiled)


def test_uncertainty_shares_one_program_between_structures(result) -> None:
    """Structures of the same padded size (here Zon and ZonWal) share the compiled
    sensitivities: a structure search compiles per size, not per candidate."""
    sensitivities(result)
    data = synthetic_building(get_model("ZonWal"), {**TRUTH, "C_wal": 2e7, "T_wal0": 15.0}, n=N)
    other = types.SimpleNamespace(
        problem=make_problem(get_model("ZonWal"), data),
        params={**TRUTH, "C_wal": 2e7, "T_wal0": 15.0},
        data=data,
    )
    sensitivities(other)
    assert _compiles() == 1 and _entries("uncertainty") == 1


def test_uncertainty_of_neighbouring_lengths_shares_one_program(result, monkeypatch) -> None:
    """Records of 37, 45 and 48 samples share one compiled Jacobian (each extended to its
    bucket of 48 samples, the extra samples dropped); each Jacobian is, to the last digit, the
    one of a program compiled for the record's own length."""
    import jaxbox.fit._fit as fit_module

    def cut(n):
        data = result.data.slice(end=result.data.index[n - 1])
        return types.SimpleNamespace(problem=result.problem, params=TRUTH, data=data)

    shared = {n: sensitivities(cut(n)) for n in (37, 45, N)}
    assert _compiles() == 1 and _entries("uncertainty") == 1
    monkeypatch.setattr(fit_module, "bucket_samples", lambda n: n)  # a program per length
    for n, (y, J) in shared.items():
        y_own, J_own = sensitivities(cut(n))
        assert y.shape == (n, 1) and J.shape == (n, 1, len(result.problem.free))
        np.testing.assert_array_equal(y, y_own)
        np.testing.assert_array_equal(J, J_own)
    assert _compiles() == 3  # 37 and 45 of their own; 48 is its own bucket


def test_collocation_compiles_once(result) -> None:
    options = {"hessian": "gauss-newton", "max_iterations": 3}
    first = collocation_fit("Zon", result.data, **options)
    assert _entries("collocation") == 1 and _compiles() == 1
    second = collocation_fit("Zon", result.data, **options)
    assert _compiles() == 1 and _compiled.info()["hits"] == 1 and _entries() == 1
    assert first.params == second.params


def test_clear_empties_every_room(result) -> None:
    _sensitivity(result), _uncertainty(result), _collocation(result), _collocation(result, 2)
    assert [_entries(room) for room in ROOMS] == [1, 1, 2]
    _compiled.clear()
    assert _entries() == 0 and [_entries(room) for room in ROOMS] == [0, 0, 0]
    assert _compiles() == 0
    _sensitivity(result)  # built again after clear()
    assert _compiles() == 1


def test_one_entry_evicts_the_previous(result) -> None:
    _compiled.set_max_entries(1)
    first = _sensitivity(result)
    _uncertainty(result)
    info = _compiled.info()
    assert info["entries"] == 1 and info["evictions"] == 1
    assert _entries("sensitivity") == 0 and _entries("uncertainty") == 1
    again = _sensitivity(result)  # evicted, so built again
    assert again is not first and _compiles() == 3 and _entries("sensitivity") == 1


def test_least_recently_used_goes_first(result) -> None:
    _compiled.set_max_entries(2)
    first = _sensitivity(result)
    _uncertainty(result)
    assert _sensitivity(result) is first  # a hit: uncertainty is now the oldest
    _collocation(result)
    assert [_entries(room) for room in ROOMS] == [1, 0, 1]
    assert _compiled.info()["evictions"] == 1
    assert _sensitivity(result) is first


def test_shrinking_evicts_and_zero_is_refused(result) -> None:
    _sensitivity(result), _uncertainty(result)
    _compiled.set_max_entries(1)
    assert _entries() == 1 and _entries("uncertainty") == 1
    with pytest.raises(ValueError, match="at least one"):
        _compiled.set_max_entries(0)


def test_a_level_set_in_xla_flags_is_not_raised_by_the_lean_option(monkeypatch) -> None:
    """``jit(lean=True)`` asks for level 1 only where ``XLA_FLAGS`` sets none: a program's own
    options override the flags, and the tests' level 0 must stay 0."""
    if _compiled.compiler_options() is None:
        pytest.skip("XLA's defaults on this backend: no options of jaxbox's")
    monkeypatch.setenv("XLA_FLAGS", "--xla_backend_optimization_level=0")
    assert "xla_backend_optimization_level" not in _compiled._options(lean=True)
    assert _compiled._options(once=True)["xla_backend_optimization_level"] == 0
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false")
    assert _compiled._options(lean=True)["xla_backend_optimization_level"] == 1
    monkeypatch.delenv("XLA_FLAGS")
    assert _compiled._options(lean=True)["xla_backend_optimization_level"] == 1
    assert "xla_backend_optimization_level" not in _compiled._options()


def test_a_key_being_built_is_built_once_and_a_failed_build_is_taken_over() -> None:
    """Two threads asking for one key (a program compiled ahead in the background, and the
    batch that needs it): one builds it, the other waits and gets the same value; where the
    build fails, the waiting caller builds it itself (and a failure reaches its own caller)."""
    import threading
    import time

    calls = []

    def slow():
        calls.append(threading.current_thread().name)
        time.sleep(0.3)
        return object()

    got = {}

    def ask(name):
        got[name] = _compiled.cached(("test", "once"), slow)

    threads = [threading.Thread(target=ask, args=(n,), name=n) for n in ("a", "b")]
    for t in threads:
        t.start()
        time.sleep(0.05)
    for t in threads:
        t.join()
    assert len(calls) == 1
    assert got["a"][0] is got["b"][0]
    assert sorted(built for _, built in got.values()) == [False, True]

    def failing():
        time.sleep(0.3)
        raise RuntimeError("no compiler")

    errors = []

    def first():
        try:
            _compiled.cached(("test", "taken over"), failing)
        except RuntimeError as err:
            errors.append(err)

    t = threading.Thread(target=first)
    t.start()
    time.sleep(0.05)
    value, built = _compiled.cached(("test", "taken over"), lambda: "second")
    t.join()
    assert (value, built) == ("second", True) and len(errors) == 1
