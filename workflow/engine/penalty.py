"""The DLFT penalties ε_N, ε_T: chosen here, once, for every stage.

Why a large, frequency-independent penalty (measured, DESIGN §3)
-----------------------------------------------------------------
The converged DLFT solution does not depend on ε in stick and separation.
In *slip* with nit > 2Nh+1 it does: the harmonics of the corrected
displacement X above Nh equal −λ/ε (eq. 11) and the stick/slip decisions of
eqs. 13–17 are taken on that polluted path. The ε → ∞ limit is the right
answer. Measured on Den Hartog's oscillator (m = k = F0 = 1, μN/F0 = 0.5,
β = 0.8, nit = 128; first-harmonic amplitude):

=========  ==========  ==========  ==========  =========
ε/k        1           10          100         ≥ 1000
Nh = 1     1.6193      1.8453      2.0400      2.1039 (identical to 7 digits up to 10⁶)
Nh = 7     2.0492      2.1030      2.2127      2.2774 (identical up to 10⁶)
=========  ==========  ==========  ==========  =========

so the penalty is :data:`FACTOR` times a *reference stiffness* of each
pair: the diagonal of the static condensed stiffness ``Re Zr[0]`` (harmonic
0 does not depend on ω, and is positive for any structure held by its
clamp). The previous choice — the mean diagonal of ``Re Zr[1]`` at the band
centre — was ≈ 1× that stiffness on the sector (+0.8 % error at the peak of
a lumped friction-pad model) and collapsed to 1e-300 N/m where k − ω²m
crossed zero inside the band.

Large ε makes Newton's start harder (from the stuck guess, Nh = 7: 158
iterations at 10³, no convergence at 10⁵), not the converged point: the
solver cascade (:mod:`workflow.engine.cascade`) therefore continues in ε
from :data:`START_FACTOR` by decades when a direct solve fails (same case:
16 iterations in all). Every FRF and wear result reports how much it moves
when ε is multiplied by :data:`CHECK_FACTOR` (:mod:`workflow.engine.epscheck`).
"""
from __future__ import annotations

import numpy as np

from workflow.errors import BundleError, SceneError

#: ε = FACTOR × reference stiffness (see the table above).
FACTOR = 1.0e3
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


def choose(Zr0: np.ndarray, eps_n: float = 0.0, eps_t: float = 0.0, factor: float = FACTOR) -> tuple:
    """(ε_N (p,), ε_T (p,)) in N/m: a user's value where given (> 0), else
    ``factor`` × :func:`reference_stiffness` per pair.

    A user value that is negative, zero-but-forced or not finite is a
    :class:`SceneError` naming ``contact.eps_n`` / ``contact.eps_t``.
    """
    for key, v in (("contact.eps_n", eps_n), ("contact.eps_t", eps_t), ("contact.penalty_factor", factor)):
        if not np.isfinite(v) or v < 0:
            raise SceneError(f"{key} = {v!r}: must be a finite number ≥ 0")
    if factor <= 0:
        raise SceneError("contact.penalty_factor must be > 0")
    p = np.asarray(Zr0).shape[-1] // 3
    k = None if (eps_n > 0 and eps_t > 0) else reference_stiffness(Zr0)
    en = np.full(p, float(eps_n)) if eps_n > 0 else factor * k[:, 0]
    et = np.full(p, float(eps_t)) if eps_t > 0 else factor * k[:, 1]
    return en, et


def contact_law(model, contact, Zr0: np.ndarray, *, mu=None):
    """The :class:`~workflow.contact.ContactLaw` of a scene's ``[contact]`` section on ``model``.

    ``contact`` has ``mu``, ``eps_n``, ``eps_t``, ``gap`` and
    ``penalty_factor`` (the scene section, or any object with them);
    ``Zr0`` is the static condensed stiffness (3p, 3p) of the model.
    ``mu`` (p,) overrides the section's μ (e.g. a bundle's own values).
    """
    from workflow.contact import ContactLaw

    en, et = choose(Zr0, contact.eps_n, contact.eps_t, getattr(contact, "penalty_factor", FACTOR))
    p = model.n_pairs
    mu = np.full(p, float(contact.mu)) if mu is None else mu
    return ContactLaw(mu=mu, eps_n=en, eps_t=et, gap=np.asarray(model.gap, dtype=float) + float(contact.gap))


def path(factor: float, user_given: bool = False) -> tuple:
    """The ε-path of :func:`workflow.engine.cascade.along_eps_path` for penalties
    ``factor`` × the reference stiffness: half decades from
    :data:`START_FACTOR` up to (not including) the target, as fractions of
    it; empty for a user's own ε (nothing to continue from). Half decades:
    on the quick sector's tied resonance, decade steps lost Newton at
    ε·10⁻¹ → ε, half decades converged in 11–30 iterations each."""
    if user_given or factor <= START_FACTOR:
        return ()
    n = int(np.ceil(2 * np.log10(factor / START_FACTOR) - 1e-9))
    return tuple(f for f in (START_FACTOR / factor * 10.0 ** (k / 2) for k in range(n)) if f < 1.0 - 1e-12)


def scaled(law, factor: float):
    """``law`` with both penalties multiplied by ``factor``."""
    return law.with_penalty(law.eps_n * factor, law.eps_t * factor)


def describe(law) -> str:
    """One log line: the range of the chosen penalties (N/m)."""
    f = lambda a: f"{a.min():.3g}" if np.ptp(a) <= 1e-12 * abs(a.max()) else f"{a.min():.3g}…{a.max():.3g}"  # noqa: E731
    return f"ε_N = {f(law.eps_n)}, ε_T = {f(law.eps_t)} N/m"
