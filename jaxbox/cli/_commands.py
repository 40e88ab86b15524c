"""The ``jaxbox models`` and ``jaxbox fit`` commands.

``models_command(args)`` and ``fit_command(args)`` take the parsed arguments;
``add_fit_arguments(parser)`` declares those of ``fit``. Every option is checked, and the
``--plots`` folder probed, before any data is fitted.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from ._common import (
    UsageError,
    about,
    bounds,
    check_fixed_in_range,
    check_interrupted,
    check_parameters,
    check_positive,
    check_run_options,
    data_info,
    fit_default,
    fit_json,
    floats,
    int_option,
    print_json,
)
from ._data import (
    DataOptions,
    add_data_arguments,
    check_output_folders,
    load_for_model,
    slug,
)
from ._outputs import (
    Outputs,
)

__all__ = ["add_fit_arguments", "fit_command", "models_command"]


def add_fit_arguments(p) -> None:
    """Declare the arguments of ``jaxbox fit``."""
    add_data_arguments(p)
    p.add_argument("--model", "-m", required=True, help="library model name (see `jaxbox models`)")
    p.add_argument(
        "--starts",
        type=int_option,
        default=fit_default("starts"),
        help=f"number of starts (default {fit_default('starts')})",
    )
    p.add_argument(
        "--seed", type=int_option, default=0, help="seed of the Latin hypercube (default 0)"
    )
    p.add_argument(
        "--fix", action="append", default=[], metavar="P=VALUE", help="hold P at VALUE (SI)"
    )
    p.add_argument(
        "--bounds", action="append", default=[], metavar="P=LO:HI", help="bounds of P (SI)"
    )
    p.add_argument("--simulator", choices=("exact", "diffrax"), default="exact")
    p.add_argument(
        "--method",
        choices=("oe", "ml"),
        default="oe",
        help="oe: output error (default); ml: maximum likelihood of the stochastic form",
    )
    p.add_argument(
        "--max-steps",
        type=int_option,
        default=None,
        help=f"LM iterations per start (default {fit_default('max_steps')})",
    )
    p.add_argument(
        "--homotopy",
        metavar="GAINS",
        default=None,
        help="observer gains of the continuation each start also follows, e.g. "
        f"{','.join(f'{g:g}' for g in fit_default('homotopy'))} (the default), or none",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--plots", metavar="DIR", help="write the validation plots (PNG) into DIR")


# ---- models ----


def models_command(args) -> int:
    from ..models import describe_models, library_models, model_families

    models = library_models()
    if args.json:
        print_json({"models": describe_models()})
        return 0
    for m in models:
        fam = ", ".join(model_families(m.name))
        print(f"{m.name}{f' [{fam}]' if fam else ''}: {m.description}")
        print(f"  states:  {', '.join(m.states)}")
        print(f"  inputs:  {', '.join(m.inputs)}")
        print(f"  outputs: {', '.join(m.outputs)}")
        for p in m.parameters:
            print(
                f"    {p.name:<10} [{p.unit}] default {p.default:<10.4g} "
                f"bounds [{p.lower:g}, {p.upper:g}]"
            )
        print()
    return 0


# ---- fit ----


def fit_command(args) -> int:
    """``jaxbox fit DATA… --model NAME``: fit, cross-validate, print (``--json``: one document)."""
    from ..fit import fit_batch
    from ..fit._batch import fit_data
    from ..fit._fit import bucket_samples
    from ..models import get_model
    from ..select._cases import data_checks
    from ..validate import validate

    if getattr(args, "method", "oe") == "ml":
        from ._estimate import ml_fit_command

        return ml_fit_command(args)
    # every option first, nothing loaded or computed yet
    model = get_model(args.model)
    fixed = floats(args.fix, "--fix", "gA=2.5")
    limits = bounds(args.bounds)
    check_parameters(model, fixed, "--fix")
    check_parameters(model, limits, "--bounds")
    check_positive(fixed, limits)
    check_fixed_in_range(model, fixed)
    both = sorted(set(fixed) & set(limits))
    if both:
        raise UsageError(f"--fix and --bounds both give {both[0]}; a fixed parameter has no bounds")
    check_run_options(args)
    opts = DataOptions(args)
    plots = check_output_folders(args.plots, "--plots", opts.specs)
    # the data, checked in the periods used; a structure name is built for the data's columns
    # (no solar aperture without I_glo_hor), as the structure search builds it
    sets, built = load_for_model(args, opts, args.model, model)
    if built is not model:
        check_parameters(built, fixed, "--fix")
        check_parameters(built, limits, "--bounds")
    model = built
    say = _say(args)
    lengths = {len(ident) for _, _, ident, _ in sets}
    for spec, _, ident, _ in sets:
        say(
            f"fitting {model.name} on {spec}: {len(ident)} samples ({ident.start} .. {ident.end}) "
            f"from {args.starts} starts …"
        )
    if len(sets) > 1 and len(lengths) > 1:
        # neighbouring lengths are padded into one batch on the exact route (see solve_jobs)
        batches = {bucket_samples(n) for n in lengths} if args.simulator == "exact" else lengths
        say(
            "identification periods of different lengths: "
            + (
                "padded at their ends into one batch"
                if len(batches) == 1
                else f"fitted in {len(batches)} batches (neighbouring lengths padded into one)"
            )
        )
    request = {
        "model": model,
        "fixed": fixed,
        "bounds": limits,
        "starts": args.starts,
        "seed": args.seed,
        "simulator": args.simulator,
        "max_steps": args.max_steps,
        "homotopy": args.homotopy,
        "max_gap": opts.max_gap,
    }
    # each identification window prepared here (its gaps interpolated or cut), so that the
    # warnings name the DATA they are about; the fit finds nothing left to prepare
    windows = []
    for spec, _, ident, _ in sets:
        with about(spec if len(sets) > 1 else None):
            windows.append(fit_data(model, ident, opts.max_gap)[1])
    with Outputs() as outputs:
        staged = outputs.folder(plots) if plots is not None else None
        t0 = time.perf_counter()
        results = fit_batch([{**request, "data": window} for window in windows])
        t1 = time.perf_counter()
        check_interrupted()
        docs = []
        for (spec, _, ident, valid), result in zip(sets, results, strict=True):
            with about(spec if len(sets) > 1 else None):
                t2 = time.perf_counter()
                validation = validate(result, valid)
                timing = {
                    **result.timing,
                    "total_fit_s": t1 - t0,
                    "validate_s": time.perf_counter() - t2,
                }
                doc = fit_json(
                    result,
                    validation,
                    timing=timing,
                    data_info=data_info(spec, ident, valid),
                    valid=valid,
                    data_checks=data_checks(opts.ranges, opts.stuck_hours),
                )
                if staged is not None:
                    sub = Path(slug(spec, opts.specs)) if len(sets) > 1 else Path()
                    doc["plots"] = _plots(result, valid, validation, staged, sub, plots)
                check_interrupted()
                docs.append((doc, result, validation))
        outputs.commit()
    if args.json:
        if len(docs) == 1:
            print_json(docs[0][0])
        else:
            print_json({"model": model.name, "fits": [d for d, _, _ in docs]})
        return 0
    for (spec, *_), (doc, result, validation) in zip(sets, docs, strict=True):
        _print_fit(spec, doc, result, validation, several=len(docs) > 1)
    return 0


def _say(args):
    """Progress on a terminal only (stderr), never with --json."""
    if getattr(args, "json", False) or not sys.stderr.isatty():
        return lambda msg: None
    return lambda msg: print(msg, file=sys.stderr, flush=True)


def _plots(result, valid, validation, staged: Path, sub: Path, final: Path) -> list[str]:
    """Write the plots into the staging folder; return the paths they will have."""
    from ..validate import save_plots

    written = save_plots(result, validation, staged / sub, valid=valid)
    return [str(final / sub / Path(p).name) for p in written]


def _print_fit(spec, doc, result, validation, *, several: bool) -> None:
    if several:
        print(f"== {spec}")
    print(result.summary())
    print(_rmse_line(validation))
    if doc.get("kpis"):
        print(_kpi_line(doc["kpis"]))
    print("valid model" if doc["valid"] else "NOT a valid model:")
    for reason in doc["reasons"]:
        print(f"  - {reason}")
    for warning in doc.get("warnings", []):
        print(f"  (warning) {warning}")
    timing = doc["timing"]
    batch = f" (one batch of {timing['batch']} datasets)" if timing.get("batch", 1) > 1 else ""
    print(
        f"timing: compile {timing['compile_s']:.2f} s, fit {timing['fit_s']:.3f} s{batch}, "
        f"validation {timing['validate_s']:.2f} s"
    )
    if several:
        print()


def _rmse_line(validation) -> str:
    auto = ", ".join(f"{k} {v:.3f} K" for k, v in validation.rmse_auto.items())
    line = f"RMSE identification: {auto}"
    if validation.rmse_cross is not None:
        cross = ", ".join(f"{k} {v:.3f} K" for k, v in validation.rmse_cross.items())
        line += f" | validation: {cross}"
    return line


def _kpi_line(kpis) -> str:
    """HLC, solar aperture and time constants with their 95 % intervals, on one line."""

    def one(k, fmt=".4g"):
        ci = k["ci95"]
        interval = "" if ci is None else f" [{ci[0]:{fmt}}, {ci[1]:{fmt}}]"
        return f"{k['value']:{fmt}}{interval} {k['unit']}"

    parts = []
    if kpis.get("hlc") and kpis["hlc"]["value"] is not None:
        parts.append(f"HLC {one(kpis['hlc'])}")
    if kpis.get("solar_aperture") and kpis["solar_aperture"]["value"] is not None:
        parts.append(f"solar aperture {one(kpis['solar_aperture'])}")
    taus = [one(t, ".3g") for t in kpis.get("time_constants", []) if t["value"] is not None]
    if taus:
        parts.append("time constants " + ", ".join(taus))
    return "KPIs (95 % intervals): " + "; ".join(parts)
