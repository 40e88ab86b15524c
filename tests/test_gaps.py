"""Gaps in monitoring data: masked outputs, interpolated inputs, segments, window edges."""

from __future__ import annotations

import json
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd
import pytest

import jaxbox
from jaxbox.cli._main import main
from jaxbox.data import DataError, Dataset, DataWarning, concat_periods, prepare_window
from jaxbox.fit import FitError, fit_sensitivity, make_problem, problem_arrays
from jaxbox.validate import analyse_residuals, autocorrelation, ljung_box, uncertainty, validate

STEP = 3600.0
TRUTH = {"C_zon": 3e6, "R_wal": 0.01, "gA": 3.0}
INIT = ({"T_zon0": 20.0}, {"T_zon0": 22.0})
MODEL = "Zon"


def inputs(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * STEP
    return {
        "T_amb": 5 + 5 * np.sin(2 * np.pi * t / 86400) + rng.normal(0, 0.3, n),
        "Q_hea": np.where(rng.random(n) < 0.5, 2000.0, 0.0),
        "I_glo_hor": np.clip(400 * np.sin(2 * np.pi * (t / 86400 - 0.25)), 0, None),
    }


def simulated(u: dict, init: dict, start: str, model: str = MODEL) -> Dataset:
    """The model's response from ``init`` to inputs ``u``, as a dataset (no noise)."""
    n = len(next(iter(u.values())))
    data = Dataset.from_arrays(np.arange(n) * STEP, {**u, "T_zon": np.zeros(n)}, start=start)
    m = jaxbox.get_model(model)
    theta = {k: v for k, v in {**TRUTH, **init}.items() if k in m.param_names}
    return data.with_columns(T_zon=jaxbox.simulate_model(m, theta, data).y[:, 0])


@pytest.fixture(scope="module")
def two_segments():
    """Eight days with a 10-hour hole in every input after day 4: the second segment starts
    from other temperatures. A short input gap, an output gap and 0.05 K noise."""
    n, cut, back = 192, 90, 100
    u = inputs(n)
    first = simulated({k: v[:cut] for k, v in u.items()}, INIT[0], "2024-01-01")
    second = simulated(
        {k: v[back:] for k, v in u.items()},
        INIT[1],
        str(pd.Timestamp("2024-01-01") + back * pd.Timedelta("1h")),
    )
    frame = pd.concat([first.frame, second.frame]).reindex(
        pd.date_range("2024-01-01", periods=n, freq="h", name="time")
    )
    rng = np.random.default_rng(1)
    frame["T_zon"] += rng.normal(0, 0.05, n)
    frame.iloc[40, frame.columns.get_loc("T_amb")] = np.nan  # one hour: interpolated
    frame.iloc[60:63, frame.columns.get_loc("T_zon")] = np.nan  # an output gap: masked
    return Dataset(frame)


@pytest.fixture(scope="module")
def segment_fit(two_segments):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        return jaxbox.fit_model(MODEL, two_segments, starts=4)


# -- data ------------------------------------------------------------------------------------------


def test_short_input_gap_is_interpolated_with_a_warning_naming_it(two_segments):
    with pytest.warns(DataWarning) as got:
        out = prepare_window(two_segments, ("T_amb", "Q_hea", "I_glo_hor"), ("T_zon",))
    texts = [str(w.message) for w in got]
    assert any(
        "interpolated input 'T_amb' at 2024-01-02 16:00:00 (1 sample, 1 h)" in t for t in texts
    )
    raw = two_segments["T_amb"]
    i = int(np.flatnonzero(out.index == pd.Timestamp("2024-01-02 16:00"))[0])
    assert out["T_amb"][i] == pytest.approx(0.5 * (raw[39] + raw[41]), rel=1e-12)
    assert np.isnan(out["T_zon"]).sum() == 3  # the output gap stays: it is masked


def test_many_interpolated_gaps_of_one_input_are_one_note(two_segments):
    """Dozens of one-sample holes in one column give one summary, not a warning each."""
    frame = two_segments.frame.copy()
    holes = [20, 30, 45, 50, 70, 120, 130, 140]
    frame.iloc[holes, frame.columns.get_loc("I_glo_hor")] = np.nan
    frame.iloc[[150, 151], frame.columns.get_loc("I_glo_hor")] = np.nan
    with pytest.warns(DataWarning) as got:
        out = prepare_window(
            Dataset(frame), ("T_amb", "Q_hea", "I_glo_hor"), ("T_zon",), max_gap="2h"
        )
    texts = [str(w.message) for w in got]
    about = [t for t in texts if "'I_glo_hor'" in t and "interpolated" in t]
    assert len(about) == 1, texts
    assert "in 9 gaps of 1 h to 2 h (10 samples in all)" in about[0]
    assert "the first at 2024-01-01 20:00:00, the last at 2024-01-07 06:00:00" in about[0]
    # the other input's single gap keeps its own note, the long gap still cuts, the holes fill
    assert any("interpolated input 'T_amb' at 2024-01-02 16:00:00" in t for t in texts)
    assert any("splits into segments" in t for t in texts)
    assert np.isfinite(out["I_glo_hor"]).all() and len(out.segments) == 2


def test_long_gap_splits_into_segments(two_segments):
    with pytest.warns(
        DataWarning,
        match=r"inputs 'T_amb', 'Q_hea', 'I_glo_hor' missing from .*"
        r"\(10 samples, 10 h\), longer than max_gap \(1 h\).*segments",
    ):
        out = prepare_window(two_segments, ("T_amb", "Q_hea", "I_glo_hor"), ("T_zon",))
    assert out.segments == ((0, 90), (90, 182))
    assert out.index[90] - out.index[89] == pd.Timedelta("11h")
    with pytest.warns(DataWarning, match="interpolated input 'T_amb', 'Q_hea'|interpolated inputs"):
        longer = prepare_window(
            two_segments, ("T_amb", "Q_hea", "I_glo_hor"), ("T_zon",), max_gap="10h"
        )
    assert len(longer.segments) == 1 and len(longer) == 192
    model = jaxbox.get_model("ZonWal").segmented(len(out.segments))
    assert model.param_names[-2:] == ("T_zon0_s2", "T_wal0_s2")
    assert model.parameter("T_wal0_s2").is_initial_state
    assert model.segmented(1).param_names == jaxbox.get_model("ZonWal").param_names


def test_a_requests_problem_is_the_batchs_and_may_be_set_up_quietly(two_segments, segment_fit):
    """``request_problem`` sets up a fit request's problem as the batch does (segments and
    all: what a search's background thread compiles the interval program for), with the
    data's warnings per gap or (``warn=False``, a second look at the same data) without."""
    from jaxbox.fit._batch import request_problem

    request = {"model": MODEL, "data": two_segments}
    with pytest.warns(DataWarning) as caught:
        problem, data = request_problem(request)
    said = " ".join(str(w.message) for w in caught)
    assert "interpolated input 'T_amb'" in said and "segments" in said
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any warning fails
        quiet, same = request_problem(request, warn=False)
    assert quiet.simulation_key == problem.simulation_key and quiet.guess == problem.guess
    assert quiet.bounds == problem.bounds
    assert same.segments == data.segments == ((0, 90), (90, 182))
    assert problem.model.param_names == segment_fit.problem.model.param_names
    assert problem.free == segment_fit.problem.free


def test_inputs_missing_in_a_whole_window_are_refused(two_segments):
    frame = two_segments.frame
    frame["Q_hea"] = np.nan
    # a column without any value is named, with what to do
    with pytest.raises(FitError, match=r"input 'Q_hea' has no value in identification data.*"):
        jaxbox.fit_model(MODEL, Dataset(frame), starts=1)
    # each input has values, never all of them together
    apart = two_segments.frame
    half = len(apart) // 2
    apart.iloc[:half, apart.columns.get_loc("Q_hea")] = np.nan
    apart.iloc[half:, apart.columns.get_loc("T_amb")] = np.nan
    with pytest.raises(DataError, match="no sample with every input"):
        prepare_window(Dataset(apart), ["T_amb", "Q_hea"], ["T_zon"])
    arrays_data = Dataset(two_segments.frame.iloc[:30])
    problem = make_problem(jaxbox.get_model(MODEL), arrays_data.slice(end="2024-01-01 20:00"))
    with pytest.raises(FitError, match="input 'T_amb' is missing.*prepare_window"):
        problem_arrays(problem, Dataset(frame.assign(Q_hea=1.0, T_amb=np.nan)))


# -- the masked, segmented cost -------------------------------------------------------------------


def _reference_cost(model, theta, data):
    """Σ over the measured samples of (ŷ − y)² / N_measured, each segment simulated on its own
    with the plain model from its own initial states (numpy, no masking weights)."""
    base = model.segmented(1)
    errors = []
    for k, (a, b) in enumerate(data.segments, start=1):
        part = Dataset._new(data.frame.iloc[a:b], data.step)
        names = model.segment_names(k)
        th = {n: theta[n] for n in base.param_names if not n.startswith("T_")}
        th.update({m.T0: theta[n] for m, n in zip(base.network.nodes, names, strict=True)})
        ysim = jaxbox.simulate_model(base, th, part).y[:, 0]
        errors.append(ysim - part["T_zon"])
    e = np.concatenate(errors)
    e = e[np.isfinite(e)]
    return float(np.mean(e * e))


@pytest.fixture(scope="module")
def derivatives(segment_fit):
    """At a point off the optimum: the fused pass (cost, Jᵀr, JᵀJ), the residual route's
    residuals and Jacobian, and a jitted cost for finite differences."""
    problem, data = segment_fit.problem, segment_fit.data
    t, u, y, w = problem_arrays(problem, data)
    tr = problem.transform
    theta = {**TRUTH, "T_zon0": 19.0, "T_zon0_s2": 23.0, "gA": 2.0}
    z = jnp.asarray(tr.to_internal(np.asarray([theta[n] for n in problem.free])))
    members = (
        jnp.zeros((1, 0)),
        jnp.asarray(tr.lower)[None],
        jnp.asarray(tr.upper)[None],
        jnp.asarray(tr.scale)[None],
        jnp.asarray([STEP]),
    )
    arrays = tuple(jnp.asarray(a)[:, None] for a in (t, u, y, np.broadcast_to(w, y.shape)))
    fused = jax.jit(lambda zz: problem.normal_equations(zz[None], members, arrays, chunk=50))
    args = (jnp.zeros(0), t, u, y, w, tr.lower, tr.upper, tr.scale)
    residuals = jax.jit(lambda zz: problem.residuals(zz, args))
    cost = jax.jit(lambda zz: jnp.sum(problem.residuals(zz, args) ** 2))
    jac = jax.jit(jax.jacfwd(lambda zz: problem.residuals(zz, args)))
    return theta, z, fused(z), residuals(z), cost, jac(z), w


def test_masked_segmented_cost_equals_the_cost_without_those_samples(segment_fit, derivatives):
    data = segment_fit.data
    assert segment_fit.model.segments == 2 and data.segments == ((0, 90), (90, 182))
    theta, _, (cost, _, _), r, _, _, w = derivatives
    assert w.shape == (182, 1) and (w == 0).sum() == 3
    reference = _reference_cost(segment_fit.model, theta, data)
    assert float(cost[0]) == pytest.approx(reference, rel=1e-10)
    # the residual route (simulate_arrays: one scan with restarts) agrees
    assert float(r @ r) == pytest.approx(reference, rel=1e-10)


def test_gradient_of_the_segmented_cost(segment_fit, derivatives):
    """Jᵀr and JᵀJ of the fused pass against central differences and jacfwd of the residuals."""
    _, z, (_, g, H), _, cost, J, _ = derivatives
    h = 1e-6
    fd = np.asarray([(cost(z + h * e) - cost(z - h * e)) / (2 * h) for e in np.eye(len(z))])
    np.testing.assert_allclose(2 * np.asarray(g[0]), fd, rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(np.asarray(H[0]), np.asarray(J.T @ J), rtol=1e-8, atol=1e-14)
    # the second segment's initial state acts on the second segment only
    col = segment_fit.problem.free.index("T_zon0_s2")
    assert np.all(np.asarray(J)[:90, col] == 0) and np.all(np.asarray(J)[93:, col] != 0)


def test_segment_fit_recovers_the_truth(segment_fit):
    p = segment_fit.params
    for name, value in TRUTH.items():
        assert p[name] == pytest.approx(value, rel=0.03), name
    for k, init in enumerate(INIT, start=1):
        for name, value in init.items():
            key = name if k == 1 else f"{name}_s{k}"
            assert p[key] == pytest.approx(value, abs=0.05), key


def test_validation_and_intervals_of_a_segment_fit(segment_fit, two_segments):
    v = validate(segment_fit, method="exact")  # diffrax: see the command-line tests
    e = v.residuals_auto[:, 0]
    assert np.isnan(e).sum() == 3
    assert v.rmse_auto["T_zon"] == pytest.approx(np.sqrt(np.nanmean(e**2)), rel=1e-12)
    assert v.rmse_auto["T_zon"] < 0.08  # noise 0.05 K
    u = uncertainty(segment_fit, include_initial_states=True)
    assert u.n_obs == 182 - 3 and u.names[-1] == "T_zon0_s2"
    truth = {**TRUTH, **INIT[0], "T_zon0_s2": INIT[1]["T_zon0"]}
    covered = [lo <= truth[n] <= hi for n, (lo, hi) in zip(u.names, u.ci95, strict=True)]
    assert sum(covered) >= 3
    ra = v.residual_analysis("auto", max_lag=10)
    assert ra["T_zon"].stats["n"] == 179
    # a missing measurement moves no estimate
    sens = fit_sensitivity(segment_fit)["C_zon"]
    assert np.all(sens[60:63] == 0) and np.all(sens[:60] != 0)


# -- residual tests on masked series --------------------------------------------------------------


def test_masked_autocorrelation_is_parzens_estimator():
    rng = np.random.default_rng(5)
    e = rng.normal(size=300)
    lags, full = autocorrelation(e, 10)
    gappy = e.copy()
    gappy[rng.random(300) < 0.15] = np.nan
    _, r = autocorrelation(gappy, 10)
    # an explicit loop over the measured pairs
    seen = np.isfinite(gappy)
    d = np.where(seen, gappy - np.nanmean(gappy), np.nan)
    m = seen.sum()
    var = np.nansum(d**2) / m
    for k in range(1, 11):
        pairs = [(d[i], d[i + k]) for i in range(300 - k) if seen[i] and seen[i + k]]
        expected = np.mean([a * b for a, b in pairs]) / var * (m - k) / m
        assert r[k] == pytest.approx(expected, rel=1e-12)
    assert np.max(np.abs(r[1:] - full[1:])) < 0.1  # white either way
    assert ljung_box(gappy).white and ljung_box(e).white
    ar = np.zeros(300)
    for i in range(1, 300):
        ar[i] = 0.8 * ar[i - 1] + rng.normal()
    ar[rng.random(300) < 0.15] = np.nan
    assert not ljung_box(ar).white
    assert analyse_residuals(ar).outputs[0].stats["n"] == int(np.isfinite(ar).sum())


# -- windows, periods, command line ----------------------------------------------------------------


def test_shared_window_edge_belongs_to_the_first_window(two_segments):
    ident, valid = two_segments.windows(
        ("2024-01-01", "2024-01-04 00:00"), ("2024-01-04 00:00", "2024-01-06")
    )
    assert ident.end == pd.Timestamp("2024-01-04 00:00")
    assert valid.start == pd.Timestamp("2024-01-04 01:00")
    with pytest.raises(DataError, match="must start after"):
        two_segments.windows(("2024-01-01", "2024-01-04"), ("2024-01-03", "2024-01-06"))
    whole, none = two_segments.windows(None, False)
    assert none is None and len(whole) == len(two_segments)


def test_separate_periods_are_fitted_together():
    u = inputs(60, seed=7)
    a = simulated({k: v[:30] for k, v in u.items()}, INIT[0], "2024-03-01", model=MODEL)
    b = simulated({k: v[30:] for k, v in u.items()}, INIT[1], "2024-04-01", model=MODEL)
    joined = concat_periods([a, b])
    assert joined.segments == ((0, 30), (30, 60))
    result = jaxbox.fit_model(MODEL, [a, b], starts=2)
    assert result.model.param_names[-1] == "T_zon0_s2"
    assert result.params["T_zon0_s2"] == pytest.approx(22.0, abs=1e-3)
    assert result.params["C_zon"] == pytest.approx(TRUTH["C_zon"], rel=1e-3)
    with pytest.raises(DataError, match="not after period 0"):
        concat_periods([b, a])


@pytest.fixture(scope="module")
def gap_csv(tmp_path_factory):
    """Ten days of hourly data with 64 hours missing at the end, noise and an output gap."""
    n = 240
    data = simulated(inputs(n, seed=11), INIT[0], "2024-01-01")
    frame = data.frame.reset_index()
    frame["T_zon"] += np.random.default_rng(2).normal(0, 0.05, n)
    frame.loc[20:22, "T_zon"] = np.nan
    frame = frame.drop(index=range(170, 234))
    path = tmp_path_factory.mktemp("gaps") / "gap.csv"
    frame.to_csv(path, index=False)
    return path


@pytest.mark.slow
def test_command_line_on_data_with_gaps(gap_csv, capsys):
    with pytest.warns(DataWarning, match="gaps"):
        loaded = jaxbox.load(gap_csv)
    assert len(loaded) == 240 and np.isnan(loaded["T_zon"][170:234]).all()
    common = ["fit", str(gap_csv), "--model", MODEL, "--starts", "2", "--json"]
    # the 64-hour gap lies outside both windows; they share the edge 2024-01-04 00:00
    edge = ["--train", "2024-01-01..2024-01-04", "--validate", "2024-01-04..2024-01-06 23:00"]
    assert main([*common, *edge]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["data"]["validate"][0] == "2024-01-04 01:00:00"
    assert doc["rmse_auto"]["T_zon"] < 0.1 and doc["rmse_cross"]["T_zon"] < 0.1
    # the whole file: two segments around the 64-hour gap
    assert main([*common, "--validate", "none"]) == 0
    out = capsys.readouterr()
    doc = json.loads(out.out)
    assert "inputs 'T_amb', 'Q_hea', 'I_glo_hor' missing from 2024-01-08 02:00:00" in out.err
    assert doc["rmse_cross"] is None and doc["data"]["validate"] is None
    assert "T_zon0_s2" in doc["params"] and doc["params"]["R_wal"]["ci95"] is not None
    assert doc["data"]["segments"] == [
        ["2024-01-01 00:00:00", "2024-01-08 01:00:00"],
        ["2024-01-10 18:00:00", "2024-01-10 23:00:00"],
    ]
    assert doc["residuals"]["auto"]["T_zon"]["ljung_box"]["lags"] >= 1
    assert doc["residuals"]["cross"] is None
    assert main([*common, "--max-gap", "2 fortnights"]) == 2
    assert capsys.readouterr().err.startswith("error: cannot read --max-gap")


@pytest.mark.slow
def test_select_without_a_valid_model_exits_1(gap_csv, capsys, monkeypatch):
    from jaxbox.select import _cases

    argv = ["select", str(gap_csv), "--models", MODEL, "--starts", "2", "--validate", "none"]
    assert main([*argv, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["accepted"] == MODEL and doc["fit"]["rmse_cross"] is None
    monkeypatch.setattr(_cases.Case, "is_valid", property(lambda self: False))
    assert main(argv) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("no valid model") and sum(e.startswith("no valid") for e in err) == 1
    assert "span only" not in err[-1]  # a week of data: nothing to say about its length
    assert main([*argv, "--train", "2024-01-01..2024-01-02 12:00"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert "the identification data span only 37 h" in err[-1] and "a week or more" in err[-1]


def test_greybox_cases_on_gappy_data(two_segments, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        gb = jaxbox.GreyBox(two_segments, valid=False, max_gap="2h")
        case = gb.identify(MODEL, starts=2)
    assert case.model.segments == 2 and case.result.model.param_names[-1] == "T_zon0_s2"
    assert case.validation.rmse_cross is None and np.isfinite(case.se_auto)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        gb.save(tmp_path / "gb")
        back = jaxbox.select.load_greybox(tmp_path / "gb")
    assert back[MODEL].result.params == case.result.params
    assert back[MODEL].se_auto == pytest.approx(case.se_auto, rel=1e-9)


#: an envelope building for the tests of validation across outages
ENVELOPE = {"C_zon": 2e6, "C_wal": 8e7, "R_wal": 0.005, "gA": 3.0, "T_zon0": 20.0, "T_wal0": 14.0}


def envelope_building(u: dict) -> tuple:
    """The ``ZonWal`` building :data:`ENVELOPE` driven by ``u``, with 0.02 K sensor noise:
    ``(full dataset, its simulation, the noisy data as a frame)``."""
    n = len(next(iter(u.values())))
    full = Dataset.from_arrays(np.arange(n) * STEP, {**u, "T_zon": np.zeros(n)}, start="2024-01-01")
    sim = jaxbox.simulate_model(jaxbox.get_model("ZonWal"), ENVELOPE, full)
    noise = np.random.default_rng(4).normal(0, 0.02, n)
    return full, sim, full.with_columns(T_zon=sim.y[:, 0] + noise).frame


def test_validation_carries_the_state_across_two_outages_in_turn():
    """Two six-hour outages in the validation window: the state after the second is carried from
    the run that follows the first (itself carried): one exact step across the gap, the inputs
    interpolated linearly, from the reported state before it."""
    from jaxbox.simulate._exact import discretize_foh_numpy

    n, gaps = 260, ((170, 176), (210, 216))
    u = inputs(n, seed=3)
    full, sim, frame = envelope_building(u)
    frame = frame.drop(frame.index[np.r_[tuple(slice(a, b) for a, b in gaps)]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        ident, valid = Dataset(frame).windows(("2024-01-01", "2024-01-07 03:00"), None)
        result = jaxbox.fit_model("ZonWal", ident, starts=4, seed=0)
        v = validate(result, valid, method="exact")
    A, B, _, _ = result.model.state_space_numpy(result.params)
    names = list(result.model.inputs)
    for a, b in gaps:
        after = int(np.flatnonzero(v.index_cross == full.index[b])[0])
        Phi, G0, G1 = discretize_foh_numpy(A, B, (b - a + 1) * STEP)
        u0 = np.array([u[k][a - 1] for k in names])
        u1 = np.array([u[k][b] for k in names])
        carried = Phi @ v.x_cross[after - 1] + G0 @ u0 + G1 @ (u1 - u0)
        np.testing.assert_allclose(v.x_cross[after, 1], carried[1], rtol=0, atol=1e-8)


def test_validation_estimates_the_state_after_a_long_outage():
    """A two-day outage of every signal inside the validation window, the envelope driven far
    from where the interpolated inputs would leave it (no sun and the heating on full during the
    outage): the slow wall state at the first sample after it is estimated from the segment's
    outputs, close to the true one, so the validation error stays at the noise level; carried
    across the gap instead, it would be off by kelvins."""
    from jaxbox.validate import CARRY_GAP

    n, cut, back = 288, 170, 218  # 48 h missing
    assert (back - cut) * STEP > CARRY_GAP
    u = inputs(n, seed=3)
    u["Q_hea"][cut:back] = 6000.0
    u["I_glo_hor"][cut:back] = 0.0
    full, sim, frame = envelope_building(u)
    frame = frame.drop(frame.index[cut:back])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        data = Dataset(frame)
        ident, valid = data.windows(("2024-01-01", "2024-01-07 03:00"), None)
        result = jaxbox.fit_model("ZonWal", ident, starts=4, seed=0)
        v = validate(result, valid, method="exact")
    after = len(v.index_cross) - (n - back)  # the first validation sample after the outage
    assert v.index_cross[after] == frame.index[cut]  # (the row after the dropped ones)
    true_wall = sim.x[back, 1]
    assert abs(v.x_cross[after, 1] - true_wall) < 0.1
    # the carried state (interpolated inputs: half the heating, some sun) is far off
    carried_from = v.x_cross[after - 1]
    A, B, _, _ = result.model.state_space_numpy(result.params)
    from jaxbox.simulate._exact import discretize_foh_numpy

    names = list(result.model.inputs)
    u0 = np.array([u[k][cut - 1] for k in names])
    u1 = np.array([u[k][back] for k in names])
    Phi, G0, G1 = discretize_foh_numpy(A, B, (back - cut + 1) * STEP)
    carried = Phi @ carried_from + G0 @ u0 + G1 @ (u1 - u0)
    assert abs(carried[1] - true_wall) > 1.0
    assert v.rmse_cross["T_zon"] < 0.04


def test_validation_carries_the_state_across_an_outage():
    """A six-hour outage of every signal inside the validation window: the slow envelope state
    is carried across it (one exact step with the inputs interpolated linearly), so the
    validation error stays at the noise level; the carried state equals a simulation through
    the gap with those interpolated inputs."""
    n, cut, back = 240, 170, 176
    u = inputs(n, seed=3)
    full, sim, frame = envelope_building(u)
    model = jaxbox.get_model("ZonWal")
    frame = frame.drop(frame.index[cut:back])  # every signal missing for six hours
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        data = Dataset(frame)
        ident, valid = data.windows(None, None)
        result = jaxbox.fit_model("ZonWal", ident, starts=4, seed=0)
        v = validate(result, valid, method="exact")
    assert v.se_cross < 0.05  # the state guess would leave the slow wall state off by kelvins
    # reference: the fitted model through the gap with the edge inputs interpolated linearly
    u_ref = {k: a.copy() for k, a in u.items()}
    for k in u_ref:
        u_ref[k][cut:back] = np.interp(
            np.arange(cut, back), [cut - 1, back], [u[k][cut - 1], u[k][back]]
        )
    ref = Dataset.from_arrays(np.arange(n) * STEP, {**u_ref, "T_zon": np.zeros(n)})
    x_ref = jaxbox.simulate_model(model, result.params, ref).x
    after = len(v.index_cross) - (n - back)  # the first validation sample after the outage
    np.testing.assert_allclose(v.x_cross[after, 1], x_ref[back, 1], rtol=0, atol=1e-8)


def test_data_with_an_output_gap_batch_with_data_without_one():
    """An output gap makes the weights a mask ([N, p] instead of [p]); the buildings still
    share one batch, and each result is the one fitted alone."""
    from jaxbox.fit import fit_batch, fit_model

    truth = simulated(inputs(96, seed=3), INIT[0], "2020-01-01")
    noise = 0.05 * np.random.default_rng(5).standard_normal(96)
    clean = truth.with_columns(T_zon=truth["T_zon"] + noise)
    frame = clean.frame
    frame.iloc[40:43, frame.columns.get_loc("T_zon")] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)  # the gap, which it is about
        gappy = jaxbox.load(frame)
    requests = [dict(model=MODEL, data=d, starts=3, seed=2) for d in (clean, gappy)]
    together = fit_batch(requests)
    assert [r.timing["batch"] for r in together] == [2, 2]
    for r, d in zip(together, (clean, gappy), strict=True):
        alone = fit_model(MODEL, d, starts=3, seed=2)
        assert r.cost == pytest.approx(alone.cost, rel=1e-6)
        for k, v in alone.params.items():
            assert r.params[k] == pytest.approx(v, rel=1e-5), k


def test_a_window_cut_into_dozens_of_segments_is_refused_with_the_max_gap_that_joins_them():
    """A sensor that loses a sample or three every few hours: each gap beyond max_gap would
    start a segment with initial states of its own (dozens of short experiments). More than
    MAX_CUTS such gaps are refused, naming the max_gap that interpolates all but a few; with
    it the window is one piece or a few."""
    from jaxbox.data._gaps import MAX_CUTS

    n = 400
    u = inputs(n)
    data = simulated(u, INIT[0], "2024-01-01")
    frame = data.frame.copy()
    rng = np.random.default_rng(3)
    starts = np.sort(rng.choice(np.arange(5, n - 10, 9), MAX_CUTS + 6, replace=False))
    for k, a in enumerate(starts):
        frame.iloc[a : a + 2 + k % 2, frame.columns.get_loc("T_amb")] = np.nan  # 2 or 3 h
    holed = Dataset.from_arrays(np.arange(n) * STEP, dict(frame.items()), start="2024-01-01")
    cols = (["T_amb", "Q_hea", "I_glo_hor"], ["T_zon"])
    with pytest.raises(DataError, match=r"would split into \d+ segments.*max_gap='3h'") as err:
        prepare_window(holed, *cols, what="identification data", warn=False)
    assert f"at {len(starts)} input gaps longer than max_gap (1 h; 2 h to 3 h)" in str(err.value)
    joined = prepare_window(holed, *cols, max_gap="3h", warn=False)
    assert len(joined.segments) == 1 and len(joined) == n
