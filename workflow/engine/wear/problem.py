"""The coupled vibration–wear problem: R(x; W) = 0 with the wear rate of every pair
(:class:`WearProblem`), one evaluation of it with its derivatives (:class:`WearState`), and the
Newton parts of a state's Jacobian, factored once per state (:func:`_newton_parts`).

W (per pair, total depth, m) opens the normal gap ``g = u_N + gap + W``; it is shared between
flanks, ``W_blade = share·W``, ``W_disk = (1 − share)·W``.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from workflow.engine.errors import SolverError
from workflow.engine.solvers import newton
from workflow.engine.wear import structured as matrix_free
from workflow.engine.wear.law import pressure, pressure_work, wear_per_cycle

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
    #: the same derivatives without (n × n) or (n × p) arrays (:mod:`workflow.engine.wear.structured`;
    #: kept beside the formed ones too): J = ``hb.operator(G)``; ∂rate_i/∂x = g_i · ∂a_i/∂x (g
    #: before any averaging of the rates); ∂R/∂W column i = w_i on pair i's rows
    G: np.ndarray | None = None   # contact blocks (p, 3nc, 3nc) (HBProblem.contact_blocks)
    g: np.ndarray | None = None   # ∂rate_i/∂a_i (p, 3nc) [m/cycle per N]
    w: np.ndarray | None = None   # ∂R/∂W_i on pair i's rows (p, 3nc) [N/m]
    #: M = ∂rate/∂q (p, p) of a law with a length scale at this state, q the local rates
    #: (:meth:`law.Averaging.linearised`; "slip" and "all": rate = M q), or None: the node-wise law
    rate_map: np.ndarray | None = None
    #: E (p, p) of a law whose averaged rate takes the pressure work q2 too, δrate = M δq +
    #: E δq2 (:meth:`law.Averaging.linearised`), or None; with it ∂q2_i/∂a_i (p, 3nc) [m·Pa/cycle
    #: per N] and ∂q2_i/∂W_i (p,) [Pa/cycle]
    q2_map: np.ndarray | None = None
    g2: np.ndarray | None = None
    G_W2: np.ndarray | None = None

    def averaged(self, dq, dq2=None):
        """The averaged rate's variation (p, …) from the local rates' ``dq`` and, where the law
        takes it (:attr:`q2_map`), the pressure works' ``dq2`` (p, …): ``M dq + E dq2``."""
        if self.rate_map is None:
            return dq
        out = self.rate_map @ dq
        return out if self.q2_map is None else out + self.q2_map @ dq2

    def own(self) -> tuple:
        """(g̃ (p, 3nc), G̃_W (p,)): the part of each pair's averaged rate's derivatives that
        goes through its own predictor and W — the diagonal of :meth:`averaged` (all of it for
        the node-wise law). The matrix-free step takes these (a W-method,
        :func:`workflow.engine.wear.structured.augmented_step`)."""
        if self.rate_map is None:
            return self.g, self.G_W
        m = np.diagonal(self.rate_map)
        g, gw = m[:, None] * self.g, m * self.G_W
        if self.q2_map is not None:
            e = np.diagonal(self.q2_map)
            g, gw = g + e[:, None] * self.g2, gw + e * self.G_W2
        return g, gw

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
        self.hb = hb
        #: the averaging of the frictional power over a length (the wear law with a length scale,
        #: :class:`workflow.engine.wear.law.Averaging`), or None: the node-wise law (eq. 21). It
        #: couples the pairs' rates; the matrix-free step takes that coupling's diagonal only (a
        #: W-method, :func:`workflow.engine.wear.structured.augmented_step`).
        self.averaging = averaging
        #: the linear algebra of the HB solves and pseudo-time steps: matrix-free J and GMRES
        #: (True), or J formed and factored (False; the implicit reference march always forms
        #: it); None: by size (:func:`workflow.engine.wear.structured.use`)
        self.structured = matrix_free.use(hb.n) if structured is None else bool(structured)
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
        S = E = None
        if self.averaging is not None:
            q2 = pressure_work(lam, slip, self.area, self.k_w) if self.averaging.needs_q2 else None
            rate, S, E = self.averaging.linearised(rate, q2)
        st = WearState(R=R, rate=rate, lam=lam, slip=slip, J=J, rate_map=S, q2_map=E)
        if not jacobian:
            return st
        g, g2 = self.rate_sensitivity(res, law, lam, slip, q2=E is not None)
        # W_i enters a only through pair i's normal shift: da_{j,i,N}/dW_i = ε_N,i const_j
        daW = np.zeros((self.p, 3 * self.nc))
        daW[:, 0::3] = law.eps_n[:, None] * self._const[None, :]
        st.G_W = np.einsum("pa,pa->p", g, daW)
        if g2 is not None:
            st.g2, st.G_W2 = g2, np.einsum("pa,pa->p", g2, daW)
        # ∂R/∂W_i: pair i's contact block times da_i/dW_i, on pair i's rows only
        w = np.einsum("pab,pb->pa", G, daW)
        st.G, st.g, st.w = G, g, w
        if not dense:
            return st
        # chain to x: a = a_F − A y + ε (y + shift)  ⇒  da/dy = diag(ε) − A; every row of a
        # belongs to one pair, so ∂rate/∂x has row i = g_i · (diag ε − A)[pair i's rows]
        st.G_x = hb.penalty_rows(g[:, None, :])[:, 0, :]
        if S is not None:                   # δrate = M δq (+ E δq2): the same chain for each
            G2_x = None if g2 is None else hb.penalty_rows(g2[:, None, :])[:, 0, :]
            st.G_x = st.averaged(st.G_x, G2_x)
            # M diag(G_W) (+ E diag(G_W2)) by columns: no (p, p) product with a diagonal
            st.G_W = S * st.G_W[None, :] + (0.0 if E is None else E * st.G_W2[None, :])
        st.R_W = np.zeros((self.n, self.p))
        st.R_W[self._rows, np.arange(self.p)[:, None]] = w
        return st

    def rate_sensitivity(self, res, law, lam, slip, q2: bool = False):
        """(∂q_i/∂a_i (p, 3nc) [m/cycle per N], ∂q2_i/∂a_i or None): the local wear rate's
        derivative in pair i's predictor (eq. 21 through the DLFT's dλ/da) and, if
        ``q2``, that of the pressure work (:func:`workflow.engine.wear.law.pressure_work`)."""
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
        g = self.k_w * (np.einsum("kin,ki->in", dpm, s) + np.einsum("ki,kin->in", pm, ds))   # (p, ncol)
        if not q2:
            return g, None
        g2 = np.einsum("kin,ki->in", 2.0 * pm[..., None] * dpm, s) + np.einsum("ki,kin->in", pm * pm, ds)
        return g, self.k_w * g2

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


#: reciprocal condition number (1-norm, LAPACK's estimate from the LU factors) below which a
#: state's J counts as singular for the wear solves
MIN_RCOND = 1e-14


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
