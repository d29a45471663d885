"""The verification figure: error of the project's HB against Nh, per case and frequency."""
from __future__ import annotations

from pathlib import Path


def error_figure(rows: list, floor: list, path: Path) -> Path:
    """Relative first-harmonic error against Nh (log), one line per case × frequency;
    hollow markers where the HB did not converge; dashed: the Galerkin floor."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from workflow.io import atomic_path

    fig, ax = plt.subplots(figsize=(7, 4.5))
    keys = sorted({(r["case"], r["frequency_hz"]) for r in rows})
    for case, f in keys:
        sel = sorted((r for r in rows if r["case"] == case and r["frequency_hz"] == f), key=lambda r: r["Nh"])
        nh = [r["Nh"] for r in sel]
        err = [max(r["error"], 1e-8) for r in sel]
        line, = ax.semilogy(nh, err, "-", lw=1, label=f"{case} {f:.4g} Hz" + (" (stops)" if sel[0]["stops"] else ""))
        for n, e, r in zip(nh, err, sel):
            ax.plot(n, e, "o", color=line.get_color(), mfc=line.get_color() if r["converged"] else "none")
        fl = sorted((g for g in floor if g["case"] == case and g["frequency_hz"] == f), key=lambda g: g["Nh"])
        if fl:
            ax.semilogy([g["Nh"] for g in fl], [max(g["error"], 1e-8) for g in fl], "--", color=line.get_color(),
                        lw=1)
    ax.set_xlabel("harmonics Nh")
    ax.set_ylabel("|A₁ − A₁,exact| / A₁,exact")
    ax.set_title("Project HB against exact friction solutions (dashed: Galerkin HB floor; hollow: not converged)",
                 fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6)
    fig.tight_layout()
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return path
