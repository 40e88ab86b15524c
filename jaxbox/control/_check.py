"""Is a fitted model fit for control? A closed loop on a simulated building whose truth is known.

A model valid by its fit (small errors, determined parameters, plausible physics) may still
control a building badly. Where the true building is at hand (a zoo building:
:func:`jaxbox.datasets.make_zoo`), :func:`closed_loop_check` answers directly: over the data
after the fit's identification period, the true building is the plant (its exact
discretisation, with unmeasured internal gains and white sensor noise) and is heated twice by
the same receding-horizon MPC (:class:`~jaxbox.control.LinearMPC`, the Kalman state at every
sample), once on the fitted model and once on the true model. The *model cost* is the ratio of
the two closed-loop objectives (energy cost + discomfort); the model is fit for control when
its MPC holds the comfort band (at most :data:`MAX_DISCOMFORT` K·h a day below it) at a model
cost of at most :data:`MAX_MODEL_COST`. The protocol is that of ``benchmarks/mpc.py``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..fit._problem import FitError

__all__ = ["ClosedLoopCheck", "closed_loop_check", "MAX_MODEL_COST", "MAX_DISCOMFORT"]

#: the largest model cost (closed-loop objective with the model ÷ with the truth) fit for control
MAX_MODEL_COST = 1.05
#: the most kelvin-hours per day below the comfort band that count as holding it
MAX_DISCOMFORT = 1.0
#: price per kWh at the peaks (7–10 h, 17–21 h) and otherwise
PEAK, BASE = 0.35, 0.12


@dataclasses.dataclass(frozen=True)
class ClosedLoopCheck:
    """The outcome of :func:`closed_loop_check`.

    Attributes:
        model_cost: closed-loop objective with the fitted model ÷ with the true model [-].
        discomfort_kh_per_day: K·h per day below the comfort band with the fitted model.
        true_discomfort_kh_per_day: the same with the true model.
        energy_kwh, true_energy_kwh: heating energy over the loop [kWh].
        days: length of the loop [d]; horizon: the MPC's horizon [samples].
        ok: model cost ≤ :data:`MAX_MODEL_COST` and discomfort ≤ :data:`MAX_DISCOMFORT`.
    """

    model_cost: float
    discomfort_kh_per_day: float
    true_discomfort_kh_per_day: float
    energy_kwh: float
    true_energy_kwh: float
    days: float
    horizon: int
    ok: bool

    @property
    def line(self) -> str:
        """The verdict's closed-loop line."""
        head = "fit for control" if self.ok else "NOT fit for control"
        return (
            f"closed loop on the true building ({self.days:.1f} days, MPC over "
            f"{self.horizon} samples): {head}: model cost {self.model_cost:.3f} (at most "
            f"{MAX_MODEL_COST:g}), {self.discomfort_kh_per_day:.2f} K·h a day below the comfort "
            f"band (at most {MAX_DISCOMFORT:g}; the true model's MPC "
            f"{self.true_discomfort_kh_per_day:.2f})"
        )

    def to_dict(self) -> dict:
        return {**dataclasses.asdict(self), "line": self.line}


def _price(index) -> np.ndarray:
    h = index.hour
    return np.where(((h >= 7) & (h < 10)) | ((h >= 17) & (h < 21)), PEAK, BASE)


def _true_state(plant, u: np.ndarray, n: int) -> np.ndarray:
    """The true state after ``n`` samples of the data's own inputs (noise-free)."""
    s = plant.system()
    x = np.asarray([plant.params[node.T0] for node in plant.model.network.nodes], float)
    drive = u[:-1] @ s.G0.T + (u[1:] - u[:-1]) @ s.G1.T
    for k in range(n):
        x = s.Phi @ x + drive[k]
    return x


def closed_loop_check(
    result,
    building,
    *,
    horizon: str = "24h",
    days: float | None = None,
    seed: int = 0,
) -> ClosedLoopCheck:
    """Control the true ``building`` with an MPC on ``result``'s model and on the true model.

    Args:
        result: a fit of the building's data (output error or maximum likelihood; its
            stochastic form is :func:`~jaxbox.forecast.stochastic_form`), one zone.
        building: a one-zone :class:`~jaxbox.datasets.ZooBuilding` (its true structure and
            parameters, its noise-free data).
        horizon: the MPC's horizon (a duration, a whole number of samples).
        days: length of the loop [d] (default: the rest of the building's data after the
            fit's identification period, less one horizon).
        seed: of the unmeasured gains and the sensor noise.

    The heater reaches 35 K worth of the true heat loss; the comfort band is 20 °C from 6 to
    22 h and 17 °C at night, a kelvin-hour below it costs 1; price 0.35 per kWh from 7 to 10 h
    and 17 to 21 h, 0.12 otherwise; unmeasured gains 1 K worth of loss at 7–9 h and 17–23 h,
    with white noise of 0.3 K worth.
    """
    from ..forecast import StochasticForm, noise_from_residuals, stochastic_form
    from ..forecast._forecast import horizon_steps
    from ..models import get_model
    from ..stochastic import noise_names
    from ._loop import MPCController, closed_loop, comfort_band
    from ._mpc import KalmanTracker, LinearMPC

    for attr in ("structure", "params", "data", "kpis", "noise"):
        if not hasattr(building, attr):
            raise TypeError(
                "building must be a jaxbox.datasets.ZooBuilding (a simulated building with its "
                f"truth), got {type(building).__name__}"
            )
    if getattr(building, "held_zone", None) is not None:
        raise FitError(
            f"closed_loop_check controls one zone; {building.name} has a second, held zone"
        )
    form = stochastic_form(result)
    model = form.model
    truth = get_model(building.structure)
    if len(model.outputs) != 1 or "Q_hea" not in model.inputs:
        raise FitError(
            f"closed_loop_check needs a one-zone model heated by Q_hea, got {model.name} "
            f"(outputs {model.outputs}, inputs {model.inputs})"
        )
    data = building.clean if building.clean is not None else building.data
    dt = float(data.step)
    H = horizon_steps(horizon, dt)
    end = result.data.index[-1]
    n_id = int(np.searchsorted(data.index, end))
    left = len(data) - 1 - n_id - H
    steps = left if days is None else min(left, int(round(days * 86400.0 / dt)))
    if steps < max(1, int(86400.0 / dt)):
        raise FitError(
            f"the building's data hold {max(left, 0)} samples after the fit's data (ending "
            f"{end}) and its horizon of {H}: at least a day is needed for a closed loop"
        )
    ident = building.data.slice(None, data.index[n_id])
    index = data.index[n_id:]
    price = _price(index)
    lower = comfort_band(index)
    hlc = float(building.kpis["hlc"])
    q_max = 35.0 * hlc
    rng = np.random.default_rng([seed, 1])
    hours = index.hour
    occupied = ((hours >= 7) & (hours < 9)) | ((hours >= 17) & (hours < 23))
    gains = hlc * (1.0 * occupied + 0.3 * rng.standard_normal(len(index)))[:steps]
    zero = {k: 0.0 for k in noise_names(truth)}
    plant = StochasticForm(
        truth, {**building.params, **zero}, "foh", (0.0,) * truth.n_states, "ml", "plant", dt
    )
    u_true = np.asarray(data.array(list(truth.inputs)), float)
    x0 = _true_state(plant, u_true, n_id)
    objective, kh, energy = {}, {}, {}
    forms = {"model": form, "true": noise_from_residuals(truth, building.params, ident)}
    for name, f in forms.items():
        u = np.asarray(data.array(list(f.model.inputs)), float)[n_id:]
        run = f.filter(ident)
        mpc = LinearMPC.from_form(f, horizon=H, q_max=q_max, comfort=1.0)
        ctl = MPCController(
            mpc, KalmanTracker(mpc.system, mpc.heater, run.m[-1], run.P[-1]), u, price, lower
        )
        r = closed_loop(
            plant,
            x0,
            u_true[n_id:],
            index,
            ctl,
            steps=steps,
            price=price,
            lower=lower,
            comfort=1.0,
            gains=gains,
            noise_sd=float(building.noise),
            seed=seed,
        )
        objective[name], kh[name], energy[name] = r.objective, r.discomfort_kh, r.energy_kwh
    span = steps * dt / 86400.0
    cost = objective["model"] / objective["true"]
    per_day = kh["model"] / span
    return ClosedLoopCheck(
        model_cost=float(cost),
        discomfort_kh_per_day=float(per_day),
        true_discomfort_kh_per_day=float(kh["true"] / span),
        energy_kwh=float(energy["model"]),
        true_energy_kwh=float(energy["true"]),
        days=float(span),
        horizon=int(H),
        ok=bool(cost <= MAX_MODEL_COST and per_day <= MAX_DISCOMFORT),
    )
