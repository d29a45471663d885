"""Friction-damped nonlinear modes (EPMC) and single-nonlinear-mode synthesis (issue #49).

Extended periodic motion concept (Krack 2015, J. Sound Vib. 343, 'Nonlinear modal analysis
of nonconservative systems: extension of the periodic motion concept'): the autonomous system

    M q̈ + (C − ξ M) q̇ + K q + Bᵀ λ(B q) = f_static

(the static preload stays, the harmonic load is removed) has, for every modal amplitude a,
a periodic motion of frequency ω whose dissipation — structural (C) and friction (λ) — is
exactly compensated by the artificial negative mass-proportional damping ξ M. The mode's
damping ratio is D = ξ / (2ω). Unknowns: the harmonics 0…Nh of the motion, ω and ξ;
two more equations: the amplitude ``a² = q̂₁ᴴ M q̂₁`` (Krack's mass-weighted first-harmonic
norm) and a phase condition.

Formulation (why, measured on the quick sector, m = 110, 16 pairs, Nh = 7):

* **Not the condensed relative DOFs alone.** At small amplitude every pair sticks and the
  relative harmonics U_r vanish: the motion is the tied structure's, at the pole of Z_r(ω).
  A residual on U_r alone (as :class:`~workflow.engine.hb.HBProblem`) has no amplitude there.
* **Not the full q either**: (2Nh+1)·m = 1650 unknowns, a dense LU of ~0.3 s per Newton step.
* **U_r plus one tied modal coordinate η.** With ``z = [u_r; y]`` the relative coordinates of
  :mod:`reduction.condense` and ``y = Φ η`` the tied structure's modes (``M_yy``-normalised,
  the one of ``mode`` first), the unknowns are, per harmonic, the 3p relative DOFs and η of
  the chosen tied mode; every other tied mode is condensed out exactly (Schur complement,
  one LU of a (m − 3p − 1) block per harmonic, recomputed for each (ω, ξ) with its
  ω- and ξ-derivatives). (2Nh+1)(3p+1) + 2 = 737 unknowns on the quick sector: a dense LU
  of ~10 ms. η carries the amplitude at the tied limit and the phase condition
  (sine coefficient of η's first harmonic = 0), and the other modes stay regular near ω.
* **The DLFT** is the engine's (:func:`workflow.engine.contact.dlft`, the periodic passes and
  their exact Jacobian, HBM Galerkin projection Q), on the predictor
  ``a = F − Z x + ε (u_r + gap)`` of the contact rows, with the static state's stick anchor
  (:func:`workflow.engine.studies.study.static_state`), exactly as the forced HB.
* **Continuation** in log a, natural parameter (the backbone is single-valued in a), a secant
  predictor on (harmonics / a, ω, ξ), steps halved where Newton fails.

Energies per cycle (J): ``energy_xi_J`` the work the negative damping ξM feeds in,
``ξ π ω Σ_j j² q̂_jᴴ M q̂_j``; ``energy_structural_J`` dissipated by C,
``π ω Σ_j j² q̂_jᴴ C q̂_j``; ``energy_friction_J`` dissipated by friction along the DLFT slip
path (:func:`workflow.engine.dissipation.energy_per_cycle`); ``energy_per_cycle_J`` = structural
+ friction (equal to ``energy_xi_J`` at a root: the Galerkin energy balance, up to the DLFT
slip path's difference from the truncated harmonics).

Single-nonlinear-mode synthesis (Krack, Panning-von Scheidt, Wallaschek 2014, J. Sound Vib.
332, 'A method for nonlinear modal analysis and synthesis'): near the mode's resonance the
forced response is ``q̂₁ ≈ a ψ(a)`` with ψ the mass-normalised first-harmonic deflection and

    [−Ω² + 2iΩ D(a) ω(a) + ω(a)²] a = ψ(a)ᴴ f,

solved here for every backbone amplitude (the FRF as a curve in a, both branches), the peak
where the two branches meet (``Ω = ω √(1 − 2D²)``, ``|ψᴴ f| = 2Dω² √(1 − D²) a``).

Units SI; the modal amplitude a in m·√kg (``q̂₁ᴴ M q̂₁``).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from workflow.engine import fourier
from workflow.engine.contact import SEPARATION, STICK, ContactLaw, dlft
from workflow.engine.dissipation import energy_per_cycle
from workflow.engine.errors import SceneError, SolverError
from workflow.engine.linsolve import zb_apply
from workflow.engine.solvers import newton

__all__ = ["Backbone", "Synthesis", "backbone", "synthesize", "linear_limits"]

#: Newton's tolerance on the scaled residual (dimensionless: forces over the point's inertia
#: force ω² a ‖Mφ‖, the static rows over ‖F_0‖, the normalisation rows over a²)
TOL = 1e-9
#: shortest continuation step tried after a failure, relative to the longest
MIN_SHORT = 1.0 / 16
#: then longer steps, in units of the longest, before the backbone stops
JUMPS = (0.125, 0.25, 0.5, 1.0)
#: default range of the backbone in units of the first slip onset (:func:`_onset`)
DEFAULT_RANGE = (0.1, 3000.0)
#: default number of backbone points (log-spaced over the range)
DEFAULT_POINTS = 41


# ---------------------------------------------------------------- the linear part
class _Structure:
    """The model in coordinates ``w = [u_r; η_S; η_R]``: ``z = T w`` with
    ``T = blockdiag(I, [ψ_S, Φ_R])``, ψ_S the tied mode ``mode`` (M-normalised), Φ_R the
    other tied modes. Kt, Mt, Ct, f0t, Ot: the matrices in w; na = 3p + 1 kept unknowns."""

    def __init__(self, model, mode: int):
        from reduction.condense import RelativeCoordinates, relative_coordinates

        rc = relative_coordinates(model)
        if not isinstance(rc, RelativeCoordinates):
            raise SceneError("nonlinear modes: cyclic (travelling-wave) models are not supported")
        self.rc = rc
        r = rc.n_rel
        K, M, C = (np.asarray(getattr(rc, k), dtype=float) for k in ("K", "M", "C"))
        Kyy, Myy = K[r:, r:], M[r:, r:]
        try:
            # K_yy (the tied structure) is positive definite; M_yy may have massless DOFs
            mu, phi = scipy.linalg.eigh(Myy, Kyy)
        except np.linalg.LinAlgError:
            raise SceneError("nonlinear modes: the structure with the interface tied is not positive "
                             "definite (K_yy): it has no tied modes") from None
        order = np.argsort(-mu)                       # descending μ = 1/ω²: ascending ω
        mu, phi = mu[order], phi[:, order]
        pos = np.flatnonzero(mu > 1e-14 * max(mu.max(), 1e-300))
        if not 0 <= mode < len(pos):
            raise SceneError(f"nonlinear modes: mode = {mode} but the tied structure has {len(pos)} modes")
        s = pos[mode]
        psi = phi[:, s] / np.sqrt(mu[s])              # ψᵀ M_yy ψ = 1, ψᵀ K_yy ψ = ω²
        rest = np.delete(np.arange(phi.shape[1]), s)
        ny = Kyy.shape[0]
        T = np.zeros((r + ny, r + ny))
        T[:r, :r] = np.eye(r)
        T[r:, r] = psi
        T[r:, r + 1:] = phi[:, rest]
        self.T = T
        self.Kt, self.Mt, self.Ct = T.T @ K @ T, T.T @ M @ T, T.T @ C @ T
        self.f0t = T.T @ np.asarray(rc.f_static, dtype=float)
        self.f1t = T.T @ np.asarray(rc.f_harmonic)
        self.Ot = rc.O @ T
        self.nr, self.na, self.m = r, r + 1, r + ny
        self.mode = int(mode)
        self.omega_tied = float(1.0 / np.sqrt(mu[s]))
        self.xi_tied = float(psi @ C[r:, r:] @ psi)               # 2 ζ ω of the tied mode (1/s)
        self.mass_force = float(np.linalg.norm(M[:, r:] @ psi))   # ‖M φ‖ in z (√kg)
        self.psi_y = psi

    def dynamic(self, j: int, omega: float, xi: float):
        """D_j, ∂D_j/∂ω, ∂D_j/∂ξ (complex m × m) of ``K − w²M + i w (C − ξM)``, w = jω."""
        w = j * omega
        D = self.Kt - w * w * self.Mt + 1j * w * (self.Ct - xi * self.Mt)
        dw = -2.0 * j * w * self.Mt + 1j * j * (self.Ct - xi * self.Mt)
        dx = -1j * w * self.Mt
        return D, dw, dx


@dataclass
class _Cond:
    """The augmented condensation at (ω, ξ): Z (Nh+1, na, na) and its ω-, ξ-derivatives;
    A (Nh+1, nR, na) = D_RR⁻¹ D_Ra (the condensed modes follow ``η_R = −A x_a``), D's
    derivatives kept for harmonic 1 (the normalisation's)."""

    omega: float
    xi: float
    Z: np.ndarray
    dZw: np.ndarray
    dZx: np.ndarray
    A: np.ndarray
    D1: tuple


def _condense(st: _Structure, omega: float, xi: float, nh: int) -> _Cond:
    na, m = st.na, st.m
    Z = np.empty((nh + 1, na, na), complex)
    dZw, dZx = np.empty_like(Z), np.empty_like(Z)
    A = np.empty((nh + 1, m - na, na), complex)
    D1 = None
    for j in range(nh + 1):
        D, dw, dx = st.dynamic(j, omega, xi)
        if j == 1:
            D1 = (D, dw, dx)
        if m > na:
            lu = scipy.linalg.lu_factor(D[na:, na:], check_finite=False)
            Aj = scipy.linalg.lu_solve(lu, D[na:, :na], check_finite=False)
            Lj = scipy.linalg.lu_solve(lu, D[:na, na:].T, trans=1, check_finite=False).T   # D_aR D_RR⁻¹
        else:       # nothing to condense (one interior DOF: the kept mode)
            Aj, Lj = np.zeros((0, na), complex), np.zeros((na, 0), complex)
        A[j] = Aj
        Z[j] = D[:na, :na] - D[:na, na:] @ Aj
        for dD, out in ((dw, dZw), (dx, dZx)):
            out[j] = dD[:na, :na] - dD[:na, na:] @ Aj - Lj @ dD[na:, :na] + Lj @ (dD[na:, na:] @ Aj)
    Z[0] = Z[0].real
    dZw[0] = dZx[0] = 0.0
    return _Cond(omega, xi, Z, dZw, dZx, A, D1)


# ---------------------------------------------------------------- the EPMC residual
class _EPMC:
    """Residual and Jacobian of the EPMC at modal amplitude ``a`` (set by :meth:`at`).

    Unknowns v = [X (nc, na) real coefficients, ω, ξ]; residual rows (scaled, dimensionless):
    the HB equations (nc, na) ``Z X − F + [Λ; 0]``, then ``q̂₁ᴴ M q̂₁ / a² − 1`` and the phase
    ``X[1s, η] / a``."""

    def __init__(self, st: _Structure, law: ContactLaw, nh: int, nit: int, anchor, F0, max_passes: int):
        self.st, self.law, self.nh, self.nit = st, law, int(nh), int(nit)
        self.nc = fourier.n_coef(nh)
        self.nr, self.na, self.p = st.nr, st.na, law.p
        self.nx = self.nc * self.na
        self.n = self.nx + 2
        self.E = fourier.time_from_coef_matrix(nh, nit)
        self.Q = fourier.coef_from_time_matrix(nh, nit)
        self.anchor = np.asarray(anchor, float).reshape(self.p, 2)
        self.eps = law.eps().reshape(self.nr)
        self.shift = law.offset().reshape(self.nr)
        self.F = np.zeros((self.nc, self.na))
        self.F[0] = F0
        self.max_passes = int(max_passes)
        self.static_scale = max(float(np.linalg.norm(F0)), 1e-300)
        self._cond = None
        self.a = 1.0
        self.omega_ref = st.omega_tied

    def at(self, a: float):
        """Amplitude a and the row weights of a."""
        self.a = float(a)
        return self.weights(a)

    def weights(self, a: float):
        """Row scaling: the static rows by ‖F_0‖, the dynamic ones by the inertia force of the
        tied mode at amplitude a, ω² a ‖Mφ‖ (the η rows by ω² a)."""
        dyn = self.omega_ref ** 2 * float(a) * self.st.mass_force
        w = np.full((self.nc, self.na), 1.0 / dyn)
        w[0, :] = 1.0 / self.static_scale
        w[:, self.nr] *= self.st.mass_force            # the η rows are modal forces (N/√kg)
        self.w = w.ravel()
        return self

    def cond(self, omega, xi) -> _Cond:
        c = self._cond
        if c is None or c.omega != omega or c.xi != xi:
            c = self._cond = _condense(self.st, omega, xi, self.nh)
        return c

    def split(self, v):
        return v[:self.nx].reshape(self.nc, self.na), float(v[self.nx]), float(v[self.nx + 1])

    def contact(self, X, L, jacobian: bool):
        nr = self.nr
        pred = self.F[:, :nr] - L[:, :nr] + self.eps * X[:, :nr]
        pred[0] += self.eps * self.shift
        lam_u = (self.E @ pred).reshape(self.nit, self.p, 3)
        return dlft(self.law, lam_u, self.anchor, basis=self.E, jacobian=jacobian, max_passes=self.max_passes,
                    tol=1e-10, rows=self.Q if jacobian else None)

    def first_harmonic(self, X, c: _Cond):
        """w₁ = [x_a; −A₁ x_a] (m,) complex: the full first harmonic in w coordinates."""
        xa = X[1] - 1j * X[2]
        return np.concatenate([xa, -c.A[1] @ xa])

    def evaluate(self, v, jacobian: bool = True):
        X, omega, xi = self.split(v)
        c = self.cond(omega, xi)
        nr, nc, na, nx = self.nr, self.nc, self.na, self.nx
        L = zb_apply(c.Z, X)
        res = self.contact(X, L, jacobian)
        Lam = fourier.complex_to_real(fourier.to_freq(res.lam.reshape(self.nit, nr), self.nh))
        R = L - self.F
        R[:, :nr] += Lam
        w1 = self.first_harmonic(X, c)
        Mw = self.st.Mt @ w1
        a2 = self.a ** 2
        g = float(np.real(np.vdot(w1, Mw))) / a2 - 1.0
        ph = X[2, nr] / self.a
        Rs = np.concatenate([R.ravel() * self.w, [g, ph]])
        if not jacobian:
            return Rs, None, res
        J = np.zeros((self.n, self.n))
        Zb = fourier.real_block_diag(c.Z)
        J[:nx, :nx] = Zb
        # contact rows: G (∂a/∂X), ∂a/∂X = ε[I 0] − Zb[contact rows]
        G = np.ascontiguousarray(res.dlam.transpose(1, 0, 2, 3)).reshape(self.p, 3 * nc, 3 * nc)
        Pa = -Zb.reshape(nc, na, nx)[:, :nr, :].copy()
        idx = np.arange(nc)[:, None] * na + np.arange(nr)[None, :]
        Pa.reshape(nc * nr, nx)[np.arange(nc * nr), idx.ravel()] += np.tile(self.eps, nc)
        dw = zb_apply(c.dZw, X)
        dx = zb_apply(c.dZx, X)
        cols = np.concatenate([Pa.reshape(nc, nr, nx), -dw[:, :nr, None], -dx[:, :nr, None]], axis=2)
        J[:nx, nx] = dw.ravel()
        J[:nx, nx + 1] = dx.ravel()
        k = cols.shape[2]
        Vp = cols.reshape(nc, self.p, 3, k).transpose(1, 0, 2, 3).reshape(self.p, 3 * nc, k)
        Gc = np.matmul(G, Vp).reshape(self.p, nc, 3, k).transpose(1, 0, 2, 3).reshape(nc, nr, k)
        Jv = J[:nx].reshape(nc, na, self.n)
        Jv[:, :nr, :] += Gc
        J[:nx] *= self.w[:, None]
        # normalisation: ∂(w₁ᴴ M w₁)/∂X₁c = 2 Re(H x), ∂/∂X₁s = −2 Im(H x), H = Y₁ᴴ M Y₁
        Hx = Mw[:na] - c.A[1].conj().T @ Mw[na:]
        J[nx, na:2 * na] = 2.0 * Hx.real / a2
        J[nx, 2 * na:3 * na] = -2.0 * Hx.imag / a2
        D1, dD1w, dD1x = c.D1
        for col, dD in ((nx, dD1w), (nx + 1, dD1x)):
            if self.st.m > na:
                dwR = -np.linalg.solve(D1[na:, na:], dD[na:] @ w1)
                J[nx, col] = 2.0 * float(np.real(np.vdot(Mw[na:], dwR))) / a2
        J[nx + 1, 2 * na + nr] = 1.0 / self.a
        return Rs, J, res

    # ---------------------------------------------------------------- post-processing
    def harmonics_w(self, X, c: _Cond) -> np.ndarray:
        """Harmonics (Nh+1, m) of the motion in w coordinates (the condensed modes recovered)."""
        Xa = fourier.real_to_complex(X)                      # (Nh+1, na)
        out = np.empty((self.nh + 1, self.st.m), complex)
        out[:, :self.na] = Xa
        if self.st.m > self.na:
            out[0, self.na:] = -(c.A[0].real @ X[0]) + np.linalg.solve(
                self.st.Kt[self.na:, self.na:], self.st.f0t[self.na:])
        out[1:, self.na:] = -np.einsum("jrn,jn->jr", c.A[1:], Xa[1:])
        return out


# ---------------------------------------------------------------- results
@dataclass
class Backbone:
    """The EPMC backbone of one friction-damped mode (arrays over the points, SI).

    amplitude           modal amplitude a = √(q̂₁ᴴ M q̂₁) (m·√kg)
    frequency_hz        ω/2π of the periodic motion
    damping_ratio       D = ξ / (2ω)
    xi                  the negative mass-proportional damping ξ (1/s)
    energy_per_cycle_J  dissipated per cycle: structural (C) + friction (DLFT slip path)
    energy_friction_J, energy_structural_J: its two parts; energy_xi_J the work of ξM;
    energy_friction_hb_J the friction work of the truncated harmonics, ``∮ λ·u̇_r dt =
                        −π Σ_j j Im(Λ_jᴴ U_j)`` (the Galerkin energy balance: energy_xi_J =
                        energy_structural_J + energy_friction_hb_J to the solver's tolerance;
                        energy_friction_J, on the DLFT slip path by the trapezoidal rule, differs
                        from it by the rule's error, 1.6e-3 at nit = 64 on the Jenkins oscillator)
    observed            (n, Nh+1, n_obs) complex harmonics of the observed DOFs O q (m)
    Ur                  (n, Nh+1, 3p) complex harmonics of the relative contact DOFs (m)
    z1                  (n, m) complex first harmonic in the relative coordinates of
                        :func:`reduction.condense.relative_coordinates` (z = [u_r; y], q = T z)
    stuck_pairs, separating_pairs, slipping_pairs (n,) pairs stuck all period, open at some
                        instant, slipping at some instant (and never open)
    converged, residual (scaled, dimensionless), iterations (Newton steps), nh, nit
    tied_hz, tied_damping_ratio: the linear tied mode (ω, D of the EPMC's small-amplitude limit)
    sliding_hz          the linear sliding mode (μ = 0, normal contact kept) closest to it (MAC)
    onset               modal amplitude of the first slip estimated from the tied mode
    seconds             wall time of :func:`backbone`; stopped: why it ended before the last
                        amplitude asked for ("" if it did not); walks: it ended because the
                        mode has no periodic motion beyond (the blade walks,
                        :func:`_unbalanced_mean_slip`) — the mode's end, not the solver's
    unknowns            (n, (2Nh+1)(3p+1) + 2) the solver's unknowns [X, ω, ξ] per point
    """

    amplitude: np.ndarray
    frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    xi: np.ndarray
    energy_per_cycle_J: np.ndarray
    energy_friction_J: np.ndarray
    energy_structural_J: np.ndarray
    energy_xi_J: np.ndarray
    energy_friction_hb_J: np.ndarray
    observed: np.ndarray
    Ur: np.ndarray
    z1: np.ndarray
    stuck_pairs: np.ndarray
    separating_pairs: np.ndarray
    slipping_pairs: np.ndarray
    converged: np.ndarray
    residual: np.ndarray
    iterations: np.ndarray
    nh: int
    nit: int
    mode: int
    tied_hz: float
    tied_damping_ratio: float
    sliding_hz: float
    onset: float
    seconds: float = 0.0
    stopped: str = ""
    walks: bool = False
    unknowns: np.ndarray | None = None
    info: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.amplitude)

    def rows(self) -> list[dict]:
        """One dict per point (for a CSV)."""
        obs = np.linalg.norm(self.observed[:, 1, :], axis=1) if len(self) else np.zeros(0)
        return [{"amplitude": float(self.amplitude[i]), "frequency_hz": float(self.frequency_hz[i]),
                 "damping_ratio": float(self.damping_ratio[i]), "xi_per_s": float(self.xi[i]),
                 "energy_per_cycle_J": float(self.energy_per_cycle_J[i]),
                 "energy_friction_J": float(self.energy_friction_J[i]),
                 "energy_structural_J": float(self.energy_structural_J[i]),
                 "energy_xi_J": float(self.energy_xi_J[i]), "observed_first_harmonic_m": float(obs[i]),
                 "stuck_pairs": int(self.stuck_pairs[i]), "slipping_pairs": int(self.slipping_pairs[i]),
                 "separating_pairs": int(self.separating_pairs[i]), "converged": bool(self.converged[i]),
                 "residual": float(self.residual[i]), "iterations": int(self.iterations[i]),
                 "nh": self.nh, "nit": self.nit} for i in range(len(self))]


@dataclass
class Synthesis:
    """Single-nonlinear-mode synthesis of the forced response (SI).

    freqs_hz         the frequencies asked for
    amplitude        (n_freq, k) observed first-harmonic amplitude ‖O q̂₁‖ (m) of each branch at
                     each frequency, ascending, NaN where fewer (k = most branches met)
    peak_hz, peak_amplitude_m, peak_modal_amplitude: the resonance (NaN if the force drives the
                     response beyond the backbone's last point)
    curve_amplitude  (n,) modal amplitudes of the backbone-parametrised FRF, with
    curve_low_hz, curve_high_hz (n,) its two frequencies (NaN where none), curve_observed_m (n,)
    force_norm_N     ‖f‖ of the load used
    """

    freqs_hz: np.ndarray
    amplitude: np.ndarray
    peak_hz: float
    peak_amplitude_m: float
    peak_modal_amplitude: float
    curve_amplitude: np.ndarray
    curve_low_hz: np.ndarray
    curve_high_hz: np.ndarray
    curve_observed_m: np.ndarray
    force_norm_N: float


# ---------------------------------------------------------------- helpers
def _static(st: _Structure, law: ContactLaw, max_passes: int):
    """The static contact state (relative DOFs) and the static η of the kept mode."""
    from reduction.condense import condense
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


def _states(res) -> tuple[int, int, int]:
    s = res.state
    stuck = int(np.sum(np.all(s == STICK, axis=0)))
    sep = int(np.sum(np.any(s == SEPARATION, axis=0)))
    return stuck, sep, int(s.shape[1]) - stuck - sep


# ---------------------------------------------------------------- the backbone
#: How a backbone that ends because the blade walks says so (:attr:`Backbone.walks`).
WALKS = "no periodic motion beyond"
#: :func:`_unbalanced_mean_slip`: a Jacobian direction counts as null below this fraction of
#: the largest singular value (measured on the quick sector where the path ends: 4e-16)
NULL_RATIO = 1e-10
#: ... and the residual as lying in it when this fraction of ‖R‖ does (measured there: 0.95)
NULL_SHARE = 0.5
#: Newton iterations (and backtracks) a step once the blade walks: every converged point of the
#: quick sector's backbone took ≤ 7 iterations (2026-11-29)
WALK_ITERATIONS = 8
#: the SVD behind the diagnosis is dense: done up to this many unknowns
NULL_MAX_UNKNOWNS = 4000


def _unbalanced_mean_slip(prob: "_EPMC", v, a: float) -> str:
    """Why Newton cannot go on at (v, a) [m·√kg], if it is this (else ""): every pair in
    contact slips at some instant of the cycle, so the interface no longer holds the mean
    tangential position — shifting every pair's harmonic-0 tangential displacement alike moves
    its stick anchors with it and changes no force, a null direction of the Jacobian — and the
    residual left lies in the matching mean tangential force, which no unknown then changes:
    the mean friction force cannot balance the static load, and the blade's mean position
    drifts cycle after cycle (walks). Measured on the quick sector at a = 7.47e-4 (1.56 × the
    slip onset, all 8 loaded pairs slipping through part of the cycle): σ_min/σ_max = 4e-16,
    the right singular vector the pairs' mean t₁ displacement, 95 % of ‖R‖ in its left one; at
    Nh = 11, nit = 128 at the same a."""
    if prob.n > NULL_MAX_UNKNOWNS:
        return ""
    prob.a = a
    R, J, _ = prob.evaluate(v)
    U, S, Vt = np.linalg.svd(J)
    rn = float(np.linalg.norm(R))
    if not (rn > 0 and S[-1] <= NULL_RATIO * S[0] and abs(U[:, -1] @ R) >= NULL_SHARE * rn):
        return ""
    # the null direction is a mean (harmonic-0) motion whose contact part is tangential (the
    # structure's own coordinate moves with it where the tied mode carries the shift)
    mean = Vt[-1][:prob.nx].reshape(prob.nc, prob.na)[0]
    pairs = mean[:prob.nr].reshape(prob.p, 3)
    if np.sum(mean ** 2) < 0.9 or np.sum(pairs[:, 1:] ** 2) < 0.9 * np.sum(pairs ** 2):
        return ""
    c = 1 + int(np.argmax(np.sum(pairs[:, 1:] ** 2, axis=0)))
    return (f"every pair in contact slips during the cycle and the interface no longer holds its mean position "
            f"along t{c}; {abs(U[:, -1] @ R) / rn:.0%} of Newton's residual is the mean friction force along it, "
            "which no unknown changes: it cannot balance, and the blade's mean position would drift (walk)")


def backbone(model, law: ContactLaw, *, mode: int = 0, nh: int = 7, nit: int = 64, amplitudes=None,
             onset_range=None, max_passes: int = 30, maxiter: int = 15, tol: float = TOL, max_steps: int = 400,
             log=None) -> Backbone:
    """The EPMC backbone of tied mode ``mode`` (0: the lowest tied mode) of ``model`` under ``law``.

    ``amplitudes``: the range of modal amplitudes a (m·√kg) and the least number of points,
    ``(a_min, a_max, n)``; an increasing array means ``(first, last, len)``; None: from 0.1× to
    3000× the first slip onset of the tied mode (:func:`_onset`) in at least
    ``DEFAULT_POINTS`` — or ``onset_range`` = (from, to, n) in units of that onset. ``nh``, ``nit``: harmonics and DLFT time samples (HBM, nit ≥ 2Nh+1).
    ``log``: a callable taking a message, or None.

    Pseudo-arclength continuation from the tied linear mode at a_min, in the plane of
    (log a, log ω, log ξ) (dimensionless; a secant predictor on the harmonics / a): the points
    are where it stepped, at most ``log(a_max/a_min)/(n − 1)`` apart in that plane, closer where
    Newton needed it; it stops past a_max, after ``max_steps`` steps, or where even short steps
    fail (``stopped`` says why). A blade held only by its contacts has no periodic motion once
    every pair in contact slips during the cycle and the mean friction force cannot balance the
    static load: its mean position drifts (it walks); the path ends there, and ``stopped`` says
    so (:func:`_unbalanced_mean_slip`). On the quick sector that is a = 7.45e-4 m·√kg, 1.56 × the
    slip onset (2026-11-29; at Nh = 7 and at Nh = 11 alike). Raises :class:`SceneError` on bad
    options."""
    t_start = time.perf_counter()
    if not isinstance(law, ContactLaw):
        raise TypeError("law must be a ContactLaw")
    if law.p != model.n_pairs:
        raise SceneError(f"nonlinear modes: the law has {law.p} pairs, the model {model.n_pairs}")
    nh, nit = int(nh), int(nit)
    if nh < 1:
        raise SceneError(f"nonlinear modes: Nh = {nh} must be ≥ 1")
    fourier.check_nit(nit, nh)
    st = _Structure(model, mode)
    static, x0a, F0 = _static(st, law, max_passes)
    prob = _EPMC(st, law, nh, nit, static.anchor, F0, max_passes)
    onset = _onset(st, law, static)
    a_min, a_max, npts = _amplitude_range(amplitudes, onset_range, onset)
    lim = linear_limits(model, law, mode=mode, static=static)
    path = _Path(prob, st)
    out, stopped, steps = path.follow(x0a, a_min, a_max, npts, tol=tol, maxiter=maxiter, max_steps=max_steps,
                                      log=log)
    bb = _backbone_of(prob, st, law, out["a"], out["v"])
    n = len(out["a"])
    return Backbone(**bb, converged=np.ones(n, bool), residual=np.array(out["res"]),
                    iterations=np.array(out["it"], int), nh=nh, nit=nit, mode=st.mode,
                    tied_hz=lim["tied_hz"], tied_damping_ratio=lim["tied_damping_ratio"],
                    sliding_hz=lim["sliding_hz"], onset=onset, seconds=time.perf_counter() - t_start,
                    stopped=stopped, walks=stopped.startswith(WALKS), unknowns=np.array(out["v"]).reshape(n, prob.n),
                    info={"unknowns": prob.n, "tied_hz_undamped": st.omega_tied / (2 * np.pi),
                          "sliding_damping_ratio": lim["sliding_damping_ratio"], "range": (a_min, a_max, npts),
                          "steps": steps})


def _amplitude_range(amplitudes, onset_range, onset: float) -> tuple[float, float, int]:
    """(a_min, a_max, n) of :func:`backbone` from its ``amplitudes`` / ``onset_range`` (m·√kg)."""
    if amplitudes is None:
        if not np.isfinite(onset) or onset <= 0:
            raise SolverError("nonlinear modes: no slip onset of the tied mode (no pair in contact, or none "
                              "loaded by the mode): give the amplitudes")
        lo, hi, npts = onset_range or (*DEFAULT_RANGE, DEFAULT_POINTS)
        a_min, a_max, npts = float(lo) * onset, float(hi) * onset, int(npts)
    elif isinstance(amplitudes, tuple) and len(amplitudes) == 3:
        a_min, a_max, npts = float(amplitudes[0]), float(amplitudes[1]), int(amplitudes[2])
    else:
        arr = np.asarray(amplitudes, dtype=float).ravel()
        if arr.size == 0 or np.any(np.diff(arr) <= 0):
            raise SceneError("nonlinear modes: amplitudes must be increasing")
        a_min, a_max, npts = float(arr[0]), float(arr[-1]), arr.size
    if not (0 < a_min <= a_max and np.isfinite(a_max)):
        raise SceneError(f"nonlinear modes: amplitudes must be positive and increasing (got {a_min:g} … {a_max:g})")
    return a_min, a_max, npts


class _Path:
    """The continuation's unknowns z = [X / a on the scaled rows, ω, ξ, log a] and its
    arclength equation in the plane (log a, log ω, log ξ)."""

    def __init__(self, prob: "_EPMC", st: "_Structure"):
        self.prob, self.st = prob, st
        self.na, self.nx, self.nr = prob.na, prob.nx, prob.nr

    def denorm(self, z):
        a = float(np.exp(z[-1]))
        v = z[:-1].copy()
        v[self.na:self.nx] *= a
        return v, a

    def plane(self, z):
        """(log a, log ω, log ξ) of z and its gradient rows (3, n + 1)."""
        nx = self.nx
        _, w, xi = self.prob.split(z[:-1])
        G = np.zeros((3, z.size))
        G[0, -1] = 1.0
        G[1, nx] = 1.0 / w
        G[2, nx + 1] = 1.0 / xi
        # a Newton trial may step to ξ ≤ 0 (below the structural damping): its NaN row is the
        # line search's signal to shorten the step, not something to warn about
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.array([z[-1], np.log(w), np.log(xi)]), G

    def augmented(self, z, p_prev, t, ds, jac=True):
        """The EPMC residual and the arclength row ``t · (plane(z) − p_prev) = ds``, with their Jacobian."""
        prob, na, nx, nr = self.prob, self.na, self.nx, self.nr
        v, a = self.denorm(z)
        prob.a = a
        R, J, _ = prob.evaluate(v, jacobian=jac)
        pz, G = self.plane(z)
        Ra = np.concatenate([R, [t @ (pz - p_prev) - ds]])
        if not jac:
            return Ra, None
        dv = np.ones(prob.n)
        dv[na:nx] = a
        Ja = np.empty((prob.n + 1, prob.n + 1))
        Ja[:-1, :-1] = J * dv[None, :]
        X, omega, xi = prob.split(v)
        w1 = prob.first_harmonic(X, prob.cond(omega, xi))
        f = float(np.real(np.vdot(w1, self.st.Mt @ w1)))
        vs = np.zeros(prob.n)
        vs[na:nx] = v[na:nx]
        Js = J @ vs
        Js[nx] -= 2.0 * f / a ** 2
        Js[nx + 1] -= X[2, nr] / a
        Ja[:-1, -1] = Js
        Ja[-1] = t @ G
        return Ra, Ja

    def first(self, x0a, a_min: float, tol: float, maxiter: int):
        """The first point: natural parameter at a_min from the tied mode; (z, SolveResult)."""
        prob, st = self.prob, self.st
        X = np.zeros((prob.nc, self.na))
        X[0] = x0a
        X[1, self.nr] = a_min
        v0 = np.concatenate([X.ravel(), [st.omega_tied, st.xi_tied]])
        prob.weights(a_min)
        prob.a = a_min
        r = newton(lambda v: prob.evaluate(v)[:2], v0, fun=lambda v: prob.evaluate(v, False)[0],
                   tol=tol, scale=1.0, maxiter=maxiter)
        if not r.converged:
            raise SolverError(f"nonlinear modes: the first point (a = {a_min:.3g}, the tied mode) did not converge: "
                              f"{r.reason}")
        z = r.x.copy()
        z[self.na:self.nx] /= a_min
        return np.concatenate([z, [np.log(a_min)]]), r

    def follow(self, x0a, a_min, a_max, npts, *, tol, maxiter, max_steps, log):
        """Pseudo-arclength from a_min to past a_max (see :func:`backbone`): ({"a", "v", "res",
        "it"} over the points, why it stopped early or "", steps made)."""
        prob = self.prob
        s_min, s_max = np.log(a_min), np.log(a_max)
        ds_max = (s_max - s_min) / max(npts - 1, 1) if npts > 1 else 1.0
        z0, r = self.first(x0a, a_min, tol, maxiter)
        path = [z0]
        out = {"res": [r.residual_norm], "it": [r.iterations]}
        stopped = ""
        ds = min(ds_max, s_max - s_min) if s_max > s_min else 0.0
        steps = 0
        jumps, jumping = list(JUMPS), False
        # Newton's effort a step; cut once the blade is found to walk: the shorter steps that then
        # locate the mode's end converge in a few iterations or not at all (a failed full-effort
        # solve there spent ~5 s in line searches on the quick sector)
        effort, walk = dict(maxiter=maxiter), ""
        while ds > 0 and path[-1][-1] < s_max - 1e-12:
            steps += 1
            if steps > max_steps:
                stopped = f"{max_steps} continuation steps made (max_steps) before a_max"
                break
            p_prev, _ = self.plane(path[-1])
            if len(path) >= 2:
                d = self.plane(path[-1])[0] - self.plane(path[-2])[0]
                t = d / np.linalg.norm(d)
                zp = path[-1] + (path[-1] - path[-2]) * (ds / np.linalg.norm(d))
            else:
                t = np.array([1.0, 0.0, 0.0])
                zp = path[-1].copy()
                zp[-1] += ds
            prob.weights(float(np.exp(path[-1][-1])))
            r = newton(lambda zz: self.augmented(zz, p_prev, t, ds), zp,
                       fun=lambda zz: self.augmented(zz, p_prev, t, ds, False)[0], tol=tol, scale=1.0,
                       **effort)
            if r.converged:
                jumping = False
                path.append(r.x)
                out["res"].append(r.residual_norm)
                out["it"].append(r.iterations)
                if log is not None:
                    _, a = self.denorm(r.x)
                    _, w, xi = prob.split(r.x[:-1])
                    log(f"a = {a:.4g}: {w / (2 * np.pi):.4f} Hz, D = {xi / (2 * w):.3e}, {r.iterations} iterations")
                ds = min(ds * (1.5 if r.iterations <= 4 else 1.0), ds_max)
                jumps = list(JUMPS)
                continue
            # a failed step: shorter ones down to MIN_SHORT × ds_max, then longer ones (JUMPS × ds_max)
            # unless the blade walks there: a longer step cannot cross the end of the mode
            # once seen, the walking holds for the shorter steps: their cheap solves stop where
            # their own residual says less
            walk = _unbalanced_mean_slip(prob, *self.denorm(r.x)) or walk
            if walk:
                effort = dict(maxiter=min(maxiter, WALK_ITERATIONS), max_backtracks=WALK_ITERATIONS,
                              lm_fallback=False)
            if ds > MIN_SHORT * ds_max and not jumping:
                ds *= 0.5
                continue
            if jumps and not walk:
                jumping = True
                ds = jumps.pop(0) * ds_max
                continue
            stopped = (f"{WALKS} a = {np.exp(path[-1][-1]):.4g}: {walk}" if walk else
                       f"no convergence beyond a = {np.exp(path[-1][-1]):.4g} ({r.reason})")
            break
        out["a"] = [float(np.exp(z[-1])) for z in path]
        out["v"] = [self.denorm(z)[0] for z in path]
        return out, stopped, steps


def _backbone_of(prob: "_EPMC", st: "_Structure", law, amplitudes, unknowns) -> dict:
    """The :class:`Backbone` arrays of the points (a, v): frequency, damping, the energies per
    cycle, the deflections and the contact states."""
    nh, nit, nr = prob.nh, prob.nit, prob.nr
    n = len(amplitudes)
    f_hz, D, xi_ = np.zeros(n), np.zeros(n), np.zeros(n)
    e_f, e_c, e_x, e_h = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    obs = np.zeros((n, nh + 1, st.Ot.shape[0]), complex)
    Ur = np.zeros((n, nh + 1, nr), complex)
    z1 = np.zeros((n, st.m), complex)
    stuck, sep, slip = (np.zeros(n, int) for _ in range(3))
    j = np.arange(nh + 1)
    for i, (a, v) in enumerate(zip(amplitudes, unknowns)):
        prob.at(a)
        X, omega, xi = prob.split(v)
        c = prob.cond(omega, xi)
        _, _, res = prob.evaluate(v, jacobian=False)
        W = prob.harmonics_w(X, c)
        f_hz[i], xi_[i], D[i] = omega / (2 * np.pi), xi, xi / (2 * omega)
        e_f[i] = float(energy_per_cycle(res.lam[..., 1:], res.lam_x_T / law.eps_t[None, :, None]).sum())
        mq = np.real(np.einsum("jm,mn,jn->j", W.conj(), st.Mt, W))
        cq = np.real(np.einsum("jm,mn,jn->j", W.conj(), st.Ct, W))
        e_c[i] = np.pi * omega * float(np.sum(j ** 2 * cq))
        e_x[i] = xi * np.pi * omega * float(np.sum(j ** 2 * mq))
        Lh = fourier.to_freq(res.lam.reshape(nit, nr), nh)
        e_h[i] = -np.pi * float(np.sum(j * np.imag(np.sum(Lh.conj() * W[:, :nr], axis=1))))
        obs[i] = W @ st.Ot.T
        Ur[i] = W[:, :nr]
        z1[i] = st.T @ W[1]
        stuck[i], sep[i], slip[i] = _states(res)
    return dict(amplitude=np.array(amplitudes), frequency_hz=f_hz, damping_ratio=D, xi=xi_,
                energy_per_cycle_J=e_f + e_c, energy_friction_J=e_f, energy_structural_J=e_c, energy_xi_J=e_x,
                energy_friction_hb_J=e_h, observed=obs, Ur=Ur, z1=z1, stuck_pairs=stuck, separating_pairs=sep,
                slipping_pairs=slip)


# ---------------------------------------------------------------- synthesis
def _curve(p, W, DC, DF, g, aa):
    """The synthesised FRF as a curve in the modal amplitude: the two Ω (Hz) of |L(Ω)| = g/a at
    each sample where the branches exist (``p`` = min_Ω |L| a − g ≤ 0), NaN elsewhere."""
    lo, hi = np.full(W.size, np.nan), np.full(W.size, np.nan)
    for i in np.flatnonzero(p <= 0):
        # |L|² − (g/a)² as a quartic in Ω
        c4 = [1.0, 0.0, 4 * W[i] ** 2 * DC[i] ** 2 - 2 * W[i] ** 2, 8 * W[i] ** 3 * DC[i] * DF[i],
              W[i] ** 4 + 4 * W[i] ** 4 * DF[i] ** 2 - (g[i] / aa[i]) ** 2]
        r = np.roots(c4)
        r = np.sort(r[(np.abs(r.imag) <= 1e-9 * W[i]) & (r.real > 0)].real)
        if r.size:
            lo[i], hi[i] = r[0] / (2 * np.pi), r[-1] / (2 * np.pi)
    return lo, hi


def _at_frequencies(freqs, tt, W, DC, DF, aa, g, at) -> np.ndarray:
    """(n_freq, k) observed amplitudes (m) where |L(Ω)| a = g along the backbone samples ``tt``
    (linear interpolation between the samples that bracket it), ascending, NaN-padded."""
    if not freqs.size:
        return np.zeros((0, 1))
    rows = []
    for F in freqs:
        Omg = 2 * np.pi * F
        h = np.abs(W ** 2 - Omg ** 2 + 1j * (2 * Omg * W * DC + 2 * W ** 2 * DF)) * aa - g
        cross = np.flatnonzero(np.sign(h[:-1]) * np.sign(h[1:]) < 0)
        vals = []
        for k in cross:
            x = tt[k] + h[k] / (h[k] - h[k + 1]) * (tt[k + 1] - tt[k])
            a_, *_, o_ = at(x)
            vals.append(float(o_[0] * a_[0]))
        rows.append(sorted(vals))
    out = np.full((freqs.size, max([len(r) for r in rows] + [1])), np.nan)
    for i, r in enumerate(rows):
        out[i, :len(r)] = r
    return out


def _min_over_frequency(W, Dc, Df):
    """(min_Ω |L|, argmin Ω) of ``L = ω² − Ω² + i(2ΩωD_c + 2ω²D_f)`` per sample: Newton on
    ∂|L|²/∂Ω = 4Ω³ + 2Ω(4ω²D_c² − 2ω²) + 8ω³D_cD_f from Ω = ω√(1 − 2D_c²) (the root for
    D_f = 0, the peak of the viscous form)."""
    Om = W * np.sqrt(np.maximum(1 - 2 * Dc ** 2, 1e-12))
    for _ in range(30):
        g = 4 * Om ** 3 + 2 * Om * (4 * W ** 2 * Dc ** 2 - 2 * W ** 2) + 8 * W ** 3 * Dc * Df
        h = 12 * Om ** 2 + 2 * (4 * W ** 2 * Dc ** 2 - 2 * W ** 2)
        step = g / np.where(h > 0, h, np.inf)
        Om = Om - step
        if np.all(np.abs(step) <= 1e-14 * W):
            break
    L = np.abs(W ** 2 - Om ** 2 + 1j * (2 * Om * W * Dc + 2 * W ** 2 * Df))
    return L, Om


def synthesize(bb: Backbone, model, force_scale: float = 1.0, freqs_hz=None, *, damping: str = "viscous",
               samples: int = 4000) -> Synthesis:
    """Single-nonlinear-mode synthesis of the forced response to ``force_scale × f_harmonic``
    (the model's cos ωt load) from the backbone ``bb`` of ``model``.

    Along the backbone (interpolated over its points, monotone cubic, ``samples`` points — a
    backbone that turns back in a is followed as it is) the modal equation
    ``|L(Ω)| a = |ψᴴ f|`` gives 0 or 2 frequencies per amplitude (the FRF's two branches); at
    each of ``freqs_hz`` the amplitudes where it holds (one, or three where the FRF folds).
    The observed amplitude is ``a ‖O ψ(a)‖``. The peak: the first amplitude (from small a)
    where the branches meet, ``min_Ω |L| a = |ψᴴ f|``; NaN if they never do on the backbone.

    ``damping``: "viscous" — Krack et al. (2014), ``L = −Ω² + 2iΩDω + ω²``: all the
    dissipation as a viscous term, peak at ``Ω = ω√(1 − 2D²)``; "split" — the structural part
    (``energy_structural_J``) viscous and the friction part rate-independent (hysteretic,
    ``2iD_f ω²``), as the Jenkins element's is: ``L = ω² − Ω² + i(2ΩωD_c + 2ω²D_f)``. The two
    differ by O(D²) in the peak frequency: 1e-5 on the quick sector (D < 0.6 %), 3 % at the
    Jenkins oscillator's D = 0.17."""
    from reduction.condense import relative_coordinates
    from scipy.interpolate import PchipInterpolator
    from scipy.optimize import brentq

    if len(bb) < 2:
        raise SceneError("synthesis: the backbone has fewer than 2 points")
    if damping not in ("viscous", "split"):
        raise SceneError(f"synthesis: damping {damping!r} is not one of viscous, split")
    rc = relative_coordinates(model)
    f = float(force_scale) * np.asarray(rc.f_harmonic)
    a = bb.amplitude
    w = 2 * np.pi * bb.frequency_hz
    share = np.zeros(len(bb)) if damping == "viscous" else \
        bb.energy_friction_hb_J / np.maximum(bb.energy_xi_J, 1e-300)
    Dc, Df = bb.damping_ratio * (1 - share), bb.damping_ratio * share
    modal_force = np.abs(bb.z1.conj() @ f) / a                 # |ψᴴ f| (N/√kg)
    obs_per_a = np.linalg.norm(bb.observed[:, 1, :], axis=1) / a
    t = np.arange(len(bb), dtype=float)
    interp = {k: PchipInterpolator(t, v) for k, v in (("s", np.log(a)), ("w", w), ("Dc", Dc), ("Df", Df),
                                                         ("g", modal_force), ("o", obs_per_a))}
    tt = np.linspace(0.0, t[-1], max(int(samples), 20 * len(bb)))

    def at(x):
        x = np.atleast_1d(x)
        return (np.exp(interp["s"](x)),) + tuple(interp[k](x) for k in ("w", "Dc", "Df", "g", "o"))

    aa, W, DC, DF, g, o = at(tt)
    Lmin, Om = _min_over_frequency(W, DC, DF)
    p = Lmin * aa - g
    up = np.flatnonzero((p[:-1] < 0) & (p[1:] >= 0))
    peak_hz = peak_m = peak_a = float("nan")
    if up.size:
        k = int(up[0])

        def pf(x):
            a_, w_, dc, df, g_, _ = at(x)
            return float(_min_over_frequency(w_, dc, df)[0][0] * a_[0] - g_[0])
        xp = brentq(pf, tt[k], tt[k + 1], xtol=1e-12)
        a_, w_, dc, df, _, o_ = at(xp)
        peak_a = float(a_[0])
        peak_hz = float(_min_over_frequency(w_, dc, df)[1][0]) / (2 * np.pi)
        peak_m = float(o_[0]) * peak_a
    lo, hi = _curve(p, W, DC, DF, g, aa)
    freqs = np.zeros(0) if freqs_hz is None else np.asarray(freqs_hz, dtype=float).ravel()
    out_amp = _at_frequencies(freqs, tt, W, DC, DF, aa, g, at)
    return Synthesis(freqs_hz=freqs, amplitude=out_amp, peak_hz=float(peak_hz), peak_amplitude_m=float(peak_m),
                     peak_modal_amplitude=peak_a, curve_amplitude=aa, curve_low_hz=lo, curve_high_hz=hi,
                     curve_observed_m=o * aa,
                     force_norm_N=float(np.linalg.norm(float(force_scale) * np.asarray(model.f_harmonic))))
