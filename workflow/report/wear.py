"""Wear tables and figures (paper Figs. 9–12): ``wear.csv`` and PNGs."""
from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from workflow.io import atomic_path, write_text


def write_wear_csv(path, position, flank, histories: dict, share: float) -> Path:
    """``wear.csv``: pair, flank, x, y, z [m], then per method W, W_blade, W_disk [m]."""
    buf = io.StringIO()
    w = csv.writer(buf)
    names = list(histories)
    head = ["pair", "flank", "x_m", "y_m", "z_m"]
    for m in names:
        head += [f"W_{m}_m", f"W_blade_{m}_m", f"W_disk_{m}_m"]
    w.writerow(head)
    flank_name = {0: "intrados", 1: "extrados"}
    for i in range(len(flank)):
        row = [i, flank_name.get(int(flank[i]), str(int(flank[i])))] + [f"{v:.9e}" for v in position[i]]
        for m in names:
            Wi = float(histories[m].W[i])
            row += [f"{Wi:.9e}", f"{share * Wi:.9e}", f"{(1 - share) * Wi:.9e}"]
        w.writerow(row)
    return write_text(path, buf.getvalue())


def read_wear_csv(path: Path, methods=()) -> dict:
    """Columns of :func:`write_wear_csv`'s table: ``pair`` (int), ``position``
    (p, 3) [m], ``W``, ``W_blade``, ``W_disk`` (p,) [m] (shares None if
    absent) and the ``method`` chosen: the first of ``methods`` with a
    ``W_<method>_m`` column, else the first W column."""
    from workflow.errors import GeometryError

    path = Path(path)
    if not path.is_file():
        raise GeometryError(f"wear output {path} is missing (run the wear stage)")
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        raise GeometryError(f"wear output {path} has no rows")
    cols = list(rows[0])
    w_cols = [c for c in cols if c.startswith("W_") and not c.startswith(("W_blade_", "W_disk_"))] or \
             [c for c in cols if c == "W" or c.startswith("W")]
    if not w_cols:
        raise GeometryError(f"wear output {path} has no wear-depth column (W_<method>_m)")
    chosen = next((f"W_{m}_m" for m in methods if f"W_{m}_m" in cols), w_cols[0])
    method = chosen[2:-2] if chosen.startswith("W_") and chosen.endswith("_m") else chosen

    def col(name):
        return np.array([float(r[name]) for r in rows]) if name in cols else None

    pos_cols = next(((a, b, c) for a, b, c in (("x_m", "y_m", "z_m"), ("x", "y", "z")) if a in cols), None)
    return dict(pair=np.array([int(float(r["pair"])) for r in rows]) if "pair" in cols else np.arange(len(rows)),
                position=np.column_stack([col(c) for c in pos_cols]) if pos_cols else None,
                W=col(chosen), W_blade=col(f"W_blade_{method}_m"), W_disk=col(f"W_disk_{method}_m"),
                method=method)


def plot_wear(out: Path, histories: dict, *, tip_before=None, tip_after=None, track_label="") -> list[str]:
    """Figures 9–12 of the paper; returns the file names written under ``out``.

    ``wear_profile.png`` (W per pair and method, Fig. 9), ``max_wear.png``
    (max W against cycles, Fig. 11), ``harmonic1.png`` (first harmonic of the
    tracked tangential displacement, Fig. 12), ``tip_cycle.png`` (tip
    displacement over one cycle before/after wear per method, Fig. 10).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    files = []

    def save(fig, name):
        with atomic_path(out / name, suffix=".png") as tmp:
            fig.savefig(tmp, dpi=110)
        plt.close(fig)
        files.append(name)

    fig, ax = plt.subplots(figsize=(7, 3.5))
    width = 0.8 / max(len(histories), 1)
    for j, (m, h) in enumerate(histories.items()):
        ax.bar(np.arange(len(h.W)) + j * width, np.asarray(h.W) * 1e6, width, label=m)
    ax.set_xlabel("pair")
    ax.set_ylabel("wear depth W [µm]")
    ax.legend()
    fig.tight_layout()
    save(fig, "wear_profile.png")
    for key, ylabel, name in (("max_wear", "max wear depth [µm]", "max_wear.png"),
                              ("harmonic1", f"|U₁| {track_label} [µm]", "harmonic1.png")):
        fig, ax = plt.subplots(figsize=(6, 3.5))
        for m, h in histories.items():
            y = np.asarray(getattr(h, key)) * 1e6
            cyc = np.asarray(h.cycles[: len(y)])
            ax.plot(cyc, y[: len(cyc)], "o-", ms=3, label=m)
        ax.set_xlabel("cycles (physical / pseudo-time)")
        ax.set_ylabel(ylabel)
        ax.set_xscale("symlog", linthresh=max(1.0, min((h.cycles[1] for h in histories.values()
                                                        if len(h.cycles) > 1), default=1.0)))
        ax.legend()
        fig.tight_layout()
        save(fig, name)
    if tip_before is not None:
        fig, ax = plt.subplots(figsize=(6, 3.5))
        tau = np.linspace(0, 1, len(tip_before), endpoint=False)
        ax.plot(tau, np.asarray(tip_before) * 1e6, "k-", label="before wear")
        for m, tip in (tip_after or {}).items():
            ax.plot(tau, np.asarray(tip) * 1e6, "--", label=f"worn ({m})")
        ax.set_xlabel("t / period")
        ax.set_ylabel("tip displacement [µm]")
        ax.legend()
        fig.tight_layout()
        save(fig, "tip_cycle.png")
    return files


def tip_cycles(study) -> tuple:
    """Tip displacement over one cycle (m) before wear and, per method, at the
    worn steady state — from a :class:`~workflow.engine.WearStudy` (Fig. 10)."""
    from workflow.engine.condense import recover
    from workflow.engine.wear import tip_cycle

    rc, hb, w = study.rc, study.hb, study.omega
    if not rc.O.shape[0]:
        return None, None
    load = getattr(hb, "load_scale", None)         # a held tip amplitude scales the dynamic load
    unit = recover(rc, w, np.zeros((hb.nh + 1, 3 * hb.p), dtype=complex)) if load is not None else None

    def tip(x):
        obs = recover(rc, w, hb.harmonics(x))
        if load is not None:
            obs[1:] += (load(x) - 1.0) * unit[1:]
        return tip_cycle(obs)
    return tip(study.base.x), {m: tip(h.x) for m, h in study.histories.items()}


def peak_line(peak: dict) -> str:
    """One line on where a wear response curve peaks (``peak`` of
    :func:`workflow.engine.studies.wearresponse.wear_response`): the largest worn volume, the
    cliff's bracket and how far its last bisection moved the volume."""
    if peak["detuning"] is None:
        return "no point reached a worn steady state"
    line = (f"the largest worn volume {peak['worn_volume_m3']:.4g} m³ at f/f_r = {peak['detuning']:.6g} "
            f"(max W {peak['max_wear_m']:.4g} m)")
    if peak["cliff"] is None:
        return line + f"; no cliff located: {peak['no_cliff']}"
    lo, hi = peak["cliff"]
    line += f"; the cliff between f/f_r = {lo:.6g} and {hi:.6g} ({peak['refined']} bisections)"
    if peak["change_last"] is not None:
        line += f", the last moved its upper end's volume by {peak['change_last']:+.2%}"
    if peak["unknown_inside"]:
        line += (f"; inside it f/f_r = {', '.join(f'{r:.6g}' for r in peak['unknown_inside'])} stopped short of a "
                 "worn steady state (its side unknown)")
    if peak["not_steady"]:
        line += f"; no worn steady state at f/f_r = {', '.join(f'{r:.6g}' for r in peak['not_steady'])}"
    if peak["hidden_rel"] is not None:
        line += f"; the bracket may hide {peak['hidden_rel']:.2%} more (the slope above it carried across)"
    return line


def plot_wear_response(path: Path, response: dict) -> Path:
    """The wear response curve: worn volume and max depth at the worn steady state against
    f / f_r (f_r the friction-damped resonance), and where the rows carry it the worn blade's own
    resonance against the excitation (below the diagonal the wear has pulled the resonance past
    it); marches that did not reach a steady state hollow."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from workflow.report.png import finish_axes, write_figure

    rows = response["rows"]
    r = np.array([x["detuning"] for x in rows])
    ok = np.array([x["steady"] for x in rows])
    panels = [("worn_volume_m3", 1e9, "worn volume (mm³)"), ("max_wear_m", 1e6, "max wear depth (µm, node-wise)")]
    worn_res = any(x.get("worn_resonance_hz") is not None for x in rows)
    if worn_res:
        # where the worn blade's own resonance ends up: below the diagonal it has passed the excitation
        panels.append(("worn_resonance_hz", 1.0 / response["resonance_hz"], "worn resonance f_r,worn / f_r"))
    fig, axs = plt.subplots(1, len(panels), figsize=(5 * len(panels), 4))
    if worn_res:
        axs[-1].plot(r, r, "--", color="0.5", lw=1, label="the excitation, f / f_r")
    for ax, (key, scale, label) in zip(axs, panels):
        y = np.array([np.nan if x.get(key) is None else scale * x[key] for x in rows])
        ax.plot(r, y, "-", color="C0", lw=1)
        ax.plot(r[ok], y[ok], "o", color="C0", label="worn steady state")
        if (~ok).any():
            ax.plot(r[~ok], y[~ok], "o", mfc="none", color="C3", label="not steady (where the march stopped)")
        refined = np.array([bool(x.get("refined")) for x in rows])
        if refined.any():
            ax.plot(r[refined], y[refined], "x", color="k", label="bisecting the cliff")
        cliff = (response.get("peak") or {}).get("cliff")
        if cliff is not None:
            ax.axvspan(*cliff, color="C1", alpha=0.3, lw=0, label="the cliff's bracket")
        finish_axes(ax, f"f / f_r (f_r = {response['resonance_hz']:.4g} Hz)", label)
    return write_figure(fig, path)


def plot_wear_response_meshes(path: Path, curves: dict) -> Path:
    """Wear response curves of several contact meshes on one figure: ``curves`` {label: rows},
    each row with ``detuning``, ``steady``, ``worn_volume_m3`` and ``max_wear_m`` (None or
    missing where the march stopped without a worn steady state: not drawn)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from workflow.report.png import finish_axes, write_figure

    fig, axs = plt.subplots(1, 2, figsize=(10, 4))
    for k, (label, rows) in enumerate(curves.items()):
        rows = sorted(rows, key=lambda x: x["detuning"])
        r = np.array([x["detuning"] for x in rows])
        for ax, key, scale in ((axs[0], "worn_volume_m3", 1e9), (axs[1], "max_wear_m", 1e6)):
            y = np.array([scale * x[key] if x["steady"] and x.get(key) is not None else np.nan for x in rows])
            ax.plot(r, y, "o-", color=f"C{k % 10}", lw=1, ms=3, label=label)
    for ax in axs:
        ax.xaxis.set_major_locator(plt.MaxNLocator(5))
    finish_axes(axs[0], "f / f_r (f_r: each mesh's friction-damped resonance)", "worn volume (mm³)")
    finish_axes(axs[1], "f / f_r (f_r: each mesh's friction-damped resonance)", "max wear depth (µm, node-wise)")
    return write_figure(fig, path)
