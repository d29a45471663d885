"""Partial-slip fretting wear of an elastic sphere (issue 48, 4 c): the MDR worn steady state.

The closed form and the march are in :mod:`workflow.verification.wear_mdr` (derivation and
references in its docstring; equation tags (M1)–(M4), (C1), (F1)–(F4), (W) there). Nothing here
uses the project's HB/DLFT code. Each test takes under 1 s on one core (the file ≈ 2 s of tests)."""
import math
import warnings

import numpy as np
import pytest

from workflow.verification import wear_mdr as mdr

CASE = mdr.CASE                     # R = 10 mm, d = 1 µm, a = 100 µm, μ = 0.6, c/a = 0.6
R, D, A, C = CASE.R, CASE.d, CASE.a, CASE.c
E, G = CASE.E_star, CASE.G_star


@pytest.fixture(scope="module")
def archard():
    """The Archard march on 400 springs (≈ 0.2 s)."""
    return mdr.march(CASE, 400)


# ------------------------------------------------------------------ the unworn state
def test_unworn_mdr_state_is_hertz_to_quadrature_accuracy():
    """(M1) of f = r²/(2R) by quadrature is g = x²/R; the contact edge g(a) = d is a = √(Rd);
    N = 2E*∫_0^a (d − g) dx is (4/3)E*R^½d^{3/2}; (M3) gives Hertz's p = (2E*/πR)√(a²−r²) and
    (M4) Hertz's deflection outside the contact — all to ≤ 1e-12 (Gauss–Legendre, 64 points)."""
    from scipy.optimize import brentq

    fprime = lambda r: r / R  # noqa: E731
    x = np.linspace(0.0, 1.5 * A, 31)
    g = lambda x: mdr.mdr_forward(fprime, x)  # noqa: E731
    np.testing.assert_allclose(g(x), x * x / R, rtol=1e-13, atol=1e-16 * D)
    a = brentq(lambda s: g(s)[0] - D, 0.1 * A, 2 * A, xtol=1e-16 * A, rtol=1e-15)
    hz = mdr.hertz(E, R, D)
    assert a == pytest.approx(math.sqrt(R * D), rel=1e-13) and hz["a"] == pytest.approx(a, rel=1e-13)
    t, w = mdr._panels(0.0, a, (), 64)
    N = 2 * E * (D - g(t)) @ w
    assert N == pytest.approx(4 / 3 * E * math.sqrt(R) * D ** 1.5, rel=1e-12) and hz["N"] == pytest.approx(N, rel=1e-12)
    # the pressure from q' = −E* g', g' by a 5-point stencil of the quadrature g (h⁴ ≈ 1e-12)
    hh = 1e-3 * A
    dg = lambda x: (-g(x + 2 * hh) + 8 * g(x + hh) - 8 * g(x - hh) + g(x - 2 * hh)) / (12 * hh)  # noqa: E731
    r = np.linspace(0.0, 0.99 * A, 12)
    p = mdr.mdr_pressure(lambda x: -E * dg(x), r, a)
    np.testing.assert_allclose(p, 2 * E / (np.pi * R) * np.sqrt(a * a - r * r), rtol=1e-9)
    assert p[0] == pytest.approx(hz["p0"], rel=1e-9)
    # (M4): the surface outside the contact, Hertz's closed form
    ro = np.linspace(1.01 * A, 3 * A, 9)
    w = mdr.mdr_inverse(lambda x: np.maximum(D - x * x / R, 0.0), ro, kinks=(A,))
    s = A / ro
    hertz_w = A * A / (np.pi * R) * ((2 - 1 / s ** 2) * np.arcsin(s) + np.sqrt(1 - s * s) / s)
    np.testing.assert_allclose(w, hertz_w, rtol=1e-12)


def test_unworn_spring_bed_is_cattaneo_mindlin():
    """The discrete bed (400 springs): its normal force is Hertz's to O(Δx²) (5.5e-7); the first
    loading to u₀ sticks the springs inside c = a√(1 − G*u₀/(μE*d)) (C1), and its tangential force is
    Cattaneo–Mindlin's μN(1 − (c/a)³), i.e. c/a = (1 − Q/μN)^{1/3} — here c/a = 0.6, partial slip."""
    bed = mdr.spring_bed(CASE, 400)
    F0 = bed["k_z"] * bed["delta"]
    N = 2 * F0.sum()
    assert N == pytest.approx(CASE.unworn["N"], rel=1e-5)
    z, slip, tau, _ = mdr.jenkins_cycle(np.zeros(400), CASE.mu * F0, bed["k_x"], CASE.u0, 4)
    Q = 2 * tau.sum()
    assert C / A == pytest.approx(0.6, rel=1e-14)
    assert Q == pytest.approx(CASE.mu * N * (1 - (C / A) ** 3), rel=5e-3)
    assert (1 - Q / (CASE.mu * N)) ** (1 / 3) == pytest.approx(C / A, rel=5e-3)
    # the stuck springs after the first quarter cycle are exactly those inside c (to a spacing)
    stuck = (slip == 0) & (F0 > 0)
    edge = bed["faces"][np.argmin(stuck)]
    assert abs(edge - C) <= bed["dx"]
    # (C1) both ways
    assert mdr.amplitude_for_stick(E, G, R, D, CASE.mu, C) == pytest.approx(CASE.u0, rel=1e-14)
    assert mdr.stick_radius(E, G, R, D, CASE.mu, 2 * CASE.mu * E * D / G) == 0.0      # gross slip


def test_jenkins_cycle_slip_is_exact_whatever_the_sampling():
    """The incremental return mapping over a cycle gives the steady slip 4(u₀ − μF/k_x)₊ of a
    Jenkins element exactly, for any number of samples per cycle that is a multiple of 4 (the
    turning points sampled; the element is rate-independent)."""
    k_x, u0 = 1e5, 1e-6
    limit = np.array([0.0, 0.02, 0.05, 0.099, 0.1, 0.2])      # N; k_x u₀ = 0.1 N
    exact = 4 * np.maximum(u0 - limit / k_x, 0.0)
    for steps in (4, 8, 64, 400):
        z, _, _, _ = mdr.jenkins_cycle(np.zeros(limit.size), limit, k_x, u0, steps)     # settle
        z, s, _, work = mdr.jenkins_cycle(z, limit, k_x, u0, steps)
        np.testing.assert_allclose(s, exact, rtol=1e-12, atol=1e-22)
        assert work == pytest.approx(float(limit @ exact), rel=1e-12)


# ------------------------------------------------------------------ the closed form
def test_closed_form_is_the_inverse_transform_of_the_final_1d_state():
    """(F3) for the parabola equals (M2) of (F1) — g on |x| ≤ c, d beyond — by quadrature, max'd
    with the unworn f: to 1e-12 d (grid off r = c, where the depth has its √ edge); h(c) = 0,
    h ≥ 0, and the worn depth vanishes inside c and beyond a_∞."""
    r = np.r_[np.linspace(0.0, 0.999 * C, 20), np.linspace(1.001 * C, 1.6 * A, 60)]
    quad = mdr.worn_profile_quadrature(r, lambda x: x * x / R, D, C)
    np.testing.assert_allclose(quad, mdr.worn_profile(r, R, D, C), rtol=0, atol=1e-12 * D)
    h = mdr.worn_depth(r, R, D, C)
    a_inf = mdr.touching_radius(R, D, C)
    assert np.all(h >= 0) and np.all(h[r < C] == 0) and np.all(h[r > a_inf] == 0) and np.all(h[(r > C) & (r < a_inf)] > 0)
    assert mdr.worn_depth(C, R, D, C)[0] == 0.0
    assert A < a_inf < math.sqrt(2) * A and a_inf == pytest.approx(1.18723 * A, rel=1e-5)


def test_final_state_is_an_elastic_contact_solution_by_boussinesq():
    """3D elasticity without the MDR: the half-space deflection under the closed-form final pressure
    p_∞ (F4) (Boussinesq's ring kernel) is d − f on r < c (the unworn stick zone in contact),
    d − f_∞ on c < r < a_∞ (the worn annulus touching at zero pressure) and below d − f beyond a_∞
    (a gap); p_∞ ≥ 0 and its resultant is N_∞ = 2E*(dc − c³/3R): the slip zone is unloaded."""
    from scipy.integrate import quad

    p_reg = lambda s: E * (R * D + C * C - 2 * s * s) / (np.pi * R)  # noqa: E731   p√(c²−s²)
    r_in = np.linspace(0.0, 0.9 * C, 5)
    a_inf = mdr.touching_radius(R, D, C)
    r_ann = np.linspace(1.1 * C, 0.98 * a_inf, 6)
    r_out = np.linspace(1.03 * a_inf, 1.6 * A, 4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        w_in, w_ann, w_out = (mdr.boussinesq_deflection(r, p_reg, C, E) for r in (r_in, r_ann, r_out))
    np.testing.assert_allclose(w_in, D - r_in ** 2 / (2 * R), rtol=0, atol=1e-9 * D)
    np.testing.assert_allclose(w_ann, D - mdr.worn_profile(r_ann, R, D, C), rtol=0, atol=1e-9 * D)
    assert np.all(D - w_out - r_out ** 2 / (2 * R) < 0)         # f > d − w: the gap is open
    rr = np.linspace(0.0, 0.999 * C, 50)
    assert np.all(mdr.final_pressure(rr, E, R, D, C) > 0) and np.all(mdr.final_pressure([C, 1.01 * C, A], E, R, D, C) == 0)
    N = quad(lambda th: p_reg(C * math.sin(th)) * 2 * np.pi * C * math.sin(th), 0.0, 0.5 * np.pi, epsrel=1e-13)[0]
    assert N == pytest.approx(mdr.final_load(E, R, D, C), rel=1e-12)


def test_closed_form_limits():
    """c → a (u₀ → 0, full stick): no wear, a_∞ → a, N_∞ → N₀. c → 0 (the onset of gross slip):
    the profile flattens to the indentation, f_∞ → d on the whole scar, which reaches √2 a (where
    the unworn parabola reaches d), and the contact is unloaded (N_∞ → 0)."""
    r = np.linspace(0.0, 1.5 * A, 301)
    c1 = A * (1 - 1e-10)
    assert np.max(mdr.worn_depth(r, R, D, c1)) <= 1e-9 * D
    assert mdr.touching_radius(R, D, c1) == pytest.approx(A, rel=1e-8)
    assert mdr.final_load(E, R, D, c1) == pytest.approx(CASE.unworn["N"], rel=1e-9)
    c0 = 1e-9 * A
    on = (r >= 1e-3 * A) & (r <= math.sqrt(2) * A)
    np.testing.assert_allclose(mdr.worn_profile(r[on], R, D, c0), D, rtol=1e-5)
    assert mdr.touching_radius(R, D, c0) == pytest.approx(math.sqrt(2) * A, rel=1e-8)
    assert mdr.final_load(E, R, D, c0) <= 1e-8 * CASE.unworn["N"]
    # in between: a larger stick zone wears less at every radius
    cs = np.linspace(0.1, 0.9, 5) * A
    h = np.array([mdr.worn_depth(r, R, D, c) for c in cs])
    assert np.all(np.diff(h, axis=0) <= 1e-18)


# ------------------------------------------------------------------ the march
def test_march_reaches_the_closed_form_worn_state(archard):
    """The independent-spring march (Archard, 400 springs) against (F1)–(F4): the worn depth's
    relative RMS error over r ≤ a 0.44 % (< 3 %; first order in Δx: the stick edge c falls inside
    a cell), the profile's 0.15 %; c to one spacing; a_∞ (read from the final loads by (M4)), N_∞,
    p_∞(0) and the final tangential force 2G*u₀c to 1 %. The slip annulus is unloaded."""
    res = archard
    assert res["converged"]
    cmp_ = mdr.compare(CASE, res)
    assert cmp_["depth_l2"] < 0.03 and cmp_["profile_l2"] < 0.03
    assert cmp_["depth_l2"] < 0.01                       # measured 4.4e-3
    assert abs(cmp_["c"][0] - cmp_["c"][1]) <= res["bed"]["dx"]
    for k in ("a_inf", "N", "p_centre", "Q"):
        v, e = cmp_[k]
        assert v == pytest.approx(e, rel=0.01), k
    # the annulus springs are down to the stop compression, the stuck ones untouched
    bed = res["bed"]
    annulus = ~res["stick"] & (bed["delta"] > 0)
    assert np.all(res["F"][annulus] <= 1e-4 * D * bed["k_z"] * (1 + 1e-9))
    assert np.all(res["W"][res["stick"]] == 0)


def test_final_state_independent_of_the_wear_coefficient_and_law(archard):
    """'Whatever the wear law': k_w × 10 reaches the same state in a tenth of the cycles; the law
    dW/dn ∝ p² s^½ (α = 2, β = ½: a different path, the slip zone unloading algebraically instead
    of exponentially) reaches it too — both within the march's tolerance of the Archard state and
    within 3 % of the closed form."""
    r = np.linspace(0.0, A, 2001)
    faces = archard["bed"]["faces"]
    h0 = mdr.cells_inverse(faces, archard["W"], r)
    fast = mdr.march(CASE, 400, k_w=10 * CASE.k_w)
    other = mdr.march(CASE, 400, alpha=2.0, beta=0.5)
    for res in (fast, other):
        h = mdr.cells_inverse(faces, res["W"], r)
        assert mdr._l2(r, h - h0) / mdr._l2(r, h0) < 2e-3
        assert mdr.compare(CASE, res)["depth_l2"] < 0.03
        np.testing.assert_array_equal(res["stick"], archard["stick"])
    assert fast["n"][-1] == pytest.approx(archard["n"][-1] / 10, rel=1e-9)
    # the other law's path differs: half-way (N halfway to N_∞) at a different cycle count per unit k_w
    half = 0.5 * (archard["N"][0] + archard["N"][-1])
    n_a = np.interp(-half, -archard["N"], archard["n"])
    n_o = np.interp(-half, -other["N"], other["n"])
    assert abs(n_o / n_a - 1) > 0.5


def test_normal_load_is_displacement_controlled(archard):
    """The indentation d is imposed, so the normal force is *not* conserved: it falls from N₀
    (Hertz) to N_∞ (F4), monotonically. What is conserved: per spring F + k_z W = k_z(d − g), so
    N + E*·(2∫W dx) = N₀ at every step (to rounding); and the stick zone's load (the springs stuck
    at the first cycle), which never wears and is N_∞. The friction work per cycle falls to ~0
    (the worn state does not dissipate) and the tangential force to 2G*u₀c."""
    res = archard
    N0 = 2 * res["bed"]["k_z"] * res["bed"]["delta"].sum()
    np.testing.assert_allclose(res["N"] + E * res["worn_area"], N0, rtol=1e-12)
    assert np.all(np.diff(res["N"]) <= 1e-12 * N0)
    assert res["N"][0] == pytest.approx(CASE.unworn["N"], rel=1e-5)
    assert np.ptp(res["stick_load"]) <= 1e-14 * N0
    assert res["stick_load"][0] == pytest.approx(mdr.final_load(E, R, D, C), rel=0.01)
    assert res["N"][-1] == pytest.approx(res["stick_load"][-1], rel=1e-3)
    assert res["work"][-1] <= 1e-3 * res["work"][0]
    assert res["Q"][-1] == pytest.approx(2 * G * CASE.u0 * C, rel=0.01)


def test_rows_have_the_wear_row_format():
    """:func:`mdr_rows` (quick: 400 springs, ≈ 0.3 s): rows (case, quantity, value, exact, error)
    as :mod:`workflow.verification.wear_runner` writes them, every error below 3 %."""
    rows = mdr.mdr_rows(quick=True)
    assert len(rows) >= 9
    for row in rows:
        assert set(row) == {"case", "quantity", "value", "exact", "error"} and row["case"] == "mdr_partial_slip"
        assert all(isinstance(row[k], float) for k in ("value", "exact", "error"))
        assert row["error"] < 0.03, row
