"""The parametric blade–disk sector: gmsh model, mesh and its checks.

``build_sector(params, msh_path)`` makes two separate OCC volumes — the disk
rim sector with its axial dovetail slot, and the blade (root + shank +
platform fused with a cambered, twisted airfoil) — meshes them with
second-order tetrahedra and writes a gmsh 4.1 ``.msh`` with the physical
groups of ``docs/contracts.md`` §1. The two bodies touch only on the two
contact flanks; each flank is a pair of coincident faces (one per body) with
identical structured meshes, linked by ``setPeriodic`` (identity), so every
blade flank vertex has a disk flank vertex at the same place. The bodies are
never fragmented together: that would merge the interface nodes.

Run ``python -m geometry.sector out.msh`` to build the default sector.
"""
from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from geometry import cyclic as gc
from geometry import meshing as gm
from geometry.airfoil import Airfoil
from geometry.params import SectorParams, check_params, flank_zone
from geometry.profile import Dovetail
from workflow.errors import GeometryError

__all__ = ["SectorParams", "build_sector", "build_bar", "GROUPS"]

#: Physical groups of the sector mesh: name → (dim, tag). Contract §1.
GROUPS = {
    "blade": (3, 1),
    "disk": (3, 2),
    "blade_flank_intrados": (2, 11),
    "blade_flank_extrados": (2, 12),
    "disk_flank_intrados": (2, 21),
    "disk_flank_extrados": (2, 22),
    "disk_clamp": (2, 31),
    "blade_tip": (2, 41),
}
SIDES = ("intrados", "extrados")


def build_sector(params: SectorParams | None, msh_path) -> dict:
    """Build, mesh and write the sector; return its description.

    Parameters
    ----------
    params : SectorParams or None (defaults).
    msh_path : where to write the gmsh 4.1 mesh (atomically).

    Returns
    -------
    dict (JSON-serialisable), SI units:

    * ``sector_angle`` (rad), ``element_order``, ``n_nodes``, ``n_elements``
      (tetrahedra), ``n_vertices`` (corner nodes), measured on the written file;
    * ``contact_pairs``: blade flank nodes matched to disk flank nodes, both
      flanks (= 2·nodes_along·nodes_across vertices, or with
      ``contact_nodes = "all"`` every flank node); ``pairs_per_flank``:
      vertices per flank;
    * ``pair_distance_max`` (m): largest distance between matched vertices;
      ``pair_distance_max_all_nodes`` (m): the same over every flank node
      including the quadratic mid-edge nodes;
    * ``flank_normals``: {'intrados', 'extrados'} → unit normal from the disk
      into the blade; intrados is the −y flank, extrados the +y flank;
    * ``volume_blade_m3``, ``volume_disk_m3``: OCC volumes of the bodies;
    * ``tip_point`` (m): mid-chord of the tip section, a mesh vertex on the
      ``blade_tip`` face; ``excitation_direction``: unit normal to the tip's
      chord plane (towards the extrados);
    * ``quality_min``, ``quality_mean`` (tetrahedron shape, 1 = regular),
      ``jacobian_ratio_min`` (> 0: no folded curved element);
    * ``groups``: name → [dim, tag]; ``params``: the parameters used;
    * with ``params.cyclic``: the groups ``cyclic_low`` (2, 51) and
      ``cyclic_high`` (2, 52), the disk's cut faces meshed periodic under the
      rotation by 2π/N (:mod:`geometry.cyclic`), and ``cyclic_nodes``,
      ``cyclic_distance_max`` (m), ``cyclic_blade_clearance`` (m).
    """
    p = params if params is not None else SectorParams()
    check_params(p)
    dov, foil = Dovetail.from_params(p), Airfoil.from_params(p)
    with gm.gmsh_session("bladewear-sector"):
        disk = _make_disk(dov, p.axial_length)
        blade = _make_blade(dov, foil, p.axial_length)
        info = {"volume_disk_m3": _occ_volume(disk), "volume_blade_m3": _occ_volume(blade)}
        tip_pt = _add_point(foil.tip_point())
        _sync()
        faces = _find_faces(p, dov, foil, blade, disk)
        _embed_tip_point(tip_pt, faces["blade_tip"])
        _structure_flanks(p, faces)
        if p.cyclic:
            cut = gc.find_faces(disk, p.r_in, p.r_out, p.axial_length, p.n_sectors, gm.BBOX_TOL * p.r_out)
            gc.make_periodic(cut, p.n_sectors)
        _set_sizes(p, dov, blade, disk, tip_pt)
        if p.h_flank > 0:
            gm.refine_near(dov.flank_segments().values(), p.h_flank, max(p.h_blade, p.h_disk), flank_zone(p))
        _add_groups(blade, disk, faces)
        if p.cyclic:
            for name, (dim, tag) in gc.GROUPS.items():
                gm.add_group(dim, [cut[name]], tag, name)
        gm.set_mesh_options(min(p.h_blade, p.h_disk, p.h_airfoil, p.h_flank or math.inf) / 20.0,
                            max(p.h_blade, p.h_disk, p.h_airfoil))
        gm.generate(p.element_order, [blade, disk])
        info.update(gm.check_quality(p.element_order))
        info.update(gm.write_msh(msh_path, lambda tmp: _measure(tmp, p)))
    info.update({
        "sector_angle": p.sector_angle,
        "element_order": p.element_order,
        "flank_normals": {k: list(v) for k, v in dov.flank_normals().items()},
        "tip_point": [float(v) for v in foil.tip_point()],
        "excitation_direction": [float(v) for v in foil.tip_normal()],
        "groups": {k: list(v) for k, v in (dict(GROUPS, **gc.GROUPS) if p.cyclic else GROUPS).items()},
        "params": p.to_dict(),
    })
    return info


# ---------------------------------------------------------------- CAD ----

def _occ():
    import gmsh

    return gmsh.model.occ


def _sync() -> None:
    _occ().synchronize()


def _add_point(xyz) -> int:
    return _occ().addPoint(float(xyz[0]), float(xyz[1]), float(xyz[2]))


def _occ_volume(vol: int) -> float:
    # OCC's mass of a volume is its volume (unit density).
    return float(_occ().getMass(3, vol))


def _profile_surface(segments: list[tuple[str, tuple[float, float]]]) -> int:
    """Plane surface in x = 0 from a closed outline of (kind, (y, z)); 'arc'
    segments are circular arcs centred on the engine axis."""
    occ = _occ()
    pts = [occ.addPoint(0.0, y, z) for (_, (y, z)) in segments]
    centre = None
    curves = []
    for i, (kind, _) in enumerate(segments):
        start, end = pts[i - 1], pts[i]
        if kind == "arc":
            centre = centre or occ.addPoint(0.0, 0.0, 0.0)
            curves.append(occ.addCircleArc(start, centre, end))
        else:
            curves.append(occ.addLine(start, end))
    surf = occ.addPlaneSurface([occ.addCurveLoop(curves)])
    if centre is not None:
        occ.remove([(0, centre)])
    return surf


def _extrude_x(surf: int, length: float) -> int:
    """Volume swept by a surface in x = 0 along +x."""
    out = _occ().extrude([(2, surf)], length, 0.0, 0.0)
    return next(t for (d, t) in out if d == 3)


def _make_disk(dov: Dovetail, length: float) -> int:
    """Rim sector r_in ≤ r ≤ r_out, |angle| ≤ π/n, 0 ≤ x ≤ L, minus the slot."""
    return _extrude_x(_profile_surface(dov.disk_outline()), length)


def _make_blade(dov: Dovetail, foil: Airfoil, length: float) -> int:
    """Root + shank + platform (extruded profile) fused with the airfoil."""
    outline = dov.blade_outline()
    root = _extrude_x(_profile_surface([("line", (y, z)) for (y, z) in outline]), length)
    airfoil = _make_airfoil(foil)
    import gmsh

    # OCC's default "unify same domain" after a union would merge the
    # collinear faces of the inclined face and lose the contact flank.
    gmsh.option.setNumber("Geometry.OCCUnionUnify", 0)
    out, _ = _occ().fuse([(3, root)], [(3, airfoil)])
    vols = [t for (d, t) in out if d == 3]
    if len(vols) != 1:
        raise GeometryError(f"gmsh failed: fusing root and airfoil gave {len(vols)} volumes")
    return vols[0]


def _make_airfoil(foil: Airfoil) -> int:
    """Loft through the spanwise sections (splines, blunt edges)."""
    occ = _occ()
    wires = []
    for z in foil.stations():
        up, lo = foil.section_sides(z)
        pu = [occ.addPoint(*map(float, q)) for q in up]
        pl = [occ.addPoint(*map(float, q)) for q in lo]
        curves = [occ.addSpline(pu), occ.addLine(pu[-1], pl[-1]),
                  occ.addSpline(pl[::-1]), occ.addLine(pl[0], pu[0])]
        wires.append(occ.addWire(curves))
    out = occ.addThruSections(wires, makeSolid=True, makeRuled=False)
    return next(t for (d, t) in out if d == 3)


# ------------------------------------------------------- entities ----

def _find_faces(p: SectorParams, dov: Dovetail, foil: Airfoil, blade: int, disk: int) -> dict:
    """Tags of the flank faces of both bodies, the clamp and the tip."""
    L, tol = p.axial_length, gm.BBOX_TOL * p.r_out
    faces = {}
    for side, (c1, c2) in dov.flank_segments().items():
        lo = (0.0, min(c1[0], c2[0]), min(c1[1], c2[1]))
        hi = (L, max(c1[0], c2[0]), max(c1[1], c2[1]))
        faces[f"blade_flank_{side}"] = gm.one_face(blade, lo, hi, tol, f"blade {side} flank")
        faces[f"disk_flank_{side}"] = gm.one_face(disk, lo, hi, tol, f"disk {side} flank")
    s = math.sin(dov.half_angle)
    faces["disk_clamp"] = gm.one_face(disk, (0.0, -p.r_in * s, p.r_in * math.cos(dov.half_angle)),
                                      (L, p.r_in * s, p.r_in), tol, "disk clamp")
    big = 10.0 * p.r_out
    faces["blade_tip"] = gm.one_face(blade, (-big, -big, foil.z_tip), (big, big, foil.z_tip), tol, "blade tip")
    return faces


def _embed_tip_point(pt: int, tip_face: int) -> None:
    """Force a mesh vertex at the excitation point."""
    import gmsh

    gmsh.model.mesh.embed(0, [pt], 2, tip_face)


def _structure_flanks(p: SectorParams, faces: dict) -> None:
    """Identical structured meshes on the coincident flank faces: the disk
    face is the master, the blade face its periodic copy (identity)."""
    import gmsh

    for side in SIDES:
        b, d = faces[f"blade_flank_{side}"], faces[f"disk_flank_{side}"]
        gm.make_structured(d, p.nodes_along, p.nodes_across, along_axis=0, across_bump=p.flank_grading)
        gm.make_structured(b, p.nodes_along, p.nodes_across, along_axis=0, across_bump=p.flank_grading)
        gmsh.model.mesh.setPeriodic(2, [b], [d], gm.IDENTITY)


def _set_sizes(p: SectorParams, dov: Dovetail, blade: int, disk: int, tip_pt: int) -> None:
    """Element size per body; the airfoil's own points get h_airfoil."""
    tol = gm.BBOX_TOL * p.r_out

    def blade_size(xyz: np.ndarray) -> float:
        on_foil = xyz[2] > dov.z_platform_top - tol and abs(xyz[1]) < dov.half_platform - tol
        return p.h_airfoil if on_foil else p.h_blade

    gm.set_point_sizes(gm.boundary([(3, blade)], 0), blade_size)
    gm.set_point_sizes(gm.boundary([(3, disk)], 0), lambda _: p.h_disk)
    gm.set_point_sizes([tip_pt], lambda _: p.h_airfoil)


def _add_groups(blade: int, disk: int, faces: dict) -> None:
    ents = dict(faces, blade=blade, disk=disk)
    for name, (dim, tag) in GROUPS.items():
        gm.add_group(dim, [ents[name]], tag, name)


# ------------------------------------------------------- checks ----

def _measure(msh_file: Path, p: SectorParams) -> dict:
    """Counts and flank pairing measured on the written mesh file."""
    with gm.reading(msh_file):
        n_nodes, n_el = gm.mesh_counts()
        out = {"n_nodes": n_nodes, "n_elements": n_el}
        vert_total = set()
        dmax, dmax_all, pairs = 0.0, 0.0, 0
        per_flank = {}
        for side in SIDES:
            bv, ball = gm.group_nodes(*GROUPS[f"blade_flank_{side}"])
            dv, dall = gm.group_nodes(*GROUPS[f"disk_flank_{side}"])
            if len(bv) != len(dv) or np.intersect1d(ball, dall).size:
                raise GeometryError(f"gmsh failed: the {side} flank meshes of blade and disk differ "
                                    f"({len(bv)} vs {len(dv)} vertices) or share nodes")
            dmax = max(dmax, _match_distance(gm.node_coords(bv), gm.node_coords(dv)))
            dmax_all = max(dmax_all, _match_distance(gm.node_coords(ball), gm.node_coords(dall)))
            pairs += len(ball) if p.contact_nodes == "all" else len(bv)
            per_flank[side] = len(bv)
        for name in ("blade", "disk"):
            vert_total.update(gm.group_nodes(*GROUPS[name])[0].tolist())
        out.update(n_vertices=len(vert_total), contact_pairs=pairs, pairs_per_flank=per_flank,
                   pair_distance_max=dmax, pair_distance_max_all_nodes=dmax_all)
        if p.cyclic:
            out.update(gc.check(p.n_sectors, GROUPS["blade"], p.r_out))
    expected = p.nodes_along * p.nodes_across
    if any(n != expected for n in per_flank.values()):
        raise GeometryError(f"gmsh failed: flank vertices {per_flank}, expected {expected} per flank "
                            "(nodes_along × nodes_across)")
    if dmax > 1e-9 * p.r_out:
        raise GeometryError(f"gmsh failed: flank vertices do not coincide (max distance {dmax:.3g} m)")
    return out


def _match_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance from a point of ``a`` to its nearest point of ``b``,
    requiring the nearest-neighbour map to be one-to-one."""
    from scipy.spatial import cKDTree

    if len(a) == 0:
        return math.inf
    dist, idx = cKDTree(b).query(a)
    if len(np.unique(idx)) != len(a):
        return math.inf
    return float(dist.max())


def build_bar(length: float, width: float, height: float, h: float, msh_path, order: int = 2) -> dict:
    """Clamped slender bar (see :mod:`geometry.bar`); re-exported here."""
    from geometry.bar import build_bar as _bar

    return _bar(length, width, height, h, msh_path, order=order)


def _value(text: str):
    """A command-line value: int, float, true/false, or the text itself (contact_nodes)."""
    if text in ("true", "false"):
        return text == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def main(argv: list[str] | None = None) -> int:
    """``python -m geometry.sector OUT.msh [key=value ...]``: build a sector
    (default parameters, overridden by key=value) and print its info."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(main.__doc__)
        return 0
    out, overrides = argv[0], {}
    for kv in argv[1:]:
        key, _, val = kv.partition("=")
        overrides[key] = _value(val)
    try:
        t0 = time.perf_counter()
        info = build_sector(replace(SectorParams(), **overrides), out)
        info["seconds"] = round(time.perf_counter() - t0, 3)
    except (GeometryError, TypeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for k, v in info.items():
        if k != "params":
            print(f"{k}: {json.dumps(v)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
