"""Figures of the tuned-disk modes (stage cyclic_modes): ND map, Campbell diagram, ZZENF.

Arrays in, PNG out (:mod:`workflow.report.png`). Frequencies Hz, speeds rpm.
``F`` of the ND map is (n_nd, n_modes); of the Campbell diagram (n_speeds,
n_nd, n_modes) (:mod:`reduction.cyclic_modes`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from workflow.report.png import finish_axes, write_figure


def _fold(n: int, n_sectors: int) -> int:
    r = int(n) % int(n_sectors)
    return min(r, int(n_sectors) - r)


def nd_map_figure(nds, F: np.ndarray, speed_rpm: float, n_sectors: int, path: Path) -> Path:
    """Frequency against nodal diameter, one line per mode family (the j-th mode of every ND)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5))
    for j in range(F.shape[1]):
        ax.plot(nds, F[:, j], "o-", ms=3, lw=1, label=f"mode {j + 1}")
    finish_axes(ax, "nodal diameter k", "frequency [Hz]",
                f"Nodal-diameter map, N = {n_sectors}, {speed_rpm:g} rpm (interface tied)")
    return write_figure(fig, path)


def campbell_figure(speeds_rpm, nds, F: np.ndarray, engine_orders, n_sectors: int, crossings: list,
                    path: Path) -> Path:
    """Frequencies of every ND against speed (colour = ND), EO lines f = EO·rpm/60, their resonances.

    A resonance (red) is an EO line meeting a mode of ND ``fold(EO)`` — the
    only ND the EO travelling wave excites.
    """
    import matplotlib.pyplot as plt

    rpm = np.asarray(speeds_rpm, float)
    fig, ax = plt.subplots(figsize=(8, 5.5))
    cmap = plt.get_cmap("viridis")
    kmax = max(max(nds), 1)
    for i, k in enumerate(nds):
        for j in range(F.shape[2]):
            ax.plot(rpm, F[:, i, j], color=cmap(k / kmax), lw=0.8, alpha=0.8)
    top = float(F.max()) * 1.05
    for eo in engine_orders:
        f = eo * rpm / 60.0
        ax.plot(rpm, f, "k--", lw=0.9)
        end = min(rpm[-1], 0.95 * top * 60.0 / eo) if eo else rpm[-1]
        ax.annotate(f"EO {eo} (ND {_fold(eo, n_sectors)})", (end, eo * end / 60.0), fontsize=7,
                    ha="right", va="bottom")
    if crossings:
        ax.plot([c["speed_rpm"] for c in crossings], [c["f_hz"] for c in crossings], "o", mfc="none",
                mec="red", ms=7, label="EO resonance")
    ax.set_ylim(0, top)
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(min(nds), kmax))
    fig.colorbar(sm, ax=ax, label="nodal diameter")
    finish_axes(ax, "rotation speed [rpm]", "frequency [Hz]", f"Campbell diagram, N = {n_sectors}")
    return write_figure(fig, path)


def zzenf_figure(nds, F: np.ndarray, speed_rpm: float, n_sectors: int, engine_order: int, resonances: list,
                 path: Path) -> Path:
    """ZZENF diagram at one speed (Wildheim 1979): the ND map and the zig-zag excitation line.

    Engine order EO excites ND fold(EO mod N) at f = EO·Ω/2π; as EO grows the
    excitation point runs up and down the ND axis (the zig-zag). Modes on the
    line are resonant at this speed.
    """
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5))
    for j in range(F.shape[1]):
        ax.plot(nds, F[:, j], "o-", color="0.6", ms=3, lw=0.8, label="modes (per family)" if j == 0 else None)
    if speed_rpm > 0:
        per_eo = speed_rpm / 60.0
        eos = np.arange(0, int(np.ceil(1.05 * F.max() / per_eo)) + 1)
        ax.plot([_fold(e, n_sectors) for e in eos], eos * per_eo, ".-", color="tab:blue", lw=1, ms=4,
                label=f"EO excitation at {speed_rpm:g} rpm (dots: EO = 0, 1, 2, …)")
        ax.plot([_fold(engine_order, n_sectors)], [engine_order * per_eo], "s", color="tab:blue", ms=7,
                label=f"EO {engine_order}")
    if resonances:
        ax.plot([r["nd"] for r in resonances], [r["f_hz"] for r in resonances], "o", mfc="none", mec="red", ms=9,
                label="near resonance")
    ax.set_ylim(0, 1.05 * float(F.max()))
    finish_axes(ax, "nodal diameter (EO folded: min(EO mod N, N − EO mod N))", "frequency [Hz]",
                f"ZZENF diagram, N = {n_sectors}")
    return write_figure(fig, path)
