"""Export of a fitted model: the discrete state space against scipy's discretisation and
simulation, the noise covariance against its integral, round trips (JSON, NPZ, python-control
script), the Modelica model parsed and simulated against jaxbox, and ``jaxbox export``."""

import json
import re

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
import scipy.signal

import jaxbox
from jaxbox.control import modelica_model, read_state_space, to_state_space
from jaxbox.forecast import StochasticForm
from jaxbox.stochastic import estimate_states, simulate_sde

STEP = 3600.0
TRUE = {
    "C_zon": 3.0e6,
    "C_wal": 2.5e7,
    "R_wal": 0.01,
    "fra_wal": 0.3,
    "gA": 1.5,
    "T_zon0": 21.0,
    "T_wal0": 16.0,
    "sigma_zon": 3e-4,
    "sigma_wal": 5e-5,
    "sigma_y_zon": 0.04,
}
MODEL = "BM_TiTe"  # an edge with a parametric share (fra_wal) and its complement


def _form(hold: str = "foh") -> StochasticForm:
    model = jaxbox.get_model(MODEL)
    return StochasticForm(model, dict(TRUE), hold, (1.0, 1.0), "ml", "given", STEP)


@pytest.fixture(scope="module")
def data():
    n = 4 * 24 + 1
    rng = np.random.default_rng(5)
    t = np.arange(n) * STEP
    u = {
        "T_amb": 4.0 + 3.0 * np.sin(2 * np.pi * t / 86400.0),
        "I_glo_hor": np.clip(300.0 * np.sin(2 * np.pi * t / 86400.0 - 1.5), 0, None),
        "Q_hea": rng.choice([0.0, 1200.0], n),
    }
    base = jaxbox.data.Dataset.from_arrays(t, {**u, "T_zon": np.zeros(n)})
    y, _ = simulate_sde(MODEL, TRUE, base, seed=2, x0_std=0.0)
    return base.with_columns(T_zon=y[:, 0])


def _inputs(n: int, m: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.normal(0, 1, (n, m)), axis=0) * np.asarray([1.0, 300.0, 50.0])[:m]


def test_standard_form_is_exact_for_inputs_linear_between_samples(data):
    """At a step of 15 min (not the fit's), the standard form (state ξ = x − Γ1 u) reproduces
    scipy's continuous simulation with linearly interpolated inputs."""
    ssm = to_state_space(_form(), "15min", data=data)
    assert ssm.step == 900.0 and ssm.hold == "foh"
    assert ssm.inputs == ("T_amb", "Q_hea", "I_glo_hor") and ssm.units["Q_hea"] == "W"
    assert ssm.units["I_glo_hor"] == "W/m²" and ssm.units["T_zon"] == "°C"
    u = _inputs(60, 3)
    x0 = np.asarray([20.0, 15.0])
    y, x = ssm.simulate(u, x0)
    model = jaxbox.get_model(MODEL)
    A, B, C, D = model.state_space_numpy(TRUE)
    t = np.arange(60) * 900.0
    _, yref, xref = scipy.signal.lsim((A, B, C, D), u, t, X0=x0, interp=True)
    np.testing.assert_allclose(y[:, 0], yref, atol=1e-8)
    np.testing.assert_allclose(x, xref, atol=1e-8)
    np.testing.assert_allclose(ssm.A_c, A, rtol=1e-14)


def test_zero_order_hold_matches_scipy_cont2discrete():
    ssm = to_state_space(_form("zoh"), 600.0)
    model = jaxbox.get_model(MODEL)
    A, B, C, D = model.state_space_numpy(TRUE)
    Ad, Bd, _, _, _ = scipy.signal.cont2discrete((A, B, C, D), 600.0, method="zoh")
    np.testing.assert_allclose(ssm.A, Ad, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(ssm.B, Bd, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(ssm.D, D, atol=0)
    assert ssm.x is None and ssm.xi is None


def test_noise_covariances_are_the_integrals_at_the_step():
    ssm = to_state_space(_form(), 1800.0)
    A = ssm.A_c
    S = np.diag(np.asarray([TRUE["sigma_zon"], TRUE["sigma_wal"]]) ** 2)
    Q, _ = scipy.integrate.quad_vec(
        lambda s: scipy.linalg.expm(A * s) @ S @ scipy.linalg.expm(A * s).T, 0.0, 1800.0
    )
    np.testing.assert_allclose(ssm.Q, Q, rtol=1e-7)
    np.testing.assert_allclose(ssm.R, [[TRUE["sigma_y_zon"] ** 2]], rtol=1e-14)


def test_last_state_estimate_is_the_kalman_filters(data):
    ssm = to_state_space(_form(), data=data)
    est = estimate_states(MODEL, TRUE, data, x0_std=1.0)
    np.testing.assert_allclose(ssm.x, est.filtered[-1], rtol=1e-10)
    np.testing.assert_allclose(ssm.P, est.filtered_cov[-1], rtol=1e-8)
    assert ssm.time == str(data.index[-1])


@pytest.mark.parametrize("suffix", [".json", ".npz"])
def test_round_trip(data, tmp_path, suffix):
    ssm = to_state_space(_form(), "15min", data=data)
    back = read_state_space(ssm.save(tmp_path / f"m{suffix}"))
    for k in ("A", "B", "C", "D", "Phi", "Gamma0", "Gamma1", "A_c", "B_c", "Q", "R", "x", "P"):
        np.testing.assert_array_equal(getattr(back, k), getattr(ssm, k))
    assert (back.states, back.inputs, back.outputs) == (ssm.states, ssm.inputs, ssm.outputs)
    assert back.units == ssm.units and back.params == ssm.params and back.time == ssm.time
    assert (back.step, back.hold, back.noise) == (ssm.step, ssm.hold, ssm.noise)


def test_python_control_script_round_trip(data, tmp_path):
    ssm = to_state_space(_form(), "15min", data=data)
    path = ssm.save(tmp_path / "m.py")
    ns: dict = {}
    exec(compile(path.read_text(), str(path), "exec"), ns)
    for k in ("A", "B", "C", "D", "x", "P", "Q", "R"):
        np.testing.assert_array_equal(ns[k], getattr(ssm, k))
    assert ns["dt"] == 900.0 and ns["inputs"] == list(ssm.inputs)
    control = pytest.importorskip("control")
    sys = ns["state_space"]()
    assert isinstance(sys, control.StateSpace) and sys.dt == 900.0
    u = _inputs(40, 3, seed=1)
    x0 = np.asarray([19.0, 14.0])
    y, _ = ssm.simulate(u, x0)
    xi0 = x0 - ssm.Gamma1 @ u[0]
    resp = control.forced_response(sys, T=np.arange(40) * 900.0, U=u.T, X0=xi0)
    np.testing.assert_allclose(np.ravel(resp.outputs), y[:, 0], atol=1e-9)


# ---- Modelica -----------------------------------------------------------------------------------


def _parse_modelica(text: str):
    """Parameters, inputs, outputs, states and right-hand sides of the generated model."""
    params = {
        m[1]: (m[2], float(m[3]))
        for m in re.finditer(r'parameter Real (\w+)\(unit="([^"]*)"\) = ([-+.eE\d]+)', text)
    }
    inputs = re.findall(r'RealInput (\w+)\(unit="([^"]*)"\)', text)
    outputs = re.findall(r"RealOutput (\w+)\(", text)
    starts = dict(re.findall(r"Real (T_\w+)\(start=(\w+), fixed=true", text))
    eqs = dict((m[2], (m[1], m[3])) for m in re.finditer(r"(\w+)\*der\((\w+)\) = (.+);", text))
    return params, inputs, outputs, starts, eqs


def test_modelica_model_parses_and_simulates_like_jaxbox(data):
    model = jaxbox.get_model(MODEL)
    text = modelica_model(model, TRUE)
    assert text.startswith("model BM_TiTe") and text.rstrip().endswith("end BM_TiTe;")
    params, inputs, outputs, starts, eqs = _parse_modelica(text)
    assert params["C_zon"] == ("J/K", TRUE["C_zon"]) and params["R_wal"][0] == "K/W"
    assert params["gA"][0] == "m2" and params["fra_wal"][0] == "1"
    assert params["T_zon0"] == ("degC", TRUE["T_zon0"])
    assert dict(inputs) == {"T_amb": "degC", "Q_hea": "W", "I_glo_hor": "W/m2"}
    assert outputs == ["y_T_zon"] and starts == {"T_zon": "T_zon0", "T_wal": "T_wal0"}
    assert set(eqs) == {"T_zon", "T_wal"}
    values = {k: v for k, (_, v) in params.items()}
    states = list(model.states)

    def rhs(x, u):
        env = {**values, **dict(zip(states, x, strict=True))}
        env.update(dict(zip(model.inputs, u, strict=True)))
        return np.asarray([eval(eqs[s][1], {}, env) / values[eqs[s][0]] for s in states])

    A, B, _, _ = model.state_space_numpy(TRUE)
    rng = np.random.default_rng(3)
    for _ in range(5):
        x, u = rng.normal(18, 5, 2), rng.normal(0, 1, 3) * [5, 1000, 200]
        np.testing.assert_allclose(rhs(x, u), A @ x + B @ u, rtol=1e-12, atol=1e-18)
    # the parsed equations integrated by scipy against jaxbox's simulation of the model
    uarr = data.array(list(model.inputs))
    t = np.arange(len(data)) * STEP

    def f(tt, x):
        return rhs(x, np.asarray([np.interp(tt, t, uarr[:, j]) for j in range(3)]))

    x0 = [values[starts[s]] for s in states]
    sol = scipy.integrate.solve_ivp(
        f, (0, t[-1]), x0, t_eval=t, method="LSODA", rtol=1e-10, atol=1e-10, max_step=STEP
    )
    sim = jaxbox.simulate_model(model, {k: TRUE[k] for k in model.param_names}, data)
    np.testing.assert_allclose(sol.y[0], sim.y[:, 0], atol=1e-5)


# ---- jaxbox export ------------------------------------------------------------------------------


def _cli(args, capsys):
    from jaxbox.cli._main import main

    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def fit_file(data, tmp_path_factory):
    folder = tmp_path_factory.mktemp("export")
    csv = folder / "building.csv"
    data.frame.to_csv(csv, index_label="time")
    doc = {"model": MODEL, "params": TRUE, "hold": "foh", "x0_std": [1.0, 1.0]}
    doc["data"] = {"source": str(csv), "step_s": STEP, "train": [str(data.start), str(data.end)]}
    path = folder / "fit.json"
    path.write_text(json.dumps(doc))
    return folder, path


def test_cli_export_json_and_modelica(fit_file, data, capsys):
    folder, path = fit_file
    code, out, err = _cli(["export", path, "--step", "15min", "--out", folder / "m.json"], capsys)
    assert code == 0, err
    assert "state estimate at" in out
    back = read_state_space(folder / "m.json")
    ref = to_state_space(_form(), "15min", data=data)
    np.testing.assert_allclose(back.A, ref.A, rtol=1e-12)
    np.testing.assert_allclose(back.x, ref.x, rtol=1e-9)
    code, _, err = _cli(["export", path, "--out", folder / "m.mo"], capsys)
    assert code == 0, err
    assert (folder / "m.mo").read_text() == modelica_model(jaxbox.get_model(MODEL), TRUE)


def test_cli_export_bad_input(fit_file, capsys):
    folder, path = fit_file
    code, _, err = _cli(["export", path, "--out", folder / "m.txt"], capsys)
    assert code == 2 and "give --format" in err and err.count("\n") == 1
    code, _, err = _cli(["export", path, "--step", "0min", "--out", folder / "m.json"], capsys)
    assert code == 2 and "--step must be a positive duration" in err
    code, _, err = _cli(["export", path, "--model", "Zon", "--out", folder / "m.json"], capsys)
    assert code == 2 and "is a fit of BM_TiTe, not of --model Zon" in err
