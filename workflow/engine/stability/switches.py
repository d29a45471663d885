"""The contact law along the period on the monodromy's pieces: the DLFT of a harmonic-balance
solution on a fine grid, with every stick/slip/separation switch located inside its sample
interval (:func:`_switch_pieces`).

Located to the sample only, a switch is up to T/nit off, and the largest multiplier with it,
by an amount that does not fall as 1/nit but jumps with where the switches fall between
samples (Jenkins, ω = 1.3: 1.25e-3, 1.26e-3, 4.7e-4, 7.9e-5 at nit = 1024, 2048, 4096, 8192).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workflow.engine.contact import SEPARATION, STICK
from workflow.engine.stability.tangent import _moved, _tangent_state

#: sub-intervals a sample interval with a switch is cut into (:func:`_switch_pieces`), level by
#: level: the monodromy knows the switching instants to ±T/(2·nit·8·8·8), as 2048 samples cut
#: into 64 did. Jenkins oscillators: (8, 8, 8) at nit = 256 and 512 at nit = 256 give the same
#: multiplier (7.44e-5 and −3.68e-4 from shooting; 2.7e-4, −3.8e-4 cut into 64 only); at 128
#: pairs 4078 DLFT samples instead of 65153 for 512. Its cost is the DLFT on the extra samples
#: and one monodromy step more a switch
SWITCH_REFINE = (8, 8, 8)


def _dlft_problem(hb, x, nit: int, hbm: bool = False):
    """(problem, unknowns) of the HB solution x of ``hb`` (:class:`~workflow.engine.hb.HBProblem`)
    on nit samples: ``hb`` itself when nit = hb.nit (and, with ``hbm``, its predictor is a
    Fourier series: HBM), else the same harmonics of U_r through the same law and anchor on
    a finer grid (HBM)."""
    from workflow.engine.hb import HBProblem

    if nit == hb.nit and (hb.method == "hbm" or not hbm):
        return hb, x
    prob = HBProblem(hb.Zr, hb.Fr, hb.law, hb.nh, nit, "hbm", max_passes=max(hb.max_passes, 50),
                     pass_tol=hb.pass_tol, stick_anchor=hb.stick_anchor, static=hb.static)
    return prob, prob.unknowns_from_harmonics(hb.harmonics(x))


def _dlft_samples(hb, x, nit: int):
    """The DLFT (:class:`~workflow.engine.contact.DLFTResult`) of the HB solution x of ``hb`` on
    nit uniform samples (:func:`_dlft_problem`)."""
    prob, xx = _dlft_problem(hb, x, nit)
    prob.contact_time(xx)
    return prob.last_dlft


@dataclass
class _Pieces:
    """The contact law along the period on the monodromy's pieces (:func:`_switch_pieces`):
    per piece the DLFT sample it takes its tangent from — ``state`` (n, p) (already
    :func:`_tangent_state`), ``lam`` (n, p, 3) N, ``lam_x_T`` and ``prev`` (n, p, 2) N, ``dt``
    (n,) s (the slip rate's backward difference) — and ``h`` (n,) s its duration (sum T);
    ``ref_T`` (p, 2) N; ``switches`` the sample intervals refined; ``samples`` the DLFT's."""

    state: np.ndarray
    lam: np.ndarray
    lam_x_T: np.ndarray
    prev: np.ndarray
    dt: np.ndarray
    h: np.ndarray
    ref_T: np.ndarray
    switches: int
    samples: int


def _signature(ts, lam, lam_x_T, prev) -> np.ndarray:
    """The states whose changes are switches of the tangent (nit, p): :func:`_tangent_state` for
    a pair with an anchor state (:func:`contact_tangent`'s ``active``), contact or separation
    for the others (their tangent is stick in contact: a pair that shook down onto the cone and
    slips by round-off now and then has no switch to locate)."""
    contact = ts != SEPARATION
    active = np.any(_moved(lam, lam_x_T, prev) | ~contact, axis=0)
    return np.where(active[None, :], ts, np.where(contact, STICK, SEPARATION)).astype(ts.dtype)


def _switch_pieces(hb, x, nit: int, omega: float, refine) -> _Pieces:
    """The contact law along the period of the HB solution x of ``hb`` for :func:`monodromy`,
    with the switching instants located inside the sample intervals.

    The DLFT on nit uniform samples knows a stick/slip/separation switch to an interval
    (τ_{k−1}, τ_k]. Each interval where some pair's :func:`_tangent_state` changes is cut into
    ``refine`` sub-intervals, the DLFT predictor λ_u (a Fourier series: its harmonics
    evaluated at any instant) is sampled there too, and the DLFT runs again on the
    non-uniform grid (same law, same passes, from the uniform one's reference); ``refine`` a
    sequence (r₁, r₂, …): again inside the sub-intervals that hold a switch, level by level
    (:func:`_refined`) — the same location, T/(nit·r₁·r₂…), at a fraction of the samples. Each
    sample stands for its cell (midway to its neighbours), so a switch sits midway between the
    two sub-samples it falls between: to ±T/(2·nit·Πr), without bias, and a smooth coefficient
    is taken at the middle of its cell. Consecutive sub-samples of one interval in the same
    state are merged into one piece (the first one's tangent): the monodromy pays one step per
    switch more than per sample, not ``refine``. ``refine`` ≤ 1: the uniform samples, a piece
    each (a switch then known to T/nit)."""
    prob, xx = _dlft_problem(hb, x, nit, hbm=True)
    a = prob._predictor(xx)                                   # real Fourier coefficients of λ_u (N)
    res = prob._dlft(a, jacobian=False)
    T = 2 * np.pi / omega
    tau = 2 * np.pi * np.arange(nit) / nit
    prev = np.concatenate([res.ref_T[None], res.lam_x_T[:-1]], axis=0)
    ts = _tangent_state(res.state, res.lam_x_T, prev)
    sig = _signature(ts, res.lam, res.lam_x_T, prev)
    sw = np.flatnonzero(np.any(sig != np.roll(sig, 1, axis=0), axis=1))     # a switch in (τ_{k−1}, τ_k]
    factors = [int(r) for r in np.atleast_1d(refine) if int(r) > 1]
    if not factors or sw.size == 0:
        return _Pieces(ts, res.lam, res.lam_x_T, prev, np.full(nit, T / nit), np.full(nit, T / nit), res.ref_T,
                       0, nit)
    grid = (tau, np.ones(nit, bool), sig, None, None)
    for r in factors:
        grid = _refined(prob, a, res.ref_T, grid, r)
    tau_f, coarse, sig, fine, (ts_f, prev_f) = grid
    back = np.diff(np.concatenate([[tau_f[-1] - 2 * np.pi], tau_f]))          # rad, to the previous sample
    cell = 0.5 * (back + np.roll(back, -1))                                     # rad, the sample's cell
    start = np.flatnonzero(coarse | np.any(sig != np.roll(sig, 1, axis=0), axis=1))
    h = np.add.reduceat(cell, start) / omega
    return _Pieces(ts_f[start], fine.lam[start], fine.lam_x_T[start], prev_f[start], back[start] / omega, h,
                   fine.ref_T, int(sw.size), len(tau_f))


def _refined(prob, a, ref_T, grid, r: int):
    """One level of :func:`_switch_pieces`' refinement: ``grid`` (τ (n,) rad sorted in [0, 2π),
    ``coarse`` (n,) the uniform samples, the switch signature (n, p), DLFT or None, its
    (:func:`_tangent_state`, references before each sample) or None) → the same with every interval
    (τ_{k−1}, τ_k] that holds a switch, and its two neighbours, cut into ``r``, and the DLFT (λ_u's
    harmonics ``a``, from the reference ``ref_T``) run again on the new grid."""
    from workflow.engine import fourier
    from workflow.engine.contact import dlft_pass

    tau, coarse, sig = grid[:3]
    n = len(tau)
    sw = np.flatnonzero(np.any(sig != np.roll(sig, 1, axis=0), axis=1))
    # the intervals before and after too: the DLFT sees a slip → stick reversal by the sign of the
    # predictor's increment over a sample interval, up to a sample late (the reversal may lie in
    # (τ_{k−2}, τ_{k−1}]), and the refined anchors may move a switch across a sample
    ivl = np.unique((sw[:, None] + np.arange(-2, 1)[None, :]) % n)                 # interval (τ_i, τ_{i+1}]
    lo = tau[ivl]
    hi = np.where(ivl + 1 < n, tau[(ivl + 1) % n], 2 * np.pi)
    extra = lo[:, None] + (hi - lo)[:, None] * np.arange(1, r)[None, :] / r
    tau_f = np.concatenate([tau, extra.ravel()])
    order = np.argsort(tau_f, kind="stable")
    tau_f = tau_f[order]
    coarse = np.concatenate([coarse, np.zeros(extra.size, bool)])[order]
    lam_u = (fourier.trig_matrix(prob.nh, tau_f) @ a).reshape(len(tau_f), prob.p, 3)
    fine = dlft_pass(lam_u, prob.law.mu, ref_T, periodic=True, max_passes=prob.max_passes, tol=prob.pass_tol)
    prev_f = np.concatenate([fine.ref_T[None], fine.lam_x_T[:-1]], axis=0)
    ts = _tangent_state(fine.state, fine.lam_x_T, prev_f)
    return tau_f, coarse, _signature(ts, fine.lam, fine.lam_x_T, prev_f), fine, (ts, prev_f)
