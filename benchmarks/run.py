# ruff: noqa: E501
"""The jaxbox benchmark suite: one command, results in ``benchmarks/RESULTS.md``.

    python benchmarks/run.py                # everything, peers included (about 30-60 min)
    python benchmarks/run.py --quick        # jaxbox only, fewer repeats, no 1024 starts

Problems: the richest experiment-1 model (``ZonWalIntInfWinBouC``: 4 states, 14 free parameters)
on the bundled twin house N2, identification half (hourly), from the guess plus Latin-hypercube
starts (seed 0). In the same run the peers (``_peers.py``) solve the same problem from the same
starts. Also: the diffrax route, a year of 10-minute data, parallel-in-time vs sequential
simulation, several buildings in one call, the persistent compilation cache, and a profile of one
iteration. Times are wall-clock seconds after compilation unless labelled; on a shared machine
the minimum of repeated runs is reported.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxbox  # noqa: E402
from jaxbox.datasets import twinhouse_exp1  # noqa: E402
from jaxbox.fit import DEFAULT_CONCENTRATION, _fit, make_problem, problem_arrays  # noqa: E402
from jaxbox.fit._fit import make_starts  # noqa: E402

MODEL = "ZonWalIntInfWinBouC"
REL = 1e-4  # a start "reached the best cost" within this relative margin


def log(*a):
    print(*a, flush=True)


def timed_min(fn, repeats):
    best, out = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


# ---- the machine ----------------------------------------------------------------------------------


def machine() -> dict:
    cpu = "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = "?"
    try:
        kb = int(Path("/proc/meminfo").read_text().split()[1])
        mem = f"{kb / 2**20:.0f} GiB"
    except (OSError, ValueError, IndexError):
        pass
    versions = {
        "python": platform.python_version(),
        "jax": jax.__version__,
        "numpy": np.__version__,
    }
    for mod in ("jaxlib", "scipy", "diffrax", "optimistix", "equinox", "casadi"):
        try:
            versions[mod] = __import__(mod).__version__
        except Exception:
            versions[mod] = "not installed"
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "memory": mem,
        "os": platform.platform(),
        "devices": [str(d) for d in jax.devices()],
        "gpu": any(d.platform == "gpu" for d in jax.devices()),
        "load_start": os.getloadavg(),
        "versions": versions,
    }


# ---- jaxbox multistart ----------------------------------------------------------------------------


def jaxbox_starts(ident, counts, repeats) -> dict:
    out = {}
    problem = make_problem(jaxbox.get_model(MODEL), ident)
    for S in counts:
        _fit.clear_compile_cache()
        t0 = time.perf_counter()
        first = jaxbox.fit_model(MODEL, ident, starts=S, seed=0)
        first_wall = time.perf_counter() - t0
        reps = repeats if S <= 64 else max(1, repeats - 1)
        walls, fits = [], []
        for _ in range(reps):
            t0 = time.perf_counter()
            r = jaxbox.fit_model(MODEL, ident, starts=S, seed=0)
            walls.append(time.perf_counter() - t0)
            fits.append(r.timing["fit_s"])
        st = r.starts
        out[S] = {
            "compile_s": first.timing["compile_s"],
            "first_call_s": first_wall,
            "wall_s": min(walls),
            "fit_s": min(fits),
            "per_start_s": min(fits) / S,
            "best_cost": float(r.cost),
            "costs": st.cost.tolist(),
            "converged": int(st.converged.sum()),
            "steps_median": float(np.median(st.steps)),
            "steps_max": int(st.steps.max()),
            "steps_sum": int(st.steps.sum()),
            "slots": _fit.default_slots(S),
            "memory_mb": None,
        }
        log(
            f"  jaxbox {S:5d} starts: compile {first.timing['compile_s']:.2f} s, fit "
            f"{min(fits):.3f} s (wall {min(walls):.3f} s), best {r.cost:.7g}, "
            f"{st.converged.sum()} converged, steps median {np.median(st.steps):.0f} "
            f"max {st.steps.max()}"
        )
    out["starts64"] = make_starts(problem, ident, 64, 0, DEFAULT_CONCENTRATION).tolist()
    return out


def profile_iteration(ident) -> dict:
    """Cost of one evaluation of (cost, Jᵀr, JᵀJ) per batch size, and of its parts."""
    from jaxbox.simulate._exact import normal_equations

    problem = make_problem(jaxbox.get_model(MODEL), ident)
    t, u, y, sw = problem_arrays(problem, ident)
    tr = problem.transform
    out = {}
    for B in (1, 16, 64, 256):
        X = make_starts(problem, ident, max(B, 2), 0, DEFAULT_CONCENTRATION)[:B]
        Z = jnp.asarray(tr.to_internal(X))
        members = (
            jnp.zeros((B, 0)),
            jnp.asarray(np.broadcast_to(tr.lower, (B, tr.lower.size))),
            jnp.asarray(np.broadcast_to(tr.upper, (B, tr.upper.size))),
            jnp.asarray(np.broadcast_to(tr.scale, (B, tr.scale.size))),
            jnp.full((B,), float(t[1] - t[0])),
        )
        data = (
            jnp.asarray(t)[:, None],
            jnp.asarray(u)[:, None],
            jnp.asarray(y)[:, None],
            jnp.asarray(np.broadcast_to(sw, y.shape))[:, None],
        )

        def mats(Z, members=members):
            prim = jax.vmap(problem.matrices)(Z, *members)
            tang = jax.vmap(jax.jacfwd(problem.matrices))(Z, *members)
            return prim, tang

        fm = jax.jit(mats)
        prim, tang = fm(Z)
        fn = jax.jit(
            lambda p, q, data=data: normal_equations(p, q, problem.output_states, *data[1:])
        )
        fl = jax.jit(lambda Z, m=members, d=data: problem.normal_equations(Z, m, d))
        jax.block_until_ready((fn(prim, tang), fl(Z)))
        res = {}
        for name, f, a in (("matrices", fm, (Z,)), ("scan", fn, (prim, tang)), ("total", fl, (Z,))):
            ts = []
            for _ in range(7):
                t0 = time.perf_counter()
                jax.block_until_ready(f(*a))
                ts.append(time.perf_counter() - t0)
            res[name] = min(ts) * 1e3
        res["per_member_us"] = res["total"] * 1e3 / B
        out[B] = res
        log(
            f"  one evaluation, {B:4d} members: discretisation + derivatives {res['matrices']:.2f} ms, "
            f"sensitivity scan {res['scan']:.2f} ms, total {res['total']:.2f} ms "
            f"({res['per_member_us']:.0f} µs a member)"
        )
    return out


# ---- peers ----------------------------------------------------------------------------------------


def peers(ident, starts64, which, n_casadi, n_scipy, budget) -> dict:
    import _peers

    problem = make_problem(jaxbox.get_model(MODEL), ident)
    X = np.asarray(starts64)
    out = {}
    if "casadi" in which:
        try:
            import casadi  # noqa: F401

            log(f"  CasADi + IPOPT collocation, {n_casadi} starts")
            out["casadi"] = _peers.casadi_collocation(
                problem, ident, X[:n_casadi], budget_s=budget, log=log
            )
        except ImportError:
            log("  casadi not installed (pip install jaxbox[bench]): skipped")
    if "scipy" in which:
        log(f"  scipy solve_ivp + least_squares, {n_scipy} starts")
        out["scipy"] = _peers.scipy_shooting(problem, ident, X[:n_scipy], budget_s=budget, log=log)
    for v in out.values():
        for s in v["starts"]:
            s["p"] = np.asarray(s["p"]).tolist()
    return out


# ---- the whole experiment-1 hierarchy ------------------------------------------------------------


def hierarchy(ident, counts, which, n_casadi, n_scipy, budget, scipy_models=None) -> dict:
    """Every experiment-1 model: jaxbox from 1, 64, 1024 starts; the peers from the first
    starts of the same 64-start set (the richest model is detailed in its own sections)."""
    import _peers

    out = {}
    for name in jaxbox.list_models(family="exp1"):
        model = jaxbox.get_model(name)
        problem = make_problem(model, ident)
        row = {"free": len(problem.free), "jaxbox": {}, "peers": {}}
        for S in counts:
            _fit.clear_compile_cache()
            first = jaxbox.fit_model(model, ident, starts=S, seed=0)
            fit_s, r = timed_min(
                lambda S=S, model=model: jaxbox.fit_model(model, ident, starts=S, seed=0), 2
            )
            row["jaxbox"][S] = {
                "compile_s": first.timing["compile_s"],
                "fit_s": r.timing["fit_s"],
                "wall_s": fit_s,
                "best_cost": float(r.cost),
                "costs": r.starts.cost.tolist(),
                "converged": int(r.starts.converged.sum()),
            }
            log(
                f"  {name:<22} jaxbox {S:5d} starts: compile {first.timing['compile_s']:.2f} s, "
                f"fit {r.timing['fit_s']:.3f} s, best {r.cost:.7g}"
            )
        X = make_starts(problem, ident, 64, 0, DEFAULT_CONCENTRATION)
        if name != MODEL and "casadi" in which:
            try:
                row["peers"]["casadi"] = _peers.casadi_collocation(
                    problem, ident, X[:n_casadi], budget_s=budget, log=log
                )
            except ImportError:
                log("  casadi not installed (pip install jaxbox[bench]): skipped")
        if name != MODEL and "scipy" in which and (scipy_models is None or name in scipy_models):
            row["peers"]["scipy"] = _peers.scipy_shooting(
                problem, ident, X[:n_scipy], budget_s=budget, log=log
            )
        for v in row["peers"].values():
            for st in v["starts"]:
                st["p"] = np.asarray(st["p"]).tolist()
        out[name] = row
    return out


# ---- diffrax route --------------------------------------------------------------------------------


def diffrax_route(ident, repeats) -> dict:
    from jaxbox.simulate import simulate_arrays

    out = {}
    for S in (1, 16):
        _fit.clear_compile_cache()
        first = jaxbox.fit_model(MODEL, ident, starts=S, simulator="diffrax")
        fit_s, r = timed_min(
            lambda S=S: jaxbox.fit_model(MODEL, ident, starts=S, simulator="diffrax"), repeats
        )
        ex = jaxbox.fit_model(MODEL, ident, starts=S)
        out[S] = {
            "compile_s": first.timing["compile_s"],
            "fit_s": r.timing["fit_s"],
            "exact_fit_s": min(
                jaxbox.fit_model(MODEL, ident, starts=S).timing["fit_s"] for _ in range(repeats)
            ),
            "best_cost": float(r.cost),
            "exact_best_cost": float(ex.cost),
            "steps_sum": int(r.starts.steps.sum()),
            "exact_steps_sum": int(ex.starts.steps.sum()),
        }
        log(
            f"  diffrax (Kvaerno5, one step a sample) {S} starts: compile "
            f"{first.timing['compile_s']:.1f} s, fit {r.timing['fit_s']:.2f} s, best {r.cost:.7g} "
            f"(exact: {out[S]['exact_fit_s']:.3f} s, {ex.cost:.7g})"
        )
    # its discretisation error at the optimum, against the exact solution and the misfit
    model = jaxbox.get_model(MODEL)
    theta = ex.params
    problem = make_problem(model, ident)
    t, u, y, _ = problem_arrays(problem, ident)
    y_ex = np.asarray(simulate_arrays(model, theta, t, u)[0])
    y_fx = np.asarray(
        simulate_arrays(model, theta, t, u, method="diffrax", adaptive=False, throw=False)[0]
    )
    out["error_at_optimum_K"] = float(np.max(np.abs(y_fx - y_ex)))
    out["rmse_K"] = float(np.sqrt(ex.cost))
    log(
        f"  fixed-step error at the optimum {out['error_at_optimum_K']:.2e} K "
        f"(fit RMSE {out['rmse_K']:.3f} K)"
    )
    return out


# ---- long series (subprocess: peak memory) ----------------------------------------------------------

_LONG = r"""
import json, resource, sys, time
import jax
jax.config.update("jax_enable_x64", True)
import numpy as np, jaxbox
from jaxbox.datasets import twinhouse_exp1
from jaxbox.simulate import simulate_arrays
n, S = int(sys.argv[1]), int(sys.argv[2])
model = jaxbox.get_model("ZonWalIntInfWinBouC")
src = twinhouse_exp1("N2", "10min")
cols = list(model.inputs)
U = src.array(cols)
reps = -(-n // len(U))
U = np.concatenate([U] * reps)[:n]
t = np.arange(n) * 600.0
truth = model.defaults() | {"R_bou": 0.03, "gA_e": 1.0, "gA_w": 1.5, "T_zon0": 25.0, "T_wal0": 20.0,
                            "T_int0": 24.0, "T_bou0": 22.0}
y = np.asarray(simulate_arrays(model, truth, t, U)[0][:, 0])
y = y + 0.05 * np.random.default_rng(0).normal(size=n)
data = jaxbox.Dataset.from_arrays(t, {**{c: U[:, i] for i, c in enumerate(cols)}, "T_zon": y})
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
r = jaxbox.fit_model(model, data, starts=S)
wall = time.perf_counter() - t0
r2 = jaxbox.fit_model(model, data, starts=S)
from jaxbox import _compiled
mem = _compiled.entries("fit")[0].memory_analysis()
print(json.dumps({
    "samples": n, "starts": S, "compile_s": r.timing["compile_s"], "fit_s": r2.timing["fit_s"],
    "first_call_s": wall, "best_cost": float(r.cost), "rmse": float(np.sqrt(r.cost)),
    "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    "rss_before_fit_mb": base / 1024,
    "xla_temp_mb": mem.temp_size_in_bytes / 2**20,
    "xla_args_mb": mem.argument_size_in_bytes / 2**20,
    "converged": int(r.starts.converged.sum()),
}))
"""


def long_series(n, starts_list) -> dict:
    out = {}
    for S in starts_list:
        proc = subprocess.run(
            [sys.executable, "-c", _LONG, str(n), str(S)], capture_output=True, text=True
        )
        if proc.returncode != 0:
            log(proc.stderr[-2000:])
            out[S] = {"error": proc.stderr[-500:]}
            continue
        res = json.loads(proc.stdout.strip().splitlines()[-1])
        out[S] = res
        log(
            f"  {n} samples, {S} starts: compile {res['compile_s']:.1f} s, fit {res['fit_s']:.2f} s, "
            f"peak RSS {res['peak_rss_mb']:.0f} MB (XLA scratch {res['xla_temp_mb']:.0f} MB), "
            f"RMSE {res['rmse']:.4f} K"
        )
    return out


# ---- parallel in time -----------------------------------------------------------------------------


def parallel_in_time(repeats, batches=(1, 64)) -> dict:
    """Simulation of the benchmark model by the sequential and the associative scan, for three
    lengths and the given batch sizes, on JAX's default device."""
    from jaxbox.simulate._exact import discretize_foh, simulate_foh
    from jaxbox.simulate._parallel import simulate_foh_parallel

    model = jaxbox.get_model(MODEL)
    theta = model.defaults()
    A, B, C, D = model.state_space(theta)
    x0 = model.initial_state(theta)
    out = {}
    rng = np.random.default_rng(0)
    for n in (492, 5905, 52560):
        u = jnp.asarray(rng.normal(size=(n, 5)) * [5, 5, 300, 100, 100] + [15, 15, 300, 100, 100])
        row = {}
        for B_ in batches:
            scale = jnp.asarray(np.exp(rng.normal(0, 0.2, size=(B_, 1, 1))))
            Ab = A * scale

            def run(fn, Ab=Ab, u=u):
                def one(a):
                    P = discretize_foh(a, B, 600.0)
                    return fn(*P, C, D, x0, u)[0]

                return jax.vmap(one)(Ab)

            seq = jax.jit(lambda: run(simulate_foh)).lower().compile()
            par = jax.jit(lambda: run(simulate_foh_parallel)).lower().compile()
            jax.block_until_ready((seq(), par()))
            ts, _ = timed_min(lambda seq=seq: jax.block_until_ready(seq()), repeats + 2)
            tp, _ = timed_min(lambda par=par: jax.block_until_ready(par()), repeats + 2)
            err = float(jnp.max(jnp.abs(seq() - par())))
            row[B_] = {"sequential_ms": ts * 1e3, "parallel_ms": tp * 1e3, "max_diff_K": err}
            log(
                f"  N={n:6d} batch {B_:3d}: sequential {ts * 1e3:8.2f} ms, associative scan "
                f"{tp * 1e3:8.2f} ms, max difference {err:.1e} K"
            )
        out[n] = row
    return out


# ---- several buildings in one call ------------------------------------------------------------------


def buildings(repeats) -> dict:
    from jaxbox.fit._batch import fit_many

    sets = [twinhouse_exp1(h).split()[0] for h in ("N2", "O5")]
    if len({len(s) for s in sets}) != 1:
        n = min(len(s) for s in sets)
        sets = [s.slice(s.index[0], s.index[n - 1]) for s in sets]
    _fit.clear_compile_cache()
    t0 = time.perf_counter()
    sep = [jaxbox.fit_model(MODEL, s, starts=64) for s in sets]
    sep_first = time.perf_counter() - t0
    sep_compiles = _fit.compile_cache_info()["compiles"]
    sep_fit = min(
        sum(jaxbox.fit_model(MODEL, s, starts=64).timing["fit_s"] for s in sets)
        for _ in range(repeats)
    )
    _fit.clear_compile_cache()
    t0 = time.perf_counter()
    together = fit_many(MODEL, sets, starts=64, max_steps=100, rtol=1e-6)
    many_first = time.perf_counter() - t0
    many_fit = min(
        fit_many(MODEL, sets, starts=64, max_steps=100, rtol=1e-6)[0].timing["fit_s"]
        for _ in range(repeats)
    )
    same = [abs(a.cost / b.cost - 1) for a, b in zip(sep, together, strict=True)]
    out = {
        "separate_first_s": sep_first,
        "separate_compiles": sep_compiles,
        "separate_fit_s": sep_fit,
        "batched_first_s": many_first,
        "batched_compiles": _fit.compile_cache_info()["compiles"],
        "batched_fit_s": many_fit,
        "max_rel_cost_difference": max(same),
        "best_costs": [float(a.cost) for a in together],
    }
    log(
        f"  N2 + O5, 64 starts each: separately {sep_first:.1f} s first ({sep_compiles} "
        f"compilations), fits {sep_fit:.2f} s; one call {many_first:.1f} s first "
        f"({out['batched_compiles']} compilation), fit {many_fit:.2f} s"
    )
    return out


# ---- persistent compilation cache -------------------------------------------------------------------

_CACHED = r"""
import json, sys, time
t00 = time.perf_counter()
import jax
jax.config.update("jax_enable_x64", True)
import jaxbox
from jaxbox._cache import enable_compilation_cache
enable_compilation_cache(sys.argv[1])
from jaxbox.datasets import twinhouse_exp1
ident, _ = twinhouse_exp1("N2").split()
t0 = time.perf_counter()
r = jaxbox.fit_model("ZonWalIntInfWinBouC", ident, starts=64)
print(json.dumps({"process_s": time.perf_counter() - t00, "fit_call_s": time.perf_counter() - t0,
                  "compile_s": r.timing["compile_s"]}))
"""


def persistent_cache() -> dict:
    with tempfile.TemporaryDirectory() as d:
        runs = []
        for _ in range(2):
            proc = subprocess.run(
                [sys.executable, "-c", _CACHED, d], capture_output=True, text=True, check=True
            )
            runs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    log(
        f"  first process: compile {runs[0]['compile_s']:.2f} s, process {runs[0]['process_s']:.1f} s; "
        f"second: compile {runs[1]['compile_s']:.2f} s, process {runs[1]['process_s']:.1f} s"
    )
    return {"first": runs[0], "second": runs[1]}


# ---- report ---------------------------------------------------------------------------------------


def ratio(a, b):
    return a / b if b else float("nan")


def _fmt_ttb(t: float) -> str:
    """A time to the best optimum [s]: ∞ where no start reached it."""
    if not np.isfinite(t):
        return "∞"
    return f"{t:.3f}" if t < 10 else f"{t:.0f}"


def _fmt_ratio(a: float, b: float) -> str:
    return f"{a / b:.0f}" if np.isfinite(a) and np.isfinite(b) and b > 0 else "–"


def time_to_best_row(res, best_all, peer="casadi", factor=1000.0):
    """(target, measured, met): jaxbox's time to the best optimum (99 %) against a peer's, from
    the same run's 64-start batch and the peer's starts (the first of the same set)."""
    import _peers

    j64, p = res["jaxbox"].get(64), res.get("peers", {}).get(peer)
    if not (j64 and p and p["starts"]):
        return None
    costs = np.asarray(j64["costs"])
    jp = j64["fit_s"] / len(costs)
    j_hits = int(np.sum(costs <= best_all * (1 + REL)))
    st = p["starts"]
    per = float(np.mean([s["wall_s"] for s in st]))
    hits = int(np.sum(np.asarray([s["cost"] for s in st]) <= best_all * (1 + REL)))
    jt = _peers.time_to_best(jp, j_hits, len(costs))
    pt = _peers.time_to_best(per, hits, len(st))
    r = pt / jt if np.isfinite(pt) and np.isfinite(jt) else float("nan")
    return (
        f"time to the best optimum (99 %) ≥ {factor:.0f}× faster than {peer}",
        f"jaxbox {_fmt_ttb(jt)} s ({1e3 * jp:.1f} ms a start, p = {j_hits}/{len(costs)}), "
        f"{peer} {_fmt_ttb(pt)} s ({per:.2f} s a start, p = {hits}/{len(st)}): "
        + (f"{r:.0f}×" if np.isfinite(r) else "–"),
        "yes" if np.isfinite(r) and r >= factor else "**no**",
    )


def targets(res, best_all):
    """(target, measured, met) rows from the results."""
    rows = []
    yes = lambda ok: "yes" if ok else "**no**"  # noqa: E731
    j64 = res["jaxbox"].get(64)
    if j64:
        rows.append(
            (
                "64 starts, after compilation: ≤ 1 s wall",
                f"{j64['wall_s']:.2f} s per `fit` call ({j64['fit_s']:.2f} s in the solve)",
                yes(j64["wall_s"] <= 1.0),
            )
        )
        rows.append(("compile ≤ 15 s", f"{j64['compile_s']:.1f} s", yes(j64["compile_s"] <= 15.0)))
    for name, factor in (("casadi", 5), ("scipy", 50)):
        p = res.get("peers", {}).get(name)
        if not (p and p["starts"] and j64):
            continue
        k = len(p["starts"])
        per = float(np.mean([s["wall_s"] for s in p["starts"]]))
        jp = j64["fit_s"] / 64
        jbest = float(np.min(j64["costs"][:k]))
        pbest = float(np.nanmin([s["cost"] for s in p["starts"]]))
        equal = jbest <= pbest * (1 + REL)
        rows.append(
            (
                f"≥ {factor}× faster than {name} at equal or lower cost",
                f"{per / jp:.0f}× per start ({per:.2f} s vs {jp * 1e3:.1f} ms); best cost over the same {k} starts {jbest:.7g} vs {pbest:.7g}; over 64 starts {j64['best_cost']:.7g}",
                yes(per / jp >= factor and (equal or j64["best_cost"] <= pbest * (1 + REL))),
            )
        )
    ttb = time_to_best_row(res, best_all)
    if ttb:
        rows.append(ttb)
    b = res.get("buildings")
    if b:
        rows.append(
            (
                "compile once per structure, reused across starts, windows, buildings",
                f"two houses in one call: {b['batched_compiles']} compilation; a second dataset of the same shape: none (tests/test_performance.py)",
                yes(b["batched_compiles"] == 1),
            )
        )
    c = res.get("cache")
    if c:
        rows.append(
            (
                "persistent cache: a second process starts fast",
                f"compile {c['first']['compile_s']:.1f} s → {c['second']['compile_s']:.1f} s",
                yes(c["second"]["compile_s"] < 0.5 * c["first"]["compile_s"]),
            )
        )
    lg = res.get("long", {})
    ok = [v for v in lg.values() if "error" not in v]
    if ok:
        peak = max(v["peak_rss_mb"] for v in ok)
        rows.append(
            (
                "a year of 10-minute data (52,560 samples): peak memory ≤ 2 GB",
                f"peak RSS {peak:.0f} MB (up to {max(v['starts'] for v in ok)} starts); cost linear in samples (forward sensitivities, chunked)",
                yes(peak <= 2048),
            )
        )
    par = res.get("parallel")
    if par:
        wins = [
            (n, B)
            for n, row in par.items()
            for B, v in row.items()
            if v["parallel_ms"] < v["sequential_ms"]
        ]
        rows.append(
            (
                "parallel-in-time simulation offered, and where it wins",
                "wins here at "
                + (", ".join(f"N={n} batch {B}" for n, B in wins) or "no size on this CPU")
                + "; "
                + _gpu_parallel(),
                "offered",
            )
        )
    d = res.get("diffrax")
    if d:
        v = d.get(16) or d.get(1)
        rows.append(
            (
                "diffrax route as fast as honest, ratio to exact reported",
                f"×{v['fit_s'] / v['exact_fit_s']:.0f} slower than exact; one step a sample errs by "
                f"{d['error_at_optimum_K']:.1g} K against a misfit of {d['rmse_K']:.3f} K",
                "reported",
            )
        )
    rows.append(_gpu_target())
    return rows


def _gpu_doc() -> dict | None:
    """``benchmarks/gpu.json`` (the GPU run of ``benchmarks/gpu.py``), or ``None``."""
    path = HERE / "gpu.json"
    return json.loads(path.read_text()) if path.exists() else None


def _gpu_parallel() -> str:
    """Where the associative scan wins on a GPU, from ``benchmarks/gpu.json`` when it has it."""
    doc = _gpu_doc() or {}
    par = doc.get("parallel")
    if not par:
        return "meant for GPUs (not measured: no GPU)"
    gpu = doc["machine"].get("gpu_name", "GPU").split(",")[0]
    wins = [
        v["sequential_ms"] / v["parallel_ms"]
        for row in par.values()
        for v in row.values()
        if v["parallel_ms"] < v["sequential_ms"]
    ]
    sizes = sum(len(row) for row in par.values())
    return (
        f"on the {gpu} (GPU.md) it wins at {len(wins)} of {sizes} sizes, "
        f"{min(wins):.1f}–{max(wins):.0f}×"
        if wins
        else f"on the {gpu} (GPU.md) it wins at no size"
    )


def _gpu_target() -> tuple[str, str, str]:
    """The GPU row of the targets, from ``benchmarks/gpu.json`` (its own run) when there is one."""
    doc = _gpu_doc()
    if doc is None:
        return ("GPU run of the batched benchmark", "no GPU machine available", "not run")
    best = min(doc.get("multistart", []), key=lambda r: r["per_start_ms"], default=None)
    fleet = max(doc.get("fleet", []), key=lambda r: r["fits_per_s"], default=None)
    parts = [f"{doc['machine'].get('gpu_name') or 'GPU'}, {doc['date']} (GPU.md)"]
    if best:
        parts.append(f"{best['starts']} starts at {best['per_start_ms']:.2f} ms a start")
    if fleet:
        parts.append(f"fleet batch {fleet['fits_per_s']:.0f} fits/s in the solver")
    return ("GPU run of the batched benchmark", "; ".join(parts), "run")


def report(res: dict) -> str:
    import _peers

    m = res["machine"]
    L = []
    w = L.append
    w("# jaxbox benchmarks")
    w("")
    w(
        f"Written by `python benchmarks/run.py{' ' + res['argv'] if res['argv'] else ''}` on "
        f"{res['date']}; raw numbers in `benchmarks/results.json`."
        + (
            f" The run was interrupted after a section and resumed (`--resume`) at "
            f"{', '.join(res['resumed'])} on the same machine; the sections already measured "
            "were kept."
            if res.get("resumed")
            else ""
        )
        + "".join(
            f" Measured again on {r['date']} with the code of that day (`--remeasure`): "
            f"{', '.join(r['sections'])}; the other sections are from the earlier run."
            for r in res.get("remeasured", ())
        )
    )
    w("")
    w("## Machine")
    w("")
    w(
        f"- CPU: {m['cpu']}, {m['cores']} cores (shared with other jobs: load average "
        f"{m['load_start'][0]:.1f} at the start, {res['load_end'][0]:.1f} at the end), "
        f"memory {m['memory']}"
    )
    w(f"- {m['os']}; JAX devices: {', '.join(m['devices'])}")
    w(
        "- GPU: none in this run; the batched benchmarks ran on a GPU in their own run "
        "(`benchmarks/gpu.py`, the section *jaxbox on a GPU* below) where one was lent."
        if (HERE / "gpu.json").exists() and not m.get("gpu")
        else "- GPU: none. No GPU machine was available to this run, so the batched benchmark "
        "has not been run on a GPU; the code is the same (`jax.devices()` picks the device)."
    )
    w("- versions: " + ", ".join(f"{k} {v}" for k, v in m["versions"].items()))
    w(
        "- Timings on a shared 2-core machine are noisy: each jaxbox figure is the minimum of "
        "repeated runs; peers ran once (they take minutes)."
    )
    w("")
    js = res["jaxbox"]
    best_all = min(
        [js[k]["best_cost"] for k in js if k != "starts64"]
        + [
            s["cost"]
            for p in res.get("peers", {}).values()
            for s in p["starts"]
            if np.isfinite(s["cost"])
        ]
    )
    w("## Problem")
    w("")
    w(
        f"`{MODEL}` (4 states, 14 free parameters: capacities, resistances, two window apertures, "
        "four initial temperatures) on twin house N2, experiment 1, identification half: 492 "
        "hourly samples. Starts: the default guess, then Latin-hypercube samples (seed 0). Cost: "
        "the weighted mean squared output error [K²] of `jaxbox.fit`; every route's final "
        "parameters are re-scored by jaxbox's exact simulation. Best cost found by any route: "
        f"{best_all:.7g} K² (RMSE {np.sqrt(best_all):.4f} K). A start *reached the best cost* when "
        f"its cost is within {REL:g} (relative) of that."
    )
    w("")
    w("## jaxbox, multistart")
    w("")
    w(
        "| starts | compile [s] | fit [s] | wall per call [s] | per start [ms] | best cost | "
        "at best | converged | LM steps median / max |"
    )
    w("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for k, v in js.items():
        if k == "starts64":
            continue
        at = sum(c <= best_all * (1 + REL) for c in v["costs"])
        w(
            f"| {k} | {v['compile_s']:.2f} | {v['fit_s']:.3f} | {v['wall_s']:.3f} | "
            f"{v['per_start_s'] * 1e3:.2f} | {v['best_cost']:.7g} | {at} | {v['converged']} | "
            f"{v['steps_median']:.0f} / {v['steps_max']} |"
        )
    w("")
    w(
        "*fit*: the compiled batched solve; *wall per call*: `jaxbox.fit_model(...)` end to end with the "
        "executable cached (problem set-up, starts, result). Compile: first call of a structure "
        "in a fresh cache."
    )
    w("")
    w("## Targets")
    w("")
    w("| target | measured | met |")
    w("|---|---|:-:|")
    for row in targets(res, best_all):
        w("| " + " | ".join(row) + " |")
    w("")
    if res.get("peers"):
        w("## Against the peers (same data, model, starts, cost)")
        w("")
        j64 = js.get(64) or js.get("64")
        costs64 = np.asarray(j64["costs"])
        w(
            "| route | starts run | set-up / compile [s] | time per start [s] | best cost | "
            "at best | to the best, 99 % [s] | peer ÷ jaxbox time per start "
            "| peer ÷ jaxbox to the best | jaxbox best − peer best |"
        )
        w("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        jp = j64["fit_s"] / 64
        j_hits = int(sum(costs64 <= best_all * (1 + REL)))
        j_ttb = _peers.time_to_best(jp, j_hits, 64)
        w(
            f"| jaxbox (64-start batch) | 64 | {j64['compile_s']:.1f} | {jp:.4f} | "
            f"{j64['best_cost']:.7g} | {j_hits} | {_fmt_ttb(j_ttb)} | 1 | 1 | – |"
        )
        for name, p in res["peers"].items():
            st = p["starts"]
            if not st:
                continue
            k = len(st)
            per = float(np.mean([s["wall_s"] for s in st]))
            pc = np.asarray([s["cost"] for s in st])
            pbest = float(np.nanmin(pc))
            jsub = float(np.min(costs64[:k]))
            hits = int(np.sum(pc <= best_all * (1 + REL)))
            ttb = _peers.time_to_best(per, hits, k)
            label = f"{name} (run of {p['kept_from']})" if p.get("kept_from") else name
            w(
                f"| {label} | {k} | {p['setup_s']:.1f} | {per:.2f} | {pbest:.7g} | "
                f"{hits} | {_fmt_ttb(ttb)} | {ratio(per, jp):.0f} | "
                f"{_fmt_ratio(ttb, j_ttb)} | {jsub - pbest:+.2e} (same {k} starts) |"
            )
        w("")
        w(
            "*To the best, 99 %*: (time per start) × ln 0.01 / ln(1 − p), p the share of the "
            "route's starts at the best cost, the expected time to reach the best cost with 99 % "
            "probability by independent starts (∞: no start reached it)."
        )
        w("")
        w("Per start on the same starts (cost after each route; jaxbox from its 64-start batch):")
        w("")
        names = list(res["peers"])
        w("| start | jaxbox | " + " | ".join(names) + " |")
        w("|---:|---:|" + "---:|" * len(names))
        kmax = max(len(res["peers"][n]["starts"]) for n in names)
        for i in range(kmax):
            cells = []
            for n in names:
                st = res["peers"][n]["starts"]
                cells.append(
                    f"{st[i]['cost']:.6g} ({st[i]['wall_s']:.1f} s)" if i < len(st) else "–"
                )
            w(f"| {i} | {costs64[i]:.6g} | " + " | ".join(cells) + " |")
        w("")
        for name, p in res["peers"].items():
            st = p["starts"]
            if st:
                per = float(np.mean([s["wall_s"] for s in st]))
                w(
                    f"- {name}: 64 starts at its measured time per start would take "
                    f"{64 * per:.0f} s (jaxbox: {j64['fit_s']:.2f} s, ×{ratio(64 * per, j64['fit_s']):.0f}); "
                    f"1024 starts {1024 * per / 3600:.1f} h."
                )
        w("")
    if "hierarchy" in res:
        w("## The experiment-1 hierarchy")
        w("")
        w(
            "Each model of the reference study's experiment-1 ladder on the same data; jaxbox from "
            "1, 64 and 1024 starts (compile: first call of the structure for that batch size; "
            "fit: the compiled solve), the peers from the first starts of the same 64-start set, "
            "one after the other (the richest model's peers are in the section above). *At best*: "
            f"starts within {REL:g} (relative) of the best cost any route found for that model."
        )
        w("")
        w(
            "| model | free | starts | jaxbox compile [s] | jaxbox fit [s] | per start [ms] | "
            "best cost | at best |"
        )
        w("|---|---:|---:|---:|---:|---:|---:|---:|")
        for name, row in res["hierarchy"].items():
            peer_costs = [
                st["cost"]
                for v in row["peers"].values()
                for st in v["starts"]
                if np.isfinite(st["cost"])
            ]
            best = min([v["best_cost"] for v in row["jaxbox"].values()] + peer_costs)
            row["best_any"] = best
            for S, v in row["jaxbox"].items():
                at = sum(c <= best * (1 + REL) for c in v["costs"])
                w(
                    f"| {name} | {row['free']} | {S} | {v['compile_s']:.2f} | {v['fit_s']:.3f} | "
                    f"{v['fit_s'] / int(S) * 1e3:.2f} | {v['best_cost']:.7g} | {at} / {S} |"
                )
        w("")
        w(
            "| model | peer | starts run | set-up [s] | per start [s] | best cost | at best | "
            "peer ÷ jaxbox per start | jaxbox best on the same starts |"
        )
        w("|---|---|---:|---:|---:|---:|---:|---:|---:|")
        for name, row in res["hierarchy"].items():
            j64 = row["jaxbox"].get(64) or row["jaxbox"].get("64")
            if not j64:
                continue
            jp = j64["fit_s"] / 64
            for peer, v in row["peers"].items():
                st = v["starts"]
                if not st:
                    continue
                k = len(st)
                per = float(np.mean([x["wall_s"] for x in st]))
                pc = np.asarray([x["cost"] for x in st])
                w(
                    f"| {name} | {peer} | {k} | {v['setup_s']:.1f} | {per:.2f} | "
                    f"{np.nanmin(pc):.7g} | {int(np.sum(pc <= row['best_any'] * (1 + REL)))} / {k} | "
                    f"{ratio(per, jp):.0f} | {min(j64['costs'][:k]):.7g} |"
                )
        w("")
    if "profile" in res:
        w("## Where the time goes: one evaluation of cost, Jᵀr and JᵀJ")
        w("")
        w(
            "| members | discretisation + derivatives [ms] | sensitivity scan [ms] | total [ms] | "
            "per member [µs] |"
        )
        w("|---:|---:|---:|---:|---:|")
        for B, v in res["profile"].items():
            w(
                f"| {B} | {v['matrices']:.2f} | {v['scan']:.2f} | {v['total']:.2f} | "
                f"{v['per_member_us']:.0f} |"
            )
        w("")
    if "diffrax" in res:
        d = res["diffrax"]
        w("## The diffrax route")
        w("")
        w(
            "Kvaerno5 (5th order, L-stable, implicit) with one fixed step a sample, forward-mode "
            "Jacobian through the solver (`jax.jacfwd`), the same Levenberg–Marquardt."
        )
        w("")
        w(
            "| starts | compile [s] | fit [s] | exact route fit [s] | diffrax ÷ exact | best cost "
            "(diffrax / exact) | LM steps (diffrax / exact) |"
        )
        w("|---:|---:|---:|---:|---:|---:|---:|")
        for S in (1, 16):
            v = d.get(S) or d.get(str(S))
            w(
                f"| {S} | {v['compile_s']:.1f} | {v['fit_s']:.2f} | {v['exact_fit_s']:.3f} | "
                f"{ratio(v['fit_s'], v['exact_fit_s']):.0f} | {v['best_cost']:.7g} / "
                f"{v['exact_best_cost']:.7g} | {v['steps_sum']} / {v['exact_steps_sum']} |"
            )
        w("")
        w(
            f"Fixed-step error at the optimum: {d['error_at_optimum_K']:.1e} K (largest deviation "
            f"from the exact solution), against a fit RMSE of {d['rmse_K']:.3f} K and 0.01–0.1 K "
            "sensor accuracy"
            + (
                ": well below the misfit, so one step a sample is honest for estimation"
                if d["error_at_optimum_K"] < 0.1 * d["rmse_K"]
                else ": below the misfit but not negligible against it — Kvaerno5 at fixed steps "
                "loses order on the piecewise-linear inputs (stiff order reduction), so estimate "
                "with `sim_options={'substeps': k}` or the exact route where this matters"
            )
            + "; validation always uses adaptive steps."
        )
        w("")
    if "long" in res:
        w("## A year of 10-minute data")
        w("")
        w(
            "52,560 samples (the N2 10-minute inputs repeated), `ZonWalIntInfWinBouC` simulated with "
            "known parameters plus 0.05 K noise, fitted in a separate process; peak memory is the "
            "process's maximum resident set size (Python, JAX and the data included)."
        )
        w("")
        w(
            "| starts | compile [s] | fit [s] | peak RSS [MB] | XLA scratch [MB] | RMSE [K] | "
            "converged |"
        )
        w("|---:|---:|---:|---:|---:|---:|---:|")
        for S, v in res["long"].items():
            if "error" in v:
                w(f"| {S} | error | | | | | |")
                continue
            w(
                f"| {S} | {v['compile_s']:.1f} | {v['fit_s']:.2f} | {v['peak_rss_mb']:.0f} | "
                f"{v['xla_temp_mb']:.0f} | {v['rmse']:.4f} | {v['converged']} |"
            )
        w("")
    if "parallel" in res:
        w("## Parallel in time (associative scan) vs sequential scan, simulation")
        w("")
        w("| samples | batch | sequential [ms] | associative scan [ms] | max difference [K] |")
        w("|---:|---:|---:|---:|---:|")
        for n, row in res["parallel"].items():
            for B, v in row.items():
                w(
                    f"| {n} | {B} | {v['sequential_ms']:.2f} | {v['parallel_ms']:.2f} | "
                    f"{v['max_diff_K']:.1e} |"
                )
        w("")
    if "buildings" in res:
        b = res["buildings"]
        w("## Several buildings in one call")
        w("")
        w(
            f"Twin houses N2 and O5 (identification halves, same length), 64 starts each: "
            f"separately {b['separate_compiles']} compilation(s), first calls {b['separate_first_s']:.1f} s, "
            f"fits {b['separate_fit_s']:.2f} s; with `fit_many` in one batch: "
            f"{b['batched_compiles']} compilation, first call {b['batched_first_s']:.1f} s, fit "
            f"{b['batched_fit_s']:.2f} s; best costs equal to {b['max_rel_cost_difference']:.1e} "
            "(relative)."
        )
        w("")
    if "cache" in res:
        c = res["cache"]
        w("## Persistent compilation cache")
        w("")
        w(
            f"`jaxbox._cache.enable_compilation_cache()`, 64-start fit in a new process: first process "
            f"compile {c['first']['compile_s']:.2f} s (process {c['first']['process_s']:.1f} s); second "
            f"process compile {c['second']['compile_s']:.2f} s (process {c['second']['process_s']:.1f} s) "
            "— what remains is tracing and lowering."
        )
        w("")
    if res.get("failed"):
        w("## Sections that failed in this run")
        w("")
        for key, err in res["failed"].items():
            w(f"- {key}: {err}")
        w("")
    w(res.get("notes", ""))
    for name in _TOPICS:  # written by benchmarks/<topic>.py (each its own run and date)
        section = HERE / f"{name}.md"
        if section.exists():
            w("")
            w(section.read_text())
    profile = HERE / "PROFILE.md"  # benchmarks/profile_select.py, between its markers
    if profile.exists():
        from profile_select import results_block

        w("")
        w(results_block(profile.read_text()))
    return "\n".join(L) + "\n"


#: section files of the topic benchmarks, appended to RESULTS.md in this order
_TOPICS = ("CONVERGENCE", "ZOO", "GAPS", "STOCHASTIC", "FLEET", "DESIGN", "GPU")

_SECTIONS = (
    "jaxbox",
    "profile",
    "peers",
    "hierarchy",
    "diffrax",
    "long",
    "parallel",
    "buildings",
    "cache",
)


def _int_keys(obj):
    """JSON turns integer keys (start counts, sizes) into strings; turn them back."""
    if isinstance(obj, dict):
        return {
            (int(k) if isinstance(k, str) and k.isdigit() else k): _int_keys(v)
            for k, v in obj.items()
        }
    if isinstance(obj, list):
        return [_int_keys(v) for v in obj]
    return obj


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="jaxbox only, 1 and 64 starts")
    ap.add_argument("--peers", default="casadi,scipy", help="comma list, or '' for none")
    ap.add_argument("--casadi-starts", type=int, default=16)
    ap.add_argument("--scipy-starts", type=int, default=1)
    ap.add_argument("--peer-budget", type=float, default=1800.0, help="seconds per peer")
    ap.add_argument("--hierarchy-casadi-starts", type=int, default=8)
    ap.add_argument(
        "--hierarchy-peer-budget", type=float, default=300.0, help="seconds per peer and model"
    )
    ap.add_argument(
        "--hierarchy-scipy-models",
        default="Zon,ZonWal",
        help="models of the hierarchy the scipy route runs on ('all', or a comma list; one "
        "start of a 3-4 state model takes 10+ minutes)",
    )
    ap.add_argument(
        "--resume",
        action="store_true",
        help="keep the sections of an interrupted run (benchmarks/results.partial.json)",
    )
    ap.add_argument(
        "--remeasure",
        default="",
        help="comma list of sections to measure again with the current code, keeping the "
        "others of benchmarks/results.json (e.g. the peers, which take an hour): "
        + ", ".join(_SECTIONS),
    )
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=str(HERE / "RESULTS.md"))
    ap.add_argument("--notes", default=str(HERE / "NOTES.md"), help="appended to the report")
    ap.add_argument(
        "--report-only",
        action="store_true",
        help="rewrite the report from benchmarks/results.json (and NOTES.md) without measuring",
    )
    args = ap.parse_args(argv)
    if args.report_only:
        res = json.loads((HERE / "results.json").read_text())
        notes = Path(args.notes)
        res["notes"] = notes.read_text() if notes.exists() else ""
        Path(args.out).write_text(report(_int_keys(res)))
        log(f"wrote {args.out}")
        return
    partial = HERE / "results.partial.json"
    res = {"argv": " ".join(sys.argv[1:]), "date": time.strftime("%Y-%m-%d %H:%M")}
    kept_peers: dict = {}
    again = [k for k in args.remeasure.split(",") if k]
    unknown = sorted(set(again) - set(_SECTIONS))
    if unknown:
        ap.error(f"unknown sections {unknown}; choose from {', '.join(_SECTIONS)}")
    if again and not (args.resume and partial.exists()):
        # the earlier run's sections but these (and the machine, measured now)
        old = _int_keys(json.loads((HERE / "results.json").read_text()))
        res = {k: v for k, v in old.items() if k not in again and k != "machine"}
        # a peer left out of --peers keeps its earlier result (scipy takes 15 minutes a start)
        kept_peers = {
            name: {**v, "kept_from": v.get("kept_from") or old.get("date")}
            for name, v in old.get("peers", {}).items()
            if "peers" in again and name not in args.peers.split(",")
        }
        res.setdefault("remeasured", []).append(
            {"date": time.strftime("%Y-%m-%d %H:%M"), "sections": again}
        )
        partial.write_text(json.dumps(res, indent=1, default=float))
        log(
            f"measuring again {', '.join(again)}; kept {', '.join(k for k in res if k in _SECTIONS)}"
        )
    elif args.resume and partial.exists():
        res = _int_keys(json.loads(partial.read_text()))
        res.setdefault("resumed", []).append(time.strftime("%Y-%m-%d %H:%M"))
        log(
            f"resuming the run of {res['date']}: kept {', '.join(k for k in res if k in _SECTIONS)}"
        )
    if "machine" not in res:
        log("machine")
        res["machine"] = machine()
    ident, _ = twinhouse_exp1("N2").split()
    counts = (1, 64) if args.quick else (1, 64, 1024)
    if "jaxbox" not in res:
        log("jaxbox multistart")
        res["jaxbox"] = jaxbox_starts(ident, counts, 2 if args.quick else args.repeats)
        res["starts64"] = res["jaxbox"].pop("starts64")
        partial.write_text(json.dumps(res, indent=1, default=float))
    if "starts64" not in res:  # the same deterministic Latin hypercube as jaxbox_starts
        problem = make_problem(jaxbox.get_model(MODEL), ident)
        res["starts64"] = make_starts(problem, ident, 64, 0, DEFAULT_CONCENTRATION).tolist()
    starts64 = res["starts64"]

    def section(key, title, fn, *a):
        """Run one section; a failure is logged and recorded, the others still run."""
        if key in res:
            return
        res.get("failed", {}).pop(key, None)
        log(title)
        try:
            res[key] = fn(*a)
        except Exception as err:  # a benchmark section must not lose the others
            log(f"  {title} failed: {type(err).__name__}: {err}")
            res.setdefault("failed", {})[key] = f"{type(err).__name__}: {err}"
        partial.write_text(json.dumps(res, indent=1, default=float))

    section("profile", "profile", profile_iteration, ident)
    peer_list = [p for p in args.peers.split(",") if p] if args.peers else []
    if not args.quick and peer_list:
        section(
            "peers",
            "peers",
            peers,
            ident,
            starts64,
            peer_list,
            args.casadi_starts,
            args.scipy_starts,
            args.peer_budget,
        )
        if again and res.get("peers") is not None:
            for name, v in kept_peers.items():
                res["peers"].setdefault(name, v)
    if not args.quick:
        section(
            "hierarchy",
            "the experiment-1 hierarchy",
            hierarchy,
            ident,
            counts,
            peer_list,
            args.hierarchy_casadi_starts,
            args.scipy_starts,
            args.hierarchy_peer_budget,
            None
            if args.hierarchy_scipy_models == "all"
            else set(args.hierarchy_scipy_models.split(",")),
        )
        section("diffrax", "diffrax route", diffrax_route, ident, 2)
        section("long", "long series", long_series, 52_560, (1, 16))
        section("parallel", "parallel in time", parallel_in_time, args.repeats)
        section("buildings", "buildings", buildings, 2)
        section("cache", "persistent cache", persistent_cache)
    res["load_end"] = os.getloadavg()
    res["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    notes = Path(args.notes)
    res["notes"] = notes.read_text() if notes.exists() else ""
    res.pop("starts64", None)
    (HERE / "results.json").write_text(json.dumps(res, indent=1, default=float))
    Path(args.out).write_text(report(res))
    partial.unlink(missing_ok=True)
    log(f"wrote {args.out}")


if __name__ == "__main__":
    main()
