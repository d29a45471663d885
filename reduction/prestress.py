"""Static prestress of the rotating sector with the interface tied (DESIGN §3).

The static load (centrifugal ρΩ²r_⊥ plus any applied static force) is
carried with the disk clamp fixed and every blade flank DOF bonded to its
disk partner — the "tied" limit, so the blade cannot float. The resulting
displacement u₀ [m] gives σ₀ for the geometric stiffness K_σ. The
constrained matrix is formed on rank 0 (where assembly gathers the
matrices) and factored by MUMPS — on every rank of the communicator when
there are several (row blocks scattered into an MPIAIJ matrix).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc

from reduction.constraints import constraint_map
from workflow.errors import SolverError


def tie_map(n_dofs: int, fixed: np.ndarray, blade_dofs: np.ndarray, disk_dofs: np.ndarray,
            tied: bool = True, tie: np.ndarray | None = None) -> sp.csr_matrix:
    """``T`` with ``u = T v``: clamped DOFs dropped, blade contact DOFs following the disk's,
    tied midside DOFs (``tie``, bundle ``contact.tie``) following their edges.

    Thin wrapper so callers without a :class:`~reduction.bundle.Bundle` yet can
    use :func:`reduction.constraints.constraint_map`.
    """
    like = SimpleNamespace(n_dofs=int(n_dofs), loads=SimpleNamespace(fixed=np.asarray(fixed, dtype=np.int64)),
                           contact=SimpleNamespace(blade_dofs=np.asarray(blade_dofs, dtype=np.int64).reshape(-1, 3),
                                                   disk_dofs=np.asarray(disk_dofs, dtype=np.int64).reshape(-1, 3),
                                                   tie=tie))
    return constraint_map(like, tied=tied)


def solve_spd(A: sp.spmatrix | None, b: np.ndarray | None, comm=None) -> np.ndarray | None:
    """Solve the symmetric positive-definite system ``A x = b`` (MUMPS Cholesky when present).

    With ``comm`` of more than one rank the call is collective: ``A`` and
    ``b`` are given on rank 0 (None elsewhere), scattered by row blocks into
    an MPIAIJ matrix and factored by parallel MUMPS; ``x`` is returned on
    rank 0 (None elsewhere).
    """
    size = 1 if comm is None else comm.Get_size()
    if size == 1:
        from reduction.eigen import to_petsc

        Ap = to_petsc(sp.csr_matrix(A))
        bp = PETSc.Vec().createWithArray(np.ascontiguousarray(b, dtype=float), comm=PETSc.COMM_SELF)
        return _solve(Ap, bp, PETSc.COMM_SELF)
    from reduction.parallel import ROOT, _scatter_rows, split

    pcomm = PETSc.Comm(comm)
    Ap = _scatter_rows(A, comm, pcomm)
    if comm.Get_rank() == ROOT:
        cuts = split(len(b), size)
        parts = [np.ascontiguousarray(b[cuts[r]:cuts[r + 1]], dtype=float) for r in range(size)]
    else:
        parts = None
    local = comm.scatter(parts, root=ROOT)
    bp = PETSc.Vec().createWithArray(local, size=(len(local), PETSc.DECIDE), comm=pcomm)
    x = _solve(Ap, bp, pcomm)
    pieces = comm.gather(x, root=ROOT)
    return np.concatenate(pieces) if comm.Get_rank() == ROOT else None


def _solve(Ap, bp, pcomm) -> np.ndarray:
    """This rank's part of the solution of ``Ap x = bp`` by a Cholesky factor (``preonly``)."""
    Ap.setOption(PETSc.Mat.Option.SPD, True)
    ksp = PETSc.KSP().create(pcomm)
    ksp.setOperators(Ap)
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("cholesky")
    try:
        pc.setFactorSolverType("mumps")
    except PETSc.Error:  # pragma: no cover - PETSc without MUMPS
        pc.setType("lu")
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


def static_displacement(K: sp.spmatrix | None, f: np.ndarray | None, T: sp.spmatrix | None,
                        comm=None) -> np.ndarray | None:
    """u₀ [m] solving ``(Tᵀ K T) v = Tᵀ f``, ``u₀ = T v``; zero load → zero displacement.

    With ``comm`` of more than one rank: collective, inputs and result on
    rank 0 (None elsewhere), the solve distributed (:func:`solve_spd`).
    """
    parallel = comm is not None and comm.Get_size() > 1
    root = not parallel or comm.Get_rank() == 0
    zero = bool(root and not np.any(f))
    if parallel:
        zero = comm.bcast(zero, root=0)
    if zero:
        return np.zeros(K.shape[0]) if root else None
    Kr = (T.T @ K @ T).tocsr() if root else None
    v = solve_spd(Kr, T.T @ f if root else None, comm if parallel else None)
    if not root:
        return None
    if not np.all(np.isfinite(v)):
        raise SolverError("static prestress solve returned non-finite displacements (is the disk clamped?)")
    return T @ v
