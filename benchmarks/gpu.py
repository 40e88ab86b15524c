"""The batched benchmarks on a GPU: multistart and fleet throughput, against the CPU and scipy.

    python benchmarks/gpu.py --json OUT.json            # measure (on a machine with a GPU)
    python benchmarks/gpu.py --report-only --json F     # write benchmarks/GPU.md from F

Everything is measured in one run on one machine:

* **multistart** — the 14-parameter ``ZonWalIntInfWinBouC`` on twin house N2 (the problem of
  ``benchmarks/run.py``) from the guess plus Latin-hypercube starts (seed 0), for several start
  counts, on the default JAX device (the GPU), with the default number of slots (starts iterated
  together) and with every start in one slot batch; the same counts on the machine's CPU (a
  subprocess with ``JAX_PLATFORMS=cpu``) for the ratio.
* **fleet batch** — ``jaxbox.fit_batch`` of ``ZonWal`` on synthetic buildings × 16 starts in one
  compiled call per size (as ``benchmarks/fleet.py --gpu-batch``), on the GPU and on the CPU.
* **parallel** — simulation by the sequential scan against the associative (parallel-in-time)
  scan, as ``benchmarks/run.py``'s section of that name, for 1, 64 and 1024 members on the
  GPU, 1 and 64 on the CPU.
* **scipy** — the plain scipy loop of ``benchmarks/fleet.py`` (``least_squares``, numpy exact
  simulation, the same 16 starts and bounds) on a few of the same buildings, on the same
  machine's CPU: the baseline for the ratios.

Sections write to the JSON as they finish, so an interrupted run keeps what it measured.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

MULTI = "ZonWalIntInfWinBouC"
FLEET = "ZonWal"
STARTS = 16
REL = 1e-4


def _log(*a):
    print(*a, flush=True)


def _multistart(counts: list[int], repeats: int, cpu_slots: bool) -> list[dict]:
    import numpy as np

    import jaxbox
    from jaxbox.datasets import twinhouse_exp1
    from jaxbox.fit import _fit

    ident, _ = twinhouse_exp1("N2").split()
    out = []
    for S in counts:
        # on an accelerator, also the CPU's default grouping (at most 128 slots) for comparison
        for slots in [None, 128] if cpu_slots and 128 < S <= 1024 else [None]:
            _fit.clear_compile_cache()
            t0 = time.perf_counter()
            first = jaxbox.fit_model(MULTI, ident, starts=S, seed=0, slots=slots)
            first_wall = time.perf_counter() - t0
            fits, walls = [], []
            for _ in range(repeats):
                t0 = time.perf_counter()
                r = jaxbox.fit_model(MULTI, ident, starts=S, seed=0, slots=slots)
                walls.append(time.perf_counter() - t0)
                fits.append(r.timing["fit_s"])
            cost = np.asarray(r.starts.cost, dtype=float)
            best = float(np.nanmin(cost))
            row = {
                "starts": S,
                "slots": r.timing.get("slots", slots),
                "compile_s": first.timing["compile_s"],
                "first_call_s": first_wall,
                "fit_s": min(fits),
                "wall_s": min(walls),
                "per_start_ms": 1e3 * min(fits) / S,
                "best_cost": best,
                "at_best": int(np.sum(cost <= best * (1 + REL))),
                "steps_median": float(np.median(r.starts.steps)),
            }
            _log("  ", row)
            out.append(row)
    return out


def _cpu_subprocess(args: list[str], timeout: float) -> dict | None:
    """This script's own sections on the CPU of the same machine."""
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as f:
        path = f.name
    try:
        subprocess.run(
            [sys.executable, __file__, "--inner", "--json", path, *args],
            env=env,
            timeout=timeout,
            check=False,
        )
        text = Path(path).read_text()
        return json.loads(text) if text else None
    except (subprocess.TimeoutExpired, json.JSONDecodeError) as err:
        _log(f"  CPU run incomplete: {err}")
        text = Path(path).read_text() if Path(path).exists() else ""
        return json.loads(text) if text else None
    finally:
        Path(path).unlink(missing_ok=True)


def _buildings(n: int, folder: Path):
    from jaxbox.data import load
    from jaxbox.datasets import make_fleet

    if not (folder / "truth.csv").exists():
        _, truth = make_fleet(n, folder, model=FLEET, days=31, seed=1)
        truth.to_csv(folder / "truth.csv")
    names = sorted(p.stem for p in folder.glob("b*.csv"))
    return names, [load(folder / f"{name}.csv").split()[0] for name in names]


def _fleet_batch(sizes: list[int], folder: Path, distinct: int) -> list[dict]:
    import jax

    from jaxbox.fit import fit_batch

    _, idents = _buildings(distinct, folder)
    out = []
    for size in sizes:
        reqs = [
            {"model": FLEET, "data": idents[k % len(idents)], "starts": STARTS} for k in range(size)
        ]
        t0 = time.perf_counter()
        fit_batch(reqs)
        first = time.perf_counter() - t0
        t0 = time.perf_counter()
        res = fit_batch(reqs)
        wall = time.perf_counter() - t0
        row = {
            "buildings": size,
            "fits": size * STARTS,
            "first_call_s": first,
            "wall_s": wall,
            "solver_s": res[0].timing["fit_s"],
            "fits_per_s": size * STARTS / res[0].timing["fit_s"],
            "buildings_per_s": size / wall,
            "device": str(jax.devices()[0]),
        }
        _log("  ", row)
        out.append(row)
    return out


def _scipy(folder: Path, n: int, distinct: int) -> dict:
    import fleet

    names, _ = _buildings(distinct, folder)
    return fleet._scipy_loop(folder, names[:n])


def _machine() -> dict:
    import run

    m = run.machine()
    try:
        m["gpu_name"] = subprocess.run(
            ["nvidia-smi", "--query-gpu=name,memory.total,driver_version", "--format=csv,noheader"],
            capture_output=True,
            text=True,
            timeout=20,
        ).stdout.strip()
    except (OSError, subprocess.TimeoutExpired):
        m["gpu_name"] = None
    return m


def measure(args) -> dict:
    import jax

    import jaxbox

    jaxbox.enable_x64()
    doc: dict = {"date": time.strftime("%Y-%m-%d %H:%M")}
    dump = Path(args.json)

    def save():
        tmp = dump.with_suffix(".tmp")
        tmp.write_text(json.dumps(doc, indent=1, default=float))
        tmp.replace(dump)

    counts = [int(x) for x in args.counts.split(",")]
    sizes = [int(x) for x in args.batches.split(",")]
    folder = Path(args.buildings or tempfile.mkdtemp(prefix="jaxbox-gpu-bench-"))
    folder.mkdir(parents=True, exist_ok=True)
    sections = args.sections.split(",")
    doc["machine"] = _machine()
    save()
    if "multistart" in sections:
        _log("multistart")
        doc["multistart"] = _multistart(
            counts, args.repeats, cpu_slots=jax.default_backend() != "cpu"
        )
        save()
    if "fleet" in sections:
        _log("fleet batch")
        doc["fleet"] = _fleet_batch(sizes, folder, args.distinct)
        save()
    if "parallel" in sections:
        _log("parallel in time")
        import run as bench

        # the CPU run (--inner) stops at 64 members: 1024 × 52560 samples take minutes there
        batches = (1, 64) if args.inner else (1, 64, 1024)
        doc["parallel"] = bench.parallel_in_time(args.repeats, batches=batches)
        save()
    if "scipy" in sections:
        _log("scipy loop")
        doc["scipy"] = _scipy(folder, args.scipy, args.distinct)
        save()
    if not args.inner and args.cpu_counts:
        _log("the same machine's CPU")
        doc["cpu"] = _cpu_subprocess(
            [
                "--counts",
                args.cpu_counts,
                "--batches",
                args.cpu_batches,
                "--repeats",
                "1",
                "--sections",
                ",".join(s for s in sections if s in ("multistart", "fleet", "parallel")),
                "--buildings",
                str(folder),
                "--distinct",
                str(args.distinct),
            ],
            timeout=args.cpu_timeout,
        )
        save()
    return doc


# ---- report -------------------------------------------------------------------------------


def _markdown(doc: dict) -> str:
    m = doc["machine"]
    v = m["versions"]
    lines = [
        "# jaxbox on a GPU",
        "",
        f"Written by `python benchmarks/gpu.py` on {doc['date']} (raw numbers: "
        "`benchmarks/gpu.json`)."
        + (
            ""
            if doc.get("incomplete") or doc.get("notes")
            else " One run on one machine: the GPU, that machine's CPU and the plain scipy loop "
            "measured together."
        ),
        "",
        f"- GPU: {m.get('gpu_name') or '?'}; JAX devices: {', '.join(m['devices'])}",
        f"- CPU: {m['cpu']}, {m['cores']} cores, memory {m['memory']}",
        f"- versions: python {v['python']}, jax {v['jax']}, jaxlib {v['jaxlib']}, "
        f"diffrax {v['diffrax']}, optimistix {v['optimistix']}, equinox {v['equinox']}, "
        f"numpy {v['numpy']}, scipy {v['scipy']}",
        "- float64 throughout; times are the minimum of repeats after compilation; *compile* is "
        "the first call of a structure and batch shape in a fresh in-memory cache.",
        "",
    ]
    if doc.get("incomplete"):
        lines += [f"*Incomplete run.* {doc['incomplete']}", ""]
    cpu = doc.get("cpu") or {}
    if not cpu and doc.get("baseline"):
        # no CPU run on the GPU's machine: the CPU columns come from another machine's run
        cpu = doc["baseline"]
        bm = cpu["machine"]
        lines += [
            f"*CPU columns*: not the GPU machine's CPU but {bm['cpu']}, {bm['cores']} cores "
            f"(jax {bm['versions']['jax']}), measured {cpu['date']} with this script and "
            "`JAX_PLATFORMS=cpu`: the ratios compare two machines.",
            "",
        ]
    cpu_multi = {r["starts"]: r for r in cpu.get("multistart", [])}
    if doc.get("multistart"):
        lines += [
            f"## Multistart: {MULTI} (14 parameters) on twin house N2, identification half",
            "",
            "| starts | slots | compile [s] | fit [s] | per start [ms] | CPU per start [ms] "
            "| CPU ÷ GPU | best cost | at best | LM steps median |",
            "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        for r in doc["multistart"]:
            c = cpu_multi.get(r["starts"])
            cpu_ms = f"{c['per_start_ms']:.2f}" if c else "–"
            ratio = f"{c['per_start_ms'] / r['per_start_ms']:.1f}×" if c else "–"
            lines.append(
                f"| {r['starts']} | {r['slots']} | {r['compile_s']:.1f} | {r['fit_s']:.3f} | "
                f"{r['per_start_ms']:.3f} | {cpu_ms} | {ratio} | {r['best_cost']:.9g} | "
                f"{r['at_best']} | {r['steps_median']:.0f} |"
            )
        lines += [
            "",
            "*slots*: starts iterated together (a finished start hands its slot to the next); "
            "the default on a GPU runs 257 to 1024 starts in 256 slots where such a batch runs "
            "parallel in time and every start at once otherwise (up to 16384), and at most 128 "
            "together on a CPU; the rows with 128 slots show the CPU grouping on the GPU. "
            "*CPU*: the same call with `JAX_PLATFORMS=cpu` (default slots).",
            "",
        ]
    scipy = doc.get("scipy") or cpu.get("scipy")
    where = "this machine's CPU" if doc.get("scipy") else "the CPU of the CPU columns"
    cpu_fleet = {r["buildings"]: r for r in cpu.get("fleet", [])}
    if doc.get("fleet"):
        per_fit_scipy = scipy["per_building_s"] / STARTS if scipy else None
        lines += [
            f"## Fleet batch: {FLEET} fits, buildings × {STARTS} starts in one call",
            "",
            "| buildings | fits | first call [s] | solver [s] | fits/s | buildings/s (wall) "
            "| CPU fits/s | GPU ÷ CPU | GPU ÷ scipy (per fit) |",
            "|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        for r in doc["fleet"]:
            c = cpu_fleet.get(r["buildings"])
            cfs = f"{c['fits_per_s']:.0f}" if c else "–"
            gc = f"{r['fits_per_s'] / c['fits_per_s']:.1f}×" if c else "–"
            gs = f"{r['fits_per_s'] * per_fit_scipy:.0f}×" if per_fit_scipy else "–"
            lines.append(
                f"| {r['buildings']} | {r['fits']} | {r['first_call_s']:.1f} | "
                f"{r['solver_s']:.3f} | {r['fits_per_s']:.0f} | {r['buildings_per_s']:.1f} | "
                f"{cfs} | {gc} | {gs} |"
            )
        lines.append("")
        if scipy:
            lines += [
                f"scipy loop (`least_squares`, trf, 2-point Jacobian, numpy exact simulation, "
                f"the same {STARTS} starts and bounds) on {scipy['n']} of the buildings, one "
                f"after the other on {where}: {scipy['per_building_s']:.2f} s per "
                f"building ({1 / per_fit_scipy:.1f} fits/s).",
                "",
            ]
    if doc.get("parallel"):
        cpu_par = cpu.get("parallel") or {}
        lines += [
            "## Parallel in time: simulation by the sequential and the associative scan",
            "",
            f"{MULTI}, first-order hold, random inputs, a batch of members with scaled dynamics "
            "(`benchmarks/run.py`'s section *parallel*).",
            "",
            "| samples | batch | sequential [ms] | associative scan [ms] | sequential ÷ "
            "associative | CPU sequential [ms] | CPU associative [ms] | max difference [K] |",
            "|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        for n, row in doc["parallel"].items():
            for b, v in row.items():
                c = (cpu_par.get(n) or {}).get(b)
                cs = f"{c['sequential_ms']:.2f}" if c else "–"
                cp = f"{c['parallel_ms']:.2f}" if c else "–"
                lines.append(
                    f"| {n} | {b} | {v['sequential_ms']:.2f} | {v['parallel_ms']:.2f} | "
                    f"{v['sequential_ms'] / v['parallel_ms']:.1f}× | {cs} | {cp} | "
                    f"{v['max_diff_K']:.1e} |"
                )
        lines.append("")
    for note in doc.get("notes", []):
        lines += [note, ""]
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", default=str(HERE / "gpu.json"))
    ap.add_argument("--out", default=str(HERE / "GPU.md"))
    ap.add_argument("--counts", default="1,64,1024,8192")
    ap.add_argument("--cpu-counts", default="64,256")
    ap.add_argument("--batches", default="64,256,1024,4096")
    ap.add_argument("--cpu-batches", default="64")
    ap.add_argument("--distinct", type=int, default=64, help="distinct synthetic buildings")
    ap.add_argument("--scipy", type=int, default=2, help="buildings fitted by the scipy loop")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--sections", default="multistart,fleet,parallel,scipy")
    ap.add_argument("--buildings", default=None, help="folder of the synthetic buildings")
    ap.add_argument("--cpu-timeout", type=float, default=240.0)
    ap.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--report-only", action="store_true")
    ap.add_argument(
        "--baseline",
        default=None,
        help="with --report-only: a CPU run's JSON from another machine, for the CPU columns "
        "when the GPU run has none (stored in --json)",
    )
    args = ap.parse_args(argv)
    if not args.report_only:
        measure(args)
        if args.inner:
            return
    doc = json.loads(Path(args.json).read_text())
    if args.baseline:
        doc["baseline"] = json.loads(Path(args.baseline).read_text())
        Path(args.json).write_text(json.dumps(doc, indent=1, default=float))
    Path(args.out).write_text(_markdown(doc))
    _log(f"wrote {args.out}")


if __name__ == "__main__":
    main()
