"""The synthetic reduced model of the matrix: contact pairs on a block, a tip mass, optional stiff chain."""
from __future__ import annotations

import numpy as np

from workflow.engine.model import ReducedModel
from workflow.engine.lumped import pairs_on_block


def synthetic_model(p: int = 4, *, preload: float = 0.5, k_contact: float = 2.0e6, extra_modes: int = 0,
                    spread: float = 1.0e3, seed: int = 0) -> ReducedModel:
    """A small :class:`ReducedModel` standing in for the FE one: p contact nodes on a rigid disk.

    DOFs: 3 per contact node (in its pair frame n, t1, t2; the disk side is
    rigid so ``u_r = u_node``), a root block (3) tied to each node by springs
    (~``k_contact`` N/m), a tip mass (1, along t1) on a bending spring (first
    tied mode ≈ 120 Hz) and ``extra_modes`` further masses hung from the
    block in a chain whose natural frequencies spread over ``spread`` (ratio
    highest/lowest): the ill-conditioned reduced model (many modes, widely
    spread frequencies). A weak ground spring keeps K regular when every pair
    separates. Static load: ``preload`` (N per pair) pushing each node into
    the disk (−n); harmonic load 0.1 N on the tip (t1) plus 0.03 N on the
    block (t2) and 0.02 N (n). Rayleigh damping ≈ 0.5 % on the first mode.
    """
    rng = np.random.default_rng(seed)
    mt = 0.05
    M, K, blk, tip = pairs_on_block(p, k_n=k_contact * 2.0, k_t=k_contact, scatter=(1.0, 0.3), m_node=2e-3,
                                    m_block=0.2, ground=1.0e2, m_tip=mt, k_tip=mt * (2 * np.pi * 120.0) ** 2,
                                    rng=rng, extra=extra_modes)
    nd = M.shape[0]
    prev = blk[1]
    for e in range(extra_modes):
        d = 3 * p + 4 + e
        f = 60.0 * spread ** (e / max(extra_modes - 1, 1))       # Hz, log-spread
        m = 1e-2 * spread ** (-e / max(extra_modes - 1, 1))      # lighter and stiffer up the chain
        M[d, d] = m
        k = m * (2 * np.pi * f) ** 2
        K[np.ix_([prev, d], [prev, d])] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
        prev = d
    w1 = 2 * np.pi * 120.0
    C = (0.005 / w1) * K + (0.005 * w1) * M
    B = np.zeros((3 * p, nd))
    B[:, : 3 * p] = np.eye(3 * p)
    f0 = np.zeros(nd)
    f0[0:3 * p:3] = -np.broadcast_to(np.asarray(preload, dtype=float), (p,))
    f1 = np.zeros(nd)
    f1[tip] = 0.1
    f1[blk[2]] = 0.03
    f1[blk[0]] = 0.02
    O = np.zeros((1, nd))
    O[0, tip] = 1.0
    pos = np.zeros((p, 3))
    pos[:, 0] = np.linspace(0.0, 0.04, p)
    return ReducedModel(M=M, K=K, C=C, B=B, f_static=f0, f_harmonic=f1, O=O, area=np.full(p, 1e-6),
                        gap=np.zeros(p), flank=(np.arange(p) >= p // 2).astype(int), position=pos,
                        info={"synthetic": True, "extra_modes": extra_modes, "spread": spread})
