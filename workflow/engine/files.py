"""Atomic writes: a reader sees the previous file or the new one, never half of one.

The one place where the project decides how a file is written: to a
temporary name in the same folder, fsync, then ``os.replace``. Errors from
the operating system (permissions, disk full) become
:class:`~workflow.engine.errors.OutputError` naming the path, and the
temporary file is removed. The engine writes only its model's own file
(:meth:`~workflow.engine.model.ReducedModel.save`); the application's
writers (:mod:`workflow.io`) are built on :func:`atomic_path`.
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import Iterator

from workflow.engine.errors import OutputError


def write_error(path: str | os.PathLike, exc: OSError, what: str = "") -> OutputError:
    """One line saying what could not be written and why, naming the file in the way.

    ``what`` names the kind of target ("cache folder"). The operating
    system's own words ("File exists", "Is a directory") do not say which
    path is wrong; where a file stands in place of a folder on the way to
    ``path``, or a folder where the file goes, the message names it.
    """
    path = Path(path)
    culprit = Path(exc.filename) if isinstance(getattr(exc, "filename", None), (str, os.PathLike)) else path
    why = exc.strerror or str(exc)
    if isinstance(exc, IsADirectoryError):
        why = f"{culprit} is a folder where a file belongs; remove it"
    elif isinstance(exc, (NotADirectoryError, FileExistsError)):
        blocker = next((a for a in (culprit, *culprit.parents) if a.exists() and not a.is_dir()), None)
        if blocker is not None:
            why = f"{blocker} is a file where a folder belongs; remove it"
    elif culprit != path and not culprit.name.startswith(f".{path.name}."):   # not our own temporary
        why = f"{why} ({culprit})"
    return OutputError(f"cannot write {what + ' ' if what else ''}{path}: {why}")


def current_umask() -> int:
    """The process's umask (read by setting it and back: there is no getter)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    ``suffix`` keeps the extension on the temporary name, for writers that
    choose their format from it (numpy, matplotlib, gmsh).
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix if suffix is not None else path.suffix + ".tmp",
                                   dir=path.parent)
        os.close(fd)
    except OSError as exc:
        raise write_error(path, exc) from exc
    tmp = Path(tmp)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        # mkstemp creates 0600; give the file the permissions open() would have.
        os.chmod(tmp, 0o666 & ~current_umask())
        os.replace(tmp, path)
    except OSError as exc:
        raise write_error(path, exc) from exc
    finally:
        if tmp.exists():
            tmp.unlink()


def write_npz(path: str | os.PathLike, **arrays) -> Path:
    """``numpy.savez`` to ``path`` atomically."""
    import numpy as np

    with atomic_path(path, suffix=".npz") as tmp:
        np.savez(tmp, **arrays)
    return Path(path)
