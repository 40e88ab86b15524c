"""Atomic file output: write to a temporary file in the same folder, then rename over the target.

An interrupted write never leaves a truncated file behind: the previous version stays intact
until the new one is complete and flushed. Temporary files are named
``.<name>.<host>-<pid>.<random>.tmp``: one whose process has died (a write killed outright) is
removed by :func:`remove_stale_temporaries`, which the next save into the folder calls.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import socket
import tempfile
import time
from pathlib import Path

__all__ = [
    "atomic_write_bytes",
    "atomic_write_text",
    "atomic_write_json",
    "remove_stale_temporaries",
    "temporary_prefix",
    "to_jsonable",
]

#: A temporary file or folder of ours: ``.<name>.<host>-<pid>.<random>.tmp``.
_TEMPORARY = re.compile(r"^\.(?P<name>.+)\.(?P<host>[A-Za-z0-9_-]*)-(?P<pid>\d+)\.[^.]+\.tmp$")
#: A temporary file older than this [s] is stale whoever made it (another machine's, an old
#: format without the process).
_STALE_AFTER_S = 24 * 3600.0


def _host() -> str:
    return re.sub(r"[^A-Za-z0-9_]", "_", socket.gethostname())[:40]


def temporary_prefix(name: str) -> str:
    """Prefix of a temporary file or folder standing for ``name`` (``tempfile`` adds the random
    part; give ``suffix=".tmp"``)."""
    return f".{name}.{_host()}-{os.getpid()}."


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def remove_stale_temporaries(folder: str | os.PathLike) -> list[Path]:
    """Remove the temporary files (and staging folders) in ``folder`` left by a process that
    died while writing: those of a process of this machine that no longer runs, and any older
    than a day. Those of running processes (a save going on elsewhere) are left alone.

    Returns:
        The paths removed (nothing is raised: a folder that cannot be listed or written is left
        as it is).
    """
    removed = []
    try:
        entries = list(Path(folder).iterdir())
    except OSError:
        return removed
    host, now = _host(), time.time()
    for entry in entries:
        if not (entry.name.startswith(".") and entry.name.endswith(".tmp")):
            continue
        m = _TEMPORARY.match(entry.name)
        try:
            old = now - entry.lstat().st_mtime > _STALE_AFTER_S
        except OSError:
            continue
        dead = m is not None and m["host"] == host and not _alive(int(m["pid"]))
        if not (dead or old):
            continue
        try:
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry)
            else:
                entry.unlink()
            removed.append(entry)
        except OSError:
            pass
    return removed


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file + ``os.replace``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=temporary_prefix(path.name), suffix=".tmp", dir=path.parent)
    try:
        os.chmod(tmp, 0o666 & ~_umask())  # as an ordinary open() would (mkstemp makes 0600)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


def to_jsonable(obj):
    """Convert numpy scalars/arrays, tuples and non-finite floats (→ None) for strict JSON."""
    import numpy as np

    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.bool_ | bool):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, float | np.floating):
        f = float(obj)
        return f if math.isfinite(f) else None
    return obj


def atomic_write_json(path: str | os.PathLike, obj, indent: int = 2) -> Path:
    text = json.dumps(to_jsonable(obj), indent=indent, allow_nan=False)
    return atomic_write_text(path, text + "\n")
