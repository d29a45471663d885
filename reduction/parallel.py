"""Craig–Bampton reduction of a bundle on several MPI ranks (``mpirun -n N``).

The same reduced model as :func:`reduction.reduce.reduce_bundle` — same
boundary ordering, same start blocks, same formulas — with the work and the
memory of the full model spread over the ranks, using what PETSc/MUMPS/SLEPc
provide rather than a scheme of our own:

1. **Rows.** The free (unclamped) DOFs are split into contiguous ranges, one
   per rank. Each rank reads only its rows of M, K, C from the bundle
   (:func:`reduction.bundle.matrix_rows`, a memory map of the uncompressed
   npz) plus the small arrays (contact, loads). Its rows become its part of
   PETSc MPIAIJ matrices: ``M_ff``, ``K_ff``, ``C_ff`` (free DOFs) and
   ``K_ii``, ``M_ii`` (interior DOFs; a rank owns the interior DOFs in its
   range, so the interior numbering is distributed the same way).
2. **Factor.** One parallel MUMPS LDLᵀ of ``K_ii``
   (:class:`~reduction.craig_bampton.SparseFactor` on the MPIAIJ matrix).
3. **Constraint modes** ``Ψ = −K_ii⁻¹ K_ib T_b`` of the kept boundary DOFs (tied
   midside DOFs following, :func:`reduction.tie.boundary_map`): multi-right-hand-side
   MUMPS solves on row-distributed dense blocks (MPIDENSE), 64 columns at a time.
4. **Fixed-interface modes**: the serial block shift-invert Lanczos
   (:func:`~reduction.craig_bampton.fixed_interface_modes`) run on
   row-distributed blocks: products with ``M_ii``/``K_ii`` are PETSc
   MPIAIJ × MPIDENSE products, solves use the distributed factor, and the
   small Gram matrices are summed over the ranks (reduced on rank 0 and
   broadcast, so every rank takes the same decisions bit for bit). Or
   ``eigensolver="slepc"``: SLEPc Krylov–Schur with shift-invert on the
   distributed ``K_ii``, ``M_ii`` (``-eps_*`` options apply).
5. **Load vectors** and the **projection** ``VᵀMV``, ``VᵀKV`` (boundary block
   as the exact Schur complement), ``VᵀCV``, ``B``, ``O``, loads: local
   products summed on rank 0, which builds the :class:`ReducedModel`.

Rank 0 returns the model; the other ranks return None. Equal to the serial
reduction to round-off (different MUMPS pivot orders), eigenvector signs in
degenerate subspaces aside.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from reduction.bundle import matrix_rows, pair_labels, read_bundle
from reduction.craig_bampton import MODE_TOL, SparseFactor, _load_vectors, fixed_interface_modes
from reduction.reduce import MAX_LOAD_DOFS, boundary_dofs, contact_map
from workflow.engine.model import ReducedModel
from reduction.tie import boundary_map, tie_pairs
from workflow.errors import BundleError, SolverError

ROOT = 0


# ------------------------------------------------------------- small pieces

def split(n: int, size: int) -> np.ndarray:
    """Cut points of ``n`` items into ``size`` contiguous, nearly equal ranges."""
    return np.linspace(0, n, size + 1).round().astype(np.int64)


def aij(local: sp.spmatrix, n_global: tuple[int, int], comm, n_local_cols: int | None = None):
    """A PETSc MPIAIJ matrix from this rank's rows (scipy CSR, global column numbers)."""
    from petsc4py import PETSc

    A = sp.csr_matrix(local)
    A.sort_indices()
    nloc = A.shape[0]
    cols = nloc if n_local_cols is None else n_local_cols
    return PETSc.Mat().createAIJ(size=((nloc, n_global[0]), (cols, n_global[1])),
                                 csr=(A.indptr.astype(PETSc.IntType), A.indices.astype(PETSc.IntType), A.data),
                                 comm=comm)


class RowOperator:
    """A distributed PETSc AIJ matrix acting on row-distributed dense blocks.

    ``A @ W``: W is this rank's rows (n_local, k) of a block; the result is
    this rank's rows of ``A W`` (an MPIAIJ × MPIDENSE product in PETSc).
    ``shape`` is the global shape (what the block Lanczos reads).
    """

    def __init__(self, A):
        self.A = A
        self.shape = tuple(A.getSize())
        self.n_local = A.getLocalSize()[0]
        self.n_local_cols = A.getLocalSize()[1]

    def __matmul__(self, W):
        from petsc4py import PETSc

        W = np.asarray(W, dtype=float)
        vec = W.ndim == 1
        W2 = W[:, None] if vec else W
        k = W2.shape[1]
        if k == 0:
            return np.zeros((self.n_local, 0))
        comm = self.A.getComm()
        data = np.asfortranarray(W2)
        Wd = PETSc.Mat().createDense(size=((self.n_local_cols, self.shape[1]), (PETSc.DECIDE, k)), array=data,
                                     comm=comm)
        P = self.A.matMult(Wd)
        out = P.getDenseArray().copy()
        Wd.destroy()
        P.destroy()
        return out[:, 0] if vec else out

    def destroy(self):
        self.A.destroy()


def summer(comm):
    """``gsum`` for distributed rows: the sum over ranks, identical bits on every rank.

    Reduced on rank 0 and broadcast (an all-reduce may associate the sums
    differently on different ranks, and the block Lanczos takes decisions —
    drops, convergence — on these numbers).
    """
    from mpi4py import MPI

    def gsum(a):
        a = np.ascontiguousarray(a, dtype=float)
        out = np.empty_like(a)
        comm.Reduce(a, out, op=MPI.SUM, root=ROOT)
        comm.Bcast(out, root=ROOT)
        return out

    return gsum


def reduce_root(comm, a):
    """Sum of ``a`` over ranks on rank 0 (None elsewhere)."""
    from mpi4py import MPI

    a = np.ascontiguousarray(a, dtype=float)
    out = np.empty_like(a) if comm.Get_rank() == ROOT else None
    comm.Reduce(a, out, op=MPI.SUM, root=ROOT)
    return out


# ----------------------------------------------------------------- reduction

def reduce_bundle_mpi(folder: str | Path, n_modes: int | None = 30, cutoff_hz: float | None = None, *,
                      comm=None, eigensolver: str = "lanczos", max_load_dofs: int = MAX_LOAD_DOFS,
                      tol: float = MODE_TOL) -> ReducedModel | None:
    """:func:`reduction.reduce.reduce_bundle` of the bundle folder ``folder`` on every rank of ``comm``.

    Collective. Returns the :class:`ReducedModel` on rank 0, None elsewhere.
    ``info["mpi_ranks"]`` records the number of ranks. The steps of the
    module docstring: :func:`_read_rows` (1), :func:`_basis` (2–4),
    :func:`_project` (5), :func:`_model` (rank 0).
    """
    from mpi4py import MPI
    from petsc4py import PETSc

    comm = comm or MPI.COMM_WORLD
    pcomm = PETSc.Comm(comm)
    if not n_modes:
        n_modes = None
        if not cutoff_hz:
            raise BundleError("reduction needs modes > 0 or cutoff_hz > 0")
    t_all = time.perf_counter()
    timings: dict = {}
    t0 = time.perf_counter()
    r = _read_rows(Path(folder), comm, pcomm, max_load_dofs)
    timings["read"] = time.perf_counter() - t0
    omega2, Psi, Phi, X = _basis(r, comm, n_modes, cutoff_hz, eigensolver, tol, timings)
    t0 = time.perf_counter()
    red = _project(r, comm, Psi, Phi, X)
    timings["projection"] = time.perf_counter() - t0
    for op in (r.Mf, r.Kf, r.Cf, r.Kop, r.Mop):
        if op is not None:
            op.destroy()
    if comm.Get_rank() != ROOT:
        return None
    seconds = {k: float(v) for k, v in timings.items() if not k.startswith("lanczos_")}
    seconds["total"] = time.perf_counter() - t_all
    info = {
        "method": "craig-bampton", "modes": int(Phi.shape[1]), "load_vectors": int(X.shape[1]),
        "boundary_dofs": int(r.kept.size), "size": int(red["m"]), "n_dofs": int(r.n), "free_dofs": int(r.nf),
        "pairs": int(r.sk.contact.n_pairs),
        "modes_requested": None if n_modes is None else int(n_modes), "cutoff_hz": float(cutoff_hz or 0.0),
        "fixed_interface_hz": (np.sqrt(np.clip(omega2, 0.0, None)) / (2 * np.pi)).tolist(), "solver": "mumps",
        "eigensolver": eigensolver, "eigen_stats": {k[8:]: v for k, v in timings.items() if k.startswith("lanczos_")},
        "seconds": seconds, "bundle": str(Path(folder)), "mpi_ranks": int(comm.Get_size()),
    }
    if r.sk.contact.tie is not None:
        info.update(tied_dofs=int(r.nb - r.kept.size), tie_pairs=tie_pairs(r.sk.contact).tolist())
    return _model(r.sk, red, info)


def _read_rows(folder: Path, comm, pcomm, max_load_dofs: int):
    """Step 1: this rank's rows of the free DOFs, the interior/boundary split
    (same as :func:`reduction.reduce.reduce_with_basis`) and the distributed
    operators. Returns a namespace: ``sk`` (bundle without matrices), sizes
    ``n``, ``nf``, ``nb``, ``ni``; index maps ``free``, ``fpos``, ``bnd``,
    ``is_b``, ``interior``; this rank's ranges ``f0:f1`` (free) and ``i0:i1``
    (interior), ``own`` (global DOFs), ``own_int``/``own_bnd`` (local rows);
    ``mats`` (local free-numbered rows of M, K, C), ``Kii``, ``Mii`` (MPIAIJ),
    ``T_b``, ``kept`` (:func:`reduction.tie.boundary_map`), ``KibT`` (local rows
    of K_ib T_b), ``Mf``, ``Kf``, ``Cf`` (:class:`RowOperator`, Cf None without
    damping), ``loads`` (nf, 2)."""
    from types import SimpleNamespace

    rank, size = comm.Get_rank(), comm.Get_size()
    sk = read_bundle(folder, matrices=False)
    n = sk.n_dofs
    free = sk.free_dofs
    nf = free.size
    fpos = -np.ones(n, dtype=np.int64)
    fpos[free] = np.arange(nf)
    bnd = boundary_dofs(sk, max_load_dofs)
    if bnd.size == 0:
        raise BundleError("bundle has no unclamped contact, loaded or observed DOF to keep")
    is_b = np.zeros(nf, dtype=bool)
    is_b[fpos[bnd]] = True
    interior = np.flatnonzero(~is_b)  # free-local indices
    ni = interior.size
    cuts = split(nf, size)
    f0, f1 = int(cuts[rank]), int(cuts[rank + 1])
    own = free[f0:f1]
    i0, i1 = (int(v) for v in np.searchsorted(interior, [f0, f1]))
    mats = {}
    for name in ("M", "K", "C"):
        if own.size:
            rows = matrix_rows(folder, name, int(own[0]), int(own[-1]) + 1)[own - own[0]]
        else:
            rows = sp.csr_matrix((0, n))
        mats[name] = rows[:, free].tocsr()  # free numbering
    own_int = np.flatnonzero(~is_b[f0:f1])  # local rows that are interior
    own_bnd = np.flatnonzero(is_b[f0:f1])
    Kf_i = mats["K"][own_int]
    Kii = aij(Kf_i[:, interior], (ni, ni), pcomm)
    Mii = aij(mats["M"][own_int][:, interior], (ni, ni), pcomm)
    T_b, kept = boundary_map(bnd, sk.contact.tie)
    KibT = (Kf_i[:, fpos[bnd]] @ T_b).tocsc()      # the kept DOFs' columns, tied ones following
    Mf, Kf = (RowOperator(aij(mats[k], (nf, nf), pcomm)) for k in ("M", "K"))
    c_nnz = comm.allreduce(mats["C"].nnz)
    Cf = RowOperator(aij(mats["C"], (nf, nf), pcomm)) if c_nnz else None
    loads = np.column_stack([sk.loads.static[free], sk.loads.harmonic[free]])
    return SimpleNamespace(sk=sk, n=n, free=free, nf=nf, fpos=fpos, bnd=bnd, nb=bnd.size, T_b=T_b, kept=kept,
                           is_b=is_b,
                           interior=interior, ni=ni, f0=f0, f1=f1, own=own, i0=i0, i1=i1, mats=mats,
                           own_int=own_int, own_bnd=own_bnd, Kii=Kii, Mii=Mii, KibT=KibT, Mf=Mf, Kf=Kf, Cf=Cf,
                           loads=loads, Kop=None, Mop=None)


def _basis(r, comm, n_modes, cutoff_hz, eigensolver: str, tol: float, timings: dict):
    """Steps 2–4 on the rows ``r`` of :func:`_read_rows`: MUMPS factor of
    K_ii, constraint modes Ψ, fixed-interface modes (ω² [rad²/s²], Φ) and
    load vectors X, this rank's interior rows of each; sets ``r.Kop``,
    ``r.Mop`` and fills ``timings`` [s]."""
    t0 = time.perf_counter()
    factor = SparseFactor(r.Kii, "mumps")
    timings["factor"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    Psi = -factor.solve_sparse(r.KibT)
    bad = comm.allreduce(int(not np.all(np.isfinite(Psi))))
    if bad:
        raise SolverError("constraint modes are not finite: K_ii is singular — a body is held by no boundary DOF")
    timings["constraint_modes"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    use_count = n_modes is not None and (n_modes > 0 or not cutoff_hz)
    cutoff = None if use_count else 2.0 * np.pi * cutoff_hz
    r.Kop, r.Mop = RowOperator(r.Kii), RowOperator(r.Mii)
    gsum = summer(comm)
    if eigensolver == "lanczos":
        stats: dict = {}
        omega2, Phi = fixed_interface_modes(r.Kop, r.Mop, factor, n_modes if use_count else None, cutoff, tol=tol,
                                            stats=stats, gsum=gsum, rows=slice(r.i0, r.i1))
        timings.update({f"lanczos_{k}": v for k, v in stats.items()})
    elif eigensolver == "slepc":
        omega2, Phi = _slepc_modes(r.Kii, r.Mii, n_modes if use_count else None, cutoff, slice(r.i0, r.i1))
    else:
        raise ValueError(f"unknown eigensolver {eigensolver!r} (lanczos or slepc)")
    timings["eigen"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    X = _load_vectors(r.loads[r.f0:r.f1][r.own_int], r.Kop, r.Mop, factor, Phi, gsum=gsum)
    timings["load_vectors"] = time.perf_counter() - t0
    factor.destroy()
    return omega2, Psi, Phi, X


def _project(r, comm, Psi, Phi, X) -> dict:
    """Step 5: this rank's rows of V = [T_b; Ψ | Φ | X] (T_b the boundary map,
    :func:`reduction.tie.boundary_map`), the projections summed on rank 0 (None
    elsewhere): ``Mr``, ``Kr_bb`` (boundary block as the exact Schur complement
    T_bᵀ(K_bb T_b + K_bi Ψ)), ``Kr_xn`` (columns nb: of VᵀKV), ``Cr``, ``B``,
    ``O``, ``fr``; and the sizes ``m``, ``nb`` (kept boundary DOFs)."""
    f0, f1, fpos, bnd, T_b = r.f0, r.f1, r.fpos, r.bnd, r.T_b
    nb, nm, nl = T_b.shape[1], Phi.shape[1], X.shape[1]
    m = nb + nm + nl
    V = np.zeros((f1 - f0, m))
    pos = np.searchsorted(fpos[bnd], f0 + r.own_bnd)     # this rank's boundary rows among the boundary DOFs
    V[r.own_bnd, :nb] = T_b[pos].toarray()
    V[r.own_int, :nb] = Psi
    V[r.own_int, nb:nb + nm] = Phi
    V[r.own_int, nb + nm:] = X
    MV = r.Mf @ V
    out = {"m": m, "nb": nb, "Mr": reduce_root(comm, V.T @ MV)}
    del MV
    Kb_rows = r.mats["K"][r.own_bnd][:, fpos[bnd]]
    out["Kr_bb"] = reduce_root(comm, np.asarray(T_b[pos].T @ (Kb_rows @ T_b).toarray()) + r.KibT.T @ Psi)
    KV = r.Kf @ V[:, nb:]
    out["Kr_xn"] = reduce_root(comm, V.T @ KV)
    del KV
    out["Cr"] = reduce_root(comm, V.T @ (r.Cf @ V)) if r.Cf is not None else None
    Cm = contact_map(r.sk).tocsc()[:, r.own]
    out["B"] = reduce_root(comm, Cm @ V)
    obs = np.asarray(r.sk.loads.observe, dtype=np.int64)
    O = np.zeros((obs.size, m))
    fo = fpos[obs]
    mine = (fo >= f0) & (fo < f1)
    O[mine] = V[fo[mine] - f0]
    out["O"] = reduce_root(comm, O)
    f_loc = np.column_stack([r.sk.loads.static[r.own], r.sk.loads.harmonic[r.own]])
    out["fr"] = reduce_root(comm, V.T @ f_loc)
    return out


def _model(sk, red: dict, info: dict) -> ReducedModel:
    """Rank 0: the symmetric reduced matrices from :func:`_project`'s sums and the :class:`ReducedModel`
    (in the kept boundary DOFs: tied midside DOFs follow, :mod:`reduction.tie`)."""
    m, nb = red["m"], red["nb"]
    Kr = np.empty((m, m))
    Kr[:nb, :nb] = red["Kr_bb"]
    Kr[:, nb:] = red["Kr_xn"]
    Kr[nb:, :nb] = Kr[:nb, nb:].T
    Kr = 0.5 * (Kr + Kr.T)
    Mr = 0.5 * (red["Mr"] + red["Mr"].T)
    Cr = 0.5 * (red["Cr"] + red["Cr"].T) if red["Cr"] is not None else np.zeros_like(Mr)
    c = sk.contact
    flank, position = pair_labels(sk)
    fr = red["fr"]
    model = ReducedModel(M=Mr, K=Kr, C=Cr, B=red["B"], f_static=fr[:, 0], f_harmonic=fr[:, 1], O=red["O"],
                         area=np.asarray(c.area, float), gap=np.asarray(c.gap, float), flank=np.asarray(flank),
                         position=np.asarray(position, float), info=info,
                         mu=None if c.mu is None else np.asarray(c.mu, float))  # per-pair μ (#18)
    model.validate()
    return model


def _slepc_modes(Kii, Mii, n_modes, cutoff, rows):
    """Fixed-interface modes with parallel SLEPc (Krylov–Schur, shift-invert, MUMPS); this rank's rows."""
    from reduction.eigen import eigs

    n = Kii.getSize()[0]
    if n_modes is not None:
        if not n_modes:
            return np.zeros(0), np.zeros((rows.stop - rows.start, 0))
        w2, Phi = eigs(Kii, Mii, n_modes)
        return w2, Phi[rows]
    k = 16
    while True:
        k = min(k, n)
        w2, Phi = eigs(Kii, Mii, k)
        if w2[-1] >= cutoff ** 2 or k == n:
            keep = w2 < cutoff ** 2
            return w2[keep], Phi[rows][:, keep]
        k *= 2


# ------------------------------------------------------------ modes (tied)

def frequencies_mpi(bundle, n_modes: int, tied: bool = True, sigma: float | None = None, comm=None):
    """:func:`reduction.modes.frequencies` with the eigen-solve on every rank of ``comm``.

    ``bundle`` is needed on rank 0 only (others pass None): it builds the
    constrained ``TᵀKT``, ``TᵀMT``, which are scattered by row blocks into
    MPIAIJ matrices for SLEPc shift-invert with parallel MUMPS. Returns the
    frequencies [Hz] on every rank.
    """
    from mpi4py import MPI
    from petsc4py import PETSc

    from reduction.constraints import constrain, constraint_map
    from reduction.eigen import eigs, frequencies_hz
    from reduction.modes import SIGMA

    comm = comm or MPI.COMM_WORLD
    sigma = SIGMA if sigma is None else sigma
    Kc = Mc = None
    if comm.Get_rank() == ROOT:
        T = constraint_map(bundle, tied=tied)
        Kc, Mc = constrain(bundle.K, T), constrain(bundle.M, T)
    pcomm = PETSc.Comm(comm)
    Kp, Mp = _scatter_rows(Kc, comm, pcomm), _scatter_rows(Mc, comm, pcomm)
    try:
        omega2, _ = eigs(Kp, Mp, n_modes, sigma=sigma, vectors=False)
    finally:
        Kp.destroy()
        Mp.destroy()
    return frequencies_hz(omega2)


def _scatter_rows(A, comm, pcomm):
    """Row blocks of a rank-0 scipy matrix → MPIAIJ on ``pcomm``."""
    if comm.Get_rank() == ROOT:
        A = sp.csr_matrix(A)
        cuts = split(A.shape[0], comm.Get_size())
        parts = [(A.shape, A[cuts[r]:cuts[r + 1]]) for r in range(comm.Get_size())]
    else:
        parts = None
    shape, local = comm.scatter(parts, root=ROOT)
    return aij(local, shape, pcomm)


def main(argv=None) -> int:
    """``mpirun -n N python -m reduction.parallel BUNDLE OUT.npz [--modes 30] [--cutoff-hz F] [--eigensolver …]``."""
    import argparse

    ap = argparse.ArgumentParser(description="Craig–Bampton reduction of a model bundle on all MPI ranks")
    ap.add_argument("bundle")
    ap.add_argument("out")
    ap.add_argument("--modes", type=int, default=30)
    ap.add_argument("--cutoff-hz", type=float, default=0.0)
    ap.add_argument("--eigensolver", default="lanczos", choices=("lanczos", "slepc"))
    a = ap.parse_args(argv)
    model = reduce_bundle_mpi(a.bundle, a.modes or None, a.cutoff_hz or None, eigensolver=a.eigensolver)
    if model is not None:
        model.save(a.out)
        print(f"{a.out}: {model.size} coordinates, {model.info['mpi_ranks']} ranks, "
              f"{model.info['seconds']['total']:.2f} s")
    import gc

    from petsc4py import PETSc

    # End PETSc on every rank together, else a hang at exit (see workflow.mpi.finish).
    gc.collect()
    PETSc.garbage_cleanup(PETSc.COMM_WORLD)
    PETSc.COMM_WORLD.barrier()
    PETSc._finalize()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
