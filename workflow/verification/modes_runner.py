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


def floquet_error(omega: float = 1.3, nh: int = 15, nit: int = 128) -> dict:
    """|μ|max of the engine's stability (:func:`workflow.engine.hill_stability`, its defaults) on a
    1-DOF Jenkins oscillator (m = k = 1, c = 0.02, pad k_t = 1, μN = 0.15, F = 0.1; at ω = 1.3 rad/s
    it sticks 52 % of each period, the mass's amplitude 0.27 m, 1.8 × the slip onset) about the
    engine's HB solution (Nh = ``nh``, ``nit`` samples) against event-driven shooting
    (:func:`workflow.verification.floquet.jenkins_monodromy`, converged to 1e-8):
    {"floquet_vs_shooting" (absolute difference), "engine", "shooting", "omega", "nh", "nit"}.

    Measured (2026-11-28, ``python -c "from workflow.verification.modes_runner import
    floquet_error; print(floquet_error())"``): 0.373881 against 0.373804, 7.7e-5 (1.26e-3 with
    the switching instants known to a sample, before they were located between the samples);
    7e-5 of it is ε of the tangent (:data:`workflow.engine.stability.EPS_FACTOR`); Nh = 7, 31:
    1.3e-4, 7.7e-5."""
    from workflow.engine.condense import relative_coordinates
    from workflow import engine
    from workflow.engine.hb import HBProblem
    from workflow.engine.linear import condensed
    from workflow.verification import floquet, models
    from workflow.verification.timeint import Pads

    M, K = np.array([[1.0]]), np.array([[1.0]])
    C, f = 0.02 * K, np.array([0.1])
    pads = Pads(dof=np.array([0]), k=np.array([1.0]), mu=0.5, N0=np.array([0.3]), cN=np.array([[0.0]]))
    model, _ = models.jenkins(M, C, K, f, 0, pads, "jenkins-1dof")
    law = engine.contact_law(model, mu=pads.mu)
    rc = relative_coordinates(model)
    c = condensed(rc, omega, nh)
    hb = HBProblem(c.Zr, c.Fr, law, nh, nit)
    pr = engine.solve_point(hb, [hb.x0()], solver="newton-powell", tol=1e-10, maxiter=100)
    st = engine.hill_stability(model, hb, pr.result.x, omega, rc=rc, nh_check=None)
    ref, _ = floquet.jenkins_monodromy(M, C, K, f, omega, pads)
    return {"floquet_vs_shooting": abs(st.floquet_max - ref.floquet_max), "engine": st.floquet_max,
            "shooting": ref.floquet_max, "omega": omega, "nh": nh, "nit": nit}
