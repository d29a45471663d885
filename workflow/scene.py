"""Scenes: a TOML file, resolved into typed sections with every default filled.

A scene is one TOML table per section (``[contact]``, ``[hb]``, …); the
sections are the dataclasses of :mod:`workflow.params` plus ``[geometry]``,
which is :class:`geometry.params.SectorParams` (imported lazily: reading a
scene must not import gmsh). :func:`load_scene` returns a :class:`Scene`, a
dict section → dataclass instance with the file's path and a canonical JSON
form used for cache keys.

Command-line overrides (``--set section.key=value``) are parsed as TOML
values, so ``hb.harmonics=[1,3]`` is a list and ``contact.mu=0.3`` a number;
a value that is not valid TOML is taken as a bare string
(``hb.solver=powell``).

Paths (keys whose unit is ``"path"``, e.g. ``[model] bundle``) are resolved
against the scene's folder when they come from the file and against the
current directory when they come from ``--set``, which is what a user typing
either expects.

``python -m workflow.scene --doc`` prints the Markdown reference of every key
(``docs/scenes.md``).
"""
from __future__ import annotations

import dataclasses
import json
import math
import re
import sys
import tomllib
from pathlib import Path
from typing import Any, Iterable

from workflow.errors import SceneError
from workflow.schema import resolve_section

#: Folder of the scenes shipped with bladewear (``bladewear scenes``).
SHIPPED = Path(__file__).resolve().parent / "scenes"


# ---------------------------------------------------------------- sections

def geometry_section():
    """The geometry section's dataclass, imported on first use.

    The geometry engineer keeps it in ``geometry.params`` (light) and may
    re-export it from ``geometry.sector`` (which imports gmsh); try the light
    one first.
    """
    for mod in ("geometry.params", "geometry.sector"):
        try:
            module = __import__(mod, fromlist=["SectorParams"])
        except ModuleNotFoundError as exc:
            if exc.name not in (mod, "geometry"):
                raise
            continue
        cls = getattr(module, "SectorParams", None)
        if cls is not None:
            return cls
    raise SceneError("the [geometry] section needs geometry.params.SectorParams, which is not installed")


def sections() -> dict[str, type]:
    """All scene sections: table name → dataclass, ``geometry`` first."""
    from workflow.params import SECTIONS

    return {"geometry": geometry_section(), **SECTIONS}


# ---------------------------------------------------------------- the scene

class Scene(dict):
    """Resolved scene: ``scene["contact"].mu``; also ``.path``, ``.title``.

    A plain dict of section → dataclass instance (what stages receive), with
    the file it came from and helpers for hashing and display.
    """

    def __init__(self, sections: dict, path: Path | None = None, overrides: Iterable[str] = ()):
        super().__init__(sections)
        self.path = path
        self.overrides = list(overrides)
        self.unused: set[str] = set()  # sections a model bundle replaces (set by workflow.pipeline.plan)

    @property
    def title(self) -> str:
        run = self.get("run")
        t = getattr(run, "title", "") if run is not None else ""
        return t or (self.path.stem if self.path else "scene")

    def as_dict(self, names: Iterable[str] | None = None) -> dict:
        """Plain nested dict of the given sections (all by default)."""
        names = sorted(self) if names is None else names
        return {name: section_values(self[name]) for name in names}

    def canonical(self, names: Iterable[str] | None = None) -> str:
        """Canonical JSON of the given sections: sorted keys, no whitespace.

        Two scenes that resolve to the same values give the same string,
        whatever the order, spelling (``1`` vs ``1.0`` for a float key) or
        defaults left out in the files.
        """
        return json.dumps(self.as_dict(names), sort_keys=True, separators=(",", ":"), allow_nan=False)


def section_values(obj) -> dict:
    """Field name → value of one section instance (no derived properties)."""
    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}


# ---------------------------------------------------------------- loading

def find_scene(name: str | Path) -> Path:
    """A scene file: an existing path, or the name of a shipped scene (``quick``)."""
    if not str(name).strip():
        names = ", ".join(s for s, _ in shipped_scenes()) or "none"
        raise SceneError(f"no scene given: name a scene file or a shipped scene ({names})")
    p = Path(name)
    if p.is_file():
        return p.resolve()
    for cand in (SHIPPED / f"{name}.toml", SHIPPED / str(name)):
        if cand.is_file():
            return cand
    if p.exists():
        raise SceneError(f"scene {p} is not a file")
    names = ", ".join(s for s, _ in shipped_scenes()) or "none"
    raise SceneError(f"scene {name} not found (no such file, and no shipped scene of that name; shipped: {names})")


def shipped_scenes() -> list[tuple[str, str]]:
    """(name, title) of each shipped scene, sorted by name."""
    out = []
    for f in sorted(SHIPPED.glob("*.toml")):
        try:
            title = read_toml(f).get("run", {}).get("title", "")
        except SceneError:
            title = "(malformed)"
        out.append((f.stem, title))
    return out


def read_toml(path: Path) -> dict:
    """Parse a TOML file; a syntax error becomes a :class:`SceneError` with file and line."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise SceneError(f"cannot read scene {path}: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise SceneError(f"scene {path} is not UTF-8 text") from exc
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        # tomllib's message ends with "(at line L, column C)"; put it first, as compilers do.
        msg = str(exc)
        m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
        where = f"{path}:{m.group(1)}:{m.group(2)}" if m else str(path)
        msg = re.sub(r"\s*\(at (line \d+, column \d+|end of document)\)", "", msg)
        raise SceneError(f"{where}: malformed TOML: {msg}") from exc


def parse_override(text: str) -> tuple[str, str, Any]:
    """``"section.key=value"`` → (section, key, value), the value parsed as TOML."""
    name, sep, raw = text.partition("=")
    name = name.strip()
    parts = name.split(".")
    if not sep or len(parts) != 2 or not all(parts):
        raise SceneError(f"--set {text!r}: expected section.key=value (e.g. contact.mu=0.3)")
    raw = raw.strip()
    try:
        doc = tomllib.loads(f"v = {raw}")
    except tomllib.TOMLDecodeError:
        # Not a TOML value: take it as a bare string, so hb.solver=powell works.
        return parts[0], parts[1], raw
    if list(doc) != ["v"]:
        # a value with a line break can carry more TOML ("0.3\n[hb]\ntol=5"), which was dropped
        raise SceneError(f"--set {text!r}: the value holds more than one TOML value; give one")
    return parts[0], parts[1], doc["v"]


def resolve(raw: dict, path: Path | None = None, overrides: Iterable[str] = ()) -> Scene:
    """Resolve a raw TOML dict (plus ``--set`` overrides) into a :class:`Scene`.

    Every section is filled with defaults; unknown sections, unknown keys,
    wrong types and out-of-range values raise :class:`SceneError` naming
    ``section.key``.
    """
    known = sections()
    raw = {k: v for k, v in raw.items()}
    not_tables = sorted(k for k, v in raw.items() if not isinstance(v, dict))
    if not_tables:
        raise SceneError(f"{_where(path)}top-level key {not_tables[0]!r} must be inside a [section]")
    unknown = sorted(set(raw) - set(known))
    if unknown:
        raise SceneError(f"{_where(path)}unknown section{'s' if len(unknown) > 1 else ''} "
                         f"{', '.join(f'[{u}]' for u in unknown)} (known: {', '.join(known)})")
    base = path.parent if path is not None else Path.cwd()
    tables = {name: _resolve_paths(name, known[name], dict(raw.get(name) or {}), base) for name in known}
    overrides = list(overrides)
    from_set: dict[str, str] = {}  # "section.key" → the --set text that gave it
    for text in overrides:
        sec, key, value = parse_override(text)
        if sec not in known:
            raise SceneError(f"--set {text}: unknown section [{sec}] (known: {', '.join(known)})")
        tables[sec].update(_resolve_paths(sec, known[sec], {key: value}, Path.cwd()))
        from_set[f"{sec}.{key}"] = text
    resolved = {}
    for name, cls in known.items():
        try:
            resolved[name] = resolve_section(name, cls, tables[name])
        except SceneError as exc:
            raise SceneError(f"{_blame(str(exc), from_set, path)}{exc}") from None
        except TypeError as exc:  # a dataclass without defaults for some field
            raise SceneError(f"{_where(path)}[{name}]: {exc}") from None
    _check_geometry(resolved["geometry"], path, from_set)
    return Scene(resolved, path, overrides)


def load_scene(name: str | Path, overrides: Iterable[str] = ()) -> Scene:
    """Find, read and resolve a scene file (path or shipped name)."""
    path = find_scene(name)
    return resolve(read_toml(path), path, overrides)


def _where(path: Path | None) -> str:
    return f"{path}: " if path is not None else ""


def _blame(msg: str, from_set: dict[str, str], path: Path | None) -> str:
    """Prefix of an error: the ``--set`` that gave a key the message names, else the scene file.

    The first key the message names decides (a cross-key rule names the key at fault first).
    """
    named = [(msg.find(k), k) for k in from_set if re.search(rf"(?<![\w.]){re.escape(k)}(?![\w])", msg)]
    if named:
        return f"--set {from_set[min(named)[1]]}: "
    return _where(path)


def _resolve_paths(section: str, cls, table: dict, base: Path) -> dict:
    """Make path-valued keys absolute against ``base`` (empty means unset)."""
    units = {f.name: f.metadata.get("unit", "") for f in dataclasses.fields(cls)}
    for key, value in table.items():
        if units.get(key) == "path" and isinstance(value, str) and value:
            table[key] = str((base / Path(value).expanduser()).resolve())
    return table


def _check_geometry(params, path: Path | None, from_set: dict[str, str]) -> None:
    """Run the geometry engineer's own validation when it is available.

    It names the parameter at fault (a :class:`GeometryError`), so a bad
    sector is reported by ``bladewear show`` before any meshing starts.
    """
    try:
        from geometry.params import check_params
    except ImportError:
        return
    from workflow.errors import GeometryError

    try:
        check_params(params)
    except GeometryError as exc:
        raise GeometryError(f"{_blame(str(exc), from_set, path)}{exc}") from None
    except ModuleNotFoundError as exc:
        if not (exc.name or "").startswith("geometry"):
            raise  # a missing helper module of geometry/ while it is being written: skip


# ---------------------------------------------------------------- documentation

def field_rows(cls) -> list[dict]:
    """(key, type, default, unit, doc, range) of every key of a section.

    Fields made with :func:`workflow.schema.param` carry their unit and doc;
    plain dataclass fields (``SectorParams``) take them from the class
    docstring (``name: text, m.`` entries), so the reference stays complete
    either way.
    """
    doc_entries = _docstring_entries(cls)
    rows = []
    for f in dataclasses.fields(cls):
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
            default = f.default_factory()  # type: ignore[misc]
        else:
            default = None
        meta = f.metadata
        unit, doc = meta.get("unit", ""), meta.get("doc", "")
        if not doc and f.name in doc_entries:
            doc = doc_entries[f.name]
            unit = unit or _unit_from_doc(doc)
        rng = []
        if meta.get("min") is not None:
            rng.append(f"{'>' if meta.get('min_exclusive') else '≥'} {meta['min']}")
        if meta.get("max") is not None:
            rng.append(f"≤ {meta['max']}")
        if meta.get("choices"):
            rng.append("one of " + ", ".join(map(str, meta["choices"])))
        if meta.get("item_choices"):
            rng.append("items from " + ", ".join(map(str, meta["item_choices"])))
        rows.append(dict(key=f.name, type=_type_label(default), default=default, unit=unit, doc=doc,
                         range="; ".join(rng)))
    return rows


def _type_label(default) -> str:
    return {bool: "bool", int: "int", float: "float", str: "string", list: "list"}.get(type(default), "")


def _docstring_entries(cls) -> dict[str, str]:
    """Parse ``name: text`` / ``a, b: text`` entries of an indented docstring."""
    text = cls.__doc__ or ""
    entries: dict[str, str] = {}
    current: list[str] = []
    for line in text.splitlines():
        m = re.match(r"\s+([a-z_][a-z0-9_]*(?:\s*,\s*[a-z_][a-z0-9_]*)*):\s+(.*)$", line)
        if m:
            current = [n.strip() for n in m.group(1).split(",")]
            for n in current:
                entries[n] = m.group(2).strip()
        elif current and line.strip() and line.startswith(" " * 8):
            for n in current:
                entries[n] += " " + line.strip()
        else:
            current = []
    return entries


def _unit_from_doc(doc: str) -> str:
    m = re.search(r",\s*(m|rad|Pa|N|kg|s|Hz)\b(?![²³/])", doc)
    return m.group(1) if m else ""


def _fmt(v) -> str:
    if isinstance(v, float):
        return repr(v) if (v == 0 or 1e-3 <= abs(v) < 1e6) and math.isfinite(v) else f"{v:.6g}"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return str(v)


def markdown_reference() -> str:
    """The scene reference (``docs/scenes.md``), generated from the dataclasses."""
    out = ["# Scene reference", "",
           "Generated by `python -m workflow.scene --doc > docs/scenes.md` from the section dataclasses "
           "(`workflow/params.py`, `geometry/params.py`); do not edit by hand.", "",
           "A scene is a TOML file with one table per section. Every key is optional: a key left out takes "
           "the default below. Units are SI (frequencies in Hz). Unknown sections or keys are errors. "
           "Any key can be overridden on the command line: `bladewear run SCENE --set section.key=value` "
           "(the value is parsed as TOML: `--set hb.harmonics=[1,3]`, `--set hb.solver=powell`).", "",
           "Sections: " + ", ".join(f"[`[{n}]`](#{n})" for n in sections()), ""]
    for name, cls in sections().items():
        out += [f"## {name}", ""]
        head = (cls.__doc__ or "").strip().splitlines()
        if head and not head[0].startswith(cls.__name__ + "("):
            out += [head[0], ""]
        out += ["| key | type | default | unit | meaning | allowed |", "|---|---|---|---|---|---|"]
        for r in field_rows(cls):
            doc = r["doc"].replace("|", "\\|")
            out.append(f"| `{r['key']}` | {r['type']} | `{_fmt(r['default'])}` | {r['unit']} | {doc} | "
                       f"{r['range'].replace('|', chr(92) + '|')} |")
        out.append("")
    return "\n".join(out)


def format_scene(scene: Scene) -> str:
    """Human-readable resolved scene: one TOML-like table per section, with units."""
    lines = [f"# {scene.title}" + (f"  ({scene.path})" if scene.path else "")]
    for name, cls in sections().items():
        lines.append(f"\n[{name}]" + ("  # not used: [model] bundle replaces it" if name in scene.unused else ""))
        rows = field_rows(cls)
        width = max((len(r["key"]) for r in rows), default=0)
        for r in rows:
            value = _fmt(getattr(scene[name], r["key"]))
            unit = f"  # {r['unit']}" if r["unit"] and r["unit"] != "path" else ""
            lines.append(f"{r['key'].ljust(width)} = {value}{unit}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python -m workflow.scene --doc`` (reference) or ``… SCENE`` (resolved scene)."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--doc"]:
        print(markdown_reference())
        return 0
    if len(argv) == 1:
        print(format_scene(load_scene(argv[0])))
        return 0
    print("usage: python -m workflow.scene --doc | SCENE", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
