"""Report stage: one HTML and one Markdown page, results first.

It runs last and sees every product of the run (``NEEDS_ALL``) plus
``inputs["summary"]``, the run summary so far (stage status, timings and
each stage's summary). It computes the headline (``workflow/report/
headline.py``: peak, damping achieved, deepest wear, worn frequency shift,
run time, each with its status), puts the paper's numbers beside ours for
the paper scenes (``workflow/report/paper.py``), copies the PNG figures and
the interactive 3D view (``wear_3d.html``, written by the remap stage) into
its own folder so ``report/`` stands alone when copied elsewhere, and turns
CSV tables into HTML/Markdown tables (truncated: the CSV files stay the
data). The headline is returned, so summary.json carries it as
``report.headline``. Never cached: it shows this run's timings.
"""
from __future__ import annotations

import csv
import json
import os
import platform
import shutil
from pathlib import Path

from workflow.io import write_text
from workflow.report import html as html_page
from workflow.report import markdown as md_page
from workflow.report import paper
from workflow.report.headline import headline, read_rows

NAME = "report"
SECTIONS = ("run",)
NEEDS = ()
PRODUCES = ("report",)
CACHE = False
NEEDS_ALL = True

MAX_ROWS = 12  # table rows shown per CSV
MAX_COLS = 10
MAX_FIGURES = 40  # per product: guards against a stage that writes hundreds of frames
VIEWER = "wear_3d.html"  # the remap stage's interactive page (workflow/stages/remap.py:VIEWER)


def run(scene, inputs: dict, out: Path, log) -> dict:
    """Write ``report.html``, ``report.md`` (and copies of the figures and the 3D
    view) under ``out``; return their names and the headline."""
    out = Path(out)
    summary = json.loads(Path(inputs["summary"]).read_text()) if "summary" in inputs else {}
    title = scene["run"].title or summary.get("title") or "bladewear run"
    folders = {p: Path(f) for p, f in inputs.items() if p != "summary" and Path(f).is_dir()}
    sections = collect(folders, out)
    viewer = copy_viewer(folders.get("wear_map"), out)
    h = headline(summary, folders)
    stem = Path(str(summary.get("scene", ""))).stem
    runs = (summary.get("hb") or {}).get("runs") or []
    table1 = paper.table1_side_by_side(read_rows(folders["frf"] / "cpu_table.csv"), runs) \
        if stem == "paper-frf" and "frf" in folders else []
    ratio = paper.cpu_ratio_52(summary.get("wear")) if stem == "paper-wear" else None
    stages = [(n, s, summary.get("timings", {}).get(n, "")) for n, s in summary.get("stages", {}).items()]
    scalars = {n: _scalars(summary.get(n)) for n in summary.get("stages", {})}
    args = (title, h, viewer, (table1, ratio), sections, provenance(summary), stages, scalars)
    write_text(out / "report.html", html_page.page(*args))
    write_text(out / "report.md", md_page.page(*args))
    n_fig = sum(len(s[1]) for s in sections)
    n_tab = sum(len(s[2]) for s in sections)
    log.info(f"{n_fig} figures, {n_tab} tables; headline status {h['status']}"
             + (f"; 3D view {viewer[0]} ({viewer[1] / 1e6:.2g} MB)" if viewer[0] else ""))
    return {"markdown": "report.md", "html": "report.html", "figures": n_fig, "tables": n_tab,
            "viewer_3d": viewer[0], "headline": h}


def collect(folders: dict, out: Path) -> list:
    """Per product: figures copied under ``out/figures/<product>/`` as
    ``(rel path, stem, caption, paper figure)`` and CSV tables."""
    sections, seen = [], set()
    for product, folder in sorted(folders.items()):
        real = folder.resolve()
        if real in seen:
            continue
        seen.add(real)
        figures = []
        for png in sorted(folder.rglob("*.png"))[:MAX_FIGURES]:
            rel = Path("figures") / product / png.relative_to(folder)
            (out / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(png, out / rel)
            figures.append((rel.as_posix(), png.stem, *paper.caption(png.stem)))
        tables = [_read_csv(f, folder) for f in sorted(folder.rglob("*.csv"))]
        sections.append((product, figures, [t for t in tables if t is not None]))
    return sections


def copy_viewer(folder: Path | None, out: Path) -> tuple:
    """(name, bytes) of the 3D view copied into ``out``, or (None, None)."""
    src = folder / VIEWER if folder is not None else None
    if src is None or not src.is_file():
        return None, None
    shutil.copyfile(src, out / VIEWER)
    return VIEWER, (out / VIEWER).stat().st_size


def provenance(summary: dict) -> dict:
    """Where the numbers come from: scene, overrides, code, machine, times."""
    uname = platform.uname()
    return {
        "scene": summary.get("scene", ""), "overrides": " ".join(summary.get("overrides") or []) or "none",
        "created": summary.get("created", ""), "code version": summary.get("code_version", ""),
        "cache": summary.get("cache", ""),
        "machine": f"{uname.node}: {uname.system} {uname.release} {uname.machine}, {os.cpu_count()} CPUs, "
                   f"Python {platform.python_version()}",
        "threads": f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}",
        "stage times [s]": ", ".join(f"{k} {v}" for k, v in (summary.get("timings") or {}).items()),
    }


def _read_csv(path: Path, folder: Path):
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError, csv.Error):
        return None
    if not rows:
        return None
    header, body = rows[0][:MAX_COLS], [r[:MAX_COLS] for r in rows[1:]]
    return path.relative_to(folder).as_posix(), header, body[:MAX_ROWS], len(body)


def _scalars(entry) -> list[tuple[str, str]]:
    """Flat scalar items of a stage summary (nested values are left to summary.json)."""
    if not isinstance(entry, dict):
        return []
    return [(k, _short(v)) for k, v in entry.items() if isinstance(v, (int, float, str, bool)) or v is None]


def _short(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    s = str(v)
    return s if len(s) <= 80 else s[:77] + "…"
