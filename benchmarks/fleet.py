"""Fleets on Dask: buildings per second, scaling, HLC interval coverage, against a scipy loop.

Synthetic buildings (:func:`jaxbox.datasets.make_fleet`: ZonWal with random plausible
parameters, one month of hourly twin-house weather, 0.1 K noise, known true HLC) run through
:func:`jaxbox.fleet.run_fleet` with the model ``ZonWal`` and 16 starts: fits, validation,
KPIs, the fit JSON per building and ``results.parquet``, on a LocalCluster of 1 and 2 worker
processes. Measured in the same run: a plain scipy loop (``scipy.optimize.least_squares``, the
same model simulated exactly with numpy, the same 16 starts and bounds) on a sample of the
buildings, one building after the other.

    python benchmarks/fleet.py [--sizes 100,1000] [--workers 1,2] [--scipy 8] [--out FILE]
    python benchmarks/fleet.py --gpu-batch [--batches 64,256,1024,4096]

``--gpu-batch`` measures the batched fits alone (no Dask): buildings × 16 starts in one
compiled :func:`jaxbox.fit_batch` call per size, on whatever device JAX uses (a GPU when there
is one): the throughput curve goes to ``benchmarks/fleet_gpu.json`` and joins the report of
an earlier fleet run. Writes ``benchmarks/FLEET.md`` (or ``--out``) and ``benchmarks/fleet.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

MODEL = "ZonWal"
STARTS = 16
DAYS = 31


def _fleet(n: int, folder: Path):
    from jaxbox.datasets import make_fleet

    t0 = time.perf_counter()
    _, truth = make_fleet(n, folder, model=MODEL, days=DAYS, seed=1)
    return truth, time.perf_counter() - t0


def _run(source: Path, out: Path, workers: int, cache: Path) -> dict:
    """One fleet run on a fresh LocalCluster; the steady rate from the partitions' finishes."""
    from jaxbox.fleet import load_config, read_results, run_fleet

    os.environ["JAXBOX_CACHE"] = "1"  # the workers share compiled solves through the cache
    os.environ["JAXBOX_CACHE_DIR"] = str(cache)
    stamps: list[tuple[float, int]] = []
    cfg = load_config(models=MODEL, starts=STARTS, partition_size=16)
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    summary = run_fleet(
        source,
        out,
        cfg,
        workers=workers,
        progress=False,
        on_partition=lambda i, rows: stamps.append((time.perf_counter(), len(rows))),
    )
    wall = time.perf_counter() - t0
    rows = read_results(out)
    # steady state: from the end of the first partition of every worker to the last one
    skip = min(workers, len(stamps) - 1)
    done = sum(n for _, n in stamps[skip:])
    span = stamps[-1][0] - stamps[skip - 1][0] if skip >= 1 else wall
    return {
        "buildings": summary.processed,
        "workers": workers,
        "wall_s": wall,
        "per_s": summary.processed / wall,
        "steady_per_s": done / span if span > 0 else float("nan"),
        "counts": summary.counts,
        "load": load,
        "rows": rows,
    }


def _coverage(rows, truth) -> dict:
    ok = rows[rows["status"] == "ok"].set_index("building")
    t = truth.loc[ok.index, "hlc"]
    inside = (ok["hlc_lo"] <= t) & (t <= ok["hlc_hi"])
    allrows = rows.set_index("building")
    has = allrows["hlc_lo"].notna()
    t_all = truth.loc[allrows.index[has], "hlc"]
    inside_all = (allrows.loc[has, "hlc_lo"] <= t_all) & (t_all <= allrows.loc[has, "hlc_hi"])
    rel = (ok["hlc"] - t).abs() / t
    half = (ok["hlc_hi"] - ok["hlc_lo"]) / 2 / ok["hlc"]
    return {
        "ok": int(len(ok)),
        "coverage_ok": float(inside.mean()),
        "with_interval": int(has.sum()),
        "coverage_all": float(inside_all.mean()),
        "median_rel_error": float(rel.median()),
        "median_rel_halfwidth": float(half.median()),
    }


# ---- the scipy loop ----------------------------------------------------------------------


def _scipy_fit(data, starts: np.ndarray, lower: np.ndarray, upper: np.ndarray):
    """ZonWal by scipy.optimize.least_squares (trf, bounds, 2-point Jacobian) from each start,
    simulated exactly (first-order hold, Van Loan matrix exponential) with numpy."""
    from scipy.linalg import expm
    from scipy.optimize import least_squares

    u = np.column_stack([data["T_amb"], data["Q_hea"], data["I_glo_hor"]])
    y = np.asarray(data["T_zon"], dtype=float)
    dt = float(data.step)

    def simulate(p):
        C_zon, C_wal, R_wal, gA, T_zon0, T_wal0 = p
        g = 2.0 / R_wal
        A = np.array([[-g / C_zon, g / C_zon], [g / C_wal, -2 * g / C_wal]])
        B = np.array([[0.0, 1 / C_zon, gA / C_zon], [g / C_wal, 0.0, 0.0]])
        M = np.zeros((8, 8))
        M[:2, :2], M[:2, 2:5], M[2:5, 5:8] = A * dt, B * dt, np.eye(3)
        E = expm(M)
        phi, g0, g1 = E[:2, :2], E[:2, 2:5], E[:2, 5:8]
        x = np.array([T_zon0, T_wal0])
        out = np.empty(len(y))
        for k in range(len(y)):
            out[k] = x[0]
            if k + 1 < len(y):
                x = phi @ x + g0 @ u[k] + g1 @ (u[k + 1] - u[k])
        return out

    scale = np.where(np.abs(starts[0]) > 0, np.abs(starts[0]), 1.0)
    best = None
    for s in starts:
        r = least_squares(
            lambda z: simulate(z * scale) - y,
            s / scale,
            bounds=(lower / scale, upper / scale),
            method="trf",
            x_scale="jac",
        )
        if best is None or r.cost < best.cost:
            best = r
    return best.x * scale


def _scipy_loop(folder: Path, names: list[str]) -> dict:
    import jaxbox
    from jaxbox.data import load
    from jaxbox.fit import DEFAULT_CONCENTRATION, make_problem
    from jaxbox.fit._fit import make_starts

    hlc, seconds, cpu = {}, [], []
    for name in names:
        data = load(folder / f"{name}.csv")
        ident, _ = data.split()
        t0, c0 = time.perf_counter(), time.process_time()
        problem = make_problem(jaxbox.get_model(MODEL), ident)
        starts = make_starts(problem, ident, STARTS, 0, DEFAULT_CONCENTRATION)
        lo = np.asarray(problem.transform.lower, dtype=float)
        hi = np.asarray(problem.transform.upper, dtype=float)
        p = _scipy_fit(ident, np.clip(starts, lo, hi), lo, hi)
        seconds.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        hlc[name] = 1.0 / p[list(problem.free).index("R_wal")]
    return {
        "n": len(names),
        "per_building_s": float(np.mean(seconds)),
        "cpu_per_building_s": float(np.mean(cpu)),
        "hlc": hlc,
    }


# ---- GPU batch ----------------------------------------------------------------------------


def gpu_batch(sizes: list[int], folder: Path) -> list[dict]:
    """Fits of ``size`` buildings × 16 starts in one call, per size: throughput curve."""
    import jax

    from jaxbox.data import load
    from jaxbox.fit import fit_batch

    n_max = max(sizes)
    truth, _ = _fleet(min(n_max, 1000), folder)
    names = list(truth.index)
    idents = [load(folder / f"{n}.csv").split()[0] for n in names]
    out = []
    for size in sizes:
        reqs = [
            {"model": MODEL, "data": idents[k % len(idents)], "starts": STARTS} for k in range(size)
        ]
        fit_batch(reqs)  # compile
        t0 = time.perf_counter()
        res = fit_batch(reqs)
        wall = time.perf_counter() - t0
        fits = size * STARTS
        out.append(
            {
                "buildings": size,
                "fits": fits,
                "wall_s": wall,
                "solver_s": res[0].timing["fit_s"],
                "fits_per_s": fits / res[0].timing["fit_s"],
                "buildings_per_s": size / wall,
                "device": str(jax.devices()[0]),
            }
        )
        print(out[-1], flush=True)
    return out


# ---- report -------------------------------------------------------------------------------


def _markdown(doc: dict) -> str:
    lines = [
        "## Fleets on Dask (benchmarks/fleet.py)",
        "",
        f"Written by `python benchmarks/fleet.py` on {doc['date']}; raw numbers in "
        f"`benchmarks/fleet.json`. Machine: {doc['machine']}. Synthetic buildings "
        f"(`make_fleet`: {MODEL} with random plausible parameters, {DAYS} days of hourly "
        "twin-house weather, 0.1 K noise), model "
        f"{MODEL}, {STARTS} starts, partitions of 16, identification/validation halves; each "
        "run does the fits, the validation, the KPIs, a fit JSON per building and "
        "`results.parquet`, on a fresh LocalCluster (its start and the compilations included "
        "in *wall*; *steady* counts from the end of each worker's first partition).",
        "",
        "| buildings | workers | load average | wall [s] | buildings/s (wall) "
        "| buildings/s (steady) | ok | no valid model | bad data | failed |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in doc["runs"]:
        c = r["counts"]
        later = f" ({r['date']})" if r.get("date") else ""
        lines.append(
            f"| {r['buildings']} | {r['workers']}{later} | "
            + (f"{r['load']:.1f}" if "load" in r else "–")
            + f" | {r['wall_s']:.1f} | {r['per_s']:.1f} | "
            f"{r['steady_per_s']:.1f} | {c['ok']} | {c['no_valid_model']} | {c['bad_data']} | "
            f"{c['failed']} |"
        )
    cov = doc["coverage"]
    sp = doc["scipy"]
    lines += [
        "",
        f"**HLC coverage** ({cov['n']} buildings): the 95 % interval holds the true HLC for "
        f"{100 * cov['coverage_ok']:.1f} % of the {cov['ok']} buildings with a valid model "
        f"({100 * cov['coverage_all']:.1f} % of the {cov['with_interval']} with an interval); "
        f"median error {100 * cov['median_rel_error']:.2f} %, median half-width "
        f"{100 * cov['median_rel_halfwidth']:.2f} %. Target 90–99 %.",
        "",
        f"**Against a scipy loop**: `least_squares` (trf, bounds, finite differences, numpy "
        f"simulation, the same {STARTS} starts) took {sp['per_building_s']:.2f} s per "
        f"building on one core (the fit alone, {sp['n']} buildings"
        + (f"; {sp['cpu_per_building_s']:.2f} s of CPU time" if "cpu_per_building_s" in sp else "")
        + "): "
        f"{1 / sp['per_building_s']:.2f} buildings/s. The fleet on "
        f"{doc['ratio_workers']} workers ({doc['ratio_per_s']:.1f} buildings/s steady, with "
        f"validation, KPIs and files) is **{doc['ratio']:.0f}×** the scipy loop on "
        f"{doc['ratio_workers']} cores ({doc['ratio_workers'] / sp['per_building_s']:.2f} "
        f"buildings/s); the HLCs agree to a median {100 * sp['hlc_rel_diff']:.2g} %.",
        "",
    ]
    if doc.get("gpu"):
        lines += [
            f"**Batched fits in one call** (`--gpu-batch`, device {doc['gpu'][0]['device']}):",
            "",
            "| buildings | fits (× starts) | solver [s] | fits/s | buildings/s |",
            "|---:|---:|---:|---:|---:|",
        ]
        for g in doc["gpu"]:
            lines.append(
                f"| {g['buildings']} | {g['fits']} | {g['solver_s']:.2f} | "
                f"{g['fits_per_s']:.0f} | {g['buildings_per_s']:.1f} |"
            )
        lines.append("")
    else:
        lines += ["GPU: not measured in this run (`python benchmarks/fleet.py --gpu-batch`).", ""]
    lines += [
        "The cores were shared with other jobs during these runs (load average column): the "
        "rates are those of the share the fleet got, and vary from run to run with it.",
        "",
    ]
    if doc.get("notes"):
        lines += [doc["notes"], ""]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="100,1000")
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--scipy", type=int, default=8, help="buildings fitted by the scipy loop")
    ap.add_argument("--gpu-batch", action="store_true")
    ap.add_argument("--batches", default="64,256,1024,4096")
    ap.add_argument("--out", default=str(HERE / "FLEET.md"))
    ap.add_argument("--json", default=str(HERE / "fleet.json"))
    ap.add_argument("--report-only", action="store_true", help="rewrite --out from --json")
    ap.add_argument(
        "--append",
        action="store_true",
        help="measure every --sizes × --workers run and add it to the runs of --json",
    )
    args = ap.parse_args()
    if args.report_only:
        doc = json.loads(Path(args.json).read_text())
        Path(args.out).write_text(_markdown(doc))
        print(_markdown(doc))
        return

    import jaxbox

    jaxbox.enable_x64()
    tmp = Path(tempfile.mkdtemp(prefix="jaxbox-fleet-bench-"))
    try:
        doc = {
            "date": time.strftime("%Y-%m-%d %H:%M"),
            "machine": f"{platform.machine()}, {os.cpu_count()} cores, load average "
            f"{os.getloadavg()[0]:.1f} at the start",
        }
        if args.gpu_batch:
            doc["gpu"] = gpu_batch([int(x) for x in args.batches.split(",")], tmp / "gpu")
            Path(args.json).with_name("fleet_gpu.json").write_text(json.dumps(doc, indent=1))
            if Path(args.json).exists():  # the curve joins the fleet report
                old = json.loads(Path(args.json).read_text())
                old["gpu"] = doc["gpu"]
                Path(args.json).write_text(json.dumps(old, indent=1, default=float))
                Path(args.out).write_text(_markdown(old))
            print(json.dumps(doc, indent=1))
            return
        sizes = [int(x) for x in args.sizes.split(",")]
        workers = [int(x) for x in args.workers.split(",")]
        source = tmp / "fleet"
        truth, gen_s = _fleet(max(sizes), source)
        print(f"fleet of {len(truth)} generated in {gen_s:.1f} s", flush=True)
        if args.append:
            old = json.loads(Path(args.json).read_text())
            for n in sizes:
                for w in workers:
                    r = _run(source, tmp / f"out-{n}-{w}", w, tmp / "cache")
                    r = {k: v for k, v in r.items() if k != "rows"}
                    r["date"] = doc["date"]
                    print(r, flush=True)
                    old["runs"].append(r)
            old["notes"] = (
                f"Runs dated {doc['date']} were measured by a later invocation "
                "(`--append`) on the same machine."
            )
            Path(args.json).write_text(json.dumps(old, indent=1, default=float))
            Path(args.out).write_text(_markdown(old))
            print(_markdown(old))
            return
        runs = []
        cache = tmp / "cache"
        for n in sizes:
            sub = source if n == len(truth) else tmp / f"fleet{n}"
            if sub != source:
                sub.mkdir()
                for name in truth.index[:n]:
                    shutil.copy(source / f"{name}.csv", sub / f"{name}.csv")
            for w in workers if n == min(sizes) else [max(workers)]:
                r = _run(sub, tmp / f"out-{n}-{w}", w, cache)
                print({k: v for k, v in r.items() if k != "rows"}, flush=True)
                runs.append(r)
        big = max(runs, key=lambda r: (r["buildings"], r["workers"]))
        cov = {"n": big["buildings"], **_coverage(big["rows"], truth)}
        names = list(truth.index[: args.scipy])
        sp = _scipy_loop(source, names)
        ours = big["rows"].set_index("building").loc[names, "hlc"]
        sp["hlc_rel_diff"] = float(np.median([abs(sp["hlc"][n] / ours[n] - 1) for n in names]))
        doc.update(
            runs=[{k: v for k, v in r.items() if k != "rows"} for r in runs],
            coverage=cov,
            scipy={k: v for k, v in sp.items() if k != "hlc"}
            | {"hlc_rel_diff": sp["hlc_rel_diff"]},
            generate_s=gen_s,
        )
        doc["ratio_workers"] = big["workers"]
        doc["ratio_per_s"] = big["steady_per_s"]
        doc["ratio"] = big["steady_per_s"] / (big["workers"] / sp["per_building_s"])
        Path(args.json).write_text(json.dumps(doc, indent=1, default=float))
        Path(args.out).write_text(_markdown(doc))
        print(_markdown(doc))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
