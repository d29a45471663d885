"""The interface layer (reduction/layer.py): springs in series with the contact, against closed forms."""
from dataclasses import replace

import numpy as np
import pytest

from workflow.engine.condense import condense, recover, relative_coordinates
from reduction.layer import layer_stiffness, with_interface_layer
from workflow.engine.model import ReducedModel
from workflow.engine.contact import ContactLaw
from workflow.engine.hb import HBProblem


def _model(m=12, p=2, seed=0, alpha=0.5, beta=1e-3):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((m, m))
    K = A @ A.T + m * np.eye(m)
    Mh = rng.standard_normal((m, m))
    M = Mh @ Mh.T / m + np.eye(m)
    return ReducedModel(M=M, K=K, C=alpha * M + beta * K, B=rng.standard_normal((3 * p, m)),
                        f_static=rng.standard_normal(m), f_harmonic=rng.standard_normal(m), O=np.eye(m)[:2],
                        area=rng.uniform(0.5, 2.0, p), gap=np.zeros(p), flank=np.zeros(p, int),
                        position=np.zeros((p, 3)))


@pytest.mark.parametrize("kn,kt", [(30.0, 10.0), (0.0, 10.0), (30.0, 0.0)])
def test_layer_is_a_spring_in_series_with_each_pair(kn, kt):
    """Z_r of the layered model is (Z_r⁻¹ + diag 1/k_c)⁻¹ and F_r is Z'_r Z_r⁻¹ F_r — the compliances
    of the structure and of springs k_c = k·A(1 + i jωβ) (the layer's Rayleigh damping) add; a rigid
    direction (k = 0) adds nothing. Round-off bounds the tolerance (Z_r's condition ~1e2)."""
    model, beta, omega = _model(), 1e-3, 3.7
    layered = with_interface_layer(model, kn, kt)
    assert layered.info["interface_layer"]["damping_beta"] == pytest.approx(beta, rel=1e-10)
    c0 = condense(relative_coordinates(model), omega, nh=2)
    c1 = condense(relative_coordinates(layered), omega, nh=2)
    k = layer_stiffness(model.area, kn, kt)
    for j in range(3):
        comp = np.zeros(k.size, complex)
        soft = k > 0
        comp[soft] = 1.0 / (k[soft] * (1 + 1j * j * omega * beta))
        H = np.linalg.inv(c0.Zr[j])
        Z = np.linalg.inv(H + np.diag(comp))
        np.testing.assert_allclose(c1.Zr[j], Z, rtol=1e-9, atol=1e-9 * np.abs(Z).max())
        np.testing.assert_allclose(c1.Fr[j], Z @ H @ c0.Fr[j], rtol=1e-9, atol=1e-9 * np.abs(c0.Fr[j]).max())


def test_observed_response_is_the_structures():
    """The layer carries λ from the interface to the structure: the observed DOFs of the layered
    model under interface displacement y are those of the bare model under y − C λ
    (λ = F'_r − Z'_r y, the same force on both sides of the massless springs)."""
    model, omega = _model(seed=3), 1.3
    layered = with_interface_layer(model, 20.0, 8.0)
    rc0, rc1 = relative_coordinates(model), relative_coordinates(layered)
    c1 = condense(rc1, omega, nh=1)
    rng = np.random.default_rng(1)
    y = rng.standard_normal((2, 6)) + 1j * rng.standard_normal((2, 6))
    lam = np.stack([c1.Fr[j] - c1.Zr[j] @ y[j] for j in range(2)])
    k = layer_stiffness(model.area, 20.0, 8.0)
    x = np.stack([y[j] + lam[j] / (k * (1 + 1j * j * omega * 1e-3)) for j in range(2)])
    np.testing.assert_allclose(recover(rc1, omega, y), recover(rc0, omega, x), rtol=1e-9, atol=1e-12)


def test_stiff_layer_tends_to_the_rigid_contact_as_one_over_k():
    """The tied frequencies (interface stuck) of a layered model lie below the rigid contact's and
    reach them as the layer stiffens: the springs' compliance 1/k is a first-order perturbation, so
    each tenfold k divides the gap by ten (between 8 and 12 here: the O(1/k²) remainder)."""
    import scipy.linalg as sla

    def first(model):
        rc = relative_coordinates(model)
        r = rc.n_rel
        return np.sqrt(sla.eigh(rc.K[r:, r:], rc.M[r:, r:], eigvals_only=True)[0])   # rad/s

    model = _model(seed=4)
    rigid = first(model)
    gaps = [rigid - first(with_interface_layer(model, k, k)) for k in (1e3, 1e4, 1e5)]
    assert all(g > 0 for g in gaps), gaps
    for a, b in zip(gaps, gaps[1:]):
        assert 8.0 < a / b < 12.0, gaps


def _driven_node(ks: float, N: float, a: float, area: float) -> ReducedModel:
    """A light contact node grounded by springs ks [N/m], loaded by −N normal and driven by
    ks·a cos ωt along t1: a spring ks from a driver d = a cos ωt. No damping."""
    return ReducedModel(M=1e-9 * np.eye(3), K=ks * np.eye(3), C=np.zeros((3, 3)), B=np.eye(3),
                        f_static=np.array([-N, 0.0, 0.0]), f_harmonic=np.array([0.0, ks * a, 0.0]),
                        O=np.eye(3), area=np.array([area]), gap=np.zeros(1), flank=np.zeros(1, int),
                        position=np.zeros((1, 3)))


def _loop_area(Zr, Fr, mu, eps_n, eps_t, nh, a):
    """π a Im Λ_1: the HB loop area of the pair's t1 force against the driver d = a cos ωt [J]."""
    pr = HBProblem(Zr, Fr, ContactLaw(mu=[mu], eps_n=eps_n, eps_t=eps_t, gap=[0.0]), nh, 256, "hbm")
    r = pr.solve(tol=1e-11)
    if not r.converged:
        r = pr.solve(solver="powell", tol=1e-11)
    assert r.converged, r.reason
    lam = pr.contact_harmonics(r.x)
    return np.pi * a * lam[1, 1].imag, lam[0, 0].real


@pytest.mark.parametrize("kt", [0.0, 2e7])
def test_layer_with_a_coulomb_slider_is_the_jenkins_element(kt):
    """Driver spring ks and the layer k_t·A in series with a Coulomb slider: a Jenkins element of
    stiffness k = (1/ks + 1/(k_t A))⁻¹ (k = ks for the rigid contact) under the normal load N_c the
    layer k_n·A carries beside the node's ground spring ks. At every Nh the layered model's HB
    solution is the directly written Jenkins element's (Z_r = diag(ks, k, k), F_r = (−N_c, k a)) to
    the solver's tolerance, and its loop area tends to the closed form 4μN_c(a − μN_c/k); with
    ε_T = k the DLFT is the exact Jenkins law, so what is left at Nh = 15 is the nit = 256
    sampling of the slip onset, < 2e-3 (the rigid driven Jenkins test's bound, tests/workflow/test_hb.py)."""
    ks, N, mu, a, area, kn = 1e5, 1.0, 0.5, 2e-5, 1e-2, 4e8
    k = ks if kt == 0 else 1.0 / (1.0 / ks + 1.0 / (kt * area))
    Nc = N * kn * area / (ks + kn * area)
    exact = 4 * mu * Nc * (a - mu * Nc / k)
    assert exact > 0
    rc = relative_coordinates(with_interface_layer(_driven_node(ks, N, a, area), kn, kt))
    errs = []
    for nh in (1, 5, 15):
        c = condense(rc, 2 * np.pi * 10.0, nh)
        area_hb, lam_n = _loop_area(c.Zr, c.Fr, mu, ks, k, nh, a)
        assert lam_n == pytest.approx(-Nc, rel=1e-9)
        Zj = np.broadcast_to(np.diag([ks, k, k]).astype(complex), (nh + 1, 3, 3))
        Fj = np.zeros((nh + 1, 3), complex)
        Fj[0, 0], Fj[1, 1] = -Nc, k * a
        direct = _loop_area(Zj, Fj, mu, ks, k, nh, a)[0]
        assert area_hb == pytest.approx(direct, rel=1e-8)
        errs.append(abs(area_hb - exact) / exact)
    assert errs[2] < 2e-3, errs


def test_no_layer_returns_the_model_and_bad_stiffness_is_refused():
    model = _model()
    assert with_interface_layer(model, 0.0, 0.0) is model
    with pytest.raises(ValueError, match="interface stiffness"):
        with_interface_layer(model, -1.0, 1.0)


def _grid_model(seed=4, alpha=0.5, beta=1e-3):
    """A 3 × 3 grid of pairs on a tilted plane (1 mm apart), 30 coordinates."""
    base = _model(m=30, p=9, seed=seed, alpha=alpha, beta=beta)
    u, v = np.meshgrid(np.arange(3) * 1e-3, np.arange(3) * 1e-3)
    e1, e2 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.6, 0.8])
    pos = u.reshape(-1, 1) * e1 + v.reshape(-1, 1) * e2 + np.array([0.1, 0.2, 0.3])
    gap = 1e-6 * (pos[:, 0] - 2 * pos[:, 1])                 # a linear gap field
    return replace(base, position=pos, gap=gap, area=np.full(9, 1e-6 / 4))


@pytest.mark.parametrize("per_side", [1, 2, 3])
def test_sample_points_integrate_the_flank_and_interpolate_linear_fields(per_side):
    """The points cover the area the pairs span ((2 mm)², 8 triangles), each sub-triangle equally,
    and their interpolation rows reproduce any linear field (positions, the gap) exactly."""
    from reduction.layer import sample_points

    model = _grid_model()
    N, area, pos, fl = sample_points(model.position, model.flank, per_side)
    assert N.shape == (8 * per_side ** 2, 9) and np.all(N >= 0)
    np.testing.assert_allclose(area, 4e-6 / (8 * per_side ** 2), rtol=1e-9)
    np.testing.assert_allclose(N.sum(axis=1), 1.0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(N @ model.position, pos, rtol=0, atol=1e-15)
    assert np.all(fl == 0)


def test_a_sampled_layer_is_springs_in_series_at_the_points():
    """Z_r of the sampled layer is (N₃ H N₃ᵀ + diag 1/k_c)⁻¹ — the structure's compliance H = Z_r⁻¹
    seen at the points (N₃ = N ⊗ I₃, the linear interpolation) and springs k_c = k·a(1 + i jωβ) at
    each, a its area — and F_r follows as Z'_r N₃ H F_r; the points' gaps are the nodes' gap
    interpolated. Round-off bounds the tolerance."""
    from reduction.layer import sample_points, with_sampled_layer

    model, beta, omega = _grid_model(), 1e-3, 2.9
    sampled = with_sampled_layer(model, 3e7, 1e7, 1)
    N, area, _, _ = sample_points(model.position, model.flank, 1)
    assert sampled.n_pairs == 8 and sampled.info["interface_layer"]["sample_per_side"] == 1
    np.testing.assert_allclose(sampled.gap, N @ model.gap, rtol=0, atol=1e-18)
    c0 = condense(relative_coordinates(model), omega, nh=2)
    c1 = condense(relative_coordinates(sampled), omega, nh=2)
    k = layer_stiffness(area, 3e7, 1e7)
    N3 = np.kron(N, np.eye(3))
    for j in range(3):
        H = np.linalg.inv(c0.Zr[j])
        Z = np.linalg.inv(N3 @ H @ N3.T + np.diag(1.0 / (k * (1 + 1j * j * omega * beta))))
        np.testing.assert_allclose(c1.Zr[j], Z, rtol=1e-9, atol=1e-9 * np.abs(Z).max())
        np.testing.assert_allclose(c1.Fr[j], Z @ N3 @ H @ c0.Fr[j], rtol=1e-9, atol=1e-9 * np.abs(c1.Fr[j]).max())
    with pytest.raises(ValueError, match="k_n, k_t > 0"):
        with_sampled_layer(model, 0.0, 1e7, 1)
