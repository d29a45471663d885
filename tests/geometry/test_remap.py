"""Wear back onto the geometry (geometry/remap.py, flankmap.py, jacobians.py).

A two-block dovetail (geometry/twoblock.py: separate bodies, node-matched
flanks, contracts §1 tags, quadratic tets) with its contact pairs from
reduction/pairs.py, and synthetic wear profiles.
"""
from __future__ import annotations

import numpy as np
import pytest

from geometry import remap as rm
from geometry.flankmap import interpolate_on_flank
from geometry.jacobians import cell_heights, jacobian_determinants, node_sizes, orientation_ratio
from workflow.errors import GeometryError

dolfinx = pytest.importorskip("dolfinx")


@pytest.fixture(scope="module")
def model():
    from geometry.twoblock import TwoBlockParams, build_two_block
    from reduction import dolfinx_compat as dc
    from reduction.pairs import contact_pairs

    msh, ct, ft = build_two_block(TwoBlockParams(h=0.003))
    cp = contact_pairs(dc.vector_space(msh, 2), ft)
    return msh, ct, ft, cp


def bump(cp, peak=1.0):
    """A smooth, flank-dependent wear profile [m] with maximum ``peak``."""
    pos = cp["position"]
    w = np.exp(-((pos[:, 0] - 0.012) / 0.006) ** 2) * (0.4 + pos[:, 2] / 0.008) * np.where(cp["flank"] == 1, 1, .6)
    return peak * w / w.max()


def pair_wear(cp, W, share=0.7):
    return rm.PairWear.from_total(cp["position"], cp["normal"], cp["flank"], W, share)


# ------------------------------------------------------------------ pure arrays

def test_flank_interpolation_exact_at_nodes_and_linear_between():
    rng = np.random.default_rng(0)
    # An inclined planar flank, structured 5 × 3 contact grid.
    a, b = np.array([1.0, 0, 0]), np.array([0, 0.6, 0.8])
    s, t = np.meshgrid(np.linspace(0, 0.02, 5), np.linspace(0, 0.005, 3), indexing="ij")
    nodes = np.array([0.1, 0.2, 0.3]) + s.reshape(-1, 1) * a + t.reshape(-1, 1) * b
    vals = rng.random(len(nodes))
    assert np.array_equal(interpolate_on_flank(nodes, vals, nodes[::-1]), vals[::-1])
    # A field linear in the flank plane is reproduced anywhere inside.
    lin = 3.0 + 40.0 * s.ravel() - 70.0 * t.ravel()
    u, v = rng.random(50) * 0.02, rng.random(50) * 0.005
    targets = np.array([0.1, 0.2, 0.3]) + u[:, None] * a + v[:, None] * b
    np.testing.assert_allclose(interpolate_on_flank(nodes, lin, targets), 3.0 + 40.0 * u - 70.0 * v, rtol=1e-12)


def test_jacobians_of_reference_and_flipped_tets():
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    d = jacobian_determinants(x, np.array([[0, 1, 2, 3], [1, 0, 2, 3]]))
    np.testing.assert_allclose(d[0], 1.0)
    np.testing.assert_allclose(d[1], -1.0)
    # Straight P2 tet (mid-edge nodes at the midpoints, basix edge order): same det.
    edges = [(2, 3), (1, 3), (1, 2), (0, 3), (0, 2), (0, 1)]
    x2 = np.vstack([x, [0.5 * (x[i] + x[j]) for i, j in edges]])
    np.testing.assert_allclose(jacobian_determinants(x2, np.arange(10)[None]), 1.0, rtol=1e-12)
    assert np.isclose(cell_heights(x, np.array([[0, 1, 2, 3]]))[0], 1 / np.sqrt(3))
    assert orientation_ratio(d[:1], 0.5 * d[:1])[0] == 0.5


# ------------------------------------------------------------------- on the mesh

def test_mapping_exact_at_contact_nodes(model):
    msh, _, ft, cp = model
    pw = pair_wear(cp, bump(cp, 20e-6))
    r = rm.remap_wear(msh, ft, pw, 0.3)
    x = r.x0
    for fs in r.flanks:
        sel = np.flatnonzero(cp["flank"] == fs.flank)
        d = np.linalg.norm(x[fs.nodes][:, None] - cp["position"][sel][None], axis=2)
        at = fs.nodes[np.argmin(d, axis=0)]
        assert np.min(d, axis=0).max() < 1e-12
        assert np.array_equal(r.wear[at], pw.share(fs.body)[sel])  # exact, not merely close
    # Mid-edge flank nodes carry interpolated values within the nodal range.
    assert r.wear.max() == max(pw.w_blade.max(), pw.w_disk.max())


def test_zero_wear_leaves_mesh_unchanged_bit_for_bit(model):
    msh, _, ft, cp = model
    before = np.array(msh.geometry.x, copy=True)
    r = rm.remap_wear(msh, ft, pair_wear(cp, np.zeros(len(cp["area"]))), 0.3)
    assert np.array_equal(r.x, before) and r.x.tobytes() == before.tobytes()
    assert r.max_node_motion == 0.0 and not r.info["solved"]
    assert np.array_equal(msh.geometry.x, before)


@pytest.mark.parametrize("smoothing", ["harmonic", "elastic"])
def test_motion_along_normals_max_equals_share_and_decays(model, smoothing):
    msh, _, ft, cp = model
    pw = pair_wear(cp, bump(cp, 20e-6), share=0.7)
    before = np.array(msh.geometry.x, copy=True)
    r = rm.remap_wear(msh, ft, pw, 0.3, smoothing)
    assert np.array_equal(msh.geometry.x, before)  # the mesh itself is not moved
    share_max = max(pw.w_blade.max(), pw.w_disk.max())
    np.testing.assert_allclose(r.max_node_motion, share_max, rtol=1e-12)
    # At flank nodes: along +n (blade) / −n (disk), by the body's share.
    for fs in r.flanks:
        sel = cp["flank"] == fs.flank
        n = cp["normal"][sel].mean(axis=0)
        m = r.motion[fs.nodes]
        np.testing.assert_allclose(m, rm.BODY_SIGN[fs.body] * r.wear[fs.nodes, None] * n, atol=1e-12 * share_max)
    # Inside: smaller than on the flanks, and decaying with the distance from them.
    flank = np.unique(np.concatenate([fs.nodes for fs in r.flanks]))
    inner = np.setdiff1d(np.arange(len(r.x0)), flank)
    mag = np.linalg.norm(r.motion, axis=1)
    assert mag[inner].max() < share_max
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(r.x0[flank]).query(r.x0[inner])
    bins = np.digitize(dist, [0.002, 0.004, 0.006])
    means = [mag[inner][bins == k].mean() for k in range(4) if np.any(bins == k)]
    assert len(means) >= 3
    assert all(a > b for a, b in zip(means, means[1:])), means
    assert r.orientation > 0.9


def test_no_inverted_cells_up_to_max_fraction(model):
    msh, _, ft, cp = model
    unit = rm.remap_wear(msh, ft, pair_wear(cp, bump(cp, 1e-6)), 0.3)
    scale = 0.95 * 0.3 / unit.max_fraction  # wear that reaches 95 % of the allowed fraction
    for smoothing in rm.SMOOTHING:
        r = rm.remap_wear(msh, ft, pair_wear(cp, bump(cp, scale * 1e-6)), 0.3, smoothing)
        assert 0.28 < r.max_fraction <= 0.3
        cells = np.asarray(msh.geometry.dofmap.array).reshape(-1, 10)
        ratio = orientation_ratio(jacobian_determinants(r.x0, cells), jacobian_determinants(r.x, cells))
        assert ratio.min() > 0.3 and ratio.min() == r.orientation


def test_larger_motion_is_refused_naming_pair_and_fraction(model):
    msh, _, ft, cp = model
    unit = rm.remap_wear(msh, ft, pair_wear(cp, bump(cp, 1e-6)), 0.3)
    W = bump(cp, 1.5 * 0.3 / unit.max_fraction * 1e-6)
    with pytest.raises(GeometryError, match=r"pair \d+ \((blade|disk) flank (intrados|extrados).*max_fraction = 0.3"):
        rm.remap_wear(msh, ft, pair_wear(cp, W), 0.3)
    # The same wear passes when the fraction allows it.
    assert rm.remap_wear(msh, ft, pair_wear(cp, W), 0.6).orientation > 0


def test_node_sizes_are_cell_heights(model):
    msh = model[0]
    cells = np.asarray(msh.geometry.dofmap.array).reshape(-1, 10)
    h = node_sizes(msh.geometry.x, cells)
    assert np.all(np.isfinite(h)) and np.all(h > 0)
    assert h.min() == pytest.approx(cell_heights(msh.geometry.x, cells).min())


def test_xdmf_and_worn_nodes_written(model, tmp_path):
    from reduction import dolfinx_compat as dc

    msh, ct, ft, cp = model
    r = rm.remap_wear(msh, ft, pair_wear(cp, bump(cp, 20e-6)), 0.3)
    before = np.array(msh.geometry.x, copy=True)
    rm.write_wear_xdmf(tmp_path / "wear_map.xdmf", msh, r, ct, ft)
    rm.write_worn_xdmf(tmp_path / "worn.xdmf", msh, r, ct, ft)
    rm.write_worn_nodes(tmp_path / "worn_nodes.npz", msh, r)
    assert np.array_equal(msh.geometry.x, before)
    text = (tmp_path / "wear_map.xdmf").read_text()
    assert "wear_depth" in text and "wear_motion" in text and (tmp_path / "wear_map.h5").is_file()
    assert not list(tmp_path.glob(".*tmp"))
    m2, c2, f2 = dc.read_mesh_xdmf(tmp_path / "worn.xdmf")
    assert sorted(np.unique(f2.values)) == [11, 12, 21, 22, 31, 41] and len(c2.values) == len(ct.values)
    # Same node set as the worn coordinates (the reader may renumber).
    a = np.lexsort(r.x.T)
    b = np.lexsort(m2.geometry.x.T)
    np.testing.assert_allclose(m2.geometry.x[b], r.x[a], atol=1e-15)
    z = np.load(tmp_path / "worn_nodes.npz")
    assert np.array_equal(z["gmsh_node_tags"], np.arange(1, len(r.x) + 1))
    np.testing.assert_allclose(np.linalg.norm(z["coords"] - z["coords_new"], axis=1).max(), r.max_node_motion)


def test_worn_msh_round_trip(tmp_path):
    from geometry.twoblock import TwoBlockParams, build_two_block
    from reduction import dolfinx_compat as dc
    from reduction.pairs import contact_pairs

    msh, ct, ft = build_two_block(TwoBlockParams(h=0.004, nodes_along=4, nodes_across=3), tmp_path / "new.msh")
    cp = contact_pairs(dc.vector_space(msh, 2), ft)
    r = rm.remap_wear(msh, ft, pair_wear(cp, bump(cp, 10e-6)), 0.3)
    rm.write_worn_nodes(tmp_path / "worn_nodes.npz", msh, r)
    z = np.load(tmp_path / "worn_nodes.npz")
    rm.write_worn_msh(tmp_path / "new.msh", tmp_path / "worn.msh", z["gmsh_node_tags"], z["coords"])
    m2, _, f2 = dc.read_msh(tmp_path / "worn.msh")
    np.testing.assert_allclose(np.sort(m2.geometry.x, axis=0), np.sort(r.x, axis=0), atol=1e-15)


def test_every_node_layout_carries_the_wear_exactly_to_every_flank_node(model):
    """With contact on every flank node (contact_nodes = "all") each flank
    geometry node is a contact node: the wear field on the mesh is the pairs'
    wear itself, no interpolation, on the blade and the disk flanks alike."""
    from scipy.spatial import cKDTree

    from reduction import dolfinx_compat as dc
    from reduction.pairs import contact_pairs

    msh, _, ft, _ = model
    cp = contact_pairs(dc.vector_space(msh, 2), ft, nodes="all")
    W = bump(cp, 1e-6)
    x = msh.geometry.x
    flanks = rm.flank_node_sets(msh, ft)
    wear, motion = rm.flank_field(x, flanks, pair_wear(cp, W, share=0.7))
    for fs in flanks:
        sel = cp["flank"] == fs.flank
        assert len(fs.nodes) == sel.sum()  # every geometry node of the flank is a pair
        _, near = cKDTree(cp["position"][sel]).query(x[fs.nodes])
        share = 0.7 if fs.body == "blade" else 0.3
        np.testing.assert_allclose(wear[fs.nodes], share * W[sel][near], rtol=1e-12, atol=0)
