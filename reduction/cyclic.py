"""Cyclic symmetry of a tuned bladed disk: one sector's constraint per nodal diameter.

A tuned disk is N identical sectors; sector s is sector 0 rotated by
``s·α`` about the engine axis x, ``α = 2π/N``. Its linear motions split
into nodal diameters k = 0 … N−1 (Thomas 1979; Petrov 2004 §2): in ND k
sector s moves as sector 0 rotated and phase-shifted,
``u_s(R^s x) = e^{i s φ_k} R^s u_0(x)``, ``φ_k = 2πk/N``. The sector's
high cyclic face is the low face rotated by α (``x_high = R x_low``) and
touches sector 1's low face, so continuity reads

    u_high = e^{iφ_k} R u_low                         (cyclic constraint)

with R the 3×3 rotation by α about x. Keeping every DOF but those of the
high face, ``u = T_k v`` and the sector operators of ND k are
``K_k = T_kᴴ K T_k`` (Hermitian), the same for M and C. ND k and N−k are
complex conjugates (the same frequencies, waves travelling opposite ways);
k = 0 and k = N/2 are real.

Conventions (docs/contracts.md §3 for the complex amplitudes): a complex
ND-k field ``v`` is sector 0's complex amplitude; its physical motion on
sector s is ``Re(e^{i s φ_k} R^s v e^{iωt})``. The engine-order EO
excitation of the cyclic scenes, ``F_s(t) = Re(R^s F e^{i(ωt + s·2π·EO/N)})``,
makes harmonic n of the tuned steady state live on ND ``(n·EO) mod N``.

Units: none of their own (maps are dimensionless); angles in rad.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from workflow.errors import GeometryError


def rotation_x(angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` [rad] about the x axis (the engine axis)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def match_faces(coords: np.ndarray, low: np.ndarray, high: np.ndarray, n_sectors: int,
                tol: float) -> np.ndarray:
    """Order ``high`` so that ``coords[high[i]] = R(2π/N) coords[low[i]]``.

    ``coords``: (n_nodes, 3) [m]; ``low``, ``high``: node indices of the two
    cyclic faces; ``tol`` [m]: largest accepted distance. Raises
    :class:`GeometryError` when the faces are not images of each other (the
    mesh is not periodic, or the faces are swapped).
    """
    from scipy.spatial import cKDTree

    low, high = np.asarray(low, np.int64), np.asarray(high, np.int64)
    if low.size != high.size:
        raise GeometryError(f"cyclic faces have {low.size} and {high.size} nodes: the mesh is not periodic")
    image = coords[low] @ rotation_x(2.0 * np.pi / n_sectors).T
    dist, idx = cKDTree(coords[high]).query(image)
    if low.size and (dist.max() > tol or np.unique(idx).size != low.size):
        raise GeometryError(f"cyclic faces do not match under the rotation by 2π/{n_sectors} "
                            f"(largest distance {dist.max():.3g} m > {tol:.3g} m)")
    return high[idx]


def cyclic_map(n_dofs: int, low_dofs: np.ndarray, high_dofs: np.ndarray, n_sectors: int, nd: int,
               fixed: np.ndarray | None = None) -> sp.csr_matrix:
    """Sparse ``T_k`` (n_dofs, n_kept) with ``u = T_k v`` obeying the cyclic constraint of ND ``nd``.

    ``low_dofs``, ``high_dofs``: (m, 3) x, y, z DOF indices of matched nodes
    (``high_dofs[i]`` is the image of ``low_dofs[i]``; see
    :func:`match_faces`). ``fixed``: clamped DOFs, dropped (a high node
    whose low partner is clamped is clamped too). Kept DOFs are all DOFs but
    the high face's and the clamped, in increasing order. Real (float) for
    ND 0 and N/2, complex otherwise.
    """
    low_dofs, high_dofs = np.asarray(low_dofs, np.int64), np.asarray(high_dofs, np.int64)
    if low_dofs.shape != high_dofs.shape or low_dofs.ndim != 2 or low_dofs.shape[1:] != (3,):
        raise ValueError(f"cyclic_map: low/high DOFs must both be (m, 3), got {low_dofs.shape}, {high_dofs.shape}")
    if not 0 <= nd < n_sectors:
        raise ValueError(f"nodal diameter {nd} outside 0 … {n_sectors - 1}")
    fixed = np.zeros(0, np.int64) if fixed is None else np.asarray(fixed, np.int64)
    dropped = np.zeros(n_dofs, bool)
    dropped[high_dofs.ravel()] = True
    dropped[fixed] = True
    kept = np.flatnonzero(~dropped)
    col = -np.ones(n_dofs, np.int64)
    col[kept] = np.arange(kept.size)
    phase = np.exp(2j * np.pi * nd / n_sectors)
    real = (2 * nd) % n_sectors == 0
    # high DOF a of node i = phase · Σ_b R[a, b] · low DOF b of node i
    R = rotation_x(2.0 * np.pi / n_sectors)
    rows = np.repeat(high_dofs, 3, axis=1).ravel()  # (m, 3a·3b)
    cols = col[np.tile(low_dofs, (1, 3))].ravel()
    vals = np.tile(R.ravel(), low_dofs.shape[0]) * phase
    high_fixed = np.isin(high_dofs, fixed).any(axis=1)
    keep = (cols >= 0) & ~np.repeat(high_fixed, 9) & (np.abs(vals) > 1e-15)
    rows = np.concatenate([kept, rows[keep]])
    cols = np.concatenate([np.arange(kept.size), cols[keep]])
    vals = np.concatenate([np.ones(kept.size, complex), vals[keep]])
    T = sp.csr_matrix((vals.real if real else vals, (rows, cols)), shape=(n_dofs, kept.size))
    T.sum_duplicates()
    return T


def sector_operator(A: sp.spmatrix, T: sp.spmatrix) -> sp.csr_matrix:
    """``T_kᴴ A T_k``: the sector operator of one nodal diameter (Hermitian if A is symmetric)."""
    return (T.conj().T @ A @ T).tocsr()


def constrain_map(T: sp.spmatrix, low_dofs: np.ndarray, high_dofs: np.ndarray, n_sectors: int,
                  nd: int = 0) -> sp.csr_matrix:
    """Compose an existing constraint map ``u = T w`` with the cyclic constraint of ND ``nd``.

    ``T`` (n, n_w) keeps some DOFs as columns (each kept DOF's row has one 1
    in its own column — e.g. :func:`reduction.prestress.tie_map`: clamp and
    tied interface). The cyclic faces' DOFs must not follow other DOFs in
    ``T`` (they are disk DOFs away from the flanks). Pairs whose low or high
    node is dropped by ``T`` (the clamped bore edge, on both faces) are
    skipped. Returns ``T @ T_k`` with ``T_k`` the :func:`cyclic_map` on w:
    ``u = T T_k v`` obeys both constraints (real for ND 0 and N/2).
    """
    T = sp.csr_matrix(T)
    low_dofs, high_dofs = np.asarray(low_dofs, np.int64), np.asarray(high_dofs, np.int64)

    def column(d: np.ndarray) -> np.ndarray:
        nnz = np.diff(T.indptr)[d]
        c = -np.ones(d.shape, np.int64)
        c[nnz == 1] = T.indices[T.indptr[d[nnz == 1]]]
        return c

    cl, ch = column(low_dofs), column(high_dofs)
    ok = (cl >= 0).all(axis=1) & (ch >= 0).all(axis=1)
    return (T @ cyclic_map(T.shape[1], cl[ok], ch[ok], n_sectors, nd)).tocsr()


def face_dofs(low_blocks: np.ndarray, high_blocks: np.ndarray, coords: np.ndarray, n_sectors: int,
              bs: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """(low_dofs, high_dofs), each (m, bs), of the cyclic faces' DOF blocks, high matched to low.

    ``coords`` (n_blocks, 3) [m] the block coordinates; matching tolerance
    1e-8 of the model size (:func:`match_faces`).
    """
    low = np.unique(np.asarray(low_blocks, np.int64))
    high = match_faces(coords, low, np.unique(np.asarray(high_blocks, np.int64)), n_sectors,
                       1e-8 * float(np.abs(coords).max()))
    return bs * low[:, None] + np.arange(bs), bs * high[:, None] + np.arange(bs)
