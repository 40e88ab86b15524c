"""Experiment design: how many days does each heating sequence need to pin down the HLC?

For ``ZonWal`` and ``ZonWalIntInf`` with the parameters fitted on the bundled twin-house data
(house N2, identification half, hourly) and output noise σ = 0.05 K, on the bundled weather from
2013-08-21:

1. the reference: the predicted standard deviation of the heat-loss coefficient (HLC) from a
   14-day ROLBS switching between 0 and 3 kW;
2. the days each design needs to reach it: the designed schedule (``jaxbox.design.plan``,
   c-optimal for the HLC, comfort band 15–35 °C, 0–3 kW, re-planned for each horizon), a PRBS
   (0/3 kW, the best clock period for the HLC), a ROLBS (0/3 kW) and a constant step (1.5 kW,
   co-heating); with the predicted temperature range of each;
3. the time to design a 7-day hourly schedule (first call, compiling included, and again);
4. the plain approach for the ratio: the same criterion and comfort penalty minimised by
   ``scipy.optimize.minimize`` (L-BFGS-B, box bounds on the powers) with finite-difference
   gradients, the information from finite-difference sensitivities of a numpy simulation (the
   discretised matrices precomputed once per parameter set), within a time budget.

    python benchmarks/design.py [--models ZonWal,ZonWalIntInf] [--plain-budget 300]

Writes ``benchmarks/design.json`` and ``benchmarks/DESIGN.md`` (appended to ``RESULTS.md`` by
``benchmarks/run.py``).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
import scipy.linalg
import scipy.optimize

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

import jaxbox  # noqa: E402

jaxbox.enable_x64()

from jaxbox import design  # noqa: E402
from jaxbox.design._plan import _prepare  # noqa: E402

SIGMA = 0.05
POWER = (0.0, 3000.0)
COMFORT = (15.0, 35.0)
REFERENCE_DAYS = 14
MAX_DESIGN_DAYS = 10
MAX_BASELINE_DAYS = 40


def prior_of(model: str) -> dict:
    """The parameters fitted on the bundled data, as ``jaxbox fit`` does (identification half)."""
    data = jaxbox.datasets.twinhouse_exp1("N2", "1h")
    ident, _ = data.split()
    result = jaxbox.fit_model(model, ident)
    return {k: float(v) for k, v in result.params.items()}


def context(model, prior, days):
    return _prepare(
        model,
        prior,
        sigma=SIGMA,
        days=days,
        step_s=3600.0,
        weather=None,
        free=None,
        heating=None,
        comfort=COMFORT,
        start_temperature=25.0,
    )[2]


def baselines(model, prior, days):
    """PRBS, ROLBS at 0/3 kW and the step at 1.5 kW over ``days``: their predictions."""
    ctx = context(model, prior, days)
    s = design.baseline_schedules(ctx, *POWER, None, criterion="hlc")
    return {k: ctx.report(v) for k, v in s.items()}


def days_needed_baselines(model, prior, target):
    out = {k: None for k in ("prbs", "rolbs", "step")}
    seen = {}
    for days in range(1, MAX_BASELINE_DAYS + 1):
        reps = baselines(model, prior, days)
        for k, rep in reps.items():
            if out[k] is None and rep["hlc_std"] <= target:
                out[k] = days
                seen[k] = rep
        if all(v is not None for v in out.values()):
            break
    return out, seen


def days_needed_design(model, prior, target):
    trail = []
    for days in range(1, MAX_DESIGN_DAYS + 1):
        d = design.plan(
            model, prior, sigma=SIGMA, days=days, power=POWER, comfort=COMFORT, criterion="hlc"
        )
        rep = d.reports["designed"]
        trail.append((days, rep["hlc_std"]))
        if rep["hlc_std"] <= target:
            return days, rep, trail
    return None, None, trail


# ---- the plain approach ------------------------------------------------------------------------


def plain_design(ctx, budget_s: float, loss_target: float):
    """scipy L-BFGS-B with finite-difference gradients on the same loss (criterion hlc + the
    comfort penalty), everything in numpy: FOH matrices by scipy's expm (precomputed at each
    parameter set of the central differences), sensitivities by central differences."""
    setup = ctx.setup
    model = setup.model
    phi0 = np.asarray(ctx.phis[0])
    p = len(phi0)
    dt = ctx.step
    hidx = setup.heat_index
    outs = list(setup.output_states)
    h = 1e-6

    def foh(phi):
        th = {k: float(v) for k, v in setup.theta(phi, ctx.fixed).items()}
        A, B, _, _ = (np.asarray(a) for a in model.state_space(th))
        n, m = B.shape
        M = np.zeros((n + 2 * m, n + 2 * m))
        M[:n, :n], M[:n, n : n + m] = A * dt, B * dt
        M[n : n + m, n + m :] = np.eye(m)
        E = scipy.linalg.expm(M)
        x0 = np.asarray([th[node.T0] for node in model.network.nodes])
        return E[:n, :n], E[:n, n : n + m], E[:n, n + m :], x0

    mats = [foh(phi0)]
    for i in range(p):
        for sgn in (1.0, -1.0):
            e = np.zeros(p)
            e[i] = sgn * h * (1.0 if setup.log[i] else 10.0)
            mats.append(foh(phi0 + e))
    steps = [h * (1.0 if lg else 10.0) for lg in setup.log]
    th0 = {k: float(v) for k, v in setup.theta(phi0, ctx.fixed).items()}
    c = np.zeros(p)
    for i in range(p):  # ∂ log HLC/∂φ by central differences of the numpy steady state
        vals = []
        for sgn in (1.0, -1.0):
            e = np.zeros(p)
            e[i] = sgn * steps[i]
            th = {k: float(v) for k, v in setup.theta(phi0 + e, ctx.fixed).items()}
            A, B, C, _ = (np.asarray(a) for a in model.state_space(th))
            vals.append(-np.log((C @ np.linalg.solve(-A, B))[0, hidx]))
        c[i] = (vals[0] - vals[1]) / (2 * steps[i])
    del th0
    U0 = np.asarray(ctx.inputs)
    tlo, thi = COMFORT[0] + 0.1, COMFORT[1] - 0.1

    def simulate(m, U):
        Phi, G0, G1, x0 = m
        drive = U[:-1] @ G0.T + (U[1:] - U[:-1]) @ G1.T
        xs = np.empty((len(U), len(x0)))
        xs[0] = x = x0
        for k in range(len(drive)):
            x = Phi @ x + drive[k]
            xs[k + 1] = x
        return xs[:, outs]

    def loss(u):
        U = U0.copy()
        U[:, hidx] = u
        y0 = simulate(mats[0], U)
        J = np.stack(
            [
                (simulate(mats[1 + 2 * i], U) - simulate(mats[2 + 2 * i], U)).ravel()
                / (2 * steps[i])
                for i in range(p)
            ],
            axis=1,
        )
        F = J.T @ J / ctx.sigma**2
        try:
            cov = np.linalg.inv(F)
        except np.linalg.LinAlgError:
            return 1e3
        v = c @ cov @ c
        crit = np.log(v) if v > 0 else 1e3
        comfort = np.mean(np.maximum(y0 - thi, 0) ** 2 + np.maximum(tlo - y0, 0) ** 2)
        return crit + 100.0 * comfort

    t0 = time.perf_counter()
    trace = []

    class Done(Exception):
        pass

    def fun(u):
        val = loss(u)
        trace.append((time.perf_counter() - t0, val))
        if time.perf_counter() - t0 > budget_s:
            raise Done
        return val

    u0 = np.full(ctx.n, 0.5 * (POWER[0] + POWER[1]))
    best = None
    try:
        res = scipy.optimize.minimize(
            fun,
            u0,
            method="L-BFGS-B",
            bounds=[POWER] * ctx.n,
            options={"maxiter": 10_000, "eps": 1.0},
        )
        best = res.x
    except Done:
        pass
    elapsed = time.perf_counter() - t0
    values = np.asarray([v for _, v in trace])
    reached = next((t for t, v in trace if v <= loss_target), None)
    return {
        "seconds": elapsed,
        "evaluations": len(trace),
        "best_loss": float(values.min()),
        "time_to_design_loss_s": reached,
        "finished": best is not None,
    }


# ---- the report --------------------------------------------------------------------------------


def measure(model: str, plain_budget: float) -> dict:
    print(f"== {model}", flush=True)
    t = time.perf_counter()
    prior = prior_of(model)
    print(f"fit {time.perf_counter() - t:.1f} s", flush=True)
    ref = baselines(model, prior, REFERENCE_DAYS)["rolbs"]
    target = ref["hlc_std"]
    print(f"14-day ROLBS: HLC {ref['hlc']:.2f} ± {target:.4f} W/K", flush=True)
    # the design of a 7-day hourly schedule, timed (first call compiles)
    jaxbox.fit.clear_compile_cache()
    t = time.perf_counter()
    d7 = design.plan(model, prior, sigma=SIGMA, days=7, power=POWER, comfort=COMFORT)
    first = time.perf_counter() - t
    t = time.perf_counter()
    d7 = design.plan(model, prior, sigma=SIGMA, days=7, power=POWER, comfort=COMFORT)
    again = time.perf_counter() - t
    print(f"7-day design: {first:.1f} s first, {again:.1f} s again", flush=True)
    days_design, rep_design, trail = days_needed_design(model, prior, target)
    print(f"designed: {days_design} days", flush=True)
    days_base, reps_base = days_needed_baselines(model, prior, target)
    print(f"baselines: {days_base}", flush=True)
    ctx7 = d7.context
    design_loss = d7.reports["designed"]["loss"]["hlc"]
    plain = plain_design(ctx7, plain_budget, design_loss) if plain_budget > 0 else None
    if plain:
        print(f"plain: {plain}", flush=True)
    return {
        "model": model,
        "prior": prior,
        "reference": {k: v for k, v in ref.items() if k != "outputs"},
        "target_hlc_std": target,
        "design7": {
            "first_call_s": first,
            "again_s": again,
            "timing": d7.timing,
            "reports": {
                k: {kk: vv for kk, vv in v.items() if kk != "outputs"}
                for k, v in d7.reports.items()
            },
        },
        "days": {"designed": days_design, **days_base},
        "at_days": {
            "designed": None
            if rep_design is None
            else {k: v for k, v in rep_design.items() if k != "outputs"},
            **{
                k: {kk: vv for kk, vv in v.items() if kk != "outputs"} for k, v in reps_base.items()
            },
        },
        "design_trail": trail,
        "plain": plain,
    }


def _machine() -> str:
    import jax

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores (load average "
        f"{load:.1f}), {platform.platform()}, jax {jax.__version__}, scipy {scipy.__version__}"
    )


def report(results: list[dict], machine: str) -> str:
    L = []
    w = L.append
    w("## Experiment design (benchmarks/design.py)")
    w("")
    w(
        f"Written by `python benchmarks/design.py` on "
        f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC; machine: {machine}; "
        "raw numbers in `benchmarks/design.json`."
    )
    w("")
    w(
        f"Parameters fitted on twin house N2 (identification half, hourly); noise σ = {SIGMA} K; "
        f"bundled weather from 2013-08-21; hourly schedules; heater {POWER[0]:g}–{POWER[1]:g} W. "
        "Predicted standard deviations from the Fisher information (all parameters estimated, "
        "initial states included; the building held at 25 °C before the start). The designed "
        "schedule is c-optimal for the HLC under the comfort band 15–35 °C and is re-planned for "
        "each horizon; PRBS and ROLBS switch 0/3 kW (PRBS clock: the best for the HLC), the step "
        "holds 1.5 kW. *T range*: predicted zone temperature over the experiment that reaches "
        "the target (the baselines are not constrained)."
    )
    w("")
    w(
        "| model | HLC [W/K] | target: std of 14-day ROLBS [W/K] | design | days needed | "
        "HLC std then [W/K] | T range [°C] |"
    )
    w("|---|---:|---:|---|---:|---:|---|")
    for r in results:
        for k in ("designed", "prbs", "rolbs", "step"):
            days = r["days"][k]
            rep = r["at_days"].get(k)
            w(
                f"| {r['model']} | {r['reference']['hlc']:.2f} | {r['target_hlc_std']:.4f} | {k} | "
                f"{'> ' + str(MAX_DESIGN_DAYS if k == 'designed' else MAX_BASELINE_DAYS) if days is None else days} | "  # noqa: E501
                f"{'' if rep is None else format(rep['hlc_std'], '.4f')} | "
                f"{'' if rep is None else format(rep['t_min'], '.1f') + '–' + format(rep['t_max'], '.1f')} |"  # noqa: E501
            )
    w("")
    w("### Designing a 7-day hourly schedule")
    w("")
    w(
        "| model | first call [s] (compile [s]) | again [s] | plain scipy, FD gradients | "
        "plain: best criterion / designed | ratio (time to the designed criterion) |"
    )
    w("|---|---:|---:|---|---:|---:|")
    for r in results:
        d = r["design7"]
        pl = r["plain"]
        design_loss = d["reports"]["designed"]["loss"]["hlc"]
        if pl is None:
            w(
                f"| {r['model']} | {d['first_call_s']:.1f} ({d['timing']['compile_s']:.1f}) | "
                f"{d['again_s']:.1f} | not run | | |"
            )
            continue
        reached = pl["time_to_design_loss_s"]
        ratio = (
            f"{reached / d['again_s']:.0f}× (again), {reached / d['first_call_s']:.0f}× (first)"
            if reached is not None
            else f"> {pl['seconds'] / d['again_s']:.0f}× (again), > "
            f"{pl['seconds'] / d['first_call_s']:.0f}× (first): not reached"
        )
        w(
            f"| {r['model']} | {d['first_call_s']:.1f} ({d['timing']['compile_s']:.1f}) | "
            f"{d['again_s']:.1f} | {pl['seconds']:.0f} s, {pl['evaluations']} evaluations"
            f"{'' if pl['finished'] else ' (budget)'} | "
            f"var ratio {np.exp(pl['best_loss'] - design_loss):.2f} | {ratio} |"
        )
    w("")
    w("Predicted standard deviations of the 7-day designs and their baselines (equal energy):")
    w("")
    for r in results:
        reps = r["design7"]["reports"]
        names = list(reps)
        w(f"**{r['model']}**")
        w("")
        w("| | " + " | ".join(names) + " |")
        w("|---|" + "---:|" * len(names))
        for p in reps["designed"]["std"]:
            w(f"| {p} | " + " | ".join(f"{reps[n]['std'][p]:.3g}" for n in names) + " |")
        w("| HLC [W/K] | " + " | ".join(f"{reps[n]['hlc_std']:.3g}" for n in names) + " |")
        w("| energy [kWh] | " + " | ".join(f"{reps[n]['energy_kwh']:.0f}" for n in names) + " |")
        w(
            "| T range [°C] | "
            + " | ".join(f"{reps[n]['t_min']:.1f}–{reps[n]['t_max']:.1f}" for n in names)
            + " |"
        )
        w("")
    w(
        "Targets: the designed experiment reaches the 14-day ROLBS's HLC precision in ≤ 7 days "
        "within 15–35 °C and 3 kW; designing a 7-day hourly schedule takes ≤ 60 s on 2 cores."
    )
    met = all(r["days"]["designed"] is not None and r["days"]["designed"] <= 7 for r in results)
    fast = all(r["design7"]["first_call_s"] <= 60 for r in results)
    w(f"Met here: days {'yes' if met else 'no'}; time {'yes' if fast else 'no'}.")
    w("")
    return "\n".join(L) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", default="ZonWal,ZonWalIntInf")
    ap.add_argument("--plain-budget", type=float, default=300.0, help="seconds per model")
    ap.add_argument("--out", default=str(HERE / "DESIGN.md"))
    args = ap.parse_args(argv)
    machine = _machine()
    results = [measure(m, args.plain_budget) for m in args.models.split(",")]
    (HERE / "design.json").write_text(json.dumps(results, indent=1, default=float))
    Path(args.out).write_text(report(results, machine))
    print(Path(args.out).read_text())


if __name__ == "__main__":
    main()
