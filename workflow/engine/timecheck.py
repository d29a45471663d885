"""An independent time-domain check of a harmonic-balance solution (issue #47, item 2).

The question: is the HB state at one frequency a periodic orbit of the time-domain system it
claims to solve? A spurious HB root (an alias of the truncation, a wrong branch) is not, and
the time-domain motion started from it goes elsewhere; a right one is, to the HB's truncation
error. The engine's HB and DLFT code is not used (no ``HBProblem``, no ``dlft_pass``); only the
reduced model, the law's μ, gap and wear, and :func:`workflow.engine.condense.recover` to expand the
HB's relative harmonics to every coordinate.

What is integrated
------------------
The reduced model in its own coordinates q (``docs/contracts.md`` §4)::

    M q̈ + C q̇ + K q + Bᵀ λ = f_static + f_harmonic cos ωt,     u_r = B q,

with λ in :mod:`workflow.engine.contact`'s sign convention (λ_N < 0 in contact,
``g = u_N + gap + W ≥ 0``) and the **rigid** contact law the DLFT solves: unilateral normal
contact and Coulomb friction with rigid stick. (The DLFT's ε is not a contact stiffness: a
converged DLFT solution does not depend on it in stick and normal contact; it is the stiffness
lent to the harmonics above Nh, :mod:`workflow.engine.penalty`, ≈ the pair's own static
stiffness on the dovetail. A time model with that ε as a spring would double the stuck pairs'
compliance — on the quick sector's peak it moves the first harmonic by 6 % at 10× ε, 0.6 % at
100×. A finite ``stiffening`` reproduces such a compliant model for comparison:
ε' = max(ε_law, stiffening × k_static), its tied effect reported as ``regularisation``.)

Integrator
----------
Implicit Bossak-α (generalised-α with α_f = 0): α_m = (ρ∞ − 1)/(ρ∞ + 1), γ = ½ − α_m,
β = ¼(1 − α_m)², second order, unconditionally stable; forces at t_{n+1}, so massless DOFs
(Jenkins pads, the Coulomb oscillator's witness) are met at every step. ρ∞ = 0 by default:
the contact DOFs' own fast dynamics (a CB boundary node against a rigid obstacle, far above
the harmonics an HB resolves) are damped within a step — measured on the quick sector's peak,
ρ∞ = 0.8 lets them rattle at each re-closure and moves the first harmonic by 0.4–1.2 % with
the step. The scheme is **prewarped** at ω (:func:`prewarp`): it runs on ``M̃ = α₁M + α₂C``,
``C̃ = β₁M + β₂C`` whose discrete dynamic stiffness at the forcing frequency is exactly
``K − ω²M + iωC``, so the period error of the scheme, (ωh)²/12, which near a resonance of
damping ζ moves the response by ~(ωh)²/(24ζ) (measured 1 % at 256 steps on the quick
sector's ζ = 0.2 % peak), is gone at the first harmonic; the higher harmonics keep O((jωh)²).

Every step is linear in q but for λ(B q): with ``S = (1−α_m)/(βh²) M̃ + γ/(βh) C̃ + K``
(factored once), ``G = B S⁻¹`` and ``W = G Bᵀ`` (3p × 3p), the step is the contact problem
``u = u_free − W λ`` with the law, solved for λ in Alart–Curnier form by semismooth Newton
with a line search (:class:`_Contact`), then ``q = q_free − Gᵀ λ``. Newton's matrix is
solved by the LU of a reference and a Woodbury update for the pairs whose state differs from
it (refactored when more than 1/8 of the rows differ): at 128 pairs a step went from 40 to 6 ms.

Start, steady state, measures
-----------------------------
The HB harmonics U_r are expanded to q's (:func:`q_harmonics`); the state at t = 0 is their
sum, with q̇, q̈ from the scheme's own discrete relations (so a linear HB state is a fixed point
of the period map to round-off), λ(0) from the equation of motion, each pair placed on the
law (g = 0 where the HB presses it) with its slider at ``w = u_T`` and λ_T clipped into the
cone. A lightly damped structure takes ~1/(2πζ) periods to settle (80 on the quick sector), so
after ``periods`` plain periods the period map's fixed point is found by Anderson mixing
(depth ``anderson``) of the states at the period boundaries; it stops once the remaining
transient, ``defect / (1 − ρ_slow)`` with ρ_slow the slowest decay per period of the tied
structure's modes (:func:`slow_decay`; friction only adds damping), is below ``SETTLE`` ×
the tolerance. Then:

* ``max_rel_diff``: ``max_o |X₁ᵗ − X₁ᴴᴮ| / max_o |X₁ᴴᴮ|`` over the observed DOFs, X₁ the
  complex first harmonic (phase included) of the last period — the judged number;
  ``amplitude_rel_diff`` the change of the FRF's amplitude (Euclidean norm over the observed
  DOFs, as :func:`workflow.engine.studies.frf.observed`);
* ``periodicity_defect``: ``‖x(kT) − x((k−1)T)‖ / ‖x̃‖`` of the last period, x = (ω q, q̇) in
  the mass norm, ‖x̃‖ the HB's largest *dynamic* state over the period; ``defects`` and
  ``first_harmonic_diffs`` per period (the trend); ``hb_defect`` = the first period's: how far
  one period moves the HB state itself;
* ``within_tolerance``: ``max_rel_diff ≤ tolerance`` with the motion settled; False if it
  settled elsewhere (or is off by more than the tolerance even allowing for an unsettled
  transient); None with ``reason`` when the check could not run or decide.

Cost (``workflow/bench/timecheck.py``, 128 steps a period, one core): the quick sector's peak
(16 pairs, 110 DOFs) 0.27 s, 12 % of its FRF study (2.2 s); 128 pairs (782 DOFs) 4.5 s, 11 % of
39.8 s. A wrong state costs more periods (×1.2: 0.69 s and 13.7 s).

Tolerance
---------
``tolerance = TOL_FLOOR + integrator + regularisation + NH_SAFETY × nh_change``:
the time model's own ambiguity where contact DOFs with mass re-close (:data:`TOL_FLOOR`),
the integrator's error at the step used (:func:`integrator_error`, measured by halving the
step; ``halving=True`` measures it on each call instead), the compliant model's
(``regularisation``, 0 for the rigid default) and the HB's truncation as its Nh-check measured
it (the change from Nh to 1.5 Nh estimates the error of Nh to a factor: ``NH_SAFETY``).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.linalg as sla

__all__ = ["TimeCheckOptions", "TimeCheck", "time_check", "integrator_error", "prewarp", "q_harmonics",
           "regularisation_error", "slow_decay"]

#: the time model's own ambiguity, relative: where contact DOFs with mass lift off and re-close,
#: the rigid model's first harmonic depends on how their impacts dissipate. Measured on the quick
#: sector's peak (4 of 16 pairs open 50–70 % of the period): 0.03 % from the HB at 128 steps a
#: period, 0.7 % (0.45 % in amplitude) converged in the step (1024–2048 steps), 0.4–1.2 % with
#: ρ∞ = 0.8 instead of 0 (docs in workflow/bench/timecheck.py).
TOL_FLOOR = 1.0e-2
#: the Nh-check's change (Nh → 1.5 Nh) times this bounds the HB's truncation error.
NH_SAFETY = 2.0
#: the integrator's error of the first harmonic, relative, at 128 steps a period (ρ∞ = 0,
#: prewarped), from halving the step: the quick sector's peak moves 1.9e-3 from 128 to 256 steps
#: (1e-4 from 64 to 128), a Jenkins pad (massless contact node) ≤ 2.5e-3 from 64 to 128, Den
#: Hartog's oscillator (friction on a bare mass) 1.1 % from 128 to 256. Other steps scale as
#: 1/steps (first order: the contact force jumps where a pair sticks, slips back or re-closes).
#: On a bare mass the error itself is larger than its halving change before the asymptotic
#: range (3.3 % at 128 steps against the event-driven steady state): there ``halving=True``,
#: whose doubled change (4.2 %) covers it (tests/workflow/test_timecheck.py).
INTEGRATOR_ERROR_128 = 1.2e-2
#: the remaining transient at which the march stops, as a fraction of the tolerance.
SETTLE = 0.1
#: relative change of λ (to its scale) below which a step's contact problem is solved.
NEWTON_TOL = 1e-10


def integrator_error(steps_per_period: int) -> float:
    """The stated relative error of the first harmonic at ``steps_per_period`` (first order:
    :data:`INTEGRATOR_ERROR_128` × 128 / steps)."""
    return INTEGRATOR_ERROR_128 * 128.0 / float(steps_per_period)


@dataclass
class TimeCheckOptions:
    """How the check integrates (module docstring).

    ``steps_per_period`` (fixed step T/steps); ``periods``: plain periods before the Anderson
    mixing starts (the fast part of the start-up transient dies there), ``max_periods`` in all;
    ``anderson``: mixing depth (0: plain march for ``periods`` periods); ``rho_inf`` the
    scheme's spectral radius at infinite frequency; ``warp``: prewarp at ω; ``stiffening``:
    inf = rigid contact, else a compliant penalty of that many times the static stiffness;
    ``halving``: measure the integrator's error on this call (a second run at half the steps,
    the difference doubled) instead of :func:`integrator_error`; ``budget_seconds`` (0 = none):
    stop there and report ``within_tolerance = None``; ``newton_maxiter`` per step."""

    steps_per_period: int = 128
    periods: int = 3
    max_periods: int = 60
    anderson: int = 6
    rho_inf: float = 0.0
    warp: bool = True
    stiffening: float = math.inf
    halving: bool = False
    budget_seconds: float = 0.0
    newton_maxiter: int = 40


@dataclass
class TimeCheck:
    """The result of :func:`time_check` (SI units; relative numbers are fractions).

    ``within_tolerance``: True / False, or None when the check could not run or decide
    (``reason`` says why). ``max_rel_diff``: first-harmonic complex difference at the observed
    DOFs over the last period, relative to the HB's largest; ``amplitude_rel_diff`` the same for
    the FRF's amplitude measure; ``amplitude_hb``, ``amplitude_time`` (m);
    ``periodicity_defect`` the last period's, ``hb_defect`` the first's (the HB state's own),
    ``defects`` and ``first_harmonic_diffs`` every period's (the trend); ``settled`` whether the
    remaining transient (``transient``, relative, from ``decay_per_period`` = 1 − ρ_slow) is
    below the tolerance's :data:`SETTLE`; ``verdict`` one line; ``tolerance`` and its
    ``tolerance_parts``; ``seconds`` (wall), ``periods`` integrated, ``steps``,
    ``newton_iterations`` (all steps), ``max_newton`` (one step); ``model`` the contact model
    ("rigid" or the penalty ranges)."""

    frequency_hz: float
    within_tolerance: bool | None
    reason: str | None = None
    verdict: str = ""
    max_rel_diff: float | None = None
    amplitude_rel_diff: float | None = None
    amplitude_hb: float | None = None
    amplitude_time: float | None = None
    periodicity_defect: float | None = None
    hb_defect: float | None = None
    transient: float | None = None
    decay_per_period: float | None = None
    settled: bool = False
    defects: list = field(default_factory=list)
    first_harmonic_diffs: list = field(default_factory=list)
    tolerance: float | None = None
    tolerance_parts: dict = field(default_factory=dict)
    steps_per_period: int = 0
    periods: int = 0
    steps: int = 0
    newton_iterations: int = 0
    max_newton: int = 0
    seconds: float = 0.0
    model: dict = field(default_factory=dict)
    halved: dict | None = None

    _KEYS = ("frequency_hz", "within_tolerance", "reason", "verdict", "max_rel_diff", "amplitude_rel_diff",
             "amplitude_hb", "amplitude_time", "periodicity_defect", "hb_defect", "transient", "decay_per_period",
             "settled", "tolerance", "tolerance_parts", "steps_per_period", "periods", "steps", "newton_iterations",
             "max_newton", "seconds", "model", "halved")

    def as_dict(self) -> dict:
        """JSON-serialisable summary, the per-period trends included."""
        out = {k: getattr(self, k) for k in self._KEYS}
        out["defects"] = [float(d) for d in self.defects]
        out["first_harmonic_diffs"] = [float(d) for d in self.first_harmonic_diffs]
        return out

    def log_line(self) -> str:
        """One log line, like :func:`workflow.engine.studies.epscheck.log_line`."""
        if self.within_tolerance is None:
            return f"time check at {self.frequency_hz:.4g} Hz: not judged ({self.reason})"
        verdict = "within" if self.within_tolerance else "ABOVE"
        return (f"time check at {self.frequency_hz:.4g} Hz ({self.periods} periods × {self.steps_per_period} steps, "
                f"{self.seconds:.2f} s): first harmonic {self.max_rel_diff:.2e} from the HB, {verdict} the tolerance "
                f"{self.tolerance:.2e} — {self.verdict}")


# ---------------------------------------------------------------------------------------------
def _bossak(rho_inf: float) -> tuple[float, float, float]:
    """(α_m, β, γ) of the Bossak scheme for ρ∞ ∈ [0, 1]."""
    rho = float(np.clip(rho_inf, 0.0, 1.0))
    am = (rho - 1.0) / (rho + 1.0)
    return am, 0.25 * (1.0 - am) ** 2, 0.5 - am


def _discrete(rho_inf: float, h: float, omega_j):
    """(s_v, s_a, s_m) of the Bossak scheme at the frequencies ``omega_j`` [rad/s] (array): on a
    steady sampled harmonic ``q_n = Q zⁿ``, z = e^{iω_j h}, the scheme's updates give
    ``v_n = s_v Q zⁿ``, ``a_n = s_a Q zⁿ`` (→ iω_j, −ω_j² as h → 0; 0 at ω_j = 0) and the equation
    at t_{n+1} reads ``(K + s_m M + s_v C) Q = F``, ``s_m = ((1−α_m) + α_m/z) s_a``."""
    am, beta, gamma = _bossak(rho_inf)
    w = np.atleast_1d(np.asarray(omega_j, dtype=float))
    z = np.exp(1j * w * h)
    sa = np.zeros(w.shape, dtype=complex)
    sv = np.zeros(w.shape, dtype=complex)
    nz = w != 0
    zz = z[nz]
    sa[nz] = (zz - 1.0) / (h * h * (((1.0 - gamma) + gamma * zz) / (zz - 1.0) + (0.5 - beta) + beta * zz))
    sv[nz] = sa[nz] * h * ((1.0 - gamma) + gamma * zz) / (zz - 1.0)
    return sv, sa, ((1.0 - am) + am / z) * sa


def prewarp(rho_inf: float, h: float, omega: float) -> tuple[float, float, float, float]:
    """Real (α₁, α₂, β₁, β₂) such that the scheme run on ``M̃ = α₁M + α₂C``,
    ``C̃ = β₁M + β₂C`` has at ω [rad/s] exactly the continuous dynamic stiffness
    ``K − ω²M + iωC`` (:func:`_discrete`).
    At 128 steps and ρ∞ = 0: α₁ − 1 = −2.2e-3, β₂ − 1 = −8e-4, α₂ω = 3e-5 and β₁/ω = −1.2e-4 (a
    mass-proportional damping ratio −6e-5 at ω that gives back the scheme's own dissipation there;
    a mode far below ω with less damping than that would be undamped by it)."""
    sv, _, sm = _discrete(rho_inf, h, [omega])
    A = np.array([[sm[0].real, sv[0].real], [sm[0].imag, sv[0].imag]])
    a1, b1 = np.linalg.solve(A, [-omega * omega, 0.0])
    a2, b2 = np.linalg.solve(A, [0.0, omega])
    return float(a1), float(a2), float(b1), float(b2)


def q_harmonics(model, omega: float, Ur: np.ndarray, rc=None) -> np.ndarray:
    """Complex harmonics (Nh+1, m) of the reduced coordinates q from the relative ones ``Ur``
    (Nh+1, 3p) at ω [rad/s]: :func:`workflow.engine.condense.recover` with every coordinate observed
    (``O = T``: the tied remainder solved per harmonic, docs/contracts.md §5)."""
    from workflow.engine.condense import coordinate_basis, recover, relative_coordinates

    rc = relative_coordinates(model) if rc is None else rc
    T = coordinate_basis(model)
    return recover(replace(rc, O=T, tied=None), float(omega), np.asarray(Ur, dtype=complex))


def regularisation_error(model, omega: float, eps: np.ndarray, scale: float | None = None) -> float:
    """Largest change of the tied structure's first harmonic at the observed DOFs at ω [rad/s]
    when the rigid tie of every pair is replaced by springs ``eps`` (p, 3) [N/m], relative to
    ``scale`` (m; default the tied response's norm): a compliant contact model's own error where
    it matters most (every pair stuck)."""
    M, K, C, B = (np.asarray(getattr(model, k), dtype=float) for k in ("M", "K", "C", "B"))
    D = K - omega ** 2 * M + 1j * omega * C
    f = np.asarray(model.f_harmonic, dtype=complex)
    r, m = B.shape
    A = np.zeros((m + r, m + r), dtype=complex)
    A[:m, :m], A[:m, m:], A[m:, :m] = D, B.T, B
    rigid = np.linalg.solve(A, np.concatenate([f, np.zeros(r)]))[:m]
    soft = np.linalg.solve(D + B.T @ (np.asarray(eps, float).reshape(-1)[:, None] * B), f)
    O = np.asarray(model.O, dtype=float)
    s = np.linalg.norm(O @ rigid) if scale is None else float(scale)
    return float(np.max(np.abs(O @ (soft - rigid))) / s) if s > 0 else 0.0


def slow_decay(model, omega: float, rc=None) -> float:
    """1 − ρ_slow: the smallest relative decay per period 2π/ω [rad/s] of the free vibration of
    the tied structure (every pair stuck), ``1 − exp(−2π ζ_k ω_k/ω)`` over its modes (ζ_k from
    the modal projection of C): friction and separation only add damping. 0.0125 at the quick
    sector's peak (ζ = 0.2 % at 212.6 Hz). Where nothing moves once tied (a contact on a bare
    mass: Den Hartog's oscillator), the model's own modes of non-zero frequency instead."""
    from workflow.engine.condense import relative_coordinates

    rc = relative_coordinates(model) if rc is None else rc
    r = rc.n_rel
    rate = _modal_rates(rc.K[r:, r:], rc.M[r:, r:], rc.C[r:, r:]) if rc.K.shape[0] > r else np.zeros(0)
    if rate.size == 0:
        rate = _modal_rates(*(np.asarray(getattr(model, k), dtype=float) for k in ("K", "M", "C")))
    if rate.size == 0:
        return 1.0
    return float(np.clip(1.0 - np.exp(-2.0 * np.pi * np.min(rate) / float(omega)), 1e-6, 1.0))


def _modal_rates(K: np.ndarray, M: np.ndarray, C: np.ndarray) -> np.ndarray:
    """ζ_k ω_k [1/s] of the modes of (K, M, C) with mass and a non-zero frequency (modal
    projection of C; a massless or rigid part is skipped)."""
    if not np.any(M):
        return np.zeros(0)
    mu, V = sla.eigh(M, K + 1e-12 * np.abs(K).max() * np.eye(K.shape[0]), check_finite=False)  # μ = 1/ω²
    keep = mu > 1e-12 * max(float(mu.max()), 1e-300)
    if not keep.any():
        return np.zeros(0)
    mu, V = mu[keep], V[:, keep]
    Vm = V / np.sqrt(mu)                                   # M-orthonormal
    wk = 1.0 / np.sqrt(mu)
    zeta = np.einsum("ik,ij,jk->k", Vm, C, Vm) / (2.0 * wk)
    fast = wk > 1e-6 * wk.max()
    return np.maximum(zeta[fast] * wk[fast], 0.0)


# ---------------------------------------------------------------------------------------------
class _Contact:
    """The contact law of one implicit step in Alart–Curnier form, solved for λ by semismooth
    Newton with a line search.

    Per pair, with the step's contact displacement ``u = u_free − W λ`` and compliances
    ``c = 1/ε'`` (0: rigid): the normal ``λ_N = min(0, σ_N)``, ``σ_N = λ_N + r (g − c_N λ_N)``;
    the tangential ``λ_T = P_{μ max(0, −σ_N)}(σ_T)``, ``σ_T = λ_T + r (u_T − w − c_T λ_T)``, P the
    projection onto the disc of that radius (stick: ``u_T = w + c_T λ_T``; slip: on the cone,
    along the step's slip). ``r`` per pair ≈ 1/W_ii balances the two halves of σ; the solution
    does not depend on it. The slider then sits at ``w ← u_T − c_T λ_T``."""

    def __init__(self, mu, compliance, offset, W):
        self.mu = np.asarray(mu, dtype=float)                  # (p,)
        self.c = np.asarray(compliance, dtype=float)           # (p, 3) m/N
        self.off = np.asarray(offset, dtype=float)             # (p,)
        self.W = W
        p = self.mu.shape[0]
        self.p, self.n = p, 3 * p
        dW = np.diagonal(W).reshape(p, 3)
        self.r = np.repeat(1.0 / np.maximum(dW.mean(axis=1) + self.c.mean(axis=1), 1e-300), 3)   # (3p,) N/m
        # σ = Ms λ + r (u_free + [gap, −w]),  Ms = I − r (W + C)
        self.Ms = np.eye(self.n) - self.r[:, None] * (W + np.diag(self.c.reshape(-1)))
        self.Ms3 = self.Ms.reshape(p, 3, self.n)
        self.eye = np.eye(self.n)
        # the Jacobian J = I − D Ms is solved by its LU at a reference D and a Woodbury update for
        # the rows where D differs (the pairs that slip or changed state since): at 128 pairs an
        # LU of J took 7 ms, 2/3 of a step, and some pair slips in nearly every step
        self.max_rank = max(8, self.n // 8)
        self.ref_D = None
        self.ref_lu = None
        self.Z: dict = {}
        self.factorisations = 0

    def _project(self, sig):
        """The per-pair projection P(σ) (3p,) and what its derivative needs: (P, in contact (p,),
        inside the disc (p,), ‖σ_T‖ (p,), disc radius (p,))."""
        s = sig.reshape(self.p, 3)
        sN = s[:, 0]
        con = sN < 0.0
        rad = self.mu * np.maximum(-sN, 0.0)
        nrm = np.hypot(s[:, 1], s[:, 2])
        inside = nrm <= rad
        P = s.copy()
        P[:, 0] = np.minimum(sN, 0.0)
        out = ~inside
        if out.any():
            P[out, 1:] *= (rad[out] / np.maximum(nrm[out], 1e-300))[:, None]
        return P.reshape(-1), con, inside, nrm, rad

    def _D(self, sig, con, inside, nrm, rad) -> np.ndarray:
        """D = ∂P/∂σ, (p, 3, 3) blocks."""
        p = self.p
        D = np.zeros((p, 3, 3))
        D[:, 0, 0] = con
        D[:, 1, 1] = D[:, 2, 2] = inside
        slip = con & ~inside
        if slip.any():
            s = sig.reshape(p, 3)
            th = s[slip, 1:] / nrm[slip, None]
            D[slip, 1:, 1:] = (rad[slip] / nrm[slip])[:, None, None] * (np.eye(2) - th[:, :, None] * th[:, None, :])
            D[slip, 1:, 0] = -self.mu[slip, None] * th
        return D

    def _refactor(self, D):
        J = self.eye - np.einsum("ibc,icj->ibj", D, self.Ms3).reshape(self.n, self.n)
        self.ref_D, self.ref_lu, self.Z = D, sla.lu_factor(J, check_finite=False), {}
        self.factorisations += 1

    def _newton_step(self, D, phi):
        """−J⁻¹ Φ with J = I − D Ms = J_ref − U V, U the identity's columns at the rows R where D
        differs from the reference, V = (D − D_ref)_R Ms: Woodbury on the reference's LU."""
        if self.ref_D is None:
            self._refactor(D)
        dD = D - self.ref_D
        rows = np.flatnonzero(np.any(dD != 0.0, axis=2).reshape(-1))
        if rows.size > self.max_rank:
            self._refactor(D)
            rows = rows[:0]
        y = sla.lu_solve(self.ref_lu, phi, check_finite=False)
        if rows.size == 0:
            return -y
        key = rows.tobytes()
        Z = self.Z.get(key)
        if Z is None:
            if len(self.Z) > 64:
                self.Z.clear()
            E = np.zeros((self.n, rows.size))
            E[rows, np.arange(rows.size)] = 1.0
            Z = self.Z[key] = sla.lu_solve(self.ref_lu, E, check_finite=False)      # J_ref⁻¹ U
        pair, loc = rows // 3, rows % 3
        V = np.einsum("kc,kcn->kn", dD[pair, loc, :], self.Ms3[pair])                # (k, n)
        return -(y + Z @ np.linalg.solve(np.eye(rows.size) - V @ Z, V @ y))

    def solve(self, u_free, w, lam0, tol: float, maxiter: int):
        """(λ (p, 3), u (p, 3), new w (p, 2), Newton iterations); raises FloatingPointError."""
        p = self.p
        b = u_free.copy()
        b[:, 0] += self.off
        b[:, 1:] -= w
        b = self.r * b.reshape(-1)
        lam = lam0.reshape(-1)
        sig = self.Ms @ lam + b
        P, *dd = self._project(sig)
        phi = lam - P
        err = np.max(np.abs(phi))
        it = 0
        while err > tol:
            if it == maxiter:
                raise FloatingPointError(f"‖Φ‖∞ = {err:.2e} N after {maxiter} iterations")
            it += 1
            d = self._newton_step(self._D(sig, *dd), phi)
            theta = float(phi @ phi)
            a = 1.0
            for _ in range(30):
                lam_t = lam + a * d
                sig_t = self.Ms @ lam_t + b
                P_t, *dd_t = self._project(sig_t)
                phi_t = lam_t - P_t
                theta_t = float(phi_t @ phi_t)
                if theta_t <= (1.0 - 1e-4 * a) * theta:
                    break
                a *= 0.5
            lam, sig, dd, phi = lam_t, sig_t, dd_t, phi_t
            err = np.max(np.abs(phi))
        lam = (lam - phi).reshape(p, 3)       # the exact projection (round-off below tol)
        u = u_free - (self.W @ lam.reshape(-1)).reshape(p, 3)
        w_new = u[:, 1:] - self.c[:, 1:] * lam[:, 1:]
        return lam, u, w_new, it


@dataclass
class _State:
    """The scheme's state at a step: q, q̇, q̈ (m,), sliders w (p, 2); forces λ (p, 3) and their
    rate (the next step's Newton start; not part of the dynamics)."""

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    w: np.ndarray
    lam: np.ndarray
    dlam: np.ndarray | None = None

    def __post_init__(self):
        if self.dlam is None:
            self.dlam = np.zeros_like(self.lam)

    def vector(self) -> np.ndarray:
        return np.concatenate([self.q, self.v, self.a, self.w.reshape(-1)])

    def with_vector(self, x: np.ndarray) -> "_State":
        m = self.q.shape[0]
        return _State(q=x[:m].copy(), v=x[m:2 * m].copy(), a=x[2 * m:3 * m].copy(), w=x[3 * m:].reshape(-1, 2).copy(),
                      lam=self.lam.copy(), dlam=self.dlam.copy())


class _Stepper:
    """The Bossak march of the reduced model with the contact law at a fixed step h = T/N, one
    period at a time; the step's matrices made once (prewarped where asked)."""

    def __init__(self, model, omega: float, steps_per_period: int, rho_inf: float, mu, compliance, offset, *,
                 warp: bool, lam_scale: float, newton_maxiter: int):
        M, K, C, B = (np.asarray(getattr(model, k), dtype=float) for k in ("M", "K", "C", "B"))
        h = 2.0 * np.pi / omega / steps_per_period
        if warp:
            a1, a2, b1, b2 = prewarp(rho_inf, h, omega)
            M, C = a1 * M + a2 * C, b1 * M + b2 * C
        fs, fh = np.asarray(model.f_static, float), np.asarray(model.f_harmonic, float)
        m = M.shape[0]
        am, beta, gamma = _bossak(rho_inf)
        self.h, self.gamma, self.N, self.m = h, gamma, int(steps_per_period), m
        self.c0, self.c1, self.c2 = 1.0 / (beta * h * h), 1.0 / (beta * h), 0.5 / beta - 1.0
        S = (1.0 - am) * self.c0 * M + gamma * h * self.c0 * C + K
        S = 0.5 * (S + S.T)
        rhs = np.column_stack([K, M, C, fs, fh, B.T])
        try:
            P = sla.cho_solve(sla.cho_factor(S, check_finite=False), rhs, check_finite=False)
        except np.linalg.LinAlgError:
            P = sla.lu_solve(sla.lu_factor(S, check_finite=False), rhs, check_finite=False)
        # q_free = q + S⁻¹ [f(t) − K q + M ((1−α_m)(c1 v + c2 a) − α_m a)
        #                   − C ((1 − hγc1) v + (h(1−γ) − hγc2) a)]
        PK, PM, PC = P[:, :m], P[:, m:2 * m], P[:, 2 * m:3 * m]
        self.s_s, self.s_h, self.Gt = P[:, 3 * m], P[:, 3 * m + 1], P[:, 3 * m + 2:]
        kv_m, ka_m = (1.0 - am) * self.c1, (1.0 - am) * self.c2 - am
        kv_c, ka_c = 1.0 - h * gamma * self.c1, h * (1.0 - gamma) - h * gamma * self.c2
        self.A = np.hstack([np.eye(m) - PK, kv_m * PM - kv_c * PC, ka_m * PM - ka_c * PC])   # [q; v; a] → q_free
        W = B @ self.Gt
        self.law = _Contact(mu, compliance, offset, 0.5 * (W + W.T))
        self.B, self.O = B, np.asarray(model.O, dtype=float)
        self.cos = np.cos(omega * h * np.arange(1, self.N + 1))
        self.tol, self.maxiter = NEWTON_TOL * lam_scale, int(newton_maxiter)
        self.iterations, self.max_iterations, self.steps = 0, 0, 0

    def period(self, st: _State) -> tuple[_State, np.ndarray]:
        """One period from ``st`` (at a multiple of the period): (state after it, O q at its N steps)."""
        m, h, g = self.m, self.h, self.gamma
        q, v, a, w, lam, dlam = st.q, st.v, st.a, st.w, st.lam, st.dlam
        qs = np.empty((self.N, m))
        x = np.empty(3 * m)
        for n in range(self.N):
            x[:m], x[m:2 * m], x[2 * m:] = q, v, a
            q_free = self.A @ x + self.s_s + self.cos[n] * self.s_h
            u_free = (self.B @ q_free).reshape(-1, 3)
            try:
                lam_new, _, w, it = self.law.solve(u_free, w, lam + dlam * h, self.tol, self.maxiter)
            except FloatingPointError as exc:
                raise FloatingPointError(f"the contact forces of step {n + 1} did not converge ({exc})") from None
            self.iterations += it
            self.max_iterations = max(self.max_iterations, it)
            dlam, lam = (lam_new - lam) / h, lam_new
            q_new = q_free - self.Gt @ lam.reshape(-1)
            a_new = self.c0 * (q_new - q) - self.c1 * v - self.c2 * a
            v = v + h * ((1.0 - g) * a + g * a_new)
            q, a = q_new, a_new
            qs[n] = q
        self.steps += self.N
        return _State(q=q, v=v, a=a, w=w, lam=lam, dlam=dlam), qs @ self.O.T


# ---------------------------------------------------------------------------------------------
def _first_harmonic(samples: np.ndarray) -> np.ndarray:
    """Complex first harmonic U₁ (``u = Re U₁ e^{iωt}``, docs/contracts.md §3) of one period of
    samples at t = kh, k = 1…N (a period starting at a multiple of T), (N, n) → (n,)."""
    N = samples.shape[0]
    return 2.0 / N * (np.exp(-2j * np.pi * np.arange(1, N + 1) / N) @ samples)


def _mass_norm(M: np.ndarray, X: np.ndarray) -> np.ndarray:
    """‖x‖_M of the columns of X (m, k) (Euclidean where M has no mass)."""
    if not np.any(M):
        return np.linalg.norm(X, axis=0)
    return np.sqrt(np.maximum(np.einsum("ik,ij,jk->k", X, M, X), 0.0))


# ---------------------------------------------------------------------------------------------
def time_check(model, law, omega: float, Ur, *, nh_change: float | None = None,
               options: TimeCheckOptions | None = None, rc=None) -> TimeCheck:
    """Integrate ``model`` under ``law``'s contact in time from the HB state ``Ur`` at ω [rad/s]
    and judge whether that state is a periodic orbit (module docstring).

    ``model``: the :class:`~workflow.engine.model.ReducedModel` the HB solved; ``law``: its
    :class:`~workflow.engine.contact.ContactLaw` (μ, gap and wear are read; ε only by a
    compliant ``stiffening``); ``Ur``: complex relative harmonics (Nh+1, 3p) of the HB solution
    (``Peak.Ur``, ``SweepResult.Ur[i]``); ``nh_change``: the Nh-check's relative change at this
    point (None: unknown, not charged); ``rc``: the model's relative coordinates if at hand.
    Never raises for a check that cannot run: ``within_tolerance`` is None and ``reason`` says why.
    """
    opt = options or TimeCheckOptions()
    t0 = time.perf_counter()
    out = TimeCheck(frequency_hz=float(omega) / (2.0 * np.pi), within_tolerance=None,
                    steps_per_period=int(opt.steps_per_period))

    def done(reason=None):
        out.reason = reason
        out.seconds = time.perf_counter() - t0
        return out

    if getattr(model, "is_cyclic", False):
        return done("cyclic model: the tuned disk's harmonics live on different nodal diameters, which one "
                    "sector cannot integrate in time")
    if np.iscomplexobj(model.f_harmonic) and np.any(np.imag(model.f_harmonic) != 0):
        return done("a complex harmonic load (a travelling wave on a whole disk): the integrator takes a "
                    "real load F cos ωt")
    if not (np.isfinite(omega) and omega > 0):
        return done(f"frequency {omega!r} rad/s is not positive")
    Ur = np.asarray(Ur, dtype=complex)
    p = model.n_pairs
    if Ur.ndim != 2 or Ur.shape[1] != 3 * p or Ur.shape[0] < 2 or not np.all(np.isfinite(Ur)):
        return done(f"HB harmonics of shape {Ur.shape} (expected (Nh+1 ≥ 2, {3 * p}), finite)")
    if opt.steps_per_period < 16 or opt.max_periods < 1:
        return done("options: at least 16 steps a period and 1 period")
    from workflow.engine.condense import relative_coordinates

    rc = relative_coordinates(model) if rc is None else rc
    try:
        s = _Start(model, law, float(omega), Ur, opt, rc)
    except (np.linalg.LinAlgError, ValueError) as exc:
        return done(f"the HB state cannot be expanded to the reduced coordinates: {exc}")
    if not s.amp_hb > 0:
        return done("the HB first harmonic at the observed DOFs is zero: nothing to compare")
    out.amplitude_hb = s.amp_hb
    out.model = s.describe
    out.decay_per_period = s.decay
    parts = {"floor": TOL_FLOOR, "integrator": integrator_error(opt.steps_per_period),
             "regularisation": s.regularisation,
             "nh_check": None if nh_change is None else NH_SAFETY * float(nh_change)}
    tol = float(sum(v for v in parts.values() if v is not None))
    try:
        X1, stopped = _march(s, opt, opt.steps_per_period, tol, out, t0)
    except (FloatingPointError, np.linalg.LinAlgError) as exc:
        return done(f"time integration failed after {out.periods} periods: {exc}")
    if opt.halving and not stopped and opt.steps_per_period // 2 >= 16:
        half = replace(opt, steps_per_period=opt.steps_per_period // 2)
        probe = TimeCheck(frequency_hz=out.frequency_hz, within_tolerance=None)
        try:
            X1h, stopped = _march(s, half, half.steps_per_period, tol, probe, t0)
        except (FloatingPointError, np.linalg.LinAlgError) as exc:
            return done(f"time integration at half the steps failed: {exc}")
        change = float(np.max(np.abs(X1 - X1h)) / np.max(np.abs(s.X1_hb)))
        parts["integrator"] = 2.0 * change
        out.halved = {"steps_per_period": half.steps_per_period, "max_rel_diff": probe.max_rel_diff,
                      "change": change, "periods": probe.periods, "settled": probe.settled}
        tol = float(sum(v for v in parts.values() if v is not None))
    out.tolerance, out.tolerance_parts = tol, parts
    if stopped:
        out.verdict = f"stopped: first harmonic {out.max_rel_diff:.2e} from the HB so far"
        return done(stopped)
    return done(_judge(out, tol))


def _judge(out: TimeCheck, tol: float) -> str | None:
    """Set ``out``'s verdict against ``tol``; the reason when it cannot judge (not settled), else None."""
    diff, tr = out.max_rel_diff, out.transient
    if out.settled:
        out.within_tolerance = bool(diff <= tol)
        out.verdict = ("the HB state is a periodic orbit of the time-domain model (to the tolerance)"
                       if out.within_tolerance else
                       f"the time-domain periodic orbit differs from the HB state by {diff:.2e} in the first "
                       f"harmonic: a spurious HB solution, or one not converged in Nh")
        return None
    if diff - tr > tol:
        out.within_tolerance = False
        out.verdict = (f"the time-domain motion leaves the HB state: {diff:.2e} in the first harmonic, more than "
                       f"the tolerance even allowing for the transient still left ({tr:.2e})")
        return None
    out.verdict = f"not settled: remaining transient {tr:.2e}, first harmonic {diff:.2e} from the HB"
    return (f"the motion did not settle in {out.periods} periods (remaining transient {tr:.2e} > "
            f"{SETTLE:g} × tolerance); raise max_periods")


class _Start:
    """The HB state as the scheme's start and everything the march and its measures need."""

    def __init__(self, model, law, omega: float, Ur: np.ndarray, opt: TimeCheckOptions, rc):
        from workflow.engine import penalty

        self.model, self.omega, self.opt = model, omega, opt
        M, K, C, B = (np.asarray(getattr(model, k), dtype=float) for k in ("M", "K", "C", "B"))
        self.M = M
        p, nh = model.n_pairs, Ur.shape[0] - 1
        Q = q_harmonics(model, omega, Ur, rc)                      # (Nh+1, m)
        self.Q, self.j = Q, np.arange(nh + 1)
        O = np.asarray(model.O, dtype=float)
        self.X1_hb = O @ Q[1]
        self.amp_hb = float(np.linalg.norm(self.X1_hb))
        jw = self.j * omega
        q0 = np.real(Q.sum(axis=0))
        v0 = np.real((1j * jw)[:, None] * Q).sum(axis=0)
        a0 = np.real((-jw ** 2)[:, None] * Q).sum(axis=0)
        # the dynamic scale: the HB's largest (ω q, q̇) over the period, static part excluded
        ns = max(64, 8 * nh)
        E = np.exp(2j * np.pi * np.outer(self.j, np.arange(ns)) / ns)
        Qd = Q.copy()
        Qd[0] = 0.0
        qt, vt = np.real(Qd.T @ E), np.real((Qd * (1j * jw)[:, None]).T @ E)
        self.x_scale = float(np.max(np.sqrt(_mass_norm(M, omega * qt) ** 2 + _mass_norm(M, vt) ** 2))) or 1.0
        # the contact model: rigid, or a compliant penalty for comparison
        if np.isfinite(opt.stiffening) and opt.stiffening > 0:
            from workflow.engine.condense import condense

            k = penalty.reference_stiffness(np.real(condense(rc, 0.0, 0).Zr[0]))
            en = np.maximum(law.eps_n, opt.stiffening * k[:, 0])
            et = np.maximum(law.eps_t, opt.stiffening * k[:, 1])
            eps = np.stack([en, et, et], axis=1)
            self.comp = 1.0 / eps
            self.regularisation = regularisation_error(model, omega, eps, scale=self.amp_hb)
            self.describe = {"contact": "penalty", "stiffening": float(opt.stiffening),
                             "eps_n": [float(en.min()), float(en.max())], "eps_t": [float(et.min()), float(et.max())]}
        else:
            self.comp = np.zeros((p, 3))
            self.regularisation = 0.0
            self.describe = {"contact": "rigid"}
        self.mu = np.asarray(law.mu, dtype=float)
        self.offset = law.offset()[:, 0]
        # λ(0) from the equation of motion (its part in range(Bᵀ)), onto the law
        f0 = np.asarray(model.f_static, float) + np.asarray(model.f_harmonic, float)
        lam0 = np.linalg.lstsq(B.T, f0 - M @ a0 - C @ v0 - K @ q0, rcond=None)[0].reshape(p, 3)
        press = lam0[:, 0] < 0.0
        lam0[~press] = 0.0
        nrm = np.hypot(lam0[:, 1], lam0[:, 2])
        lim = self.mu * -lam0[:, 0]
        lam0[:, 1:] *= np.where(nrm > lim, lim / np.where(nrm > 0, nrm, 1.0), 1.0)[:, None]
        u0 = (B @ q0).reshape(p, 3)
        target = u0.copy()
        g0 = u0[:, 0] + self.offset
        target[:, 0] = np.where(press, self.comp[:, 0] * lam0[:, 0], np.maximum(g0, 0.0)) - self.offset
        self.du = (target - u0).reshape(-1)        # placed by the first march's metric (_initial)
        self.w0 = target[:, 1:] - self.comp[:, 1:] * lam0[:, 1:]
        self.q0, self.lam0 = q0, lam0
        self.lam_scale = float(np.max(np.abs(lam0))) or float(np.max(np.abs(f0))) or 1.0
        try:
            self.decay = slow_decay(model, omega, rc)
        except (np.linalg.LinAlgError, ValueError):
            self.decay = 1e-3
        # Anderson's least squares in scaled coordinates: (ω q, q̇, q̈/ω) by √diag M over the scale
        dm = np.sqrt(np.maximum(np.diagonal(M), 1e-6 * float(np.max(np.diagonal(M), initial=0.0))) + 1e-300)
        uT = float(np.max(np.abs(Ur[1:].reshape(nh, p, 3)[:, :, 1:]).sum(axis=0))) or 1.0
        self.wts = np.concatenate([omega * dm, dm, 0.1 * dm / omega]) / self.x_scale
        self.wts = np.concatenate([self.wts, np.full(2 * p, 1.0 / uT)])

    def initial(self, stepper: _Stepper) -> _State:
        """The start for a march at the stepper's step: q̇, q̈ by the scheme's discrete relations
        (so a linear HB state is its periodic orbit), the pairs placed on the law by the smallest
        change of q in the step's metric S."""
        opt, omega = self.opt, self.omega
        if opt.warp:
            sv, sa, _ = _discrete(opt.rho_inf, stepper.h, self.j * omega)
        else:
            sv, sa = 1j * self.j * omega, -(self.j * omega) ** 2
        v0 = np.real(sv[:, None] * self.Q).sum(axis=0)
        a0 = np.real(sa[:, None] * self.Q).sum(axis=0)
        q0 = self.q0 + (stepper.Gt @ np.linalg.solve(stepper.law.W, self.du) if np.any(self.du) else 0.0)
        return _State(q=q0, v=v0, a=a0, w=self.w0.copy(), lam=self.lam0.copy())

    def defect(self, x_new: np.ndarray, x_old: np.ndarray) -> float:
        m = self.M.shape[0]
        d = (x_new - x_old)[:, None]
        return float(np.sqrt(_mass_norm(self.M, self.omega * d[:m])[0] ** 2 + _mass_norm(self.M, d[m:2 * m])[0] ** 2)
                     / self.x_scale)


def _march(s: _Start, opt: TimeCheckOptions, steps: int, tol: float, out: TimeCheck, t0: float):
    """Periods from the HB state until the transient left is below SETTLE × ``tol`` (plain,
    then Anderson-mixed), filling ``out``'s measures; (X₁ of the last period, stop reason)."""
    stepper = _Stepper(s.model, s.omega, steps, opt.rho_inf, s.mu, s.comp, s.offset, warp=opt.warp,
                       lam_scale=s.lam_scale, newton_maxiter=opt.newton_maxiter)
    st = s.initial(stepper)
    x = st.vector()
    dX, dF, last = [], [], None
    diffs, defects = [], []
    stopped, X1 = None, None
    out.settled = False
    for k in range(max(opt.max_periods, 1)):
        st_new, obs = stepper.period(st)
        x_new = st_new.vector()
        X1 = _first_harmonic(obs)
        diffs.append(float(np.max(np.abs(X1 - s.X1_hb)) / np.max(np.abs(s.X1_hb))))
        defects.append(s.defect(x_new, x))
        out.periods, out.steps = k + 1, stepper.steps
        out.newton_iterations, out.max_newton = stepper.iterations, stepper.max_iterations
        out.transient = defects[-1] / s.decay
        if k + 1 >= opt.periods and out.transient <= SETTLE * tol:
            out.settled = True
            break
        if k + 1 >= opt.periods and diffs[-1] - out.transient > 2.0 * tol:
            break       # off by more than twice the tolerance whatever the transient left: decided
        if opt.budget_seconds > 0 and time.perf_counter() - t0 > opt.budget_seconds:
            stopped = f"time budget of {opt.budget_seconds:.3g} s spent after {k + 1} periods"
            break
        if opt.anderson and k + 1 >= opt.periods:
            f = (x_new - x) * s.wts
            if last is not None:
                dX.append(x - last[0])
                dF.append(f - last[1])
                del dX[:-opt.anderson], dF[:-opt.anderson]
            last = (x, f)
            if dF:
                Fm = np.column_stack(dF)
                g = np.linalg.lstsq(Fm, f, rcond=None)[0]
                x = x + f / s.wts - (np.column_stack(dX) + Fm / s.wts[:, None]) @ g
            else:
                x = x_new
            st = st_new.with_vector(x)
        else:
            x, st = x_new, st_new
    out.first_harmonic_diffs, out.defects = diffs, defects
    out.hb_defect = defects[0]
    out.periodicity_defect = defects[-1]
    out.max_rel_diff = diffs[-1]
    out.amplitude_time = float(np.linalg.norm(X1))
    out.amplitude_rel_diff = abs(out.amplitude_time - s.amp_hb) / s.amp_hb
    return X1, stopped
