"""The HTML report: one self-contained page with the table, figures and the accepted model."""

import re

import numpy as np
import pytest

from jaxbox.data import Dataset
from jaxbox.models import get_model
from jaxbox.report import greybox_report, write_report
from jaxbox.select import GreyBox
from jaxbox.simulate import simulate_arrays


@pytest.fixture(scope="module")
def greybox():
    model = get_model("Zon")
    n = 120
    t = np.arange(n) * 3600.0
    rng = np.random.default_rng(7)
    day = 2 * np.pi * t / 86400
    u = {
        "T_amb": 10 + 5 * np.sin(day - 2),
        "Q_hea": 500.0 * (rng.random(n) > 0.5),
        "I_glo_hor": np.maximum(0, 400 * np.sin(day)),
    }
    theta = {"C_zon": 4.0e6, "R_wal": 0.01, "gA": 2.0, "T_zon0": 24.0}
    y, _ = simulate_arrays(model, theta, t, np.stack([u[k] for k in model.inputs], axis=1))
    data = Dataset.from_arrays(t, {**u, "T_zon": np.asarray(y[:, 0]) + 0.05 * rng.normal(size=n)})
    gb = GreyBox(data, name="test <house>")
    gb.identify("Zon", starts=2)
    return gb


def test_report_is_self_contained(greybox, tmp_path):
    path = write_report(greybox, tmp_path / "report.html")
    text = path.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>") and text.rstrip().endswith("</html>")
    assert "test &lt;house&gt;" in text  # escaped
    assert "Model selection" in text and "Accepted model: Zon" in text
    assert "95 % interval" in text and "Verdict" in text
    images = re.findall(r'src="([^"]+)"', text)
    assert len(images) >= 5
    assert all(s.startswith("data:image/png;base64,") for s in images)  # nothing external
    assert "http://" not in text and "https://" not in text


def test_report_without_a_valid_model(tmp_path):
    t = np.arange(48) * 3600.0
    data = Dataset.from_arrays(
        t, {"T_zon": 20 + 0 * t, "T_amb": 10 + 0 * t, "Q_hea": 0 * t, "I_glo_hor": 0 * t}
    )
    text = greybox_report(GreyBox(data))
    assert "No valid model" in text


def test_hostile_report_arguments_are_refused_by_name(greybox, tmp_path):
    """None or a Dataset for the GreyBox, a string for the selection and a number for the
    title raised AttributeError or were printed; a folder as the path failed in os.replace
    naming a temporary file; a selection naming a case of another GreyBox raised KeyError."""
    from jaxbox.select import Selection

    with pytest.raises(TypeError, match="gb must be a jaxbox.select.GreyBox, got NoneType"):
        greybox_report(None)
    with pytest.raises(TypeError, match="gb must be a jaxbox.select.GreyBox, got Dataset"):
        greybox_report(greybox.data)
    with pytest.raises(TypeError, match="selection must be a Selection"):
        greybox_report(greybox, "Zon")
    with pytest.raises(TypeError, match="title must be text"):
        greybox_report(greybox, title=5)
    other = Selection(greybox, "ZonWal", ("ZonWal",), "done", (), 0.0)
    with pytest.raises(ValueError, match="accepted 'ZonWal', which is not a fitted case"):
        greybox_report(greybox, other)
    with pytest.raises(IsADirectoryError, match="is a folder; give a file name in it"):
        write_report(greybox, tmp_path)
    with pytest.raises(TypeError, match="path must be a file path"):
        write_report(greybox, None)
    assert list(tmp_path.iterdir()) == []  # nothing written, no temporary file left
