"""Small gmsh models with the physical groups of contracts §1, for tests.

``dovetail_msh``: a prismatic blade root (trapezoid, wider at the bottom)
held in a disk slot; the two bodies touch only on the two inclined flanks,
which carry identical meshes (``setPeriodic``, identity; no fragment: DESIGN
§4). ``bar_msh``: a clamped bar with ``blade``/``disk_clamp``/``blade_tip``.
"""
from __future__ import annotations


import gmsh
import numpy as np

# Half profile in the y–z plane (m): lobe half-width b1 at z1, neck half-width
# b2 at z2 > z1 (a dovetail: the disk overhangs the blade flank), slot bottom
# clearance g, disk half-width w from z = 0; blade neck up to z2 + H.
DOVETAIL = dict(b1=0.006, z1=0.010, b2=0.003, z2=0.014, g=0.002, w=0.012, H=0.010, L=0.020)


def _poly(pts):
    p = [gmsh.model.occ.addPoint(y=y, z=z, x=0.0) for y, z in pts]
    lines = [gmsh.model.occ.addLine(p[i], p[(i + 1) % len(p)]) for i in range(len(p))]
    return gmsh.model.occ.addPlaneSurface([gmsh.model.occ.addCurveLoop(lines)])


def _surface_near(vol, centre, tol=1e-7):
    for dim, tag in gmsh.model.getBoundary([(3, vol)], oriented=False):
        c = gmsh.model.occ.getCenterOfMass(dim, tag)
        if np.allclose(c, centre, atol=tol):
            return tag
    raise RuntimeError(f"no face of volume {vol} at {centre}")


def dovetail_msh(path, h=0.004, order=2, d=DOVETAIL, periodic=True) -> dict:
    """Write the two-body dovetail to ``path``; return a geometry-info dict.

    ``periodic=False`` meshes the flanks independently (a broken model whose
    vertices do not coincide, for error tests)."""
    b1, z1, b2, z2, g, w, H, L = (d[k] for k in ("b1", "z1", "b2", "z2", "g", "w", "H", "L"))
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.model.add("dovetail")
        blade2 = _poly([(-b1, z1), (b1, z1), (b2, z2), (b2, z2 + H), (-b2, z2 + H), (-b2, z2)])
        disk2 = _poly([(-w, 0), (w, 0), (w, z2), (b2, z2), (b1, z1), (b1, z1 - g), (-b1, z1 - g), (-b1, z1),
                       (-b2, z2), (-w, z2)])
        blade = gmsh.model.occ.extrude([(2, blade2)], L, 0, 0)[1][1]
        disk = gmsh.model.occ.extrude([(2, disk2)], L, 0, 0)[1][1]
        gmsh.model.occ.remove([(2, blade2), (2, disk2)], recursive=False)
        gmsh.model.occ.synchronize()
        ym, zm = 0.5 * (b1 + b2), 0.5 * (z1 + z2)
        flank = {}
        for side, sgn in (("intrados", -1), ("extrados", 1)):
            c = (L / 2, sgn * ym, zm)
            flank[side] = (_surface_near(blade, c), _surface_near(disk, c))
        clamp = _surface_near(disk, (L / 2, 0.0, 0.0))
        tip = _surface_near(blade, (L / 2, 0.0, z2 + H))
        eye = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
        for bl, dk in flank.values() if periodic else ():
            gmsh.model.mesh.setPeriodic(2, [bl], [dk], eye)
        gmsh.model.addPhysicalGroup(3, [blade], 1)
        gmsh.model.addPhysicalGroup(3, [disk], 2)
        gmsh.model.addPhysicalGroup(2, [flank["intrados"][0]], 11)
        gmsh.model.addPhysicalGroup(2, [flank["extrados"][0]], 12)
        gmsh.model.addPhysicalGroup(2, [flank["intrados"][1]], 21)
        gmsh.model.addPhysicalGroup(2, [flank["extrados"][1]], 22)
        gmsh.model.addPhysicalGroup(2, [clamp], 31)
        gmsh.model.addPhysicalGroup(2, [tip], 41)
        gmsh.option.setNumber("Mesh.CharacteristicLengthMax", h)
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(order)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(path))
        vb = gmsh.model.occ.getMass(3, blade)
        vd = gmsh.model.occ.getMass(3, disk)
    finally:
        gmsh.finalize()
    s = np.hypot(b1 - b2, z2 - z1)
    return {"volume_blade_m3": vb, "volume_disk_m3": vd, "flank_area_m2": 2 * s * L,
            "tip_point": [L, 0.0, z2 + H], "excitation_direction": [1.0, 0.0, 0.0]}


def bar_msh(path, dims, h, axis=0, order=2) -> dict:
    """A box bar of full extents ``dims`` (m), from 0 to its length along ``axis``
    and centred on the other two axes: blade=1, disk_clamp=31 (root face at 0),
    blade_tip=41 (free end)."""
    dims = np.asarray(dims, dtype=float)
    lo = -dims / 2
    lo[axis] = 0.0
    root, end = np.zeros(3), np.zeros(3)
    end[axis] = dims[axis]
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.model.add("bar")
        v = gmsh.model.occ.addBox(*lo, *dims)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [v], 1)
        gmsh.model.addPhysicalGroup(2, [_surface_near(v, root)], 31)
        gmsh.model.addPhysicalGroup(2, [_surface_near(v, end)], 41)
        gmsh.option.setNumber("Mesh.CharacteristicLengthMax", h)
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(order)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    direction = np.zeros(3)
    direction[(axis + 2) % 3] = 1.0
    return {"volume_blade_m3": float(np.prod(dims)), "volume_disk_m3": 0.0,
            "tip_point": end.tolist(), "excitation_direction": direction.tolist()}
