"""Static prestress of the rotating sector with the interface tied (DESIGN §3).

The static load (centrifugal ρΩ²r_⊥ plus any applied static force) is
carried with the disk clamp fixed and every blade flank DOF bonded to its
disk partner — the "tied" limit, so the blade cannot float. The resulting
displacement u₀ [m] gives σ₀ for the geometric stiffness K_σ. Serial
scipy/PETSc on the gathered matrices (rank 0): the solve is one sparse
Cholesky, cheap next to the eigen-solves that follow.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc

from reduction.constraints import constraint_map
from workflow.errors import SolverError


def tie_map(n_dofs: int, fixed: np.ndarray, blade_dofs: np.ndarray, disk_dofs: np.ndarray,
            tied: bool = True) -> sp.csr_matrix:
    """``T`` with ``u = T v``: clamped DOFs dropped, blade contact DOFs following the disk's.

    Thin wrapper so callers without a :class:`~reduction.bundle.Bundle` yet can
    use :func:`reduction.constraints.constraint_map`.
    """
    like = SimpleNamespace(n_dofs=int(n_dofs), loads=SimpleNamespace(fixed=np.asarray(fixed, dtype=np.int64)),
                           contact=SimpleNamespace(blade_dofs=np.asarray(blade_dofs, dtype=np.int64).reshape(-1, 3),
                                                   disk_dofs=np.asarray(disk_dofs, dtype=np.int64).reshape(-1, 3)))
    return constraint_map(like, tied=tied)


def solve_spd(A: sp.spmatrix, b: np.ndarray) -> np.ndarray:
    """Solve the symmetric positive-definite system ``A x = b`` (MUMPS Cholesky when present)."""
    from reduction.eigen import to_petsc

    Ap = to_petsc(sp.csr_matrix(A))
    Ap.setOption(PETSc.Mat.Option.SPD, True)
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    ksp.setOperators(Ap)
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("cholesky")
    try:
        pc.setFactorSolverType("mumps")
    except PETSc.Error:  # pragma: no cover - PETSc without MUMPS
        pc.setType("lu")
    bp = PETSc.Vec().createWithArray(np.ascontiguousarray(b, dtype=float), comm=PETSc.COMM_SELF)
    xp = bp.duplicate()
    try:
        ksp.solve(bp, xp)
    except PETSc.Error as exc:
        raise SolverError(f"static prestress solve failed (singular stiffness? is the disk clamped?): {exc}") from exc
    if ksp.getConvergedReason() < 0:
        raise SolverError(f"static prestress solve failed: KSP reason {ksp.getConvergedReason()} "
                          "(singular stiffness: is the disk clamped and the interface tied?)")
    x = xp.getArray().copy()
    for o in (ksp, Ap, bp, xp):
        o.destroy()
    return x


def static_displacement(K: sp.spmatrix, f: np.ndarray, T: sp.spmatrix) -> np.ndarray:
    """u₀ [m] solving ``(Tᵀ K T) v = Tᵀ f``, ``u₀ = T v``; zero load → zero displacement."""
    if not np.any(f):
        return np.zeros(K.shape[0])
    Kr = (T.T @ K @ T).tocsr()
    v = solve_spd(Kr, T.T @ f)
    if not np.all(np.isfinite(v)):
        raise SolverError("static prestress solve returned non-finite displacements (is the disk clamped?)")
    return T @ v
