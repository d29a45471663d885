"""Figures of the mistuning stage: every blade's FRF, the blade amplitudes around the disk
(localisation), and the Monte Carlo's amplification factors."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from workflow.report.png import finish_axes, write_figure


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_blade_frf(path: Path, resp, tuned_freqs, tuned_amp, tuned_tied) -> Path:
    """Every blade's friction-damped first-harmonic tip amplitude (m) against frequency (Hz),
    the tuned disk's for reference (friction-damped on ``tuned_freqs``, tied on the response's
    tied grid)."""
    plt = _plt()
    fig, axs = plt.subplots(1, 2, figsize=(12.0, 4.2))
    ax = axs[0]
    ok = resp.converged
    for b in range(resp.amplitude.shape[1]):
        ax.plot(resp.freqs_hz[ok], resp.amplitude[ok, b], "-", lw=0.7, color="0.55")
    ax.plot(tuned_freqs, tuned_amp, "k-", lw=1.8, label="tuned (every blade)")
    if resp.peak.get("hz"):
        b = resp.peak["blade"]
        if resp.solved_hz is not None and len(resp.solved_hz) > int(ok.sum()):
            # the grid's few points fall between the blades' peaks: the peak blade at every point solved
            ax.plot(resp.solved_hz, resp.solved_amplitude[:, b], ".-", ms=3, lw=0.8, color="tab:red", alpha=0.6,
                    label=f"blade {b}, grid and peak search")
        ax.plot([resp.peak["hz"]], [resp.peak["amplitude_m"]], "ro", label=f"largest blade peak (blade {b})")
    ax.plot([], [], "-", color="0.55", label="mistuned, one line a blade")
    finish_axes(ax, "frequency (Hz)", "tip amplitude (m)", f"friction-damped, HBM Nh = {resp.nh}")
    ax = axs[1]
    for b in range(resp.tied.shape[1]):
        ax.semilogy(resp.tied_freqs_hz, resp.tied[:, b], "-", lw=0.7, color="0.55")
    ax.semilogy(resp.tied_freqs_hz, tuned_tied, "k-", lw=1.8, label="tuned")
    finish_axes(ax, "frequency (Hz)", "tip amplitude (m)", "interface tied (linear)")
    return write_figure(fig, path)


def plot_localisation(path: Path, deviations, friction_peaks, tied_peaks, tuned_friction, tuned_tied) -> Path:
    """Each blade's largest amplitude over the band relative to the tuned disk's peak, around
    the disk (polar), friction-damped and tied, with its stiffness deviation."""
    plt = _plt()
    n = len(friction_peaks)
    th = 2 * np.pi * np.arange(n) / n
    fig = plt.figure(figsize=(11.0, 4.6))
    ax = fig.add_subplot(1, 2, 1, projection="polar")
    close = lambda a: np.append(a, a[:1])  # noqa: E731
    ax.plot(close(th), close(np.asarray(friction_peaks) / tuned_friction), "o-", ms=3, label="friction-damped")
    ax.plot(close(th), close(np.asarray(tied_peaks) / tuned_tied), "s-", ms=3, label="tied")
    ax.plot(close(th), np.ones(n + 1), "k:", lw=1, label="tuned")
    ax.set_title("blade peak / tuned peak around the disk")
    ax.legend(loc="lower left", fontsize=8, bbox_to_anchor=(-0.15, -0.15))
    ax = fig.add_subplot(1, 2, 2)
    ax.bar(np.arange(n), 100 * np.asarray(deviations), color="0.6")
    finish_axes(ax, "blade", "stiffness deviation δ (%)", "mistuning pattern")
    return write_figure(fig, path)


def plot_amplification(path: Path, rows, bound: float) -> Path:
    """Histograms of the Monte Carlo's amplification factors (tied, friction-damped) with
    their 95th percentiles, each one's 95 % interval (:func:`~workflow.engine.studies.mistuning.percentile_interval`;
    "?" where the samples are too few to bound it) and Whitehead's bound."""
    from workflow.engine.studies.mistuning import percentile_interval

    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for key, label in (("af_tied", "tied"), ("af_friction", "friction-damped")):
        v = np.array([r[key] for r in rows if r[key] is not None], float)
        if v.size:
            ci = percentile_interval(v)
            lo, hi = ("?" if x is None else f"{x:.3f}" for x in (ci["lo"], ci["hi"]))
            ax.hist(v, bins=max(5, v.size // 4), alpha=0.55,
                    label=f"{label}: p95 {np.percentile(v, 95):.3f} [{lo}, {hi}]")
    ax.axvline(bound, color="k", ls="--", lw=1, label=f"Whitehead (1 + √N)/2 = {bound:.2f}")
    finish_axes(ax, "amplification factor", "patterns", f"{len(rows)} mistuning patterns")
    return write_figure(fig, path)


def plot_wear_map(path: Path, W, flank, position, tuned_W=None) -> Path:
    """The disk wear map: worn depth [µm] of every pair (flank by flank, each by its radial
    position [m]) on every blade, and each blade's deepest point against the tuned sector's."""
    plt = _plt()
    W = np.asarray(W, float)
    pos = np.asarray(position, float).reshape(W.shape[1], -1)
    radius = np.hypot(pos[:, 1], pos[:, 2]) if pos.shape[1] == 3 else pos[:, 0]   # the disk turns about x
    order = np.lexsort((radius, np.asarray(flank)))
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(11.0, 4.4), gridspec_kw={"width_ratios": [1.6, 1.0]})
    im = a0.imshow(1e6 * W[:, order].T, aspect="auto", origin="lower", cmap="magma",
                   extent=(-0.5, W.shape[0] - 0.5, -0.5, W.shape[1] - 0.5))
    fig.colorbar(im, ax=a0, label="worn depth (µm)")
    finish_axes(a0, "blade", "pair (flank by flank, by radius)", "worn steady state around the disk")
    a1.bar(np.arange(W.shape[0]), 1e6 * W.max(axis=1), color="0.45", label="mistuned disk")
    if tuned_W is not None:
        a1.axhline(1e6 * float(np.max(tuned_W)), color="C0", ls="--", lw=1.2, label="tuned sector")
    finish_axes(a1, "blade", "deepest point (µm)", "each blade's deepest wear")
    return write_figure(fig, path)
