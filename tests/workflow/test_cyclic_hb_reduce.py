"""The per-ND reduction and condensation of a cyclic sector (lumped tuned disk of
:mod:`cyclicmodels`): exact against the unreduced ND sector operators, the
general ω-derivative of a Hermitian-based D, save/load, and refusals."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from cyclicmodels import sector_bundle
from workflow.engine.condense import condense, recover, relative_coordinates
from reduction.cyclic_reduce import (CyclicReducedModel, reduce_cyclic, reduced_tied_frequencies, sector_matrices,
                                     tied_frequencies)
from reduction.reduce import contact_map
from workflow.errors import BundleError

N = 5


def _direct(bundle, nd, j, omega):
    """Eq. 3 on the unreduced ND-nd sector: Zr = (B H Bᴴ)⁻¹, Fr = Zr B H f (f: the
    tip load on j = 1, none above; j ≥ 1: at j = 0 the blade floats and H does not exist)."""
    T, K, M, C, kept = sector_matrices(bundle, nd)
    D = (K - (j * omega) ** 2 * M + 1j * j * omega * C).toarray()
    B = (contact_map(bundle) @ T).toarray()
    f = T.conj().T @ (bundle.loads.harmonic if j == 1 else 0 * bundle.loads.harmonic)
    H = np.linalg.inv(D)
    Zr = np.linalg.inv(B @ H @ B.conj().T)
    return Zr, Zr @ B @ H @ f


def test_condensed_stiffness_per_harmonic_is_that_of_its_nodal_diameter():
    """EO 3, N 5: harmonics 1, 2 on ND 3, 1 — Zr and Fr equal the direct
    condensation of the unreduced ND operators (the interior is small, so the
    Craig–Bampton basis keeps every mode and is exact)."""
    b = sector_bundle(N)
    cyc = reduce_cyclic(b, 3, 2)
    c = condense(relative_coordinates(cyc), 2.7, 2)
    for j, nd in ((1, 3), (2, 1)):
        Zr, Fr = _direct(b, nd, j, 2.7)
        np.testing.assert_allclose(c.Zr[j], Zr, rtol=0, atol=1e-10 * np.abs(Zr).max())
        np.testing.assert_allclose(c.Fr[j], Fr, rtol=0, atol=1e-10 * max(np.abs(Fr).max(), 1.0))
    assert np.abs(c.Zr[1] - c.Zr[1].T).max() > 1e-3 * np.abs(c.Zr[1]).max()   # not complex symmetric


def test_omega_derivatives_of_hermitian_nodal_diameters_match_finite_differences():
    """The general formula (D_ry D_yy⁻¹ ≠ Aᵀ when D is not complex symmetric)."""
    rc = relative_coordinates(reduce_cyclic(sector_bundle(N), 1, 3))
    w, h = 2.3, 1e-6
    c = condense(rc, w, 3, derivative=True)
    cp, cm = condense(rc, w + h, 3), condense(rc, w - h, 3)
    np.testing.assert_allclose(c.dZr, (cp.Zr - cm.Zr) / (2 * h), rtol=0, atol=1e-6 * np.abs(c.dZr).max())
    np.testing.assert_allclose(c.dFr, (cp.Fr - cm.Fr) / (2 * h), rtol=0, atol=1e-6 * np.abs(c.dFr).max())


def test_recovery_solves_the_nd_equations():
    """The observed tip from U_r: the ND-k sector equations hold with λ = Fr − Zr Ur."""
    b = sector_bundle(N)
    cyc = reduce_cyclic(b, 2, 1)
    rc = relative_coordinates(cyc)
    w = 1.9
    rng = np.random.default_rng(1)
    Ur = rng.standard_normal((2, 6)) + 1j * rng.standard_normal((2, 6))
    Ur[0] = Ur[0].real
    tip = recover(rc, w, Ur)
    T, K, M, C, kept = sector_matrices(b, 2)
    D = (K - w ** 2 * M + 1j * w * C).toarray()
    B = (contact_map(b) @ T).toarray()
    lam = condense(rc, w, 1).Fr[1] - condense(rc, w, 1).Zr[1] @ Ur[1]
    # solve the unreduced sector for u with B u = Ur and D u + Bᴴ λ = f: consistent iff the tip matches
    f = T.conj().T @ b.loads.harmonic
    u = np.linalg.solve(D, f - B.conj().T @ lam)
    np.testing.assert_allclose(B @ u, Ur[1], atol=1e-10)
    obs = np.searchsorted(kept, b.loads.observe)
    np.testing.assert_allclose(tip[1], u[obs], atol=1e-10)


def test_tied_frequencies_of_the_reduced_nd_models_equal_the_sector_operators():
    b = sector_bundle(N)
    cyc = reduce_cyclic(b, 1, 2)
    for k, m in cyc.models.items():
        ref = tied_frequencies(b, k, 4)
        np.testing.assert_allclose(reduced_tied_frequencies(m, 4), ref, rtol=1e-9)
    # …and the union over k of the ND spectra is the full disk's (ND k and N−k alike)
    f1, f4 = tied_frequencies(b, 1, 4), tied_frequencies(b, 4, 4)
    np.testing.assert_allclose(f1, f4, rtol=1e-9)


def test_save_load_roundtrip_and_validation(tmp_path):
    cyc = reduce_cyclic(sector_bundle(N), 3, 3)
    cyc.save(tmp_path / "c.npz")
    back = CyclicReducedModel.load(tmp_path / "c.npz")
    assert back.engine_order == 3 and back.n_sectors == N and sorted(back.models) == [0, 1, 3, 4]
    for k in cyc.models:
        np.testing.assert_array_equal(back.models[k].K, cyc.models[k].K)
    c1, c2 = condense(relative_coordinates(cyc), 2.0, 3), condense(relative_coordinates(back), 2.0, 3)
    np.testing.assert_array_equal(c1.Zr, c2.Zr)
    back.models[1].K = back.models[1].K + 1j * np.triu(np.ones_like(back.models[1].K.real), 1)
    with pytest.raises(BundleError, match="ND 1: K is not Hermitian"):
        back.validate()
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(BundleError, match="cannot be read"):
        CyclicReducedModel.load(tmp_path / "bad.npz")


def test_refusals_name_the_cause():
    b = sector_bundle(N)
    b.cyclic = None
    with pytest.raises(BundleError, match="no cyclic.npz"):
        reduce_cyclic(b, 1, 1)
    b = sector_bundle(N)
    b.loads.observe = np.array([0, 1, 2])  # the low cyclic face's node
    with pytest.raises(BundleError, match="on a cyclic face"):
        reduce_cyclic(b, 1, 1)


def test_fixed_interface_modes_of_a_hermitian_interior_by_eigsh():
    """Beyond the dense size: eigsh shift-invert on a complex Hermitian pencil,
    M-orthonormal, against dense eigh."""
    import scipy.sparse as sp

    from reduction import cyclic_reduce

    rng = np.random.default_rng(0)
    n = 300
    A = rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n))
    K = A @ A.conj().T + n * np.eye(n)
    M = np.eye(n) + 0.1 * np.diag(rng.random(n))
    V, w = cyclic_reduce.craig_bampton_hermitian(sp.csr_matrix(M), sp.csr_matrix(K), np.arange(3), 5)
    Phi = V[3:, 3:]
    np.testing.assert_allclose(Phi.conj().T @ M[3:, 3:] @ Phi, np.eye(5), atol=1e-10)
    ref = sla.eigh(K[3:, 3:], M[3:, 3:], eigvals_only=True)[:5]
    np.testing.assert_allclose(w ** 2, ref, rtol=1e-10)


def test_harmonics_beyond_the_reduced_nodal_diameters_are_refused_naming_the_key():
    from workflow.errors import SceneError
    from workflow.stages.hb import cyclic_check

    cyc = reduce_cyclic(sector_bundle(N), 3, 1)
    assert cyclic_check(cyc, 1) == {"n_sectors": N, "engine_order": 3, "nodal_diameters": [0, 3]}
    with pytest.raises(SceneError, match=r"nodal diameters \[1\].*reduction.cyclic_harmonics to ≥ 2"):
        cyclic_check(cyc, 2)
    assert cyclic_check(reduce_cyclic(sector_bundle(N), 0, 1), 5)["nodal_diameters"] == [0] * 6  # EO 0: all ND 0
