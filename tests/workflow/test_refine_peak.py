"""The refined friction-damped peak (engine.studies.peak.refine_peak) against a closed form."""
from __future__ import annotations

import numpy as np
import pytest


def test_refined_peak_of_a_damped_oscillator_is_the_closed_form_one():
    """μ = 0 leaves m ẍ + c ẋ + k x = F cos ωt: |X| = F / √((k − mω²)² + (cω)²) peaks at
    ω_n √(1 − 2ζ²) with F / (2ζ k √(1 − ζ²)). A 7-point grid of 0.4 Hz steps misses it by 0.2 Hz;
    the bounded search between the grid neighbours finds it."""
    from workflow.engine.condense import relative_coordinates
    from workflow import engine
    from workflow.engine.studies.peak import refine_peak
    from workflow.verification import models

    m, fn, zeta, force = 1.0, 10.0, 0.02, 1.0
    k = m * (2 * np.pi * fn) ** 2
    c = 2 * zeta * np.sqrt(k * m)
    model, _ = models.coulomb(m, k, c, 1.0, force, 0.0)
    law = engine.contact_law(model, mu=0.0)
    v = engine.Variant("hbm", 1, 16)
    opt = engine.FRFOptions(reference=None, eps_check_factor=0.0)
    study = engine.frf(model, law, [v], band_hz=(9.0, 11.4), points=7, options=opt)
    grid = study.runs[0]
    f_exact = fn * np.sqrt(1 - 2 * zeta ** 2)
    a_exact = force / (2 * zeta * k * np.sqrt(1 - zeta ** 2))
    i = int(np.argmax(grid.amplitude))
    assert abs(grid.freqs_hz[i] - f_exact) > 0.1 and grid.amplitude[i] < 0.9 * a_exact  # the grid misses it
    pk = refine_peak(relative_coordinates(model), grid, law, study.static, v, 1e-7 * fn,
                     solver=opt.solver, tol=opt.tol, maxiter=opt.max_iterations, max_passes=opt.max_passes,
                     eps_path=opt.eps_path)
    assert pk.hz == pytest.approx(f_exact, rel=1e-6)
    assert pk.amplitude == pytest.approx(a_exact, rel=1e-8)
    assert pk.evaluations > 7 and pk.grid_index == i


def test_frf_study_reports_the_refined_peak_of_its_most_converged_sweep():
    """engine.frf refines the peak of the variant with the most harmonics (no reference
    here) by default: the damped oscillator's closed-form peak, not the grid's largest point."""
    from workflow import engine
    from workflow.verification import models

    m, fn, zeta, force = 1.0, 10.0, 0.02, 1.0
    k = m * (2 * np.pi * fn) ** 2
    model, _ = models.coulomb(m, k, 2 * zeta * np.sqrt(k * m), 1.0, force, 0.0)
    variants = [engine.Variant("hbm", 1, 16), engine.Variant("hbm", 3, 32)]
    study = engine.frf(model, engine.contact_law(model, mu=0.0), variants, band_hz=(9.0, 11.4), points=7,
                       options=engine.FRFOptions(reference=None, eps_check_factor=0.0))
    pk = study.peak
    assert pk["run"] == "HBM-3 nit=32"
    assert abs(pk["hz"] - fn * np.sqrt(1 - 2 * zeta ** 2)) <= 2 * pk["xtol_hz"]
    # within 2·PEAK_XTOL of the peak |X| is flat to (2·PEAK_XTOL)²/(2ζ²) = 5e-9 (μ = 0: linear, each
    # point solved to round-off by Newton's one step)
    assert pk["amplitude_m"] == pytest.approx(force / (2 * zeta * k * np.sqrt(1 - zeta ** 2)), rel=1e-8)
    assert pk["amplitude_m"] > 1.3 * pk["grid_amplitude_m"]


#: the damped oscillator of these tests: m, f_n [Hz], ζ, F0
OSC = (1.0, 10.0, 0.02, 1.0)


def _search(monkeypatch, patch: dict):
    """The peak search on the damped oscillator's 7-point grid (μ = 0), after ``patch``
    ({(object, attribute): value}, through ``monkeypatch``): (Peak, points of the grid)."""
    from workflow.engine.condense import relative_coordinates
    from workflow import engine
    from workflow.engine.studies.peak import refine_peak
    from workflow.verification import models

    m, fn, zeta, force = OSC
    k = m * (2 * np.pi * fn) ** 2
    model, _ = models.coulomb(m, k, 2 * zeta * np.sqrt(k * m), 1.0, force, 0.0)
    law = engine.contact_law(model, mu=0.0)
    v = engine.Variant("hbm", 1, 16)
    opt = engine.FRFOptions(reference=None, eps_check_factor=0.0, refine_peak=False)
    study = engine.frf(model, law, [v], band_hz=(9.0, 11.4), points=7, options=opt)
    for (obj, name), value in patch.items():
        monkeypatch.setattr(obj, name, value)
    pk = refine_peak(relative_coordinates(model), study.runs[0], law, study.static, v, 1e-7 * fn, solver="newton",
                     tol=opt.tol, maxiter=opt.max_iterations, max_passes=opt.max_passes, eps_path=opt.eps_path)
    return pk, len(study.freqs_hz)


def _closed_form(pk):
    m, fn, zeta, force = OSC
    k = m * (2 * np.pi * fn) ** 2
    assert pk.hz == pytest.approx(fn * np.sqrt(1 - 2 * zeta ** 2), rel=1e-6)
    # xtol = 1e-7 f_n: |X| within (2e-7)²/(2ζ²) = 5e-11 of its peak (linear: round-off per point)
    assert pk.amplitude == pytest.approx(force / (2 * zeta * k * np.sqrt(1 - zeta ** 2)), rel=1e-8)


def test_the_peak_search_shares_one_structured_solve(monkeypatch):
    """Where the structured linear solve applies (forced here on the damped oscillator), the
    search's points share one: each point starts from the last one's lagged blocks instead of
    a factorisation of its own, and the peak is still the closed-form one."""
    from workflow.engine import linsolve
    from workflow.engine import cascade

    made = []
    init = linsolve.StructuredSolve.__init__
    pk, grid = _search(monkeypatch, {
        (cascade, "STRUCTURED_MIN_UNKNOWNS"): 0,
        (linsolve.StructuredSolve, "__init__"): lambda self, *a, **kw: (made.append(self), init(self, *a, **kw))[1]})
    assert len(made) == 1 and made[0].stats["solves"] > 0
    assert made[0].stats["factorizations"] < pk.evaluations - grid
    _closed_form(pk)


def test_the_peak_search_keeps_only_the_peaks_condensation(monkeypatch):
    """Each point of the search condenses its frequency (302 MB at 512 pairs); only the highest
    point's condensation is kept — the one Peak returns, at the peak's frequency."""
    import gc
    import weakref

    from workflow.engine import linear

    refs, most = [], []
    condensed = linear.condensed

    def counted(*a, **kw):
        gc.collect()
        most.append(sum(r() is not None for r in refs))     # the search's condensations still held
        c = condensed(*a, **kw)
        refs.append(weakref.ref(c))
        return c

    pk, grid = _search(monkeypatch, {(linear, "condensed"): counted})
    assert len(refs) == pk.evaluations - grid > 5 and max(most) == 1
    gc.collect()
    assert [r() for r in refs if r() is not None] == [pk.cond]
    assert pk.cond.omega == pytest.approx(2 * np.pi * pk.hz, rel=1e-15)
    _closed_form(pk)
