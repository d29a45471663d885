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


def _interval_pressure_and_slip(lam, uT, area) -> tuple:
    """(p̄_k, ‖Δu_T‖_k) (nit, p): the trapezoidal pressure [Pa] and the slip increment [m] of
    every interval k−1 → k of the period (periodic wrap); uT (nit, p, 2) or (nit, p, 3) with its
    normal part dropped."""
    uT = np.asarray(uT, dtype=float)
    if uT.shape[-1] == 3:
        uT = uT[..., 1:]
    p = pressure(lam, area)
    return 0.5 * (p + np.roll(p, 1, axis=0)), slip_increments(uT)


def wear_per_cycle(lam: np.ndarray, uT: np.ndarray, area, k_w: float) -> np.ndarray:
    """Archard wear depth per cycle ΔW (p,) [m/cycle] (eq. 21, 22b).

    lam : (nit, p, 3) multipliers λ over one period [N] (λ_N < 0 in contact).
    uT  : (nit, p, 2) tangential slip path [m] (or (nit, p, 3) relative
          displacements [n, t1, t2], whose normal part is dropped).
    area: (p,) tributary areas [m²]; k_w: Archard coefficient [m²/N].
    """
    pm, ds = _interval_pressure_and_slip(lam, uT, area)
    return k_w * np.sum(pm * ds, axis=0)


def pressure_work(lam: np.ndarray, uT: np.ndarray, area, k_w: float) -> np.ndarray:
    """``k_w ∮ p_N² |du_T|`` (p,) [m·Pa/cycle]: the frictional work per cycle weighted once more
    by the pressure, with the trapezoid of :func:`wear_per_cycle`. Over q (that function's rate)
    it is the pair's work-weighted mean contact pressure [Pa] (:class:`Averaging`, "pressure")."""
    pm, ds = _interval_pressure_and_slip(lam, uT, area)
    return k_w * np.sum(pm * pm * ds, axis=0)


#: how an averaged rate is formed (:class:`Averaging`)
AVERAGING_OVER = ("pressure", "slip", "all")


class Averaging:
    """The wear law with a length scale ℓ, from S (p, p), a row-stochastic Gaussian of width ℓ
    weighted by the tributary areas within each flank; q the pair's local rate k_w ∮ p_N |du_T|
    [m/cycle] (the cycle's frictional work per unit area through k_w).

    * ``over = "pressure"``: each pair wears under its own contact pressure capped at the mean
      pressure of the pairs within ℓ, r_i = q_i min(1, p̄_i / P_i), with P_i = q2_i / q_i the
      pair's work-weighted mean pressure (q2 = k_w ∮ p_N² |du_T|, :func:`pressure_work`) and
      p̄_i = (S q2)_i / (S q)_i the same mean over ℓ. A pressure peak narrower than ℓ (an edge
      whose pressure grows as 1/h with the contact mesh) wears at its neighbourhood's level; a
      pair below it keeps its node-wise rate. r_i is continuous in the
      state: it goes to 0 with the pair's own work q_i, whether it sticks or lifts off, and p̄
      weights each neighbour by its work. ℓ → 0 is the node-wise law exactly (p̄ = P).
    * ``over = "slip"`` (the default): r = M q, M_ij = χ_i S_ij / Σ_k S_ik χ_k, χ_i = 1 where
      pair i slips in contact (q_i > 0). A slipping pair wears at the mean q of the slipping
      pairs within ℓ of it; a stuck or open pair wears nothing. Its rate jumps from 0 to its
      neighbours' mean where it starts or stops slipping, and the pseudo-time march's steps
      chatter there (docs/wear.md).
    * ``over = "all"``: r = S q. Every pair within ℓ of a slipping one wears, a stuck one too.

    In all three the worn steady states are the node-wise law's (q = 0 everywhere): r = 0
    exactly where q = 0. They change only the path to them, and so which one it ends on.
    """

    def __init__(self, S, over: str = "slip"):
        if over not in AVERAGING_OVER:
            raise ValueError(f"wear averaging over {over!r}: one of {', '.join(AVERAGING_OVER)}")
        self.S, self.over = np.asarray(S, dtype=float), over

    @property
    def needs_q2(self) -> bool:
        """Whether the rate needs each pair's :func:`pressure_work` beside q."""
        return self.over == "pressure"

    def operator(self, q) -> np.ndarray:
        """M (p, p) of "slip" and "all" at the local rates ``q`` (p,) [m/cycle]: r = M q."""
        if self.over == "all":
            return self.S
        if self.over != "slip":
            raise ValueError(f"wear averaging over {self.over!r} is not a linear map of q: use linearised")
        chi = (np.asarray(q) > 0.0).astype(float)
        share = self.S @ chi                       # > 0 wherever χ = 1 (S_ii > 0)
        return (chi / np.where(share > 0.0, share, 1.0))[:, None] * self.S

    def linearised(self, q, q2=None) -> tuple:
        """(r, M, E): the averaged rate r (p,) [m/cycle] at the local rates ``q`` (and, for
        "pressure", ``q2``, :func:`pressure_work`) and its first variation ``δr = M δq + E δq2``
        (the slipping set and the capped set held), E (p, p) or None where r does not take q2.
        Capped rows of "pressure", r_i = p̄_i q_i² / q2_i with p̄ = S q2 / S q:
        ∂r_i/∂q_j = 2 δ_ij r_i / q_i − r_i S_ij / (S q)_i and
        ∂r_i/∂q2_j = −δ_ij r_i / q2_i + (q_i² / q2_i) S_ij / (S q)_i; the others r_i = q_i."""
        q = np.asarray(q, dtype=float)
        if self.over != "pressure":
            M = self.operator(q)
            return M @ q, M, None
        if q2 is None:
            raise ValueError("wear averaging over the pressure needs each pair's pressure work q2")
        q2 = np.asarray(q2, dtype=float)
        Sq, Sq2 = self.S @ q, self.S @ q2
        on = (q > 0.0) & (q2 > 0.0)
        pbar = np.where(on, Sq2 / np.where(on, Sq, 1.0), 0.0)
        own = np.where(on, q2 / np.where(on, q, 1.0), 0.0)
        cap = on & (own > pbar)
        r = q.copy()
        qq = np.where(cap, q * q / np.where(cap, q2, 1.0), 0.0)          # q_i² / q2_i [m/cycle / Pa]
        r[cap] = pbar[cap] * qq[cap]
        n = len(q)
        M, E = np.eye(n), np.zeros((n, n))
        c = np.flatnonzero(cap)
        M[c] = -(r[c] / Sq[c])[:, None] * self.S[c]
        M[c, c] += 2.0 * r[c] / q[c]
        E[c] = (qq[c] / Sq[c])[:, None] * self.S[c]
        E[c, c] -= r[c] / q2[c]
        return r, M, E


def averaging(position, area, flank, length: float, over: str = "slip") -> Averaging | None:
    """The wear law with the length scale ``length`` [m] (a Gaussian weighted by the tributary
    areas, within each flank: :func:`workflow.engine.wear.measures.filter_matrix`) taken as
    ``over`` says (:class:`Averaging`), or None for length 0 — the node-wise law. Each choice
    keeps the worn steady state what it is: no slip anywhere, no wear anywhere."""
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
