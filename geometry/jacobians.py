"""Signed Jacobian determinants and element heights of Lagrange tetrahedra.

Used to prove that moving a mesh kept every element's orientation: a cell is
valid after the motion when its Jacobian determinant has the same sign as
before at every check point (the 4 vertices and the points of a degree-4
quadrature rule). dolfinx does not orient gmsh's cells, so the *sign* before
the motion may be either; what must not change is the sign.

Node numbering is dolfinx's (basix) for the coordinate element: vertices 0–3,
then for degree 2 the edges (2,3), (1,3), (1,2), (0,3), (0,2), (0,1).
Pure numpy (+ basix for the shape functions): arrays in, arrays out, SI.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

#: Vertices of the reference tetrahedron.
REF_VERTICES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


@lru_cache(maxsize=4)
def _shape_gradients(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Check points (q, 3) in the reference cell and dφ/dξ (q, 3, nodes)."""
    import basix

    rule, _ = basix.make_quadrature(basix.CellType.tetrahedron, 4)
    pts = np.vstack([REF_VERTICES, rule])
    el = basix.create_element(basix.ElementFamily.P, basix.CellType.tetrahedron, degree,
                              basix.LagrangeVariant.equispaced)
    tab = el.tabulate(1, pts)  # (1 + 3 derivatives, q, nodes, 1)
    return pts, np.moveaxis(tab[1:4, :, :, 0], 0, 1)


def degree_of(nodes_per_cell: int) -> int:
    """Lagrange degree of a tetrahedron with this many nodes (4 → 1, 10 → 2)."""
    for k in (1, 2, 3):
        if (k + 1) * (k + 2) * (k + 3) // 6 == nodes_per_cell:
            return k
    raise ValueError(f"{nodes_per_cell} nodes per cell is not a Lagrange tetrahedron")


def jacobian_determinants(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(n_cells, q) signed det(∂x/∂ξ) [m³ per unit reference volume] at the check points.

    ``x``: (N, 3) node coordinates [m]; ``cells``: (n_cells, nodes) node
    indices in basix order.
    """
    x = np.asarray(x, dtype=float)
    cells = np.asarray(cells)
    _, dphi = _shape_gradients(degree_of(cells.shape[1]))
    xc = x[cells]  # (c, nodes, 3)
    J = np.einsum("qjn,cni->cqij", dphi, xc)  # J[c,q,i,j] = ∂x_i/∂ξ_j
    return np.linalg.det(J)


def orientation_ratio(det_before: np.ndarray, det_after: np.ndarray) -> np.ndarray:
    """Per cell, min over check points of det_after/det_before (> 0: orientation kept)."""
    return np.min(det_after / det_before, axis=1)


def cell_heights(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(n_cells,) smallest height [m] of each tetrahedron (vertex to opposite face).

    A vertex that moves by less than its height cannot, alone, flip a
    straight tetrahedron; this is the "local element size" of the remap.
    """
    v = np.asarray(x, dtype=float)[np.asarray(cells)[:, :4]]
    e1, e2, e3 = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0], v[:, 3] - v[:, 0]
    vol6 = np.abs(np.einsum("ci,ci->c", e1, np.cross(e2, e3)))
    faces = ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2))
    area2 = np.stack([np.linalg.norm(np.cross(v[:, b] - v[:, a], v[:, c] - v[:, a]), axis=1) for a, b, c in faces],
                     axis=1)
    return vol6 / area2.max(axis=1)  # h = 3V / A = (6V) / (2A)


def node_sizes(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(N,) local element size [m] at each node: the smallest height of the
    cells that contain it (inf for nodes in no cell)."""
    h = cell_heights(x, cells)
    out = np.full(len(x), np.inf)
    np.minimum.at(out, np.asarray(cells).ravel(), np.repeat(h, np.asarray(cells).shape[1]))
    return out
