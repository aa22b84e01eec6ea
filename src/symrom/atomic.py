"""Atomic file output: a reader never sees a half-written file, a failure leaves nothing behind.

Every writer in symrom goes through these helpers: files by ``atomic_path`` /
``write_text_atomic`` / ``write_with`` (temporary file beside the target, then
rename), directories by ``atomic_dir`` (temporary directory, then swap),
``check_output_file`` refuses to overwrite an existing output unless asked, and
``check_writable`` refuses, before any work, an output that could not be written.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path: str | os.PathLike, suffix: str = "") -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    Nothing is left behind on failure, and a reader never sees a half-written file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix or ".tmp", dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        # mkstemp makes the file private (0600); give it the permissions of a normal new file.
        os.chmod(tmp_path, 0o666 & ~_umask())
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def _umask() -> int:
    """The process's file-creation mask (read by setting it and putting it back)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def write_with(path: str | os.PathLike, writer: Callable[[Path], None]) -> None:
    """Call ``writer(tmp)`` and move ``tmp`` onto ``path`` atomically."""
    with atomic_path(path, suffix=Path(path).suffix) as tmp:
        writer(tmp)


class OutputExistsError(FileExistsError):
    """An output already exists and overwriting was not asked for."""


@contextmanager
def atomic_dir(path: str | os.PathLike, force: bool = False) -> Iterator[Path]:
    """Yield a fresh temporary directory that replaces ``path`` on success.

    Raises ``OutputExistsError`` up front if ``path`` exists and not ``force``.
    On failure the temporary directory is removed and ``path`` is untouched.
    """
    import shutil

    path = Path(path)
    if path.exists() and not force:
        raise OutputExistsError(f"{path} exists; pass force=True to overwrite it")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    # mkdtemp makes the folder private (0700); give it the permissions of a normal new folder.
    os.chmod(tmp, 0o777 & ~_umask())
    try:
        yield tmp
        if path.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{path.name}.old.", dir=path.parent))
            os.replace(path, old / "x")
            os.replace(tmp, path)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, path)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


class OutputIsInputError(ValueError):
    """An output would replace (or, being a folder, delete) one of the command's inputs."""


def check_output_file(path: str | os.PathLike, force: bool,
                      inputs: tuple[str | os.PathLike, ...] = ()) -> Path:
    """Refuse an existing output unless ``force``, and always an output that is one of
    ``inputs`` or a folder holding one (replacing it would destroy the input)."""
    path = Path(path)
    target = path.resolve()
    for src in inputs:
        src = Path(src)
        if not src.exists():
            continue
        if src.resolve() == target:
            raise OutputIsInputError(f"out={path} is the input {src}; choose another output "
                                     "(force=True would replace the input)")
        if path.is_dir() and src.resolve().is_relative_to(target):
            raise OutputIsInputError(f"out={path} holds the input {src}; choose another output "
                                     "(force=True would delete the input)")
    if path.exists() and not force:
        raise OutputExistsError(f"{path} exists; pass force=True to overwrite it")
    check_writable(path)
    return path


class OutputNotWritableError(PermissionError):
    """An output's location cannot be written (read-only folder, a file in the way)."""


def check_writable(path: str | os.PathLike, inside: bool = False) -> Path:
    """Refuse, before any work, an output ``path`` that could not be written.

    The writers above make their temporary file or folder beside ``path`` (in its
    parent, created if missing), so the nearest existing folder above ``path`` must
    be a folder this process may write in; with ``inside`` (a folder written into in
    place, e.g. a resumable run directory) ``path`` itself counts, if it exists.
    Raises ``OutputNotWritableError`` naming ``path`` and the folder in the way.
    """
    path = Path(path)
    start = path if inside else path.parent
    anc = start.absolute()
    while not anc.exists() and not anc.is_symlink() and anc != anc.parent:
        anc = anc.parent
    if not anc.is_dir():
        raise OutputNotWritableError(f"cannot write {path}: {anc} is not a folder")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise OutputNotWritableError(f"cannot write {path}: the folder {anc} is not writable "
                                     "(permission denied)")
    return path
