"""Buildings whose records differ in length, fitted in one call: old code against new.

A fleet's records rarely have one length (a month of 28–31 days, a sensor's first or last
day cut, a gap trimmed). ``fit_batch`` used to batch only records of the same length, so a
fleet of N lengths compiled N programs and ran N calls; it now pads records of neighbouring
lengths (one sixteenth of an octave) with samples of weight 0 and runs them together.

What follows the fit pays for every length too, unless it shares programs the same way: the
post-simulation of the validation data (diffrax, adaptive) extends a record to its run length
and the parameters' intervals (the Jacobian at the optimum) to its bucket of samples.

Each code runs in a fresh process without the persistent cache (every compilation counted),
alternating old and new for ``--rounds`` rounds, on ``--n`` synthetic buildings of
``jaxbox.datasets.make_fleet`` (hourly), each record ending between 28 and 31 days and split
into identification and the last 5–7 days for validation: ``fit_batch`` of one model
(``ZonWal``, 16 starts) on the identification records, then, building by building,
``validate`` on the validation days and ``uncertainty``. The old code is this tree's
``jaxbox/`` as it is at ``--baseline`` (``git archive``; ``3d616c9``: before the fit's
bucketing, ``53e99ce~1``: before the post-simulation's and the intervals'). The two codes'
costs, HLCs, validation RMSEs and standard errors are compared building by building.

    python benchmarks/lengths.py [--n 24] [--baseline 3d616c9] [--rounds 2]

Writes ``benchmarks/lengths.json``; the table goes into ``benchmarks/RESULTS.md`` by hand.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

_CHILD = r"""
import json, sys, time
t00 = time.perf_counter()
import jax
jax.config.update("jax_enable_x64", True)
import numpy as np
import jaxbox
from jaxbox.datasets import make_fleet
from jaxbox.fit import fit_batch
from jaxbox.validate import kpis
n, seed = int(sys.argv[1]), int(sys.argv[2])
data, truth = make_fleet(n, days=31, seed=seed)
rng = np.random.default_rng(seed)
ends = {k: int(rng.integers(28 * 24, 31 * 24)) for k in data}
# the identification record, then a validation record of the next 5-7 days
split = {k: ends[k] - int(rng.integers(5 * 24, 7 * 24)) for k in data}
cut = {k: d.slice(d.index[0], d.index[split[k]]) for k, d in data.items()}
weeks = {k: d.slice(d.index[split[k] + 1], d.index[ends[k]]) for k, d in data.items()}
names = list(cut)
t0 = time.perf_counter()
res = fit_batch([{"model": "ZonWal", "data": cut[k], "starts": 16} for k in names])
fit_s = time.perf_counter() - t0
# what follows a fit, building by building: the post-simulation of the validation days (diffrax,
# the validation's default) and the parameters' intervals (the Jacobian at the optimum)
from jaxbox.validate import uncertainty, validate
t0 = time.perf_counter()
val = [validate(r, weeks[k]) for r, k in zip(res, names)]
validate_s = time.perf_counter() - t0
t0 = time.perf_counter()
unc = [uncertainty(r) for r in res]
intervals_s = time.perf_counter() - t0
print(json.dumps({
    "jaxbox": jaxbox.__file__,
    "process_s": time.perf_counter() - t00,
    "fit_batch_s": fit_s,
    "validate_s": validate_s,
    "intervals_s": intervals_s,
    "rmse": [float(next(iter((v.rmse_cross or v.rmse_auto).values()))) for v in val],
    "se": [[float(x) for x in u.std] for u in unc],
    "week_lengths": [len(weeks[k]) for k in names],
    "lengths": [len(cut[k]) for k in names],
    "calls": len({(r.timing["compile_s"], r.timing["fit_s"]) for r in res}),
    "compile_s": sum({(r.timing["compile_s"], r.timing["fit_s"]): r.timing["compile_s"]
                      for r in res}.values()),
    "cost": [float(r.cost) for r in res],
    "hlc": [float(kpis(r).hlc.value) for r in res],
    "hlc_true": [float(truth.loc[k, "hlc"]) for k in names],
}))
"""


#: the phases timed in each process [s]
_PHASES = ("process_s", "fit_batch_s", "validate_s", "intervals_s")


def _old_tree(rev: str, into: Path) -> Path:
    archive = subprocess.run(
        ["git", "archive", rev, "jaxbox"], cwd=ROOT, check=True, capture_output=True
    ).stdout
    with tempfile.TemporaryFile() as f:
        f.write(archive)
        f.seek(0)
        with tarfile.open(fileobj=f) as tar:
            tar.extractall(into, filter="data")
    return into


def _run(pythonpath: str, n: int, seed: int) -> dict:
    env = {**os.environ, "JAXBOX_CACHE": "0", "JAXBOX_EXPORTED": "0", "PYTHONPATH": pythonpath}
    with tempfile.TemporaryDirectory() as cwd:  # not this checkout: the code is PYTHONPATH's
        proc = subprocess.run(
            [sys.executable, "-c", _CHILD, str(n), str(seed)],
            cwd=cwd,
            env=env,
            check=True,
            capture_output=True,
            text=True,
        )
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--baseline", default="3d616c9")
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        old_path = str(_old_tree(args.baseline, Path(tmp)))
        runs: dict[str, list] = {"old": [], "new": []}
        for _ in range(args.rounds):
            runs["old"].append(_run(old_path, args.n, args.seed))
            runs["new"].append(_run(str(ROOT), args.n, args.seed))
    old, new = runs["old"][0], runs["new"][0]
    # each code the one its processes imported
    assert old["jaxbox"].startswith(old_path) and new["jaxbox"].startswith(str(ROOT))
    best = {k: {m: min(r[m] for r in v) for m in _PHASES} for k, v in runs.items()}
    rel = lambda a, b: max(abs(x / y - 1) for x, y in zip(a, b, strict=True))  # noqa: E731
    out = {
        "date": time.strftime("%Y-%m-%d %H:%M"),
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs",
        "load": os.getloadavg(),
        "n": args.n,
        "baseline": args.baseline,
        "rounds": args.rounds,
        "distinct_lengths": len(set(new["lengths"])),
        "calls": {"old": old["calls"], "new": new["calls"]},
        "compile_s": {"old": old["compile_s"], "new": new["compile_s"]},
        "best": best,
        "ratio_fit_batch": best["new"]["fit_batch_s"] / best["old"]["fit_batch_s"],
        "ratio_process": best["new"]["process_s"] / best["old"]["process_s"],
        "max_rel_cost": rel(new["cost"], old["cost"]),
        "max_rel_hlc": rel(new["hlc"], old["hlc"]),
        "max_rel_hlc_truth": rel(new["hlc"], new["hlc_true"]),
        "ratio_validate": best["new"]["validate_s"] / best["old"]["validate_s"],
        "ratio_intervals": best["new"]["intervals_s"] / best["old"]["intervals_s"],
        "max_rel_rmse": rel(new["rmse"], old["rmse"]),
        "max_rel_se": rel(sum(new["se"], []), sum(old["se"], [])),
        "distinct_week_lengths": len(set(new["week_lengths"])),
        "runs": runs,
    }
    from jaxbox._io import atomic_write_json

    atomic_write_json(HERE / "lengths.json", out, indent=1)
    print(json.dumps({k: v for k, v in out.items() if k != "runs"}, indent=1))


if __name__ == "__main__":
    main()
