"""Harmonic conventions of bladewear (docs/contracts.md §3), in one place.

* Normalised time ``τ = ωt`` (rad), samples ``τ_k = 2πk/nit``, ``k = 0…nit−1``.
* Real harmonic-major coefficients ``[u0; u1c; u1s; …; uNc; uNs]`` — an array
  whose leading axis has ``nc = 2Nh+1`` entries (paper eq. 2); any trailing
  axes (DOFs, pairs, components) ride along.
* Complex amplitude of harmonic j: ``U_j = u_jc − i u_js``, so that
  ``u(τ) = Re Σ_j U_j e^{ijτ}``; harmonic 0 is real. Complex arrays have a
  leading axis of ``Nh+1`` entries.
* Real block form of a complex per-harmonic stiffness ``Z_j = A + iB`` acting
  on ``[u_jc; u_js]``: ``[[A, B], [−B, A]]`` (paper eq. 4 with
  ``A = K − (jω)²M``, ``B = jωC``).
* HDHB operators for ``nit = 2Nh+1`` (paper eqs. 6, 7, 9): ``T`` maps time
  samples to real coefficients, ``T⁻¹`` coefficients to samples.

The units of every array are those of the quantity it carries (m for
displacements, N for forces, N/m for stiffnesses); the transforms are
dimensionless.

Time ⇄ frequency transforms of sampled signals use ``numpy.fft.rfft/irfft``
(O(nit log nit)), never a dense nit × nit DFT; the small nit × nc matrices
below exist for Jacobians only.
"""
from __future__ import annotations

import numpy as np

__all__ = [
    "n_coef", "check_nit", "real_to_complex", "complex_to_real", "to_time",
    "to_freq", "time_from_coef_matrix", "coef_from_time_matrix",
    "hdhb_operators", "real_block", "real_block_diag", "derivative_matrix",
    "derivative", "sample_times",
]


def n_coef(nh: int) -> int:
    """Number of real coefficients ``2Nh+1`` of a series truncated at ``Nh``."""
    return 2 * int(nh) + 1


def default_nit(nh: int) -> int:
    """Time samples per period when a scene says 0: the smallest power of 2 ≥ 4·(2Nh+1), at
    least 64. Why not 2Nh+1: the DLFT's stick–slip transitions alias onto the retained
    harmonics. Light-pad chain at its peak (0.95 ω₁) against its rigid-ground integration,
    error of HBM at Nh = 3 / 7 / 11 / 17 (2026-11-28, ``python -m workflow.bench.penalty_bias
    --part default``): nit = 2Nh+1: 8.8 / 1.35 / 0.77 / 0.48 %; 4(2Nh+1): 1.25 / 0.44 / 0.32 /
    0.27 %. The power of 2 keeps the rfft fast; 64 costs nothing at small Nh."""
    return max(64, 1 << int(np.ceil(np.log2(4 * n_coef(nh)))))


def check_nit(nit: int, nh: int, name: str = "nit") -> None:
    """Raise ``ValueError`` unless ``nit ≥ 2Nh+1`` (no aliasing of retained harmonics).

    With fewer samples the ``Nh``-th harmonic is not resolved and the
    frequency → time → frequency round trip is not the identity.
    """
    if int(nit) != nit or nit < n_coef(nh):
        raise ValueError(f"{name} = {nit}: need an integer nit ≥ 2·Nh+1 = {n_coef(nh)} "
                         f"time samples for Nh = {nh}")


def sample_times(nit: int) -> np.ndarray:
    """Normalised instants ``τ_k = 2πk/nit`` (rad), shape (nit,)."""
    return 2.0 * np.pi * np.arange(nit) / nit


def real_to_complex(x: np.ndarray) -> np.ndarray:
    """Real harmonic-major (2Nh+1, …) → complex (Nh+1, …) with ``U_j = u_jc − i u_js``
    (single precision stays single: the structured solve's preconditioner, :mod:`workflow.engine.linsolve`)."""
    x = np.asarray(x)
    x = x if x.dtype == np.float32 else x.astype(float, copy=False)
    nc = x.shape[0]
    if nc % 2 != 1:
        raise ValueError(f"real coefficient array needs an odd leading size 2Nh+1, got {nc}")
    nh = (nc - 1) // 2
    U = np.empty((nh + 1,) + x.shape[1:], dtype=np.complex64 if x.dtype == np.float32 else complex)
    U[0] = x[0]
    U[1:] = x[1::2] - 1j * x[2::2]
    return U


def complex_to_real(U: np.ndarray) -> np.ndarray:
    """Complex (Nh+1, …) → real harmonic-major (2Nh+1, …); Im U_0 is dropped (single precision stays single)."""
    U = np.asarray(U)
    nh = U.shape[0] - 1
    x = np.empty((2 * nh + 1,) + U.shape[1:], dtype=np.float32 if U.dtype == np.complex64 else float)
    x[0] = U[0].real
    x[1::2] = U[1:].real
    x[2::2] = -U[1:].imag
    return x


def to_time(U: np.ndarray, nit: int) -> np.ndarray:
    """Time samples ``u(τ_k) = Re Σ_j U_j e^{ijτ_k}`` of complex harmonics (eq. 2).

    ``U``: complex (Nh+1, …) → real (nit, …) by ``irfft`` along axis 0.
    Requires ``nit ≥ 2Nh+1``.
    """
    U = np.asarray(U)
    nh = U.shape[0] - 1
    check_nit(nit, nh)
    # irfft computes (1/nit)[X_0 + 2 Re Σ X_m e^{imτ}] (m below Nyquist), hence
    # X_0 = nit·U_0 and X_m = nit·U_m/2.
    X = np.zeros((nit // 2 + 1,) + U.shape[1:], dtype=complex)
    X[0] = nit * U[0].real
    X[1:nh + 1] = 0.5 * nit * U[1:]
    return np.fft.irfft(X, n=nit, axis=0)


def to_freq(u_t: np.ndarray, nh: int) -> np.ndarray:
    """Complex harmonics 0…Nh of time samples (nit, …) on ``τ_k = 2πk/nit``.

    Inverse of :func:`to_time` for band-limited signals; for others it is the
    Galerkin (least-squares) projection onto harmonics 0…Nh, i.e. the AFT
    step of paper Fig. 1. Requires ``nit ≥ 2Nh+1``.
    """
    u_t = np.asarray(u_t, dtype=float)
    nit = u_t.shape[0]
    check_nit(nit, nh)
    X = np.fft.rfft(u_t, axis=0)[: nh + 1]
    U = X * (2.0 / nit)
    U[0] = X[0].real / nit
    return U


def time_from_coef_matrix(nh: int, nit: int) -> np.ndarray:
    """Matrix E (nit × 2Nh+1) with ``u(τ_k) = Σ_j E[k, j] x_j`` (eq. 2/6, the paper's T⁻¹).

    Columns: 1, cos jτ, sin jτ for j = 1…Nh. Small; for Jacobians only.
    """
    check_nit(nit, nh)
    return trig_matrix(nh, sample_times(nit))


def trig_matrix(nh: int, tau: np.ndarray) -> np.ndarray:
    """Rows ``[1, cos jτ, sin jτ]`` (len(τ) × 2Nh+1) at arbitrary instants τ [rad] (eq. 2)."""
    E = np.empty((len(tau), n_coef(nh)))
    E[:, 0] = 1.0
    j = np.arange(1, nh + 1)
    E[:, 1::2] = np.cos(np.outer(tau, j))
    E[:, 2::2] = np.sin(np.outer(tau, j))
    return E


def coef_from_time_matrix(nh: int, nit: int) -> np.ndarray:
    """Matrix P (2Nh+1 × nit): real coefficients of samples (the paper's T, eq. 7).

    ``P = (2/nit)[½; cos jτ_k; sin jτ_k]``; ``P @ E = I`` for ``nit ≥ 2Nh+1``
    and ``P = E⁻¹`` when ``nit = 2Nh+1``.
    """
    E = time_from_coef_matrix(nh, nit)
    P = (2.0 / nit) * E.T
    P[0] *= 0.5
    return P


def hdhb_operators(nh: int) -> tuple[np.ndarray, np.ndarray]:
    """``(T, Tinv)`` of paper eqs. 7 and 9 for ``nit = 2Nh+1``.

    ``x = T @ u_samples`` (coefficients of samples), ``u_samples = Tinv @ x``.
    They are the scalar operators; the paper's ``⊗ I_N`` acts on trailing axes.
    """
    nit = n_coef(nh)
    return coef_from_time_matrix(nh, nit), time_from_coef_matrix(nh, nit)


def real_block(Z: np.ndarray, dtype=float) -> np.ndarray:
    """The real form of complex harmonic blocks ``Z`` (…, m, m): (…, 2m, 2m) with rows and
    columns (cos, sin) × DOF, ``[[Re Z, Im Z], [−Im Z, Re Z]]`` — ``U = u_c − i u_s`` mapped
    to ``(Re ZU, −Im ZU)`` (eq. 4). Units those of ``Z``."""
    Z = np.asarray(Z)
    m = Z.shape[-1]
    out = np.empty(Z.shape[:-2] + (2, m, 2, m), dtype=dtype)
    A, B = Z.real, Z.imag
    out[..., 0, :, 0, :], out[..., 0, :, 1, :], out[..., 1, :, 0, :], out[..., 1, :, 1, :] = A, B, -B, A
    return out.reshape(Z.shape[:-2] + (2 * m, 2 * m))


def real_block_diag(Z: np.ndarray) -> np.ndarray:
    """Harmonic-block-diagonal real matrix of complex (Nh+1, m, m) per-harmonic ``Z``.

    Returns (nc·m × nc·m) acting on flattened harmonic-major real vectors
    (coefficient index major, DOF minor); harmonic 0 uses ``Re Z_0`` only.
    Units those of ``Z``.
    """
    Z = np.asarray(Z)
    nh = Z.shape[0] - 1
    m = Z.shape[1]
    nc = n_coef(nh)
    out = np.zeros((nc, m, nc, m))
    out[0, :, 0, :] = Z[0].real
    blocks = real_block(Z[1:]).reshape(nh, 2, m, 2, m)
    for j in range(1, nh + 1):
        out[2 * j - 1:2 * j + 1, :, 2 * j - 1:2 * j + 1, :] = blocks[j - 1]
    return out.reshape(nc * m, nc * m)


def derivative_matrix(nh: int) -> np.ndarray:
    """d/dτ on real coefficients (nc × nc): ``(u_jc, u_js) → (j u_js, −j u_jc)``.

    Dimensionless (per radian of τ); multiply by ω for d/dt.
    """
    nc = n_coef(nh)
    D = np.zeros((nc, nc))
    for j in range(1, nh + 1):
        D[2 * j - 1, 2 * j] = j
        D[2 * j, 2 * j - 1] = -j
    return D


def derivative(U: np.ndarray) -> np.ndarray:
    """d/dτ of complex harmonics (Nh+1, …): ``U_j → i j U_j``."""
    U = np.asarray(U)
    j = np.arange(U.shape[0]).reshape((-1,) + (1,) * (U.ndim - 1))
    return 1j * j * U
