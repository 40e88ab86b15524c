"""Structure search on the zoo of synthetic test buildings: recovery, coverage, validation error.

For each building of :func:`jaxbox.datasets.make_zoo` (known structure, parameters and noise),
the default ``select`` (the structure search, criterion ``cv``, halves for identification and
validation) is run, and the benchmark records:

* structure recovery: the accepted structure is the true one, or an equivalent one (the same
  number of states, the same inputs and the same number of resistances);
* coverage of the 95 % intervals of the true parameters, when the true structure is accepted;
* the accepted model's validation RMSE relative to the noise level;
* the search time, per data length and step.

Usage::

    python benchmarks/zoo.py [--n 100] [--seed 0] [--steps 10min,60min] [--days 14]
                             [--out benchmarks/ZOO.md] [--json benchmarks/zoo.json] [--jobs 1]

``--jobs N`` searches N buildings at once, one process each (on the CPU, sharing the persistent
compilation cache): for a many-core machine.

Targets (issue: any real building): recovery ≥ 80 %, validation RMSE ≤ 1.5× the noise on ≥ 90 %.
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import platform
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def _signature(model) -> tuple:
    """What makes two structures equivalent: states, inputs, number of resistances."""
    return (model.n_states, tuple(sorted(model.inputs)), len(model.network.edges))


def _without_offsets(name: str) -> str:
    """The structure without its sensor offsets (``Off``): a property of the sensor, not of the
    building, so structure recovery is judged without them (their detection is counted apart)."""
    from jaxbox.models._grammar import is_structure_name, parse_structure

    if not is_structure_name(name):
        return name
    s = parse_structure(name)
    return type(s)(s.states, frozenset(t for t in s.tokens if t[1] != "Off"), s.bound_zones).name


def run_one(b, starts: int, offsets: bool = True, beam: int = 1) -> dict:
    import dataclasses

    import jaxbox
    from jaxbox.data import DataWarning
    from jaxbox.models import Grammar, get_model
    from jaxbox.validate import uncertainty

    t0 = time.perf_counter()
    row = {
        "building": b.name,
        "truth": b.structure,
        "step": b.step,
        "heating": b.heating,
        "noise": b.noise,
        "offset": b.offset,
        "samples": len(b.data),
        "gaps": len(b.gaps) + len(b.outages),
    }
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DataWarning)
            gb = jaxbox.GreyBox(b.data, name=b.name)
            grammar = Grammar.from_columns(gb.data.columns)
            grammar = dataclasses.replace(grammar, offsets=offsets)
            s = jaxbox.structure_search(gb, starts=starts, grammar=grammar, beam=beam)
    except Exception as err:  # noqa: BLE001 - a benchmark row records any failure
        row.update(status="failed", error=f"{type(err).__name__}: {err}"[:300])
        row["search_s"] = time.perf_counter() - t0
        return row
    row["search_s"] = time.perf_counter() - t0
    row["candidates"] = len(s.tree)
    if s.case is None and s.form_model is not None:  # a held zone's heat-demand/steady form
        m = s.form_model
        name = m.structure if hasattr(m, "structure") else s.form
        row.update(status="other_form", form=s.form, accepted=f"{name} ({s.form})")
        return row
    if s.case is None:
        row.update(status="no_valid_model")
        return row
    case = s.case
    row["status"] = "ok"
    row["accepted"] = case.model.name
    structure = _without_offsets(case.model.name)
    row["offset_modelled"] = structure != case.model.name
    row["exact"] = structure == b.structure
    truth = get_model(b.structure)
    row["equivalent"] = row["exact"] or _signature(get_model(structure)) == _signature(truth)
    rmse = case.validation.rmse_cross or case.validation.rmse_auto
    row["rmse_valid"] = float(np.mean(list(rmse.values())))
    row["rmse_over_noise"] = row["rmse_valid"] / max(b.noise, 1e-9)
    if row["exact"]:
        try:
            unc = uncertainty(case.result)
            hits = []
            for name, (lo, hi) in zip(unc.names, np.asarray(unc.ci95), strict=True):
                if name in b.params and not name.startswith("T_"):
                    hits.append(bool(lo <= b.params[name] <= hi))
            row["covered"], row["intervals"] = int(sum(hits)), len(hits)
        except (ValueError, KeyError, AttributeError) as err:
            row["coverage_error"] = str(err)[:200]
    return row


def markdown(doc: dict) -> str:
    rows = doc["rows"]
    ok = [r for r in rows if r.get("status") == "ok"]
    n = len(rows)
    partial = (
        f" The run was stopped after {n} of {doc['n']} buildings; these are its rows."
        if n < doc.get("n", n)
        else ""
    )
    lines = [
        "## Structure search on the zoo (benchmarks/zoo.py)",
        "",
        f"Written by `python benchmarks/zoo.py{' --only …' if doc.get('only') else ''}"
        f"{'' if doc.get('offsets', True) else ' --no-offsets'}"
        f"{' --beam ' + str(doc['beam']) if doc.get('beam_given') else ''}` on {doc['date']}"
        f"{'' if 'offsets' in doc else ' (before the sensor-offset token `Off`)'}; "
        f"{doc['machine']}; raw numbers in `benchmarks/zoo.json`. Default `select` (structure "
        f"search, criterion cv, beam {doc.get('beam', 1)}, {doc['starts']} starts per "
        f"candidate, data split in halves)."
        f"{partial}",
        "",
        "| buildings | accepted a valid model | exact structure | equivalent | "
        "RMSE ≤ 1.5× noise | median search [s] |",
        "|---:|---:|---:|---:|---:|---:|",
    ]

    def pct(k):
        return f"{100 * k / max(n, 1):.0f} %"

    other = [r for r in rows if r.get("status") == "other_form"]
    lines.append(
        f"| {n} | {pct(len(ok) + len(other))} | {pct(sum(r['exact'] for r in ok))} | "
        f"{pct(sum(r['equivalent'] for r in ok))} | "
        f"{pct(sum(r['rmse_over_noise'] <= 1.5 for r in ok))} | "
        f"{np.median([r['search_s'] for r in rows]):.0f} |"
    )
    if other:
        lines += [
            "",
            f"A valid model in a held zone's other form (the zone temperature as an input, "
            f"`select`'s heat-demand or steady-state form; not compared with the truth's "
            f"structure): {', '.join(r['building'] + ' ' + r['accepted'] for r in other)}.",
        ]
    lines += ["", "By step:", "", "| step | buildings | equivalent | RMSE ≤ 1.5× noise |"]
    lines.append("|---|---:|---:|---:|")
    for step in sorted({r["step"] for r in rows}):
        rs = [r for r in rows if r["step"] == step]
        oks = [r for r in rs if r.get("status") == "ok"]
        lines.append(
            f"| {step} | {len(rs)} | {sum(r['equivalent'] for r in oks)}/{len(rs)} | "
            f"{sum(r['rmse_over_noise'] <= 1.5 for r in oks)}/{len(rs)} |"
        )
    if any("offset_modelled" in r for r in ok):
        with_off = [r for r in ok if r.get("offset")]
        without = [r for r in ok if not r.get("offset")]
        lines += [
            "",
            "Sensor offsets (structures are compared without `Off`): modelled on "
            f"{sum(r['offset_modelled'] for r in with_off)} of the {len(with_off)} buildings "
            f"whose sensor has an offset, and on {sum(r['offset_modelled'] for r in without)} "
            f"of the {len(without)} without."
            + ("" if doc.get("offsets", True) else " (This run searched without `Off`.)"),
        ]
    cov = [r for r in ok if r.get("intervals")]
    if cov:
        hit = sum(r["covered"] for r in cov)
        tot = sum(r["intervals"] for r in cov)
        lines += ["", f"Coverage of the 95 % intervals (true structure accepted): {hit}/{tot}."]
    lines += ["", "| building | truth | accepted | step | heating | RMSE/noise | search [s] |"]
    lines.append("|---|---|---|---|---|---:|---:|")
    for r in rows:
        ratio = f"{r['rmse_over_noise']:.2f}" if "rmse_over_noise" in r else r.get("status")
        lines.append(
            f"| {r['building']} | {r['truth']} | {r.get('accepted', '–')} | {r['step']} | "
            f"{r['heating']} | {ratio} | {r['search_s']:.0f} |"
        )
    return "\n".join(lines) + "\n"


def _write(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (a stopped run leaves the last complete file)."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _worker(args) -> dict:
    """One building in a worker process (``--jobs``): the CPU backend, the shared cache."""
    b, starts, offsets, beam = args
    import jaxbox

    row = run_one(b, starts, offsets=offsets, beam=beam)
    jaxbox._compiled.release()
    return row


def _init_worker() -> None:
    import jaxbox

    jaxbox.enable_x64()
    jaxbox.enable_compilation_cache()


def _rows(zoo, starts: int, offsets: bool, jobs: int, beam: int):
    """The rows of the buildings ``zoo``, one at a time or ``jobs`` processes at once (in the
    order they finish)."""
    import jaxbox

    if jobs <= 1:
        for b in zoo:
            yield run_one(b, starts, offsets=offsets, beam=beam)
            jaxbox._compiled.release()  # every building compiles new structures
        return
    import multiprocessing as mp

    os.environ["JAX_PLATFORMS"] = "cpu"  # the workers' searches run on the CPU
    os.environ["JAXBOX_THREADS"] = "1"  # a process per core: no parts side by side within one
    ctx = mp.get_context("spawn")
    # two-zone buildings first: their searches are the longest, and the pool ends sooner
    zoo = sorted(zoo, key=lambda b: -len(b.data.columns))
    with ctx.Pool(jobs, initializer=_init_worker) as pool:
        yield from pool.imap_unordered(_worker, [(b, starts, offsets, beam) for b in zoo])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", default="10min,60min")
    ap.add_argument("--days", type=float, default=14.0)
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--out", default=str(HERE / "ZOO.md"))
    ap.add_argument("--json", default=str(HERE / "zoo.json"))
    ap.add_argument("--report-only", action="store_true", help="rewrite --out from --json")
    ap.add_argument("--skip", type=int, default=0, help="resume: keep the first rows of --json")
    ap.add_argument("--only", default="", help="comma list of buildings (z003,…) to run alone")
    ap.add_argument(
        "--no-offsets", action="store_true", help="search without the sensor-offset token Off"
    )
    ap.add_argument(
        "--beam", type=int, default=None, help="the search's beam (default: select's default)"
    )
    ap.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="buildings searched at once, one process each on the CPU (a many-core machine)",
    )
    args = ap.parse_args(argv)
    if args.report_only:  # also after an interrupted run: the rows measured so far
        doc = json.loads(Path(args.json).read_text())
        Path(args.out).write_text(markdown(doc))
        print(markdown(doc))
        return

    import jaxbox

    jaxbox.enable_x64()
    jaxbox.enable_compilation_cache()
    zoo = jaxbox.datasets.make_zoo(
        args.n, seed=args.seed, step=args.steps.split(","), days=args.days
    )
    doc = {
        "date": time.strftime("%Y-%m-%d %H:%M"),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, load average "
        f"{os.getloadavg()[0]:.1f} at the start",
        "starts": args.starts,
        "n": args.n,
        "rows": [],
    }
    doc["offsets"] = not args.no_offsets
    doc["beam_given"] = args.beam is not None
    default = inspect.signature(jaxbox.structure_search).parameters["beam"].default
    doc["beam"] = default if args.beam is None else args.beam
    if args.only:
        chosen = set(args.only.split(","))
        zoo = [b for b in zoo if b.name in chosen]
        doc["n"] = len(zoo)
        doc["only"] = args.only
    if args.skip:
        doc["rows"] = json.loads(Path(args.json).read_text())["rows"][: args.skip]
        zoo = zoo[len(doc["rows"]) :]
    if args.jobs > 1:
        doc["machine"] += f", {args.jobs} buildings at once (one process each, CPU)"
    order = {b.name: k for k, b in enumerate(zoo)}
    for row in _rows(zoo, args.starts, not args.no_offsets, args.jobs, doc["beam"]):
        doc["rows"].append(row)
        doc["rows"].sort(key=lambda r: order.get(r["building"], 0))
        print(json.dumps(row), flush=True)
        _write(Path(args.json), json.dumps(doc, indent=1))  # partial results survive
    Path(args.out).write_text(markdown(doc))
    print(markdown(doc))


if __name__ == "__main__":
    main()
