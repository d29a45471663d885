"""The time-domain check of an HB solution (workflow/engine/timecheck.py, issue #47 item 2).

Small reduced models written here by hand (docs/contracts.md §4, §6: one pair, the ground as
the disk side, the preload −N on the normal DOF so that λ_N = −N < 0 in contact):

* a **Jenkins oscillator**: a mass on a spring k, tied by a spring k_d to a massless contact
  node that rubs on the ground (μN); q = [x, pad n, pad t1, pad t2];
* a **Coulomb oscillator** (Den Hartog's): the mass itself rubs on the ground; q = [n, t1, t2,
  witness] (a massless unloaded witness, so that the model has a DOF that is no contact DOF).

The HB states come from the engine's front door (``engine.frf`` at one frequency); the
independent reference for the Coulomb oscillator is the event-driven integrator of
``workflow.verification.timeint`` (the engine module itself imports neither).
"""
from __future__ import annotations

import numpy as np
import pytest

from workflow.engine.model import ReducedModel
from workflow import engine
from workflow.engine.timecheck import TimeCheckOptions, integrator_error, time_check


def jenkins_oscillator(*, m=1.0, k=1.0, kd=1.0, zeta=0.02, N0=0.6, force=0.2, kn=1e3) -> ReducedModel:
    """Mass m on a spring k, forced by ``force`` cos ωt, tied through k_d to a massless pad
    pressed by N0 onto the ground (normal stiffness kn, only felt if it separated). Tied
    frequency √((k + k_d)/m) = 1.41 rad/s, free 1 rad/s; ζ on the tied mode. Observed: x."""
    M = np.diag([m, 0.0, 0.0, 0.0])
    K = np.zeros((4, 4))
    K[0, 0] = k
    K[np.ix_([0, 2], [0, 2])] += kd * np.array([[1.0, -1.0], [-1.0, 1.0]])
    K[1, 1], K[3, 3] = kn, kd
    C = np.zeros((4, 4))
    C[0, 0] = 2.0 * zeta * np.sqrt((k + kd) * m)
    return ReducedModel(M=M, K=K, C=C, B=np.eye(3, 4, 1), f_static=np.array([0.0, -N0, 0.0, 0.0]),
                        f_harmonic=np.array([force, 0.0, 0.0, 0.0]), O=np.array([[1.0, 0.0, 0.0, 0.0]]),
                        area=np.ones(1), gap=np.zeros(1), flank=np.zeros(1, int), position=np.zeros((1, 3)))


def coulomb_oscillator(*, m=1.0, k=1.0, c=0.1, normal=1.0, force=1.0) -> ReducedModel:
    """``m ẍ + c ẋ + k x + μN sgn ẋ = F0 cos ωt``: the mass's t1 DOF is the pair's t1 (its normal
    and t2 DOFs the same oscillator, held and unloaded). Observed: x."""
    return ReducedModel(M=np.diag([m, m, m, 0.0]), K=np.diag([k, k, k, k]), C=np.diag([c, c, c, 0.0]),
                        B=np.eye(3, 4), f_static=np.array([-normal, 0.0, 0.0, 0.0]),
                        f_harmonic=np.array([0.0, force, 0.0, 0.0]), O=np.array([[0.0, 1.0, 0.0, 0.0]]),
                        area=np.ones(1), gap=np.zeros(1), flank=np.zeros(1, int), position=np.zeros((1, 3)))


def hb_state(model, law, omega: float, nh: int, nit: int):
    """(U_r harmonics, first-harmonic amplitude) of the engine's HB at ω [rad/s]."""
    st = engine.frf(model, law, [engine.Variant("hbm", nh, nit)], freqs_hz=[omega / (2 * np.pi)],
                    options=engine.FRFOptions(nh_check=False, eps_check_factor=0.0))
    r = st.runs[0]
    assert r.converged[0]
    return r.Ur[0], float(r.amplitude[0])


@pytest.mark.parametrize("mu", [1e3, 0.0])
def test_linear_limits_are_periodic_orbits_to_round_off(mu):
    """Stuck (μ large) and free (μ = 0) the Jenkins oscillator is linear, its HB exact; the
    prewarped scheme (exact dynamic stiffness at ω) started from it stays on it: the first
    harmonic and the periodicity agree to round-off (measured 1e-13)."""
    model = jenkins_oscillator()
    law = engine.contact_law(model, mu=mu)
    Ur, _ = hb_state(model, law, 1.3, 3, 16)
    tc = time_check(model, law, 1.3, Ur)
    assert tc.within_tolerance is True and tc.settled
    assert tc.max_rel_diff < 1e-9 and tc.periodicity_defect < 1e-9 and tc.hb_defect < 1e-9


def test_jenkins_hb_near_its_peak_agrees_within_the_tolerance():
    """HBM-7 (nit = 64) just above the friction-damped peak, where the pad sticks and slips each
    period: a periodic orbit of the time-domain model to 2.6e-3 (128 steps; 2.4e-3 at 256 — the
    HB's own truncation: its Nh-check there moves 1.2e-3)."""
    model = jenkins_oscillator()
    law = engine.contact_law(model, mu=0.5)
    Ur, _ = hb_state(model, law, 1.25, 7, 64)
    tc = time_check(model, law, 1.25, Ur, nh_change=1.2e-3)
    assert tc.within_tolerance is True and tc.settled
    assert tc.max_rel_diff < 5e-3 and tc.amplitude_rel_diff < 5e-3
    assert tc.tolerance == pytest.approx(sum(v for v in tc.tolerance_parts.values() if v is not None))
    assert tc.tolerance_parts["nh_check"] == pytest.approx(2 * 1.2e-3)
    assert tc.model == {"contact": "rigid"}
    assert tc.as_dict()["defects"] == tc.defects


@pytest.mark.parametrize("factor", [1.2, 0.8])
def test_perturbed_hb_state_is_flagged(factor):
    """The HB state with its harmonics scaled by ±20 % is not a periodic orbit: the motion settles
    on the true one, 13–25 % away in the first harmonic, and the check says so."""
    model = jenkins_oscillator()
    law = engine.contact_law(model, mu=0.5)
    Ur, _ = hb_state(model, law, 1.25, 7, 64)
    bad = Ur.copy()
    bad[1:] *= factor
    tc = time_check(model, law, 1.25, bad)
    assert tc.within_tolerance is False
    assert tc.max_rel_diff > 3 * tc.tolerance
    assert tc.reason is None and "HB" in tc.verdict


def test_truncated_hb_of_a_coulomb_oscillator_is_flagged():
    """HBM-1 on Den Hartog's oscillator (μN/F0 = 0.5, β = 0.8, ζ = 0.05) is 14 % below the
    event-driven steady state; the check finds the time-domain orbit 13 % away and flags it,
    while the time-domain amplitude itself is within its stated error of the reference."""
    from workflow.verification import timeint

    model = coulomb_oscillator(c=0.1)
    law = engine.contact_law(model, mu=0.5)
    Ur, a_hb = hb_state(model, law, 0.8, 1, 64)
    ref = float(timeint.coulomb_steady_state(1.0, 1.0, 0.1, 0.5, 1.0, 0.8).first[0])
    assert (ref - a_hb) / ref > 0.1
    tc = time_check(model, law, 0.8, Ur, options=TimeCheckOptions(halving=True))
    assert tc.within_tolerance is False and tc.max_rel_diff > 0.1
    assert abs(tc.amplitude_time - ref) / ref <= tc.tolerance_parts["integrator"]


def test_spurious_collocation_roots_are_flagged_and_converged_hb_is_not():
    """The extreme matrix's gross-slip case (4 pads on a block, force ×10, the pairs slipping ≥ 95 % of the
    period): TCM at nit = 2Nh+1 has discrete roots that move with ε (tests/workflow/test_extreme.py:
    reverse slip); the time-domain orbit (9.708e-5 m from every start, at 128 and 256 steps) is
    13 % (ε = k) and 37 % (ε = 10³ k) from them: flagged. HBM converges to it as Nh grows
    (2.7 / 1.5 / 0.7 / 0.4 % at Nh = 3 / 7 / 15 / 25): Nh = 15 passes."""
    from dataclasses import replace

    from workflow.engine.studies import extreme as X
    from workflow.engine.studies.extreme import hbproblem

    su = X.setup(X.synthetic_model(4), X.Settings(max_iterations=30, pseudo_steps=150))
    by = {c.name: c for c in X.build_cases(su)}
    model = replace(su.model, f_harmonic=10.0 * su.model.f_harmonic)     # the case's force_scale
    for name, method, nh, nit, ok in (("penalty-1e+0", "tcm", None, 7, False), ("penalty-1e+3", "tcm", None, 7, False),
                                      ("penalty-1e+0", "hbm", 15, 128, True)):
        case = replace(by[name], force_scale=10.0, nh=nh, nit=nit)
        r = X.run_case(su, case, method, "newton")
        assert r.converged and r.slipping > 0.95
        tc = time_check(model, hbproblem._law(su, case, su.model), case.omega, r.U)
        assert tc.within_tolerance is ok, (name, method, tc.log_line())
        # a wrong state is decided before the motion has settled (off by more than twice the
        # tolerance whatever the transient left); a right one only once it has
        assert tc.settled is ok
        assert tc.amplitude_time == pytest.approx(9.708e-5, rel=2e-3 if ok else 1e-2)


def test_halving_the_step_changes_less_than_the_stated_integrator_error():
    """128 → 64 steps a period moves the Jenkins oscillator's time-domain first harmonic by
    2.5e-3 at most (measured at ω = 1.2, 1.25, 1.3 rad/s), below :func:`integrator_error` (1.2e-2
    at 128 steps), and the measured estimate (the change, doubled) is what ``halving`` charges."""
    model = jenkins_oscillator()
    law = engine.contact_law(model, mu=0.5)
    Ur, _ = hb_state(model, law, 1.25, 7, 64)
    tc = time_check(model, law, 1.25, Ur, options=TimeCheckOptions(halving=True))
    assert tc.halved is not None and tc.halved["steps_per_period"] == 64
    assert tc.halved["change"] < integrator_error(128)
    assert tc.tolerance_parts["integrator"] == pytest.approx(2 * tc.halved["change"])
    assert tc.within_tolerance is True


def test_halving_covers_the_first_order_error_of_a_bare_mass():
    """Friction on a bare mass (Den Hartog) makes the force jump at each reversal: the scheme is
    first order there (−3.3 % at 128 steps, −2.2 % at 256, −0.6 % at 512 against the event-driven
    steady state). The halving estimate (doubled change, 4.2 %) covers the actual error."""
    from workflow.verification import timeint

    model = coulomb_oscillator(c=0.1)
    law = engine.contact_law(model, mu=0.5)
    Ur, _ = hb_state(model, law, 0.8, 7, 64)
    ref = float(timeint.coulomb_steady_state(1.0, 1.0, 0.1, 0.5, 1.0, 0.8).first[0])
    tc = time_check(model, law, 0.8, Ur, options=TimeCheckOptions(halving=True))
    err = abs(tc.amplitude_time - ref) / ref
    assert 0.01 < err <= tc.tolerance_parts["integrator"]


def test_a_check_that_cannot_run_says_why():
    model = jenkins_oscillator()
    law = engine.contact_law(model, mu=0.5)
    tc = time_check(model, law, 1.25, np.zeros((3, 4), complex))
    assert tc.within_tolerance is None and "shape" in tc.reason
    tc = time_check(model, law, -1.0, np.zeros((3, 3), complex))
    assert tc.within_tolerance is None and "positive" in tc.reason
    # U_r = 0 is a real candidate (every pair stuck at the static state): judged, and wrong here
    tc = time_check(model, law, 1.25, np.zeros((3, 3), complex))
    assert tc.within_tolerance is False
    unforced = jenkins_oscillator(force=0.0)
    tc = time_check(unforced, engine.contact_law(unforced, mu=0.5), 1.25, np.zeros((3, 3), complex))
    assert tc.within_tolerance is None and "zero" in tc.reason
    Ur, _ = hb_state(model, law, 1.25, 3, 32)
    tc = time_check(model, law, 1.25, Ur, options=TimeCheckOptions(budget_seconds=1e-9))
    assert tc.within_tolerance is None and "budget" in tc.reason and tc.periods >= 1


def test_the_frf_study_checks_its_peak_in_time_and_a_failure_is_not_a_result(monkeypatch):
    """engine.frf runs the check on its refined headline peak by default (FRFStudy.time_check);
    a peak that is not a periodic orbit is listed by unconverged() (exit 3), never a warning."""
    from workflow.engine import timecheck

    model = jenkins_oscillator()
    law = engine.contact_law(model, mu=0.5)
    study = engine.frf(model, law, [engine.Variant("hbm", 5, 64)], band_hz=(0.18, 0.24), points=7)
    tc = study.time_check
    assert tc["within_tolerance"] is True and tc["frequency_hz"] == pytest.approx(study.peak["hz"])
    assert not [u for u in study.unconverged() + study.warnings() if u.startswith("time check")]

    real = timecheck.time_check

    def shifted(model, law, omega, Ur, **kw):         # the same peak state, 20 % too large
        return real(model, law, omega, 1.2 * np.asarray(Ur), **kw)

    monkeypatch.setattr(timecheck, "time_check", shifted)
    study = engine.frf(model, law, [engine.Variant("hbm", 5, 64)], band_hz=(0.18, 0.24), points=7)
    assert study.time_check["within_tolerance"] is False
    (line,) = [u for u in study.unconverged() if u.startswith("time check")]
    assert "not a periodic orbit" in line
    assert engine.frf(model, law, [engine.Variant("hbm", 5, 64)], band_hz=(0.18, 0.24), points=7,
                      options=engine.FRFOptions(time_check=False)).time_check == {}
