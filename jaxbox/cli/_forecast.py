"""``jaxbox forecast``: a forecast with bands from a fit file (and the heat demand for a setpoint).

``jaxbox forecast DATA --params FIT.json --at TIME --horizon 24h [--inputs FUTURE.csv]
--out forecast.csv [--plot forecast.png]``: the Kalman filter of the fit's stochastic form over
DATA up to ``--at``, then the forecast over the horizon driven by the inputs of ``--inputs`` (a
weather forecast, planned heating) or, without it, by the measured inputs after ``--at`` (a
backtest: the forecast's RMSE and the bands' coverage are printed). A fit file of an
output-error fit has no noise parameters: they are estimated from its residuals over DATA up to
``--at`` (said so on the output).
"""

from __future__ import annotations

import json
from pathlib import Path

from ._common import UsageError, print_json
from ._data import DataOptions, add_data_arguments, load_data

__all__ = [
    "add_forecast_arguments",
    "forecast_command",
    "read_fit",
    "fit_form",
    "check_fit_params",
    "output_file",
]


def add_forecast_arguments(p) -> None:
    """Declare the arguments of ``jaxbox forecast``."""
    add_data_arguments(p)
    p.add_argument(
        "--params",
        required=True,
        metavar="FIT.json",
        help="the fit: the JSON of `jaxbox fit --json` (output error or --method ml)",
    )
    p.add_argument("--model", "-m", help="model name (default: the fit file's)")
    p.add_argument(
        "--at",
        required=True,
        metavar="TIME",
        help="origin of the forecast: the data up to TIME are filtered",
    )
    p.add_argument(
        "--horizon", default="24h", metavar="DURATION", help="forecast horizon (default 24h)"
    )
    p.add_argument(
        "--inputs",
        metavar="FUTURE.csv",
        help="future inputs (time and the model's input columns) after --at; default: the "
        "measured inputs of DATA (a backtest, scored against the measurements)",
    )
    p.add_argument(
        "--setpoint",
        type=float,
        metavar="°C",
        help="instead of the free forecast: the heating power that holds the zone at this "
        "setpoint (the model inverted, clipped to the heater's range), with the energy",
    )
    p.add_argument(
        "--setback",
        metavar="°C@HH:MM-HH:MM",
        help="a lower setpoint over part of each day, e.g. 17@22:00-06:00 (with --setpoint)",
    )
    p.add_argument("--q-max", type=float, metavar="W", help="the heater's maximum power [W]")
    p.add_argument(
        "--q-min", type=float, default=0.0, metavar="W", help="its minimum power (default 0)"
    )
    p.add_argument(
        "--parameters",
        action="store_true",
        help="the bands also hold the uncertainty of the estimated parameters (from the fit "
        "file's standard deviations and correlations)",
    )
    p.add_argument("--out", required=True, metavar="FORECAST.csv", help="CSV file to write")
    p.add_argument("--plot", metavar="FORECAST.png", help="also draw the forecast")
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")


def output_file(text: str, option: str) -> Path:
    """The file an option names for writing: a name in a folder that exists."""
    path = Path(text)
    if not text.strip() or path.name in ("", ".", ".."):
        raise UsageError(f"{option} is empty or not a file name; give a file to write")
    if path.is_dir():
        raise UsageError(f"{option} {text}: it is a folder; give a file to write")
    if not path.parent.exists():
        raise UsageError(f"{option} {text}: folder {path.parent} does not exist")
    return path


def read_fit(path: str, option: str = "--params") -> dict:
    """A fit file: ``model`` (or None), ``params`` {name: SI value}, ``hold``, ``x0_std``, and
    ``state`` / ``state_cov`` where the file holds a state estimate. Reads the JSON of
    ``jaxbox fit --json`` (output error: ``params`` of ``{"value": …}``; ``--method ml``:
    numbers) or a plain ``{name: value}`` object."""
    try:
        doc = json.loads(Path(path).read_text())
    except OSError as err:
        raise UsageError(f"{option} {path}: cannot read it ({err.strerror or err})") from None
    except json.JSONDecodeError as err:
        raise UsageError(f"{option} {path}: not JSON ({err.msg} at line {err.lineno})") from None
    if isinstance(doc, dict) and "fits" in doc:
        if not isinstance(doc["fits"], list) or len(doc["fits"]) != 1:
            raise UsageError(f"{option} {path} holds several fits; save the one to use alone")
        doc = doc["fits"][0]
    if not isinstance(doc, dict):
        raise UsageError(f"{option} {path}: expected a JSON object")
    if "table" in doc and "fit" in doc and "params" not in doc:
        # the JSON of `jaxbox select --json` (or its selection.json): the accepted model's fit,
        # or the network of the heat-demand form it accepted (the zone's initial temperature
        # is then the measured one: see fill_initial_outputs)
        form = doc.get("form_model")
        if isinstance(doc["fit"], dict):
            doc = doc["fit"]
        elif isinstance(form, dict) and isinstance(form.get("params"), dict):
            fixed = form.get("fixed") if isinstance(form.get("fixed"), dict) else {}
            doc = {"model": form.get("structure"), "params": {**fixed, **form["params"]}}
        else:
            raise UsageError(
                f"{option} {path}: the structure search it holds accepted no model; fit one "
                "with `jaxbox fit DATA --model NAME --json` and give that file"
            )
    raw = doc.get("params", doc)
    params = {}
    if isinstance(raw, dict):
        for name, value in raw.items():
            if isinstance(value, dict):
                value = value.get("value")
            if isinstance(value, int | float) and not isinstance(value, bool):
                params[name] = float(value)
            elif name in ("model", "method", "hold"):
                continue
            else:
                params = None
                break
    if not params:
        raise UsageError(
            f"{option} {path}: no parameters; expected the JSON of `jaxbox fit --json` or "
            "{name: value} (SI)"
        )
    model = doc.get("model") if isinstance(doc.get("model"), str) else None
    columns = doc.get("model_columns")
    columns = (
        columns if isinstance(columns, list) and all(isinstance(c, str) for c in columns) else None
    )
    info = doc.get("data") if isinstance(doc.get("data"), dict) else {}
    step = info.get("step_s")
    return {
        "covariance": _covariance(doc),
        "step": float(step) if isinstance(step, int | float) and step > 0 else None,
        "model": model,
        "columns": columns,
        "params": params,
        "hold": doc.get("hold"),
        "x0_std": doc.get("x0_std"),
        "state": doc.get("state"),
        "state_cov": doc.get("state_cov"),
    }


def _covariance(doc: dict):
    """``(names, covariance)`` [SI²] of the estimated parameters from a fit document's
    standard deviations and correlations (``--method ml``: ``table`` and ``correlation``
    ``{names, matrix}``; output error: ``params[…].std`` and ``correlation`` as nested
    dicts), or None where it has none."""
    import numpy as np

    corr = doc.get("correlation")
    try:
        if isinstance(corr, dict) and "names" in corr and "matrix" in corr:
            names = list(corr["names"])
            sd = [doc["table"][n]["sd"] for n in names]
            R = np.asarray(corr["matrix"], float)
        elif isinstance(corr, dict) and corr:
            names = list(corr)
            sd = [doc["params"][n]["std"] for n in names]
            R = np.asarray([[corr[a][b] for b in names] for a in names], float)
        else:
            return None
        sd = np.asarray(sd, float)
    except (KeyError, TypeError, ValueError):
        return None
    if R.shape != (len(names), len(names)) or not (np.all(np.isfinite(R)) and np.all(sd >= 0)):
        return None
    return tuple(names), R * sd[:, None] * sd[None, :]


def fit_model_of(fit: dict, name: str | None, path: str, option: str = "--params", columns=None):
    """The model of a fit file (``--model`` must agree with the file's own). A structure name
    is built for the columns it was fitted on (the file's ``model_columns``), else for
    ``columns`` (the data at hand), else with every input the grammar knows."""
    from ..models import get_model

    columns = fit.get("columns") or columns
    if name and fit["model"] and get_model(name).name != get_model(fit["model"]).name:
        raise UsageError(
            f"{option} {path} is a fit of {fit['model']}, not of --model {name}; give the fit "
            f"file of {name} or leave --model out"
        )
    if not (name or fit["model"]):
        raise UsageError(f"{option} {path} does not name its model; give --model")
    return get_model(name or fit["model"], columns)


def check_fit_params(fit: dict, model, path: str, option: str = "--params") -> None:
    """The parameters of a fit file must be those of ``model`` (its noise parameters may be
    missing: an output-error fit); else one line asking whether it is another model's."""
    from ..stochastic import noise_names

    params = fit["params"]
    known = set(model.param_names) | set(noise_names(model))
    extra = sorted(set(params) - known)
    missing = [n for n in model.param_names if n not in params]
    if extra or missing:
        what = f"{', '.join(extra)} not parameters of {model.name}" if extra else ""
        if missing:
            what += ("; " if what else "") + f"{', '.join(missing)} missing"
        raise UsageError(f"{option} {path}: {what}; was it fitted with another model?")


def fit_form(
    fit: dict,
    model,
    path: str,
    data=None,
    option: str = "--params",
    step: float | None = None,
    max_gap: float | None = None,
):
    """The stochastic form of a fit file: its noise parameters where it has them (a
    maximum-likelihood fit), else noise estimated from the residuals over ``data``."""
    from ..forecast import StochasticForm, noise_from_residuals
    from ..stochastic import noise_names

    check_fit_params(fit, model, path, option)
    params = fit["params"]
    noise = noise_names(model)
    if all(n in params for n in noise):
        step = float(data.step) if data is not None else fit["step"] or step
        if step is None:
            raise UsageError(f"{option} {path} does not say its sampling step; give --step")
        x0 = fit["x0_std"]
        if not (isinstance(x0, list) and len(x0) == model.n_states):
            x0 = [1.0] * model.n_states
        return StochasticForm(
            model=model,
            params={n: params[n] for n in (*model.param_names, *noise)},
            hold=fit["hold"] or "foh",
            x0_std=tuple(float(v) for v in x0),
            source="ml",
            note="noise parameters of the fit file (maximum likelihood)",
            step=step,
        )
    if data is None:
        raise UsageError(
            f"{option} {path} is an output-error fit without noise parameters; its stochastic "
            "form needs data to estimate them from"
        )
    from ..data._gaps import DEFAULT_MAX_GAP

    gap = DEFAULT_MAX_GAP if max_gap is None else max_gap  # None: the fits' default
    return noise_from_residuals(model, params, data, max_gap=gap)


def fill_initial_outputs(fit: dict, model, data) -> None:
    """The initial temperature ``T_<node>0`` of each measured state that the fit file lacks
    (a heat-demand form, whose zone temperature was an input) set to its first measurement in
    ``data`` [°C]."""
    import numpy as np

    for state in model.states:  # states are named after their node's temperature: T_zon
        name = f"{state}0"
        if name in model.param_names and name not in fit["params"] and state in model.outputs:
            x = np.asarray(data[state], float)
            x = x[np.isfinite(x)]
            if x.size:
                fit["params"][name] = float(x[0])


def _future_data(path: str, opts):
    """``--inputs FUTURE.csv`` read as DATA is (``--map``, ``--unit``, ``--scale``, the time
    and CSV options: the same logger's format), the maps of columns it lacks (the outputs,
    which a file of future inputs need not hold) left out."""
    import copy

    import pandas as pd

    opts = copy.copy(opts)
    if opts.columns and str(path).lower().endswith((".csv", ".txt")):
        try:
            header = set(pd.read_csv(path, nrows=0, sep=opts.sep or ",").columns)
        except (OSError, ValueError, pd.errors.ParserError):
            header = None  # load reports what is wrong with the file
        if header is not None:
            opts.columns = {
                k: v
                for k, v in opts.columns.items()
                if all(c in header for c in ([v] if isinstance(v, str) else v))
            }
    return load_data(path, opts)


def _history(data, at: str):
    from ..data import DataError

    try:
        history = data.slice(None, at)
    except DataError as err:
        raise UsageError(f"--at {at}: {err}") from None
    if len(history) == len(data) and history.end < data._bound(at, "--at"):
        raise UsageError(
            f"--at {at} is after the data's last sample ({data.end}): the forecast starts from "
            f"the state the filter estimates at --at from the data up to it; give --at "
            f"{data.end} or earlier (and --inputs FUTURE.csv with the inputs after it)"
        )
    if len(history) < 3:
        raise UsageError(
            f"--at {at}: the data hold {len(history)} sample(s) up to it; the filter needs at "
            f"least 3 (the data start at {data.start})"
        )
    return history


def forecast_command(args) -> int:
    """``jaxbox forecast DATA --params FIT.json --at TIME --horizon 24h --out FORECAST.csv``."""
    import numpy as np

    from ..forecast import forecast, plot_forecast

    opts = DataOptions(args)
    if len(opts.specs) != 1:
        raise UsageError("jaxbox forecast takes one DATA")
    if getattr(opts, "train", None) or getattr(opts, "valid", None):
        raise UsageError("--train and --validate do not apply to forecast: give --at")
    out = output_file(args.out, "--out")
    plot = None if args.plot is None else output_file(args.plot, "--plot")
    if args.setpoint is not None and args.parameters:
        raise UsageError("--parameters applies to the forecast, not to the heat demand")
    if args.setpoint is None and (args.setback or args.q_max is not None):
        raise UsageError("--setback and --q-max go with --setpoint")
    if args.setpoint is not None and args.q_max is None:
        raise UsageError("--setpoint needs the heater's maximum power --q-max W")
    if args.setback:
        from ..forecast import parse_setback

        parse_setback(args.setback)
    fit = read_fit(args.params)
    data = load_data(opts.specs[0], opts)
    model = fit_model_of(fit, args.model, args.params, columns=data.columns)
    history = _history(data, args.at)
    history.require(list(model.inputs) + list(model.outputs), what=f"model {model.name}")
    fill_initial_outputs(fit, model, history)
    form = fit_form(fit, model, args.params, history, max_gap=opts.max_gap)
    future = data if args.inputs is None else _future_data(args.inputs, opts)
    if args.setpoint is not None:
        return _demand_command(args, form, history, future, out, opts.max_gap)
    cov = None
    if args.parameters:
        from ..stochastic import noise_names

        cov = fit["covariance"]
        if cov is None:
            raise UsageError(
                f"--parameters: {args.params} holds no covariance of its parameters (the "
                "standard deviations and correlations of `jaxbox fit --json`)"
            )
        keep = [i for i, n in enumerate(cov[0]) if n not in noise_names(model)]
        cov = (tuple(cov[0][i] for i in keep), cov[1][keep][:, keep])
    frame = forecast(
        form,
        history,
        future,
        horizon=args.horizon,
        parameters=cov or False,
        max_gap=opts.max_gap,
    )
    tmp = out.with_name(out.name + ".part")
    frame.to_csv(tmp, index_label="time")
    fig = plot_forecast(frame, history) if plot is not None else None
    tmp.replace(out)
    if fig is not None:
        fig.savefig(plot, dpi=110)
    summary = {
        "model": model.name,
        "origin": frame.attrs["origin"],
        "horizon_samples": len(frame),
        "noise": form.note,
        "parameters": bool(cov),
        "calibration": frame.attrs["calibration"],
        "missing_inputs": frame.attrs.get("bridged"),
        "out": str(out),
        "outputs": {},
    }
    for o in model.outputs:
        row = {
            "mean_end": float(frame[f"{o}_mean"].iloc[-1]),
            "sd_end": float(frame[f"{o}_sd"].iloc[-1]),
        }
        if args.inputs is None and f"{o}_measured" in frame:
            meas = frame[f"{o}_measured"].to_numpy()
            ok = np.isfinite(meas)
            err = meas[ok] - frame[f"{o}_mean"].to_numpy()[ok]
            row.update(
                n=int(ok.sum()),
                rmse=float(np.sqrt(np.mean(err**2))) if ok.any() else None,
                cover50=_inside(frame, o, "50", ok),
                cover95=_inside(frame, o, "95", ok),
            )
        summary["outputs"][o] = row
    if args.json:
        print_json(summary)
        return 0
    with_theta = "; the bands hold the parameters' uncertainty" if cov else ""
    print(f"wrote {len(frame)} rows to {out} ({form.note}{with_theta})")
    print(f"bands calibrated on the history: {frame.attrs['calibration']}")
    if frame.attrs.get("bridged"):
        print(f"missing inputs: {frame.attrs['bridged']}")
    for o, row in summary["outputs"].items():
        end = frame.index[-1]
        print(f"{o} at {end}: {row['mean_end']:.2f} ± {row['sd_end']:.2f} °C (mean ± sd)")
        if "rmse" in row and row["n"]:
            print(
                f"backtest {o}: RMSE {row['rmse']:.3f} K over {row['n']} samples; the 95 % "
                f"band holds {row['cover95']:.0%} of the measurements, the 50 % band "
                f"{row['cover50']:.0%}"
            )
    return 0


def _demand_command(args, form, history, future, out: Path, max_gap: float) -> int:
    """``jaxbox forecast … --setpoint 21 [--setback 17@22:00-06:00] --q-max 3000``."""
    from ..forecast import heat_demand

    frame = heat_demand(
        form,
        history,
        future,
        setpoint=args.setpoint,
        setback=args.setback,
        q_max=args.q_max,
        q_min=args.q_min,
        horizon=args.horizon,
        max_gap=max_gap,
    )
    tmp = out.with_name(out.name + ".part")
    frame.to_csv(tmp, index_label="time")
    tmp.replace(out)
    if args.plot:
        _plot_demand(frame).savefig(args.plot, dpi=110)
    a = frame.attrs
    summary = {
        "model": a["model"],
        "origin": a["origin"],
        "heater": a["heater"],
        "energy_kwh": a["energy_kwh"],
        "energy_kwh_95": [a["energy_kwh_lo95"], a["energy_kwh_hi95"]],
        "unreached": [list(s) for s in a["unreached"]],
        "noise": a["noise"],
        "out": str(out),
    }
    if args.json:
        print_json(summary)
        return 0
    print(f"wrote {len(frame)} rows to {out} ({a['noise']})")
    print(
        f"heat demand {a['heater']} over {len(frame)} samples from {a['origin']}: "
        f"{a['energy_kwh']:.2f} kWh (95 %: {a['energy_kwh_lo95']:.2f}–{a['energy_kwh_hi95']:.2f}), "
        f"peak {frame[a['heater']].max():.0f} W"
    )
    return 0


def _plot_demand(frame):
    from matplotlib.figure import Figure

    a = frame.attrs
    fig = Figure(figsize=(10.0, 5.5), layout="constrained")
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    t = frame.index.to_numpy()
    ax1.fill_between(t, frame[f"{a['zone']}_lo95"], frame[f"{a['zone']}_hi95"], alpha=0.25, lw=0)
    ax1.plot(t, frame[a["zone"]], label=a["zone"])
    ax1.step(t, frame["setpoint"], where="pre", color="0.3", ls="--", label="setpoint")
    ax1.set_ylabel("°C")
    ax1.legend(loc="best", fontsize="small")
    ax2.fill_between(
        t, frame[f"{a['heater']}_lo95"], frame[f"{a['heater']}_hi95"], step="pre", alpha=0.25
    )
    ax2.step(t, frame[a["heater"]], where="pre", label=f"{a['heater']} [W]")
    ax2.axhline(a["q_max"], color="tab:red", lw=0.8, ls=":")
    ax2.set_ylabel("W")
    ax1.set_title(f"heat demand of {a['model']} from {a['origin']}: {a['energy_kwh']:.1f} kWh")
    return fig


def _inside(frame, output: str, band: str, ok) -> float | None:
    if not ok.any():
        return None
    meas = frame[f"{output}_measured"].to_numpy()[ok]
    lo = frame[f"{output}_lo{band}"].to_numpy()[ok]
    hi = frame[f"{output}_hi{band}"].to_numpy()[ok]
    return float(((meas >= lo) & (meas <= hi)).mean())
