"""Constraint maps on the full DOF vector: clamping and tying the interface.

``u = T v``: ``T`` keeps the free DOFs and, when tying, writes every blade
contact DOF as its disk partner's (or 0 for a grounded partner). Then
``TᵀKT``, ``TᵀMT`` are the constrained operators. A bundle's tied midside
DOFs (``contact.tie``, the ``"linear"`` contact layout) always follow their
edge, ``u_dep = (u_a + u_b)/2``: they are part of the structure.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from reduction.bundle import Bundle


def constraint_map(bundle: Bundle, tied: bool) -> sp.csr_matrix:
    """(n, n_kept) sparse map from kept DOFs to all DOFs.

    Clamped DOFs are dropped. With ``tied``, blade contact DOFs are dropped and
    follow their disk partners (node-to-node bonding: the interface as one
    body, the paper's "tied" limit). Tied midside DOFs (``contact.tie``) are
    dropped and follow their edges in every case.
    """
    n, c = bundle.n_dofs, bundle.contact
    fixed = np.asarray(bundle.loads.fixed, dtype=np.int64)
    tie = getattr(c, "tie", None)
    if tie is None or not len(tie):
        return _follow_map(n, fixed, c.blade_dofs, c.disk_dofs, tied)
    from reduction.tie import tie_matrix

    T_tie, kept = tie_matrix(n, tie)
    col = -np.ones(n, dtype=np.int64)
    col[kept] = np.arange(kept.size)
    renum = lambda d: np.where(np.asarray(d) >= 0, col[np.maximum(np.asarray(d), 0)], -1)  # noqa: E731
    return (T_tie @ _follow_map(kept.size, col[fixed], renum(c.blade_dofs), renum(c.disk_dofs), tied)).tocsr()


def _follow_map(n: int, fixed: np.ndarray, blade_dofs: np.ndarray, disk_dofs: np.ndarray,
                tied: bool) -> sp.csr_matrix:
    """The 0/1 map of :func:`constraint_map` on ``n`` DOFs without ties."""
    follow = np.arange(n)  # DOF i takes the value of DOF follow[i]; -1 → zero
    follow[fixed] = -1
    if tied:
        b, d = np.asarray(blade_dofs).ravel(), np.asarray(disk_dofs).ravel()
        on_blade = b >= 0
        follow[b[on_blade]] = np.where(d[on_blade] >= 0, follow[np.maximum(d[on_blade], 0)], -1)
    kept = np.flatnonzero(follow == np.arange(n))
    col_of = -np.ones(n, dtype=np.int64)
    col_of[kept] = np.arange(kept.size)
    rows = np.flatnonzero(follow >= 0)
    cols = col_of[follow[rows]]
    if np.any(cols < 0):  # a chain blade→disk→clamped: resolve the clamped end
        good = cols >= 0
        rows, cols = rows[good], cols[good]
    return sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n, kept.size))


def constrain(A: sp.spmatrix, T: sp.spmatrix) -> sp.csr_matrix:
    """``Tᵀ A T`` as CSR."""
    return (T.T @ A @ T).tocsr()
