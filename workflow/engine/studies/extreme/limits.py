"""Closed-form limits a case must approach: constrained, free (μ = 0), tied and open-contact responses (m)."""
from __future__ import annotations

import math

import numpy as np

from workflow.engine import fourier
from workflow.engine.contact import SEPARATION
from workflow.engine.hb import HBProblem


def constrained_response(Zr: np.ndarray, Fr: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """Linear response for harmonics ≥ 1 (Nh+1, 3p) with the relative DOFs ``fixed`` (bool, 3p)
    held at 0 and the others free of contact force: ``Z_ff,j U_f,j = F_f,j``; row 0 left zero."""
    nh1, r = Fr.shape
    free = ~np.asarray(fixed, dtype=bool)
    U = np.zeros((nh1, r), dtype=complex)
    if free.any():
        for j in range(1, nh1):
            U[j, free] = np.linalg.solve(Zr[j][np.ix_(free, free)], Fr[j, free])
    return U


def free_limit(Zr: np.ndarray, Fr: np.ndarray, open_pairs: np.ndarray | None = None) -> np.ndarray:
    """μ = 0 limit for harmonics ≥ 1: normal tied on closed pairs, everything else free.

    ``open_pairs`` (bool, p): pairs separated all period (free in all directions); default none.
    """
    r = Fr.shape[1]
    fixed = np.zeros(r, dtype=bool)
    fixed[0::3] = True
    if open_pairs is not None:
        fixed[0::3] &= ~np.asarray(open_pairs, dtype=bool)
    return constrained_response(Zr, Fr, fixed)


def free_first_order(prob0: HBProblem, x0: np.ndarray, mu: float) -> np.ndarray:
    """O(μ) correction (Nh+1, 3p) of the free limit for a small μ > 0 (harmonics ≥ 1; row 0 zero).

    ``prob0``/``x0``: the μ = 0 HB problem and its root (normal tied on closed pairs, λ_T ≡ 0).
    To first order in μ every closed pair slips along the free motion with the Coulomb force
    ``λ_T(t) = μ |λ_N(t)| v_T/‖v_T‖`` (λ_N, v_T of the μ = 0 root; R = Zr U + λ − F, so −λ_T opposes
    the slip velocity); the correction is the free limit's response to −λ_T,
    ``Z_ff,j δU_f,j = −Λ_T,f,j``. The μ > 0 solution lies at ``free + δU + O(μ²)``: how far μ is from
    "small" is ``‖δU‖/‖U_free‖`` (it is ∝ μ·|λ_N|, the static normal force, not μ alone).
    """
    lam = prob0.contact_time(x0)                                     # (nit, p, 3)
    U = prob0.harmonics(x0)
    v = fourier.to_time(fourier.derivative(U), prob0.nit).reshape(lam.shape)
    vT = v[..., 1:]
    nv = np.linalg.norm(vT, axis=-1, keepdims=True)
    closed = lam[..., :1] < 0.0
    with np.errstate(all="ignore"):
        dirn = np.where((nv > 0) & closed, vT / np.where(nv > 0, nv, 1.0), 0.0)
    lamT = np.zeros_like(lam)
    lamT[..., 1:] = mu * np.abs(lam[..., :1]) * dirn
    LT = fourier.to_freq(lamT.reshape(prob0.nit, -1), prob0.nh)
    return constrained_response(prob0.Zr, -LT, _free_fixed(prob0.Zr.shape[1] // 3, _open_pairs(prob0, x0)))


def _free_fixed(p: int, open_pairs) -> np.ndarray:
    fixed = np.zeros(3 * p, dtype=bool)
    fixed[0::3] = True
    if open_pairs is not None:
        fixed[0::3] &= ~np.asarray(open_pairs, dtype=bool)
    return fixed


def tied_limit(Zr: np.ndarray, Fr: np.ndarray, open_pairs: np.ndarray | None = None) -> np.ndarray:
    """μ → ∞ / excitation → 0 limit for harmonics ≥ 1: closed pairs tied (U = 0), open pairs free."""
    p = Fr.shape[1] // 3
    closed = np.ones(p, dtype=bool) if open_pairs is None else ~np.asarray(open_pairs, dtype=bool)
    return constrained_response(Zr, Fr, np.repeat(closed, 3))


def linear_open(Zr: np.ndarray, Fr: np.ndarray) -> np.ndarray:
    """Response without contact forces, ``U_j = Zr_j⁻¹ Fr_j`` (Nh+1, 3p), all harmonics."""
    U = np.empty(Fr.shape, dtype=complex)
    for j in range(Fr.shape[0]):
        Z = np.real(Zr[j]) if j == 0 else Zr[j]
        U[j] = np.linalg.solve(Z, Fr[j])
    return U


def tied_scale(Zr: np.ndarray, Fr: np.ndarray) -> float:
    """Norm of the free-limit harmonics ≥ 1 (m): the yardstick of "U ≈ 0" (tied limit)."""
    return float(np.linalg.norm(free_limit(Zr, Fr)[1:]))


def _open_pairs(prob: HBProblem, x) -> np.ndarray:
    """Pairs separated during the whole period at x (bool, p)."""
    return np.all(prob.contact_state(x) == SEPARATION, axis=0)


def _rel(a, b, scale=None) -> float | None:
    d = float(np.linalg.norm(np.asarray(a) - np.asarray(b)))
    s = float(np.linalg.norm(b)) if scale is None else float(scale)
    if not math.isfinite(d) or not math.isfinite(s) or s <= 0:
        return None
    return d / s
