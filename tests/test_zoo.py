"""The zoo of synthetic buildings: determinism, valid structures, plausible truth, exact
simulation, thermostat, gaps, CSV round trip and one recovery by a fit."""

import json

import numpy as np
import pandas as pd
import pytest

import jaxbox
from jaxbox.datasets import ZOO_TRUTH_CSV, ZOO_TRUTH_JSON, make_zoo
from jaxbox.datasets._zoo import DAY_HOURS, _matrices, _setback
from jaxbox.models._grammar import Grammar, parse_structure
from jaxbox.validate import kpi_values

jaxbox.enable_x64()


def _model(b):
    return parse_structure(b.structure).build(Grammar.from_columns(b.data.columns))


@pytest.fixture(scope="module")
def zoo():
    return make_zoo(40, seed=3, days=4)


@pytest.fixture(scope="module")
def clean():
    """Noise-free buildings: every heating kind, one and two zones, every step."""
    return make_zoo(
        6,
        seed=11,
        days=3,
        noise=0.0,
        offset=0.0,
        gaps=0.0,
        two_zone=0.5,
        structure=None,
        step=["5min", "10min", "60min"],
    )


def test_deterministic_and_independent_of_n(zoo):
    again = make_zoo(3, seed=3, days=4)
    for a, b in zip(zoo[:3], again, strict=True):
        assert a.name == b.name and a.structure == b.structure
        assert a.params == b.params
        assert a.data.equals(b.data)
    other = make_zoo(3, seed=4, days=4)
    assert [b.params for b in other] != [b.params for b in again]


def test_variety(zoo):
    assert {b.step for b in zoo} == {"5min", "10min", "60min"}
    assert {b.heating for b in zoo} == {"thermostat", "prbs", "rolbs"}
    assert any(b.held_zone is not None for b in zoo)
    assert sum(b.held_zone is None for b in zoo) > len(zoo) / 2  # mostly one zone
    assert len({b.structure for b in zoo}) > 10


def test_structures_are_grammar_names_fed_by_the_columns(zoo):
    for b in zoo:
        s = parse_structure(b.structure)
        assert s.name == b.structure
        model = _model(b)
        model.check_data(b.data)
        assert model.n_states <= 4
        assert set(b.params) == set(model.param_names)
        assert b.data.columns[0].startswith("T_zon")


def test_parameters_inside_bounds_and_time_constants_plausible(zoo):
    for b in zoo:
        model = _model(b)
        for p in model.parameters:
            v = b.params[p.name]
            if p.name.startswith(("R_", "C_")):
                assert p.lower * 10 < v < p.upper / 10, (b.name, p.name, v)
            elif p.name.startswith("fra_"):
                assert 0.05 < v < 0.95, (b.name, p.name, v)
            elif p.name.startswith("gA"):
                assert 0.0 < v < p.upper / 5, (b.name, p.name, v)
            else:  # initial temperatures
                assert 10.0 < v < 30.0, (b.name, p.name, v)
        tau = np.asarray(b.kpis["time_constants"])
        assert tau.min() >= 10 / 60 and tau.max() <= 30 * 24
        assert 40.0 * 0.99 < b.kpis["hlc"] < 400.0 * 1.01 * 1.5


def test_kpis_as_kpi_values_and_matrices_as_the_model(zoo):
    for b in zoo[:4]:
        model = _model(b)
        ref = kpi_values(model, b.params)
        assert ref["hlc"] == pytest.approx(b.kpis["hlc"], rel=1e-9)
        assert ref["solar_aperture"] == pytest.approx(b.kpis["solar_aperture"], rel=1e-9)
        assert ref["time_constants"] == pytest.approx(b.kpis["time_constants"], rel=1e-9)
        A, B, C = _matrices(model, b.params)
        A0, B0, C0, _ = model.state_space(b.params)
        np.testing.assert_allclose(A, np.asarray(A0), rtol=1e-12, atol=0)
        np.testing.assert_allclose(B, np.asarray(B0), rtol=1e-12, atol=0)


def test_truth_reproduces_the_noise_free_data(clean):
    kinds = set()
    for b in clean:
        model = _model(b)
        sim = jaxbox.simulate_model(model, b.params, b.clean)
        y = b.clean.array(list(model.outputs))
        np.testing.assert_allclose(sim.y, y, rtol=0, atol=1e-8)
        assert b.data.equals(b.clean)  # no noise, offset or gap
        kinds.add((b.heating, b.held_zone is not None))
    assert len(kinds) >= 3


def test_thermostat_holds_the_setpoints():
    zoo = make_zoo(
        3, seed=5, days=6, heating="thermostat", zones=(1,), gaps=0.0, offset=0.0, noise=0.05
    )
    for b in zoo:
        f = b.data.frame
        sp = _setback(f.index)
        q = f["Q_hea"].to_numpy()
        step = pd.Timedelta(b.step)
        hours = (f.index - f.index.normalize()) / pd.Timedelta(hours=1)
        settled = np.asarray(f.index >= f.index[0] + pd.Timedelta(hours=3))  # from T_zon0
        for h in DAY_HOURS:  # two hours to settle after each setpoint change
            settled &= ~((hours >= h) & (hours < h + 2 + step / pd.Timedelta(hours=1)))
        active = (q > 1.0) & (q < 0.98 * q.max())
        active[1:] &= active[:-1]
        ok = settled & active
        assert ok.sum() > 20, b.name
        err = f["T_zon"].to_numpy()[ok] - sp[ok]
        assert np.abs(err).max() < 0.5 + 5 * b.noise, (b.name, b.step, np.abs(err).max())
        assert abs(np.median(err)) < 0.2


def test_held_zone_nearly_constant():
    zoo = make_zoo(4, seed=2, days=4, zones=(2,), gaps=0.0, offset=0.0, noise=0.02)
    for b in zoo:
        z = b.held_zone
        col = f"T_zon{z}"
        q = b.data[f"Q_hea{z}"]
        on = q > 1.0
        assert on.mean() > 0.5
        t = b.data[col][on]
        assert np.abs(np.median(t) - b.setpoint) < 0.3, b.name


@pytest.mark.filterwarnings("ignore:the data have gaps")
@pytest.mark.filterwarnings("ignore:identification data")
def test_gaps_where_the_truth_says_and_csv_round_trip(tmp_path):
    zoo = make_zoo(5, tmp_path, seed=7, days=5, gaps=1.0, offset=1.0)
    truth = json.loads((tmp_path / ZOO_TRUTH_JSON).read_text())
    table = pd.read_csv(tmp_path / ZOO_TRUTH_CSV, index_col="building")
    assert list(table.index) == [b.name for b in zoo] == [t["name"] for t in truth]
    for b, t in zip(zoo, truth, strict=True):
        assert t["structure"] == b.structure and t["params"] == pytest.approx(b.params)
        assert b.offset != 0.0 and b.gaps and b.outages
        f = b.data.frame
        zones = [c for c in f.columns if c.startswith("T_zon") and c in _model(b).outputs]
        missing = f[zones].isna().all(axis=1)
        assert (f[zones].isna().any(axis=1) == missing).all()
        expect = pd.Series(False, index=f.index)
        for first, last in b.gaps:
            expect[first:last] = True
        assert (missing == expect).all()
        expect[:] = False
        for first, last in b.outages:
            expect[first:last] = True
        assert (f.isna().all(axis=1) == expect).all()
        # the clean data only differ by noise and offset where measured
        diff = f[zones] - b.clean.frame[zones]
        assert np.nanmean(diff.to_numpy()) == pytest.approx(b.offset, abs=4 * b.noise / 10)
        path = tmp_path / f"{b.name}.csv"
        head = pd.read_csv(path, nrows=2)
        assert head.columns[0] == "time"
        assert len(pd.read_csv(path)) == len(f) - int(expect.sum())  # outage rows left out
        loaded = jaxbox.load(path)
        assert loaded.equals(b.data)
    # a building with an outage and output gaps fits (segments, masked outputs)
    b = zoo[0]
    fit = jaxbox.fit_model(b.structure, jaxbox.load(tmp_path / f"{b.name}.csv"), starts=2)
    assert all(np.isfinite(v) for v in fit.params.values())


def test_recovers_the_hlc_of_a_noisy_building():
    (b,) = make_zoo(
        1,
        seed=1,
        structure="Zon+Wal",
        step="60min",
        heating="prbs",
        noise=0.05,
        offset=0.0,
        gaps=0.0,
        days=14,
    )
    fit = jaxbox.fit_model(b.structure, b.data, starts=8)
    got = kpi_values(_model(b), fit.params)
    assert got["hlc"] == pytest.approx(b.kpis["hlc"], rel=0.03)


def test_errors(tmp_path):
    from jaxbox.datasets import make_fleet

    with pytest.raises(ValueError, match="n \\(buildings\\) must be an integer ≥ 1"):
        make_zoo(0)
    for kwargs, error, words in [
        ({"n": 2.5}, TypeError, "n \\(buildings\\) must be an integer"),
        ({"n": 2, "seed": -1}, ValueError, "seed must be an integer ≥ 0"),
        ({"n": 2, "seed": "x"}, TypeError, "seed must be an integer ≥ 0"),
        ({"n": 2, "days": float("nan")}, ValueError, "days must be finite"),
        ({"n": 2, "noise": -0.1}, ValueError, "noise is a standard deviation"),
    ]:
        with pytest.raises(error, match=words):
            make_fleet(**kwargs)
        if "noise" not in kwargs:
            with pytest.raises(error, match=words):
                make_zoo(**kwargs)
    (tmp_path / "taken").write_text("a file")
    with pytest.raises(ValueError, match="is a file; give a folder"):
        make_fleet(2, tmp_path / "taken", days=2)
    with pytest.raises(ValueError, match="steps"):
        make_zoo(1, step="15min")
    with pytest.raises(ValueError, match="heating"):
        make_zoo(1, heating="radiator")
