"""The cyclic sector (geometry.cyclic = true): periodic cut faces; the default mesh unchanged."""
from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

COARSE = dict(h_blade=0.006, h_disk=0.010, h_airfoil=0.009)
#: sha256 and node count of the coarse default (cyclic = false) sector written by the code before
#: geometry.cyclic existed (commit 9dfec82): the flag must not change the paper's mesh.
DEFAULT_SHA256 = "056cc7a4b2aecf1e9865c59f987c7513df276127a25f9950e4cc5fa9ac73bc5b"
DEFAULT_NODES = 3944


def _rot(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


@pytest.fixture(scope="module")
def cyclic47(tmp_path_factory, read_msh):
    from geometry.params import SectorParams
    from geometry.sector import build_sector

    path = tmp_path_factory.mktemp("cyc") / "c.msh"
    info = build_sector(SectorParams(cyclic=True, **COARSE), path)
    return info, read_msh(path)


def test_default_sector_is_unchanged(tmp_path):
    """(d) cyclic = false writes byte-for-byte the mesh of before."""
    from geometry.params import SectorParams
    from geometry.sector import build_sector

    info = build_sector(SectorParams(**COARSE), tmp_path / "d.msh")
    assert info["n_nodes"] == DEFAULT_NODES
    assert hashlib.sha256((tmp_path / "d.msh").read_bytes()).hexdigest() == DEFAULT_SHA256
    assert "cyclic_low" not in info["groups"]


def test_every_low_node_has_its_rotated_image_on_the_high_face(cyclic47):
    info, mesh = cyclic47
    assert info["groups"]["cyclic_low"] == [2, 51] and info["groups"]["cyclic_high"] == [2, 52]
    low, high = mesh.xyz(mesh.nodes("cyclic_low")), mesh.xyz(mesh.nodes("cyclic_high"))
    assert len(low) == len(high) == info["cyclic_nodes"] > 20
    d, idx = cKDTree(high).query(low @ _rot(2 * math.pi / 47).T)
    assert d.max() < 1e-12 and np.unique(idx).size == len(low)
    # the faces are the cut planes at ±π/N through the x axis (low: +y, high: −y)
    h = math.pi / 47
    np.testing.assert_allclose(low[:, 1] * math.cos(h) - low[:, 2] * math.sin(h), 0, atol=1e-12)
    np.testing.assert_allclose(high[:, 1] * math.cos(h) + high[:, 2] * math.sin(h), 0, atol=1e-12)


def test_cyclic_faces_are_disk_only_and_the_rest_is_the_same_sector(cyclic47, default_sector):
    info, mesh = cyclic47
    blade = mesh.nodes("blade")
    assert not np.intersect1d(blade, mesh.nodes("cyclic_low")).size
    assert not np.intersect1d(blade, mesh.nodes("cyclic_high")).size
    assert set(mesh.nodes("cyclic_low")) <= set(mesh.nodes("disk"))
    assert info["cyclic_blade_clearance"] > 1e-3
    assert info["contact_pairs"] == default_sector[0]["contact_pairs"]


def test_blade_reaching_a_cut_is_refused(monkeypatch, tmp_path):
    """The mesh check: a blade node on a cut plane is a GeometryError."""
    import geometry.cyclic as gc
    from geometry.params import SectorParams
    from geometry.sector import build_sector
    from workflow.errors import GeometryError

    real = gc.check
    monkeypatch.setattr(gc, "check", lambda n, blade, r: real(n, (3, 2), r))   # the disk touches both cuts
    with pytest.raises(GeometryError, match="reaches a cyclic face"):
        build_sector(SectorParams(cyclic=True, **COARSE), tmp_path / "x.msh")
    assert not (tmp_path / "x.msh").exists()


def test_cyclic_must_be_a_boolean():
    from geometry.params import SectorParams, check_params
    from workflow.errors import GeometryError

    with pytest.raises(GeometryError, match="geometry.cyclic"):
        check_params(SectorParams(cyclic=1))
