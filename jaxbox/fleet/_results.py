"""The results of a fleet run: a Parquet dataset with one row per building, written part by
part as partitions finish (each part atomically), and the per-building fit documents.

Layout under the output folder::

    results.parquet/part-<run>-<partition>.parquet   one file per finished partition
    fits/<building>.json                             the fit document of each building
    reports/<building>.html                          (with reports) the selection report

Every part has the same schema (:data:`SCHEMA`), so ``pandas.read_parquet(out /
"results.parquet")`` reads the whole fleet. A part is first written under a name starting with
a dot (ignored by Parquet readers) and renamed when complete: a crash leaves no half part.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from .._io import atomic_write_json
from ._sources import safe_name

__all__ = ["SCHEMA", "RESULTS", "write_part", "done_buildings", "read_results", "write_docs"]

RESULTS = "results.parquet"

_PARAM = pa.struct(
    [
        ("name", pa.string()),
        ("unit", pa.string()),
        ("value", pa.float64()),
        ("std", pa.float64()),
        ("ci_lo", pa.float64()),
        ("ci_hi", pa.float64()),
        ("free", pa.bool_()),
    ]
)
_F = pa.float64()
_LIST = pa.list_(pa.float64())

#: one row per building
SCHEMA = pa.schema(
    [
        ("building", pa.string()),
        ("status", pa.string()),
        ("message", pa.string()),
        ("model", pa.string()),
        ("form", pa.string()),
        ("n_train", pa.int64()),
        ("n_valid", pa.int64()),
        ("step_s", _F),
        ("params", pa.list_(_PARAM)),
        ("cost", _F),
        ("converged", pa.bool_()),
        ("starts", pa.int64()),
        ("starts_at_best", pa.int64()),
        ("rmse_auto", _F),
        ("rmse_cross", _F),
        ("valid", pa.bool_()),
        ("reasons", pa.string()),
        ("warnings", pa.string()),
        ("hlc", _F),
        ("hlc_std", _F),
        ("hlc_lo", _F),
        ("hlc_hi", _F),
        ("solar_aperture", _F),
        ("solar_aperture_std", _F),
        ("solar_aperture_lo", _F),
        ("solar_aperture_hi", _F),
        ("tau_h", _LIST),
        ("tau_std_h", _LIST),
        ("tau_lo_h", _LIST),
        ("tau_hi_h", _LIST),
        ("kpi_interval", pa.string()),
        ("load_s", _F),
        ("fit_s", _F),
        ("select_s", _F),
        ("compile_s", _F),
        ("validate_s", _F),
        ("kpi_s", _F),
        ("report_s", _F),
        ("total_s", _F),
        ("batch", pa.int64()),
        ("partition", pa.int64()),
        ("worker", pa.string()),
    ]
)

_DEFAULTS = {
    pa.string(): None,
    pa.int64(): None,
    pa.bool_(): None,
    _F: math.nan,
}


def _column(field: pa.Field, rows: list[dict]) -> pa.Array:
    default = _DEFAULTS.get(field.type)
    if pa.types.is_list(field.type):
        values = [r.get(field.name) or [] for r in rows]
    else:
        values = [r.get(field.name, default) for r in rows]
    return pa.array(values, type=field.type)


def rows_table(rows: list[dict]) -> pa.Table:
    """The rows as a table of :data:`SCHEMA` (missing fields null/``nan``/empty)."""
    return pa.Table.from_arrays([_column(f, rows) for f in SCHEMA], schema=SCHEMA)


def write_part(out: Path, run: str, partition: int, rows: list[dict]) -> Path:
    """Write one partition's rows as ``results.parquet/part-<run>-<partition>.parquet``,
    atomically."""
    folder = Path(out) / RESULTS
    folder.mkdir(parents=True, exist_ok=True)
    final = folder / f"part-{run}-{partition:06d}.parquet"
    tmp = folder / f".{final.name}.tmp"
    pq.write_table(rows_table(rows), tmp)
    os.replace(tmp, final)
    return final


def write_docs(out: Path, docs: dict[str, dict], html: dict[str, str] | None = None) -> None:
    """Each building's fit document (``fits/<building>.json``) and report, atomically."""
    if docs:
        fits = Path(out) / "fits"
        fits.mkdir(parents=True, exist_ok=True)
        for name, doc in docs.items():
            atomic_write_json(fits / f"{safe_name(name)}.json", doc)
    if html:
        reports = Path(out) / "reports"
        reports.mkdir(parents=True, exist_ok=True)
        for name, text in html.items():
            path = reports / f"{safe_name(name)}.html"
            tmp = path.with_name(f".{path.name}.tmp")
            tmp.write_text(text, encoding="utf-8")
            os.replace(tmp, path)


def _parts(out: Path) -> list[Path]:
    folder = Path(out) / RESULTS
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.glob("part-*.parquet"))


def done_buildings(out: Path) -> set[str]:
    """Buildings with a row in the results already (for ``resume``)."""
    done: set[str] = set()
    for part in _parts(out):
        try:
            done.update(pq.read_table(part, columns=["building"]).column(0).to_pylist())
        except (pa.ArrowInvalid, OSError):  # an unreadable part: its buildings run again
            continue
    return done


def read_results(out: str | os.PathLike):
    """The results of a fleet run as a pandas DataFrame (one row per building, the latest row
    of a building that ran twice), sorted by building."""
    import pandas as pd

    parts = _parts(Path(out))
    if not parts:
        return rows_table([]).to_pandas()
    frame = pd.concat([pq.read_table(p).to_pandas() for p in parts], ignore_index=True)
    frame = frame.drop_duplicates("building", keep="last")
    return frame.sort_values("building").reset_index(drop=True)
