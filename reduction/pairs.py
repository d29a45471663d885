"""Node-to-node contact pairs on the dovetail flanks (contracts §1–2).

Two layouts of the contact nodes (``nodes`` argument, scene key
``geometry.contact_nodes``):

* ``"vertices"``: the flank mesh *vertices* (corner nodes of the quadratic
  facets); the midside nodes carry no contact. Areas and normals below.
* ``"all"``: every node of the quadratic flank facets (vertices and
  midsides) — a *linear contact layer* over the quadratic interior: each
  6-node facet is split through its midside nodes into 4 three-node
  sub-triangles and each sub-triangle's area is lumped in thirds to its
  corners (:func:`linear_layer`). All areas are positive, they sum to the
  flank area exactly for straight-sided facets (the dovetail flanks are
  planar), and ``Σ A_i x_i = ∫ x dA`` (the lumped sub-triangle has its
  centroid right), so a uniform pressure gives the exact resultant force
  and moment. The consistent P2 weights ``∫ N_i dA`` would give the vertices
  zero area (0 at corners, A/3 at midsides), so p_N = −λ_N/A is undefined
  at vertex pairs that carry load: measured in ``docs/contact-layout.md``.
* ``"linear"``: a linear contact *surface* over the quadratic interior. The
  contact nodes are the vertices, and every midside node of a flank facet
  is tied to the midpoint of its edge, ``u_m = (u_a + u_b)/2``, on the blade
  and on the disk (:func:`tie_midsides`; the bundle's ``contact.tie``,
  applied by the reduction, :mod:`reduction.tie`). Both flank surfaces are
  then piecewise linear on the same triangles, so their gap is linear
  between the vertex pairs: no interpenetration anywhere when the vertex
  pairs are closed or open. Areas are the P1 ones ``∫ φ_i ds`` (A/3 per
  facet and vertex) — the row sums of the layer above with each midside's
  share split between its edge's ends. This is the paper's node count
  (``nodes_along × nodes_across``) on a consistent scheme.

Blade nodes (groups 11, 12) are matched to disk nodes (21, 22) by
coordinates — the flanks are meshed identically (``setPeriodic``) so every
node has a partner at distance ~0. Per pair (``"vertices"``):

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
#: Contact-node layouts (module docstring); "vertices" is the paper's node-to-node layout.
NODE_LAYOUTS = ("vertices", "all", "linear")


def layout_of(geometry_info: dict | None) -> str:
    """The contact-node layout recorded in a geometry info dict (``params.contact_nodes``)."""
    params = (geometry_info or {}).get("params") or {}
    layout = params.get("contact_nodes", "vertices")
    if layout not in NODE_LAYOUTS:
        raise GeometryError(f"geometry.contact_nodes = {layout!r} is not one of {NODE_LAYOUTS}")
    return layout


def linear_layer(tri6: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The linear contact layer of quadratic triangles: 4 sub-triangles each.

    ``tri6``: (t, 6, 3) node coordinates [m], ordered v0, v1, v2, m01, m12,
    m20 (midside m_ab on edge ab). Returns the sub-triangles' corners
    (4t, 3, 3) [m], areas (4t,) [m²] and unit normals (4t, 3), oriented like
    v0 → v1 → v2. For straight-sided facets the four areas are a quarter of
    the facet's each and sum to it exactly.
    """
    tri6 = np.asarray(tri6, dtype=float).reshape(-1, 6, 3)
    v0, v1, v2, m01, m12, m20 = (tri6[:, k] for k in range(6))
    corners = np.concatenate([np.stack(c, axis=1) for c in
                              ((v0, m01, m20), (m01, v1, m12), (m20, m12, v2), (m01, m12, m20))])
    cr = 0.5 * np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area = np.linalg.norm(cr, axis=1)
    if np.any(area <= 0):
        raise GeometryError("a flank facet has a degenerate sub-triangle (zero area)")
    return corners, area, cr / area[:, None]


def lump_to_nodes(points: np.ndarray, corners: np.ndarray, area: np.ndarray, normal: np.ndarray,
                  tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Tributary areas (k,) [m²] and area-weighted normal sums (k, 3) of ``points``.

    Each sub-triangle gives a third of its area (and of its area × normal) to
    each corner — the row sums of its P1 mass matrix — so ``Σ A_i x_i`` is
    the exact first moment ``∫ x dA`` of the layer. Every corner must be one
    of ``points`` within ``tol`` [m].
    """
    points = np.asarray(points, dtype=float)
    flat = np.asarray(corners, dtype=float).reshape(-1, 3)
    if len(flat) == 0:
        return np.zeros(len(points)), np.zeros((len(points), 3))
    dist, idx = cKDTree(points).query(flat)
    if dist.max() > tol:
        raise GeometryError(f"a flank facet node is not a contact node (distance {dist.max():.3g} m, "
                            f"tolerance {tol:.3g} m)")
    w = np.repeat(np.asarray(area, dtype=float) / 3.0, 3)
    nw = np.repeat(np.asarray(normal, dtype=float), 3, axis=0) * w[:, None]
    lumped = np.bincount(idx, weights=w, minlength=len(points))
    nsum = np.stack([np.bincount(idx, weights=nw[:, k], minlength=len(points)) for k in range(3)], axis=1)
    return lumped, nsum


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


def _facet_nodes(V, facet_tags, group: int, xV: np.ndarray) -> np.ndarray:
    """(t, 6, 3) coordinates [m] of this rank's owned facets of ``group``:
    vertices, then the midside node nearest each edge's midpoint."""
    mesh = V.mesh
    fdim = mesh.topology.dim - 1
    facets = dc.tagged_entities(facet_tags, group)
    facets = facets[facets < mesh.topology.index_map(fdim).size_local]
    # locate_dofs_topological is collective: every rank calls it, with or without facets.
    xf = xV[dc.blocks_of_facets(V, facets)]
    if facets.size == 0:
        return np.zeros((0, 6, 3))
    xv = np.asarray(mesh.geometry.x, dtype=float)[dc.facet_vertex_nodes(mesh, facets)]
    tree = cKDTree(xf)
    mids = [xf[tree.query(0.5 * (xv[:, a] + xv[:, b]))[1]] for a, b in ((0, 1), (1, 2), (2, 0))]
    return np.concatenate([xv, np.stack(mids, axis=1)], axis=1)


def flank_node_data(V, facet_tags, flanks=FLANKS):
    """Every flank node (vertices and midsides) and the disk flank facets, on rank 0.

    Returns ``{group: (global_blocks, coords)}`` for every group plus
    ``"facets"`` → ``{disk group: (tri6 (t, 6, 3), mean normal (3,))}`` with
    the mean normal ``∫ n ds`` (outward of the disk); ``None`` on other ranks.
    """
    mesh = V.mesh
    _, ds = dc.measures(mesh, facet_tags=facet_tags)
    n = ufl.FacetNormal(mesh)
    xV = dc.block_coordinates(V)
    out, facets = {}, {}
    for group in [g for pair in flanks for g in pair]:
        out[group] = dc.gather_owned_blocks(V, dc.blocks_on_facets(V, facet_tags, group), xV)
    for _, gd in flanks:
        n_mean = np.array([dc.assemble_scalar(n[i] * ds(gd)) for i in range(3)])
        tri6 = mesh.comm.gather(_facet_nodes(V, facet_tags, gd, xV), root=dc.ROOT)
        if tri6 is not None:
            facets[gd] = (np.concatenate(tri6), n_mean)
    if mesh.comm.rank != dc.ROOT:
        return None
    out["facets"] = facets
    return out


def _layer_area_normal(xd: np.ndarray, tri6: np.ndarray, n_mean: np.ndarray, tol: float):
    """Linear-layer areas (p,), normal sums (p, 3) and vertex mask (p,) at the disk nodes ``xd``."""
    corners, a, nt = linear_layer(tri6)
    # Facet orientation from gmsh is arbitrary: turn every sub-triangle out of the disk.
    nt = nt * np.where(nt @ n_mean < 0, -1.0, 1.0)[:, None]
    area, nsum = lump_to_nodes(xd, corners, a, nt, tol)
    d, _ = cKDTree(tri6[:, :3].reshape(-1, 3)).query(xd)
    return area, nsum, d <= tol


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


def contact_pairs(V, facet_tags, flanks=FLANKS, bs: int = 3, nodes: str = "vertices") -> dict | None:
    """Contact arrays of contracts §2 (rank 0; ``None`` elsewhere).

    Keys: ``blade_dofs``, ``disk_dofs`` (p×3 int), ``normal``, ``t1``, ``t2``
    (p×3), ``area`` (p, m²), ``gap`` (p, m, zeros), ``flank`` (p int),
    ``position`` (p×3, m), and ``vertex`` (p bool: the node is a facet
    corner; not a bundle key, :func:`bundle_keys` drops it). ``nodes``: the
    layout, one of :data:`NODE_LAYOUTS`. Missing flank groups give no pairs
    for that flank.
    """
    if nodes not in NODE_LAYOUTS:
        raise GeometryError(f"contact_nodes = {nodes!r} is not one of {NODE_LAYOUTS}")
    data = (flank_vertex_data if nodes == "vertices" else flank_node_data)(V, facet_tags, flanks)
    if data is None:
        return None
    parts = []
    for f, (gb, gd) in enumerate(flanks):
        (bb, xb), (bd, xd) = data[gb], data[gd]
        if len(xb) == 0 and len(xd) == 0:
            continue
        tol = MATCH_TOL_REL * _spacing(xd)
        ib = _match(xd, xb, tol, f"flank groups {gb} (blade) / {gd} (disk)")
        if nodes == "vertices":
            xs, area, xw, nsum = data["p1"][gd]
            ip = _match(xd, xs, tol, f"disk flank group {gd} (P1 vs P2 vertices)")
            iw = _match(xd, xw, tol, f"disk flank group {gd} (vector P1 vs P2 vertices)")
            area, nsum, vertex = area[ip], nsum[iw], np.ones(len(xd), bool)
        else:
            area, nsum, vertex = _layer_area_normal(xd, *data["facets"][gd], tol)
        tie = None
        if nodes == "linear":
            keep, tie, area, nsum = tie_midsides(xd, vertex, area, nsum, data["facets"][gd][0], tol)
            mid_blocks = np.column_stack([bb[ib][tie[:, 0]], bd[tie[:, 0]]])
            xd, bd, ib, vertex = xd[keep], bd[keep], ib[keep], vertex[keep]
        n, t1, t2 = frames(nsum)
        # Order along x, then across the flank (along the flank's mean t2).
        t2m = t2.mean(axis=0)
        key_x = np.round((xd[:, 0] - xd[:, 0].min()) / max(tol, 1e-15)).astype(np.int64)
        order = np.lexsort((xd @ t2m, key_x))
        part = dict(blade=bb[ib][order], disk=bd[order], normal=n[order], t1=t1[order], t2=t2[order],
                    area=area[order], flank=np.full(len(order), f), position=xd[order], vertex=vertex[order])
        if tie is not None:   # (midside blade block, midside disk block, pair a, pair b), pairs numbered globally
            rank = np.empty_like(order)
            rank[order] = np.arange(len(order)) + sum(len(q["area"]) for q in parts)
            part["ties"] = np.column_stack([mid_blocks, rank[tie[:, 1]], rank[tie[:, 2]]])
        parts.append(part)
    if not parts:
        z = np.zeros((0, 3))
        return dict(blade_dofs=np.zeros((0, 3), np.int64), disk_dofs=np.zeros((0, 3), np.int64), normal=z, t1=z,
                    t2=z, area=np.zeros(0), gap=np.zeros(0), flank=np.zeros(0, np.int64), position=z,
                    vertex=np.zeros(0, bool))
    cat = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    comp = np.arange(bs)
    out = dict(blade_dofs=bs * cat["blade"][:, None] + comp, disk_dofs=bs * cat["disk"][:, None] + comp,
               normal=cat["normal"], t1=cat["t1"], t2=cat["t2"], area=cat["area"], gap=np.zeros(len(cat["area"])),
               flank=cat["flank"].astype(np.int64), position=cat["position"], vertex=cat["vertex"])
    if "ties" in cat:
        out["tie"] = tie_dofs(cat["ties"], out["blade_dofs"], out["disk_dofs"], bs)
    return out


def tie_midsides(x: np.ndarray, vertex: np.ndarray, area: np.ndarray, nsum: np.ndarray, tri6: np.ndarray,
                 tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The ``"linear"`` layout of one flank from its every-node layer data.

    ``x`` (k, 3) every flank node [m], ``vertex`` (k,) its corner mask,
    ``area``, ``nsum`` the linear layer's areas and normal sums
    (:func:`_layer_area_normal`), ``tri6`` the flank facets (t, 6, 3).
    Returns ``keep`` (the vertex indices into ``x``), ``tie`` (k_m, 3) int
    (midside index into ``x``, its edge's two ends as indices into
    ``x[keep]``), and the vertices' areas and normal sums with each
    midside's share split equally between its edge's ends: A/12 + 2·(A/4)/2
    = A/3 per facet and vertex, the P1 areas ``∫ φ_i ds``.
    """
    tree = cKDTree(x)
    ends = {}
    for a, b, m in ((0, 1, 3), (1, 2, 4), (2, 0, 5)):
        dm, im = tree.query(tri6[:, m])
        da, ia = tree.query(tri6[:, a])
        db, ib = tree.query(tri6[:, b])
        if max(dm.max(initial=0), da.max(initial=0), db.max(initial=0)) > tol:
            raise GeometryError("a flank facet node is not a contact node (linear layout)")
        for i, j, k in zip(im, ia, ib):
            ends[int(i)] = (int(j), int(k))
    mids = np.flatnonzero(~vertex)
    if set(mids.tolist()) != set(ends):
        raise GeometryError("linear contact layout: the flank's midside nodes are not the facets' edge midpoints")
    keep = np.flatnonzero(vertex)
    new = -np.ones(len(x), np.int64)
    new[keep] = np.arange(len(keep))
    tie = np.array([(m, new[ends[m][0]], new[ends[m][1]]) for m in mids], dtype=np.int64).reshape(-1, 3)
    if np.any(tie[:, 1:] < 0):
        raise GeometryError("linear contact layout: an edge ends at a midside node")
    W = np.zeros((len(x), len(keep)))
    W[keep, np.arange(len(keep))] = 1.0
    np.add.at(W, (tie[:, 0], tie[:, 1]), 0.5)
    np.add.at(W, (tie[:, 0], tie[:, 2]), 0.5)
    return keep, tie, W.T @ area, W.T @ nsum


def tie_dofs(ties: np.ndarray, blade_dofs: np.ndarray, disk_dofs: np.ndarray, bs: int = 3) -> np.ndarray:
    """Bundle ``contact.tie`` rows (dependent DOF, master a, master b), weights ½ ½:
    per tie (midside blade block, midside disk block, pair a, pair b) and
    component, one row for the blade and one for the disk."""
    rows = []
    for c in range(bs):
        for body, dofs in ((0, blade_dofs), (1, disk_dofs)):
            rows.append(np.column_stack([bs * ties[:, body] + c, dofs[ties[:, 2], c], dofs[ties[:, 3], c]]))
    return np.concatenate(rows).astype(np.int64) if rows else np.zeros((0, 3), np.int64)


def bundle_keys(pairs: dict) -> dict:
    """The entries of a :func:`contact_pairs` dict that the bundle's ``Contact`` holds (contracts §2)."""
    return {k: v for k, v in pairs.items() if k != "vertex"}
