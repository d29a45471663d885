"""FRF tables and figures (paper Table 1, Figs. 4–8): CSV, Markdown and PNG files.

Takes an :class:`workflow.engine.studies.study.FRFStudy` (or its parts) and writes;
computes nothing but what a table or a picture needs.
"""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

FRF_COLUMNS = ("method", "Nh", "nit", "solver", "frequency_hz", "amplitude_m", "iterations", "seconds",
               "converged", "amplitude_max_m", "role", "reason", "stable", "floquet_max")


def _csv(rows, header) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()


def _g(x) -> str:
    return "" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.9g}"


def write_outputs(out: Path, study) -> dict:
    """Every FRF file of an :class:`~workflow.engine.studies.study.FRFStudy`; {name: path relative to out}."""
    runs, ref = study.runs, study.reference
    files = {"frf": _frf_csv(out / "frf.csv", runs, ref), "linear": _linear_csv(out / "linear.csv", study)}
    files.update(_cpu_table(out, runs))
    if ref is not None:
        files["error_vs_time"] = _error_csv(out / "error_vs_time.csv", runs, study.reference_convergence)
    files.update(_figures(out, runs, ref, study.freqs_hz, study.tied, study.sliding,
                          uncertainty=(study.reference_convergence or {}).get("max_rel_change")))
    return files


def _frf_csv(path: Path, runs, ref) -> str:
    from workflow.io import write_text

    rows = []
    for r, role in [(r, "variant") for r in runs] + ([(ref, "reference")] if ref else []):
        v = r.variant
        for i, f in enumerate(r.freqs_hz):
            rows.append([v.method, v.nh, v.nit, r.solver, _g(float(f)), _g(float(r.amplitude[i])),
                         int(r.iterations[i]), f"{r.seconds[i]:.6f}", int(r.converged[i]),
                         _g(float(r.amplitude_max[i])), role, "" if r.converged[i] else r.reasons[i],
                         "" if r.stable is None or r.stable[i] is None else int(r.stable[i]),
                         "" if r.floquet_max is None or not np.isfinite(r.floquet_max[i]) else _g(float(r.floquet_max[i]))])
    write_text(path, _csv(rows, FRF_COLUMNS))
    return path.name


def _linear_csv(path: Path, study) -> str:
    from workflow.io import write_text

    stuck = study.stuck if study.stuck is not None else np.full(len(study.freqs_hz), np.nan)
    write_text(path, _csv([[_g(float(f)), _g(float(a)), _g(float(b)), _g(float(c))]
                           for f, a, b, c in zip(study.freqs_hz, study.tied, study.sliding, stuck)],
                          ("frequency_hz", "tied_m", "sliding_m", "stuck_m")))
    return path.name


def _cpu_table(out: Path, runs) -> dict:
    """Paper Table 1: process CPU seconds scaled to 50 frequencies, normalised
    by HBM-1 nit=105 (else the first variant)."""
    from workflow.io import write_text

    base = next((r for r in runs if r.variant.method == "hbm" and r.variant.nh == 1 and r.variant.nit == 105),
                runs[0] if runs else None)
    cpu_rows = []
    for r in runs:
        s50 = r.cpu_seconds * 50.0 / max(len(r.freqs_hz), 1)
        cpu_rows.append((r, s50, s50 / (base.cpu_seconds * 50.0 / max(len(base.freqs_hz), 1))
                         if base and base.cpu_seconds > 0 else float("nan")))
    write_text(out / "cpu_table.csv", _csv(
        [[r.variant.method, r.variant.nh, r.variant.nit, r.variant.nit_label, f"{s:.6g}", f"{nrm:.6g}"]
         for r, s, nrm in cpu_rows],
        ("method", "Nh", "nit", "nit_label", "cpu_seconds_per_50", "normalised")))
    write_text(out / "cpu_table.md", _cpu_markdown(cpu_rows, base))
    return {"cpu_table": "cpu_table.csv", "cpu_table_md": "cpu_table.md"}


def _error_csv(path: Path, runs, convergence) -> str:
    """Error against run time; ``reference_uncertainty`` is the reference's own
    change under its nit/Nh/ε check (an error below it is not resolved)."""
    from workflow.io import write_text

    unc = (convergence or {}).get("max_rel_change")
    write_text(path, _csv(
        [[r.variant.method, r.variant.nh, r.variant.nit, r.solver, f"{r.total_seconds:.6g}", _g(r.error),
          r.converged_points, len(r.freqs_hz), _g(unc)] for r in runs],
        ("method", "Nh", "nit", "solver", "seconds", "error", "converged_points", "points",
         "reference_uncertainty")))
    return path.name


def _cpu_markdown(cpu_rows, base) -> str:
    cols = []
    for r, _, _ in cpu_rows:
        key = (r.variant.method, r.variant.nit_label)
        if key not in cols:
            cols.append(key)
    nhs = sorted({r.variant.nh for r, _, _ in cpu_rows})
    cell = {(r.variant.method, r.variant.nit_label, r.variant.nh): nrm for r, _, nrm in cpu_rows}
    head = "| Nh | " + " | ".join(f"{m.upper()} nit={lab}" for m, lab in cols) + " |"
    sep = "|---|" + "---|" * len(cols)
    lines = [head, sep]
    for nh in nhs:
        vals = [cell.get((m, lab, nh)) for m, lab in cols]
        lines.append(f"| {nh} | " + " | ".join("" if v is None else f"{v:.3g}" for v in vals) + " |")
    ref = f"{base.variant.label}" if base else "—"
    secs = f"{base.cpu_seconds * 50.0 / max(len(base.freqs_hz), 1):.3g} s" if base else ""
    n = len(base.freqs_hz) if base else 0
    return (f"Process CPU time (all threads) scaled to 50 frequencies (from the {n} computed), normalised by "
            f"{ref} ({secs}) — cf. paper Table 1.\n\n"
            + "\n".join(lines) + "\n")


_STYLE = {"hbm": "-", "tcm": "--", "hdhb": ":"}


def _layout(fig) -> None:
    """Fixed margins for the 7 × 4.5 in figures of this module: ``tight_layout``
    measured ~0.08 s a figure here (a third of the stage's drawing time), and
    these axes' labels do not change size."""
    fig.subplots_adjust(left=0.13, right=0.97, bottom=0.105, top=0.93)


def _figures(out: Path, runs, ref, freqs, tied, slide, uncertainty=None) -> dict:
    """The FRF figures (PNG); {name: file}. ``uncertainty``: the reference's own change under
    its nit/Nh check (drawn on the error figure)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from workflow.io import atomic_path

    files = {}

    def save(fig, name):
        with atomic_path(out / name, suffix=".png") as tmp:
            fig.savefig(tmp, dpi=110, format="png")
        plt.close(fig)
        files[name.removesuffix(".png")] = name

    nhs = sorted({r.variant.nh for r in runs})
    for k in range(0, len(nhs), 2):
        grp = nhs[k:k + 2]
        _frf_axes(plt, save, freqs, tied, slide, ref, [r for r in runs if r.variant.nh in grp], "FRF, Nh = " + ", ".join(map(str, grp)) + " (cf. Figs. 4–5)",
                 "frf_nh" + "_".join(map(str, grp)) + ".png")
    if nhs:
        _frf_axes(plt, save, freqs, tied, slide, ref, [r for r in runs if r.variant.nh == nhs[0]],
                 f"Aliasing at Nh = {nhs[0]}: nit = 2Nh+1 vs larger nit (cf. Fig. 6)", "frf_nit_aliasing.png")

    _iterations_figure(plt, save, runs)
    _tangential_figure(plt, save, runs, ref)
    if ref is not None:
        fig, _ = error_figure(runs, ref.variant.label, uncertainty)
        save(fig, "error_vs_time.png")
    return files


def _frf_axes(plt, save, freqs, tied, slide, ref, sel, title, name):
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.semilogy(freqs, tied, color="0.6", lw=1, ls="-.", label="linear, tied")
    ax.semilogy(freqs, slide, color="0.8", lw=1, ls="-.", label="linear, sliding (μ = 0)")
    if ref is not None:
        ax.semilogy(ref.freqs_hz, ref.amplitude, "k-", lw=2.5, alpha=0.35, label=f"reference {ref.variant.label}")
    for r in sel:
        m = np.where(r.converged, r.amplitude, np.nan)
        line, = ax.semilogy(r.freqs_hz, m, ls=_STYLE.get(r.variant.method, "-"), marker=".", ms=3,
                            label=r.variant.label)
        if r.stable is not None and any(s is False for s in r.stable):
            # unstable points (hb.stability): over the curve, dashed between two unstable neighbours
            bad = np.array([s is False for s in r.stable])
            ax.semilogy(r.freqs_hz, np.where(bad, m, np.nan), ls="none", marker="o", mfc="none", ms=6,
                        color=line.get_color(), label=f"{r.variant.label}: unstable")
            seg = bad & np.roll(bad, -1)
            for i in np.flatnonzero(seg[:-1]):
                ax.semilogy(r.freqs_hz[i:i + 2], m[i:i + 2], ls="--", color="w", lw=1.2)
    top = max([np.nanmax(r.amplitude) for r in sel if np.isfinite(r.amplitude).any()] + [1e-300])
    ax.set_ylim(top / 30, top * 3)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("tip amplitude, 1st harmonic (m)")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    _layout(fig)
    save(fig, name)


def _iterations_figure(plt, save, runs):
    """Solver iterations against frequency (cf. Fig. 7)."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for r in runs:
        ax.plot(r.freqs_hz, r.iterations, ls=_STYLE.get(r.variant.method, "-"), marker=".", ms=3,
                label=r.variant.label)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("solver iterations")
    ax.set_title("Iterations against frequency (cf. Fig. 7)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    _layout(fig)
    save(fig, "iterations.png")


def _tangential_figure(plt, save, runs, ref):
    """Tangential relative displacement of the most moving pair over a period at resonance (cf. Fig. 8)."""
    from workflow.engine import fourier

    base = ref if ref is not None else max(runs, key=lambda r: (r.variant.nh, r.variant.nit))
    if base.converged.any():
        i_res = int(np.nanargmax(np.where(base.converged, base.amplitude, np.nan)))
        U = base.Ur[i_res]
        amp_t = np.linalg.norm(np.abs(U[1:]).reshape(U.shape[0] - 1, -1, 3)[:, :, 1:], axis=(0, 2))
        pair = int(np.argmax(amp_t))
        f_res = base.freqs_hz[i_res]
        # each run's point nearest to that frequency (the same index on a grid;
        # arc-length runs have points of their own)
        at = {id(r): int(np.argmin(np.abs(r.freqs_hz - f_res))) for r in runs + [base]}
        wanted = [("hbm", 7), ("hdhb", 7), ("hdhb", 17)]
        sel = [r for r in runs if (r.variant.method, r.variant.nh) in wanted and r.converged[at[id(r)]]]
        if not sel:
            sel = [r for r in runs if r.converged[at[id(r)]]][:4]
        tau = fourier.sample_times(256)
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for r in ([base] if ref is not None else []) + sel:
            k = at[id(r)]
            ut = fourier.to_time(r.Ur[k], 256).reshape(256, -1, 3)[:, pair, 1]
            lab = f"reference {r.variant.label}" if r is ref else r.variant.label
            ax.plot(tau, ut * 1e6, ls=_STYLE.get(r.variant.method, "-") if r is not ref else "-",
                    lw=2.5 if r is ref else 1.2, alpha=0.4 if r is ref else 1.0, color="k" if r is ref else None,
                    label=lab)
            if r.variant.method == "hdhb":  # its unknowns: the samples themselves
                ts = fourier.sample_times(r.variant.nit)
                us = fourier.to_time(r.Ur[k], r.variant.nit).reshape(r.variant.nit, -1, 3)[:, pair, 1]
                ax.plot(ts, us * 1e6, "o", ms=3, color=ax.lines[-1].get_color())
        ax.set_xlabel("τ = ωt (rad)")
        ax.set_ylabel(f"u_t1 of pair {pair} (µm)")
        ax.set_title(f"Tangential relative displacement over a period at {base.freqs_hz[i_res]:.2f} Hz (cf. Fig. 8)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
        _layout(fig)
        save(fig, "tangential.png")


#: colour and marker of each HB formulation on the error figure
_COLOR = {"hbm": "C0", "tcm": "C1", "hdhb": "C2"}
_MARKER = {"hbm": "o", "tcm": "s", "hdhb": "^"}
#: the saving dpi (:func:`_figures`): the error figure is drawn at it, so that its labels are placed
#: in the pixels they will have
DPI = 110


def error_figure(runs, ref_label: str, uncertainty: float | None = None):
    """FRF error against run time, each variant against the reference: (figure, label Texts).

    Log–log; colour and marker say the formulation, a filled marker a fixed nit and an open
    one nit = 2Nh+1; each point labelled ``METHOD-Nh/nit`` by :func:`workflow.report.labels.place_labels`
    (no two labels overlap, none leaves the axes; far ones get a leader line). ``uncertainty``:
    the reference's own change under its nit/Nh check, a dashed line — errors below it are
    not resolved."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from workflow.report.labels import place_labels

    fig, ax = plt.subplots(figsize=(7, 4.5), dpi=DPI)
    pts = [(max(r.total_seconds, 1e-4), max(r.error, 1e-12), r) for r in runs
           if r.error is not None and math.isfinite(r.error) and math.isfinite(r.total_seconds)]
    for t, e, r in pts:
        m, c = r.variant.method, _COLOR.get(r.variant.method, "C3")
        ax.plot([t], [e], _MARKER.get(m, "o"), ms=6, color=c, mfc="white" if r.variant.collocated else c,
                mew=1.3, zorder=3)
    ax.set_xscale("log")
    ax.set_yscale("log")
    handles = [Line2D([], [], ls="", marker=_MARKER[m], color=_COLOR[m], label=m.upper())
               for m in _MARKER if any(r.variant.method == m for *_, r in pts)]
    handles += [Line2D([], [], ls="", marker="o", color="0.3", label="fixed nit"),
                Line2D([], [], ls="", marker="o", color="0.3", mfc="white", label="nit = 2Nh+1")]
    ys = [e for _, e, _ in pts]
    if uncertainty:
        ax.axhline(uncertainty, color="0.4", ls="--", lw=1, zorder=1)
        handles.append(Line2D([], [], color="0.4", ls="--", lw=1,
                              label=f"reference's own uncertainty {uncertainty:.1e}"))
        ys.append(uncertainty)
    if pts:   # limits fixed before the labels are placed: room around the points for them
        xs = [t for t, _, _ in pts]
        ax.set_xlim(min(xs) / 1.7, max(xs) * 1.7)
        ax.set_ylim(min(ys) / 3.0, max(ys) * 3.0)
    ax.set_xlabel("wall time of the sweep (s)")
    ax.set_ylabel("max |A − A_ref| / max A_ref")
    ax.set_title(f"FRF error against run time (reference {ref_label})")
    ax.grid(True, which="both", alpha=0.3)
    _layout(fig)
    leg = ax.legend(handles=handles, fontsize=7, loc="best", framealpha=0.9)
    renderer = fig.canvas.get_renderer()
    box = leg.get_window_extent(renderer)
    # held where "best" put it: the leader lines drawn next would otherwise move it at saving
    leg.set_loc(tuple(ax.transAxes.inverted().transform((box.x0, box.y0))))
    texts = place_labels(ax, [(t, e) for t, e, _ in pts],
                         [f"{r.variant.method.upper()}-{r.variant.nh}/{r.variant.nit}" for *_, r in pts],
                         fontsize=6.5, marker_px=9.0, avoid=[(box.x0, box.y0, box.x1, box.y1)])
    return fig, texts
