"""Write notebooks/control.ipynb: identify a zoo building, forecast it with bands, its heat
demand for a setpoint, then MPC in closed loop against a thermostat."""

from _notebook import write
from nbformat.v4 import new_code_cell
from nbformat.v4 import new_markdown_cell as md


def code(text: str):
    return new_code_cell(text.strip("\n"))


write(
    "notebooks/control.ipynb",
    [
        md(
            "# Forecast and control with an identified model\n\n"
            "A simulated building of the zoo (known truth, real weather of the twin-house site, "
            "hourly): its model is identified from the first week, then used for what it is "
            "for — a forecast with uncertainty bands, the heat demand for a setpoint, and "
            "model-predictive control in closed loop, where the true building is the plant."
        ),
        code(
            """
import matplotlib.pyplot as plt
import numpy as np

import jaxbox

jaxbox.enable_x64()
from jaxbox.control import (
    KalmanTracker,
    LinearMPC,
    MPCController,
    PIController,
    closed_loop,
    comfort_band,
)
from jaxbox.datasets import make_zoo
from jaxbox.forecast import StochasticForm
from jaxbox.stochastic import noise_names

kind = dict(step="60min", days=12, heating="prbs", gaps=0, offset=0, structure="Zon+Wal")
b = make_zoo(1, seed=5, **kind)[0]
data = b.data
ident = data.slice(None, data.index[24 * 6])
fit = jaxbox.fit_model(b.structure, ident, starts=4)
print(fit.summary())
"""
        ),
        md(
            "## A forecast with bands\n\n"
            "The Kalman filter of the fit's stochastic form estimates the state at the end of "
            "the history; the mean and the covariance are propagated 24 h ahead with the "
            "(here: measured) weather and heating. An output-error fit has no noise model, so "
            "its noise is estimated from its residuals — the forecast says so."
        ),
        code(
            """
history = data.slice(None, data.index[24 * 7])
fc = fit.forecast(history, data, horizon="24h")
print(fc.attrs["noise"])
measured = fc["T_zon_measured"]
inside = (measured >= fc["T_zon_lo95"]) & (measured <= fc["T_zon_hi95"])
print(f"95 % band holds {inside.mean():.0%} of the measurements")
fig = jaxbox.plot_forecast(fc, history)
"""
        ),
        md(
            "## Heat demand for a setpoint\n\n"
            "The model inverted: the heating power that holds the zone at 21 °C by day and "
            "17 °C from 22:00 to 06:00, within the heater's range; the energy comes with a "
            "95 % band from a Monte Carlo of the stochastic model."
        ),
        code(
            """
q_max = 35 * b.kpis["hlc"]
hd = fit.heat_demand(
    history, data, setpoint=21.0, setback="17@22:00-06:00", q_max=q_max, horizon="36h"
)
a = hd.attrs
print(f"{a['energy_kwh']:.1f} kWh (95 %: {a['energy_kwh_lo95']:.1f}–{a['energy_kwh_hi95']:.1f})")
fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(10, 5))
ax1.plot(hd.index, hd["T_zon"], label="zone")
ax1.step(hd.index, hd["setpoint"], where="pre", ls="--", color="0.4", label="setpoint")
ax1.set_ylabel("°C")
ax1.legend()
ax2.fill_between(hd.index, hd["Q_hea_lo95"], hd["Q_hea_hi95"], step="pre", alpha=0.3)
ax2.step(hd.index, hd["Q_hea"], where="pre")
ax2.set_ylabel("W")
"""
        ),
        md(
            "## MPC in closed loop\n\n"
            "The true building is the plant (its true parameters, unmeasured internal gains, "
            "sensor noise). Each hour the MPC's Kalman filter reads the measured temperature, "
            "a linear program (HiGHS) plans 24 h of heating against the price and the comfort "
            "band, and the first hour is applied. A PI thermostat heats the same building."
        ),
        code(
            """
model = fit.model
u = data.array(list(model.inputs))
n0 = len(ident) - 1
index, uu = data.index[n0:], u[n0:]
H, steps = 24, 72
hours = index.hour
peak = ((hours >= 7) & (hours < 10)) | ((hours >= 17) & (hours < 21))
price = np.where(peak, 0.35, 0.12)
lower = comfort_band(index)
gains = 0.3 * b.kpis["hlc"] * np.random.default_rng(0).standard_normal(steps)

# the plant: the true building, started from its true state
zero = {k: 0.0 for k in noise_names(model)}
held = (0.0,) * model.n_states
plant = StochasticForm(model, {**b.params, **zero}, "foh", held, "ml", "plant", 3600.0)
s = plant.system()
x0 = np.array([b.params[node.T0] for node in model.network.nodes])
for k in range(n0):
    x0 = s.Phi @ x0 + s.G0 @ u[k] + s.G1 @ (u[k + 1] - u[k])

form = fit.stochastic_form()
run = form.filter(ident)
mpc = LinearMPC.from_form(form, horizon=H, q_max=q_max, comfort=1.0)
tracker = KalmanTracker(mpc.system, mpc.heater, run.m[-1], run.P[-1])
controllers = {
    "MPC": MPCController(mpc, tracker, uu, price, lower),
    "PI": PIController(
        comfort_band(index + np.timedelta64(2, "h")) + 0.5,
        kp=q_max / 2,
        ti=7200.0,
        q_max=q_max,
        dt=3600.0,
    ),
}
loops = {}
for name, c in controllers.items():
    opts = dict(steps=steps, price=price, lower=lower, gains=gains, noise_sd=b.noise)
    loops[name] = r = closed_loop(plant, x0, uu, index, c, **opts)
    print(f"{name}: {r.energy_kwh:.1f} kWh, cost {r.cost:.2f}, {r.discomfort_kh:.2f} K·h below")
assert loops["MPC"].cost < loops["PI"].cost
"""
        ),
        code(
            """
fig, (ax1, ax2, ax3) = plt.subplots(3, 1, sharex=True, figsize=(10, 7))
for name, r in loops.items():
    f = r.frame()
    ax1.plot(f.index, f["T_zon"], label=name)
    ax2.step(f.index, f["Q_hea"], where="post", label=name)
ax1.step(f.index, f["lower"], where="post", color="0.3", ls="--", label="comfort band")
ax1.set_ylabel("°C")
ax1.legend()
ax2.set_ylabel("W")
ax2.legend()
ax3.step(f.index, f["price"], where="post", color="tab:red")
ax3.set_ylabel("price per kWh")
"""
        ),
    ],
)
