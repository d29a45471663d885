"""Two reduced models on one frequency grid: the nonlinear FRF of a new and a worn sector.

The remap stage's comparison (contracts §8): both models share the new
model's DLFT penalties, so the comparison is free of ε; each keeps its own
``gap`` (the worn bundle's already holds W, so both run at contact-law W = 0).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np


def frf_new_vs_worn(new, worn, law, variant, f_range_hz, points: int, options, gap: float = 0.0) -> dict:
    """Nonlinear FRF of the reduced models ``new`` and ``worn`` through
    :func:`workflow.engine.frf`, one grid of ``points`` frequencies [Hz]
    around the new model's first excited tied mode
    (``f_range_hz`` = (f_start, f_stop) as :func:`workflow.engine.linear.band`
    reads them: zeros mean ±10 %).

    ``law``: the new model's :class:`~workflow.engine.contact.ContactLaw`; its μ and
    ε serve both models, whose gaps are each model's own ``gap`` + ``gap`` [m]
    (the scene's uniform offset).
    Returns ``{"freqs_hz", "new": SweepResult, "worn": ..., "tied_hz":
    {"new", "worn"}, "variant"}``; each SweepResult carries its ``static`` state.
    """
    from workflow.engine.condense import relative_coordinates
    from workflow.engine.contact import ContactLaw
    from workflow.engine.linear import band, first_excited_mode
    from workflow.engine.studies.study import frf

    f_new, _ = first_excited_mode(relative_coordinates(new))
    f0, f1 = band(f_range_hz[0], f_range_hz[1], f_new)
    out = {"freqs_hz": np.linspace(f0, f1, int(points)), "tied_hz": {}, "variant": variant}
    out["peak"] = {}
    # the comparison reads the two peaks only: the checks of the FRF study are not run twice more
    options = replace(options, refine_peak=True, peak_xtol=PEAK_XTOL, branch_check=False, time_check=False)
    for key, model in (("new", new), ("worn", worn)):
        lk = ContactLaw(mu=law.mu, eps_n=law.eps_n, eps_t=law.eps_t,
                        gap=np.asarray(model.gap, dtype=float) + float(gap))
        study = frf(model, lk, [variant], band_hz=(f0, f1), points=int(points), options=options)
        out[key] = study.runs[0]
        out[key].static = study.static
        out["tied_hz"][key] = study.tied_hz
        pk = study.peak
        out["peak"][key] = (None, None) if pk is None else (pk["hz"], pk["amplitude_m"])
    return out


#: Peak frequency tolerance of the new-vs-worn comparison (:attr:`FRFOptions.peak_xtol`), relative
#: to the peak frequency: worn − new shifts are ~1e-6 of it on the sectors we ran, far below a grid step.
PEAK_XTOL = 1e-8
