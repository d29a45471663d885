"""Contact pairs: partners coincide, frames, tributary areas, ordering, errors."""
import numpy as np
import pytest

import meshes
from reduction import dolfinx_compat as dc
from reduction.pairs import contact_pairs
from workflow.errors import GeometryError


@pytest.fixture(scope="module")
def pairs(dovetail_mesh):
    mesh, _, ft = dovetail_mesh
    V = dc.vector_space(mesh, 2)
    return contact_pairs(V, ft), dc.gather_block_coordinates(V)


def test_partners_coincide_and_are_vertices(pairs, dovetail):
    p, X = pairs
    b, d = p["blade_dofs"], p["disk_dofs"]
    assert b.shape == d.shape == (len(p["area"]), 3) and len(p["area"]) > 10
    np.testing.assert_array_equal(b % 3, np.tile([0, 1, 2], (len(b), 1)))
    np.testing.assert_array_equal(b[:, 1:] - b[:, :1], np.tile([1, 2], (len(b), 1)))
    np.testing.assert_allclose(X[b[:, 0] // 3], X[d[:, 0] // 3], atol=1e-12)
    np.testing.assert_allclose(X[d[:, 0] // 3], p["position"], atol=1e-15)
    assert len(np.intersect1d(b, d)) == 0  # separate nodes: the bodies are not fused


def test_frames_orthonormal_with_normal_into_blade(pairs):
    p, _ = pairs
    R = np.stack([p["normal"], p["t1"], p["t2"]], axis=1)
    np.testing.assert_allclose(np.einsum("pij,pkj->pik", R, R), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)  # right-handed
    # Test dovetail (meshes.DOVETAIL): flanks rise 4 in z per 3 in y; the blade
    # is on the neck side, so n = (0, ±0.8, −0.6) — inwards and down.
    for f, sy in ((0, 1.0), (1, -1.0)):
        np.testing.assert_allclose(p["normal"][p["flank"] == f], np.tile([0, 0.8 * sy, -0.6], (np.sum(p["flank"] == f), 1)),
                                   atol=1e-12)
    assert np.all(np.abs(p["t1"][:, 0] - 1) < 1e-12)  # x lies in the flank plane
    assert np.all(p["position"][p["flank"] == 0, 1] < 0)  # intrados = −y


def test_tributary_areas_sum_to_flank_area(pairs, dovetail):
    p, _ = pairs
    assert np.all(p["area"] > 0)
    assert p["area"].sum() == pytest.approx(dovetail[1]["flank_area_m2"], rel=1e-12)
    for f in (0, 1):
        assert p["area"][p["flank"] == f].sum() == pytest.approx(dovetail[1]["flank_area_m2"] / 2, rel=1e-12)
    np.testing.assert_array_equal(p["gap"], 0.0)


def test_ordering_flank_then_x(pairs):
    p, _ = pairs
    assert np.all(np.diff(p["flank"]) >= 0)
    for f in (0, 1):
        x = p["position"][p["flank"] == f, 0]
        assert np.all(np.diff(x) >= -1e-12)


def test_unmatched_flank_meshes_raise(tmp_path):
    path = tmp_path / "broken.msh"
    meshes.dovetail_msh(path, h=0.004, periodic=False)
    mesh, _, ft = dc.read_msh(path)
    with pytest.raises(GeometryError, match="flank"):
        contact_pairs(dc.vector_space(mesh, 2), ft)


def test_build_bundle_accepts_given_pairs(dovetail, dovetail_mesh, pairs):
    """``pairs=`` overrides the vertex matching (the remap's worn mesh uses the unworn pairs)."""
    from conftest import TI
    from reduction.assemble import build_bundle

    given = {k: v.copy() for k, v in pairs[0].items()}
    given["area"] = given["area"] * 2.0
    b, _ = build_bundle(*dovetail_mesh, dovetail[1], TI, damping=dict(modal_ratio=0.0), pairs=given)
    np.testing.assert_array_equal(b.contact.area, given["area"])
