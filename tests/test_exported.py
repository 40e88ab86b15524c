"""Fit programs kept as serialized exports: a later process skips their tracing, same results."""

from pathlib import Path

import jax
import numpy as np
import pytest
from _reference import synthetic_building

import jaxbox
from jaxbox import _compiled, _exported
from jaxbox.models import get_model

TRUTH = {"C_zon": 2.0e6, "C_wal": 3.0e7, "R_wal": 0.01, "gA": 2.0, "T_zon0": 19.0, "T_wal0": 16.0}


@pytest.fixture(scope="module")
def data():
    return synthetic_building(get_model("ZonWal"), TRUTH, n=96, seed=5, noise=0.05)


def _fit(data):
    """A fit compiled afresh (the in-process cache emptied first)."""
    _compiled.clear()
    return jaxbox.fit.fit_model(get_model("ZonWal"), data, starts=3, seed=1)


def test_an_exported_fit_is_read_back_without_tracing(data, tmp_path, monkeypatch):
    """Off: nothing written. On: the first fit writes its program, a later one (a new process
    as far as the in-process cache knows) reads it instead of exporting, and both give the
    direct program's results to the last digit."""
    monkeypatch.setattr(_exported, "directory", lambda: None)
    direct = _fit(data)
    monkeypatch.setattr(_exported, "directory", lambda: tmp_path)
    first = _fit(data)
    files = sorted(tmp_path.glob("fit-*.bin"))
    assert len(files) == 1 and files[0].stat().st_size > 0
    assert files[0].stat().st_mode & 0o044 == 0o044  # readable by the other users of a cache
    assert not list(tmp_path.glob("*.tmp"))

    def no_export(*a, **k):
        raise AssertionError("exported again instead of read back")

    monkeypatch.setattr(jax.export, "export", no_export)
    again = _fit(data)
    assert sorted(tmp_path.glob("fit-*.bin")) == files
    for res in (first, again):
        assert res.cost == direct.cost
        np.testing.assert_array_equal(res.starts.params, direct.starts.params)
        np.testing.assert_array_equal(res.starts.steps, direct.starts.steps)


def test_the_hlc_programs_are_read_back_without_tracing(data, tmp_path, monkeypatch):
    """The KPIs' program and the outdoor-referenced HLC's (what a select's report computes for
    its accepted model) are kept as exports too: a later process reads them back instead of
    tracing them, with the direct programs' values to the last digit."""
    from jaxbox.validate import kpis, outdoor_hlc

    monkeypatch.setattr(_exported, "directory", lambda: None)
    res = _fit(data)
    data_b = data.with_columns(T_bou=data["T_amb"] + 3.0)  # a boundary that follows T_amb
    res_b = jaxbox.fit.fit_model(get_model("Zon+Wal+Bou"), data_b, starts=2, seed=1)

    def numbers():
        _compiled.clear()  # a new process, as far as the in-process cache knows
        k, o = kpis(res), outdoor_hlc(res_b)
        return [k.hlc.value, k.hlc.std, o.value, o.hlc, *o.ci95]

    direct = numbers()
    monkeypatch.setattr(_exported, "directory", lambda: tmp_path)
    first = numbers()
    files = sorted(tmp_path.glob("kpi-*.bin"))
    assert len(files) == 2  # the KPIs' program and the outdoor HLC's

    def no_export(*a, **k):
        raise AssertionError("exported again instead of read back")

    monkeypatch.setattr(jax.export, "export", no_export)
    again = numbers()
    assert sorted(tmp_path.glob("kpi-*.bin")) == files
    assert first == direct and again == direct


def test_a_damaged_artifact_is_exported_again(data, tmp_path, monkeypatch):
    monkeypatch.setattr(_exported, "directory", lambda: tmp_path)
    good = _fit(data)
    (path,) = tmp_path.glob("fit-*.bin")
    path.write_bytes(b"not a program")
    again = _fit(data)
    assert again.cost == good.cost
    assert path.stat().st_size > len(b"not a program")


def test_artifacts_are_named_by_program_source_and_options():
    """Another key, another jaxbox source or other compiler options: another artifact; a key
    shown by an address (it differs from process to process) or holding an array shown
    abridged (two keys could share it) is never kept."""
    a = _exported._digest("fit", ("fit", 1, (3, 4)), None)
    assert a == _exported._digest("fit", ("fit", 1, (3, 4)), None)
    assert a != _exported._digest("fit", ("fit", 2, (3, 4)), None)
    assert a != _exported._digest("fit", ("fit", 1, (3, 4)), {"xla_backend_optimization_level": 1})
    assert _exported._digest("fit", ("fit", object()), None) is None
    assert _exported._digest("fit", ("fit", np.arange(5000)), None) is None
    saved = list(_exported._SOURCE)
    try:
        _exported._SOURCE[:] = ["another source"]
        assert a != _exported._digest("fit", ("fit", 1, (3, 4)), None)
    finally:
        _exported._SOURCE[:] = saved


def test_the_folder_is_in_the_persistent_cache_unless_turned_off(monkeypatch):
    monkeypatch.setenv("JAXBOX_EXPORTED", "1")
    base = jax.config.jax_compilation_cache_dir
    expected = None if not base else Path(base) / "jaxbox-exported"
    assert _exported.directory() == expected
    monkeypatch.setenv("JAXBOX_EXPORTED", "0")
    assert _exported.directory() is None


def _read_back(tmp_path, monkeypatch, pattern, run, same):
    """``run()`` with exports off, then writing its artifacts, then reading them back (the
    in-process cache emptied before each): the same results each time, and the last run
    exports nothing."""
    monkeypatch.setattr(_exported, "directory", lambda: None)
    _compiled.clear()
    direct = run()
    monkeypatch.setattr(_exported, "directory", lambda: tmp_path)
    _compiled.clear()
    first = run()
    files = sorted(tmp_path.glob(pattern))
    assert files and all(f.stat().st_size > 0 for f in files)

    def no_export(*a, **k):
        raise AssertionError("exported again instead of read back")

    monkeypatch.setattr(jax.export, "export", no_export)
    _compiled.clear()
    again = run()
    assert sorted(tmp_path.glob(pattern)) == files
    same(first, direct)
    same(again, direct)


# three compilations of a large program; the fit's read-back (fast tier) shares the mechanism
@pytest.mark.slow
def test_the_adaptive_post_simulation_is_read_back(tmp_path, monkeypatch):
    """The diffrax post-simulation of a validation (the most of a later ``jaxbox fit``'s
    tracing) goes through an export too, and runs to the last digit as compiled directly."""
    from jaxbox.simulate._diffrax import diffrax_runs_numpy

    A = np.array([[-1e-4, 5e-5], [2e-5, -3e-5]])
    B = np.array([[5e-5, 1e-6], [1e-5, 0.0]])
    t = np.arange(24) * 3600.0
    u = np.stack([np.stack([5 + np.sin(t / 4e4), 300 * np.cos(t / 2e4) ** 2], 1)] * 2)
    x0 = np.array([[20.0, 18.0], [21.0, 17.0]])

    def same(a, b):
        np.testing.assert_array_equal(a, b)

    def run():
        return diffrax_runs_numpy(A, B, t, u, x0)

    _read_back(tmp_path, monkeypatch, "diffrax-runs-*.bin", run, same)


# three compilations of a large program; the fit's read-back (fast tier) shares the mechanism
@pytest.mark.slow
def test_a_maximum_likelihood_fit_is_read_back(data, tmp_path, monkeypatch):
    """The stochastic fit's solve and its Hessian at the optimum (most of a later ``jaxbox
    fit --method ml``'s tracing) go through exports too, with the same results."""
    from jaxbox.stochastic import fit_ml

    def run():
        return fit_ml("Zon", data, starts=2, max_steps=40)

    def same(a, b):
        assert a.objective == b.objective
        np.testing.assert_array_equal(a.starts.params, b.starts.params)
        np.testing.assert_array_equal(a.hessian, b.hessian)

    _read_back(tmp_path, monkeypatch, "stochastic*.bin", run, same)
    names = {f.name.split("-")[0] for f in tmp_path.glob("stochastic*.bin")}
    assert names == {"stochastic"} and len(list(tmp_path.glob("stochastic-hessian-*.bin"))) == 1
