"""Saving and loading a GreyBox: plain JSON + NPZ, identical numbers, atomic writes."""

import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from jaxbox.data import Dataset
from jaxbox.models import get_model
from jaxbox.select import GreyBox, PersistError, load_greybox, save_greybox
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


@pytest.mark.parametrize("zone", ["+02:00", "Europe/Berlin", "UTC"])
def test_data_in_a_time_zone_come_back_in_it(greybox, zone, tmp_path):
    """Time stamps with a zone or an offset (local time across a clock change is read at one
    offset) are saved as instants and read back in the same zone: the cases' periods match."""
    import pandas as pd

    frame = greybox.data.frame
    frame.index = frame.index.tz_localize("UTC").tz_convert(
        "Europe/Berlin" if zone == "Europe/Berlin" else "UTC"
    )
    if zone == "+02:00":
        frame.index = frame.index.tz_convert(pd.Timestamp("2024-01-01T00:00+02:00").tzinfo)
    gb = GreyBox(Dataset(frame), name="zoned")
    gb.add_case("Zon", starts=2)
    save_greybox(gb, tmp_path / "gb")
    back = load_greybox(tmp_path / "gb")
    assert back.data.equals(gb.data) and str(back.data.index.tz) == str(gb.data.index.tz)
    assert back.train == gb.train and list(back.cases) == ["Zon"]


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


def test_save_refuses_a_file_and_another_tools_index(greybox, tmp_path):
    """A file as the folder was FileExistsError/NotADirectoryError; another tool's
    greybox.json was overwritten, and a file of its named arrays-*.npz removed."""
    (tmp_path / "a-file").write_text("x")
    with pytest.raises(PersistError, match="is a file; give a folder"):
        save_greybox(greybox, tmp_path / "a-file")
    with pytest.raises(PersistError, match="lies under the file"):
        greybox.save(tmp_path / "a-file" / "gb")
    theirs = tmp_path / "theirs"
    theirs.mkdir()
    (theirs / "greybox.json").write_text('{"format": "othertool/3"}')
    with pytest.raises(PersistError, match="othertool/3.*another folder"):
        greybox.save(theirs)
    assert (theirs / "greybox.json").read_text() == '{"format": "othertool/3"}'
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    (mixed / "arrays-train.npz").write_text("not ours")
    greybox.save(mixed)
    greybox.save(mixed)
    assert (mixed / "arrays-train.npz").read_text() == "not ours"


def test_max_gap_stuck_hours_and_infinite_bounds_come_back(greybox, tmp_path):
    """The GreyBox's max_gap came back as the default; an infinite bound was saved as null
    and its save could not be loaded."""
    gb = GreyBox(greybox.data, max_gap="3h", stuck_hours=None)
    inf = float("inf")
    gb.identify("Zon", starts=1, max_steps=20, bounds={"T_zon0": (-inf, inf)})
    back = load_greybox(gb.save(tmp_path / "gb"))
    assert back.max_gap == 3 * 3600.0 and back.stuck_hours is None
    assert back["Zon"].bounds == {"T_zon0": (-inf, inf)}
    assert back["Zon"].result.params == gb["Zon"].result.params


def test_a_custom_model_named_like_a_library_model_loads_as_itself(greybox, tmp_path):
    """A custom model saved under a library model's name came back as the library model: a
    two-state network named 'Zon' as the one-state Zon, a Zon with other bounds with the
    library's bounds (and the fit's estimation problem with them)."""
    two_states = get_model("ZonWal").renamed("Zon", "two states under the name Zon")
    narrow = get_model("Zon").with_parameters({"R_wal": {"upper": 0.5}, "gA": {"default": 1.0}})
    unbounded = get_model("Zon").with_parameters({"gA": {"upper": float("inf")}})
    assert narrow.name == two_states.name == "Zon"
    gb = GreyBox(greybox.data, name="custom")
    gb.add_case(two_states, name="two states")
    gb.identify(narrow, name="narrow", starts=1, max_steps=20)
    gb.add_case(unbounded, name="unbounded")
    gb.add_case("Zon", name="library")
    back = load_greybox(gb.save(tmp_path / "gb"))
    for name in ("two states", "narrow", "unbounded", "library"):
        assert back[name].model == gb[name].model, name
    assert back["two states"].model.states == ("T_zon", "T_wal")
    assert back["unbounded"].model.parameter("gA").upper == float("inf")
    assert back["narrow"].result.problem.bounds == gb["narrow"].result.problem.bounds
    assert back["narrow"].result.params == gb["narrow"].result.params
    # the model given on load must be the one saved; one of the same declaration is taken
    with pytest.raises(PersistError, match=r"cases\[0\]: models\['Zon'\] is not the model"):
        load_greybox(tmp_path / "gb", models={"Zon": get_model("Zon")})
    one = GreyBox(greybox.data, name="narrow only")
    one.add_case(narrow, name="narrow")
    one.save(tmp_path / "one")
    with pytest.raises(PersistError, match=r"\(R_wal upper 10.0 \(saved: 0.5\); gA default"):
        load_greybox(tmp_path / "one", models={"Zon": get_model("Zon")})
    described = narrow.renamed("Zon", "the same model, described otherwise")
    assert load_greybox(tmp_path / "one", models={"Zon": described})["narrow"].model == described


def test_every_library_model_and_grammar_structure_is_declared_faithfully():
    """A model's declaration, through JSON, builds the same model again (a save refuses a
    model that would not): every library model, structures of the grammar, a segmented model
    (saved without its segments) and a model with a parameter share of a resistance."""
    from jaxbox.models import Grammar, RCNetwork, library_models, random_structure
    from jaxbox.models import components as c
    from jaxbox.select._persist import declared_model, model_declaration

    def again(model):
        return declared_model(json.loads(json.dumps(model_declaration(model), allow_nan=False)))

    for model in library_models():
        assert again(model) == model, model.name
    columns = ["T_zon", "T_amb", "T_bou", "Q_hea", "I_glo_hor", "I_s", "I_e", "I_w", "P_ele"]
    grammar = Grammar.from_columns(columns)
    rng = np.random.default_rng(0)
    for _ in range(40):
        model = random_structure(grammar, rng).build(grammar)
        assert again(model) == model, model.name
    zonwal = get_model("ZonWal")
    assert again(zonwal.segmented(3)) == zonwal
    shared = (
        RCNetwork("Share", "a wall capacity inside R_wal")
        .node("zon", output=True)
        .node("wal")
        .constant("gro")
        .resistance("zon", "gro", "R_gro")
        .resistance("zon", "wal", "R_wal", scale="0.5*fra_wal")
        .resistance("wal", "T_amb", "R_wal", scale="1-fra_wal")
        .heat("zon", "Q_hea")
        .heat("zon", "I_glo_hor", gain="gA*0.25")
        .parameter("fra_wal", lower=0.1, upper=0.9)
        .add(c.sensor_offset)
        .build({"C_wal": {"upper": 1e9}})
    )
    assert again(shared) == shared


def test_a_save_of_an_earlier_version_finds_its_models_by_name(saved):
    """Cases saved without their model's declaration load the library model of that name, or
    the model given in models=."""
    folder, doc = saved
    for case in doc["cases"]:
        del case["declaration"]
    _rewrite(folder, doc)
    back = load_greybox(folder)
    assert back["Zon"].model == get_model("Zon") and back["Zon"].done
    with pytest.raises(PersistError, match=r"cases\[0\]"):
        load_greybox(folder, models={"Zon": get_model("ZonWal")})


def test_load_names_a_models_entry_that_is_not_a_model(saved):
    folder, _ = saved
    with pytest.raises(TypeError, match=r"models\['Zon'\] must be an RCModel"):
        load_greybox(folder, models={"Zon": 3})  # was 'no library model named 3'


def test_load_rejects_other_files(tmp_path):
    (tmp_path / "greybox.json").write_text('{"format": "other"}')
    with pytest.raises(ValueError, match="not a saved GreyBox"):
        load_greybox(tmp_path)


# -- a saved folder is not trusted -----------------------------------------------------------------


@pytest.fixture()
def saved(greybox, tmp_path):
    """A saved GreyBox folder and its index as a dict."""
    folder = tmp_path / "gb"
    save_greybox(greybox, folder)
    return folder, json.loads((folder / "greybox.json").read_text())


def _rewrite(folder, doc):
    (folder / "greybox.json").write_text(json.dumps(doc))


@pytest.mark.parametrize(
    "arrays", ["../elsewhere/arrays-0123456789abcdef.npz", "/etc/passwd", "greybox.json", "x.npz"]
)
def test_arrays_are_read_only_from_inside_the_folder(saved, arrays, tmp_path):
    folder, doc = saved
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "arrays-0123456789abcdef.npz").write_bytes(
        next(folder.glob("arrays-*.npz")).read_bytes()
    )
    _rewrite(folder, {**doc, "arrays": arrays})
    with pytest.raises(PersistError, match="arrays"):
        load_greybox(folder)


def test_an_arrays_file_linking_outside_the_folder_is_refused(saved, tmp_path):
    folder, doc = saved
    (arrays,) = folder.glob("arrays-*.npz")
    outside = tmp_path / "outside.npz"
    arrays.rename(outside)
    arrays.symlink_to(outside)
    with pytest.raises(PersistError, match="outside the folder"):
        load_greybox(folder)


def _set(doc, path, value):
    doc = json.loads(json.dumps(doc))
    *head, last = path
    target = doc
    for key in head:
        target = target[key]
    if value is KeyError:
        del target[last]
    else:
        target[last] = value
    return doc


@pytest.mark.parametrize(
    "path, value, field",
    [
        (["name"], KeyError, "name"),
        (["name"], 3, "name"),
        (["train"], "2024-01-01", "train"),
        (["train"], ["2024-01-01"], "train"),
        (["valid"], 5, "valid"),
        (["cases"], {"a": 1}, "cases"),
        (["cases", 0], [], "cases[0]"),
        (["cases", 0, "model"], KeyError, "cases[0].model"),
        (["cases", 0, "model"], "NoSuchModel", "cases[0].model"),
        (["cases", 0, "guess"], None, "cases[0].guess"),
        (["cases", 0, "guess", "values"], [1, 2], "cases[0].guess.values"),
        (["cases", 0, "fixed"], {"gA": "two"}, "cases[0].fixed"),
        (["cases", 0, "bounds"], {"gA": [1]}, "cases[0].bounds"),
        (["cases", 0, "starts"], "3", "cases[0].starts"),
        (["cases", 0, "starts"], 0, "cases[0].starts"),
        (["cases", 0, "seed"], 1.5, "cases[0].seed"),
        (["cases", 0, "notes"], "a note", "cases[0].notes"),
        (["cases", 0, "result"], [], "cases[0].result"),
        (["cases", 0, "result", "arrays"], "case7", "cases[0].result.arrays"),
        (["cases", 0, "result", "best"], 99, "cases[0].result.best"),
        (["cases", 0, "result", "best"], True, "cases[0].result.best"),
        (["cases", 0, "result", "params"], KeyError, "cases[0].result.params"),
        (["cases", 0, "result", "params", "R_wal"], KeyError, "cases[0].result.params"),
        (["cases", 0, "result", "status"], "converged", "cases[0].result.status"),
        (["cases", 1, "name"], "Zon", "cases[1].name"),
        (["cases", 0, "train"], ["2099-01-01", "2099-02-01"], "cases[0].train"),
        (["tz"], 2, "tz"),
        (["tz"], "Mars/Olympus_Mons", "data"),
        (["stuck_hours"], "24", "stuck_hours"),
        # values of the right type that a GreyBox or a case does not take: checked on load
        # as when declared (they loaded, or failed deep inside with no file named)
        (["stuck_hours"], -1, "stuck_hours"),
        (["ranges"], {"T_zon": [50, 0]}, "T_zon"),
        (["train"], ["2099-01-01", "2099-02-01"], "train 2099-01-01"),
        (["cases", 0, "settings", "postsim"], "bogus", "cases[0].settings: postsim"),
        (["cases", 0, "settings", "max_steps"], -1, "cases[0].settings: max_steps"),
        (["cases", 0, "seed"], -5, "cases[0].seed"),
        (["cases", 0, "starts"], 10**12, "cases[0].starts"),
        (["cases", 0, "free"], ["C_zon"], "cases[0].result.free"),
        # the declaration of a case's model is checked and built again
        (["cases", 0, "declaration"], [], "cases[0].declaration"),
        (["cases", 0, "declaration", "name"], "Other", "cases[0].model is 'Zon'"),
        (["cases", 0, "declaration", "network", "nodes", 0, "name"], 3, "nodes[0].name"),
        (["cases", 0, "declaration", "network", "edges"], KeyError, "network.edges"),
        (["cases", 0, "declaration", "network", "edges", 0, "R"], "R_x", "cases[0].declaration"),
        (["cases", 0, "declaration", "parameters", 0, "lower"], "low", "parameters[0].lower"),
        (["cases", 0, "declaration", "parameters", 0, "upper"], -1, "cases[0].declaration"),
        (["cases", 0, "declaration", "network", "sources", 0, "gain"], [], "gain"),
    ],
)
def test_a_malformed_index_gives_one_error_naming_the_field(saved, path, value, field):
    folder, doc = saved
    _rewrite(folder, _set(doc, path, value))
    with pytest.raises(PersistError) as err:
        load_greybox(folder)
    assert field in str(err.value)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    "content", ["", "{not json", "[1, 2]", '"text"', "null", b"\xff\xfe\x00binary"]
)
def test_a_damaged_index_is_a_persist_error(saved, content):
    folder, _ = saved
    index = folder / "greybox.json"
    index.write_bytes(content if isinstance(content, bytes) else content.encode())
    with pytest.raises(PersistError, match="greybox.json"):
        load_greybox(folder)


def test_damaged_or_missing_arrays(saved, tmp_path):
    folder, doc = saved
    (arrays,) = folder.glob("arrays-*.npz")
    arrays.write_bytes(b"not a zip file")
    with pytest.raises(PersistError, match="arrays"):
        load_greybox(folder)
    arrays.unlink()
    with pytest.raises(PersistError, match="missing"):
        load_greybox(folder)
    with pytest.raises(PersistError, match="no saved GreyBox"):
        load_greybox(tmp_path / "nothing-here")
    # arrays of another save: the shapes do not agree with the index
    np.savez(arrays, **{"data/values": np.zeros((3, 2))})
    with pytest.raises(PersistError, match="data/time_ns"):
        load_greybox(folder)


def test_stale_temporaries_are_removed_by_the_next_save_and_load(greybox, tmp_path):
    from jaxbox._io import temporary_prefix

    folder = tmp_path / "gb"
    save_greybox(greybox, folder)
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    )
    pid = int(dead.stdout)
    mine = temporary_prefix("greybox.json")
    theirs = mine.replace(f"-{os.getpid()}.", f"-{pid}.")
    (folder / f"{theirs}abc123.tmp").write_text("half a save")  # a save that was killed
    (folder / f"{mine}def456.tmp").write_text("a save going on")  # this process: alive
    old = folder / ".arrays-x.npz.tmp"  # an old format, a day old
    old.write_text("x")
    os.utime(old, (time.time() - 2 * 86400,) * 2)
    load_greybox(folder)
    left = sorted(p.name for p in folder.glob(".*.tmp"))
    assert left == [f"{mine}def456.tmp"]
    (folder / f"{theirs}abc123.tmp").write_text("half a save")
    save_greybox(greybox, folder)
    assert sorted(p.name for p in folder.glob(".*.tmp")) == [f"{mine}def456.tmp"]


# -- concurrent and killed saves -------------------------------------------------------------------

_SAVER = """
import sys
import numpy as np
from jaxbox.data import Dataset
from jaxbox.select import GreyBox, save_greybox

folder, start = sys.argv[1], int(sys.argv[2])
t = np.arange(48) * 3600.0
k = start
while True:
    data = Dataset.from_arrays(
        t, {"T_zon": 20 + 0.001 * k + np.sin(t / 4e4), "T_amb": 5 + np.cos(t / 4e4),
            "Q_hea": np.full(48, 500.0), "I_glo_hor": np.zeros(48)}
    )
    gb = GreyBox(data, name=f"version {k}")
    gb.add_case("Zon", name="not-run").notes.append(f"version {k}")
    save_greybox(gb, folder)
    print(k, flush=True)
    k += 1
"""


def _version(gb) -> int:
    k = int(gb.name.split()[-1])
    assert gb["not-run"].notes == [f"version {k}"]  # index and arrays of one version
    assert gb.data["T_zon"][0] == pytest.approx(20 + 0.001 * k)
    return k


def _saver(folder, start=0):
    return subprocess.Popen(
        [sys.executable, "-c", _SAVER, str(folder), str(start)],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "JAXBOX_CACHE": "0"},
    )


@pytest.mark.slow
def test_kill_during_save_leaves_the_old_or_the_new_version(tmp_path):
    """A save killed (SIGKILL) at random moments: the folder always loads, as the last
    version completed or the one being saved; the next save removes what the killed one
    left."""
    folder = tmp_path / "gb"
    rng = np.random.default_rng(0)
    seen = []
    for round_ in range(4):
        proc = _saver(folder, start=1000 * round_)
        first = proc.stdout.readline()  # one save done: the process runs its loop
        assert first.strip() == str(1000 * round_)
        time.sleep(rng.uniform(0.0, 0.3))
        proc.kill()
        done = [first, *proc.stdout.read().split()]
        proc.wait()
        last = int(done[-1])
        k = _version(load_greybox(folder))
        assert k in (last, last + 1)
        seen.append(k)
    assert len(list(folder.glob("arrays-*.npz"))) <= 3
    proc = _saver(folder, start=9000)
    proc.stdout.readline()
    proc.stdout.readline()  # two saves: the leftovers of the killed ones are gone
    proc.kill()
    proc.wait()
    assert not [p for p in folder.glob(".*.tmp")]
    assert len(list(folder.glob("arrays-*.npz"))) <= 3
    assert _version(load_greybox(folder)) >= 9001


@pytest.mark.slow
def test_a_reader_during_saves_sees_a_whole_version(tmp_path):
    """One process saves over and over while this one loads over and over: every load gives a
    complete version (its index and its arrays), never an error."""
    folder = tmp_path / "gb"
    proc = _saver(folder)
    try:
        proc.stdout.readline()
        versions = []
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < 4.0:
            versions.append(_version(load_greybox(folder)))
    finally:
        proc.kill()
        proc.wait()
    assert len(versions) > 20
    assert versions == sorted(versions) and versions[-1] > versions[0]  # saves went on


@pytest.mark.slow
def test_two_savers_and_a_reader(tmp_path):
    """Two processes save into one folder at the same time while this one loads: the saves
    take turns, every load gives a whole version of one of them, and the folder loads after."""
    folder = tmp_path / "gb"
    savers = [_saver(folder), _saver(folder, start=10**6)]
    try:
        for proc in savers:
            proc.stdout.readline()
        seen = set()
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < 3.0:
            seen.add(_version(load_greybox(folder)) >= 10**6)
    finally:
        for proc in savers:
            proc.kill()
            proc.wait()
    assert _version(load_greybox(folder)) >= 0
    assert seen  # versions of one saver or the other, never an error
