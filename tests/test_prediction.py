"""k-step-ahead prediction performance against brute-force re-simulation from every origin."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxbox.data import Dataset
from jaxbox.fit import FitResult, StartReport, make_problem
from jaxbox.models import get_model
from jaxbox.simulate import simulate_arrays, simulate_model
from jaxbox.validate import prediction_performance, validate

N = 200
STEP = 3600.0
TRUTH = {"C_zon": 3e6, "C_wal": 4e7, "R_wal": 0.01, "gA": 2.0, "T_zon0": 20.0, "T_wal0": 14.0}


def _inputs(n, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * STEP
    day = 2 * np.pi * t / 86400.0
    return t, {
        "T_amb": 8.0 + 5.0 * np.sin(day - 2.0) + rng.normal(0, 0.5, n),
        "Q_hea": 1500.0 * (rng.random(n) > 0.5),
        "I_glo_hor": np.maximum(0.0, 600.0 * np.sin(day - 1.5)),
    }


def _data(model, theta, n, sigma, seed=1):
    t, u = _inputs(n)
    clean = Dataset.from_arrays(t, {**u, "T_zon": np.zeros(n)})
    y = simulate_model(model, theta, clean).y[:, 0]
    return clean.with_columns(T_zon=y + np.random.default_rng(seed).normal(0, sigma, n))


def _result_at(model, data, theta):
    """A FitResult holding ``theta`` as its optimum (no optimisation needed for these checks)."""
    model = get_model(model)
    problem = make_problem(model, data, guess=theta)
    p = np.asarray([theta[n] for n in problem.free])
    e = simulate_model(model, theta, data).y - data.array(list(model.outputs))
    cost = float(np.sum(np.asarray(problem.weights) * np.mean(e * e, axis=0)))
    report = StartReport(
        initial=p[None],
        params=p[None],
        cost=np.asarray([cost]),
        steps=np.asarray([0]),
        status=("converged",),
    )
    return FitResult.from_best(
        problem=problem, data=data, report=report, best=0, timing={}, settings={}
    )


def test_noise_free_data_at_the_truth_predict_exactly():
    data = _data("ZonWal", TRUTH, N, sigma=0.0)
    res = _result_at("ZonWal", data, TRUTH)
    pf = prediction_performance(res)
    assert pf.measured_states == ("T_zon",)
    assert list(pf.horizons) == [1, 2, 3, 6, 12, 24]
    assert np.max(pf.rmse_auto) < 1e-9 and pf.sim_se_auto < 1e-9


def test_k_step_rmse_against_brute_force():
    """Re-initialise [measured T_zon, simulated T_wal] at every origin and simulate k steps."""
    model = get_model("ZonWal")
    data = _data(model, TRUTH, N, sigma=0.2)
    theta = {**TRUTH, "C_wal": 2e7, "R_wal": 0.012}  # a model that does not match the data
    res = _result_at(model, data, theta)
    ks = (1, 2, 5, 13)
    pf = prediction_performance(res, horizons=ks)
    t = np.asarray(data.t)
    u = data.array(list(model.inputs))
    y = data.array(["T_zon"])[:, 0]
    xs = simulate_model(model, theta, data).x
    xhat = xs.copy()
    xhat[:, 0] = y
    th = {k: jnp.asarray(v) for k, v in theta.items()}
    # one simulation of K + 1 samples from every origin (inputs padded past the end)
    K = max(ks)
    upad = np.concatenate([u, np.repeat(u[-1:], K, axis=0)])
    windows = np.stack([upad[i : i + K + 1] for i in range(N)])

    def one(x0, uu):
        return simulate_arrays(model, th, t[: K + 1], uu, x0=x0)[0][:, 0]

    pred = np.asarray(jax.vmap(one)(jnp.asarray(xhat), jnp.asarray(windows)))
    for j, k in enumerate(ks):
        origins = np.arange(N - k)
        expected = np.sqrt(np.mean((pred[origins, k] - y[origins + k]) ** 2))
        assert pf.rmse_auto[j, 0] == pytest.approx(expected, rel=1e-9)
    # the simulation error is the open-loop RMSE
    assert pf.sim_rmse_auto[0] == pytest.approx(np.sqrt(np.mean((xs[:, 0] - y) ** 2)), rel=1e-9)
    # re-initialisation helps one step ahead; the simulation is the stricter criterion
    assert pf.rmse_auto[0, 0] < pf.sim_rmse_auto[0]


def test_cross_validation_period_runs_on_from_the_identification_state():
    model = get_model("ZonWal")
    full = _data(model, TRUTH, 2 * N, sigma=0.1)
    ident, valid = full.split()
    theta = {**TRUTH, "C_zon": 4e6}
    res = _result_at(model, ident, theta)
    pf = prediction_performance(res, valid, horizons=[1, 24])
    v = validate(res, valid, method="exact")
    assert pf.sim_rmse_cross[0] == pytest.approx(v.rmse_cross["T_zon"], rel=1e-9)
    assert pf.sim_rmse_auto[0] == pytest.approx(v.rmse_auto["T_zon"], rel=1e-9)
    assert pf.rmse_cross.shape == (2, 1) and pf.se_cross.shape == (2,)
    assert pf.rmse_cross[0, 0] < pf.rmse_cross[1, 0]
    # the default post-simulation (adaptive diffrax) agrees with the exact route
    vd = validate(res, valid)
    assert vd.rmse_cross["T_zon"] == pytest.approx(v.rmse_cross["T_zon"], rel=1e-5)
    np.testing.assert_allclose(vd.sim_cross, v.sim_cross, rtol=0, atol=1e-5)
    with pytest.raises(ValueError, match="unknown post-simulation method 'euler'"):
        validate(res, valid, method="euler")
    d = pf.to_dict()
    json.dumps(d, allow_nan=False)
    assert set(d["cross"]["rmse"]["T_zon"]) == {1, 24}


def test_horizons_are_checked():
    data = _data("ZonWal", TRUTH, N, sigma=0.1)
    res = _result_at("ZonWal", data, TRUTH)
    with pytest.raises(ValueError, match="horizons"):
        prediction_performance(res, horizons=[0, 3])
    with pytest.raises(ValueError, match="horizons"):
        prediction_performance(res, horizons=[N])


def test_horizons_must_be_whole_samples():
    """A horizon of 1.5 samples was silently cut to 1; a string or a single number raised
    int()'s or iteration's message (a single number is now one horizon)."""
    data = _data("ZonWal", TRUTH, N, sigma=0.1)
    res = _result_at("ZonWal", data, TRUTH)
    with pytest.raises(TypeError, match="horizons"):
        prediction_performance(res, horizons=[1.5])
    with pytest.raises(TypeError, match="horizons"):
        prediction_performance(res, horizons="6")
    assert list(prediction_performance(res, horizons=6).horizons) == [6]
