"""``jaxbox fit --method ml`` (maximum likelihood of the stochastic form) and ``jaxbox estimate``
(filtered and smoothed states from a fit, written to a CSV).

``ml_fit_command(args)`` is called by ``jaxbox fit`` when ``--method ml`` is given;
``add_estimate_arguments(p)`` and ``estimate_command(args)`` make ``jaxbox estimate``.
"""

from __future__ import annotations

import json
import time
import types
from pathlib import Path

from ._common import (
    UsageError,
    bounds,
    check_interrupted,
    check_parameters,
    check_positive,
    check_run_options,
    data_info,
    floats,
    print_json,
)
from ._data import DataOptions, add_data_arguments, load_data, load_for_model

__all__ = ["ml_fit_command", "add_estimate_arguments", "estimate_command"]

#: k of the k-step-ahead prediction errors reported
K_STEPS = (1, 2, 4, 8)


def _stochastic_view(model):
    """The model as the option checks see it: its physical and noise parameters."""
    from ..stochastic import noise_parameters

    specs = {p.name: p for p in (*model.parameters, *noise_parameters(model))}
    return types.SimpleNamespace(
        name=model.name, param_names=tuple(specs), parameter=lambda n: specs[n]
    )


def _one_series(data, model, max_gap: float, what: str, where: str):
    """``data`` with its short input gaps interpolated (up to ``max_gap`` [s], as the
    output-error fit does), as the one regular series the Kalman filter of the stochastic form
    runs over; a longer gap, which would cut it in two, is refused with the ``--max-gap`` that
    bridges it and, as ``where`` says, the data on one side of it."""
    import numpy as np

    from ..data import DataError, prepare_window
    from ..data._gaps import _duration

    if data is None:
        return None
    try:
        ready = prepare_window(
            data, model.inputs, model.outputs, max_gap=max_gap, what=what, warn=False
        )
    except DataError as err:
        raise UsageError(str(err)) from None
    if len(ready.segments) <= 1:
        return ready
    index, step = ready.index, ready.step
    cuts = [(index[a - 1], index[a]) for a, _ in ready.segments[1:]]
    widest = max((b - a).total_seconds() - step for a, b in cuts)
    first = cuts[0]
    bridge = _duration(1, float(np.ceil(widest / 3600.0) * 3600.0)).replace(" ", "")
    raise UsageError(
        f"{what}: the inputs are missing from {first[0] + np.timedelta64(int(step), 's')} to "
        f"{first[1] - np.timedelta64(int(step), 's')}"
        + (f" (and in {len(cuts) - 1} more gap(s))" if len(cuts) > 1 else "")
        + f", longer than --max-gap {_duration(1, max_gap)}; the Kalman filter of the "
        f"stochastic form runs over one series: give --max-gap {bridge} to interpolate "
        f"{'them' if len(cuts) > 1 else 'it'}, or {where}"
    )


def ml_fit_command(args) -> int:
    """``jaxbox fit DATA… --model NAME --method ml``."""
    from ..fit import FitError
    from ..models import get_model
    from ..stochastic import DEFAULT_ML_MAX_STEPS, fit_ml

    model = get_model(args.model)
    view = _stochastic_view(model)
    fixed = floats(args.fix, "--fix", "sigma_wal=0")
    limits = bounds(args.bounds)
    check_parameters(view, fixed, "--fix")
    check_parameters(view, limits, "--bounds")
    check_positive(fixed, limits)
    if args.plots:
        raise UsageError("--plots is not available with --method ml; use jaxbox estimate")
    if args.simulator != "exact":
        raise UsageError("--simulator does not apply to --method ml (the filter is exact)")
    if args.max_steps is None:
        args.max_steps = DEFAULT_ML_MAX_STEPS
    check_run_options(args)
    opts = DataOptions(args)
    sets, built = load_for_model(args, opts, args.model, model)
    if built is not model:  # a structure built for the data's columns
        model, view = built, _stochastic_view(built)
        check_parameters(view, fixed, "--fix")
        check_parameters(view, limits, "--bounds")
    docs = []
    for spec, _, ident, valid in sets:
        where = "--train/--validate windows on one side of it"
        ident = _one_series(ident, model, opts.max_gap, "identification data", where)
        valid = _one_series(valid, model, opts.max_gap, "validation data", where)
        t0 = time.perf_counter()
        try:
            result = fit_ml(
                model,
                ident,
                fixed=fixed,
                bounds=limits,
                starts=args.starts,
                seed=args.seed,
                max_steps=args.max_steps,
            )
        except FitError as err:
            raise UsageError(str(err)) from None
        t1 = time.perf_counter()
        check_interrupted()
        docs.append((spec, ml_json(result, ident, valid, spec, t1 - t0), result))
    if args.json:
        if len(docs) == 1:
            print_json(docs[0][1])
        else:
            print_json({"model": model.name, "method": "ml", "fits": [d for _, d, _ in docs]})
        return 0
    for spec, doc, result in docs:
        if len(docs) > 1:
            print(f"== {spec}")
        print(result.summary())
        for name, r in doc["residuals"]["outputs"].items():
            lb, cp = r["ljung_box"], r["cumulated_periodogram"]
            print(
                f"innovations {name}: Ljung–Box p = {lb['p_value']:.3g}, cumulated periodogram "
                f"p = {cp['p_value']:.3g} ({'white' if r['white'] else 'NOT white'})"
            )
        ks = ", ".join(f"{k}: {v[model.outputs[0]]:.3f} K" for k, v in doc["k_step_rmse"].items())
        print(f"k-step RMSE (identification, {model.outputs[0]}) {ks}")
        sim = doc["simulation_rmse"]
        cross = (
            "none"
            if sim["validation"] is None
            else ", ".join(f"{o} {v:.3f} K" for o, v in sim["validation"].items())
        )
        print(
            "open-loop RMSE: "
            + ", ".join(f"{o} {v:.3f} K" for o, v in sim["identification"].items())
            + f" | validation: {cross}"
        )
    return 0


def ml_json(result, ident, valid, spec, total_s: float) -> dict:
    """The JSON document of a maximum-likelihood fit."""
    from ..stochastic import innovation_tests

    tests = result.innovation_tests()
    # ``valid`` is None with --validate none: the validation entries are null
    valid_states = None if valid is None else result.states(valid)

    doc = result.to_dict()
    starts = list(result.starts.status)
    doc.update(
        starts={
            "n": len(starts),
            "converged": starts.count("converged"),
            "max_steps": starts.count("max_steps"),
            "failed": sum(s not in ("converged", "max_steps") for s in starts),
            "at_best": result.n_at_best(),
            "best": result.best,
        },
        residuals={
            "kind": "standardised one-step innovations",
            "white": tests.white,
            "outputs": {o.name: o.to_dict() for o in tests},
            "validation": None
            if valid_states is None
            else {o.name: o.to_dict() for o in innovation_tests(valid_states)},
        },
        validation=None
        if valid_states is None
        else {"loglik": valid_states.loglik, "n": len(valid)},
        k_step_rmse={str(k): v["rmse"] for k, v in result.states().k_step_errors(K_STEPS).items()},
        simulation_rmse={
            "identification": result.simulation_rmse(),
            "validation": None if valid is None else result.simulation_rmse(valid),
        },
        data=data_info(spec, ident, valid),
    )
    doc["timing"] = {**doc["timing"], "total_s": total_s}
    for o in doc["residuals"]["outputs"].values():
        o.pop("residuals", None)
    for o in (doc["residuals"]["validation"] or {}).values():
        o.pop("residuals", None)
    return doc


# ---- estimate ----


def add_estimate_arguments(p) -> None:
    """Declare the arguments of ``jaxbox estimate``."""
    add_data_arguments(p)
    p.add_argument("--model", "-m", required=True, help="library model name")
    p.add_argument(
        "--params",
        required=True,
        metavar="FIT.json",
        help="parameters: the JSON of `jaxbox fit --method ml --json`, or {name: value} (SI)",
    )
    p.add_argument("--out", required=True, metavar="STATES.csv", help="CSV file to write")
    p.add_argument(
        "--hold", choices=("foh", "zoh"), default=None, help="input hold (default: the fit's)"
    )
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")


def _read_params(path: str) -> dict:
    try:
        doc = json.loads(Path(path).read_text())
    except OSError as err:
        raise UsageError(f"--params {path}: cannot read it ({err.strerror or err})") from None
    except json.JSONDecodeError as err:
        raise UsageError(f"--params {path}: not JSON ({err.msg} at line {err.lineno})") from None
    if isinstance(doc, dict) and "fits" in doc:
        if len(doc["fits"]) != 1:
            raise UsageError(
                f"--params {path} holds {len(doc['fits'])} fits; save the one to use alone"
            )
        doc = doc["fits"][0]
    if not isinstance(doc, dict):
        raise UsageError(f"--params {path}: expected a JSON object")
    params = doc.get("params", doc)
    if not isinstance(params, dict) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in params.values()
    ):
        raise UsageError(f"--params {path}: 'params' must map parameter names to numbers")
    return {"params": params, "hold": doc.get("hold"), "x0_std": doc.get("x0_std")}


def estimate_command(args) -> int:
    """``jaxbox estimate DATA --model NAME --params FIT.json --out STATES.csv``."""
    from ..fit import FitError
    from ..models import get_model
    from ..stochastic import estimate_states

    model = get_model(args.model)
    fit = _read_params(args.params)
    view = _stochastic_view(model)
    extra = sorted(set(fit["params"]) - set(view.param_names))
    if extra:
        raise UsageError(
            f"--params {args.params}: {', '.join(extra)} not parameters of {model.name}'s "
            f"stochastic form ({', '.join(view.param_names)}); was it fitted with another model?"
        )
    opts = DataOptions(args)
    if len(opts.specs) != 1:
        raise UsageError("jaxbox estimate takes one DATA")
    if getattr(opts, "train", None) or getattr(opts, "valid", None):
        raise UsageError("--train and --validate do not apply to estimate: it filters all of DATA")
    out = Path(args.out)
    if not out.parent.exists():
        raise UsageError(f"--out {out}: folder {out.parent} does not exist")
    hold = args.hold or fit["hold"] or "foh"
    data = load_data(opts.specs[0], opts)
    data.require(list(model.inputs) + list(model.outputs), what=f"model {model.name}")
    data = _one_series(data, model, opts.max_gap, "the data", "a file of the rows on one side")
    x0 = fit["x0_std"]
    if isinstance(x0, list) and len(x0) != model.n_states:
        raise UsageError(
            f"--params {args.params}: x0_std holds {len(x0)} value(s) but {model.name} has "
            f"{model.n_states} state(s) ({', '.join(model.states)}); was it fitted with another "
            "model?"
        )
    try:
        est = estimate_states(
            model,
            fit["params"],
            data,
            hold=hold,
            x0_std=dict(zip(model.states, x0, strict=True)) if isinstance(x0, list) else x0,
        )
    except FitError as err:
        raise UsageError(str(err)) from None
    frame = est.to_frame(("filtered", "smoothed"))
    # everything computed before the file is written: an error leaves no file behind
    summary = {
        "model": model.name,
        "out": str(out),
        "samples": len(frame),
        "loglik": est.loglik,
        "current": est.current(),
    }
    tmp = out.with_name(out.name + ".part")
    try:
        frame.to_csv(tmp, index_label="time")
        tmp.replace(out)
    finally:
        tmp.unlink(missing_ok=True)
    if args.json:
        print_json(summary)
    else:
        states = ", ".join(f"{k} {v:.2f} °C" for k, v in summary["current"]["states"].items())
        print(f"wrote {len(frame)} rows to {out}; filtered state at {est.index[-1]}: {states}")
    return 0
