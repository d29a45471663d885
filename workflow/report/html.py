"""The run's report page (HTML): results first, evidence next, provenance last.

Order of the page: the headline (five numbers with units and status marks,
then a model-checks card), the checks behind them with reasons, the
interactive 3D wear view, the paper side by side (paper scenes), the figures
with captions saying what to look at, the tables (units in the headers), and
at the end the provenance (scene, overrides, code version, machine, stage
times, the stages' scalar summaries).

Every headline number is a ``<span data-key=… data-value=…>``: ``data-value``
is the exact value of ``report.headline`` in summary.json (the browser test
compares them); the text is that value formatted with its unit.
"""
from __future__ import annotations

import html

from workflow.report import format as fmt
from workflow.report.headline import ORDER, Check

COLOURS = {"green": "#1a7f37", "amber": "#b26a00", "red": "#c62828", "none": "#8a8a8a"}
LABELS = {"green": "converged", "amber": "warning", "red": "not converged", "none": "not checked"}
e = html.escape

CSS = """
body{font-family:system-ui,sans-serif;max-width:78em;margin:1em auto;padding:0 1em;color:#1d1d1d}
h1{font-size:1.45em;margin:.2em 0 .3em}h2{margin-top:1.6em;border-bottom:1px solid #ddd}
.banner{padding:.45em .8em;border-radius:4px;color:#fff;font-weight:600;margin-bottom:.7em}
.cards{display:grid;grid-template-columns:repeat(3,1fr);gap:.6em}
.card{border:1px solid #ccc;border-left:6px solid var(--c);border-radius:4px;padding:.45em .7em}
.card h3{margin:0;font-size:.95em;color:#444}.card .v{font-size:1.45em;font-weight:600;margin:.15em 0}
.card .s{font-size:.82em;color:#333}.card ul{margin:.3em 0 0;padding-left:1.1em;font-size:.78em;color:#444}
.dot{display:inline-block;width:.75em;height:.75em;border-radius:50%;background:var(--c);margin-right:.35em}
table{border-collapse:collapse;margin:.5em 0 1.2em;font-size:.9em}td,th{border:1px solid #ccc;padding:.2em .55em}
td.n{text-align:right;font-variant-numeric:tabular-nums}th{background:#f3f3f3}
figure{margin:1em 0 1.6em}figure img{max-width:100%;border:1px solid #eee}figcaption{font-size:.9em;color:#333}
iframe{width:100%;height:34em;border:1px solid #ccc}details{margin:.4em 0}code{font-size:.92em}
"""


def _val(key: str, value, text: str) -> str:
    """A headline number: exact value in ``data-value``, formatted text shown."""
    return f"<span data-key='{e(key)}' data-value='{e(repr(value))}'>{e(text)}</span>"


def _status_of(checks: list[Check], items) -> str:
    st = [c.status for c in checks if c.item in items]
    return max(st, key=ORDER.__getitem__, default="none")


def cards(h: dict) -> list[dict]:
    """The headline cards: title, value HTML, sub-line HTML, check items they stand on."""
    ratio, z_eq, z_t = h.get("amplitude_ratio"), h.get("equivalent_damping_ratio"), h.get("tied_damping_ratio")
    pos = h.get("max_wear_position_m")
    where = (h.get("max_wear_where") or "") + (
        f" at x, y, z = {', '.join(f'{1e3 * c:.1f}' for c in pos)} mm" if pos else "")
    tied = _val("tied_peak_amplitude_m", h.get("tied_peak_amplitude_m"), fmt.si(h.get("tied_peak_amplitude_m"), "m"))
    z_span = _val("equivalent_damping_ratio", z_eq, fmt.percent(z_eq))
    if h.get("peak_source") is None and h.get("tied_peak_amplitude_m") is None:  # a scene without an FRF
        peak_sub = f"no FRF in this run (the scene's outputs have no “frf”); tied linear peak {tied}"
        damping_sub = f"not computed: it needs the FRF; ζ<sub>eq</sub> = {z_span}"
    else:
        peak_sub = (f"tip, 1st harmonic; tied linear peak {tied} at {e(fmt.hz(h.get('tied_peak_hz')))}, sliding "
                    f"(μ = 0) {e(fmt.si(h.get('sliding_peak_amplitude_m'), 'm'))} at "
                    f"{e(fmt.hz(h.get('sliding_peak_hz')))}, stuck (the pairs closed under the preload held: "
                    f"μ → ∞) {e(fmt.si(h.get('stuck_peak_amplitude_m'), 'm'))} at {e(fmt.hz(h.get('stuck_peak_hz')))}"
                    f"; from {e(str(h.get('peak_source') or '—'))}")
        if h.get("peak_amplitude_nh_limit_m") is not None:
            peak_sub += (f"; Nh → ∞ estimate {e(fmt.si(h['peak_amplitude_nh_limit_m'], 'm'))} "
                         "(Richardson in 1/Nh from the Nh check)")
        es = h.get("eps_sensitivity")
        if es:
            peak_sub += (f"; penalty sensitivity: the peak moves by {es['rel_change']:.1e} with ε × {es['factor']:g}")
        damping_sub = (f"equivalent damping ratio ζ<sub>eq</sub> = {z_span} (structural ζ = {e(fmt.percent(z_t))}; "
                       "ζ<sub>eq</sub> = ζ · tied peak / friction peak)")
    return [
        dict(title="Friction-damped resonance peak", items=("peak",),
             value=_val("peak_hz", h.get("peak_hz"), fmt.hz(h.get("peak_hz"))) + ", "
             + _val("peak_amplitude_m", h.get("peak_amplitude_m"), fmt.si(h.get("peak_amplitude_m"), "m")),
             sub=peak_sub),
        dict(title="Damping achieved by friction", items=("damping",), status_items=("damping", "peak"),
             value="amplitude ratio " + _val("amplitude_ratio", ratio, "—" if ratio is None else f"{ratio:.3g}"),
             sub=damping_sub),
        dict(title="Deepest wear", items=("wear",),
             value=_val("max_wear_m", h.get("max_wear_m"), fmt.si(h.get("max_wear_m"), "m")),
             sub=e(f"{where} ({h.get('wear_method') or '—'}; blade + disk)"
                   + (f"; worn volume {h['worn_volume_m3'] * 1e9:.4g} mm³" if h.get("worn_volume_m3") is not None
                      else "")) if h.get("max_wear_m") is not None
             else "no wear study in this run"),
        dict(title="Worn blade's frequency shift", items=("worn",),
             value=_val("worn_frequency_shift_hz", h.get("worn_frequency_shift_hz"),
                        fmt.signed_hz(h.get("worn_frequency_shift_hz"))),
             sub=e(h.get("worn_frequency_shift_source") or "not computed (see the check below)")),
        dict(title="Run time", items=(),
             value=_val("run_seconds", h.get("run_seconds"), fmt.seconds(h.get("run_seconds"))),
             sub="all stages, this run (cached stages count their load time)"),
        dict(title="Model checks", items=("model",), value="mesh, reduction", sub=""),
    ]


def headline_html(h: dict) -> str:
    """The banner and the cards (the first screen of the report)."""
    checks = [Check(**c) for c in h.get("checks", [])]
    st = h.get("status", "none")
    bad = [c for c in checks if c.status in ("red", "amber")]
    msg = {"green": "all results converged and every check within tolerance",
           "none": "no checks in this run"}.get(st, f"{len(bad)} check(s) need attention, see below")
    out = [f"<div class='banner' style='background:{COLOURS[st]}' data-key='status' data-value='{e(repr(st))}'>"
           f"Status: {e(LABELS[st])} — {e(msg)}</div><div class='cards'>"]
    for c in cards(h):
        cs = _status_of(checks, c.get("status_items", c["items"]))
        reasons = "".join(f"<li><span class='dot' style='--c:{COLOURS[k.status]}'></span>{e(k.name)}: {e(k.reason)}</li>"
                          for k in checks if k.item in c["items"])
        if "status_items" in c:
            reasons += "<li>and the peak's checks (first card)</li>"
        label = f" <small>({e(LABELS[cs])})</small>" if c["items"] else ""
        out.append(f"<div class='card' style='--c:{COLOURS[cs]}'><h3><span class='dot'></span>{e(c['title'])}"
                   f"{label}</h3><div class='v'>{c['value']}</div>"
                   f"<div class='s'>{c['sub']}</div>" + (f"<ul>{reasons}</ul>" if reasons else "") + "</div>")
    out.append("</div>")
    return "\n".join(out)


def warnings_html(h: dict) -> str:
    w = h.get("warnings") or []
    if not w:
        return ""
    return ("<h2>Warnings</h2><ul>" + "".join(f"<li style='color:{COLOURS['red'] if 'not converge' in x else '#5a3d00'}'>"
                                              f"{e(x)}</li>" for x in w) + "</ul>")


def viewer_html(rel: str | None, size_bytes: int | None) -> str:
    """The interactive 3D view, embedded (iframe) and linked."""
    if not rel:
        return ""
    size = f", {size_bytes / 1e6:.2g} MB" if size_bytes else ""
    return (f"<h2>Worn sector in 3D</h2><p>Drag to turn, wheel to zoom; flanks coloured by wear depth. "
            f"<a href='{e(rel)}'>Open full window</a> (self-contained{e(size)}, works offline).</p>"
            f"<iframe src='{e(rel)}' title='interactive 3D view of the worn sector' loading='eager'></iframe>")


def paper_html(table1: list[dict], ratio: dict | None) -> str:
    """Table 1 and the §5.2 CPU ratio, ours beside the paper's."""
    if not table1 and not ratio:
        return ""
    out = ["<h2>Beside the paper (Salles et al. 2012)</h2>"]
    if table1:
        out.append("<p><b>Table 1</b> (§5.1, Figs. 4–7): CPU time of 50 frequencies, normalised by HBM, Nh = 1, "
                   "nit = 105 [–]. Each side is normalised by its own HBM-1 cost and measured on its own code and "
                   "machine: compare the trends (which column is cheapest at each Nh, how cost grows with Nh), not "
                   "the digits. Each cell: <b>ours</b> / paper (as printed in the paper).</p>")
        cols = list(dict.fromkeys(r["column"] for r in table1))
        cell = {(r["Nh"], r["column"]): r for r in table1}
        out.append("<table><tr><th>Nh</th>" + "".join(f"<th>{e(c)}</th>" for c in cols) + "</tr>")
        for nh in sorted({r["Nh"] for r in table1}):
            out.append(f"<tr><td class='n'>{nh}</td>" + "".join(
                f"<td class='n'><b>{cell[nh, c]['ours']:.3g}</b>{_gave_up(cell[nh, c])} / {e(cell[nh, c]['paper_text'])}</td>"
                if (nh, c) in cell else "<td></td>" for c in cols) + "</tr>")
        out.append("</table>")
        if any(r.get("not_converged") for r in table1):
            out.append("<p><small>* (k): k of the variant's 50 points did not converge; its CPU includes those "
                       "solves up to the iteration limit (Warnings above).</small></p>")
    if ratio:
        d, ref = ratio.get("profile_max_rel_diff"), e(ratio.get("reference", "reference"))
        secs = [ratio.get("pseudo_seconds"), ratio.get("reference_seconds")]
        out.append(f"<p><b>§5.2</b> (Figs. 9–12): time to the worn steady state, pseudo-time over the {ref} "
                   "physical-time march (the paper's reference: the implicit scheme with DLFT, 100 %). Ours is "
                   "wall-clock time of this run, the paper's CPU time.</p>"
                   "<table><tr><th></th><th>ours</th><th>paper</th></tr>"
                   f"<tr><td>time ratio pseudo-time / {ref} march [–]</td><td class='n'>{ratio['ours']:.3g}</td>"
                   f"<td class='n'>{ratio['paper']:.2g}</td></tr>"
                   + (f"<tr><td>time pseudo-time, {ref} [s]</td><td class='n'>{secs[0]:.3g}, {secs[1]:.3g}</td>"
                      "<td class='n'>29 %, 100 % (CPU)</td></tr>" if None not in secs else "")
                   + f"<tr><td>wear profiles apart [% of max W]</td><td class='n'>"
                   f"{'—' if d is None else f'{100 * d:.2g}'}</td><td class='n'>“the same” (Fig. 9)</td></tr></table>")
    return "\n".join(out)


def _gave_up(row: dict) -> str:
    k = row.get("not_converged") or 0
    return f"<sup>*&nbsp;({k})</sup>" if k else ""


def figures_html(sections) -> str:
    """``sections``: [(product, [(rel path, stem, caption, paper figure)], tables)]."""
    out = []
    for product, figures, _ in sections:
        if not figures:
            continue
        out.append(f"<h2>Figures: {e(product)}</h2>")
        for rel, stem, cap, paper in figures:
            ref = f" <i>(paper {e(paper)})</i>" if paper else ""
            out.append(f"<figure><img src='{e(rel)}' alt='{e(stem)}' loading='lazy'><figcaption><b>{e(stem)}</b>"
                       f"{ref}. {e(cap)}</figcaption></figure>")
    return "\n".join(out)


def tables_html(sections) -> str:
    out = []
    for product, _, tables in sections:
        for caption, head, rows, total in tables:
            more = f" (first {len(rows)} of {total} rows; the CSV has them all)" if total > len(rows) else ""
            out.append(f"<p><b>{e(product)}/{e(caption)}</b>{e(more)}</p><table><tr>"
                       + "".join(f"<th>{e(fmt.header(h))}</th>" for h in head) + "</tr>")
            out += ["<tr>" + "".join(f"<td class='n'>{e(c)}</td>" for c in r) + "</tr>" for r in rows]
            out.append("</table>")
    return ("<h2>Tables</h2>" + "\n".join(out)) if out else ""


def provenance_html(prov: dict, stages: list[tuple], scalars: dict) -> str:
    """Scene, overrides, code version, machine, times; then each stage's scalars (folded)."""
    out = ["<h2>Provenance</h2><table>"]
    out += [f"<tr><th>{e(k)}</th><td>{e(str(v))}</td></tr>" for k, v in prov.items()]
    out.append("</table><table><tr><th>stage</th><th>status</th><th>time [s]</th></tr>")
    out += [f"<tr><td>{e(n)}</td><td>{e(str(s))}</td><td class='n'>{e(str(t))}</td></tr>" for n, s, t in stages]
    out.append("</table>")
    for name, items in scalars.items():
        if items:
            out.append(f"<details><summary>{e(name)}: stage summary</summary><table>"
                       + "".join(f"<tr><td>{e(k)}</td><td class='n'>{e(v)}</td></tr>" for k, v in items)
                       + "</table></details>")
    return "\n".join(out)


def page(title: str, h: dict, viewer: tuple, paper: tuple, sections, prov: dict, stages, scalars) -> str:
    """The whole report page."""
    body = [f"<h1>{e(title)}</h1>", headline_html(h), warnings_html(h), viewer_html(*viewer),
            paper_html(*paper), figures_html(sections), tables_html(sections),
            provenance_html(prov, stages, scalars)]
    return ("<!doctype html><html lang='en'><head><meta charset='utf-8'>"
            "<meta name='viewport' content='width=device-width,initial-scale=1'>"
            f"<title>{e(title)}</title><style>{CSS}</style></head><body>\n"
            + "\n".join(b for b in body if b) + "\n</body></html>\n")
