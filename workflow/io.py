"""The application's writers (text, CSV, JSON, npz, folders): a reader sees the previous file or the new one.

Everything the project writes (bundles, caches, CSV, figures, summary.json)
goes through these helpers, built on the engine's one primitive
(:func:`workflow.engine.files.atomic_path`: a temporary name in the same
folder, fsync, then ``os.replace``). Errors from the operating system
(permissions, disk full) become :class:`~workflow.errors.OutputError` naming
the path, and the temporary file is removed.
"""
from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator

from workflow.engine.files import atomic_path, current_umask, write_error, write_npz  # noqa: F401  (write_npz: re-exported for the application)


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically and return the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return Path(path)


def write_rows(path: str | os.PathLike, rows: list) -> Path:
    """Rows (dicts with the same keys, the first row's order) as CSV, atomically;
    floats with 9 significant digits, a cell with a comma, quote or newline quoted (RFC 4180)."""
    import csv
    import io

    keys = list(rows[0])
    cell = lambda v: f"{v:.9g}" if isinstance(v, float) else str(v)  # noqa: E731
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(keys)
    w.writerows([cell(r[k]) for k in keys] for r in rows)
    return write_text(path, buf.getvalue())


def write_json(path: str | os.PathLike, data) -> Path:
    """Write ``data`` as indented JSON atomically (NumPy scalars and arrays allowed)."""
    return write_text(path, json.dumps(data, indent=2, default=json_default) + "\n")


def json_default(obj):
    """``json.dumps``'s ``default``: NumPy arrays and scalars as lists and numbers, paths as text."""
    import numpy as np

    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


@contextlib.contextmanager
def atomic_dir(path: str | os.PathLike) -> Iterator[Path]:
    """Yield an empty temporary folder; on success it replaces ``path`` whole.

    A crash leaves the previous folder (or none) and a ``.tmp`` sibling that
    the next call removes.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
        os.chmod(tmp, 0o777 & ~current_umask())  # mkdtemp creates 0700
    except OSError as exc:
        raise write_error(path, exc) from exc
    try:
        yield tmp
        old = None
        if path.exists():
            old = path.with_name(f".{path.name}.old")
            if old.exists():
                shutil.rmtree(old)
            os.replace(path, old)
        os.replace(tmp, path)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except OSError as exc:
        raise write_error(path, exc) from exc
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


# ---------------------------------------------------------------- checksums

#: Name of a cache entry's own record (excluded from its checksums).
_SKIP = (".stage.json",)


def file_digest(path: str | os.PathLike) -> str:
    """SHA-256 of a file's bytes (hex), read in 1 MiB chunks."""
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def manifest(folder: str | os.PathLike) -> dict[str, list]:
    """``{relative path: [size in bytes, sha256]}`` of every file under ``folder``.

    Recorded when a cache entry is written, checked by :func:`verify_manifest`
    before the entry is used: a file truncated, edited, replaced or deleted
    afterwards is caught (size first, so most damage costs no hashing).
    """
    folder = Path(folder)
    out = {}
    for f in sorted(p for p in folder.rglob("*") if p.is_file() and not p.is_symlink()):
        rel = f.relative_to(folder).as_posix()
        if rel in _SKIP:
            continue
        out[rel] = [f.stat().st_size, file_digest(f)]
    return out


#: the key of a cache entry's record that holds the digest of the record itself
RECORD_DIGEST = "record_sha256"


def _record_digest(record: dict) -> str:
    """SHA-256 of ``record``'s canonical JSON (sorted keys, compact), without :data:`RECORD_DIGEST`."""
    import hashlib

    plain = {k: v for k, v in record.items() if k != RECORD_DIGEST}
    text = json.dumps(plain, sort_keys=True, separators=(",", ":"), default=json_default)
    return hashlib.sha256(text.encode()).hexdigest()


def seal_record(record: dict) -> dict:
    """``record`` (JSON-able) as it will read back, with its own digest under
    :data:`RECORD_DIGEST`: the record holds the stage's summary, so an edit or damage that
    leaves it valid JSON is caught like a damaged file (:func:`record_problem`)."""
    plain = json.loads(json.dumps(record, default=json_default))
    plain[RECORD_DIGEST] = _record_digest(plain)
    return plain


def record_problem(record: dict) -> str | None:
    """None if ``record`` (read back from JSON) is as :func:`seal_record` sealed it, else why not."""
    digest = record.get(RECORD_DIGEST)
    if digest is None:
        return "its record .stage.json has no digest of its own (written by an older version)"
    if _record_digest(record) != digest:
        return "its record .stage.json changed since it was written (digest differs)"
    return None


def verify_manifest(folder: str | os.PathLike, recorded: dict) -> str | None:
    """None if every file of ``recorded`` (:func:`manifest`) is in ``folder`` unchanged,
    else a short description of the first difference."""
    folder = Path(folder)
    if not isinstance(recorded, dict):
        return "no file checksums recorded"
    for rel, entry in sorted(recorded.items()):
        f = folder / rel
        try:
            size, digest = int(entry[0]), str(entry[1])
            st = f.stat()
        except (OSError, TypeError, ValueError, IndexError):
            return f"{rel} is missing"
        if not f.is_file():
            return f"{rel} is missing"
        if st.st_size != size:
            return f"{rel} has {st.st_size} bytes, {size} were written"
        try:
            if file_digest(f) != digest:
                return f"{rel} changed since it was written (checksum differs)"
        except OSError as exc:
            return f"{rel} cannot be read ({exc.strerror or exc})"
    return None
