"""The engine's nonlinear modes (:mod:`workflow.engine.studies.nlmodes`) against the independent Jenkins
reference of :mod:`workflow.verification.masing` — the ``nonlinear_modes.checks`` of the stage.
Like :mod:`workflow.verification.runner`, it calls the engine; the reference never does.

The case: a unit mass on a spring k = 1 N/m with a Jenkins element (k_t = 2 N/m, μN = 0.3 N, slip
onset 0.15 m) and light damping c = 0.002 N·s/m (tests/workflow/test_nlmodes.py uses the same).
"""
from __future__ import annotations

import numpy as np

M, K, C, KT, MU, N = 1.0, 1.0, 0.002, 2.0, 0.5, 0.6


def jenkins_errors(nh: int = 7, nit: int = 64) -> dict:
    """Largest relative errors of the EPMC frequency and damping ratio against the Galerkin EPMC
    with the exact hysteresis (:func:`workflow.verification.masing.epmc_galerkin`, Nh = 25) at four
    amplitudes in slip (1.2–5 × the onset): {"jenkins_frequency_error", "jenkins_damping_error",
    "amplitudes", "nh", "nit"}."""
    from workflow.engine import contact_law
    from workflow.engine.studies import nlmodes
    from workflow.verification import masing, models
    from workflow.verification.timeint import Pads

    pads = Pads(dof=np.array([0]), k=np.array([KT]), mu=MU, N0=np.array([N]), cN=np.zeros((1, 1)))
    model, _ = models.jenkins([[M]], [[C]], [[K]], [0.1], 0, pads, "jenkins-1")
    bb = nlmodes.backbone(model, contact_law(model, mu=MU), nh=nh, nit=nit, amplitudes=(0.05, 20.0, 14))
    X = bb.amplitude / np.sqrt(M)
    slip = np.flatnonzero((X > 1.2 * MU * N / KT) & (X < 5.0))
    pick = slip[[0, slip.size // 3, 2 * slip.size // 3, -1]] if slip.size >= 4 else slip
    ef, ed = [], []
    for i in pick:
        ref = masing.epmc_galerkin(X[i], M, K, C, KT, MU * N)[0]
        ef.append(abs(2 * np.pi * bb.frequency_hz[i] / ref.omega - 1))
        ed.append(abs(bb.damping_ratio[i] / ref.damping_ratio - 1))
    return {"jenkins_frequency_error": float(max(ef)) if ef else None,
            "jenkins_damping_error": float(max(ed)) if ed else None,
            "amplitudes": [float(X[i]) for i in pick], "nh": nh, "nit": nit}
