"""An internal error (a fault of jaxbox, not of the input) exits 3 with one line that says where
the traceback went, and leaves no partial output; exit 1 stays "no valid model"."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_hostile import csv

import jaxbox.validate
from jaxbox.cli._main import INTERNAL_ERROR, main


def _broken_validate(*args, **kwargs):
    raise RuntimeError("a fault planted by the test\nsecond line")


@pytest.fixture
def broken(tmp_path, monkeypatch):
    """A tiny building in ``tmp_path`` (the working folder and the temporary folder), and a
    validation that fails as a bug would."""
    import tempfile

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(jaxbox.validate, "validate", _broken_validate)
    logs = tmp_path / "tmp"
    logs.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(logs))
    monkeypatch.delenv("JAXBOX_DEBUG", raising=False)
    return csv(tmp_path / "data.csv"), logs


def _argv(data: Path) -> list[str]:
    return ["fit", str(data), "--model", "Zon", "--starts", "1", "--max-steps", "3"]


def test_internal_error_exits_3_with_the_log_named(broken, tmp_path, capsys):
    data, logs = broken
    code = main([*_argv(data), "--plots", "plots"])
    out = capsys.readouterr()
    assert code == INTERNAL_ERROR == 3
    lines = out.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: internal error (RuntimeError: ")
    assert "Traceback" not in out.err and "second line" not in out.err
    written = list(logs.glob("jaxbox-error-*.log"))
    assert len(written) == 1 and str(written[0]) in lines[0]
    trace = written[0].read_text()
    assert "Traceback" in trace and "_broken_validate" in trace and "second line" in trace
    assert out.out == ""
    assert not (tmp_path / "plots").exists()  # no partial output, no folder made


def test_internal_error_traceback_on_stderr_with_jaxbox_debug(broken, capsys, monkeypatch):
    data, logs = broken
    monkeypatch.setenv("JAXBOX_DEBUG", "1")
    code = main(_argv(data))
    out = capsys.readouterr()
    assert code == 3
    lines = out.err.strip().splitlines()
    assert lines[0].startswith("Traceback") and "_broken_validate" in out.err
    assert lines[-1].startswith("error: internal error (RuntimeError: ")
    assert "traceback is above" in lines[-1]
    assert sum(line.startswith("error: ") for line in lines) == 1
    assert list(logs.iterdir()) == []
