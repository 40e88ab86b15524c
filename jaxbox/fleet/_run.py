"""Run a fleet on Dask: partitions of buildings as tasks, results written as they finish.

By default a :class:`dask.distributed.LocalCluster` starts with one single-threaded worker
process per core; ``scheduler="tcp://HOST:PORT"`` uses a running cluster (``dask scheduler``
and ``dask worker`` processes, which must see the input files); ``workers=0`` runs every
partition in this process (no Dask). At most two partitions per worker are in flight, and each
finished partition's rows are written at once, so memory stays bounded and a crash loses only
the partitions in flight; ``resume`` skips the buildings that already have a row.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time
import uuid
from collections import Counter
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path

from .._io import atomic_write_json
from ._config import FleetConfig, FleetError, load_config
from ._results import RESULTS, done_buildings, write_docs, write_part
from ._sources import Building, discover
from ._work import STATUSES, process_partition

__all__ = ["run_fleet", "FleetRun"]

#: the settings of a local worker: one thread each (the parallelism is across workers)
_SINGLE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
_SINGLE_THREAD_XLA = "--xla_cpu_multi_thread_eigen=false"


def worker_env(environ=None) -> dict[str, str]:
    """The variables a local worker process starts with: one thread each, and the XLA flags of
    ``environ`` (default ``os.environ``) kept, so that the workers compile what this process
    would."""
    environ = os.environ if environ is None else environ
    flags = [f for f in (environ.get("XLA_FLAGS", "").strip(), _SINGLE_THREAD_XLA) if f]
    return {"XLA_FLAGS": " ".join(flags), **_SINGLE_THREAD}


@dataclasses.dataclass(frozen=True)
class FleetRun:
    """Summary of a fleet run.

    Attributes:
        out: the output folder.
        buildings: buildings in the source.
        skipped: buildings skipped because they had a row already (``resume``).
        counts: rows written in this run per status.
        partitions: partitions run.
        workers: Dask workers (0: in this process).
        elapsed_s: wall-clock time of the run [s].
    """

    out: Path
    buildings: int
    skipped: int
    counts: dict
    partitions: int
    workers: int
    elapsed_s: float

    @property
    def processed(self) -> int:
        return sum(self.counts.values())

    @property
    def buildings_per_s(self) -> float:
        return self.processed / self.elapsed_s if self.elapsed_s > 0 else float("nan")

    def to_dict(self) -> dict:
        return {
            "out": str(self.out),
            "buildings": self.buildings,
            "skipped": self.skipped,
            "processed": self.processed,
            "counts": dict(self.counts),
            "partitions": self.partitions,
            "workers": self.workers,
            "elapsed_s": self.elapsed_s,
            "buildings_per_s": self.buildings_per_s,
        }


def _partitions(buildings: list[Building], size: int) -> list[list[Building]]:
    return [buildings[i : i + size] for i in range(0, len(buildings), size)]


def _failed_rows(part: list[Building], index: int, err: BaseException) -> list[dict]:
    text = f"task failed: {type(err).__name__}: {err}"
    return [
        {"building": b.name, "status": "failed", "message": text, "partition": index} for b in part
    ]


def _local_cluster(workers: int, stack: ExitStack):
    """A LocalCluster of ``workers`` single-threaded processes, closed with ``stack``."""
    from distributed import Client, LocalCluster

    env = worker_env()
    saved = {k: os.environ.get(k) for k in env}
    os.environ.update(env)  # inherited by the worker processes
    try:
        cluster = stack.enter_context(
            LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",
                silence_logs=50,  # a worker's heartbeat at shutdown is no news
            )
        )
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return stack.enter_context(Client(cluster))


def _progress_bar(total: int, show: bool | None):
    from tqdm.auto import tqdm

    if show is None:
        show = sys.stderr.isatty()
    return tqdm(total=total, unit="bldg", disable=not show, file=sys.stderr, smoothing=0.1)


def run_fleet(
    source: str | os.PathLike,
    out: str | os.PathLike,
    config: FleetConfig | str | os.PathLike | None = None,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    resume: bool = False,
    fit_json: bool = True,
    progress: bool | None = None,
    on_partition: Callable[[int, list[dict]], None] | None = None,
) -> FleetRun:
    """Identify, validate and compute the KPIs of every building of a fleet.

    Args:
        source: a folder with one CSV/Parquet file per building, or a long-format
            ``.parquet``/``.csv`` file with a ``building`` column.
        out: output folder (``results.parquet``, ``fits/``, ``fleet.json``).
        config: a :class:`FleetConfig`, the path of a TOML file, or ``None`` (the defaults).
        scheduler: address of a running Dask scheduler (``tcp://HOST:PORT``); ``None`` starts
            a LocalCluster.
        workers: worker processes of the LocalCluster (default: one per core); 0 runs every
            partition in this process, without Dask.
        resume: skip buildings that already have a row in ``out``; without it, an ``out``
            holding results is refused.
        fit_json: write each building's fit document.
        progress: show a progress bar (default: when stderr is a terminal).
        on_partition: called with each partition's index and rows once they are written.

    Returns:
        :class:`FleetRun`. The rows: :func:`jaxbox.fleet.read_results`.

    Raises:
        FleetError: a bad source, configuration or output folder.
    """
    t0 = time.perf_counter()
    cfg = config if isinstance(config, FleetConfig) else load_config(config)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise FleetError(f"--out {out} is a file; give a folder")
    if workers is not None and workers < 0:
        raise FleetError(f"workers must be 0 (in this process) or more, got {workers}")
    if scheduler is not None and workers is not None:
        raise FleetError("give a scheduler address or a number of local workers, not both")
    done = done_buildings(out)
    if done and not resume:
        raise FleetError(
            f"{out} holds the results of a fleet run already ({len(done)} buildings); "
            "resume it, or give a new output folder"
        )
    out.mkdir(parents=True, exist_ok=True)
    buildings = discover(source, out)
    todo = [b for b in buildings if b.name not in done]
    parts = _partitions(todo, cfg.partition_size)
    run = time.strftime("%Y%m%dT%H%M%S") + f"-{uuid.uuid4().hex[:8]}"  # unique per run
    meta = {
        "source": str(source),
        "config": cfg.to_dict(),
        "scheduler": scheduler,
        "run": run,
        "results": str(out / RESULTS),
    }
    atomic_write_json(out / "fleet.json", {**meta, "status": "running"})
    counts: Counter = Counter()
    config_dict = cfg.to_dict()

    def finish(index: int, outcome: dict) -> None:
        rows = outcome["rows"]
        write_part(out, run, index, rows)
        write_docs(out, outcome.get("docs", {}), outcome.get("html"))
        counts.update(r["status"] for r in rows)
        bar.update(len(rows))
        if on_partition is not None:
            on_partition(index, rows)

    n_workers = 0
    with ExitStack() as stack:
        bar = stack.enter_context(_progress_bar(len(todo), progress))
        if workers == 0:
            for i, part in enumerate(parts):
                try:
                    outcome = process_partition(i, part, config_dict, fit_json)
                except Exception as err:  # noqa: BLE001 - the partition becomes failed rows
                    outcome = {"rows": _failed_rows(part, i, err)}
                finish(i, outcome)
        elif parts:
            from distributed import Client, as_completed

            if scheduler is not None:
                client = stack.enter_context(Client(scheduler, timeout="30s"))
            else:
                client = _local_cluster(workers or os.cpu_count() or 1, stack)
            n_workers = max(1, len(client.scheduler_info(n_workers=-1)["workers"]))
            limit = 2 * n_workers
            pending = list(enumerate(parts))[::-1]
            futures = {}

            def submit():
                i, part = pending.pop()
                fut = client.submit(
                    process_partition,
                    i,
                    part,
                    config_dict,
                    fit_json,
                    key=f"jaxbox-fleet-{run}-{i}",
                    pure=False,
                    retries=0,
                )
                futures[fut] = (i, part)
                return fut

            queue = as_completed([submit() for _ in range(min(limit, len(pending)))])
            for fut in queue:
                i, part = futures.pop(fut)
                try:
                    outcome = fut.result()
                except Exception as err:  # noqa: BLE001 - a worker died, a task raised
                    outcome = {"rows": _failed_rows(part, i, err)}
                fut.release()
                finish(i, outcome)
                if pending:
                    queue.add(submit())
    elapsed = time.perf_counter() - t0
    summary = FleetRun(
        out=out,
        buildings=len(buildings),
        skipped=len(buildings) - len(todo),
        counts={s: counts.get(s, 0) for s in STATUSES},
        partitions=len(parts),
        workers=n_workers,
        elapsed_s=elapsed,
    )
    atomic_write_json(out / "fleet.json", {**meta, "status": "done", **summary.to_dict()})
    return summary
