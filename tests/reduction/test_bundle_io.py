"""The assembled bundle: written, read back, loads and damping as specified."""
import json

import numpy as np
import pytest

from reduction import dolfinx_compat as dc
from reduction.bundle import read_bundle
from reduction.modes import frequencies, modes
from workflow.errors import GeometryError


def test_round_trip(rotating_bundle, tmp_path):
    from reduction.bundle import write_bundle

    b, summary, info = rotating_bundle
    assert (b.path / "mesh.xdmf").is_file() and (b.path / "mesh.h5").is_file()
    meta = json.loads((b.path / "meta.json").read_text())
    write_bundle(b, tmp_path / "copy")
    c = read_bundle(tmp_path / "copy")
    for name in ("M", "K", "C"):
        assert abs(getattr(b, name) - getattr(c, name)).max() == 0.0
    for k in ("blade_dofs", "disk_dofs", "normal", "t1", "t2", "area", "gap", "flank", "position"):
        np.testing.assert_array_equal(getattr(b.contact, k), getattr(c.contact, k))
    for k in ("fixed", "static", "harmonic", "observe"):
        np.testing.assert_array_equal(getattr(b.loads, k), getattr(c.loads, k))
    np.testing.assert_array_equal(b.coords, c.coords)
    assert c.meta["n_dofs"] == b.n_dofs == summary["n_dofs"]
    assert meta["material"]["young"] == 110e9 and meta["omega_rad_s"] == pytest.approx(10000 * np.pi / 30)
    assert set(meta["timings"]) >= {"mesh_read_s", "assembly_s", "prestress_s", "pairs_s"}


def test_loads(rotating_bundle):
    b, summary, info = rotating_bundle
    L = b.loads
    # Clamp: every DOF on the z = 0 face of the disk.
    z0 = np.flatnonzero(np.abs(b.coords[:, 2]) < 1e-12)
    np.testing.assert_array_equal(np.sort(L.fixed), np.sort((3 * z0[:, None] + np.arange(3)).ravel()))
    # Harmonic: 0.1 N along the excitation direction at the tip block, observed there.
    tip = L.observe[0] // 3
    np.testing.assert_array_equal(L.observe, 3 * tip + np.arange(3))
    np.testing.assert_allclose(b.coords[tip], info["tip_point"], atol=1e-12)
    np.testing.assert_allclose(L.harmonic[L.observe], [0.1, 0, 0])
    assert np.count_nonzero(L.harmonic) == 1
    # Centrifugal: Σ f_z = ρ Ω² ∫ z dV > 0, no axial resultant.
    fz = L.static.reshape(-1, 3).sum(axis=0)
    assert fz[2] > 0 and abs(fz[0]) < 1e-9 * fz[2]


def test_rotation_raises_tied_frequency_and_modal_damping(rotating_bundle):
    b, summary, _ = rotating_bundle
    f, w2, phi = modes(b, 1, tied=True)
    assert f[0] == pytest.approx(summary["first_tied_hz"], rel=1e-8)
    # ζ₁ = φᵀCφ / (2ω₁) with mass-normalised φ
    zeta = phi[:, 0] @ (b.C @ phi[:, 0]) / (2 * np.sqrt(w2[0]))
    assert zeta == pytest.approx(0.002, rel=1e-6)
    # Frames / pairs made it into the bundle: tied ≠ free (the free blade floats).
    free = frequencies(b, 4, tied=False)
    assert free[0] < 1e-3 * f[0]


def test_read_msh_tags(dovetail, dovetail_mesh):
    mesh, ct, ft = dovetail_mesh
    np.testing.assert_array_equal(dc.tag_values(ct), [1, 2])
    np.testing.assert_array_equal(dc.tag_values(ft), [11, 12, 21, 22, 31, 41])
    assert dc.geometry_degree(mesh) == 2
    idx = dc.input_global_indices(mesh)
    assert len(idx) == mesh.geometry.x.shape[0] and len(np.unique(idx)) == len(idx)


def test_read_msh_errors(tmp_path):
    with pytest.raises(GeometryError, match="does not exist"):
        dc.read_msh(tmp_path / "nope.msh")
    (tmp_path / "bad.msh").write_text("not a mesh\n")
    with pytest.raises(GeometryError, match="bad.msh"):
        dc.read_msh(tmp_path / "bad.msh")


def test_canonical_order_is_a_relabelling_that_undoes_any_permutation():
    """reduction.bundle.canonical_order sorts DOF blocks by position (coincident nodes by their
    neighbours in K): a bundle and any node permutation of it give the same canonical bundle,
    and the physics (a K quadratic form, the loads on the contact DOFs) is unchanged."""
    import scipy.sparse as sp

    from reduction.bundle import Bundle, Contact, Loads, canonical_order

    rng = np.random.default_rng(3)
    nodes = 6
    coords = rng.random((nodes, 3))
    coords[5] = coords[4]                        # two coincident nodes (a matched flank pair)
    n = 3 * nodes
    K = sp.random(n, n, density=0.3, random_state=1)
    K = (K + K.T + n * sp.eye(n)).tocsr()
    K = K.tolil()
    K[12, 0] = K[0, 12] = 1.0                   # node 4 touches node 0, node 5 does not: they differ
    K[15, 0] = K[0, 15] = 0.0
    K = K.tocsr()
    K.eliminate_zeros()
    M = sp.eye(n, format="csr")
    contact = Contact(blade_dofs=np.array([[12, 13, 14]]), disk_dofs=np.array([[15, 16, 17]]),
                      normal=np.array([[0, 0, 1.0]]), t1=np.array([[1.0, 0, 0]]), t2=np.array([[0, 1.0, 0]]),
                      area=np.ones(1), gap=np.zeros(1))
    loads = Loads(fixed=np.array([0, 1, 2]), static=rng.random(n), harmonic=rng.random(n), observe=np.array([6, 7, 8]))
    b0 = Bundle(M=M, K=K, C=0.01 * K, contact=contact, loads=loads, coords=coords)
    perm_nodes = rng.permutation(nodes)
    p = (3 * perm_nodes[:, None] + np.arange(3)).ravel()
    inv = np.argsort(p)
    b1 = Bundle(M=M[p][:, p], K=K[p][:, p].tocsr(), C=0.01 * K[p][:, p].tocsr(),
                contact=Contact(blade_dofs=inv[contact.blade_dofs], disk_dofs=inv[contact.disk_dofs],
                                normal=contact.normal, t1=contact.t1, t2=contact.t2, area=contact.area, gap=contact.gap),
                loads=Loads(fixed=np.sort(inv[loads.fixed]), static=loads.static[p], harmonic=loads.harmonic[p],
                            observe=inv[loads.observe]), coords=coords[perm_nodes])
    c0, c1 = canonical_order(b0), canonical_order(b1)
    np.testing.assert_array_equal(c0.coords, c1.coords)
    assert abs(c0.K - c1.K).max() == 0 and abs(c0.M - c1.M).max() == 0
    for a, b in ((c0.contact.blade_dofs, c1.contact.blade_dofs), (c0.contact.disk_dofs, c1.contact.disk_dofs),
                 (c0.loads.fixed, c1.loads.fixed), (c0.loads.observe, c1.loads.observe),
                 (c0.loads.static, c1.loads.static)):
        np.testing.assert_array_equal(a, b)
    # a relabelling: every DOF keeps its node — the contact and observed nodes sit where they were,
    # and a node's load and stiffness travel with it
    assert np.array_equal(c0.coords[c0.contact.blade_dofs[0, 0] // 3], coords[4])
    assert np.array_equal(c0.coords[c0.loads.observe[0] // 3], coords[2])
    j = int(np.flatnonzero(np.all(c0.coords == coords[3], axis=1))[0])
    np.testing.assert_array_equal(c0.loads.static[3 * j:3 * j + 3], loads.static[9:12])
    assert c0.K[3 * j, 3 * j] == K[9, 9]
