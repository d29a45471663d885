"""Craig–Bampton per nodal diameter of a tuned disk, and the cyclic reduced model.

A sector bundle with ``cyclic.npz`` (:class:`reduction.bundle.Cyclic`) is
reduced once per nodal diameter the harmonic balance needs: harmonic j of an
engine-order-EO travelling wave lives on ND ``k_j = (j·EO) mod N`` (Petrov
2004, "A method for use of cyclic symmetry properties in analysis of
nonlinear multiharmonic vibrations of bladed discs", J. Turbomach. 126;
:mod:`reduction.cyclic`). For each such k:

1. the sector operators ``K_k = T_kᴴ K T_k`` (same for M, C; complex
   Hermitian, real for k = 0 and N/2) of :func:`reduction.cyclic.cyclic_map`;
2. Craig–Bampton on them (:func:`craig_bampton_hermitian`): boundary = the
   contact DOFs of both bodies + concentrated-load and observed DOFs
   (:func:`reduction.reduce.boundary_dofs`), in the SAME order for every ND
   and none on a cyclic face (asserted), so the relative map ``B`` is one real
   matrix; interior fixed-interface modes of ``(K_k,ii, M_k,ii)`` by scipy
   ``splu`` + ``eigsh`` shift-invert (petsc4py here is a real build, MUMPS
   cannot factor a complex matrix);
3. loads ``T_kᴴ f``: the static (centrifugal) load on ND 0 only — with its
   interior static response appended as a load vector, as in the
   fixed-boundary reduction — and the tip load (sector 0's amplitude of the
   EO wave ``F_s = Re(R^s F e^{i(ωt + s·2π·EO/N)})``) on ND EO mod N only.

The result, :class:`CyclicReducedModel`, is one :class:`ReducedModel` per ND
(complex M, K, C; real B; the pair data shared) and goes wherever a
ReducedModel goes: :func:`workflow.engine.condense.relative_coordinates` gives each
harmonic its ND's condensed dynamic stiffness. Units: SI; ω in rad/s.
"""
from __future__ import annotations

import json
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from workflow.engine.model import ReducedModel
from workflow.errors import BundleError, SolverError
from workflow.io import write_npz

_PAIR_FIELDS = ("area", "gap", "flank", "position")
#: interiors up to this many DOFs get their fixed-interface modes from a dense eigensolver.
DENSE_INTERIOR = 200


def _hermitian(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + A.conj().T)


def _ritz(X: np.ndarray, K: sp.spmatrix, M: sp.spmatrix, drop: float = 1e-10):
    """Rayleigh–Ritz on span(X): ``(ω², Y)`` with ``Yᴴ M Y = I``, ``Yᴴ K Y = diag ω²``.

    Directions whose M-norm² is below ``drop`` × the largest are dropped
    (a load vector already in span(Φ)).
    """
    G = _hermitian(X.conj().T @ (M @ X))
    g, U = np.linalg.eigh(G)
    keep = g > drop * max(g.max(initial=0.0), np.finfo(float).tiny)
    X = X @ (U[:, keep] / np.sqrt(g[keep]))
    w2, Y = np.linalg.eigh(_hermitian(X.conj().T @ (K @ X)))
    return w2, X @ Y


def craig_bampton_hermitian(M: sp.spmatrix, K: sp.spmatrix, boundary: np.ndarray, n_modes: int,
                            loads: np.ndarray | None = None, timings: dict | None = None):
    """Craig–Bampton basis of Hermitian (M, K) (complex or real), ``(V, ω_fixed)``.

    ``V`` (n, nb + nm + nl) = [[I, 0, 0], [Ψ, Φ, X]] (rows boundary, interior;
    see :mod:`reduction.craig_bampton`), ``Ψ = −K_ii⁻¹ K_ib``, Φ the ``n_modes``
    lowest fixed-interface modes (``Φᴴ M_ii Φ = I``), X the interior static
    responses ``K_ii⁻¹ f_i`` of the ``loads`` columns made M-orthogonal to Φ.
    ``ω_fixed`` [rad/s]. ``timings`` gets ``factor``, ``constraint_modes``,
    ``eigen``, ``load_vectors`` [s].
    """
    M, K = sp.csr_matrix(M), sp.csr_matrix(K)
    n = K.shape[0]
    boundary = np.asarray(boundary, np.int64)
    mask = np.ones(n, bool)
    mask[boundary] = False
    interior = np.flatnonzero(mask)
    Kii, Mii = K[interior][:, interior].tocsc(), M[interior][:, interior].tocsc()
    t = {} if timings is None else timings
    t0 = time.perf_counter()
    try:
        lu = spla.splu(Kii, permc_spec="MMD_AT_PLUS_A")
    except RuntimeError as exc:
        raise SolverError(f"sector operator K_ii is singular ({exc}): is a body held by no boundary DOF?") from exc
    t["factor"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    Psi = -lu.solve(K[interior][:, boundary].toarray())
    t["constraint_modes"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    nm = min(int(n_modes), interior.size)
    if nm > 0 and (nm >= interior.size - 1 or interior.size <= DENSE_INTERIOR):
        # ARPACK needs k < n − 1: a small interior is solved densely (all modes: CB exact)
        w2, Phi = sla.eigh(Kii.toarray(), Mii.toarray(), subset_by_index=[0, nm - 1])
    elif nm > 0:
        op = spla.LinearOperator(Kii.shape, matvec=lu.solve, dtype=Kii.dtype)
        # shift-invert about 0 (K_ii is definite): the lowest modes converge first
        _, Phi = spla.eigsh(Kii, k=nm, M=Mii, sigma=0.0, OPinv=op, which="LM", tol=1e-12)
        w2, Phi = _ritz(Phi, Kii, Mii)
    else:
        w2, Phi = np.zeros(0), np.zeros((interior.size, 0), Kii.dtype)
    t["eigen"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    X = np.zeros((interior.size, 0), Phi.dtype)
    if loads is not None:
        F = np.asarray(loads).reshape(n, -1)[interior]
        F = F[:, np.linalg.norm(F, axis=0) > 0]
        if F.shape[1]:
            X = lu.solve(F.astype(np.result_type(F, Kii.dtype)))
            X = X - Phi @ (Phi.conj().T @ (Mii @ X))
            X = _ritz(X, Kii, Mii, drop=1e-8)[1]
    t["load_vectors"] = time.perf_counter() - t0
    nb = boundary.size
    V = np.zeros((n, nb + Phi.shape[1] + X.shape[1]), dtype=np.result_type(Psi, Phi, X))
    V[boundary, np.arange(nb)] = 1.0
    V[interior, :nb] = Psi
    V[interior, nb:nb + Phi.shape[1]] = Phi
    V[interior, nb + Phi.shape[1]:] = X
    return V, np.sqrt(np.clip(w2, 0.0, None))


@dataclass
class CyclicReducedModel:
    """A tuned disk's sector reduced per nodal diameter (module doc).

    ``models``: {ND k: :class:`ReducedModel`} with complex Hermitian M, K, C
    (real at k = 0, N/2), one real B (3p × m) and the same pairs;
    ``f_static`` is non-zero on ND 0 only, ``f_harmonic`` on ND EO mod N
    only. ``engine_order`` EO and ``n_sectors`` N fix which ND each harmonic
    uses (:meth:`nodal_diameters`). ``info``: provenance and timings.
    """

    models: dict
    engine_order: int
    n_sectors: int
    info: dict = field(default_factory=dict)

    is_cyclic = True

    @property
    def _any(self) -> ReducedModel:
        return self.models[min(self.models)]

    def __getattr__(self, name):
        # the pair data (area, gap, flank, position, mu, n_pairs, B) are the same on every ND
        if name in _PAIR_FIELDS + ("mu", "n_pairs", "B", "friction"):
            return getattr(self._any, name)
        raise AttributeError(name)

    @property
    def size(self) -> int:
        """Reduced coordinates of harmonic 1's ND model (the excited one)."""
        return self.models[self.nodal_diameters(1)[1]].size

    def nodal_diameters(self, nh: int) -> list[int]:
        """ND of each harmonic 0…nh, ``(j·EO) mod N``."""
        from workflow.engine.condense import nodal_diameter_of_harmonic

        return [nodal_diameter_of_harmonic(j, self.engine_order, self.n_sectors) for j in range(nh + 1)]

    def save(self, path: str | Path) -> Path:
        """One ``.npz``: ``nd<k>__<field>`` arrays and a JSON ``meta``."""
        arrays = {}
        for k, m in self.models.items():
            for name in ("M", "K", "C", "B", "f_static", "f_harmonic", "O") + _PAIR_FIELDS:
                arrays[f"nd{k}__{name}"] = getattr(m, name)
            if m.mu is not None:
                arrays[f"nd{k}__mu"] = np.asarray(m.mu, float)
        meta = {"engine_order": self.engine_order, "n_sectors": self.n_sectors, "nds": sorted(self.models),
                "info": self.info, "nd_info": {str(k): m.info for k, m in self.models.items()}}
        return write_npz(path, meta=np.array(json.dumps(meta, default=str)), **arrays)

    @classmethod
    def load(cls, path: str | Path) -> "CyclicReducedModel":
        path = Path(path)
        try:
            with np.load(path) as z:
                meta = json.loads(str(z["meta"]))
                models = {}
                for k in meta["nds"]:
                    get = {name: z[f"nd{k}__{name}"] for name in ("M", "K", "C", "B", "f_static", "f_harmonic",
                                                                 "O") + _PAIR_FIELDS}
                    mu = z[f"nd{k}__mu"] if f"nd{k}__mu" in z else None
                    models[int(k)] = ReducedModel(**get, mu=mu, info=meta["nd_info"].get(str(k), {}))
        except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise BundleError(f"cyclic reduced model {path} cannot be read: {exc}") from exc
        model = cls(models=models, engine_order=int(meta["engine_order"]), n_sectors=int(meta["n_sectors"]),
                    info=meta.get("info", {}))
        model.validate()
        return model

    def validate(self) -> None:
        """Raise :class:`BundleError` naming the first inconsistency."""
        if not self.models:
            raise BundleError("cyclic reduced model has no nodal diameter")
        if self.n_sectors < 2 or not all(0 <= k < self.n_sectors for k in self.models):
            raise BundleError(f"cyclic reduced model: NDs {sorted(self.models)} outside 0 … {self.n_sectors - 1}")
        ref = self._any
        for k, m in self.models.items():
            m.validate()
            for name in ("M", "K", "C", "f_static", "f_harmonic", "O"):
                if not np.all(np.isfinite(getattr(m, name))):
                    raise BundleError(f"cyclic reduced model ND {k}: {name} has non-finite entries")
            for name in ("M", "K"):
                A = getattr(m, name)
                if np.abs(A - A.conj().T).max(initial=0.0) > 1e-8 * np.abs(A).max(initial=0.0):
                    raise BundleError(f"cyclic reduced model ND {k}: {name} is not Hermitian")
            if np.iscomplexobj(m.B) or m.B.shape[0] != ref.B.shape[0] or \
                    not all(np.array_equal(getattr(m, f), getattr(ref, f)) for f in _PAIR_FIELDS):
                raise BundleError(f"cyclic reduced model ND {k}: its contact pairs (B, area, gap, …) differ from "
                                  f"ND {min(self.models)}'s")


def _kept(n: int, high_dofs: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """Columns of :func:`reduction.cyclic.cyclic_map`: all DOFs but the high face's and the clamped."""
    dropped = np.zeros(n, bool)
    dropped[np.asarray(high_dofs, np.int64).ravel()] = True
    dropped[np.asarray(fixed, np.int64)] = True
    return np.flatnonzero(~dropped)


def nodal_diameters_needed(engine_order: int, n_sectors: int, nh_max: int) -> list[int]:
    """Sorted NDs of harmonics 0…nh_max under engine order EO: ``{(j·EO) mod N}``."""
    from workflow.engine.condense import nodal_diameter_of_harmonic

    return sorted({nodal_diameter_of_harmonic(j, engine_order, n_sectors) for j in range(nh_max + 1)})


def sector_matrices(bundle, nd: int):
    """``(T_k, K_k, M_k, C_k, kept)``: ND-k sector operators of a cyclic bundle (sparse)."""
    from reduction.cyclic import cyclic_map, sector_operator

    cy = bundle.cyclic
    T = cyclic_map(bundle.n_dofs, cy.low_dofs, cy.high_dofs, cy.n_sectors, nd, fixed=bundle.loads.fixed)
    kept = _kept(bundle.n_dofs, cy.high_dofs, bundle.loads.fixed)
    return T, sector_operator(bundle.K, T), sector_operator(bundle.M, T), sector_operator(bundle.C, T), kept


def reduce_cyclic(bundle, engine_order: int, nh_max: int, n_modes: int = 30) -> CyclicReducedModel:
    """Craig–Bampton of a cyclic sector bundle on every ND harmonics 0…nh_max need (module doc).

    ``n_modes`` fixed-interface modes per ND. ``info["seconds_per_nd"]``: the
    wall time [s] of each ND's reduction; each ND model's ``info["seconds"]``
    splits it (sector operators, factor, constraint modes, eigen, load
    vectors, projection).
    """
    from workflow.engine.condense import nodal_diameter_of_harmonic
    from reduction.reduce import boundary_dofs

    cy = bundle.cyclic
    if cy is None:
        raise BundleError(f"model bundle {bundle.path}: no cyclic.npz — a cyclic run needs the sector's cyclic "
                          "faces (the assembly writes them for a [cyclic] scene)")
    if bundle.contact.tie is not None and len(bundle.contact.tie):
        raise BundleError(f"model bundle {bundle.path}: tied midside nodes (geometry.contact_nodes = \"linear\") "
                          "are not implemented with cyclic symmetry; use geometry.contact_nodes = \"vertices\" "
                          "or \"all\" in a [cyclic] scene")
    t_all = time.perf_counter()
    bnd = boundary_dofs(bundle)
    faces = np.concatenate([np.asarray(cy.low_dofs).ravel(), np.asarray(cy.high_dofs).ravel()])
    if np.intersect1d(bnd, faces).size:
        raise BundleError(f"model bundle {bundle.path}: contact/loaded/observed DOFs lie on a cyclic face "
                          "(the cyclic reduction needs them inside the sector)")
    n_sectors = int(cy.n_sectors)
    nds = nodal_diameters_needed(engine_order, n_sectors, nh_max)  # includes ND 0 (harmonic 0)
    nd_eo = nodal_diameter_of_harmonic(1, engine_order, n_sectors)
    models = {k: _reduce_nd(bundle, k, bnd, n_modes, static=k == 0, harmonic=k == nd_eo) for k in nds}
    info = {"nodal_diameters": nds, "engine_order": int(engine_order), "nh_max": int(nh_max),
            "modes": int(n_modes), "seconds_per_nd": {k: m.info["seconds"]["total"] for k, m in models.items()},
            "seconds": time.perf_counter() - t_all,
            "bundle": str(bundle.path) if bundle.path is not None else None}
    out = CyclicReducedModel(models=models, engine_order=int(engine_order), n_sectors=n_sectors, info=info)
    out.validate()
    return out


def _reduce_nd(bundle, k: int, bnd: np.ndarray, n_modes: int, *, static: bool, harmonic: bool) -> ReducedModel:
    """The ND-k reduced model: sector operators, Craig–Bampton, projection (see :func:`reduce_cyclic`)."""
    from reduction.bundle import pair_labels
    from reduction.reduce import contact_map

    t = {}
    t0 = time.perf_counter()
    T, Kk, Mk, Ck, kept = sector_matrices(bundle, k)
    col = -np.ones(bundle.n_dofs, np.int64)
    col[kept] = np.arange(kept.size)
    Th = T.conj().T
    fs = Th @ bundle.loads.static if static else np.zeros(kept.size)
    fh = Th @ bundle.loads.harmonic if harmonic else np.zeros(kept.size)
    t["operators"] = time.perf_counter() - t0
    V, omega = craig_bampton_hermitian(Mk, Kk, col[bnd], n_modes, loads=np.column_stack([fs, fh]), timings=t)
    t0 = time.perf_counter()
    Vh = V.conj().T
    B = np.asarray(contact_map(bundle) @ T @ V)
    if np.abs(B.imag).max(initial=0.0) > 1e-12 * np.abs(B).max(initial=1.0):
        raise BundleError("cyclic reduction: the relative map B is complex — a contact DOF sits on a cyclic face")
    obs = np.asarray(bundle.loads.observe, np.int64)
    O = np.zeros((obs.size, V.shape[1]), V.dtype)
    held = col[obs] >= 0  # a clamped observed DOF reads 0
    O[held] = V[col[obs[held]]]
    c = bundle.contact
    flank, position = pair_labels(bundle)
    zero = np.zeros((V.shape[1],) * 2, V.dtype)
    model = ReducedModel(M=_hermitian(Vh @ (Mk @ V)), K=_hermitian(Vh @ (Kk @ V)),
                         C=_hermitian(Vh @ (Ck @ V)) if Ck.nnz else zero, B=np.ascontiguousarray(B.real),
                         f_static=Vh @ fs, f_harmonic=Vh @ fh, O=O.real if not np.abs(O.imag).any() else O,
                         area=np.asarray(c.area, float), gap=np.asarray(c.gap, float), flank=np.asarray(flank),
                         position=np.asarray(position, float), mu=None if c.mu is None else np.asarray(c.mu, float))
    t["projection"] = time.perf_counter() - t0
    t["total"] = sum(t.values())
    model.info = {"method": "craig-bampton-cyclic", "nodal_diameter": int(k), "modes": int(omega.size),
                  "boundary_dofs": int(bnd.size), "size": int(V.shape[1]), "sector_dofs": int(kept.size),
                  "fixed_interface_hz": (omega / (2 * np.pi)).tolist(), "seconds": {a: float(b) for a, b in t.items()}}
    return model


def tied_frequencies(bundle, nd: int, count: int) -> np.ndarray:
    """Lowest ``count`` frequencies [Hz] of the unreduced ND-``nd`` sector with the
    interface tied (:func:`reduction.bundle.tied_map` on the sector operator's
    DOFs), by ``eigsh`` shift-invert on the Hermitian matrices — the reference
    of a reduced ND model (:func:`reduced_tied_frequencies`)."""
    from reduction.bundle import tied_map

    T, K, M, _, kept = sector_matrices(bundle, nd)
    L = sp.csc_matrix(tied_map(bundle))[kept]
    L = L[:, np.flatnonzero(np.diff(L.indptr))]  # tied DOFs that live on the high face only are not unknowns
    Kt, Mt = (sp.csc_matrix(L.T @ A @ L) for A in (K, M))
    lu = spla.splu(Kt, permc_spec="MMD_AT_PLUS_A")
    op = spla.LinearOperator(Kt.shape, matvec=lu.solve, dtype=Kt.dtype)
    w2 = spla.eigsh(Kt, k=count, M=Mt, sigma=0.0, OPinv=op, which="LM", return_eigenvectors=False, tol=1e-12)
    return np.sort(np.sqrt(np.clip(np.real(w2), 0, None))) / (2 * np.pi)


def reduced_tied_frequencies(model: ReducedModel, count: int) -> np.ndarray:
    """Lowest ``count`` frequencies [Hz] of a (complex) reduced model with u_r = 0."""
    from workflow.engine.condense import relative_coordinates

    rc = relative_coordinates(model)
    r = rc.n_rel
    w2 = sla.eigh(_hermitian(rc.K[r:, r:]), _hermitian(rc.M[r:, r:]), eigvals_only=True)
    return np.sqrt(np.clip(w2[:count], 0, None)) / (2 * np.pi)
