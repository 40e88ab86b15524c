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
