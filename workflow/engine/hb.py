"""Harmonic-balance problems on a condensed model: HBM, TCM and HDHB (paper §1–2).

The linear part is given per harmonic on the relative contact DOFs
(docs/contracts.md §5): ``Zr`` complex (Nh+1, 3p, 3p) in N/m and ``Fr``
complex (Nh+1, 3p) in N, so that ``Zr U_r + λ = Fr`` (eq. 3). The contact
multiplier λ comes from the DLFT law of :mod:`workflow.engine.contact` (eqs. 11–17),
the same law for the three formulations:

* ``hbm`` — unknowns: real harmonic coefficients of U_r (eq. 2),
  ``n = (2Nh+1)·3p``; residual in frequency ``R = Z Ũ + λ̃ − F̃`` (eq. 3), λ̃
  by AFT (rfft to nit samples, DLFT pass, rfft back), nit ≥ 2Nh+1 free.
* ``tcm`` — unknowns: the same coefficients; residual in time at 2Nh+1
  collocation instants ``R = T⁻¹(Z Ũ − F̃) + λ̄`` (eqs. 5–8). The DLFT runs on
  the nit grid; the collocation instants are the grid samples
  ``k_m = ⌊m·nit/(2Nh+1)⌋``, m = 0…2Nh — equally spaced (exactly the paper's
  τ_m) when 2Nh+1 divides nit (nit = 105 serves Nh = 1, 2, 3, 7, 17), only
  nearly so otherwise (the square collocation system stays well posed: the
  trigonometric interpolation at distinct instants is unisolvent). We do not
  use the least-squares variant: least squares over all nit samples is
  exactly the Galerkin HBM above.
* ``hdhb`` — unknowns: time samples Ū at nit = 2Nh+1 instants (eq. 9),
  ``R = H Ū + λ̄ − F̄`` (eq. 10) with ``H = T⁻¹ Z T`` where our ``T`` maps
  samples to coefficients (the paper's eq. 10 writes ``T Z T⁻¹`` with its
  own labelling; ours is the one consistent with ``Ũ = T Ū``); the DLFT acts
  directly on the unknown instants (eq. 12).

With nit = 2Nh+1 the three are the same equations in different unknowns
(``R_tcm = T⁻¹ R_hbm``, ``R_hdhb(Ū) = T⁻¹ R_hbm(T Ū)``) and share roots.

All three are one code path: with ``y`` the unknowns, ``a`` the predictor in
the space the DLFT is differentiated against (coefficients for HBM/TCM,
samples for HDHB)::

    a   = a_F − A y + ε (y + shift)            (eq. 11/12)
    λ_u = basis · a   (time samples)           λ = DLFT(λ_u)
    R   = Rlin y − r_F + Q λ
    J   = Rlin + G (diag ε − A),   G = Q · dλ/da  (block-diagonal over pairs)

Unknown ordering is always leading-index major: ``y.reshape(2Nh+1, 3p)``,
pair-major ``[p0n, p0t1, p0t2, p1n, …]`` inside each block.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workflow.engine import fourier
from workflow.engine.contact import STICK, ContactLaw, DLFTResult, dlft
from workflow.engine.errors import SceneError
from workflow.engine.linsolve import ContactJacobian, StructuredSolve, split_pq, zb_apply
from workflow.engine.solvers import SolveResult, newton, powell

__all__ = ["METHODS", "HBProblem", "StaticState", "condensed_form"]

METHODS = ("hbm", "tcm", "hdhb")


def condensed_form(c) -> dict:
    """The :class:`HBProblem` keywords of a condensation's form (``compliance``, ``stiffness``:
    :class:`workflow.engine.condense.Condensed`): none for the stiffness form."""
    if getattr(c, "compliance", False):
        return {"compliance": True, "stiffness": c.stiffness}
    return {}


@dataclass
class StaticState:
    """The harmonic-0 (static preload) contact state, :meth:`HBProblem.static_state`.

    u       (p, 3) static relative displacement (m)
    lam     (p, 3) static multiplier (N); λ_N < 0 in contact
    state   (p,) 0 separation, 1 stick, 2 slip
    anchor  (p, 2) tangential stick anchor (m) carried into the dynamic solve
    result  the Newton :class:`SolveResult`
    """

    u: np.ndarray
    lam: np.ndarray
    state: np.ndarray
    anchor: np.ndarray
    result: SolveResult


class HBProblem:
    """A harmonic-balance problem ``Zr U_r + λ(U_r) = Fr`` on relative contact DOFs.

    Parameters
    ----------
    Zr : complex (≥Nh+1, 3p, 3p) condensed dynamic stiffness per harmonic (N/m);
        harmonic 0 real. Harmonics above ``nh`` are ignored.
    Fr : complex (≥Nh+1, 3p) condensed forcing per harmonic (N).
    contact : :class:`~workflow.engine.contact.ContactLaw` with p pairs.
    nh : number of harmonics Nh ≥ 0.
    nit : time samples per period for the DLFT (nit ≥ 2Nh+1; = 2Nh+1 for hdhb).
    method : "hbm", "tcm" or "hdhb".
    max_passes, pass_tol : DLFT periodic passes limit and tolerance.
    stick_anchor : (p, 2) initial tangential stick anchor (m); if None it is
        set by :meth:`static_state` (called by :meth:`x0`), zeros before.
    static : a :class:`StaticState` already solved (e.g. by
        :func:`workflow.engine.static_state`, with its ε-continuation): used
        by :meth:`x0` and, if ``stick_anchor`` is None, for the anchor.
    compliance : HBM in the interface forces (:func:`~workflow.engine.linsolve.split_pq`): ``Zr`` holds Z_0 and
        the compliances H_j = Z_j⁻¹ (m/N) of harmonics j ≥ 1, and ``stiffness(j, U_j)`` →
        Z_j U_j (N) converts a displacement guess (:meth:`unknowns_from_harmonics`).
    """

    def __init__(self, Zr, Fr, contact: ContactLaw, nh: int, nit: int, method: str = "hbm", *,
                 max_passes: int = 30, pass_tol: float = 1e-10, stick_anchor=None, static=None,
                 compliance: bool = False, stiffness=None):
        if method not in METHODS:
            raise SceneError(f"hb.method: {method!r} is not one of {', '.join(METHODS)}")
        if compliance and method != "hbm":
            raise SceneError(f"hb.method: {method!r} has no compliance form (a whole disk's harmonic balance is hbm)")
        self.compliance, self.stiffness = bool(compliance), stiffness
        if not isinstance(contact, ContactLaw):
            raise TypeError("contact must be a ContactLaw")
        nh = int(nh)
        if nh < 0:
            raise SceneError(f"hb.harmonics: Nh = {nh} must be ≥ 0")
        Zr = np.asarray(Zr)
        Fr = np.asarray(Fr)
        p = contact.p
        nr = 3 * p
        if Zr.ndim != 3 or Zr.shape[0] < nh + 1 or Zr.shape[1:] != (nr, nr):
            raise SceneError(f"hb: Zr has shape {Zr.shape}, expected (≥{nh + 1}, {nr}, {nr}) "
                             f"for Nh = {nh} and {p} pairs")
        if Fr.shape[0] < nh + 1 or Fr.shape[1:] != (nr,):
            raise SceneError(f"hb: Fr has shape {Fr.shape}, expected (≥{nh + 1}, {nr})")
        if not (np.all(np.isfinite(Zr)) and np.all(np.isfinite(Fr))):
            raise SceneError("hb: Zr or Fr contains NaN or inf")
        nc = fourier.n_coef(nh)
        if int(nit) != nit or nit < nc:
            raise SceneError(f"hb.time_samples: nit = {nit} must be an integer ≥ 2·Nh+1 = {nc}")
        if method == "hdhb" and nit != nc:
            raise SceneError(f"hb.time_samples: HDHB needs nit = 2·Nh+1 = {nc} (got {nit}); "
                             "its unknowns are the samples themselves")
        self.method, self.nh, self.nit, self.p = method, nh, int(nit), p
        self.nc, self.nr, self.n = nc, nr, nc * nr
        self.law = contact
        self.max_passes, self.pass_tol = int(max_passes), float(pass_tol)
        self.stick_anchor = np.zeros((p, 2)) if stick_anchor is None else \
            np.array(stick_anchor, dtype=float).reshape(p, 2)
        if stick_anchor is None and static is not None:
            self.stick_anchor = np.array(static.anchor, dtype=float).reshape(p, 2)
        self._anchor_set = stick_anchor is not None or static is not None
        self._static: StaticState | None = static
        self.last_dlft: DLFTResult | None = None
        self.linsolver = None          # a StructuredSolve kept by the cascade for this frequency
        self.stats = {"evaluations": 0, "jacobians": 0, "max_passes": 0, "unconverged_passes": 0}
        self._set_linear(Zr[: nh + 1], Fr[: nh + 1])

    # ------------------------------------------------------------------ set-up
    def _set_linear(self, Zr, Fr):
        nh, nc, nit = self.nh, self.nc, self.nit
        self.Zr, self.Fr = Zr, Fr
        self._lin_memo = None                                     # (x, _linear(x)) of the last x
        Fc = fourier.complex_to_real(Fr)                          # (nc, nr)
        self.F_coef = Fc
        self.load_factor = 1.0                                    # :meth:`scale_load`
        self._dense = None                                        # (n × n) forms, on demand only
        E = fourier.time_from_coef_matrix(nh, nit)                # (nit, nc)
        if self.method == "hbm":
            self.basis = E
            self._Lr = None                                       # identity
            self._Lp = None
            self.Q = fourier.coef_from_time_matrix(nh, nit)       # Galerkin projection
            self._const = np.eye(nc)[0]                           # constant term = coef 0
        elif self.method == "tcm":
            self.kc = (np.arange(nc) * nit) // nc                 # collocation grid indices
            Ec = fourier.trig_matrix(nh, 2.0 * np.pi * self.kc / nit)   # (nc, nc) = T⁻¹ at τ_m
            self.basis = E
            self._Lr = Ec
            self._Lp = None
            self.Q = None                                          # selection of rows kc
            self._const = np.eye(nc)[0]
            self._Ec = Ec
        else:  # hdhb
            T, Tinv = fourier.hdhb_operators(nh)
            self.T, self.Tinv = T, Tinv
            self.basis = np.eye(nit)
            self._Lr = Tinv
            self._Lp = Tinv
            self.Q = None                                          # identity
            self._const = np.ones(nc)                              # a constant in every sample
        self.r_F = self._apply_L(self._Lr, Fc)
        self.a_F = self._apply_L(self._Lp, Fc)
        if not np.isfinite(np.linalg.norm(self.r_F)):
            # every tolerance is relative to ‖F‖: an infinite one would accept any residual
            raise SceneError("hb: the load's norm ‖F_r‖ overflows (excitation.amplitude or the "
                             "preload too large for double precision)")
        self._refresh_penalty()

    def load_terms(self, F_coef) -> tuple[np.ndarray, np.ndarray]:
        """(r_F (n,), a_F (nc, nr)): where real load coefficients ``F_coef`` (2Nh+1, 3p) [N]
        enter the residual and the DLFT predictor — both linear in the load."""
        return self._apply_L(self._Lr, F_coef).ravel(), self._apply_L(self._Lp, F_coef)

    def scale_load(self, s: float) -> None:
        """The dynamic load (harmonics ≥ 1 of ``Fr``) × s in the residual and the predictor, the
        static preload kept (a held amplitude's load scale,
        :mod:`workflow.engine.studies.amplitude`); ``Fr`` stays the unit load."""
        Fc = fourier.complex_to_real(self.Fr)
        Fc[1:] *= s
        self.F_coef, self.load_factor = Fc, float(s)
        self.r_F, self.a_F = self._apply_L(self._Lr, Fc), self._apply_L(self._Lp, Fc)

    # The linear operators, applied without forming (n × n) matrices: Zb
    # harmonic by harmonic (workflow.engine.linsolve.zb_apply), HDHB's H = T⁻¹ Zb T
    # with FFTs (T: samples → coefficients is an rfft, T⁻¹ an irfft).
    def _to_coef(self, y):
        return fourier.complex_to_real(fourier.to_freq(y, self.nh))

    def _to_samples(self, c):
        return fourier.to_time(fourier.real_to_complex(c), self.nit)

    def _apply_A(self, y):
        """A y for y (nc, nr): Zb y (HBM, TCM) or H y (HDHB); in the compliance form the forces
        P y the unknowns stand for (:func:`~workflow.engine.linsolve.split_pq`)."""
        return self._apply_PQ(y)[0]

    def _apply_PQ(self, y):
        """(A y, the displacement coefficients of y): (Zb y, y) in the stiffness form, HDHB's
        (T⁻¹ Zb T y, y), the compliance form's (P y, Q y) — one product with the arrays of Zr."""
        if self.method == "hdhb":
            return self._to_samples(zb_apply(self.Zr, self._to_coef(y))), y
        return split_pq(zb_apply(self.Zr, y), y, self.compliance)

    def _linear(self, x):
        """(u, A y, Rlin y) for the unknowns x, y = x as (nc, nr), u its displacement
        coefficients (y itself but in the compliance form): one product with Zb serves
        the DLFT predictor and the residual's linear part (Rlin = A for HBM and HDHB, Ec·A
        for TCM); at 512 pairs that product is the residual's largest cost. The last x's
        are kept (:meth:`residual_along`): Newton's Jacobian at an accepted trial point
        makes no product again."""
        x = np.asarray(x, dtype=float)
        if self._lin_memo is not None and np.array_equal(self._lin_memo[0], x):
            return self._lin_memo[1]
        Ay, u = self._apply_PQ(x.reshape(self.nc, self.nr))
        return self._remember(x, Ay, self._rlin(Ay), u if self.compliance else None)

    def _rlin(self, Ay):
        return self._Ec @ Ay if self.method == "tcm" else Ay

    def _remember(self, x, Ay, Ry, u=None):
        """(u, A y, Rlin y) kept for x; u (the compliance form's displacement coefficients) or,
        by default, a view of the memo's own copy of x, never of the caller's array: MINPACK
        (Powell) overwrites its x buffer in place, and a kept view of it turned the next
        residual at the same point into garbage."""
        xc = np.array(x, dtype=float)
        lin = (xc.reshape(self.nc, self.nr) if u is None else u, Ay, Ry)
        self._lin_memo = (xc, lin)
        return lin

    def residual_along(self, x, dx):
        """``α → (x + α dx, R(x + α dx))`` for a line search along dx from x: the linear part
        is ``A x + α A dx`` (A linear), so the trial points cost one product with Zb in all
        (A dx) instead of one each; the accepted point's is kept for its Jacobian
        (:meth:`_linear`). Measured on the 512-pair sector (HBM Nh = 7, 9 points): 216 → 90
        products of 11.7 ms. Equal to :meth:`residual` to round-off (1e-16 of ‖A x‖)."""
        x = np.asarray(x, dtype=float)
        dx = np.asarray(dx, dtype=float)
        u, Ay, Ry = self._linear(x)
        Ad, ud = self._apply_PQ(dx.reshape(self.nc, self.nr))
        Rd = self._rlin(Ad)

        def at(alpha: float):
            xt = x + alpha * dx
            lin = self._remember(xt, Ay + alpha * Ad, Ry + alpha * Rd, u + alpha * ud if self.compliance else None)
            return xt, self._evaluate(xt, False, lin)[0]
        return at

    def _dense_parts(self):
        """The dense (n × n) Rlin and A (N/m), formed on first use and kept —
        for the dense Jacobian (:meth:`residual_jacobian`) of small problems."""
        if self._dense is None:
            nc, n, nr = self.nc, self.n, self.nr
            Zb = fourier.real_block_diag(self.Zr)
            if self.compliance:     # (P, Q): P = diag(Z_0, I, …), Q = diag(I, H_1, …)
                P, Q = np.eye(n), Zb.copy()
                P[:nr, :nr], Q[:nr, :nr] = Zb[:nr, :nr], np.eye(nr)
                self._dense = (P, P, Q)
            elif self.method == "hbm":
                self._dense = (Zb, Zb)
            elif self.method == "tcm":
                self._dense = ((self._Ec @ Zb.reshape(nc, -1)).reshape(n, n), Zb)
            else:
                # H = (T⁻¹ ⊗ I) Zb (T ⊗ I), as two BLAS products
                H = (self.Tinv @ Zb.reshape(nc, -1)).reshape(n, nc, nr)
                H = np.matmul(H.transpose(0, 2, 1), self.T).transpose(0, 2, 1).reshape(n, n)
                self._dense = (H, H)
        return self._dense

    @property
    def Rlin(self) -> np.ndarray:
        """Dense linear part of the Jacobian (n × n, N/m); formed on first access."""
        return self._dense_parts()[0]

    @property
    def A(self) -> np.ndarray:
        """Dense predictor matrix (n × n, N/m) of ``a = a_F − A y + …``; formed on first access."""
        return self._dense_parts()[1]

    def _eps_dense(self) -> np.ndarray:
        """∂(ε u)/∂y (n × n, N/m): diag ε, or diag ε · Q in the compliance form."""
        eps = np.tile(self._eps, self.nc)
        return eps[:, None] * self._dense_parts()[2] if self.compliance else np.diag(eps)

    def _refresh_penalty(self):
        self._eps = self.law.eps().reshape(self.nr)
        self._shift = np.outer(self._const, self.law.offset().reshape(self.nr))   # (nc, nr)
        self._pen = None

    def _penalty_parts(self):
        """(diag ε − A, its per-harmonic blocks or None), dense, on first use."""
        if self._pen is not None:
            return self._pen
        M = self._eps_dense() - self.A                                       # diag ε − A
        blocks = None
        if self.method != "hdhb":
            # HBM/TCM: A = Z is block-diagonal in harmonics, so G·(diag ε − A) only
            # couples the cos/sin coefficients of one harmonic: keep those blocks,
            # per pair rows (j, c') → (p, 3s, s·3p), to multiply by G harmonic by harmonic.
            nc, p, nr = self.nc, self.p, self.nr
            M5 = M.reshape(nc, p, 3, nc, nr)
            blocks = []
            for h in range(self.nh + 1):
                idx = [0] if h == 0 else [2 * h - 1, 2 * h]
                s = len(idx)
                Mh = M5[np.ix_(idx, range(p), range(3), idx, range(nr))]
                Mh = np.ascontiguousarray(Mh.transpose(1, 0, 2, 3, 4)).reshape(p, 3 * s, s * nr)
                blocks.append((idx, Mh))
        self._pen = (M, blocks)
        return self._pen

    @staticmethod
    def _apply_L(L, v):
        return v if L is None else L @ v

    def linear_form(self, stiffness=None) -> dict:
        """The keywords that give another problem this one's form: ``compliance`` and its
        ``stiffness`` map (``stiffness``: another frequency's, else this one's)."""
        return {"compliance": self.compliance, "stiffness": stiffness or self.stiffness}

    def with_linear(self, Zr, Fr, stiffness=None) -> "HBProblem":
        """A new problem at another frequency: same law, method, Nh, nit, anchor, form
        (``stiffness``: the compliance form's map at that frequency) and the same
        :class:`~workflow.engine.linsolve.StructuredSolve`, if any."""
        new = HBProblem(Zr, Fr, self.law, self.nh, self.nit, self.method, max_passes=self.max_passes,
                        pass_tol=self.pass_tol, stick_anchor=self.stick_anchor, static=self._static,
                        **self.linear_form(stiffness))
        new._anchor_set = True
        # the structured solve's blocks are lagged anyway: a neighbouring frequency's are a
        # good preconditioner (GMRES always solves with the new K), refactored when GMRES slows
        new.linsolver = self.linsolver
        return new

    @property
    def static(self) -> StaticState | None:
        """The static state in use (given, or solved by :meth:`x0`), or None."""
        return self._static

    def set_wear(self, W) -> None:
        """Set the wear depth vector W (p,) in metres (opens the normal gap)."""
        self.law = self.law.with_wear(W)
        # W only shifts the normal gap: ε, hence diag ε − A and its blocks, are unchanged
        self._shift = np.outer(self._const, self.law.offset().reshape(self.nr))

    def set_contact(self, law: ContactLaw) -> None:
        """Replace the contact law (same number of pairs)."""
        if law.p != self.p:
            raise SceneError(f"contact: {law.p} pairs given, the model has {self.p}")
        self.law = law
        self._refresh_penalty()

    def set_stick_anchor(self, anchor) -> None:
        """Set the tangential stick anchor (p, 2) in metres: the start-of-period
        stick reference is ``λ_x^{−1,T} = ε_T · anchor`` (only matters for pairs
        that stick during the whole period)."""
        self.stick_anchor = np.array(anchor, dtype=float).reshape(self.p, 2)
        self._anchor_set = True

    def stick_anchor_of(self, x) -> np.ndarray:
        """The converged period-start stick anchor (p, 2, m) of the state x — to
        carry the interface's history to the next solve (e.g. next frequency)."""
        res = self._dlft(self._predictor(x), jacobian=False)
        return res.ref_T / self.law.eps_t[:, None]

    def residual_scale(self) -> float:
        """‖F‖₂ in the residual's space (N); the solvers' tolerance is relative to it."""
        s = float(np.linalg.norm(self.r_F))
        return s if s > 0 else 1.0

    # ------------------------------------------------------------ conversions
    def coefficients(self, x) -> np.ndarray:
        """Real harmonic coefficients (2Nh+1, 3p) of U_r (m) for unknowns x."""
        y = np.asarray(x, dtype=float).reshape(self.nc, self.nr)
        if self.compliance:
            return self._linear(x)[0].copy()
        return self.T @ y if self.method == "hdhb" else y

    def unknowns_from_coefficients(self, coef) -> np.ndarray:
        """Unknown vector (n,) from real coefficients (2Nh+1, 3p) of U_r; in the compliance
        form the forces Z_j U_j of harmonics ≥ 1, by the problem's ``stiffness`` map."""
        coef = np.asarray(coef, dtype=float).reshape(self.nc, self.nr)
        if self.compliance:
            if self.stiffness is None:
                raise SceneError("hb: a compliance-form problem needs its stiffness map to take a displacement guess")
            U = fourier.real_to_complex(coef)
            for j in range(1, self.nh + 1):
                U[j] = self.stiffness(j, U[j])
            return fourier.complex_to_real(U).ravel()
        return (self.Tinv @ coef if self.method == "hdhb" else coef).ravel()

    def unknowns_from_harmonics(self, U) -> np.ndarray:
        """Unknown vector from complex harmonics (any number ≥ 1, 3p) of U_r: those above Nh
        dropped, the missing ones zero (a root at another Nh seeds this one)."""
        U = np.asarray(U)
        full = np.zeros((self.nh + 1, self.nr), dtype=complex)
        m = min(len(U), self.nh + 1)
        full[:m] = U[:m]
        return self.unknowns_from_coefficients(fourier.complex_to_real(full))

    def harmonics(self, x) -> np.ndarray:
        """Complex harmonics (Nh+1, 3p) of U_r (m), ``U_j = u_jc − i u_js``."""
        return fourier.real_to_complex(self.coefficients(x))

    def relative_time(self, x) -> np.ndarray:
        """u_r at τ_k = 2πk/nit, (nit, p, 3) in the pair frames (m)."""
        return fourier.to_time(self.harmonics(x), self.nit).reshape(self.nit, self.p, 3)

    # --------------------------------------------------------------- contact
    def _predictor(self, x, linear=None):
        """The DLFT predictor a (eqs. 11–12) at x (N); ``linear``: :meth:`_linear` of x, if made."""
        y, Ay, _ = self._linear(x) if linear is None else linear
        return self.a_F - Ay + self._eps * (y + self._shift)

    def _dlft(self, a, jacobian, projected: bool = False):
        """The DLFT of the predictor a; ``projected``: its ``dlam`` as HBM's contact rows Q·dλ/da
        (:meth:`contact_blocks`, :func:`workflow.engine.contact.dlft_pass` ``rows``), not per instant."""
        lam_u = (self.basis @ a).reshape(self.nit, self.p, 3)
        rows = self.Q if projected and jacobian and self.method == "hbm" else None
        res = dlft(self.law, lam_u, self.stick_anchor, basis=self.basis, jacobian=jacobian,
                   max_passes=self.max_passes, tol=self.pass_tol, rows=rows)
        self.last_dlft = res
        self.stats["max_passes"] = max(self.stats["max_passes"], res.passes)
        if not res.converged:
            self.stats["unconverged_passes"] += 1
        return res

    def contact_time(self, x) -> np.ndarray:
        """λ at τ_k, (nit, p, 3) in the pair frames (N); λ_N < 0 in contact."""
        return self._dlft(self._predictor(x), jacobian=False).lam

    def contact_state(self, x) -> np.ndarray:
        """Contact state per instant and pair (nit, p): 0 separation, 1 stick, 2 slip."""
        return self._dlft(self._predictor(x), jacobian=False).state

    def contact_harmonics(self, x) -> np.ndarray:
        """Complex harmonics (Nh+1, 3p) of λ (N), consistent with ``Zr U + λ = Fr``
        at a root: the Galerkin projection of the samples (HBM, HDHB) or the
        trigonometric interpolant through the collocation instants (TCM)."""
        lam = self.contact_time(x).reshape(self.nit, self.nr)
        if self.method == "tcm":
            return fourier.real_to_complex(np.linalg.solve(self._Ec, lam[self.kc]))
        return fourier.to_freq(lam, self.nh)

    def _lam_rows(self, lam):
        """Contact term of the residual from time samples (nit, nr) → (nc, nr)."""
        if self.method == "hbm":
            return fourier.complex_to_real(fourier.to_freq(lam, self.nh))
        if self.method == "tcm":
            return lam[self.kc]
        return lam

    def contact_blocks(self, dlam, projected: bool = False):
        """Per-pair blocks G (p, 3nc, 3nc) of Q·dλ/da, rows (m, c), columns (j, c'): the
        contact part of the Jacobian, ``J = Rlin + G (diag ε − A)`` (dimensionless).
        ``dlam`` is :attr:`DLFTResult.dlam` of an evaluation with the Jacobian (``projected``:
        of :meth:`_dlft` with ``projected``, HBM's Q·dλ/da already)."""
        if self.method == "hbm":
            G = dlam.transpose(1, 0, 2, 3) if projected else np.einsum("ok,kicn->iocn", self.Q, dlam, optimize=True)
        elif self.method == "tcm":
            G = dlam[self.kc].transpose(1, 0, 2, 3)
        else:
            G = dlam.transpose(1, 0, 2, 3)
        return np.ascontiguousarray(G).reshape(self.p, 3 * self.nc, 3 * self.nc)

    def apply_contact_blocks(self, G, V):
        """Block-diagonal G (:meth:`contact_blocks`) times V whose rows are ordered
        (j, pair, c'); V (n, ...) → (n, ...), e.g. ``∂R/∂p = G ∂a/∂p`` for a
        parameter p entering the DLFT predictor a."""
        nc, p = self.nc, self.p
        tail = V.shape[1:]
        Vp = V.reshape((nc, p, 3) + tail)
        Vp = np.moveaxis(Vp, 1, 0).reshape((p, 3 * nc, -1))
        out = np.matmul(G, Vp).reshape((p, nc, 3, -1))
        return np.moveaxis(out, 0, 1).reshape((self.n,) + tail)

    def _GM(self, G):
        """G · (diag ε − A) (n × n): batched per pair, harmonic by harmonic for HBM/TCM."""
        M, Mblocks = self._penalty_parts()
        if Mblocks is None:
            return self.apply_contact_blocks(G, M)
        nc, p = self.nc, self.p
        rows = self.penalty_rows(G).reshape(p, nc, 3, self.n)
        return rows.transpose(1, 0, 2, 3).reshape(self.n, self.n)

    def penalty_rows(self, G) -> np.ndarray:
        """Rows G (p, k, 3nc) per pair, over the columns (j, c) of that pair's predictor a, times
        ``diag ε − A`` = ∂a/∂y: (p, k, n), block i = G_i · (diag ε − A)[rows of pair i] (N/m
        per unit of G). For HBM/TCM one product per harmonic (A is block-diagonal in
        harmonics); the wear rate's ∂/∂x takes it with k = 1 (:mod:`workflow.engine.wear`): 0.7 ms a
        state at 128 pairs (n = 2688, Nh = 3) against 18.7 ms for the (p × n)(n × n) product
        with mostly zero rows it replaced, equal to 2e-16."""
        M, Mblocks = self._penalty_parts()
        nc, p, nr, n = self.nc, self.p, self.nr, self.n
        k = G.shape[1]
        if Mblocks is None:     # HDHB: A couples every harmonic; the pair's rows of M, gathered
            Mp = np.ascontiguousarray(M.reshape(nc, p, 3, n).transpose(1, 0, 2, 3)).reshape(p, 3 * nc, n)
            return np.matmul(G, Mp)
        G4 = G.reshape(p, k, nc, 3)
        out = np.empty((p, k, nc, nr))
        for idx, Mh in Mblocks:
            s = len(idx)
            out[:, :, idx, :] = np.matmul(G4[:, :, idx, :].reshape(p, k, 3 * s), Mh).reshape(p, k, s, nr)
        return out.reshape(p, k, n)

    # -------------------------------------------------------------- residual
    def _evaluate(self, x, jacobian, lin=None, form: bool = True):
        x = np.asarray(x, dtype=float)
        if x.shape != (self.n,):
            raise ValueError(f"x must have shape ({self.n},), got {x.shape}")
        lin = self._linear(x) if lin is None else lin
        res = self._dlft(self._predictor(x, lin), jacobian)
        R = lin[2].ravel() - self.r_F.ravel() + self._lam_rows(res.lam.reshape(self.nit, self.nr)).ravel()
        self.stats["evaluations"] += 1
        if not jacobian:
            return R, None, None
        G = self.contact_blocks(res.dlam)
        if not form:
            return R, None, G
        J = self.jacobian(G)
        self.stats["jacobians"] += 1
        return R, J, G

    def jacobian(self, G) -> np.ndarray:
        """``Rlin + G (diag ε − A)`` (n × n, N/m), formed, for contact blocks G
        (:meth:`contact_blocks`); :meth:`operator` is the same matrix-free."""
        return self.Rlin + self._GM(G)

    def residual(self, x) -> np.ndarray:
        """Residual R(x) (n,) in N (eq. 3 / 8 / 10 for hbm / tcm / hdhb)."""
        return self._evaluate(x, False)[0]

    def residual_jacobian(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(R, J) with the analytic Jacobian J = ∂R/∂x (n × n, N/m), exact for the
        converged DLFT pass away from stick/slip/separation switches."""
        R, J, _ = self._evaluate(x, True)
        return R, J

    def coefficient_blocks(self, G) -> np.ndarray:
        """The per-pair DLFT blocks G (:meth:`contact_blocks`) brought to harmonic
        coefficients, G̃ (p, 3nc, 3nc), so that ``J = L_r K L_p⁻¹`` with
        ``K = Zb + G̃ (diag ε − Zb)`` (:mod:`workflow.engine.linsolve`): G itself for
        HBM, ``Ec⁻¹ G`` for TCM, ``T G T⁻¹`` for HDHB (per pair, on the time
        indices)."""
        if self.method == "hbm":
            return G
        nc, p = self.nc, self.p
        G5 = G.reshape(p, nc, 3, nc, 3)
        if self.method == "tcm":
            G5 = np.einsum("am,pmcjd->pacjd", np.linalg.inv(self._Ec), G5, optimize=True)
        else:
            G5 = np.einsum("am,pmcjd,jb->pacbd", self.T, G5, self.Tinv, optimize=True)
        return np.ascontiguousarray(G5).reshape(p, 3 * nc, 3 * nc)

    def residual_blocks(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(R, G): the residual and its per-pair contact blocks (:meth:`contact_blocks`), with
        ``last_dlft.dlam`` per instant, J not formed: ``J = Rlin + G (diag ε − A)`` is
        :meth:`operator` of G (the wear march's structured steps, :mod:`workflow.engine.wear`)."""
        R, _, G = self._evaluate(x, True, form=False)
        self.stats["jacobians"] += 1
        return R, G

    def operator(self, G):
        """``Rlin + G (diag ε − A)`` for per-pair blocks G (p, 3nc, 3nc) laid out as
        :meth:`contact_blocks`, matrix-free: :class:`~workflow.engine.linsolve.ContactJacobian`."""
        left, right = {"hbm": (None, None), "tcm": (self._Ec if self.method == "tcm" else None, None),
                       "hdhb": (getattr(self, "Tinv", None), getattr(self, "T", None))}[self.method]
        return ContactJacobian(self.Zr, self._eps, self.coefficient_blocks(G), left=left, right=right,
                               compliance=self.compliance)

    def penalty_apply(self, v) -> np.ndarray:
        """``(diag ε − A) v`` = ∂a/∂y · v for unknowns v (n,): (nc, nr) in the predictor's layout
        (N per unit of v) — one product with Zb (compliance form: ``ε Q v − P v``)."""
        y = np.asarray(v, dtype=float).reshape(self.nc, self.nr)
        Ay, u = self._apply_PQ(y)
        return self._eps * u - Ay

    def residual_operator(self, x):
        """(R, J) with J the matrix-free :class:`~workflow.engine.linsolve.ContactJacobian`
        (the same ∂R/∂x as :meth:`residual_jacobian`, never formed): for
        :func:`workflow.engine.solvers.newton` with ``linear=StructuredSolve()``."""
        x = np.asarray(x, dtype=float)
        if x.shape != (self.n,):
            raise ValueError(f"x must have shape ({self.n},), got {x.shape}")
        lin = self._linear(x)
        res = self._dlft(self._predictor(x, lin), True, projected=True)
        R = lin[2].ravel() - self.r_F.ravel() + self._lam_rows(res.lam.reshape(self.nit, self.nr)).ravel()
        self.stats["evaluations"] += 1
        self.stats["jacobians"] += 1
        return R, self.operator(self.contact_blocks(res.dlam, projected=True))

    def residual_jacobian_omega(self, x, dZr, dFr):
        """(R, J, ∂R/∂ω) given the ω-derivatives of the linear part (contracts §5).

        The contact law does not depend on ω but the DLFT predictor does,
        through Z and F: ``∂R/∂ω = L_r q − G L_p q`` with
        ``q = ∂Z/∂ω Ũ − ∂F/∂ω`` (coefficients). Units N·s/rad.
        """
        if self.compliance:
            raise NotImplementedError("hb: the compliance form has no ω-derivative (grid sweeps only)")
        R, J, G = self._evaluate(x, True)
        dZb = fourier.real_block_diag(np.asarray(dZr)[: self.nh + 1])
        q = (dZb @ self.coefficients(x).ravel()).reshape(self.nc, self.nr) \
            - fourier.complex_to_real(np.asarray(dFr)[: self.nh + 1])
        Rw = self._apply_L(self._Lr, q).ravel() - self.apply_contact_blocks(G, self._apply_L(self._Lp, q).ravel()[:, None])[:, 0]
        return R, J, Rw

    # ------------------------------------------------------------ initial guess
    def static_state(self, *, tol: float = 1e-10, maxiter: int = 60, apply: bool = True,
                     u0=None) -> StaticState:
        """Solve the harmonic-0 (static preload) problem alone and set the stick anchor.

        ``Zr[0] u + λ(u) = Fr[0]`` with a single DLFT step (nit = 1,
        ``periodic=False``) from a zero tangential anchor. Assumption: the
        interface was assembled stress-free and tied (zero tangential offset)
        and the static load (preload, centrifugal) is applied in one
        proportional step — no loading history. A pair that sticks keeps
        u_T = 0; one that slips ends where Coulomb lets it. The resulting
        anchor ``λ_x^T/ε_T`` (= the static u_T at convergence) becomes the
        stick reference of the dynamic solve, which fixes the otherwise
        non-unique static tangential offset of pairs that never slip
        ("stuck zeroth harmonic"). With ``apply`` False the anchor is returned
        but not set.
        """
        Z0 = np.real(self.Zr[0])
        F0 = np.real(self.Fr[0])
        p, nr = self.p, self.nr
        eps = self._eps
        off = self.law.offset().reshape(nr)
        Mst = np.diag(eps) - Z0
        one = np.ones((1, 1))
        zero = np.zeros((p, 2))

        def ev(u, jac):
            lam_u = (F0 - Z0 @ u + eps * (u + off)).reshape(1, p, 3)
            r = dlft(self.law, lam_u, zero, basis=one, periodic=False, jacobian=jac)
            R = Z0 @ u + r.lam.reshape(nr) - F0
            if not jac:
                return R, r
            G = r.dlam.reshape(p, 3, 3)
            J = Z0 + np.einsum("iab,ibn->ian", G, Mst.reshape(p, 3, nr)).reshape(nr, nr)
            return R, J, r

        scale = max(float(np.linalg.norm(F0)), 1e-300)
        start = np.zeros(nr) if u0 is None else np.asarray(u0, dtype=float).reshape(nr)
        res = newton(lambda u: ev(u, True)[:2], start, fun=lambda u: ev(u, False)[0],
                     tol=tol, scale=scale if np.linalg.norm(F0) > 0 else 1.0, maxiter=maxiter)
        _, r = ev(res.x, False)
        anchor = r.lam_x_T[0] / self.law.eps_t[:, None]
        st = StaticState(u=res.x.reshape(p, 3), lam=r.lam[0], state=r.state[0], anchor=anchor, result=res)
        if apply:
            self.stick_anchor = anchor.copy()
            self._anchor_set = True
        self._static = st
        return st

    def x0(self, sliding: bool = False) -> np.ndarray:
        """Initial guess: the static state for harmonic 0 (solving it and setting
        the anchor if no anchor was given) and, for j ≥ 1, the linear response
        with every pair in contact at the static state tied (U_j = 0 there)
        and separated pairs free (``Z_j,ff U_f = F_j,f``, under the load as scaled:
        :meth:`scale_load`). ``sliding``: pairs in
        contact keep only u_N = 0, their tangential DOFs free (μ = 0)."""
        if self._static is None:
            self.static_state(apply=not self._anchor_set)
        st = self._static
        U = np.zeros((self.nh + 1, self.nr), dtype=complex)
        U[0] = st.u.reshape(self.nr)
        free = np.repeat(st.state == 0, 3)
        if sliding:
            free = np.ones(self.nr, bool)
            free[0::3] = st.state == 0
        if self.compliance:
            return fourier.complex_to_real(self._tied_forces(U, free)).ravel()
        if free.any():
            for j in range(1, self.nh + 1):
                U[j, free] = np.linalg.solve(self.Zr[j][np.ix_(free, free)], self.load_factor * self.Fr[j, free])
        return self.unknowns_from_harmonics(U)

    def _tied_forces(self, U, free):
        """:meth:`x0`'s guess in the compliance form: harmonic 0 ``U[0]``; for j ≥ 1 the forces
        Z_j U_j of the same linear response, from H_j: a free DOF carries no contact force
        (y_f = F_f), a tied one no displacement (H_cc y_c = −H_cf y_f)."""
        Y = np.zeros_like(U)
        Y[0] = U[0]
        tied = ~free
        for j in range(1, self.nh + 1):
            Y[j, free] = self.load_factor * self.Fr[j, free]
            if tied.any() and free.any():
                H = self.Zr[j]
                Y[j, tied] = -np.linalg.solve(H[np.ix_(tied, tied)], H[np.ix_(tied, free)] @ Y[j, free])
        return Y

    # ----------------------------------------------------------------- solve
    def solve(self, x0=None, *, solver: str = "newton", tol: float = 1e-9, maxiter: int = 50,
              linear: str = "dense", **kw) -> SolveResult:
        """Solve R(x) = 0 with ``newton`` or ``powell`` (tol relative to ‖F‖).
        ``linear``: Newton's linear solve, "dense" (LU of the formed J) or
        "structured" (GMRES on the matrix-free J, :mod:`workflow.engine.linsolve`)."""
        x0 = self.x0() if x0 is None else np.asarray(x0, dtype=float)
        scale = self.residual_scale()
        if solver == "newton" and linear == "structured":
            return newton(self.residual_operator, x0, fun=self.residual, tol=tol, scale=scale,
                          maxiter=maxiter, linear=kw.pop("linsolver", None) or StructuredSolve(),
                          along=self.residual_along, **kw)
        if solver == "newton":
            if linear != "dense":
                raise SceneError(f"hb.linear_solver: {linear!r} is not one of dense, structured")
            return newton(self.residual_jacobian, x0, fun=self.residual, tol=tol, scale=scale,
                          maxiter=maxiter, **kw)
        if solver == "powell":
            return powell(self.residual, self.residual_jacobian, x0, tol=tol, scale=scale,
                          maxfev=kw.pop("maxfev", 40 * maxiter), **kw)
        raise SceneError(f"solver.method: {solver!r} is not one of newton, powell")

    def stuck_pairs(self, x) -> np.ndarray:
        """Boolean (p,): pairs that stick during the whole period at x."""
        return np.all(self.contact_state(x) == STICK, axis=0)
