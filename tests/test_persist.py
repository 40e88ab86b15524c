"""Saving and loading a GreyBox: plain JSON + NPZ, identical numbers, atomic writes."""

import json
import os

import numpy as np
import pytest

from jaxbox.data import Dataset
from jaxbox.models import get_model
from jaxbox.select import GreyBox, load_greybox, save_greybox
from jaxbox.simulate import simulate_arrays
from jaxbox.validate import validate

TRUTH = {"C_zon": 4.0e6, "R_wal": 0.01, "gA": 2.0, "T_zon0": 24.0}


@pytest.fixture(scope="module")
def greybox():
    model = get_model("Zon")
    n = 120
    t = np.arange(n) * 3600.0
    rng = np.random.default_rng(2)
    day = 2 * np.pi * t / 86400
    u = {
        "T_amb": 10 + 5 * np.sin(day - 2),
        "Q_hea": 500.0 * (rng.random(n) > 0.5),
        "I_glo_hor": np.maximum(0, 400 * np.sin(day)),
    }
    U = np.stack([u[k] for k in model.inputs], axis=1)
    y, _ = simulate_arrays(model, TRUTH, t, U)
    data = Dataset.from_arrays(t, {**u, "T_zon": np.asarray(y[:, 0]) + 0.05 * rng.normal(size=n)})
    gb = GreyBox(data, name="test house")
    gb.identify("Zon", starts=3, seed=4)
    gb.identify("Zon", name="Zon-manual", guess={"R_wal": 0.02}, starts=2, bounds={"gA": (0, 10)})
    gb.add_case("Zon", name="not-run")
    return gb


def test_save_load_revalidate_identical(greybox, tmp_path):
    index = save_greybox(greybox, tmp_path / "gb")
    assert index.name == "greybox.json"
    doc = json.loads(index.read_text())  # plain JSON
    assert [c["name"] for c in doc["cases"]] == ["Zon", "Zon-manual", "not-run"]
    npz = list((tmp_path / "gb").glob("arrays-*.npz"))
    assert len(npz) == 1
    with np.load(npz[0], allow_pickle=False) as z:  # no pickle inside
        assert "data/values" in z.files

    back = load_greybox(tmp_path / "gb")
    assert back.name == greybox.name and list(back.cases) == list(greybox.cases)
    assert back.data.equals(greybox.data)
    assert back.train == greybox.train and back.valid_period == greybox.valid_period
    for name in ("Zon", "Zon-manual"):
        a, b = greybox[name], back[name]
        assert b.result.params == a.result.params
        assert b.result.cost == a.result.cost
        np.testing.assert_array_equal(b.result.starts.initial, a.result.starts.initial)
        np.testing.assert_array_equal(b.result.starts.params, a.result.starts.params)
        assert b.result.starts.status == a.result.starts.status
        assert b.result.problem.bounds == a.result.problem.bounds
        assert b.guess == a.guess and b.bounds == a.bounds
        va, vb = validate(a.result, a.valid), validate(b.result, b.valid)
        assert vb.se_auto == va.se_auto and vb.se_cross == va.se_cross
        assert vb.rmse_cross == va.rmse_cross
        np.testing.assert_array_equal(vb.sim_cross, va.sim_cross)
        assert b.is_valid == a.is_valid and b.reasons == a.reasons
    assert not back["not-run"].done
    assert back.table().equals(greybox.table())


def test_interrupted_save_leaves_the_previous_file_intact(greybox, tmp_path, monkeypatch):
    folder = tmp_path / "gb"
    save_greybox(greybox, folder)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    real = os.replace
    calls = []

    def crash(src, dst):
        calls.append(dst)
        if str(dst).endswith("greybox.json"):  # dies while publishing the new index
            raise KeyboardInterrupt
        return real(src, dst)

    greybox["Zon"].notes.append("changed after the first save")
    try:
        monkeypatch.setattr(os, "replace", crash)
        with pytest.raises(KeyboardInterrupt):
            save_greybox(greybox, folder)
    finally:
        monkeypatch.setattr(os, "replace", real)
        greybox["Zon"].notes.pop()
    assert calls  # the crash did happen mid-save
    assert not list(folder.glob(".*.tmp"))  # no temporary file left behind
    assert (folder / "greybox.json").read_bytes() == before["greybox.json"]
    back = load_greybox(folder)  # the previous save still loads
    assert back["Zon"].result.params == greybox["Zon"].result.params
    assert "changed after the first save" not in back["Zon"].notes


def test_interrupted_write_of_the_arrays(greybox, tmp_path, monkeypatch):
    folder = tmp_path / "gb"
    save_greybox(greybox, folder)
    index = (folder / "greybox.json").read_bytes()

    def crash(fd):
        raise OSError("disk full")

    greybox["Zon"].notes.append("changed")
    try:
        monkeypatch.setattr(os, "fsync", crash)
        with pytest.raises(OSError, match="disk full"):
            save_greybox(greybox, folder)
    finally:
        monkeypatch.undo()
        greybox["Zon"].notes.pop()
    assert (folder / "greybox.json").read_bytes() == index
    assert len(list(folder.glob("arrays-*.npz"))) == 1
    assert load_greybox(folder / "greybox.json")["Zon"].done


def test_load_rejects_other_files(tmp_path):
    (tmp_path / "greybox.json").write_text('{"format": "other"}')
    with pytest.raises(ValueError, match="not a saved GreyBox"):
        load_greybox(tmp_path)
