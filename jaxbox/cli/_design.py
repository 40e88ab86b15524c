"""The ``jaxbox design`` command: plan the heating of an identification experiment.

``add_design_arguments(parser)`` declares its options, ``design_command(args)`` runs it. Every
option is checked, and the output file's folder probed for writing, before any computing; the
CSV is written to a temporary file and moved into place at the end.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
from pathlib import Path

from ._common import UsageError, int_option, number, print_json

__all__ = ["add_design_arguments", "design_command"]


def add_design_arguments(p) -> None:
    """Declare the arguments of ``jaxbox design``."""
    p.add_argument("--model", "-m", help="library model name (default: the one of --params)")
    p.add_argument("--params", metavar="FIT.json", help="prior values: a `jaxbox fit --json` file")
    p.add_argument("--days", type=float, default=7.0, help="horizon [days] (default 7)")
    p.add_argument("--step", default="1h", help="sample step: 1h, 30min, 3600 [s]… (default 1h)")
    p.add_argument("--sigma", type=float, default=0.05, help="output noise std [K] (default 0.05)")
    p.add_argument("--power", default="0:3000", help="heater power MIN:MAX [W] (default 0:3000)")
    p.add_argument("--binary", action="store_true", help="on/off heater: only MIN or MAX")
    p.add_argument(
        "--comfort", default="15:35", help="zone temperature band LOW:HIGH [°C], or 'none'"
    )
    p.add_argument("--max-energy", metavar="E", help="energy budget: J, or with a unit: 150kWh")
    p.add_argument("--criterion", choices=("D", "A", "hlc"), default="hlc")
    p.add_argument(
        "--weather",
        metavar="DATA",
        help="weather inputs (CSV or bundled name); default the bundled twin-house weather",
    )
    p.add_argument(
        "--start-temperature",
        type=float,
        help="zone held at [°C] before the start (default: the best of 5 in the band)",
    )
    p.add_argument(
        "--robust", type=int_option, default=0, metavar="N", help="average over N prior samples"
    )
    p.add_argument(
        "--spread", type=float, help="std of log θ of the prior samples (default: the fit's)"
    )
    p.add_argument(
        "--starts",
        type=int_option,
        help="optimiser starts (default: jaxbox.design.plan's, 4)",
    )
    p.add_argument("--seed", type=int_option, default=0)
    p.add_argument("--out", "-o", required=True, metavar="CSV", help="the schedule (CSV)")
    p.add_argument("--baselines", action="store_true", help="add the baselines to the CSV")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def _pair(text: str, option: str) -> tuple[float, float]:
    lo, sep, hi = str(text).partition(":")
    if not sep:
        raise UsageError(f"{option} {text!r} must look like LOW:HIGH")
    a, b = number(lo, option), number(hi, option)
    if not a < b:
        raise UsageError(f"{option} {text!r}: {a:g} must be below {b:g}")
    return a, b


def _step(text: str) -> float:
    import pandas as pd

    try:
        seconds = float(text)
    except ValueError:
        try:
            seconds = pd.Timedelta(text).total_seconds()
        except (ValueError, TypeError):
            raise UsageError(f"--step {text!r}: give e.g. 1h, 30min or seconds") from None
    if not (math.isfinite(seconds) and seconds > 0):
        raise UsageError(f"--step {text!r} must be > 0")
    return seconds


def _energy(text: str | None) -> float | None:
    if text is None:
        return None
    t = text.strip().lower().replace(" ", "")
    factor = 1.0
    for unit, f in (("kwh", 3.6e6), ("mj", 1e6), ("j", 1.0)):
        if t.endswith(unit):
            t, factor = t[: -len(unit)], f
            break
    value = number(t, "--max-energy") * factor
    if not value > 0:
        raise UsageError(f"--max-energy {text!r} must be > 0")
    return value


def _check_out(text: str) -> Path:
    path = Path(text)
    if path.is_dir():
        raise UsageError(f"--out {text!r} is a folder; give a CSV file name")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise UsageError(f"--out {text!r}: the folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK):
        raise UsageError(f"--out {text!r}: cannot write into {str(folder)!r}")
    return path


def design_command(args) -> int:
    """Run ``jaxbox design``: plan, print the predicted stds vs the baselines, write the CSV."""
    if args.model is None and args.params is None:
        raise UsageError("give --model NAME, or --params FIT.json (which names the model)")
    if args.params is not None and not Path(args.params).is_file():
        raise UsageError(f"--params {args.params!r}: no such file")
    power = _pair(args.power, "--power")
    comfort = None if str(args.comfort).lower() == "none" else _pair(args.comfort, "--comfort")
    step = _step(args.step)
    energy = _energy(args.max_energy)
    if not (math.isfinite(args.sigma) and args.sigma > 0):
        raise UsageError(f"--sigma must be > 0 [K], got {args.sigma}")
    if not (math.isfinite(args.days) and args.days > 0):
        raise UsageError(f"--days must be > 0, got {args.days}")
    if args.spread is not None and not (math.isfinite(args.spread) and args.spread >= 0):
        raise UsageError(f"--spread must be ≥ 0, got {args.spread}")
    if args.starts is not None and args.starts < 1:
        raise UsageError(f"--starts must be at least 1, got {args.starts}")
    if args.robust < 0:
        raise UsageError(f"--robust must be ≥ 0, got {args.robust}")
    if args.seed < 0:
        raise UsageError(f"--seed must be ≥ 0, got {args.seed}")
    if args.start_temperature is not None and not math.isfinite(args.start_temperature):
        raise UsageError(
            f"--start-temperature must be a finite number [°C], got {args.start_temperature}"
        )
    out = _check_out(args.out)
    weather = None
    if args.weather is not None:
        from ._data import load_data

        weather = load_data(args.weather)
    from ..design import plan

    design = plan(
        args.model,
        args.params,
        sigma=args.sigma,
        days=args.days,
        step=step,
        weather=weather,
        power=power,
        binary=args.binary,
        comfort=comfort,
        max_energy=energy,
        criterion=args.criterion,
        start_temperature=args.start_temperature,
        robust=args.robust,
        spread=args.spread,
        seed=args.seed,
        **({} if args.starts is None else {"starts": args.starts}),
    )
    # everything computed before the file is written: an error leaves no file behind
    doc = {**design.to_dict(), "out": str(out)} if args.json else None
    summary = None if args.json else design.summary()
    fd, tmp = tempfile.mkstemp(prefix=".jaxbox-design-", suffix=".csv", dir=out.parent or ".")
    os.close(fd)
    try:
        design.to_csv(tmp, baselines=args.baselines)
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    if doc is not None:
        print_json(doc)
    else:
        print(summary)
        print(f"schedule written to {out}", file=sys.stderr)
    return 0
