"""Floquet stability of a periodic harmonic-balance solution (issue #49): :func:`hill_stability`
on a reduced model, by the monodromy (default) or by Hill's method.

The penalty
-----------
The DLFT's ε (:mod:`workflow.engine.penalty`) is *not* a contact stiffness: it is the
stiffness the HB lends to the unresolved harmonics (at the automatic choice ≈ the contact
DOFs' own static stiffness), and the contact it solves is rigid. A tangent with that ε
would put a compliance the model does not have in series with the structure (a Jenkins pad
of spring k_d with ε ≈ k_d: half the stuck stiffness). The tangent here takes
``ε_Hill = eps_factor × k_static`` per pair and direction (:func:`workflow.engine.penalty.
reference_stiffness`), a stand-in for ε → ∞ whose error falls as 1/eps_factor; the
default :data:`EPS_FACTOR` = 10⁴ is measured converged (the bench reports the change of the
largest multiplier from 10³ to 10⁴ and 10⁵).

SI units: M kg, K N/m, C N·s/m, ω rad/s, exponents s in 1/s.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from workflow.engine.stability.hill import _pencil, hill_descriptor
from workflow.engine.stability.monodromy_matrix import RICHARDSON, SUBSTEPS, _live_multipliers
from workflow.engine.stability.switches import SWITCH_REFINE, _dlft_samples, _Pieces, _switch_pieces
from workflow.engine.stability.tangent import contact_tangent, tangent_blocks

#: ε of the Hill tangent as a multiple of the static contact stiffness (the rigid limit; module docstring)
EPS_FACTOR = 1.0e4


#: a multiplier up to 1 + STABLE_TOL counts as stable (neutral directions: a free rigid-body
#: motion of a separated blade has multiplier 1 to round-off)
STABLE_TOL = 1.0e-6


#: samples per period of the monodromy's tangent. The switching instants are located inside
#: the sample intervals (:data:`SWITCH_REFINE`); what nit still sets is the integration of the
#: smoothly varying tangent, with :data:`SUBSTEPS` and :data:`RICHARDSON` O(1/nit³): 128 pairs
#: (HBM-3, 191–234 Hz, 2026-11-29) the largest multiplier within 1.4e-5 of nit = 8192 at 256,
#: 1.7e-6 at 512, 2.1e-7 at 1024 (backward Euler extrapolated once, 2 substeps: 5.5e-4, 1.4e-4,
#: 3.4e-5, 8.7e-6 at 256 … 2048)
MONODROMY_NIT = 256


@dataclass
class Stability:
    """Stability of one periodic HB solution (:func:`hill_stability`).

    stable              largest multiplier ≤ 1 + :data:`STABLE_TOL`
    floquet_max         the largest Floquet multiplier |exp(s T)| (dimensionless)
    exponents           selected exponents s (1/s), decreasing real part
    truncation_change   |floquet_max(nh_hill) − floquet_max(nh_check)| (None: not checked)
    method              "dense" or "shift-invert" (and "+ritz(r)" when projected)
    seconds             wall time of the whole analysis (both truncations)
    nh_hill, nh_check   the harmonics of the Hill problem and of the truncation check
    eps_factor          ε of the tangent / static stiffness
    memory              anchors as states (True) or the memoryless tangent
    radius              search radius of the shift-invert (inf: dense, every exponent)
    anchors             pairs carrying an anchor state (those that slip or separate)
    """

    stable: bool
    floquet_max: float
    exponents: np.ndarray
    truncation_change: float | None
    method: str
    seconds: float
    nh_hill: int = 0
    nh_check: int | None = None
    eps_factor: float = EPS_FACTOR
    memory: bool = True
    radius: float = float("inf")
    anchors: int = 0
    detail: dict = field(default_factory=dict, repr=False)


def _ritz(rcM, rcK, nr: int, eps: np.ndarray, omega: float, modes, cache: dict | None = None):
    """(V, key): a Ritz basis V (m, r) for δq in relative coordinates: the modes of the structure with
    every pair stuck (ε on [n, t1, t2]) and with the pairs sliding (ε on n only) below
    ``modes`` × ω if a float, or the ``modes`` lowest of each if an int; M-orthonormalised.
    ``cache``: a dict that keeps the two eigenproblems' solutions (they do not depend on ω) for
    the next call on the same structure and ε — the points of a sweep (0.55 s a point at 128
    pairs, 782 DOFs) — and the basis itself under ``key`` (the modes kept: the same at neighbouring
    points; None without a cache)."""
    vecs, kept = [], []
    # only the modes below twice the bound (a sweep's later points reuse them), again if a point needs more
    top = (2 * modes * omega) ** 2 if isinstance(modes, float) else None
    for j, mask in enumerate((np.ones(3), np.array([1.0, 0.0, 0.0]))):
        key = (j, rcM.shape, eps.tobytes(), top is None)
        if cache is not None and key in cache and (cache[key][2] >= (modes * omega) ** 2 if top is not None
                                                   else len(cache[key][0]) >= min(int(modes), rcM.shape[0])):
            lam, V, _ = cache[key]
        else:
            Kc = rcK.copy()
            Kc[np.arange(nr), np.arange(nr)] += eps * np.tile(mask, nr // 3)
            if top is None:
                lam, V = sla.eigh(Kc, rcM, subset_by_index=(0, min(int(modes), rcM.shape[0]) - 1))
            else:   # a partial solve: half the time of the whole spectrum at 782 DOFs
                lam, V = sla.eigh(Kc, rcM, subset_by_value=(-np.inf, top), driver="gvx")
            if cache is not None:
                cache[key] = lam, V, top
        keep = (lam <= (modes * omega) ** 2) if isinstance(modes, float) else (np.arange(len(lam)) < int(modes))
        vecs.append(V[:, keep])
        kept.append(keep.tobytes())
    key = None if cache is None else ("basis", rcM.shape, eps.tobytes(), *kept)
    if key is not None and key in cache:
        return cache[key], key
    V = np.concatenate(vecs, axis=1)
    # M-orthonormal basis of the union (drop dependent directions)
    G = V.T @ rcM @ V
    g, W = np.linalg.eigh(G)
    keep = g > 1e-10 * g.max()
    V = V @ (W[:, keep] / np.sqrt(g[keep]))
    if key is not None:
        cache[key] = V
    return V, key


def _structure(rc, nr: int, en, et, omega: float, modes, cache: dict | None = None):
    """(M, C, K, B, tag) of the linearised structure in relative coordinates (B = [I, 0]: the
    first ``nr`` are the contact DOFs), or on the Ritz basis of ``modes`` (:func:`_ritz`, tag
    "+ritz(n)"; with ``cache`` the projection is kept with its basis: 12 ms a point at 782 DOFs)."""
    M, K, C = (np.asarray(getattr(rc, a), dtype=float) for a in ("M", "K", "C"))
    if modes is None:
        return M, C, K, sp.hstack([sp.identity(nr), sp.csr_matrix((nr, M.shape[0] - nr))]).tocsr(), ""
    V, key = _ritz(M, K, nr, np.stack([en, et, et], axis=1).ravel(), omega, modes, cache)
    if key is not None and ("projected",) + key in cache:
        return cache[("projected",) + key]
    out = V.T @ M @ V, V.T @ C @ V, V.T @ K @ V, V[:nr], f"+ritz({V.shape[1]})"
    if key is not None:
        cache[("projected",) + key] = out
    return out


def _monodromy_exponents(hb, x, nit: int, omega: float, structure, eps, memory: bool, substeps: int,
                         refine: int, levels: int = RICHARDSON):
    """(|μ|max, exponents s (1/s, by decreasing |μ|), pieces, tangent blocks) of the monodromy
    (:func:`monodromy`) of the HB solution x of ``hb`` on nit samples; ``structure`` (M, C, K, B)
    of :func:`_structure`, ``eps`` (ε_N, ε_T) (p,) N/m of the tangent."""
    M, C, K, B = structure
    en, et = eps
    if memory:      # the switching instants located inside the sample intervals
        pc = _switch_pieces(hb, x, nit, omega, refine)
        tan = tangent_blocks(pc.state, pc.lam, pc.lam_x_T, pc.ref_T, en, et, hb.law.mu, omega, memory,
                             eps_dlft_t=hb.law.eps_t, prev=pc.prev, dt=pc.dt)
        h = pc.h
    else:           # the memoryless tangent has no anchor to switch: the DLFT's own samples
        pc = _dlft_samples(hb, x, nit)
        tan = tangent_blocks(pc.state, pc.lam, pc.lam_x_T, pc.ref_T, en, et, hb.law.mu, omega, memory,
                             eps_dlft_t=hb.law.eps_t)
        h = None
    mult = _live_multipliers(M, C, K, B, tan, omega, substeps=substeps, h=h, levels=levels)
    mult = mult[np.argsort(-np.abs(mult))]
    with np.errstate(divide="ignore", invalid="ignore"):   # a multiplier 0: s = −∞ (a slaved anchor)
        s = np.log(mult.astype(complex)) / (2 * np.pi / omega)
    return float(np.abs(mult[0])), s, pc, tan


def _hill_solve(tan: dict, res, structure, omega: float, nh: int, memory: bool, n_exp, dense):
    """:func:`hill_stability`'s Hill branch at ``nh`` harmonics: (|μ|max, exponents (1/s), the DLFT
    ``res``, the dense tangent ``tan`` (:func:`contact_tangent`), solver, radius (1/s), size)."""
    M, C, K, B = structure
    na = 2 * int(tan["active"].sum()) if memory else 0
    kw = dict(Ku=tan["Ku"])
    if na:
        kw.update(Kw=tan["Kw"], Ew=tan["Ew"], Aw=tan["Aw"], Au=tan["Au"])
    A, E = _pencil(M, C, K, omega, nh, B=B, **kw)
    h = hill_descriptor(A, E, omega, nh, M.shape[0], na, n_exp=n_exp, dense=dense)
    return h.floquet_max, h.exponents, res, tan, h.method, h.radius, h.size


def hill_stability(model, hb, x, omega: float, *, method: str = "monodromy", nh_hill: int | None = None,
                   nh_check: int | None = 0, memory: bool = True, eps_factor: float = EPS_FACTOR,
                   nit: int | None = None, dense: bool | None = None, n_exp: int | None = None, modes=None,
                   rc=None, substeps: int = SUBSTEPS, refine=SWITCH_REFINE, levels: int = RICHARDSON,
                   cache: dict | None = None) -> Stability:
    """Floquet stability of the HB solution ``x`` of ``hb`` (:class:`~workflow.engine.hb.HBProblem`)
    at ω (rad/s) on ``model`` (:class:`~workflow.engine.model.ReducedModel`).

    The periodic orbit enters only through the contact law's samples along the period
    (:func:`contact_tangent` of the DLFT at x, ``nit`` samples); the structure's own M, C, K are
    those of ``model`` in relative coordinates (``rc``: :func:`workflow.engine.condense.relative_coordinates`,
    computed if not given), where B = [I, 0]. The q-harmonics the condensation eliminated,
    ``q_h = (K − (hω)²M + ihωC)⁻¹(F_h − Bᵀλ_h)``, are not needed: the linear problem is the
    full one, not the condensed Zr (which is not polynomial in s).

    method    "monodromy" (default): the monodromy of the linearisation by time integration
              (:func:`monodromy`, nit default max(hb.nit, :data:`MONODROMY_NIT`), the
              switching instants located to T/(nit·Π``refine``) by :func:`_switch_pieces`,
              ``refine`` 1: to the sample; ``substeps`` backward-Euler steps a piece, ``levels``
              Richardson halvings), the check at 2·nit; "hill": Hill's method
              (:func:`hill_descriptor`) at ``nh_hill`` harmonics (default max(2·Nh, 8)), the
              check at ``nh_check`` (0: ⌈1.5·nh_hill⌉), the DLFT on nit ≥ 4·nh+1 samples.
              ``nh_check`` None: no check, half the cost.
    memory    anchors as states (exact, default) or the memoryless tangent
    eps_factor ε of the tangent / static stiffness per pair and direction
    modes     None: the full δq; a float: a Ritz basis of the modes with the pairs stuck
              and sliding below modes × ω; an int: that many of each (large models)
    dense, n_exp  Hill's eigensolver, see :func:`hill_descriptor`
    cache     a dict kept across calls on one model (a sweep's points): the Ritz basis's
              eigenproblems (:func:`_ritz`)
    """
    from workflow.engine.condense import relative_coordinates
    from workflow.engine import penalty
    from workflow.engine.errors import SceneError

    if method not in ("monodromy", "hill"):
        raise SceneError(f"stability.method: {method!r} is not one of monodromy, hill")
    t0 = time.perf_counter()
    rc = relative_coordinates(model) if rc is None else rc
    ks = penalty.reference_stiffness(np.real(hb.Zr[0]))
    en, et = eps_factor * ks[:, 0], eps_factor * ks[:, 1]
    M, C, K, B, tag = _structure(rc, hb.nr, en, et, omega, modes, cache)

    if method == "monodromy":
        nit = max(hb.nit, MONODROMY_NIT) if nit is None else int(nit)

        def solve(n_samples):
            fm, s, pc, tan = _monodromy_exponents(hb, x, int(n_samples), omega, (M, C, K, B), (en, et), memory,
                                                  substeps, refine, levels)
            return fm, s, pc, tan, "monodromy", float("inf"), 2 * M.shape[0]
        first = solve(nit)
        check = solve(2 * nit) if nh_check is not None else None
        nh_hill, nh_check = 0, None
    else:
        nh_hill = max(2 * hb.nh, 8) if nh_hill is None else int(nh_hill)
        if nh_check == 0:
            nh_check = int(np.ceil(1.5 * nh_hill))
        top = max(nh_hill, nh_check or 0)
        if nit is None:
            nit = hb.nit if hb.nit >= 4 * top + 1 else 8 * (top + 1)
        res = _dlft_samples(hb, x, int(nit))
        tan = contact_tangent(res.state, res.lam, res.lam_x_T, res.ref_T, en, et, hb.law.mu, omega, memory,
                              eps_dlft_t=hb.law.eps_t)
        first = _hill_solve(tan, res, (M, C, K, B), omega, nh_hill, memory, n_exp, dense)
        check = _hill_solve(tan, res, (M, C, K, B), omega, nh_check, memory, n_exp, dense) if nh_check else None
    fm, s, res, tan, how, radius, size = first
    s = s[np.argsort(-s.real)]
    detail = {"size": size, "nit": int(nit), "states": np.bincount(res.state.ravel(), minlength=3)}
    if isinstance(res, _Pieces):
        detail.update(pieces=len(res.h), switches=res.switches, samples=res.samples)
    return Stability(stable=bool(fm <= 1 + STABLE_TOL), floquet_max=fm, exponents=s,
                     truncation_change=None if check is None else abs(check[0] - fm), method=how + tag,
                     seconds=time.perf_counter() - t0, nh_hill=nh_hill, nh_check=nh_check,
                     eps_factor=eps_factor, memory=memory, radius=radius, anchors=int(tan["active"].sum()),
                     detail=detail)
