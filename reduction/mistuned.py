"""The mistuned bladed disk from one tuned sector: blades physical, the disk by nodal diameters.

A dovetail blade touches its disk only through its contact pairs, so a sector's operators split
into two bodies that share no stiffness, mass or damping term (:func:`split_bodies`): the blade
(sector-local, never on a cyclic face) and the disk (cyclic). The whole disk of N sectors is

* N **blade** substructures: the tuned blade's Craig–Bampton model (boundary: its contact,
  loaded and observed DOFs; fixed-interface modes; its static load's interior shape), blade s
  with its own stiffness factor ``1 + δ_s`` (and mass factor ``1 + γ_s``). This is exact for a
  blade whose stiffness (mass) scales uniformly — Young's modulus (density) scatter: the
  constraint modes ``−K_ii⁻¹ K_ib`` and the fixed-interface mode shapes do not change under a
  scaling, only the modal frequencies (by ``√((1+δ)/(1+γ))``). No mistuning projection onto
  tuned modes is made (no CMM/SNM approximation, Lim et al. 2007): every blade keeps its contact
  DOFs physical, so the DLFT stays exact blade by blade;
* the **disk**, reduced once per nodal diameter k = 0 … ⌊N/2⌋ (Craig–Bampton on its ND-k sector
  operators :func:`reduction.cyclic_reduce.sector_matrices`, boundary its contact DOFs; k and N−k
  are complex conjugates) and brought back to physical coordinates by a unitary change: its
  contact DOFs sector by sector (``b_s = N^{-1/2} Σ_k e^{iksα} b_k``, a DFT over the NDs,
  :func:`_disk_physical`), its fixed-interface modes of ND k and N−k as one real pair
  (``η_k = (a + i c)/√2``). Harmonic j of a mistuned response lives on every ND, which is why
  the disk needs all of them.

The result (:func:`whole_disk`) is one real :class:`~workflow.engine.model.ReducedModel` with
coordinates ``[blade 0, …, blade N−1, disk contact DOFs of sectors 0 … N−1, disk modes]``,
which goes wherever a ReducedModel goes (the engine's HB, sweeps, wear). Its only truncation is
each substructure's modes, the same kind as the tuned cyclic model's;
:func:`cyclic_model` rebuilds the tuned cyclic model (one ND model per harmonic) from the same
substructures — the reference a tuned whole disk must reproduce.

Frames and phases follow :mod:`reduction.cyclic`: every sector's quantities are in its own
(rotated) frame, sector s's tip load is ``R^s F e^{i s 2π EO/N}`` (complex ``f_harmonic``), the
pairs are sector-major (sector s's are rows ``3p·s … 3p(s+1)`` of B), the observed DOFs too.
Units: SI (m, kg, s, N); ω in rad/s.
"""
from __future__ import annotations

import json
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph

from reduction.cyclic import rotation_x
from workflow.engine.model import ReducedModel
from workflow.errors import BundleError
from workflow.io import write_npz

#: ‖C − αM − βK‖_F / ‖C‖_F at or below which the blade's damping is Rayleigh, so that a
#: mistuned blade's is ``αM_s + βK_s`` (:func:`_rayleigh`); the project's bundles reduce to ~1e-14.
RAYLEIGH_TOL = 1e-10


@dataclass
class Blade:
    """The tuned blade's reduced model (real): ``M`` [kg], ``K`` [N/m], ``C`` [N s/m] (mb, mb);
    ``B`` (3p, mb) its part of the relative contact map; ``f_static``, ``f_harmonic`` (mb,) [N]
    (sector 0's tip load amplitude); ``O`` (n_obs, mb); ``rayleigh`` (α [1/s], β [s]) or None."""

    M: np.ndarray
    K: np.ndarray
    C: np.ndarray
    B: np.ndarray
    f_static: np.ndarray
    f_harmonic: np.ndarray
    O: np.ndarray
    rayleigh: tuple | None = None

    @property
    def size(self) -> int:
        return self.M.shape[0]


@dataclass
class DiskND:
    """The disk's ND-k reduced model: coordinates ``[b (nb contact DOFs), η (modes, load shapes)]``,
    complex Hermitian ``M``, ``K``, ``C`` (real at k = 0, N/2), ``B`` (3p, m) real (zero on η),
    ``f_static`` (m,) [N] sector 0's static load (ND 0 only, sector-0 convention of
    :mod:`reduction.cyclic_reduce`)."""

    M: np.ndarray
    K: np.ndarray
    C: np.ndarray
    B: np.ndarray
    f_static: np.ndarray
    nb: int

    @property
    def size(self) -> int:
        return self.M.shape[0]


@dataclass
class Substructures:
    """A tuned sector as blade + disk-per-ND substructures (module doc); ``pairs``: area, gap,
    flank, position (sector 0), mu (or None); ``info``: provenance and timings."""

    blade: Blade
    disk: dict
    n_sectors: int
    engine_order: int
    pairs: dict
    info: dict = field(default_factory=dict)

    @property
    def n_pairs(self) -> int:
        return self.blade.B.shape[0] // 3

    def nd(self, k: int) -> DiskND:
        """ND k's disk model, conjugating ND N−k's for k > N/2."""
        k = int(k) % self.n_sectors
        if k in self.disk:
            return self.disk[k]
        d = self.disk[self.n_sectors - k]
        return DiskND(M=d.M.conj(), K=d.K.conj(), C=d.C.conj(), B=d.B, f_static=d.f_static.conj(), nb=d.nb)

    def save(self, path: str | Path) -> Path:
        """One ``.npz`` written atomically."""
        b = self.blade
        arrays = {f"blade__{n}": getattr(b, n) for n in ("M", "K", "C", "B", "f_static", "f_harmonic", "O")}
        for k, d in self.disk.items():
            arrays.update({f"nd{k}__{n}": getattr(d, n) for n in ("M", "K", "C", "B", "f_static")})
        arrays.update({f"pair__{n}": np.asarray(v) for n, v in self.pairs.items() if v is not None})
        meta = {"n_sectors": self.n_sectors, "engine_order": self.engine_order, "nds": sorted(self.disk),
                "nb": {str(k): d.nb for k, d in self.disk.items()}, "info": self.info,
                "rayleigh": None if b.rayleigh is None else list(b.rayleigh)}
        return write_npz(path, meta=np.array(json.dumps(meta, default=str)), **arrays)

    @classmethod
    def load(cls, path: str | Path) -> "Substructures":
        path = Path(path)
        try:
            with np.load(path) as z:
                meta = json.loads(str(z["meta"]))
                blade = Blade(**{n: z[f"blade__{n}"] for n in ("M", "K", "C", "B", "f_static", "f_harmonic", "O")},
                              rayleigh=None if meta["rayleigh"] is None else tuple(meta["rayleigh"]))
                disk = {int(k): DiskND(**{n: z[f"nd{k}__{n}"] for n in ("M", "K", "C", "B", "f_static")},
                                       nb=int(meta["nb"][str(k)])) for k in meta["nds"]}
                pairs = {n: (z[f"pair__{n}"] if f"pair__{n}" in z else None)
                         for n in ("area", "gap", "flank", "position", "mu")}
        except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise BundleError(f"substructures {path} cannot be read: {exc}") from exc
        out = cls(blade=blade, disk=disk, n_sectors=int(meta["n_sectors"]), engine_order=int(meta["engine_order"]),
                  pairs=pairs, info=meta.get("info", {}))
        out.validate(str(path))
        return out

    def validate(self, where: str = "substructures") -> None:
        """Raise :class:`BundleError` naming the first inconsistency (a damaged file is never used)."""
        N = self.n_sectors
        missing = [k for k in range(N // 2 + 1) if k not in self.disk]
        if N < 2 or missing:
            raise BundleError(f"{where}: the disk lacks nodal diameters {missing} of {N} sectors")
        for name, A in [("blade", self.blade)] + [(f"ND {k}", d) for k, d in self.disk.items()]:
            for m in ("M", "K", "C"):
                X = getattr(A, m)
                if X.shape != (A.size, A.size) or not np.all(np.isfinite(X)):
                    raise BundleError(f"{where}: {name} {m} is {X.shape} or non-finite")
            if A.B.shape != (3 * self.n_pairs, A.size):
                raise BundleError(f"{where}: {name} B is {A.B.shape}, expected ({3 * self.n_pairs}, {A.size})")


def split_bodies(bundle) -> tuple[np.ndarray, np.ndarray]:
    """(blade DOFs, disk DOFs), sorted free DOFs of the two bodies of a dovetail sector.

    The bodies are the connected components of the free DOFs' stiffness and mass graph; the
    blade's holds every ``contact.blade_dofs``, the disk's every ``contact.disk_dofs`` and the
    cyclic faces. Raises :class:`BundleError` when the sector is not two such bodies (a blade
    glued to its disk, or a third body).
    """
    free = bundle.free_dofs
    A = (abs(sp.csr_matrix(bundle.K)) + abs(sp.csr_matrix(bundle.M)))[free][:, free]
    n, label = csgraph.connected_components(A, directed=False)
    local = -np.ones(bundle.n_dofs, np.int64)
    local[free] = np.arange(free.size)
    c = bundle.contact

    def body(dofs, name):
        d = local[np.asarray(dofs).ravel()]
        labs = np.unique(label[d[d >= 0]])
        if labs.size != 1:
            raise BundleError(f"mistuned disk: the {name} DOFs lie on {labs.size} bodies (expected one)")
        return int(labs[0])

    lb, ld = body(c.blade_dofs, "blade contact"), body(c.disk_dofs, "disk contact")
    if n != 2 or lb == ld:
        raise BundleError(f"mistuned disk: the sector has {n} connected bodies with the blade and disk "
                          f"{'the same' if lb == ld else 'apart'}; it needs exactly a blade held by contact "
                          "alone and a disk")
    faces = local[np.concatenate([np.asarray(bundle.cyclic.low_dofs).ravel(),
                                  np.asarray(bundle.cyclic.high_dofs).ravel()])]
    if np.any(label[faces[faces >= 0]] != ld):
        raise BundleError("mistuned disk: a cyclic face DOF is not on the disk")
    return free[label == lb], free[label == ld]


def _rayleigh(M: np.ndarray, K: np.ndarray, C: np.ndarray) -> tuple | None:
    """(α [1/s], β [s]) with C = αM + βK to :data:`RAYLEIGH_TOL`, else None (least squares)."""
    if not np.abs(C).max(initial=0.0):
        return (0.0, 0.0)
    A = np.stack([M.ravel(), K.ravel()], axis=1)
    coef = np.linalg.lstsq(A, C.ravel(), rcond=None)[0]
    res = np.linalg.norm(C - coef[0] * M - coef[1] * K) / np.linalg.norm(C)
    return (float(coef[0]), float(coef[1])) if res <= RAYLEIGH_TOL else None


def _sym(A):
    return 0.5 * (A + A.conj().T)


def reduce_blade(bundle, blade: np.ndarray, n_modes: int) -> tuple[Blade, dict]:
    """The blade's real Craig–Bampton model (module doc) and its timings [s]."""
    from reduction.cyclic_reduce import craig_bampton_hermitian
    from reduction.reduce import boundary_dofs, contact_map

    t0 = time.perf_counter()
    L = bundle.loads
    bnd_all = boundary_dofs(bundle)
    bnd = np.intersect1d(bnd_all, blade)
    obs = np.asarray(L.observe, np.int64)
    if not np.isin(obs, blade).all():
        raise BundleError("mistuned disk: every observed DOF (loads.observe) must be on the blade")
    disk_load = np.setdiff1d(np.flatnonzero(L.harmonic), blade)
    if disk_load.size:
        raise BundleError(f"mistuned disk: the harmonic load acts on {disk_load.size} disk DOFs; the mistuned "
                          "disk takes its engine-order load on the blades")
    col = -np.ones(bundle.n_dofs, np.int64)
    col[blade] = np.arange(blade.size)
    K, M, C = (sp.csr_matrix(A)[blade][:, blade] for A in (bundle.K, bundle.M, bundle.C))
    fs, fh = np.asarray(L.static)[blade], np.asarray(L.harmonic)[blade]
    timings: dict = {}
    V, _ = craig_bampton_hermitian(M, K, col[bnd], n_modes, loads=np.column_stack([fs, fh]), timings=timings)
    Vt = V.T
    Mr, Kr = _sym(Vt @ (M @ V)), _sym(Vt @ (K @ V))
    Cr = _sym(Vt @ (C @ V)) if C.nnz else np.zeros_like(Mr)
    B = np.asarray(contact_map(bundle)[:, blade] @ V)
    O = np.zeros((obs.size, V.shape[1]))
    O[:] = V[col[obs]]
    out = Blade(M=Mr, K=Kr, C=Cr, B=B, f_static=Vt @ fs, f_harmonic=Vt @ fh, O=O, rayleigh=_rayleigh(Mr, Kr, Cr))
    timings["total"] = time.perf_counter() - t0
    return out, timings


def reduce_disk_nd(bundle, disk: np.ndarray, k: int, n_modes: int) -> tuple[DiskND, dict]:
    """The disk's ND-k Craig–Bampton model (boundary: its contact DOFs) and its timings [s]."""
    from reduction.cyclic_reduce import craig_bampton_hermitian, sector_matrices
    from reduction.reduce import contact_map

    t0 = time.perf_counter()
    T, Kk, Mk, Ck, kept = sector_matrices(bundle, k)
    col = -np.ones(bundle.n_dofs, np.int64)
    col[kept] = np.arange(kept.size)
    own = col[disk]
    own = np.sort(own[own >= 0])  # the disk's kept columns (its high face is folded onto the low)
    c = bundle.contact
    bnd = np.unique(np.asarray(c.disk_dofs).ravel())
    bnd = bnd[bnd >= 0]
    local = -np.ones(kept.size, np.int64)
    local[own] = np.arange(own.size)
    if np.any(col[bnd] < 0) or np.any(local[col[bnd]] < 0):
        raise BundleError("mistuned disk: a disk contact DOF is clamped or on a cyclic face")
    Kd, Md, Cd = (A[own][:, own] for A in (Kk, Mk, Ck))
    fs = (T.conj().T @ np.asarray(bundle.loads.static))[own] if k == 0 else None
    timings: dict = {}
    V, _ = craig_bampton_hermitian(Md, Kd, local[col[bnd]], n_modes, loads=fs, timings=timings)
    Vh = V.conj().T
    Td = T[:, own]
    B = np.asarray(contact_map(bundle) @ Td @ V)
    if np.abs(B.imag).max(initial=0.0) > 1e-12 * np.abs(B).max(initial=1.0):
        raise BundleError("mistuned disk: the disk's relative map is complex — a contact DOF sits on a cyclic face")
    real = (2 * k) % bundle.cyclic.n_sectors == 0
    cast = (lambda A: np.ascontiguousarray(A.real)) if real else (lambda A: A)
    out = DiskND(M=cast(_sym(Vh @ (Md @ V))), K=cast(_sym(Vh @ (Kd @ V))),
                 C=cast(_sym(Vh @ (Cd @ V))) if Cd.nnz else np.zeros((V.shape[1],) * 2, V.dtype),
                 B=np.ascontiguousarray(B.real), f_static=cast(Vh @ fs) if fs is not None else np.zeros(V.shape[1]),
                 nb=int(bnd.size))
    timings["total"] = time.perf_counter() - t0
    return out, timings


def substructures(bundle, engine_order: int, blade_modes: int, disk_modes: int) -> Substructures:
    """Blade and disk-per-ND substructures of a cyclic sector bundle (module doc).

    ``blade_modes``, ``disk_modes``: fixed-interface modes of the blade and of the disk per ND.
    Every ND 0 … ⌊N/2⌋ is reduced (a mistuned response needs them all).
    """
    from reduction.bundle import pair_labels

    if bundle.cyclic is None:
        raise BundleError(f"model bundle {bundle.path}: no cyclic.npz — the mistuned disk needs a cyclic sector "
                          "([geometry] cyclic = true)")
    if bundle.contact.tie is not None and len(bundle.contact.tie):
        raise BundleError("mistuned disk: tied midside nodes (geometry.contact_nodes = \"linear\") are not "
                          "implemented; use \"vertices\" or \"all\"")
    t0 = time.perf_counter()
    blade_dofs, disk_dofs = split_bodies(bundle)
    blade, tb = reduce_blade(bundle, blade_dofs, blade_modes)
    N = int(bundle.cyclic.n_sectors)
    disk, td = {}, {}
    for k in range(N // 2 + 1):
        disk[k], td[k] = reduce_disk_nd(bundle, disk_dofs, k, disk_modes)
    c = bundle.contact
    flank, position = pair_labels(bundle)
    pairs = {"area": np.asarray(c.area, float), "gap": np.asarray(c.gap, float), "flank": np.asarray(flank),
             "position": np.asarray(position, float), "mu": None if c.mu is None else np.asarray(c.mu, float)}
    info = {"method": "blade + disk per ND", "blade_dofs": int(blade_dofs.size), "disk_dofs": int(disk_dofs.size),
            "blade_modes": int(blade_modes), "disk_modes": int(disk_modes), "blade_size": blade.size,
            "disk_sizes": {str(k): d.size for k, d in disk.items()},
            "rayleigh": blade.rayleigh is not None,
            "seconds": {"blade": tb["total"], "disk": sum(t["total"] for t in td.values()),
                        "total": time.perf_counter() - t0},
            "bundle": str(bundle.path) if bundle.path is not None else None}
    out = Substructures(blade=blade, disk=disk, n_sectors=N, engine_order=int(engine_order), pairs=pairs, info=info)
    out.validate()
    return out


def _factors(values, n: int, name: str) -> np.ndarray:
    v = np.zeros(n) if values is None else np.asarray(values, float).ravel()
    if v.shape != (n,) or not np.all(np.isfinite(v)) or np.any(v <= -1.0):
        raise ValueError(f"{name}: expected {n} finite deviations > −1 (one per blade), got shape {v.shape}")
    return v


def _disk_physical(sub: Substructures, name: str) -> np.ndarray:
    """The disk's ``name`` (M, K or C) in physical coordinates [contact DOFs of sectors 0…N−1,
    real mode pairs] (module doc): a real symmetric matrix."""
    N = sub.n_sectors
    nb = sub.disk[0].nb
    blocks = np.stack([getattr(sub.nd(k), name)[:nb, :nb] for k in range(N)])
    circ = np.fft.ifft(blocks, axis=0)  # C_d = (1/N) Σ_k e^{2πikd/N} A_k^bb
    if np.abs(circ.imag).max(initial=0.0) > 1e-9 * np.abs(circ).max(initial=1.0):
        raise BundleError(f"mistuned disk: the disk's {name} is not conjugate-symmetric over the NDs")
    s = np.arange(N)
    A_bb = circ.real[(s[:, None] - s[None, :]) % N]            # (N, N, nb, nb): block [s, t] = C_{s−t}
    A_bb = A_bb.transpose(0, 2, 1, 3).reshape(N * nb, N * nb)
    cols, diag = [], []
    for k in range(N // 2 + 1):
        A = getattr(sub.disk[k], name)
        bh, hh = A[:nb, nb:], A[nb:, nb:]
        phase = np.exp(2j * np.pi * k * s / N)[:, None, None]
        col = (phase * bh[None]).reshape(N * nb, -1) / np.sqrt(N)
        if (2 * k) % N == 0:  # ND 0 and N/2: real modes of their own
            cols.append(col.real)
            diag.append(np.real(hh))
        else:
            cols.append(np.hstack([np.sqrt(2) * col.real, -np.sqrt(2) * col.imag]))
            diag.append(np.block([[hh.real, -hh.imag], [hh.imag, hh.real]]))
    from scipy.linalg import block_diag

    bh = np.hstack(cols)
    hh = block_diag(*diag)
    return _sym(np.block([[A_bb, bh], [bh.T, hh]]))


def _disk_static(sub: Substructures) -> np.ndarray:
    """The disk's static load in physical coordinates: every sector's own, plus ND 0's modes
    (a unitary ND-0 coordinate's generalised force is √N × sector 0's)."""
    N = sub.n_sectors
    d0 = sub.disk[0]
    nb = d0.nb
    parts = [np.tile(np.real(d0.f_static[:nb]), N), np.sqrt(N) * np.real(d0.f_static[nb:])]
    for k in range(1, N // 2 + 1):
        parts.append(np.zeros(sub.disk[k].size - nb if (2 * k) % N == 0 else 2 * (sub.disk[k].size - nb)))
    return np.concatenate(parts)


def whole_disk(sub: Substructures, stiffness=None, mass=None) -> ReducedModel:
    """The whole disk, blade s's stiffness × (1 + stiffness[s]) and mass × (1 + mass[s]) (module doc).

    ``stiffness``, ``mass``: (N,) deviations (None: tuned). A mistuned blade's damping is
    ``αM_s + βK_s`` with the tuned blade's Rayleigh coefficients (the same damping law), or the
    tuned blade's C where that is not Rayleigh; its static load scales with its mass (centrifugal).
    """
    N, b = sub.n_sectors, sub.blade
    dk, dm = _factors(stiffness, N, "stiffness mistuning"), _factors(mass, N, "mass mistuning")
    mb, p = b.size, sub.n_pairs
    D = {name: _disk_physical(sub, name) for name in ("M", "K", "C")}
    md = D["M"].shape[0]
    n = N * mb + md
    M, K, C = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
    fs, fh = np.zeros(n), np.zeros(n, complex)
    B = np.zeros((3 * p * N, n))
    O = np.zeros((N * b.O.shape[0], n))
    nb = sub.disk[0].nb
    Bd = sub.disk[0].B[:, :nb]
    for s in range(N):
        q = slice(s * mb, (s + 1) * mb)
        Ms, Ks = (1 + dm[s]) * b.M, (1 + dk[s]) * b.K
        M[q, q], K[q, q] = Ms, Ks
        C[q, q] = b.C if b.rayleigh is None else b.rayleigh[0] * Ms + b.rayleigh[1] * Ks
        fs[q] = (1 + dm[s]) * b.f_static
        fh[q] = b.f_harmonic * np.exp(2j * np.pi * s * sub.engine_order / N)
        r = slice(3 * p * s, 3 * p * (s + 1))
        B[r, q] = b.B
        B[r, N * mb + s * nb: N * mb + (s + 1) * nb] = Bd
        O[s * b.O.shape[0]:(s + 1) * b.O.shape[0], q] = b.O
    d = slice(N * mb, n)
    M[d, d], K[d, d], C[d, d] = D["M"], D["K"], D["C"]
    fs[d] = _disk_static(sub)
    pr = sub.pairs
    pos = np.concatenate([np.asarray(pr["position"]) @ rotation_x(2 * np.pi * s / N).T for s in range(N)])
    info = {"method": "mistuned-whole-disk", "n_sectors": N, "engine_order": sub.engine_order,
            "pairs_per_sector": p, "blade_size": mb, "disk_size": md, "size": n,
            "stiffness_mistuning": dk.tolist(), "mass_mistuning": dm.tolist(),
            "observed_per_sector": int(b.O.shape[0]), **{f"sub_{k}": v for k, v in sub.info.items()
                                                         if k in ("blade_modes", "disk_modes")}}
    return ReducedModel(M=M, K=K, C=C, B=B, f_static=fs, f_harmonic=fh if np.abs(fh.imag).any() else fh.real,
                        O=O, area=np.tile(pr["area"], N), gap=np.tile(pr["gap"], N),
                        flank=np.tile(pr["flank"], N), position=pos,
                        mu=None if pr["mu"] is None else np.tile(pr["mu"], N), info=info)


def cyclic_model(sub: Substructures, nds) -> "CyclicReducedModel":
    """The tuned cyclic model of :mod:`reduction.cyclic_reduce` rebuilt from the substructures:
    ND k's model is the blade beside the disk's ND-k model (sector-0 convention: sector 0's
    loads, unscaled). A tuned :func:`whole_disk` must reproduce its response."""
    from scipy.linalg import block_diag

    from reduction.cyclic_reduce import CyclicReducedModel

    b, N = sub.blade, sub.n_sectors
    nd_eo = sub.engine_order % N
    models = {}
    for k in sorted(set(int(x) for x in nds)):
        d = sub.nd(k)
        z = np.zeros(d.size)
        pr = sub.pairs
        models[k] = ReducedModel(
            M=block_diag(b.M, d.M), K=block_diag(b.K, d.K), C=block_diag(b.C, d.C), B=np.hstack([b.B, d.B]),
            f_static=np.concatenate([b.f_static, d.f_static]) if k == 0 else np.zeros(b.size + d.size),
            f_harmonic=np.concatenate([b.f_harmonic, z]) if k == nd_eo else np.zeros(b.size + d.size),
            O=np.hstack([b.O, np.zeros((b.O.shape[0], d.size))]), area=pr["area"], gap=pr["gap"],
            flank=pr["flank"], position=pr["position"], mu=pr["mu"], info={"nodal_diameter": k})
    return CyclicReducedModel(models=models, engine_order=sub.engine_order, n_sectors=N,
                              info={"method": "blade + disk per ND (substructures)"})


def _add_blade_blocks(M: np.ndarray, blocks) -> np.ndarray:
    """M (N·n, N·n) with ``blocks[s]`` (n, n) added on its diagonal block s (each blade's own
    3p × 3p term, block diagonal over the blades), in place; returns M."""
    n = M.shape[0] // len(blocks)
    for s, B in enumerate(blocks):
        M[s * n:(s + 1) * n, s * n:(s + 1) * n] += B
    return M


class _TiedSolve:
    """``b ↦ A⁻¹ b`` for the tied interface's A = S_b + S_d of one harmonic without forming A:
    GMRES on ``A P⁻¹`` (the true residual), P the tuned disk's A — the blades' mean S_b beside
    the disk, block circulant, so P⁻¹ is one 3p × 3p inverse per nodal diameter between two
    FFTs over the sectors, exact without mistuning. Converged to :data:`RTOL` of ‖b‖ or
    refused for a dense LU of A (made once, then used for every solve)."""

    #: relative residual of the solves (the condensed load F_r and the recoveries take them)
    RTOL = 1e-13
    #: GMRES iterations before the dense LU takes over
    MAXITER = 200

    def __init__(self, Sb, blocks, circulant):
        self.Sb, self.blocks, self._circulant = Sb, blocks, circulant
        self.Pinv = np.linalg.inv(blocks + Sb.mean(axis=0))
        self.N, self.n = Sb.shape[0], Sb.shape[1]
        self._lu = None

    def _ft(self, B, v):
        """The circulant of the per-ND blocks B applied to v (N·n,): FFT, block products, iFFT."""
        V = np.fft.fft(v.reshape(self.N, self.n), axis=0)
        return np.fft.ifft(np.einsum("kab,kb->ka", B, V), axis=0).ravel()

    def apply(self, v):
        """A v for v (N·n,)."""
        return np.einsum("sab,sb->sa", self.Sb, v.reshape(self.N, self.n)).ravel() + self._ft(self.blocks, v)

    def __call__(self, b):
        import scipy.linalg as sla
        import scipy.sparse.linalg as spla

        from workflow.engine.solvers import gmres_rtol

        b = np.asarray(b, dtype=complex)
        nb = float(np.linalg.norm(b))
        if nb == 0.0:
            return np.zeros_like(b)
        if self._lu is None:
            m = b.size
            op = spla.LinearOperator((m, m), matvec=lambda z: self.apply(self._ft(self.Pinv, z)), dtype=complex)
            z, _ = spla.gmres(op, b, restart=self.MAXITER, maxiter=1, atol=0.0, **gmres_rtol(0.1 * self.RTOL))
            x = self._ft(self.Pinv, z)
            if np.all(np.isfinite(x)) and np.linalg.norm(self.apply(x) - b) <= self.RTOL * nb:
                return x
            A = _add_blade_blocks(self._circulant(self.blocks), self.Sb)
            self._lu = sla.lu_factor(A, overwrite_a=True, check_finite=False)
        return sla.lu_solve(self._lu, b, check_finite=False)


class WholeDiskCoordinates:
    """The whole (mistuned) disk condensed onto its relative contact DOFs, substructure by
    substructure: the :func:`workflow.engine.condense.condense` / :func:`~workflow.engine.condense.recover`
    of a :func:`whole_disk` model without forming it (the paper's eq. 3–4 on N × 3p DOFs).

    Per harmonic j (Ω = jω): each blade's dynamic stiffness condensed onto its contact DOFs,
    ``S_b,s`` (its other coordinates are few), and the disk's, ``S_d,k`` per ND k (its modes);
    both in pair frames (``v = R u``, R the contact map's 3×3 blocks; one node per pair a
    side). The disk's physical interface stiffness is block circulant, ``S_d[s, t] = N⁻¹ Σ_k
    e^{ik(s−t)α} S_d,k`` (one FFT); with the tied interface ``A = S_b + S_d`` (block diagonal +
    circulant, regular: the disk is clamped) the relative equations ``Z_r r + λ = F_r`` have

        Z_r = S_b − S_b A⁻¹ S_b,        F_r = g_b − S_b A⁻¹ (g_b + g_d)

    (``v_b = v_d + r``, the blade's contact force eliminated; g the condensed loads), regular at
    Ω = 0 although a blade alone floats. One dense inverse of A (3pN)² a harmonic is the cost
    (harmonic 0 does not depend on ω and is made once); A⁻¹ of the last ω is kept for
    :meth:`recover`. ``n_rel`` = 3pN; ω-derivatives are not provided (grid sweeps and bounded
    peak searches need none). ``form = "compliance"``: harmonics ≥ 1 condense to the compliance
    ``H = Z_r⁻¹ = S_b⁻¹ + S_d⁻¹`` (:meth:`compliance`) instead, with every solve with A iterative
    (:class:`_TiedSolve`), for the engine's harmonic balance in the interface forces.
    """

    is_whole_disk = True
    #: the forms :meth:`condense` gives (``form``)
    FORMS = ("stiffness", "compliance")

    def __init__(self, sub: Substructures, stiffness=None, mass=None, form: str = "stiffness"):
        N, b = sub.n_sectors, sub.blade
        if form not in self.FORMS:
            raise ValueError(f"whole disk: form {form!r} is not one of {', '.join(self.FORMS)}")
        self.sub, self.N, self.form = sub, N, form
        self.dk, self.dm = _factors(stiffness, N, "stiffness mistuning"), _factors(mass, N, "mass mistuning")
        p = sub.n_pairs
        self.n_rel = 3 * p * N
        c = np.flatnonzero(np.abs(b.B).max(axis=0) > 0)
        if c.size != 3 * p:
            raise BundleError(f"mistuned disk: the blade has {c.size} contact DOFs for {p} pairs (one node a pair)")
        self.c, self.w = c, np.setdiff1d(np.arange(b.size), c)
        self.Rb_inv = np.linalg.inv(b.B[:, c])
        nb = sub.disk[0].nb
        if nb != 3 * p:
            raise BundleError(f"mistuned disk: the disk has {nb} contact DOFs for {p} pairs (one node a pair)")
        self.Rd_inv = np.linalg.inv(-sub.disk[0].B[:, :nb])
        self.f_phase = np.exp(2j * np.pi * np.arange(N) * sub.engine_order / N)
        self._zero = None
        self._kept = (None, None)  # (ω, {j: (A⁻¹, S_b blocks, g_b, per-blade w-solves)})
        #: ω [rad/s] → the last observed harmonics recovered there (every blade's: a sweep's
        #: point records the norm over all blades; the study reads each blade's from here)
        self.observed_at: dict = {}

    def in_form(self, form: str) -> "WholeDiskCoordinates":
        """The same disk (substructures, mistuning) condensing in ``form`` (:attr:`FORMS`)."""
        return self if form == self.form else WholeDiskCoordinates(self.sub, self.dk, self.dm, form=form)

    # -- the substructures at one harmonic --------------------------------------------------
    def _blade(self, j: int, omega: float):
        """(S̃_b (N, 3p, 3p), g̃_b (N, 3p), solve data) of every blade at harmonic j."""
        b, W = self.sub.blade, j * omega
        c, w = self.c, self.w
        S, g, aux = [], [], []
        for s in range(self.N):
            K, M = (1 + self.dk[s]) * b.K, (1 + self.dm[s]) * b.M
            C = b.C if b.rayleigh is None else b.rayleigh[0] * M + b.rayleigh[1] * K
            D = K - W * W * M + 1j * W * C
            f = ((1 + self.dm[s]) * b.f_static if j == 0 else
                 b.f_harmonic * self.f_phase[s] if j == 1 else np.zeros(b.size)).astype(complex)
            X = np.linalg.solve(D[np.ix_(w, w)], np.column_stack([D[np.ix_(w, c)], f[w]]))
            Sc = D[np.ix_(c, c)] - D[np.ix_(c, w)] @ X[:, :-1]
            gc = f[c] - D[np.ix_(c, w)] @ X[:, -1]
            S.append(self.Rb_inv.T @ Sc @ self.Rb_inv)
            g.append(self.Rb_inv.T @ gc)
            aux.append(X)
        return np.array(S), np.array(g), aux

    def _disk_blocks(self, j: int, omega: float):
        """(S̃_d,k (N, 3p, 3p) per nodal diameter k in pair frames, g̃_d of ND 0 at harmonic 0 or
        None) of the disk at harmonic j."""
        W, N = j * omega, self.N
        blocks, g0 = [], None
        for k in range(N):
            d = self.sub.nd(k)
            nb = d.nb
            D = d.K - W * W * d.M + 1j * W * d.C
            X = np.linalg.solve(D[nb:, nb:], np.column_stack([D[nb:, :nb], d.f_static[nb:]]))
            Sk = D[:nb, :nb] - D[:nb, nb:] @ X[:, :nb]
            blocks.append(self.Rd_inv.T @ Sk @ self.Rd_inv)
            if k == 0 and j == 0:
                g0 = self.Rd_inv.T @ (d.f_static[:nb] - D[:nb, nb:] @ X[:, nb])
        return np.array(blocks), g0

    def _circulant(self, blocks: np.ndarray) -> np.ndarray:
        """The physical (3pN, 3pN) block-circulant operator of per-ND blocks (N, 3p, 3p):
        block (s, t) = N⁻¹ Σ_k e^{ik(s−t)α} B_k, one FFT over the NDs."""
        N, n = self.N, self.n_rel // self.N
        circ = np.fft.ifft(blocks, axis=0)
        out = np.empty((N * n, N * n), circ.dtype)
        t = np.arange(N)
        for s in range(N):      # block row by block row: no transposed copy of the whole matrix
            out[s * n:(s + 1) * n].reshape(n, N, n)[:] = circ[(s - t) % N].transpose(1, 0, 2)
        return out

    def _disk(self, j: int, omega: float):
        """(S̃_d physical (3pN, 3pN), g̃_d (N, 3p)) of the disk at harmonic j."""
        blocks, g0 = self._disk_blocks(j, omega)
        gd = np.tile(g0, (self.N, 1)) if g0 is not None else np.zeros((self.N, self.n_rel // self.N), complex)
        return self._circulant(blocks), gd

    def compliance(self, omega: float, j: int = 1) -> np.ndarray:
        """The interface compliance ``H = Z_r⁻¹`` (3pN, 3pN) complex [m/N] at harmonic j ≥ 1 and
        ω [rad/s], without an inverse of the whole disk: blade and disk are in series across the
        relative DOFs (``Z_r = S_b (S_b + S_d)⁻¹ S_d``), so ``H = S_b⁻¹ + S_d⁻¹`` — each blade's
        3p × 3p inverse on the diagonal and the disk's per-ND inverses made circulant. Measured on
        the 752-pair disk (two threads, 2026-11-29): 0.10 s a harmonic against 4.6 s for Z_r
        (:meth:`condense`), ``H Z_r`` = I to 8e-11 (``python -m workflow.bench.disk_compliance``).
        Harmonic 0 has none of its own: a blade alone floats (S_b singular)."""
        if j < 1:
            raise ValueError("compliance: harmonic j ≥ 1 (at j = 0 a blade alone floats)")
        Sb, _, _ = self._blade(j, omega)
        blocks, _ = self._disk_blocks(j, omega)
        return self._compliance_of(Sb, blocks)

    def _compliance_of(self, Sb, blocks) -> np.ndarray:
        """H = S_b⁻¹ + S_d⁻¹ (3pN)² from the blades' S_b (N, 3p, 3p) and the disk's per-ND blocks."""
        return _add_blade_blocks(self._circulant(np.linalg.inv(blocks)), np.linalg.inv(Sb))

    def _compliant_harmonic(self, j: int, omega: float):
        """(H_j, F_r,j, kept) of harmonic j ≥ 1 in the compliance form: no inverse of A; F_r and
        every later use of A⁻¹ (:meth:`recover`, the stiffness map) by :class:`_TiedSolve`."""
        Sb, gb, aux = self._blade(j, omega)
        blocks, _ = self._disk_blocks(j, omega)
        solve = _TiedSolve(Sb, blocks, self._circulant)
        N, n = self.N, self.n_rel // self.N
        y = solve(gb.ravel()).reshape(N, n)          # the disk's load is static: g_d = 0 for j ≥ 1
        Fr = gb.ravel() - np.einsum("sab,sb->sa", Sb, y).ravel()
        return self._compliance_of(Sb, blocks), Fr, (solve, Sb, gb, aux)

    def _stiffness_map(self, kept: dict):
        """``(j, U_j) → Z_j U_j`` [N] for the harmonics ``kept`` of the compliance form:
        ``S_b U − S_b A⁻¹ S_b U``, one solve with A (a guess in displacements → its forces)."""
        N, n = self.N, self.n_rel // self.N

        def stiffness(j: int, U):
            solve, Sb = kept[j][0], kept[j][1]
            SU = np.einsum("sab,sb->sa", Sb, np.asarray(U).reshape(N, n))
            return (SU - np.einsum("sab,sb->sa", Sb, solve(SU.ravel()).reshape(N, n))).ravel()
        return stiffness

    def _harmonic(self, j: int, omega: float, out=None):
        """(Z_r, F_r, kept) of harmonic j at ω [rad/s] in the stiffness form: Z_r written into
        ``out`` (3pN, 3pN) complex if given."""
        import scipy.linalg as sla

        Sb, gb, aux = self._blade(j, omega)
        Sd, gd = self._disk(j, omega)
        N, n = self.N, self.n_rel // self.N
        Ainv = sla.inv(_add_blade_blocks(Sd, Sb), overwrite_a=True, check_finite=False)
        # S_b A⁻¹ S_b with S_b block diagonal: one BLAS product per block column, then per block
        # row (0.08 s a harmonic at 752 pairs, against 0.3 s for numpy's stacked 48 × 48 products)
        Zr = np.empty_like(Ainv) if out is None else out
        for t in range(N):
            np.matmul(Ainv[:, t * n:(t + 1) * n], Sb[t], out=Zr[:, t * n:(t + 1) * n])
        for t in range(N):
            Zr[t * n:(t + 1) * n] = Sb[t] @ Zr[t * n:(t + 1) * n]
        Zr = _add_blade_blocks(np.negative(Zr, out=Zr), Sb)
        y = Ainv @ (gb + gd).ravel()
        Fr = gb.ravel() - np.einsum("sab,sb->sa", Sb, y.reshape(N, n)).ravel()
        return Zr, Fr, (Ainv, Sb, gb + gd, aux)

    # -- the condense / recover protocol of workflow.engine.condense ------------------------------
    def condense(self, omega: float, nh: int, derivative: bool = False):
        """Z_r, F_r of harmonics 0…nh at ω [rad/s] (a :class:`workflow.engine.condense.Condensed`)."""
        from workflow.engine.condense import Condensed

        if derivative:
            raise NotImplementedError("the whole disk's condensation has no ω-derivative: use grid sweeps")
        r = self.n_rel
        Zr = np.empty((nh + 1, r, r), complex)
        Fr = np.empty((nh + 1, r), complex)
        kept = {}
        compliance = self.form == "compliance"
        for j in range(nh + 1):
            if j == 0 and self._zero is not None:
                Zr[0], Fr[0], kept[0] = self._zero
                continue
            if compliance and j:
                Zr[j], Fr[j], kept[j] = self._compliant_harmonic(j, omega)
            else:
                _, Fr[j], kept[j] = self._harmonic(j, omega, out=Zr[j])
            if j == 0:
                self._zero = (Zr[0].copy(), Fr[0].copy(), kept[0])
        self._kept = (float(omega), kept)
        if compliance:
            return Condensed(omega=omega, Zr=Zr, Fr=Fr, compliance=True, stiffness=self._stiffness_map(kept))
        return Condensed(omega=omega, Zr=Zr, Fr=Fr)

    def recover(self, omega: float, Ur) -> np.ndarray:
        """Observed harmonics (Nh+1, N·n_obs) [m] of every blade (sector-major, each in its own
        frame) from the relative harmonics ``Ur`` (Nh+1, 3pN)."""
        Ur = np.asarray(Ur)
        om, kept = self._kept
        if om != float(omega) or any(j not in kept for j in range(Ur.shape[0])):
            self.condense(omega, Ur.shape[0] - 1)
            kept = self._kept[1]
        b, N, n = self.sub.blade, self.N, self.n_rel // self.N
        out = np.zeros((Ur.shape[0], N * b.O.shape[0]), complex)
        Oc, Ow = b.O[:, self.c], b.O[:, self.w]
        for j in range(Ur.shape[0]):
            Ainv, Sb, g, aux = kept[j]
            r = Ur[j].reshape(N, n)
            b_d = g.ravel() - np.einsum("sab,sb->sa", Sb, r).ravel()
            vd = (Ainv @ b_d if isinstance(Ainv, np.ndarray) else Ainv(b_d)).reshape(N, n)
            for s in range(N):
                uc = self.Rb_inv @ (vd[s] + r[s])
                X = aux[s]
                w = X[:, -1] - X[:, :-1] @ uc
                out[j, s * b.O.shape[0]:(s + 1) * b.O.shape[0]] = Oc @ uc + Ow @ w
        self.observed_at[float(omega)] = out
        return out

    def tip_map(self, omega: float) -> tuple[np.ndarray, np.ndarray]:
        """(C (N·n_obs, 3pN), d (N·n_obs,)) complex: every blade's observed first harmonic is
        ``o₁ = C r₁ + s d`` [m] for relative first harmonics r₁ [m] and the load scale s — the
        affine map :meth:`recover` applies, formed from the kept A⁻¹ at ω [rad/s] in block
        products instead of 3pN + 1 recoveries. With ``P_s = O_c − O_w X_s`` (blade s's
        interior solve) and ``v_d = A⁻¹ (g − S_b r)``: ``o_s = P_s R_b⁻¹ (v_d,s + r_s) + O_w x_s``."""
        if self.form != "stiffness":
            raise NotImplementedError("whole disk: the tip map reads A⁻¹ of the stiffness form")
        om, kept = self._kept
        if om != float(omega) or 1 not in kept:
            self.condense(omega, 1)
            kept = self._kept[1]
        Ainv, Sb, g, aux = kept[1]
        b, N, n = self.sub.blade, self.N, self.n_rel // self.N
        m = b.O.shape[0]
        Oc, Ow = b.O[:, self.c], b.O[:, self.w]
        # (I − A⁻¹ S_b) with S_b block diagonal: A⁻¹'s column blocks times each blade's S_b
        E = -np.matmul(Ainv.reshape(N * n, N, n).transpose(1, 0, 2), Sb).transpose(1, 0, 2).reshape(N * n, N * n)
        E[np.diag_indices(N * n)] += 1.0
        v0 = (Ainv @ g.ravel()).reshape(N, n)
        C = np.empty((N * m, N * n), complex)
        d = np.empty(N * m, complex)
        for s in range(N):
            Q = (Oc - Ow @ aux[s][:, :-1]) @ self.Rb_inv
            C[s * m:(s + 1) * m] = Q @ E[s * n:(s + 1) * n]
            d[s * m:(s + 1) * m] = Q @ v0[s] + Ow @ aux[s][:, -1]
        return C, d

    def tied_response(self, omega: float) -> np.ndarray:
        """Observed first-harmonic amplitudes (N·n_obs,) [m] with the interface tied (r = 0):
        one solve of ``A v = g`` at ω [rad/s] (:class:`_TiedSolve`: A never formed; the disk's load
        is static, so g = g_b at harmonic 1)."""
        Sb, gb, aux = self._blade(1, omega)
        blocks, _ = self._disk_blocks(1, omega)
        N, n = self.N, self.n_rel // self.N
        v = _TiedSolve(Sb, blocks, self._circulant)(gb.ravel()).reshape(N, n)
        b = self.sub.blade
        m = b.O.shape[0]
        out = np.zeros(N * m, complex)
        for s in range(N):
            uc = self.Rb_inv @ v[s]
            w = aux[s][:, -1] - aux[s][:, :-1] @ uc
            out[s * m:(s + 1) * m] = b.O[:, self.c] @ uc + b.O[:, self.w] @ w
        return out
