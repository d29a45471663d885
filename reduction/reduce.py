"""Reduce a model bundle onto its contact interface (contracts §2 → §4).

Craig–Bampton (:mod:`reduction.craig_bampton`) on the unclamped DOFs with
boundary = every contact DOF of both bodies + the DOFs of a concentrated
harmonic load + the observed DOFs; then the reduced matrices ``VᵀMV``,
``VᵀKV``, ``VᵀCV``, the relative-displacement map ``B`` (q → u_r in each
pair's (n, t1, t2) frame, pair-major), reduced loads and ``O``.

A load spread over many DOFs (the centrifugal static load; a distributed
harmonic load) does not make its DOFs boundary DOFs: its interior static
response is appended as a load vector instead, which keeps the static
response to it exact (see :func:`reduction.craig_bampton.craig_bampton`).

Units: SI. Reduced coordinates q = [u_b (m); η (modal, kg^½·m); load vectors].
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from reduction.bundle import Bundle, pair_labels
from reduction.craig_bampton import craig_bampton
from workflow.engine.model import ReducedModel
from reduction.tie import boundary_map, tie_pairs
from workflow.errors import BundleError

#: A harmonic load on at most this many DOFs makes them boundary DOFs;
#: a wider one is represented by a load vector.
MAX_LOAD_DOFS = 24


@dataclass
class Basis:
    """The reduction basis behind a ReducedModel: u_full[free] = V q, clamped DOFs 0."""

    V: np.ndarray  # (n_free, m)
    free: np.ndarray  # (n_free,) full DOF indices of V's rows
    boundary: np.ndarray  # (nb,) full DOF indices of the first nb coordinates
    n_modes: int
    n_load: int
    n_dofs: int

    def expand(self, q: np.ndarray) -> np.ndarray:
        """Full displacement vector(s) (n_dofs,) or (n_dofs, k) from q."""
        q = np.asarray(q)
        u = np.zeros((self.n_dofs,) + q.shape[1:], dtype=np.result_type(q, float))
        u[self.free] = self.V @ q
        return u


def contact_map(bundle: Bundle) -> sp.csr_matrix:
    """(3p, n) sparse map u → u_r = R_k (u_blade − u_disk), pair-major [n, t1, t2].

    Grounded sides (index −1) contribute nothing.
    """
    c = bundle.contact
    R = c.frames()  # (p, 3, 3), rows n, t1, t2
    p = c.n_pairs
    rows = np.repeat(np.arange(3 * p), 3).reshape(p, 3, 3)  # row 3k+a, 3 global components
    parts = []
    for dofs, sign in ((c.blade_dofs, 1.0), (c.disk_dofs, -1.0)):
        cols = np.broadcast_to(dofs[:, None, :], (p, 3, 3))
        ok = cols >= 0
        parts.append((rows[ok], cols[ok], sign * R[ok]))
    r, col, v = (np.concatenate(x) for x in zip(*parts))
    return sp.csr_matrix((v, (r, col)), shape=(3 * p, bundle.n_dofs))


def boundary_dofs(bundle: Bundle, max_load_dofs: int = MAX_LOAD_DOFS) -> np.ndarray:
    """Sorted unclamped DOFs kept physically: contact (both bodies), tied
    midside DOFs (``contact.tie``), a concentrated harmonic load (≤
    ``max_load_dofs`` DOFs), observed DOFs."""
    c, L = bundle.contact, bundle.loads
    parts = [c.blade_dofs.ravel(), c.disk_dofs.ravel(), np.asarray(L.observe).ravel()]
    if c.tie is not None:  # tied midside DOFs follow their masters in the constraint modes (reduction.tie)
        parts.append(np.asarray(c.tie)[:, 0])
    loaded = np.flatnonzero(L.harmonic)
    if loaded.size <= max_load_dofs:
        parts.append(loaded)
    b = np.unique(np.concatenate(parts).astype(np.int64))
    b = b[b >= 0]
    return np.setdiff1d(b, L.fixed)


def reduce_with_basis(bundle: Bundle, n_modes: int | None = 30, cutoff_hz: float | None = None, *,
                      solver: str = "mumps", eigensolver: str = "lanczos",
                      max_load_dofs: int = MAX_LOAD_DOFS) -> tuple[ReducedModel, Basis]:
    """:func:`reduce_bundle` that also returns the basis (for validation and recovery)."""
    t_all = time.perf_counter()
    n = bundle.n_dofs
    free = bundle.free_dofs
    local = -np.ones(n, dtype=np.int64)
    local[free] = np.arange(free.size)
    bnd = boundary_dofs(bundle, max_load_dofs)
    if bnd.size == 0:
        raise BundleError("bundle has no unclamped contact, loaded or observed DOF to keep")
    Mf, Kf, Cf = (sp.csr_matrix(A)[free][:, free] for A in (bundle.M, bundle.K, bundle.C))
    loads = np.column_stack([bundle.loads.static[free], bundle.loads.harmonic[free]])
    c = bundle.contact
    T_b, kept = boundary_map(bnd, c.tie)
    timings: dict = {}
    V, omega = craig_bampton(Mf, Kf, local[bnd], n_modes, cutoff_hz, loads=loads, solver=solver,
                             eigensolver=eigensolver, timings=timings, combine=T_b)
    nb, nm = kept.size, omega.size
    nl = V.shape[1] - nb - nm

    t0 = time.perf_counter()
    Kr = _project_stiffness(Kf, V, local[bnd], T_b)
    Mr = _sandwich(Mf, V)
    Cr = _sandwich(Cf, V) if Cf.nnz else np.zeros_like(Mr)
    B = np.asarray(contact_map(bundle)[:, free] @ V)
    obs = np.asarray(bundle.loads.observe, dtype=np.int64)
    O = np.zeros((obs.size, V.shape[1]))
    held = local[obs] >= 0  # a clamped observed DOF reads 0
    O[held] = V[local[obs[held]]]
    fs, fh = V.T @ bundle.loads.static[free], V.T @ bundle.loads.harmonic[free]
    timings["projection"] = time.perf_counter() - t0

    flank, position = pair_labels(bundle)
    seconds = {k: float(v) for k, v in timings.items() if not k.startswith("lanczos_")}
    seconds["total"] = time.perf_counter() - t_all
    info = {
        "method": "craig-bampton",
        "modes": int(nm),
        "load_vectors": int(nl),
        "boundary_dofs": int(nb),
        "size": int(V.shape[1]),
        "n_dofs": int(n),
        "free_dofs": int(free.size),
        "pairs": int(c.n_pairs),
        "modes_requested": None if n_modes is None else int(n_modes),
        "cutoff_hz": float(cutoff_hz or 0.0),
        "fixed_interface_hz": (omega / (2 * np.pi)).tolist(),
        "solver": solver,
        "eigensolver": eigensolver,
        "eigen_stats": {k[8:]: v for k, v in timings.items() if k.startswith("lanczos_")},
        "seconds": seconds,
        "bundle": str(bundle.path) if bundle.path is not None else None,
    }
    model = ReducedModel(M=Mr, K=Kr, C=Cr, B=B, f_static=fs, f_harmonic=fh, O=O, area=np.asarray(c.area, float),
                         gap=np.asarray(c.gap, float), flank=np.asarray(flank), position=np.asarray(position, float),
                         info=info, mu=None if c.mu is None else np.asarray(c.mu, float))
    if c.tie is not None:
        info.update(tied_dofs=int(bnd.size - kept.size), tie_pairs=tie_pairs(c).tolist())
    model.validate()
    return model, Basis(V=V, free=free, boundary=bnd[kept], n_modes=nm, n_load=nl, n_dofs=n)


def reduce_bundle(bundle: Bundle, n_modes: int | None = 30, cutoff_hz: float | None = None, **kwargs) -> ReducedModel:
    """Craig–Bampton reduced model of ``bundle`` (contracts §4).

    ``n_modes`` fixed-interface modes, or (``n_modes=None`` or 0) every mode
    below ``cutoff_hz`` [Hz]. ``kwargs``: ``solver`` ("mumps" | "splu"),
    ``eigensolver`` ("lanczos" | "slepc"), ``max_load_dofs``. ``info`` holds
    the modes kept, boundary DOF count, fixed-interface frequencies [Hz] and
    wall times [s] (factor, constraint_modes, eigen, load_vectors,
    projection, total).
    """
    if not n_modes:
        n_modes = None
        if not cutoff_hz:
            raise BundleError("reduction needs modes > 0 or cutoff_hz > 0")
    return reduce_with_basis(bundle, n_modes, cutoff_hz, **kwargs)[0]


def _project_stiffness(K, V, bnd, T_b):
    """VᵀKV with the boundary block as the exact Schur complement T_bᵀ(K_bb T_b + K_bi Ψ).

    With V's boundary columns ``[T_b; Ψ]`` (T_b the tie map, or I) and ``K_ib T_b + K_ii Ψ = 0``,
    ``[T_b; Ψ]ᵀ K [T_b; Ψ] = T_bᵀ(K_bb T_b + K_bi Ψ)``; this avoids a sparse product with the
    nb (hundreds to thousands) constraint-mode columns. The other blocks are formed directly.
    """
    n = K.shape[0]
    nb = T_b.shape[1]
    mask = np.ones(n, dtype=bool)
    mask[bnd] = False
    interior = np.flatnonzero(mask)
    Kr = np.empty((V.shape[1], V.shape[1]))
    Kb = K[bnd]
    KbbT, Kbi, T_t = (Kb[:, bnd] @ T_b).tocsc(), Kb[:, interior], T_b.T.tocsr()
    for s in range(0, nb, PROJECTION_COLUMNS):
        e = min(s + PROJECTION_COLUMNS, nb)
        Kr[:nb, s:e] = T_t @ (KbbT[:, s:e].toarray() + Kbi @ V[interior, s:e])
    Kr[:, nb:] = V.T @ (K @ V[:, nb:])
    Kr[nb:, :nb] = Kr[:nb, nb:].T
    return _symmetric(Kr)


#: columns of V a projection takes at a time (:func:`_sandwich`): its n × m products were
#: the reduction's largest arrays after V (measured on 144 pairs at h_blade 2 mm: 9.1 GB peak)
PROJECTION_COLUMNS = 256


def _sandwich(A, V):
    """VᵀAV for a symmetric A by blocks of :data:`PROJECTION_COLUMNS` columns, so that no n × m
    product AV is ever whole; only the upper triangle's blocks are formed, the lower is their
    transpose."""
    m = V.shape[1]
    out = np.empty((m, m))
    for s in range(0, m, PROJECTION_COLUMNS):
        e = min(s + PROJECTION_COLUMNS, m)
        out[:e, s:e] = V[:, :e].T @ (A @ V[:, s:e])
    lower = np.tril_indices(m, -1)
    out[lower] = out.T[lower]
    return out


def _symmetric(A):
    return 0.5 * (A + A.T)
