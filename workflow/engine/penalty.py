"""The DLFT penalties ε_N, ε_T: chosen here, once, for every stage.

What ε is (measured, docs/solver-guide.md "Penalty ε")
------------------------------------------------------
At a DLFT root (eqs. 11–17) the first Nh harmonics of the corrected
displacement X equal U; with nit > 2Nh+1 samples the harmonics of X above Nh
are ``−λ_h/ε``. Had those harmonics been resolved, the structure would give
``U_h = −Zr(hω)⁻¹ λ_h`` (eq. 3; no force acts there). So ε *is* the stiffness
the model lends the unresolved harmonics, and the best single value is the
contact DOF's own dynamic stiffness above the first harmonic. With nit = 2Nh+1
(collocated variants) a root does not see ε at all
(:func:`workflow.engine.cascade.collocated`).

The automatic rule, per pair and direction (:func:`unresolved_stiffness`,
:func:`choose`): the compliance ``c = median_h Re(1/Zr_ii(hω))`` over
h = 2…:data:`HARMONICS` at the first excited tied frequency, and

    ε = clip(1/c, k_static, CAP·k_static),   1/c := ∞ where c ≤ 0,

with ``k_static`` the static condensed stiffness (:func:`reference_stiffness`).

* A finite-element contact node (the dovetail) is stiffness-dominated far
  above the first mode: Re Zr_ii(hω) stays within ±5 % of k_static up to
  h = 40 on the quick sector, so ε ≈ k_static.
* A massless slider on a spring k_d (Jenkins pads): Zr → k_d, so ε ≈ k_d.
* A contact on a bare mass (Den Hartog's oscillator): Zr(hω) = k − (hω)²m < 0,
  the unresolved harmonics see inertia that no positive ε matches, and the
  ε → ∞ limit (CAP × k_static) is the best a penalty can do.

Measured, peak amplitude or error against independent references:

=================================  ======  ======  ======  ======  =====
Nh                                  1       3       5       7       11
pad chain vs time integration,
  max error / peak, CAP·k (old)    12.1 %  2.53 %  2.56 %  1.61 %  0.37 %
  automatic (≈ k_d)                0.28 %  0.056 % 0.063 % 0.063 % 0.010 %
quick sector, refined peak (mm),
  CAP·k_static (old default)       3.990   3.826   3.829   3.842
  automatic (≈ k_static)           3.908   3.863   3.858   3.860   3.857
  collocated nit = 2Nh+1 (ε-free)  3.548   3.926   3.871   3.862   3.861
=================================  ======  ======  ======  ======  =====

so on the dovetail the automatic penalty is converged in Nh to 0.1 % from
Nh = 3, where the large one is still 0.5 % off at Nh = 7 — and 5–8× slower
(its Newton basin shrinks as 1/ε; 49.7 s against 6.4 s for the HBM-7 sweep).
``contact.penalty_factor`` > 0 restores ε = factor × k_static for every pair.
A user's ``contact.eps_n`` / ``eps_t`` (N/m) win over both. Every FRF and
wear result reports how much it moves with Nh (``nh_check``, the measure of
convergence) and with ε × :data:`CHECK_FACTOR` (``eps_check``, the model's
sensitivity; :mod:`workflow.engine.studies.epscheck`).
"""
from __future__ import annotations

import numpy as np

from workflow.engine.errors import BundleError, SceneError

#: the largest automatic penalty, as a multiple of the static stiffness: the
#: stand-in for ε → ∞ where the unresolved harmonics see inertia (Den Hartog:
#: the first harmonic is identical to 7 digits from 10³ to 10⁶).
CAP = 1.0e3
#: harmonics 2…HARMONICS at the tied frequency sample the unresolved range
HARMONICS = 32
#: a user's ε_N or ε_T (contact.eps_n, eps_t) at most this multiple of the static stiffness of
#: every pair: the ε-check and :func:`eps_limit` solve again up to 100 × it, and with the DLFT's
#: Jacobian conditioned as ε/k a relative tolerance of 1e-8 has no digits left past ~1e8 × k
#: (ε_N = 1e18 N/m on the quick sector, 5e12 × k: no frequency point in 300 s)
USER_MAX = 1.0e6
#: the ε-continuation starts at this multiple of the reference stiffness.
START_FACTOR = 1.0
#: the ε-check re-solves with ε multiplied by this.
CHECK_FACTOR = 10.0
#: relative change of the observed amplitude under the ε-check above which a
#: result is reported as not converged in ε.
CHECK_TOL = 1.0e-3


def reference_stiffness(Zr0: np.ndarray) -> np.ndarray:
    """Positive stiffness (p, 2) per pair, [normal, tangential] (N/m).

    The diagonal of ``Re Zr[0]`` (the static condensed stiffness on the
    relative DOFs), tangential = mean of t1 and t2. A direction with no
    stiffness of its own (≤ 1e-12 of the largest, e.g. a lumped model that
    gives a DOF nothing) takes the mean over the pairs that have one in the
    same direction. Raises :class:`BundleError` if no pair has any.
    """
    d = np.real(np.diagonal(np.asarray(Zr0))).reshape(-1, 3)
    k = np.stack([d[:, 0], 0.5 * (d[:, 1] + d[:, 2])], axis=1)
    top = np.max(np.abs(d)) if d.size else 0.0
    if not np.all(np.isfinite(k)) or top <= 0:
        raise BundleError("reduced model: the static condensed stiffness on the contact DOFs is zero or not "
                          "finite (is the structure clamped? contact.eps_n / contact.eps_t can be set by hand)")
    for c, key in ((0, "contact.eps_n"), (1, "contact.eps_t")):
        ok = k[:, c] > 1e-12 * top
        if not ok.any():
            raise BundleError(f"reduced model: no pair has a positive static stiffness in the "
                              f"{'normal' if c == 0 else 'tangential'} direction; set {key} by hand")
        k[~ok, c] = k[ok, c].mean()
    return k


def unresolved_stiffness(rc, omega: float, harmonics: int = HARMONICS) -> np.ndarray:
    """Stiffness (p, 2) per pair, [normal, tangential] (N/m), that the contact DOFs show
    the harmonics a HB leaves unresolved: ``1 / median_h Re(1/Zr_ii(hω))`` over
    h = 2…``harmonics`` at ``omega`` (rad/s), each DOF with the others held (the
    diagonal of the condensed Zr, eq. 3); +inf where that median compliance is ≤ 0
    (inertia-dominated: Den Hartog's bare mass). Tangential: the mean of the t1 and
    t2 compliances. The range does not depend on Nh, so one law serves every variant
    of a study (on the dovetail the stiffness is flat in h). A cyclic model is
    sampled on the excitation's nodal diameter. The median ignores the few h that
    sit on a resonance of the structure with the interface free."""
    from workflow.engine.condense import diagonal
    from workflow.engine.blas import large_blas

    base = rc.harmonic(1) if hasattr(rc, "by_nd") else rc
    with large_blas(int(base.n_rel)):
        d = diagonal(base, float(omega), int(harmonics))[2:]       # (H−1, 3p)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.median(np.real(1.0 / d), axis=0).reshape(-1, 3)    # m/N
    c = np.stack([c[:, 0], 0.5 * (c[:, 1] + c[:, 2])], axis=1)
    with np.errstate(divide="ignore"):
        return np.where(c > 0, 1.0 / np.where(c > 0, c, 1.0), np.inf)


def choose(Zr0: np.ndarray, eps_n: float = 0.0, eps_t: float = 0.0, factor: float = 0.0,
           k_unresolved: np.ndarray | None = None) -> tuple:
    """(ε_N (p,), ε_T (p,)) in N/m: a user's value where given (> 0); else, with
    ``factor`` > 0, ``factor`` × :func:`reference_stiffness`; else the automatic
    rule of the module docstring, ``clip(k_unresolved, k, CAP·k)`` per pair and
    direction (``k_unresolved`` from :func:`unresolved_stiffness`; None — a model
    with no tied mode to sample at — gives CAP·k).

    A user value that is negative or not finite, or ε above :data:`USER_MAX` × a pair's static
    stiffness, is a :class:`SceneError` naming ``contact.eps_n`` / ``contact.eps_t`` /
    ``contact.penalty_factor``.
    """
    for key, v in (("contact.eps_n", eps_n), ("contact.eps_t", eps_t), ("contact.penalty_factor", factor)):
        if not np.isfinite(v) or v < 0:
            raise SceneError(f"{key} = {v!r}: must be a finite number ≥ 0")
    p = np.asarray(Zr0).shape[-1] // 3
    if eps_n > 0 or eps_t > 0:
        ref = reference_stiffness(Zr0)
        for key, v, col in (("contact.eps_n", eps_n, 0), ("contact.eps_t", eps_t, 1)):
            if v > 0 and v > USER_MAX * float(np.min(ref[:, col])):
                raise SceneError(f"{key} = {v:.3g} N/m is {v / float(np.min(ref[:, col])):.2g} × the static "
                                 f"stiffness at a pair ({float(np.min(ref[:, col])):.3g} N/m): above "
                                 f"{USER_MAX:.0e} × it the DLFT's Jacobian leaves double precision no room "
                                 f"for hb.tol (the automatic rule, 0, takes up to {CAP:.0e} ×)")
    k = None if (eps_n > 0 and eps_t > 0) else reference_stiffness(Zr0)
    if k is None:
        auto = None
    elif factor > 0:
        auto = factor * k
    elif k_unresolved is None:
        auto = CAP * k
    else:
        auto = np.clip(np.asarray(k_unresolved, dtype=float).reshape(p, 2), k, CAP * k)
    en = np.full(p, float(eps_n)) if eps_n > 0 else auto[:, 0]
    et = np.full(p, float(eps_t)) if eps_t > 0 else auto[:, 1]
    return en, et


def path(factor: float) -> tuple:
    """The ε-path of :func:`workflow.engine.cascade.along_eps_path` for penalties
    up to ``factor`` × the reference stiffness: half decades from
    :data:`START_FACTOR` up to (not including) the target, as fractions of
    it; empty for a penalty within half a decade of the start level. Half decades:
    on the quick sector's tied resonance, decade steps lost Newton at
    ε·10⁻¹ → ε, half decades converged in 11–30 iterations each."""
    if factor <= START_FACTOR * 10.0 ** 0.5:
        return ()       # within half a decade of the start: a level below it would add nothing
    n = int(np.ceil(2 * np.log10(factor / START_FACTOR) - 1e-9))
    return tuple(f for f in (START_FACTOR / factor * 10.0 ** (k / 2) for k in range(n)) if f < 1.0 - 1e-12)


def path_of(law, Zr0: np.ndarray) -> tuple:
    """The ε-path of ``law`` (:func:`path`) from its largest ratio ε / static stiffness
    over pairs and directions; ``Zr0`` is the static condensed stiffness."""
    k = reference_stiffness(Zr0)
    return path(float(max(np.max(law.eps_n / k[:, 0]), np.max(law.eps_t / k[:, 1]))))


def scaled(law, factor: float):
    """``law`` with both penalties multiplied by ``factor``."""
    return law.with_penalty(law.eps_n * factor, law.eps_t * factor)


def describe(law) -> str:
    """One log line: the range of the chosen penalties (N/m)."""
    f = lambda a: f"{a.min():.3g}" if np.ptp(a) <= 1e-12 * abs(a.max()) else f"{a.min():.3g}…{a.max():.3g}"  # noqa: E731
    return f"ε_N = {f(law.eps_n)}, ε_T = {f(law.eps_t)} N/m"


# ----------------------------------------------------------------- the ε-limit (issue 47)
#: the factors (× the law's ε) at which :func:`eps_limit` wants the result: the default
#: and two decades up. On the light-pad chain (workflow/bench/penalty_bias.py, 0.95 ω₁,
#: nit = 4(2Nh+1)) A(ε) is a hump, not a 1/ε approach: Nh = 7 gives +0.08, +0.25, +0.44, +0.67,
#: +0.59, +0.32, +0.02, −0.79 % at × 0.3, 0.5, 1, 3, 10, 30, 100, 1000 against the rigid-ground
#: integration, so one × 10 step (0.15 %) straddles the hump and under-reports the default's
#: +0.44 %; the spread over two decades (0.42 %) does not — at Nh ≤ 11. At Nh ≥ 15 the residual
#: (+0.31, +0.17, +0.11 % at Nh = 15, 23, 31) no longer moves with ε (spread 0.15, 0.02,
#: 0.01 %): it is truncation (the pad's Zr(hω) falls from k_d to 0 at h ≈ 20–32), seen by
#: the Nh-check, not by any ε-check. The ε → ∞ limit is *not* the answer there (−0.8 % at
#: Nh = 7, and nit-dependent: −1.6 % at nit = 16(2Nh+1)): in slip the pad moves at the
#: unresolved harmonics, so a rigid contact does not make them zero.
LIMIT_FACTORS = (1.0, 10.0, 100.0)
#: observed orders p (A ≈ A∞ + c·ε^−p) accepted as the asymptotic range of the sequence
ORDER_BAND = (0.5, 2.0)


def _order(f: np.ndarray, d1: float, d2: float) -> float | None:
    """p with (f3^−p − f2^−p)/(f2^−p − f1^−p) = d2/d1 (bisection on p ∈ [0.05, 8]); None if the
    ratio is not in (0, 1) for any p there (differences of opposite sign, or growing)."""
    q = d2 / d1
    g = lambda p: (f[2] ** -p - f[1] ** -p) / (f[1] ** -p - f[0] ** -p) - q  # noqa: E731
    lo, hi = 0.05, 8.0
    if not (q > 0) or g(lo) * g(hi) > 0:
        return None
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if g(lo) * g(mid) > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def eps_limit(factors, values, *, tol: float = CHECK_TOL, band: tuple = ORDER_BAND) -> dict:
    """The ε → ∞ limit of a scalar result from its values at several penalty factors — pure.

    ``factors`` (k ≥ 2, > 0, × the law's ε; 1 is the default) and ``values`` (same length,
    e.g. the peak amplitude solved at each). Uses the last three factors (two if that is all):

    * ``changes``: relative change between consecutive factors (sorted);
    * ``spread``: max |A(f) − A(f₀)| / |A(f₀)| over all factors, f₀ the smallest — the
      ε-sensitivity over the whole range, the measure to report instead of one step
      (it bounds the bias where one step does not; it is not the convergence measure —
      the Nh-check is);
    * ``order``: observed p of A ≈ A∞ + c·ε^−p from the last three (None if the last two
      differences have opposite signs or do not shrink);
    * ``asymptotic``: True if ``order`` is within ``band``, or the last relative change is
      ≤ ``tol`` and smaller than the one before or the one before is ≤ ``tol`` too
      (converged; a collocated variant, ε-free, is); False otherwise — then the sequence is
      *not* in its asymptotic range and neither the one-step change nor ``limit`` bounds
      the bias; with two values, True only if the change is ≤ ``tol``;
    * ``limit``: Richardson with the observed order (p = 1 if only two values), or the last
      value where converged; None if not ``asymptotic``;
    * ``bias``: (A(f₀) − limit)/|limit| (None without a limit).
    """
    f = np.asarray(factors, dtype=float)
    a = np.asarray(values, dtype=float)
    if f.shape != a.shape or f.size < 2 or np.any(f <= 0) or not np.all(np.isfinite(a)):
        raise ValueError("eps_limit: need ≥ 2 positive factors and as many finite values")
    i = np.argsort(f)
    f, a = f[i], a[i]
    rel = np.abs(np.diff(a)) / np.maximum(np.abs(a[1:]), 1e-300)
    spread = float(np.max(np.abs(a - a[0])) / max(abs(a[0]), 1e-300))
    out = {"factors": f.tolist(), "values": a.tolist(), "changes": rel.tolist(), "spread": spread,
           "order": None, "asymptotic": False, "limit": None, "bias": None}
    if f.size == 2:
        if rel[-1] <= tol:
            out.update(asymptotic=True, limit=float(a[1]))
        else:
            return out
    else:
        ff, aa = f[-3:], a[-3:]
        d1, d2 = aa[1] - aa[0], aa[2] - aa[1]
        converged = rel[-1] <= tol and (abs(d2) < abs(d1) or rel[-2] <= tol)
        p = _order(ff, d1, d2) if d1 != 0 else None
        out["order"] = p
        if converged:
            out.update(asymptotic=True, limit=float(aa[2]))
        elif p is not None and band[0] <= p <= band[1]:
            lim = aa[2] + d2 * ff[2] ** -p / (ff[1] ** -p - ff[2] ** -p)
            out.update(asymptotic=True, limit=float(lim))
        else:
            return out
    out["bias"] = float((a[0] - out["limit"]) / max(abs(out["limit"]), 1e-300))
    return out


def nh_limit(nhs, values, *, order: float = 1.0, tol: float = CHECK_TOL, band: tuple = ORDER_BAND) -> dict:
    """The Nh → ∞ estimate of a scalar result from its values at several Nh — pure; the
    default that converges where the ε-limit does not (issue 47).

    With two values (the variant's own Nh and the Nh-check's :func:`finer` Nh, already solved
    by ``nh_check``): Richardson in 1/Nh with the assumed ``order`` (A ≈ A∞ + c·Nh^−order);
    ``asymptotic`` is None (not verified). With three or more: :func:`eps_limit` with the Nh as
    the factors (observed order, asymptotic check). Keys: as :func:`eps_limit` (``bias``:
    the smallest Nh's relative error against ``limit``).

    Measured on the light-pad chain (rigid-ground integration, 0.875…0.95 ω₁, nit = 4(2Nh+1),
    the Nh-check's pair): max |error| over the band 0.18 / 0.09 / 0.15 % at Nh = 3 / 7 / 11
    against 1.25 / 0.44 / 0.32 % for the plain default (the peak dominates both)."""
    n = np.asarray(nhs, dtype=float)
    a = np.asarray(values, dtype=float)
    if n.size >= 3:
        return eps_limit(n, a, tol=tol, band=band)
    if n.shape != a.shape or n.size != 2 or np.any(n <= 0) or n[0] == n[1] or not np.all(np.isfinite(a)):
        raise ValueError("nh_limit: need two distinct positive Nh (or ≥ 3) and as many finite values")
    i = np.argsort(n)
    n, a = n[i], a[i]
    w = n ** float(order)
    lim = float((w[1] * a[1] - w[0] * a[0]) / (w[1] - w[0]))
    rel = abs(a[1] - a[0]) / max(abs(a[1]), 1e-300)
    return {"factors": n.tolist(), "values": a.tolist(), "changes": [rel], "spread": rel, "order": float(order),
            "asymptotic": None, "limit": lim, "bias": float((a[0] - lim) / max(abs(lim), 1e-300))}
