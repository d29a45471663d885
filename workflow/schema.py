"""Scene schema: every key, its type, unit, default and admissible values.

A scene section is a dataclass whose fields are made with :func:`param`; the
registry :data:`SECTIONS` maps a TOML table name to its dataclass. This module
resolves a raw TOML dict into typed section objects, filling defaults and
rejecting, with one message naming ``section.key``, anything unknown,
mistyped or out of range.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

from workflow.errors import SceneError


def param(default, unit: str = "", doc: str = "", *, min=None, max=None, min_exclusive: bool = False,
          choices=None, item_choices=None, finite: bool = True, min_items: int = 1):
    """A scene key: default value, unit, one-line doc and its admissible range.

    ``min``/``max`` bound numbers (``min_exclusive`` for a strict lower bound);
    ``choices`` restricts a value, ``item_choices`` each item of a list. A
    list key must be given as a TOML list of at least ``min_items`` items,
    each of the type of the default's items (int lists take integers only).
    """
    meta = dict(unit=unit, doc=doc, min=min, max=max, min_exclusive=min_exclusive, choices=choices,
                item_choices=item_choices, finite=finite, min_items=min_items)
    if isinstance(default, list):
        return dataclasses.field(default_factory=lambda d=default: list(d), metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def shown(value, wants_text: bool = False) -> str:
    """A value as a user wrote it in TOML, for an error message.

    An unquoted date or time (``2026-01-01``, ``12:30:00``) is a TOML date,
    not text or a number: said so, as written, and where the key
    ``wants_text``, with the quotes that make it a string.
    """
    import datetime

    if isinstance(value, (datetime.date, datetime.time)):
        quote = f' (quote it: "{value.isoformat()}")' if wants_text else ""
        return f"the TOML date/time {value.isoformat()}{quote}"
    return repr(value)


def _type_name(v) -> str:
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string", list: "a list"}.get(type(v), type(v).__name__)


def coerce(section: str, key: str, f: dataclasses.Field, value: Any) -> Any:
    """Check one value against its field; return it with the field's type."""
    name = f"{section}.{key}"
    default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
    meta = f.metadata
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise SceneError(f"{name} must be true or false, got {shown(value)}")
    elif isinstance(default, float):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SceneError(f"{name} must be a number, got {shown(value)}")
        value = float(value)
    elif isinstance(default, int):
        if isinstance(value, bool) or not (isinstance(value, int) or (isinstance(value, float) and value.is_integer())):
            raise SceneError(f"{name} must be an integer, got {shown(value)}")
        value = int(value)
    elif isinstance(default, str):
        if not isinstance(value, str):
            raise SceneError(f"{name} must be a string, got {shown(value, wants_text=True)}")
    elif isinstance(default, list):
        if not isinstance(value, list):
            raise SceneError(f"{name} must be a list, e.g. {name}=[{_example(default, value)}]; got {shown(value)}")
        if len(value) < meta.get("min_items", 1):
            raise SceneError(f"{name} must list at least {meta.get('min_items', 1)} value(s), got []")
        items = meta.get("item_choices")
        for item in value:
            _check_item(name, default, item)
            if isinstance(item, float) and not math.isfinite(item):
                raise SceneError(f"{name} contains {shown(item)}; values must be finite")
            if items is not None and item not in items:
                raise SceneError(f"{name} contains {shown(item)}; allowed: {', '.join(map(str, items))}")
        _check_range(name, meta, value)
        return list(value)
    if isinstance(value, float) and meta.get("finite", True) and not math.isfinite(value):
        raise SceneError(f"{name} must be finite, got {shown(value)}")
    if meta.get("choices") is not None and value not in meta["choices"]:
        raise SceneError(f"{name} = {shown(value)} is not one of: {', '.join(map(str, meta['choices']))}")
    _check_range(name, meta, [value])
    return value


def _example(default, value) -> str:
    """The items of a list example for a value that is not a list."""
    if isinstance(value, str) and value.startswith("[") and value.endswith("]"):
        # [hbm, tcm] is no TOML (bare words) and came as one string: its items quoted
        return ", ".join(f'"{v.strip()}"' for v in value[1:-1].split(",") if v.strip())
    return repr(value) if isinstance(value, (int, float, str)) and not isinstance(value, bool) else repr(default[0])


def _check_item(name: str, default: list, item) -> None:
    """Each item of a list key has the type of the default's items (numbers: int or float)."""
    if not default:
        return
    kind = type(default[0])
    if kind is bool:
        ok = isinstance(item, bool)
    elif kind is int:
        ok = isinstance(item, int) and not isinstance(item, bool)
    elif kind is float:
        ok = isinstance(item, (int, float)) and not isinstance(item, bool)
    else:
        ok = isinstance(item, kind)
    if not ok:
        what = {int: "integers", float: "numbers", str: "strings", bool: "true/false"}.get(kind, kind.__name__)
        raise SceneError(f"{name} contains {shown(item)}; its items must be {what}")


def _check_range(name, meta, values):
    lo, hi = meta.get("min"), meta.get("max")
    for v in values:
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            continue
        if isinstance(v, float) and math.isnan(v):
            raise SceneError(f"{name} must be a number, got nan")
        if lo is not None and (v < lo or (meta.get("min_exclusive") and v <= lo)):
            op = ">" if meta.get("min_exclusive") else "≥"
            raise SceneError(f"{name} = {v!r} must be {op} {lo}")
        if hi is not None and v > hi:
            raise SceneError(f"{name} = {v!r} must be ≤ {hi}")


def resolve_section(section: str, cls, raw: dict | None):
    """Instantiate section ``cls`` from a raw table; unknown keys are errors."""
    raw = dict(raw or {})
    if not isinstance(raw, dict):
        raise SceneError(f"[{section}] must be a table")
    known = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(raw) - set(known))
    if unknown:
        hint = _closest(unknown[0], known)
        raise SceneError(f"unknown key {section}.{unknown[0]}" + (f" (did you mean {section}.{hint}?)" if hint else ""))
    values = {k: coerce(section, k, known[k], v) for k, v in raw.items()}
    obj = cls(**values)
    check = getattr(obj, "check", None)
    if check is not None:
        check()  # cross-key rules, raising SceneError naming the keys
    return obj


def _closest(key: str, known) -> str | None:
    import difflib

    hits = difflib.get_close_matches(key, list(known), n=1, cutoff=0.6)
    return hits[0] if hits else None


def describe(cls) -> list[dict]:
    """Rows (key, default, unit, doc) of a section, for docs and ``bladewear show``."""
    rows = []
    for f in dataclasses.fields(cls):
        default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        rows.append(dict(key=f.name, default=default, unit=f.metadata.get("unit", ""), doc=f.metadata.get("doc", "")))
    return rows
