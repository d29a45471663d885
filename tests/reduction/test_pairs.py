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


# ------------------------------------------------- every node: the linear contact layer

def test_linear_layer_of_one_flat_p2_triangle():
    """Corners get A/12, midsides A/4 (all positive, sum A); Σ A_i x_i = A · centroid."""
    from reduction.pairs import linear_layer, lump_to_nodes

    v = np.array([[0.0, 0.0, 0.0], [3.0, 0.5, 0.2], [0.7, 2.0, -0.4]])
    x6 = np.concatenate([v, 0.5 * (v + np.roll(v, -1, axis=0))])  # v0 v1 v2 m01 m12 m20
    A = 0.5 * np.linalg.norm(np.cross(v[1] - v[0], v[2] - v[0]))
    corners, a, n = linear_layer(x6[None])
    np.testing.assert_allclose(a, A / 4, rtol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=1e-14)
    lumped, nsum = lump_to_nodes(x6, corners, a, n, tol=1e-12)
    np.testing.assert_allclose(lumped, A * np.array([1, 1, 1, 3, 3, 3]) / 12, rtol=1e-14)
    np.testing.assert_allclose(lumped @ x6, A * v.mean(axis=0), rtol=1e-14)
    np.testing.assert_allclose(nsum.sum(axis=0), A * n[0], rtol=1e-14)


def test_lump_refuses_a_corner_that_is_no_node():
    from reduction.pairs import linear_layer, lump_to_nodes

    v = np.eye(3)
    x6 = np.concatenate([v, 0.5 * (v + np.roll(v, -1, axis=0))])
    corners, a, n = linear_layer(x6[None])
    with pytest.raises(GeometryError, match="not a contact node"):
        lump_to_nodes(x6[:5], corners, a, n, tol=1e-9)


@pytest.fixture(scope="module")
def all_pairs(dovetail_mesh):
    mesh, _, ft = dovetail_mesh
    V = dc.vector_space(mesh, 2)
    return contact_pairs(V, ft, nodes="all"), dc.gather_block_coordinates(V)


def test_all_layout_pairs_every_flank_node(all_pairs, pairs, dovetail_mesh):
    p, X = all_pairs
    mesh, _, ft = dovetail_mesh
    V = dc.vector_space(mesh, 2)
    for f, (gb, gd) in enumerate(((11, 21), (12, 22))):
        sel = p["flank"] == f
        assert sel.sum() == len(dc.blocks_on_facets(V, ft, gd)) == len(dc.blocks_on_facets(V, ft, gb))
    np.testing.assert_allclose(X[p["blade_dofs"][:, 0] // 3], X[p["disk_dofs"][:, 0] // 3], atol=1e-12)
    # The vertices are exactly the pairs of the vertex layout; the rest are midside nodes.
    np.testing.assert_allclose(p["position"][p["vertex"]], pairs[0]["position"], atol=1e-15)
    assert (~p["vertex"]).sum() > p["vertex"].sum()


def test_all_layout_areas_integrate_a_uniform_pressure_exactly(all_pairs, dovetail_mesh):
    """Σ A_i = flank area; Σ A_i n_i = ∫ n ds; Σ A_i x_i × n_i = ∫ x × n ds (force, moment), to round-off."""
    import ufl

    p, _ = all_pairs
    mesh, _, ft = dovetail_mesh
    _, ds = dc.measures(mesh, facet_tags=ft)
    x, n = ufl.SpatialCoordinate(mesh), ufl.FacetNormal(mesh)
    assert np.all(p["area"] > 0)
    for f, gd in ((0, 21), (1, 22)):
        s = p["flank"] == f
        a, nn, xx = p["area"][s], p["normal"][s], p["position"][s]
        area = dc.assemble_scalar(dc.constant(mesh, 1.0) * ds(gd))
        force = np.array([dc.assemble_scalar(n[i] * ds(gd)) for i in range(3)])
        moment = np.array([dc.assemble_scalar(ufl.cross(x, n)[i] * ds(gd)) for i in range(3)])
        assert abs(a.sum() - area) <= 1e-12 * area
        np.testing.assert_allclose(a @ nn, force, atol=1e-12 * area)
        np.testing.assert_allclose(a @ np.cross(xx, nn), moment, atol=1e-12 * area * np.abs(xx).max())


def test_all_layout_frames_match_the_flat_flank(all_pairs, pairs):
    p, _ = all_pairs
    for f in (0, 1):
        n0 = pairs[0]["normal"][pairs[0]["flank"] == f][0]
        np.testing.assert_allclose(p["normal"][p["flank"] == f], np.tile(n0, ((p["flank"] == f).sum(), 1)), atol=1e-12)
    R = np.stack([p["normal"], p["t1"], p["t2"]], axis=1)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)


def test_layout_follows_the_geometry_parameters(dovetail, dovetail_mesh, all_pairs):
    """build_bundle reads ``params.contact_nodes`` from the geometry info; a bad value names the key."""
    from conftest import TI
    from reduction.assemble import build_bundle

    info = dict(dovetail[1], params=dict(contact_nodes="all"))
    b, s = build_bundle(*dovetail_mesh, info, TI, damping=dict(modal_ratio=0.0))
    assert b.contact.n_pairs == len(all_pairs[0]["area"])
    assert s["flank_area_m2"] == pytest.approx(dovetail[1]["flank_area_m2"], rel=1e-12)
    with pytest.raises(GeometryError, match="contact_nodes"):
        build_bundle(*dovetail_mesh, dict(dovetail[1], params=dict(contact_nodes="edges")), TI)
