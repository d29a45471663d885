"""Hill's method: Floquet exponents of a linear periodic system in the frequency domain.

Exact for a smooth periodic system (Duffing: 1e-9 against shooting at 10 harmonics) and for a
constant tangent (all pairs stuck). With the DLFT's anchors the stick/slip switches make the
anchor rows switch between differential and algebraic along the period: the truncated pencil
then has spurious eigenvalues and does not converge in N (Jenkins, ω = 1.3: 0.917, 0.839 at
N = 8, 16, an infinite one selected at 32, against 0.374), which is why the monodromy
(:mod:`workflow.engine.stability.monodromy_matrix`) is the default. Hill's method is kept for smooth
laws and as the generic core (:func:`hill_exponents`).

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
the largest is ≤ 1 + :data:`~workflow.engine.stability.floquet.STABLE_TOL`.

Solvers. Small problems (≤ :data:`DENSE_MAX` unknowns) take every eigenvalue (LAPACK's
QZ). Larger ones take the ``n_exp`` exponents nearest the shift σ = :data:`SHIFT` × ω by
shift-invert Arnoldi (ARPACK through :func:`scipy.sparse.linalg.eigs` on
``(𝒜 − σℰ)⁻¹ ℰ``, one sparse LU): every exponent whose copy lies within the returned
``radius`` of σ is found, so the least stable ones are, as long as the radius exceeds
ω/2 + (σ − Re s) for them (reported, :attr:`~workflow.engine.stability.floquet.Stability.radius`). ``modes`` projects δq on
a Ritz basis (the structure's modes with the contacts stuck and with them sliding, below a
cut-off) for large models.

SI units: M kg, K N/m, C N·s/m, ω rad/s, exponents s in 1/s.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

#: at most this many unknowns of the Hill pencil are solved densely (all eigenvalues)
DENSE_MAX = 1500


#: shift of the shift-invert Arnoldi, as a multiple of ω (right of the imaginary axis: the
#: least stable exponents are the nearest)
SHIFT = 0.05


#: exponents (with their copies) asked of ARPACK by default
N_EXP = 40


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
