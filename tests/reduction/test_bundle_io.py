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
