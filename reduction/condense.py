"""Exact per-harmonic condensation onto relative contact DOFs (paper eq. 3–4).

Paper eq. 3 writes ``Z_r = (B H Bᵀ)⁻¹`` with ``H = D⁻¹``. A dovetail blade is
held only through its contact pairs, so at harmonic 0 ``D_0 = K`` is singular
(the blade floats) and ``H_0`` does not exist. We therefore change
coordinates first, ``q = T [u_r; y]`` with ``B T = [I, 0]``, so the relative
displacements are explicit unknowns, and take the Schur complement onto them:

    Z_r = D'_rr − D'_ry D'_yy⁻¹ D'_yr,     F_r = f'_r − D'_ry D'_yy⁻¹ f'_y,

with ``D' = Tᵀ D T``, ``f' = Tᵀ f``. ``D'_yy`` is the structure with the
interface tied, which is regular; where ``D`` is regular this equals eq. 3
exactly. The relative equations are then ``Z_r U_r + λ = F_r`` (eq. 3), with
λ the DLFT multiplier (sign: ``docs/contracts.md`` §6).

Complex harmonic amplitudes follow ``docs/contracts.md`` §3:
``D_j = K − (jω)² M + i jω C`` [N/m], ω in rad/s.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from reduction.reduced import ReducedModel


@dataclass
class RelativeCoordinates:
    """A reduced model rewritten in coordinates ``z = [u_r; y]`` (``q = T z``).

    Computed once per model; every frequency and harmonic reuses it.
    """

    M: np.ndarray  # Tᵀ M T
    K: np.ndarray
    C: np.ndarray
    f_static: np.ndarray  # Tᵀ f
    f_harmonic: np.ndarray
    O: np.ndarray  # O T: z → observed DOFs
    n_rel: int  # 3p


@dataclass
class Condensed:
    """Per-harmonic condensed dynamic stiffness and load at one ω.

    ``Zr``: (Nh+1, 3p, 3p) complex [N/m]; ``Fr``: (Nh+1, 3p) complex [N];
    ``dZr``, ``dFr``: their derivatives with respect to ω [per rad/s], or None.
    """

    omega: float
    Zr: np.ndarray
    Fr: np.ndarray
    dZr: np.ndarray | None = None
    dFr: np.ndarray | None = None

    @property
    def nh(self) -> int:
        return self.Zr.shape[0] - 1


def relative_coordinates(model: ReducedModel) -> RelativeCoordinates:
    """Build ``T`` with ``B T = [I, 0]`` from a QR factorisation of ``Bᵀ``.

    ``B = Rᵀ Qᵀ`` (economy QR of Bᵀ, B of full row rank 3p), so
    ``T = [Q R⁻ᵀ, N]`` with N an orthonormal basis of null(B).
    """
    B = model.B
    n_rel, m = B.shape
    Q, R = np.linalg.qr(B.T, mode="complete")
    Rr = R[:n_rel]
    if n_rel and np.min(np.abs(np.diag(Rr))) <= 1e-12 * np.max(np.abs(np.diag(Rr))):
        raise ValueError("relative-displacement map B is rank deficient: two pairs share DOFs?")
    T = np.empty((m, m))
    T[:, :n_rel] = sla.solve_triangular(Rr, Q[:, :n_rel].T, lower=False).T  # Q R⁻ᵀ
    T[:, n_rel:] = Q[:, n_rel:]
    return RelativeCoordinates(M=T.T @ model.M @ T, K=T.T @ model.K @ T, C=T.T @ model.C @ T,
                               f_static=T.T @ model.f_static, f_harmonic=T.T @ model.f_harmonic,
                               O=model.O @ T, n_rel=n_rel)


def dynamic_stiffness(rc: RelativeCoordinates, j: int, omega: float) -> tuple[np.ndarray, np.ndarray]:
    """``D_j`` and ``∂D_j/∂ω`` in relative coordinates (paper eq. 4, complex form)."""
    w = j * omega
    D = rc.K - w * w * rc.M + 1j * w * rc.C
    dD = -2.0 * j * w * rc.M + 1j * j * rc.C
    return D, dD


def harmonic_load(rc: RelativeCoordinates, j: int) -> np.ndarray:
    """Complex amplitude of the load at harmonic j: static at 0, cos(ωt) force at 1."""
    if j == 0:
        return rc.f_static.astype(complex)
    if j == 1:
        return rc.f_harmonic.astype(complex)
    return np.zeros(rc.M.shape[0], dtype=complex)


def condense(rc: RelativeCoordinates, omega: float, nh: int, derivative: bool = False) -> Condensed:
    """Condense onto relative DOFs for harmonics 0…nh at ω [rad/s] (eq. 3).

    One LU of ``D'_yy`` per harmonic serves Z_r, F_r and their ω-derivatives.
    """
    r = rc.n_rel
    Zr = np.empty((nh + 1, r, r), dtype=complex)
    Fr = np.empty((nh + 1, r), dtype=complex)
    dZr = np.empty_like(Zr) if derivative else None
    dFr = np.empty_like(Fr) if derivative else None
    for j in range(nh + 1):
        D, dD = dynamic_stiffness(rc, j, omega)
        f = harmonic_load(rc, j)
        if D.shape[0] == r:
            # every coordinate is a relative contact DOF (e.g. Den Hartog's oscillator):
            # nothing to condense, and LAPACK refuses an empty factorisation
            Zr[j], Fr[j] = D, f
            if derivative:
                dZr[j], dFr[j] = dD, np.zeros(r, dtype=complex)
            continue
        lu = sla.lu_factor(D[r:, r:], check_finite=False)
        rhs = np.concatenate([D[r:, :r], f[r:, None]], axis=1)
        sol = sla.lu_solve(lu, rhs, check_finite=False)
        A, b = sol[:, :r], sol[:, r]  # D_yy⁻¹ D_yr, D_yy⁻¹ f_y
        Zr[j] = D[:r, :r] - D[:r, r:] @ A
        Fr[j] = f[:r] - D[:r, r:] @ b
        if derivative:
            # D is complex symmetric, so D_ry D_yy⁻¹ = Aᵀ.
            At = A.T
            dZr[j] = dD[:r, :r] - dD[:r, r:] @ A - At @ dD[r:, :r] + At @ dD[r:, r:] @ A
            dFr[j] = -dD[:r, r:] @ b + At @ (dD[r:, r:] @ b)
    return Condensed(omega=omega, Zr=Zr, Fr=Fr, dZr=dZr, dFr=dFr)


def recover(rc: RelativeCoordinates, omega: float, Ur: np.ndarray) -> np.ndarray:
    """Observed response harmonics (Nh+1, n_obs) from relative ones ``Ur`` (Nh+1, 3p).

    Solves the tied remainder ``D'_yy y = f'_y − D'_yr u_r`` per harmonic and
    maps ``z = [u_r; y]`` to the observed DOFs.
    """
    r = rc.n_rel
    out = np.empty((Ur.shape[0], rc.O.shape[0]), dtype=complex)
    for j in range(Ur.shape[0]):
        D, _ = dynamic_stiffness(rc, j, omega)
        f = harmonic_load(rc, j)
        y = np.linalg.solve(D[r:, r:], f[r:] - D[r:, :r] @ Ur[j]) if D.shape[0] > r else np.zeros(0, complex)
        out[j] = rc.O[:, :r] @ Ur[j] + rc.O[:, r:] @ y
    return out
