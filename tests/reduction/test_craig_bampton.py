"""Craig–Bampton basis: mathematical properties on a two-body lattice."""
import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

import lattice
from reduction.craig_bampton import craig_bampton
from reduction.reduce import boundary_dofs
from workflow.errors import SolverError


def _split(bundle):
    """(M, K on free DOFs, boundary indices into them, free DOFs)."""
    free = bundle.free_dofs
    local = -np.ones(bundle.n_dofs, dtype=int)
    local[free] = np.arange(free.size)
    return bundle.M[free][:, free], bundle.K[free][:, free], local[boundary_dofs(bundle)], free


@pytest.fixture(scope="module")
def parts():
    return _split(lattice.lattice_bundle())


def test_modal_blocks_are_identity_and_diagonal(parts):
    M, K, b, free = parts
    loads = np.random.default_rng(0).standard_normal((M.shape[0], 1))
    V, w = craig_bampton(M, K, b, 12, loads=loads)
    nb, nm = b.size, w.size
    Mr, Kr = V.T @ M @ V, V.T @ K @ V
    interior = slice(nb, V.shape[1])  # modes + load vector
    np.testing.assert_allclose(Mr[interior, interior], np.eye(nm + 1), atol=1e-12)
    np.testing.assert_allclose(Kr[nb:nb + nm, nb:nb + nm], np.diag(w ** 2), rtol=1e-10, atol=1e-8 * w[-1] ** 2)
    # constraint modes are K-orthogonal to everything with the boundary held
    assert np.abs(Kr[:nb, nb:]).max() < 1e-9 * np.abs(Kr).max()
    np.testing.assert_array_equal(V[b, np.arange(nb)], 1.0)
    assert np.all(V[b][:, nb:] == 0)


def test_fixed_interface_frequencies_match_dense_and_slepc(parts):
    M, K, b, _ = parts
    mask = np.ones(M.shape[0], bool)
    mask[b] = False
    w2 = sla.eigh(K[mask][:, mask].toarray(), M[mask][:, mask].toarray(), eigvals_only=True)[:15]
    _, w = craig_bampton(M, K, b, 15)
    _, ws = craig_bampton(M, K, b, 15, eigensolver="slepc")
    # Lanczos stops at ‖ω²K⁻¹Mφ − φ‖_M ≤ MODE_TOL = 1e-6: ω² to MODE_TOL²/(relative gap) ≤ 1.2e-10 here
    # (gaps of 1/ω² ≥ 0.87 % among the lowest 30); SLEPc's tolerance is 1e-10 (reduction.eigen)
    np.testing.assert_allclose(w ** 2, w2, rtol=1e-9)
    np.testing.assert_allclose(ws ** 2, w2, rtol=1e-9)


def test_cutoff_keeps_exactly_the_modes_below_it(parts):
    M, K, b, _ = parts
    _, w_all = craig_bampton(M, K, b, 30)
    cut = 0.5 * (w_all[17] + w_all[18]) / (2 * np.pi)
    V, w = craig_bampton(M, K, b, None, cutoff_hz=cut)
    assert w.size == 18 and V.shape[1] == b.size + 18
    np.testing.assert_allclose(w, w_all[:18], rtol=1e-9)


def test_splu_and_mumps_give_the_same_basis(parts):
    M, K, b, _ = parts
    V1, w1 = craig_bampton(M, K, b, 6, solver="mumps")
    V2, w2 = craig_bampton(M, K, b, 6, solver="splu")
    nb = b.size
    np.testing.assert_allclose(V1[:, :nb], V2[:, :nb], atol=1e-10 * np.abs(V1[:, :nb]).max())
    np.testing.assert_allclose(w1, w2, rtol=1e-9)


def test_static_exactness_with_contact_springs():
    """Boundary + distributed static loads: reduced static solution = full one, to round-off.

    Contact as linear springs (λ = k_c u_r) acting on boundary DOFs only; the
    distributed load is exact through its load vector.
    """
    bundle = lattice.lattice_bundle()
    M, K, b, free = _split(bundle)
    S = lattice.contact_operator(bundle)[:, free]
    kc = np.tile([5e6, 1e6, 1e6], bundle.contact.n_pairs)
    Kfull = (K + S.T @ sp.diags(kc) @ S).toarray()
    rng = np.random.default_rng(1)
    f = np.zeros(M.shape[0])
    f[b] = rng.standard_normal(b.size)  # loads on boundary DOFs
    f_dist = bundle.loads.static[free]  # a load on (almost) every blade DOF
    V, _ = craig_bampton(M, K, b, 3, loads=f_dist)
    for load in (f, f + f_dist):
        u = np.linalg.solve(Kfull, load)
        q = np.linalg.solve(V.T @ Kfull @ V, V.T @ load)
        np.testing.assert_allclose(V @ q, u, atol=1e-10 * np.abs(u).max())


def test_floating_interior_is_reported():
    """Without the contact DOFs on the boundary the blade floats: K_ii is singular."""
    bundle = lattice.lattice_bundle()
    M, K, _, free = _split(bundle)
    local = -np.ones(bundle.n_dofs, dtype=int)
    local[free] = np.arange(free.size)
    with pytest.raises(SolverError):
        craig_bampton(M, K, local[bundle.loads.observe], 4, solver="splu")
