"""The static contact state the modes start from, the slip onset and the linear (tied, sliding) limits."""
from __future__ import annotations

import numpy as np
import scipy.linalg

from workflow.engine.contact import SEPARATION, ContactLaw
from workflow.engine.studies.nlmodes.structure import _Structure


def _static(st: _Structure, law: ContactLaw, max_passes: int):
    """The static contact state (relative DOFs) and the static η of the kept mode."""
    from workflow.engine.condense import condense
    from workflow.engine.studies.study import static_state

    c = condense(st.rc, 0.0, 0)
    s = static_state(c.Zr, c.Fr, law, max_passes=max_passes)
    u0 = s.u.reshape(st.nr)
    na = st.na
    K = st.Kt
    # interior (η_S, η_R) from K_ηη η = f_η − K_ηu u
    eta = np.linalg.solve(K[st.nr:, st.nr:], st.f0t[st.nr:] - K[st.nr:, :st.nr] @ u0)
    x0 = np.concatenate([u0, eta[:1]])
    F0 = st.f0t[:na] - (K[:na, na:] @ np.linalg.solve(K[na:, na:], st.f0t[na:]) if st.m > na else 0.0)
    return s, x0, F0


def _onset(st: _Structure, law: ContactLaw, static) -> float:
    """Modal amplitude at which the first pair would slip (or open) in the tied mode: the
    tied mode's contact force amplitudes per unit a (tangential ‖λ̂_T‖, normal |λ̂_N|) against
    each pair's cone, ``‖λ̂_T‖ a = μ (|λ_N0| − |λ̂_N| a)`` — the oscillation's force range
    fits the cone's radius (elastic shakedown: a pair that slips statically, on the cone,
    settles inside it under a small oscillation and dissipates nothing) — or the normal
    force's ``|λ̂_N| a = |λ_N0|`` (lift-off), whichever comes first. An estimate of where
    the backbone leaves the linear tied mode, for its default range."""
    D, _, _ = st.dynamic(1, st.omega_tied, st.xi_tied)
    r = st.nr
    lam1 = -(D[:r, r:] @ np.concatenate([[1.0], np.zeros(st.m - r - 1)]))     # per unit η
    lam1 = lam1.reshape(-1, 3)
    lam0 = static.lam
    mu = law.mu
    contact = static.state != SEPARATION
    if not contact.any():
        return float("nan")
    margin = mu * np.abs(lam0[:, 0])
    rate = np.linalg.norm(np.abs(lam1[:, 1:]), axis=1) + mu * np.abs(lam1[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        a_slip = np.where(rate > 0, np.maximum(margin, 0.0) / rate, np.inf)
        a_open = np.where(np.abs(lam1[:, 0]) > 0, np.abs(lam0[:, 0]) / np.abs(lam1[:, 0]), np.inf)
    a = np.minimum(a_slip, a_open)[contact]
    return float(np.min(a)) if np.isfinite(a).any() else float("nan")


def linear_limits(model, law: ContactLaw | None = None, *, mode: int = 0, static=None) -> dict:
    """The linear limits of the tied mode ``mode``: {"tied_hz", "tied_damping_ratio" (from the
    complex eigenvalues of M, K, C with the pairs in static contact tied: D = −Re λ/|λ|,
    frequency |λ|/2π — the EPMC's own small-amplitude limit, exact for modal damping),
    "sliding_hz", "sliding_damping_ratio" (μ = 0: the pairs in contact keep u_N, their
    tangential DOFs free; the mode of largest mass-weighted MAC with the tied one)}.
    Without ``law``/``static`` every pair counts as in contact."""
    st = _Structure(model, mode)
    rc, r = st.rc, st.nr
    K, M, C = (np.asarray(getattr(rc, k), float) for k in ("K", "M", "C"))
    state = np.ones(r // 3, int) if static is None else np.asarray(static.state)
    contact = state != SEPARATION
    tied_fixed = np.repeat(contact, 3)
    slide_fixed = np.zeros(r, bool)
    slide_fixed[0::3] = contact
    phi_t = np.zeros(K.shape[0])
    phi_t[r:] = st.psi_y

    def modes(fixed):
        keep = np.concatenate([~fixed, np.ones(K.shape[0] - r, bool)])
        k, m, c = K[np.ix_(keep, keep)], M[np.ix_(keep, keep)], C[np.ix_(keep, keep)]
        n = k.shape[0]
        # first-order form: [[0, I], [−M⁻¹… ]] via the generalised problem A y = λ B y
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-k, -c]])
        B = np.block([[np.eye(n), np.zeros((n, n))], [np.zeros((n, n)), m]])
        lam, vec = scipy.linalg.eig(A, B)
        ok = np.isfinite(lam) & (lam.imag > 0)
        if not ok.any():        # nothing oscillates: the structure slides as a rigid body (a floating blade)
            return 0.0, float("nan")
        lam, vec = lam[ok], vec[:n, ok]
        full = np.zeros((K.shape[0], vec.shape[1]), complex)
        full[keep] = vec
        num = np.abs(phi_t @ M @ full) ** 2
        den = np.real(np.einsum("ik,ij,jk->k", full.conj(), M, full))
        mac = num / np.where(den > 0, den, np.inf)
        i = int(np.argmax(mac))
        w = abs(lam[i])
        return w / (2 * np.pi), float(-lam[i].real / w)

    f_t, d_t = modes(tied_fixed)
    f_s, d_s = modes(slide_fixed)
    return {"tied_hz": float(f_t), "tied_damping_ratio": d_t, "sliding_hz": float(f_s), "sliding_damping_ratio": d_s}
