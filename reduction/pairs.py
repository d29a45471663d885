"""Node-to-node contact pairs on the dovetail flanks (contracts §1–2).

Contact nodes are the flank mesh *vertices* (corner nodes of the quadratic
facets). Blade vertices (groups 11, 12) are matched to disk vertices (21, 22)
by coordinates — the flanks are meshed identically (``setPeriodic``) so every
vertex has a partner at distance ~0. Per pair:

* ``normal`` n: outward normal of the disk flank (from the disk into the
  blade), the facet normals averaged at the node with the facet areas as
  weights: ``∫_flank n ψ_i ds`` with vector P1 hat functions ψ_i.
* ``t1``: the axial direction x projected on the tangent plane; ``t2 = n × t1``.
* ``area``: tributary area ``∫_flank φ_i ds`` [m²] with scalar P1 hat
  functions φ_i, so the areas sum to the flank area (DESIGN §3 "Wear").

Ordering: flank (intrados 0, extrados 1), then x, then across the flank —
independent of partition and mesh numbering. Heavy lifting happens on rank 0
after gathering owned entries, so this also runs under MPI.
"""
from __future__ import annotations

import numpy as np
import ufl
from scipy.spatial import cKDTree

from reduction import dolfinx_compat as dc
from workflow.errors import GeometryError

#: (blade group, disk group) per flank, flank 0 = intrados, 1 = extrados.
FLANKS = ((11, 21), (12, 22))
#: Coordinates closer than this fraction of the smallest flank-vertex spacing coincide.
MATCH_TOL_REL = 1e-3


def flank_vertex_data(V, facet_tags, flanks=FLANKS):
    """Gather flank vertex data to rank 0.

    Returns, on rank 0, a dict ``{group: (global_blocks, coords)}`` for every
    group in ``flanks`` plus ``"p1"`` → ``{group: (coords, area, coords, normal_sum)}``
    for the disk groups; ``None`` on other ranks.
    """
    mesh = V.mesh
    S = dc.scalar_space(mesh, 1)
    W = dc.vector_space(mesh, 1)
    _, ds = dc.measures(mesh, facet_tags=facet_tags)
    disk_groups = tuple(d for _, d in flanks)
    dsd = ds(disk_groups)
    phi, psi = ufl.TestFunction(S), ufl.TestFunction(W)
    n = ufl.FacetNormal(mesh)  # on an exterior disk facet: outward of the disk = into the blade
    area = dc.assemble_vector_local(phi * dsd)
    nsum = dc.assemble_vector_local(ufl.inner(n, psi) * dsd).reshape(-1, 3)
    xV, xS = dc.block_coordinates(V), dc.block_coordinates(S)
    out = {}
    for group in [g for pair in flanks for g in pair]:
        blocks = dc.blocks_at_vertices_of_facets(V, facet_tags, group)
        out[group] = dc.gather_owned_blocks(V, blocks, xV)
    p1 = {}
    xW = dc.block_coordinates(W)
    for group in disk_groups:
        g = dc.gather_owned_blocks(S, dc.blocks_at_vertices_of_facets(S, facet_tags, group), xS, area)
        gw = dc.gather_owned_blocks(W, dc.blocks_at_vertices_of_facets(W, facet_tags, group), xW, nsum)
        if g is not None:
            p1[group] = (g[1], g[2], gw[1], gw[2])
    if mesh.comm.rank != dc.ROOT:
        return None
    out["p1"] = p1
    return out


def _match(xa: np.ndarray, xb: np.ndarray, tol: float, what: str) -> np.ndarray:
    """Index into ``xb`` of the point coinciding with each point of ``xa``."""
    if len(xa) != len(xb):
        raise GeometryError(f"{what}: {len(xa)} vs {len(xb)} vertices — the flank meshes are not identical "
                            "(setPeriodic on the flank pair, no fragment: DESIGN §4)")
    dist, idx = cKDTree(xb).query(xa)
    if len(xa) and (dist.max() > tol or len(np.unique(idx)) != len(idx)):
        raise GeometryError(f"{what}: vertices do not coincide (largest distance {dist.max():.3g} m, "
                            f"tolerance {tol:.3g} m)")
    return idx


def _spacing(x: np.ndarray) -> float:
    """Smallest distance between two distinct points of ``x`` [m]."""
    if len(x) < 2:
        return 1.0
    d, _ = cKDTree(x).query(x, k=2)
    return float(d[:, 1].min())


def frames(normal_sum: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit (n, t1, t2), each (p, 3), from area-weighted normal sums.

    t1 is x projected on the tangent plane (y when n ∥ x), t2 = n × t1, so
    (n, t1, t2) is right-handed.
    """
    nrm = np.linalg.norm(normal_sum, axis=1, keepdims=True)
    if np.any(nrm == 0):
        raise GeometryError("a disk flank vertex has a zero normal (no flank facet around it?)")
    n = normal_sum / nrm
    ax = np.tile([1.0, 0.0, 0.0], (len(n), 1))
    ax[np.abs(n[:, 0]) > 0.99] = [0.0, 1.0, 0.0]
    t1 = ax - np.sum(ax * n, axis=1, keepdims=True) * n
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return n, t1, np.cross(n, t1)


def contact_pairs(V, facet_tags, flanks=FLANKS, bs: int = 3) -> dict | None:
    """Contact arrays of contracts §2 (rank 0; ``None`` elsewhere).

    Keys: ``blade_dofs``, ``disk_dofs`` (p×3 int), ``normal``, ``t1``, ``t2``
    (p×3), ``area`` (p, m²), ``gap`` (p, m, zeros), ``flank`` (p int),
    ``position`` (p×3, m). Missing flank groups give no pairs for that flank.
    """
    data = flank_vertex_data(V, facet_tags, flanks)
    if data is None:
        return None
    parts = []
    for f, (gb, gd) in enumerate(flanks):
        (bb, xb), (bd, xd) = data[gb], data[gd]
        if len(xb) == 0 and len(xd) == 0:
            continue
        tol = MATCH_TOL_REL * _spacing(xd)
        ib = _match(xd, xb, tol, f"flank groups {gb} (blade) / {gd} (disk)")
        xs, area, xw, nsum = data["p1"][gd]
        ip = _match(xd, xs, tol, f"disk flank group {gd} (P1 vs P2 vertices)")
        iw = _match(xd, xw, tol, f"disk flank group {gd} (vector P1 vs P2 vertices)")
        n, t1, t2 = frames(nsum[iw])
        # Order along x, then across the flank (along the flank's mean t2).
        t2m = t2.mean(axis=0)
        key_x = np.round((xd[:, 0] - xd[:, 0].min()) / max(tol, 1e-15)).astype(np.int64)
        order = np.lexsort((xd @ t2m, key_x))
        parts.append(dict(blade=bb[ib][order], disk=bd[order], normal=n[order], t1=t1[order], t2=t2[order],
                          area=area[ip][order], flank=np.full(len(order), f), position=xd[order]))
    if not parts:
        z = np.zeros((0, 3))
        return dict(blade_dofs=np.zeros((0, 3), np.int64), disk_dofs=np.zeros((0, 3), np.int64), normal=z, t1=z,
                    t2=z, area=np.zeros(0), gap=np.zeros(0), flank=np.zeros(0, np.int64), position=z)
    cat = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    comp = np.arange(bs)
    return dict(blade_dofs=bs * cat["blade"][:, None] + comp, disk_dofs=bs * cat["disk"][:, None] + comp,
                normal=cat["normal"], t1=cat["t1"], t2=cat["t2"], area=cat["area"], gap=np.zeros(len(cat["area"])),
                flank=cat["flank"].astype(np.int64), position=cat["position"])
