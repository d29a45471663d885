"""Lumped "pairs on a block" structures: small models with node-to-node contact.

A root block (3 DOFs) carries p contact nodes (3 DOFs each, in their pair
frame n, t1, t2; the disk side is rigid, so u_r is the node displacement) on
springs, and a tip mass (1 DOF along t1) on a bending spring to the block.
Their stuck, sliding and open limits are known in closed form, which makes
them the synthetic model of the stiff/extreme matrix and of the tests.
"""
from __future__ import annotations

import numpy as np


def _spring(K: np.ndarray, a: int, b: int, k: float) -> None:
    K[np.ix_([a, b], [a, b])] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])


def pairs_on_block(p: int, *, k_n: float, k_t: float, scatter: tuple[float, float], m_node: float,
                   m_block: float, ground: float, m_tip: float, k_tip: float, rng: np.random.Generator,
                   extra: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Mass and stiffness of the block model, ``(M, K, block_dofs, tip_dof)``.

    ``k_n``, ``k_t``: node–block spring stiffness along n and t1/t2 [N/m],
    each scaled by ``lo + width·U(0,1)`` with ``scatter = (lo, width)`` so
    that pairs differ. ``ground`` [N/m] keeps K regular when every pair
    separates. Masses [kg]; ``k_tip`` [N/m] couples the block's t1 DOF to
    the tip. ``extra`` appends that many zero DOFs for the caller to fill.
    """
    lo, width = scatter
    nd = 3 * p + 4 + extra
    blk = 3 * p + np.arange(3)
    tip = 3 * p + 3
    M = np.zeros((nd, nd))
    K = np.zeros((nd, nd))
    for i in range(p):
        for c in range(3):
            d = 3 * i + c
            M[d, d] = m_node
            _spring(K, d, blk[c], (k_n if c == 0 else k_t) * (lo + width * rng.random()))
    for c in range(3):
        M[blk[c], blk[c]] = m_block
        K[blk[c], blk[c]] += ground
    M[tip, tip] = m_tip
    _spring(K, blk[1], tip, k_tip)
    return M, K, blk, tip
