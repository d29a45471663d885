"""Small grounded contact models for the pseudo-time and wear tests (no FE).

``block_model``: p contact nodes (3 DOFs each, pair frame n, t1, t2; the disk
is rigid so u_r = u_node) tied by springs to a root block (3 DOFs) that
carries a tip mass along t1. A static ``preload`` (per pair) pushes the nodes
into the disk; a harmonic force on the tip drives the tangential motion.
Condensation per harmonic as in contracts §5 (``Zr = (B H Bᵀ)⁻¹``).
"""
from __future__ import annotations

import numpy as np

from workflow.engine.contact import ContactLaw
from workflow.engine.hb import HBProblem
from hbmodels import root_model


def block_model(preload=(6.0, 12.0, 6.0), force=2.0, seed=0) -> dict:
    preload = np.asarray(preload, dtype=float)
    return root_model(preload.size, preload=preload, force=force, force_t2=0.0, seed=seed)


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
