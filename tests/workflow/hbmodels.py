"""Tiny condensed models for the HB tests (no FE, no reduction package).

``condense`` is a hand-written version of contracts §5: for j = 0…Nh,
``D_j = K − (jω)²M + i jωC``, ``H_j = D_j⁻¹``, ``Zr_j = (B H_j Bᵀ)⁻¹``,
``Fr_j = Zr_j B H_j f_j`` (f_0 static, f_1 harmonic), plus ω-derivatives.
"""
from __future__ import annotations

import numpy as np

from workflow.engine.contact import ContactLaw
from workflow.engine.lumped import pairs_on_block


def condense(model: dict, omega: float, nh: int):
    """(Zr, Fr, dZr, dFr) of a physical model dict with M, K, C, B, f0, f1."""
    M, K, C, B = model["M"], model["K"], model["C"], model["B"]
    m = B.shape[0]
    Zr = np.zeros((nh + 1, m, m), dtype=complex)
    Fr = np.zeros((nh + 1, m), dtype=complex)
    dZr = np.zeros_like(Zr)
    dFr = np.zeros_like(Fr)
    for j in range(nh + 1):
        f = model["f0"] if j == 0 else (model["f1"] if j == 1 else np.zeros(K.shape[0]))
        D = K - (j * omega) ** 2 * M + 1j * j * omega * C
        dD = -2.0 * j ** 2 * omega * M + 1j * j * C
        H = np.linalg.inv(D)
        dH = -H @ dD @ H
        G = B @ H @ B.T
        Z = np.linalg.inv(G)
        dZ = -Z @ (B @ dH @ B.T) @ Z
        Zr[j] = Z
        Fr[j] = Z @ (B @ (H @ f))
        dZr[j] = dZ
        dFr[j] = dZ @ (B @ (H @ f)) + Z @ (B @ (dH @ f))
    Zr[0] = Zr[0].real
    Fr[0] = Fr[0].real
    return Zr, Fr, dZr, dFr


def recover(model: dict, omega: float, lam: np.ndarray, nh: int) -> np.ndarray:
    """Physical harmonics (Nh+1, ndof): q_j = H_j (f_j − Bᵀ λ_j)."""
    M, K, C, B = model["M"], model["K"], model["C"], model["B"]
    q = np.zeros((nh + 1, K.shape[0]), dtype=complex)
    for j in range(nh + 1):
        f = model["f0"] if j == 0 else (model["f1"] if j == 1 else np.zeros(K.shape[0]))
        D = K - (j * omega) ** 2 * M + 1j * j * omega * C
        q[j] = np.linalg.solve(D, f - B.T @ lam[j])
    return q


def root_model(p: int = 2, *, preload: float = 10.0, tangential_static: float = 0.0,
               force: float = 1.0, force_t2: float = 0.3, force_n: float = 0.0,
               seed: int = 0) -> dict:
    """A blade root block on p grounded contact nodes plus a tip mass.

    DOFs: contact nodes (3 each, pair frame n, t1, t2; the disk side is
    rigid so u_r = u_node), a root block (3) and a tip mass (1, along t1).
    Each node is tied to the block by springs; the block to the tip by a
    bending spring; a weak ground spring keeps K invertible when every
    pair separates. Static load: ``preload`` pushing each node into the
    disk (−n) and ``tangential_static`` along t1; harmonic load on the tip
    (t1) and on the block (t2, and n with ``force_n``). ``preload`` may be
    one value per pair. First mode ≈ 25 Hz·2π when stuck.
    """
    mt = 0.2
    M, K, blk, tip = pairs_on_block(p, k_n=2.0e5, k_t=1.0e5, scatter=(1.0, 0.2), m_node=0.01, m_block=0.5,
                                    ground=10.0, m_tip=mt, k_tip=mt * (2 * np.pi * 25.0) ** 2,
                                    rng=np.random.default_rng(seed))
    nd = M.shape[0]
    C = 2e-4 * K + 0.5 * M
    B = np.zeros((3 * p, nd))
    B[:, : 3 * p] = np.eye(3 * p)
    f0 = np.zeros(nd)
    f0[0:3 * p:3] = -preload
    f0[1:3 * p:3] = tangential_static
    f1 = np.zeros(nd)
    f1[tip] = force
    f1[blk[2]] = force_t2
    f1[blk[0]] = force_n
    return {"M": M, "K": K, "C": C, "B": B, "f0": f0, "f1": f1, "tip": tip, "p": p}


def law_for(p: int, mu=0.3, eps=1e5, gap=None, wear=None) -> ContactLaw:
    return ContactLaw(mu=np.broadcast_to(mu, (p,)).astype(float), eps_n=eps, eps_t=eps,
                      gap=np.zeros(p) if gap is None else gap, wear=wear)


def jenkins(k: float, kn: float, N: float, a: float, nh: int):
    """Massless grounded Jenkins element driven in t1: spring k from the driver
    d = a cos τ to the contact node, normal spring kn with static load −N.
    Zr = diag(kn, k, k) in every harmonic, Fr_0 = (−N, 0, 0), Fr_1 = (0, k a, 0)."""
    Zr = np.zeros((nh + 1, 3, 3), dtype=complex)
    Zr[:] = np.diag([kn, k, k])
    Fr = np.zeros((nh + 1, 3), dtype=complex)
    Fr[0, 0] = -N
    if nh >= 1:
        Fr[1, 1] = k * a
    return Zr, Fr


def gap_model(*, force: float = 1.0, k1: float = 1.0e4, k2: float = 3.0e4, m: float = 1.0,
              zeta: float = 0.01) -> dict:
    """A mass (3 DOFs) on ground springs k1, tied by springs k2 to a light contact
    node (3 DOFs) that meets the rigid disk after an initial gap: piecewise
    linear hardening k1 → k1 + k2 once the gap closes (a fold for light damping).
    Harmonic force on the mass towards the disk (−n); no static load."""
    nd = 6
    M = np.diag([1e-3, 1e-3, 1e-3, m, m, m])
    K = np.zeros((nd, nd))
    for c in range(3):
        K[np.ix_([c, 3 + c], [c, 3 + c])] += k2 * np.array([[1, -1], [-1, 1]])
        K[3 + c, 3 + c] += k1
        K[c, c] += 1e-3 * k2
    C = 2 * zeta * np.sqrt(k1 * m) / k1 * K   # stiffness-proportional, ζ at the open mode
    B = np.zeros((3, nd))
    B[:, :3] = np.eye(3)
    f1 = np.zeros(nd)
    f1[3] = -force
    f1[4] = 0.1 * force
    return {"M": M, "K": K, "C": C, "B": B, "f0": np.zeros(nd), "f1": f1, "p": 1, "obs": 3}
