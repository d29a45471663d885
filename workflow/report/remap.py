"""The remap stage's new-vs-worn nonlinear FRF: its summary entries and its figure."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from workflow.engine.studies.peak import peak
from workflow.report.png import finish_axes, write_figure


def frf_summary(frf: dict) -> dict:
    """Summary entries of :func:`workflow.engine.studies.compare.frf_new_vs_worn` (Hz, m)."""
    pk = frf.get("peak") or {k: peak(frf[k]) for k in ("new", "worn")}  # refined, else the grid's largest
    v = frf["variant"]
    return {
        "frf_peak_hz": {k: pk[k][0] for k in pk},
        "frf_peak_amplitude_m": {k: pk[k][1] for k in pk},
        "frf_peak_search": "bounded scalar search between grid neighbours" if frf.get("peak") else "grid point",
        "frf_tied_hz": dict(frf["tied_hz"]),
        "frf_band_hz": [float(frf["freqs_hz"][0]), float(frf["freqs_hz"][-1])],
        "frf_points": int(len(frf["freqs_hz"])),
        "frf_converged": {k: frf[k].converged_points for k in ("new", "worn")},
        "frf_variant": {"method": v.method, "harmonics": v.nh, "time_samples": v.nit},
    }


def render_frf_worn_vs_new(frf: dict, path: Path) -> Path:
    """``path`` (.png): first-harmonic tip amplitude of the new and worn models."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for key, style in (("new", "o-"), ("worn", "s--")):
        r = frf[key]
        a = np.where(r.converged, r.amplitude, np.nan)
        f_pk, a_pk = (frf.get("peak") or {}).get(key) or peak(r)
        lab = f"{key}" + (f": peak {f_pk:.2f} Hz, {a_pk:.3g} m" if f_pk is not None else " (no point converged)")
        ax.plot(r.freqs_hz, a, style, ms=4, label=lab)
    finish_axes(ax, "frequency (Hz)", "tip amplitude, 1st harmonic (m)",
                f"nonlinear FRF, new vs worn ({frf['variant'].label})")
    return write_figure(fig, path)
