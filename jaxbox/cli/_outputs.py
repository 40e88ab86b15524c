"""Output folders of the command line: probed for writing before any computing
(:func:`check_folder`), written all at once at the end (:class:`Outputs`)."""

from __future__ import annotations

import os
import secrets
import shutil
import tempfile
from collections.abc import Callable
from datetime import datetime
from pathlib import Path

from .._io import remove_stale_temporaries, temporary_prefix
from ._common import (
    UsageError,
    check_interrupted,
    deferred_interrupt,
    forget_interrupt,
    on_interrupt,
)

__all__ = ["Outputs", "check_folder", "fresh_folder", "reason"]


def check_folder(text: str | None, option: str) -> Path | None:
    """The output folder of ``option``, probed for writing before any computing: a file, a
    folder under a file, a place that cannot be written are refused (a probe file is created in
    it, and removed, together with any folder made for it)."""
    if text is None:
        return None
    if not text.strip():
        raise UsageError(f"{option} is empty; give a folder")
    path = Path(text)
    try:
        if path.exists() and not path.is_dir():
            raise UsageError("it is a file, not a folder; give a folder")
        made = _make_folder(path)
    except UsageError as err:
        raise UsageError(f"{option} {text!r}: {err}") from None
    except (OSError, ValueError) as err:
        raise UsageError(f"{option} {text!r}: cannot make this folder ({reason(err)})") from None
    try:
        fd, probe = tempfile.mkstemp(prefix=".jaxbox-probe-", dir=path)
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        raise UsageError(f"{option} {text!r}: cannot write into it ({reason(err)})") from None
    finally:
        _remove_folders(made)
    return path


def reason(err: BaseException) -> str:
    return getattr(err, "strerror", None) or str(err)


def _make_folder(path: Path) -> list[Path]:
    """``mkdir -p`` that returns the folders it made (deepest last)."""
    missing = []
    p = path
    while not p.exists():
        missing.append(p)
        if p.parent == p:
            break
        p = p.parent
    if p.exists() and not p.is_dir():
        raise UsageError(f"{p} is a file, so no folder can be made under it")
    made = []
    for folder in reversed(missing):
        folder.mkdir()
        made.append(folder)
    return made


def _remove_folders(made: list[Path]) -> None:
    for folder in reversed(made):
        try:
            folder.rmdir()
        except OSError:
            pass


class Outputs:
    """The files one command writes, all or nothing.

    :meth:`folder` gives a hidden staging folder inside a target folder (made if needed); once
    everything is computed, :meth:`commit` moves each staged file into place (``os.replace``:
    atomic per file, Ctrl-C held back meanwhile) and runs the ``after`` actions (saving
    GreyBoxes, themselves atomic). Leaving the ``with`` block by an error or Ctrl-C removes the
    staging folders and the target folders this run made. Staging folders of a run killed
    outright are removed by the next run writing there.
    """

    def __init__(self) -> None:
        self._staged: list[tuple[Path, Path]] = []
        self._made: list[Path] = []
        self._after: list[Callable[[], object]] = []
        self.committed = False

    def __enter__(self) -> Outputs:
        on_interrupt(self.discard)
        return self

    def __exit__(self, kind, err, tb) -> None:
        forget_interrupt(self.discard)
        if not self.committed:
            self.discard()

    def folder(self, target: Path) -> Path:
        """A staging folder whose files :meth:`commit` moves into ``target``."""
        target = Path(target)
        self._made += _make_folder(target)
        remove_stale_temporaries(target)
        # named and recorded before it is made: a Ctrl-C between the two finds it in the list
        # (a folder made by mkdtemp and lost before it was recorded stayed behind); the
        # ".tmp" suffix lets the next run writing here remove it if this process is killed
        while True:
            staging = target / f"{temporary_prefix('jaxbox-out')}{secrets.token_hex(6)}.tmp"
            self._staged.append((staging, target))
            try:
                staging.mkdir()
            except FileExistsError:  # this process's own (the name holds its pid): draw again
                self._staged.pop()
                continue
            return staging

    def after(self, action: Callable[[], object]) -> None:
        """Run ``action`` at commit, after the staged files are in place."""
        self._after.append(action)

    def commit(self) -> None:
        check_interrupted()
        with deferred_interrupt():
            for staging, target in self._staged:
                _move_tree(staging, target)
                shutil.rmtree(staging, ignore_errors=True)
            for action in self._after:
                action()
            self.committed = True

    def discard(self) -> None:
        for staging, _ in self._staged:
            shutil.rmtree(staging, ignore_errors=True)
        for folder in sorted(self._made, key=lambda p: len(p.parts), reverse=True):
            try:
                folder.rmdir()  # only if empty: what was there before stays
            except OSError:
                pass


def _move_tree(source: Path, target: Path) -> None:
    target.mkdir(parents=True, exist_ok=True)
    for item in sorted(source.iterdir()):
        if item.is_dir():
            _move_tree(item, target / item.name)
        else:
            os.replace(item, target / item.name)


def fresh_folder() -> Path:
    """A new ``jaxbox-out-<date>-<time>`` folder name in the current directory."""
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    path = Path(f"jaxbox-out-{stamp}")
    n = 1
    while path.exists():
        n += 1
        path = Path(f"jaxbox-out-{stamp}-{n}")
    return path
