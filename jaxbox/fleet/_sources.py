"""Where a fleet's buildings come from: a folder of files, or one long-format table.

* A **folder**: every ``*.csv``, ``*.csv.gz`` and ``*.parquet`` file in it is one building,
  named after the file (the generator's answer key ``truth.csv`` is not a building).
* A **long-format** Parquet or CSV file with a ``building`` column: the rows of each building
  form its data. A Parquet file is read building by building (row filters, so a task reads
  only its partition); a CSV file is split once, in chunks, into one file per building under
  the output folder (``inputs/``), so memory stays bounded whatever its size.

Only names and paths are held for the whole fleet; the data are read by the task that fits
them.
"""

from __future__ import annotations

import dataclasses
import os
import re
from pathlib import Path

import pandas as pd

from ..datasets._fleet import TRUTH_FILE
from ._config import FleetError

__all__ = ["Building", "discover", "read_buildings", "BUILDING_COLUMN"]

#: the column that names the building in a long-format table
BUILDING_COLUMN = "building"
_SUFFIXES = (".csv", ".csv.gz", ".parquet")
_CHUNK_ROWS = 500_000


@dataclasses.dataclass(frozen=True)
class Building:
    """One building of a fleet: its name, the file holding its data, and whether that file
    is a long-format table (rows selected by the ``building`` column)."""

    name: str
    path: str
    long: bool = False


def _stem(path: Path) -> str:
    name = path.name
    for suffix in _SUFFIXES:
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return path.stem


def safe_name(name: str) -> str:
    """A file-name-safe form of a building name."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", str(name)).strip("._") or "building"


def discover(source: str | os.PathLike, work: str | os.PathLike | None = None) -> list[Building]:
    """The buildings of ``source`` (a folder, or a long-format ``.parquet``/``.csv`` file),
    sorted by name. A long CSV file is split into ``work/inputs/<building>.csv`` first.

    Raises:
        FleetError: no such path, no building in it, a long table without a ``building``
            column, or two files for one building name.
    """
    src = Path(source)
    if src.is_dir():
        files = sorted(
            p
            for p in src.iterdir()
            if p.is_file() and p.name.endswith(_SUFFIXES) and p.name != TRUTH_FILE
        )
        if not files:
            raise FleetError(
                f"{src}: no building files (*.csv, *.csv.gz, *.parquet) in this folder"
            )
        seen: dict[str, Path] = {}
        for p in files:
            name = _stem(p)
            if name in seen:
                raise FleetError(
                    f"{src}: two files for building {name!r} ({seen[name].name}, {p.name}); "
                    "keep one"
                )
            seen[name] = p
        return [Building(n, str(p)) for n, p in seen.items()]
    if not src.exists():
        raise FleetError(f"{src}: no such file or folder")
    if src.name.endswith(".parquet"):
        return _parquet_buildings(src)
    if src.name.endswith((".csv", ".csv.gz")):
        if work is None:
            raise FleetError("a long-format CSV file needs an output folder to be split into")
        return _split_long_csv(src, Path(work) / "inputs")
    raise FleetError(f"{src}: give a folder of CSV files, or a long-format .parquet/.csv file")


def _parquet_buildings(path: Path) -> list[Building]:
    import pyarrow.parquet as pq

    schema = pq.read_schema(path)
    if BUILDING_COLUMN not in schema.names:
        raise FleetError(
            f"{path}: a long-format table needs a {BUILDING_COLUMN!r} column naming each "
            f"row's building; its columns are {', '.join(schema.names)}"
        )
    ids = pq.read_table(path, columns=[BUILDING_COLUMN]).column(0).unique().to_pylist()
    return [Building(str(b), str(path), long=True) for b in sorted(map(str, ids))]


def _split_long_csv(path: Path, folder: Path) -> list[Building]:
    """Split a long CSV into one CSV per building, chunk by chunk (bounded memory)."""
    head = pd.read_csv(path, nrows=0)
    if BUILDING_COLUMN not in head.columns:
        raise FleetError(
            f"{path}: a long-format table needs a {BUILDING_COLUMN!r} column naming each row's "
            f"building; its columns are {', '.join(map(str, head.columns))}"
        )
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob("*.csv"):
        old.unlink()
    names: dict[str, Path] = {}
    for chunk in pd.read_csv(path, chunksize=_CHUNK_ROWS, dtype={BUILDING_COLUMN: str}):
        for name, rows in chunk.groupby(BUILDING_COLUMN, sort=False):
            name = str(name)
            target = names.setdefault(name, folder / f"{safe_name(name)}.csv")
            rows.drop(columns=[BUILDING_COLUMN]).to_csv(
                target, mode="a", header=not target.exists(), index=False
            )
    return [Building(n, str(p)) for n, p in sorted(names.items())]


def read_buildings(buildings: list[Building], load_options: dict) -> dict[str, object]:
    """Each building's :class:`~jaxbox.data.Dataset`, or the error that refused it.

    Long Parquet tables are read once per file for all the buildings asked (a row filter).
    """
    from ..data import DataError, load

    out: dict[str, object] = {}
    long: dict[str, list[str]] = {}
    for b in buildings:
        if b.long:
            long.setdefault(b.path, []).append(b.name)
            continue
        try:
            path = Path(b.path)
            if b.path.endswith(".parquet"):
                out[b.name] = load(pd.read_parquet(path), **load_options)
            else:
                out[b.name] = load(path, **load_options)
        except (DataError, OSError, ValueError) as err:
            out[b.name] = err
    for path, names in long.items():
        import pyarrow.parquet as pq

        table = pq.read_table(path, filters=[(BUILDING_COLUMN, "in", names)])
        frame = table.to_pandas()
        frame[BUILDING_COLUMN] = frame[BUILDING_COLUMN].astype(str)
        groups = dict(tuple(frame.groupby(BUILDING_COLUMN, sort=False)))
        for name in names:
            rows = groups.get(name)
            try:
                if rows is None:
                    raise DataError(f"building {name!r} has no rows in {path}")
                rows = rows.drop(columns=[BUILDING_COLUMN]).reset_index(drop=True)
                out[name] = load(rows, **load_options)
            except (DataError, ValueError) as err:
                out[name] = err
    return out
