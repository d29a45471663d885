"""The resonance dwell and the mission (duty cycle) operating points of the wear study (issue 48
item 1), on a lumped model whose worn states are known in closed form.

The model: a 1 kg mass on a spring k (10 Hz), damping ζ = 2 % of the tied mode, 1 N on the mass;
two Jenkins pads (k_t = 0.1 k each, from the mass to a contact node, μ = 0.5) each on its own
normal spring k_n with a static load N₀ (pad B 4 N, pad C 4.2 N; k_n = N₀ / 1 µm). A pad's wear
W unloads it, N = N₀ − k_n W, so a pad that slips slips ever more and wears to lift-off at
W = N₀/k_n = 1 µm; one that sticks never wears. With both pads on, the tied resonance is
10.95 Hz; B slips at the friction-damped peak, C (a little more load) sticks there. Wear of B
lowers the resonance: at a fixed frequency the response then falls off the peak and C keeps
sticking; following the peak, the response grows as B's damping goes and C slips too. With both
pads lifted off, the system is the linear m, k, c oscillator.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

K = (2 * np.pi * 10.0) ** 2          # N/m: the mass's own spring, 10 Hz
ZETA = 0.02
LOADS = (4.0, 4.2)                   # N: pad B, pad C
DELTA = 1e-6                         # m: each pad's lift-off depth N₀/k_n
#: a march ends past lift-off by its last step, within its error control: 3.6e-5 of N₀/k_n here at
#: rtol = 1e-3 (3.5e-5 on the verification's Jenkins element, docs/wear.md)
LIFT_TOL = 1e-4


def pad_model():
    """ReducedModel, q = [x, (n, t1, t2) of pad B, of pad C]: the mass (observed) and two
    massless contact nodes, each with k_t to the mass (t1), k_t grounded (t2, unloaded) and a
    grounded normal spring k_n under the static load −N₀."""
    from workflow.engine.model import ReducedModel

    kt = 0.1 * K
    size = 1 + 3 * len(LOADS)
    M, Kmat, C = np.zeros((size, size)), np.zeros((size, size)), np.zeros((size, size))
    M[0, 0], Kmat[0, 0] = 1.0, K
    C[0, 0] = 2 * ZETA * np.sqrt(K + len(LOADS) * kt)
    B = np.zeros((3 * len(LOADS), size))
    fs, fh = np.zeros(size), np.zeros(size)
    fh[0] = 1.0
    for i, n0 in enumerate(LOADS):
        dn, d1, d2 = 1 + 3 * i, 2 + 3 * i, 3 + 3 * i
        Kmat[np.ix_([0, d1], [0, d1])] += kt * np.array([[1.0, -1.0], [-1.0, 1.0]])
        Kmat[dn, dn] += n0 / DELTA
        Kmat[d2, d2] += kt
        fs[dn] = -n0
        B[3 * i:3 * i + 3, [dn, d1, d2]] = np.eye(3)
    O = np.zeros((1, size))
    O[0, 0] = 1.0
    p = len(LOADS)
    return ReducedModel(M=M, K=Kmat, C=C, B=B, f_static=fs, f_harmonic=fh, O=O, area=np.full(p, 1e-6),
                        gap=np.zeros(p), flank=np.zeros(p, int), position=np.zeros((p, 3)))


def options(**kw):
    from workflow.engine import WearOptions

    base = dict(methods=("pseudo-time",), nh=3, nit=32, k_w=1e-16, tol=1e-10, max_steps=3000, steady_tol=1e-5,
                rtol=1e-3, nh_check=False, eps_check_factor=0.0, compare_unworn=False, resonance_shift=False,
                dwell_step=1e-2)
    return WearOptions(**{**base, **kw})


class _Studies(dict):
    """The model, its law and, made when first asked for (once per module), the wear at
    detuning 1 (~0.5 s), the dwell (~1.2 s) and a two-point mission (~1 s)."""

    RUNS = {"detuning": dict(operating_point="detuning"), "dwell": dict(operating_point="resonance"),
            "mission": dict(operating_point="mission", mission=((1.0, 0.5), (0.97, 0.5)))}

    def __missing__(self, name):
        from workflow import engine

        self[name] = engine.worn_steady_state(self["model"], self["law"], options(**self.RUNS[name]))
        return self[name]


@pytest.fixture(scope="module")
def studies():
    from workflow import engine

    model = pad_model()
    return _Studies(model=model, law=engine.contact_law(model, mu=0.5))


def test_dwell_ends_at_the_peak_of_its_own_worn_system(studies):
    """The dwell's last stage is a worn steady state (the march's own test) and the peak of the
    system with that wear, found afresh with the march's static state, is its frequency within
    ``dwell_tol``. Both pads end lifted off, so that peak is the linear oscillator's amplitude
    peak, f_n √(1 − 2ζ_k²) (ζ_k of the mass's own spring), to the peak search's 1e-6."""
    from workflow.engine.studies.operating import friction_damped_resonance

    st, opt = studies["dwell"], options(operating_point="resonance")
    h = st.histories["pseudo-time"]
    d = st.operating_point["dwell"]
    f = st.operating_point["frequency_hz"]
    assert h.steady and d["converged"] and d["history"][-1]["steady"]
    assert f == pytest.approx(st.omega / (2 * np.pi), rel=1e-15) == d["frequencies_hz"][-1]
    again = friction_damped_resonance(studies["model"], studies["law"].with_wear(h.W), method="hbm", nh=3, nit=32,
                                      tol=1e-10, max_iterations=opt.max_iterations, max_passes=opt.max_passes,
                                      static=st.hb.static)
    assert abs(again["hz"] / f - 1.0) <= opt.dwell_tol
    assert np.all(h.W >= DELTA * (1 - LIFT_TOL))
    zeta_k = 2 * ZETA * np.sqrt(1.2 * K) / (2 * np.sqrt(K))
    assert f == pytest.approx(10.0 * np.sqrt(1 - 2 * zeta_k ** 2), rel=3e-6)


def test_dwell_follows_the_falling_resonance_and_wears_deeper_than_detuning(studies):
    """Wear lowers this model's resonance: the dwell's frequency goes from the new model's peak
    (10.93 Hz) to the worn one (10.00 Hz, the mass's own spring), re-locating the peak after each
    stage (as B starts to wear the peak first rises a little — less friction damping — then falls
    as B loses its load). At detuning 1 (the new peak, held) only B wears, to lift-off; following
    the peak, C slips as well and wears to lift-off too: the dwell is the worst case."""
    det, st = studies["detuning"], studies["dwell"]
    d = st.operating_point["dwell"]
    f = np.array(d["frequencies_hz"])
    # the new model's peak, searched once for each study: equal to round-off (one ulp apart on some CPUs)
    assert f[0] == pytest.approx(det.operating_point["frequency_hz"], rel=1e-12)
    assert f[0] == pytest.approx(st.operating_point["resonance_hz"], rel=1e-12)
    assert f[-1] < 0.92 * f[0]
    assert d["relocations"] == d["stages"] == len(d["history"]) >= 3
    W_det, W_dwell = det.histories["pseudo-time"].W, st.histories["pseudo-time"].W
    assert W_det[0] == pytest.approx(DELTA, rel=LIFT_TOL) and W_det[1] == 0.0
    assert np.all(W_dwell >= W_det - LIFT_TOL * DELTA) and W_dwell[1] == pytest.approx(DELTA, rel=LIFT_TOL)


def test_a_mission_of_one_point_is_that_detuning(studies):
    """One point with share 1 is operating_point = "detuning" at its f / f_r, step for step."""
    from workflow import engine

    det = studies["detuning"].histories["pseudo-time"]
    st = engine.worn_steady_state(studies["model"], studies["law"],
                                  options(operating_point="mission", mission=((1.0, 1.0),)))
    h = st.histories["pseudo-time"]
    np.testing.assert_array_equal(h.W, det.W)
    np.testing.assert_array_equal(h.x, det.x)
    np.testing.assert_array_equal(h.cycles, det.cycles)
    np.testing.assert_array_equal(h.max_rate, det.max_rate)
    assert st.omega == studies["detuning"].omega and h.steady


def _rates(model, law, frequencies, W):
    """Each frequency's wear rate (p,) [m/cycle] at the wear W, its vibration solved afresh."""
    from workflow.engine.studies.wearstudy import build_problem
    from workflow.engine.wear import WearProblem

    out = []
    for f in frequencies:
        hb, _, _ = build_problem(model, law, options(frequency_hz=f))
        res, s = WearProblem(hb, model.area, 1e-16).solve_hb(hb.x0(), W, tol=1e-10)
        assert res.converged
        out.append(s.rate)
    return out


def test_a_mission_sums_the_rates_of_its_points_with_their_shares(studies):
    """Two points, f / f_r = 1 and 0.97, half the cycles each. The mission's rate is the
    share-weighted sum of the points' rates, each solved on its own: unworn (where only the peak
    wears) and at the mission's worn state. Rates are ≥ 0, so a zero sum with positive shares
    means every point's own rate is zero: the mission's worn steady state is steady for each
    point. Physics of this model: B slips at the peak and so wears to lift-off (N₀/k_n) whatever
    else the mission does, C sticks at both points and stays unworn; the 0.97 point wears B more
    slowly than the peak, so the mission takes between the peak's own cycles and 1/share × them."""
    model, law = studies["model"], studies["law"]
    st, det = studies["mission"], studies["detuning"].histories["pseudo-time"]
    h = st.histories["pseudo-time"]
    pts = st.operating_point["points"]
    assert [(p["detuning"], p["share"]) for p in pts] == [(1.0, 0.5), (0.97, 0.5)]
    freqs = [p["frequency_hz"] for p in pts]
    assert freqs[0] == pytest.approx(st.operating_point["resonance_hz"], rel=1e-15)
    new = _rates(model, law, freqs, np.zeros(2))
    assert new[0].max() > 0 and new[1].max() == 0.0
    assert h.max_rate[0] == pytest.approx(float(np.max(0.5 * new[0] + 0.5 * new[1])), rel=1e-6)
    worn = _rates(model, law, freqs, h.W)
    scale = float(new[0].max())
    np.testing.assert_allclose(h.final_rate, 0.5 * worn[0] + 0.5 * worn[1], rtol=0, atol=1e-6 * scale)
    assert h.steady and max(float(worn[0].max()), float(worn[1].max())) <= 1e-3 * scale
    assert h.W[0] == pytest.approx(DELTA, rel=LIFT_TOL) and h.W[1] == 0.0
    assert det.cycles[-1] < h.cycles[-1] < det.cycles[-1] / 0.5


@pytest.mark.parametrize("mission, match", [
    (((1.0, 0.6), (0.97, 0.5)), "sum to 1.1"),
    (((1.0, 1.2), (0.97, -0.2)), "must be ≥ 0"),
    ((), "empty"),
    (((3.0, 1.0),), "outside"),
])
def test_bad_missions_are_scene_errors_naming_the_key(mission, match):
    from workflow.engine import worn_steady_state
    from workflow.errors import SceneError

    model = pad_model()
    with pytest.raises(SceneError, match=f"wear.mission.*{match}"):
        worn_steady_state(model, None, options(operating_point="mission", mission=mission))


def test_the_scene_checks_the_mission():
    from workflow import params
    from workflow.errors import SceneError
    from workflow.schema import resolve_section

    ok = resolve_section("wear", params.Wear, {"operating_point": "mission", "mission": [[1.0, 0.25], [0.98, 0.75]]})
    assert ok.mission == [[1.0, 0.25], [0.98, 0.75]]
    for raw, match in (({"operating_point": "mission", "mission": [[1.0, 0.7], [0.9, 0.2]]}, "wear.mission.*sum to 0.9"),
                       ({"operating_point": "mission", "mission": [[1.0, 1.0, 2.0]]}, r"wear.mission\[0\]"),
                       ({"operating_point": "mission", "mission": [[1.0, 1.5], [0.9, -0.5]]}, r"wear.mission\[1\].*≥ 0"),
                       ({"operating_point": "mission"}, "wear.mission is empty"),
                       ({"mission": [[1.0, 1.0]]}, "wear.mission is set but wear.operating_point")):
        with pytest.raises(SceneError, match=match):
            resolve_section("wear", params.Wear, raw)
    assert resolve_section("wear", params.Wear, {"operating_point": "resonance"}).dwell_tol > 0


def test_the_wear_response_cliff_is_pad_b_slip_onset():
    """The wear response curve of the two-pad model has its cliff where pad B starts to slip on
    the new blade: below it both pads stick (the tied linear response, no wear, the worn detuning
    the point's own, < 1); above it B slips, wears to lift-off (W = N₀/k_n) and leaves the mass on
    k + k_t with C stuck, whose resonance lies ~4 % below — the wear has dragged it through the
    excitation (worn detuning > 1). B's slip onset in closed form: k_t |X| = μ N_B with
    X = 1 N / |k + 2k_t − ω² + iωc| (its lower root). The AFT sees the tangential force at nit
    samples a period only, so it finds the onset where the sampled peak reaches μ N_B: between
    the closed form's frequency and the one where k_t |X| cos(π/nit) = μ N_B. The bisected bracket
    must straddle that interval, 2⁻⁸ of the sampled one wide."""
    from scipy.optimize import brentq

    from workflow import engine
    from workflow.engine.studies.wearresponse import wear_response

    nit = 128
    model = pad_model()
    resp = wear_response(model, engine.contact_law(model, mu=0.5), options(resonance_shift=True, nit=nit),
                         [0.99, 1.0], refine=8)
    kt, c = 0.1 * K, 2 * ZETA * np.sqrt(1.2 * K)

    def onset(force):                 # ω [rad/s] below the tied resonance where k_t|X| = force
        return brentq(lambda w: kt / np.hypot(1.2 * K - w * w, c * w) - force, 0.9 * np.sqrt(1.2 * K),
                      np.sqrt(1.2 * K))

    f_r = 2 * np.pi * resp["resonance_hz"]
    exact, sampled = onset(0.5 * LOADS[0]) / f_r, onset(0.5 * LOADS[0] / np.cos(np.pi / nit)) / f_r
    lo, hi = resp["peak"]["cliff"]
    assert hi - lo == pytest.approx(0.01 / 2 ** 8, rel=1e-9)
    assert lo < sampled and hi >= exact
    for row in resp["rows"]:
        if row["detuning"] <= lo:
            assert row["max_wear_m"] == 0.0 and row["worn_detuning"] == pytest.approx(row["detuning"], rel=1e-12)
        else:
            assert row["max_wear_m"] == pytest.approx(DELTA, rel=LIFT_TOL) and row["worn_detuning"] > 1.03
    assert resp["peak"]["worn_volume_m3"] == pytest.approx(DELTA * 1e-6, rel=LIFT_TOL)
