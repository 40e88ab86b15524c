"""The ``jaxbox`` sub-commands: models, fit, demo."""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Sequence
from datetime import datetime
from pathlib import Path

from .._io import to_jsonable

__all__ = ["run", "UsageError", "add_data_arguments", "load_all"]

DATA_HELP = (
    "CSV file with a 'time' column and canonical columns (T_zon, T_amb, Q_hea, I_glo_hor, …), "
    "or a bundled dataset: twinhouse_exp1:N2, twinhouse_exp1:O5 (add @10min for 10-minute data)"
)


def add_data_arguments(p) -> None:
    """DATA and the options that read and split it (shared by ``fit`` and ``select``)."""
    p.add_argument(
        "data",
        metavar="DATA",
        nargs="+",
        help=DATA_HELP + "; several DATA of the same length are fitted together in one batch",
    )
    p.add_argument(
        "--map",
        action="append",
        default=[],
        metavar="CANONICAL=COLUMN",
        help="take canonical signal CANONICAL from your column COLUMN (repeatable)",
    )
    p.add_argument("--time", metavar="COLUMN", help="name of the time column (default: time)")
    p.add_argument(
        "--resample", metavar="RULE", help="resample first, e.g. 1h (mean, right-closed)"
    )
    p.add_argument(
        "--train", metavar="START..END", help="identification period (default: first half)"
    )
    p.add_argument("--validate", metavar="START..END", help="validation period (default: the rest)")


class UsageError(ValueError):
    """A command-line argument is malformed; the message says the expected form."""


def run(args) -> int:
    from ._select import demo_command, select_command

    commands = {"models": _models, "fit": _fit, "select": select_command, "demo": demo_command}
    return commands[args.command](args)


def _print_json(obj) -> None:
    print(json.dumps(to_jsonable(obj), indent=2, allow_nan=False))


def _progress(msg: str, args) -> None:
    """Progress on a terminal only (stderr), never with --json."""
    if not getattr(args, "json", False) and sys.stderr.isatty():
        print(msg, file=sys.stderr, flush=True)


# ---- models ----


def _models(args) -> int:
    from ..models import describe_models, library_models, model_families

    models = library_models()
    if args.json:
        _print_json({"models": describe_models()})
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


# ---- argument helpers ----


def _pairs(items, what: str, example: str) -> dict[str, str]:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise UsageError(f"{what} {item!r} must look like {example}")
        out[key.strip()] = value.strip()
    return out


def _floats(items, what: str, example: str) -> dict[str, float]:
    out = {}
    for key, value in _pairs(items, what, example).items():
        try:
            out[key] = float(value)
        except ValueError:
            raise UsageError(f"{what} {key}={value!r}: {value!r} is not a number") from None
    return out


def _bounds(items) -> dict[str, tuple[float, float]]:
    out = {}
    for key, value in _pairs(items, "--bounds", "R_wal=0.001:0.1").items():
        lo, sep, hi = value.partition(":")
        try:
            out[key] = (float(lo), float(hi))
        except ValueError:
            raise UsageError(f"--bounds {key}={value!r} must look like {key}=LO:HI") from None
        if not sep:
            raise UsageError(f"--bounds {key}={value!r} must look like {key}=LO:HI")
    return out


def _period(text: str | None, what: str):
    if text is None:
        return None
    start, sep, end = text.partition("..")
    if not sep:
        raise UsageError(f"{what} {text!r} must look like START..END (either side may be empty)")
    return (start.strip() or None, end.strip() or None)


def load_data(spec: str, *, columns=None, time_column=None, resample=None):
    """A dataset from a CSV path or a bundled name ``twinhouse_exp1:N2[@10min]``."""
    from ..data import load
    from ..datasets import twinhouse_exp1

    if spec.startswith("twinhouse_exp1"):
        name, _, res = spec.partition("@")
        _, _, house = name.partition(":")
        data = twinhouse_exp1(house=house or "N2", resolution=res or "1h")
        if columns:
            raise UsageError("--map applies to CSV files, not to a bundled dataset")
        return data.resample(resample) if resample else data
    return load(spec, time=time_column, columns=columns or None, resample=resample)


def split_periods(data, train=None, valid=None):
    """Identification and validation datasets from optional (start, end) periods."""
    if train is None and valid is None:
        return data.split()
    if train is not None:
        ident = data.slice(*train)
    else:
        ident = data.slice(None, data.index[data.index < _ts(valid[0] or data.start)][-1])
    if valid is not None:
        val = data.slice(*valid)
    else:
        rest = data.index[data.index > ident.end]
        if len(rest) == 0:
            raise UsageError(
                "no data left after the identification period for validation; shorten --train "
                "or give --validate"
            )
        val = data.slice(rest[0], None)
    return ident, val


def _ts(x):
    import pandas as pd

    return pd.Timestamp(x)


# ---- fit ----


def fit_json(result, validation, *, timing, data_info, valid=None) -> dict:
    """The JSON document of one fit (schema in the README).

    The estimate with its uncertainty, residual analysis and validity verdict come from
    :func:`jaxbox.validate.fit_report`; this adds the multistart counts, timings and data.
    """
    from ..validate import fit_report

    doc = fit_report(result, valid, validation=validation)
    starts = result.starts
    status = list(starts.status)
    doc.update(
        model=result.model.name,
        starts={
            "n": starts.n,
            "converged": status.count("converged"),
            "max_steps": status.count("max_steps"),
            "failed": sum(s not in ("converged", "max_steps") for s in status),
            "at_best": starts.n_at_best(),
            "best": result.best,
        },
        simulator=result.problem.simulator,
        timing=timing,
        data=data_info,
    )
    return doc


def load_all(args):
    """Every DATA of the command line: ``[(spec, data, ident, valid), …]``."""
    columns = _pairs(args.map, "--map", "T_zon=living_temp")
    train, validate = _period(args.train, "--train"), _period(args.validate, "--validate")
    if len(set(args.data)) < len(args.data):
        raise UsageError("the same DATA is given twice; give each dataset once")
    from ..data import DataError

    out = []
    for spec in args.data:
        try:
            data = load_data(spec, columns=columns, time_column=args.time, resample=args.resample)
            ident, valid = split_periods(data, train, validate)
        except (DataError, UsageError) as err:
            if len(args.data) == 1:
                raise
            raise type(err)(f"{spec}: {err}") from None  # which of the files
        out.append((spec, data, ident, valid))
    return out


def _fit(args) -> int:
    from ..fit import fit_batch
    from ..models import get_model
    from ..validate import validate

    fixed = _floats(args.fix, "--fix", "gA=2.5")
    bounds = _bounds(args.bounds)
    model = get_model(args.model)
    sets = load_all(args)
    for spec, _, ident, _ in sets:
        what = f"model {model.name}" + (f" on {spec}" if len(sets) > 1 else "")
        ident.require(list(model.inputs) + list(model.outputs), what=what)
    if args.starts < 1:
        raise UsageError(f"--starts must be at least 1, got {args.starts}")
    lengths = {len(ident) for _, _, ident, _ in sets}
    for spec, _, ident, _ in sets:
        _progress(
            f"fitting {model.name} on {spec}: {len(ident)} samples ({ident.start} .. {ident.end}) "
            f"from {args.starts} starts …",
            args,
        )
    if len(sets) > 1 and len(lengths) > 1:
        _progress(
            "identification periods of different lengths: each length is fitted in a batch "
            "of its own",
            args,
        )
    request = {
        "model": model,
        "fixed": fixed,
        "bounds": bounds,
        "starts": args.starts,
        "seed": args.seed,
        "simulator": args.simulator,
        "max_steps": args.max_steps,
    }
    t0 = time.perf_counter()
    results = fit_batch([{**request, "data": ident} for _, _, ident, _ in sets])
    t1 = time.perf_counter()
    docs = []
    for (spec, _, ident, valid), result in zip(sets, results, strict=True):
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
            data_info=_data_info(spec, ident, valid),
            valid=valid,
        )
        if args.plots:
            folder = Path(args.plots)
            if len(sets) > 1:
                folder = folder / _slug(spec, args.data)
            doc["plots"] = _plots(result, valid, validation, folder)
        docs.append((doc, result, validation))
    if args.json:
        if len(docs) == 1:
            _print_json(docs[0][0])
        else:
            _print_json({"model": model.name, "fits": [d for d, _, _ in docs]})
        return 0
    for (spec, *_), (doc, result, validation) in zip(sets, docs, strict=True):
        if len(docs) > 1:
            print(f"== {spec}")
        print(result.summary())
        print(_rmse_line(validation))
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
        if len(docs) > 1:
            print()
    return 0


def _slug(spec: str, specs: Sequence[str] = ()) -> str:
    """A folder name for a DATA argument, unique among ``specs`` (the numbered position is
    prefixed when two files share a name)."""

    def name(x: str) -> str:
        base = Path(x).stem if not x.startswith("twinhouse_exp1") else x
        return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in base) or "data"

    slug = name(spec)
    if [name(x) for x in specs].count(slug) > 1:
        slug = f"{list(specs).index(spec) + 1}-{slug}"
    return slug


def _plots(result, valid, validation, directory) -> list[str]:
    try:
        from ..validate import save_plots
    except ImportError:  # plotting arrives with the validation package
        raise UsageError("--plots is not available in this version") from None
    return [str(p) for p in save_plots(result, validation, directory)]


def _rmse_line(validation) -> str:
    auto = ", ".join(f"{k} {v:.3f} K" for k, v in validation.rmse_auto.items())
    line = f"RMSE identification: {auto}"
    if validation.rmse_cross is not None:
        cross = ", ".join(f"{k} {v:.3f} K" for k, v in validation.rmse_cross.items())
        line += f" | validation: {cross}"
    return line


def _data_info(spec, ident, valid) -> dict:
    return {
        "source": spec,
        "step_s": ident.step,
        "train": [str(ident.start), str(ident.end)],
        "validate": [str(valid.start), str(valid.end)],
        "n_train": len(ident),
        "n_validate": len(valid),
    }


def _out_dir(out: str | None) -> Path:
    """The output folder: ``out``, or a fresh ``jaxbox-out-<date>-<time>`` folder."""
    if out:
        path = Path(out)
    else:
        stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
        path = Path(f"jaxbox-out-{stamp}")
        n = 1
        while path.exists():
            n += 1
            path = Path(f"jaxbox-out-{stamp}-{n}")
    path.mkdir(parents=True, exist_ok=True)
    return path
