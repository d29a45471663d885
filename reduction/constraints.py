"""Constraint maps on the full DOF vector: clamping and tying the interface.

``u = T v``: ``T`` keeps the free DOFs and, when tying, writes every blade
contact DOF as its disk partner's (or 0 for a grounded partner). Then
``TᵀKT``, ``TᵀMT`` are the constrained operators. A bundle's tied midside
DOFs (``contact.tie``, the ``"linear"`` contact layout) always follow their
edge, ``u_dep = (u_a + u_b)/2``: they are part of the structure.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp

from reduction.bundle import Bundle


def constraint_map(bundle: Bundle, tied: bool) -> sp.csr_matrix:
    """(n, n_kept) sparse 0/1 map from kept DOFs to all DOFs.

    Clamped DOFs are dropped. With ``tied``, blade contact DOFs are dropped and
    follow their disk partners (node-to-node bonding: the interface as one
    body, the paper's "tied" limit).
    """
    n = bundle.n_dofs
    tie = getattr(bundle.contact, "tie", None)
    if tie is not None and len(tie):
        return _with_ties(bundle, tied)
    follow = np.arange(n)  # DOF i takes the value of DOF follow[i]; -1 → zero
    follow[bundle.loads.fixed] = -1
    if tied:
        b, d = bundle.contact.blade_dofs.ravel(), bundle.contact.disk_dofs.ravel()
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


def _with_ties(bundle: Bundle, tied: bool) -> sp.csr_matrix:
    """:func:`constraint_map` of a bundle with ``contact.tie``: the map of the
    structure without the dependent DOFs, composed with ``u_dep = (u_a + u_b)/2``."""
    from reduction.tie import tie_matrix

    T_tie, kept = tie_matrix(bundle.n_dofs, bundle.contact.tie)
    col = -np.ones(bundle.n_dofs, dtype=np.int64)
    col[kept] = np.arange(kept.size)
    c, L = bundle.contact, bundle.loads
    renum = lambda d: np.where(np.asarray(d) >= 0, col[np.maximum(np.asarray(d), 0)], -1)  # noqa: E731
    inner = SimpleNamespace(n_dofs=int(kept.size), loads=SimpleNamespace(fixed=col[np.asarray(L.fixed, np.int64)]),
                            contact=SimpleNamespace(blade_dofs=renum(c.blade_dofs), disk_dofs=renum(c.disk_dofs)))
    return (T_tie @ constraint_map(inner, tied)).tocsr()
