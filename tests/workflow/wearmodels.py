"""Small grounded contact models for the pseudo-time and wear tests (no FE).

``block_model``: p contact nodes (3 DOFs each, pair frame n, t1, t2; the disk
is rigid so u_r = u_node) tied by springs to a root block (3 DOFs) that
carries a tip mass along t1. A static ``preload`` (per pair) pushes the nodes
into the disk; a harmonic force on the tip drives the tangential motion.
Condensation per harmonic as in contracts §5 (``Zr = (B H Bᵀ)⁻¹``).
"""
from __future__ import annotations

import numpy as np

from workflow.contact import ContactLaw
from workflow.hb import HBProblem
from workflow.lumped import pairs_on_block


def block_model(preload=(6.0, 12.0, 6.0), force=2.0, seed=0) -> dict:
    preload = np.asarray(preload, dtype=float)
    p = preload.size
    M, K, blk, tip = pairs_on_block(p, k_n=2.0e5, k_t=1.0e5, scatter=(1.0, 0.2), m_node=0.01, m_block=0.5,
                                    ground=10.0, m_tip=0.2, k_tip=0.2 * (2 * np.pi * 25.0) ** 2,
                                    rng=np.random.default_rng(seed))
    nd = M.shape[0]
    C = 2e-4 * K + 0.5 * M
    B = np.zeros((3 * p, nd))
    B[:, : 3 * p] = np.eye(3 * p)
    f0 = np.zeros(nd)
    f0[0:3 * p:3] = -preload
    f1 = np.zeros(nd)
    f1[tip] = force
    return {"M": M, "K": K, "C": C, "B": B, "f0": f0, "f1": f1, "tip": tip, "p": p}


def condense(model: dict, omega: float, nh: int):
    M, K, C, B = model["M"], model["K"], model["C"], model["B"]
    m = B.shape[0]
    Zr = np.zeros((nh + 1, m, m), dtype=complex)
    Fr = np.zeros((nh + 1, m), dtype=complex)
    for j in range(nh + 1):
        f = model["f0"] if j == 0 else (model["f1"] if j == 1 else np.zeros(K.shape[0]))
        H = np.linalg.inv(K - (j * omega) ** 2 * M + 1j * j * omega * C)
        Zr[j] = np.linalg.inv(B @ H @ B.T)
        Fr[j] = Zr[j] @ (B @ (H @ f))
    Zr[0] = Zr[0].real
    Fr[0] = Fr[0].real
    return Zr, Fr


def law(p, mu=0.3, eps=1e5) -> ContactLaw:
    return ContactLaw(mu=np.full(p, float(mu)), eps_n=eps, eps_t=eps, gap=np.zeros(p))


def hb_problem(freq_hz=20.0, nh=3, nit=32, method="hbm", mu=0.3, **kw) -> HBProblem:
    model = block_model(**kw)
    Zr, Fr = condense(model, 2 * np.pi * freq_hz, nh)
    return HBProblem(Zr, Fr, law(model["p"], mu), nh, nit, method)
