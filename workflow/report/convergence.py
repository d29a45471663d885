"""The contact-convergence study's figures: quantities against the contact-mesh size, worn profiles."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from workflow.report.png import finish_axes, write_figure


def plot(out: Path, rows: list[dict], points, pflank, profiles) -> list[str]:
    """``convergence.png`` (each quantity and its change to the finest mesh
    against the contact-mesh size) and ``profiles.png`` (worn profiles, when
    ``profiles`` is given); returns the file names relative to ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = [("peak_hz", "peak frequency (Hz)"), ("peak_amplitude_m", "peak amplitude (m)"),
            ("energy_J", "energy per cycle at the peak (J)"), ("max_wear_m", "max wear depth (m)")]
    keys = [(k, lab) for k, lab in keys if sum(r[k] is not None for r in rows) >= 2]
    fig, axs = plt.subplots(2, len(keys), figsize=(3.6 * len(keys), 6.4), squeeze=False)
    for j, (k, lab) in enumerate(keys):
        rs = [r for r in rows if r[k] is not None]      # the wear may stop short of the finest mesh
        h = np.array([r["h_contact_m"] for r in rs])
        q = np.array([r[k] for r in rs], dtype=float)
        axs[0, j].plot(1e3 * h, q, "o-")
        axs[0, j].set_title(lab, fontsize=9)
        d = np.abs(q[:-1] - q[-1]) / abs(q[-1])
        axs[1, j].semilogy(1e3 * h[:-1], np.where(d > 0, d, np.nan), "s-")
        axs[1, j].set_title("|q − q_finest| / q_finest", fontsize=9)
        for ax in axs[:, j]:
            ax.invert_xaxis()  # finer meshes to the right
            ax.set_xlabel("flank element length along x (mm)")
            ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("contact-mesh convergence: " + ", ".join(f"{r['pairs']}" for r in rows) + " pairs")
    files = [write_figure(fig, out / "convergence.png")]
    if profiles is not None:
        files.append(plot_profiles(out / "profiles.png", [r for r in rows if r["max_wear_m"] is not None],
                                   points, pflank, profiles))
    return [str(Path(f).relative_to(out)) for f in files]


def plot_profiles(path: Path, rows, points, pflank, profiles) -> Path:
    """Worn profile along x on each flank, at the across-flank line of its maximum wear."""
    import matplotlib.pyplot as plt

    flanks = np.unique(pflank)
    fig, axs = plt.subplots(1, len(flanks), figsize=(6 * len(flanks), 4), squeeze=False)
    for j, f in enumerate(flanks):
        sel = np.flatnonzero(pflank == f)
        x = points[sel, 0]
        ax = axs[0, j]
        fin = profiles[-1, sel]
        line = np.isclose(np.linalg.norm(points[sel, 1:] - points[sel[np.argmax(fin)], 1:], axis=1), 0.0,
                          atol=1e-9)
        for r, W in zip(rows, profiles):
            o = np.argsort(x[line])
            ax.plot(1e3 * x[line][o], W[sel][line][o], ".-", label=f"{r['pairs']} pairs")
        finish_axes(ax, "x (mm)", "wear depth W (m)",
                    f"flank {int(f)} ({'intrados' if f == 0 else 'extrados'}), line of max wear", title_size=9)
    return write_figure(fig, path)
