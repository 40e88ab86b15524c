"""The exhaustive reference of the structure search, and the search's regret against it.

For a building, every structure the component grammar allows up to ``--components`` components
is identified (level by level, each level in one batched call, each structure starting from the
optimum of the structure one component smaller that first reached it, as in the search), judged
with the same verdict and the same reductions (:mod:`jaxbox.select._reduce`), and the best valid
one is chosen by the same criterion (:func:`jaxbox.select._search._accept`). The default
``select`` (:func:`jaxbox.structure_search`) runs on the same GreyBox data; its *regret* is its
validation SE divided by the exhaustive best's (≤ 1 where the search accepted a structure larger
than the exhaustive reference goes).

Buildings: a sample of the zoo (``--zoo N``), the twin houses as shipped (``N2``, ``O5``), the
twin-house preparations of :data:`_buildings.VARIANTS` (``--variants 1h``: those at that step;
``1h,10min`` for all), DarkGreyBox's demo office and the Purdue house (``../shared/data``).

Usage::

    python benchmarks/exhaustive.py [--zoo 6] [--components 3] [--only NAME,...] [--variants 1h]
        [--out benchmarks/EXHAUSTIVE.md] [--json benchmarks/exhaustive.json]
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

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _buildings import VARIANTS, darkgreybox_office, purdue_house, twinhouse_variant  # noqa: E402


def exhaustive(gb, components: int, starts: int = 8, say=lambda _: None) -> dict:
    """Identify every structure up to ``components`` components on ``gb``'s data; the best
    valid by validation SE, and how many structures were identified and valid."""
    from jaxbox.models import Grammar
    from jaxbox.models._grammar import roots
    from jaxbox.select._search import _accept, _Judge, _Search

    grammar = Grammar.from_columns(gb.data.columns)
    rule = _Judge("cv", 0.02, 0.05)
    search = _Search(
        gb, grammar, rule, beam=10**6, lookahead=0, max_depth=components,
        kw={"starts": starts, "seed": 0}, say=say,
    )  # fmt: skip
    t0 = time.perf_counter()
    level = [(search.declare(s, None, "root", 0), None) for s in roots(grammar)]
    _, children = search.step(level, 0)  # judged against nothing: every verdict is computed
    for depth in range(1, components + 1):
        grown = [(c, None) for c, _ in children if c.done]
        _, children = search.step(search.extensions(grown, depth), depth)
        if not children:
            break
    cases = [gb.cases[n] for n in search.nodes]
    valid = [c for c in cases if c.done and c.is_valid]
    best = _accept(valid, rule)
    return {
        "identified": len(cases),
        "valid": len(valid),
        "reduced": sum(n in search.reduced for n in search.nodes),
        "best": None if best is None else best.model.name,
        "best_case": None if best is None else best.name,
        "best_se": None if best is None else float(best.score),
        "best_fixed": {} if best is None else dict(best.fixed),
        "seconds": time.perf_counter() - t0,
    }


def searched(gb, starts: int = 8) -> dict:
    import jaxbox
    from jaxbox.validate import heat_loss_coefficients

    t0 = time.perf_counter()
    s = jaxbox.structure_search(gb, starts=starts)
    out = {"seconds": time.perf_counter() - t0, "candidates": len(s.tree)}
    if s.case is None and s.form_model is not None:  # a held zone: another form accepted
        m = s.form_model
        name = getattr(m, "structure", None)
        return {
            **out,
            "accepted": f"{name} ({s.form} form)" if name else f"{s.form} form",
            "form": s.form,
            "se": None,  # not a zone-temperature SE: no regret
            "hlc": float(m.hlc),
        }
    if s.case is None:
        return {**out, "accepted": None, "se": None}
    case = s.case
    ua = heat_loss_coefficients(case.model, case.result.params)
    return {
        **out,
        "accepted": case.model.name,
        "case": case.name,
        "se": float(case.score),
        "rmse_ident": float(case.se_auto),
        "hlc": float(next(iter(ua.values()))[0]) if ua else None,
        "fixed": dict(case.fixed),
    }


def buildings(args) -> list:
    """(name, thunk making the GreyBox) of the buildings asked for."""
    import jaxbox
    from jaxbox.datasets import make_zoo

    out = []
    for b in make_zoo(args.zoo, seed=args.seed, days=args.days) if args.zoo else []:
        out.append((b.name, lambda b=b: jaxbox.GreyBox(b.data, name=b.name), b.noise))
    for house in ("N2", "O5"):
        out.append((f"{house} shipped", lambda h=house: twinhouse_variant(h), None))
    for house in ("N2", "O5") if args.variants else ():
        for zone, columns, step in VARIANTS:
            if step not in args.variants.split(","):
                continue
            label = f"{house} {zone} {'all' if columns == 'all' else 'no-sup-cel'} {step}"
            make = lambda h=house, z=zone, c=columns, s=step: twinhouse_variant(h, z, c, s)  # noqa: E731
            out.append((label, make, None))
    out.append(("darkgreybox office", darkgreybox_office, None))
    out.append(("purdue house", purdue_house, None))
    return out


def run(name, make, noise, components, starts) -> dict:
    from jaxbox.data import DataWarning

    row = {"building": name, "components": components}
    if noise is not None:
        row["noise"] = noise
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DataWarning)
            row["search"] = searched(make(), starts)
            row["exhaustive"] = exhaustive(make(), components, starts)
    except Exception as err:  # noqa: BLE001 - a benchmark row records any failure
        row["error"] = f"{type(err).__name__}: {err}"[:300]
        return row
    s, e = row["search"].get("se"), row["exhaustive"].get("best_se")
    if s is not None and e is not None:
        row["regret"] = s / e
    return row


def markdown(doc: dict) -> str:
    lines = [
        "## Regret of the structure search against the exhaustive reference",
        "",
        f"Written by `python benchmarks/exhaustive.py` on {doc['date']}; {doc['machine']}; raw "
        "numbers in `benchmarks/exhaustive.json`. Every structure of the grammar up to the "
        "number of components shown is identified (each from the optimum of a structure one "
        "component smaller), judged with the same verdict and reductions, and the best valid "
        "one by validation SE is the reference. Regret = the default search's validation SE ÷ "
        "the reference's (below 1 where the search accepted a structure larger than the "
        "reference goes). Target: ≤ 1.10.",
        "",
        "| building | measured | search: accepted | SE [K] | time [s] | exhaustive: structures "
        "(valid) | best | SE [K] | time [s] | regret |",
        "|---|---|---|---:|---:|---:|---|---:|---:|---:|",
    ]
    for r in doc["rows"]:
        if "error" in r:
            lines.append(
                f"| {r['building']} | {r.get('date', doc['date'])} | {r['error']} | | | | | | | |"
            )
            continue
        s, e = r["search"], r["exhaustive"]
        se = "–" if s["se"] is None else f"{s['se']:.3f}"
        be = "–" if e["best_se"] is None else f"{e['best_se']:.3f}"
        reg = f"{r['regret']:.3f}" if "regret" in r else "–"
        lines.append(
            f"| {r['building']} | {r.get('date', doc['date'])} | "
            f"{s['accepted'] or 'no valid model'} | {se} | "
            f"{s['seconds']:.0f} | {e['identified']} ({e['valid']}), ≤ {r['components']} "
            f"components | {e['best'] or '–'} | {be} | {e['seconds']:.0f} | {reg} |"
        )
    regrets = [r["regret"] for r in doc["rows"] if "regret" in r]
    if regrets:
        lines += [
            "",
            f"Regret ≤ 1.10 on {sum(x <= 1.10 for x in regrets)} of {len(regrets)} buildings; "
            f"worst {max(regrets):.3f}.",
        ]
    lines += [""] + [str(note) for note in doc.get("notes", ())]
    return "\n".join(lines).rstrip("\n") + "\n"


def _write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def main(argv=None) -> int:
    import jax

    import jaxbox

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--zoo", type=int, default=6, help="zoo buildings (the first N)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--days", type=float, default=14.0)
    p.add_argument("--components", type=int, default=3)
    p.add_argument("--starts", type=int, default=8)
    p.add_argument("--only", default="", help="comma-separated building names")
    p.add_argument(
        "--variants",
        default="",
        help="the twin-house preparations of _buildings.VARIANTS at these steps (1h,10min)",
    )
    p.add_argument("--out", type=Path, default=HERE / "EXHAUSTIVE.md")
    p.add_argument("--json", type=Path, default=HERE / "exhaustive.json")
    args = p.parse_args(argv)
    jaxbox.enable_x64()
    only = {s.strip() for s in args.only.split(",") if s.strip()}
    doc = {
        "date": datetime.date.today().isoformat(),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, jax {jax.__version__}",
        "rows": [],
    }
    if args.json.exists() and only:  # keep the other buildings' rows and the notes on them
        before = json.loads(args.json.read_text())
        doc["rows"] = [r for r in before["rows"] if r["building"] not in only]
        doc["notes"] = before.get("notes", [])
    for name, make, noise in buildings(args):
        if only and name not in only:
            continue
        row = {**run(name, make, noise, args.components, args.starts), "date": doc["date"]}
        print(json.dumps(row, default=str), flush=True)
        doc["rows"].append(row)
        _write(args.json, json.dumps(doc, indent=1, default=str))
        _write(args.out, markdown(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
