"""The ``jaxbox fleet`` command: a fleet of buildings on Dask, and a synthetic fleet to try it.

``jaxbox fleet SOURCE --out OUT`` identifies every building of SOURCE (a folder of CSV files or
a long-format table with a ``building`` column) on a local Dask cluster, or on a running one
with ``--scheduler tcp://HOST:PORT``; ``jaxbox fleet make DIR --n N`` writes a synthetic fleet
with its answer key ``truth.csv``.
"""

from __future__ import annotations

import sys

from ._common import UsageError, int_option, print_json
from ._data import _stuck_hours

__all__ = ["add_fleet_arguments", "fleet_command"]


def add_fleet_arguments(p) -> None:
    """Declare the arguments of ``jaxbox fleet``."""
    p.add_argument(
        "source",
        metavar="SOURCE",
        help="folder with one CSV/Parquet file per building, or a long-format .parquet/.csv "
        "file with a 'building' column; or 'make' to write a synthetic fleet into DIR",
    )
    p.add_argument("dir", nargs="?", metavar="DIR", help="(with 'make') the folder to write")
    p.add_argument("--out", metavar="OUT", help="output folder (results.parquet, fits/)")
    p.add_argument("--config", metavar="FILE.toml", help="settings (see the README)")
    p.add_argument(
        "--models",
        "--model",
        dest="models",
        metavar="search|A,B,…|FAMILY|all",
        help="'search' (the structure search), one model (fitted as given) or several, a "
        "family or 'all' (forward selection); default: the config, else search",
    )
    p.add_argument("--starts", type=int_option, help="starts per fit (default: the config)")
    p.add_argument("--seed", type=int_option, help="seed of the starts (default 0)")
    p.add_argument("--partition-size", type=int_option, help="buildings per Dask task (default 16)")
    p.add_argument(
        "--max-gap",
        metavar="DURATION",
        help="input gaps up to DURATION (e.g. 2h) are interpolated, longer ones cut the window "
        "(default: the config, else 1h)",
    )
    p.add_argument(
        "--stuck-hours",
        metavar="H",
        help="a temperature unchanged for H hours is a stuck sensor; 'none': no such check "
        "(default: the config, else 24)",
    )
    p.add_argument(
        "--scheduler", metavar="tcp://HOST:PORT", help="address of a running Dask scheduler"
    )
    p.add_argument(
        "--workers",
        type=int,
        help="local worker processes (default: one per core; 0: in this process, no Dask)",
    )
    p.add_argument("--resume", action="store_true", help="skip buildings already in OUT")
    p.add_argument("--no-fits", action="store_true", help="no fit JSON per building")
    p.add_argument("--json", action="store_true", help="print the run summary as JSON")
    # jaxbox fleet make DIR
    p.add_argument(
        "--n", type=int_option, help=f"(make) number of buildings (default {_MAKE['n']})"
    )
    p.add_argument(
        "--days", type=float, help=f"(make) days of hourly data (default {_MAKE['days']:g})"
    )
    p.add_argument(
        "--noise", type=float, help=f"(make) noise on T_zon [K] (default {_MAKE['noise']:g})"
    )


#: the defaults of the options of ``jaxbox fleet make``
_MAKE = {"n": 20, "days": 31.0, "noise": 0.1}
#: the options of ``jaxbox fleet SOURCE`` that ``make`` does not take (attribute, option)
_RUN_ONLY = (
    ("out", "--out"),
    ("config", "--config"),
    ("starts", "--starts"),
    ("partition_size", "--partition-size"),
    ("max_gap", "--max-gap"),
    ("stuck_hours", "--stuck-hours"),
    ("scheduler", "--scheduler"),
    ("workers", "--workers"),
    ("resume", "--resume"),
    ("no_fits", "--no-fits"),
)


def _hours(text: str | None):
    """``--stuck-hours`` read as ``jaxbox select`` reads it, as the config takes it: a number
    of hours, ``"none"`` (no check), or ``None`` (not given: the config's)."""
    if text is None:
        return None
    hours = _stuck_hours(text)
    return "none" if hours is None else hours


def _given(args, pairs) -> list[str]:
    """The options of ``pairs`` (attribute, option) given on the command line."""
    return [option for attr, option in pairs if getattr(args, attr, None) not in (None, False)]


def _models(text: str | None):
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise UsageError("--models must be 'search' or name models (A,B,…), a family or 'all'")
    return names[0] if len(names) == 1 and "," not in text else tuple(names)


def _make(args) -> int:
    from ..datasets import FLEET_MODELS, make_fleet

    if args.dir is None:
        raise UsageError("jaxbox fleet make DIR --n N: give the folder to write")
    extra = _given(args, _RUN_ONLY)
    if extra:
        raise UsageError(
            f"{extra[0]} does not apply to 'jaxbox fleet make DIR' (it takes --n, --days, "
            "--noise, --model, --seed, --json)"
        )
    n, days, noise = (
        _MAKE[k] if getattr(args, k) is None else getattr(args, k) for k in ("n", "days", "noise")
    )
    model = args.models or "ZonWal"
    if model not in FLEET_MODELS:
        raise UsageError(f"--model {model!r}: the generator draws {', '.join(FLEET_MODELS)}")
    try:
        _, truth = make_fleet(
            n,
            args.dir,
            model=model,
            days=days,
            noise=noise,
            seed=0 if args.seed is None else args.seed,
        )
    except ValueError as err:
        raise UsageError(str(err)) from None
    if args.json:
        print_json({"dir": args.dir, "buildings": len(truth), "truth": f"{args.dir}/truth.csv"})
    else:
        print(f"{len(truth)} buildings ({model}) in {args.dir}, answer key {args.dir}/truth.csv")
    return 0


def fleet_command(args) -> int:
    """``jaxbox fleet SOURCE --out OUT`` (or ``jaxbox fleet make DIR --n N``)."""
    from ..fleet import FleetError, load_config, run_fleet

    if args.source == "make" and args.dir is not None:
        return _make(args)
    if args.dir is not None:
        raise UsageError(f"unexpected argument {args.dir!r} (one SOURCE, and --out OUT)")
    make_only = _given(args, (("n", "--n"), ("days", "--days"), ("noise", "--noise")))
    if make_only:
        raise UsageError(
            f"{make_only[0]} applies to 'jaxbox fleet make DIR' only, not to a fleet to identify"
        )
    if not args.out:
        raise UsageError("give the output folder: jaxbox fleet SOURCE --out OUT")
    if args.workers is not None and args.workers < 0:
        raise UsageError(f"--workers must be 0 or more, got {args.workers}")
    if args.scheduler is not None:
        if args.workers is not None:
            raise UsageError("--scheduler and --workers exclude each other")
        if "://" not in args.scheduler:
            raise UsageError(f"--scheduler {args.scheduler!r}: give an address tcp://HOST:PORT")
    try:
        config = load_config(
            args.config,
            models=_models(args.models),
            starts=args.starts,
            seed=args.seed,
            partition_size=args.partition_size,
            max_gap=args.max_gap,
            stuck_hours=_hours(args.stuck_hours),
        )
        summary = run_fleet(
            args.source,
            args.out,
            config,
            scheduler=args.scheduler,
            workers=args.workers,
            resume=args.resume,
            fit_json=not args.no_fits,
            progress=None if not args.json else False,
        )
    except FleetError as err:
        text = str(err)
        for attr, option in (("max_gap", "--max-gap"), ("stuck_hours", "--stuck-hours")):
            if getattr(args, attr) is not None:  # given here, not in the config file
                text = text.replace(f"data.{attr}=", f"{option} ")
                text = text.replace(f"data.{attr}", option)
        raise UsageError(text) from None
    doc = summary.to_dict()
    if args.json:
        print_json(doc)
        return 0
    counts = ", ".join(f"{v} {k}" for k, v in doc["counts"].items() if v)
    skipped = f" ({doc['skipped']} done before, skipped)" if doc["skipped"] else ""
    print(
        f"{doc['processed']} buildings{skipped}: {counts or 'none'}; "
        f"{doc['elapsed_s']:.1f} s, {doc['buildings_per_s']:.1f} buildings/s"
    )
    print(f"results: {args.out}/results.parquet", file=sys.stdout)
    return 0
