"""Condensation onto relative DOFs (paper eq. 3) against direct formulas."""
import numpy as np
import pytest

from workflow.engine.condense import condense, recover, relative_coordinates
from workflow.engine.model import ReducedModel


def _random_model(m=12, p=2, seed=0, floating=False):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((m, m))
    K = A @ A.T + m * np.eye(m)
    Mh = rng.standard_normal((m, m))
    M = Mh @ Mh.T / m + np.eye(m)
    C = 1e-3 * K + 0.5 * M
    B = rng.standard_normal((3 * p, m))
    if floating:
        # Make K singular along a direction that moves the relative DOFs, like a
        # blade held only by its contact pairs.
        A = rng.standard_normal((m, m - 1))
        K = A @ A.T
    return ReducedModel(M=M, K=K, C=C, B=B, f_static=rng.standard_normal(m), f_harmonic=rng.standard_normal(m),
                        O=np.eye(m)[:2], area=np.ones(p), gap=np.zeros(p), flank=np.zeros(p, int),
                        position=np.zeros((p, 3)))


def test_matches_eq3_where_D_is_regular():
    model = _random_model()
    rc = relative_coordinates(model)
    omega = 3.7
    cond = condense(rc, omega, nh=3)
    for j in range(4):
        D = model.K - (j * omega) ** 2 * model.M + 1j * j * omega * model.C
        H = np.linalg.inv(D)
        f = [model.f_static, model.f_harmonic, 0 * model.f_static, 0 * model.f_static][j]
        Zr = np.linalg.inv(model.B @ H @ model.B.T)
        np.testing.assert_allclose(cond.Zr[j], Zr, rtol=1e-9, atol=1e-9 * np.abs(Zr).max())
        np.testing.assert_allclose(cond.Fr[j], Zr @ model.B @ H @ f, rtol=1e-8, atol=1e-10)


def test_omega_derivatives_match_finite_differences():
    model = _random_model(seed=1)
    rc = relative_coordinates(model)
    w, h = 2.3, 1e-6
    c = condense(rc, w, nh=2, derivative=True)
    cp, cm = condense(rc, w + h, nh=2), condense(rc, w - h, nh=2)
    np.testing.assert_allclose(c.dZr, (cp.Zr - cm.Zr) / (2 * h), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(c.dFr, (cp.Fr - cm.Fr) / (2 * h), rtol=1e-6, atol=1e-6)


def test_recovery_solves_the_full_equations():
    """q from the recovered response satisfies D q + Bᵀλ = f with λ = Fr − Zr Ur."""
    model = _random_model(seed=2)
    model.O = np.eye(model.size)
    rc = relative_coordinates(model)
    omega = 1.1
    cond = condense(rc, omega, nh=1)
    rng = np.random.default_rng(5)
    Ur = rng.standard_normal((2, 6)) + 1j * rng.standard_normal((2, 6))
    obs = recover(rc, omega, Ur)
    for j in range(2):
        lam = cond.Fr[j] - cond.Zr[j] @ Ur[j]
        D = model.K - (j * omega) ** 2 * model.M + 1j * j * omega * model.C
        f = model.f_static if j == 0 else model.f_harmonic
        np.testing.assert_allclose(D @ obs[j] + model.B.T @ lam, f, atol=1e-9)
        np.testing.assert_allclose(model.B @ obs[j], Ur[j], atol=1e-10)


def test_floating_body_static_condensation_is_finite():
    """K singular in a mode that moves u_r: H_0 does not exist, Z_r0 does."""
    model = _random_model(seed=3, floating=True)
    assert np.linalg.matrix_rank(model.K) < model.size
    rc = relative_coordinates(model)
    cond = condense(rc, 0.0, nh=0)
    assert np.all(np.isfinite(cond.Zr[0]))
    # Z_r0 inherits exactly the one zero-energy direction.
    ev = np.linalg.eigvalsh(0.5 * (cond.Zr[0].real + cond.Zr[0].real.T))
    assert abs(ev[0]) < 1e-8 * ev[-1] and ev[1] > 1e-6 * ev[-1]


def test_every_coordinate_a_contact_dof_needs_no_condensation():
    """Den Hartog's oscillator as a bundle: u_r is the whole model, so Zr = D_j and
    Fr = f_j exactly (LAPACK used to refuse the empty interior factorisation)."""
    from workflow.engine.condense import condense, recover, relative_coordinates
    from workflow.engine.model import ReducedModel

    M, K, C = np.eye(3), np.diag([2.0, 1.0, 1.0]), 0.1 * np.eye(3)
    m = ReducedModel(M=M, K=K, C=C, B=np.eye(3), f_static=np.array([-0.5, 0, 0.0]), f_harmonic=np.array([0, 1.0, 0]),
                     O=np.array([[0, 1.0, 0]]), area=np.ones(1), gap=np.zeros(1), flank=np.zeros(1, int),
                     position=np.zeros((1, 3)))
    rc = relative_coordinates(m)
    c = condense(rc, 0.7, 2, derivative=True)
    np.testing.assert_allclose(c.Zr[1], K - 0.49 * M + 0.7j * C, atol=1e-14)
    np.testing.assert_allclose(c.Fr[1], [0, 1.0, 0], atol=1e-14)
    np.testing.assert_allclose(c.dZr[2], -2 * 4 * 0.7 * M + 2j * C, atol=1e-14)
    U = np.array([[0, 0, 0], [0, 0.3 - 0.1j, 0], [0, 0, 0]], dtype=complex)
    assert recover(rc, 0.7, U)[1, 0] == U[1, 1]


def _both_paths(monkeypatch, rc, omega, nh, Ur=None):
    """(modal, LU) condensations of ``rc`` at ω, with derivatives, and their recoveries of Ur."""
    import workflow.engine.condense as cd

    out = []
    for modal in (True, False):
        monkeypatch.setattr(cd, "TIED_BASIS", modal)
        rc.tied = None
        c = condense(rc, omega, nh, derivative=True)
        out.append((c, None if Ur is None else recover(rc, omega, Ur)))
    rc.tied = None
    monkeypatch.undo()
    return out


def _close(a, b, rtol, floor=0.0):
    assert np.abs(a - b).max() <= rtol * max(np.abs(b).max(), floor)


def test_the_tied_basis_condenses_a_reduced_sector_as_the_lu_does(rotating_bundle, monkeypatch):
    """The project's own bundle (modal damping: C = βK before the reduction) is Rayleigh after
    it, so the condensation goes through the tied modes; Z_r, F_r, their ω-derivatives and the
    recovered response equal the LU path's statically, at the first tied frequency (the worst
    conditioned: 4e-13 measured on the 512-pair sector) and at three times it."""
    import workflow.engine.condense as cd
    from reduction.reduce import reduce_bundle

    bundle, summary, _ = rotating_bundle
    rc = relative_coordinates(reduce_bundle(bundle, 10))
    tm = cd.tied_basis(rc)
    assert tm is not None and tm.alpha == pytest.approx(0.0, abs=1e-9) and tm.beta > 0
    assert cd.condensation(rc) == "tied basis"
    f1 = summary["first_tied_hz"]
    rng = np.random.default_rng(0)
    Ur = 1e-6 * (rng.standard_normal((4, rc.n_rel)) + 1j * rng.standard_normal((4, rc.n_rel)))
    for omega in (0.0, 2 * np.pi * f1, 6 * np.pi * f1):
        (m, om), (lu, ol) = _both_paths(monkeypatch, rc, omega, 3, Ur)
        # an ω-derivative is compared on the scale of its function over 2π·f1 (at ω = 0 the
        # LU's dF_r is round-off, ~1e-24 N·s)
        w1 = 2 * np.pi * f1
        for name, floor in (("Zr", 0), ("Fr", 0), ("dZr", np.abs(lu.Zr).max() / w1),
                            ("dFr", np.abs(lu.Fr).max() / w1)):
            _close(getattr(m, name), getattr(lu, name), 1e-10, floor)
        _close(om, ol, 1e-10)


def test_a_damping_that_is_not_rayleigh_keeps_the_lu():
    """A C that is not αM + βK cannot be diagonalised with K and M: no tied modes, and the
    condensation is eq. 3 as before (the random model's regular-D check)."""
    import workflow.engine.condense as cd

    model = _random_model(seed=4)
    rng = np.random.default_rng(1)
    A = rng.standard_normal(model.C.shape)
    model.C = model.C + 1e-3 * (A + A.T)
    rc = relative_coordinates(model)
    assert cd.tied_basis(rc) is None and rc.tied is False
    assert cd.condensation(rc) == "LU per harmonic"
    omega = 2.9
    c = condense(rc, omega, nh=1)
    D = model.K - omega ** 2 * model.M + 1j * omega * model.C
    Zr = np.linalg.inv(model.B @ np.linalg.inv(D) @ model.B.T)
    np.testing.assert_allclose(c.Zr[1], Zr, rtol=1e-9, atol=1e-9 * np.abs(Zr).max())


def test_the_tied_frequencies_come_from_the_condensations_basis(rotating_bundle, monkeypatch):
    """`workflow.engine.linear.tied_modes` reads the tied basis instead of solving the same
    eigenproblem again: the same frequencies and modal responses as its own eigh(K_yy, M_yy)."""
    import workflow.engine.condense as cd
    from reduction.reduce import reduce_bundle
    from workflow.engine.linear import tied_modes

    rc = relative_coordinates(reduce_bundle(rotating_bundle[0], 10))
    assert cd.tied_basis(rc) is not None
    f, s = tied_modes(rc)
    monkeypatch.setattr(cd, "TIED_BASIS", False)
    f0, s0 = tied_modes(rc)
    np.testing.assert_allclose(f, f0, rtol=1e-9)
    np.testing.assert_allclose(s, s0, atol=1e-9)


@pytest.mark.parametrize("split", [10.0, pytest.param(3.0, marks=pytest.mark.slow)])  # the lower split in make test-slow
def test_the_high_modes_series_condenses_as_the_rank_update_and_the_lu_do(rotating_bundle, monkeypatch, split):
    """Tied modes far above the excitation enter Z_r through their power series in
    (b/a)·μ (workflow.engine.condense.HighModeSeries): Z_r, F_r and their ω-derivatives equal the
    rank update over every mode to round-off, and the LU path as closely as that does. This
    small sector's tied modes span only 58× its first tied frequency (the 512-pair sector's
    1.7e4×), so the split is lowered to 10× and 3× and the series lengthened to 40 terms: at
    10× it serves every harmonic up to 6× the first tied frequency; those beyond its remainder
    bound (9× at a split of 10×, 3× at 3×) take the full rank update."""
    import workflow.engine.condense as cd
    from reduction.reduce import reduce_bundle

    bundle, summary, _ = rotating_bundle
    rc = relative_coordinates(reduce_bundle(bundle, 10))
    w1 = 2 * np.pi * summary["first_tied_hz"]
    monkeypatch.setattr(cd, "SERIES_MIN_DOFS", 0)
    monkeypatch.setattr(cd, "SERIES_SPLIT", split)
    monkeypatch.setattr(cd, "SERIES_TERMS", 40)
    tm = cd.tied_basis(rc)
    series = cd._high_mode_series(rc, tm)
    assert series is not None and 0 < len(series.low) < len(tm.mu)
    used = []
    coefficients = cd._series_coefficients
    monkeypatch.setattr(cd, "_series_coefficients", lambda *a: used.append(coefficients(*a)) or used[-1])
    for omega in (0.0, w1, 3 * w1):
        used.clear()
        tm.series = series
        with_series = condense(rc, omega, 3, derivative=True)
        assert used[0] is not None                        # harmonic 0: always the series
        if split == 10.0 and omega <= w1:
            assert all(u is not None for u in used)
        if omega == 3 * w1:
            assert used[-1] is None                       # harmonic 3 at 9 w1: the rank update
            assert split == 3.0 or used[1] is not None
        tm.series = False
        rank_update = condense(rc, omega, 3, derivative=True)
        monkeypatch.setattr(cd, "TIED_BASIS", False)
        rc.tied = None
        lu = condense(rc, omega, 3, derivative=True)
        monkeypatch.setattr(cd, "TIED_BASIS", True)
        rc.tied = tm
        for name, floor in (("Zr", 0), ("Fr", 0), ("dZr", np.abs(lu.Zr).max() / w1), ("dFr", np.abs(lu.Fr).max() / w1)):
            _close(getattr(with_series, name), getattr(rank_update, name), 1e-13, floor)
            _close(getattr(with_series, name), getattr(lu, name), 1e-10, floor)


def test_all_harmonics_at_once_equal_the_condensation_harmonic_by_harmonic(rotating_bundle, monkeypatch):
    """Where every harmonic takes the high-mode series, `condense` forms Z_r of all of them in one
    product with the series' stack (workflow.engine.condense._condense_all): the same Z_r and F_r as
    harmonic by harmonic (the derivative path, which keeps that loop) and as the LU. Where a
    harmonic is beyond the series (3 w1 here: harmonic 3 at 9 w1), the loop serves them all."""
    import workflow.engine.condense as cd
    from reduction.reduce import reduce_bundle

    bundle, summary, _ = rotating_bundle
    rc = relative_coordinates(reduce_bundle(bundle, 10))
    w1 = 2 * np.pi * summary["first_tied_hz"]
    monkeypatch.setattr(cd, "SERIES_MIN_DOFS", 0)
    monkeypatch.setattr(cd, "SERIES_SPLIT", 10.0)
    monkeypatch.setattr(cd, "SERIES_TERMS", 40)
    monkeypatch.setattr(cd, "CHUNK", 1000)          # several chunks of the stack's columns
    for omega, at_once in ((0.0, True), (w1, True), (3 * w1, False)):
        assert (cd._condense_all(rc, omega, 3) is not None) == at_once
        fast = condense(rc, omega, 3)
        loop = condense(rc, omega, 3, derivative=True)
        monkeypatch.setattr(cd, "TIED_BASIS", False)
        tm, rc.tied = rc.tied, None
        lu = condense(rc, omega, 3)
        monkeypatch.setattr(cd, "TIED_BASIS", True)
        rc.tied = tm
        for name in ("Zr", "Fr"):
            _close(getattr(fast, name), getattr(loop, name), 1e-14)
            _close(getattr(fast, name), getattr(lu, name), 1e-10)


def test_the_diagonals_equal_those_of_the_condensed_stiffness(rotating_bundle):
    """`diagonal` (the automatic penalty's sampling of 33 harmonics) sums the tied modes per
    contact DOF instead of forming Z_r; a model without a tied basis (damping not Rayleigh)
    takes the diagonals of `condense`."""
    import workflow.engine.condense as cd
    from reduction.reduce import reduce_bundle

    bundle, summary, _ = rotating_bundle
    rc = relative_coordinates(reduce_bundle(bundle, 10))
    assert cd.tied_basis(rc) is not None
    for omega in (0.0, 2 * np.pi * summary["first_tied_hz"]):
        ref = np.diagonal(condense(rc, omega, 12).Zr, axis1=1, axis2=2)
        _close(cd.diagonal(rc, omega, 12), ref, 1e-12)
    model = _random_model(seed=4)
    A = np.random.default_rng(1).standard_normal(model.C.shape)
    model.C = model.C + 1e-3 * (A + A.T)
    rc = relative_coordinates(model)
    assert cd.tied_basis(rc) is None
    np.testing.assert_array_equal(cd.diagonal(rc, 2.9, 2), np.diagonal(condense(rc, 2.9, 2).Zr, axis1=1, axis2=2))


def test_the_recovery_map_is_the_recovery_column_by_column(rotating_bundle, monkeypatch):
    """recover_map's (C, d) through the tied basis is the affine map recover applies: d the
    recovery of Ur = 0, C's column k that of the unit relative harmonic k less d — statically,
    at the first tied frequency and above, harmonics 0–2. Both are the same sums in another
    order: round-off (1e-10 of the largest entry, as the tied basis against the LU above). Where
    recover takes the LU path, there is no map to form."""
    import workflow.engine.condense as cd
    from workflow.engine.condense import recover_map
    from reduction.reduce import reduce_bundle

    bundle, summary, _ = rotating_bundle
    rc = relative_coordinates(reduce_bundle(bundle, 10))
    w1 = 2 * np.pi * summary["first_tied_hz"]
    for omega in (0.0, w1, 3 * w1):
        for j in (0, 1, 2):
            C, d = recover_map(rc, omega, j)
            Ur = np.zeros((j + 1, rc.n_rel), complex)
            d_ref = recover(rc, omega, Ur)[j]
            C_ref = np.empty_like(C)
            for k in range(rc.n_rel):
                Ur[j, k] = 1.0
                C_ref[:, k] = recover(rc, omega, Ur)[j] - d_ref
                Ur[j, k] = 0.0
            _close(d, d_ref, 1e-10)
            _close(C, C_ref, 1e-10)
    monkeypatch.setattr(cd, "TIED_BASIS", False)
    rc.tied = None
    assert recover_map(rc, w1, 1) is None


def test_the_blockwise_coordinates_condense_as_the_dense_qr_does(rotating_bundle, monkeypatch):
    """A pair's rows of B touch only its two nodes, so T is made block by block (sparse): B T =
    [I, 0] to round-off, and Z_r, F_r and the recovered response equal those of the dense QR of
    the whole Bᵀ (T_r = Bᵀ(BBᵀ)⁻¹ is the same; the null bases differ by a rotation) statically
    and at the first tied frequency — to round-off (1e-10 of the largest entry, as the tied
    basis against the LU above)."""
    import scipy.sparse as sp

    import workflow.engine.condense as cd
    from reduction.reduce import reduce_bundle

    bundle, summary, _ = rotating_bundle
    model = reduce_bundle(bundle, 10)
    rc_b, T = cd._relative(model)
    assert sp.issparse(T) and T.nnz <= 6 * model.B.shape[1] + model.M.shape[0]
    _close(model.B @ T.toarray(), np.eye(*model.B.shape), 1e-13)
    monkeypatch.setattr(cd, "BLOCK_MAX", 0)
    rc_d, Td = cd._relative(model)
    assert isinstance(Td, np.ndarray)
    rng = np.random.default_rng(1)
    Ur = 1e-6 * (rng.standard_normal((3, rc_b.n_rel)) + 1j * rng.standard_normal((3, rc_b.n_rel)))
    for omega in (0.0, 2 * np.pi * summary["first_tied_hz"]):
        cb, cdn = cd.condense(rc_b, omega, 2), cd.condense(rc_d, omega, 2)
        _close(cb.Zr, cdn.Zr, 1e-10)
        _close(cb.Fr, cdn.Fr, 1e-10)
        _close(recover(rc_b, omega, Ur), recover(rc_d, omega, Ur), 1e-10)


def test_a_model_with_other_loads_shares_the_coordinates_and_tied_basis(rotating_bundle):
    """A scaled excitation (``replace(model, f_harmonic=…)``, as the wear stage's held force
    does) reuses the kept coordinates and tied basis: the same matrices, only Tᵀ f new, so
    F_r scales and Z_r does not change."""
    from dataclasses import replace

    from reduction.reduce import reduce_bundle

    bundle, summary, _ = rotating_bundle
    model = reduce_bundle(bundle, 10)
    rc = relative_coordinates(model)
    omega = 2 * np.pi * 0.9 * summary["first_tied_hz"]
    c = condense(rc, omega, 1)
    scaled = replace(model, f_harmonic=2.5 * model.f_harmonic)
    rc2 = relative_coordinates(scaled)
    assert rc2 is not rc and rc2.M is rc.M and rc2.tied is rc.tied
    c2 = condense(rc2, omega, 1)
    _close(c2.Zr, c.Zr, 1e-14)
    _close(c2.Fr[1], 2.5 * c.Fr[1], 1e-12)
    _close(c2.Fr[0], c.Fr[0], 1e-12)
