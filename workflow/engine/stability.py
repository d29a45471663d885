"""Hill's method: Floquet stability of a periodic harmonic-balance solution (issue #49).

The linearised problem
----------------------
About a T-periodic solution q(t) (T = 2π/ω) of ``M q̈ + C q̇ + K q + Bᵀ λ(t) = f(t)``
(docs/contracts.md §4, §6) a perturbation δq obeys the linear T-periodic system

    M δq̈ + C δq̇ + K δq + Bᵀ δλ = 0,      δu = B δq   (relative contact DOFs),

with δλ the linearised DLFT law along the period (:mod:`workflow.engine.contact`). The
DLFT is a rigid contact (eqs. 13–17: in stick ``X_T`` equals the anchor, in contact the gap
is closed; ε is numerical) with *memory*: a pair in stick pulls towards an anchor w that
only slip moves. Its exact linearisation therefore carries the anchor perturbation δw of
every pair that slips or separates during the period as a state (Jenkins element: a
spring ε_T in series with a Coulomb slider, ε → ∞):

* contact, normal: ``δλ_N = ε_N δu_N``; separation: ``δλ = 0`` and the anchor follows,
  ``δw = δu_T``;
* tangential: ``δλ_T = ε_T (δu_T − δw)`` with, in stick, ``δẇ = 0``; in slip (direction
  t = λ_T/‖λ_T‖, n ⊥ t in the tangent plane) the Coulomb limit along t,
  ``ε_T tᵀ(δu_T − δw) = μ δ|λ_N| = −μ ε_N δu_N`` (algebraic: the μ·dλ_N coupling), and
  across t the rotation of the slip direction, ``nᵀδẇ = κ nᵀ(δu_T − δw)`` with
  ``κ = |ẇ| ε_T/(μ|λ_N|)`` (1/s, the slip rate over the elastic slip length).

This periodic descriptor system is exact for the piecewise-smooth law: its algebraic slip
rows reproduce the saltation at stick → slip (the perturbed force is clipped to the cone).
At s = 0 it is the HB Jacobian's linearisation (the DLFT carries the same anchor
derivative, :func:`workflow.engine.contact.dlft_pass`), so an exponent crosses 0 exactly at
a fold of the HB curve. A pair stuck during the whole period keeps no anchor state: its
anchor is a parameter set by the load history (the "stuck zeroth harmonic" of
:meth:`~workflow.engine.hb.HBProblem.static_state`) whose perturbation is a neutral
multiplier 1 of the family of periodic solutions, not a dynamic instability; so is a pair
whose anchor the DLFT never moves (it only touches the cone after shaking down: every
reference on a circle is periodic, :func:`workflow.engine.contact.dlft_pass`), which takes
the stick tangent at the touching instants.

``memory=False`` drops the anchors: the memoryless tangent ``δλ = K_c(t) δu`` (ε_N in
contact, ε_T in stick, in slip ``fac·ε_T (I − t tᵀ)`` and ``−μ ε_N t`` on δu_N, zero when
separated; the issue's first formulation). It is not the linearisation of a law with
memory: in stick it pulls δu back to 0 instead of to its value at the stick onset, and in
slip it keeps the perturbed force the cone clips, so friction does not damp perturbations.
Measured on the 1-DOF Jenkins oscillator (ω = 1.3, stable, shooting 0.3738) it finds a real
multiplier 1.58–1.64: an *unstable* orbit that is stable.

Two ways to the multipliers
---------------------------
* ``method="monodromy"`` (default): the monodromy matrix of the linearised system,
  integrated over one period on the tangent's pieces (:func:`monodromy`): the DLFT's nit
  samples, with each stick/slip/separation switch located inside its sample interval
  (:func:`_switch_pieces`). Located to the sample only, a switch was up to T/nit off, and
  the largest multiplier with it, by an amount that does not fall as 1/nit but jumps with
  where the switches fall between samples (Jenkins, ω = 1.3: 1.25e-3, 1.26e-3, 4.7e-4,
  7.9e-5 at nit = 1024, 2048, 4096, 8192). Measured against event-driven shooting
  (2026-11-28, :mod:`workflow.verification.floquet`; the 1-DOF Jenkins oscillator of
  tests/workflow/test_stability.py, HB Nh = 15, nit = 128): 7.7e-5 at ω = 1.3 and 3.7e-4 at
  ω = 1.2 (normal load varying) at the defaults, against 1.26e-3 and 4.9e-4 with the switches
  at the samples. What is left is not the monodromy's: ε of the tangent (:data:`EPS_FACTOR`;
  10⁴ → 10⁶ moves it by 7e-5 on both) and, at ω = 1.2, the HB orbit itself (its AFT on 128
  samples: with 1024 and Nh = 31 the error is 8.8e-5, ε's part); the monodromy's own part,
  nit = 1024…8192 and refine = 64…256 against 8192 and 256, is below 5.5e-5. The defaults
  since 2026-11-29 (nit = 256, the switches cut into 8 three times, backward Euler extrapolated
  twice: :data:`MONODROMY_NIT`, :data:`SWITCH_REFINE`, :data:`RICHARDSON`) give 7.4e-5 and
  3.7e-4. The monodromy is integrated through its structure (the anchors' 2×2 blocks eliminated
  pair by pair, :func:`_step_operators`) and only on the states that are not slaved at the
  period's start (:func:`_live_multipliers`): at 128 pairs 18 columns instead of 238.
* ``method="hill"``: Hill's method below. It is exact for a smooth periodic system (Duffing:
  1e-9 against shooting at 10 harmonics) and for a constant tangent (all stuck), but the
  stick/slip switches make the anchor rows switch between differential and algebraic:
  the truncated pencil then has spurious eigenvalues and does not converge in N (Jenkins,
  ω = 1.3: 0.917, 0.839 at N = 8, 16, an infinite one selected at 32, against 0.374). It is
  kept for smooth laws and as the generic core (:func:`hill_exponents`).

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

Hill's method
-------------
With the Floquet form ``z(t) = e^{st} Σ_{n=−N…N} z_n e^{inωt}`` a first-order periodic
descriptor system ``E(t) ż = A(t) z`` becomes the generalised eigenproblem (Hill 1886;
Lazarus & Thomas 2010, eqs. 10–14; Peletan et al. 2013, §3; Detroux et al. 2015, §2.3)

    Σ_k [Â_{n−k} − i k ω Ê_{n−k}] z_k = s Σ_k Ê_{n−k} z_k,     n = −N…N,

with Â_j, Ê_j the complex Fourier coefficients of A(t), E(t) (from samples, by FFT;
nit ≥ 4N+1 so that |j| ≤ 2N is not aliased). Here z = [δq, δv, δw], E = diag(I, M, E_w(t)).

Selection rule. The truncated problem has (2N+1) copies ``s + i n ω`` of each exponent; a
copy's eigenvector is the same coefficients shifted by n harmonics. We keep the copy whose
eigenvector's *harmonic centroid* ``c = Σ n ‖δq_n‖² / Σ ‖δq_n‖²`` (and δw) satisfies
|c| < ½: one copy per family in the untruncated problem, where shifting moves c by exactly
1 — the eigenvector-symmetry rule of Lazarus & Thomas 2010 (§3.2) in a form that needs no
count of the DOFs. Unlike the strip rule |Im s| ≤ ω/2 it does not need the copy of a mode
far above Nω (which the truncation lacks) to be in the problem: the central copy of any
mode has c ≈ 0. Multipliers are ``|exp(s T)| = exp(Re s · T)``; the solution is stable when
the largest is ≤ 1 + :data:`STABLE_TOL`.

Solvers. Small problems (≤ :data:`DENSE_MAX` unknowns) take every eigenvalue (LAPACK's
QZ). Larger ones take the ``n_exp`` exponents nearest the shift σ = :data:`SHIFT` × ω by
shift-invert Arnoldi (ARPACK through :func:`scipy.sparse.linalg.eigs` on
``(𝒜 − σℰ)⁻¹ ℰ``, one sparse LU): every exponent whose copy lies within the returned
``radius`` of σ is found, so the least stable ones are, as long as the radius exceeds
ω/2 + (σ − Re s) for them (reported, :attr:`Stability.radius`). ``modes`` projects δq on
a Ritz basis (the structure's modes with the contacts stuck and with them sliding, below a
cut-off) for large models.

Everything takes SI units: M kg, K N/m, C N·s/m, ω rad/s, exponents s in 1/s.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from workflow.engine.contact import SEPARATION, SLIP, STICK
from workflow.engine.jit import compiled

__all__ = ["Stability", "HillResult", "hill_exponents", "hill_descriptor", "hill_stability",
           "contact_tangent", "tangent_blocks", "monodromy", "EPS_FACTOR", "STABLE_TOL"]

#: ε of the Hill tangent as a multiple of the static contact stiffness (the rigid limit; module docstring)
EPS_FACTOR = 1.0e4
#: a multiplier up to 1 + STABLE_TOL counts as stable (neutral directions: a free rigid-body
#: motion of a separated blade has multiplier 1 to round-off)
STABLE_TOL = 1.0e-6
#: at most this many unknowns of the Hill pencil are solved densely (all eigenvalues)
DENSE_MAX = 1500
#: shift of the shift-invert Arnoldi, as a multiple of ω (right of the imaginary axis: the
#: least stable exponents are the nearest)
SHIFT = 0.05
#: exponents (with their copies) asked of ARPACK by default
N_EXP = 40
#: samples per period of the monodromy's tangent. The switching instants are located inside
#: the sample intervals (:data:`SWITCH_REFINE`); what nit still sets is the integration of the
#: smoothly varying tangent, with :data:`SUBSTEPS` and :data:`RICHARDSON` O(1/nit³): 128 pairs
#: (HBM-3, 191–234 Hz, 2026-11-29) the largest multiplier within 1.4e-5 of nit = 8192 at 256,
#: 1.7e-6 at 512, 2.1e-7 at 1024 (backward Euler extrapolated once, 2 substeps: 5.5e-4, 1.4e-4,
#: 3.4e-5, 8.7e-6 at 256 … 2048)
MONODROMY_NIT = 256
#: relative change of a pair's stick reference λ_x^T (of max|λ|) above which its anchor moves
ANCHOR_TOL = 1e-9
#: backward-Euler steps a sample interval in :func:`monodromy` (Richardson-extrapolated)
SUBSTEPS = 1
#: Richardson's halvings of the monodromy's backward-Euler step (:func:`_extrapolated`): 2 removes
#: the h and h² terms, 1, 2 and 4 steps a piece
RICHARDSON = 2
#: sub-intervals a sample interval with a switch is cut into (:func:`_switch_pieces`), level by
#: level: the monodromy knows the switching instants to ±T/(2·nit·8·8·8), as 2048 samples cut
#: into 64 did. Jenkins oscillators: (8, 8, 8) at nit = 256 and 512 at nit = 256 give the same
#: multiplier (7.44e-5 and −3.68e-4 from shooting; 2.7e-4, −3.8e-4 cut into 64 only); at 128
#: pairs 4078 DLFT samples instead of 65153 for 512. Its cost is the DLFT on the extra samples
#: and one monodromy step more a switch
SWITCH_REFINE = (8, 8, 8)


@dataclass
class HillResult:
    """:func:`hill_descriptor`'s output. ``exponents`` (k,) complex, 1/s: the selected
    Floquet exponents (one per family, sorted by decreasing real part); ``multipliers``
    |exp(sT)| of them; ``all`` every eigenvalue computed; ``centroid`` their harmonic
    centroids; ``radius`` (1/s): ARPACK's search radius about ``sigma`` (inf when dense);
    ``method`` "dense" or "shift-invert"; ``size`` unknowns of the pencil."""

    exponents: np.ndarray
    multipliers: np.ndarray
    all: np.ndarray
    centroid: np.ndarray
    radius: float
    sigma: complex
    method: str
    size: int

    @property
    def floquet_max(self) -> float:
        return float(self.multipliers.max()) if len(self.multipliers) else float("nan")


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


# ------------------------------------------------------------------ Fourier blocks
def _coefficients(samples: np.ndarray, nh: int) -> np.ndarray:
    """Complex Fourier coefficients F̂_j, j = −2N…2N, of T-periodic samples (nit, …) on
    τ_k = 2πk/nit: ``F(τ) = Σ_j F̂_j e^{ijτ}``; (4N+1, …), index j + 2N."""
    samples = np.asarray(samples)
    nit = samples.shape[0]
    if nit < 4 * nh + 1:
        raise ValueError(f"Hill: {nit} time samples alias the harmonics ±{2 * nh} of an Nh = {nh} "
                         f"Hill problem; give nit ≥ {4 * nh + 1}")
    F = np.fft.fft(samples, axis=0) / nit
    j = np.arange(-2 * nh, 2 * nh + 1)
    return F[j % nit]


def _toeplitz(hat: np.ndarray, nh: int, rows=None, cols=None) -> sp.csr_matrix:
    """Block Toeplitz (nc·a × nc·b), block (n, k) = hat[n − k] (hat: (4N+1, a, b) coefficients,
    index j + 2N), harmonic-major; ``rows``/``cols``: (a', a) / (b, b') maps applied around it
    (None: identity). Sparse: zero entries of every coefficient are left out."""
    nc = 2 * nh + 1
    _, a, b = hat.shape
    mask = np.any(hat != 0, axis=0)
    ii, jj = np.nonzero(mask)
    n = np.arange(nc)
    N, Kk = np.meshgrid(n, n, indexing="ij")
    vals = hat[(N - Kk + 2 * nh)[:, :, None], ii[None, None, :], jj[None, None, :]]   # (nc, nc, nnz)
    r = (N[:, :, None] * a + ii[None, None, :]).ravel()
    c = (Kk[:, :, None] * b + jj[None, None, :]).ravel()
    T = sp.csr_matrix((vals.ravel(), (r, c)), shape=(nc * a, nc * b))
    return T


def _blockdiag(A, nc: int, diag_scale=None) -> sp.csr_matrix:
    """I_nc ⊗ A (A dense or sparse); with ``diag_scale`` (nc,) the block n times diag_scale[n]."""
    A = sp.csr_matrix(A)
    if diag_scale is None:
        return sp.kron(sp.identity(nc, format="csr"), A, format="csr")
    return sp.kron(sp.diags(diag_scale), A, format="csr")


# ------------------------------------------------------------------ the Hill pencil
def _pencil(M, C, K, omega, nh, B=None, Ku=None, Cu=None, Kw=None, Ew=None, Au=None, Aw=None):
    """(𝒜, ℰ) sparse complex, the Hill pencil of the module docstring, unknowns ordered
    [δq (nc·m); δv (nc·m); δw (nc·na)], each harmonic-major (n = −N…N). The tangents are
    sample arrays (nit, ·, ·) on δu = B δq: Ku (r×r), Cu (r×r, velocity), Kw (r×na); the
    anchor equations ``E_w δẇ = A_u δu + A_w δw``: Ew, Aw (na×na), Au (na×r)."""
    m = M.shape[0]
    nc = 2 * nh + 1
    n = np.arange(-nh, nh + 1)
    I_m = sp.identity(m, format="csr")
    Bs = sp.identity(m, format="csr") if B is None else sp.csr_matrix(B)
    BB = _blockdiag(Bs, nc)
    iw = 1j * omega * n
    Aqq = _blockdiag(I_m, nc, -iw)
    Aqv = _blockdiag(I_m, nc)
    Avq = -_blockdiag(K, nc)
    Avv = -_blockdiag(C, nc) - _blockdiag(M, nc, iw)
    if Ku is not None:
        Avq = Avq - BB.T @ _toeplitz(_coefficients(Ku, nh), nh) @ BB
    if Cu is not None:
        Avv = Avv - BB.T @ _toeplitz(_coefficients(Cu, nh), nh) @ BB
    Eqq, Evv = _blockdiag(I_m, nc), _blockdiag(M, nc)
    if Kw is None:
        A = sp.bmat([[Aqq, Aqv], [Avq, Avv]], format="csc")
        E = sp.block_diag([Eqq, Evv], format="csc")
        return A, E
    na = Kw.shape[2]
    Ewt = _toeplitz(_coefficients(Ew, nh), nh)
    Avw = -BB.T @ _toeplitz(_coefficients(Kw, nh), nh)
    Awq = _toeplitz(_coefficients(Au, nh), nh) @ BB
    Aww = _toeplitz(_coefficients(Aw, nh), nh) - Ewt @ sp.diags(np.repeat(iw, na))
    A = sp.bmat([[Aqq, Aqv, None], [Avq, Avv, Avw], [Awq, None, Aww]], format="csc")
    E = sp.block_diag([Eqq, Evv, Ewt], format="csc")
    return A, E


def _centroid(V: np.ndarray, m: int, na: int, nh: int) -> np.ndarray:
    """Harmonic centroid Σ n w_n / Σ w_n of eigenvectors V (columns) with w_n = ‖δq_n‖² + ‖δw_n‖²."""
    nc = 2 * nh + 1
    q = np.abs(V[: nc * m]) ** 2
    w = q.reshape(nc, m, -1).sum(axis=1)
    if na:
        w = w + (np.abs(V[2 * nc * m:]) ** 2).reshape(nc, na, -1).sum(axis=1)
    n = np.arange(-nh, nh + 1)[:, None]
    tot = w.sum(axis=0)
    return (n * w).sum(axis=0) / np.where(tot > 0, tot, 1.0)


def hill_descriptor(A: sp.spmatrix, E: sp.spmatrix, omega: float, nh: int, m: int, na: int = 0, *,
                    n_exp: int | None = None, sigma: complex | None = None, dense: bool | None = None,
                    ) -> HillResult:
    """Floquet exponents of a Hill pencil (𝒜, ℰ) from :func:`_pencil` (``m`` DOFs, ``na``
    anchor states a harmonic; ω rad/s): every eigenvalue (``dense``, default when the
    pencil has ≤ :data:`DENSE_MAX` unknowns) or the ``n_exp`` nearest ``sigma`` (default
    :data:`SHIFT`·ω) by shift-invert Arnoldi, then the centroid selection (module docstring)."""
    size = A.shape[0]
    dense = size <= DENSE_MAX if dense is None else dense
    T = 2 * np.pi / omega
    sigma = SHIFT * omega if sigma is None else sigma
    if dense:
        w, V = sla.eig(A.toarray(), E.toarray(), check_finite=False, overwrite_a=True, overwrite_b=True)
        ok = np.isfinite(w)
        w, V = w[ok], V[:, ok]
        radius, method = float("inf"), "dense"
    else:
        k = min(int(n_exp or N_EXP), size - 2)
        lu = spla.splu((A - sigma * E).tocsc())
        Ec = E.tocsr()
        op = spla.LinearOperator((size, size), matvec=lambda x: lu.solve(Ec @ x), dtype=complex)
        nu, V = spla.eigs(op, k=k, which="LM", tol=1e-12, maxiter=max(1000, 20 * k))
        ok = np.abs(nu) > 0
        w, V = sigma + 1.0 / nu[ok], V[:, ok]
        radius = float(np.max(np.abs(w - sigma))) if len(w) else 0.0
        method = "shift-invert"
    c = _centroid(V, m, na, nh)
    sel = np.abs(c) < 0.5
    s = w[sel]
    order = np.argsort(-s.real)
    s = s[order]
    return HillResult(exponents=s, multipliers=np.exp(s.real * T), all=w, centroid=c, radius=radius,
                      sigma=sigma, method=method, size=size)


def hill_exponents(M, C, K, Kt_samples, Ct_samples, omega: float, nh: int, *, B=None,
                   n_exp: int | None = None, sigma: complex | None = None, dense: bool | None = None
                   ) -> HillResult:
    """Floquet exponents of ``M δq̈ + (C + Bᵀ C_t(t) B) δq̇ + (K + Bᵀ K_t(t) B) δq = 0`` by
    Hill's method truncated at ``nh`` harmonics (any linear T-periodic second-order system).

    M, C, K: (m, m) kg, N·s/m, N/m (M may be singular: massless DOFs give infinite
    eigenvalues, left out). Kt_samples, Ct_samples: (nit, r, r) the time-varying stiffness
    (N/m) and damping (N·s/m) at τ_k = 2πk/nit (None: absent), nit ≥ 4·nh+1; B (r, m)
    (default identity). ω rad/s. Returns a :class:`HillResult` (exponents in 1/s)."""
    M, C, K = (np.asarray(a, dtype=float) for a in (M, C, K))
    A, E = _pencil(M, C, K, omega, nh, B=B, Ku=None if Kt_samples is None else np.asarray(Kt_samples, float),
                   Cu=None if Ct_samples is None else np.asarray(Ct_samples, float))
    return hill_descriptor(A, E, omega, nh, M.shape[0], 0, n_exp=n_exp, sigma=sigma, dense=dense)


# ------------------------------------------------------------------ the DLFT tangent
def _moved(lam, lam_x_T, prev) -> np.ndarray:
    """(nit, p) bool: the DLFT moved the pair's stick reference at the sample (from ``prev``,
    the reference before it, N), by more than :data:`ANCHOR_TOL` of max|λ|."""
    d = lam_x_T - prev
    # ‖d‖ as np.linalg.norm takes it, and max|λ| without |λ|'s copy: the same bits at a third of the
    # time (the refined grids' signatures, 2026-11-29 round 2)
    top = max(float(lam.max()), -float(lam.min()))
    return np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]) > ANCHOR_TOL * max(top, 1e-300)


def _tangent_state(state, lam_x_T, prev) -> np.ndarray:
    """The contact state the tangent takes (nit, p): the DLFT's, except that a sample it
    labels slip while keeping the anchor (``touch``: stuck within 1e-7 of the cone, the
    reference kept bit for bit, :func:`workflow.engine.contact.dlft_pass`) is stick. The DLFT
    labels them slip for the HB Jacobian of a pair that shook down onto the cone; at a genuine
    slip → stick reversal they are the first instants of stick (the force leaves the cone
    quadratically: on the Jenkins oscillator at ω = 1.3 they lengthened each slip phase by
    6.8e-5 T, and the largest multiplier stayed 2.8e-4 off the shooting's at nit = 16384…65536,
    7.9e-5 without them). Told by the anchor kept exactly, not by a threshold on its move: near
    a reversal a slipping pair's move per sample falls below any, the finer the samples the
    earlier."""
    kept = (lam_x_T[..., 0] == prev[..., 0]) & (lam_x_T[..., 1] == prev[..., 1])
    return np.where((state == SLIP) & kept, STICK, state).astype(state.dtype)


def tangent_blocks(state, lam, lam_x_T, ref_T, eps_n, eps_t, mu, omega: float, memory: bool = True,
                   eps_dlft_t=None, prev=None, dt=None) -> dict:
    """The linearised DLFT law along the period (module docstring) pair by pair, from a
    :class:`~workflow.engine.contact.DLFTResult`'s samples: state (nit, p), λ (nit, p, 3) N,
    λ_x^T (nit, p, 2) N, its start reference ref_T (p, 2) N; ε_N, ε_T (p,) N/m of the tangent;
    μ (p,); ω rad/s; ``eps_dlft_t`` (p,) N/m the DLFT's own ε_T (λ_x^T = ε_DLFT·w; default
    ``eps_t``). ``prev`` (nit, p, 2) N: the stick reference before each sample, and ``dt``
    (nit,) s: the time since that reference (the slip rate's backward difference); default the
    uniform grid τ_k = 2πk/nit (``prev`` the previous sample's, ref_T before the first;
    dt = T/nit). With memory the tangent takes :func:`_tangent_state`.

    The law couples nothing across pairs, so it is kept as blocks: ``Kp`` (nit, p, 3, 3) N/m on
    each pair's δu; ``active`` (p,) bool the pairs with an anchor state (they slip or separate at
    some instant), ``idx`` their indices (pa,); per active pair a, on its own δu and δw only,
    ``Kw`` (nit, pa, 3, 2) N/m, ``Ew``, ``Aw`` (nit, pa, 2, 2) (Aw 1/s), ``Au`` (nit, pa, 2, 3)
    (the anchor equations ``E_w δẇ = A_u δu + A_w δw``), ``contact`` (nit, pa) bool (not separated:
    a separated pair's anchor is slaved, δw = δu_T). :func:`contact_tangent` assembles them."""
    nit, p = state.shape
    if prev is None:
        prev = np.concatenate([ref_T[None], lam_x_T[:-1]], axis=0)
    if memory:
        state = _tangent_state(state, lam_x_T, prev)
    contact, stick, slip = state != SEPARATION, state == STICK, state == SLIP
    lamT = lam[:, :, 1:]
    nT = np.linalg.norm(lamT, axis=2)
    t = lamT / np.maximum(nT, 1e-300)[:, :, None]                       # slip direction
    tt = np.einsum("kia,kib->kiab", t, t)
    I2 = np.eye(2)
    Kp = np.zeros((nit, p, 3, 3))
    Kp[:, :, 0, 0] = np.where(contact, eps_n, 0.0)
    if not memory:
        # λ_pre = λ^k + λ_x^k − λ_x^{k−1}: fac = ‖λ_T‖/‖λ_pre^T‖ (1 when touching the cone)
        fac = nT / np.maximum(np.linalg.norm(lamT + lam_x_T - prev, axis=2), 1e-300)
        Kp[:, :, 1:, 1:] = np.where(stick[:, :, None, None], eps_t[None, :, None, None] * I2,
                                    np.where(slip[:, :, None, None],
                                             (fac * eps_t[None, :])[:, :, None, None] * (I2 - tt), 0.0))
        Kp[:, :, 1:, 0] = np.where(slip[:, :, None], -(mu * eps_n)[None, :, None] * t, 0.0)
        return {"Kp": Kp, "active": np.zeros(p, bool), "idx": np.zeros(0, int)}
    # a pair's anchor is a state only if the law moves it during the period (slip or separation);
    # stuck all period, or only touching the cone (shakedown: the DLFT keeps the anchor), it is a
    # parameter of a family of periodic solutions — a neutral multiplier 1, left out
    active = np.any(_moved(lam, lam_x_T, prev) | ~contact, axis=0)
    idx = np.flatnonzero(active)
    Kp[:, :, 1:, 1:] = np.where(contact[:, :, None, None], eps_t[None, :, None, None] * I2, 0.0)
    # slip rate |ẇ| = |Δλ_x^T|/(ε_DLFT Δt) (backward difference): κ = |ẇ| ε_T / (μ|λ_N|)
    dt = np.full(nit, 2 * np.pi / omega / nit) if dt is None else np.asarray(dt, dtype=float)
    wdot = np.linalg.norm(lam_x_T - prev, axis=2) / dt[:, None] / (eps_t if eps_dlft_t is None else eps_dlft_t)[None, :]
    # κ only matters while a pair slips (μ|λ_N| > 0); elsewhere 0, not an overflow the masks then drop
    cone = mu[None, :] * np.abs(lam[:, :, 0])
    kappa = np.divide(wdot * eps_t[None, :], cone, out=np.zeros_like(cone), where=cone > 0)[:, idx, None, None]
    st, sl, sep, ct = (s[:, idx, None, None] for s in (stick, slip, ~contact, contact))
    ti, tti = t[:, idx], tt[:, idx]
    ni = np.stack([-ti[..., 1], ti[..., 0]], axis=-1)                    # ⊥ t in the tangent plane
    nn = np.einsum("kia,kib->kiab", ni, ni)
    Kw = np.zeros((nit, len(idx), 3, 2))
    Kw[:, :, 1:, :] = np.where(ct, -eps_t[idx, None, None] * I2, 0.0)
    Ew = np.where(st, I2, np.where(sl, nn, 0.0))
    # slip: t-row tᵀ(δu_T − δw) + μ (ε_N/ε_T) δu_N = 0 (divided by ε_T); n-row nᵀδẇ = κ nᵀ(δu_T − δw)
    Aw = np.where(sl, -(tti + kappa * nn), np.where(sep, -I2, 0.0))
    slipAu = np.concatenate([(ti * (mu * eps_n / eps_t)[idx, None])[..., None], tti + kappa * nn], axis=-1)
    sepAu = np.concatenate([np.zeros((2, 1)), I2], axis=1)
    Au = np.where(sl, slipAu, np.where(sep, sepAu, 0.0))
    return {"Kp": Kp, "active": active, "idx": idx, "Kw": Kw, "Ew": Ew, "Aw": Aw, "Au": Au, "contact": contact[:, idx]}


def contact_tangent(state, lam, lam_x_T, ref_T, eps_n, eps_t, mu, omega: float, memory: bool = True,
                    eps_dlft_t=None, prev=None, dt=None):
    """The linearised DLFT law along the period (module docstring), assembled: the arguments
    of :func:`tangent_blocks`. Returns a dict of sample arrays on δu (3p) and the anchor states
    (2 per pair that slips or separates at some instant, ``active`` (p,) bool): ``Ku`` (nit, 3p,
    3p) N/m, ``Kw`` (nit, 3p, na) N/m, ``Ew``, ``Aw`` (nit, na, na), ``Au`` (nit, na, 3p);
    without ``memory`` only ``Ku`` (the memoryless tangent). Dense: (nit, 3p, 3p) is for small
    models (Hill's method); :func:`monodromy` takes the blocks."""
    blk = tangent_blocks(state, lam, lam_x_T, ref_T, eps_n, eps_t, mu, omega, memory, eps_dlft_t, prev, dt)
    nit, p = state.shape
    out = {"Ku": _pair_blockdiag(blk["Kp"]), "active": blk["active"]}
    if not memory:
        return out
    idx = blk["idx"]
    own = np.arange(len(idx))
    out["Kw"] = _scatter(blk["Kw"], idx, own, p, len(idx))
    out["Ew"] = _scatter(blk["Ew"], own, own, len(idx), len(idx))
    out["Aw"] = _scatter(blk["Aw"], own, own, len(idx), len(idx))
    out["Au"] = _scatter(blk["Au"], own, idx, len(idx), p)
    return out


def _scatter(blocks: np.ndarray, rows, cols, nr: int, nc: int) -> np.ndarray:
    """(nit, k, a, b) blocks → (nit, nr·a, nc·b) dense, block k at block-row rows[k], block-column cols[k]."""
    nit, k, a, b = blocks.shape
    out = np.zeros((nit, nr, a, nc, b))
    out[:, rows, :, cols, :] = blocks.transpose(1, 0, 2, 3)
    return out.reshape(nit, nr * a, nc * b)


def _pair_blockdiag(Kp: np.ndarray) -> np.ndarray:
    """(nit, p, 3, 3) per-pair blocks → (nit, 3p, 3p) block-diagonal."""
    ar = np.arange(Kp.shape[1])
    return _scatter(Kp, ar, ar, len(ar), len(ar))


def monodromy(M, C, K, B, tan: dict, omega: float, *, substeps: int = SUBSTEPS, richardson: bool = True,
              h=None, levels: int = RICHARDSON) -> np.ndarray:
    """Monodromy matrix (dimensionless, (2m + na)²) of the linearised periodic system of the
    module docstring, ``E(t) ż = A(t) z`` with z = [δq, δv, δw], by time integration over one
    period with the tangent's coefficients (:func:`tangent_blocks`, ``tan``) constant on each of
    its pieces: ``h`` (n,) s the pieces' durations in order (sum T; default the nit uniform
    intervals T/nit). Backward Euler, ``substeps`` a piece, extrapolated unless ``richardson``
    is False (Richardson, ``levels`` halvings: 2·Z(h/2) − Z(h) at 1, eliminating h and h² at 2,
    :func:`_extrapolated`). Backward Euler is the one-step method that
    handles the algebraic slip rows (E singular, index 1): the step that enters slip projects δw
    onto the cone's constraint — the saltation of the exact law. Its error: O(h²) after
    extrapolation, and that of the switching instants, which the pieces carry
    (:func:`_switch_pieces`: to T/(nit·refine)). M, C, K (m, m), B (3p, m). Each step is solved
    through its structure (:func:`_step_operators`); :func:`_live_multipliers` integrates only
    the states that are not slaved at the start."""
    m = M.shape[0]
    n = 2 * m + 2 * len(tan.get("idx", ()))
    h = _durations(tan, omega, h)
    subs = _substeps(substeps, levels if richardson else 0)
    return _extrapolated(_propagate(M, C, K, B, tan, h, subs, np.arange(len(h)), np.arange(n)))


def _substeps(substeps: int, levels: int) -> list:
    """Backward-Euler steps a piece of Richardson's table (:func:`_extrapolated`): substeps·2^j, j ≤ levels."""
    return [int(substeps) * 2 ** j for j in range(int(levels) + 1)]


def _extrapolated(Zs: list) -> np.ndarray:
    """Richardson's extrapolation of the monodromies ``Zs`` by backward Euler at s, 2s, … 2^levels·s
    steps a piece (:func:`_substeps`): Neville's table T_{j,k} = T_{j,k−1} + (T_{j,k−1} − T_{j−1,k−1})/(2^k − 1)
    removes the h^k term of the error at column k (backward Euler's error has every power of h,
    its step on a piece of constant coefficients being a rational function of h). Each of the
    terms is L-stable (→ 0 for a stiff mode), and so is their combination."""
    T = [Zs[0]]
    for j in range(1, len(Zs)):
        row = [Zs[j]]
        for k in range(1, j + 1):
            row.append(row[k - 1] + (row[k - 1] - T[k - 1]) / (2 ** k - 1))
        T = row
    return T[-1]


def _durations(tan: dict, omega: float, h) -> np.ndarray:
    """The pieces' durations (s): ``h``, checked, or the nit uniform intervals T/nit."""
    nit = tan["Kp"].shape[0]
    h = np.full(nit, 2 * np.pi / omega / nit) if h is None else np.asarray(h, dtype=float)
    if h.shape != (nit,):
        raise ValueError(f"monodromy: {h.shape} durations for {nit} tangent pieces")
    return h


def _live_multipliers(M, C, K, B, tan: dict, omega: float, *, substeps: int = SUBSTEPS, h=None,
                      levels: int = RICHARDSON) -> np.ndarray:
    """The nonzero Floquet multipliers of :func:`monodromy` (with as many zeros as it takes), at a
    fraction of its cost: the period starts at the piece with the fewest pairs in contact (the
    eigenvalues of Φ(T + t₀, t₀) = Φ(t₀, 0)Φ(T, t₀) and of Φ(T, 0) = Φ(T, t₀)Φ(t₀, 0) are the
    same), and only the states that are not slaved there are integrated: δq, δv and the anchors
    of the pairs in contact. A separated pair's anchor is slaved (δw = δu_T: its column of the
    monodromy is zero), so the monodromy is block-triangular and its nonzero eigenvalues are
    those of the live block. At 128 pairs (Ritz size 7, 112 anchors) 18 columns instead of 238."""
    m = M.shape[0]
    h = _durations(tan, omega, h)
    idx = tan.get("idx", np.zeros(0, int))
    contact = tan.get("contact", np.zeros((len(h), 0), bool))
    k0 = int(np.argmin(contact.sum(axis=1))) if len(idx) else 0
    order = (k0 + np.arange(len(h))) % len(h)
    a = np.flatnonzero(contact[k0])
    cols = np.concatenate([np.arange(2 * m), 2 * m + np.stack([2 * a, 2 * a + 1], axis=1).ravel()]).astype(int)
    Z = _extrapolated(_propagate(M, C, K, B, tan, h[order], _substeps(substeps, levels), order, cols))
    return np.linalg.eigvals(Z[cols])


#: pieces whose step operators :func:`_propagate` holds at once (memory: at 128 pairs, Ritz size 7, 4 MB)
_CHUNK = 256


def _propagate(M, C, K, B, tan: dict, h: np.ndarray, subs, order: np.ndarray, cols: np.ndarray) -> list:
    """[Z (n, len(cols)) for s in ``subs``]: the columns ``cols`` of the identity carried over the
    pieces ``order`` of ``tan`` (durations ``h``, s, in that order) by s backward-Euler steps a
    piece (:func:`_step_operators`). Every s in one sweep over the pieces: the law's blocks, which
    do not depend on the step, are prepared once a chunk for all of them (:func:`_law_blocks`). A
    separated pair's anchor rows are slaved (δw = δu_T): they are not carried but set from δq when
    the pair touches again (``touch``, :func:`_index_rows`) and at the end."""
    m = M.shape[0]
    Bd = np.asarray(B.toarray() if sp.issparse(B) else B, dtype=float)
    Bp = Bd.reshape(-1, 3, m)                                   # (p, 3, m): each pair's rows of B
    idx = tan.get("idx", np.zeros(0, int))
    contact = tan.get("contact", np.ones((len(order), 0), bool))[order]
    BT = Bp[idx, 1:, :]                                         # (pa, 2, m): δu_T of the anchors' pairs
    n = 2 * m + 2 * len(idx)
    touch = np.zeros_like(contact)
    touch[1:] = contact[1:] & ~contact[:-1]                     # the pairs that touch again at the piece
    ptr, rows, ta = _index_rows(touch, m)
    slaved = BT[ta].reshape(-1, m)                              # their rows δw = B_T δq
    Zs = [np.eye(n)[:, cols] for _ in subs]
    v1 = np.empty((m, len(cols)))
    for lo in range(0, len(order), _CHUNK):     # the step operators of a chunk of pieces at a time (memory)
        law = _law_blocks(K, Bp, tan, order[lo:lo + _CHUNK])
        for Z, sub in zip(Zs, subs):
            ops = _step_operators(M, C, law, h[lo:lo + _CHUNK] / sub)
            if _pieces_numba is not None:
                _pieces_numba(Z, ops["Av"], ops["hs"], ops["ptr"], ops.get("rows", _NO_ROWS),
                              ops.get("D", _NO_D), ops.get("P", np.zeros((0, m))),
                              np.ascontiguousarray(ptr[lo:lo + len(ops["hs"]) + 1]), rows, slaved, int(sub), m)
                continue
            for j in range(len(ops["hs"])):
                k = lo + j
                if ptr[k + 1] > ptr[k]:     # the anchors of the pairs that touch again start from their slaved value
                    r = slice(2 * ptr[k], 2 * ptr[k + 1])
                    Z[rows[r]] = slaved[r] @ Z[:m]
                for _ in range(sub):
                    _step(Z, v1, ops, j, m)
    for Z in Zs:
        _slave(Z, ~contact[-1], BT, m)
    return Zs


def _index_rows(mask: np.ndarray, m: int):
    """(ptr (n+1,), rows (2e,), a (e,)) of the entries (k, a) of ``mask`` (n, pa) bool in order of k:
    piece k's are e ∈ [ptr[k], ptr[k+1]), their anchors a and rows 2m + 2a, 2m + 2a + 1 of the state."""
    k, a = np.nonzero(mask)
    ptr = np.searchsorted(k, np.arange(mask.shape[0] + 1))
    return ptr, 2 * m + np.stack([2 * a, 2 * a + 1], axis=1).ravel(), a


def _slave(Z, which: np.ndarray, BT: np.ndarray, m: int) -> None:
    """The anchor rows of the pairs ``which`` (pa,) bool set to their slaved value δw = δu_T = B_T δq."""
    a = np.flatnonzero(which)
    if len(a):
        rows = 2 * m + np.stack([2 * a, 2 * a + 1], axis=1).ravel()
        Z[rows] = BT[a].reshape(2 * len(a), m) @ Z[:m]


def _law_blocks(K, Bp, tan: dict, sel: np.ndarray) -> dict:
    """The parts of :func:`_step_operators` on the pieces ``sel`` that do not depend on the step:
    ``KB`` (n, m, m) N/m = K + BᵀK_u B, and of the anchors ``L`` (n, m, pa, 2) N/m = BᵀK_w per pair,
    and the entries (piece, pair) whose 2×2 block must be solved (``ke``, ``ae``): not stuck (a stuck
    pair's E_w = I, A_w = A_u = 0 give D = I, P = 0 exactly) and in contact or pushing (a separated
    pair's rows are slaved, and with K_w = 0 it adds nothing: 80 % of them at 128 pairs), with their
    ``Ew``, ``Aw`` (1/s), ``AuB`` = A_u B_a (e, 2, m), ``Le`` (e, m, 2), ``slip`` (in contact: their
    rows are carried). Only the nonzero law is multiplied out: per pair the components of K_u that
    are nonzero somewhere (memory: the diagonal), K_w where ≠ 0 (in contact)."""
    m = K.shape[0]
    Kp = tan["Kp"][sel]
    n, p = Kp.shape[:2]
    comp = np.flatnonzero(np.any(Kp != 0, axis=(0, 1)))          # of the 3×3 components
    ci, cj = np.divmod(comp, 3)
    W = (Bp[:, ci, :, None] * Bp[:, cj, None, :]).reshape(p * len(comp), m * m)     # B_iᵀ B_j per pair
    KB = K + (Kp.reshape(n, p, 9)[:, :, comp].reshape(n, -1) @ W).reshape(n, m, m)
    idx = tan.get("idx", np.zeros(0, int))
    out = {"KB": KB, "pa": len(idx)}
    if not len(idx):
        return out
    Ba = Bp[idx]                                                             # (pa, 3, m)
    Kw, Ew, Aw, Au = (tan[k][sel] for k in ("Kw", "Ew", "Aw", "Au"))
    push = np.any(Kw != 0, axis=(2, 3))
    kf, af = np.nonzero(push)
    L = np.zeros((n, m, len(idx), 2))
    L[kf, :, af] = np.matmul(Ba[af].transpose(0, 2, 1), Kw[kf, af])         # the anchors' force BᵀK_w
    stuck = np.all(Ew == np.eye(2), axis=(2, 3)) & ~np.any(Aw, axis=(2, 3)) & ~np.any(Au, axis=(2, 3))
    contact = tan["contact"][sel]
    ke, ae = np.nonzero(~stuck & (contact | push))
    out.update(L=L, ke=ke, ae=ae, Ew=Ew[ke, ae], Aw=Aw[ke, ae], AuB=np.matmul(Au[ke, ae], Ba[ae]),
               Le=L[ke, :, ae], slip=contact[ke, ae])
    return out


def _step_operators(M, C, law: dict, hs: np.ndarray) -> dict:
    """One backward-Euler step on the pieces of ``law`` (:func:`_law_blocks`; steps ``hs`` s), solved
    for the new state z₁ = [q₁, v₁, w₁] from z₀ through the anchors' 2×2 blocks: E z₁ − hs A z₁ = E z₀
    reads q₁ = q₀ + hs v₁, and per active pair a (its δu = B_a q) ``G_a w₁ = E_w w₀ + hs A_u B_a q₁``
    with G_a = E_w − hs A_w (2×2: I in stick, hs I when separated, (1 + hs κ) nnᵀ + hs ttᵀ in slip —
    never singular), so w₁ = D w₀ + P q₁ with D = G⁻¹E_w, P = hs G⁻¹A_u B_a; the velocity rows are
    then the m×m system ``S v₁ = M v₀ − hs K_eff q₀ − hs L D w₀``, S = M + hs C + hs² K_eff,
    K_eff = K + BᵀK_u B + L P, L = BᵀK_w. Only the pairs not stuck are solved (a stuck pair's
    D = I, P = 0). Per piece: ``Av`` (m, n) with v₁ = Av z₀; of the pairs in slip (a separated one's
    rows are slaved, :func:`_propagate`) ``ptr`` (n+1,), ``rows`` (2e,), ``D`` (e, 2, 2), ``P`` (2e, m),
    piece k's entries e ∈ [ptr[k], ptr[k+1]) (:func:`_index_rows`); ``hs``."""
    m = M.shape[0]
    npc = len(hs)
    hs3 = hs[:, None, None]
    Keff, pa = law["KB"], law["pa"]
    L = np.zeros((npc, m, 0))
    ops = {"hs": hs, "ptr": np.zeros(npc + 1, int)}
    if pa:
        ke, ae = law["ke"], law["ae"]
        he = hs[ke, None, None]
        Gi = np.linalg.inv(law["Ew"] - he * law["Aw"])
        D, P = np.matmul(Gi, law["Ew"]), he * np.matmul(Gi, law["AuB"])
        Keff = Keff.copy()
        np.add.at(Keff, ke, np.matmul(law["Le"], P))                # + L P of the pairs solved
        LD = law["L"].copy()
        LD[ke, :, ae] = np.matmul(law["Le"], D)                     # L D (a stuck pair's D = I)
        L = LD.reshape(npc, m, 2 * pa)
        s = law["slip"]
        ptr, rows, _ = _index_rows(_entries_mask(ke[s], ae[s], npc, pa), m)
        ops.update(ptr=ptr, rows=rows, D=D[s], P=P[s].reshape(-1, m))
    X = np.linalg.solve(M + hs3 * C + hs3 ** 2 * Keff,
                        np.concatenate([Keff, np.broadcast_to(M, Keff.shape), L], axis=2))   # S⁻¹[K_eff, M, L D]
    ops["Av"] = np.concatenate([-hs3 * X[:, :, :m], X[:, :, m:2 * m], -hs3 * X[:, :, 2 * m:]], axis=2)
    return ops


def _entries_mask(k: np.ndarray, a: np.ndarray, n: int, pa: int) -> np.ndarray:
    """(n, pa) bool, True at the entries (k, a)."""
    mask = np.zeros((n, pa), bool)
    mask[k, a] = True
    return mask


def _step(Z, v1, ops: dict, k: int, m: int) -> None:
    """One backward-Euler step of piece k (:func:`_step_operators`) applied to the columns of Z, in
    place (``v1`` (m, ncol) scratch): the rows of the anchors that slip in the piece are updated, a
    stuck pair's stay (D = I, P = 0) and a separated one's are slaved (:func:`_propagate`)."""
    np.matmul(ops["Av"][k], Z, out=v1)                 # from the old state
    Z[:m] += ops["hs"][k] * v1                          # q₁
    Z[m:2 * m] = v1
    lo, hi = ops["ptr"][k], ops["ptr"][k + 1]
    if hi > lo:
        rows = ops["rows"][2 * lo:2 * hi]
        w0 = Z[rows]
        Z[rows] = (ops["D"][lo:hi] @ w0.reshape(-1, 2, Z.shape[1])).reshape(len(rows), -1) + ops["P"][2 * lo:2 * hi] @ Z[:m]


def _pieces_loops(Z, Av, hs, ptr, rows, D, P, tptr, trows, slaved, sub, m):
    """The pieces of one chunk of :func:`_propagate`, ``sub`` steps each, as loops for numba:
    per piece the anchors that touch again set to their slaved value (``tptr``, ``trows``,
    ``slaved``: :func:`_index_rows` of the chunk), then :func:`_step` ``sub`` times. A Python
    call per step costs more than the step (7 × 238 by 18 columns at 128 pairs). The product
    ``Av[j] @ Z`` is a loop too, compiled with fastmath so that its sums vectorise: numba's
    ``np.dot`` took 5.3 of the 6.3 s of its compilation, which a fresh checkout (CI) pays once
    a process; now 2.5 s, and the steps of a 50-point stability at 128 pairs take 0.33 s instead
    of 0.57 s (1.5 s as a plain loop; 2026-11-29, one thread)."""
    nc, nz = Z.shape[1], Z.shape[0]
    v1 = np.empty((m, nc))
    for j in range(Av.shape[0]):
        for r in range(2 * tptr[j], 2 * tptr[j + 1]):
            row = trows[r]
            for c in range(nc):
                acc = 0.0
                for i in range(m):
                    acc += slaved[r, i] * Z[i, c]
                Z[row, c] = acc
        for _ in range(sub):
            for i in range(m):
                for c in range(nc):
                    acc = 0.0
                    for q in range(nz):
                        acc += Av[j, i, q] * Z[q, c]
                    v1[i, c] = acc
            for i in range(m):
                for c in range(nc):
                    Z[i, c] += hs[j] * v1[i, c]
                    Z[m + i, c] = v1[i, c]
            for e in range(ptr[j], ptr[j + 1]):
                a, b = rows[2 * e], rows[2 * e + 1]
                for c in range(nc):
                    pa = 0.0
                    pb = 0.0
                    for i in range(m):
                        pa += P[2 * e, i] * Z[i, c]
                        pb += P[2 * e + 1, i] * Z[i, c]
                    wa, wb = Z[a, c], Z[b, c]
                    Z[a, c] = D[e, 0, 0] * wa + D[e, 0, 1] * wb + pa
                    Z[b, c] = D[e, 1, 0] * wa + D[e, 1, 1] * wb + pb


#: the compiled :func:`_pieces_loops`, or None: :func:`_step` a call a step (the test oracle)
_pieces_numba = compiled(_pieces_loops, fastmath=True)
_NO_ROWS, _NO_D = np.zeros(0, np.int64), np.zeros((0, 2, 2))


# ------------------------------------------------------------------ on a reduced model
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
    (n,) s (the slip rate's backward difference) — and ``h`` (n,) s its duration (sum T);
    ``ref_T`` (p, 2) N; ``switches`` the sample intervals refined; ``samples`` the DLFT's."""

    state: np.ndarray
    lam: np.ndarray
    lam_x_T: np.ndarray
    prev: np.ndarray
    dt: np.ndarray
    h: np.ndarray
    ref_T: np.ndarray
    switches: int
    samples: int


def _signature(ts, lam, lam_x_T, prev) -> np.ndarray:
    """The states whose changes are switches of the tangent (nit, p): :func:`_tangent_state` for
    a pair with an anchor state (:func:`contact_tangent`'s ``active``), contact or separation
    for the others (their tangent is stick in contact: a pair that shook down onto the cone and
    slips by round-off now and then has no switch to locate)."""
    contact = ts != SEPARATION
    active = np.any(_moved(lam, lam_x_T, prev) | ~contact, axis=0)
    return np.where(active[None, :], ts, np.where(contact, STICK, SEPARATION)).astype(ts.dtype)


def _switch_pieces(hb, x, nit: int, omega: float, refine) -> _Pieces:
    """The contact law along the period of the HB solution x of ``hb`` for :func:`monodromy`,
    with the switching instants located inside the sample intervals.

    The DLFT on nit uniform samples knows a stick/slip/separation switch to an interval
    (τ_{k−1}, τ_k]. Each interval where some pair's :func:`_tangent_state` changes is cut into
    ``refine`` sub-intervals, the DLFT predictor λ_u (a Fourier series: its harmonics
    evaluated at any instant) is sampled there too, and the DLFT runs again on the
    non-uniform grid (same law, same passes, from the uniform one's reference); ``refine`` a
    sequence (r₁, r₂, …): again inside the sub-intervals that hold a switch, level by level
    (:func:`_refined`) — the same location, T/(nit·r₁·r₂…), at a fraction of the samples. Each
    sample stands for its cell (midway to its neighbours), so a switch sits midway between the
    two sub-samples it falls between: to ±T/(2·nit·Πr), without bias, and a smooth coefficient
    is taken at the middle of its cell. Consecutive sub-samples of one interval in the same
    state are merged into one piece (the first one's tangent): the monodromy pays one step per
    switch more than per sample, not ``refine``. ``refine`` ≤ 1: the uniform samples, a piece
    each (a switch then known to T/nit)."""
    prob, xx = _dlft_problem(hb, x, nit, hbm=True)
    a = prob._predictor(xx)                                   # real Fourier coefficients of λ_u (N)
    res = prob._dlft(a, jacobian=False)
    T = 2 * np.pi / omega
    tau = 2 * np.pi * np.arange(nit) / nit
    prev = np.concatenate([res.ref_T[None], res.lam_x_T[:-1]], axis=0)
    ts = _tangent_state(res.state, res.lam_x_T, prev)
    sig = _signature(ts, res.lam, res.lam_x_T, prev)
    sw = np.flatnonzero(np.any(sig != np.roll(sig, 1, axis=0), axis=1))     # a switch in (τ_{k−1}, τ_k]
    factors = [int(r) for r in np.atleast_1d(refine) if int(r) > 1]
    if not factors or sw.size == 0:
        return _Pieces(ts, res.lam, res.lam_x_T, prev, np.full(nit, T / nit), np.full(nit, T / nit), res.ref_T,
                       0, nit)
    grid = (tau, np.ones(nit, bool), sig, None, None)
    for r in factors:
        grid = _refined(prob, a, res.ref_T, grid, r)
    tau_f, coarse, sig, fine, (ts_f, prev_f) = grid
    back = np.diff(np.concatenate([[tau_f[-1] - 2 * np.pi], tau_f]))          # rad, to the previous sample
    cell = 0.5 * (back + np.roll(back, -1))                                     # rad, the sample's cell
    start = np.flatnonzero(coarse | np.any(sig != np.roll(sig, 1, axis=0), axis=1))
    h = np.add.reduceat(cell, start) / omega
    return _Pieces(ts_f[start], fine.lam[start], fine.lam_x_T[start], prev_f[start], back[start] / omega, h,
                   fine.ref_T, int(sw.size), len(tau_f))


def _refined(prob, a, ref_T, grid, r: int):
    """One level of :func:`_switch_pieces`' refinement: ``grid`` (τ (n,) rad sorted in [0, 2π),
    ``coarse`` (n,) the uniform samples, the switch signature (n, p), DLFT or None, its
    (:func:`_tangent_state`, references before each sample) or None) → the same with every interval
    (τ_{k−1}, τ_k] that holds a switch, and its two neighbours, cut into ``r``, and the DLFT (λ_u's
    harmonics ``a``, from the reference ``ref_T``) run again on the new grid."""
    from workflow.engine import fourier
    from workflow.engine.contact import dlft_pass

    tau, coarse, sig = grid[:3]
    n = len(tau)
    sw = np.flatnonzero(np.any(sig != np.roll(sig, 1, axis=0), axis=1))
    # the intervals before and after too: the DLFT sees a slip → stick reversal by the sign of the
    # predictor's increment over a sample interval, up to a sample late (the reversal may lie in
    # (τ_{k−2}, τ_{k−1}]), and the refined anchors may move a switch across a sample
    ivl = np.unique((sw[:, None] + np.arange(-2, 1)[None, :]) % n)                 # interval (τ_i, τ_{i+1}]
    lo = tau[ivl]
    hi = np.where(ivl + 1 < n, tau[(ivl + 1) % n], 2 * np.pi)
    extra = lo[:, None] + (hi - lo)[:, None] * np.arange(1, r)[None, :] / r
    tau_f = np.concatenate([tau, extra.ravel()])
    order = np.argsort(tau_f, kind="stable")
    tau_f = tau_f[order]
    coarse = np.concatenate([coarse, np.zeros(extra.size, bool)])[order]
    lam_u = (fourier.trig_matrix(prob.nh, tau_f) @ a).reshape(len(tau_f), prob.p, 3)
    fine = dlft_pass(lam_u, prob.law.mu, ref_T, periodic=True, max_passes=prob.max_passes, tol=prob.pass_tol)
    prev_f = np.concatenate([fine.ref_T[None], fine.lam_x_T[:-1]], axis=0)
    ts = _tangent_state(fine.state, fine.lam_x_T, prev_f)
    return tau_f, coarse, _signature(ts, fine.lam, fine.lam_x_T, prev_f), fine, (ts, prev_f)


def _ritz(rcM, rcK, nr: int, eps: np.ndarray, omega: float, modes, cache: dict | None = None):
    """(V, key): a Ritz basis V (m, r) for δq in relative coordinates: the modes of the structure with
    every pair stuck (ε on [n, t1, t2]) and with the pairs sliding (ε on n only) below
    ``modes`` × ω if a float, or the ``modes`` lowest of each if an int; M-orthonormalised.
    ``cache``: a dict that keeps the two eigenproblems' solutions (they do not depend on ω) for
    the next call on the same structure and ε — the points of a sweep (0.55 s a point at 128
    pairs, 782 DOFs) — and the basis itself under ``key`` (the modes kept: the same at neighbouring
    points; None without a cache)."""
    vecs, kept = [], []
    for j, mask in enumerate((np.ones(3), np.array([1.0, 0.0, 0.0]))):
        key = (j, rcM.shape, eps.tobytes())
        if cache is not None and key in cache:
            lam, V = cache[key]
        else:
            Kc = rcK.copy()
            Kc[np.arange(nr), np.arange(nr)] += eps * np.tile(mask, nr // 3)
            lam, V = sla.eigh(Kc, rcM)
            if cache is not None:
                cache[key] = lam, V
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
    at ω (rad/s) on ``model`` (:class:`~reduction.reduced.ReducedModel`).

    The periodic orbit enters only through the contact law's samples along the period
    (:func:`contact_tangent` of the DLFT at x, ``nit`` samples); the structure's own M, C, K are
    those of ``model`` in relative coordinates (``rc``: :func:`reduction.condense.relative_coordinates`,
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
    from reduction.condense import relative_coordinates
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
