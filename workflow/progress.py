"""Finished pieces of a long stage, kept across interrupted runs (a Monte Carlo's patterns, a
contact-convergence study's meshes).

A cached stage is written whole or not at all (:func:`workflow.io.atomic_dir`): a run stopped
three hours into a 100-pattern Monte Carlo would otherwise lose every pattern. While the
pipeline computes a stage it offers a progress folder beside the stage's cache entry, named by
the entry's key — a hash of the stage's scene sections, its inputs and the code, so a piece
found there belongs to the same computation. A stage keeps each finished piece there, one JSON
file each, written atomically, and reads it back on the next run instead of computing it. The
folder is removed once the entry is committed. A piece whose file is damaged — unreadable, not
JSON, another key or name, its checksum wrong — is counted in :attr:`Progress.damaged` and
computed again, never used.

Under MPI every rank sees the same folder (the cache is shared) and writes its own pieces.
"""
from __future__ import annotations

import contextlib
import contextvars
import hashlib
import json
import re
from pathlib import Path
from typing import Iterator

from workflow.io import json_default, write_text

_current: contextvars.ContextVar["Progress | None"] = contextvars.ContextVar("bladewear_progress", default=None)
_NAME = re.compile(r"^[A-Za-z0-9_.-]+$")


def _digest(data) -> str:
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()


class Progress:
    """The progress folder of one stage computation (module doc); ``key`` its cache key."""

    def __init__(self, folder: str | Path, key: str):
        self.folder, self.key = Path(folder), str(key)
        #: names of the pieces found damaged (and so computed again)
        self.damaged: list[str] = []
        #: how many pieces :meth:`get` found intact
        self.found = 0

    def _path(self, name: str) -> Path:
        if not _NAME.match(name):
            raise ValueError(f"progress piece name {name!r}: letters, digits, '_', '.', '-' only")
        return self.folder / f"{name}.json"

    def get(self, name: str):
        """The data a previous run kept under ``name`` (JSON types), or None (none, or damaged)."""
        path = self._path(name)
        try:
            rec = json.loads(path.read_text())
        except FileNotFoundError:
            return None
        except (OSError, ValueError):
            self.damaged.append(name)
            return None
        ok = (isinstance(rec, dict) and rec.get("key") == self.key and rec.get("name") == name
              and "data" in rec and rec.get("sha256") == _digest(rec["data"]))
        if not ok:
            self.damaged.append(name)
            return None
        self.found += 1
        return rec["data"]

    def put(self, name: str, data) -> Path:
        """Keep ``data`` (JSON types — numbers, strings, None, lists, dicts — NumPy scalars and arrays
        as lists) under ``name``, atomically."""
        data = json.loads(json.dumps(data, default=json_default))   # the stored form: get() sees its checksum
        rec = {"key": self.key, "name": name, "sha256": _digest(data), "data": data}
        return write_text(self._path(name), json.dumps(rec, indent=1) + "\n")


@contextlib.contextmanager
def stage_progress(folder: str | Path, key: str) -> Iterator[Progress]:
    """Offer ``folder`` to the stage computed inside (the pipeline's use): :func:`current` returns it."""
    token = _current.set(Progress(folder, key))
    try:
        yield _current.get()
    finally:
        _current.reset(token)


def kept(folder: str | Path) -> int:
    """How many pieces an interrupted run left in ``folder`` (``bladewear show``; unchecked: a damaged
    one is found so only when read)."""
    try:
        return sum(1 for f in Path(folder).iterdir() if f.suffix == ".json" and not f.name.startswith("."))
    except OSError:
        return 0


def current() -> Progress | None:
    """The progress folder of the stage being computed, or None (outside a pipeline run)."""
    return _current.get()
