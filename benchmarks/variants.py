"""The default search on the twin houses prepared in several reasonable ways.

The measured 10-minute tables of IEA EBC Annex 58 experiment 1 (``../shared/data/
twinhouse_exp1``) can be prepared as :data:`_buildings.VARIANTS`: the zone as the mean of the
six heated rooms with their total heating, or the living room alone with its own heater and its
five heated neighbours' mean temperature as a measured boundary, with or without the
supply-air and cellar columns, at 10 minutes or hourly. For each variant of each house the
default ``select`` (the structure search, the data in halves) is run, and the benchmark records
the accepted structure, its validation RMSE, whether it is valid, its heat-loss coefficient
(HLC: the steady-state heat flow per kelvin seen by the heating) and the search time. Targets:
N2 ≤ 0.30 K and O5 ≤ 0.45 K validation RMSE, valid; for one zone definition, the HLC of a
house's variants within ±10 % of each other.

Usage::

    python benchmarks/variants.py [--houses N2,O5] [--zones mean,living] [--steps 1h,10min]
        [--out benchmarks/VARIANTS.md] [--json benchmarks/variants.json]
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _buildings import VARIANTS, twinhouse_variant  # noqa: E402

#: validation RMSE targets [K] per house
TARGETS = {"N2": 0.30, "O5": 0.45}


def run(house: str, zone: str, columns: str, step: str, starts: int) -> dict:
    import jaxbox
    from jaxbox.data import DataWarning
    from jaxbox.validate import heat_loss_coefficients, hlc_interval

    row = {"house": house, "zone": zone, "columns": columns, "step": step}
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DataWarning)
            s = jaxbox.structure_search(
                twinhouse_variant(house, zone, columns, step), starts=starts
            )
    except Exception as err:  # noqa: BLE001 - a benchmark row records any failure
        row["error"] = f"{type(err).__name__}: {err}"[:300]
        return row
    row["seconds"] = time.perf_counter() - t0
    row["candidates"] = len(s.tree)
    if s.case is None:
        row["accepted"] = None
        return row
    case = s.case
    ua = heat_loss_coefficients(case.model, case.result.params)
    rmse = case.validation.rmse_cross or case.validation.rmse_auto
    row.update(
        accepted=case.model.name,
        case=case.name,
        rmse_valid=float(np.mean(list(rmse.values()))),
        valid=bool(case.is_valid),
        hlc=float(next(iter(ua.values()))[0]) if ua else None,
    )
    try:  # the outdoor-referenced HLC with its interval (what `select` reports)
        out = hlc_interval(s)
        out = None if out is None else out.outdoor
    except (ValueError, np.linalg.LinAlgError):
        out = None
    if out is not None:
        row.update(
            hlc_outdoor=out.value,
            hlc_outdoor_ci95=[float(v) for v in out.ci95],
            follow={b: round(v["alpha"], 3) for b, v in out.follow.items()},
        )
    return row


def markdown(doc: dict) -> str:
    lines = [
        "## The default search on twin-house variants",
        "",
        f"Written by `python benchmarks/variants.py` on {doc['date']}; {doc['machine']}; raw "
        "numbers in `benchmarks/variants.json`. The default `select` (structure search, data in "
        "halves) on each preparation of the measured 10-minute tables. Targets: validation RMSE "
        "N2 ≤ 0.30 K, O5 ≤ 0.45 K, valid; for one zone definition the HLC of a house's variants "
        "within ±10 % of each other.",
        "",
        "Zones: `mean`, the mean of the six heated rooms with their total heating (as shipped); "
        "`living`, the living room's air (the mean of its three heights) with its own heater as "
        "`Q_hea` and the mean of the five other heated rooms as a measured neighbour `T_adj` "
        "(token `Adj`). Until 2026-11-29 the living-room rows used the living room's "
        "temperature with the whole house's heating and no neighbours, which puts the heat of "
        "six rooms into one: 0.49 K on N2, 0.65–0.91 K on O5.",
        "",
        "| house | zone | columns | step | measured | accepted | valid | RMSE valid [K] | target "
        "| HLC held [W/K] | HLC outdoor [W/K] | search [s] |",
        "|---|---|---|---|---|---|---|---:|---|---:|---:|---:|",
    ]
    for r in doc["rows"]:
        if "error" in r:
            lines.append(
                f"| {r['house']} | {r['zone']} | {r['columns']} | {r['step']} | "
                f"{r.get('date', doc['date'])} | {r['error']} | | | | | | |"
            )
            continue
        ok = r.get("rmse_valid") is not None and r["rmse_valid"] <= TARGETS[r["house"]]
        rmse = "–" if r.get("rmse_valid") is None else f"{r['rmse_valid']:.3f}"
        hlc = "–" if r.get("hlc") is None else f"{r['hlc']:.1f}"
        out = "–"
        if r.get("hlc_outdoor") is not None:
            lo, hi = r["hlc_outdoor_ci95"]
            out = f"{r['hlc_outdoor']:.1f} [{lo:.0f}, {hi:.0f}]"
        lines.append(
            f"| {r['house']} | {r['zone']} | {r['columns']} | {r['step']} | "
            f"{r.get('date', doc['date'])} | {r.get('accepted') or 'no valid model'} | "
            f"{'yes' if r.get('valid') else 'no'} | "
            f"{rmse} | {'met' if ok and r.get('valid') else 'missed'} | {hlc} | {out} | "
            f"{r['seconds']:.0f} |"
        )
    lines += [
        "",
        "*HLC held*: the heating per kelvin of steady zone rise with every temperature input "
        "held (the zone's conductance to all its measured surroundings: it depends on which "
        "the preparation carries and the search takes). *HLC outdoor*: per kelvin of "
        "zone–outdoor difference, each measured boundary as it behaves in the data (its daily "
        "means' slope on the zone–outdoor difference; `jaxbox.validate.outdoor_hlc`), with its "
        "95 % interval: the quantity an analyst compares across preparations.",
        "",
        "HLC spread per house and zone definition (half the range over its middle; target ±10 %):",
        "",
    ]
    for key, label in (("hlc", "held"), ("hlc_outdoor", "outdoor")):
        groups: dict[tuple, list[float]] = {}
        for r in doc["rows"]:
            if r.get(key):
                groups.setdefault((r["house"], r["zone"]), []).append(r[key])
        for (house, zone), v in sorted(groups.items()):
            mid = 0.5 * (max(v) + min(v))
            spread = 100 * (max(v) - min(v)) / (2 * mid)
            lines.append(
                f"- {house}, {zone}, HLC {label}: {len(v)} variants, {min(v):.1f}–{max(v):.1f} "
                f"W/K, ±{spread:.1f} % of the mid-range ({'met' if spread <= 10 else 'missed'})"
            )
    lines += [
        "",
        "Search times are wall-clock seconds on a shared 2-core machine, where another benchmark "
        "often ran beside this one: compare them within a run, not with quiet-machine timings "
        "(`benchmarks/RESULTS.md`).",
    ]
    for note in doc.get("notes", ()):
        lines += ["", str(note)]
    return "\n".join(lines).rstrip("\n") + "\n"


def _write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def main(argv=None) -> int:
    import jax

    import jaxbox

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--houses", default="N2,O5")
    p.add_argument("--steps", default="1h,10min")
    p.add_argument("--zones", default="mean,living")
    p.add_argument("--starts", type=int, default=8)
    p.add_argument("--out", type=Path, default=HERE / "VARIANTS.md")
    p.add_argument("--json", type=Path, default=HERE / "variants.json")
    args = p.parse_args(argv)
    jaxbox.enable_x64()
    steps = args.steps.split(",")
    doc = {
        "date": datetime.date.today().isoformat(),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, jax {jax.__version__}",
        "rows": [],
    }
    key = ("house", "zone", "columns", "step")
    if args.json.exists():  # a rerun of some variants keeps the others' rows and the notes
        before = json.loads(args.json.read_text())
        doc["rows"] = before["rows"]
        doc["notes"] = before.get("notes", [])
    for house in args.houses.split(","):
        for zone, columns, step in VARIANTS:
            if step not in steps or zone not in args.zones.split(","):
                continue
            row = {**run(house, zone, columns, step, args.starts), "date": doc["date"]}
            print(json.dumps(row), flush=True)
            doc["rows"] = [
                r for r in doc["rows"] if tuple(r[k] for k in key) != tuple(row[k] for k in key)
            ]
            doc["rows"].append(row)
            doc["rows"].sort(key=lambda r: (r["house"], r["zone"], r["columns"], r["step"]))
            _write(args.json, json.dumps(doc, indent=1))
            _write(args.out, markdown(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
