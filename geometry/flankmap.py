"""Values known at the contact nodes of a flank, carried to any point of it.

The contact nodes are the flank mesh vertices, but a flank also has mid-edge
nodes (quadratic meshes) and a user's mesh may be finer than its contact
grid. A flank is (nearly) planar, so each point gets two in-plane parameters
(along, across) from the principal axes of the contact nodes, and values are
interpolated linearly on the Delaunay triangulation of the contact nodes in
that plane. Points that coincide with a contact node (within ``snap``) take
its value exactly — no round-off from barycentric weights — and points just
outside the triangulation (round-off on the flank's border) take the nearest
node's value.

Pure numpy/scipy: arrays in, arrays out; coordinates in metres.
"""
from __future__ import annotations

import numpy as np
from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator
from scipy.spatial import cKDTree

#: Points closer than this fraction of the smallest contact-node spacing coincide.
SNAP_REL = 1e-6


def flank_axes(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centroid (3,) and in-plane unit axes (2, 3) of a set of flank points.

    The axes are the two principal directions of the point cloud (largest
    spread first: "along", then "across"); the third, dropped, is the normal.
    """
    points = np.asarray(points, dtype=float)
    c = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - c, full_matrices=False)
    return c, vt[:2]


def flank_params(points: np.ndarray, centre: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """(m, 2) in-plane coordinates [m] of points (m, 3) in the frame ``(centre, axes)``."""
    return (np.asarray(points, dtype=float) - centre) @ axes.T


def min_spacing(points: np.ndarray) -> float:
    """Smallest distance [m] between two distinct points (inf for fewer than two)."""
    if len(points) < 2:
        return np.inf
    d, _ = cKDTree(points).query(points, k=2)
    return float(d[:, 1].min())


def interpolate_on_flank(nodes: np.ndarray, values: np.ndarray, targets: np.ndarray,
                         snap: float | None = None) -> np.ndarray:
    """Values at the ``targets`` (m, 3) of a field given at contact ``nodes`` (p, 3).

    ``values``: (p,) or (p, k). Returns (m,) or (m, k): exact copies at
    targets within ``snap`` [m] of a node (default :data:`SNAP_REL` × the
    smallest node spacing), piecewise linear in the flank plane elsewhere,
    nearest-node outside the nodes' hull.
    """
    nodes = np.asarray(nodes, dtype=float)
    values = np.asarray(values, dtype=float)
    targets = np.asarray(targets, dtype=float)
    out_shape = (len(targets),) + values.shape[1:]
    if len(targets) == 0:
        return np.zeros(out_shape)
    if len(nodes) == 0:
        raise ValueError("interpolate_on_flank: no contact nodes on this flank")
    if snap is None:
        snap = SNAP_REL * min_spacing(nodes) if len(nodes) > 1 else 1e-12
    dist, nearest = cKDTree(nodes).query(targets)
    out = np.empty(out_shape)
    hit = dist <= snap
    out[hit] = values[nearest[hit]]
    rest = ~hit
    if np.any(rest):
        if len(nodes) < 3:
            out[rest] = values[nearest[rest]]
            return out
        centre, axes = flank_axes(nodes)
        uv, tv = flank_params(nodes, centre, axes), flank_params(targets[rest], centre, axes)
        lin = LinearNDInterpolator(uv, values)(tv)
        bad = np.isnan(lin).reshape(len(tv), -1).any(axis=1)
        if np.any(bad):
            lin[bad] = NearestNDInterpolator(uv, values)(tv[bad])
        out[rest] = lin
    return out


def common_points(position: np.ndarray, flank: np.ndarray, shape) -> tuple[np.ndarray, np.ndarray]:
    """A ``shape`` = (along, across) grid of points [m] on each flank, spanning
    the pairs' extent in the flank plane; returns (points (k, 3), flank (k,)).
    The contact-mesh study compares its meshes' fields there."""
    pts, fl = [], []
    for f in np.unique(flank):
        x = position[flank == f]
        c, axes = flank_axes(x)
        uv = flank_params(x, c, axes)
        u = np.linspace(uv[:, 0].min(), uv[:, 0].max(), int(shape[0]))
        w = np.linspace(uv[:, 1].min(), uv[:, 1].max(), int(shape[1]))
        U, V = np.meshgrid(u, w, indexing="ij")
        pts.append(c + U.reshape(-1, 1) * axes[0] + V.reshape(-1, 1) * axes[1])
        fl.append(np.full(U.size, f))
    return np.concatenate(pts), np.concatenate(fl)


def profile_at(points, pflank, position, flank, W) -> np.ndarray:
    """A field W (p,) of the pairs at ``position`` (p, 3) [m] on ``flank`` (p,),
    carried to the ``points`` of :func:`common_points` on ``pflank``, flank by
    flank (:func:`interpolate_on_flank`: linear in the flank plane)."""
    out = np.zeros(len(points))
    for f in np.unique(pflank):
        sel = flank == f
        out[pflank == f] = interpolate_on_flank(position[sel], W[sel], points[pflank == f])
    return out
