"""Wear with the tip held at an amplitude (``wear.control = "amplitude"``,
workflow/engine/studies/amplitude.py) against the closed form of one Jenkins element."""
from __future__ import annotations

import numpy as np
import pytest

from workflow.verification.wear_exact import JenkinsWear, _model
from workflow.verification.wear_runner import JENKINS, JENKINS_HZ, _options, history_error

#: the far end's ground spring over the element's: the far end's motion departs from X cos ωt by
#: the element's force over k_g, a relative O(k_t / k_g) = 1e-6
STIFF = 1e6
#: the tied frequency of the far end's mass [Hz], far above the wear frequency's harmonics
TIED_HZ = 1000.0


def _driven(ref: JenkinsWear, load_share: float):
    """Case (a) with its imposed far end made a DOF: a mass on a ground spring k_g = STIFF·k_t,
    tied at TIED_HZ, joined to the contact node by the element's k_t and loaded at JENKINS_HZ
    by a force that moves it ``load_share`` × X; it is the observed DOF (the "tip")."""
    kg = STIFF * ref.k_t
    mf = (kg + ref.k_t) / (2 * np.pi * TIED_HZ) ** 2
    w = 2 * np.pi * JENKINS_HZ
    K = np.diag([ref.k_n, ref.k_t, ref.k_t, kg])
    K[np.ix_([1, 3], [1, 3])] += ref.k_t * np.array([[0.0, -1.0], [-1.0, 1.0]])
    M = np.diag([0.0, 0.0, 0.0, mf])
    fs = np.array([-ref.N0, 0.0, 0.0, 0.0])
    fh = np.array([0.0, 0.0, 0.0, load_share * (kg + ref.k_t - mf * w * w) * ref.X])
    return _model(M, K, np.eye(3, 4), fs, fh, np.array([[0.0, 0.0, 0.0, 1.0]]), [ref.A], [0.0])


def _study(control: str, **kw):
    from workflow import engine

    model = _driven(JENKINS, 0.5)
    law = engine.contact_law(model, mu=JENKINS.mu, eps_n=JENKINS.k_n, eps_t=JENKINS.k_t)
    opt = _options(kw.pop("methods", ("pseudo-time",)), JENKINS.k_w, JENKINS_HZ, control=control, rtol=1e-4, **kw)
    return engine.worn_steady_state(model, law, opt)


@pytest.fixture(scope="module")
def held_at_x():
    """Case (a)'s driven element worn with its far end held at X (pseudo-time)."""
    return _study("amplitude", tip_amplitude_m=JENKINS.X)


def test_held_amplitude_wears_as_the_imposed_jenkins_element(held_at_x):
    """Held at X, the element wears along case (a)'s logistic to lift-off (W = N₀/k_n), though
    the model's own load moves the far end X/2: under that force the element sticks (N₀ ≥ k_t X
    / 2μ) and never wears. Bounds: the march's error control (pseudo-time at rtol 1e-4; at 1e-3
    it measured 4e-4 of δ₀ on case (a)) and the far end's departure from X cos ωt,
    O(k_t/k_g) = 1e-6."""
    held = held_at_x
    h = held.histories["pseudo-time"]
    assert h.steady
    assert held.operating_point["control"]["load_scale_new"] == pytest.approx(2.0, rel=1e-3)
    assert float(h.W[0]) == pytest.approx(JENKINS.delta0, rel=1e-3)
    _, _, err = history_error(h, JENKINS.wear, JENKINS.delta0)
    assert err < 1e-3
    from workflow.report.wear import tip_cycles

    before, after = tip_cycles(held)     # the tip held at X, new and worn (its cycle, load scale included)
    for cycle in (before, after["pseudo-time"]):
        assert np.max(np.abs(cycle)) == pytest.approx(JENKINS.X, rel=1e-5)
    forced = _study("force")
    assert forced.histories["pseudo-time"].steady and float(np.max(forced.histories["pseudo-time"].W)) == 0.0


@pytest.mark.slow   # ~8 s beside other jobs
def test_the_implicit_march_and_the_checks_hold_the_amplitude_too():
    """The implicit reference march, the Nh-check and the ε-check on the held amplitude: the
    implicit march first order in its block (3.8e-3 of δ₀ at block_tol 0.01 on case (a), so
    ~1e-3 at 0.0025); the checks' marches end on the same lift-off whatever Nh and ε."""
    held = _study("amplitude", tip_amplitude_m=JENKINS.X, methods=("implicit",), block_tol=0.0025,
                  nh_check=True, eps_check_factor=10.0)
    h = held.histories["implicit"]
    assert h.steady and float(h.W[0]) == pytest.approx(JENKINS.delta0, rel=1e-3)
    assert history_error(h, JENKINS.wear, JENKINS.delta0)[2] < 3e-3
    for check in (held.nh_check, held.eps_check):
        assert check["measure"] == "worn profile" and check["max_rel_change"] < 1e-3


def test_the_bordered_jacobian_is_the_derivative_of_the_residual_and_the_rates():
    """∂/∂[x; s] of the held-amplitude residual and of the wear rates against central differences
    at a slipping state (smooth there: the element slips over a part of the cycle)."""
    from workflow import engine
    from workflow.engine.studies.amplitude import AmplitudeProblem, tip_map
    from workflow.engine.studies.wearstudy import build_problem, unworn_point
    from workflow.engine.wear import WearProblem

    model = _driven(JENKINS, 1.0)
    law = engine.contact_law(model, mu=JENKINS.mu, eps_n=JENKINS.k_n, eps_t=JENKINS.k_t)
    opt = _options(("pseudo-time",), JENKINS.k_w, JENKINS_HZ)
    hb, rc, omega = build_problem(model, law, opt)
    base = unworn_point(hb, omega, opt, ())
    ap = AmplitudeProblem(WearProblem(hb, model.area, opt.k_w, opt.blade_share), tip_map(rc, omega), 1.2 * JENKINS.X)
    z = np.append(base.x, 1.1)
    W = np.array([0.2 * JENKINS.delta0])
    st = ap.evaluate(z, W, jacobian=True)
    assert st.rate[0] > 0
    rng = np.random.default_rng(3)
    for v in (np.eye(z.size)[-1] * 1e-7, np.append(rng.standard_normal(z.size - 1) * 1e-7 * np.abs(z).max(), 0.0)):
        dR = (ap.evaluate(z + v, W).R - ap.evaluate(z - v, W).R) / 2
        dr = (ap.evaluate(z + v, W).rate - ap.evaluate(z - v, W).rate) / 2
        assert np.linalg.norm(dR - st.J @ v) <= 1e-6 * np.linalg.norm(dR)
        assert np.linalg.norm(dr - st.G_x @ v) <= 1e-6 * np.linalg.norm(dr)


def test_a_held_amplitude_needs_one_frequency_and_a_positive_amplitude():
    from workflow.engine.studies.amplitude import AmplitudeProblem
    from workflow.errors import SceneError
    from workflow.params import Wear

    for point in ("resonance", "mission"):
        with pytest.raises(SceneError, match="wear.control"):
            Wear(control="amplitude", operating_point=point, mission=[[1.0, 1.0]] if point == "mission" else []).check()
    Wear(control="amplitude", operating_point="detuning").check()
    with pytest.raises(SceneError, match="tip_amplitude_m"):
        AmplitudeProblem(None, (np.zeros((1, 3)), np.zeros(1)), 0.0)


def test_the_matrix_free_bordered_march_is_the_formed_one():
    """The held amplitude's march without J formed (the vibration's structured GMRES, bordered
    by the load scale: wear_structured with ``st.border``) takes the formed-J march's steps and
    ends on its profile, to the GMRES tolerance."""
    from workflow import engine
    from workflow.engine.studies.amplitude import AmplitudeProblem, tip_map
    from workflow.engine.studies.wearstudy import build_problem, march, unworn_point
    from workflow.engine.wear import WearProblem

    ends = []
    for structured in (False, True):
        model = _driven(JENKINS, 0.5)
        law = engine.contact_law(model, mu=JENKINS.mu, eps_n=JENKINS.k_n, eps_t=JENKINS.k_t)
        opt = _options(("pseudo-time",), JENKINS.k_w, JENKINS_HZ)
        hb, rc, omega = build_problem(model, law, opt)
        base = unworn_point(hb, omega, opt, ())
        wp = WearProblem(hb, model.area, opt.k_w, opt.blade_share, structured=structured)
        ap = AmplitudeProblem(wp, tip_map(rc, omega), JENKINS.X)
        start = ap.start(base.x, tol=opt.tol)
        assert start.converged
        h = march(ap, start.x, "pseudo-time", opt, 1, opt.block_tol)
        assert h.steady
        ends.append((h.iterations, np.asarray(h.W), float(h.x[-1])))
    (n0, W0, s0), (n1, W1, s1) = ends
    assert n0 == n1
    assert np.max(np.abs(W1 - W0)) <= 1e-6 * np.max(W0)
    assert s1 == pytest.approx(s0, rel=1e-6)


def _load_scale(hb) -> float:
    """The scale of ``hb``'s dynamic load against its unit load (:meth:`HBProblem.scale_load`)."""
    from workflow.engine import fourier

    unit = fourier.complex_to_real(hb.Fr)[1:]
    return float(np.linalg.norm(hb.F_coef[1:]) / np.linalg.norm(unit))


def test_where_the_built_load_does_not_solve_the_held_amplitude_starts_from_a_smaller_one(monkeypatch, held_at_x):
    """The unworn point under the load as built only starts a held amplitude's search: where it
    fails (made to here), the point under a tenth of the load starts it, and the march holds
    the same tip at the same load scale and wears the same. Bounds: the vibration's Newton
    tolerance (1e-8 of ‖F‖) on the scale; the marches take the same steps from states that
    agree to it (measured 0 difference in W at 1e-12 of δ₀)."""
    from workflow.engine.errors import SolverError
    from workflow.engine.studies.wearstudy import unworn

    direct = held_at_x
    real, scales = unworn.unworn_point, []

    def fails_as_built(hb, *args):
        scales.append(_load_scale(hb))
        if scales[-1] > 0.5:
            raise SolverError("made to fail under the load as built")
        return real(hb, *args)

    monkeypatch.setattr(unworn, "unworn_point", fails_as_built)     # where _unworn_start looks it up
    held = _study("amplitude", tip_amplitude_m=JENKINS.X)
    assert scales == pytest.approx([1.0, 0.1])
    s0, s1 = (st.operating_point["control"]["load_scale_new"] for st in (direct, held))
    assert s1 == pytest.approx(s0, rel=1e-7)
    w0, w1 = (st.histories["pseudo-time"].W for st in (direct, held))
    assert held.histories["pseudo-time"].steady and np.max(np.abs(w1 - w0)) < 1e-6 * JENKINS.delta0
    with pytest.raises(SolverError, match="made to fail"):     # a fixed force has no other load to start from
        _study("force")


def test_the_continuation_in_amplitude_reaches_the_held_state_where_the_jump_fails(monkeypatch, held_at_x):
    """:meth:`AmplitudeProblem.start`: where Newton's jump from the scaled start fails (made to
    here), geometric steps in the amplitude from the start's own (X/2 → X: 4 steps, each one
    solve) reach the same held state. Bound: the Newton tolerance, as above."""
    from workflow.engine.studies.amplitude import CONTINUATION_STEPS, AmplitudeProblem

    direct = held_at_x
    real, targets = AmplitudeProblem.solve_hb, []

    def jump_fails(self, z, W, **kw):
        targets.append(self.target)
        res, st = real(self, z, W, **kw)
        if len(targets) == 1:
            res.converged, res.reason = False, "made to fail"
        return res, st

    monkeypatch.setattr(AmplitudeProblem, "solve_hb", jump_fails)
    held = _study("amplitude", tip_amplitude_m=JENKINS.X)
    steps = targets[1:CONTINUATION_STEPS + 1]
    assert steps == pytest.approx(JENKINS.X * 2.0 ** (np.arange(1, CONTINUATION_STEPS + 1) / CONTINUATION_STEPS - 1))
    s0, s1 = (st.operating_point["control"]["load_scale_new"] for st in (direct, held))
    assert s1 == pytest.approx(s0, rel=1e-7) and s1 == pytest.approx(2.0, rel=1e-3)
