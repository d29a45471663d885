"""nit = 2Nh+1: the DLFT roots at the law's ε are roots at every smaller ε, so collocated
variants are solved at the ε-path's first level and checked at the law's ε
(workflow/engine/cascade.py: collocated, _at_law; docs/solver-guide.md, "Penalty ε")."""
from __future__ import annotations

import numpy as np
import pytest

from workflow.engine.condense import condense, relative_coordinates
from test_hb_stage import blade_chain
from workflow import engine
from workflow.engine import cascade, penalty
from workflow.engine.hb import HBProblem

#: the module's sweeps (~11 s): make test-slow, to keep make test within 3 minutes on 2 cores;
#: the three collocated forms' one FRF is also tests/workflow/test_hb_stage.py's
pytestmark = pytest.mark.slow

BAND = (94.0, 104.0)


@pytest.fixture(scope="module")
def sweeps():
    """HBM, TCM and HDHB at Nh = 5, nit = 11 through the friction-damped resonance, default ε."""
    model = blade_chain(force=0.2, preload=np.array([2.0, 8.0, 30.0]))
    law = engine.contact_law(model, mu=0.3)
    opt = engine.FRFOptions(eps_check_factor=0.0, refine_peak=False)
    runs = {m: engine.frf(model, law, [engine.Variant(m, 5, 11)], band_hz=BAND, points=41, options=opt)
            for m in ("hbm", "tcm", "hdhb")}
    return model, law, runs


def _residual(model, law, study, i, factor=1.0, method="hbm"):
    r = study.runs[0]
    c = condense(relative_coordinates(model), 2 * np.pi * r.freqs_hz[i], 5)
    prob = HBProblem(c.Zr, c.Fr, penalty.scaled(law, factor), 5, 11, method, static=study.static)
    return float(np.linalg.norm(prob.residual(prob.unknowns_from_harmonics(r.Ur[i]))) / prob.residual_scale())


def test_every_point_converges_and_is_a_root_at_the_laws_eps(sweeps):
    """Along the ε-path 21/41 (HBM) and 17/41 (TCM, HDHB) points converged here; each
    reported root is checked independently by its residual at the law's own ε."""
    model, law, runs = sweeps
    for m, st in runs.items():
        r = st.runs[0]
        assert r.converged.all(), (m, r.reasons)
        worst = max(_residual(model, law, st, i, method="hbm") for i in range(0, 41, 5))
        assert worst <= 1e-8, (m, worst)


def test_the_three_collocated_forms_give_one_frf(sweeps):
    _, _, runs = sweeps
    a = {m: st.runs[0].amplitude for m, st in runs.items()}
    top = a["hbm"].max()
    assert np.max(np.abs(a["tcm"] - a["hbm"])) < 1e-9 * top
    assert np.max(np.abs(a["hdhb"] - a["hbm"])) < 1e-9 * top


def test_roots_hold_at_every_smaller_eps_but_not_beyond_nit(sweeps):
    """The law's roots are roots at ε·10⁻³ and ε·10⁻⁶ too (the theorem the shortcut rests
    on); an HBM root at nit = 32 > 2Nh+1 is not a root at another ε (X above Nh is −λ/ε)."""
    model, law, runs = sweeps
    st = runs["hdhb"]
    i = int(np.argmax(st.runs[0].amplitude))
    for f in (1e-3, 1e-6):
        assert _residual(model, law, st, i, f, method="hdhb") <= 1e-8
    opt = engine.FRFOptions(eps_check_factor=0.0, refine_peak=False)
    wide = engine.frf(model, law, [engine.Variant("hbm", 5, 32)], band_hz=BAND, points=41, options=opt)
    j = int(np.argmax(wide.runs[0].amplitude))
    c = condense(relative_coordinates(model), 2 * np.pi * wide.runs[0].freqs_hz[j], 5)
    prob = HBProblem(c.Zr, c.Fr, penalty.scaled(law, 1e-3), 5, 32, "hbm", static=wide.static)
    x = prob.unknowns_from_harmonics(wide.runs[0].Ur[j])
    assert np.linalg.norm(prob.residual(x)) / prob.residual_scale() > 1e-4


def test_a_collocated_point_is_accepted_only_by_its_residual_at_the_laws_eps(sweeps, monkeypatch):
    """_at_law rejects a 'root' of the moderate problem that is not one at the law's ε: a
    perturbed point, with Newton at the law's ε unable to fix it in 0 steps."""
    model, law, runs = sweeps
    st = runs["hbm"]
    r = st.runs[0]
    i = int(np.argmax(r.amplitude))
    c = condense(relative_coordinates(model), 2 * np.pi * r.freqs_hz[i], 5)
    prob = HBProblem(c.Zr, c.Fr, law, 5, 11, "hbm", static=st.static)
    x = prob.unknowns_from_harmonics(r.Ur[i])
    from workflow.engine.solvers import SolveResult

    good = cascade.PointResult(SolveResult(x=x, converged=True, iterations=0, residual_norm=0.0,
                                           reason="converged"), 3, "newton")
    assert cascade._at_law(prob, good, 1e-8).converged
    bad = cascade.PointResult(SolveResult(x=x * 1.05, converged=True, iterations=0, residual_norm=0.0,
                                          reason="converged"), 3, "newton")
    monkeypatch.setattr(cascade, "POLISH_STEPS", 0)
    out = cascade._at_law(prob, bad, 1e-8)
    assert not out.converged and "law's ε" in out.result.reason
