"""The full ring of N sectors by plain index bookkeeping: an independent reference for cyclic symmetry.

Sector s is sector 0 rotated by s·α about x (α = 2π/N). Its matrices in the
global frame are ``Q_s A Q_sᵀ`` with ``Q_s = blockdiag(R^s)`` (isotropic
material: a rotated copy of the same body). Ring nodes: every node of every
sector, except that sector s's high-face node i *is* sector s+1's low-face
node i (the faces are matched by coordinates here, with a KD-tree — not with
reduction.cyclic's maps), and that a tied blade flank node *is* its disk
partner. ``G_s`` (n_ring, n_sector) places sector s: block R^s at (ring id,
sector node); ``A_ring = Σ G_s A G_sᵀ``, ``f_ring = Σ G_s f``, and sector
0's displacement is ``G_0ᵀ u_ring`` (R⁰ = I).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree


def rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def ring_ids(coords, low_nodes, high_nodes, follow, n_sectors):
    """(N, nb) ring node id of each sector node and the ring node count.

    ``follow[j]`` = the node j is identified with inside its own sector (its
    disk partner for a tied blade flank node, else j).
    """
    nb = coords.shape[0]
    R = rot_x(2 * np.pi / n_sectors)
    d, idx = cKDTree(coords[high_nodes]).query(coords[low_nodes] @ R.T)
    assert d.max() < 1e-9 * np.abs(coords).max()
    high_of_low = np.asarray(high_nodes)[idx]          # high node i = image of low node low_nodes[i]
    is_high = np.zeros(nb, bool)
    is_high[high_of_low] = True
    own = np.flatnonzero(~is_high & (follow == np.arange(nb)))
    n_own = own.size
    local = -np.ones(nb, np.int64)
    local[own] = np.arange(n_own)
    ids = np.empty((n_sectors, nb), np.int64)
    for s in range(n_sectors):
        ids[s] = s * n_own + local[follow]
        nxt = ((s + 1) % n_sectors) * n_own
        ids[s, high_of_low] = nxt + local[np.asarray(low_nodes)]
    assert (ids >= 0).all()
    return ids, n_sectors * n_own


def placements(ids: np.ndarray, n_ring: int, n_sectors: int) -> list[sp.csr_matrix]:
    """``G_s`` (3 n_ring, 3 nb) for each sector."""
    nb = ids.shape[1]
    out = []
    for s in range(n_sectors):
        Rs = rot_x(2 * np.pi * s / n_sectors)
        rows = (3 * ids[s][:, None, None] + np.arange(3)[None, :, None]) * np.ones((1, 1, 3), np.int64)
        cols = (3 * np.arange(nb)[:, None, None] + np.arange(3)[None, None, :]) * np.ones((1, 3, 1), np.int64)
        vals = np.broadcast_to(Rs, (nb, 3, 3))
        G = sp.csr_matrix((vals.ravel(), (rows.ravel(), cols.ravel())), shape=(3 * n_ring, 3 * nb))
        G.sum_duplicates()
        out.append(G)
    return out


def assemble_ring(A: sp.spmatrix, G: list) -> sp.csr_matrix:
    return sum((g @ A @ g.T for g in G[1:]), G[0] @ A @ G[0].T).tocsr()


def ring_from_bundle(bundle):
    """(ids, G, free ring DOFs) of the tied, clamped ring of ``bundle`` (which carries ``cyclic``)."""
    nb = bundle.n_dofs // 3
    follow = np.arange(nb)
    b, d = bundle.contact.blade_dofs[:, 0] // 3, bundle.contact.disk_dofs[:, 0] // 3
    follow[b] = d
    cy = bundle.cyclic
    ids, n_ring = ring_ids(bundle.coords, cy.low_dofs[:, 0] // 3, cy.high_dofs[:, 0] // 3, follow, cy.n_sectors)
    G = placements(ids, n_ring, cy.n_sectors)
    clamped_nodes = np.unique(bundle.loads.fixed // 3)
    fixed_ring = np.unique((3 * ids[:, clamped_nodes][..., None] + np.arange(3)).ravel())
    free = np.setdiff1d(np.arange(3 * n_ring), fixed_ring)
    return ids, G, free
