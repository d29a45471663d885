"""The run's report as Markdown, in the HTML page's order (results first, provenance last)."""
from __future__ import annotations

from workflow.report import format as fmt
from workflow.report.html import LABELS

MARK = {"green": "🟢", "amber": "🟠", "red": "🔴", "none": "⚪"}
#: A check's verdict (a card's is :data:`workflow.report.html.LABELS`).
VERDICT = {"green": "ok", "amber": "warning", "red": "failed", "none": "not checked"}


def _cell(s) -> str:
    return str(s).replace("|", "\\|").replace("\n", " ")


def _limit(h: dict) -> str:
    """The peak's Nh → ∞ estimate (the Nh-check's Richardson in 1/Nh), when the run has one."""
    lim = h.get("peak_amplitude_nh_limit_m")
    return "" if lim is None else f"; Nh → ∞ estimate {fmt.si(lim, 'm')}"


def _worn(h: dict) -> str:
    """Worn volume and operating point beside the deepest wear (the node-wise maximum is the
    mesh-sensitive number; the volume converges with the contact mesh)."""
    out = ""
    if h.get("worn_volume_m3") is not None:
        out += f"; worn volume {h['worn_volume_m3'] * 1e9:.4g} mm³"
    if h.get("wear_frequency_hz") is not None:
        out += f"; at {fmt.hz(h['wear_frequency_hz'])} ({h.get('wear_operating_point') or 'fixed frequency'})"
    return out


def headline_md(h: dict) -> list[str]:
    st = h.get("status", "none")
    pos = h.get("max_wear_position_m")
    where = (h.get("max_wear_where") or "") + (f" at ({', '.join(f'{1e3 * c:.1f}' for c in pos)}) mm" if pos else "")
    no_frf = h.get("peak_source") is None and h.get("tied_peak_amplitude_m") is None
    rows = [
        ("friction-damped peak", f"{fmt.hz(h.get('peak_hz'))}, {fmt.si(h.get('peak_amplitude_m'), 'm')}",
         "no FRF in this run (the scene's outputs have no “frf”)" if no_frf else
         f"tied peak {fmt.si(h.get('tied_peak_amplitude_m'), 'm')}, sliding {fmt.si(h.get('sliding_peak_amplitude_m'), 'm')}, "
         f"stuck {fmt.si(h.get('stuck_peak_amplitude_m'), 'm')}"
         + _limit(h)),
        ("damping achieved", "amplitude ratio " + ("—" if h.get("amplitude_ratio") is None
                                                   else f"{h['amplitude_ratio']:.3g}"),
         "not computed: it needs the FRF" if no_frf else
         f"ζ_eq = {fmt.percent(h.get('equivalent_damping_ratio'))} (structural {fmt.percent(h.get('tied_damping_ratio'))})"),
        ("deepest wear", fmt.si(h.get("max_wear_m"), "m"), where + _worn(h)),
        ("worn frequency shift", fmt.signed_hz(h.get("worn_frequency_shift_hz")),
         h.get("worn_frequency_shift_source") or "not computed"),
        ("run time", fmt.seconds(h.get("run_seconds")), ""),
    ]
    out = [f"**Status: {MARK[st]} {LABELS[st]}**", "", "| result | value | detail |", "|---|---|---|"]
    out += [f"| {a} | {_cell(b)} | {_cell(c)} |" for a, b, c in rows]
    out += ["", "| | check | status | reason |", "|---|---|---|---|"]
    out += [f"| {c['item']} | {_cell(c['name'])} | {MARK[c['status']]} {VERDICT[c['status']]} | {_cell(c['reason'])} |"
            for c in h.get("checks", [])]
    return out + [""]


def _ratio_md(ratio: dict) -> list[str]:
    """§5.2 beside the paper: time ratio, times, profiles apart."""
    ref, d = ratio.get("reference", "reference"), ratio.get("profile_max_rel_diff")
    secs = [ratio.get("pseudo_seconds"), ratio.get("reference_seconds")]
    out = ["## Beside the paper: §5.2 (Figs. 9–12), time to the worn steady state", "",
           f"Pseudo-time over the {ref} physical-time march (the paper's reference: the implicit scheme with DLFT). "
           "Ours: wall-clock time of this run; the paper's: CPU time.", "",
           "| | ours | paper |", "|---|---|---|",
           f"| time ratio pseudo-time / {ref} march [–] | {ratio['ours']:.3g} | {ratio['paper']:.2g} |"]
    if None not in secs:
        out.append(f"| time pseudo-time, {ref} [s] | {secs[0]:.3g}, {secs[1]:.3g} | 29 %, 100 % (CPU) |")
    out.append(f"| wear profiles apart [% of max W] | {'—' if d is None else f'{100 * d:.2g}'} | “the same” (Fig. 9) |")
    return out + [""]


def page(title: str, h: dict, viewer: tuple, paper: tuple, sections, prov: dict, stages, scalars) -> str:
    """The Markdown report (same arguments as :func:`workflow.report.html.page`)."""
    lines = [f"# {title}", ""] + headline_md(h)
    if h.get("warnings"):
        lines += ["## Warnings", ""] + [f"* {_cell(w)}" for w in h["warnings"]] + [""]
    if viewer[0]:
        lines += [f"Interactive 3D view of the worn sector: [{viewer[0]}]({viewer[0]}) (open in a browser)", ""]
    table1, ratio = paper
    if table1:
        lines += ["## Beside the paper: Table 1 (§5.1, Figs. 4–7), CPU time of 50 frequencies normalised by "
                  "HBM Nh = 1 nit = 105", "",
                  "| Nh | method, nit | ours [–] | paper [–] |", "|---|---|---|---|"]
        lines += [f"| {r['Nh']} | {r['column']} | {r['ours']:.3g}" + (f" * ({r['not_converged']})" if r.get("not_converged")
                                                                    else "") + f" | {r['paper_text']} |" for r in table1]
        if any(r.get("not_converged") for r in table1):
            lines += ["", "\\* (k): k of the variant's 50 points did not converge; its CPU includes those solves."]
        lines += [""]
    if ratio:
        lines += _ratio_md(ratio)
    for product, figures, _ in sections:
        for rel, stem, cap, fig in figures:
            lines += [f"![{rel.rsplit('/', 1)[-1]}]({rel})", "", f"*{stem}*" + (f" (paper {fig})" if fig else "") + f". {cap}", ""]
    for product, _, tables in sections:
        for caption, head, rows, total in tables:
            more = f" (first {len(rows)} of {total} rows)" if total > len(rows) else ""
            lines += [f"**{product}/{caption}**{more}", "", "| " + " | ".join(_cell(fmt.header(x)) for x in head) + " |",
                      "|" + "---|" * len(head)]
            lines += ["| " + " | ".join(_cell(c) for c in r + [""] * (len(head) - len(r))) + " |" for r in rows]
            lines.append("")
    lines += ["## Provenance", ""] + [f"* {k}: `{_cell(v)}`" for k, v in prov.items()] + [""]
    lines += ["| stage | status | time [s] |", "|---|---|---|"] + [f"| {n} | {s} | {t} |" for n, s, t in stages]
    return "\n".join(lines) + "\n"
