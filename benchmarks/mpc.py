"""Model-predictive control in closed loop on zoo buildings: does a model judged by its fit
also control the building well?

For each zoo building (one zone, hourly, 28 days of real weather from the twin-house site, a
PRBS heating sequence in the data), the model of its true structure is identified from the first
14 days, by maximum likelihood (`ml`) and by output error (`oe`, the noise of its stochastic form
estimated from its residuals). Over the next 13 days the true building is the plant (exact
discretisation of its true parameters, with unmeasured internal gains and white sensor noise),
heated by:

* the linear MPC (`jaxbox.control.LinearMPC`, 24-h horizon, the Kalman state at every
  hour) on the identified model;
* the same MPC on the true model (its noise estimated from the residuals of the same
  identification data);
* a PI thermostat on the measured temperature, its setpoint the comfort band's lower edge
  + 0.5 K, switched to the day value 2 h early (a preheat); one tuning for every building
  (`kp = q_max / 2` per K, integral time 2 h, anti-windup), not tuned per building.

Price: 0.35 per kWh from 7 to 10 h and from 17 to 21 h, 0.12 otherwise; comfort band: 20 °C from
6 to 22 h, 17 °C at night (no upper edge: the house cannot cool); discomfort costs 1 per K·h
below it. Reported per building: energy cost, K·h of discomfort, and the model cost = the
closed-loop objective (energy cost + discomfort) with the identified model ÷ with the true one.

    python benchmarks/mpc.py [--buildings 6] [--seed 38] [--out benchmarks/MPC.md]
    python benchmarks/mpc.py --markdown   # MPC.md again from benchmarks/mpc.json

Writes ``benchmarks/MPC.md`` (and ``benchmarks/mpc.json``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

import jaxbox  # noqa: E402

jaxbox.enable_x64()

from jaxbox.control import (  # noqa: E402
    KalmanTracker,
    LinearMPC,
    MPCController,
    PIController,
    closed_loop,
    comfort_band,
)
from jaxbox.control._check import _price  # noqa: E402  (the verdict's closed loop: same protocol)
from jaxbox.control._check import _true_state as _plant_state  # noqa: E402
from jaxbox.datasets import make_zoo  # noqa: E402
from jaxbox.forecast import StochasticForm, noise_from_residuals, stochastic_form  # noqa: E402
from jaxbox.stochastic import noise_names  # noqa: E402

HORIZON = 24  # samples (hours)
COMFORT = 1.0  # price of one K·h below the band


def _one(b, starts: int, seed: int) -> dict:
    model = jaxbox.get_model(b.structure)
    n = len(b.data)
    n_id = (n - 1) // 2
    ident = b.data.slice(None, b.data.index[n_id])
    u = b.data.array(list(model.inputs))
    index = b.data.index[n_id:]
    uu = u[n_id:]
    steps = len(index) - 1 - HORIZON
    price = _price(index)
    lower = comfort_band(index)
    hlc = float(b.kpis["hlc"])
    q_max = 35.0 * hlc
    rng = np.random.default_rng([seed, 1])
    hours = index.hour
    occupied = ((hours >= 7) & (hours < 9)) | ((hours >= 17) & (hours < 23))
    # unmeasured gains: 1 K worth of loss when occupied, and noise of 0.3 K worth
    gains = hlc * (1.0 * occupied + 0.3 * rng.standard_normal(len(index)))[:steps]
    zero = {k: 0.0 for k in noise_names(model)}
    plant = StochasticForm(
        model, {**b.params, **zero}, "foh", (0.0,) * model.n_states, "ml", "plant", b.data.step
    )
    x0 = _plant_state(plant, u, n_id)
    forms, fit_s = {}, {}
    for method in ("ml", "oe"):
        t0 = time.perf_counter()
        fit = jaxbox.fit_model(model, ident, method=method, starts=starts)
        forms[method] = stochastic_form(fit)
        fit_s[method] = time.perf_counter() - t0
    forms["true"] = noise_from_residuals(model, b.params, ident)

    def mpc(form):
        run = form.filter(ident)
        m = LinearMPC.from_form(form, horizon=HORIZON, q_max=q_max, comfort=COMFORT)
        return MPCController(
            m, KalmanTracker(m.system, m.heater, run.m[-1], run.P[-1]), uu, price, lower
        )

    preheat = comfort_band(index + np.timedelta64(2, "h")) + 0.5
    runs = {}
    for name, ctl in (
        ("ml", mpc(forms["ml"])),
        ("oe", mpc(forms["oe"])),
        ("true", mpc(forms["true"])),
        ("pi", PIController(preheat, kp=q_max / 2, ti=2 * 3600.0, q_max=q_max, dt=b.data.step)),
    ):
        t0 = time.perf_counter()
        r = closed_loop(
            plant,
            x0,
            uu,
            index,
            ctl,
            steps=steps,
            price=price,
            lower=lower,
            comfort=COMFORT,
            gains=gains,
            noise_sd=b.noise,
            seed=seed,
        )
        runs[name] = {
            "energy_kwh": r.energy_kwh,
            "cost": r.cost,
            "discomfort_kh": r.discomfort_kh,
            "discomfort_kh_per_day": r.discomfort_kh / (steps * b.data.step / 86400.0),
            "objective": r.objective,
            "loop_s": time.perf_counter() - t0,
        }
    row = {
        "building": b.name,
        "structure": b.structure,
        "hlc": hlc,
        "noise": b.noise,
        "days": steps * b.data.step / 86400.0,
        "fit_s": fit_s,
        "runs": runs,
        "model_cost": {m: runs[m]["objective"] / runs["true"]["objective"] for m in ("ml", "oe")},
    }
    print(
        f"{b.name} {b.structure:<22} model cost ml {row['model_cost']['ml']:.3f} "
        f"oe {row['model_cost']['oe']:.3f}; cost ml {runs['ml']['cost']:.2f} true "
        f"{runs['true']['cost']:.2f} pi {runs['pi']['cost']:.2f}; K·h ml "
        f"{runs['ml']['discomfort_kh']:.2f} pi {runs['pi']['discomfort_kh']:.2f}",
        flush=True,
    )
    return row


def _markdown(rows: list[dict], args, total_s: float) -> str:
    lines = [
        "# MPC in closed loop on zoo buildings",
        "",
        "Generated by `python benchmarks/mpc.py"
        + (f" --buildings {args.buildings}" if args.buildings != 6 else "")
        + f"` ({platform.machine()}, {os.cpu_count()} CPUs, {total_s:.0f} s in all).",
        "",
        (__doc__ or "").split("\n\n", 1)[1].split("\n    python")[0].strip(),
        "",
        "Scope: a handful of one-zone buildings at an hourly step, a perfect weather forecast "
        "(the measured weather), one price profile; the plant has the structure the model is "
        "fitted with (the model error comes from the estimation alone). The closed loop of the "
        "true model is the reference, not an optimum: both use the same horizon and the same "
        "Kalman filter, so a model cost below 1 is possible.",
        "",
        "| building | structure | days | energy cost ml / oe / true / PI "
        "| K·h below band ml / oe / true / PI | model cost ml | model cost oe |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        R = r["runs"]
        cost = " / ".join(f"{R[k]['cost']:.2f}" for k in ("ml", "oe", "true", "pi"))
        kh = " / ".join(f"{R[k]['discomfort_kh']:.2f}" for k in ("ml", "oe", "true", "pi"))
        lines.append(
            f"| {r['building']} | {r['structure']} | {r['days']:.1f} | {cost} | {kh} | "
            f"{r['model_cost']['ml']:.3f} | {r['model_cost']['oe']:.3f} |"
        )
    n = len(rows)

    def share(test) -> str:
        return f"{sum(bool(test(r)) for r in rows)} of {n}"

    lines += [
        "",
        "## Against the targets",
        "",
        f"* comfort (≤ 1 K·h per day below the band) held by the identified model's MPC: ml "
        f"{share(lambda r: r['runs']['ml']['discomfort_kh_per_day'] <= 1.0)}, oe "
        f"{share(lambda r: r['runs']['oe']['discomfort_kh_per_day'] <= 1.0)} buildings "
        f"(PI thermostat: {share(lambda r: r['runs']['pi']['discomfort_kh_per_day'] <= 1.0)});",
        f"* model cost ≤ 1.05: ml {share(lambda r: r['model_cost']['ml'] <= 1.05)}, oe "
        f"{share(lambda r: r['model_cost']['oe'] <= 1.05)} buildings (median ml "
        f"{np.median([r['model_cost']['ml'] for r in rows]):.3f}, oe "
        f"{np.median([r['model_cost']['oe'] for r in rows]):.3f}; worst ml "
        f"{max(r['model_cost']['ml'] for r in rows):.3f}, oe "
        f"{max(r['model_cost']['oe'] for r in rows):.3f});",
        f"* energy cost below the thermostat's: ml "
        f"{share(lambda r: r['runs']['ml']['cost'] < r['runs']['pi']['cost'])}, oe "
        f"{share(lambda r: r['runs']['oe']['cost'] < r['runs']['pi']['cost'])} buildings "
        f"(mean saving ml "
        f"{np.mean([1 - r['runs']['ml']['cost'] / r['runs']['pi']['cost'] for r in rows]):.0%}).",
        "",
        "Timing: identification "
        f"{np.mean([r['fit_s']['ml'] for r in rows]):.0f} s (ml, {args.starts} starts) and "
        f"{np.mean([r['fit_s']['oe'] for r in rows]):.0f} s (oe) per building; a closed loop of "
        f"{rows[0]['days']:.0f} days (one linear program per hour) "
        f"{np.mean([r['runs']['ml']['loop_s'] for r in rows]):.1f} s.",
        "",
    ]
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--buildings", type=int, default=6)
    ap.add_argument("--seed", type=int, default=38)
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--out", default=str(HERE / "MPC.md"))
    ap.add_argument("--markdown", action="store_true", help="only rewrite MPC.md from mpc.json")
    args = ap.parse_args(argv)
    out = Path(args.out)
    if args.markdown:
        doc = json.loads(out.with_name("mpc.json").read_text())
        out.write_text(_markdown(doc["rows"], args, doc["total_s"]))
        print(f"wrote {out}")
        return
    t0 = time.perf_counter()
    zoo = make_zoo(
        args.buildings,
        seed=args.seed,
        zones=(1,),
        step="60min",
        days=28,
        heating="prbs",
        gaps=0.0,
        offset=0.0,
        max_states=3,
        prefix="m",
    )
    rows = [_one(b, args.starts, args.seed) for b in zoo]
    total = time.perf_counter() - t0
    out.write_text(_markdown(rows, args, total))
    doc = {"total_s": total, "rows": rows}
    out.with_name("mpc.json").write_text(json.dumps(doc, indent=1, default=float))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
