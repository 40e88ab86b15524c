"""Closed-loop simulation: a controller heats a simulated building (the plant).

The plant is a model with its (true) parameters, discretised exactly at the control step: the
weather follows the fit's first-order hold, the heater's power and the unmeasured heat gains are
constant over each interval. At each sample the controller reads the measured zone temperature
(plant output plus white noise) and sets the power over the next interval.

Controllers: :class:`MPCController` (a :class:`~jaxbox.control.LinearMPC` on a fitted model, its
state from a :class:`~jaxbox.control.KalmanTracker`) and :class:`PIController` (a thermostat).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from ._mpc import KalmanTracker, LinearMPC

__all__ = ["LoopResult", "MPCController", "PIController", "closed_loop", "comfort_band"]


def comfort_band(index: pd.DatetimeIndex, day: float = 20.0, night: float = 17.0, hours=(6, 22)):
    """The comfort band's lower edge [°C] at each time: ``day`` from ``hours[0]`` to
    ``hours[1]`` o'clock, ``night`` otherwise."""
    h = index.hour
    return np.where((h >= hours[0]) & (h < hours[1]), float(day), float(night))


@dataclasses.dataclass
class MPCController:
    """A receding-horizon MPC: at sample ``k`` the filter takes the measurement, the program is
    solved over the next ``H`` intervals with the inputs forecast ``inputs[k : k + H + 1]``, the
    first power is applied and the filter predicts the next sample with it.

    Attributes:
        mpc: the program; tracker: the Kalman filter (its state at the first sample).
        inputs: the model's inputs [N + H + 1, m] (the heater's column ignored).
        price: price per kWh over each interval [N + H]; lower, upper: the comfort band at
            each sample [N + H + 1] (upper: None for none).
    """

    mpc: LinearMPC
    tracker: KalmanTracker
    inputs: np.ndarray
    price: np.ndarray
    lower: np.ndarray
    upper: np.ndarray | None = None

    def act(self, k: int, y) -> float:
        H = self.mpc.horizon
        self.tracker.update(y, self.inputs[k])
        plan = self.mpc.plan(
            self.tracker.m,
            self.inputs[k : k + H + 1],
            self.price[k : k + H],
            self.lower[k + 1 : k + H + 1],
            None if self.upper is None else self.upper[k + 1 : k + H + 1],
        )
        q = float(plan.q[0])
        self.tracker.predict(self.inputs[k], self.inputs[k + 1], q)
        return q


@dataclasses.dataclass
class PIController:
    """A PI thermostat on the measured zone temperature: ``q = kp e + ki Σ e Δt`` with
    ``e = setpoint − y`` [K], clipped to ``[0, q_max]``, the integral frozen while saturated
    (anti-windup).

    Attributes:
        setpoint: [°C] at each sample; kp [W/K]; ti: integral time [s]; q_max [W]; dt [s].
    """

    setpoint: np.ndarray
    kp: float
    ti: float
    q_max: float
    dt: float
    integral: float = 0.0

    def act(self, k: int, y) -> float:
        e = float(self.setpoint[k] - np.asarray(y, float)[0])
        if not np.isfinite(e):
            e = 0.0
        q = self.kp * (e + self.integral / self.ti)
        if 0.0 < q < self.q_max or (q >= self.q_max and e < 0) or (q <= 0 and e > 0):
            self.integral += e * self.dt
        return float(np.clip(self.kp * (e + self.integral / self.ti), 0.0, self.q_max))


@dataclasses.dataclass(frozen=True, eq=False)
class LoopResult:
    """A closed-loop run.

    Attributes:
        index: sample times [N + 1]; T: the plant's zone temperature [°C]; y: measured [°C];
        q: the heater's power over each interval [W] [N]; lower: the band's lower edge [N + 1].
        energy_kwh, cost (Σ price · energy), discomfort_kh (kelvin-hours below the band over
        the samples after the first), objective (cost + comfort · discomfort_kh).
    """

    index: pd.DatetimeIndex
    T: np.ndarray
    y: np.ndarray
    q: np.ndarray
    lower: np.ndarray
    price: np.ndarray
    energy_kwh: float
    cost: float
    discomfort_kh: float
    objective: float

    def frame(self) -> pd.DataFrame:
        """One row per sample: zone temperature, measured, band, power (over the interval that
        starts there), price."""
        n = len(self.q)
        return pd.DataFrame(
            {
                "T_zon": self.T,
                "measured": self.y,
                "lower": self.lower,
                "Q_hea": np.append(self.q, np.nan),
                "price": np.append(self.price[:n], np.nan),
            },
            index=self.index,
        )


def closed_loop(
    plant,
    x0,
    inputs,
    index: pd.DatetimeIndex,
    controller,
    *,
    steps: int,
    price,
    lower,
    comfort: float = 1.0,
    gains=None,
    noise_sd: float = 0.0,
    heater: str = "Q_hea",
    zone: str | None = None,
    seed: int | None = 0,
) -> LoopResult:
    """Run ``controller`` on the plant for ``steps`` intervals.

    Args:
        plant: the true building as a :class:`~jaxbox.forecast.StochasticForm` (its process
            noise is not used: the disturbance is ``gains``).
        x0: the plant's state at the first sample [°C].
        inputs: the plant's inputs [≥ steps + 1, m] (the heater's column ignored).
        index: the sample times [≥ steps + 1].
        controller: an object with ``act(k, y) -> q`` [W].
        price: per kWh over each interval; lower: the band's lower edge at each sample.
        comfort: the price of one kelvin-hour below the band (for ``objective``).
        gains: unmeasured heat gains into the heater's node over each interval [W] (default 0).
        noise_sd: white measurement noise [K]; seed: its seed.
    """
    model = plant.model
    s = plant.system()
    j = model.inputs.index(heater)
    row = model.outputs.index(zone or model.outputs[0])
    u = np.array(inputs, dtype=float)
    u[:, j] = 0.0
    drive = u[:-1] @ s.G0.T + (u[1:] - u[:-1]) @ s.G1.T
    g = s.G0[:, j]
    gains = np.zeros(steps) if gains is None else np.asarray(gains, float)
    rng = np.random.default_rng(seed)
    x = np.asarray(x0, float)
    T, Y, Q = [], [], []
    for k in range(steps + 1):
        t = float(s.C[row] @ x)
        y = np.full(len(model.outputs), np.nan)
        y[row] = t + noise_sd * rng.standard_normal()
        T.append(t)
        Y.append(y[row])
        if k == steps:
            break
        q = controller.act(k, y)
        Q.append(q)
        x = s.Phi @ x + drive[k] + g * (q + gains[k])
    T, Y, Q = np.asarray(T), np.asarray(Y), np.asarray(Q)
    price = np.asarray(price, float)[:steps]
    low = np.asarray(lower, float)[: steps + 1]
    dt = s.dt
    energy = float(Q.sum() * dt / 3.6e6)
    cost = float(price @ Q * dt / 3.6e6)
    kh = float(np.clip(low[1:] - T[1:], 0.0, None).sum() * dt / 3600.0)
    return LoopResult(
        index=index[: steps + 1],
        T=T,
        y=Y,
        q=Q,
        lower=low,
        price=price,
        energy_kwh=energy,
        cost=cost,
        discomfort_kh=kh,
        objective=cost + comfort * kh,
    )
