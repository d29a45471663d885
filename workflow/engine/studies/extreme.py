"""Stiff and extreme cases: does every solve converge to the right answer or say why not?

A matrix run (issue 8) on any :class:`reduction.reduced.ReducedModel`: for
each *case* (a change of the penalty, friction, excitation, preload, gap,
resolution, frequency, wear or conditioning) and each formulation
(hbm / tcm / hdhb) and solver (newton / powell / pseudo-time), one
:class:`CaseResult`: converged or not, iterations, seconds, the error against
the limit the case must approach (where one exists) and a diagnosis naming
the cause when it did not converge (empty when it did).

Nothing here trusts a solver's "converged": :func:`verify` re-evaluates the
residual at the returned point, checks it is finite, that the DLFT periodic
passes converged there, and that the contact forces obey Coulomb and
unilaterality; a solve that fails any of these is reported as not converged
with that diagnosis. Non-finite numbers never reach the results (errors are
``None`` when there is nothing to compare).

Limits (all on the relative displacements U_r, harmonics ≥ 1 unless said;
``rel(a, b) = ‖a − b‖ / ‖b‖``):

* penalty ε·s, s ∈ 10⁻³…10³: DLFT's promise — the solution equals the one at
  s = 1 (all harmonics, including the static one);
* μ = 0: the *free* limit — λ_T ≡ 0; if the contact stays closed the normal
  relative motion is tied (U_N,j = 0, j ≥ 1) and the tangential one free:
  ``Z_TT U_T = F_T`` computed directly from Zr (:func:`free_limit`);
* μ → ∞ and excitation → 0: the *tied* limit U_r,j = 0 (j ≥ 1), measured
  relative to the free response at the same excitation;
* contact open all period (gap larger than the static approach, or preload
  pulling the blade out): the linear response without contact
  ``U_j = Zr_j⁻¹ Fr_j`` (all harmonics).

Units SI; frequencies in rad/s inside, Hz in the tables.
"""
from __future__ import annotations

import csv
import io
import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
import scipy.linalg

from reduction.condense import condense, relative_coordinates
from reduction.reduced import ReducedModel
from workflow.engine.contact import SEPARATION, SLIP, STICK, ContactLaw
from workflow.engine import fourier, penalty
from workflow.engine.linear import tied_modes
from workflow.engine.errors import BladewearError
from workflow.engine.hb import HBProblem
from workflow.engine.lumped import pairs_on_block

__all__ = ["GROUPS", "METHODS", "SOLVERS", "Settings", "Setup", "Case", "CaseResult", "synthetic_model",
           "setup", "build_cases", "run_case", "run_matrix", "verify", "free_limit", "tied_scale",
           "linear_open", "conditioning", "to_csv", "to_markdown", "tolerance", "free_first_order", "is_off",
           "off_without_diagnosis"]

METHODS = ("hbm", "tcm", "hdhb")
SOLVERS = ("newton", "powell", "pseudo-time")
GROUPS = ("penalty", "friction", "excitation", "contact", "resolution", "frequency", "wear", "conditioning",
          "divergence")


# ---------------------------------------------------------------- synthetic model

def synthetic_model(p: int = 4, *, preload: float = 0.5, k_contact: float = 2.0e6, extra_modes: int = 0,
                    spread: float = 1.0e3, seed: int = 0) -> ReducedModel:
    """A small :class:`ReducedModel` standing in for the FE one: p contact nodes on a rigid disk.

    DOFs: 3 per contact node (in its pair frame n, t1, t2; the disk side is
    rigid so ``u_r = u_node``), a root block (3) tied to each node by springs
    (~``k_contact`` N/m), a tip mass (1, along t1) on a bending spring (first
    tied mode ≈ 120 Hz) and ``extra_modes`` further masses hung from the
    block in a chain whose natural frequencies spread over ``spread`` (ratio
    highest/lowest): the ill-conditioned reduced model (many modes, widely
    spread frequencies). A weak ground spring keeps K regular when every pair
    separates. Static load: ``preload`` (N per pair) pushing each node into
    the disk (−n); harmonic load 0.1 N on the tip (t1) plus 0.03 N on the
    block (t2) and 0.02 N (n). Rayleigh damping ≈ 0.5 % on the first mode.
    """
    rng = np.random.default_rng(seed)
    mt = 0.05
    M, K, blk, tip = pairs_on_block(p, k_n=k_contact * 2.0, k_t=k_contact, scatter=(1.0, 0.3), m_node=2e-3,
                                    m_block=0.2, ground=1.0e2, m_tip=mt, k_tip=mt * (2 * np.pi * 120.0) ** 2,
                                    rng=rng, extra=extra_modes)
    nd = M.shape[0]
    prev = blk[1]
    for e in range(extra_modes):
        d = 3 * p + 4 + e
        f = 60.0 * spread ** (e / max(extra_modes - 1, 1))       # Hz, log-spread
        m = 1e-2 * spread ** (-e / max(extra_modes - 1, 1))      # lighter and stiffer up the chain
        M[d, d] = m
        k = m * (2 * np.pi * f) ** 2
        K[np.ix_([prev, d], [prev, d])] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
        prev = d
    w1 = 2 * np.pi * 120.0
    C = (0.005 / w1) * K + (0.005 * w1) * M
    B = np.zeros((3 * p, nd))
    B[:, : 3 * p] = np.eye(3 * p)
    f0 = np.zeros(nd)
    f0[0:3 * p:3] = -np.broadcast_to(np.asarray(preload, dtype=float), (p,))
    f1 = np.zeros(nd)
    f1[tip] = 0.1
    f1[blk[2]] = 0.03
    f1[blk[0]] = 0.02
    O = np.zeros((1, nd))
    O[0, tip] = 1.0
    pos = np.zeros((p, 3))
    pos[:, 0] = np.linspace(0.0, 0.04, p)
    return ReducedModel(M=M, K=K, C=C, B=B, f_static=f0, f_harmonic=f1, O=O, area=np.full(p, 1e-6),
                        gap=np.zeros(p), flank=(np.arange(p) >= p // 2).astype(int), position=pos,
                        info={"synthetic": True, "extra_modes": extra_modes, "spread": spread})


# ---------------------------------------------------------------- set-up

@dataclass
class Settings:
    """What the matrix runs with (from the scene's [contact], [hb], [extreme], [excitation])."""

    mu: float = 0.5
    eps_n: float = 0.0           # 0: reference stiffness (see :func:`setup`)
    eps_t: float = 0.0
    gap: float = 0.0             # added to the model's gaps (m)
    max_passes: int = 30
    amplitude: float = 0.1       # N: the excitation the model's f_harmonic stands for
    nh: int = 3
    nit: int = 32
    frequency_ratio: float = 0.97  # ω / ω_tied of the base cases
    tol: float = 1e-8
    max_iterations: int = 100
    pseudo_steps: int = 400
    methods: tuple = METHODS
    solvers: tuple = SOLVERS
    groups: tuple = GROUPS
    max_harmonics: int = 31
    max_time_samples: int = 1024
    penalty_decades: int = 3
    excitation_factors: tuple = (1e-6, 1e-4, 1e-2, 1.0, 1e1, 1e2, 1e3)
    wear_blocks: int = 30        # reference march: blocks at most
    wear_k: float = 1e-11        # m²/N: "very large" Archard coefficient (paper-like: 1e-13)
    extra_modes: int = 12        # conditioning case (synthetic models only)
    spread: float = 1e3


@dataclass
class Setup:
    """The model and what every case derives from it."""

    model: ReducedModel
    rc: object
    settings: Settings
    omega_tied: float            # rad/s, first tied resonance (pole of Zr)
    omega_free: float            # rad/s, free-interface resonance nearest above it (zero of Zr)
    omega: float                 # rad/s, base frequency
    eps_ref: np.ndarray          # (p, 2) [ε_N, ε_T] per pair: the reference stiffness (N/m)

    @property
    def p(self) -> int:
        return self.model.n_pairs


def _eig_freqs(K, M) -> np.ndarray:
    w2 = scipy.linalg.eigh(K, M, eigvals_only=True)
    return np.sqrt(np.maximum(w2, 0.0))


def setup(model: ReducedModel, settings: Settings | None = None) -> Setup:
    """Relative coordinates, reference frequencies and penalty of ``model``.

    * ω_tied: lowest eigenfrequency of the structure with the interface tied
      (the y–y block of the relative coordinates; Zr has a pole there,
      bounded only by damping) — "at resonance";
    * ω_free: the free-interface eigenfrequency (the whole K, M) nearest
      above 1.05 ω_tied (Zr is singular there up to damping; the response
      of the separated/slipping structure resonates) — "anti-resonance" of
      the tied response seen from the interface;
    * ε_ref: each pair's static condensed stiffness
      (:func:`workflow.engine.penalty.reference_stiffness`, the bounds of the
      application's automatic penalty are multiples of it), so the penalty
      cases span ε/k = 10⁻³…10³ around the interface's own stiffness; the
      automatic penalty lies between 1× (the dovetail) and 10³× (a bare mass).
    """
    s = settings or Settings()
    model.validate()
    rc = relative_coordinates(model)
    ft = 2 * np.pi * tied_modes(rc)[0]      # the FRF's and the wear's tied frequencies, not a second eigh
    omega_tied = float(ft[ft > 1e-6 * max(ft.max(), 1.0)][0])
    ff = _eig_freqs(rc.K, rc.M)
    above = ff[ff > 1.05 * omega_tied]
    omega_free = float(above[0]) if above.size else 2.0 * omega_tied
    omega = s.frequency_ratio * omega_tied
    eps_ref = penalty.reference_stiffness(condense(rc, 0.0, 0).Zr[0])
    return Setup(model=model, rc=rc, settings=s, omega_tied=omega_tied, omega_free=omega_free,
                 omega=omega, eps_ref=eps_ref)


# ---------------------------------------------------------------- cases

@dataclass
class Case:
    """One point of the matrix (before choosing method and solver).

    ``limit``: how the error is measured — "penalty" (vs the ε = 1× solution
    of the same method/solver), "free", "tied", "open" (linear response
    without contact), or "" (no limit: converge or diagnose).
    """

    name: str
    group: str
    omega: float
    mu: float
    eps_scale: float = 1.0
    force_scale: float = 1.0          # × f_harmonic
    static_scale: float = 1.0         # × f_static
    gap: float | np.ndarray = 0.0     # added to model gaps (m)
    nh: int | None = None
    nit: int | None = None
    limit: str = ""
    maxiter: int | None = None        # override (divergence cases)
    pseudo: dict = field(default_factory=dict)   # options for the pseudo-time solver
    wear: dict | None = None          # wear cases: {"k_w": …, "mode": …}
    model: ReducedModel | None = None  # a different model (conditioning)
    scaled: bool = False              # solve with row/column scaling
    note: str = ""


def _static_free_normal(su: Setup) -> np.ndarray:
    """Normal relative displacement (p,) of the static state without contact (m)."""
    c = condense(su.rc, su.omega, 0)
    u0 = np.linalg.solve(np.real(c.Zr[0]), np.real(c.Fr[0]))
    return u0.reshape(-1, 3)[:, 0]


def build_cases(su: Setup) -> list[Case]:
    """The case list of issue 8 for this model, restricted to ``settings.groups``."""
    s = su.settings
    w = su.omega
    mu = s.mu
    out: list[Case] = []
    g = set(s.groups)
    if "penalty" in g:
        for e in range(-s.penalty_decades, s.penalty_decades + 1):
            out.append(Case(f"penalty-1e{e:+d}", "penalty", w, mu, eps_scale=10.0 ** e, limit="penalty"))
    if "friction" in g:
        out += [Case("mu-0", "friction", w, 0.0, limit="free"),
                Case("mu-1e-4", "friction", w, 1e-4, limit="free"),
                Case("mu-0.5", "friction", w, 0.5),
                Case("mu-1e4", "friction", w, 1e4, limit="tied")]
    if "excitation" in g:
        for f in s.excitation_factors:
            out.append(Case(f"force-{f:.0e}", "excitation", w, mu, force_scale=f,
                            limit="tied" if f <= 1e-6 else "",
                            note=f"{f * s.amplitude:.3g} N"))
    if "contact" in g:
        u0 = _static_free_normal(su)          # < 0: the preload pushes the blade into the disk
        approach = float(np.max(-u0))
        out += [Case("no-preload", "contact", w, mu, static_scale=0.0,
                     note="grazing at rest: the excitation opens and closes the contact"),
                Case("lift-off", "contact", w, mu, static_scale=-1.0, limit="open",
                     note="static load pulls the blade out: contact open all period"),
                Case("grazing", "contact", w, mu, gap=-u0, note="gap = static approach: zero normal force"),
                Case("gap-open", "contact", w, mu, gap=-u0 + 10.0 * approach + 1e-9, limit="open",
                     note="gap far larger than the static approach"),
                Case("gap-small", "contact", w, mu, gap=0.5 * approach, note="initial gap, closes under preload"),
                Case("interference", "contact", w, mu, gap=-approach, note="initial interference")]
    if "resolution" in g:
        nh_hi = s.max_harmonics
        out += [Case(f"nh-{nh_hi}", "resolution", w, mu, nh=nh_hi, nit=max(2 * nh_hi + 2, 64)),
                Case(f"nit-{s.max_time_samples}", "resolution", w, mu, nit=s.max_time_samples)]
    if "frequency" in g:
        out += [Case("at-resonance", "frequency", su.omega_tied, mu, note="first tied resonance: Zr pole"),
                Case("at-anti-resonance", "frequency", su.omega_free, mu,
                     note="free-interface resonance: Zr singular")]
    if "wear" in g:
        out += [Case("wear-large-k", "wear", w, mu, wear={"k_w": s.wear_k, "mode": "steady"},
                     note="huge Archard coefficient: steady state in a few blocks"),
                Case("wear-opens", "wear", w, mu, force_scale=30.0, static_scale=0.02,
                     wear={"k_w": 10.0 * s.wear_k, "mode": "open"},
                     note="light preload, gross slip: wear opens the contact")]
    if "conditioning" in g and su.model.info.get("synthetic"):
        ill = synthetic_model(su.p, extra_modes=s.extra_modes, spread=s.spread)
        out += [Case("ill-conditioned", "conditioning", w, mu, model=ill,
                     note=f"{s.extra_modes} extra modes over ×{s.spread:g} in frequency, unscaled"),
                Case("ill-conditioned-scaled", "conditioning", w, mu, model=ill, scaled=True,
                     note="same, residual / ‖F‖ and unknowns / characteristic displacement")]
    elif "conditioning" in g:
        out += [Case("conditioning", "conditioning", w, mu, note="this model, unscaled"),
                Case("conditioning-scaled", "conditioning", w, mu, scaled=True, note="this model, scaled")]
    if "divergence" in g:
        out += [Case("diverge-maxiter", "divergence", w, mu, force_scale=100.0, maxiter=1,
                     pseudo={"max_steps": 2}, note="deliberately starved of iterations"),
                Case("diverge-explicit", "divergence", su.omega_tied, mu, force_scale=10.0,
                     pseudo={"scheme": "rk4", "cfl": 3.0, "precond": "none"},
                     note="explicit pseudo-time at 3× its stability limit")]
    return out


# ---------------------------------------------------------------- results

@dataclass
class CaseResult:
    """One row of the matrix."""

    name: str
    group: str
    method: str
    solver: str
    converged: bool
    iterations: int
    seconds: float
    error: float | None
    diagnosis: str
    tolerance: float | None = None     # how far from its limit a right solution may be (see :func:`tolerance`)
    residual: float | None = None      # ‖R‖/‖F‖ at the end
    separated: float | None = None     # fraction of (instant, pair) separated
    slipping: float | None = None
    sticking: float | None = None
    cond: float | None = None          # condition number of the final Jacobian (as solved)
    note: str = ""
    x: np.ndarray | None = field(default=None, repr=False)
    U: np.ndarray | None = field(default=None, repr=False)

    def row(self) -> dict:
        keys = ("name", "group", "method", "solver", "converged", "iterations", "seconds", "error",
                "tolerance", "diagnosis", "residual", "separated", "slipping", "sticking", "cond", "note")
        return {k: _clean(getattr(self, k)) for k in keys}


def _clean(v):
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    return v


# ---------------------------------------------------------------- building a problem

def _model_for(su: Setup, case: Case):
    if case.model is None:
        return su.model, su.rc
    return case.model, relative_coordinates(case.model)


def _law(su: Setup, case: Case, model: ReducedModel) -> ContactLaw:
    s = su.settings
    p = model.n_pairs
    ref = su.eps_ref if model is su.model else penalty.reference_stiffness(
        condense(relative_coordinates(model), 0.0, 0).Zr[0])
    eN = s.eps_n if s.eps_n > 0 else ref[:, 0]
    eT = s.eps_t if s.eps_t > 0 else ref[:, 1]
    gap = np.asarray(model.gap, dtype=float) + s.gap + np.broadcast_to(case.gap, (p,))
    return ContactLaw(mu=np.full(p, case.mu), eps_n=eN * case.eps_scale, eps_t=eT * case.eps_scale, gap=gap)


def condensed(su: Setup, case: Case):
    """(Zr, Fr) of the case: the condensation at ω with loads scaled (Nh+1 harmonics)."""
    model, rc = _model_for(su, case)
    nh = su.settings.nh if case.nh is None else case.nh
    c = condense(rc, case.omega, nh)
    Zr, Fr = c.Zr.copy(), c.Fr.copy()
    Fr[0] = np.real(Fr[0]) * case.static_scale
    Fr[1:] *= case.force_scale
    return model, Zr, Fr, nh


def problem(su: Setup, case: Case, method: str) -> HBProblem:
    """The HB problem of one case and method."""
    s = su.settings
    model, Zr, Fr, nh = condensed(su, case)
    nit = s.nit if case.nit is None else case.nit
    nit = max(nit, 2 * nh + 1)
    if method == "hdhb":
        nit = 2 * nh + 1
    law = _law(su, case, model)
    return HBProblem(Zr, Fr, law, nh, nit, method, max_passes=s.max_passes)


# ---------------------------------------------------------------- limits

def constrained_response(Zr: np.ndarray, Fr: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """Linear response for harmonics ≥ 1 (Nh+1, 3p) with the relative DOFs ``fixed`` (bool, 3p)
    held at 0 and the others free of contact force: ``Z_ff,j U_f,j = F_f,j``; row 0 left zero."""
    nh1, r = Fr.shape
    free = ~np.asarray(fixed, dtype=bool)
    U = np.zeros((nh1, r), dtype=complex)
    if free.any():
        for j in range(1, nh1):
            U[j, free] = np.linalg.solve(Zr[j][np.ix_(free, free)], Fr[j, free])
    return U


def free_limit(Zr: np.ndarray, Fr: np.ndarray, open_pairs: np.ndarray | None = None) -> np.ndarray:
    """μ = 0 limit for harmonics ≥ 1: normal tied on closed pairs, everything else free.

    ``open_pairs`` (bool, p): pairs separated all period (free in all directions); default none.
    """
    r = Fr.shape[1]
    fixed = np.zeros(r, dtype=bool)
    fixed[0::3] = True
    if open_pairs is not None:
        fixed[0::3] &= ~np.asarray(open_pairs, dtype=bool)
    return constrained_response(Zr, Fr, fixed)


def free_first_order(prob0: HBProblem, x0: np.ndarray, mu: float) -> np.ndarray:
    """O(μ) correction (Nh+1, 3p) of the free limit for a small μ > 0 (harmonics ≥ 1; row 0 zero).

    ``prob0``/``x0``: the μ = 0 HB problem and its root (normal tied on closed pairs, λ_T ≡ 0).
    To first order in μ every closed pair slips along the free motion with the Coulomb force
    ``λ_T(t) = μ |λ_N(t)| v_T/‖v_T‖`` (λ_N, v_T of the μ = 0 root; R = Zr U + λ − F, so −λ_T opposes
    the slip velocity); the correction is the free limit's response to −λ_T,
    ``Z_ff,j δU_f,j = −Λ_T,f,j``. The μ > 0 solution lies at ``free + δU + O(μ²)``: how far μ is from
    "small" is ``‖δU‖/‖U_free‖`` (it is ∝ μ·|λ_N|, the static normal force, not μ alone).
    """
    lam = prob0.contact_time(x0)                                     # (nit, p, 3)
    U = prob0.harmonics(x0)
    v = fourier.to_time(fourier.derivative(U), prob0.nit).reshape(lam.shape)
    vT = v[..., 1:]
    nv = np.linalg.norm(vT, axis=-1, keepdims=True)
    closed = lam[..., :1] < 0.0
    with np.errstate(all="ignore"):
        dirn = np.where((nv > 0) & closed, vT / np.where(nv > 0, nv, 1.0), 0.0)
    lamT = np.zeros_like(lam)
    lamT[..., 1:] = mu * np.abs(lam[..., :1]) * dirn
    LT = fourier.to_freq(lamT.reshape(prob0.nit, -1), prob0.nh)
    return constrained_response(prob0.Zr, -LT, _free_fixed(prob0.Zr.shape[1] // 3, _open_pairs(prob0, x0)))


def _free_fixed(p: int, open_pairs) -> np.ndarray:
    fixed = np.zeros(3 * p, dtype=bool)
    fixed[0::3] = True
    if open_pairs is not None:
        fixed[0::3] &= ~np.asarray(open_pairs, dtype=bool)
    return fixed


def tied_limit(Zr: np.ndarray, Fr: np.ndarray, open_pairs: np.ndarray | None = None) -> np.ndarray:
    """μ → ∞ / excitation → 0 limit for harmonics ≥ 1: closed pairs tied (U = 0), open pairs free."""
    p = Fr.shape[1] // 3
    closed = np.ones(p, dtype=bool) if open_pairs is None else ~np.asarray(open_pairs, dtype=bool)
    return constrained_response(Zr, Fr, np.repeat(closed, 3))


def linear_open(Zr: np.ndarray, Fr: np.ndarray) -> np.ndarray:
    """Response without contact forces, ``U_j = Zr_j⁻¹ Fr_j`` (Nh+1, 3p), all harmonics."""
    U = np.empty(Fr.shape, dtype=complex)
    for j in range(Fr.shape[0]):
        Z = np.real(Zr[j]) if j == 0 else Zr[j]
        U[j] = np.linalg.solve(Z, Fr[j])
    return U


def tied_scale(Zr: np.ndarray, Fr: np.ndarray) -> float:
    """Norm of the free-limit harmonics ≥ 1 (m): the yardstick of "U ≈ 0" (tied limit)."""
    return float(np.linalg.norm(free_limit(Zr, Fr)[1:]))


def _open_pairs(prob: HBProblem, x) -> np.ndarray:
    """Pairs separated during the whole period at x (bool, p)."""
    return np.all(prob.contact_state(x) == SEPARATION, axis=0)


def _rel(a, b, scale=None) -> float | None:
    d = float(np.linalg.norm(np.asarray(a) - np.asarray(b)))
    s = float(np.linalg.norm(b)) if scale is None else float(scale)
    if not math.isfinite(d) or not math.isfinite(s) or s <= 0:
        return None
    return d / s


# ---------------------------------------------------------------- verification

def verify(prob: HBProblem, x: np.ndarray, tol: float) -> tuple[bool, str, dict]:
    """Independent check of a claimed solution: (ok, diagnosis, facts).

    ok means: x finite; ‖R(x)‖ ≤ 10·tol·‖F‖ (a solver's own test is tol);
    the DLFT periodic passes converged at x; the corrected forces satisfy
    Coulomb ‖λ_T‖ ≤ μ|λ_N|(1 + 1e-9) and λ_N ≤ 0. ``facts``: ‖R‖/‖F‖,
    state fractions, DLFT passes.
    """
    facts: dict = {}
    x = np.array(x, dtype=float, copy=True)
    if not np.all(np.isfinite(x)):
        return False, "non-finite unknowns", facts
    with np.errstate(all="ignore"):
        R = prob.residual(x)
    res = prob.last_dlft
    scale = prob.residual_scale()
    rel = float(np.linalg.norm(R)) / scale
    facts["residual"] = rel
    facts["passes"] = res.passes
    st = res.state
    facts["separated"] = float(np.mean(st == SEPARATION))
    facts["slipping"] = float(np.mean(st == SLIP))
    facts["sticking"] = float(np.mean(st == STICK))
    sep = st == SEPARATION
    facts["intermittent"] = float(np.mean(np.any(sep, axis=0) & ~np.all(sep, axis=0)))   # pairs that open and close
    facts["open_pairs"] = int(np.sum(np.all(sep, axis=0)))
    if not math.isfinite(rel):
        return False, "non-finite residual at the returned point", facts
    if not res.converged:
        return False, (f"DLFT stick reference not periodic after {res.passes} passes "
                       f"(change {res.ref_change:.2e} N; raise contact.max_passes)"), facts
    lam = res.lam
    mu = prob.law.mu
    nT = np.sqrt(lam[..., 1] ** 2 + lam[..., 2] ** 2)
    if np.any(lam[..., 0] > 0) or np.any(nT > mu[None, :] * np.abs(lam[..., 0]) * (1 + 1e-9) + 1e-300):
        return False, "contact forces violate Coulomb or unilaterality", facts
    if rel > 10.0 * tol:
        return False, f"residual ‖R‖/‖F‖ = {rel:.2e} above the tolerance {tol:.0e}", facts
    return True, "", facts


# ---------------------------------------------------------------- scaling

def scaling(prob: HBProblem, x0: np.ndarray, J0: np.ndarray | None = None):
    """Row and column scalings (r, c) of the residual: R̂(z) = r ⊙ R(c ⊙ z).

    Rows: 1/‖F‖ per unknown block … refined by one equilibration pass, so the
    scaled Jacobian diag(r) J diag(c) has unit row and column max-norms;
    columns: a characteristic displacement per unknown. Returned as
    positive (n,) arrays.
    """
    if J0 is None:
        _, J0 = prob.residual_jacobian(x0)
    A = np.abs(J0)
    c = 1.0 / np.sqrt(np.maximum(A.max(axis=0), 1e-300))     # characteristic displacement ~ 1/√k
    A = A * c[None, :]
    r = 1.0 / np.maximum(A.max(axis=1), 1e-300)
    A = A * r[:, None]
    c2 = 1.0 / np.maximum(A.max(axis=0), 1e-300)
    return r, c * c2


def conditioning(prob: HBProblem, x: np.ndarray) -> tuple[float, float]:
    """cond₂(J) and cond₂ of the scaled J at x (see :func:`scaling`)."""
    _, J = prob.residual_jacobian(x)
    r, c = scaling(prob, x, J)
    with np.errstate(all="ignore"):
        return float(np.linalg.cond(J)), float(np.linalg.cond(r[:, None] * J * c[None, :]))


# ---------------------------------------------------------------- one solve

def _solve(prob: HBProblem, x0, solver: str, *, tol: float, maxiter: int, pseudo: dict, scaled: bool):
    """Run one solver; returns (SolveResult in the problem's unknowns, cond of the final J as solved)."""
    from workflow.engine.pseudotime import integrate
    from workflow.engine.solvers import newton, powell

    scale = prob.residual_scale()
    if scaled:
        r, c = scaling(prob, x0)
        fun = lambda z: r * prob.residual(c * z)                       # noqa: E731
        fun_jac = lambda z: _scaled_rj(prob, r, c, z)                  # noqa: E731
        z0 = x0 / c
        # the convergence test stays on the true residual: ‖r⊙R‖ ≥ min(r)‖R‖
        sc = scale * float(np.min(r))
    else:
        c = None
        fun, fun_jac, z0, sc = prob.residual, prob.residual_jacobian, x0, scale
    if solver == "newton":
        res = newton(fun_jac, z0, fun=fun, tol=tol, scale=sc, maxiter=maxiter)
    elif solver == "powell":
        res = powell(fun, fun_jac, z0, tol=tol, scale=sc, maxfev=40 * maxiter)
    elif solver == "pseudo-time":
        opts = {"scheme": "ser", "precond": "jacobian", "max_steps": 400}
        opts.update(pseudo)
        if prob.method == "hdhb" and opts["scheme"] == "block-jacobi":
            opts.setdefault("blocks", prob.nit)
        res = integrate(fun, fun_jac, z0, tol=tol, scale=sc, **opts)
    else:
        raise ValueError(f"unknown solver {solver!r}")
    if scaled:
        res.x = c * res.x
    return res


def _scaled_rj(prob, r, c, z):
    R, J = prob.residual_jacobian(c * z)
    return r * R, r[:, None] * J * c[None, :]


def _diagnose(res, prob: HBProblem, x, solver: str, facts: dict, cond: float | None) -> str:
    """Name the most likely cause of a failed solve (measured at the final point)."""
    parts = [res.reason or "not converged"]
    if facts.get("residual") is not None:
        parts.append(f"‖R‖/‖F‖ = {facts['residual']:.1e}")
    sep = facts.get("separated") or 0.0
    inter = facts.get("intermittent") or 0.0
    if inter > 0.0:
        parts.append(f"{inter:.0%} of the pairs open and close within the period: stalled at a kink of the "
                     "piecewise-smooth residual (separation/contact switches)")
    if sep >= 1.0:
        parts.append("contact open everywhere (is the blade held without it?)")
    elif facts.get("open_pairs"):
        parts.append(f"{facts['open_pairs']} pair(s) open all period")
    if solver == "pseudo-time" and x is not None and prob.n <= 1500:
        try:
            _, J = prob.residual_jacobian(x)
            neg = int(np.sum(np.linalg.eigvals(J).real < 0))
        except (np.linalg.LinAlgError, ValueError):
            neg = 0
        if neg:
            parts.append(f"J has {neg} eigenvalue(s) with Re < 0 here: the steady state is not an attracting "
                         "equilibrium of ∂x/∂t* = −R (slipping pairs see the free-interface Zr, indefinite above "
                         "its resonances); use newton")
    if cond is not None and cond > 1e12:
        parts.append(f"ill-conditioned Jacobian (cond {cond:.1e})")
    if prob.stats.get("unconverged_passes"):
        parts.append(f"DLFT passes hit the limit {prob.stats['unconverged_passes']}×")
    return "; ".join(parts)


def run_case(su: Setup, case: Case, method: str, solver: str, reference: dict | None = None) -> CaseResult:
    """Solve one (case, method, solver) and measure it; never raises on numerical failure."""
    s = su.settings
    t0 = time.perf_counter()
    out = CaseResult(case.name, case.group, method, solver, False, 0, 0.0, None, "", note=case.note)
    try:
        if case.wear is not None:
            return _run_wear(su, case, method, solver, out, t0)
        prob = problem(su, case, method)
        with np.errstate(all="ignore"):
            x0 = prob.x0()
        if not np.all(np.isfinite(x0)):
            out.diagnosis = "initial guess not finite (static problem singular: the blade floats?)"
            out.seconds = time.perf_counter() - t0
            return out
        maxiter = s.max_iterations if case.maxiter is None else case.maxiter
        pseudo = dict(case.pseudo)
        pseudo.setdefault("max_steps", s.pseudo_steps)
        with np.errstate(all="ignore"):
            res = _solve(prob, x0, solver, tol=s.tol, maxiter=maxiter, pseudo=pseudo, scaled=case.scaled)
        out.iterations = int(res.iterations)
        x = res.x
        ok, why, facts = verify(prob, x, s.tol)
        cond = None
        try:
            if prob.n <= 1500:
                cj, cs = conditioning(prob, x)
                cond = cs if case.scaled else cj
                out.note = (out.note + "; " if out.note else "") + f"cond(J) {cj:.1e}, scaled {cs:.1e}"
        except (np.linalg.LinAlgError, ValueError):
            pass
        out.cond = cond
        out.residual = facts.get("residual")
        out.separated, out.slipping, out.sticking = (facts.get("separated"), facts.get("slipping"),
                                                     facts.get("sticking"))
        if res.converged and ok:
            out.converged = True
        elif res.converged:
            out.diagnosis = f"solver claimed convergence but {why}"
        else:
            out.diagnosis = _diagnose(res, prob, x if np.all(np.isfinite(x)) else None, solver, facts, cond) \
                if not why.startswith("DLFT") else f"{res.reason}; {why}"
        if np.all(np.isfinite(x)):
            out.x = x
            out.U = prob.harmonics(x)
        if out.converged:
            info: dict = {}
            out.error = _error(su, case, prob, out.U, reference, info)
            out.tolerance = tolerance(su, case, info.get("delta"))
            if out.error is not None and out.tolerance is not None and out.error > out.tolerance:
                try:
                    _explain_off(su, case, prob, x, solver, out, reference, info, facts)
                except Exception as exc:          # noqa: BLE001 — an off row never goes out without a diagnosis
                    out.diagnosis = (f"converged {out.error:.2g} from the reference (tolerance {out.tolerance:.1g}); "
                                     f"diagnosing it failed: {type(exc).__name__}: {exc}")
    except (np.linalg.LinAlgError, FloatingPointError, ValueError, BladewearError) as exc:
        out.diagnosis = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    out.seconds = time.perf_counter() - t0
    return out


TOL_LIMIT = 100.0          # × settings.tol: free (μ = 0), tied and open limits (a verified root: ‖R‖/‖F‖ ≤ 10·tol)
TOL_PENALTY = 1e-4         # penalty cases: the ε = 1× solution, to the accuracy of two solves
FIRST_ORDER_SMALL = 0.1    # "μ small": the O(μ) distance to the free limit below 10 % of it


def tolerance(su: Setup, case: Case, delta: float | None = None) -> float | None:
    """How far from its reference a right solution of ``case`` may be (relative, as the error).

    free (μ = 0), tied, open: ``TOL_LIMIT·tol``. free at μ > 0: that plus 2δ, δ = ‖δU‖/‖U_free‖ the
    first-order distance (:func:`free_first_order`) — but at most 2·``FIRST_ORDER_SMALL``: a case whose
    δ is larger is not near its limit, and is diagnosed as such. penalty: ``max(TOL_PENALTY, 10⁴·tol)``.
    None: no limit.
    """
    t = su.settings.tol
    if case.limit in ("free", "tied", "open"):
        base = TOL_LIMIT * t
        if case.limit == "free" and case.mu > 0 and delta is not None:
            return base + 2.0 * min(delta, FIRST_ORDER_SMALL)
        return base
    if case.limit == "penalty":
        return max(TOL_PENALTY, 1e4 * t)
    return None


def _free_root(su: Setup, case: Case, method: str):
    """The μ = 0 HB root of the case (problem, x) by Newton, or (problem, None) if it fails verification."""
    from workflow.engine.solvers import newton

    p0 = problem(su, replace(case, mu=0.0), method)
    x0 = p0.x0()
    r = newton(p0.residual_jacobian, x0, fun=p0.residual, tol=su.settings.tol,
               scale=p0.residual_scale(), maxiter=su.settings.max_iterations)
    ok, _, _ = verify(p0, r.x, su.settings.tol)
    return p0, (r.x if r.converged and ok else None)


def _error(su: Setup, case: Case, prob: HBProblem, U: np.ndarray, reference: dict | None,
           info: dict | None = None) -> float | None:
    """Relative distance of U to the case's reference; ``info`` gets what the diagnosis needs
    (free limit at μ > 0: δ, the μ = 0 root's open pairs and friction force)."""
    info = {} if info is None else info
    if case.limit == "penalty":
        ref = (reference or {}).get("penalty")
        if ref is None:
            return None
        # a fully stuck interface has U ≡ 0: measure against the free-response yardstick then
        return _rel(U, ref, scale=max(float(np.linalg.norm(ref)), tied_scale(prob.Zr, prob.Fr)))
    if case.limit in ("free", "tied"):
        x = prob.unknowns_from_harmonics(U)
        op = _open_pairs(prob, x)
        if case.limit == "free":
            Uf = free_limit(prob.Zr, prob.Fr, op)
            info["open"] = int(np.sum(op))
            if case.mu > 0:
                p0, x0 = _free_root(su, case, prob.method)
                if x0 is not None:
                    op0 = _open_pairs(p0, x0)
                    Uf0 = free_limit(p0.Zr, p0.Fr, op0)
                    dU = free_first_order(p0, x0, case.mu)
                    nf = float(np.linalg.norm(Uf0[1:]))
                    lamN = np.abs(p0.contact_time(x0)[..., 0])
                    info.update(delta=float(np.linalg.norm(dU[1:])) / nf if nf > 0 else None,
                                open0=int(np.sum(op0)), friction=float(case.mu * lamN.max()),
                                mu0_distance=_rel(U[1:], p0.harmonics(x0)[1:]))
            return _rel(U[1:], Uf[1:])
        return _rel(U[1:], tied_limit(prob.Zr, prob.Fr, op)[1:], scale=tied_scale(prob.Zr, prob.Fr))
    if case.limit == "open":
        return _rel(U, linear_open(prob.Zr, prob.Fr))
    return None


def _explain_off(su: Setup, case: Case, prob: HBProblem, x: np.ndarray, solver: str, out: CaseResult,
                 reference: dict | None, info: dict, facts: dict) -> None:
    """A verified root farther from its reference than its tolerance: a wrong solution or a wrong reference?

    First Newton is run on from the returned point (tolerance 10⁻³·tol): if that moves the solution
    to within the tolerance, the returned point was not the solution (a solver stopping on its own
    step test — ‖F‖ can be dominated by the static load, so ‖R‖/‖F‖ ≤ 10·tol need not resolve the
    vibration) and the row becomes not converged. Otherwise the point is a root and the diagnosis
    names why it is not at the reference (μ not small, separation, ε-dependence, another root).
    """
    from workflow.engine.solvers import newton

    s = su.settings
    e, t = out.error, out.tolerance
    try:
        with np.errstate(all="ignore"):
            pol = newton(prob.residual_jacobian, np.array(x, dtype=float), fun=prob.residual,
                         tol=1e-3 * s.tol, scale=prob.residual_scale(), maxiter=10)
        ok, _, _ = verify(prob, pol.x, s.tol)
        e_p = _error(su, case, prob, prob.harmonics(pol.x), reference) if ok else None
        moved = _rel(prob.harmonics(pol.x)[1:], out.U[1:], scale=max(float(np.linalg.norm(out.U[1:])), 1e-300))
    except (np.linalg.LinAlgError, FloatingPointError, ValueError, BladewearError):
        e_p, moved, pol = None, None, None
    lim = {"free": "free limit (μ = 0)", "tied": "tied limit", "open": "open-contact linear response",
           "penalty": "ε = 1× solution"}.get(case.limit, case.limit)
    head = f"converged {e:.2g} from the {lim} (tolerance {t:.1g})"
    if e_p is not None and e_p <= t:
        out.converged = False
        out.diagnosis = (f"{solver} stopped short of the root at ‖R‖/‖F‖ = {out.residual:.1e} ({head}): Newton "
                         f"from there reaches the reference (error {e_p:.1e}, {pol.iterations} iteration(s), "
                         f"U moved {moved:.1e}) — the returned point is not the solution; ‖F‖ is dominated "
                         "by the static load, so ‖R‖/‖F‖ ≤ 10·tol does not resolve the vibration")
        return
    where = ("Newton from the returned point stays there" if e_p is not None and moved is not None
             and moved <= t else "Newton from the returned point does not settle within the tolerance")
    p = prob.p
    inter = int(round((facts.get("intermittent") or 0.0) * p))
    opn = int(facts.get("open_pairs") or 0)
    if case.limit in ("free", "tied") and inter:
        out.diagnosis = (f"{head}: the limit assumes contact closed or open all period; the solution separates "
                         f"within the period on {inter} of {p} pairs; {where}")
        return
    if case.limit == "free" and case.mu > 0 and info.get("delta") is not None:
        d = info["delta"]
        if d > FIRST_ORDER_SMALL:
            mu_small = case.mu * 0.01 / d
            out.diagnosis = (f"{head}: the reference is not near — μ = {case.mu:g} is not small on this model: "
                             f"the O(μ) distance from the μ = 0 root is δ = {d:.2g} (Coulomb force μ|λ_N| up to "
                             f"{info['friction']:.3g} N: it scales with the static normal load, not μ alone); the free "
                             f"limit is approached for μ ≲ {mu_small:.1g} (δ = 1 %); {opn} of {p} pairs open all period"
                             f" (μ = 0: {info.get('open0')}), none opening within it; {where}")
        else:
            out.diagnosis = (f"{head}: farther than the first-order distance δ = {d:.2g} from the μ = 0 root "
                             f"(distance to it {info.get('mu0_distance') or float('nan'):.2g}); another root? {where}")
        return
    if case.limit == "penalty" and (facts.get("slipping") or 0.0) > 0.0:
        out.diagnosis = (f"{head}: ε-dependent root — {facts['slipping']:.0%} of (instant, pair) slip; DLFT's "
                         "ε-independence holds while pairs stick (HBM at nit > 2Nh+1: the truncated λ; small ε: "
                         f"reverse-slip roots; docs/solver-guide.md); {where}")
        return
    band = 10.0 * s.tol * prob.residual_scale()
    fh = float(np.linalg.norm(prob.Fr[1:]))
    if fh > 0 and band >= 1e-3 * fh:
        st = prob.static
        cone = int(np.sum(st.state == SLIP)) if st is not None else 0
        out.diagnosis = (f"{head}: the tolerance does not resolve the vibration — 10·tol·‖F‖ = {band:.1e} N against "
                         f"a harmonic load of {fh:.1e} N (‖F‖ is the static load), so points this far apart all "
                         f"pass verification; {cone} of {p} pairs slip at the static state (on the Coulomb cone, "
                         f"where the tied limit is not exact); {where}")
        return
    out.diagnosis = (f"{head}: {where} (another root, or a reference that does not apply here); "
                     f"{opn} of {p} pairs open all period, {inter} open and close")


# ---------------------------------------------------------------- wear

def _run_wear(su: Setup, case: Case, method: str, solver: str, out: CaseResult, t0: float) -> CaseResult:
    """Wear cases: the reference march (newton/powell rows: explicit/implicit) or pseudo-time (eq. 22)."""
    try:
        from workflow.engine import wear as wmod
    except ImportError as exc:
        out.diagnosis = f"not run: workflow/engine/wear not available ({exc})"
        out.seconds = time.perf_counter() - t0
        return out
    s = su.settings
    prob = problem(su, case, method)
    x0 = prob.x0()
    wp = wmod.WearProblem(prob, su.model.area if case.model is None else case.model.area, case.wear["k_w"])
    cycles = 1e5
    if solver == "pseudo-time":
        h = wmod.pseudo_time_wear(wp, x0, cycles_per_block=cycles, tol=s.tol, max_steps=s.pseudo_steps)
    else:
        scheme = "implicit" if solver == "powell" else "explicit"
        out.solver = f"march-{scheme}"
        h = wmod.march_reference(wp, x0, scheme=scheme, cycles_per_block=cycles, max_blocks=s.wear_blocks,
                                 tol=s.tol)
    out.iterations = int(h.iterations)
    W = np.asarray(h.W)
    if not np.all(np.isfinite(W)) or not np.all(np.isfinite(h.x)):
        out.diagnosis = "non-finite wear or unknowns"
    ok, why, facts = verify(prob, h.x, s.tol) if np.all(np.isfinite(h.x)) else (False, "non-finite", {})
    out.residual = facts.get("residual")
    out.separated, out.slipping, out.sticking = facts.get("separated"), facts.get("slipping"), facts.get("sticking")
    out.converged = bool(h.steady and ok)
    if not out.converged and not out.diagnosis:
        out.diagnosis = h.reason if not h.steady else f"wear steady but {why}"
    elif out.converged:
        rate = np.asarray(h.final_rate)
        out.error = float(np.max(rate) * cycles / max(float(np.max(W)), 1e-300)) if W.max() > 0 else 0.0
        # yardstick: the static normal relative displacement without contact (m)
        approach = float(np.max(np.abs(_static_free_normal(su))))
        if approach > 0 and W.max() > 10.0 * approach:
            out.converged = False
            out.diagnosis = (f"wear overshoot: max W = {W.max():.3g} m is {W.max() / approach:.3g}× the static "
                             "approach; the contact was opened by one long step, not by wear (the steady state "
                             "with zero rates is not the physical one)")
        sep = facts.get("separated", 0.0)
        out.note += f"; max W {W.max():.3e} m, separated {sep:.0%} of (instant, pair)"
    out.x = h.x
    out.seconds = time.perf_counter() - t0
    return out


# ---------------------------------------------------------------- the matrix

def run_matrix(su: Setup, cases: list[Case] | None = None, *, progress: Callable | None = None) -> list[CaseResult]:
    """All (case, method, solver) of the set-up; penalty errors against the 1× solution."""
    s = su.settings
    cases = build_cases(su) if cases is None else cases
    # wear cases: one formulation (the first) — the wear drivers are formulation-agnostic and slow
    jobs = [(c, m, v) for c in cases for m in (s.methods[:1] if c.wear is not None else s.methods)
            for v in s.solvers]
    # the ε = 1× solutions first: they are the penalty cases' reference
    order = sorted(range(len(jobs)), key=lambda i: not (jobs[i][0].limit == "penalty" and jobs[i][0].eps_scale == 1.0))
    refs: dict = {}
    results: dict[int, CaseResult] = {}
    it = progress(order, len(order)) if progress else order
    for i in it:
        case, method, solver = jobs[i]
        ref = refs.get((method, solver), refs.get(method))
        r = run_case(su, case, method, solver, reference={"penalty": ref})
        if case.limit == "penalty" and case.eps_scale == 1.0:
            if r.converged:
                refs[(method, solver)] = r.U
                refs.setdefault(method, r.U)
                r.error = 0.0
        results[i] = r
    return [results[i] for i in range(len(jobs))]


# ---------------------------------------------------------------- tables

_COLUMNS = ("name", "group", "method", "solver", "converged", "iterations", "seconds", "error", "tolerance",
            "diagnosis", "residual", "separated", "slipping", "sticking", "cond", "note")


def is_off(r: CaseResult) -> bool:
    """A converged solve farther from its reference than its tolerance (it must carry a diagnosis)."""
    return bool(r.converged and r.error is not None and r.tolerance is not None and r.error > r.tolerance)


def off_without_diagnosis(results: list[CaseResult]) -> int:
    """Converged solves farther from their reference than their tolerance with no diagnosis (must be 0)."""
    return sum(1 for r in results if is_off(r) and not r.diagnosis)


def to_csv(results: list[CaseResult]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=_COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in results:
        row = r.row()
        w.writerow({k: ("" if row[k] is None else (f"{row[k]:.6g}" if isinstance(row[k], float) else row[k]))
                    for k in _COLUMNS})
    return buf.getvalue()


def _fmt(v, spec=".2e") -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "**no**"
    if isinstance(v, float):
        return format(v, spec)
    return str(v)


def to_markdown(results: list[CaseResult], su: Setup | None = None) -> str:
    lines = ["# Stiff and extreme cases", ""]
    if su is not None:
        s = su.settings
        lines += [f"Model: {su.p} contact pairs, {su.model.size} reduced DOFs. Base: Nh = {s.nh}, nit = {s.nit}, "
                  f"f = {su.omega / 2 / np.pi:.2f} Hz ({s.frequency_ratio:g} × tied resonance "
                  f"{su.omega_tied / 2 / np.pi:.2f} Hz; free-interface resonance {su.omega_free / 2 / np.pi:.2f} Hz), "
                  f"μ = {s.mu:g}, ε_ref = ({su.eps_ref[:, 0].mean():.3g}, {su.eps_ref[:, 1].mean():.3g}) N/m (mean "
                  f"static stiffness per pair), tol = {s.tol:g}.", ""]
    n_ok = sum(r.converged for r in results)
    off = [r for r in results if is_off(r)]
    lines += [f"{n_ok} of {len(results)} solves converged (each verified independently: finite, "
              f"‖R‖/‖F‖ ≤ 10·tol, DLFT periodic, Coulomb and λ_N ≤ 0). Error: distance to the case's "
              f"reference; tol.: how far a right solution may be from it. {len(off)} converged solve(s) "
              f"farther than that, each with a diagnosis ({sum(not r.diagnosis for r in off)} without).", "",
              "| case | method | solver | conv. | iter. | s | error | tol. | ‖R‖/‖F‖ | sep/slip/stick | diagnosis |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        st = "–" if r.separated is None else f"{r.separated:.2f}/{r.slipping:.2f}/{r.sticking:.2f}"
        diag = (r.diagnosis or "").replace("|", "\\|")
        lines.append(f"| {r.name} | {r.method} | {r.solver} | {_fmt(r.converged)} | {r.iterations} | "
                     f"{r.seconds:.2f} | {_fmt(r.error)} | {_fmt(r.tolerance, '.0e')} | {_fmt(r.residual, '.1e')} | {st} | "
                     f"{diag} |")
    notes = {}
    for r in results:
        if r.note and r.name not in notes:
            notes[r.name] = r.note
    if notes:
        lines += ["", "Notes (first method/solver of each case):", ""]
        lines += [f"* **{k}**: {v}" for k, v in notes.items()]
    return "\n".join(lines) + "\n"
