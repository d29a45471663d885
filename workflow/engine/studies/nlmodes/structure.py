"""The linear part: the model in tied-mode coordinates ``w = [u_r; η_S; η_R]`` and its condensation
onto the kept unknowns ``[u_r; η_S]`` at (ω, ξ)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from workflow.engine.errors import SceneError


class _Structure:
    """The model in coordinates ``w = [u_r; η_S; η_R]``: ``z = T w`` with
    ``T = blockdiag(I, [ψ_S, Φ_R])``, ψ_S the tied mode ``mode`` (M-normalised), Φ_R the
    other tied modes. Kt, Mt, Ct, f0t, Ot: the matrices in w; na = 3p + 1 kept unknowns."""

    def __init__(self, model, mode: int):
        from workflow.engine.condense import RelativeCoordinates, relative_coordinates

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
