"""GreyBox, Case, initial-guess strategies and forward selection on a short synthetic case."""

import numpy as np
import pytest
from _reference import synthetic_building

from jaxbox.models import get_model
from jaxbox.select import (
    GreyBox,
    candidate_models,
    forward_selection,
    lhs_starts,
    manual_guess,
    naming_guess,
    parent_guess,
    state_ranges,
)

TRUTH = {
    "C_zon": 3.0e6,
    "C_wal": 4.0e7,
    "R_wal": 0.012,
    "gA": 2.5,
    "T_zon0": 26.0,
    "T_wal0": 19.0,
}


def synthetic(n=240, seed=0, noise=0.02):
    """ZonWal data (hourly): a two-state truth, so Zon under-fits and ZonWal is right."""
    return synthetic_building(get_model("ZonWal"), TRUTH, n=n, seed=seed, noise=noise)


@pytest.fixture(scope="module")
def data():
    return synthetic()


@pytest.fixture(scope="module")
def selection(data):
    gb = GreyBox(data, name="synthetic")
    lines = []
    sel = forward_selection(gb, ["ZonWal", "Zon"], starts=4, seed=1, progress=lines.append)
    return sel, lines


# -- initial guesses --------------------------------------------------------------------------


def test_naming_guess_starts_states_from_the_data(data):
    g = naming_guess(get_model("ZonWal"), data)
    assert g.source == "naming"
    assert g.values["T_zon0"] == pytest.approx(data["T_zon"][0])
    # the unmeasured wall state starts between the zone and ambient temperatures it links
    lo, hi = sorted([data["T_zon"][0], data["T_amb"][0]])
    assert lo <= g.values["T_wal0"] <= hi
    assert g.values["C_wal"] == get_model("ZonWal").parameter("C_wal").default


def test_state_ranges_span_the_linked_temperatures(data):
    r = state_ranges(get_model("ZonWal"), data)
    lo, g, hi = r["T_wal0"]
    assert lo < min(data["T_zon"][0], data["T_amb"][0])
    assert hi > max(data["T_zon"][0], data["T_amb"][0])
    assert lo < g < hi
    lo, g, hi = r["T_zon0"]
    assert g == pytest.approx(data["T_zon"][0]) and hi - lo == pytest.approx(2.0)


def test_parent_guess_inherits_same_named_parameters(data):
    parent = {"C_zon": 5e6, "R_wal": 0.02, "gA": 3.0, "T_zon0": 25.0}
    g = parent_guess(get_model("ZonWal"), data, parent, "Zon")
    assert g.source == "parent" and g.parent == "Zon"
    assert set(g.inherited) == set(parent)
    assert g.values["C_zon"] == 5e6 and g.values["R_wal"] == 0.02
    assert g.values["C_wal"] == get_model("ZonWal").parameter("C_wal").default


def test_lhs_starts_sample_states_around_the_data(data):
    model = get_model("ZonWal")
    guess = naming_guess(model, data).values
    names, x0 = lhs_starts(model, data, guess, 16, seed=5)
    assert x0.shape == (16, len(names))
    np.testing.assert_allclose(x0[0], [guess[n] for n in names])
    ranges = state_ranges(model, data)
    for n in ("T_zon0", "T_wal0"):
        lo, _, hi = ranges[n]
        col = x0[:, names.index(n)]
        assert np.all((col >= lo) & (col <= hi)), n
    # reproducible for a seed, different for another
    np.testing.assert_array_equal(x0, lhs_starts(model, data, guess, 16, seed=5)[1])
    assert not np.array_equal(x0, lhs_starts(model, data, guess, 16, seed=6)[1])


def test_manual_guess_and_unknown_names(data):
    gb = GreyBox(data)
    case = gb.add_case("Zon", guess={"R_wal": 0.02})
    assert case.guess.source == "manual" and case.guess.values["R_wal"] == 0.02
    with pytest.raises(ValueError, match="no parameter"):
        gb.add_case("Zon", guess={"R_nope": 1.0})
    with pytest.raises(ValueError, match="parent"):
        gb.add_case("Zon", guess="parent")
    assert gb.add_case("Zon").name == "Zon#2"


def test_an_explicit_name_in_use_is_refused_not_renamed(data):
    """A name given twice was silently changed to 'A#2': the user's name is theirs; made-up
    names (the model's, a retry's) still get #2, #3…"""
    gb = GreyBox(data, name="house")
    first = gb.add_case("Zon", name="A")
    with pytest.raises(ValueError, match=r"'house' already has a case named 'A'.*another name"):
        gb.add_case("ZonWal", name="A")
    assert list(gb.cases) == ["A"] and gb["A"] is first and first.model.name == "Zon"
    assert [gb.add_case("Zon").name, gb.add_case("Zon").name] == ["Zon", "Zon#2"]
    with pytest.raises(ValueError, match="remove_case"):
        gb.add_case("Zon", name="Zon")  # the model's name, given: refused as well
    # removed, the name is free again
    assert gb.remove_case("A") is first
    assert gb.add_case("ZonWal", name="A").model.name == "ZonWal"
    with pytest.raises(KeyError, match="no case 'nope'"):
        gb.remove_case("nope")
    gb["Zon#2"].parent = "A"  # as if it had started from A's optimum
    with pytest.raises(ValueError, match="parent of 'Zon#2'"):
        gb.remove_case("A")
    # a retry made up by a selection: suffixed, not refused
    from jaxbox.select._forward import _retry_of

    retries = [_retry_of(gb, gb["Zon"], "narrowed").name for _ in range(2)]
    assert retries == ["Zon+narrowed", "Zon+narrowed#2"]


@pytest.mark.parametrize(
    "kw, error, words",
    [
        ({"name": 5}, TypeError, "name must be"),
        ({"name": " "}, ValueError, "name must not be empty"),
        ({"starts": 0}, ValueError, "starts must be a whole number"),
        ({"starts": 2.5}, TypeError, "starts must be a whole number"),
        ({"starts": 10**9}, ValueError, "starts must be a whole number from 1 to"),
        ({"seed": -1}, ValueError, "seed must be"),
        ({"seed": "a"}, TypeError, "seed must be"),
        ({"fixed": {"C_foo": 1.0}}, ValueError, "no parameter.*C_foo"),
        ({"fixed": {"C_zon": "big"}}, ValueError, "fixed value of C_zon must be a number"),
        ({"fixed": {"gA": float("nan")}}, ValueError, "fixed value of gA is nan"),
        ({"bounds": {"C_zon": 5.0}}, ValueError, "bounds of C_zon must be a pair"),
        ({"bounds": {"C_zon": (5e6, 1e6)}}, ValueError, "bounds of C_zon: lower"),
        ({"bounds": {"C_zon": (1, 2, 3)}}, ValueError, "bounds of C_zon must be a pair"),
        ({"free": ["C_foo"]}, ValueError, "no parameter.*C_foo"),
        ({"free": []}, ValueError, "nothing to estimate"),
        ({"guess": {"C_zon": "big"}}, ValueError, "guess of C_zon must be a number"),
        ({"guess": {"C_zon": float("nan")}}, ValueError, "guess of C_zon is nan"),
        ({"guess": {"C_zon": -1.0}}, ValueError, "guess of C_zon.*outside its bounds"),
        ({"max_steps": -1}, ValueError, "max_steps must be"),
        ({"rtol": "a"}, TypeError, "rtol must be a number"),
        ({"postsim": "nope"}, ValueError, "postsim must be one of"),
        ({"simulator": "euler"}, ValueError, "simulator must be one of"),
        ({"weights": "x"}, ValueError, "weights must"),
        ({"guess": "parent", "parent": "nope"}, ValueError, "parent 'nope' is not a case"),
        ({"guess": "parent", "parent": 3}, TypeError, "parent must be the name"),
    ],
)
def test_add_case_refuses_hostile_arguments_when_declared(data, kw, error, words):
    """Refused when declared, naming the argument, and nothing is added (they were accepted and
    failed when run, or inside a selection as a failed case)."""
    gb = GreyBox(data)
    with pytest.raises(error, match=words):
        gb.add_case("Zon", **kw)
    assert len(gb) == 0


def test_add_case_parent_only_with_the_parent_guess(selection):
    gb = selection[0].greybox
    n = len(gb)
    with pytest.raises(ValueError, match="guess='parent'"):
        gb.add_case("ZonWal", parent="Zon")  # was silently a naming guess
    assert len(gb) == n


def test_manual_guess_refuses_text_and_nan(data):
    with pytest.raises(TypeError, match="value of R_wal must be a number"):
        manual_guess(get_model("Zon"), data, {"R_wal": "0.01"})
    with pytest.raises(ValueError, match="value of R_wal must be finite"):
        manual_guess(get_model("Zon"), data, {"R_wal": float("inf")})


@pytest.mark.parametrize(
    "candidates, kw, error, words",
    [
        (None, {}, TypeError, "candidates must be a list"),
        (3, {}, TypeError, "candidates must be a list"),
        (["Zon", "Zon"], {}, ValueError, "Zon more than once"),
        (["Zon"], {"margin": "0.1"}, ValueError, "margin must be a fraction"),
        (["Zon"], {"patience": True}, ValueError, "patience must be"),
        (["Zon"], {"inherit": "no"}, TypeError, "inherit must be True or False"),
        (["Zon"], {"progress": "x"}, TypeError, "progress must be a function"),
        (["Zon"], {"starts": 10**9}, ValueError, "starts must be a whole number"),
        (["Zon"], {"postsim": "nope"}, ValueError, "postsim must be one of"),
        (["Zon"], {"rtol": "a"}, TypeError, "rtol must be a number"),
    ],
)
def test_forward_selection_refuses_bad_options_before_any_case(data, candidates, kw, error, words):
    """Refused before any case is declared (a bad setting made every case fail, a huge number
    of starts ran out of memory inside numpy, duplicates were identified twice)."""
    gb = GreyBox(data)
    with pytest.raises(error, match=words):
        forward_selection(gb, candidates, **kw)
    assert len(gb) == 0


def test_candidate_models_sorted_and_filtered(data):
    names = [m.name for m in candidate_models(["ZonWal", "Zon"])]
    assert names == ["Zon", "ZonWal"]
    fed = [m.name for m in candidate_models("all", data)]
    assert "Zon" in fed and "ZonWal" in fed
    assert "ZonWalIntInfWin" not in fed  # the data have no I_e, I_w
    assert [m.name for m in candidate_models("exp1")][0] == "Zon"


# -- forward selection ------------------------------------------------------------------------


def test_forward_selection_accepts_the_true_structure(selection):
    sel, lines = selection
    gb = sel.greybox
    assert sel.order[:2] == ("Zon", "ZonWal")
    assert sel.accepted == "ZonWal"
    zon, zonwal = gb["Zon"], gb["ZonWal"]
    assert zonwal.is_valid
    assert zonwal.se_cross < zon.se_cross
    assert zonwal.se_auto < zon.se_auto
    # the child inherited from its parent
    assert zonwal.guess.source == "parent" and zonwal.parent == "Zon"
    assert "C_zon" in zonwal.guess.inherited
    # parameters recovered close to the truth from slightly noisy data
    assert zonwal.result.params["R_wal"] == pytest.approx(TRUTH["R_wal"], rel=0.05)
    # progress per model and per batch of starts
    assert any("[1/2] Zon" in line for line in lines)
    assert any("4 starts in one batch" in line for line in lines)


def _failing_fits(monkeypatch, fits=()):
    """jaxbox.fit.fit_batch failing every start of the models not in ``fits`` (as a fit whose
    every start failed), fitting the others."""
    import jaxbox.fit
    from jaxbox.fit import FitError

    real = jaxbox.fit.fit_batch

    def fit_batch(requests, **kw):
        mine = [r for r in requests if r["model"].name in fits]
        done = iter(real(mine, **kw) if mine else [])
        return [
            next(done) if r["model"].name in fits else FitError("every start failed (test)")
            for r in requests
        ]

    monkeypatch.setattr(jaxbox.fit, "fit_batch", fit_batch)


def test_a_selection_whose_every_candidate_failed_says_so(data, monkeypatch):
    """It said 'every candidate was identified' when none could be."""
    _failing_fits(monkeypatch)
    lines = []
    sel = forward_selection(GreyBox(data), ["Zon", "ZonWal"], starts=2, progress=lines.append)
    assert sel.accepted is None and sel.order == ("Zon", "ZonWal")
    assert "every candidate was identified" not in sel.stopped
    assert sel.stopped.startswith("every candidate was tried and none could be identified")
    assert "all 2 fit(s) failed" in sel.stopped
    assert "accepted: none (no model could be identified)" in lines[-1]


def test_a_selection_with_some_failed_candidates_names_them(data, monkeypatch):
    _failing_fits(monkeypatch, fits=("Zon",))
    sel = forward_selection(GreyBox(data), ["Zon", "ZonWal"], starts=2, max_steps=30)
    assert sel.greybox["Zon"].done and not sel.greybox["ZonWal"].done
    assert sel.stopped == (
        "every candidate was tried; 1 of 2 case(s) could not be identified: ZonWal (their "
        "notes say why)"
    )


def test_a_stop_says_what_the_candidates_did():
    """A candidate that failed was reported as 'not valid'; a mixed streak as the last one."""
    from types import SimpleNamespace

    from jaxbox.select._forward import _Climb

    def climb(patience):
        models = [SimpleNamespace(name=n) for n in ("A", "B", "C", "D")]
        c = _Climb(
            None,
            models,
            starts=1,
            seed=0,
            margin=0.05,
            patience=patience,
            inherit=True,
            retry=False,
            settings={},
            say=lambda msg: None,
        )
        c.best, c.k = SimpleNamespace(name="A", score=1.0), 1
        return c

    def case(name, done=True, valid=False, score=2.0):
        return SimpleNamespace(name=name, done=done, is_valid=valid, score=score, valid=object())

    one = climb(1)
    one._judge(case("B", done=False))
    assert one.stopped == "stopped after B: 1 candidate(s) in a row could not be identified"
    assert one.skipped == ("C", "D")
    two = climb(2)
    two._judge(case("B", done=False))
    two._judge(case("C", valid=True))
    assert two.stopped == (
        "stopped after C: 2 candidate(s) in a row did not improve on A (1 could not be "
        "identified, 1 did not lower the validation SE by 5 %)"
    )


def test_lockstep_selection_on_two_buildings_matches_one_by_one(selection, data):
    """Two buildings climb together, each step's fits in one batch; each climbs as it would
    alone (same cases, same optima)."""
    from jaxbox.select import forward_selection_many

    sel, _ = selection
    boxes = [GreyBox(data, name="a"), GreyBox(synthetic(seed=4), name="b")]
    lines = []
    sels = forward_selection_many(boxes, ["ZonWal", "Zon"], starts=4, seed=1, progress=lines.append)
    assert [s.greybox for s in sels] == boxes
    assert sels[0].order == sel.order and sels[0].accepted == sel.accepted
    for name in sel.order:
        alone, together = sel.greybox[name], boxes[0][name]
        assert together.timing["batch"] == 2
        assert together.result.cost == pytest.approx(alone.result.cost, rel=1e-9)
        np.testing.assert_allclose(
            together.result.starts.params, alone.result.starts.params, rtol=1e-7
        )
    assert sels[1].accepted == "ZonWal"
    assert boxes[1]["ZonWal"].result.params["R_wal"] == pytest.approx(TRUTH["R_wal"], rel=0.05)
    assert any(line.startswith("b: ") for line in lines)
    with pytest.raises(ValueError, match="at least one"):
        forward_selection_many([], ["Zon"])


def test_table_and_plot(selection):
    sel, _ = selection
    t = sel.greybox.table()
    assert list(t.index[:2]) == ["Zon", "ZonWal"]
    for col in ("n_params", "se_auto", "se_cross", "valid", "reasons", "rmse_auto_T_zon"):
        assert col in t.columns
    assert t.loc["Zon", "n_params"] == 4 and t.loc["ZonWal", "n_params"] == 6
    text = sel.greybox.table_text()
    assert "ZonWal" in text and "SE cross" in text
    fig = sel.greybox.plot(accepted=sel.accepted)
    assert fig.axes[0].get_xlabel() == "number of free parameters"
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_case_starts_are_reproducible(selection):
    sel, _ = selection
    case = sel.greybox["ZonWal"]
    np.testing.assert_array_equal(case.start_values(), case.result.starts.initial)


def test_selection_without_validation_data_ranks_by_identification_error(data):
    gb = GreyBox(data, train=(None, None), valid=False)
    sel = forward_selection(gb, ["Zon"], starts=2)
    case = gb["Zon"]
    assert case.validation.se_cross is None and case.score == case.se_auto
    assert sel.accepted in (None, "Zon")


def test_select_command_json(data, tmp_path, capsys):
    import argparse
    import json

    from jaxbox.cli._select import add_select_arguments, select_command

    csv = tmp_path / "house.csv"
    data.frame.reset_index().to_csv(csv, index=False)
    parser = argparse.ArgumentParser()
    add_select_arguments(parser)
    args = parser.parse_args(
        [
            str(csv),
            "--models",
            "Zon,ZonWal",
            "--starts",
            "4",
            "--seed",
            "1",
            "--json",
            "--out",
            str(tmp_path / "o"),
        ]
    )
    assert select_command(args) == 0
    captured = capsys.readouterr()
    assert captured.err == ""  # quiet with --json
    doc = json.loads(captured.out)
    assert [row["case"] for row in doc["table"]][:2] == ["Zon", "ZonWal"]
    assert doc["accepted"] == "ZonWal"
    assert doc["fit"]["model"] == "ZonWal" and "rmse_cross" in doc["fit"]
    assert (tmp_path / "o" / "report.html").exists()
    assert (tmp_path / "o" / "greybox" / "greybox.json").exists()


@pytest.mark.slow
def test_select_command_on_two_buildings(data, tmp_path, capsys):
    import json

    from jaxbox.cli._main import main

    paths = []
    for name, d in (("a", data), ("b", synthetic(seed=4))):
        paths.append(tmp_path / f"{name}.csv")
        frame = d.frame.reset_index()
        if name == "b":
            frame.loc[len(frame) - 5, "T_zon"] = float("nan")  # a gap in validation: warned
        frame.to_csv(paths[-1], index=False)
    out = tmp_path / "o"
    args = ["select", *map(str, paths), "--models", "Zon,ZonWal", "--starts", "4", "--seed", "1"]
    assert main([*args, "--json", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    warned = [line for line in captured.err.splitlines() if line.startswith("warning: ")]
    assert warned and all(line.startswith(f"warning: {paths[1]}: ") for line in warned), warned
    doc = json.loads(captured.out)
    assert [b["dataset"] for b in doc["buildings"]] == [str(p) for p in paths]
    assert [b["accepted"] for b in doc["buildings"]] == ["ZonWal", "ZonWal"]
    assert all(row["timing"]["batch"] == 2 for b in doc["buildings"] for row in b["table"])
    for name in ("a", "b"):
        assert (out / name / "report.html").exists()
        assert (out / name / "greybox" / "greybox.json").exists()


def test_command_line_says_when_no_candidate_could_be_identified(capsys):
    """`jaxbox select`'s last lines tell a selection whose fits all failed from one whose fitted
    models were all rejected."""
    from types import SimpleNamespace

    from jaxbox.cli._select import _print_table

    def run(done):
        gb = SimpleNamespace(
            table_text=lambda: "table",
            cases={"Zon": SimpleNamespace(done=done), "ZonWal": SimpleNamespace(done=False)},
        )
        sel = SimpleNamespace(stopped="stopped", case=None)
        _print_table(gb, sel)
        return capsys.readouterr().out.strip().splitlines()[-1]

    assert run(done=False).startswith("no model: none of the candidates could be identified")
    assert run(done=True) == "no valid model: none accepted"
