"""Wear measures that can converge with the contact mesh, and the wear study's operating point
(issue 48 items 1 and 3)."""
from __future__ import annotations

import numpy as np
import pytest

from workflow.engine.wear.measures import (filter_matrix, filtered_profile, profile_l2, scar, wear_measures,
                                           worn_volume)


def _flank(nx: int, ny: int, length=0.04, width=0.01, flank=0):
    """A rectangular flank meshed nx × ny, pairs at the cell centres with their tributary areas."""
    x = (np.arange(nx) + 0.5) * length / nx
    y = (np.arange(ny) + 0.5) * width / ny
    X, Y = np.meshgrid(x, y, indexing="ij")
    pos = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    return pos, np.full(X.size, length * width / X.size), np.full(X.size, flank)


def _profile(pos, depth=2e-6, centre=0.01, half=0.008):
    """A smooth scar: depth · cos² over |x − centre| < half, zero outside (m)."""
    s = np.clip((pos[:, 0] - centre) / half, -1.0, 1.0)
    return depth * np.cos(0.5 * np.pi * s) ** 2


def test_volume_and_rms_of_a_uniform_depth_are_exact():
    pos, A, fl = _flank(8, 3)
    W = np.full(len(A), 1.5e-6)
    assert worn_volume(W, A, fl)[0] == pytest.approx(1.5e-6 * 0.04 * 0.01, rel=1e-12)
    assert profile_l2(W, A, fl)[0] == pytest.approx(1.5e-6, rel=1e-12)


def test_filter_keeps_constants_and_tends_to_the_identity_and_the_mean():
    pos, A, fl = _flank(10, 4)
    A = A * np.linspace(0.5, 1.5, len(A))                      # uneven tributary areas
    for ell in (1e-4, 2e-3, 1.0):
        S = filter_matrix(pos, A, ell)
        np.testing.assert_allclose(S.sum(axis=1), 1.0, rtol=1e-13)
        np.testing.assert_allclose(S @ np.full(len(A), 3.0), 3.0, rtol=1e-13)
    np.testing.assert_array_equal(filter_matrix(pos, A, 0.0), np.eye(len(A)))
    # ℓ far below the spacing (1 mm): the identity to exp(−(1 mm)²/(2ℓ²)); far above: the area mean
    np.testing.assert_allclose(filter_matrix(pos, A, 1e-4), np.eye(len(A)), atol=1e-20)
    W = np.random.default_rng(1).random(len(A))
    np.testing.assert_allclose(filter_matrix(pos, A, 1e3) @ W, np.sum(A * W) / A.sum(), rtol=1e-9)


def test_flanks_are_filtered_apart():
    p0, A0, f0 = _flank(6, 2, flank=0)
    p1, A1, f1 = _flank(6, 2, flank=1)
    pos, A, fl = np.vstack([p0, p1]), np.concatenate([A0, A1]), np.concatenate([f0, f1])
    W = np.where(fl == 0, 1e-6, 0.0)
    Wf = filtered_profile(W, pos, A, fl, 1.0)                 # same positions, a huge ℓ
    np.testing.assert_allclose(Wf[fl == 0], 1e-6, rtol=1e-12)
    assert np.all(Wf[fl == 1] == 0.0)


def test_integral_measures_converge_with_the_contact_mesh():
    """A smooth scar sampled on meshes 8×2 … 64×8: the volume and the ℓ-filtered RMS depth converge
    at the midpoint rule's second order (the change shrinks ≥ 3× per doubling), the scar width
    to within one cell; the node-wise maximum only approaches the depth as a cell centre nears the
    scar's centre."""
    meshes = [(8, 2), (16, 4), (32, 8), (64, 8)]
    exact_volume = 2e-6 * 0.01 * 0.008                       # ∫ depth cos² over 2·half × width
    vol, l2, width = [], [], []
    for nx, ny in meshes:
        pos, A, fl = _flank(nx, ny)
        m = wear_measures(_profile(pos), pos, A, fl, 2e-3)["flanks"]["intrados"]
        vol.append(m["worn_volume_m3"])
        l2.append(m["profile_l2_m"])
        width.append(m["scar_width_m"])
        cell = 0.04 / nx
        assert abs(m["scar_width_m"] - 2 * 0.008 * (2 / np.pi) * np.arccos(np.sqrt(0.05))) <= 2 * cell
    err = np.abs(np.array(vol) - exact_volume)
    assert err[1] <= err[0] / 3 and err[2] <= err[1] / 3 and err[-1] / exact_volume < 1e-3
    d = np.abs(np.diff(l2))
    assert d[1] <= d[0] / 3 and d[-1] / l2[-1] < 1e-3


def test_scar_ignores_a_flank_that_barely_wears():
    p0, A0, f0 = _flank(6, 2, flank=0)
    p1, A1, f1 = _flank(6, 2, flank=1)
    pos, A, fl = np.vstack([p0, p1]), np.concatenate([A0, A1]), np.concatenate([f0, f1])
    W = np.where(fl == 0, _profile(pos), 1e-17 * _profile(pos))
    sc = scar(W, pos, A, fl)
    assert sc[0]["width_m"] > 0 and sc[1] == {"area_m2": 0.0, "width_m": 0.0}


def _block():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from test_wear import _reduced_block_model
    from workflow.engine.contact import ContactLaw

    m = _reduced_block_model()
    return m, ContactLaw(mu=np.full(m.n_pairs, 0.3), eps_n=1e5, eps_t=1e5, gap=np.zeros(m.n_pairs))


def test_detuning_wears_at_the_friction_damped_peak():
    """operating_point = "detuning", r = 1: the wear runs at the model's own friction-damped peak —
    the amplitude there is not exceeded 0.1 % to either side (a maximum, whatever found it)."""
    from workflow.engine import WearOptions, solve_point, worn_steady_state
    from workflow.engine.hb import HBProblem
    from workflow.engine.linear import condensed
    from workflow.engine.condense import relative_coordinates
    from workflow.engine.studies.frf import observed

    m, law = _block()
    opt = WearOptions(methods=("pseudo-time",), nh=2, nit=32, k_w=1e-14, cycles_per_block=1e6, eps_check_factor=0.0,
                      nh_check=False, compare_unworn=False, max_steps=3, operating_point="detuning",
                      resonance_shift=False)
    st = worn_steady_state(m, law, opt)
    f_r = st.operating_point["resonance_hz"]
    assert st.operating_point["kind"] == "detuning" and st.omega / 2 / np.pi == pytest.approx(f_r, rel=1e-14)
    rc = relative_coordinates(m)

    def amp(f):
        c = condensed(rc, 2 * np.pi * f, 2)
        hb = HBProblem(c.Zr, c.Fr, law, 2, 32)
        pr = solve_point(hb, [hb.x0()], solver="newton-powell", tol=1e-10, maxiter=100)
        assert pr.converged
        return observed(rc, c.omega, hb.harmonics(pr.result.x))[0]

    top = amp(f_r)
    assert top == pytest.approx(st.operating_point["resonance_amplitude_m"], rel=1e-6)
    assert amp(f_r * 0.999) < top and amp(f_r * 1.001) < top


def test_detuning_out_of_range_and_unknown_operating_point_are_scene_errors():
    from workflow.engine import WearOptions, worn_steady_state
    from workflow.errors import SceneError

    m, law = _block()
    with pytest.raises(SceneError, match="wear.operating_point"):
        worn_steady_state(m, law, WearOptions(operating_point="resonant"))
    with pytest.raises(SceneError, match="wear.detuning"):
        worn_steady_state(m, law, WearOptions(operating_point="detuning", detuning=3.0))


def test_wear_response_curve_of_a_jenkins_oscillator():
    """The wear response curve (engine.studies.operating.wear_response) of the cycle-jump
    oscillator of workflow/verification/wear_exact.py: off its slip band (f/f_r = 0.9, 0.95,
    1.1) the pad sticks, dissipates nothing and does not wear; inside it (1.0, 1.05) it slips and
    wears to lift-off, W = N₀/k_n (the closed form's end state, to the march's steady tolerance);
    the dissipation is largest at the friction-damped peak itself."""
    from workflow import engine
    from workflow.engine.studies.wearresponse import wear_response
    from workflow.verification.wear_runner import _options, oscillator

    o = oscillator()
    model = o.model()
    resp = wear_response(model, engine.contact_law(model, mu=o.mu), _options(("pseudo-time",), o.k_w, 0.0, nh=3),
                         [1.1, 0.9, 1.0, 0.95, 1.05], keep_states=True)
    rows = resp["rows"]
    assert [r["detuning"] for r in rows] == [0.9, 0.95, 1.0, 1.05, 1.1]
    for r in rows:
        assert r["steady"] and r["frequency_hz"] == pytest.approx(r["detuning"] * resp["resonance_hz"], rel=1e-14)
        assert r["W"].max() == r["max_wear_m"]
        if r["detuning"] in (1.0, 1.05):
            assert r["max_wear_m"] == pytest.approx(o.delta0, rel=1e-4) and r["energy_new_J"] > 0
        else:
            assert r["max_wear_m"] == 0.0 and r["energy_new_J"] == 0.0
    assert max(rows, key=lambda r: r["energy_new_J"])["detuning"] == 1.0


def test_each_point_of_the_wear_response_curve_says_where_its_worn_resonance_is():
    """With ``resonance_shift`` each point gives its worn blade's friction-damped resonance: where
    the pad sticks nothing wears and the worn resonance is the new one (the detuning the worn
    blade sees is the point's own); where it wears to lift-off the blade is the linear oscillator
    without its pad, whose peak (10 Hz · √(1 − 2ζ²)) lies 29 % below the tied resonance, outside
    the search's ±10 % band: not found, said as None."""
    from dataclasses import replace

    from workflow import engine
    from workflow.engine.studies.wearresponse import wear_response
    from workflow.verification.wear_runner import _options, oscillator

    o = oscillator()
    model = o.model()
    opt = replace(_options(("pseudo-time",), o.k_w, 0.0, nh=3), resonance_shift=True)
    resp = wear_response(model, engine.contact_law(model, mu=o.mu), opt, [0.95, 1.0])
    stuck, worn = resp["rows"]
    assert stuck["max_wear_m"] == 0.0 and stuck["worn_resonance_hz"] == pytest.approx(resp["resonance_hz"], rel=1e-12)
    assert stuck["worn_detuning"] == pytest.approx(0.95, rel=1e-12)
    assert worn["max_wear_m"] == pytest.approx(o.delta0, rel=1e-4)
    assert worn["worn_resonance_hz"] is None and worn["worn_detuning"] is None


def _cliff_curve(r_c=0.99737, v_top=1.3e-9, drag=0.003):
    """A wear response curve with a cliff at r_c, as the quick sector's: below it the worn blade's
    resonance stays above the excitation (worn detuning r / (1 − 1e-4·(r − 0.99)/0.01) < 1) and the
    worn volume is small; from r_c on the wear drags the resonance `drag` below its new value
    (worn detuning r / (1 − drag) > 1) and the volume falls from v_top at the cliff as 1/(1 + 300(r − r_c))."""
    def point(r):
        above = r >= r_c
        return {"detuning": r, "steady": True, "max_wear_m": 1e-5 if above else 1e-6, "refined": True,
                "worn_detuning": r / (1.0 - drag) if above else r / (1.0 + 3e-4),
                "worn_volume_m3": v_top / (1.0 + 300.0 * (r - r_c)) if above else 0.2 * v_top}
    return point


def test_the_cliff_of_a_wear_response_curve_is_bracketed_and_halved():
    """:func:`cliff` finds the neighbours across which the worn detuning crosses 1, and
    :func:`bisect_cliff` halves that bracket a march at a time around the true cliff r_c: after n
    bisections it is (0.998 − 0.995)/2ⁿ wide and holds r_c; the volume at its upper end rises
    towards the curve's maximum v_top (the limit r → r_c from above), its last step the
    difference of two points of the closed-form curve."""
    from workflow.engine.studies.wearresponse import bisect_cliff, cliff, peak

    r_c, v_top = 0.99737, 1.3e-9
    point = _cliff_curve(r_c, v_top)
    sampled = [dict(point(r), refined=False) for r in (0.99, 0.995, 0.998, 1.0, 1.005)]
    assert cliff(sampled) == (0.995, 0.998)
    assert peak(sampled, 0)["change_last"] is None and peak(sampled, 0)["detuning"] == 0.998
    for n in (1, 4, 8):
        rows = bisect_cliff(sampled, point, n)
        lo, hi = cliff(rows)
        assert len(rows) == len(sampled) + n and sum(r["refined"] for r in rows) == n
        assert hi - lo == pytest.approx(0.003 / 2 ** n, rel=1e-9) and lo < r_c <= hi
        pk = peak(rows, n)
        assert pk["cliff"] == [lo, hi] and pk["detuning"] == hi
        assert pk["worn_volume_m3"] == pytest.approx(v_top / (1 + 300 * (hi - r_c)), rel=1e-12)
        v = pk["upper_volumes"]
        assert v[0] == point(0.998)["worn_volume_m3"] and all(b > a for a, b in zip(v, v[1:]))
        assert v[-1] < v_top and (v_top - v[-1]) / v_top <= 300 * 0.003 / 2 ** n
        if len(v) > 1:
            assert pk["change_last"] == pytest.approx((v[-1] - v[-2]) / v[-1], rel=1e-12)
        # the curve is convex above the cliff: the chord's slope carried across the bracket
        # under-reads what the bracket hides by less than the curve's own slope at the cliff
        hidden = (v_top - pk["worn_volume_m3"]) / pk["worn_volume_m3"]
        assert 0.0 < pk["hidden_rel"] <= 300.0 * (hi - lo) * v_top / pk["worn_volume_m3"]
        assert pk["hidden_rel"] <= hidden * (hi - lo) / (hi - r_c) + 1e-15


def test_a_cliff_is_not_guessed_across_unknown_sides_or_without_a_crossing():
    """No bracket where the worn detuning never crosses 1; a point whose worn resonance was not
    found, or whose march stopped short of a worn steady state with the resonance still above
    the excitation, has no side: the bracket spans it, names it, and is not bisected at it again;
    of two crossings, the one whose upper point wore more."""
    from workflow.engine.studies.wearresponse import bisect_cliff, cliff, peak

    def row(r, wd, v=1e-10):
        return {"detuning": r, "worn_detuning": wd, "worn_volume_m3": v, "steady": True, "max_wear_m": 0.0}

    assert cliff([row(0.99, 0.99), row(1.0, 0.999), row(1.01, 0.9999)]) is None
    assert "does not cross 1" in peak([row(0.99, 0.99), row(1.0, 0.999)], 0)["no_cliff"]
    assert "resonance_shift off" in peak([row(0.99, None), row(1.0, None)], 0)["no_cliff"]
    unknown = [row(0.99, 0.99), dict(row(1.0, 0.998), steady=False), row(1.01, 1.01)]
    assert cliff([row(0.99, 0.99), row(1.0, None), row(1.01, 1.01)]) == (0.99, 1.01)
    assert cliff(unknown) == (0.99, 1.01)
    assert peak(unknown, 0)["unknown_inside"] == [1.0] and peak(unknown, 0)["not_steady"] == [1.0]
    # stopped short with its resonance already dragged below the excitation: above the cliff,
    # since more wear only lowers it further; its volume is no worn state
    dragged = [row(0.99, 0.99, 1e-10), dict(row(1.0, 1.002, 9e-10), steady=False), row(1.01, 1.01, 2e-10)]
    assert cliff(dragged) == (0.99, 1.0)
    assert peak(dragged, 0)["detuning"] == 1.01 and peak(dragged, 0)["upper_volumes"] == [2e-10]
    # its middle is the point whose side is unknown: marching it again tells nothing
    assert bisect_cliff(unknown, lambda r: pytest.fail("the same march again"), 3) == unknown
    assert peak([dict(row(1.0, 1.002), steady=False)], 0)["detuning"] is None
    assert cliff([row(0.99, 0.99), row(0.995, 1.001, 1e-10), row(0.997, 0.9991), row(0.998, 1.002, 5e-10)]) \
        == (0.997, 0.998)
    rows = [row(0.99, 0.99), row(1.0, 0.999)]
    assert bisect_cliff(rows, lambda r: pytest.fail("no march without a cliff"), 3) == rows
