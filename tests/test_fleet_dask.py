"""Fleets on real Dask clusters: a LocalCluster of two worker processes, and a cluster started
as separate ``dask scheduler`` / ``dask worker`` processes, both against the in-process run."""

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from jaxbox.cli._main import main
from jaxbox.datasets import make_fleet
from jaxbox.fleet import load_config, read_results, run_fleet
from jaxbox.fleet._run import worker_env

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
CFG = {"models": "ZonWal", "starts": 4, "partition_size": 2}
COLUMNS = ["status", "model", "hlc", "hlc_lo", "hlc_hi", "solar_aperture", "rmse_cross"]


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """A persistent compilation cache for the worker processes of this module (the second
    cluster loads what the first compiled); never turned on in this process."""
    return str(tmp_path_factory.mktemp("jax-cache"))


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fleet")
    make_fleet(6, folder, days=7, seed=11)
    (folder / "broken.csv").write_text("time,T_zon\n2020-01-01,20\n", encoding="utf-8")
    return folder


@pytest.fixture(scope="module")
def inline(fleet, tmp_path_factory):
    out = tmp_path_factory.mktemp("inline")
    run_fleet(fleet, out, load_config(**CFG), workers=0, fit_json=False)
    return read_results(out).set_index("building")


def _same(rows, inline):
    assert list(rows.index) == list(inline.index)
    assert list(rows["status"]) == list(inline["status"])
    assert rows.loc["broken", "status"] == "bad_data"
    ok = inline["status"] != "bad_data"
    for col in COLUMNS[2:]:
        assert np.allclose(rows.loc[ok, col], inline.loc[ok, col], rtol=1e-9, atol=0), col
    for a, b in zip(rows.loc[ok, "params"], inline.loc[ok, "params"], strict=True):
        assert [p["name"] for p in a] == [p["name"] for p in b]
        assert np.allclose([p["value"] for p in a], [p["value"] for p in b], rtol=1e-9)


def test_local_cluster_of_two_workers_matches_the_in_process_run(
    fleet, inline, cache, tmp_path, monkeypatch
):
    monkeypatch.setenv("JAXBOX_CACHE", "1")  # inherited by the worker processes only
    monkeypatch.setenv("JAXBOX_CACHE_DIR", cache)
    summary = run_fleet(fleet, tmp_path, load_config(**CFG), workers=2, fit_json=False)
    assert summary.workers == 2 and summary.partitions == 4
    rows = read_results(tmp_path).set_index("building")
    _same(rows, inline)
    assert rows["worker"].str.startswith("tcp://").all()
    assert rows["worker"].nunique() == 2  # both worker processes took partitions


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dask(*args) -> list[str]:
    exe = Path(sys.executable).parent / "dask"
    return [str(exe), *args] if exe.exists() else [sys.executable, "-m", "dask", *args]


def test_fleet_command_on_a_separately_started_cluster(fleet, inline, cache, tmp_path, capsys):
    from distributed import Client

    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, **worker_env(), "PYTHONPATH": str(ROOT), "JAXBOX_CACHE": "1"}
    env["JAXBOX_CACHE_DIR"] = cache
    logs = open(tmp_path / "dask.log", "w")  # noqa: SIM115 - closed below
    procs = [
        subprocess.Popen(
            _dask("scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"),
            cwd=ROOT,
            env=env,
            stdout=logs,
            stderr=subprocess.STDOUT,
        )
    ]
    try:
        # the workers start beside the scheduler (each keeps trying to connect until it is up)
        for _ in range(2):
            procs.append(
                subprocess.Popen(
                    _dask(
                        "worker",
                        address,
                        "--nworkers",
                        "1",
                        "--nthreads",
                        "1",
                        "--no-dashboard",
                        "--host",
                        "127.0.0.1",
                    ),
                    cwd=ROOT,
                    env=env,
                    stdout=logs,
                    stderr=subprocess.STDOUT,
                )
            )
        deadline = time.monotonic() + 60
        while True:  # the scheduler is up once it accepts a client
            try:
                with Client(address, timeout="2s"):
                    break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.5)
        with Client(address, timeout="10s") as client:
            client.wait_for_workers(2, timeout=60)
        out = tmp_path / "out"
        code = main(
            [
                "fleet",
                str(fleet),
                "--out",
                str(out),
                "--scheduler",
                address,
                "--model",
                "ZonWal",
                "--starts",
                "4",
                "--partition-size",
                "2",
                "--no-fits",
                "--json",
            ]
        )
        assert code == 0, capsys.readouterr().err
        doc = json.loads(capsys.readouterr().out)
        assert doc["workers"] == 2 and doc["processed"] == 7
        rows = read_results(out).set_index("building")
        _same(rows, inline)
        assert rows["worker"].nunique() == 2
    finally:
        for p in procs[::-1]:
            p.terminate()
        for p in procs[::-1]:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
        logs.close()


def test_forward_selection_per_building_with_a_report(fleet, tmp_path):
    """Several models: the forward selection runs on each building (in this process), the
    accepted model's row, fit document (with the selection) and report are written."""
    cfg = load_config(models=["Zon", "ZonWal"], starts=2, partition_size=2, reports=True)
    sub = tmp_path / "two"
    sub.mkdir()
    for name in ("b0", "b1"):
        (sub / f"{name}.csv").write_bytes((fleet / f"{name}.csv").read_bytes())
    summary = run_fleet(sub, tmp_path / "out", cfg, workers=0)
    rows = read_results(tmp_path / "out").set_index("building")
    assert summary.processed == 2
    assert set(rows["model"]) <= {"Zon", "ZonWal"}
    assert (rows["status"] == "ok").any()
    assert np.all(rows["select_s"] > 0)
    doc = json.loads((tmp_path / "out" / "fits" / "b0.json").read_text())
    assert doc["selection"]["order"][0] == "Zon"
    assert (tmp_path / "out" / "reports" / "b0.html").read_text().count("<table>") >= 2
