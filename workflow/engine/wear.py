"""Archard fretting wear on the HB solution, to the worn steady state (paper eqs. 20–22).

Kernel (eq. 21/22b), vectorised over pairs: per cycle

    ΔW_i = k_w ∮ p_N,i |du_T,i|  ≈  k_w Σ_k ½(p_N,i(τ_k) + p_N,i(τ_{k−1})) ‖u_T,i(τ_k) − u_T,i(τ_{k−1})‖

(trapezoidal in the pressure, periodic wrap k−1 = −1 ↦ nit−1), with
``p_N = −λ_N / A_i ≥ 0`` [Pa] (contracts §6: λ_N < 0 in contact), A_i the
tributary area [m²], k_w [m²/N = 1/Pa], u_T the tangential slip path [m].
The slip path is the DLFT corrected displacement ``X_T = λ_x^T / ε_T``
(eq. 11, :mod:`workflow.engine.contact`): it is *bit-for-bit constant* while a pair
sticks, so stick contributes exactly nothing and a fully stuck interface has
a rate of exactly 0. (The band-limited U_r of the HB unknowns wiggles during
stick and would wear a stuck pair.) During separation p_N = 0.

W (per pair, total depth, m) opens the normal gap ``g = u_N + gap + W``; it
is shared between flanks, ``W_blade = share·W``, ``W_disk = (1 − share)·W``.

Two ways to the worn steady state (where every rate is 0):

* reference (paper refs. 5, 7): march in physical time by blocks of N cycles;
  per block solve the HB problem at the current W (Newton, warm start), then
  ``W += N·rate`` (explicit) or solve ``W⁺ = W + N·rate(x(W⁺), W⁺)`` by
  Newton on W with the exact sensitivity ``d rate/dW = ∂rate/∂W −
  ∂rate/∂x J⁻¹ ∂R/∂W`` (implicit).
* pseudo-time (eq. 22): integrate the augmented system ``R(x; W) = 0``,
  ``∂W/∂t* = rate(x; W)`` along the wear trajectory, t* in *cycles* (the
  wear equation is eq. 21 as is, so the pseudo-time W history is comparable
  with the physical one, Figs. 11–12). The vibration is the fast time scale
  of the dual time stepping, slaved to W (pseudo-time mass → 0): each step is
  one linearly implicit (Rosenbrock–Euler) step of the whole system with its
  exact Jacobian — a Newton step on x and an implicit Euler step on W — with
  error control on W (:func:`pseudo_time_wear`). J is factored once per
  state and Δx eliminated, so each step length tried costs a p × p solve —
  or, from Newton's structured size up, J is never formed and each step is one
  GMRES solve with the HB Jacobian's own structure (:mod:`workflow.engine.wear_structured`).

Both stop when the wear still to come, extrapolated from the decay of the
largest rate (:func:`remaining_wear`), is at most ``steady_tol·max W``.
"""
from __future__ import annotations

import inspect
import math
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.linalg
import scipy.sparse.linalg

from workflow.engine import fourier
from workflow.engine.errors import SolverError
from workflow.engine.solvers import newton

#: times the reference march halves a block whose HB solve fails before it stops
MAX_BLOCK_HALVINGS = 4
#: the implicit reference block's wear equation ``W_n = W + N·rate(W_n)`` holds to this
#: fraction of max W when the block is accepted (:func:`_reference_block`)
W_EQ_TOL = 1e-6

__all__ = ["slip_increments", "wear_per_cycle", "pressure", "WearProblem", "WearState", "WearHistory",
           "march_reference", "pseudo_time_wear", "profile_rel_diff", "tip_cycle"]


# ------------------------------------------------------------------ kernel

def pressure(lam: np.ndarray, area: np.ndarray) -> np.ndarray:
    """Contact pressure ``p_N = −λ_N/A ≥ 0`` [Pa], (nit, p), from λ (nit, p, 3) [N] and A (p,) [m²]."""
    return np.maximum(-np.asarray(lam)[..., 0], 0.0) / np.asarray(area, dtype=float)


def slip_increments(uT: np.ndarray) -> np.ndarray:
    """``‖u_T(τ_k) − u_T(τ_{k−1})‖`` (nit, p) [m] of a tangential path (nit, p, 2), periodic wrap."""
    uT = np.asarray(uT, dtype=float)
    d = uT - np.roll(uT, 1, axis=0)
    return np.sqrt(np.sum(d * d, axis=-1))


def wear_per_cycle(lam: np.ndarray, uT: np.ndarray, area, k_w: float) -> np.ndarray:
    """Archard wear depth per cycle ΔW (p,) [m/cycle] (eq. 21, 22b).

    lam : (nit, p, 3) multipliers λ over one period [N] (λ_N < 0 in contact).
    uT  : (nit, p, 2) tangential slip path [m] (or (nit, p, 3) relative
          displacements [n, t1, t2], whose normal part is dropped).
    area: (p,) tributary areas [m²]; k_w: Archard coefficient [m²/N].
    """
    uT = np.asarray(uT, dtype=float)
    if uT.shape[-1] == 3:
        uT = uT[..., 1:]
    p = pressure(lam, area)
    ds = slip_increments(uT)
    return k_w * np.sum(0.5 * (p + np.roll(p, 1, axis=0)) * ds, axis=0)


# ------------------------------------------------------------------ coupled problem

@dataclass
class WearState:
    """One evaluation of the wear problem at (x, W)."""

    R: np.ndarray                 # HB residual (n,) [N]
    rate: np.ndarray              # wear depth per cycle (p,) [m/cycle]
    lam: np.ndarray               # (nit, p, 3) [N]
    slip: np.ndarray              # (nit, p, 2) X_T [m]
    J: np.ndarray | None = None   # ∂R/∂x (n, n)
    R_W: np.ndarray | None = None  # ∂R/∂W (n, p)
    G_x: np.ndarray | None = None  # ∂rate/∂x (p, n)
    G_W: np.ndarray | None = None  # ∂rate/∂W (p,) (diagonal: a pair's rate sees only its own W)
    #: (J⁻¹R, J⁻¹∂R/∂W, ∂rate/∂x·J⁻¹R, ∂rate/∂x·J⁻¹∂R/∂W, LU of J) once per state, or False if J is
    #: singular (:func:`_newton_parts`)
    newton_parts: tuple | bool | None = None
    #: the same derivatives without (n × n) or (n × p) arrays (:mod:`workflow.engine.wear_structured`;
    #: kept beside the formed ones too): J = ``hb.operator(G)``; ∂rate_i/∂x = g_i · ∂a_i/∂x (g
    #: before any averaging of the rates); ∂R/∂W column i = w_i on pair i's rows
    G: np.ndarray | None = None   # contact blocks (p, 3nc, 3nc) (HBProblem.contact_blocks)
    g: np.ndarray | None = None   # ∂rate_i/∂a_i (p, 3nc) [m/cycle per N]
    w: np.ndarray | None = None   # ∂R/∂W_i on pair i's rows (p, 3nc) [N/m]

    @property
    def has_jacobian(self) -> bool:
        return self.J is not None or self.G is not None


class WearProblem:
    """An :class:`workflow.engine.hb.HBProblem` plus Archard wear on its pairs.

    hb    the HB problem (any method); its contact law's W is driven from here
    area  (p,) tributary areas [m²]; k_w [m²/N]; share: blade fraction of W.

    Adapter note: the wear rate's derivatives need the DLFT sensitivities of
    the evaluation (``hb.last_dlft`` with ``dlam``, :class:`DLFTResult`), the
    predictor map ``a = a_F − A y + ε(y + shift)`` (``hb.A``, ``hb.basis``,
    the law's ε) and the per-pair contact blocks of the residual
    (:meth:`HBProblem.contact_blocks`, :meth:`HBProblem.apply_contact_blocks`).
    """

    def __init__(self, hb, area, k_w: float, share: float = 0.5, eps_path=(), structured: bool | None = None,
                 averaging=None):
        from workflow.engine import wear_structured

        self.hb = hb
        #: (p, p) row-stochastic averaging of the frictional power over a length (the wear law
        #: with a length scale, :func:`averaging`), or None: the node-wise law (eq. 21). It
        #: couples pairs, so the march forms J (the matrix-free step's rank-one pair blocks assume
        #: a pair's rate depends on its own pair alone).
        self.averaging = None if averaging is None else np.asarray(averaging, dtype=float)
        if self.averaging is not None:
            structured = False
        #: the linear algebra of the HB solves and pseudo-time steps: matrix-free J and GMRES
        #: (True), or J formed and factored (False; the implicit reference march always forms
        #: it); None: by size (:func:`workflow.engine.wear_structured.use`)
        self.structured = wear_structured.use(hb.n) if structured is None else bool(structured)
        #: :func:`workflow.engine.cascade.along_eps_path` factors for vibration solves
        #: that plain Newton does not finish (large ε shrinks its basin)
        self.eps_path = tuple(eps_path)
        self.area = np.broadcast_to(np.asarray(area, dtype=float), (hb.p,)).copy()
        if np.any(self.area <= 0):
            raise SolverError("wear: pair areas must be > 0")
        self.k_w = float(k_w)
        self.share = float(share)
        self.p, self.n, self.nc, self.nit, self.nr = hb.p, hb.n, hb.nc, hb.nit, hb.nr
        # constant-in-time vector in the predictor space (e0 for coefficients, ones for samples)
        self._const = np.linalg.lstsq(hb.basis, np.ones(hb.nit), rcond=None)[0]
        self._const[np.abs(self._const) < 1e-12] = 0.0
        # rows of the predictor a (nc, p, 3) belonging to pair i: index j·3p + 3i + c at column 3j + c
        j = np.arange(self.nc)[:, None, None]
        i = np.arange(self.p)[None, :, None]
        c = np.arange(3)[None, None, :]
        self._rows = (j * self.nr + 3 * i + c).transpose(1, 0, 2).reshape(self.p, 3 * self.nc)
        self.evaluations = 0

    # W -----------------------------------------------------------------
    @property
    def W(self) -> np.ndarray:
        return self.hb.law.wear.copy()

    def set_wear(self, W) -> None:
        self.hb.set_wear(np.maximum(np.asarray(W, dtype=float), 0.0))

    # evaluation ----------------------------------------------------------
    def evaluate(self, x, W=None, jacobian: bool = False, dense: bool | None = None) -> WearState:
        """R, wear rate and (optionally) all first derivatives at (x, W): formed (J, ∂R/∂W,
        ∂rate/∂x) if ``dense`` (None: unless :attr:`structured`), else as blocks (G, g, w)."""
        if W is not None:
            self.set_wear(W)
        hb = self.hb
        self.evaluations += 1
        dense = not self.structured if dense is None else dense
        G = J = None
        if jacobian:
            R, G = hb.residual_blocks(x)
            J = hb.jacobian(G) if dense else None
        else:
            R = hb.residual(x)
        res = hb.last_dlft
        law = hb.law
        lam = res.lam
        slip = res.lam_x_T / law.eps_t[None, :, None]
        rate = wear_per_cycle(lam, slip, self.area, self.k_w)
        S = self.averaging
        st = WearState(R=R, rate=rate if S is None else S @ rate, lam=lam, slip=slip, J=J)
        if not jacobian:
            return st
        g = self.rate_sensitivity(res, law, lam, slip)
        # W_i enters a only through pair i's normal shift: da_{j,i,N}/dW_i = ε_N,i const_j
        daW = np.zeros((self.p, 3 * self.nc))
        daW[:, 0::3] = law.eps_n[:, None] * self._const[None, :]
        st.G_W = np.einsum("pa,pa->p", g, daW)
        # ∂R/∂W_i: pair i's contact block times da_i/dW_i, on pair i's rows only
        w = np.einsum("pab,pb->pa", G, daW)
        st.G, st.g, st.w = G, g, w
        if not dense:
            return st
        # chain to x: a = a_F − A y + ε (y + shift)  ⇒  da/dy = diag(ε) − A; every row of a
        # belongs to one pair, so ∂rate/∂x has row i = g_i · (diag ε − A)[pair i's rows]
        st.G_x = hb.penalty_rows(g[:, None, :])[:, 0, :]
        if S is not None:                   # rate = S · rate_local: its derivatives likewise
            st.G_x = S @ st.G_x
            st.G_W = S * st.G_W[None, :]
        st.R_W = np.zeros((self.n, self.p))
        st.R_W[self._rows, np.arange(self.p)[:, None]] = w
        return st

    def rate_sensitivity(self, res, law, lam, slip):
        """∂rate_i/∂a_i (p, 3nc) [m/cycle per N]: the wear rate's derivative in pair i's
        predictor (eq. 21 through the DLFT's dλ/da)."""
        hb, p, nc, nit = self.hb, self.p, self.nc, self.nit
        ncol = 3 * nc
        dlam = res.dlam                                        # (nit, p, 3, ncol): dλ/da_i
        A = self.area
        pN = pressure(lam, A)                                  # (nit, p)
        dp = -dlam[:, :, 0, :] / A[None, :, None]              # (nit, p, ncol); λ_N ≤ 0 always
        # dλ_u^T/da: λ_u[k, i, c] = Σ_j basis[k, j] a[j, i, c]
        du = np.zeros((nit, 2, ncol))
        for c in (1, 2):
            du[:, c - 1, c::3] = hb.basis
        dX = (du[:, None] - dlam[:, :, 1:, :]) / law.eps_t[None, :, None, None]   # (nit, p, 2, ncol)
        d = slip - np.roll(slip, 1, axis=0)                     # (nit, p, 2)
        s = np.sqrt(np.sum(d * d, axis=-1))                     # (nit, p)
        tdir = np.where(s[..., None] > 0, d / np.maximum(s, 1e-300)[..., None], 0.0)
        ds = np.einsum("kic,kicn->kin", tdir, dX - np.roll(dX, 1, axis=0))
        pm = 0.5 * (pN + np.roll(pN, 1, axis=0))
        dpm = 0.5 * (dp + np.roll(dp, 1, axis=0))
        return self.k_w * (np.einsum("kin,ki->in", dpm, s) + np.einsum("ki,kin->in", pm, ds))   # (p, ncol)

    # solves --------------------------------------------------------------
    def solve_hb(self, x0, W, *, tol, maxiter=50, dense: bool | None = None) -> tuple:
        """R(x; W) = 0 from x0 (warm start): Newton (along the ε-path if any), else the
        engine's whole cascade (:func:`workflow.engine.cascade.solve_point`) from
        Newton's best iterate and x0. Returns (SolveResult, WearState); ``dense``: see
        :meth:`evaluate` (Newton's linear solve follows it)."""
        self.set_wear(W)
        hb = self.hb
        dense = not self.structured if dense is None else dense
        if dense:
            res = newton(hb.residual_jacobian, x0, fun=hb.residual, tol=tol, scale=hb.residual_scale(),
                         maxiter=maxiter)
        else:
            res = hb.solve(x0, tol=tol, maxiter=maxiter, linear="structured", linsolver=self.linsolver())
        if not res.converged and self.eps_path:
            from workflow.engine.cascade import along_eps_path

            alt = along_eps_path(hb, x0, self.eps_path, tol, maxiter)
            if alt.converged:
                res = alt
        if not res.converged:
            # The DLFT residual is non-smooth where pairs sit on the Coulomb cone
            # (shakedown) and Newton can cycle there; the cascade has Powell, pseudo-
            # transient continuation and continuation in ε and Nh (measured on the quick
            # sector at 2 N, W = 25 µm: Newton and Powell stalled, the cascade converged
            # by Nh-continuation from the stalled iterate, by PTC from the stuck state).
            from workflow.engine.cascade import solve_point

            start = res.x if np.all(np.isfinite(res.x)) else None
            pr = solve_point(hb, [start, np.asarray(x0, dtype=float)], solver="newton-powell", tol=tol,
                             maxiter=maxiter, eps_path=self.eps_path)
            alt = pr.result
            alt.iterations = res.iterations + pr.iterations
            alt.jacobian_evaluations += res.jacobian_evaluations
            if alt.converged or (np.isfinite(alt.residual_norm) and alt.residual_norm < res.residual_norm):
                res = alt
        return res, self.evaluate(res.x, jacobian=True, dense=dense)

    def linsolver(self):
        """The structured linear solve of this problem's matrix-free steps (made once: its
        preconditioner is lagged from step to step, :class:`workflow.engine.linsolve.StructuredSolve`)."""
        if getattr(self, "_linsolver", None) is None:
            from workflow.engine.linsolve import StructuredSolve

            self._linsolver = StructuredSolve()
        return self._linsolver

    def total_rate_jacobian(self, st: WearState) -> np.ndarray:
        """``d rate/dW`` (p, p) along the HB solution manifold: ∂rate/∂W − ∂rate/∂x J⁻¹ ∂R/∂W
        (J⁻¹ by least squares where J is singular, :func:`_newton_parts`)."""
        parts = _newton_parts(st)
        GY = parts[3] if parts is not None else st.G_x @ scipy.linalg.lstsq(st.J, st.R_W)[0]
        return rate_w(st) - GY


def rate_w(st: WearState) -> np.ndarray:
    """∂rate/∂W at fixed x as a (p, p) matrix: diagonal for the node-wise law (a pair's rate sees
    only its own W), full with a length scale (:attr:`WearProblem.averaging`)."""
    return np.diag(st.G_W) if st.G_W.ndim == 1 else st.G_W


def averaging(position, area, flank, length: float) -> np.ndarray | None:
    """(p, p) averaging of the frictional power over ``length`` [m] (a Gaussian weighted by the
    tributary areas, within each flank: :func:`workflow.engine.wear_measures.filter_matrix`), or
    None for length 0 — the wear law with a length scale: rate_i = k_w Σ_j S_ij q_j, q the
    cycle's frictional work per unit area. Averaging q (not p or the slip alone) keeps the worn
    steady state what it is: no slip anywhere, no wear anywhere."""
    from workflow.engine.wear_measures import filter_matrix

    if length <= 0:
        return None
    fl = np.asarray(flank)
    S = np.zeros((len(fl), len(fl)))
    for f in np.unique(fl):
        m = np.flatnonzero(fl == f)
        S[np.ix_(m, m)] = filter_matrix(np.asarray(position)[m], np.asarray(area)[m], length)
    return S


#: reciprocal condition number (1-norm, LAPACK's estimate from the LU factors) below which a
#: state's J counts as singular for the wear solves
MIN_RCOND = 1e-14


#: A march whose max W still grows as t^γ, γ ≥ this, over a decade of cycles has no
#: worn steady state (:func:`_trend`); constant-rate wear has γ = 1.
PERSISTENT_GROWTH = 0.5
PERSISTENT = ": persistent slip, no worn steady state"
#: How a pseudo-time march that lost the vibration says so (:func:`_resolve_vibration`).
UNSOLVABLE = "vibration not solvable at the reached wear"
#: How a march stopped by its ``max_cycles`` or ``max_increment`` says so: one stage of a march
#: whose frequency changes between stages (:mod:`workflow.engine.studies.operating`: the
#: resonance dwell), not a verdict on the wear.
STAGE_END = "end of stage"
#: A stage's wear budget counts as spent when less than this fraction of it is left (the last
#: steps are shortened to land on it, :func:`_stage_end`).
STAGE_SLACK = 0.05


# ------------------------------------------------------------------ history

@dataclass
class WearHistory:
    """Result of a wear computation (either method).

    W             final wear depth (p,) [m]
    x             final HB unknowns
    steady        every rate within tolerance at the end
    seconds       wall time; iterations: blocks (reference) or pseudo-time steps
    hb_solves     Newton solves (reference) / Jacobian evaluations (pseudo-time)
    cycles        (k,) physical cycles (reference) or pseudo-time in cycles
    max_wear      (k,) max W [m] at each iteration (Fig. 11)
    max_rate      (k,) largest wear rate [m/cycle] at each iteration
    harmonic1     (k,) |first harmonic| of the tracked tangential DOF [m] (Fig. 12)
    W_history     (k, p) W at each iteration
    reason        why it stopped
    persistent_slip  stopped because the wear rate does not decay (:func:`_trend`):
                  no worn steady state at this load
    vibration_lost   stopped because no periodic vibration was found at the reached wear
                  (the whole solver cascade failed); ``finer_nh``: the same wear re-solved at
                  1.5×Nh by :func:`workflow.engine.studies.wearstudy.finer_nh_resolve` (nh, nit,
                  converged, iterations), which tells a truncation artefact from the physics
    """

    method: str
    W: np.ndarray
    x: np.ndarray
    steady: bool
    seconds: float
    iterations: int
    hb_solves: int
    jacobian_evaluations: int
    cycles: list = field(default_factory=list)
    max_wear: list = field(default_factory=list)
    max_rate: list = field(default_factory=list)
    harmonic1: list = field(default_factory=list)
    W_history: list = field(default_factory=list)
    final_rate: np.ndarray | None = None
    reason: str = ""
    persistent_slip: bool = False
    vibration_lost: bool = False
    finer_nh: dict | None = None

    def summary(self) -> dict:
        return {"seconds": self.seconds, "iterations": self.iterations, "max_wear_m": float(np.max(self.W)),
                "steady": bool(self.steady), "hb_solves": self.hb_solves,
                "jacobian_evaluations": self.jacobian_evaluations,
                "cycles": float(self.cycles[-1]) if self.cycles else 0.0, "reason": self.reason,
                "persistent_slip": bool(self.persistent_slip), "vibration_lost": bool(self.vibration_lost),
                **({"finer_nh": self.finer_nh} if self.finer_nh is not None else {})}


def remaining_wear(hist: WearHistory) -> float:
    """Wear [m] the most-wearing pair has still to gain, extrapolated from the decay of the
    largest rate over the last doubling of the path's time t (cycles): locally
    ``r(t') = r·(t'/t)^−α``, so ``∫_t^∞ r = r·t/(α − 1)`` for α > 1, and ∞ for a rate that
    decays no faster than 1/t (no finite limit in sight). 0 once every rate is 0.

    For an exponential decay (time constant τ) this gives 2 ln 2·r·τ·t/(t − 2τ ln 2), 1.6×
    the true remainder at t = 10τ and 1.4× as t/τ → ∞: it errs on the side of marching
    on. Measured on the contact-convergence dovetail (0.5 N, 16…80 pairs): the max rate decays as t^−0.8 … t^−1.5 for
    decades of t, so a test on the rate alone (N·r ≤ tol·max W, before this function)
    stopped at 1e8 cycles with max W 20–60 % short of its limit."""
    c, r = hist.cycles, hist.max_rate
    if not r or r[-1] == 0.0:
        return 0.0
    t = c[-1]
    j = int(np.searchsorted(c, 0.5 * t, side="right")) - 1
    if j < 0 or c[j] <= 0.0 or r[j] <= 0.0:
        return math.inf
    alpha = math.log(r[j] / r[-1]) / math.log(t / c[j])
    return r[-1] * t / (alpha - 1.0) if alpha > 1.0 else math.inf


def _growth(hist: WearHistory) -> float | None:
    """d ln(max W)/d ln t over the last decade of the path's time (or since its first
    worn point, if at least a doubling); None on a shorter path."""
    c, w = np.asarray(hist.cycles, float), np.asarray(hist.max_wear, float)
    ok = (c > 0) & (w > 0)
    if ok.sum() < 2:
        return None
    c, w = c[ok], w[ok]
    j = max(int(np.searchsorted(c, 0.1 * c[-1], side="right")) - 1, 0)
    if c[-1] < 2.0 * c[j]:
        return None
    return math.log(w[-1] / w[j]) / math.log(c[-1] / c[j])


def _trend(hist: WearHistory) -> tuple[bool, str]:
    """(persistent, text): does max W still grow like t^γ with γ ≥ PERSISTENT_GROWTH over the
    last decade of cycles? Archard under persistent slip wears at a constant rate (the
    flanks sink as a body, the contact forces do not change): γ = 1 and no worn steady
    state. A rate decaying as t^−α gives γ = 1 − α; measured on the quick sector (0.5 N)
    0.16–0.22 along the path, at 2 N 1.6 (growing). A phase where the rate rises again
    while W grows little over the decade (contact-convergence dovetail, 42 pairs, 4e9
    cycles: γ = 0.16) is not persistent slip — the reason this reads W over a decade and
    not the rate now."""
    g = _growth(hist)
    if g is None:
        return False, ""
    if g >= PERSISTENT_GROWTH:
        return True, f"max W grows as t^{g:.2f} over the last decade of cycles{PERSISTENT}"
    return False, f"max W grows as t^{g:.2f} over the last decade of cycles"


def _steady_or_persistent(hist: WearHistory, cycles_per_block, steady_tol) -> tuple[bool, str | None]:
    """(steady, stop reason or None) after the path's last point: steady when the wear
    still to come (:func:`remaining_wear`) is at most ``steady_tol``·max W; stopped, not
    steady, when past the horizon of ``cycles_per_block/steady_tol`` cycles the wear shows
    persistent slip (:func:`_trend`)."""
    if remaining_wear(hist) <= steady_tol * (hist.max_wear[-1] if hist.max_wear else 0.0):
        return True, "steady"
    if hist.cycles[-1] >= cycles_per_block / steady_tol:
        persistent, text = _trend(hist)
        if persistent:
            return False, text
    return False, None


def _close(hist: WearHistory, steady: bool, reason: str) -> None:
    """``hist.steady`` and ``hist.reason`` at the end of a march; one stopped short of the
    steady state (steps or blocks spent) says how its wear was still growing
    (:func:`_trend`) and is flagged ``persistent_slip`` if it grew as under persistent slip."""
    hist.steady, hist.reason = steady, reason
    if not (steady or hist.persistent_slip or reason.startswith(STAGE_END)):
        hist.persistent_slip, text = _trend(hist)
        hist.reason = "; ".join(filter(None, (reason, text)))


def _h1(wp: WearProblem, x, track: int) -> float:
    """|U_1| of relative DOF ``track`` (pair-major index 3i + c) [m]."""
    return float(np.abs(wp.hb.harmonics(x)[1, track])) if wp.hb.nh >= 1 else 0.0


# ------------------------------------------------------------------ step control

def penetration_scale(wp: WearProblem, st: WearState) -> float:
    """Largest ``−⟨λ_N⟩ / k_N`` [m] over the pairs, with k_N each pair's static condensed
    normal stiffness (:func:`workflow.engine.penalty.reference_stiffness`): the W scale
    of the dynamics.

    A wear depth of that order unloads a pair through the structure's own
    stiffness, so it is the natural absolute scale of W for the step controls
    (W starts at 0, where a purely relative control is undefined). It used to
    be ``−⟨λ_N⟩/ε_N`` — the penalty's interpenetration, which shrank 1000× when
    ε became 10³× the stiffness and made the reference march take thousands of
    blocks to leave W ≈ 0 (paper-wear: not steady after 1000 blocks).
    """
    from workflow.engine.penalty import reference_stiffness

    k_n = reference_stiffness(np.real(wp.hb.Zr[0]))[:, 0]
    pen = np.maximum(-np.mean(st.lam[..., 0], axis=0), 0.0) / k_n
    return max(float(np.max(pen)) if pen.size else 0.0, 1e-300)


def _wscale(W, pen) -> float:
    return max(float(np.max(W)) if W.size else 0.0, pen)


# ------------------------------------------------------------------ reference

def march_reference(wp: WearProblem, x0, *, scheme: str = "explicit", cycles_per_block: float = 1e5,
                    max_blocks: int = 400, steady_tol: float = 1e-3, tol: float = 1e-9,
                    track: int = 1, newton_w_iterations: int = 8, block_tol: float = 0.0,
                    max_cycles: float = math.inf, max_increment: float = math.inf) -> WearHistory:
    """Wear marched in physical time by blocks of N cycles (refs. 5, 7).

    explicit: ``W_{k+1} = W_k + N·rate(x_k, W_k)``;
    implicit: ``W_{k+1} = W_k + N·rate(x(W_{k+1}), W_{k+1})`` by Newton on W
    (Jacobian ``I − N d rate/dW`` along the HB solutions), W never decreasing.
    Each W needs a converged HB solve (Newton, warm start).

    Block size: ``block_tol`` = 0: fixed, N = ``cycles_per_block``;
    ``block_tol`` > 0: adaptive, the block wears at most ``block_tol`` of the
    current W scale, ``N·max rate ≤ block_tol·max(max W, pen)`` (pen: the
    largest normal interpenetration at W = 0, :func:`penetration_scale`), so
    the slow time step resolves the wear dynamics; the profile converges
    (first order) as ``block_tol`` → 0 where the rates decay smoothly. Where
    a pair's rate drops to 0 at a jump, the implicit blocks locate it
    (:func:`_reference_block`): paper-wear's worn steady state is set by such
    jumps, and block_tol = 0.01 and 0.0025 agree to 6.4e-7. Stops at the steady state
    (:func:`_steady_or_persistent`: the wear still to come within ``steady_tol`` of max W) or after
    ``max_blocks`` — or, not steady, after ``max_cycles`` cycles or once the deepest pair has worn
    ``max_increment`` [m] more than at the start (the last blocks shortened to land there: one
    stage of a march whose frequency changes, :func:`_stage_end`).
    """
    if scheme not in ("explicit", "implicit"):
        raise ValueError(f"wear reference scheme {scheme!r}: explicit or implicit")
    t0 = time.perf_counter()
    Nref = float(cycles_per_block)
    W = np.zeros(wp.p) if wp.W is None else wp.W
    res, st = wp.solve_hb(x0, W, tol=tol, dense=True if scheme == "implicit" else None)   # see _reference_block
    solves, nje = 1, res.jacobian_evaluations + 1
    if not res.converged:
        raise SolverError(f"wear reference: HB solve at W = 0 failed: {res.reason}")
    pen = penetration_scale(wp, st)
    x = res.x
    hist = WearHistory(method=f"reference-{scheme}", W=W, x=x, steady=False, seconds=0.0, iterations=0,
                       hb_solves=0, jacobian_evaluations=0)
    cyc = 0.0
    _record(hist, wp, cyc, x, W, st.rate, track)
    reason = f"max blocks ({max_blocks})"
    steady = False
    k = 0
    for k in range(1, max_blocks + 1):
        if k > 1 or st.rate.max() == 0:
            steady, why = _steady_or_persistent(hist, Nref, steady_tol)
            if why is not None:
                reason, hist.persistent_slip = why, not steady
                k -= 1
                break
        N = Nref
        if block_tol > 0:
            N = block_tol * _wscale(W, pen) / max(float(st.rate.max()), 1e-300)
        N, end = _stage_end(N, cyc, W - hist.W_history[0], st.rate, max_cycles, max_increment)
        if end:
            reason = end
            break
        res, stn, Wn, N, used = _halved_block(wp, x, W, st, N, scheme, tol, newton_w_iterations)
        solves, nje = solves + used[0], nje + used[1]
        if Wn is None:
            reason, hist.vibration_lost = f"HB solve failed at block {k}, {MAX_BLOCK_HALVINGS} halvings: {res.reason}", True
            break
        W, x, st = np.maximum(Wn, W), res.x, stn
        cyc += N
        _record(hist, wp, cyc, x, W, st.rate, track)
    hist.W, hist.x = W, x
    hist.final_rate = st.rate
    hist.iterations = len(hist.cycles) - 1
    hist.hb_solves, hist.jacobian_evaluations = solves, nje
    _close(hist, steady, reason)
    hist.seconds = time.perf_counter() - t0
    return hist


def _halved_block(wp: WearProblem, x, W, st: WearState, N: float, scheme: str, tol: float, newton_w_iterations: int):
    """One block of :func:`march_reference` of N cycles, halved up to :data:`MAX_BLOCK_HALVINGS`
    times: a block that crosses a contact-state change can leave the HB solver at a kink, and a
    smaller wear step gets past it. (HB result, state, W⁺ or None if every halving failed, the
    block's cycles, (HB solves, Jacobian evaluations))."""
    solves = nje = 0
    for halving in range(MAX_BLOCK_HALVINGS + 1):
        res, stn, Wn, used, w_solved = _reference_block(wp, x, W, st, N, scheme, tol, newton_w_iterations)
        if _hb_ok(wp, res, tol) and not w_solved and halving == MAX_BLOCK_HALVINGS:
            # still no root in the shortest block: a jump of the rate (an event) lies within
            # N·rate; cross it with the explicit step, as the march in physical time would
            solves, nje = solves + used[0], nje + used[1]
            res, stn, Wn, used, w_solved = _reference_block(wp, x, W, st, N, "explicit", tol, 0)
        solves, nje = solves + used[0], nje + used[1]
        if _hb_ok(wp, res, tol) and w_solved:
            return res, stn, Wn, N, (solves, nje)
        N *= 0.5
    return res, stn, None, N, (solves, nje)


def _stage_end(h: float, t: float, dW, rate, max_cycles: float, max_increment: float) -> tuple[float, str]:
    """(step or block h [cycles] shortened to land on the stage's end, "" or why the stage ends
    here): at ``t`` cycles into the stage with the deepest pair ``max(dW)`` [m] deeper than at its
    start, the stage ends at ``max_cycles`` or, within :data:`STAGE_SLACK`, at ``max_increment``;
    a step wears about h·max rate, so h ≤ (what is left) / max rate lands near it."""
    if t >= max_cycles * (1.0 - 1e-12):
        return h, f"{STAGE_END} ({max_cycles:.4g} cycles)"
    left = max_increment - (float(np.max(dW)) if np.size(dW) else 0.0)
    if math.isfinite(max_increment) and left <= STAGE_SLACK * max_increment:
        return h, f"{STAGE_END} (wear +{max_increment:.3g} m)"
    top = float(np.max(rate)) if np.size(rate) else 0.0
    return min(h, max_cycles - t, left / top if top > 0 else math.inf), ""


def _hb_ok(wp, res, tol) -> bool:
    """A block's HB solve is usable: converged, or stopped within 10³ × ``tol`` (scaled residual)."""
    return bool(res.converged or (np.isfinite(res.residual_norm)
                                  and res.residual_norm <= 1e3 * tol * wp.hb.residual_scale()))


def _reference_block(wp, x, W, st, N, scheme, tol, newton_w_iterations):
    """One block of N cycles from wear W: ``(res, state, W_next, (solves, jacobians), solved)``.

    Explicit: ``W + N·rate(W)`` (``solved`` always). Implicit: ``W_n = W + N·rate(W_n)`` by
    Newton on W, each residual an HB solve at the trial wear; ``solved`` says whether that
    equation holds to :data:`W_EQ_TOL` of max W at the end. It may have no root at all: a
    pair whose rate *grows* with its own wear and then drops to 0 when the HB solution
    jumps to a sticking state (paper-wear, 48 pairs, block_tol = 0.01: rate 6.7e-18 →
    9.3e-18 m/cycle over +1 nm of wear, 0 at +10 nm, against N·rate = 18 nm) — a block
    must then be shorter than the way to the jump, not accepted unsolved (it was, and the
    march then sat for 870 blocks at W + 1e-18 m with the same rate, never steady; now it
    ends steady in 157 blocks). :func:`march_reference` halves such a block, and crosses
    the jump with the explicit step if even the shortest block has no root.
    """
    solves = nje = 0
    Wn = W + N * st.rate          # explicit step, or the implicit predictor
    dense = True if scheme == "implicit" else None       # total_rate_jacobian forms J⁻¹∂R/∂W
    res, stn = wp.solve_hb(x, Wn, tol=tol, dense=dense)
    solves, nje = 1, res.jacobian_evaluations + 1
    if scheme == "explicit":
        return res, stn, Wn, (solves, nje), True

    F = Wn - W - N * stn.rate
    for _ in range(newton_w_iterations):
        if _w_solved(F, Wn):
            break
        Jw = np.eye(wp.p) - N * wp.total_rate_jacobian(stn)
        try:
            dW = np.linalg.solve(Jw, -F)
        except np.linalg.LinAlgError:
            dW = -F
        Wn = np.maximum(Wn + dW, W)
        res, stn = wp.solve_hb(res.x, Wn, tol=tol, dense=dense)
        solves += 1
        nje += res.jacobian_evaluations + 1
        F = Wn - W - N * stn.rate
    return res, stn, Wn, (solves, nje), _w_solved(F, Wn)


def _w_solved(F, Wn) -> bool:
    """The implicit block's residual ``F = W_n − W − N·rate(W_n)`` is within :data:`W_EQ_TOL` of max W."""
    return bool(np.max(np.abs(F)) <= W_EQ_TOL * max(float(np.max(Wn)), 1e-300))


# ------------------------------------------------------------------ pseudo-time

#: :func:`pseudo_time_wear` reports its progress every this many accepted steps
REPORT_STEPS = 20


def pseudo_time_wear(wp: WearProblem, x0, *, cycles_per_block: float = 1e5,
                     steady_tol: float = 1e-3, tol: float = 1e-9, max_steps: int = 400,
                     rtol: float = 1e-3, track: int = 1, x_tol: float = 1e-3, x_corrections: int = 3,
                     dt_max_blocks: float = 0.0, order: int = 2, max_cycles: float = math.inf,
                     max_increment: float = math.inf, report=None) -> WearHistory:
    """Integrate the augmented system (eq. 22a–b) along the wear trajectory to zero wear rates.
    ``report(message)``: the march's progress every :data:`REPORT_STEPS` accepted steps.

    Unknowns ``z = [x; W]``. The vibration is the fast part of the dual
    time scales (pseudo-time mass θ J → 0: it is slaved to W), the wear
    ``Ẇ = rate(x; W)`` the slow part, t* in cycles. Each pseudo-time step is
    one linearly implicit (Rosenbrock–Euler) step of the augmented DAE with
    its exact Jacobian

        [ J          ∂R/∂W        ] [Δx]   [ −R(x; W)  ]
        [ −h ∂r/∂x   I − h ∂r/∂W  ] [ΔW] = [ h·rate    ]

    i.e. a Newton step on the vibration and a linearly implicit Euler step on the wear, with
    one Jacobian per step, factored once per state (:func:`_augmented_step`) — the HB problem
    is *not* converged at each slow step (only corrected by up to ``x_corrections`` Newton steps
    at fixed W when ``‖R‖ > x_tol·‖F‖``, a relaxed tolerance: measured on the 48-pair paper-wear
    case, x_tol = 1e-5 made 63 corrections in 39 steps (4.3 s) and x_tol = 1e-3 10 in 37
    (2.6 s), both within 1 % of the converged reference profile).
    Step control on the wear variables only (the vibration error is excluded): local error
    ``½h‖rate(z⁺) − rate(z)‖∞ ≤ rtol·max(max W, pen)`` (pen: :func:`penetration_scale`),
    rejected steps retried with a smaller h, so the integration tracks the physical wear
    trajectory (the worn steady state is a manifold — any W where every pair sticks or
    separates — and the profile reached is the end of the path). Stops at
    the steady state of :func:`march_reference` after a final HB solve to ``tol`` at the
    reached W. The one integrator of the wear system (``pseudotime.scheme = "ser"``);
    ``dt_max_blocks`` > 0 caps h at that many ``cycles_per_block``. ``max_cycles``,
    ``max_increment`` [m]: stop, not steady, at that pseudo-time (cycles) or once the deepest pair
    has worn that much more than at the start (one stage of a march whose frequency changes,
    :func:`_stage_end`).
    """
    t0 = time.perf_counter()
    N = float(cycles_per_block)
    x, W, st, pen, hist = _march_start(wp, x0, tol, track)
    if float(st.rate.max()) == 0.0:
        return _steady_at_start(hist, st, t0)
    hmax = dt_max_blocks * N if dt_max_blocks else np.inf
    h = min(math.sqrt(rtol) * _wscale(W, pen) / float(st.rate.max()), hmax)
    t, steps, rejected, count = 0.0, 0, 0, {"nje": 0, "corrections": 0, "reanchored": 0}
    steady, reason = False, f"max steps ({max_steps})"
    failed = 0          # consecutive steps refused by the vibration (not by the wear error)
    while steps + rejected < max_steps:
        steady, why = _steady_or_persistent(hist, N, steady_tol) if steps else (False, None)
        if why is None and failed == 2:
            (x, st, why), failed = _resolve_vibration(wp, x, st, W, tol, count), 0
        if why:
            reason, hist.persistent_slip, hist.vibration_lost = why, why.endswith(PERSISTENT), why.startswith(UNSOLVABLE)
            break
        h, end = _stage_end(h, t, W - hist.W_history[0], st.rate, max_cycles, max_increment)
        if end:
            reason = end
            break
        xn, Wn, stn, ok = _wear_step(wp, x, W, st, h, x_tol, x_corrections, count)
        err, ws, fac = _local_error(h, st, stn, _wscale(Wn, pen), rtol)
        failed = 0 if ok else failed + 1
        if ok and err <= rtol * ws:
            if order == 2:
                xn, Wn, stn = _trapezoidal(wp, W, st, xn, Wn, stn, h, count)
            elif not stn.has_jacobian:
                stn = wp.evaluate(xn, Wn, jacobian=True)
            x, W, st = xn, Wn, stn
            t += h
            steps += 1
            _record(hist, wp, t, x, W, st.rate, track)
            h = min(h * min(4.0, max(0.3, fac)), hmax)
            if report is not None and steps % REPORT_STEPS == 0:
                report(_progress(hist, steps, rejected, time.perf_counter() - t0))
        else:
            rejected += 1
            h *= min(0.5, max(0.1, fac)) if ok else 0.25
    _finish(hist, wp, x, W, st, steady, reason, count, (N, steady_tol, tol))
    hist.reason += (f" ({steps} steps, {rejected} rejected, {count['corrections']} vibration corrections, "
                    f"{count['reanchored']} vibration re-solves)")
    hist.iterations = steps
    hist.seconds = time.perf_counter() - t0
    return hist


def _march_start(wp: WearProblem, x0, tol: float, track: int):
    """(x, W, state, penetration scale [m], history) of :func:`pseudo_time_wear` at its start:
    the vibration solved at the current W, recorded as the history's first point."""
    W = wp.W
    res0, st = wp.solve_hb(x0, W, tol=tol)
    hist = WearHistory(method="pseudo-time-ser", W=W, x=res0.x, steady=False, seconds=0.0, iterations=0,
                       hb_solves=1, jacobian_evaluations=res0.jacobian_evaluations + 1)
    _record(hist, wp, 0.0, res0.x, W, st.rate, track)
    return res0.x, W, st, penetration_scale(wp, st), hist


def _steady_at_start(hist: WearHistory, st: WearState, t0: float) -> WearHistory:
    """``hist`` closed as steady: nothing wears at the start (every rate zero)."""
    hist.steady, hist.reason, hist.final_rate = True, "steady (no wear at W0)", st.rate
    hist.seconds = time.perf_counter() - t0
    return hist


def _local_error(h: float, st: WearState, stn: WearState, ws: float, rtol: float) -> tuple[float, float, float]:
    """(error ½h‖rate(z⁺) − rate(z)‖∞ [m], its scale ``ws`` [m], the step factor) of one step."""
    err = 0.5 * h * float(np.max(np.abs(stn.rate - st.rate)))
    return err, ws, (0.9 * math.sqrt(rtol * ws / err) if err > 0 else 4.0)


def _progress(hist: WearHistory, steps: int, rejected: int, seconds: float) -> str:
    """One line on a march's progress from its last recorded point."""
    return (f"wear march: {steps} steps ({rejected} rejected), {hist.cycles[-1]:.3g} cycles, max W "
            f"{hist.max_wear[-1]:.3e} m, max rate {hist.max_rate[-1]:.2e} m/cycle, {seconds:.0f} s")


def _finish(hist: WearHistory, wp: WearProblem, x, W, st: WearState, steady: bool, reason: str, count: dict,
            tols) -> None:
    """Final vibration solve of :func:`pseudo_time_wear` at the reached W (the
    profile is W; x to full tolerance for the outputs), then ``hist``'s end
    state; ``tols`` = (cycles per block, steady_tol, HB tol). A steady march
    whose final solve is no longer steady is reported so; a march that lost the vibration
    (``hist.vibration_lost``) is not solved again from the x the whole cascade just failed from."""
    N, steady_tol, tol = tols
    res = None
    if not hist.vibration_lost:
        res, stf = wp.solve_hb(x, W, tol=tol)
        count["nje"] += res.jacobian_evaluations + 1
    if res is not None and res.converged:
        x, st = res.x, stf
        hist.max_rate[-1] = float(np.max(st.rate)) if np.size(st.rate) else 0.0   # same W, converged x
        if steady and not _steady_or_persistent(hist, N, steady_tol)[0]:
            steady, reason = False, "not steady after the final vibration solve"
    hist.W, hist.x = W, x
    hist.final_rate = st.rate
    _close(hist, steady, reason)
    hist.hb_solves = 2
    hist.jacobian_evaluations += count["nje"]


def _resolve_vibration(wp: WearProblem, x, st: WearState, W, tol: float, count: dict):
    """(x, state, "") back on R(x; W) = 0 at the reached W — or (x, st, why) if not solvable.

    After two steps refused by the vibration in a row, the state carried forward sits
    too far off the vibration manifold (accepted at the relaxed tolerance, then shifted
    by the trapezoidal correction) for the corrections of any step, however short
    (measured on the quick sector at 2 N: 169 of 200 steps refused at W = 25 µm, h
    shrinking to 1e-18 cycles); the whole cascade re-solves it (:meth:`WearProblem.solve_hb`)."""
    res, stx = wp.solve_hb(x, W, tol=tol)
    count["nje"] += res.jacobian_evaluations
    count["reanchored"] += 1
    if not res.converged:
        return x, st, f"{UNSOLVABLE} ({res.reason})"
    return res.x, stx, ""


def _record(hist: WearHistory, wp: WearProblem, cycles: float, x, W, rate, track: int) -> None:
    """Append one point of the wear path to ``hist``: cycles, max W [m], max rate [m/cycle],
    tracked first harmonic [m], W."""
    hist.cycles.append(cycles)
    hist.max_wear.append(float(W.max()))
    hist.max_rate.append(float(np.max(rate)) if np.size(rate) else 0.0)
    hist.harmonic1.append(_h1(wp, x, track))
    hist.W_history.append(W.copy())


def _newton_parts(st: WearState):
    """``(y0, Y, g0, GY, lu)``: ``y0 = J⁻¹R`` (m), ``Y = J⁻¹ ∂R/∂W`` (n, p),
    ``g0 = ∂rate/∂x·y0``, ``GY = ∂rate/∂x·Y`` (p, p) and J's LU factors — one
    factorisation per state, shared by every trial step from it; None if J is singular."""
    if st.newton_parts is None:
        st.newton_parts = False
        # ‖J‖₁ as ‖Jᵀ‖∞ of the Fortran-ordered view, without the two copies of J that
        # np.linalg.norm(J, 1) and np.isfinite(J) made (n = 2100: 3.5 ms against 13 ms, ×570
        # in a 100-pair march); it is finite exactly when every entry of J is
        anorm = scipy.linalg.lapack.dlange("I", st.J.T)
        if not np.isfinite(anorm):
            return None
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", scipy.linalg.LinAlgWarning)
                lu = scipy.linalg.lu_factor(st.J, check_finite=False)
            rcond, info = scipy.linalg.lapack.dgecon(lu[0], anorm, norm="1")
            if info != 0 or not rcond >= MIN_RCOND:
                return None
            sol = scipy.linalg.lu_solve(lu, np.column_stack([st.R, st.R_W]), check_finite=False)
        except (scipy.linalg.LinAlgWarning, np.linalg.LinAlgError, ValueError):
            return None
        if np.all(np.isfinite(sol)):
            y0, Y = sol[:, 0], sol[:, 1:]
            st.newton_parts = (y0, Y, st.G_x @ y0, st.G_x @ Y, lu)
    return st.newton_parts or None


#: A one-vector solve with a trial state's J (:func:`_near_solve`): GMRES iterations of its one
#: cycle, and the relative residual it must reach (the LU's own is ~1e-15; a Newton shift of x
#: this close is the same step to ~1e-11, far below the vibration's tolerance). Beyond the
#: cycle, J is factored as before.
NEAR_ITERS, NEAR_RTOL = 30, 1e-11
_GMRES_RTOL = "rtol" if "rtol" in inspect.signature(scipy.sparse.linalg.gmres).parameters else "tol"


def _near_solve(ref: WearState, st: WearState, b):
    """``st.J⁻¹ b`` by GMRES preconditioned with the LU of ``ref``, a state one step away whose
    :func:`_newton_parts` are made; None if there is none or GMRES does not reach
    :data:`NEAR_RTOL` (true residual) in :data:`NEAR_ITERS` — the caller factors st.J then.

    The trapezoidal correction and the vibration corrections of a pseudo-time step need J⁻¹ of
    their state for one vector only, but :func:`_newton_parts` factored J for each (an LU is
    2n³/3 flops; a GMRES iteration ~4n²). Measured on the interface-scaling sectors (Nh = 3,
    the step's own LU as preconditioner, to 1e-12): 8 (64 pairs) and 10 (128 pairs)
    iterations median, 16 and 19 at most, every solve converged, the shifts equal to the
    LU's to 1e-11."""
    parts = ref.newton_parts if ref is not None else None
    if not parts or st.J is None:
        return None
    J, lu, n = st.J, parts[4], b.size
    A = scipy.sparse.linalg.LinearOperator((n, n), matvec=lambda v: J @ v, dtype=float)
    M = scipy.sparse.linalg.LinearOperator((n, n), matvec=lambda v: scipy.linalg.lu_solve(lu, v, check_finite=False),
                                           dtype=float)
    y, _ = scipy.sparse.linalg.gmres(A, b, M=M, restart=NEAR_ITERS, maxiter=1, atol=0.0,
                                     **{_GMRES_RTOL: 0.1 * NEAR_RTOL})
    if not np.all(np.isfinite(y)) or np.linalg.norm(b - J @ y) > NEAR_RTOL * np.linalg.norm(b):
        return None
    return y


def _j_solve(wp: WearProblem, ref: WearState, st: WearState, b, dW=None):
    """``J⁻¹ (b + ∂R/∂W dW)`` with J of ``st`` (None: singular or not solved): GMRES on the
    matrix-free J where the state has no J formed (:func:`workflow.engine.wear_structured.solve`);
    else GMRES preconditioned with ``ref``'s LU (:func:`_near_solve`), else st's own LU."""
    if st.J is None:
        from workflow.engine import wear_structured

        return wear_structured.solve(wp, st, b if dW is None else b + wear_structured.r_w_times(st, dW))
    rhs = b if dW is None else b + st.R_W @ dW
    y = _near_solve(ref, st, rhs)
    if y is None:
        parts = _newton_parts(st)
        y = None if parts is None else parts[0] + (0.0 if dW is None else parts[1] @ dW)
    return y


def _augmented_step(wp: WearProblem, st: WearState, h: float):
    """(Δx, ΔW) of the linearly implicit step (see :func:`pseudo_time_wear`),

        [ J          ∂R/∂W        ] [Δx]   [ −R     ]
        [ −h ∂r/∂x   I − h ∂r/∂W  ] [ΔW] = [ h·rate ],

    by eliminating Δx = −J⁻¹R − J⁻¹∂R/∂W ΔW: the p × p Schur system
    ``(I − h diag ∂r/∂W + h ∂r/∂x J⁻¹∂R/∂W) ΔW = h (rate − ∂r/∂x J⁻¹R)``.
    J is factored once per state (:func:`_newton_parts`), so a step retried
    with a smaller h costs a p × p solve, not an (n + p) LU (measured to the
    worn steady state on the contact-convergence meshes at Nh = 5, old and new
    side by side: 42 pairs 46.9 → 49.7 s, 80 pairs 293 → 257 s). A singular J
    (rcond < :data:`MIN_RCOND`) falls back to the whole (n + p) system. A state without J
    formed (``wp.structured``) takes :func:`workflow.engine.wear_structured.augmented_step` (None if
    its solve fails)."""
    if st.J is None:                        # matrix-free (:mod:`workflow.engine.wear_structured`)
        from workflow.engine import wear_structured

        return wear_structured.augmented_step(wp, st, h)
    n, p = st.J.shape[0], st.rate.size
    parts = _newton_parts(st)
    if parts is not None:
        y0, Y, g0, GY, _ = parts
        S = h * GY + np.eye(p) - h * rate_w(st)
        try:
            dW = np.linalg.solve(S, h * (st.rate - g0))
            return -y0 - Y @ dW, dW
        except np.linalg.LinAlgError:
            pass
    A = np.zeros((n + p, n + p))
    A[:n, :n] = st.J
    A[:n, n:] = st.R_W
    A[n:, :n] = -h * st.G_x
    A[n:, n:] = np.eye(p) - h * rate_w(st)
    b = np.concatenate([-st.R, h * st.rate])
    try:
        dz = np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        dz = scipy.linalg.lstsq(A, b)[0]
    return dz[:n], dz[n:]


def _wear_step(wp: WearProblem, x, W, st: WearState, h: float, x_tol: float, x_corrections: int, count: dict):
    """One linearly implicit step of the augmented system (see :func:`pseudo_time_wear`),
    then the relaxed vibration corrections at the new W; (x⁺, W⁺, state⁺, acceptable).
    The state at the trial point carries no Jacobian unless a correction needs one."""
    scale = wp.hb.residual_scale()
    step = _augmented_step(wp, st, h)
    if step is None:                    # a matrix-free solve failed: refused, h shrinks
        return x, W, st, False
    dx, dW = step
    xn = x_pred = x + dx
    Wn = np.maximum(W + dW, W)          # wear never decreases
    stn = wp.evaluate(xn, Wn)
    for _ in range(x_corrections):          # relaxed vibration convergence at fixed W (Newton)
        if np.linalg.norm(stn.R) <= x_tol * scale:
            break
        stn = wp.evaluate(xn, Wn, jacobian=True)
        count["nje"] += 1
        dx = _j_solve(wp, st, stn, stn.R)
        if dx is None:
            break
        xn = xn - dx
        stn = wp.evaluate(xn, Wn)
        count["corrections"] += 1
    if wp.eps_path and not np.linalg.norm(stn.R) <= x_tol * scale:
        # large ε: Newton's basin at fixed W is small; the root from the moderate-ε one
        res, stn = wp.solve_hb(x_pred, Wn, tol=x_tol)
        xn = res.x
        count["nje"] += res.jacobian_evaluations
        count["corrections"] += int(res.iterations)
    ok = np.all(np.isfinite(stn.R)) and np.linalg.norm(stn.R) <= max(10 * x_tol, 1e-3) * scale
    return xn, Wn, stn, bool(ok)


def _trapezoidal(wp: WearProblem, W, st: WearState, xn, Wn, stn: WearState, h: float, count: dict):
    """Local extrapolation to the trapezoidal rule (the step's error estimate is
    the Euler one): W⁺ = W + ½h(rate + rate⁺), x moved along the HB manifold by
    the Newton step ``−J⁺⁻¹(R⁺ + ∂R/∂W⁺ (W⁺ − Wn))`` with the trial state's own
    Jacobian. (A chord with the step's J, which saves this factorisation, let x
    drift off the manifold where the contact state changed within the step:
    measured on the quick sector, the worn depth moved 1.313 → 1.318 µm and its
    Nh-check 0.17 → 0.87 %.) The new state is evaluated with its Jacobian: the
    next step's."""
    Wc = np.maximum(W + 0.5 * h * (st.rate + stn.rate), W)
    if not stn.has_jacobian:
        stn = wp.evaluate(xn, Wn, jacobian=True)
    shift = _j_solve(wp, st, stn, stn.R, Wc - Wn)
    if shift is not None and np.all(np.isfinite(shift)):
        xn = xn - shift
    count["nje"] += 1
    return xn, Wc, wp.evaluate(xn, Wc, jacobian=True)


def profile_rel_diff(W_a, W_b) -> float:
    """max |W_a − W_b| / max(max W_a, max W_b) — the 2 % agreement measure."""
    W_a, W_b = np.asarray(W_a), np.asarray(W_b)
    top = max(float(np.max(W_a)), float(np.max(W_b)), 1e-300)
    return float(np.max(np.abs(W_a - W_b))) / top


def tip_cycle(observed_harmonics: np.ndarray, nit: int = 128, dof: int = 0) -> np.ndarray:
    """Time history over one period (nit,) of observed DOF ``dof`` from complex harmonics (Nh+1, n_obs)."""
    return fourier.to_time(np.asarray(observed_harmonics)[:, dof], nit)

