"""A user's bundle is checked before it is solved (issue 18, items 3 and 13).

Symmetry of M, K, C; positive definiteness of the stiffness with the
interface tied and the clamped DOFs removed (a floating structure, K = −K
and an indefinite K − ω²M all fail, naming the file); distinct blade and
disk DOFs; an optional per-pair friction coefficient carried to the
reduced model. The block Lanczos stops with an error instead of growing
its basis towards n on a matrix it cannot converge on.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import lattice
from reduction.bundle import Bundle, Contact, Loads, check_definite, read_bundle, tied_map, write_bundle
from reduction.craig_bampton import SparseFactor, fixed_interface_modes
from reduction.reduce import reduce_bundle
from workflow.engine.model import ReducedModel
from workflow.errors import BundleError, SolverError


def _with(b: Bundle, **kw) -> Bundle:
    fields = dict(M=b.M, K=b.K, C=b.C, contact=b.contact, loads=b.loads, meta=b.meta, coords=b.coords, path=b.path)
    fields.update(kw)
    return Bundle(**fields)


@pytest.fixture(scope="module")
def lat():
    return lattice.lattice_bundle()


def test_good_bundle_passes_and_tied_map_ties_pairs(lat):
    info = check_definite(lat)
    assert info["method"] == "eigenvalues" and 0 < info["min_ratio"] < 1
    T = tied_map(lat)
    c = lat.contact
    # blade and disk DOF of a pair map to the same tied DOF; clamped DOFs to none
    for k in range(c.n_pairs):
        assert (T[c.blade_dofs[k]] != T[c.disk_dofs[k]]).nnz == 0
    assert T[lat.loads.fixed].nnz == 0
    # the tied system has n − clamped − (tied pairs' blade DOFs, whose disk partners are free) DOFs
    assert T.shape[1] == lat.n_dofs - lat.loads.fixed.size - 3 * c.n_pairs


@pytest.mark.parametrize("name", ["M", "K", "C"])
def test_non_symmetric_matrix_names_file(lat, tmp_path, name):
    A = sp.lil_matrix(getattr(lat, name))
    i, j = 7, 12
    A[i, j] = A[i, j] + 1e-3 * abs(getattr(lat, name)).max()
    path = tmp_path / "b"
    write_bundle(lat, path)
    sp.save_npz(path / f"{name}.npz", sp.csr_matrix(A))   # broken on disk, as a user's tool might
    with pytest.raises(BundleError, match=rf"{name}\.npz is not symmetric"):
        read_bundle(path)


def test_symmetry_tolerance_accepts_round_off(lat):
    K = lat.K + sp.csr_matrix(([1e-12 * abs(lat.K).max()], ([3], [5])), shape=lat.K.shape)
    from reduction.bundle import validate

    validate(_with(lat, K=K))


@pytest.mark.parametrize("kind, needle", [
    ("negative", "negative eigenvalue"),
    ("dynamic", "negative eigenvalue"),       # K − (2π·1 kHz)² M: indefinite, used to give a wrong FRF
    ("floating", "the structure floats"),     # no clamped DOF: rigid-body modes
])
def test_not_positive_definite(lat, kind, needle):
    if kind == "negative":
        b = _with(lat, K=-lat.K)
    elif kind == "dynamic":
        b = _with(lat, K=sp.csr_matrix(lat.K - (2 * np.pi * 1e3) ** 2 * lat.M))
    else:
        L = lat.loads
        b = _with(lat, loads=Loads(fixed=np.zeros(0, int), static=L.static, harmonic=L.harmonic, observe=L.observe))
    with pytest.raises(BundleError, match=needle):
        check_definite(b)


def test_large_bundle_uses_ldlt_inertia(lat, monkeypatch):
    import reduction.bundle as rb

    monkeypatch.setattr(rb, "DENSE_CHECK", 10)
    assert check_definite(lat)["method"] == "ldlt-inertia"
    with pytest.raises(BundleError, match="not positive definite"):
        check_definite(_with(lat, K=sp.csr_matrix(lat.K - (2 * np.pi * 1e3) ** 2 * lat.M)))
    L = lat.loads
    with pytest.raises(BundleError, match="floats"):
        check_definite(_with(lat, loads=Loads(fixed=np.zeros(0, int), static=L.static, harmonic=L.harmonic,
                                              observe=L.observe)))


def test_grounded_pairs_hold_a_structure_without_clamps():
    # every pair grounded (disk side −1): the blade is held by the contact alone, which is a valid model
    b = lattice.lattice_bundle(grounded_pairs=6)
    assert np.all(b.contact.disk_dofs == -1)
    assert check_definite(b)["tied_dofs"] > 0


def test_same_dof_on_both_sides_is_named(lat):
    c = lat.contact
    disk = c.disk_dofs.copy()
    disk[2] = c.blade_dofs[2]
    from reduction.bundle import validate

    with pytest.raises(BundleError, match="pair 2 has the same DOF in blade_dofs and disk_dofs"):
        validate(_with(lat, contact=Contact(**{**c.__dict__, "disk_dofs": disk})))


@pytest.mark.parametrize("mu", [np.array([0.3, -0.1, 0.3, 0.3, 0.3, 0.3]), np.full(6, np.nan), np.full(4, 0.3)])
def test_bad_per_pair_mu(lat, mu):
    from reduction.bundle import validate

    with pytest.raises(BundleError, match="mu must be"):
        validate(_with(lat, contact=Contact(**{**lat.contact.__dict__, "mu": mu})))


def test_per_pair_mu_round_trip_and_reduction(lat, tmp_path):
    mu = np.linspace(0.1, 0.6, lat.contact.n_pairs)
    b = _with(lat, contact=Contact(**{**lat.contact.__dict__, "mu": mu}))
    write_bundle(b, tmp_path / "b")
    back = read_bundle(tmp_path / "b")
    np.testing.assert_array_equal(back.contact.mu, mu)
    red = reduce_bundle(back, n_modes=6)
    np.testing.assert_array_equal(red.mu, mu)
    red.save(tmp_path / "r.npz")
    again = ReducedModel.load(tmp_path / "r.npz")
    got, source = again.friction(0.5)
    np.testing.assert_array_equal(got, mu)
    assert source == "bundle contact.npz"
    # without μ in the bundle the scene's applies on every pair; old files (no "mu") still load
    plain = reduce_bundle(lat, n_modes=6)
    assert plain.mu is None
    plain.save(tmp_path / "p.npz")
    got, source = ReducedModel.load(tmp_path / "p.npz").friction(0.25)
    np.testing.assert_array_equal(got, np.full(lat.contact.n_pairs, 0.25))
    assert source == "scene contact.mu"


def test_too_many_modes_names_the_key(lat):
    with pytest.raises(SolverError, match=r"reduction\.modes"):
        reduce_bundle(lat, n_modes=100000)


def test_lanczos_gives_up_instead_of_growing_to_n():
    """A non-symmetric K (which validation now refuses) used to run the block Lanczos towards n."""
    n = 1200
    K = sp.diags(np.linspace(1.0, 2.0, n)) + sp.random(n, n, density=0.01, random_state=2) * 2.0
    M = sp.identity(n, format="csr")
    f = SparseFactor(sp.csr_matrix(K), "splu")
    with pytest.raises(SolverError, match="no converged fixed-interface modes"):
        fixed_interface_modes(sp.csr_matrix(K), M, f, n_modes=10, tol=1e-12)
