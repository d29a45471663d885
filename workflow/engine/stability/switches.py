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
    (n,) or (n, p) s (the slip rate's backward difference; per pair on the pairs' own grids) — and
    ``h`` (n,) s its duration (sum T); ``ref_T`` (p, 2) N; ``switches`` the uniform sample intervals
    with a switch; ``samples`` the DLFT's (refined: the union of the pairs' grids)."""

    state: np.ndarray
    lam: np.ndarray
    lam_x_T: np.ndarray
    prev: np.ndarray
    dt: np.ndarray
    h: np.ndarray
    ref_T: np.ndarray
    switches: int
    samples: int


def _signature(ts, lam, lam_x_T, prev, top: float = 0.0) -> np.ndarray:
    """The states whose changes are switches of the tangent (nit, p): :func:`_tangent_state` for
    a pair with an anchor state (:func:`contact_tangent`'s ``active``), contact or separation
    for the others (their tangent is stick in contact: a pair that shook down onto the cone and
    slips by round-off now and then has no switch to locate)."""
    contact = ts != SEPARATION
    active = np.any(_moved(lam, lam_x_T, prev, top) | ~contact, axis=0)
    return np.where(active[None, :], ts, np.where(contact, STICK, SEPARATION)).astype(ts.dtype)


def _switch_pieces(hb, x, nit: int, omega: float, refine) -> _Pieces:
    """The contact law along the period of the HB solution x of ``hb`` for :func:`monodromy`,
    with the switching instants located inside the sample intervals.

    The DLFT on nit uniform samples knows a stick/slip/separation switch to an interval
    (τ_{k−1}, τ_k]. Each pair's intervals where its :func:`_tangent_state` changes are cut into
    ``refine`` sub-intervals, the DLFT predictor λ_u (a Fourier series: its harmonics
    evaluated at any instant) is sampled there too, and the DLFT runs again on the pair's
    non-uniform grid (same law, same passes, from the uniform one's reference); ``refine`` a
    sequence (r₁, r₂, …): again inside the sub-intervals that hold the pair's switch, level by
    level (:func:`_refined`) — the same location, T/(nit·r₁·r₂…), at a fraction of the samples.
    Every pair on its own grid, because the DLFT couples nothing across pairs: with 128 pairs
    some pair switches in most sample intervals, and one grid for all put ~1100 samples under
    every pair, where their own grids hold 265 on average (the 128-pair sector at nit = 256), and
    a pair that never switches keeps its uniform samples. Each sample stands for its cell (midway
    to its neighbours), so a switch sits midway between the two sub-samples it falls between: to
    ±T/(2·nit·Πr), without bias, and a smooth coefficient is taken at the middle of its cell. The
    monodromy's pieces lie on the union of the pairs' grids, each pair at its nearest own sample
    (:func:`_union_pieces`); consecutive union samples of one interval where no pair changes are
    merged into one piece (the first one's tangent): the monodromy pays one step per switch more
    than per sample, not ``refine``. ``refine`` ≤ 1: the uniform samples, a piece each (a switch
    then known to T/nit)."""
    prob, xx = _dlft_problem(hb, x, nit, hbm=True)
    a = prob._predictor(xx)                                   # real Fourier coefficients of λ_u (N)
    return _pieces_of(prob, a, prob._dlft(a, jacobian=False), omega, refine)


def _pieces_of(prob, a, res, omega: float, refine) -> _Pieces:
    """:func:`_switch_pieces` from the DLFT problem ``prob`` (its ``nh``, ``law.mu``,
    ``max_passes``, ``pass_tol``), λ_u's real Fourier coefficients ``a`` (2Nh+1, 3p) N and their
    DLFT ``res`` on the uniform samples. Only the pairs that switch get grids of their own
    (:class:`_PairGrids`); the others keep the uniform samples (at 128 pairs 7 of 128 on average
    switch, and bookkeeping every pair on the refined grids cost more than the DLFT there)."""
    nit = res.state.shape[0]
    T = 2 * np.pi / omega
    tau = 2 * np.pi * np.arange(nit) / nit
    prev = np.concatenate([res.ref_T[None], res.lam_x_T[:-1]], axis=0)
    ts = _tangent_state(res.state, res.lam_x_T, prev)
    sig = _signature(ts, res.lam, res.lam_x_T, prev)
    change = sig != np.roll(sig, 1, axis=0)
    sw = np.flatnonzero(np.any(change, axis=1))                             # a switch in (τ_{k−1}, τ_k]
    factors = [int(r) for r in np.atleast_1d(refine) if int(r) > 1]
    if not factors or sw.size == 0:
        return _Pieces(ts, res.lam, res.lam_x_T, prev, np.full(nit, T / nit), np.full(nit, T / nit), res.ref_T,
                       0, nit)
    from workflow.engine import fourier

    uniform = _Uniform(tau, res.lam, res.lam_x_T, ts, prev)
    pairs = np.flatnonzero(np.any(change, axis=0))                          # the pairs that switch
    q = pairs.size
    lam_u = np.einsum("kj,jic->kic", fourier.trig_matrix(prob.nh, tau), a.reshape(a.shape[0], -1, 3)[:, pairs])
    rest = np.delete(res.lam, pairs, axis=1)
    top = max(float(rest.max()), -float(rest.min())) if rest.size else 0.0
    grid = _PairGrids(pairs, top, np.repeat(tau[:, None], q, axis=1), np.ones((nit, q), bool), np.full(q, nit), lam_u,
                      res.lam[:, pairs], res.lam_x_T[:, pairs], res.state[:, pairs], res.ref_T[pairs], ts[:, pairs],
                      prev[:, pairs], sig[:, pairs])
    for r in factors:
        grid = _refined(prob, a, grid, r)
    ref_T = res.ref_T.copy()
    ref_T[pairs] = grid.ref_T
    return _union_pieces(grid, uniform, ref_T, omega, int(sw.size))


@dataclass
class _Uniform:
    """The DLFT on the uniform samples ``tau`` (nit,) rad, of every pair: ``lam`` (nit, p, 3),
    ``lam_x_T`` (nit, p, 2) N, ``ts`` (nit, p) :func:`_tangent_state`, ``prev`` (nit, p, 2) N."""

    tau: np.ndarray
    lam: np.ndarray
    lam_x_T: np.ndarray
    ts: np.ndarray
    prev: np.ndarray


@dataclass
class _PairGrids:
    """The own samples of the period of the pairs ``pairs`` (q,) that switch and their DLFT there
    (:func:`_refined`), as columns padded to one length: ``tau`` (n, q) rad sorted in [0, 2π) (rows
    ≥ ``count`` repeat the pair's last sample: the DLFT is idempotent on a repeated predictor),
    ``coarse`` (n, q) the uniform samples, ``top`` N max|λ| of the other pairs (the scale of
    :func:`_signature`, as with every pair on the grid), ``count`` (q,) each pair's samples, ``lam_u`` (n, q, 3) N
    the DLFT predictor there; the DLFT's ``lam`` (n, q, 3), ``lam_x_T`` (n, q, 2) N, ``state``
    (n, q), ``ref_T`` (q, 2) N; ``ts`` (n, q) :func:`_tangent_state`, ``prev`` (n, q, 2) N the
    references before each sample, ``sig`` (n, q) the switch signature (:func:`_signature`;
    padding repeats the last sample's)."""

    pairs: np.ndarray
    top: float
    tau: np.ndarray
    coarse: np.ndarray
    count: np.ndarray
    lam_u: np.ndarray
    lam: np.ndarray
    lam_x_T: np.ndarray
    state: np.ndarray
    ref_T: np.ndarray
    ts: np.ndarray
    prev: np.ndarray
    sig: np.ndarray


def _refined(prob, a, g: _PairGrids, r: int) -> _PairGrids:
    """One level of :func:`_switch_pieces`' refinement, pair by pair: every interval
    (τ_{k−1}, τ_k] of a pair's grid that holds its switch, and its two neighbours, cut into
    ``r``, and the DLFT (λ_u's harmonics ``a``) run again on the new grids of the pairs that
    switch, all at once, from their references of the level before; a pair that never switches
    keeps its grid and its DLFT (at 128 pairs more than half of them)."""
    from workflow.engine import fourier
    from workflow.engine.contact import dlft_pass

    n, p = g.tau.shape
    cols = np.arange(p)
    rows = np.arange(n)[:, None]
    before = np.concatenate([g.sig[g.count - 1, cols][None], g.sig[:-1]], axis=0)
    k, i = np.nonzero((g.sig != before) & (rows < g.count))                    # pair i switches in row k
    moving = np.unique(i)                                                       # the pairs refined
    # the intervals before and after too: the DLFT sees a slip → stick reversal by the sign of the
    # predictor's increment over a sample interval, up to a sample late (the reversal may lie in
    # (τ_{k−2}, τ_{k−1}]), and the refined anchors may move a switch across a sample
    j = ((k[:, None] + np.arange(-2, 1)[None, :]) % g.count[i][:, None]).ravel()
    ii = np.repeat(i, 3)
    j, ii = np.unique(np.stack([j, ii]), axis=1)                              # interval (τ_j, τ_{j+1}] of pair ii
    lo = g.tau[j, ii]
    hi = np.where(j + 1 < g.count[ii], g.tau[np.minimum(j + 1, n - 1), ii], g.tau[0, ii] + 2 * np.pi)
    extra = (lo[:, None] + (hi - lo)[:, None] * np.arange(1, r)[None, :] / r).ravel()
    # the moving pairs' samples, old and new, sorted pair by pair (local pair index 0 … len(moving))
    valid = (rows < g.count)[:, moving]
    new_owner = np.repeat(np.searchsorted(moving, ii), r - 1)
    vals = np.concatenate([g.tau[:, moving][valid], extra])
    owner = np.concatenate([np.broadcast_to(np.arange(moving.size), valid.shape)[valid], new_owner])
    coarse = np.concatenate([g.coarse[:, moving][valid], np.zeros(extra.size, bool)])
    # λ_u at the new instants only (the others are carried): its harmonics at each one's pair
    E = fourier.trig_matrix(prob.nh, extra)
    a3 = a.reshape(E.shape[1], -1, 3)
    lu = np.concatenate([g.lam_u[:, moving][valid], np.einsum("kj,jkc->kc", E, a3[:, g.pairs[moving[new_owner]]])])
    order = np.lexsort((vals, owner))
    vals, owner, coarse, lu = vals[order], owner[order], coarse[order], lu[order]
    count_m = np.bincount(owner, minlength=moving.size)
    pos = np.arange(vals.size) - np.concatenate([[0], np.cumsum(count_m)[:-1]])[owner]
    count = g.count.copy()
    count[moving] = count_m
    m = int(count.max())
    last = np.arange(m)[:, None] < count                                         # not padding

    def grown(x, fill=None):
        """x (n, p, …) to m rows, the new rows repeating the last; the moving pairs' columns set."""
        y = np.concatenate([x, np.repeat(x[-1:], m - n, axis=0)]) if m > n else x.copy()
        if fill is not None:
            z = np.empty((m, moving.size) + x.shape[2:], x.dtype)
            z[pos, owner] = fill
            y[:, moving] = z
        return y

    tau = grown(g.tau, vals)
    coarse_all = grown(g.coarse, coarse) & last
    lam_u = grown(g.lam_u, lu)
    tau = np.where(last, tau, tau[count - 1, cols])                              # padding: the last sample again
    lam_u = np.where(last[..., None], lam_u, lam_u[count - 1, cols][None])
    mu = np.broadcast_to(np.asarray(prob.law.mu, float), (a3.shape[1],))[g.pairs[moving]]
    fine = dlft_pass(lam_u[:, moving], mu, g.ref_T[moving], periodic=True, max_passes=prob.max_passes,
                     tol=prob.pass_tol)
    lam, lam_x_T, state = grown(g.lam), grown(g.lam_x_T), grown(g.state)
    lam[:, moving], lam_x_T[:, moving], state[:, moving] = fine.lam, fine.lam_x_T, fine.state
    ref_T = g.ref_T.copy()
    ref_T[moving] = fine.ref_T
    prev = np.concatenate([ref_T[None], lam_x_T[:-1]], axis=0)
    ts = _tangent_state(state, lam_x_T, prev)
    sig = _signature(ts, lam, lam_x_T, prev, g.top)
    sig = np.where(last, sig, sig[count - 1, cols])
    return _PairGrids(g.pairs, g.top, tau, coarse_all, count, lam_u, lam, lam_x_T, state, ref_T, ts, prev, sig)


def _union_pieces(g: _PairGrids, u: _Uniform, ref_T: np.ndarray, omega: float, switches: int) -> _Pieces:
    """The monodromy's pieces from the switching pairs' own grids ``g`` (:func:`_refined`) and the
    uniform samples ``u`` of the others: the union of their samples, each pair taken at its
    nearest own sample (cyclic; so its switch sits midway between its two samples around it), a
    piece starting at every uniform sample and wherever some pair's signature changes. ``dt``
    per piece and pair: the pair's own sample spacing (its slip rate's backward difference);
    ``ref_T`` (p, 2) N every pair's reference."""
    U = np.unique(np.concatenate([u.tau, g.tau[np.arange(g.tau.shape[0])[:, None] < g.count]]))
    coarse_u = np.isin(U, u.tau)
    near_u = _nearest(u.tau[:, None], np.array([len(u.tau)]), U)[:, 0]     # (nU,): every uniform pair's
    near = _nearest(g.tau, g.count, U)                                       # (nU, q)
    nit = len(u.tau)
    sig = g.sig[near, np.arange(g.pairs.size)]              # the other pairs' signatures never change
    start = np.flatnonzero(coarse_u | np.any(sig != np.roll(sig, 1, axis=0), axis=1))
    back = np.diff(np.concatenate([[U[-1] - 2 * np.pi], U]))                     # rad, to the previous sample
    cell = 0.5 * (back + np.roll(back, -1))                                         # rad, the sample's cell
    h = np.add.reduceat(cell, start) / omega
    ku, kg = near_u[start], near[start]                                            # (n,), (n, q)
    cols = np.arange(g.pairs.size)
    back_u = np.diff(np.concatenate([[u.tau[-1] - 2 * np.pi], u.tau]))
    back_g = g.tau - np.concatenate([g.tau[g.count - 1, cols][None] - 2 * np.pi, g.tau[:-1]], axis=0)

    def pieces(uni, own):
        """(n, p, …): every pair's value at its piece's sample, the switching pairs' from ``own``."""
        out = uni[ku].copy()
        out[:, g.pairs] = own[kg, cols]
        return out

    dt = pieces(np.broadcast_to(back_u[:, None], (nit, ref_T.shape[0])), back_g) / omega
    return _Pieces(pieces(u.ts, g.ts), pieces(u.lam, g.lam), pieces(u.lam_x_T, g.lam_x_T), pieces(u.prev, g.prev),
                   dt, h, ref_T, switches, len(U))


def _nearest(tau: np.ndarray, count: np.ndarray, U: np.ndarray) -> np.ndarray:
    """(nU, q): for every instant of ``U`` (rad, sorted) each column's nearest own sample (cyclic,
    the later one on a tie) of ``tau`` (n, q) rad, sorted, its first ``count`` (q,) rows valid."""
    m, q = tau.shape
    cols = np.arange(q)
    valid = np.arange(m)[:, None] < count
    L = 4 * np.pi
    own = (tau + L * cols).T[valid.T]                                              # column-major, sorted
    first = np.concatenate([[0], np.cumsum(count)[:-1]])
    after = np.searchsorted(own, (U[None, :] + L * cols[:, None]).ravel()).reshape(q, -1) - first[:, None]
    bef = after - 1
    t_after = np.where(after < count[:, None], tau[np.minimum(after, m - 1), cols[:, None]],
                       tau[0, cols][:, None] + 2 * np.pi)
    t_bef = np.where(bef >= 0, tau[np.maximum(bef, 0), cols[:, None]], tau[count - 1, cols][:, None] - 2 * np.pi)
    return np.where(t_after - U[None, :] <= U[None, :] - t_bef, after % count[:, None], bef % count[:, None]).T
