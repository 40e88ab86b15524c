"""The ``jaxbox select`` command (forward selection) and ``jaxbox demo`` (selection + report).

``select_command(args)`` and ``demo_command(args)`` take the parsed arguments;
``add_select_arguments(parser)`` and ``add_demo_arguments(parser)`` declare them.
"""

from __future__ import annotations

import json
import sys
import time

from .._io import atomic_write_json, to_jsonable
from ._commands import (
    UsageError,
    _data_info,
    _out_dir,
    _slug,
    add_data_arguments,
    fit_json,
    load_all,
    load_data,
)

__all__ = ["select_command", "demo_command", "add_select_arguments", "add_demo_arguments"]


def add_select_arguments(p) -> None:
    """Declare the arguments of ``jaxbox select`` on an argparse (sub)parser."""
    add_data_arguments(p)
    p.add_argument(
        "--models",
        default="all",
        metavar="A,B,…|FAMILY|all",
        help="candidate models: comma-separated names, a library family (exp1, …) or 'all' "
        "(every library model the data can feed; default)",
    )
    _common(p)
    p.add_argument("--out", metavar="DIR", help="save the GreyBox, the table and a report in DIR")


def add_demo_arguments(p) -> None:
    """Declare the arguments of ``jaxbox demo``."""
    p.add_argument(
        "--out", metavar="DIR", help="output folder (default: a fresh jaxbox-out-* folder)"
    )
    p.add_argument("--house", choices=("N2", "O5"), default="N2")
    _common(p, patience=3)


def _common(p, patience: int = 1) -> None:
    p.add_argument("--starts", type=int, default=8, help="starts per model (default 8)")
    p.add_argument("--seed", type=int, default=0, help="seed of the Latin hypercubes")
    p.add_argument(
        "--margin",
        type=float,
        default=0.0,
        help="relative improvement of the validation SE a model must bring (default 0)",
    )
    p.add_argument(
        "--patience",
        type=int,
        default=patience,
        help=f"stop after this many models in a row that do not improve (default {patience})",
    )
    p.add_argument("--max-steps", type=int, default=200, help="LM iterations per start")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout (quiet)")


def _say(args):
    if getattr(args, "json", False):
        return None
    return lambda msg: print(msg, file=sys.stderr, flush=True)


def _candidates(text: str):
    from ..models import families

    text = (text or "all").strip()
    if text == "all" or text in families():
        return text
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise UsageError("--models must name models (A,B,…), a family or 'all'")
    return names


def _run_selection(sets, args, candidates):
    """Forward selection on every ``(spec, data, ident, valid)``: one GreyBox each, in
    lock-step, each step's fits batched over the buildings."""
    from ..select import GreyBox, forward_selection_many

    if args.starts < 1:
        raise UsageError(f"--starts must be at least 1, got {args.starts}")
    boxes = [
        GreyBox(
            data,
            train=(str(ident.start), str(ident.end)),
            valid=(str(valid.start), str(valid.end)),
            name=spec,
        )
        for spec, data, ident, valid in sets
    ]
    selections = forward_selection_many(
        boxes,
        candidates,
        starts=args.starts,
        seed=args.seed,
        margin=args.margin,
        patience=args.patience,
        max_steps=args.max_steps,
        progress=_say(args),
    )
    return list(zip(boxes, selections, strict=True))


def _document(gb, sel, spec, ident, valid) -> dict:
    table = []
    for name in sel.order:
        c = gb.cases[name]
        row = c.row()
        row["reasons"] = list(c.reasons)
        row["notes"] = list(c.notes)
        row["rmse_auto"] = None if c.validation is None else dict(c.validation.rmse_auto)
        row["rmse_cross"] = None if c.validation is None else c.validation.rmse_cross
        row["timing"] = dict(c.timing)
        table.append(
            {
                k: v
                for k, v in row.items()
                if not k.startswith("rmse_auto_") and not k.startswith("rmse_cross_")
            }
        )
    doc = {"dataset": spec, "table": table, **sel.to_dict(), "fit": None}
    if sel.case is not None:
        c = sel.case
        doc["fit"] = fit_json(
            c.result,
            c.validation,
            timing={**c.result.timing, **c.timing},
            data_info=_data_info(spec, ident, valid),
            valid=c.valid,
        )
    return doc


def _write_outputs(gb, sel, doc, out) -> dict:
    from ..report import write_report

    paths = {
        "selection": str(atomic_write_json(out / "selection.json", doc)),
        "greybox": str(gb.save(out / "greybox")),
        "report": str(write_report(gb, out / "report.html", sel)),
    }
    return paths


def _print_table(gb, sel) -> None:
    print()
    print(gb.table_text())
    print()
    print(sel.stopped)
    if sel.case is None:
        print("no valid model: none accepted")
    else:
        print(f"accepted: {sel.accepted}")
        print(sel.case.result.summary())


def select_command(args) -> int:
    """``jaxbox select DATA…``: forward selection; ``--json`` prints the table and the
    accepted model's fit document (with several DATA: ``{"buildings": [document, …]}``)."""

    sets = [
        (spec, data.slice(ident.start, valid.end), ident, valid)
        for spec, data, ident, valid in load_all(args)
    ]
    candidates = _candidates(args.models)
    t0 = time.perf_counter()
    outcomes = _run_selection(sets, args, candidates)
    elapsed = time.perf_counter() - t0
    docs = []
    out = _out_dir(args.out) if args.out else None
    for (spec, _, ident, valid), (gb, sel) in zip(sets, outcomes, strict=True):
        doc = _document(gb, sel, spec, ident, valid)
        doc["elapsed_s"] = elapsed
        if out is not None:
            folder = out if len(sets) == 1 else out / _slug(spec, args.data)
            folder.mkdir(parents=True, exist_ok=True)
            doc["files"] = _write_outputs(gb, sel, doc, folder)
        docs.append(doc)
    if args.json:
        body = docs[0] if len(docs) == 1 else {"buildings": docs, "elapsed_s": elapsed}
        print(json.dumps(to_jsonable(body), indent=2, allow_nan=False))
        return 0
    for (gb, sel), doc in zip(outcomes, docs, strict=True):
        if len(docs) > 1:
            print(f"\n== {gb.name}")
        _print_table(gb, sel)
        if out is not None:
            print(f"\nreport: {doc['files']['report']}")
    return 0


def demo_command(args) -> int:
    """``jaxbox demo``: forward selection over the experiment-1 hierarchy on a bundled twin
    house, the table on stdout, an HTML report (and the saved GreyBox) in ``--out``."""
    from ..datasets import CITATION

    out = _out_dir(args.out)
    spec = f"twinhouse_exp1:{args.house}"
    data = load_data(spec)
    ident, valid = data.split()
    say = _say(args) or (lambda msg: None)
    say(
        f"jaxbox demo: twin house {args.house} (IEA EBC Annex 58, Holzkirchen 2013), "
        f"{len(data)} hourly samples; identification {ident.start} .. {ident.end}, "
        f"validation {valid.start} .. {valid.end}"
    )
    t0 = time.perf_counter()
    ((gb, sel),) = _run_selection([(spec, data, ident, valid)], args, "exp1")
    doc = _document(gb, sel, spec, ident, valid)
    doc["elapsed_s"] = time.perf_counter() - t0
    doc["files"] = _write_outputs(gb, sel, doc, out)
    atomic_write_json(out / "selection.json", doc)
    if args.json:
        print(json.dumps(to_jsonable({**doc, "out": str(out)}), indent=2, allow_nan=False))
        return 0
    _print_table(gb, sel)
    print()
    print(f"report: {doc['files']['report']} ({doc['elapsed_s']:.0f} s)")
    print(f"data: {CITATION}")
    return 0
