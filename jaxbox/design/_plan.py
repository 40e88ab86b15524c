"""Plan a heating sequence that maximises the information of an identification experiment.

The heating power per sample is ``u = P_min + (P_max − P_min) · s``, ``s = (1 + sin z)/2`` (the
power bounds hold by construction, and a power on a bound can leave it again: unlike a logistic,
the sine does not flatten out, so the switching times of a bang-bang schedule keep moving; the
logistic got stuck in worse local optima); the optimiser (:class:`optimistix.BFGS`, gradients
by autodiff through the simulator and its sensitivities) minimises::

    loss(z) = criterion(u) + ρ · (comfort + energy) [+ μ · binary]

* ``criterion``: D, A or hlc (:mod:`~jaxbox.design._fisher`), averaged over the prior samples in
  a robust design;
* ``comfort``: mean squared excursion [K²] of the predicted outputs (nominal prior) outside the
  comfort band shrunk by a margin of 0.1 K;
* ``energy``: squared relative excess of the energy ``step · Σ u`` over the maximum;
* ``binary`` (on/off heaters): ``mean s(1 − s)``, added in a second
  phase that starts from the relaxed optimum and pushes it to 0/1 before rounding.

ρ starts at 100 and grows tenfold (up to three times) while a constraint is violated. Several
starts (constant mid power, PRBS, ROLBS and random patterns) are optimised together under
``vmap``; the best feasible one is kept. The compiled solver is reused for every design of the
same model structure, criterion and horizon.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pandas as pd

from .._compiled import cached, jit
from .._x64 import require_x64
from ..models import ModelError
from ._context import Context, default_weather, make_context
from ._fisher import CRITERIA, Setup, make_setup
from ._prior import load_prior, prior_samples
from ._sequences import levels, prbs, rolbs, step

__all__ = ["Design", "plan", "evaluate", "baseline_schedules"]

_MARGIN = 0.1  # K inside the comfort band
_RHO0 = 100.0
_MU = 2.0
_START_GRID = 5  # start temperatures tried across the comfort band


@dataclasses.dataclass(frozen=True, eq=False)
class Design:
    """A planned experiment and what it predicts, with the baselines of equal length and energy.

    Attributes:
        model: the model name.
        criterion: ``"D"``, ``"A"`` or ``"hlc"``.
        heating: the designed input.
        index: time stamps of the schedule.
        power: the designed heating [W] per sample (rounded to the power bounds when binary).
        relaxed: the continuous optimum before rounding (binary designs), else None.
        schedules: every schedule [W] by name: ``designed``, ``prbs``, ``rolbs``, ``step``.
        reports: what each schedule predicts (:meth:`Context.report`), by the same names.
        rounding_loss: criterion after rounding minus the relaxed one (log units; binary only).
        settings: the inputs of the design (sigma, step, power, comfort, max energy…).
        timing: ``compile_s`` and ``design_s``.
        context: the design problem, to evaluate other schedules (:meth:`Context.report`).
    """

    model: str
    criterion: str
    heating: str
    index: pd.DatetimeIndex
    power: np.ndarray
    relaxed: np.ndarray | None
    schedules: dict
    reports: dict
    rounding_loss: float | None
    settings: dict
    timing: dict
    context: Context

    def schedule(self, baselines: bool = False) -> pd.DataFrame:
        """The schedule: heating [W] and predicted outputs [°C] per time stamp (with the
        baselines' heating as ``<heating>_<name>`` columns on request)."""
        rep = self.reports["designed"]
        frame = pd.DataFrame({self.heating: self.power}, index=self.index)
        for j, o in enumerate(self.context.setup.model.outputs):
            frame[f"{o}_predicted"] = rep["outputs"][:, j]
        if baselines:
            for name, p in self.schedules.items():
                if name != "designed":
                    frame[f"{self.heating}_{name}"] = p
        frame.index.name = "time"
        return frame

    def to_csv(self, path, baselines: bool = False) -> None:
        """Write :meth:`schedule` as CSV (time stamps in the first column)."""
        self.schedule(baselines).to_csv(path, float_format="%.6g")

    def table(self) -> pd.DataFrame:
        """Predicted standard deviation [SI] of every free parameter and of the HLC [W/K], with
        energy and predicted temperature range, per schedule (columns)."""
        rows = {}
        for name, rep in self.reports.items():
            col = dict(rep["std"])
            col["HLC [W/K]"] = rep["hlc_std"]
            col["HLC rel. std"] = rep["hlc_std"] / rep["hlc"]
            col["energy [kWh]"] = rep["energy_kwh"]
            col["T min [°C]"] = rep["t_min"]
            col["T max [°C]"] = rep["t_max"]
            col[f"loss {self.criterion}"] = rep["loss"][self.criterion]
            rows[name] = col
        return pd.DataFrame(rows)

    def summary(self) -> str:
        """A plain-text table of the predicted standard deviations, designed vs baselines."""
        t = self.table()
        lines = [
            f"design of {self.model} ({self.criterion}-optimal, {len(self.power)} samples of "
            f"{self.settings['step']:g} s, σ = {self.settings['sigma']:g} K) in "
            f"{self.timing['design_s']:.1f} s (+{self.timing['compile_s']:.1f} s compiling), "
            f"the building held at {self.settings['start_temperature']:.3g} °C before the start"
        ]
        if self.rounding_loss is not None:
            lines.append(
                f"on/off rounding changed the criterion by {self.rounding_loss:+.3g} (log units)"
            )
        for name, rep in self.reports.items():
            if rep["unidentifiable"]:
                lines.append(
                    f"the {name} schedule leaves {', '.join(rep['unidentifiable'])} "
                    "unidentifiable (singular Fisher information): their std is inf"
                )
        names = list(t.columns)
        lines.append(f"{'predicted std':<16}" + "".join(f"{n:>12}" for n in names))
        for row, values in t.iterrows():
            lines.append(f"{row:<16}" + "".join(f"{v:>12.4g}" for v in values))
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready: settings, timing, rounding loss and each schedule's predictions."""
        reps = {
            k: {kk: vv for kk, vv in v.items() if kk != "outputs"} for k, v in self.reports.items()
        }
        return {
            "model": self.model,
            "criterion": self.criterion,
            "heating": self.heating,
            "settings": self.settings,
            "timing": self.timing,
            "rounding_loss": self.rounding_loss,
            "predictions": reps,
        }


# ---- the compiled solver -----------------------------------------------------------------------


def _solver_fn(setup: Setup, criterion: str, max_steps: int, Z, args):
    """The solver compiled ahead of time for these shapes: ``(executable, compiled now)``.

    One compilation per model structure, criterion, horizon, number of starts and of prior
    samples; bounds, comfort, energy, noise, weather and prior values are arguments."""
    shapes = tuple((a.shape, str(a.dtype)) for a in jax.tree_util.tree_leaves((Z, args)))

    def build():
        def loss(z, args):
            mats, tangents, c, U0, sigma, lo, hi, tlo, thi, emax, dt, rho, mu = args
            s = 0.5 * (1.0 + jnp.sin(z))
            u = lo + (hi - lo) * s
            U = U0.at[:, setup.heat_index].set(u)
            F = setup.information(mats, tangents, U, sigma)
            value = jnp.mean(jax.vmap(lambda f, cc: setup.criterion(criterion, f, cc))(F, c))
            y = setup.simulate(jax.tree_util.tree_map(lambda a: a[0], mats), U)
            comfort = jnp.mean(jax.nn.relu(y - thi) ** 2 + jax.nn.relu(tlo - y) ** 2)
            energy = jax.nn.relu(dt * jnp.sum(u) / emax - 1.0) ** 2
            return value + rho * (comfort + energy) + mu * jnp.mean(s * (1.0 - s))

        solver = optx.BFGS(rtol=1e-8, atol=1e-8)

        def solve(Z0, args):
            def one(z):
                sol = optx.minimise(loss, solver, z, args, max_steps=max_steps, throw=False)
                return sol.value, loss(sol.value, args), sol.stats["num_steps"]

            return jax.vmap(one)(Z0)

        return jit(solve).lower(Z, args).compile()

    key = ("design", "solve", setup.key, criterion, int(max_steps), shapes)
    return cached(key, build)


def _starts(n: int, count: int, seed: int, step_s: float) -> np.ndarray:
    rng = np.random.default_rng(seed)
    Z = [np.zeros(n)]
    hours = max(1, int(round(3600 / step_s)))
    patterns = [rolbs(n, 1, 48 * hours, 6, seed), prbs(n, 8 * hours, seed + 1)]
    for p in patterns:
        Z.append(1.2 * (2.0 * p - 1.0))
    while len(Z) < count:
        Z.append(rng.uniform(-1.5, 1.5, n))
    return np.asarray(Z[:count])


def _unidentifiable(ctx: Context, powers) -> list[str]:
    """The free parameters that none of the schedules ``powers`` [k, N] [W] identifies (empty
    when one of them identifies every parameter)."""
    common = None
    for u in powers:
        names = ctx.report(u)["unidentifiable"]
        common = names if common is None else [n for n in common if n in names]
        if not common:
            return []
    return common or []


def _unidentifiable_error(ctx: Context, names, what: str) -> ModelError:
    return ModelError(
        f"{what} leaves {', '.join(names)} of {ctx.setup.model.name} unidentifiable (the "
        "outputs do not depend on them, or only in a combination: the Fisher information is "
        "singular); leave them out of the free parameters (free=, or the 'free' list of the fit "
        "JSON), or give weather and power bounds that excite them"
    )


# ---- baselines ---------------------------------------------------------------------------------


def baseline_schedules(
    ctx: Context,
    lo: float,
    hi: float,
    energy_j: float | None,
    *,
    criterion: str = "hlc",
    prbs_clock: int | None = None,
    rolbs_longest: int | None = None,
    seed: int = 0,
) -> dict:
    """PRBS, ROLBS and step schedules [W] of the context's length.

    With ``energy_j`` [J] the binary ones switch between ``lo`` and the level that gives that
    energy (capped at ``hi``) and the step holds the mean power; without it they switch between
    ``lo`` and ``hi`` and the step holds the middle. The PRBS clock is the best for ``criterion``
    among 1, 2, 4, … samples (up to a quarter of the horizon) unless given; the ROLBS durations
    span one sample to ``rolbs_longest`` (default 72 h, at most a quarter of the horizon).
    """
    lo, hi = _check_pair("power", (lo, hi), "W")
    if lo < 0:
        raise ModelError(f"power bounds must be ≥ 0 W (a heater), got {lo:g}")
    if energy_j is not None:
        energy_j = _real("energy_j", energy_j, "J")
        if not (math.isfinite(energy_j) and energy_j >= 0):
            raise ModelError(f"energy_j must be ≥ 0 [J] or None, got {energy_j}")
    if criterion not in CRITERIA:
        raise ModelError(f"unknown criterion {criterion!r}; choose one of {', '.join(CRITERIA)}")
    if prbs_clock is not None:
        prbs_clock = _count("prbs_clock", prbs_clock, 1)
    if rolbs_longest is not None:
        rolbs_longest = _count("rolbs_longest", rolbs_longest, 1)
    seed = _count("seed", seed, 0)
    n = ctx.n
    hours = max(1, int(round(3600 / ctx.step)))

    def scaled(pattern):
        if energy_j is None:
            return levels(pattern, lo, hi)
        on = pattern.sum()
        target = energy_j / ctx.step
        high = hi if on == 0 else min(hi, max(lo, lo + (target - n * lo) / on))
        return levels(pattern, lo, high)

    out = {}
    if prbs_clock is None:
        best = None
        clock = 1
        while clock <= max(1, n // 4):
            u = scaled(prbs(n, clock, seed + 1))
            value = ctx.report(u)["loss"][criterion]
            if best is None or value < best[0]:
                best = (value, u)
            clock *= 2
        out["prbs"] = best[1]
    else:
        out["prbs"] = scaled(prbs(n, int(prbs_clock), seed + 1))
    longest = rolbs_longest or min(72 * hours, max(1, n // 4))
    out["rolbs"] = scaled(rolbs(n, 1, int(longest), 6, seed))
    if energy_j is None:
        out["step"] = np.full(n, 0.5 * (lo + hi))
    else:
        out["step"] = np.full(n, min(hi, max(lo, energy_j / (n * ctx.step))))
    out["step"] = np.asarray(out["step"]) * step(n)
    return out


def _args(ctx, lo, hi, tlo, thi, emax, rho, mu):
    extra = (lo, hi, tlo, thi, emax, ctx.step, rho, mu)
    return (*ctx.args(), *(jnp.asarray(float(v)) for v in extra))


def _design_one(ctx, solve, Z, criterion, lo, hi, tlo, thi, emax, comfort, max_energy, binary):
    """Solve one design problem: the relaxed optimum (ρ raised while a constraint is violated),
    then, for on/off heaters, the binary phase and the rounding."""

    def to_power(z):
        return lo + (hi - lo) * 0.5 * (1.0 + np.sin(np.asarray(z)))

    def violation(u):
        rep = ctx.report(u)
        v = 0.0
        if comfort:
            v = max(v, rep["t_max"] - comfort[1], comfort[0] - rep["t_min"])
        if max_energy is not None:
            v = max(v, (np.sum(u) * ctx.step - max_energy) / max_energy * 10)
        return v

    def best_of(Zs, losses):
        order = np.argsort(np.asarray(losses))
        for i in order:
            if violation(to_power(Zs[i])) <= 1e-6:
                return int(i)
        return int(order[0])

    rho = _RHO0
    Zs, losses, _ = solve(Z, _args(ctx, lo, hi, tlo, thi, emax, rho, 0.0))
    for _ in range(3):
        i = best_of(np.asarray(Zs), losses)
        if violation(to_power(np.asarray(Zs)[i])) <= 1e-6:
            break
        rho *= 10.0
        Zs, losses, _ = solve(Zs, _args(ctx, lo, hi, tlo, thi, emax, rho, 0.0))
    i = best_of(np.asarray(Zs), losses)
    relaxed = to_power(np.asarray(Zs)[i])
    rounding_loss = None
    designed = relaxed
    if binary:
        Zb, lb, _ = solve(Zs, _args(ctx, lo, hi, tlo, thi, emax, rho, _MU))
        zb = np.asarray(Zb)[best_of(np.asarray(Zb), lb)]
        designed = np.where(np.sin(zb) >= 0.0, hi, lo)
        if max_energy is not None:
            designed = _within_budget(designed, np.sin(zb), lo, hi, ctx.step, max_energy)
        rounding_loss = (
            ctx.report(designed)["loss"][criterion] - ctx.report(relaxed)["loss"][criterion]
        )
    return {
        "designed": designed,
        "relaxed": relaxed,
        "rounding_loss": rounding_loss,
        "loss": ctx.report(designed)["loss"][criterion],
        "violation": violation(designed),
    }


def _within_budget(u, score, lo: float, hi: float, step: float, budget: float) -> np.ndarray:
    """An on/off schedule [W] cut to the energy budget [J]: the on samples whose relaxed value
    ``score`` is lowest (the least surely on) are switched off until it fits."""
    excess = float(np.sum(u)) * step - budget
    if excess <= 0.0:
        return u
    on = np.flatnonzero(u == hi)
    k = min(len(on), int(np.ceil(excess / ((hi - lo) * step) - 1e-9)))
    u = u.copy()
    u[on[np.argsort(score[on], kind="stable")[:k]]] = lo
    return u


def _warn_violation(rep: dict, comfort, max_energy, lo: float, hi: float) -> None:
    """Warn that the designed schedule breaks a constraint, saying which and by how much."""
    broken = []
    if comfort and (rep["t_min"] < comfort[0] - 1e-6 or rep["t_max"] > comfort[1] + 1e-6):
        broken.append(
            f"the predicted temperature {rep['t_min']:.3g}–{rep['t_max']:.3g} °C leaves the "
            f"comfort band {comfort[0]:g}–{comfort[1]:g} °C"
        )
    if max_energy is not None and rep["energy_kwh"] * 3.6e6 > max_energy * (1 + 1e-6):
        broken.append(
            f"it uses {rep['energy_kwh']:.4g} kWh of the {max_energy / 3.6e6:.4g} kWh allowed"
        )
    if broken:
        warnings.warn(
            f"no schedule within the power bounds {lo:g}–{hi:g} W met the constraints: "
            f"{'; '.join(broken)}; widen the comfort band, raise the power bounds or the energy "
            "budget, or change the start temperature",
            stacklevel=3,
        )


# ---- the front end -----------------------------------------------------------------------------


def _check_pair(name, pair, unit):
    if isinstance(pair, str | bytes | Mapping) or not hasattr(pair, "__len__") or len(pair) != 2:
        raise ModelError(f"{name} must be a pair (low, high) in {unit}, got {pair!r}")
    try:
        a, b = (float(pair[0]), float(pair[1]))
    except (TypeError, ValueError):
        raise ModelError(f"{name} must be a pair (low, high) in {unit}, got {pair!r}") from None
    if not (math.isfinite(a) and math.isfinite(b) and a < b):
        raise ModelError(f"{name} must be finite with low < high [{unit}], got ({a:g}, {b:g})")
    return a, b


def _real(name: str, value, unit: str) -> float:
    """A number argument as a float (a TypeError naming it otherwise); finiteness is checked
    by the caller."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise TypeError(f"{name} must be a number [{unit}], got {value!r}")
    return float(value)


def _count(name: str, value, minimum: int) -> int:
    """A whole-number argument ≥ ``minimum`` (a TypeError or ModelError naming it otherwise)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise TypeError(f"{name} must be an integer ≥ {minimum}, got {value!r}")
    if value < minimum:
        raise ModelError(f"{name} must be an integer ≥ {minimum}, got {value}")
    return int(value)


def _step(step) -> float:
    """The sample step [s]: a number > 0."""
    step = _real("step", step, "s")
    if not (math.isfinite(step) and step > 0):
        raise ModelError(f"step must be > 0 [s], got {step}")
    return step


def _horizon(days, step_s: float) -> int:
    """The number of samples of ``days`` [days] at ``step_s`` [s]: a whole number, ≥ 4."""
    days = _real("days", days, "days")
    if not (math.isfinite(days) and days > 0):
        raise ModelError(f"days must be a horizon > 0 [days], got {days}")
    steps = days * 86400.0 / step_s
    n = round(steps)
    if abs(steps - n) > 1e-6 * max(steps, 1.0):
        raise ModelError(
            f"the horizon of {days:g} days is {steps:.4g} steps of {step_s:g} s; give a whole "
            f"number of steps (e.g. days={max(n, 1) * step_s / 86400:.6g})"
        )
    if n < 4:
        raise ModelError(f"the horizon of {days:g} days holds {n} steps of {step_s:g} s; give ≥ 4")
    return n


def _prepare(
    model,
    params,
    *,
    sigma,
    days,
    step_s,
    weather,
    free,
    heating,
    comfort,
    start_temperature,
    robust=0,
    spread=None,
    seed=0,
):
    require_x64()
    sigma = _real("sigma", sigma, "K")
    if not (math.isfinite(sigma) and sigma > 0):
        raise ModelError(f"sigma must be a noise standard deviation > 0 [K], got {sigma}")
    step_s = _step(step_s)
    n = _horizon(days, step_s)
    if start_temperature is not None:
        start_temperature = _real("start_temperature", start_temperature, "°C")
        if not math.isfinite(start_temperature):
            raise ModelError(
                f"start_temperature must be a finite number [°C], got {start_temperature}"
            )
    robust = _count("robust", robust, 0)
    seed = _count("seed", seed, 0)
    prior = load_prior(model, params, free)
    setup = make_setup(prior.model, prior.free, heating)
    weather = default_weather(step_s) if weather is None else weather
    if start_temperature is None:
        start_temperature = 0.5 * (comfort[0] + comfort[1]) if comfort else 20.0
    names = tuple(setup.free[i] for i in setup.interest if setup.log[i])
    samples = None
    if robust and robust > 1:
        samples = prior_samples(prior, names, int(robust), spread, seed)
    ctx = make_context(prior, setup, weather, n, step_s, sigma, start_temperature, samples, names)
    return prior, setup, ctx


def _schedule(power) -> np.ndarray:
    """A heating schedule [W] as a 1-D float array of at least 4 finite samples."""
    try:
        power = np.asarray(power, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(
            f"power must be a sequence of numbers (heating [W] per sample), got "
            f"{type(power).__name__}"
        ) from None
    if power.ndim != 1 or len(power) < 4:
        raise ModelError(
            f"power must be a 1-D schedule of at least 4 samples [W], got shape {power.shape}"
        )
    bad = np.flatnonzero(~np.isfinite(power))
    if len(bad):
        raise ModelError(
            f"the power has {len(bad)} non-finite value(s) (NaN or inf), the first at sample "
            f"{bad[0]}; give a finite heating power [W] for every sample"
        )
    return power


def evaluate(
    power,
    model=None,
    params=None,
    *,
    sigma: float = 0.05,
    step: float = 3600.0,
    weather=None,
    free=None,
    heating: str | None = None,
    start_temperature: float = 25.0,
) -> dict:
    """What a heating schedule ``power`` [W per sample] predicts: :meth:`Context.report`
    (standard deviations of every free parameter and of the HLC, energy, temperatures).

    The other arguments as in :func:`plan`; the horizon is the schedule's length. A schedule
    that leaves parameters unidentifiable (``report["unidentifiable"]``) gets a warning naming
    them.
    """
    power = _schedule(power)
    days = len(power) * step / 86400.0
    _, _, ctx = _prepare(
        model,
        params,
        sigma=sigma,
        days=days,
        step_s=step,
        weather=weather,
        free=free,
        heating=heating,
        comfort=None,
        start_temperature=start_temperature,
    )
    rep = ctx.report(power)
    if rep["unidentifiable"]:
        warnings.warn(
            f"the schedule leaves {', '.join(rep['unidentifiable'])} unidentifiable (singular "
            "Fisher information): their standard deviations, and the criteria they enter, are "
            "inf",
            stacklevel=2,
        )
    return rep


def plan(
    model=None,
    params: Mapping | str | None = None,
    *,
    sigma: float = 0.05,
    days: float = 7.0,
    step: float = 3600.0,
    weather=None,
    power: tuple[float, float] = (0.0, 3000.0),
    binary: bool = False,
    comfort: tuple[float, float] | None = (15.0, 35.0),
    max_energy: float | None = None,
    criterion: str = "hlc",
    start_temperature: float | None = None,
    robust: int = 0,
    spread: float | None = None,
    free=None,
    heating: str | None = None,
    starts: int = 4,
    max_steps: int = 1000,
    seed: int = 0,
    prbs_clock: int | None = None,
) -> Design:
    """Plan the heating of an identification experiment: the schedule that minimises the
    predicted uncertainty of the estimates (see :mod:`jaxbox.design`).

    Args:
        model: an :class:`~jaxbox.models.RCModel` or library name (optional with a fit JSON).
        params: prior parameter values: the path of a fit JSON (``jaxbox fit --json``), a mapping
            ``name -> value`` [SI], or None for the model's defaults.
        sigma: standard deviation of the measurement noise of the outputs [K].
        days: horizon [days]; the schedule has ``round(days · 86400 / step)`` samples.
        step: sample step [s] of the schedule and of the data the fit will see.
        weather: a :class:`~jaxbox.data.Dataset` with the model's other inputs (a forecast or a
            typical period) from the start of the experiment; default the bundled twin-house
            weather (Holzkirchen, from 2013-08-21).
        power: heater power bounds (min, max) [W].
        binary: on/off heater: only min or max power (relaxed, then rounded).
        comfort: band (low, high) [°C] for the predicted outputs (the zone temperature), or None.
        max_energy: maximum heating energy ``step · Σ power`` [J] (1 kWh = 3.6e6 J), or None.
        criterion: ``"D"`` (log det), ``"A"`` (trace) of the covariance of the model parameters
            in relative terms, or ``"hlc"`` (variance of the heat-loss coefficient).
        start_temperature: zone temperature [°C] the building is held at before the experiment
            (its initial state is that steady state); default: the best of five temperatures
            across the comfort band (1 K inside it), each designed for (preheating is part of
            the experiment; the baselines get the same start).
        robust: number of prior samples (> 1: the criterion is averaged over them; the first is
            the nominal prior).
        spread: standard deviation of ``log θ`` of the prior samples (e.g. 0.3); None: the
            fit's covariance (with a fit JSON).
        free: parameters the experiment will estimate (default the fit's free ones, or all).
        heating: the designed input (default the model's only ``Q_hea*``).
        starts: optimiser starts (constant, ROLBS-, PRBS-shaped, random), solved together.
        max_steps: BFGS iterations per start and phase.
        seed: seed of the random starts, prior samples and baselines.
        prbs_clock: PRBS clock period [samples] of the baseline (default: the best of 1, 2, 4…).

    Returns:
        :class:`Design`: the schedule, its predicted standard deviations and those of the
        baselines (PRBS, ROLBS, step) of equal length and energy.

    Raises:
        ModelError: bad arguments; or free parameters that no start schedule, or the designed
            one, identifies (named; a baseline that leaves some unidentifiable is reported
            with an infinite criterion instead).
    """
    if criterion not in CRITERIA:
        raise ModelError(f"unknown criterion {criterion!r}; choose one of {', '.join(CRITERIA)}")
    if not isinstance(binary, bool | np.bool_):
        raise TypeError(f"binary must be True (an on/off heater) or False, got {binary!r}")
    starts, max_steps = _count("starts", starts, 1), _count("max_steps", max_steps, 1)
    seed, robust = _count("seed", seed, 0), _count("robust", robust, 0)
    if prbs_clock is not None:
        prbs_clock = _count("prbs_clock", prbs_clock, 1)
    lo, hi = _check_pair("power", power, "W")
    if lo < 0:
        raise ModelError(f"power bounds must be ≥ 0 W (a heater), got {lo:g}")
    if comfort is not None:
        comfort = _check_pair("comfort", comfort, "°C")
        if comfort[1] - comfort[0] <= 2 * _MARGIN:
            raise ModelError(f"the comfort band {comfort} is narrower than {2 * _MARGIN} K")
    if max_energy is not None:
        max_energy = _real("max_energy", max_energy, "J")
        if not (math.isfinite(max_energy) and max_energy > 0):
            raise ModelError(f"max_energy must be > 0 [J], got {max_energy}")
        least = lo * _horizon(days, _step(step)) * step
        if least > max_energy:
            raise ModelError(
                f"max_energy {max_energy:.4g} J ({max_energy / 3.6e6:.4g} kWh) is below the "
                f"energy of the minimum power {lo:g} W over the horizon ({least / 3.6e6:.4g} "
                "kWh); raise max_energy or lower the minimum power"
            )
    if start_temperature is None:
        band = comfort or (15.0, 30.0)
        temperatures = list(np.linspace(band[0] + 1.0, band[1] - 1.0, _START_GRID))
    else:
        temperatures = [start_temperature]
    tlo, thi = (comfort[0] + _MARGIN, comfort[1] - _MARGIN) if comfort else (-1e9, 1e9)
    emax = max_energy if max_energy is not None else math.inf
    compile_s = 0.0
    t1 = time.perf_counter()
    best = None
    for temperature in temperatures:
        prior, setup, ctx = _prepare(
            model,
            params,
            sigma=sigma,
            days=days,
            step_s=step,
            weather=weather,
            free=free,
            heating=heating,
            comfort=comfort,
            start_temperature=temperature,
            robust=robust,
            spread=spread,
            seed=seed,
        )
        # ∂ log HLC/∂φ: rounding only (~1e-17) when the HLC depends on no free parameter
        if criterion == "hlc" and np.max(np.abs(np.asarray(ctx.linear[2][0]))) < 1e-9:
            raise ModelError(
                f"the HLC of {setup.model.name} depends on no free parameter (the "
                "resistances are fixed): criterion 'hlc' has nothing to minimise; free them or "
                "choose criterion 'D' or 'A'"
            )
        Z = jnp.asarray(_starts(ctx.n, starts, seed, ctx.step))
        unseen = _unidentifiable(ctx, lo + (hi - lo) * 0.5 * (1.0 + np.sin(np.asarray(Z))))
        if unseen:
            raise _unidentifiable_error(ctx, unseen, "every start schedule of the optimiser")
        t0 = time.perf_counter()
        solve, built = _solver_fn(
            setup, criterion, max_steps, Z, _args(ctx, lo, hi, tlo, thi, emax, _RHO0, 0.0)
        )
        if built:
            compile_s += time.perf_counter() - t0
        one = _design_one(
            ctx, solve, Z, criterion, lo, hi, tlo, thi, emax, comfort, max_energy, binary
        )
        score = (one["violation"] > 1e-6, one["loss"])
        if best is None or score < best[0]:
            best = (score, temperature, prior, setup, ctx, one)
    _, start_temperature, prior, setup, ctx, one = best
    designed, relaxed, rounding_loss = one["designed"], one["relaxed"], one["rounding_loss"]
    unseen = ctx.report(designed)["unidentifiable"]
    if unseen:
        raise _unidentifiable_error(ctx, unseen, "the designed schedule")
    if one["violation"] > 1e-6:
        _warn_violation(ctx.report(designed), comfort, max_energy, lo, hi)
    design_s = time.perf_counter() - t1 - compile_s
    energy = float(np.sum(designed) * ctx.step)
    schedules = {"designed": designed}
    schedules.update(
        baseline_schedules(
            ctx, lo, hi, energy, criterion=criterion, prbs_clock=prbs_clock, seed=seed
        )
    )
    reports = {k: ctx.report(v) for k, v in schedules.items()}
    settings = {
        "sigma": float(sigma),
        "days": float(days),
        "step": float(step),
        "samples": ctx.n,
        "power": [lo, hi],
        "binary": bool(binary),
        "comfort": None if comfort is None else list(comfort),
        "max_energy_j": max_energy,
        "start_temperature": float(start_temperature),
        "robust": int(robust),
        "spread": spread,
        "free": list(setup.free),
        "prior": prior.source,
        "weather_start": str(ctx.index[0]),
    }
    return Design(
        model=setup.model.name,
        criterion=criterion,
        heating=setup.heating,
        index=ctx.index,
        power=np.asarray(designed),
        relaxed=relaxed if binary else None,
        schedules=schedules,
        reports=reports,
        rounding_loss=None if rounding_loss is None else float(rounding_loss),
        settings=settings,
        timing={"compile_s": compile_s, "design_s": design_s},
        context=ctx,
    )
