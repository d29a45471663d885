"""Figures of the nonlinear-modes stage: the backbone (frequency, damping ratio and energy per
cycle against modal amplitude) and the single-mode synthesis against the direct HB FRF."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from workflow.report.png import finish_axes, write_figure


def plot_backbone(path: Path, bb) -> Path:
    """Three panels against the modal amplitude a (m·√kg, log): frequency (Hz) with the tied and
    sliding limits, damping ratio D (%), energy dissipated per cycle (J: friction, structural)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a = bb.amplitude
    fig, axs = plt.subplots(1, 3, figsize=(13.5, 4.0))
    ax = axs[0]
    ax.semilogx(a, bb.frequency_hz, "o-", ms=3, label=f"EPMC, Nh = {bb.nh}")
    ax.axhline(bb.tied_hz, color="k", ls=":", lw=1, label=f"tied {bb.tied_hz:.2f} Hz")
    if bb.sliding_hz and bb.frequency_hz.min() - bb.sliding_hz < 0.2 * bb.tied_hz:
        ax.axhline(bb.sliding_hz, color="k", ls="--", lw=1, label=f"sliding {bb.sliding_hz:.2f} Hz")
    finish_axes(ax, "modal amplitude a (m·√kg)", "frequency (Hz)", "natural frequency", which="both")
    ax = axs[1]
    ax.semilogx(a, 100 * bb.damping_ratio, "o-", ms=3, label="D = ξ / 2ω")
    ax.axhline(100 * bb.tied_damping_ratio, color="k", ls=":", lw=1, label="tied (structural)")
    finish_axes(ax, "modal amplitude a (m·√kg)", "damping ratio (%)", "modal damping", which="both")
    ax = axs[2]
    ax.loglog(a, np.where(bb.energy_friction_J > 0, bb.energy_friction_J, np.nan), "o-", ms=3,
              label="friction (none while every pair sticks)")
    ax.loglog(a, bb.energy_structural_J, "s-", ms=3, label="structural")
    finish_axes(ax, "modal amplitude a (m·√kg)", "energy per cycle (J)", "dissipation", which="both")
    from matplotlib.ticker import NullFormatter

    for ax in axs:       # the decade labels only: minor labels of a short log axis overlap
        ax.xaxis.set_minor_formatter(NullFormatter())
    if bb.walks:
        fig.suptitle(f"the mode ends at a = {a[-1]:.3g} m·√kg: every pair slips during the cycle and the "
                     "mean friction force cannot balance — beyond, the blade walks", fontsize=8)
    elif bb.stopped:
        fig.suptitle(f"backbone stopped at a = {a[-1]:.3g}: {bb.stopped}", fontsize=8)
    return write_figure(fig, path)


def plot_synthesis(path: Path, curves) -> Path:
    """Per force level: the direct HB FRF (points) and the single-mode synthesis (line) of the
    observed first-harmonic amplitude, with both peaks. ``curves``: (force N, direct dict of
    :func:`workflow.stages.nonlinear_modes.direct_peak`, :class:`~workflow.engine.studies.nlmodes.Synthesis`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for k, (F, d, syn) in enumerate(curves):
        c = f"C{k}"
        ax.plot(d["freqs_hz"], d["amplitude"], "o", ms=4, color=c, label=f"direct HB, {F:g} N")
        ok = np.isfinite(syn.curve_low_hz) & np.isfinite(syn.curve_high_hz)
        f = np.concatenate([syn.curve_low_hz[ok], syn.curve_high_hz[ok][::-1]])
        y = np.concatenate([syn.curve_observed_m[ok], syn.curve_observed_m[ok][::-1]])
        ax.plot(f, y, "-", color=c, lw=1.2, label=f"single-mode synthesis, {F:g} N")
        if d["hz"] is not None:
            ax.plot([d["hz"]], [d["amplitude_m"]], "x", color=c, ms=8)
    lo, hi = min(c[1]["freqs_hz"][0] for c in curves), max(c[1]["freqs_hz"][-1] for c in curves)
    ax.set_xlim(lo, hi)
    ax.set_yscale("log")
    finish_axes(ax, "frequency (Hz)", "tip amplitude, 1st harmonic (m)", "synthesis vs direct HB")
    return write_figure(fig, path)
