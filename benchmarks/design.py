"""Experiment design: how many days does each heating sequence need to pin down the HLC?

For ``ZonWal`` and ``ZonWalIntInf`` with the parameters fitted on the bundled twin-house data
(house N2, identification half, hourly) and output noise σ = 0.05 K, on the bundled weather from
2013-08-21:

1. the references: the predicted standard deviation of the heat-loss coefficient (HLC) from a
   14-day ROLBS switching between 0 and 500 W (the levels of the twin-house experiment) and
   between 0 and 3 kW (the design's limit);
2. the days each design needs to reach each: the designed schedule (``jaxbox.design.plan``,
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


#: start temperatures (the building held there before the experiment), as ``plan`` tries them
STARTS = tuple(float(t) for t in np.linspace(COMFORT[0] + 1.0, COMFORT[1] - 1.0, 5))


def context(model, prior, days, start):
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
        start_temperature=start,
    )[2]


def baselines(model, prior, days, power=POWER):
    """PRBS, ROLBS at 0/3 kW and the step at 1.5 kW over ``days``: their predictions, each
    from its best start temperature (the same choice the design gets)."""
    best = {}
    for start in STARTS:
        ctx = context(model, prior, days, start)
        s = design.baseline_schedules(ctx, *power, None, criterion="hlc")
        for k, v in s.items():
            rep = ctx.report(v)
            rep["start_temperature"] = start
            if k not in best or rep["hlc_std"] < best[k]["hlc_std"]:
                best[k] = rep
    return best


def _strip(rep):
    return None if rep is None else {k: v for k, v in rep.items() if k != "outputs"}


def days_needed(trail: list, target: float):
    """The first (days, report) of a trail whose HLC std reaches ``target``, or (None, None)."""
    return next(((d, r) for d, r in trail if r["hlc_std"] <= target), (None, None))


def baseline_trails(model, prior, target):
    """PRBS, ROLBS and step predictions for 1, 2, … days until each reaches ``target``."""
    trails = {k: [] for k in ("prbs", "rolbs", "step")}
    for days in range(1, MAX_BASELINE_DAYS + 1):
        for k, rep in baselines(model, prior, days).items():
            trails[k].append((days, _strip(rep)))
        if all(days_needed(t, target)[0] is not None for t in trails.values()):
            break
    return trails


def design_trail(model, prior, target):
    """The designed schedule re-planned for 1, 2, … days until it reaches ``target``."""
    trail = []
    for days in range(1, MAX_DESIGN_DAYS + 1):
        d = design.plan(
            model, prior, sigma=SIGMA, days=days, power=POWER, comfort=COMFORT, criterion="hlc"
        )
        rep = dict(d.reports["designed"], start_temperature=d.settings["start_temperature"])
        trail.append((days, _strip(rep)))
        print(f"  designed {days} d: HLC std {rep['hlc_std']:.4f}", flush=True)
        if rep["hlc_std"] <= target:
            break
    return trail


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
    refs = {
        "ROLBS 0/500 W (the twin-house levels)": baselines(
            model, prior, REFERENCE_DAYS, (0.0, 500.0)
        )["rolbs"],
        "ROLBS 0/3 kW": baselines(model, prior, REFERENCE_DAYS)["rolbs"],
    }
    for k, r in refs.items():
        print(f"14-day {k}: HLC {r['hlc']:.2f} ± {r['hlc_std']:.4f} W/K", flush=True)
    # the design of a 7-day hourly schedule, timed (first call compiles)
    jaxbox.fit.clear_compile_cache()
    t = time.perf_counter()
    d7 = design.plan(model, prior, sigma=SIGMA, days=7, power=POWER, comfort=COMFORT)
    first = time.perf_counter() - t
    first_timing = dict(d7.timing)
    t = time.perf_counter()
    d7 = design.plan(model, prior, sigma=SIGMA, days=7, power=POWER, comfort=COMFORT)
    again = time.perf_counter() - t
    print(f"7-day design: {first:.1f} s first, {again:.1f} s again", flush=True)
    hardest = min(r["hlc_std"] for r in refs.values())
    trails = {"designed": design_trail(model, prior, hardest)}
    trails.update(baseline_trails(model, prior, hardest))
    ctx7 = d7.context
    design_loss = d7.reports["designed"]["loss"]["hlc"]
    plain = plain_design(ctx7, plain_budget, design_loss) if plain_budget > 0 else None
    if plain:
        print(f"plain: {plain}", flush=True)
    needed = {}
    for k, r in refs.items():
        needed[k] = {}
        for name, trail in trails.items():
            days, rep = days_needed(trail, r["hlc_std"])
            needed[k][name] = {"days": days, "report": rep}
    return {
        "model": model,
        "prior": prior,
        "references": {k: _strip(r) for k, r in refs.items()},
        "needed": needed,
        "design7": {
            "first_call_s": first,
            "again_s": again,
            "timing_first": first_timing,
            "timing_again": d7.timing,
            "start_temperature": d7.settings["start_temperature"],
            "reports": {k: _strip(v) for k, v in d7.reports.items()},
        },
        "trails": trails,
        "plain": plain,
    }


def _machine() -> str:
    import jax

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores (load average "
        f"{load:.1f}), {platform.platform()}, jax {jax.__version__}, scipy {scipy.__version__}"
    )


def report(results: list[dict], machine: str, written: str) -> str:
    L = []
    w = L.append
    w("## Experiment design (benchmarks/design.py)")
    w("")
    w(
        f"Written by `python benchmarks/design.py` on {written}; machine: {machine}; "
        "raw numbers in `benchmarks/design.json`."
    )
    w("")
    w(
        f"Parameters fitted on twin house N2 (identification half, hourly); noise σ = {SIGMA} K; "
        f"bundled weather from 2013-08-21; hourly schedules; heater {POWER[0]:g}–{POWER[1]:g} W. "
        "Predicted standard deviations from the Fisher information (all parameters estimated, "
        "initial states included). Every schedule starts from the building held at the best of "
        f"{', '.join(f'{t:g}' for t in STARTS)} °C (its steady state). The designed "
        "schedule is c-optimal for the HLC under the comfort band 15–35 °C and is re-planned for "
        "each horizon; PRBS and ROLBS switch 0/3 kW (PRBS clock: the best for the HLC), the step "
        "holds 1.5 kW. *T range*: predicted zone temperature over the experiment that reaches "
        "the target (the baselines are not constrained)."
    )
    w("")
    w(
        "| model | reference (14 days) | its HLC std [W/K] | design | days needed | "
        "HLC std then [W/K] | start [°C] | T range [°C] |"
    )
    w("|---|---|---:|---|---:|---:|---:|---|")
    for r in results:
        for ref, ref_rep in r["references"].items():
            for k, item in r["needed"][ref].items():
                days, rep = item["days"], item["report"]
                cap = MAX_DESIGN_DAYS if k == "designed" else MAX_BASELINE_DAYS
                w(
                    f"| {r['model']} | {ref} | {ref_rep['hlc_std']:.4f} | {k} | "
                    f"{'> ' + str(cap) if days is None else days} | "
                    f"{'' if rep is None else format(rep['hlc_std'], '.4f')} | "
                    f"{'' if rep is None else format(rep['start_temperature'], 'g')} | "
                    f"{'' if rep is None else format(rep['t_min'], '.1f')}–"
                    f"{'' if rep is None else format(rep['t_max'], '.1f')} |"
                )
    w("")
    w("### Designing a 7-day hourly schedule")
    w("")
    w(
        "jaxbox: `plan(days=7)` end to end — five start temperatures, each a 4-start BFGS "
        "(gradients by autodiff through the simulator and its sensitivities), baselines and "
        "reports; *first call* includes compiling (first call − again ≈ compile time). Plain: "
        "scipy L-BFGS-B on the same criterion and comfort penalty at the design's start "
        "temperature only, finite-difference gradients, a numpy simulation and "
        "finite-difference sensitivities; it runs until L-BFGS-B stops (or the budget ends)."
    )
    w("")
    w(
        "| model | jaxbox first call [s] | jaxbox again [s] | plain scipy [s] | "
        "plain's HLC variance / designed | time ratio plain / jaxbox (again; first call) |"
    )
    w("|---|---:|---:|---:|---:|---:|")
    for r in results:
        d = r["design7"]
        pl = r["plain"]
        design_loss = d["reports"]["designed"]["loss"]["hlc"]
        if pl is None:
            w(f"| {r['model']} | {d['first_call_s']:.1f} | {d['again_s']:.1f} | not run | | |")
            continue
        w(
            f"| {r['model']} | {d['first_call_s']:.1f} | {d['again_s']:.1f} | "
            f"{pl['seconds']:.0f} ({pl['evaluations']} evaluations"
            f"{'' if pl['finished'] else ', budget'}) | "
            f"{np.exp(pl['best_loss'] - design_loss):.2f} | "
            f"{pl['seconds'] / d['again_s']:.1f}×; {pl['seconds'] / d['first_call_s']:.1f}× |"
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
    met = {
        ref: all(
            r["needed"][ref]["designed"]["days"] is not None
            and r["needed"][ref]["designed"]["days"] <= 7
            for r in results
        )
        for ref in results[0]["references"]
    }
    days_text = "; ".join(f"against the {k}: {'yes' if v else 'no'}" for k, v in met.items())
    fast = all(r["design7"]["first_call_s"] <= 60 for r in results)
    w(f"Met here — ≤ 7 days {days_text}; design time {'yes' if fast else 'no'}.")
    w("")
    return "\n".join(L) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", default="ZonWal,ZonWalIntInf")
    ap.add_argument("--plain-budget", type=float, default=300.0, help="seconds per model")
    ap.add_argument("--out", default=str(HERE / "DESIGN.md"))
    ap.add_argument(
        "--report-only", action="store_true", help="rewrite the report from design.json"
    )
    args = ap.parse_args(argv)
    if args.report_only:
        doc = json.loads((HERE / "design.json").read_text())
        Path(args.out).write_text(report(doc["results"], doc["machine"], doc["written"]))
        print(Path(args.out).read_text())
        return
    machine = _machine()
    results = [measure(m, args.plain_budget) for m in args.models.split(",")]
    written = f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC"
    doc = {"machine": machine, "written": written, "results": results}
    (HERE / "design.json").write_text(json.dumps(doc, indent=1, default=float))
    Path(args.out).write_text(report(results, machine, written))
    print(Path(args.out).read_text())


if __name__ == "__main__":
    main()
