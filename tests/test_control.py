"""Linear MPC: the program on a one-state building against its hand solution, the controller's
Kalman filter against the batch filter, the closed loop on a simulated building."""

import math

import numpy as np
import pandas as pd
import pytest

import jaxbox
from jaxbox.control import (
    KalmanTracker,
    LinearMPC,
    MPCController,
    PIController,
    closed_loop,
    comfort_band,
)
from jaxbox.fit import FitError
from jaxbox.forecast import StochasticForm
from jaxbox.stochastic import simulate_sde

DT = 3600.0
ZON = {"C_zon": 5.0e6, "R_wal": 0.005, "gA": 2.0, "T_zon0": 18.0}
NOISE = {"sigma_zon": 2e-4, "sigma_y_zon": 0.05}


def _form(noise=NOISE, x0_std=1.0) -> StochasticForm:
    model = jaxbox.get_model("Zon")
    return StochasticForm(model, {**ZON, **noise}, "foh", (x0_std,), "ml", "given", DT)


def _hand(T0, Ta, L, price, qmax, comfort):
    """The two-interval program by hand: heat ``need`` kelvin at the end of the second
    interval at the cheapest price per kelvin (``p0/(a b)`` early, ``p1/b`` late, ``comfort``
    per K·h not to), up to the heater's maximum per interval."""
    tau = ZON["C_zon"] * ZON["R_wal"]
    a = math.exp(-DT / tau)
    b = ZON["R_wal"] * (1 - a)  # K per W held over one interval
    need = L - (a * a * T0 + (1 - a * a) * Ta)
    kwh, kh = DT / 3.6e6, DT / 3600.0
    per_kelvin = {0: price[0] * kwh / (a * b), 1: price[1] * kwh / b}
    gain = {0: a * b, 1: b}
    q = [0.0, 0.0]
    for i in sorted(per_kelvin, key=per_kelvin.get):
        if per_kelvin[i] >= comfort * kh or need <= 0:
            break
        q[i] = min(qmax, need / gain[i])
        need -= q[i] * gain[i]
    return np.asarray(q), max(need, 0.0), a, b


@pytest.mark.parametrize(
    "price, comfort, qmax",
    [
        ((0.10, 0.40), 5.0, 6000.0),  # early heating is cheaper, capped by the heater
        ((0.40, 0.10), 5.0, 6000.0),  # late heating is cheaper
        ((0.10, 0.40), 5.0, 1e5),  # all early
        ((0.40, 0.40), 0.01, 6000.0),  # discomfort cheaper than heating
    ],
)
def test_one_state_program_matches_the_hand_solution(price, comfort, qmax):
    mpc = LinearMPC.from_form(_form(), horizon=2, q_max=qmax, comfort=comfort)
    T0, Ta, L = 15.0, 0.0, 21.0
    inputs = np.zeros((3, 3))
    inputs[:, 0] = Ta  # T_amb; Q_hea and I_glo_hor zero
    plan = mpc.plan([T0], inputs, price, lower=[-50.0, L])
    q, short, a, b = _hand(T0, Ta, L, price, qmax, comfort)
    _, M = mpc.response()
    np.testing.assert_allclose(M, [[b, 0.0], [a * b, b]], rtol=1e-12)
    np.testing.assert_allclose(plan.q, q, rtol=1e-7, atol=1e-6)
    np.testing.assert_allclose(plan.below, [0.0, short], atol=1e-7)
    kwh, kh = DT / 3.6e6, DT / 3600.0
    assert plan.cost == pytest.approx(np.dot(price, q) * kwh + comfort * short * kh, rel=1e-7)
    assert 0 < q.sum() or short > 0


def test_program_checks_its_input():
    mpc = LinearMPC.from_form(_form(), horizon=4, q_max=5000.0)
    with pytest.raises(FitError, match="inputs hold 2 ahead"):
        mpc.plan([18.0], np.zeros((3, 3)), 0.1, 20.0)
    with pytest.raises(FitError, match="price must hold 4 finite values"):
        mpc.plan([18.0], np.zeros((5, 3)), [0.1, np.nan, 0.1, 0.1], 20.0)
    with pytest.raises(FitError, match="no heater input 'Q_hea2'"):
        LinearMPC.from_form(_form(), horizon=4, q_max=5000.0, heater="Q_hea2")
    with pytest.raises(FitError, match="q_min < q_max"):
        LinearMPC.from_form(_form(), horizon=4, q_max=0.0)


@pytest.fixture(scope="module")
def data():
    n = 3 * 24 + 1
    t = np.arange(n) * DT
    u = {
        "T_amb": 3.0 + 3.0 * np.sin(2 * np.pi * t / 86400.0),
        "I_glo_hor": np.clip(200.0 * np.sin(2 * np.pi * t / 86400.0 - 1.5), 0, None),
        "Q_hea": np.zeros(n),
    }
    base = jaxbox.data.Dataset.from_arrays(t, {**u, "T_zon": np.zeros(n)})
    y, _ = simulate_sde("Zon", {**ZON, **NOISE}, base, seed=1, x0_std=0.0)
    return base.with_columns(T_zon=y[:, 0])


def test_tracker_is_the_kalman_filter(data):
    """Update then predict, sample by sample (the heater off), gives the batch filter's
    filtered states."""
    form = _form()
    run = form.filter(data)
    s = form.system()
    tr = KalmanTracker(s, 1, s.m0.copy(), s.P0.copy())
    u = data.array(["T_amb", "Q_hea", "I_glo_hor"])
    y = data.array(["T_zon"])
    for k in range(len(data)):
        tr.update(y[k], u[k])
        np.testing.assert_allclose(tr.m, run.m[k], rtol=1e-12)
        np.testing.assert_allclose(tr.P, run.P[k], rtol=1e-9)
        if k + 1 < len(data):
            tr.predict(u[k], u[k + 1], 0.0)


def _loop(controller_of, data, steps=48, H=12):
    form = _form()
    u = data.array(["T_amb", "Q_hea", "I_glo_hor"])
    index = data.index
    hours = index.hour
    price = np.where((hours >= 17) & (hours < 21), 0.40, 0.10)
    lower = comfort_band(index, day=20.0, night=17.0)
    plant = _form({"sigma_zon": 0.0, "sigma_y_zon": 0.05}, 0.0)
    ctl = controller_of(form, u, price, lower, H)
    return closed_loop(
        plant, [18.0], u, index, ctl, steps=steps, price=price, lower=lower, noise_sd=0.0
    )


def test_closed_loop_mpc_holds_the_band_and_beats_a_thermostat(data):
    """The plant is the model itself (no gains, no noise): the MPC keeps the zone in the band
    (to the solver's tolerance) and pays less than a PI thermostat, which must overshoot to
    keep it."""

    def mpc(form, u, price, lower, H):
        m = LinearMPC.from_form(form, horizon=H, q_max=8000.0, comfort=5.0)
        tr = KalmanTracker(m.system, m.heater, np.asarray([18.0]), np.asarray([[1e-6]]))
        return MPCController(m, tr, u, price, lower)

    def pi(form, u, price, lower, H):
        return PIController(lower + 0.5, kp=4000.0, ti=2 * DT, q_max=8000.0, dt=DT)

    a, b = _loop(mpc, data), _loop(pi, data)
    assert a.discomfort_kh < 0.02
    assert np.all(a.q >= -1e-9) and np.all(a.q <= 8000.0 + 1e-9)
    assert a.cost < b.cost
    frame = a.frame()
    assert list(frame.columns) == ["T_zon", "measured", "lower", "Q_hea", "price"]
    assert len(frame) == 49 and np.isnan(frame["Q_hea"].iloc[-1])
    assert a.energy_kwh == pytest.approx(a.q.sum() * DT / 3.6e6)
    assert isinstance(a.index, pd.DatetimeIndex)


def test_upper_edge_is_priced_and_never_heated_past():
    """A zone above the band's upper edge and cooling on its own: no heating, and the
    predicted excess is the free response above the edge (the heater cannot cool)."""
    mpc = LinearMPC.from_form(_form(), horizon=3, q_max=5000.0, comfort=2.0)
    tau = ZON["C_zon"] * ZON["R_wal"]
    a = math.exp(-DT / tau)
    T0, Ta = 26.0, 10.0
    inputs = np.zeros((4, 3))
    inputs[:, 0] = Ta
    plan = mpc.plan([T0], inputs, 0.2, lower=15.0, upper=24.0)
    free = Ta + (T0 - Ta) * a ** np.arange(1, 4)
    np.testing.assert_allclose(plan.q, 0.0, atol=1e-9)
    np.testing.assert_allclose(plan.T, free, rtol=1e-12)
    np.testing.assert_allclose(plan.above, np.clip(free - 24.0, 0, None), atol=1e-9)
    kh = DT / 3600.0
    assert plan.cost == pytest.approx(2.0 * kh * np.clip(free - 24.0, 0, None).sum(), rel=1e-7)


@pytest.mark.slow
def test_closed_loop_check_tells_a_model_fit_for_control_from_one_that_is_not():
    """The fit of a zoo building's true structure controls it as well as the truth (model cost
    near 1, the band held); the same fit with its resistances at 40 % (a heat loss 2.5 times
    too high) is not fit for control. The verdict carries the check where the plant is given."""
    import dataclasses

    from jaxbox.control import MAX_MODEL_COST, closed_loop_check
    from jaxbox.datasets import make_zoo
    from jaxbox.validate import check_validity

    (b,) = make_zoo(
        1,
        seed=38,
        zones=(1,),
        step="60min",
        days=12,
        heating="prbs",
        gaps=0.0,
        offset=0.0,
        max_states=2,
        prefix="m",
    )
    n = len(b.data)
    fit = jaxbox.fit_model(b.structure, b.data.slice(None, b.data.index[(n - 1) // 2]), starts=2)
    verdict = check_validity(fit, plant=b)
    good = verdict.closed_loop
    assert good.ok and abs(good.model_cost - 1.0) < 0.03 and good.days == pytest.approx(5.0)
    assert good.discomfort_kh_per_day <= 1.0
    assert "(control) closed loop on the true building" in verdict.summary()
    assert verdict.to_dict()["closed_loop"]["model_cost"] == good.model_cost
    scaled = {k: v * 0.4 if k.startswith("R_") else v for k, v in fit.params.items()}
    bad = closed_loop_check(dataclasses.replace(fit, params=scaled), b, days=3)
    assert not bad.ok and bad.model_cost > MAX_MODEL_COST
    assert "NOT fit for control" in bad.line
    with pytest.raises(TypeError, match="building must be a jaxbox.datasets.ZooBuilding"):
        closed_loop_check(fit, b.data)
