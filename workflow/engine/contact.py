"""Dynamic Lagrangian frictional contact law (DLFT, paper eqs. 11–17), 3D, per node pair.

Sign convention (docs/contracts.md §6 — stated here and nowhere else)
---------------------------------------------------------------------
* Relative DOFs of pair i are ``u_r = u_blade − u_disk`` in the pair frame
  ``(n, t1, t2)``, n pointing from the disk into the blade; arrays carry them
  as the last axis of length 3, ``[n, t1, t2]`` (metres).
* λ (newtons) is the multiplier of eq. 3, ``Zr U_r + λ = Fr``: the force the
  disk exerts on the blade is ``−λ``. Hence **λ_N < 0 in contact**
  (compression), and a predicted ``λ_N ≥ 0`` means separation (eq. 15).
* Normal gap function ``g = u_N + gap + W ≥ 0`` with ``gap`` the initial
  opening (> 0 open, < 0 interference) and ``W ≥ 0`` the wear depth. The
  paper's ``U^N − W`` becomes our shifted displacement ``u_N + gap + W``, so
  ``X^N = 0`` in contact means ``g = 0``.
* ``λ_x = ε X`` is the penalty image of the corrected displacement X of
  eq. 11; its tangential part is the stick reference ("anchor") remembered
  from one instant to the next.
* Contact pressure ``p_N = −λ_N / area ≥ 0``.

The law, one instant k (eqs. 13–17), given the predictor
``λ_u = F_r − Z_r U_r + ε (U_r + [gap + W, 0, 0])`` (eq. 11/12, evaluated
by the caller in the time domain):

* predictor ``λ_pre^T = λ_u^T − λ_x^{k−1,T}``, ``λ_pre^N = λ_u^N``;
* separation (``λ_pre^N ≥ 0``): ``λ = 0``, ``λ_x = λ_u``;
* stick (``‖λ_pre^T‖ < μ|λ_pre^N|``): ``λ = λ_pre``, ``λ_x^T = λ_x^{k−1,T}``;
* slip: ``λ^N = λ_pre^N``, ``λ^T = μ|λ_pre^N| λ_pre^T/‖λ_pre^T‖``,
  ``λ_x^T = λ_u^T − λ^T``.

The pass is sequential in time (stick remembers the previous instant) and
vectorised over pairs. A periodic solution needs the reference at the start
of the period to equal the one at its end: passes are repeated until it stops
changing (see :func:`dlft_pass`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from workflow.engine.errors import SceneError
from workflow.engine.jit import compiled

__all__ = ["SEPARATION", "STICK", "SLIP", "ContactLaw", "DLFTResult", "dlft_pass", "dlft"]

SEPARATION, STICK, SLIP = 0, 1, 2

_TINY = 1e-300
#: relative distance to the Coulomb cone within which a stuck instant is "touching"
#: (takes the slip derivative); above the periodic-pass tolerance.
_TOUCH = 1e-7
#: a pre-slip force beyond the cone by less than this many ε_mach × (‖λ_pre^T‖'s operands, the
#: predictor and the stick reference) is round-off, not slip: ``λ_pre^T = λ_u^T − λ_x^T`` is the
#: difference of two forces of that size, each the sum of up to 2Nh+1 harmonics' terms. A pair
#: that shook down onto the cone sits there to round-off; counted as slip it moved its reference
#: by ~1e-18 of its displacement each period and wore a stuck interface at ~1e-29 m/cycle — a
#: pseudo-time march then chased that "wear" over 1e19 cycles (quick sector at 0.98 f_r).
_ROUND = 64.0 * float(np.finfo(float).eps)
#: smallest singular value of I − ∂Φ/∂r (relative) for a periodic reference to count as isolated
_ISOLATED = 1e-6


def _per_pair(value, p: int, name: str, *, positive: bool = False,
              nonnegative: bool = False) -> np.ndarray:
    """Broadcast a scalar or (p,) value to a float (p,) array and validate it."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{name}: not a number or array of numbers ({exc})") from None
    if a.ndim == 0:
        a = np.full(p, float(a))
    if a.shape != (p,):
        raise SceneError(f"{name}: expected a scalar or {p} values (one per pair), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise SceneError(f"{name}: values must be finite (got NaN or inf)")
    if positive and np.any(a <= 0):
        raise SceneError(f"{name}: values must be > 0 (min {a.min():g})")
    if nonnegative and np.any(a < 0):
        raise SceneError(f"{name}: values must be ≥ 0 (min {a.min():g})")
    return a


@dataclass(frozen=True, eq=False)
class ContactLaw:
    """Per-pair parameters of the DLFT law.

    mu     friction coefficient, (p,) or scalar, ≥ 0 (dimensionless)
    eps_n  normal DLFT penalty ε_N, scalar or (p,), > 0 (N/m)
    eps_t  tangential DLFT penalty ε_T, scalar or (p,), > 0 (N/m)
    gap    initial normal opening, (p,) (m; > 0 open, < 0 interference)
    wear   wear depth W, (p,) ≥ 0 (m); default zeros

    ``p`` is taken from ``gap``. In stick and separation the converged HB
    solution does not depend on ε; in slip with nit > 2Nh+1 it does: the
    harmonics of X above Nh are −λ/ε, so ε is the stiffness lent to the
    unresolved harmonics, and the penalties are chosen once, as the contact
    DOFs' own stiffness at those harmonics, in :mod:`workflow.engine.penalty`. Invalid values raise
    :class:`~workflow.engine.errors.SceneError` naming ``contact.<field>``.
    """

    mu: np.ndarray
    eps_n: np.ndarray
    eps_t: np.ndarray
    gap: np.ndarray
    wear: np.ndarray = field(default=None)
    #: (p,) fraction of the period [0, 1) at which each pair's DLFT pass begins from its stick
    #: anchor (default 0): where a pair shakes down onto the cone depends on the instant its
    #: passes start, so a whole disk's sector s starts at its engine-order delay — the same
    #: instant of its own excitation as the cyclic sector's (:func:`start_samples`)
    phase: np.ndarray = field(default=None)

    def __post_init__(self):
        # p comes from the first per-pair array among gap, mu, wear
        p = None
        for v in (self.gap, self.mu, self.wear):
            if v is not None and np.ndim(v) == 1:
                p = len(v)
                break
        if p is None:
            raise SceneError("contact.gap: expected one value per pair (an array)")
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731  (frozen dataclass)
        set_("gap", _per_pair(self.gap, p, "contact.gap"))
        set_("mu", _per_pair(self.mu, p, "contact.mu", nonnegative=True))
        set_("eps_n", _per_pair(self.eps_n, p, "contact.eps_n", positive=True))
        set_("eps_t", _per_pair(self.eps_t, p, "contact.eps_t", positive=True))
        w = np.zeros(p) if self.wear is None else self.wear
        set_("wear", _per_pair(w, p, "contact.wear", nonnegative=True))
        ph = np.zeros(p) if self.phase is None else np.mod(_per_pair(self.phase, p, "contact.phase"), 1.0)
        set_("phase", ph)

    @property
    def p(self) -> int:
        """Number of node pairs."""
        return self.gap.shape[0]

    def with_wear(self, wear) -> "ContactLaw":
        """Copy with a new wear depth vector W (p,) in metres."""
        return replace(self, wear=np.asarray(wear, dtype=float).copy())

    def with_penalty(self, eps_n, eps_t) -> "ContactLaw":
        """Copy with new penalties (N/m)."""
        return replace(self, eps_n=eps_n, eps_t=eps_t)

    def eps(self) -> np.ndarray:
        """Penalties per relative DOF, (p, 3) = [ε_N, ε_T, ε_T] (N/m)."""
        return np.stack([self.eps_n, self.eps_t, self.eps_t], axis=1)

    def offset(self) -> np.ndarray:
        """Shift (p, 3) added to u_r so that its normal part is the gap function g (m)."""
        off = np.zeros((self.p, 3))
        off[:, 0] = self.gap + self.wear
        return off


@dataclass
class DLFTResult:
    """Output of :func:`dlft_pass` (time samples on τ_k = 2πk/nit).

    lam       (nit, p, 3) corrected multipliers λ^k (N), eq. 14
    lam_x_T   (nit, p, 2) tangential λ_x^k (N) — the stick references
    state     (nit, p) int8: 0 separation, 1 stick, 2 slip
    passes    number of sequential passes made
    converged whether the period-start reference stopped changing
    ref_T     (p, 2) reference λ_x^{−1,T} the final pass started from (N)
    ref_change last max |λ_x^{end,T} − λ_x^{start,T}| (N)
    dlam      (nit, p, 3, 3m) or None: dλ^k_{i,c} / d a_{j,i,c'} at column
              3j+c', where the caller's predictor is λ_u[k,i,c] = Σ_j basis[k,j] a[j,i,c]
              (exact for the converged periodic fixed point; see dlft_pass);
              (r, p, 3, 3m), ``rows · dλ/da`` over the instants, if dlft_pass had ``rows``
    """

    lam: np.ndarray
    lam_x_T: np.ndarray
    state: np.ndarray
    passes: int
    converged: bool
    ref_T: np.ndarray
    ref_change: float
    dlam: np.ndarray | None = None


def _inv2(A: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Inverse of (p, 2, 2) matrices where ``ok``; zero elsewhere."""
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
    safe = np.where(ok, det, 1.0)
    inv = np.empty_like(A)
    inv[:, 0, 0] = A[:, 1, 1]
    inv[:, 1, 1] = A[:, 0, 0]
    inv[:, 0, 1] = -A[:, 0, 1]
    inv[:, 1, 0] = -A[:, 1, 0]
    inv /= safe[:, None, None]
    inv[~ok] = 0.0
    return inv


def _one_pass_numpy(lam_u, mu, ref, dlu, start):
    """One sequential pass over the period from reference ``ref`` (p, 2), pair i from
    instant ``start[i]`` on (outputs in time order).

    ``dlu`` (nit, 3, ncol) is the sensitivity of λ_u^k (same for every pair)
    with respect to the caller's columns, the last two being the reference;
    sensitivities S of λ_x^T (p, 2, ncol) are carried through the branches.

    Every branch is written ``λ^T = f · λ_pre^T`` with f = 1 (stick),
    μ|λ_pre^N|/‖λ_pre^T‖ (slip), 0 (separation), and ``λ_x^T = λ_u^T − λ^T``,
    so one set of array operations serves all pairs (no per-pair branching).
    """
    nit, p, _ = lam_u.shape
    ncol = dlu.shape[2]
    luN = lam_u[:, :, 0]
    luT = lam_u[:, :, 1:]
    # the normal part has no memory: vectorise it over time (eq. 15 / X^N = 0)
    sep_all = luN >= 0.0
    limit_all = -mu[None, :] * luN            # μ|λ_pre^N| in contact
    lam = np.empty((nit, p, 3))
    lam[:, :, 0] = np.where(sep_all, 0.0, luN)
    dlam = np.empty((nit, p, 3, ncol))
    dlam[:, :, 0, :] = np.where(sep_all[:, :, None], 0.0, dlu[:, None, 0, :])
    lxT_all = np.empty((nit, p, 2))
    state = np.empty((nit, p), dtype=np.int8)
    lxT = ref.copy()
    S = np.zeros((p, 2, ncol))
    S[:, 0, ncol - 2] = 1.0  # d ref / d ref = I
    S[:, 1, ncol - 1] = 1.0
    mu_col = mu[:, None]
    ip = np.arange(p)
    for j in range(nit):
        k = (j + start) % nit                 # (p,): each pair's instant at step j
        luTk = luT[k, ip]
        dluk = dlu[k]                          # (p, 3, ncol)
        preT = luTk - lxT
        nT = np.sqrt(preT[:, 0] * preT[:, 0] + preT[:, 1] * preT[:, 1])
        sep = sep_all[k, ip]
        lim = limit_all[k, ip]
        rnd = _ROUND * (np.sqrt(np.sum(luTk * luTk, axis=1)) + np.sqrt(np.sum(lxT * lxT, axis=1)))
        slip = (nT > lim + rnd) & ~sep
        stick = ~(slip | sep)
        # A pair that slipped while the periods settled ends *on* the cone
        # (shakedown): its forces are those of stick to O(δ), but its reference
        # follows the touching instant, so it takes the slip derivative.
        touch = stick & (nT >= lim * (1.0 - _TOUCH))
        state[k, ip] = np.where(sep, SEPARATION, np.where(slip | touch, SLIP, STICK))
        inv = 1.0 / np.maximum(nT, _TINY)
        fac = np.where(stick, 1.0, np.where(slip, lim * inv, 0.0))
        lamT = fac[:, None] * preT
        lam[k, ip, 1:] = lamT
        # stick keeps the anchor bit-for-bit so a pair stuck all period is an exact fixed point
        lxT = np.where(stick[:, None], lxT, luTk - lamT)
        lxT_all[k, ip] = lxT
        # sensitivities: dλ^T = f dλ_pre^T + λ_pre^T ⊗ df, with, in slip,
        # df = −(μ dλ_pre^N + f t·dλ_pre^T)/‖λ_pre^T‖  (|λ_pre^N| = −λ_pre^N, t = λ_pre^T/‖λ_pre^T‖)
        dpreT = dluk[:, 1:] - S
        dT = fac[:, None, None] * dpreT
        if slip.any() or touch.any():
            that = preT * inv[:, None]
            tdp = that[:, 0, None] * dpreT[:, 0] + that[:, 1, None] * dpreT[:, 1]
            dfac = -(mu_col * dluk[:, 0] + fac[:, None] * tdp) * (inv * (slip | touch))[:, None]
            dT += preT[:, :, None] * dfac[:, None, :]
        dlam[k, ip, 1:] = dT
        S = dluk[:, 1:] - dT
    return lam, lxT_all, state, dlam, S


def _one_pass_loops(lam_u, mu, ref, dlu, start):
    """:func:`_one_pass_numpy` written as explicit loops over time and pairs
    (same branches, same sensitivities, same outputs), for numba to compile.

    Pure Python it is far too slow to use; compiled (``_one_pass_numba``) it
    removes the per-instant interpreter overhead that dominates the NumPy
    pass (~30 µs × nit). The NumPy version stays the fallback and the oracle.
    One function on purpose: it is the sequential physics of one
    period, compiled whole by numba; splitting it would put a call per
    instant and pair back into the hot loop.
    """
    nit, p, _ = lam_u.shape
    ncol = dlu.shape[2]
    lam = np.empty((nit, p, 3))
    dlam = np.empty((nit, p, 3, ncol))
    lxT_all = np.empty((nit, p, 2))
    state = np.empty((nit, p), dtype=np.int8)
    S = np.zeros((p, 2, ncol))
    dT = np.empty((2, ncol))
    for i in range(p):
        S[i, 0, ncol - 2] = 1.0
        S[i, 1, ncol - 1] = 1.0
    for i in range(p):
        mui = mu[i]
        l0 = ref[i, 0]
        l1 = ref[i, 1]
        for j in range(nit):
            k = (j + start[i]) % nit
            luN = lam_u[k, i, 0]
            sep = luN >= 0.0
            lim = -mui * luN
            if sep:
                lam[k, i, 0] = 0.0
                for n in range(ncol):
                    dlam[k, i, 0, n] = 0.0
            else:
                lam[k, i, 0] = luN
                for n in range(ncol):
                    dlam[k, i, 0, n] = dlu[k, 0, n]
            p0 = lam_u[k, i, 1] - l0
            p1 = lam_u[k, i, 2] - l1
            nT = np.sqrt(p0 * p0 + p1 * p1)
            rnd = _ROUND * (np.sqrt(lam_u[k, i, 1] ** 2 + lam_u[k, i, 2] ** 2) + np.sqrt(l0 * l0 + l1 * l1))
            slip = (nT > lim + rnd) and not sep
            stick = not (slip or sep)
            touch = stick and (nT >= lim * (1.0 - _TOUCH))
            if sep:
                state[k, i] = SEPARATION
            elif slip or touch:
                state[k, i] = SLIP
            else:
                state[k, i] = STICK
            inv = 1.0 / max(nT, _TINY)
            if stick:
                fac = 1.0
            elif slip:
                fac = lim * inv
            else:
                fac = 0.0
            t0 = fac * p0
            t1 = fac * p1
            lam[k, i, 1] = t0
            lam[k, i, 2] = t1
            if not stick:
                l0 = lam_u[k, i, 1] - t0
                l1 = lam_u[k, i, 2] - t1
            lxT_all[k, i, 0] = l0
            lxT_all[k, i, 1] = l1
            for c in range(2):
                for n in range(ncol):
                    dT[c, n] = fac * (dlu[k, 1 + c, n] - S[i, c, n])
            if slip or touch:
                h0 = p0 * inv
                h1 = p1 * inv
                for n in range(ncol):
                    d0 = dlu[k, 1, n] - S[i, 0, n]
                    d1 = dlu[k, 2, n] - S[i, 1, n]
                    tdp = h0 * d0 + h1 * d1
                    dfac = -(mui * dlu[k, 0, n] + fac * tdp) * inv
                    dT[0, n] += p0 * dfac
                    dT[1, n] += p1 * dfac
            for c in range(2):
                for n in range(ncol):
                    dlam[k, i, 1 + c, n] = dT[c, n]
                    S[i, c, n] = dlu[k, 1 + c, n] - dT[c, n]
    return lam, lxT_all, state, dlam, S


#: the compiled pass, or None: the NumPy pass (the fallback and the test oracle)
_one_pass_numba = compiled(_one_pass_loops)


def _one_pass(lam_u, mu, ref, dlu, start):
    """One sequential pass: compiled loops when numba is importable, else NumPy."""
    if _one_pass_numba is not None:
        return _one_pass_numba(np.ascontiguousarray(lam_u, dtype=float), np.ascontiguousarray(mu, dtype=float),
                               np.ascontiguousarray(ref, dtype=float), np.ascontiguousarray(dlu, dtype=float),
                               np.ascontiguousarray(start, dtype=np.int64))
    return _one_pass_numpy(lam_u, mu, ref, dlu, start)


def start_samples(law: ContactLaw, nit: int) -> np.ndarray:
    """(p,) the instant each pair's DLFT pass begins (:attr:`ContactLaw.phase` on nit samples)."""
    return np.rint(law.phase * nit).astype(np.int64) % max(int(nit), 1)


def _predictor_columns(basis, nit: int, jacobian: bool) -> np.ndarray:
    """dλ_u/d(columns), (nit, 3, 3m + 2): the predictor basis per component, plus
    two columns for the start reference (only those without ``jacobian``)."""
    if not jacobian:
        return np.zeros((nit, 3, 2))
    if basis is None:
        raise ValueError("jacobian=True needs the predictor basis")
    basis = np.asarray(basis, dtype=float)
    m = basis.shape[1]
    dlu = np.zeros((nit, 3, m, 3))
    for c in range(3):
        dlu[:, c, :, c] = basis
    return np.concatenate([dlu.reshape(nit, 3, 3 * m), np.zeros((nit, 3, 2))], axis=2)


def _next_reference(ref, end, d, S, stuck, Dr, ncol: int, newton: bool):
    """The start reference of the next pass and its carried derivative: Newton
    on the fixed point ``r = Φ(r)`` per pair (2×2, ``newton``; not for stuck
    pairs or a singular ``I − ∂Φ/∂r``), plain substitution otherwise."""
    p = ref.shape[0]
    A = S[:, :, ncol:]
    ok = np.zeros(p, dtype=bool)
    inv = None
    if newton:
        IA = np.eye(2)[None] - A
        det = IA[:, 0, 0] * IA[:, 1, 1] - IA[:, 0, 1] * IA[:, 1, 0]
        ok = ~stuck & (np.abs(det) > 1e-8)
        inv = _inv2(IA, ok)
        new = np.where(ok[:, None], ref + np.einsum("iab,ib->ia", inv, d), end)
    else:
        new = end.copy()
    if Dr is not None:
        # substitution r ← Φ(a, r): Dr ← ∂Φ/∂a + ∂Φ/∂r Dr; a Newton step on
        # the fixed point has the implicit-function derivative (I − ∂Φ/∂r)⁻¹ ∂Φ/∂a
        Dr_sub = S[:, :, :ncol] + np.einsum("iab,ibn->ian", A, Dr)
        if ok.any():
            Dr = np.where(ok[:, None, None], np.einsum("iab,ibn->ian", inv, S[:, :, :ncol]), Dr_sub)
        else:
            Dr = Dr_sub
    return new, Dr


def _periodic_jacobian(dlam, S, state, Dr, ncol: int, periodic: bool, rows=None):
    """dλ/da of the last pass including the start reference's dependence on a (``rows ·`` it over
    the instants, if given: the correction is linear in the instants' rows, so the per-instant
    (nit, p, 3, 3m) correction is never formed — at 512 pairs, nit = 64, Nh = 7 a 35 MB array;
    the correction and the projection took 26 ms a Jacobian, 8 ms so)."""
    if rows is not None:
        dlam = (rows @ dlam.reshape(dlam.shape[0], -1)).reshape((rows.shape[0],) + dlam.shape[1:])
    dl = dlam[..., :ncol]
    if not periodic:
        return dl
    # Isolated fixed point (I − ∂Φ/∂r regular): implicit-function
    # derivative, independent of the passes' path. Neutral directions
    # (a pair touching the cone at one instant after shakedown: any
    # reference on a circle is periodic) are set by where the passes
    # started, so there the derivative is the one carried along them.
    stuck = np.all(state == STICK, axis=0)
    IA = np.eye(2)[None] - S[:, :, ncol:]
    sv = np.linalg.svd(IA, compute_uv=False)
    iso = ~stuck & (sv[:, 1] > _ISOLATED * np.maximum(sv[:, 0], 1.0))
    dr = np.einsum("iab,ibn->ian", _inv2(IA, iso), S[:, :, :ncol])
    dr = np.where(iso[:, None, None], dr, Dr)
    if rows is not None:
        return dl + np.matmul(dlam[..., ncol:], dr)
    return dl + np.einsum("kicr,irn->kicn", dlam[..., ncol:], dr)


def _pass_inputs(lam_u, mu, lam_x0_T, max_passes: int, start):
    """:func:`dlft_pass`'s inputs checked and shaped: λ_u (nit, p, 3), μ (p,), the start
    reference (p, 2) and each pair's start instant (p,) in [0, nit)."""
    lam_u = np.asarray(lam_u, dtype=float)
    if lam_u.ndim != 3 or lam_u.shape[2] != 3:
        raise ValueError(f"lam_u must be (nit, p, 3), got {lam_u.shape}")
    if max_passes < 1:
        raise ValueError("max_passes must be ≥ 1")
    nit, p, _ = lam_u.shape
    start = np.zeros(p, np.int64) if start is None else np.asarray(start, np.int64) % nit
    return (lam_u, np.broadcast_to(np.asarray(mu, dtype=float), (p,)), np.array(lam_x0_T, dtype=float).reshape(p, 2),
            start)


def dlft_pass(lam_u: np.ndarray, mu, lam_x0_T: np.ndarray, *, basis: np.ndarray | None = None,
              periodic: bool = True, max_passes: int = 20, tol: float = 1e-10,
              accelerate: bool = True, jacobian: bool = False, rows: np.ndarray | None = None,
              start: np.ndarray | None = None) -> DLFTResult:
    """DLFT correction in the time domain (eqs. 13–17), repeated to a periodic state.

    Parameters
    ----------
    lam_u : (nit, p, 3) predictor λ_u of eq. 11/12 per instant and pair (N),
        i.e. ``F_r − Z_r U_r + ε (U_r + [gap + W, 0, 0])`` sampled in time.
    mu : (p,) or scalar friction coefficient.
    lam_x0_T : (p, 2) stick reference λ_x^{−1,T} before the first instant (N),
        ``ε_T ×`` the tangential anchor displacement.
    basis : (nit, m) matrix with ``λ_u[k] = Σ_j basis[k, j] a_j`` (per pair and
        component): the columns the Jacobian is taken against (real Fourier
        coefficients for HBM/TCM, identity for HDHB). Needed if ``jacobian``.
    periodic : if False, a single pass from ``lam_x0_T`` (a load step, e.g.
        the static state). If True, passes repeat until the reference at the
        period start equals the one at its end within
        ``tol · max|λ_u|``, or ``max_passes`` is reached (``converged`` False).
    accelerate : from the second pass on, update the reference of each pair
        by a Newton step on the fixed point ``r = Φ(r)`` (2×2 per pair, from
        the carried sensitivities) instead of plain substitution; a pair stuck
        during the whole period keeps its reference (any reference is a fixed
        point — the stuck zeroth harmonic, fixed by the caller's static
        state). The first pass is always a substitution: it takes a pair
        from the start anchor onto the cone the way the physical transient
        does, so a pair that shakes down lands where its history puts it (a
        Newton step there would land elsewhere on the circle of periodic
        references, through a step whose derivative needs ∂²Φ).
    jacobian : also return ``dlam``.
    rows : (r, nit), optional: ``dlam`` as ``rows · dλ/da`` (r, p, 3, 3m), e.g. HBM's projection Q,
        applied before the periodic correction (:func:`_periodic_jacobian`).
    start : (p,) int, optional: the instant each pair's pass begins (default 0); ``lam_x0_T`` and
        ``ref_T`` are the references just before it (:func:`start_samples`).

    Jacobian: the sensitivities of λ_x^T (per pair, 2 × (3m + 2)) are carried
    through the pass, with two extra columns for the start reference. For the
    converged periodic state ``r = Φ(a, r)``, ``dr/da = (I − ∂Φ/∂r)⁻¹ ∂Φ/∂a``
    (implicit function theorem, i.e. the limit of propagating across
    infinitely many passes) where that inverse exists. Where it does not — a
    pair that slipped while the passes settled and now touches the cone at
    one instant: every reference on a circle is periodic, ``I − ∂Φ/∂r`` is
    singular across the slip direction — the reference is set by the start
    anchor and the passes made, and ``dr/da`` is the derivative carried along
    those passes (``∂Φ/∂a + ∂Φ/∂r · dr/da`` per substitution). Measured on
    the sector (16 pairs, HBM-1, 50 frequencies): the implicit-function
    pseudo-inverse used before dropped that component, the Jacobian was 27 %
    off finite differences, Newton converged linearly (ratio 0.5–0.75) in
    1230 iterations; with the carried derivative, 206. Pairs stuck all period
    keep ``dr/da = 0``: their reference is an external parameter.
    """
    lam_u, mu, ref, start = _pass_inputs(lam_u, mu, lam_x0_T, max_passes, start)
    nit, p, _ = lam_u.shape
    dlu = _predictor_columns(basis, nit, jacobian)
    ncol = dlu.shape[2] - 2
    scale = max(float(np.abs(lam_u).max()), _TINY)
    passes, converged, change, prev_change = 0, not periodic, 0.0, np.inf
    # d(start reference)/da along the passes made (the start anchor is a parameter):
    # the derivative where the fixed point is not isolated (docstring, Jacobian)
    Dr = np.zeros((p, 2, ncol)) if (jacobian and periodic) else None
    last = (start - 1) % nit, np.arange(p)       # each pair's last instant of its pass
    while True:
        lam, lxT, state, dlam, S = _one_pass(lam_u, mu, ref, dlu, start)
        passes += 1
        if not periodic:
            break
        end = lxT[last]
        d = end - ref
        change = float(np.abs(d).max())
        converged = change <= tol * scale
        if converged or passes >= max_passes:
            break
        ref, Dr = _next_reference(ref, end, d, S, np.all(state == STICK, axis=0), Dr, ncol,
                                  accelerate and passes >= 2 and change < prev_change)
        prev_change = change
    out_dlam = _periodic_jacobian(dlam, S, state, Dr, ncol, periodic, rows) if jacobian else None
    return DLFTResult(lam=lam, lam_x_T=lxT, state=state, passes=passes, converged=converged,
                      ref_T=ref, ref_change=change, dlam=out_dlam)


def dlft(law: ContactLaw, lam_u: np.ndarray, anchor_T: np.ndarray, **kw) -> DLFTResult:
    """:func:`dlft_pass` with the law's μ and a stick reference given as a
    tangential anchor displacement (p, 2) in metres: ``λ_x^{−1,T} = ε_T · anchor``.

    Storing the anchor as a displacement keeps a stuck pair's static offset
    independent of ε_T.
    """
    ref = law.eps_t[:, None] * np.asarray(anchor_T, dtype=float).reshape(law.p, 2)
    if np.any(law.phase) and "start" not in kw:
        kw["start"] = start_samples(law, np.shape(lam_u)[0])
    return dlft_pass(lam_u, law.mu, ref, **kw)
