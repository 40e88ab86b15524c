"""What a user waits for, command by command: cold (an empty persistent cache) and warm (a
second process on it), an old code against the new in the same run.

Each command runs as the user runs it, a fresh process of ``python -m jaxbox ...`` with its own
persistent compilation cache (``JAXBOX_CACHE_DIR``): *cold* on an empty one, *warm* in a second
process on the one the cold run filled. With ``--baseline REV`` the *old* code is this tree as
it is at ``REV`` (``git archive``, put first on ``PYTHONPATH``), run alternately with the new
one, round by round; each figure is the minimum over ``--rounds``. The processor time of the
process (user + system) is reported beside the wall-clock time: on a shared machine it is the
steadier measure of what each code costs. The commands' JSON documents of the two codes are
compared (every number but timings): they must agree to 1e-6 relative.

    python benchmarks/commands.py [--baseline HEAD] [--rounds 2] [--only fit,ml]

Writes ``benchmarks/commands.json`` and the table into ``benchmarks/RESULTS.md`` between the
lines ``<!-- commands -->`` and ``<!-- /commands -->`` (appended when they are missing).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

#: name -> (what it is, the command line after ``jaxbox``; {out}: a fresh folder)
COMMANDS = {
    "fit": (
        "`fit` of the 14-parameter model (output error, post-simulated by diffrax)",
        ["fit", "twinhouse_exp1:N2", "-m", "ZonWalIntInfWinBouC", "--json"],
    ),
    "ml": (
        "`fit --method ml` of `ZonWal` (Kalman filter, exact Hessian)",
        ["fit", "twinhouse_exp1:N2", "-m", "ZonWal", "--method", "ml", "--json"],
    ),
    "select": (
        "the default `select` (structure search)",
        ["select", "twinhouse_exp1:N2", "--json"],
    ),
    "demo": ("`demo` (the README's first command)", ["demo", "--json", "--out", "{out}"]),
}

#: keys whose values are timings or places, not results
_SKIP = ("time", "timing", "_s", "elapsed", "path", "out", "folder", "file", "report", "version")


def _code(rev: str, work: Path) -> Path:
    """This tree's ``jaxbox`` package as it is at ``rev``, in a folder of its own."""
    dest = work / f"code-{rev.replace('/', '_')}"
    dest.mkdir(parents=True, exist_ok=True)
    blob = subprocess.run(
        ["git", "archive", rev, "jaxbox"], cwd=ROOT, check=True, capture_output=True
    ).stdout
    archive = work / "code.tar"
    archive.write_bytes(blob)
    with tarfile.open(archive) as tar:
        tar.extractall(dest, filter="data")
    return dest


def _run(argv: list[str], code: Path, cache: Path, work: Path) -> dict:
    out = work / f"out-{time.monotonic_ns()}"
    argv = [a.replace("{out}", str(out)) for a in argv]
    env = {**os.environ, "JAXBOX_CACHE_DIR": str(cache), "PYTHONPATH": str(code)}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "jaxbox", *argv],
        env=env,
        cwd=work,  # not this tree: ``python -m`` puts the working folder first on the path
        capture_output=True,
        text=True,
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode not in (0, 1):
        raise SystemExit(f"jaxbox {' '.join(argv)} failed ({proc.returncode}):\n{proc.stderr}")
    shutil.rmtree(out, ignore_errors=True)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall_s": wall, "cpu_s": cpu, "doc": json.loads(proc.stdout), "rc": proc.returncode}


def _numbers(doc, path: str = "") -> dict[str, float]:
    """Every number of a JSON document by its path, timings and places left out."""
    out: dict[str, float] = {}
    if isinstance(doc, dict):
        for k, v in doc.items():
            if any(s in str(k).lower() for s in _SKIP):
                continue
            out.update(_numbers(v, f"{path}/{k}"))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out.update(_numbers(v, f"{path}/{i}"))
    elif isinstance(doc, (int, float)) and not isinstance(doc, bool):
        out[path] = float(doc)
    return out


def _difference(a: dict, b: dict) -> tuple[float, str, int]:
    """The largest relative difference between the numbers of two documents, where, and how
    many numbers one has that the other has not."""
    na, nb = _numbers(a), _numbers(b)
    worst, where = 0.0, ""
    for k in na.keys() & nb.keys():
        x, y = na[k], nb[k]
        if math.isnan(x) and math.isnan(y) or x == y:
            continue
        d = abs(x - y) / max(abs(x), abs(y), 1e-300)
        if d > worst:
            worst, where = d, k
    return worst, where, len(na.keys() ^ nb.keys())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--baseline", default="HEAD", help="the old code's revision")
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--only", default=",".join(COMMANDS), help="commands, comma-separated")
    p.add_argument("--json", default=str(HERE / "commands.json"))
    p.add_argument("--results", default=str(HERE / "RESULTS.md"))
    args = p.parse_args()
    names = [n for n in args.only.split(",") if n]
    work = Path(tempfile.mkdtemp(prefix="jaxbox-commands-"))
    codes = {"old": _code(args.baseline, work), "new": ROOT}
    for c, path in codes.items():  # each code is the one its processes import
        env = {**os.environ, "PYTHONPATH": str(path)}
        got = subprocess.run(
            [sys.executable, "-c", "import jaxbox; print(jaxbox.__file__)"],
            env=env,
            cwd=work,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        if not Path(got).is_relative_to(path):
            raise SystemExit(f"the {c} code is not the one imported: {got}")
    load0 = os.getloadavg()[0]
    runs: dict = {n: {c: {"cold": [], "warm": []} for c in codes} for n in names}
    docs: dict = {n: {} for n in names}
    try:
        for r in range(args.rounds):
            for name in names:
                argv = COMMANDS[name][1]
                order = ("old", "new") if r % 2 == 0 else ("new", "old")
                for c in order:
                    cache = work / f"cache-{name}-{c}-{r}"
                    for phase in ("cold", "warm"):
                        got = _run(argv, codes[c], cache, work)
                        runs[name][c][phase].append({k: got[k] for k in ("wall_s", "cpu_s")})
                        docs[name].setdefault(c, got["doc"])
                        print(
                            f"round {r + 1} {name} {c} {phase}: {got['wall_s']:.1f} s "
                            f"(cpu {got['cpu_s']:.1f} s)",
                            flush=True,
                        )
                    shutil.rmtree(cache, ignore_errors=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    load1 = os.getloadavg()[0]
    rev = subprocess.run(
        ["git", "rev-parse", "--short", args.baseline], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    record = {
        "date": time.strftime("%Y-%m-%d %H:%M"),
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs",
        "load": [load0, load1],
        "baseline": rev,
        "rounds": args.rounds,
        "commands": {},
    }
    for name in names:
        diff = _difference(docs[name]["old"], docs[name]["new"])
        record["commands"][name] = {
            "argv": COMMANDS[name][1],
            "runs": runs[name],
            "largest_relative_difference": diff[0],
            "where": diff[1],
            "numbers_only_in_one": diff[2],
        }
    Path(args.json).write_text(json.dumps(record, indent=1) + "\n")
    _splice(Path(args.results), _markdown(record))


def _markdown(rec: dict) -> str:
    lines = [
        "## What a user waits for, command by command (benchmarks/commands.py)",
        "",
        f"Generated by `python benchmarks/commands.py --baseline {rec['baseline']}` on "
        f"{rec['date']} ({rec['machine']}; load average {rec['load'][0]:.1f} at the start, "
        f"{rec['load'][1]:.1f} at the end). Each command a fresh process, as a user runs it: "
        "*cold* on an empty persistent cache, *warm* a second process on it; *old* is the "
        f"package at `{rec['baseline']}`, *new* this tree, run alternately; each figure the "
        f"minimum of {rec['rounds']} rounds, wall-clock time and (in brackets) the processor "
        "time of the process.",
        "",
        "| command | cold old [s] | cold new [s] | new/old | warm old [s] | warm new [s] "
        "| new/old | results |",
        "|---|---:|---:|---:|---:|---:|---:|---|",
    ]
    for name, c in rec["commands"].items():
        cells = [COMMANDS[name][0]]
        for phase in ("cold", "warm"):
            o = {k: min(r[k] for r in c["runs"]["old"][phase]) for k in ("wall_s", "cpu_s")}
            n = {k: min(r[k] for r in c["runs"]["new"][phase]) for k in ("wall_s", "cpu_s")}
            cells += [
                f"{o['wall_s']:.1f} ({o['cpu_s']:.1f})",
                f"{n['wall_s']:.1f} ({n['cpu_s']:.1f})",
                f"{n['wall_s'] / o['wall_s']:.2f}",
            ]
        d = c["largest_relative_difference"]
        same = "the same" if d <= 1e-6 and not c["numbers_only_in_one"] else "DIFFER"
        cells.append(f"{same} (largest relative difference {d:.1e})")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _splice(path: Path, text: str) -> None:
    start, end = "<!-- commands -->", "<!-- /commands -->"
    body = path.read_text()
    block = f"{start}\n{text}{end}"
    if start in body and end in body:
        a, b = body.index(start), body.index(end) + len(end)
        body = body[:a] + block + body[b:]
    else:
        body = body.rstrip("\n") + "\n\n" + block + "\n"
    tmp = path.with_suffix(".tmp")
    tmp.write_text(body)
    tmp.replace(path)


if __name__ == "__main__":
    main()
