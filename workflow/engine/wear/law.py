"""Archard's fretting-wear law on a harmonic-balance solution (paper eqs. 20–22b): the kernel.

Kernel (eq. 21/22b), vectorised over pairs: per cycle

    ΔW_i = k_w ∮ p_N,i |du_T,i|  ≈  k_w Σ_k ½(p_N,i(τ_k) + p_N,i(τ_{k−1})) ‖u_T,i(τ_k) − u_T,i(τ_{k−1})‖

(trapezoidal in the pressure, periodic wrap k−1 = −1 ↦ nit−1), with
``p_N = −λ_N / A_i ≥ 0`` [Pa] (contracts §6: λ_N < 0 in contact), A_i the
tributary area [m²], k_w [m²/N = 1/Pa], u_T the tangential slip path [m].
The slip path is the DLFT corrected displacement ``X_T = λ_x^T / ε_T``
(eq. 11, :mod:`workflow.engine.contact`): it is *bit-for-bit constant* while a pair
sticks, so stick contributes exactly nothing and a fully stuck interface has
a rate of exactly 0. (The band-limited U_r of the HB unknowns wiggles during
stick and would wear a stuck pair.) During separation p_N = 0.

W (per pair, total depth, m) opens the normal gap ``g = u_N + gap + W``; it
is shared between flanks, ``W_blade = share·W``, ``W_disk = (1 − share)·W``.

"""
from __future__ import annotations

import numpy as np

from workflow.engine import fourier

def pressure(lam: np.ndarray, area: np.ndarray) -> np.ndarray:
    """Contact pressure ``p_N = −λ_N/A ≥ 0`` [Pa], (nit, p), from λ (nit, p, 3) [N] and A (p,) [m²]."""
    return np.maximum(-np.asarray(lam)[..., 0], 0.0) / np.asarray(area, dtype=float)


def slip_increments(uT: np.ndarray) -> np.ndarray:
    """``‖u_T(τ_k) − u_T(τ_{k−1})‖`` (nit, p) [m] of a tangential path (nit, p, 2), periodic wrap."""
    uT = np.asarray(uT, dtype=float)
    d = uT - np.roll(uT, 1, axis=0)
    return np.sqrt(np.sum(d * d, axis=-1))


def wear_per_cycle(lam: np.ndarray, uT: np.ndarray, area, k_w: float) -> np.ndarray:
    """Archard wear depth per cycle ΔW (p,) [m/cycle] (eq. 21, 22b).

    lam : (nit, p, 3) multipliers λ over one period [N] (λ_N < 0 in contact).
    uT  : (nit, p, 2) tangential slip path [m] (or (nit, p, 3) relative
          displacements [n, t1, t2], whose normal part is dropped).
    area: (p,) tributary areas [m²]; k_w: Archard coefficient [m²/N].
    """
    uT = np.asarray(uT, dtype=float)
    if uT.shape[-1] == 3:
        uT = uT[..., 1:]
    p = pressure(lam, area)
    ds = slip_increments(uT)
    return k_w * np.sum(0.5 * (p + np.roll(p, 1, axis=0)) * ds, axis=0)


#: the pairs an averaged rate is shared over (:class:`Averaging`)
AVERAGING_OVER = ("slip", "all")


class Averaging:
    """The wear law with a length scale: rate_i = k_w Σ_j M_ij q_j, q the cycle's frictional work
    per unit area [J/m² per cycle → m per cycle through k_w], M from S (p, p), a row-stochastic
    Gaussian of width ℓ weighted by the tributary areas within each flank.

    * ``over = "all"``: M = S. Every pair within ℓ of a slipping one wears, a stuck one too.
    * ``over = "slip"``: M_ij = χ_i S_ij / Σ_k S_ik χ_k, χ_i = 1 where pair i slips in contact
      (q_i > 0). A slipping pair wears at the mean q of the slipping pairs within ℓ of it; a stuck
      or open pair wears nothing, as the stick zone of a partial-slip fretting scar stays unworn.
      The worn steady states are the node-wise law's (q = 0 everywhere); only the path to them is
      smoothed. χ is piecewise constant in the state, so the derivatives take it as fixed.
    """

    def __init__(self, S, over: str = "slip"):
        if over not in AVERAGING_OVER:
            raise ValueError(f"wear averaging over {over!r}: one of {', '.join(AVERAGING_OVER)}")
        self.S, self.over = np.asarray(S, dtype=float), over

    def operator(self, q) -> np.ndarray:
        """M (p, p) at the local rates ``q`` (p,) [m/cycle]: the averaged rate is ``M @ q``."""
        if self.over == "all":
            return self.S
        chi = (np.asarray(q) > 0.0).astype(float)
        share = self.S @ chi                       # > 0 wherever χ = 1 (S_ii > 0)
        return (chi / np.where(share > 0.0, share, 1.0))[:, None] * self.S


def averaging(position, area, flank, length: float, over: str = "slip") -> Averaging | None:
    """The averaging of the frictional power over ``length`` [m] (a Gaussian weighted by the
    tributary areas, within each flank: :func:`workflow.engine.wear.measures.filter_matrix`) among
    the pairs ``over`` selects (:class:`Averaging`), or None for length 0 — the node-wise law.
    Averaging q (not p or the slip alone) keeps the worn steady state what it is: no slip
    anywhere, no wear anywhere."""
    from workflow.engine.wear.measures import filter_matrix

    if length <= 0:
        return None
    fl = np.asarray(flank)
    S = np.zeros((len(fl), len(fl)))
    for f in np.unique(fl):
        m = np.flatnonzero(fl == f)
        S[np.ix_(m, m)] = filter_matrix(np.asarray(position)[m], np.asarray(area)[m], length)
    return Averaging(S, over)


def profile_rel_diff(W_a, W_b) -> float:
    """max |W_a − W_b| / max(max W_a, max W_b) — the 2 % agreement measure."""
    W_a, W_b = np.asarray(W_a), np.asarray(W_b)
    top = max(float(np.max(W_a)), float(np.max(W_b)), 1e-300)
    return float(np.max(np.abs(W_a - W_b))) / top


def tip_cycle(observed_harmonics: np.ndarray, nit: int = 128, dof: int = 0) -> np.ndarray:
    """Time history over one period (nit,) of observed DOF ``dof`` from complex harmonics (Nh+1, n_obs)."""
    return fourier.to_time(np.asarray(observed_harmonics)[:, dof], nit)
