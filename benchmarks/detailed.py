"""Structure search on detailed buildings outside the grammar: can the heat-loss coefficient be
trusted?

For each building of :func:`jaxbox.datasets.make_detailed_zoo` (15–20-state networks with
multi-layer walls, occupancy, scheduled ventilation, sun on every facade, PI thermostats or
open-loop heating, coloured and quantised sensor noise), the default ``jaxbox select`` is run
(the structure search, criterion ``cv``, its default beam and starts, the data split in halves)
and the accepted model's heat-loss coefficient with its 95 % interval, as ``select`` reports
it (:func:`jaxbox.validate.hlc_interval`: the accepted model's HAC interval widened over the
near-best structures), is compared with the truth (the static heat loss of the
detailed network at the mean ventilation).

Targets: a valid model on ≥ 95 % of the buildings; validation RMSE ≤ 0.3 K, HLC within ±15 %
of the truth, the 95 % interval covering the truth and no wider than ±25 %, each on ≥ 80 %.

Usage::

    python benchmarks/detailed.py [--n 40] [--seed 0] [--rerun] [--report-only] [--ablate K]
        [--reveal K]

``--ablate K`` searches the first K buildings again without their unmeasured occupancy gains
(``make_detailed_zoo(…, occupancy=False)``), to show how much of the HLC error they cause;
``--reveal K`` with the gains and the ground's temperature measured (``reveal=("gains",
"ground")``), to show what the two unmeasured quantities cost.

Each building's row is cached in ``benchmarks/detailed.json`` as soon as it is done, with the
git commit it was measured at; a second run resumes with the buildings not yet there
(``--rerun`` measures every building again). ``--out`` (``benchmarks/ZOO.md``) gets the section
"Detailed buildings (outside the grammar)" rewritten in place.
"""

from __future__ import annotations

import argparse
import inspect
import json
import math
import os
import platform
import subprocess
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SECTION = "## Detailed buildings (outside the grammar)"
KINDS = ("thermostat", "prbs", "rolbs")
#: targets: share of buildings
TARGETS = {
    "valid": 0.95,
    "rmse": 0.80,
    "hlc15": 0.80,
    "covers": 0.80,
    "narrow": 0.80,
}


def _commit() -> str:
    try:
        out = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            cwd=HERE,
            capture_output=True,
            text=True,
            check=True,
        )
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", "jaxbox"],
            cwd=HERE.parent,
            capture_output=True,
            text=True,
            check=True,
        )
        return out.stdout.strip() + ("+changes" if dirty.stdout.strip() else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def _select_defaults() -> dict:
    """The search settings of ``jaxbox select`` (its defaults, no copy kept here)."""
    import jaxbox
    from jaxbox.select import forward_selection

    starts = inspect.signature(forward_selection).parameters["starts"].default
    sig = inspect.signature(jaxbox.structure_search).parameters
    return {
        "starts": starts,
        "criterion": sig["criterion"].default,
        "beam": sig["beam"].default,
        "seed": 0,
    }


def run_one(b, settings: dict, commit: str = "") -> dict:
    import jaxbox
    from jaxbox.data import DataWarning
    from jaxbox.validate import fit_report, hlc_interval

    truth = float(b.kpis["hlc"])
    row = {
        "building": b.name,
        "network": b.structure,
        "states": b.states,
        "step": b.step,
        "heating": b.heating,
        "heater": b.heater,
        "use": b.use,
        "samples": len(b.data),
        "columns": list(b.data.columns),
        "hlc_true": truth,
        **gains(b),
        "commit": commit or _commit(),
    }
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DataWarning)
            # a ground at a constant temperature (revealed) is no stuck sensor
            held = {"stuck_hours": None} if "T_gro" in b.data.columns else {}
            gb = jaxbox.GreyBox(b.data, name=b.name, **held)
            s = jaxbox.structure_search(gb, **settings)
    except Exception as err:  # noqa: BLE001 - a benchmark row records any failure
        row.update(status="failed", error=f"{type(err).__name__}: {err}"[:300])
        row["search_s"] = time.perf_counter() - t0
        return row
    row["search_s"] = time.perf_counter() - t0
    row["candidates"] = len(s.tree)
    row["form"] = s.form
    if s.case is None and s.form_model is not None:  # a held zone's heat-demand or steady form
        m = s.form_model
        row.update(
            status="ok", accepted=f"{m.structure} ({s.form})" if hasattr(m, "structure") else s.form
        )
        v = float(m.hlc)
        lo, hi = map(float, m.hlc_interval)
        row.update(hlc=v, hlc_error=v / truth - 1.0, hlc_ci95=[lo, hi])
        row.update(covers=bool(lo <= truth <= hi), half_width=0.5 * (hi - lo) / abs(v))
        return row
    if s.case is None:
        row["status"] = "no_valid_model"
        return row
    case = s.case
    row["status"] = "ok"
    row["accepted"] = case.model.name
    rmse = case.validation.rmse_cross or case.validation.rmse_auto
    row["rmse_valid"] = float(np.mean(list(rmse.values())))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            doc = fit_report(case.result, case.valid, validation=case.validation)
        hlc = (doc.get("kpis") or {}).get("hlc")
    except Exception as err:  # noqa: BLE001
        row["kpi_error"] = f"{type(err).__name__}: {err}"[:300]
        hlc = None
    if hlc and hlc.get("ci95") is not None:  # the accepted model's own (HAC) interval
        row["hlc_ci95_model"] = [float(x) for x in hlc["ci95"]]
    try:  # what `jaxbox select` reports: widened over the near-best structures
        spread = hlc_interval(s)
        if spread is not None:
            hlc = {**(hlc or {}), **spread.to_dict()}
            row["hlc_method"] = spread.method
    except Exception as err:  # noqa: BLE001
        row["spread_error"] = f"{type(err).__name__}: {err}"[:300]
    if hlc and hlc.get("value") is not None:
        v = float(hlc["value"])
        row["hlc"] = v
        row["hlc_error"] = v / truth - 1.0
        ci = hlc.get("ci95")
        if ci is not None:
            lo, hi = map(float, ci)
            row["hlc_ci95"] = [lo, hi]
            row["covers"] = bool(lo <= truth <= hi)
            row["half_width"] = 0.5 * (hi - lo) / abs(v)
    return row


def _undetermined(rows: list[dict]) -> str:
    """How often the reported HLC is marked not determined (its interval wider than ±100 % of
    its value, :attr:`jaxbox.validate.HlcInterval.determined`), and its error there and
    elsewhere."""
    marked = [abs(r["hlc_error"]) for r in rows if r.get("half_width", 0.0) > 1.0]
    other = [abs(r["hlc_error"]) for r in rows if 0.0 <= r.get("half_width", -1.0) <= 1.0]
    if not marked:
        return "No HLC is marked not determined (an interval wider than ±100 % of its value)."
    return (
        f"The HLC is marked not determined (its interval wider than ±100 % of its value) on "
        f"{len(marked)} of {len(rows)}: median |error| {100 * np.median(marked):.0f} % there, "
        f"{100 * np.median(other):.0f} % on the other {len(other)}."
    )


def gains(b) -> dict:
    """Mean unmeasured occupancy gain [W] and mean measured heating [W] over the building's
    data, the gain's share of the two (a model without the gain explains the warmth it brings
    by a lower HLC), and the share of the HLC lost through the floor to an unmeasured ground
    (0 with a measured cellar)."""
    from jaxbox.datasets._detailed import _occupancy

    occ = float(b.params["q_occ_peak"] * np.mean(_occupancy(b.data.index, b.use)))
    heat = float(np.nanmean(b.data.frame["Q_hea"].to_numpy()))
    ground = 0.0 if "T_bou" in b.data.columns else b.hlc_parts["floor"] / b.kpis["hlc"]
    return {
        "gains_w": occ,
        "heating_w": heat,
        "gains_share": occ / (occ + heat),
        "ground_share": ground,
    }


def _fill(rows: list[dict], zoo) -> None:
    """Add :func:`gains` to rows measured without it."""
    by_name = {b.name: b for b in zoo}
    for r in rows:
        if "ground_share" not in r and r["building"] in by_name:
            r.update(gains(by_name[r["building"]]))


def _checks(r: dict) -> dict:
    ok = r.get("status") == "ok"
    return {
        "valid": ok,
        "rmse": ok and r.get("rmse_valid", np.inf) <= 0.3,
        "hlc15": ok and abs(r.get("hlc_error", np.inf)) <= 0.15,
        "covers": ok and bool(r.get("covers", False)),
        "narrow": ok and r.get("half_width", np.inf) <= 0.25,
    }


def markdown(doc: dict) -> str:
    rows = doc["rows"]
    n = len(rows)
    commits = sorted({r.get("commit", "?") for r in rows})
    lines = [
        SECTION,
        "",
        f"Written by `python benchmarks/detailed.py` (last row {doc['date']}); {doc['machine']}; "
        f"jaxbox at commit{'s' if len(commits) > 1 else ''} {', '.join(commits)} (`+changes`: "
        "with uncommitted changes to `jaxbox/` in the working tree); raw numbers in "
        "`benchmarks/detailed.json`. Buildings of `jaxbox.datasets.make_detailed_zoo("
        f"{doc['n']}, seed={doc['seed']})`: 15–20-state networks (multi-layer walls and roof, a "
        "floor slab to the ground or a measured cellar, an internal mass, a radiator or a floor "
        "heating), unmeasured occupancy gains, scheduled ventilation, the sun on each facade, "
        "PI thermostats with night setback or open-loop PRBS/ROLBS heating, white and AR(1) "
        "sensor noise quantised to 0.1 K — no structure of the grammar is the truth. Each is "
        "searched as `jaxbox select` does (structure search, criterion "
        f"{doc['settings']['criterion']}, beam {doc['settings']['beam']}, "
        f"{doc['settings']['starts']} starts per candidate, data split in halves); the HLC and "
        "its 95 % interval are those `select` reports, the truth the static heat loss of the "
        "detailed network at its mean ventilation.",
        "",
    ]
    if n < doc["n"]:
        lines += [f"{n} of the {doc['n']} buildings are done; the numbers are theirs.", ""]
    labels = {
        "valid": "valid model",
        "rmse": "validation RMSE ≤ 0.3 K",
        "hlc15": "HLC within ±15 %",
        "covers": "95 % interval covers the truth",
        "narrow": "interval no wider than ±25 %",
    }
    groups = [("all", rows)] + [(k, [r for r in rows if r["heating"] == k]) for k in KINDS]
    head = "| target | goal | " + " | ".join(f"{g} ({len(rs)})" for g, rs in groups) + " |"
    lines += [head, "|---|---:|" + "---:|" * len(groups)]
    for key, label in labels.items():
        cells = []
        for g, rs in groups:
            hit = sum(_checks(r)[key] for r in rs)
            share = hit / len(rs) if rs else float("nan")
            mark = " ✓" if g == "all" and rs and share >= TARGETS[key] else ""
            mark = " ✗" if g == "all" and rs and share < TARGETS[key] else mark
            cells.append(f"{hit}/{len(rs)} ({100 * share:.0f} %){mark}" if rs else "–")
        lines.append(f"| {label} | ≥ {100 * TARGETS[key]:.0f} % | " + " | ".join(cells) + " |")
    errs = [abs(r["hlc_error"]) for r in rows if "hlc_error" in r]
    if errs:
        lines += [
            "",
            f"HLC error |reported/true − 1|: median {100 * np.median(errs):.1f} %, 90th "
            f"percentile {100 * np.percentile(errs, 90):.1f} %, worst {100 * max(errs):.1f} %; "
            f"median search {np.median([r['search_s'] for r in rows]):.0f} s.",
            "",
            _undetermined(rows),
            "",
            "| group | buildings | median signed HLC error | HLC within ±15 % | interval covers |",
            "|---|---:|---:|---:|---:|",
        ]
        split = [
            ("radiator", lambda r: r["heater"] == "radiator"),
            ("floor heating", lambda r: r["heater"] == "floor"),
            ("floor to the ground (unmeasured)", lambda r: "T_bou" not in r["columns"]),
            ("floor to a measured cellar (T_bou)", lambda r: "T_bou" in r["columns"]),
            ("facade irradiances measured", lambda r: "I_s" in r["columns"]),
            ("global horizontal only", lambda r: "I_s" not in r["columns"]),
        ] + [(f"step {s}", lambda r, s=s: r["step"] == s) for s in ("10min", "30min", "60min")]
        split += [
            (
                "unmeasured gains < 15 % of gains + heating",
                lambda r: r.get("gains_share", 1.0) < 0.15,
            ),
            (
                "unmeasured gains ≥ 15 % of gains + heating",
                lambda r: r.get("gains_share", 0.0) >= 0.15,
            ),
        ]
        for label, keep in split:
            rs = [r for r in rows if keep(r)]
            signed = [r["hlc_error"] for r in rs if "hlc_error" in r]
            if not rs:
                continue
            med = f"{100 * np.median(signed):+.1f} %" if signed else "–"
            lines.append(
                f"| {label} | {len(rs)} | {med} | {sum(_checks(r)['hlc15'] for r in rs)} | "
                f"{sum(_checks(r)['covers'] for r in rs)} |"
            )
        both = [(r["gains_share"], r["hlc_error"]) for r in rows if "hlc_error" in r]
        both = [(g, e) for g, e in both if g is not None]
        if len(both) > 2:
            g, e = np.asarray(both).T
            lines += [
                "",
                "The unmeasured occupancy gains' share of the mean heat input (gains + heating) "
                f"is {100 * np.median(g):.0f} % at the median; the HLC error correlates with it "
                f"(Pearson r = {np.corrcoef(g, e)[0, 1]:+.2f}; a model without the gains "
                "explains the warmth they bring by a lower HLC, by about that share).",
            ]
        both = [(r["ground_share"], r["hlc_error"]) for r in rows if "hlc_error" in r]
        both = [(g, e) for g, e in both if g is not None and g > 0]
        if len(both) > 2:
            g, e = np.asarray(both).T
            lines += [
                "",
                "The floor's share of the HLC, lost to a ground at an unmeasured constant "
                f"temperature, is {100 * np.median(g):.0f} % at the median on the {len(g)} "
                "buildings without a measured cellar; the HLC error correlates with it "
                f"(Pearson r = {np.corrcoef(g, e)[0, 1]:+.2f}).",
            ]
            lines += _without_ground(rows, doc.get("revealed", []))
    lines += _rerun(doc, "ablation") + _rerun(doc, "revealed")
    lines += [
        "",
        "| building | step | heating | heater | states | accepted | RMSE [K] | true HLC [W/K] | "
        "reported [W/K] | 95 % interval | error | half-width | covers |",
        "|---|---|---|---|---:|---|---:|---:|---:|---|---:|---:|---|",
    ]
    for r in rows:
        if r.get("status") != "ok":
            lines.append(
                f"| {r['building']} | {r['step']} | {r['heating']} | {r['heater']} | "
                f"{r['states']} | {r.get('status')} | – | {r['hlc_true']:.0f} | – | – | – | – | – |"
            )
            continue
        ci = r.get("hlc_ci95")
        lines.append(
            f"| {r['building']} | {r['step']} | {r['heating']} | {r['heater']} | {r['states']} | "
            f"{r['accepted']} | {r['rmse_valid']:.3f} | {r['hlc_true']:.0f} | "
            + (f"{r['hlc']:.0f}" if "hlc" in r else "–")
            + " | "
            + (f"{ci[0]:.0f}–{ci[1]:.0f}" if ci else "–")
            + " | "
            + (f"{100 * r['hlc_error']:+.1f} %" if "hlc_error" in r else "–")
            + " | "
            + (f"±{100 * r['half_width']:.1f} %" if "half_width" in r else "–")
            + " | "
            + ("yes" if r.get("covers") else "no")
            + " |"
        )
    return "\n".join(lines) + "\n"


#: the reruns of the first buildings with one thing changed: key in the json, option, the words
#: for the markdown (what changed, the label of the two columns)
_RERUNS = {
    "ablation": (
        "--ablate",
        "Without the unmeasured occupancy gains (`--ablate {k}`: the first {k} buildings again, "
        "`make_detailed_zoo(…, occupancy=False)`, the ventilation at its base rate throughout, "
        "everything else the same):",
        ("with gains", "without"),
    ),
    "revealed": (
        "--reveal",
        "With what the data leave unmeasured measured after all (`--reveal {k}`: the first {k} "
        "buildings again, `make_detailed_zoo(…, reveal=('gains', 'ground'))`: the occupancy gains "
        "as a column `P_ele` (token `Ele`) and the ground's temperature as `T_gro` (token `Gro`) "
        "where the floor lies on the ground; the same buildings and data otherwise). What the "
        "search gains here is what the two unmeasured quantities cost:",
        ("as measured", "revealed"),
    ),
}


def _rerun(doc: dict, key: str) -> list[str]:
    """The first buildings again with one thing changed (``--ablate``, ``--reveal``), against
    the rows."""
    again = doc.get(key) or []
    if not again:
        return []
    option, intro, (a_, b_) = _RERUNS[key]
    rows = {r["building"]: r for r in doc["rows"]}
    pairs = [(rows[a["building"]], a) for a in again if a["building"] in rows]
    lines = [
        "",
        intro.format(k=len(pairs)),
        "",
        f"| building | heating | accepted {a_} | HLC error | accepted {b_} | "
        f"HLC error | covers ({a_} / {b_}) |",
        "|---|---|---|---:|---|---:|---|",
    ]

    def err(r):
        return f"{100 * r['hlc_error']:+.1f} %" if "hlc_error" in r else r.get("status", "–")

    for r, a in pairs:
        lines.append(
            f"| {r['building']} | {r['heating']} | {r.get('accepted', '–')} | {err(r)} | "
            f"{a.get('accepted', '–')} | {err(a)} | "
            f"{'yes' if r.get('covers') else 'no'} / {'yes' if a.get('covers') else 'no'} |"
        )
    first = [abs(r["hlc_error"]) for r, _ in pairs if "hlc_error" in r]
    second = [abs(a["hlc_error"]) for _, a in pairs if "hlc_error" in a]
    if first and second:
        signed = [a["hlc_error"] for _, a in pairs if "hlc_error" in a]
        rmse = [a["rmse_valid"] for _, a in pairs if "rmse_valid" in a]
        lines += [
            "",
            f"Median |HLC error| {100 * np.median(first):.1f} % {a_}, "
            f"{100 * np.median(second):.1f} % {b_} (median signed {100 * np.median(signed):+.1f} "
            f"%); within ±15 %: {sum(e <= 0.15 for e in first)}/{len(first)} {a_}, "
            f"{sum(e <= 0.15 for e in second)}/{len(second)} {b_}; the interval covers the "
            f"truth {sum(bool(r.get('covers')) for r, _ in pairs)}/{len(pairs)} {a_}, "
            f"{sum(bool(a.get('covers')) for _, a in pairs)}/{len(pairs)} {b_}; validation "
            f"RMSE ≤ 0.3 K {sum(x <= 0.3 for x in rmse)}/{len(pairs)} {b_}.",
        ]
    return lines


def _write(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (a stopped run leaves the last complete file)."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def write_section(path: Path, text: str, section: str = SECTION) -> None:
    """Replace (or append) the section ``section`` (a ``## `` heading, by default
    :data:`SECTION`) of the markdown file ``path``, up to the next such heading."""
    old = path.read_text() if path.exists() else ""
    if section in old:
        head, rest = old.split(section, 1)
        nxt = rest.find("\n## ")
        tail = "" if nxt < 0 else rest[nxt + 1 :]
        new = head + text + ("\n" + tail if tail else "")
    else:
        new = old.rstrip("\n") + ("\n\n" if old else "") + text
    _write(path, new)


def _without_ground(rows: list[dict], revealed: list[dict]) -> list[str]:
    """What the reported HLC matches if the ground's conductance is taken out of the truth: a
    ground at a constant temperature takes a constant heat from a zone held at a constant
    temperature, which a model puts into its offset, not into its HLC."""
    got = []
    for r in rows:
        if r.get("hlc") is None or r.get("ground_share") is None or not r.get("hlc_true"):
            continue
        ref = r["hlc_true"] * (1.0 - r["ground_share"])
        lo, hi = r.get("hlc_ci95") or (math.nan, math.nan)
        got.append((r["ground_share"] > 0, r["hlc"] / ref - 1.0, lo <= ref <= hi))
    eg = np.asarray([e for g, e, _ in got if g])
    if len(eg) < 3:
        return []
    measured = [r for r in revealed if "T_gro" in r.get("columns", ())]
    n_gro = sum("Gro" in (r.get("accepted") or "") for r in measured)
    whole = [r["hlc_error"] for r in rows if r.get("ground_share") and "hlc_error" in r]
    e = np.asarray([x for _, x, _ in got])
    return [
        "",
        "Against the truth without the floor's conductance to the ground (the conductance to "
        "the outdoor air and to a measured cellar only): on the "
        f"{len(eg)} buildings on the ground the median signed error is "
        f"{100 * np.median(eg):+.1f} % (against the whole truth "
        f"{100 * np.median(whole):+.1f} %); "
        f"on all {len(got)}, within ±15 % {int(np.sum(np.abs(e) <= 0.15))}, the interval "
        f"covers {sum(c for _, _, c in got)}. What the models miss is mostly that "
        "conductance: the ground's heat flows through a heavy slab to a constant temperature, "
        "so over a record of days it changes only with the zone's slow mean, which an offset "
        "or a lower HLC absorbs as well (with the ground's temperature given as a column, "
        f"`--reveal`, the search takes it on {n_gro} of the {len(measured)} buildings).",
    ]


def _rerun_first(doc, key, kept, k, changed, args, settings, path) -> None:
    """Search the first ``k`` buildings again, made with ``changed`` (``make_detailed_zoo``
    options), into ``doc[key]`` (those in ``kept`` are not searched again)."""
    import jaxbox

    again = jaxbox.datasets.make_detailed_zoo(args.n, seed=args.seed, **changed)
    for b in again[:k]:
        if b.name in kept:
            continue
        row = run_one(b, settings, doc["commit"])
        jaxbox._compiled.release()
        doc[key].append(row)
        print(json.dumps(row), flush=True)
        _write(path, json.dumps(doc, indent=1))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=str(HERE / "ZOO.md"))
    ap.add_argument("--json", default=str(HERE / "detailed.json"))
    ap.add_argument("--rerun", action="store_true", help="measure every building again")
    ap.add_argument("--report-only", action="store_true", help="rewrite --out from --json")
    ap.add_argument("--only", default="", help="comma list of buildings (d003,…)")
    ap.add_argument(
        "--ablate",
        type=int,
        default=0,
        help="also search the first K buildings again without occupancy gains",
    )
    ap.add_argument(
        "--reveal",
        type=int,
        default=0,
        help="also search the first K buildings again with the gains and ground measured",
    )
    args = ap.parse_args(argv)
    path = Path(args.json)
    if args.report_only:
        doc = json.loads(path.read_text())
        if any("ground_share" not in r for r in doc["rows"]):
            import jaxbox

            _fill(doc["rows"], jaxbox.datasets.make_detailed_zoo(doc["n"], seed=doc["seed"]))
            _write(path, json.dumps(doc, indent=1))
        write_section(Path(args.out), markdown(doc))
        print(markdown(doc))
        return

    import jaxbox

    jaxbox.enable_x64()
    jaxbox.enable_compilation_cache()
    settings = _select_defaults()
    zoo = jaxbox.datasets.make_detailed_zoo(args.n, seed=args.seed)
    done: dict[str, dict] = {}
    ablated: dict[str, dict] = {}
    revealed: dict[str, dict] = {}
    old = json.loads(path.read_text()) if path.exists() else {}
    if old.get("seed") == args.seed:
        if not args.rerun:
            _fill(old.get("rows", []), zoo)
            done = {r["building"]: r for r in old.get("rows", [])}
        if not (args.rerun and args.ablate):  # a rerun keeps the ablation unless it is asked for
            ablated = {r["building"]: r for r in old.get("ablation", [])}
        if not (args.rerun and args.reveal):
            revealed = {r["building"]: r for r in old.get("revealed", [])}
    doc = {
        "date": time.strftime("%Y-%m-%d %H:%M"),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, one building at a time",
        "n": args.n,
        "seed": args.seed,
        "settings": settings,
        "commit": _commit(),
        "rows": [],
    }
    chosen = set(args.only.split(",")) if args.only else None
    for b in zoo:
        if b.name in done and (chosen is None or b.name not in chosen):
            doc["rows"].append(done[b.name])
            continue
        if chosen is not None and b.name not in chosen:
            continue
        row = run_one(b, settings, doc["commit"])  # the code imported at the start
        jaxbox._compiled.release()  # every building compiles new structures
        doc["rows"].append(row)
        doc["date"] = time.strftime("%Y-%m-%d %H:%M")
        print(json.dumps(row), flush=True)
        _write(path, json.dumps(doc, indent=1))
        write_section(Path(args.out), markdown(doc))
    reruns = (
        ("ablation", ablated, args.ablate, {"occupancy": False}),
        ("revealed", revealed, args.reveal, {"reveal": ("gains", "ground")}),
    )
    for key, kept, k, changed in reruns:
        if kept or k:
            doc[key] = [kept[b.name] for b in zoo if b.name in kept]
        if k:
            _rerun_first(doc, key, kept, k, changed, args, settings, path)
    _write(path, json.dumps(doc, indent=1))
    write_section(Path(args.out), markdown(doc))
    print(markdown(doc))


if __name__ == "__main__":
    main()
