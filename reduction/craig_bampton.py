"""Craig–Bampton reduction: static constraint modes plus fixed-interface modes.

With the DOFs split into boundary ``b`` (kept physically) and interior ``i``,

    u = V q,   V = [[I, 0], [Ψ, Φ]]   (rows b, i; columns u_b, η),

``Ψ = −K_ii⁻¹ K_ib`` (static response of the interior to a unit boundary
displacement) and ``Φ`` the lowest mass-normalised modes of ``(K_ii, M_ii)``
(interface held fixed), ``Φᵀ M_ii Φ = I``, ``Φᵀ K_ii Φ = diag(ω²)``.

Everything with ``K_ii⁻¹`` goes through ONE sparse factorisation
(:class:`SparseFactor`): the constraint modes are one multi-right-hand-side
solve, and the fixed-interface modes come from a block shift-invert Lanczos
on the same factor. Why not SLEPc's Krylov–Schur (``reduction.eigen.eigs``,
still available with ``eigensolver="slepc"``)? A MUMPS triangular solve is
memory-bound: on a 49k-DOF P2 elasticity model one right-hand side costs
0.10 s, a block of 32 costs 0.25 s (7.7 ms each). Krylov–Schur applies the
operator one vector at a time (25 s for 30 modes there); the block method
needs a few blocks (≈ 1–2 s) and reuses the factor of the constraint modes.
Measured on the same model: MUMPS LDLᵀ factor 2.2 s + 510 right-hand sides
4.3 s, against scipy ``splu`` 18 s + 25 s (MMD ordering; 39 s + 44 s with
the default COLAMD) — so MUMPS is the default, ``splu`` the fallback.

Optional *load vectors* (``loads=``) append, per load, the interior static
response ``K_ii⁻¹ f_i`` (made M- and K-orthogonal to Φ and to each other).
With them a distributed load (centrifugal) has an exact static response in
the reduced model, without making every loaded DOF a boundary DOF.

Distributed use (:mod:`reduction.parallel`): :class:`SparseFactor` also
takes an assembled PETSc MPIAIJ matrix (parallel MUMPS; ``solve`` then maps
this rank's rows of the right-hand sides to its rows of the solution), and
the block Lanczos / load-vector helpers take ``gsum`` (sum of an array over
the ranks; the identity here) and ``rows`` (this rank's slice of the global
rows), with operators that map row-distributed blocks to row-distributed
blocks. Serial calls are unchanged.

Units: M [kg], K [N/m]; frequencies in rad/s unless named ``_hz``.
"""
from __future__ import annotations

import itertools
import time

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from workflow.errors import SolverError

# A MUMPS solve costs about the same for 1 and for 32 right-hand sides; beyond
# ~64 columns it stops paying (measured), so multi-RHS solves go in chunks.
_CHUNK = 64
# Residual ‖ω² K⁻¹Mφ − φ‖_M at which a fixed-interface mode counts as converged
# (serial and distributed reductions). Tighter does not make 2 MPI ranks agree
# better with 1: measured on the quick scene, 1e-9 and 1e-11 left the FRF 1.4e-8
# and 2.9e-8 apart (6.1e-8 at 1e-6), the round-off floor of the DOF numbering
# (workflow/bench/renumbering.py); 1e-11 is not reached on a renumbered K.
MODE_TOL = 1e-6


def _same(a):
    """The serial ``gsum``: an array summed over one rank is itself."""
    return a


def _is_petsc(A) -> bool:
    return type(A).__module__.startswith("petsc4py")


class SparseFactor:
    """One factorisation of a sparse symmetric matrix, reused for many solves.

    ``solver="mumps"`` (PETSc/MUMPS LDLᵀ, works for indefinite matrices too)
    or ``"splu"`` (scipy SuperLU). ``solve`` takes (n,) or (n, k) arrays,
    real or complex, and returns the same shape.
    """

    def __init__(self, A: sp.spmatrix, solver: str = "mumps"):
        self.n = A.getSize()[0] if _is_petsc(A) else A.shape[0]
        self.solver = solver
        self.parallel = _is_petsc(A) and A.getComm().getSize() > 1
        if self.n == 0:
            return
        if solver == "splu":
            try:
                self._lu = spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A")
            except RuntimeError as exc:
                raise SolverError(f"sparse factorisation failed ({exc}): the matrix is singular — "
                                  "is a body held by no boundary/clamped DOF?") from exc
        elif solver == "mumps":
            self._init_mumps(A)
        else:
            raise ValueError(f"unknown sparse solver {solver!r} (mumps or splu)")

    def _init_mumps(self, A):
        from petsc4py import PETSc

        from reduction.eigen import to_petsc

        self._PETSc = PETSc
        self._own = not _is_petsc(A)
        self._A = to_petsc(A) if self._own else A
        self._comm = self._A.getComm()
        ksp = PETSc.KSP().create(self._comm)
        ksp.setOperators(self._A)
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType("cholesky")  # LDLᵀ (MUMPS SYM=2: symmetric, not assumed definite)
        pc.setFactorSolverType("mumps")
        if self.parallel:
            ksp.setFromOptions()  # PETSC_OPTIONS: -mat_mumps_icntl_* (memory, ordering) on clusters
        try:
            ksp.setUp()
            F = pc.getFactorMatrix()
            info = F.getMumpsInfog(1)
        except PETSc.Error as exc:
            raise SolverError("MUMPS factorisation failed: the matrix is singular — is a body held by "
                              "no boundary/clamped DOF?") from exc
        if info < 0:
            raise SolverError(f"MUMPS factorisation failed (INFOG(1) = {info})")
        self._ksp, self._F = ksp, F

    def solve(self, B: np.ndarray) -> np.ndarray:
        """``A⁻¹ B`` for a dense (n,) or (n, k) array (complex: real and imaginary parts)."""
        B = np.asarray(B)
        if np.iscomplexobj(B):
            return self.solve(B.real) + 1j * self.solve(B.imag)
        vec = B.ndim == 1
        B2 = B[:, None] if vec else B
        if self.n == 0:
            return np.zeros_like(B, dtype=float)
        X = np.empty(B2.shape)
        for s in range(0, B2.shape[1], _CHUNK):
            X[:, s:s + _CHUNK] = self._solve_block(np.asarray(B2[:, s:s + _CHUNK], dtype=float))
        return X[:, 0] if vec else X

    def solve_sparse(self, B: sp.spmatrix) -> np.ndarray:
        """``A⁻¹ B`` for a sparse (n, k) right-hand side, densified one chunk at a time."""
        X = np.empty(B.shape)
        for s, Xc in self.solve_chunks(B):
            X[:, s:s + Xc.shape[1]] = Xc
        return X

    def solve_chunks(self, B: sp.spmatrix):
        """``A⁻¹ B`` for a sparse (n, k) right-hand side as (first column, (n, ≤ 64) block) pairs,
        so that a caller writes each block where it belongs without a whole (n, k) copy."""
        B = sp.csc_matrix(B)
        for s in range(0, B.shape[1], _CHUNK):
            yield s, self._solve_block(B[:, s:s + _CHUNK].toarray())

    def _solve_block(self, B: np.ndarray) -> np.ndarray:
        if self.solver == "splu":
            return self._lu.solve(B)
        PETSc = self._PETSc
        n, k = B.shape
        size = ((n, self.n), (PETSc.DECIDE, k)) if self.parallel else (n, k)  # parallel: this rank's rows
        comm = self._comm if self.parallel else PETSc.COMM_SELF
        Bd = PETSc.Mat().createDense(size=size, array=np.asfortranarray(B), comm=comm)
        Xd = PETSc.Mat().createDense(size=size, comm=comm)
        Xd.setUp()
        self._F.matSolve(Bd, Xd)
        X = Xd.getDenseArray().copy()
        Bd.destroy()
        Xd.destroy()
        return X

    def destroy(self):
        if self.solver == "mumps" and self.n:
            self._ksp.destroy()
            if self._own:
                self._A.destroy()


def _m_orthonormalize(W, M, Q=None, MQ=None, drop=1e-10, MW=None, gsum=_same):
    """Columns of W made M-orthonormal and M-orthogonal to Q (CGS, twice).

    ``MQ = M Q`` is given; ``M W`` is formed once and then updated with the
    same dense operations as W (sparse products are the expensive part).
    ``MW`` may be passed when known. Returns ``(W, MW)``; directions already in span(Q) (M-norm² below
    ``drop`` × the largest one before projection) are dropped, so the result
    may have fewer columns. ``gsum``: see the module docstring (distributed rows).
    """
    MW = M @ W if MW is None else MW
    scale = gsum(np.einsum("ij,ij->j", W, MW)).max(initial=0.0)
    for sweep in range(2):  # the second sweep repairs what round-off left of the first
        for _ in range(2 - sweep):  # CGS2, then once more after the rescaling
            if Q is not None and Q.shape[1]:
                C = gsum(MQ.T @ W)
                W = W - Q @ C
                MW = MW - MQ @ C
        G = gsum(W.T @ MW)
        g, U = np.linalg.eigh(0.5 * (G + G.T))
        keep = g > (drop * max(scale, np.finfo(float).tiny) if sweep == 0 else 0.0)
        T = U[:, keep] / np.sqrt(g[keep])
        W, MW = W @ T, MW @ T
    return W, MW


class _Columns:
    """A growing (n, k) array without a copy per append (capacity doubles)."""

    def __init__(self, n, capacity):
        self.a = np.empty((n, max(capacity, 1)))
        self.k = 0

    def append(self, X):
        if self.k + X.shape[1] > self.a.shape[1]:
            grown = np.empty((self.a.shape[0], 2 * (self.k + X.shape[1])))
            grown[:, :self.k] = self.a[:, :self.k]
            self.a = grown
        self.a[:, self.k:self.k + X.shape[1]] = X
        self.k += X.shape[1]

    @property
    def view(self):
        return self.a[:, :self.k]


def fixed_interface_modes(K, M, factor: SparseFactor, n_modes: int | None = None, cutoff: float | None = None,
                          block: int = 16, tol: float = MODE_TOL, seed: int = 0, stats: dict | None = None,
                          gsum=_same, rows: slice | None = None):
    """Lowest eigenpairs of ``K φ = ω² M φ`` by block shift-invert Lanczos (σ = 0).

    ``factor`` factorises K (K regular). Either ``n_modes`` (count) or
    ``cutoff`` (ω [rad/s]: every mode below it) decides how many. The
    Krylov basis of ``K⁻¹M`` is kept M-orthonormal (full reorthogonalisation);
    after each block a Rayleigh–Ritz step gives ω² and M-normalised vectors.
    Converged when ‖ω² K⁻¹Mφ − φ‖_M ≤ tol for every wanted pair (K⁻¹M of
    the basis is kept, so checking costs no solve).
    Returns ``(omega2 [rad²/s²], Phi (n, k))``. Distributed (``gsum``,
    ``rows``): ``K``, ``M`` map this rank's rows to its rows, Phi is this
    rank's rows, and the start blocks are the serial ones' rows (same result).
    """
    n = K.shape[0]
    rows = slice(0, n) if rows is None else rows
    n_local = rows.stop - rows.start
    if n_modes is None and cutoff is None:
        raise ValueError("give n_modes or cutoff")
    if n == 0 or n_modes == 0:
        return np.zeros(0), np.zeros((n, 0))
    if n_modes is not None and n_modes > n:
        raise SolverError(f"{n_modes} fixed-interface modes asked, but only {n} interior DOFs exist "
                          f"(set reduction.modes ≤ {n})")
    rng = np.random.default_rng(seed)
    b = min(block, n)
    cap = min(n, 3 * (n_modes or 16) + 4 * b)
    # SQ = S Q with S = K⁻¹M, and M S Q: residuals of Ritz pairs without extra solves or sparse products
    Q, MQ, KQ, SQ, MSQ = (_Columns(n_local, cap) for _ in range(5))
    first = 0  # Ritz pairs below this index have converged already
    W, MW = _m_orthonormalize(factor.solve(M @ rng.standard_normal((n, b))[rows]), M, gsum=gsum)
    KW = K @ W
    A = gsum(W.T @ KW)  # Rayleigh quotient matrix, grown block by block (Q is M-orthonormal)
    # A symmetric positive definite pencil converges in a few blocks beyond the
    # wanted count (measured: Krylov dimension ≈ 2–3× the modes); a
    # non-symmetric or indefinite K never does, and growing the basis up to n
    # (a full re-orthogonalised Krylov space of a big model) looks like a hang.
    max_dim = 8 * (n_modes or 16) + 16 * b  # with a cut-off: grown below with the count under it
    while True:
        if Q.k >= max_dim and Q.k < n:
            raise SolverError(f"block Lanczos found no converged fixed-interface modes within a Krylov space of "
                              f"{Q.k} vectors ({n_modes or 'cut-off'} modes asked): is K symmetric and positive "
                              "definite on the interior DOFs?")
        Q.append(W), MQ.append(MW), KQ.append(KW)
        S_last = factor.solve(MW)  # the next Krylov block, before orthogonalisation
        MS_last = M @ S_last
        SQ.append(S_last), MSQ.append(MS_last)
        theta, Y = np.linalg.eigh(0.5 * (A + A.T))
        if cutoff is not None and n_modes is None:
            max_dim = max(max_dim, 4 * int(np.sum(theta < cutoff ** 2)) + 16 * b)
        complete = Q.k >= n
        want = _wanted(theta, n_modes, cutoff, complete)
        if want is not None:
            k = min(want + (n_modes is None), theta.size)  # with a cut-off: also the first mode above it
            # Residual of the shift-invert operator, ‖ω² S φ − φ‖_M: scale-free,
            # unlike ‖Kφ − ω²Mφ‖, which the stiffest elements dominate.
            j = np.arange(min(first, k), k)
            D = (SQ.view @ Y[:, j]) * theta[j] - Q.view @ Y[:, j]
            MD = (MSQ.view @ Y[:, j]) * theta[j] - MQ.view @ Y[:, j]
            rel = np.sqrt(np.abs(gsum(np.einsum("ij,ij->j", D, MD))))
            bad = np.flatnonzero(rel > tol)
            first = int(j[bad[0]]) if bad.size else k
            if complete or not bad.size:
                if stats is not None:
                    stats.update(krylov_dim=int(Q.k), max_residual=float(rel.max(initial=0.0)))
                return theta[:want], Q.view @ Y[:, :want]
        W, MW = _m_orthonormalize(S_last, M, Q.view, MQ.view, MW=MS_last, gsum=gsum)
        if W.shape[1] == 0:  # invariant subspace: continue from a fresh random block
            W, MW = _m_orthonormalize(factor.solve(M @ rng.standard_normal((n, b))[rows]), M, Q.view, MQ.view,
                                      gsum=gsum)
            if W.shape[1] == 0:
                raise SolverError("block Lanczos stalled: no new direction")
        KW = K @ W
        QKW = gsum(Q.view.T @ KW)
        A = np.block([[A, QKW], [QKW.T, gsum(W.T @ KW)]])


def _wanted(theta, n_modes, cutoff, complete):
    """How many Ritz values are wanted, or None while the basis is too small to tell."""
    if n_modes is not None:
        return n_modes if theta.size >= n_modes + 4 or complete else None
    below = int(np.sum(theta < cutoff ** 2))
    return below if complete or below < theta.size - 4 else None  # a margin of Ritz values above the cut-off


def craig_bampton(M: sp.spmatrix, K: sp.spmatrix, boundary: np.ndarray, n_modes: int | None = None,
                  cutoff_hz: float | None = None, *, loads: np.ndarray | None = None, solver: str = "mumps",
                  eigensolver: str = "lanczos", tol: float = MODE_TOL, timings: dict | None = None,
                  combine: sp.spmatrix | None = None):
    """Craig–Bampton basis of (M, K) on unclamped DOFs.

    ``boundary``: unique DOF indices (into M, K) kept physically — every
    contact DOF of both bodies, loaded and observed DOFs. ``n_modes`` or
    ``cutoff_hz`` [Hz] sets the number of fixed-interface modes (``n_modes``
    wins when both are given and non-zero). ``loads``: optional (n,) or (n, L)
    load vectors whose interior static response is appended (see module doc).

    ``combine`` (nb, nb') sparse: the boundary DOFs as a map of nb' kept ones (tied DOFs
    following their masters, :func:`reduction.tie.tie_map`): the constraint modes are then
    those of the kept DOFs, ``[combine; −K_ii⁻¹ K_ib combine]`` — nb' solves instead of nb,
    and V that much narrower (a linear contact surface ties three midside DOFs to every
    vertex DOF: 12 279 boundary DOFs for 3 267 kept at 544 pairs).

    Returns ``(V, omega_fixed)``: V (n, nb' + nm + nl) with columns
    [boundary DOFs in the given order (or the kept ones) | fixed-interface modes | load vectors],
    and the nm fixed-interface frequencies [rad/s]. ``timings`` (a dict) gets
    the wall times [s] of ``factor``, ``constraint_modes``, ``eigen``,
    ``load_vectors`` and a few solver statistics.
    """
    M, K = sp.csr_matrix(M), sp.csr_matrix(K)
    n = K.shape[0]
    boundary = np.asarray(boundary, dtype=np.int64)
    if np.unique(boundary).size != boundary.size:
        raise ValueError("boundary DOFs must be unique")
    if n_modes is None and not cutoff_hz:
        raise ValueError("give n_modes or cutoff_hz")
    mask = np.ones(n, dtype=bool)
    mask[boundary] = False
    interior = np.flatnonzero(mask)
    Kii, Kib = K[interior][:, interior], K[interior][:, boundary]
    Mii = M[interior][:, interior]
    t = {} if timings is None else timings

    t0 = time.perf_counter()
    factor = SparseFactor(Kii, solver)
    t["factor"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    combine = sp.identity(boundary.size, format="csr") if combine is None else sp.csr_matrix(combine)
    psi = factor.solve_chunks(Kib @ combine)
    first = next(psi, None)      # a singular K_ii shows here, before the eigensolver meets it
    if first is not None:
        _finite_modes(first[1])
    t["constraint_modes"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    use_count = n_modes is not None and (n_modes > 0 or not cutoff_hz)
    cutoff = None if use_count else 2.0 * np.pi * cutoff_hz
    if eigensolver == "lanczos":
        stats = {}
        omega2, Phi = fixed_interface_modes(Kii, Mii, factor, n_modes if use_count else None, cutoff, tol=tol,
                                            stats=stats)
        t.update({f"lanczos_{k}": v for k, v in stats.items()})
    elif eigensolver == "slepc":
        omega2, Phi = _slepc_modes(Kii, Mii, n_modes if use_count else None, cutoff)
    else:
        raise ValueError(f"unknown eigensolver {eigensolver!r} (lanczos or slepc)")
    t["eigen"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    X = np.zeros((interior.size, 0))
    if loads is not None:
        X = _load_vectors(np.asarray(loads).reshape(n, -1)[interior], Kii, Mii, factor, Phi)
    t["load_vectors"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    try:
        V = _basis(n, boundary, interior, combine, itertools.chain([first] if first is not None else [], psi), Phi, X)
    finally:
        factor.destroy()
    t["constraint_modes"] += time.perf_counter() - t0
    return V, np.sqrt(np.clip(omega2, 0.0, None))


def _basis(n: int, boundary, interior, combine, psi, Phi, X) -> np.ndarray:
    """V (n, nb' + nm + nl) = [combine on the boundary rows, Ψ on the interior ones | Φ | X]:
    ``psi`` the (first column, K_ii⁻¹ K_ib combine block) pairs of :meth:`SparseFactor.solve_chunks`,
    written negated (Ψ = −K_ii⁻¹ K_ib combine) straight into their rows block by block — V is the
    reduction's largest array (n × nb'), and a whole Ψ beside it (and −Ψ) tripled it."""
    nb, nm, nl = combine.shape[1], Phi.shape[1], X.shape[1]
    V = np.zeros((n, nb + nm + nl))
    cc = combine.tocoo()
    V[boundary[cc.row], cc.col] = cc.data
    V[interior, nb:nb + nm] = Phi
    V[interior, nb + nm:] = X
    for s, Y in psi:
        _finite_modes(Y)
        V[interior, s:s + Y.shape[1]] = -Y
    return V


def _finite_modes(block: np.ndarray):
    """Raise if a block of constraint modes is not finite."""
    if not np.all(np.isfinite(block)):
        raise SolverError("constraint modes are not finite: K_ii is singular — a body is held by no boundary DOF")


def _load_vectors(F, Kii, Mii, factor, Phi, drop=1e-8, gsum=_same):
    """Interior static responses ``K_ii⁻¹ F`` made M- and K-orthogonal to Φ and to each other.

    A small Rayleigh–Ritz on the cleaned vectors diagonalises them, so the
    whole interior block of VᵀMV is I and of VᵀKV diagonal.
    """
    norms = np.linalg.norm(F, axis=0) if gsum is _same else np.sqrt(gsum(np.einsum("ij,ij->j", F, F)))
    F = F[:, norms > 0]
    if F.shape[1] == 0:
        return np.zeros((F.shape[0], 0))
    X = factor.solve(F)
    MPhi = Mii @ Phi
    X, _ = _m_orthonormalize(X, Mii, Phi, MPhi, drop=drop, gsum=gsum)
    if X.shape[1] == 0:
        return X
    k2, Y = sla.eigh(gsum(X.T @ (Kii @ X)))
    return X @ Y


def _slepc_modes(Kii, Mii, n_modes, cutoff):
    """Fixed-interface modes with SLEPc Krylov–Schur (one solve per Krylov vector)."""
    from reduction.eigen import eigs

    if n_modes is not None:
        return eigs(Kii, Mii, n_modes) if n_modes else (np.zeros(0), np.zeros((Kii.shape[0], 0)))
    k = 16
    while True:  # grow the request until a mode above the cut-off shows up
        k = min(k, Kii.shape[0])
        w2, Phi = eigs(Kii, Mii, k)
        if w2[-1] >= cutoff ** 2 or k == Kii.shape[0]:
            keep = w2 < cutoff ** 2
            return w2[keep], Phi[:, keep]
        k *= 2
