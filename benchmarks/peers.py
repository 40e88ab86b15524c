"""Peers on their own data: the default ``select`` against a peer's published results.

DarkGreyBox's demo office (``../shared/data/darkgreybox_office``, hourly, boiler-heated, an
occupied office with a holiday shutdown) with that tool's own split: train to 2020-01-19 23:00,
test the last five days. DarkGreyBox's published table (its tutorial notebooks, as quoted in the
data set's README) selects ``TiTeThRia`` at train 0.372 K and test 0.341 K RMSE, with
``Ria`` = 0.637 K/kW (UA = 1/Ria = 1.569 kW/K: its envelope node has no path to ambient). The
default ``select`` is run on the same split (``Q_hea`` = ``Ph`` in W), and its train and test
RMSE and heat-loss coefficient with its 95 % interval are written to ``benchmarks/PEERS.md``.

Usage: ``python benchmarks/peers.py [--out benchmarks/PEERS.md]``
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

from _buildings import darkgreybox_office  # noqa: E402

#: DarkGreyBox's published results on its demo data (model, train RMSE, test RMSE [K], UA [W/K])
DARKGREYBOX = [
    ("TiTeThRia (selected, row 0)", 0.371866, 0.340593, 1.0e3 / 0.6373867020486088),
    ("TiTe (demo 03)", 0.449866, 0.484442, None),
    ("Ti (demo 01)", 0.864778, 0.973313, 1.0e3 / 0.6365759228493182),
]


def ours() -> dict:
    import jaxbox
    from jaxbox.data import DataWarning
    from jaxbox.validate import kpis, uncertainty

    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        s = jaxbox.structure_search(darkgreybox_office())
    case = s.case
    k = kpis(case.result, uncertainty(case.result))
    return {
        "accepted": case.model.name,
        "train_rmse": float(case.validation.rmse_auto["T_zon"]),
        "test_rmse": float(case.validation.rmse_cross["T_zon"]),
        "hlc": float(k.hlc.value),
        "hlc_ci95": [float(v) for v in k.hlc.ci95],
        "valid": bool(case.is_valid),
        "seconds": time.perf_counter() - t0,
    }


def markdown(doc: dict) -> str:
    r = doc["jaxbox"]
    lo, hi = r["hlc_ci95"]
    lines = [
        "## Peers on their own data",
        "",
        f"Written by `python benchmarks/peers.py` on {doc['date']}; {doc['machine']}; raw "
        "numbers in `benchmarks/peers.json`.",
        "",
        "### DarkGreyBox's demo office",
        "",
        "Hourly, 33 days, an occupied office heated by gas boilers (`Ph` [kW], `Ti`, `Ta`); "
        "DarkGreyBox's split: train 2019-12-23 … 2020-01-19 23:00 (672 h), test the last five "
        "days (120 h). DarkGreyBox's numbers are its tutorials' stored outputs (explicit Euler "
        "at 1 h, `Ti0` fixed to the first measurement), as quoted in the data set's README; "
        "jaxbox's are the default `select` (structure search, exact discretisation, initial "
        "states estimated).",
        "",
        "| tool | model | train RMSE [K] | test RMSE [K] | UA [W/K] |",
        "|---|---|---:|---:|---:|",
        f"| jaxbox `select` (default) | `{r['accepted']}` | {r['train_rmse']:.3f} | "
        f"{r['test_rmse']:.3f} | {r['hlc']:.0f} [{lo:.0f}, {hi:.0f}] |",
    ]
    for name, train, test, ua in DARKGREYBOX:
        lines.append(
            f"| DarkGreyBox | {name} | {train:.3f} | {test:.3f} | "
            f"{'–' if ua is None else f'{ua:.0f}'} |"
        )
    best = DARKGREYBOX[0]
    lines += [
        "",
        f"jaxbox's accepted model is valid: {'yes' if r['valid'] else 'no'}; train "
        f"{r['train_rmse'] / best[1]:.2f}× and test {r['test_rmse'] / best[2]:.2f}× "
        f"DarkGreyBox's best; its UA {100 * (r['hlc'] / best[3] - 1):+.1f} % from that model's "
        f"(search {r['seconds']:.0f} s).",
    ]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    import jax

    import jaxbox

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=HERE / "PEERS.md")
    p.add_argument("--json", type=Path, default=HERE / "peers.json")
    args = p.parse_args(argv)
    jaxbox.enable_x64()
    doc = {
        "date": datetime.date.today().isoformat(),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, jax {jax.__version__}",
        "jaxbox": ours(),
    }
    for path, text in ((args.json, json.dumps(doc, indent=1)), (args.out, markdown(doc))):
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(text)
        os.replace(tmp, path)
    print(markdown(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
