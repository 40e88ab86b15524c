"""Detailed buildings: what HLC can any candidate of the search reach?

The detailed zoo (:func:`jaxbox.datasets.make_detailed_zoo`) asks the default ``select`` for a
heat-loss coefficient within ±15 % of the truth on 80 % of the buildings. This script asks a
question before that one: among *all* the candidates the search fitted on a building, is
there one whose HLC is within ±15 %? If none is, no rule choosing among them can meet the
target, and the error is in what the data and the grammar determine, not in the choice.

For each building the default ``jaxbox.structure_search`` runs (as ``benchmarks/detailed.py``
does); then, per fitted candidate, its HLC at the optimum (:func:`jaxbox.validate.kpi_values`)
and whether it is valid. Reported per building: the accepted model's HLC error, the closest
HLC of any valid candidate and of any candidate, whether the truth lies within the span of the
valid candidates' HLCs, and the accepted structure refitted on the whole record (both halves:
twice the weather a split leaves the fit).

Usage::

    python benchmarks/hlc_reach.py [--n 40] [--seed 0] [--reveal] [--report-only]

``--reveal`` runs the same buildings with the occupancy gains and the ground's temperature
measured (``reveal=("gains", "ground")``), kept under its own key. Rows are cached in
``benchmarks/hlc_reach.json`` as they are done; the section
"Detailed buildings: the HLC any candidate reaches" of ``benchmarks/ZOO.md`` is rewritten.
"""

from __future__ import annotations

import argparse
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
from detailed import _commit, _write, write_section  # noqa: E402  (the detailed zoo's script)

SECTION = "## Detailed buildings: the HLC any candidate reaches (benchmarks/hlc_reach.py)"
WITHIN = 0.15


def run_one(b) -> dict:
    """The search on building ``b`` and the HLC of every candidate it fitted."""
    import jaxbox
    from jaxbox.data import DataWarning
    from jaxbox.validate import hlc_interval, kpi_values, kpis

    truth = float(b.kpis["hlc"])
    row = {"building": b.name, "heating": b.heating, "heater": b.heater, "step": b.step}
    row.update(hlc_true=truth, ground="T_bou" not in b.data.columns, samples=len(b.data))
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        held = {"stuck_hours": None} if "T_gro" in b.data.columns else {}
        gb = jaxbox.GreyBox(b.data, name=b.name, **held)
        s = jaxbox.structure_search(gb, seed=0)
        cands = []
        for name, case in gb.cases.items():
            if not case.done or case.result is None:
                continue
            try:
                h = kpi_values(case.model, case.result.params).get("hlc")
            except Exception:  # noqa: BLE001 - a candidate without an HLC is left out
                h = None
            if h is None or not np.isfinite(h):
                continue
            judged = case.verdict is not None
            cands.append(
                {
                    "case": name,
                    "model": case.model.name,
                    "hlc": float(h),
                    "error": float(h) / truth - 1.0,
                    "score": float(case.score),
                    "valid": bool(case.is_valid) if judged else None,
                    "accepted": s.case is not None and case is s.case,
                }
            )
        row["search_s"] = time.perf_counter() - t0
        row["candidates"] = cands
        acc = next((c for c in cands if c["accepted"]), None)
        if acc is not None:
            row["accepted"] = acc["model"]
            row["error"] = acc["error"]
            try:  # the interval `select` reports
                row["ci95"] = [float(v) for v in hlc_interval(s).ci95]
            except Exception as err:  # noqa: BLE001
                row["ci_failed"] = f"{type(err).__name__}: {err}"[:200]
            whole = jaxbox.GreyBox(b.data, name=b.name, train=(None, None), valid=False, **held)
            try:
                hlc = kpis(whole.identify(acc["model"]).result, interval="hac").hlc
                row["whole_error"] = float(hlc.value) / truth - 1.0
                row["whole_ci95"] = [float(v) for v in hlc.ci95]
            except Exception as err:  # noqa: BLE001 - a benchmark row records any failure
                row["whole_failed"] = f"{type(err).__name__}: {err}"[:200]
    return row


def _closest(cands, valid_only: bool) -> float:
    errs = [abs(c["error"]) for c in cands if (c["valid"] is True or not valid_only)]
    return min(errs) if errs else float("inf")


def _span(cands) -> bool:
    errs = [c["error"] for c in cands if c["valid"] is True]
    return bool(errs) and min(errs) <= 0.0 <= max(errs)


def _summary(rows: list[dict]) -> dict:
    ok = [r for r in rows if "error" in r]
    return {
        "n": len(rows),
        "accepted": sum(abs(r["error"]) <= WITHIN for r in ok),
        "whole": sum(abs(r.get("whole_error", np.inf)) <= WITHIN for r in ok),
        "closest_valid": sum(_closest(r["candidates"], True) <= WITHIN for r in rows),
        "closest_any": sum(_closest(r["candidates"], False) <= WITHIN for r in rows),
        "span": sum(_span(r["candidates"]) for r in rows),
        "covers": sum(_covers(r, "ci95") for r in ok),
        "whole_covers": sum(_covers(r, "whole_ci95") for r in ok),
        "narrow": sum(_narrow(r, "ci95", r["error"]) for r in ok),
        "whole_narrow": sum(_narrow(r, "whole_ci95", r.get("whole_error", np.nan)) for r in ok),
        "intervals": sum("ci95" in r for r in ok),
    }


def _covers(r: dict, key: str) -> bool:
    ci = r.get(key)
    return ci is not None and ci[0] <= r["hlc_true"] <= ci[1]


def _narrow(r: dict, key: str, error: float) -> bool:
    """The interval ``key`` no wider than ±25 % of its own HLC."""
    ci = r.get(key)
    if ci is None or not np.isfinite(error):
        return False
    value = r["hlc_true"] * (1.0 + error)
    return 0.5 * (ci[1] - ci[0]) <= 0.25 * abs(value)


MARGINS = (0.02, 0.05, 0.1, 0.25, 0.5, 1.0)


def _near(r: dict, margin: float) -> list[float]:
    """The HLC errors of the candidates not found invalid (valid, or left unjudged by the
    search, which judges lazily) whose criterion is within ``margin`` (relative) of the
    accepted model's, the accepted model's first."""
    acc = next((c for c in r["candidates"] if c["accepted"]), None)
    if acc is None:
        return []
    lim = (1.0 + margin) * acc["score"]
    near = [
        c["error"]
        for c in r["candidates"]
        if c is not acc and c["valid"] is not False and c["score"] <= lim
    ]
    return [acc["error"], *near]


def _margins(rows: list[dict]) -> list[str]:
    """Coverage and width of the span of the near-best candidates' HLCs, per margin."""
    out = [
        "| margin | candidates in the span (median) | truth within the span | "
        "span within ±25 % of the accepted HLC |",
        "|---:|---:|---:|---:|",
    ]
    ok = [r for r in rows if "error" in r]
    for m in MARGINS:
        spans = [_near(r, m) for r in ok]
        cover = sum(min(e) <= 0.0 <= max(e) for e in spans)
        narrow = 0
        for r, e in zip(ok, spans, strict=True):
            lo, hi = (1.0 + min(e)) / (1.0 + r["error"]), (1.0 + max(e)) / (1.0 + r["error"])
            narrow += lo >= 0.75 and hi <= 1.25
        n_in = float(np.median([len(e) for e in spans])) if spans else 0.0
        out.append(f"| {m:.0%} | {n_in:.0f} | {_pct(cover, len(ok))} | {_pct(narrow, len(ok))} |")
    return out


def _pct(k: int, n: int) -> str:
    return f"{k}/{n} ({100 * k / max(n, 1):.0f} %)"


def markdown(doc: dict) -> str:
    lines = [
        SECTION,
        "",
        f"Written by `python benchmarks/hlc_reach.py` ({doc['date']}); {doc['machine']}; jaxbox "
        f"at {doc['commit']}; raw numbers in `benchmarks/hlc_reach.json`. The buildings of the "
        f"section above (`make_detailed_zoo({doc['n']}, seed={doc['seed']})`), each searched by "
        "the default `structure_search`; then the HLC of every candidate it fitted (at its "
        "optimum on the identification half). *Closest valid*: some valid candidate within "
        "±15 % of the truth; *closest of all*: some candidate, valid or not; *span*: the truth "
        "between the lowest and the highest HLC of the valid candidates; *whole record*: the "
        "accepted structure refitted on both halves. If no candidate comes within ±15 %, no "
        "rule choosing among them can.",
        "",
    ]
    groups = [("as measured", doc.get("rows", []))]
    if doc.get("revealed"):
        at = f", at {doc['revealed_commit']}" if doc.get("revealed_commit") else ""
        groups.append((f"gains and ground measured (`--reveal`{at})", doc["revealed"]))
    lines += [
        "| data | buildings | accepted within ±15 % | whole record | closest valid | "
        "closest of all | truth within the valid span |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for label, rows in groups:
        if not rows:
            continue
        s = _summary(rows)
        n = s["n"]
        lines.append(
            f"| {label} | {n} | {_pct(s['accepted'], n)} | {_pct(s['whole'], n)} | "
            f"{_pct(s['closest_valid'], n)} | {_pct(s['closest_any'], n)} | {_pct(s['span'], n)} |"
        )
    lines.append("")
    lines += [
        "The 95 % interval `select` reports (`hlc_interval`, on the identification half) against "
        "the accepted structure's own HAC interval refitted on the whole record (covers the "
        "truth / no wider than ±25 %):",
        "",
        "| data | buildings | `select`'s interval covers | narrow | whole record covers | narrow |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for label, rows in groups:
        s = _summary(rows)
        if not s["intervals"]:
            continue
        n = s["n"]
        lines.append(
            f"| {label} | {n} | {_pct(s['covers'], n)} | {_pct(s['narrow'], n)} | "
            f"{_pct(s['whole_covers'], n)} | {_pct(s['whole_narrow'], n)} |"
        )
    lines.append("")
    rows = doc.get("rows", [])
    if rows:
        lines += [
            "By kind, as measured (within ±15 %: accepted / closest valid / closest of all):",
            "",
            "| group | buildings | accepted | closest valid | closest of all |",
            "|---|---:|---:|---:|---:|",
        ]
        kinds = sorted({r["heating"] for r in rows})
        sel = [(k, [r for r in rows if r["heating"] == k]) for k in kinds]
        sel += [
            ("floor to the ground (unmeasured)", [r for r in rows if r["ground"]]),
            ("floor to a measured cellar", [r for r in rows if not r["ground"]]),
        ]
        for label, rs in sel:
            s = _summary(rs)
            lines.append(
                f"| {label} | {s['n']} | {s['accepted']} | {s['closest_valid']} | "
                f"{s['closest_any']} |"
            )
        lines += [
            "",
            "The span of the HLC point estimates of the candidates not found invalid (valid, "
            "or not judged: the search judges validity lazily) whose criterion (the validation "
            "SE) is within a margin of the accepted model's, as the structure part of "
            "`hlc_interval` takes them (there at 2 %, each with its own interval, which widens "
            "the span further): how often it holds the truth, and how often it stays within "
            "±25 % of the accepted HLC:",
            "",
            *_margins(rows),
        ]
        lines += [
            "",
            "| building | heating | accepted | error | whole record | valid candidates | "
            "their HLC errors (lowest … highest) | closest valid |",
            "|---|---|---|---:|---:|---:|---|---:|",
        ]
        for r in rows:
            v = [c["error"] for c in r["candidates"] if c["valid"] is True]
            span = f"{min(v):+.0%} … {max(v):+.0%}" if v else "–"
            we = r.get("whole_error")
            lines.append(
                f"| {r['building']} | {r['heating']} | {r.get('accepted', '–')} | "
                f"{r.get('error', float('nan')):+.1%} | "
                f"{'–' if we is None else f'{we:+.1%}'} | {len(v)} | {span} | "
                f"{_closest(r['candidates'], True):.1%} |"
            )
    return "\n".join(lines).replace("+nan%", "–") + "\n"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--reveal", action="store_true", help="the gains and ground measured")
    ap.add_argument("--out", default=str(HERE / "ZOO.md"))
    ap.add_argument("--json", default=str(HERE / "hlc_reach.json"))
    ap.add_argument("--report-only", action="store_true")
    args = ap.parse_args(argv)
    path = Path(args.json)
    doc = json.loads(path.read_text()) if path.exists() else {}
    if args.report_only:
        write_section(Path(args.out), markdown(doc), SECTION)
        print(markdown(doc))
        return
    import jaxbox

    jaxbox.enable_x64()
    key = "revealed" if args.reveal else "rows"
    if doc.get("n") != args.n or doc.get("seed") != args.seed:
        doc = {"n": args.n, "seed": args.seed}
    doc.update(
        date=time.strftime("%Y-%m-%d %H:%M"),
        machine=f"{platform.machine()}, {os.cpu_count()} cores",
    )
    doc["commit" if key == "rows" else "revealed_commit"] = _commit()
    kept = {r["building"]: r for r in doc.get(key, [])}
    reveal = ("gains", "ground") if args.reveal else ()
    zoo = jaxbox.datasets.make_detailed_zoo(args.n, seed=args.seed, reveal=reveal)
    doc[key] = []
    for b in zoo:
        row = kept.get(b.name) or run_one(b)
        if b.name not in kept:
            jaxbox._compiled.release()
            print(b.name, row.get("accepted"), f"{row.get('error', float('nan')):+.2f}", flush=True)
        doc[key].append(row)
        _write(path, json.dumps(doc, indent=1))
        write_section(Path(args.out), markdown(doc), SECTION)
    print(markdown(doc))


if __name__ == "__main__":
    main()
