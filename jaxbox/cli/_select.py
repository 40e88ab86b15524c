"""The ``jaxbox select`` command (structure search or forward selection) and ``jaxbox demo``
(selection + report).

``select_command(args)`` and ``demo_command(args)`` take the parsed arguments;
``add_select_arguments(parser)`` and ``add_demo_arguments(parser)`` declare them.
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

from .._io import atomic_write_json
from ._common import (
    UsageError,
    about,
    check_interrupted,
    check_run_options,
    cli_message,
    data_info,
    fit_default,
    fit_json,
    float_option,
    int_option,
    print_json,
    progress,
)
from ._data import (
    DataOptions,
    add_data_arguments,
    check_output_folders,
    check_windows,
    load_all,
    load_data,
    require_model_columns,
    slug,
)
from ._outputs import (
    Outputs,
    check_folder,
    fresh_folder,
)

__all__ = ["select_command", "demo_command", "add_select_arguments", "add_demo_arguments"]


def add_select_arguments(p) -> None:
    """Declare the arguments of ``jaxbox select`` on an argparse (sub)parser."""
    add_data_arguments(p)
    p.add_argument(
        "--models",
        default="search",
        metavar="search|A,B,…|FAMILY|all",
        help="'search' (default): a structure search of the component grammar; or a forward "
        "selection over comma-separated names, a library family (exp1, bacher-madsen, …) or "
        "'all' (every library model the data can feed)",
    )
    p.add_argument(
        "--criterion",
        choices=("cv", "aic", "bic", "lr"),
        default="cv",
        help="search: rank candidates by validation SE (cv, default), AIC, BIC or a "
        "likelihood-ratio test on the identification data",
    )
    p.add_argument(
        "--method",
        choices=("oe", "ml"),
        default="oe",
        help="oe: output error (default); ml: maximum likelihood of the stochastic form, with "
        "a forward selection by likelihood-ratio tests over --models (nested, simplest first; "
        "default the bacher-madsen ladder)",
    )
    p.add_argument(
        "--beam",
        type=int_option,
        default=1,
        help="search: how many of the best structures each step grows (default 1)",
    )
    p.add_argument(
        "--continued",
        type=int_option,
        default=None,
        metavar="K",
        help="how many starts of each model (the first; in a search, of each grown candidate) "
        "also follow the continuation, the others the output error alone (default all; 1 "
        "halves the fits of a search, at the risk of a model only the others' continuation "
        "finds)",
    )
    p.add_argument(
        "--polish",
        type=int_option,
        default=None,
        metavar="K",
        help="how many of each candidate's best starts are solved on to the full tolerance "
        "after every start was solved to a looser one (default 2 in a search; 0: every start "
        "to the full tolerance)",
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
    starts = fit_default("starts")  # forward_selection's and the search's too (one copy)
    p.add_argument(
        "--starts", type=int_option, default=starts, help=f"starts per model (default {starts})"
    )
    p.add_argument("--seed", type=int_option, default=0, help="seed of the Latin hypercubes")
    p.add_argument(
        "--margin",
        type=float_option,
        default=None,
        help="relative improvement of the validation SE a model must bring (default 0 for a "
        "forward selection, 0.02 for the search)",
    )
    p.add_argument(
        "--patience",
        type=int_option,
        default=patience,
        help=f"stop after this many models in a row that do not improve (default {patience})",
    )
    p.add_argument(
        "--max-steps",
        type=int_option,
        default=None,
        help=f"LM iterations per start (default {fit_default('max_steps')})",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout (quiet)")


def _candidates(text: str, data=None):
    """The candidate models of ``--models``, checked (names known, fed by the data)."""
    from ..data import DataError
    from ..models import ModelError, families
    from ..select import candidate_models

    text = (text or "all").strip()
    if text == "search":
        from ..models import Grammar

        if data is not None:
            try:
                Grammar.from_columns(data.columns)
            except ModelError as err:
                raise UsageError(f"--models search: {err}") from None
        return "search"
    if text != "all" and text not in families():
        names = [n.strip() for n in text.split(",") if n.strip()]
        if not names:
            raise UsageError("--models must name models (A,B,…), a family or 'all'")
        text = names
    try:
        models = candidate_models(text, data)
        if data is not None and text != "all":  # named models or a family: fed by the data?
            for m in models:
                require_model_columns(data, m)
    except (ModelError, DataError) as err:
        raise UsageError(f"--models: {err}") from None
    except ValueError as err:  # no candidate the data can feed
        shown = text if isinstance(text, str) else ",".join(text)
        raise UsageError(f"--models {shown}: {err}") from None
    return models


def _run_selection(
    sets, args, candidates, ranges, max_gap, stuck_hours: float | None, allow=frozenset()
):
    """Forward selection on every ``(spec, data, ident, valid)``: one GreyBox each, in
    lock-step, each step's fits batched over the buildings (``allow``: ``--allow``)."""
    from ..data import DataWarning, allowing
    from ..select import GreyBox, forward_selection_many, structure_search

    with warnings.catch_warnings(), allowing(allow):  # the windows' warnings were given
        warnings.simplefilter("ignore", DataWarning)
        boxes = [
            GreyBox(
                data,
                train=(str(ident.start), str(ident.end)),
                valid=False if valid is None else (str(valid.start), str(valid.end)),
                name=spec,
                ranges=ranges,
                max_gap=max_gap,
                stuck_hours=stuck_hours,
            )
            for spec, data, ident, valid in sets
        ]
    # --margin left out: each method's own default (0.02 for the search, 0 for the chains)
    # (the demo has no --continued, --polish or --margin: each method's own default)
    common = dict(starts=args.starts, seed=args.seed, max_steps=args.max_steps)
    continued, polish = getattr(args, "continued", None), getattr(args, "polish", None)
    margin = getattr(args, "margin", None)
    if continued is not None:
        common["continued"] = continued
    if polish is not None:
        common["polish"] = polish or None
    if margin is not None:
        common["margin"] = margin
    if candidates == "search":
        say = progress(args)
        selections = []
        for gb in boxes:
            if len(boxes) > 1:
                say(f"== {gb.name}")
            with about(gb.name if len(boxes) > 1 else None):  # its warnings name the file
                selections.append(
                    structure_search(
                        gb, criterion=args.criterion, beam=args.beam, progress=say, **common
                    )
                )
            check_interrupted()
        return list(zip(boxes, selections, strict=True))
    selections = forward_selection_many(
        boxes, candidates, patience=args.patience, progress=progress(args), **common
    )
    check_interrupted()
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
    doc = {"dataset": spec, "table": table, **sel.to_dict(), "fit": None, "hlc": None}
    if sel.case is not None:
        doc["hlc"] = _hlc(sel)
        c = sel.case
        doc["fit"] = fit_json(
            c.result,
            c.validation,
            timing={**c.result.timing, **c.timing},
            data_info=data_info(spec, ident, valid),
            valid=c.valid,
            data_checks=c.data_checks,
        )
    elif getattr(sel, "form_model", None) is not None:
        doc["hlc"] = _form_hlc(sel.form_model)
    return doc


def _form_hlc(model) -> dict | None:
    """The HLC of an accepted heat-demand or steady-state model, in the fields of the
    temperature form's (:func:`_hlc`): value, interval, its method and warnings."""
    import numpy as np

    value, (lo, hi) = float(model.hlc), model.hlc_interval
    if not np.isfinite(value):
        return None
    return {
        "value": value,
        "unit": "W/K",
        "ci95": [float(lo), float(hi)],
        "level": 0.95,
        "method": model.hlc_method,
        "form": model.form,
        "models": [{"model": model.structure, "value": value, "ci95": [float(lo), float(hi)]}],
        "warnings": list(getattr(model, "warnings", ())),
        "zone_excess": getattr(model, "zone_excess", None),
        "per_100_w": getattr(model, "per_100_w", None),
    }


def _hlc(sel) -> dict | None:
    """The accepted model's HLC with its interval and how it was made (coloured residuals,
    near-best structures: :func:`jaxbox.validate.hlc_interval`)."""
    import numpy as np

    from ..validate import hlc_interval

    try:
        out = hlc_interval(sel)
    except (ValueError, np.linalg.LinAlgError):  # no finite optimum, a singular model
        return None
    return None if out is None else out.to_dict()


def _stage_outputs(outputs: Outputs, gb, sel, doc, folder: Path) -> None:
    """The selection document and the report staged for ``folder``; the GreyBox saved there at
    commit (its own save is atomic). ``doc["files"]`` gets the final paths."""
    from ..report import write_report

    staged = outputs.folder(folder)
    doc["files"] = {
        "selection": str(folder / "selection.json"),
        "greybox": str(folder / "greybox" / "greybox.json"),
        "report": str(folder / "report.html"),
    }
    write_report(gb, staged / "report.html", sel)
    atomic_write_json(staged / "selection.json", doc)
    outputs.after(lambda: gb.save(folder / "greybox"))


def _print_table(gb, sel, hlc: dict | None = None) -> None:
    print()
    print(gb.table_text())
    print()
    tree = getattr(sel, "tree_text", None)
    if tree is not None:
        print(f"search tree ({sel.criterion}; * accepted):")
        print(tree())
        print()
    print(sel.stopped)
    form = getattr(sel, "form_model", None)
    if form is not None:  # the heat-demand or steady-state form of a held zone
        print(f"accepted: the {sel.form} form ({sel.choice.why})")
        print(form.summary())
    elif sel.case is None:
        identified = any(case.done for case in gb.cases.values())
        print(
            "no valid model: none accepted"
            if identified
            else "no model: none of the candidates could be identified (see the notes above)"
        )
    else:
        print(f"accepted: {sel.accepted}")
        print(sel.case.result.summary())
        if hlc is not None:
            print(_hlc_text(hlc))


def _hlc_text(hlc: dict) -> str:
    """The HLC line of the text output (and its warnings)."""
    from ..validate._hlc import NOT_DETERMINED, _outdoor_text, _unmeasured_text

    ci = hlc["ci95"]
    shown = "[-]" if ci is None else f"[{ci[0]:.4g}, {ci[1]:.4g}]"
    lines = [
        f"heat-loss coefficient {hlc['value']:.4g} W/K, {round(100 * hlc['level'])} % interval "
        f"{shown} ({hlc['method']})"
    ]
    if hlc.get("determined") is False:
        lines[0] += NOT_DETERMINED
    if hlc.get("outdoor"):
        lines.append("  " + _outdoor_text(hlc["outdoor"], round(100 * hlc["level"])))
    if hlc.get("zone_excess") is not None:
        lines.append("  " + _unmeasured_text(hlc["zone_excess"]))
    return "\n".join(lines + [f"  warning: {w}" for w in hlc["warnings"]])


def select_command(args) -> int:
    """``jaxbox select DATA…``: structure search (default) or forward selection; ``--json``
    prints the table and the accepted model's fit document (with several DATA:
    ``{"buildings": [document, …]}``)."""
    if getattr(args, "method", "oe") == "ml":
        return _ml_select(args)
    check_run_options(args)
    opts = DataOptions(args)
    out = check_output_folders(args.out, "--out", opts.specs)
    sets = [
        (spec, data.slice(ident.start, (ident if valid is None else valid).end), ident, valid)
        for spec, data, ident, valid in load_all(args, opts)
    ]
    candidates = _candidates(args.models, sets[0][1])
    for _, data, _, _ in sets[1:]:
        _candidates(args.models, data)
    if len(sets) == 1 and candidates != "search":  # sized for the building, as the search sizes
        from ..select._scale import sized_model

        candidates = [sized_model(m, sets[0][2]) for m in candidates]
    with Outputs() as outputs:
        t0 = time.perf_counter()
        outcomes = _run_selection(
            sets, args, candidates, opts.ranges, opts.max_gap, opts.stuck_hours, opts.allow
        )
        elapsed = time.perf_counter() - t0
        docs = []
        for (spec, _, ident, valid), (gb, sel) in zip(sets, outcomes, strict=True):
            with about(spec if len(sets) > 1 else None):
                doc = _document(gb, sel, spec, ident, valid)
                doc["elapsed_s"] = elapsed
                if out is not None:
                    folder = out if len(sets) == 1 else out / slug(spec, opts.specs)
                    _stage_outputs(outputs, gb, sel, doc, folder)
            docs.append(doc)
        outputs.commit()
    if args.json:
        print_json(docs[0] if len(docs) == 1 else {"buildings": docs, "elapsed_s": elapsed})
    else:
        for (gb, sel), doc in zip(outcomes, docs, strict=True):
            if len(docs) > 1:
                print(f"\n== {gb.name}")
            _print_table(gb, sel, doc.get("hlc"))
            if out is not None:
                print(f"\nreport: {doc['files']['report']}")
    return _no_valid_model(outcomes)


def _ml_select(args) -> int:
    """``jaxbox select DATA… --method ml``: forward selection by likelihood-ratio tests
    (Bacher & Madsen 2011) of maximum-likelihood fits, on the identification window."""
    from ..fit import FitError
    from ..stochastic import DEFAULT_ML_MAX_STEPS, forward_selection_lr

    if args.models in ("search", "all"):
        args.models = "bacher-madsen"
    if args.out:
        raise UsageError("--out is not available with --method ml; use --json")
    if args.continued is not None:
        raise UsageError(
            "--continued is for output-error fits (the continuation is theirs); leave it out "
            "with --method ml"
        )
    if args.polish is not None:
        raise UsageError("--polish is for output-error fits; leave it out with --method ml")
    if args.max_steps is None:
        args.max_steps = DEFAULT_ML_MAX_STEPS
    check_run_options(args)
    opts = DataOptions(args)
    sets = load_all(args, opts)
    models = _candidates(args.models, sets[0][1])
    docs = []
    for spec, _, ident, _ in sets:
        t0 = time.perf_counter()
        try:
            out = forward_selection_lr(
                models, ident, starts=args.starts, seed=args.seed, max_steps=args.max_steps
            )
        except FitError as err:
            raise UsageError(f"{spec}: {err}") from None
        check_interrupted()
        docs.append(
            {
                "dataset": spec,
                "method": "ml",
                "accepted": out["accepted"],
                "table": out["table"],
                "elapsed_s": time.perf_counter() - t0,
            }
        )
    if args.json:
        print_json(docs[0] if len(docs) == 1 else {"buildings": docs})
        return 0
    for doc in docs:
        print(f"\n== {doc['dataset']}: forward selection by likelihood ratio (ML)")
        print(f"{'model':<24} {'n_free':>6} {'loglik':>10} {'AIC':>10} {'LR p':>9}  accepted")
        for r in doc["table"]:
            p = "–" if r["pvalue"] is None else f"{r['pvalue']:.3g}"
            print(
                f"{r['model']:<24} {r['n_free']:>6} {r['loglik']:>10.2f} {r['aic']:>10.2f} "
                f"{p:>9}  {'yes' if r['accepted'] else ''}"
            )
        print(f"accepted: {doc['accepted']}")
    return 0


#: Identification data shorter than this [h] are named when no model is valid.
SHORT_IDENT_HOURS = 72.0


def _heated_elsewhere(gb) -> str:
    """Where the heating of ``gb``'s data runs in its validation period, the options that
    identify on that period instead (validation data must follow the identification data, so
    without them); else nothing."""
    import numpy as np

    from ..data import signal_unit

    valid = gb.valid
    if valid is None:
        return ""
    heated = [
        c
        for c in valid.columns
        if signal_unit(c) == "W" and np.any(np.nan_to_num(np.asarray(valid[c], float)) != 0.0)
    ]
    if not heated:
        return ""
    c, d = gb.valid_period
    return (
        f" (the validation period has '{heated[0]}': identify on it, "
        f"--train '{c}..{d}' --validate none)"
    )


#: the data checks' warnings that may explain why no model is valid: a unit or a column in doubt
_UNIT_WARNINGS = ("fahrenheit", "kilowatt", "sign")


def _unit_warnings(gb) -> list[tuple[str, str]]:
    """``(column, text)`` of each warning of the data checks on ``gb``'s identification data
    that puts a unit or a column in doubt (°F, swapped columns, kW, the heating's sign),
    repeated where no model is valid: given at the start, they have scrolled away by the end."""
    from ..data import find_implausible

    checks = next((c.data_checks for c in gb.cases.values() if c.data_checks), None) or {}
    try:
        found = find_implausible(gb.ident, overrides=checks.get("data_overrides"))
    except Exception:  # noqa: BLE001 - a hint, never a new failure
        return []
    return [
        (f.column, f"the data check warned: {f.message.rstrip('.')}")
        for f in found
        if not f.severe and f.kind in _UNIT_WARNINGS and not f.message.startswith("allowed:")
    ]


def _no_valid_model(outcomes) -> int:
    """0 when every building has an accepted model; else 1, with one line on stderr."""
    import sys

    none = [
        gb for gb, sel in outcomes if sel.case is None and getattr(sel, "form_model", None) is None
    ]
    if not none:
        return 0
    which = "" if len(outcomes) == 1 else f" for {', '.join(gb.name for gb in none)}"
    short = []
    for gb in none:
        ident = gb.ident
        hours = len(ident) * ident.step / 3600.0
        if hours < SHORT_IDENT_HOURS:
            short.append(f"{hours:.3g} h" if len(none) == 1 else f"{gb.name} {hours:.3g} h")
    hint = (
        f"; the identification data span only {', '.join(short)}: slow building states need "
        "days of data with varying heating (a week or more is usual; --train)"
        if short
        else ""
    )
    # the likelier causes are named first, in the one line read last: no heat input in the
    # identification data (the scale of every model undetermined), then an input's unit in
    # doubt where its gain sits on a bound
    from ..select._cases import idle_heat_inputs, unit_doubts

    doubts: list[str] = []
    for gb in none:
        judged = [c for c in gb.cases.values() if c.done]
        idle = idle_heat_inputs(judged)
        if idle and len(none) == 1:
            idle = [idle[0] + _heated_elsewhere(gb)]
        units = unit_doubts(list(gb.cases.values()))  # a gain on a bound: the fits' evidence
        warned = [  # the data checks' warnings on the other columns
            text
            for column, text in _unit_warnings(gb)
            if not any(u.startswith(repr(column)) for u in units)
        ]
        found = idle + units + warned
        doubts += [d for d in found if d not in doubts]
    first = f"{doubts[0]}; " if doubts else ""
    print(
        cli_message(
            f"no valid model{which}: {first}none of the candidates passed the validity checks{hint}"
        ),
        file=sys.stderr,
        flush=True,
    )
    return 1


def demo_command(args) -> int:
    """``jaxbox demo``: forward selection over the experiment-1 hierarchy on a bundled twin
    house, the table on stdout, an HTML report (and the saved GreyBox) in ``--out``."""
    from ..data._gaps import DEFAULT_MAX_GAP
    from ..data._plausible import STUCK_HOURS
    from ..datasets import CITATION

    check_run_options(args)
    out = check_folder(args.out or str(fresh_folder()), "--out")
    spec = f"twinhouse_exp1:{args.house}"
    data = load_data(spec)
    ident, valid = data.split()
    check_windows(ident, valid, None, None, STUCK_HOURS)
    say = progress(args)
    say(
        f"jaxbox demo: twin house {args.house} (IEA EBC Annex 58, Holzkirchen 2013), "
        f"{len(data)} hourly samples; identification {ident.start} .. {ident.end}, "
        f"validation {valid.start} .. {valid.end}"
    )
    with Outputs() as outputs:
        t0 = time.perf_counter()
        ((gb, sel),) = _run_selection(
            [(spec, data, ident, valid)], args, "exp1", None, DEFAULT_MAX_GAP, STUCK_HOURS
        )
        doc = _document(gb, sel, spec, ident, valid)
        doc["elapsed_s"] = time.perf_counter() - t0
        _stage_outputs(outputs, gb, sel, doc, out)
        outputs.commit()
    if args.json:
        print_json({**doc, "out": str(out)})
        return 0
    _print_table(gb, sel, doc.get("hlc"))
    print()
    print(f"report: {doc['files']['report']} ({doc['elapsed_s']:.0f} s)")
    print(f"data: {CITATION}")
    return 0
