"""Generalised symmetric eigenproblems K φ = ω² M φ with SLEPc (shift-invert).

Accepts scipy sparse matrices (serial) or assembled PETSc matrices (any
communicator); the factorisation of ``K − σM`` is MUMPS when PETSc has it.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc
from slepc4py import SLEPc

from workflow.errors import SolverError


def to_petsc(A: sp.spmatrix, comm=None) -> PETSc.Mat:
    """A sequential PETSc AIJ copy of a scipy sparse matrix."""
    A = sp.csr_matrix(A)
    A.sort_indices()
    return PETSc.Mat().createAIJ(size=A.shape, csr=(A.indptr.astype(PETSc.IntType), A.indices.astype(PETSc.IntType),
                                                     A.data), comm=comm or PETSc.COMM_SELF)


def _has_mumps() -> bool:
    try:
        return "mumps" in PETSc.Sys.getPackageInfo() if hasattr(PETSc.Sys, "getPackageInfo") else True
    except Exception:  # pragma: no cover - depends on the PETSc build
        return True


def eigs(K, M, n_modes: int, sigma: float = 0.0, tol: float = 1e-10, vectors: bool = True):
    """Lowest ``n_modes`` eigenpairs above the shift ``sigma`` [rad²/s²].

    Returns ``(omega2, Phi)``: ω² sorted ascending (rad²/s²) and the
    mass-normalised modes as an (n, n_modes) array (``None`` without
    ``vectors``). Raises :class:`SolverError` when fewer modes converge.
    """
    Kp = K if isinstance(K, PETSc.Mat) else to_petsc(K)
    Mp = M if isinstance(M, PETSc.Mat) else to_petsc(M)
    eps = SLEPc.EPS().create(Kp.getComm())
    eps.setOperators(Kp, Mp)
    eps.setProblemType(SLEPc.EPS.ProblemType.GHEP)
    eps.setDimensions(n_modes, PETSc.DECIDE)
    eps.setTolerances(tol, 200)
    eps.setWhichEigenpairs(SLEPc.EPS.Which.TARGET_MAGNITUDE)
    eps.setTarget(sigma)
    st = eps.getST()
    st.setType(SLEPc.ST.Type.SINVERT)
    st.setShift(sigma)
    ksp = st.getKSP()
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("lu")
    try:
        pc.setFactorSolverType("mumps")
    except PETSc.Error:  # pragma: no cover
        pass
    eps.setFromOptions()
    eps.solve()
    nconv = eps.getConverged()
    if nconv < n_modes:
        raise SolverError(f"eigen-solver converged {nconv} of {n_modes} modes (shift {sigma:g} rad²/s²)")
    vals = np.array([eps.getEigenvalue(i).real for i in range(nconv)])
    order = np.argsort(vals)[:n_modes]
    Phi = None
    if vectors:
        vr, _ = Kp.createVecs()
        cols = []
        for i in order:
            eps.getEigenvector(int(i), vr)
            cols.append(_gather(vr))
        Phi = np.column_stack(cols)
    eps.destroy()
    return vals[order], Phi


def _gather(v: PETSc.Vec) -> np.ndarray:
    """Whole vector on every rank (small reduced bases only)."""
    if v.getComm().getSize() == 1:
        return v.getArray().copy()
    scatter, full = PETSc.Scatter.toAll(v)
    scatter.scatter(v, full, PETSc.InsertMode.INSERT, PETSc.ScatterMode.FORWARD)
    out = full.getArray().copy()
    scatter.destroy()
    full.destroy()
    return out


def frequencies_hz(omega2: np.ndarray) -> np.ndarray:
    """ω² [rad²/s²] → f [Hz]; tiny negative round-off is clipped to 0."""
    return np.sqrt(np.clip(omega2, 0.0, None)) / (2.0 * np.pi)
