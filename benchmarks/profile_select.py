"""Where the default ``jaxbox select`` spends its time: tracing, lowering, XLA compilation, the
fits, the verdicts and intervals, the validation, the report.

Each run is a fresh process (``python benchmarks/profile_select.py --child ...``) that runs the
command in-process under :mod:`cProfile`, with JAX's monitoring events summed: the time spent
tracing Python into jaxprs, lowering them to MLIR, compiling them with XLA, and loading
executables from the persistent compilation cache. *Cold*: an empty persistent cache; *warm*: a
second process on the cache the cold one filled. The profile's cumulative times of jaxbox's
own phases (fits, verdicts, intervals, validation, KPIs, report) overlap the JAX columns (a
fit's first call includes its compilation); the table says which is which.

With ``--baseline REV`` the same runs are made, alternating, by an *old* code as well: this
tree with the paths ``--baseline-paths`` (the fit and its compile paths by default) as they are
at ``REV`` (``git archive``; a path written ``PATH@REV2`` as it is at ``REV2``), so that only
what those paths changed is measured, and the selection (accepted model, cost, SE, HLC) is
compared between the two. Each code's figure is the minimum over ``--rounds`` rounds (cold:
each on an empty cache of its own; warm: a second process on it).

    python benchmarks/profile_select.py [--data twinhouse_exp1:N2] [--out benchmarks/PROFILE.md]
        [--baseline HEAD~1] [--rounds 2]

Writes ``benchmarks/PROFILE.md`` (and ``benchmarks/profile.json``), and the same table into
``benchmarks/RESULTS.md`` between the lines ``<!-- profile_select -->`` and
``<!-- /profile_select -->`` (appended when they are missing).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import os
import platform
import pstats
import resource
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
from collections import defaultdict
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

#: JAX's monitoring events, summed per run [s]
EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "tracing",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lowering",
    "/jax/core/compile/backend_compile_duration": "XLA compile",
    "/jax/compilation_cache/cache_retrieval_time_sec": "cache loads",
}

#: jaxbox's phases: (label, module path fragment, function name); cumulative time of the
#: outermost call of each
PHASES = [
    ("fits: the batched multistart (incl. its compilation)", "jaxbox/fit/_fit.py", "_multistart"),
    ("verdicts", "jaxbox/validate/_verdict.py", "check_validity"),
    ("parameter intervals", "jaxbox/validate/_uncertainty.py", "uncertainty"),
    ("validation (post-simulation)", "jaxbox/validate/_postsim.py", "validate"),
    ("residual analysis", "jaxbox/validate/_residuals.py", "analyse_residuals"),
    ("KPIs and their intervals", "jaxbox/validate/_kpi.py", "kpis"),
    ("reductions", "jaxbox/select/_reduce.py", "reduction"),
    ("data loading and checks", "jaxbox/data/_load.py", "load"),
    ("report (HTML, plots)", "jaxbox/report/_html.py", "write_report"),
]


def _child(args) -> None:
    t_start = time.perf_counter()
    import jax

    from jaxbox.cli._main import main as cli_main

    sums: dict[str, float] = defaultdict(float)
    counts: dict[str, int] = defaultdict(int)

    def listen(event: str, duration: float, **_):
        if event in EVENTS:
            sums[EVENTS[event]] += duration
            counts[EVENTS[event]] += 1

    jax.monitoring.register_event_duration_secs_listener(listen)
    t_import = time.perf_counter() - t_start
    argv = ["select", args.data, "--json"]
    if args.report:
        argv += ["--out", str(Path(args.workdir) / "out")]
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    sink = io.StringIO()
    stdout = sys.stdout
    sys.stdout = sink
    try:
        if args.no_profile:
            code = cli_main(argv)
        else:
            prof.enable()
            code = cli_main(argv)
            prof.disable()
    finally:
        sys.stdout = stdout
    wall = time.perf_counter() - t0
    doc = {
        "exit": code,
        "import_s": t_import,
        "wall_s": wall,
        "jax": {k: {"seconds": sums[k], "events": counts[k]} for k in EVENTS.values()},
        "selection": _selection(sink.getvalue()),
    }
    if not args.no_profile:
        doc.update(_profile_parts(pstats.Stats(prof)))
    Path(args.result).write_text(json.dumps(doc, indent=1))


def _profile_parts(stats: pstats.Stats) -> dict:
    """jaxbox's phases (:data:`PHASES`) and its 40 functions of most cumulative time."""
    phases = {}
    for label, path, name in PHASES:
        cum = 0.0
        calls = 0
        for (file, _line, func), (cc, _nc, _tt, ct, _callers) in stats.stats.items():
            if func == name and file.replace(os.sep, "/").endswith(path):
                cum += ct
                calls += cc
        phases[label] = {"seconds": cum, "calls": calls}
    top = sorted(
        (
            (ct, cc, f"{file.split('jaxbox/', 1)[-1]}:{func}")
            for (file, _line, func), (cc, _nc, _tt, ct, _callers) in stats.stats.items()
            if "/jaxbox/" in file.replace(os.sep, "/") and "/site-packages/" not in file
        ),
        reverse=True,
    )[:40]
    return {"top": [{"seconds": t, "calls": c, "function": f} for t, c, f in top], "phases": phases}


def _selection(text: str) -> dict:
    """What a selection must keep from one code to another: the accepted model, its cost, SE
    (auto and cross), RMSE and parameters, and the HLC with its interval."""
    try:
        doc = json.loads(text)
    except ValueError:
        return {}
    fit = doc.get("fit") or {}
    hlc = doc.get("hlc") or {}
    return {
        "accepted": doc.get("accepted"),
        "cost": fit.get("cost"),
        "se_auto": fit.get("se_auto"),
        "se_cross": fit.get("se_cross"),
        "rms_error": fit.get("rms_error"),
        "params": fit.get("params"),
        "hlc": hlc.get("value"),
        "hlc_ci95": hlc.get("ci95"),
    }


def _run(
    data: str, cache: Path, workdir: Path, report: bool, code: Path = ROOT, profile: bool = True
) -> dict:
    result = workdir / f"result-{time.monotonic_ns()}.json"
    env = {
        **os.environ,
        "JAXBOX_CACHE_DIR": str(cache),
        "PYTHONPATH": str(code),
    }
    env.pop("JAXBOX_CACHE", None)
    t0 = time.perf_counter()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    cmd = [sys.executable, __file__, "--child", "--data", data, "--result", str(result)]
    cmd += ["--workdir", str(workdir)] + (["--report"] if report else [])
    cmd += [] if profile else ["--no-profile"]
    subprocess.run(cmd, env=env, check=True)
    doc = json.loads(result.read_text())
    doc["process_s"] = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    # the processor time of the process (user and system, every thread): on a machine shared
    # with other work, less disturbed by it than the wall-clock time
    doc["cpu_s"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return doc


def _markdown(runs: dict, args, load: tuple[float, float]) -> str:
    cold, warm = runs["cold"], runs["warm"]
    lines = [
        "# Where the default select spends its time",
        "",
        f"Generated by `python benchmarks/profile_select.py` on {time.strftime('%Y-%m-%d %H:%M')} "
        f"({platform.machine()}, {os.cpu_count()} CPUs; load average {load[0]:.1f} at the "
        f"start, {load[1]:.1f} at the end): `jaxbox select {args.data} --json`"
        + (" --out DIR" if args.report else "")
        + ", each run a fresh process.",
        "",
        "| | cold (empty cache) [s] | warm (persistent cache) [s] |",
        "|---|---:|---:|",
        f"| process, end to end | {cold['process_s']:.1f} | {warm['process_s']:.1f} |",
        f"| the command (after imports) | {cold['wall_s']:.1f} | {warm['wall_s']:.1f} |",
    ]
    for name in EVENTS.values():
        c, w = cold["jax"][name], warm["jax"][name]
        lines.append(
            f"| JAX: {name} ({c['events']} / {w['events']} events) | {c['seconds']:.1f} | "
            f"{w['seconds']:.1f} |"
        )
    lines.append("| *jaxbox's phases (cumulative; they include the JAX time of their calls)* | | |")
    for label, _, _ in PHASES:
        c, w = cold["phases"][label], warm["phases"][label]
        if c["calls"] == 0 and w["calls"] == 0:
            continue
        lines.append(f"| {label} ({c['calls']} calls) | {c['seconds']:.1f} | {w['seconds']:.1f} |")
    jax_cold = sum(cold["jax"][k]["seconds"] for k in ("tracing", "lowering", "XLA compile"))
    jax_warm = sum(warm["jax"][k]["seconds"] for k in ("tracing", "lowering", "XLA compile"))
    lines += [
        "",
        "The functions of jaxbox with the most cumulative time, cold:",
        "",
        "| function | calls | cold [s] |",
        "|---|---:|---:|",
        *[f"| `{r['function']}` | {r['calls']} | {r['seconds']:.1f} |" for r in cold["top"][:25]],
    ]
    lines += [
        "",
        f"Tracing, lowering and compiling take {jax_cold:.0f} s of {cold['wall_s']:.0f} s cold "
        f"({jax_cold / cold['wall_s']:.0%}) and {jax_warm:.0f} s of {warm['wall_s']:.0f} s warm "
        f"({jax_warm / warm['wall_s']:.0%}): the persistent cache saves XLA's compilation, not "
        "the tracing and lowering that find the cache key. Python, tracing included, runs slower "
        "under the profiler; the old-against-new runs below go without it.",
        "",
    ]
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default="twinhouse_exp1:N2")
    ap.add_argument("--report", action="store_true", help="also --out (the HTML report)")
    ap.add_argument("--out", default=str(HERE / "PROFILE.md"))
    ap.add_argument("--baseline", default="", help="a commit: measure the old code too")
    ap.add_argument(
        "--baseline-paths",
        default="jaxbox/fit,jaxbox/_compiled.py,jaxbox/_cache.py",
        help="the paths taken from --baseline (the rest of the tree is this one's; PATH@REV: "
        "that path from REV)",
    )
    ap.add_argument("--rounds", type=int, default=1, help="rounds of old and new (--baseline)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--no-profile", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--result", help=argparse.SUPPRESS)
    ap.add_argument("--workdir", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        _child(args)
        return
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        cache = work / "cache"
        runs = {
            "cold": _run(args.data, cache, work, args.report),
            "warm": _run(args.data, cache, work, args.report),
        }
        if args.baseline:
            runs["versus"] = _versus(args, work)
    load1 = os.getloadavg()[0]
    out = Path(args.out)
    text = _markdown(runs, args, (load0, load1))
    if args.baseline:
        text += _versus_markdown(runs["versus"], args)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    out.with_name("profile.json").write_text(json.dumps(runs, indent=1))
    _into_results(out.with_name("RESULTS.md"), text)
    print(text)


def _old_tree(baseline: str, paths: list[str], into: Path) -> Path:
    """This tree's ``jaxbox`` with ``paths`` as they are at ``baseline`` (a path written
    ``PATH@REV`` as it is at ``REV``)."""
    shutil.copytree(ROOT / "jaxbox", into / "jaxbox", ignore=shutil.ignore_patterns("__pycache__"))
    by_rev: dict[str, list[str]] = defaultdict(list)
    for spec in paths:
        path, _, rev = spec.partition("@")
        by_rev[rev or baseline].append(path)
        target = into / path
        if target.is_dir():
            shutil.rmtree(target)
        elif target.exists():
            target.unlink()
    for k, (rev, revpaths) in enumerate(by_rev.items()):
        archive = into / f"old-{k}.tar"
        subprocess.run(
            ["git", "archive", "--format=tar", "-o", str(archive), rev, *revpaths],
            cwd=ROOT,
            check=True,
        )
        with tarfile.open(archive) as tf:
            tf.extractall(into, filter="data")
    return into


def _versus(args, work: Path) -> dict:
    """Cold and warm runs of the old and the new code, alternating, without the profiler."""
    paths = [p for p in args.baseline_paths.split(",") if p]
    old = _old_tree(args.baseline, paths, work / "old")
    runs: dict = {"baseline": args.baseline, "paths": paths, "old": [], "new": []}
    for k in range(args.rounds):
        for which, code in (("old", old), ("new", ROOT)):
            cache = work / f"cache-{which}-{k}"
            cold = _run(args.data, cache, work, args.report, code, profile=False)
            warm = _run(args.data, cache, work, args.report, code, profile=False)
            runs[which].append({"cold": cold, "warm": warm})
            print(
                f"{which} round {k + 1}: cold {cold['process_s']:.1f} s ({cold['cpu_s']:.1f} s "
                f"CPU), warm {warm['process_s']:.1f} s ({warm['cpu_s']:.1f} s CPU)",
                file=sys.stderr,
                flush=True,
            )
    return runs


def _same(a: dict, b: dict, rel: float = 1e-6) -> tuple[bool, float]:
    """Whether two selections agree (the model by name, the numbers within ``rel``) and the
    largest relative difference of their numbers."""
    worst = 0.0

    def walk(x, y) -> bool:
        nonlocal worst
        if isinstance(x, dict) and isinstance(y, dict):
            return x.keys() == y.keys() and all(walk(x[k], y[k]) for k in x)
        if isinstance(x, list | tuple) and isinstance(y, list | tuple):
            return len(x) == len(y) and all(walk(p, q) for p, q in zip(x, y, strict=True))
        if isinstance(x, int | float) and isinstance(y, int | float):
            d = abs(x - y) / max(abs(x), abs(y), 1e-300)
            worst = max(worst, d)
            return d <= rel
        return x == y

    return walk(a, b), worst


def _versus_markdown(v: dict, args) -> str:
    def best(which: str, phase: str, key: str = "process_s") -> float:
        return min(r[phase][key] for r in v[which])

    compile_s = {
        w: {
            ph: min(
                sum(r[ph]["jax"][k]["seconds"] for k in ("tracing", "lowering", "XLA compile"))
                for r in v[w]
            )
            for ph in ("cold", "warm")
        }
        for w in ("old", "new")
    }
    lines = [
        "",
        "## Old against new (same run, alternating processes, no profiler)",
        "",
        f"*old*: this tree with `{'`, `'.join(v['paths'])}` as at `{v['baseline']}` (a path "
        f"`PATH@REV` as at `REV`); *new*: this "
        f"tree. Each figure the minimum of {len(v['new'])} round(s) (cold: an empty cache of its "
        "own; warm: a second process on it). The machine was shared with other work (load "
        "average in the heading): the processor time of the process is the steadier measure of "
        "what each code costs, the wall-clock time what a user waits for on such a machine.",
        "",
        "| | old [s] | new [s] | new / old |",
        "|---|---:|---:|---:|",
    ]
    for phase in ("cold", "warm"):
        for key, label in (
            ("process_s", "process, end to end"),
            ("wall_s", "the command"),
            ("cpu_s", "processor time of the process (user + system)"),
        ):
            o, n = best("old", phase, key), best("new", phase, key)
            lines.append(f"| {phase}: {label} | {o:.1f} | {n:.1f} | {n / o:.2f} |")
        o, n = compile_s["old"][phase], compile_s["new"][phase]
        lines.append(
            f"| {phase}: JAX tracing, lowering, compiling | {o:.1f} | {n:.1f} | {n / o:.2f} |"
        )
    same, worst = _same(v["old"][0]["cold"]["selection"], v["new"][0]["cold"]["selection"])
    sel = v["new"][0]["cold"]["selection"]
    lines += [
        "",
        f"Selection: old `{v['old'][0]['cold']['selection'].get('accepted')}`, new "
        f"`{sel.get('accepted')}`; accepted model, cost, SE, RMSE, parameters and HLC with its "
        f"interval {'the same' if same else '**not** the same'} within 1e-6 (relative; largest "
        f"difference {worst:.1e}).",
        "",
    ]
    return "\n".join(lines)


#: the markers of the profile's section in RESULTS.md
MARKERS = ("<!-- profile_select -->", "<!-- /profile_select -->")


def results_block(text: str) -> str:
    """PROFILE.md's ``text`` as RESULTS.md's section: its headings one level down, between
    :data:`MARKERS` (``benchmarks/run.py`` writes the same block when it rewrites RESULTS.md)."""
    body = "\n".join("#" + line if line.startswith("#") else line for line in text.splitlines())
    return f"{MARKERS[0]}\n{body}\n{MARKERS[1]}"


def _into_results(path: Path, text: str) -> None:
    """The table as a section of RESULTS.md, between its markers."""
    if not path.exists():
        return
    start, end = MARKERS
    block = results_block(text)
    old = path.read_text()
    if start in old and end in old:
        new = old[: old.index(start)] + block + old[old.index(end) + len(end) :]
    else:
        new = old.rstrip("\n") + "\n\n" + block + "\n"
    path.write_text(new)


if __name__ == "__main__":
    main()
