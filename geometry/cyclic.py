"""The disk's cyclic faces: the two cuts of the disk at ±π/N, meshed periodic.

A tuned disk is N copies of the sector rotated by ``α = 2π/N`` about the
engine axis x (``reduction/cyclic.py`` for the conventions). The rim sector
is bounded by two planes through the x axis at angles ±α/2 from the z axis.
With ``R = rotation_x(α)`` (y' = cos α·y − sin α·z) the +y cut maps onto the
−y cut, so the **low** face is the +y cut and the **high** face the −y cut:
``x_high = R x_low``. The high face is meshed as gmsh's periodic copy of the
low face under R (``setPeriodic`` with the 4×4 row-major affine of R), so
every low node has its rotated image on the high face — the node-to-node
matching the cyclic constraint ``u_high = e^{iφ_k} R u_low`` needs.

Units: m, rad.
"""
from __future__ import annotations

import math

import numpy as np

from geometry import meshing as gm
from workflow.errors import GeometryError

#: Physical groups of the cyclic faces: name → (dim, tag).
GROUPS = {"cyclic_low": (2, 51), "cyclic_high": (2, 52)}


def affine(R: np.ndarray) -> list[float]:
    """4×4 row-major affine transform (no translation) of the 3×3 matrix ``R`` — gmsh's layout."""
    A = np.eye(4)
    A[:3, :3] = R
    return [float(v) for v in A.ravel()]


def find_faces(disk: int, r_in: float, r_out: float, length: float, n_sectors: int, tol: float) -> dict:
    """Tags of the disk's cut faces: {'cyclic_low': +y face, 'cyclic_high': −y face}."""
    h = math.pi / n_sectors
    s, c = math.sin(h), math.cos(h)
    out = {}
    for name, sign in (("cyclic_low", 1.0), ("cyclic_high", -1.0)):
        ys = sorted((sign * r_in * s, sign * r_out * s))
        out[name] = gm.one_face(disk, (0.0, ys[0], r_in * c), (length, ys[1], r_out * c), tol,
                                f"disk {name} (cut at {'+' if sign > 0 else '−'}π/{n_sectors})")
    return out


def make_periodic(faces: dict, n_sectors: int) -> None:
    """Mesh the high face as the periodic copy of the low one under the rotation by 2π/N."""
    import gmsh

    from reduction.cyclic import rotation_x

    gmsh.model.mesh.setPeriodic(2, [faces["cyclic_high"]], [faces["cyclic_low"]],
                                affine(rotation_x(2.0 * math.pi / n_sectors)))


def check(n_sectors: int, blade_group: tuple[int, int], r_out: float) -> dict:
    """On the current (read-back) model: every low node has its image on the
    high face and no blade node lies on either cut plane.

    Returns ``cyclic_nodes`` (nodes per face) and ``cyclic_distance_max`` (m,
    largest |R x_low − x_high|); raises :class:`GeometryError` otherwise.
    """
    from reduction.cyclic import match_faces

    tol = 1e-9 * r_out
    _, low = gm.group_nodes(*GROUPS["cyclic_low"])
    _, high = gm.group_nodes(*GROUPS["cyclic_high"])
    if low.size == 0:
        raise GeometryError("gmsh failed: the cyclic faces carry no mesh nodes")
    tags = np.concatenate([low, high])
    xyz = gm.node_coords(tags)
    i_low, i_high = np.arange(low.size), low.size + np.arange(high.size)
    matched = match_faces(xyz, i_low, i_high, n_sectors, tol)   # GeometryError if not periodic
    R = _rotation(n_sectors)
    dist = float(np.linalg.norm(xyz[i_low] @ R.T - xyz[matched], axis=1).max())
    _, blade = gm.group_nodes(*blade_group)
    bxyz = gm.node_coords(blade)
    h = math.pi / n_sectors
    # signed distances of the blade nodes to the two cut planes (normals into the sector)
    d_low = bxyz[:, 2] * math.sin(h) - bxyz[:, 1] * math.cos(h)
    d_high = bxyz[:, 2] * math.sin(h) + bxyz[:, 1] * math.cos(h)
    gap = float(min(d_low.min(), d_high.min()))
    if gap <= tol:
        raise GeometryError(f"the blade reaches a cyclic face (closest blade node {gap:.3g} m from a cut plane): "
                            "narrow geometry.platform_width or lower geometry.n_sectors")
    return {"cyclic_nodes": int(low.size), "cyclic_distance_max": dist, "cyclic_blade_clearance": gap}


def _rotation(n_sectors: int) -> np.ndarray:
    from reduction.cyclic import rotation_x

    return rotation_x(2.0 * math.pi / n_sectors)
