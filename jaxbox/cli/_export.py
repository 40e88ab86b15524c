"""``jaxbox export FIT.json --step 15min --format json|npz|modelica|python-control --out PATH``:
a fit file as the exact discrete-time state space of :func:`jaxbox.control.to_state_space`, a
Modelica model of its RC network, or a python-control script.

The last state estimate (and, for an output-error fit, the noise of its stochastic form) needs
data: ``--data DATA``, or by default the fit file's own data (``data.source`` with its
identification window) where that can be read. Without any, the export has no state estimate
and, for an output-error fit, no noise covariances.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from ._common import UsageError, print_json
from ._forecast import (
    check_fit_params,
    fill_initial_outputs,
    fit_form,
    fit_model_of,
    output_file,
    read_fit,
)

__all__ = ["add_export_arguments", "export_command"]

_SUFFIX = {".json": "json", ".npz": "npz", ".mo": "modelica", ".py": "python-control"}


def add_export_arguments(p) -> None:
    """Declare the arguments of ``jaxbox export``."""
    p.add_argument("fit", metavar="FIT.json", help="the JSON of `jaxbox fit --json`")
    p.add_argument("--model", "-m", help="model name (default: the fit file's)")
    p.add_argument(
        "--step", metavar="DURATION", help="sampling step, e.g. 15min (default: the fit's)"
    )
    p.add_argument(
        "--format",
        choices=tuple(dict.fromkeys(_SUFFIX.values())),  # jaxbox.control.FORMATS (tested)
        help="json, npz, modelica or python-control (default from the suffix of --out: .json, "
        ".npz, .mo, .py)",
    )
    p.add_argument("--out", required=True, metavar="PATH", help="file to write")
    p.add_argument(
        "--data",
        metavar="DATA",
        help="data whose end the state estimate is for (CSV or a bundled name; default: the "
        "fit's own identification data where it can be read)",
    )
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")


def _fit_data(path: str, given: str | None):
    """The data of the state estimate: ``--data``, else the fit file's source and window."""
    from ..data import DataError
    from ..datasets import is_bundled
    from ._data import load_data

    if given:
        return load_data(given), f"--data {given}"
    try:
        doc = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError):
        return None, "no data"
    info = doc.get("data") if isinstance(doc, dict) else None
    source = info.get("source") if isinstance(info, dict) else None
    if not isinstance(source, str) or not (is_bundled(source) or Path(source).is_file()):
        return None, "no data (give --data for the state estimate)"
    try:
        data = load_data(source)
        train = info.get("train")
        if isinstance(train, list) and len(train) == 2:
            data = data.slice(*train)
    except DataError:
        return None, "no data (the fit's data could not be read: give --data)"
    return data, f"the fit's data ({source})"


def export_command(args) -> int:
    """``jaxbox export FIT.json --step 15min --format json --out MODEL.json``."""
    from ..control import modelica_model, to_state_space
    from ..data import DataError
    from ..forecast import StochasticForm
    from ..stochastic import noise_names

    out = output_file(args.out, "--out")
    fmt = args.format or _SUFFIX.get(out.suffix)
    if fmt is None:
        raise UsageError(
            f"--out {out}: give --format (json, npz, modelica, python-control) or a suffix "
            ".json, .npz, .mo or .py"
        )
    fit = read_fit(args.fit, option="FIT.json")
    step = _step(args.step)
    data, where = _fit_data(args.fit, args.data)
    columns = None if data is None else data.columns
    model = fit_model_of(fit, args.model, args.fit, option="FIT.json", columns=columns)
    if data is not None:
        try:
            data.require(list(model.inputs) + list(model.outputs), what=f"model {model.name}")
        except DataError:
            if args.data:
                raise
            # the fit's file read again without the column mapping it was loaded with
            data, where = None, "no data (the fit's data name their columns otherwise: give --data)"
    if data is not None:
        fill_initial_outputs(fit, model, data)
    check_fit_params(fit, model, args.fit, option="FIT.json")
    noisy = all(n in fit["params"] for n in noise_names(model))
    if data is None and not noisy:  # an output-error fit without data: no noise, no state
        params = {n: fit["params"][n] for n in model.param_names}
        params.update({n: 0.0 for n in noise_names(model)})
        if step is None and fit["step"] is None:
            raise UsageError("give --step: without data the fit's step is not known")
        form = StochasticForm(
            model, params, "foh", (1.0,) * model.n_states, "oe", "", fit["step"] or step
        )
    else:
        form = fit_form(fit, model, args.fit, data, option="FIT.json", step=step)
    ssm = to_state_space(form, step, data=data)
    if data is None and not noisy:
        ssm = dataclasses.replace(
            ssm, Q=None, R=None, noise="unknown: an output-error fit exported without data"
        )
    text = modelica_model(model, fit["params"]) if fmt == "modelica" else None
    ssm.save(out, fmt, modelica=text)
    summary = {
        "model": model.name,
        "format": fmt,
        "out": str(out),
        "step_s": ssm.step,
        "hold": ssm.hold,
        "state_estimate": None if ssm.x is None else {"time": ssm.time, "x": ssm.x.tolist()},
        "state_from": where,
        "noise": ssm.noise,
    }
    if args.json:
        print_json(summary)
        return 0
    est = "no state estimate" if ssm.x is None else f"state estimate at {ssm.time} from {where}"
    print(f"wrote {model.name} ({fmt}, step {ssm.step:g} s, {ssm.hold} hold) to {out}; {est}")
    return 0


def _step(text: str | None) -> float | None:
    """``--step`` in seconds (a duration such as 15min, or seconds)."""
    import pandas as pd

    if text is None:
        return None
    try:
        seconds = float(text)
    except ValueError:
        try:
            seconds = pd.Timedelta(text).total_seconds()
        except (TypeError, ValueError):
            seconds = float("nan")
    if not seconds > 0 or seconds == float("inf"):
        raise UsageError(f"--step must be a positive duration such as 15min or 900, got {text!r}")
    return seconds
