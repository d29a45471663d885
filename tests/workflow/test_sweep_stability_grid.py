"""The FRF's stability reads the sweep's own condensations (engine.studies.sweepstability,
``grid=``) instead of condensing every point again: the same multipliers, for a grid kept at a
higher Nh than the variant's too (its harmonics 0…Nh are the variant's condensation)."""
from __future__ import annotations

import numpy as np

from workflow.engine.condense import relative_coordinates
from workflow import engine
from workflow.engine.linear import CondensedGrid
from workflow.engine.studies.sweepstability import sweep_stability
from workflow.verification import models
from workflow.verification.timeint import Pads


def test_stability_on_the_sweeps_condensations_equals_condensing_again(monkeypatch):
    # a Jenkins oscillator (1 DOF, pad stiffness 1, μN0 = 0.15) through its resonance
    K = np.array([[1.0]])
    pads = Pads(dof=np.array([0]), k=np.array([1.0]), mu=0.5, N0=np.array([0.3]), cN=np.array([[0.0]]))
    model, _ = models.jenkins(K.copy(), 0.02 * K, K, [0.1], 0, pads, "jenkins-1dof")
    law = engine.contact_law(model, mu=pads.mu)
    w = np.array([1.2, 1.3])
    study = engine.frf(model, law, [engine.Variant("hbm", 7, 64)], freqs_hz=w / (2 * np.pi),
                       options=engine.FRFOptions(eps_check_factor=0.0, nh_check=False, branch_check=False,
                                                 time_check=False, refine_peak=False, tol=1e-10))
    r = study.runs[0]
    assert r.converged.all()
    rc = relative_coordinates(model)
    grid = CondensedGrid(rc, 2 * np.pi * r.freqs_hz, 9)       # a higher Nh, as a study's nh_max
    for _ in grid:
        pass
    a = sweep_stability(model, rc, study.law, study.static, r)
    # with the grid no point is condensed again
    import workflow.engine.linear as linear

    def refused(*a, **k):
        raise AssertionError("condensed again although the sweep's grid holds the point")

    monkeypatch.setattr(linear, "condensed", refused)
    b = sweep_stability(model, rc, study.law, study.static, r, grid=grid)
    assert a["stable"] == b["stable"] == [True, True]
    # the same condensation, sliced: equal to round-off of the multipliers' eigensolve
    assert np.abs(a["floquet_max"] - b["floquet_max"]).max() <= 1e-12
