"""The DLFT contact law linearised along a periodic solution: the tangent of the stability analysis.

The linearised problem
----------------------
About a T-periodic solution q(t) (T = 2π/ω) of ``M q̈ + C q̇ + K q + Bᵀ λ(t) = f(t)``
(docs/contracts.md §4, §6) a perturbation δq obeys the linear T-periodic system

    M δq̈ + C δq̇ + K δq + Bᵀ δλ = 0,      δu = B δq   (relative contact DOFs),

with δλ the linearised DLFT law along the period (:mod:`workflow.engine.contact`). The
DLFT is a rigid contact (eqs. 13–17: in stick ``X_T`` equals the anchor, in contact the gap
is closed; ε is numerical) with *memory*: a pair in stick pulls towards an anchor w that
only slip moves. Its exact linearisation therefore carries the anchor perturbation δw of
every pair that slips or separates during the period as a state (Jenkins element: a
spring ε_T in series with a Coulomb slider, ε → ∞):

* contact, normal: ``δλ_N = ε_N δu_N``; separation: ``δλ = 0`` and the anchor follows,
  ``δw = δu_T``;
* tangential: ``δλ_T = ε_T (δu_T − δw)`` with, in stick, ``δẇ = 0``; in slip (direction
  t = λ_T/‖λ_T‖, n ⊥ t in the tangent plane) the Coulomb limit along t,
  ``ε_T tᵀ(δu_T − δw) = μ δ|λ_N| = −μ ε_N δu_N`` (algebraic: the μ·dλ_N coupling), and
  across t the rotation of the slip direction, ``nᵀδẇ = κ nᵀ(δu_T − δw)`` with
  ``κ = |ẇ| ε_T/(μ|λ_N|)`` (1/s, the slip rate over the elastic slip length).

This periodic descriptor system is exact for the piecewise-smooth law: its algebraic slip
rows reproduce the saltation at stick → slip (the perturbed force is clipped to the cone).
At s = 0 it is the HB Jacobian's linearisation (the DLFT carries the same anchor
derivative, :func:`workflow.engine.contact.dlft_pass`), so an exponent crosses 0 exactly at
a fold of the HB curve. A pair stuck during the whole period keeps no anchor state: its
anchor is a parameter set by the load history (the "stuck zeroth harmonic" of
:meth:`~workflow.engine.hb.HBProblem.static_state`) whose perturbation is a neutral
multiplier 1 of the family of periodic solutions, not a dynamic instability; so is a pair
whose anchor the DLFT never moves (it only touches the cone after shaking down: every
reference on a circle is periodic, :func:`workflow.engine.contact.dlft_pass`), which takes
the stick tangent at the touching instants.

``memory=False`` drops the anchors: the memoryless tangent ``δλ = K_c(t) δu`` (ε_N in
contact, ε_T in stick, in slip ``fac·ε_T (I − t tᵀ)`` and ``−μ ε_N t`` on δu_N, zero when
separated; the issue's first formulation). It is not the linearisation of a law with
memory: in stick it pulls δu back to 0 instead of to its value at the stick onset, and in
slip it keeps the perturbed force the cone clips, so friction does not damp perturbations.
Measured on the 1-DOF Jenkins oscillator (ω = 1.3, stable, shooting 0.3738) it finds a real
multiplier 1.58–1.64: an *unstable* orbit that is stable.
"""
from __future__ import annotations

import numpy as np

from workflow.engine.contact import SEPARATION, SLIP, STICK

#: relative change of a pair's stick reference λ_x^T (of max|λ|) above which its anchor moves
ANCHOR_TOL = 1e-9


def _moved(lam, lam_x_T, prev, top: float = 0.0) -> np.ndarray:
    """(nit, p) bool: the DLFT moved the pair's stick reference at the sample (from ``prev``,
    the reference before it, N), by more than :data:`ANCHOR_TOL` of max|λ| (or of ``top`` N if
    larger: the max over pairs not passed in)."""
    d = lam_x_T - prev
    # ‖d‖ as np.linalg.norm takes it, and max|λ| without |λ|'s copy: the same bits at a third of the
    # time (the refined grids' signatures, 2026-11-29 round 2)
    top = max(float(lam.max()), -float(lam.min()), top)
    return np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]) > ANCHOR_TOL * max(top, 1e-300)


def _tangent_state(state, lam_x_T, prev) -> np.ndarray:
    """The contact state the tangent takes (nit, p): the DLFT's, except that a sample it
    labels slip while keeping the anchor (``touch``: stuck within 1e-7 of the cone, the
    reference kept bit for bit, :func:`workflow.engine.contact.dlft_pass`) is stick. The DLFT
    labels them slip for the HB Jacobian of a pair that shook down onto the cone; at a genuine
    slip → stick reversal they are the first instants of stick (the force leaves the cone
    quadratically: on the Jenkins oscillator at ω = 1.3 they lengthened each slip phase by
    6.8e-5 T, and the largest multiplier stayed 2.8e-4 off the shooting's at nit = 16384…65536,
    7.9e-5 without them). Told by the anchor kept exactly, not by a threshold on its move: near
    a reversal a slipping pair's move per sample falls below any, the finer the samples the
    earlier."""
    kept = (lam_x_T[..., 0] == prev[..., 0]) & (lam_x_T[..., 1] == prev[..., 1])
    return np.where((state == SLIP) & kept, STICK, state).astype(state.dtype)


def tangent_blocks(state, lam, lam_x_T, ref_T, eps_n, eps_t, mu, omega: float, memory: bool = True,
                   eps_dlft_t=None, prev=None, dt=None) -> dict:
    """The linearised DLFT law along the period (module docstring) pair by pair, from a
    :class:`~workflow.engine.contact.DLFTResult`'s samples: state (nit, p), λ (nit, p, 3) N,
    λ_x^T (nit, p, 2) N, its start reference ref_T (p, 2) N; ε_N, ε_T (p,) N/m of the tangent;
    μ (p,); ω rad/s; ``eps_dlft_t`` (p,) N/m the DLFT's own ε_T (λ_x^T = ε_DLFT·w; default
    ``eps_t``). ``prev`` (nit, p, 2) N: the stick reference before each sample, and ``dt``
    (nit,) or (nit, p) s: the time since that reference (the slip rate's backward difference); default the
    uniform grid τ_k = 2πk/nit (``prev`` the previous sample's, ref_T before the first;
    dt = T/nit). With memory the tangent takes :func:`_tangent_state`.

    The law couples nothing across pairs, so it is kept as blocks: ``Kp`` (nit, p, 3, 3) N/m on
    each pair's δu; ``active`` (p,) bool the pairs with an anchor state (they slip or separate at
    some instant), ``idx`` their indices (pa,); per active pair a, on its own δu and δw only,
    ``Kw`` (nit, pa, 3, 2) N/m, ``Ew``, ``Aw`` (nit, pa, 2, 2) (Aw 1/s), ``Au`` (nit, pa, 2, 3)
    (the anchor equations ``E_w δẇ = A_u δu + A_w δw``), ``contact`` (nit, pa) bool (not separated:
    a separated pair's anchor is slaved, δw = δu_T), ``stick`` (nit, pa) bool (E_w = I, A_w = A_u = 0).
    :func:`contact_tangent` assembles them."""
    nit, p = state.shape
    if prev is None:
        prev = np.concatenate([ref_T[None], lam_x_T[:-1]], axis=0)
    if memory:
        state = _tangent_state(state, lam_x_T, prev)
    contact, stick, slip = state != SEPARATION, state == STICK, state == SLIP
    I2 = np.eye(2)
    Kp = np.zeros((nit, p, 3, 3))
    Kp[:, :, 0, 0] = np.where(contact, eps_n, 0.0)
    if not memory:
        lamT = lam[:, :, 1:]
        nT = np.linalg.norm(lamT, axis=2)
        t = lamT / np.maximum(nT, 1e-300)[:, :, None]                   # slip direction
        tt = np.einsum("kia,kib->kiab", t, t)
        # λ_pre = λ^k + λ_x^k − λ_x^{k−1}: fac = ‖λ_T‖/‖λ_pre^T‖ (1 when touching the cone)
        fac = nT / np.maximum(np.linalg.norm(lamT + lam_x_T - prev, axis=2), 1e-300)
        Kp[:, :, 1:, 1:] = np.where(stick[:, :, None, None], eps_t[None, :, None, None] * I2,
                                    np.where(slip[:, :, None, None],
                                             (fac * eps_t[None, :])[:, :, None, None] * (I2 - tt), 0.0))
        Kp[:, :, 1:, 0] = np.where(slip[:, :, None], -(mu * eps_n)[None, :, None] * t, 0.0)
        return {"Kp": Kp, "active": np.zeros(p, bool), "idx": np.zeros(0, int)}
    # a pair's anchor is a state only if the law moves it during the period (slip or separation);
    # stuck all period, or only touching the cone (shakedown: the DLFT keeps the anchor), it is a
    # parameter of a family of periodic solutions — a neutral multiplier 1, left out
    active = np.any(_moved(lam, lam_x_T, prev) | ~contact, axis=0)
    idx = np.flatnonzero(active)
    pa = len(idx)
    Kp[:, :, 1, 1] = Kp[:, :, 2, 2] = np.where(contact, eps_t, 0.0)
    ct, sep = contact[:, idx], ~contact[:, idx]
    Kw = np.zeros((nit, pa, 3, 2))
    Kw[:, :, 1, 0] = Kw[:, :, 2, 1] = np.where(ct, -eps_t[idx], 0.0)
    Ew, Aw, Au = np.zeros((nit, pa, 2, 2)), np.zeros((nit, pa, 2, 2)), np.zeros((nit, pa, 2, 3))
    Ew[stick[:, idx]] = I2
    Aw[sep] = -I2
    Au[sep] = np.concatenate([np.zeros((2, 1)), I2], axis=1)
    # what depends on the slip direction and rate, on the entries that slip only (a few % of them)
    k, a = np.nonzero(slip[:, idx])
    i = idx[a]
    lt = lam[k, i, 1:]
    t = lt / np.maximum(np.sqrt(lt[:, 0] * lt[:, 0] + lt[:, 1] * lt[:, 1]), 1e-300)[:, None]    # slip direction
    n = np.stack([-t[:, 1], t[:, 0]], axis=-1)                          # ⊥ t in the tangent plane
    tt, nn = t[:, :, None] * t[:, None, :], n[:, :, None] * n[:, None, :]
    # slip rate |ẇ| = |Δλ_x^T|/(ε_DLFT Δt) (backward difference): κ = |ẇ| ε_T / (μ|λ_N|)
    dt = np.full(nit, 2 * np.pi / omega / nit) if dt is None else np.asarray(dt, dtype=float)
    d = lam_x_T[k, i] - prev[k, i]
    wdot = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) / (dt[k] if dt.ndim == 1 else dt[k, i]) / \
        (eps_t if eps_dlft_t is None else eps_dlft_t)[i]
    # κ only matters while a pair slips (μ|λ_N| > 0); elsewhere 0, not an overflow
    cone = mu[i] * np.abs(lam[k, i, 0])
    kappa = np.divide(wdot * eps_t[i], cone, out=np.zeros_like(cone), where=cone > 0)[:, None, None]
    # slip: t-row tᵀ(δu_T − δw) + μ (ε_N/ε_T) δu_N = 0 (divided by ε_T); n-row nᵀδẇ = κ nᵀ(δu_T − δw)
    Ew[k, a] = nn
    Aw[k, a] = -(tt + kappa * nn)
    Au[k, a, :, 0] = t * (mu * eps_n / eps_t)[i, None]
    Au[k, a, :, 1:] = tt + kappa * nn
    return {"Kp": Kp, "active": active, "idx": idx, "Kw": Kw, "Ew": Ew, "Aw": Aw, "Au": Au, "contact": ct,
            "stick": stick[:, idx]}


def contact_tangent(state, lam, lam_x_T, ref_T, eps_n, eps_t, mu, omega: float, memory: bool = True,
                    eps_dlft_t=None, prev=None, dt=None):
    """The linearised DLFT law along the period (module docstring), assembled: the arguments
    of :func:`tangent_blocks`. Returns a dict of sample arrays on δu (3p) and the anchor states
    (2 per pair that slips or separates at some instant, ``active`` (p,) bool): ``Ku`` (nit, 3p,
    3p) N/m, ``Kw`` (nit, 3p, na) N/m, ``Ew``, ``Aw`` (nit, na, na), ``Au`` (nit, na, 3p);
    without ``memory`` only ``Ku`` (the memoryless tangent). Dense: (nit, 3p, 3p) is for small
    models (Hill's method); :func:`monodromy` takes the blocks."""
    blk = tangent_blocks(state, lam, lam_x_T, ref_T, eps_n, eps_t, mu, omega, memory, eps_dlft_t, prev, dt)
    nit, p = state.shape
    out = {"Ku": _pair_blockdiag(blk["Kp"]), "active": blk["active"]}
    if not memory:
        return out
    idx = blk["idx"]
    own = np.arange(len(idx))
    out["Kw"] = _scatter(blk["Kw"], idx, own, p, len(idx))
    out["Ew"] = _scatter(blk["Ew"], own, own, len(idx), len(idx))
    out["Aw"] = _scatter(blk["Aw"], own, own, len(idx), len(idx))
    out["Au"] = _scatter(blk["Au"], own, idx, len(idx), p)
    return out


def _scatter(blocks: np.ndarray, rows, cols, nr: int, nc: int) -> np.ndarray:
    """(nit, k, a, b) blocks → (nit, nr·a, nc·b) dense, block k at block-row rows[k], block-column cols[k]."""
    nit, k, a, b = blocks.shape
    out = np.zeros((nit, nr, a, nc, b))
    out[:, rows, :, cols, :] = blocks.transpose(1, 0, 2, 3)
    return out.reshape(nit, nr * a, nc * b)


def _pair_blockdiag(Kp: np.ndarray) -> np.ndarray:
    """(nit, p, 3, 3) per-pair blocks → (nit, 3p, 3p) block-diagonal."""
    ar = np.arange(Kp.shape[1])
    return _scatter(Kp, ar, ar, len(ar), len(ar))
