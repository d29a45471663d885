"""A tiny two-body dovetail for tests and demos of the wear remap.

A blade root with a trapezoidal cross-section (wider at the bottom) sits
between two disk blocks that touch it on its two inclined faces. The bodies
are separate volumes (not fragmented) whose touching faces carry identical
structured triangle meshes (``setPeriodic``, identity), and the physical
groups use the tags of ``docs/contracts.md`` §1:

=====  ===============================  ==================================
 tag    group                             here
=====  ===============================  ==================================
 1      blade (volume)                    trapezoid prism
 2      disk (volume)                     the two side blocks
 11/12  blade flank intrados / extrados   inclined face at y < 0 / y > 0
 21/22  disk flank intrados / extrados    the same faces, disk side
 31     disk clamp                        the blocks' outer faces y = ±w
 41     blade tip                         the blade's top face
=====  ===============================  ==================================

Coordinates follow contracts §1: x axial (slot along x), y circumferential,
z radial. All lengths in metres. Building takes well under a second.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workflow.errors import GeometryError


@dataclass(frozen=True)
class TwoBlockParams:
    """Dimensions [m] and mesh controls of the two-block dovetail.

    ``length``: axial length; ``height``: radial height of the root;
    ``bottom_half``/``top_half``: half widths of the blade root at z = 0 and
    z = height; ``disk_half``: half width of the whole assembly (clamped
    faces); ``h``: target element size; ``nodes_along``/``nodes_across``:
    flank vertices along x and across the flank; ``order``: 1 or 2.
    """

    length: float = 0.02
    height: float = 0.008
    bottom_half: float = 0.008
    top_half: float = 0.004
    disk_half: float = 0.016
    h: float = 0.004
    nodes_along: int = 6
    nodes_across: int = 4
    order: int = 2


def build_two_block(params: TwoBlockParams = TwoBlockParams(), msh_path=None, comm=None):
    """Mesh the two-block model with gmsh.

    Returns ``(mesh, cell_tags, facet_tags)`` as dolfinx objects (through
    :func:`reduction.dolfinx_compat.model_to_mesh`), and writes the gmsh ``.msh`` to
    ``msh_path`` if given.
    """
    import gmsh
    from mpi4py import MPI

    comm = comm or MPI.COMM_WORLD
    p = params
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("twoblock")
    try:
        blade, disk_ex, disk_in = _volumes(p)
        f = _faces(p, blade, disk_ex, disk_in)
        _flank_grids(p, f)
        _group(3, [blade], 1, "blade")
        _group(3, [disk_ex, disk_in], 2, "disk")
        _group(2, [f["bf_in"]], 11, "blade_flank_intrados")
        _group(2, [f["bf_ex"]], 12, "blade_flank_extrados")
        _group(2, [f["df_in"]], 21, "disk_flank_intrados")
        _group(2, [f["df_ex"]], 22, "disk_flank_extrados")
        _group(2, f["clamp"], 31, "disk_clamp")
        _group(2, [f["tip"]], 41, "blade_tip")
        gmsh.model.mesh.generate(3)
        if p.order == 2:
            gmsh.model.mesh.setOrder(2)
        if msh_path is not None:
            gmsh.write(str(msh_path))
        from reduction.dolfinx_compat import model_to_mesh

        return model_to_mesh(gmsh.model, comm, 3)  # tags named cell_tags / facet_tags
    finally:
        gmsh.finalize()


def _volumes(p: TwoBlockParams) -> tuple[int, int, int]:
    """The blade and the two disk halves (gmsh volume tags), extruded along x by ``p.length``."""
    import gmsh

    occ = gmsh.model.occ
    b, t, w, H, L = p.bottom_half, p.top_half, p.disk_half, p.height, p.length

    def prism(yz):
        pts = [occ.addPoint(0.0, y, z) for y, z in yz]
        lines = [occ.addLine(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
        surf = occ.addPlaneSurface([occ.addCurveLoop(lines)])
        out = occ.extrude([(2, surf)], L, 0.0, 0.0)
        return next(tag for dim, tag in out if dim == 3)

    blade = prism([(-b, 0.0), (b, 0.0), (t, H), (-t, H)])
    disk_ex = prism([(b, 0.0), (w, 0.0), (w, H), (t, H)])
    disk_in = prism([(-b, 0.0), (-t, H), (-w, H), (-w, 0.0)])
    occ.synchronize()
    return blade, disk_ex, disk_in


def _faces(p: TwoBlockParams, blade: int, disk_ex: int, disk_in: int) -> dict:
    """Face tags found by their centres: the four flanks (``bf_in``, ``bf_ex``,
    ``df_in``, ``df_ex``), the blade ``tip`` and the disk ``clamp`` (two faces)."""
    import gmsh

    occ = gmsh.model.occ
    b, t, w, H = p.bottom_half, p.top_half, p.disk_half, p.height

    def faces(vol):
        return [tag for _, tag in gmsh.model.getBoundary([(3, vol)], oriented=False)]

    def centre(tag):
        return np.array(occ.getCenterOfMass(2, tag))

    ym = 0.5 * (b + t)  # y of the flank centres
    def find(vol, pred):
        hits = [f for f in faces(vol) if pred(centre(f))]
        if len(hits) != 1:
            raise GeometryError(f"two-block model: expected one face, found {len(hits)}")
        return hits[0]

    near = lambda a, c: abs(a - c) < 1e-9
    return {"bf_in": find(blade, lambda c: near(c[1], -ym) and near(c[2], 0.5 * H)),
            "bf_ex": find(blade, lambda c: near(c[1], ym) and near(c[2], 0.5 * H)),
            "df_in": find(disk_in, lambda c: near(c[1], -ym) and near(c[2], 0.5 * H)),
            "df_ex": find(disk_ex, lambda c: near(c[1], ym) and near(c[2], 0.5 * H)),
            "tip": find(blade, lambda c: near(c[2], H)),
            "clamp": [find(disk_ex, lambda c: near(c[1], w)), find(disk_in, lambda c: near(c[1], -w))]}


def _flank_grids(p: TwoBlockParams, f: dict) -> None:
    """Structured flank grids of ``nodes_along × nodes_across`` vertices on the
    blade flanks, copied to the disk flanks (periodic: node-to-node pairs), and
    the mesh sizes."""
    import gmsh

    flank_len = math.hypot(p.bottom_half - p.top_half, p.height)
    for face in (f["bf_in"], f["bf_ex"]):
        for _, curve in gmsh.model.getBoundary([(2, face)], oriented=False):
            lo, hi = gmsh.model.getBoundingBox(1, curve)[0::3], gmsh.model.getBoundingBox(1, curve)[3::3]
            along = abs(hi[0] - lo[0]) > 0.5 * p.length
            gmsh.model.mesh.setTransfiniteCurve(curve, p.nodes_along if along else p.nodes_across)
        gmsh.model.mesh.setTransfiniteSurface(face)
    identity = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    gmsh.model.mesh.setPeriodic(2, [f["df_in"], f["df_ex"]], [f["bf_in"], f["bf_ex"]], identity)
    gmsh.option.setNumber("Mesh.MeshSizeMax", p.h)
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.25 * min(p.h, flank_len / max(p.nodes_across - 1, 1)))


def _group(dim, tags, tag, name):
    """A named physical group (gmsh 4.8's addPhysicalGroup takes no name)."""
    import gmsh

    gmsh.model.addPhysicalGroup(dim, tags, tag)
    gmsh.model.setPhysicalName(dim, tag, name)


def flank_nodes(params: TwoBlockParams = TwoBlockParams()):
    """Contact node positions (p, 3) [m], flank ids (p,) and unit normals
    (p, 3) from the disk into the blade, in bundle order (flank, x, across)."""
    p = params
    pos, flank, normal = [], [], []
    for f, sgn in ((0, -1.0), (1, 1.0)):
        # The blade's outward normal on the face from (sgn·b, 0) to (sgn·t, H)
        # points away from the blade; n (disk → blade) is its opposite.
        d = np.array([sgn * (p.top_half - p.bottom_half), p.height])
        out = sgn * np.array([d[1], -d[0]]) / np.hypot(*d)
        n = np.array([0.0, -out[0], -out[1]])
        for x in np.linspace(0.0, p.length, p.nodes_along):
            for s in np.linspace(0.0, 1.0, p.nodes_across):
                pos.append([x, sgn * (p.bottom_half + s * (p.top_half - p.bottom_half)), s * p.height])
                flank.append(f)
                normal.append(n)
    return np.array(pos), np.array(flank), np.array(normal)
