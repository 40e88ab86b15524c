"""Compiled programs that a later process loads without tracing them again.

JAX's persistent compilation cache (:func:`jaxbox.enable_compilation_cache`) saves XLA's
compilation in a second process, not the tracing and lowering that find the cache entry: a
batched fit of a structure search is traced from Python and lowered to StableHLO in every
process, about a second per program on a 2-core CPU, four programs in a search of the bundled
house. :func:`compile_program` exports the program once (``jax.export``: the same tracing),
keeps the serialized artifact beside the persistent cache, and compiles the program through
it; a later process reads the artifact back and lowers only a call of it, and XLA's persistent
cache finds the executable the first process compiled. The program is the same: its results
are those of the program compiled directly.

An artifact is found again only under the same program key (structure, shapes, solver
settings), the same jaxbox source, JAX version, backend and compiler options; any change makes
a new one. Without a persistent cache directory, with ``JAXBOX_EXPORTED=0``, or where a program
cannot be exported or serialized (``flatbuffers`` missing), the program is lowered and compiled
directly, as before.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Callable, Hashable
from pathlib import Path

__all__ = ["compile_program", "directory", "source_digest"]

_ENV = "JAXBOX_EXPORTED"
#: the folder inside the persistent compilation cache
_FOLDER = "jaxbox-exported"
_SOURCE: list[str] = []
#: program keys that failed to export in this process (not tried again)
_FAILED: set[str] = set()


def directory() -> Path | None:
    """Where artifacts are kept: a folder in JAX's persistent compilation cache directory
    (``None``: no persistent cache, or ``JAXBOX_EXPORTED=0``)."""
    if os.environ.get(_ENV, "1").strip().lower() in ("0", "no", "off", "false"):
        return None
    import jax

    base = jax.config.jax_compilation_cache_dir
    return Path(base) / _FOLDER if base else None


def source_digest() -> str:
    """A digest of jaxbox's Python source (every ``.py`` file of the package), once a process."""
    if not _SOURCE:
        root = Path(__file__).resolve().parent
        h = hashlib.sha256()
        for path in sorted(root.rglob("*.py")):
            h.update(str(path.relative_to(root)).encode())
            h.update(path.read_bytes())
        _SOURCE.append(h.hexdigest())
    return _SOURCE[0]


def _digest(name: str, key: Hashable, options: dict | None) -> str | None:
    """The artifact's name for ``key``; ``None`` where the key's text does not name the program
    (an object shown by its address, which differs from process to process; an array shown
    abridged, which two programs could share)."""
    import jax
    import jaxlib

    text = repr(key)
    if " at 0x" in text or "..." in text:
        return None
    h = hashlib.sha256()
    for part in (
        name,
        text,
        source_digest(),
        jax.__version__,
        jaxlib.__version__,
        jax.default_backend(),
        repr(sorted((options or {}).items())),
        str(bool(jax.config.jax_enable_x64)),
    ):
        h.update(part.encode())
        h.update(b"\0")
    return f"{name}-{h.hexdigest()[:40]}.bin"


def _write(path: Path, blob: bytes) -> None:
    """Write ``blob`` to ``path`` atomically (a temporary file in its folder, then a rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(blob)
        os.chmod(tmp, 0o644)  # as an ordinary file (a temporary one is its owner's alone)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def compile_program(name: str, key: Hashable, jitted: Callable, args: tuple):
    """``jitted.lower(*args).compile()``, through a serialized export kept for later processes.

    Args:
        name: the room of the program (``"fit"``), the start of the artifact's name.
        key: the program's key in :mod:`jaxbox._compiled` (what makes it this program).
        jitted: the function, made by :func:`jaxbox._compiled.jit` (whose XLA compiler
            options the program keeps).
        args: its arguments (arrays or ``jax.ShapeDtypeStruct``).

    Returns:
        The compiled program, called as ``jitted`` would be.
    """
    import jax

    from ._compiled import options_of

    options = options_of(jitted)
    folder = directory()
    file = None if folder is None else _digest(name, key, options)
    if file is None or file in _FAILED:
        return jitted.lower(*args).compile()
    path = folder / file
    exported = None
    try:
        exported = jax.export.deserialize(bytearray(path.read_bytes()))
    except FileNotFoundError:
        pass
    except Exception:  # noqa: BLE001 - a damaged or foreign artifact: export it again
        exported = None
    if exported is None:
        try:
            exported = jax.export.export(jitted)(*args)
            blob = bytes(exported.serialize())
        except Exception:  # noqa: BLE001 - not exportable here: compile it directly
            _FAILED.add(file)
            return jitted.lower(*args).compile()
        try:
            _write(path, blob)
        except OSError:  # a cache folder that cannot be written: this process only
            pass
    return jax.jit(exported.call, compiler_options=options).lower(*args).compile()
