"""The blade–disk sector mesh: contract groups, node-matched flanks, volumes,
no overlap, tip point, validation of parameters and of gmsh failures."""
from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial import cKDTree

from geometry.params import SectorParams
from geometry.profile import Dovetail
from geometry.sector import build_sector, main
from workflow.errors import GeometryError

CONTRACT_GROUPS = {
    ("blade", 3, 1), ("disk", 3, 2),
    ("blade_flank_intrados", 2, 11), ("blade_flank_extrados", 2, 12),
    ("disk_flank_intrados", 2, 21), ("disk_flank_extrados", 2, 22),
    ("disk_clamp", 2, 31), ("blade_tip", 2, 41),
}
SIDES = ("intrados", "extrados")


def test_physical_groups_are_the_contracts(default_sector):
    _, _, mesh = default_sector
    assert {(g.name, g.dim, g.tag) for g in mesh.groups.values()} == CONTRACT_GROUPS


def test_second_order_tetrahedra_only(default_sector):
    info, _, mesh = default_sector
    assert info["element_order"] == 2
    for g in mesh.groups.values():
        assert g.elem_types == ({11} if g.dim == 3 else {9}), g.name   # 10-node tet, 6-node tri


def test_every_blade_flank_vertex_has_a_coincident_disk_partner(default_sector):
    info, _, mesh = default_sector
    scale = SectorParams().r_out
    for side in SIDES:
        for what in ("vertices", "nodes"):          # corner nodes, then with mid-edge nodes
            b = getattr(mesh, what)(f"blade_flank_{side}")
            d = getattr(mesh, what)(f"disk_flank_{side}")
            assert len(b) == len(d)
            assert not np.intersect1d(b, d).size, "bodies must not share nodes"
            dist, idx = cKDTree(mesh.xyz(d)).query(mesh.xyz(b))
            assert dist.max() < 1e-12 * scale
            assert len(np.unique(idx)) == len(b), "pairing is one-to-one"
    assert info["pair_distance_max"] < 1e-12 * scale
    assert info["contact_pairs"] == 2 * 4 * 2


def test_bodies_share_no_node_and_coincide_only_on_the_flanks(default_sector):
    _, _, mesh = default_sector
    blade, disk = mesh.nodes("blade"), mesh.nodes("disk")
    assert not np.intersect1d(blade, disk).size
    tree = cKDTree(mesh.xyz(disk))
    dist, _ = tree.query(mesh.xyz(blade))
    touching = set(blade[dist < 1e-9].tolist())
    flank = set(np.concatenate([mesh.nodes(f"blade_flank_{s}") for s in SIDES]).tolist())
    assert touching == flank


def _inside(poly: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Even–odd rule: is each (y, z) point strictly inside the polygon?"""
    y, z = pts[:, 0], pts[:, 1]
    inside = np.zeros(len(pts), dtype=bool)
    for (y0, z0), (y1, z1) in zip(poly, np.roll(poly, -1, axis=0)):
        crosses = (z0 > z) != (z1 > z)
        with np.errstate(divide="ignore", invalid="ignore"):
            yc = y0 + (z - z0) * (y1 - y0) / (z1 - z0)
        inside ^= crosses & (y < yc)
    return inside


def _dist_to_polygon(poly: np.ndarray, pts: np.ndarray) -> np.ndarray:
    best = np.full(len(pts), np.inf)
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        ab = b - a
        t = np.clip(((pts - a) @ ab) / (ab @ ab), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(pts - (a + t[:, None] * ab), axis=1))
    return best


def test_blade_and_disk_do_not_overlap(default_sector):
    """Every node of one body lies outside the other body's profile (or on
    its boundary): blade nodes are not inside the disk's rim and disk nodes
    are not inside the blade root."""
    _, _, mesh = default_sector
    dov = Dovetail.from_params(SectorParams())
    blade_yz = mesh.xyz(mesh.nodes("blade"))[:, 1:]
    disk_yz = mesh.xyz(mesh.nodes("disk"))[:, 1:]
    tol = 1e-9
    root = dov.blade_outline()
    bad = _inside(root, disk_yz) & (_dist_to_polygon(root, disk_yz) > tol)
    assert not bad.any(), disk_yz[bad][:5]
    # Below the chord T'–T the slot is a polygon: blade nodes there must be in it.
    low = blade_yz[:, 1] < dov.T[1]
    slot = dov.slot_polygon()
    pts = blade_yz[low]
    outside = ~_inside(slot, pts) & (_dist_to_polygon(slot, pts) > tol)
    assert not outside.any(), pts[outside][:5]
    # Above it, blade nodes keep clear of the rim top.
    r = np.hypot(blade_yz[~low, 0], blade_yz[~low, 1])
    assert (np.abs(blade_yz[~low, 0]) <= dov.T[0] + tol).all() or (r > dov.r_out).all()


def test_flank_normals_point_from_disk_into_blade(default_sector):
    info, _, mesh = default_sector
    for side in SIDES:
        n = np.array(info["flank_normals"][side])
        assert np.isclose(np.linalg.norm(n), 1.0) and n[2] < -0.1
        assert np.sign(n[1]) == (1 if side == "intrados" else -1)
        tri = mesh.xyz(mesh.groups[f"blade_flank_{side}"].corners.ravel()).reshape(-1, 3, 3)
        nt = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        nt /= np.linalg.norm(nt, axis=1)[:, None]
        assert np.allclose(np.abs(nt @ n), 1.0, atol=1e-9), "flank triangles lie in the flank plane"
        # Off-face vertices of the tetrahedra on each flank lie on the right side.
        for body, sign in (("blade", 1.0), ("disk", -1.0)):
            face_nodes = set(mesh.vertices(f"{body}_flank_{side}").tolist())
            tets = mesh.groups[body].corners
            on = np.isin(tets, list(face_nodes))
            touching = tets[on.sum(axis=1) == 3]
            assert len(touching) >= 2 * (4 - 1) * (2 - 1)
            apex = touching[~np.isin(touching, list(face_nodes))]
            origin = mesh.xyz([next(iter(face_nodes))])[0]
            assert (sign * ((mesh.xyz(apex) - origin) @ n) > 0).all(), (body, side)


def test_disk_volume_matches_the_analytic_rim_minus_slot(default_sector):
    info, _, mesh = default_sector
    p = SectorParams()
    dov = Dovetail.from_params(p)
    annulus = 0.5 * p.sector_angle * (p.r_out ** 2 - p.r_in ** 2)
    expected = (annulus - dov.slot_area()) * p.axial_length
    assert info["volume_disk_m3"] == pytest.approx(expected, rel=1e-9)
    # The slot removes what it should: the analytic slot area is not trivial.
    assert 0.05 * annulus < dov.slot_area() < 0.5 * annulus
    # The straight-sided mesh is within the chord error of the arcs.
    tets = mesh.xyz(mesh.groups["disk"].corners.ravel()).reshape(-1, 4, 3)
    vol = np.abs(np.einsum("ij,ij->i", tets[:, 1] - tets[:, 0],
                           np.cross(tets[:, 2] - tets[:, 0], tets[:, 3] - tets[:, 0]))).sum() / 6
    assert vol == pytest.approx(expected, rel=2e-3)


def test_blade_volume_is_root_plus_airfoil(default_sector):
    info, _, _ = default_sector
    p = SectorParams()
    root = Dovetail.from_params(p).root_area() * p.axial_length
    # The airfoil is a plate of constant thickness along a parabolic camber
    # line (arc length ≈ chord·(1 + 8/3·camber²)).
    foil = p.thickness * p.chord * (1 + 8 / 3 * p.camber ** 2) * p.span
    assert info["volume_blade_m3"] == pytest.approx(root + foil, rel=0.01)


def test_clamp_is_the_inner_rim_face(default_sector):
    _, _, mesh = default_sector
    p = SectorParams()
    xyz = mesh.xyz(mesh.nodes("disk_clamp"))
    assert np.allclose(np.hypot(xyz[:, 1], xyz[:, 2]), p.r_in, atol=1e-9)
    assert np.ptp(xyz[:, 0]) == pytest.approx(p.axial_length)
    assert np.abs(np.arctan2(xyz[:, 1], xyz[:, 2])).max() == pytest.approx(math.pi / p.n_sectors)


def test_tip_point_is_a_tip_vertex_and_excitation_is_normal_to_the_chord(default_sector):
    info, _, mesh = default_sector
    p = SectorParams()
    tip = mesh.xyz(mesh.vertices("blade_tip"))
    assert np.linalg.norm(tip - np.array(info["tip_point"]), axis=1).min() < 1e-12
    assert np.allclose(tip[:, 2], tip[0, 2]) and tip[0, 2] > p.r_out + p.span
    e = np.array(info["excitation_direction"])
    assert np.isclose(np.linalg.norm(e), 1.0) and abs(e[2]) < 1e-12
    # The tip section is thin along e and long across it.
    spread_e = np.ptp(tip @ e)
    chord_dir = np.cross(e, [0.0, 0.0, 1.0])
    assert spread_e <= p.thickness + p.camber * p.chord + 1e-9
    assert np.ptp(tip @ chord_dir) == pytest.approx(p.chord, rel=0.02)


def test_info_is_json_serialisable_and_mesh_is_modest(default_sector):
    info, _, mesh = default_sector
    json.dumps(info)
    assert info["n_nodes"] == len(mesh.node_tags)
    assert 20_000 <= 3 * info["n_nodes"] <= 60_000
    assert info["quality_min"] > 0.01 and info["jacobian_ratio_min"] > 0.3
    assert info["sector_angle"] == pytest.approx(2 * math.pi / 47)


@pytest.mark.parametrize("along,across", [(2, 2), (3, 3), (8, 3), (12, 6)])
def test_contact_node_count_follows_the_grid(tmp_path, along, across, read_msh):
    p = replace(SectorParams(), nodes_along=along, nodes_across=across,
                h_disk=0.01, h_blade=0.006, h_airfoil=0.012)
    info = build_sector(p, tmp_path / "s.msh")
    mesh = read_msh(tmp_path / "s.msh")
    for side in SIDES:
        for body in ("blade", "disk"):
            assert len(mesh.vertices(f"{body}_flank_{side}")) == along * across
        xyz = mesh.xyz(mesh.vertices(f"blade_flank_{side}"))
        assert len(np.unique(xyz[:, 0].round(12))) == along       # structured along x
    assert info["contact_pairs"] == 2 * along * across
    assert info["pair_distance_max"] < 1e-12 * p.r_out


def test_graded_flanks_crowd_their_vertices_towards_the_long_edges(tmp_path, read_msh):
    """geometry.flank_grading: the same vertex count and node-to-node pairs, the spacing across
    smallest at both long edges (gmsh's Bump: the end cell ≈ √g × the even spacing) and the
    rows across still straight lines along x."""
    g, along, across = 0.2, 12, 5
    p = replace(SectorParams(), nodes_along=along, nodes_across=across, flank_grading=g,
                h_disk=0.01, h_blade=0.006, h_airfoil=0.012)
    info = build_sector(p, tmp_path / "s.msh")
    mesh = read_msh(tmp_path / "s.msh")
    assert info["contact_pairs"] == 2 * along * across and info["pair_distance_max"] < 1e-12 * p.r_out
    for side in SIDES:
        xyz = mesh.xyz(mesh.vertices(f"blade_flank_{side}"))
        row = xyz[np.isclose(xyz[:, 0], xyz[:, 0].min())][:, 1:]          # one row across, at the first x
        d = np.linalg.norm(row - row[np.argmin(row[:, 0])], axis=1)
        gaps = np.diff(np.sort(d))
        even = d.max() / (across - 1)
        assert gaps.size == across - 1 and gaps[0] == pytest.approx(gaps[-1], rel=1e-9)   # symmetric
        assert gaps[0] < gaps[across // 2 - 1] and 0.3 < gaps[0] / (math.sqrt(g) * even) < 1.5
        assert len(np.unique(xyz[:, 0].round(12))) == along


def test_first_order_mesh(tmp_path, read_msh):
    p = replace(SectorParams(), element_order=1, h_airfoil=0.012)
    info = build_sector(p, tmp_path / "s.msh")
    mesh = read_msh(tmp_path / "s.msh")
    assert mesh.groups["blade"].elem_types == {4} and info["element_order"] == 1


def test_same_parameters_give_the_same_file(tmp_path):
    p = replace(SectorParams(), h_airfoil=0.012)
    build_sector(p, tmp_path / "a.msh")
    build_sector(p, tmp_path / "b.msh")
    assert (tmp_path / "a.msh").read_bytes() == (tmp_path / "b.msh").read_bytes()


def test_mesh_sizes_drive_the_refinement(default_sector, tmp_path):
    d = SectorParams()
    coarse = build_sector(replace(d, h_blade=2 * d.h_blade, h_disk=2 * d.h_disk, h_airfoil=2 * d.h_airfoil),
                          tmp_path / "c.msh")
    assert default_sector[0]["n_nodes"] > 2.0 * coarse["n_nodes"]


def _element_sizes(mesh, p) -> tuple[np.ndarray, np.ndarray]:
    """Per tetrahedron of both bodies: its rms edge length [m] and its centroid's distance [m]
    to the nearer contact flank (a segment in the y–z plane, extruded along x)."""
    corners = np.vstack([mesh.groups[b].corners for b in ("blade", "disk")])
    q = mesh.xyz(corners)                                           # (n, 4, 3)
    edges = [q[:, j] - q[:, i] for i, j in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))]
    size = np.sqrt(sum((e * e).sum(1) for e in edges) / 6.0)
    yz = q.mean(1)[:, 1:]
    dist = np.full(len(yz), np.inf)
    for a, b in Dovetail.from_params(p).flank_segments().values():
        a, b = np.asarray(a), np.asarray(b)
        t = np.clip((yz - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
        dist = np.minimum(dist, np.linalg.norm(yz - a - t[:, None] * (b - a), axis=1))
    return size, dist


@pytest.mark.slow  # 4–9 s on the 2-core machine: make test-slow keeps make test within 3 min
def test_flank_size_refines_the_solid_next_to_the_flanks_only(tmp_path, read_msh):
    """geometry.h_flank: within flank_zone of the flanks the tetrahedra are as fine as in a sector
    meshed at h_flank throughout (gmsh's Delaunay edges are ~1.3 × its size either way); beyond
    the growth band they keep the bodies' size; the flanks' node-to-node pairs are untouched."""
    from geometry.meshing import GROWTH
    from geometry.params import flank_zone

    h = 0.002
    base = replace(SectorParams(), h_airfoil=0.012, nodes_along=10, nodes_across=4)
    builds = {"base": base, "local": replace(base, h_flank=h), "global": replace(base, h_blade=h, h_disk=h)}
    info, size, dist = {}, {}, {}
    for name, p in builds.items():
        info[name] = build_sector(p, tmp_path / f"{name}.msh")
        size[name], dist[name] = _element_sizes(read_msh(tmp_path / f"{name}.msh"), p)
    zone = flank_zone(base)
    near = {k: np.median(size[k][dist[k] < zone]) for k in builds}
    assert near["local"] == pytest.approx(near["global"], rel=0.15)
    assert near["base"] > 1.5 * near["local"], "without h_flank the zone keeps the bodies' sizes"
    far = zone + (max(base.h_blade, base.h_disk) - h) / GROWTH
    # Beyond the band the local mesh is back near the bodies' size (gmsh grades it down from the
    # finer surface meshes that cross the zone, so not all the way: 6.0 against 7.8 mm here).
    away = {k: np.median(size[k][dist[k] > far]) for k in builds}
    assert away["local"] > 0.7 * away["base"] and away["local"] > 1.5 * away["global"]
    assert info["local"]["contact_pairs"] == info["base"]["contact_pairs"]
    assert info["local"]["pair_distance_max"] < 1e-12 * base.r_out
    assert info["base"]["n_nodes"] < info["local"]["n_nodes"] < info["global"]["n_nodes"]


D = SectorParams()
BAD = [
    ({"n_sectors": 2}, "n_sectors"),
    ({"n_sectors": 47.0}, "n_sectors"),
    ({"r_in": 0.25}, "r_in"),
    ({"r_in": 0.229}, "r_in"),                   # slot bottom below the rim's inner radius
    ({"axial_length": 0.0}, "axial_length"),
    ({"neck_width": -0.008}, "neck_width"),
    ({"lobe_width": 0.008}, "lobe_width"),       # no wider than the neck
    ({"lobe_width": 0.03}, "lobe_width"),        # slot wider than the sector
    ({"flank_angle": math.radians(85)}, "flank_angle"),
    ({"flank_angle": 45.0}, "flank_angle"),      # degrees by mistake
    ({"flank_length": 0.008}, "flank_length"),   # longer than the inclined face
    ({"flank_length": 0.0065}, "flank_length"),  # no room left for the neck clearance
    ({"clearance": 0.0}, "clearance"),
    ({"clearance": 0.005}, "clearance"),
    ({"neck_height": 1e-6}, "neck_height"),
    ({"platform_width": 0.04}, "platform_width"),  # blade wider than the sector
    ({"platform_width": 0.006}, "platform_width"),
    ({"chord": 0.08}, "chord"),
    ({"thickness": 0.02}, "thickness"),
    ({"camber": 0.5}, "camber"),
    ({"twist": 2.0}, "twist"),
    ({"nodes_along": 1}, "nodes_along"),
    ({"nodes_across": 1}, "nodes_across"),
    ({"nodes_across": 2.5}, "nodes_across"),
    ({"nodes_along": 2, "nodes_across": 5}, "nodes_along"),    # flank cells 40 × 1.25 mm
    ({"nodes_along": 100}, "nodes_across"),                     # flank cells 0.4 × 5 mm
    ({"flank_grading": 0.0}, "flank_grading"),
    ({"flank_grading": 1.5}, "flank_grading"),
    ({"nodes_along": 7, "nodes_across": 5, "flank_grading": 0.2}, "nodes_along"),  # end cells 6.7 × 0.56 mm
    ({"relief_angle": -0.1}, "relief_angle"),
    ({"element_order": 3}, "element_order"),
    ({"h_blade": 1e-5}, "h_blade"),              # would make billions of elements
    ({"h_disk": float("nan")}, "h_disk"),
    ({"h_flank": -1e-3}, "h_flank"),
    ({"h_flank": 0.005}, "h_flank"),             # coarser than h_blade: would do nothing
    ({"h_flank": 2e-5}, "h_flank"),              # would make billions of elements
    ({"span": True}, "span"),
]


@pytest.mark.parametrize("kw,name", BAD, ids=[f"{k}" for k, _ in BAD])
def test_bad_parameters_raise_naming_the_parameter(tmp_path, kw, name):
    with pytest.raises(GeometryError) as err:
        build_sector(replace(D, **kw), tmp_path / "s.msh")
    assert f"geometry.{name}" in str(err.value)
    assert not (tmp_path / "s.msh").exists()


def test_gmsh_failure_becomes_geometry_error_and_gmsh_stays_usable(tmp_path, monkeypatch):
    import gmsh

    p = replace(SectorParams(), h_airfoil=0.012)
    build_sector(p, tmp_path / "s.msh")
    before = (tmp_path / "s.msh").read_bytes()

    def boom(dim=3):
        raise Exception("the mesher gave up")

    monkeypatch.setattr(gmsh.model.mesh, "generate", boom)
    with pytest.raises(GeometryError, match="gmsh failed: the mesher gave up"):
        build_sector(p, tmp_path / "s.msh")
    monkeypatch.undo()
    assert (tmp_path / "s.msh").read_bytes() == before, "a failed build leaves the old file"
    assert build_sector(p, tmp_path / "t.msh")["contact_pairs"] == 16


def test_a_mesh_gmsh_cannot_make_raises(tmp_path, monkeypatch):
    """A real error inside gmsh (flank faces that a shifted 'identity' cannot
    map onto each other) surfaces as GeometryError, not a bare Exception."""
    import geometry.meshing as gm

    shifted = list(gm.IDENTITY)
    shifted[3] = 1e-3                       # x + 1 mm
    monkeypatch.setattr(gm, "IDENTITY", shifted)
    with pytest.raises(GeometryError, match="gmsh failed: .*periodic"):
        build_sector(replace(SectorParams(), h_airfoil=0.012), tmp_path / "s.msh")
    assert not (tmp_path / "s.msh").exists()


def test_poor_quality_is_refused(tmp_path, monkeypatch):
    import geometry.meshing as gm

    monkeypatch.setattr(gm, "tet_quality", lambda order: (1e-6, 0.5))
    with pytest.raises(GeometryError, match="quality"):
        build_sector(replace(SectorParams(), h_airfoil=0.012), tmp_path / "s.msh")


def test_command_line(tmp_path, capsys):
    assert main([str(tmp_path / "c.msh"), "h_airfoil=0.012", "nodes_along=3"]) == 0
    out = capsys.readouterr().out
    assert "contact_pairs: 12" in out and (tmp_path / "c.msh").exists()
    assert main([str(tmp_path / "d.msh"), "nodes_along=1"]) == 2
    assert "nodes_along" in capsys.readouterr().err


@pytest.mark.slow
def test_paper_wear_grid_on_a_finer_mesh(tmp_path):
    """8 × 3 contact nodes per flank (48 in all, the paper's wear study) on a
    mesh about twice as fine."""
    p = replace(SectorParams(), nodes_along=8, nodes_across=3,
                h_blade=0.0025, h_disk=0.005, h_airfoil=0.004)
    info = build_sector(p, tmp_path / "s.msh")
    assert info["contact_pairs"] == 48
    assert info["pair_distance_max"] < 1e-12 * p.r_out
    assert info["quality_min"] > 0.01
