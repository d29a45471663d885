"""Report stage: one Markdown and one HTML page with the run's figures and tables.

It runs last and sees every product of the run (``NEEDS_ALL``) plus
``inputs["summary"]``, the run summary so far (stage status, timings and
each stage's summary). It copies the PNG figures the stages wrote into its
own folder, so ``report/`` stands alone when copied elsewhere, and turns CSV
tables into Markdown/HTML tables (truncated: the CSV files stay the data).
Never cached: it shows this run's timings.
"""
from __future__ import annotations

import csv
import html
import json
import shutil
from pathlib import Path

from workflow.io import write_text

NAME = "report"
SECTIONS = ("run",)
NEEDS = ()
PRODUCES = ("report",)
CACHE = False
NEEDS_ALL = True

MAX_ROWS = 12  # table rows shown per CSV
MAX_COLS = 10
MAX_FIGURES = 40  # per product: guards against a stage that writes hundreds of frames


def run(scene, inputs: dict, out: Path, log) -> dict:
    """Write ``report.md`` and ``report.html`` under ``out``; return their names."""
    summary = json.loads(Path(inputs["summary"]).read_text()) if "summary" in inputs else {}
    title = scene["run"].title or summary.get("title") or "bladewear run"
    sections = []  # (product, figures [(rel png, caption)], tables [(caption, header, rows, total rows)])
    seen: set[Path] = set()
    for product, folder in sorted(inputs.items()):
        if product == "summary":
            continue
        folder = Path(folder)
        real = folder.resolve()
        if real in seen or not folder.is_dir():
            continue
        seen.add(real)
        figures = []
        for png in sorted(folder.rglob("*.png"))[:MAX_FIGURES]:
            rel = Path("figures") / product / png.relative_to(folder)
            (out / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(png, out / rel)
            figures.append((rel.as_posix(), png.relative_to(folder).as_posix()))
        tables = [_read_csv(f, folder) for f in sorted(folder.rglob("*.csv"))]
        sections.append((product, figures, [t for t in tables if t is not None]))
    n_fig = sum(len(s[1]) for s in sections)
    n_tab = sum(len(s[2]) for s in sections)
    log.info(f"{n_fig} figures, {n_tab} tables")
    write_text(out / "report.md", _markdown(title, summary, sections))
    write_text(out / "report.html", _html(title, summary, sections))
    return {"markdown": "report.md", "html": "report.html", "figures": n_fig, "tables": n_tab}


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


def _md_cell(s: str) -> str:
    return str(s).replace("|", "\\|").replace("\n", " ")


def _markdown(title, summary, sections) -> str:
    lines = [f"# {title}", ""]
    if summary.get("scene"):
        lines += [f"Scene: `{summary['scene']}`" + (f", overrides: `{' '.join(summary['overrides'])}`"
                                                    if summary.get("overrides") else ""), ""]
    bad = summary.get("unconverged") or {}
    if bad:
        # The run finished (exit status 3), but these results are not solutions.
        lines += ["## ⚠ Unconverged results", "", "<span style='color:#c00'>**These results did not converge; "
                  "read them as such (exit status 3).**</span>", ""]
        lines += [f"- **{_md_cell(name)}**: {_md_cell(line)}" for name, ls in bad.items() for line in ls]
        lines.append("")
    stages = summary.get("stages", {})
    if stages:
        lines += ["## Stages", "", "| stage | status | time (s) |", "|---|---|---|"]
        for name, status in stages.items():
            lines.append(f"| {name} | {status} | {summary.get('timings', {}).get(name, '')} |")
        lines.append("")
        for name in stages:
            items = _scalars(summary.get(name))
            if items:
                lines += [f"### {name}", "", "| | |", "|---|---|"]
                lines += [f"| {_md_cell(k)} | {_md_cell(v)} |" for k, v in items]
                lines.append("")
    for product, figures, tables in sections:
        if not figures and not tables:
            continue
        lines += [f"## {product}", ""]
        for rel, caption in figures:
            lines += [f"![{caption}]({rel})", "", f"*{caption}*", ""]
        for caption, header, rows, total in tables:
            lines += [f"**{caption}**" + (f" (first {len(rows)} of {total} rows)" if total > len(rows) else ""), ""]
            lines.append("| " + " | ".join(_md_cell(h) for h in header) + " |")
            lines.append("|" + "---|" * len(header))
            for r in rows:
                lines.append("| " + " | ".join(_md_cell(c) for c in r + [""] * (len(header) - len(r))) + " |")
            lines.append("")
    return "\n".join(lines) + "\n"


def _html(title, summary, sections) -> str:
    e = html.escape
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>{e(title)}</title>",
             "<style>body{font-family:sans-serif;max-width:70em;margin:2em auto;padding:0 1em}"
             "table{border-collapse:collapse;margin:.5em 0 1.5em}td,th{border:1px solid #ccc;padding:.2em .6em;"
             "text-align:right}img{max-width:100%}figure{margin:1em 0}</style></head><body>",
             f"<h1>{e(title)}</h1>"]
    if summary.get("scene"):
        parts.append(f"<p>Scene: <code>{e(summary['scene'])}</code></p>")
    bad = summary.get("unconverged") or {}
    if bad:
        parts.append("<div style='color:#c00;border:2px solid #c00;padding:.5em 1em'>"
                     "<h2>Unconverged results</h2><p>These results did not converge (exit status 3):</p><ul>"
                     + "".join(f"<li><b>{e(name)}</b>: {e(line)}</li>" for name, ls in bad.items() for line in ls)
                     + "</ul></div>")
    stages = summary.get("stages", {})
    if stages:
        parts.append("<h2>Stages</h2><table><tr><th>stage</th><th>status</th><th>time (s)</th></tr>")
        for name, status in stages.items():
            parts.append(f"<tr><td>{e(name)}</td><td>{e(status)}</td>"
                         f"<td>{e(str(summary.get('timings', {}).get(name, '')))}</td></tr>")
        parts.append("</table>")
        for name in stages:
            items = _scalars(summary.get(name))
            if items:
                parts.append(f"<h3>{e(name)}</h3><table>")
                parts += [f"<tr><td>{e(k)}</td><td>{e(v)}</td></tr>" for k, v in items]
                parts.append("</table>")
    for product, figures, tables in sections:
        if not figures and not tables:
            continue
        parts.append(f"<h2>{e(product)}</h2>")
        for rel, caption in figures:
            parts.append(f"<figure><img src='{e(rel)}' alt='{e(caption)}'><figcaption>{e(caption)}</figcaption></figure>")
        for caption, header, rows, total in tables:
            more = f" (first {len(rows)} of {total} rows)" if total > len(rows) else ""
            parts.append(f"<p><b>{e(caption)}</b>{e(more)}</p><table><tr>"
                         + "".join(f"<th>{e(h)}</th>" for h in header) + "</tr>")
            parts += ["<tr>" + "".join(f"<td>{e(c)}</td>" for c in r) + "</tr>" for r in rows]
            parts.append("</table>")
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"
