"""A clamped slender bar: the simplest mesh with the sector's groups, to test
the assembly against Euler–Bernoulli (first bending frequency of a
cantilever: f₁ = (1.8751²/2π)·√(EI/(ρAL⁴))).
"""
from __future__ import annotations

import math

from geometry import meshing as gm
from workflow.errors import GeometryError

#: Physical groups of the bar: name → (dim, tag), a subset of the sector's.
BAR_GROUPS = {"blade": (3, 1), "disk_clamp": (2, 31), "blade_tip": (2, 41)}


def build_bar(length: float, width: float, height: float, h: float, msh_path, order: int = 2) -> dict:
    """Mesh the box 0 ≤ x ≤ length, |y| ≤ width/2, |z| ≤ height/2 (m) with
    tetrahedra of size ``h`` (m) and ``order`` 1 or 2; write ``msh_path``.

    Groups: ``blade`` (3, 1) the volume, ``disk_clamp`` (2, 31) the face
    x = 0, ``blade_tip`` (2, 41) the face x = length, with a mesh vertex at
    its centre. Returns ``n_nodes``, ``n_elements``, ``element_order``,
    ``volume_m3``, ``tip_point``, quality figures and ``groups``.
    """
    for name, v in (("length", length), ("width", width), ("height", height), ("h", h)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise GeometryError(f"bar parameter {name!r}: must be a finite number > 0, got {v!r}")
    if order not in (1, 2):
        raise GeometryError(f"bar parameter 'order': must be 1 or 2, got {order!r}")
    est = 1.5 * length * width * height / (h ** 3 / (6 * math.sqrt(2)))
    if est > gm_limit():
        raise GeometryError(f"bar parameter 'h': {h} m would make ~{est:.3g} elements (limit {gm_limit()})")

    import gmsh

    tip = [float(length), 0.0, 0.0]
    with gm.gmsh_session("bladewear-bar"):
        occ = gmsh.model.occ
        vol = occ.addBox(0.0, -0.5 * width, -0.5 * height, length, width, height)
        pt = occ.addPoint(*tip)
        occ.synchronize()
        tol = gm.BBOX_TOL * max(length, width, height)
        big = max(width, height)
        clamp = gm.one_face(vol, (0.0, -big, -big), (0.0, big, big), tol, "clamp")
        tipf = gm.one_face(vol, (length, -big, -big), (length, big, big), tol, "tip")
        gmsh.model.mesh.embed(0, [pt], 2, tipf)
        gm.add_group(3, [vol], 1, "blade")
        gm.add_group(2, [clamp], 31, "disk_clamp")
        gm.add_group(2, [tipf], 41, "blade_tip")
        gm.set_point_sizes(gm.boundary([(3, vol)], 0) + [pt], lambda _: h)
        gm.set_mesh_options(h / 20.0, h)
        gm.generate(order, [vol])
        info = {"volume_m3": float(occ.getMass(3, vol))}
        info.update(gm.check_quality(order))
        info.update(gm.write_msh(msh_path, _measure))
    info.update(element_order=order, tip_point=tip, groups={k: list(v) for k, v in BAR_GROUPS.items()})
    return info


def gm_limit() -> int:
    from geometry.params import MAX_ELEMENTS

    return MAX_ELEMENTS


def _measure(msh_file) -> dict:
    with gm.reading(msh_file):
        n_nodes, n_el = gm.mesh_counts()
    return {"n_nodes": n_nodes, "n_elements": n_el}
