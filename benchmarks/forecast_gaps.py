"""Forecasts from histories with missing inputs: the bands' coverage and the RMSE against the
same backtest on complete data.

Each building is fitted (output error) on the first half of its data; its second half is
backtested from every hour (:func:`jaxbox.forecast.backtest`, 24 h ahead, bands calibrated per
origin) as measured, and with inputs knocked out of the *whole* record (the filter runs over
it from the start):

* *short gaps*: 5 % of the hours, one hour each, at random (bridged by interpolation);
* *long gaps*: every input missing for 6 h once every two days (the filter reopens after each).

A backtest scores no origin whose horizon holds a missing input; the record as measured is
scored on the same origins (one origin a call).

* twin houses N2 and O5 (bundled, hourly), model ``ZonWal``;
* the occupied office of ``../shared/data/darkgreybox_office`` (hourly, kW of heating), the
  structure ``Zon+Int`` built for its columns (where the data are beside the checkout).

    python benchmarks/forecast_gaps.py [--out benchmarks/FORECAST.md]

Appends (or replaces) the section between ``<!-- forecast_gaps -->`` and
``<!-- /forecast_gaps -->`` of ``--out``; raw numbers in ``benchmarks/forecast_gaps.json``.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

import jaxbox  # noqa: E402

jaxbox.enable_x64()

from jaxbox.forecast import backtest  # noqa: E402

HOURS = (1, 6, 24)
OFFICE = ROOT.parent / "shared" / "data" / "darkgreybox_office" / "demo_data.csv"
MARK = ("<!-- forecast_gaps -->", "<!-- /forecast_gaps -->")


def _cases():
    for house in ("N2", "O5"):
        yield f"twin house {house}", jaxbox.datasets.twinhouse_exp1(house), "ZonWal"
    if OFFICE.exists():
        frame = pd.read_csv(OFFICE, index_col=0, parse_dates=True)
        frame = pd.DataFrame(
            {"T_amb": frame["Ta"], "T_zon": frame["Ti"], "Q_hea": frame["Ph"] * 1000.0}
        )
        data = jaxbox.data.Dataset(frame)
        grammar = jaxbox.models.Grammar.from_columns(data.columns)
        model = jaxbox.models.parse_structure("Zon+Int").build(grammar)
        yield "office (DarkGreyBox demo)", data, model


def _knock_out(data, inputs, kind: str, seed: int = 0):
    frame = data.frame.copy()
    n = len(frame)
    hour = max(1, int(round(3600.0 / data.step)))
    rows: list[int] = []
    if kind == "short gaps":
        rng = np.random.default_rng(seed)
        starts = rng.choice(np.arange(0, n - hour, hour), size=int(0.05 * n / hour), replace=False)
        rows = sorted({int(s) + k for s in starts for k in range(hour)})
    elif kind == "long gaps":
        every, width = 48 * hour, 6 * hour
        rows = [s + k for s in range(every // 2, n - width, every) for k in range(width)]
    for name in inputs:
        frame.iloc[rows, frame.columns.get_loc(name)] = np.nan
    return jaxbox.data.Dataset(frame, check=False), np.asarray(rows, dtype=int)


def _scored(data, start, steps: int, every: int, rows: np.ndarray) -> np.ndarray:
    """The origins a backtest from ``start`` scores where ``rows`` miss an input: those whose
    rows ``o … o + steps`` hold none of them."""
    first = int(np.searchsorted(data.index, pd.Timestamp(start)))
    origins = np.arange(first, len(data) - steps, every)
    missing = np.zeros(len(data), dtype=bool)
    missing[rows] = True
    cum = np.concatenate([[0], np.cumsum(missing)])
    return origins[cum[origins + steps + 1] - cum[origins] == 0]


def _at(fit, data, origins, steps: int) -> dict:
    """The backtest of ``data`` scored on ``origins`` only (one origin a call, pooled):
    ``{hours: {cover95, cover50, rmse, n}}``."""
    err2: dict[int, list] = {h: [] for h in HOURS}
    c95: dict[int, list] = {h: [] for h in HOURS}
    c50: dict[int, list] = {h: [] for h in HOURS}
    for o in origins:
        t = backtest(fit, data, start=data.index[o], horizon=steps, every=10**9)
        t = t[t["output"] == t["output"].iloc[0]]
        for r in t.to_dict("records"):
            h = int(round(r["hours"]))
            if h in err2 and r["n"]:
                err2[h].append(r["rmse"] ** 2)
                c95[h].append(r["cover95"])
                c50[h].append(r["cover50"])
    return {
        h: {
            "cover95": float(np.mean(c95[h])),
            "cover50": float(np.mean(c50[h])),
            "rmse": float(np.sqrt(np.mean(err2[h]))),
            "n": len(err2[h]),
        }
        for h in HOURS
    }


def _one(name: str, data, model) -> dict:
    ident, _ = data.split()
    fit = jaxbox.fit_model(model, ident, starts=8)
    inputs = [c for c in fit.model.inputs if c in data.columns]
    every = max(1, int(round(3600.0 / data.step)))
    steps = int(round(24 * 3600.0 / data.step))
    out: dict = {"building": name, "model": fit.model.name, "cases": {}}
    for kind in ("short gaps", "long gaps"):
        gappy, rows = _knock_out(data, inputs, kind)
        t0 = time.perf_counter()
        table = backtest(fit, gappy, start=ident.index[-1], horizon=steps, every=every)
        seconds = time.perf_counter() - t0
        table = table[table["output"] == table["output"].iloc[0]]
        by_hours = {int(round(r["hours"])): r for r in table.to_dict("records")}
        origins = _scored(data, ident.index[-1], steps, every, rows)
        assert origins.size == table.attrs["origins"], (origins.size, table.attrs["origins"])
        case = {
            "missing_rows": int(rows.size),
            "origins": int(origins.size),
            "backtest_s": seconds,
            "gappy": {
                h: {k: float(by_hours[h][k]) for k in ("cover95", "cover50", "rmse", "n")}
                for h in HOURS
            },
            "complete": _at(fit, data, origins, steps),
        }
        out["cases"][kind] = case
        for which in ("complete", "gappy"):
            print(
                f"{name:<28} {kind:<11} {which:<8} origins {origins.size:>4} "
                + " ".join(
                    f"{h}h {case[which][h]['cover95']:.2f} {case[which][h]['rmse']:.3f}"
                    for h in HOURS
                ),
                flush=True,
            )
    return out


def _markdown(rows: list[dict], commit: str, date: str) -> str:
    head = (
        "| building | inputs knocked out | samples | origins | history | "
        + " | ".join(f"{h} h: 95 % / 50 % / RMSE [K]" for h in HOURS)
        + " |"
    )
    lines = [
        MARK[0],
        "## Missing inputs in the history (benchmarks/forecast_gaps.py)",
        "",
        f"Written by `python benchmarks/forecast_gaps.py` ({date}, jaxbox at {commit}; "
        f"{platform.machine()}, raw numbers in `benchmarks/forecast_gaps.json`). Each building "
        "fitted by output error on its first half, its second half backtested from every hour, "
        "24 h ahead, the bands calibrated per origin, with inputs knocked out of the whole "
        "record: *short*, 5 % of the hours one hour each at random (bridged by interpolation); "
        "*long*, every input missing for 6 h once every two days (the filter reopens after "
        "each). A backtest scores no origin whose horizon holds a missing input; the record "
        "*as measured* is scored on the same origins (one origin a call). Before this code one "
        "missing input anywhere in the history refused every forecast after it.",
        "",
        head,
        "|" + "---|" * (5 + len(HOURS)),
    ]
    for r in rows:
        for kind, c in r["cases"].items():
            for which, label in (("complete", "as measured"), ("gappy", "with the gaps")):
                cells = [
                    f"{c[which][h]['cover95']:.2f} / {c[which][h]['cover50']:.2f} / "
                    f"{c[which][h]['rmse']:.3f}"
                    for h in HOURS
                ]
                lines.append(
                    f"| {r['building']} ({r['model']}) | {kind.split()[0]} | "
                    f"{c['missing_rows']} | {c['origins']} | {label} | " + " | ".join(cells) + " |"
                )
    lines += ["", MARK[1]]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(HERE / "FORECAST.md"))
    args = ap.parse_args()
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT
    ).stdout.strip()
    date = time.strftime("%Y-%m-%d %H:%M")
    rows = [_one(*case) for case in _cases()]
    (HERE / "forecast_gaps.json").write_text(
        json.dumps({"date": date, "commit": commit, "rows": rows}, indent=1)
    )
    section = _markdown(rows, commit, date)
    out = Path(args.out)
    text = out.read_text() if out.exists() else ""
    if MARK[0] in text and MARK[1] in text:
        a, b = text.index(MARK[0]), text.index(MARK[1]) + len(MARK[1])
        text = text[:a] + section + text[b:]
    else:
        text = text.rstrip("\n") + "\n\n" + section + "\n"
    out.write_text(text)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
