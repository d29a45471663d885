"""The model bundle: the folder that separates the FE half from the dynamics.

Anything that writes a bundle (our assembly, or a user's own matrices) can be
reduced and solved; anything the dynamics needs is in it. Layout and meaning
of every array are in ``docs/contracts.md`` §2; this module is the only code
that knows the file names. All quantities are SI (m, kg, s, N).
"""
from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from workflow.errors import BundleError
from workflow.io import atomic_dir

MATRICES = ("M", "K", "C")
CONTACT_KEYS = ("blade_dofs", "disk_dofs", "normal", "t1", "t2", "area", "gap")
LOAD_KEYS = ("fixed", "static", "harmonic", "observe")
OPTIONAL_CONTACT_KEYS = ("flank", "position", "mu", "tie")
#: Largest |A − Aᵀ| accepted, relative to the largest |A| (assembly round-off is ~1e-16).
SYMMETRY_TOL = 1e-8
#: Tied stiffnesses up to this size are checked densely (eigenvalues); larger ones by LDLᵀ inertia.
DENSE_CHECK = 2000


@dataclass
class Contact:
    """Node-to-node contact pairs (p pairs).

    ``blade_dofs``/``disk_dofs``: (p, 3) int DOF indices of the x, y, z
    components; -1 marks a grounded side. ``normal``, ``t1``, ``t2``: (p, 3)
    unit vectors, n from the disk into the blade. ``area``: (p,) tributary
    area [m²]. ``gap``: (p,) initial normal gap [m] (>0 open). ``flank``: (p,)
    0 intrados, 1 extrados. ``position``: (p, 3) pair coordinates [m].
    ``mu``: optional (p,) Coulomb friction coefficient of each pair (absent:
    the scene's ``contact.mu`` applies; see ``ReducedModel.friction``).
    ``tie``: optional (k, 3) int rows ``(dependent DOF, master a, master b)``:
    ``u_dep = (u_a + u_b)/2`` — the midside nodes of a linear contact surface
    (``geometry.contact_nodes = "linear"``); masters are contact DOFs, the
    reduction eliminates the dependent ones (:mod:`reduction.tie`).
    """

    blade_dofs: np.ndarray
    disk_dofs: np.ndarray
    normal: np.ndarray
    t1: np.ndarray
    t2: np.ndarray
    area: np.ndarray
    gap: np.ndarray
    flank: np.ndarray | None = None
    position: np.ndarray | None = None
    mu: np.ndarray | None = None
    tie: np.ndarray | None = None

    @property
    def n_pairs(self) -> int:
        return int(self.blade_dofs.shape[0])

    def frames(self) -> np.ndarray:
        """(p, 3, 3) rotation R with rows (n, t1, t2): u_local = R @ u_global."""
        return np.stack([self.normal, self.t1, self.t2], axis=1)


@dataclass
class Loads:
    """Boundary conditions and loads on the full DOF vector (n DOFs).

    ``fixed``: clamped DOF indices. ``static``: (n,) static force [N]
    (centrifugal plus any applied). ``harmonic``: (n,) amplitude of the
    cos(ωt) excitation [N]. ``observe``: DOF indices reported as the response.
    """

    fixed: np.ndarray
    static: np.ndarray
    harmonic: np.ndarray
    observe: np.ndarray


@dataclass
class Cyclic:
    """The sector's two cyclic faces (optional ``cyclic.npz``; :mod:`reduction.cyclic`).

    ``low_dofs``, ``high_dofs``: (m, 3) x, y, z DOF indices of matched
    nodes, ``high`` the image of ``low`` under the rotation by 2π/N about x.
    ``n_sectors``: N, sectors of the whole disk. A bundle without it is the
    paper's fixed-boundary sector.
    """

    low_dofs: np.ndarray
    high_dofs: np.ndarray
    n_sectors: int


@dataclass
class Bundle:
    """Full-model matrices [SI], contact pairs, loads and provenance."""

    M: sp.csr_matrix
    K: sp.csr_matrix
    C: sp.csr_matrix
    contact: Contact
    loads: Loads
    meta: dict = field(default_factory=dict)
    coords: np.ndarray | None = None  # (n/3, 3) coordinates of each DOF block [m]
    path: Path | None = None
    cyclic: Cyclic | None = None

    @property
    def n_dofs(self) -> int:
        return int(self.M.shape[0])

    @property
    def free_dofs(self) -> np.ndarray:
        """Indices of the DOFs that are not clamped."""
        mask = np.ones(self.n_dofs, dtype=bool)
        mask[self.loads.fixed] = False
        return np.flatnonzero(mask)


def pair_labels(bundle: "Bundle") -> tuple[np.ndarray, np.ndarray]:
    """``(flank, position)`` of every pair, filled in where a bundle lacks them.

    A user's bundle may omit both: flank defaults to 0 and the position to
    the blade node's coordinates (``nodes.npz``), else the origin [m].
    """
    c = bundle.contact
    p = c.n_pairs
    flank = c.flank if c.flank is not None else np.zeros(p, dtype=np.int64)
    if c.position is not None:
        position = c.position
    elif bundle.coords is not None:
        position = bundle.coords[np.maximum(c.blade_dofs[:, 0], 0) // 3]
    else:
        position = np.zeros((p, 3))
    return flank, position


def write_bundle(bundle: Bundle, path: str | Path, extra_files: dict[str, Path] | None = None) -> Path:
    """Validate and write ``bundle`` to the folder ``path`` atomically.

    ``extra_files`` maps a file name in the bundle (e.g. ``mesh.xdmf``) to an
    existing file that is moved in with it.
    """
    validate(bundle)
    path = Path(path)
    with atomic_dir(path) as tmp:
        for name in MATRICES:
            # Uncompressed: zlib on ~10⁶ nonzeros costs seconds and saves little.
            sp.save_npz(tmp / f"{name}.npz", getattr(bundle, name).tocsr(), compressed=False)
        c = bundle.contact
        arrays = {k: getattr(c, k) for k in CONTACT_KEYS}
        for k in OPTIONAL_CONTACT_KEYS:
            if getattr(c, k) is not None:
                arrays[k] = getattr(c, k)
        np.savez(tmp / "contact.npz", **arrays)
        np.savez(tmp / "loads.npz", **{k: getattr(bundle.loads, k) for k in LOAD_KEYS})
        if bundle.coords is not None:
            np.savez(tmp / "nodes.npz", coords=bundle.coords)
        if bundle.cyclic is not None:
            cy = bundle.cyclic
            np.savez(tmp / "cyclic.npz", low_dofs=cy.low_dofs, high_dofs=cy.high_dofs,
                     n_sectors=np.int64(cy.n_sectors))
        (tmp / "meta.json").write_text(json.dumps(bundle.meta, indent=2, default=_jsonable) + "\n")
        for name, src in (extra_files or {}).items():
            Path(src).replace(tmp / name)
    bundle.path = path
    return path


def read_bundle(path: str | Path, matrices: bool = True) -> Bundle:
    """Read and validate the bundle folder ``path``; errors name the file at fault.

    ``matrices=False`` reads everything but M, K, C, which are then empty
    sparse matrices of the right shape (a *skeleton*: contact, loads, coords
    and meta for the ranks of a parallel reduction, which read their own rows
    with :func:`matrix_rows`).
    """
    path = Path(path)
    if not path.is_dir():
        raise BundleError(f"model bundle {path} is not a folder")
    missing = [f for f in ("M.npz", "K.npz", "C.npz", "contact.npz", "loads.npz") if not (path / f).is_file()]
    if missing:
        raise BundleError(f"model bundle {path} lacks {', '.join(missing)}")
    current = path  # the file being read, for the error message
    try:
        mats = {}
        for name in MATRICES:
            current = path / f"{name}.npz"
            mats[name] = sp.load_npz(current).tocsr() if matrices else sp.csr_matrix(tuple(_matrix_shape(current)))
        current = path / "contact.npz"
        with np.load(path / "contact.npz") as z:
            absent = [k for k in CONTACT_KEYS if k not in z]
            if absent:
                raise BundleError(f"model bundle {path}/contact.npz lacks {', '.join(absent)}")
            contact = Contact(**{k: z[k] for k in CONTACT_KEYS},
                              **{k: z[k] if k in z else None for k in OPTIONAL_CONTACT_KEYS})
        current = path / "loads.npz"
        with np.load(path / "loads.npz") as z:
            absent = [k for k in LOAD_KEYS if k not in z]
            if absent:
                raise BundleError(f"model bundle {path}/loads.npz lacks {', '.join(absent)}")
            loads = Loads(**{k: z[k] for k in LOAD_KEYS})
        coords = None
        current = path / "nodes.npz"
        if (path / "nodes.npz").is_file():
            with np.load(path / "nodes.npz") as z:
                coords = z["coords"]
        cyclic = None
        current = path / "cyclic.npz"
        if current.is_file():
            with np.load(current) as z:
                cyclic = Cyclic(low_dofs=z["low_dofs"], high_dofs=z["high_dofs"], n_sectors=int(z["n_sectors"]))
        current = path / "meta.json"
        meta = json.loads((path / "meta.json").read_text()) if (path / "meta.json").is_file() else {}
    except BundleError:
        raise
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        # A truncated or foreign file: name it rather than leak a zipfile error.
        raise BundleError(f"model bundle file {current} cannot be read: {exc}") from exc
    for k in INDEX_KEYS["contact"]:
        if getattr(contact, k) is not None:
            setattr(contact, k, _as_index(getattr(contact, k), f"model bundle {path}/contact.npz '{k}'"))
    for k in INDEX_KEYS["loads"]:
        setattr(loads, k, _as_index(getattr(loads, k), f"model bundle {path}/loads.npz '{k}'"))
    if cyclic is not None:
        for k in INDEX_KEYS["cyclic"]:
            setattr(cyclic, k, _as_index(getattr(cyclic, k), f"model bundle {path}/cyclic.npz '{k}'"))
    bundle = Bundle(**mats, contact=contact, loads=loads, meta=meta, coords=coords, path=path, cyclic=cyclic)
    validate(bundle)
    return bundle


#: Integer arrays of each file (DOF indices, and the flank label): a file may store them as
#: floats holding exact integers, which :func:`read_bundle` converts (:func:`_as_index`).
INDEX_KEYS = {"contact": ("blade_dofs", "disk_dofs", "tie", "flank"), "loads": ("fixed", "observe"),
              "cyclic": ("low_dofs", "high_dofs")}


def _as_index(a, where: str) -> np.ndarray:
    """``a`` as int64; a float array is accepted if every entry is an exact integer
    (MATLAB and many tools write indices as doubles), anything else is a BundleError naming ``where``."""
    a = np.asarray(a)
    if a.dtype.kind in "iu":
        return a.astype(np.int64, copy=False)
    if a.dtype.kind != "f":
        raise BundleError(f"{where} must hold integers, got {a.dtype} values")
    if a.size == 0:
        return a.astype(np.int64)
    bad = ~np.isfinite(a) | (a != np.round(a)) | (np.abs(a) > 2.0 ** 53)
    if np.any(bad):
        i = np.unravel_index(int(np.flatnonzero(bad)[0]), a.shape)
        raise BundleError(f"{where} must hold integers, but entry {tuple(int(v) for v in i)} is {a[i]!r} "
                          f"({int(bad.sum())} such entries)")
    return a.astype(np.int64)


def matrix_rows(path: str | Path, name: str, r0: int, r1: int) -> sp.csr_matrix:
    """Rows ``r0:r1`` of bundle matrix ``name`` (``"M"``, ``"K"``, ``"C"``) as CSR, shape (r1 − r0, n).

    The bundle's matrices are uncompressed CSR npz files (:func:`write_bundle`),
    so only the wanted slice of ``indices``/``data`` is read from disk (memory
    map); a compressed or non-CSR file (a user's bundle) is loaded whole and
    sliced.
    """
    f = Path(path) / f"{name}.npz"
    try:
        with np.load(f) as z:
            fmt, shape = z["format"].item(), tuple(int(v) for v in z["shape"])
        fmt = fmt.decode() if isinstance(fmt, bytes) else str(fmt)
        arrays = {k: _stored_array(f, k) for k in ("indptr", "indices", "data")} if fmt == "csr" else {}
        if fmt != "csr" or any(a is None for a in arrays.values()):
            return sp.load_npz(f).tocsr()[r0:r1]
        indptr = np.asarray(arrays["indptr"][r0:r1 + 1], dtype=np.int64)
        a, b = int(indptr[0]), int(indptr[-1])
        return sp.csr_matrix((np.array(arrays["data"][a:b]), np.array(arrays["indices"][a:b]), indptr - a),
                             shape=(r1 - r0, shape[1]))
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise BundleError(f"model bundle matrix {f} cannot be read: {exc}") from exc


def _matrix_shape(f: Path) -> tuple[int, int]:
    with np.load(f) as z:
        return tuple(int(v) for v in z["shape"])


def _stored_array(f: Path, key: str):
    """A read-only memory map of array ``key`` stored uncompressed in the npz ``f`` (None if compressed)."""
    import struct

    with zipfile.ZipFile(f) as zf:
        info = zf.getinfo(f"{key}.npy")
    if info.compress_type != zipfile.ZIP_STORED:
        return None
    with open(f, "rb") as fh:
        fh.seek(info.header_offset)
        head = fh.read(30)
        name_len, extra_len = struct.unpack("<HH", head[26:30])
        fh.seek(info.header_offset + 30 + name_len + extra_len)
        version = np.lib.format.read_magic(fh)
        reader = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, fortran, dtype = reader(fh)
        offset = fh.tell()
    if not shape or 0 in shape:
        return np.zeros(shape, dtype=dtype)
    return np.memmap(f, dtype=dtype, mode="r", shape=shape, offset=offset, order="F" if fortran else "C")


def _check_tie(c: Contact, n: int, fixed, at: str) -> None:
    """``contact.tie``: (k, 3) DOFs in range; masters are contact DOFs; a dependent DOF is
    no contact DOF, no master, not clamped and tied once."""
    t = np.asarray(c.tie)
    if t.ndim != 2 or t.shape[1] != 3 or t.dtype.kind not in "iu":
        raise BundleError(f"{at}contact.npz: tie must be (k, 3) integer DOF rows, got shape {t.shape}")
    if t.size and (t.min() < 0 or t.max() >= n):
        raise BundleError(f"{at}contact.npz: tie indexes outside 0..{n - 1}")
    contact = np.concatenate([c.blade_dofs.ravel(), c.disk_dofs.ravel()])
    dep = t[:, 0]
    u, counts = np.unique(dep, return_counts=True)
    bad = (np.isin(dep, contact) | np.isin(dep, t[:, 1:]) | np.isin(dep, np.asarray(fixed))
           | np.isin(dep, u[counts > 1]))
    if np.any(bad):
        raise BundleError(f"{at}contact.npz: tie row {int(np.flatnonzero(bad)[0])} has a dependent DOF that is "
                          "a contact DOF, a master, clamped or tied twice")
    if not np.all(np.isin(t[:, 1:], contact)):
        raise BundleError(f"{at}contact.npz: a tie master is not a contact DOF (blade_dofs / disk_dofs)")


def validate(b: Bundle) -> None:
    """Raise :class:`BundleError` naming the first inconsistent array.

    Shapes, integer index arrays (:data:`INDEX_KEYS`; :func:`read_bundle`
    converts floats holding exact integers, an in-memory bundle must hold
    integers), index ranges, finiteness, symmetry of M, K, C (to
    :data:`SYMMETRY_TOL`), a positive mass diagonal on every free DOF,
    orthonormal frames, every contact DOF in one pair only (a repeated pair
    or a DOF shared by two pairs makes the contact map rank deficient),
    distinct blade and disk DOFs in each pair, ``flank`` 0 or 1, and an
    optional per-pair ``mu`` (finite, ≥ 0). Positive definiteness is
    :func:`check_definite` (costlier: a factorisation).
    """
    n = b.M.shape[0]
    at = f"model bundle {b.path}: " if b.path is not None else ""
    for name in MATRICES:
        m = getattr(b, name)
        if m.shape != (n, n):
            raise BundleError(f"{at}bundle matrix {name} is {m.shape[0]}x{m.shape[1]}, expected {n}x{n}")
        if not np.all(np.isfinite(m.data)):
            raise BundleError(f"{at}bundle matrix {name} ({name}.npz) has non-finite entries")
        _check_symmetric(m, f"{at}{name}.npz")
    c = b.contact
    for file, obj in (("contact", c), ("loads", b.loads), ("cyclic", b.cyclic)):
        for k in INDEX_KEYS[file] if obj is not None else ():
            a = getattr(obj, k)
            if a is not None and np.asarray(a).dtype.kind not in "iu":
                raise BundleError(f"{at}{file}.npz: '{k}' must hold integers, got {np.asarray(a).dtype} values")
    p = c.blade_dofs.shape[0]
    for k in ("blade_dofs", "disk_dofs", "normal", "t1", "t2"):
        if np.shape(getattr(c, k)) != (p, 3):
            raise BundleError(f"bundle contact.{k} has shape {np.shape(getattr(c, k))}, expected ({p}, 3)")
    for k in ("area", "gap"):
        if np.shape(getattr(c, k)) != (p,):
            raise BundleError(f"bundle contact.{k} has shape {np.shape(getattr(c, k))}, expected ({p},)")
    for k in ("blade_dofs", "disk_dofs"):
        d = getattr(c, k)
        if d.size and (d.max() >= n or d.min() < -1):
            raise BundleError(f"bundle contact.{k} indexes outside 0..{n - 1} (or -1 for grounded)")
    if np.any((c.blade_dofs < 0) & (c.disk_dofs < 0)):
        raise BundleError("bundle contact pair grounded on both sides (blade_dofs and disk_dofs both -1)")
    same = np.flatnonzero(np.any((c.blade_dofs == c.disk_dofs) & (c.blade_dofs >= 0), axis=1))
    if same.size:
        raise BundleError(f"{at}contact.npz: pair {same[0]} has the same DOF in blade_dofs and disk_dofs "
                          f"({same.size} such pairs): a pair joins two different nodes")
    _check_unique_dofs(c, at)
    if c.flank is not None:
        flank = np.asarray(c.flank)
        if flank.shape != (p,) or not np.all((flank == 0) | (flank == 1)):
            bad = flank[(flank != 0) & (flank != 1)] if flank.shape == (p,) else flank
            raise BundleError(f"{at}contact.npz: 'flank' must be ({p},) labels 0 (intrados) or 1 (extrados), got "
                              f"shape {flank.shape}" + (f", values {np.unique(bad)[:5].tolist()}" if bad.size else ""))
    if c.mu is not None:
        mu = np.asarray(c.mu)
        if mu.shape != (p,) or mu.dtype.kind not in "fiu" or not np.all(np.isfinite(mu)) or np.any(mu < 0):
            raise BundleError(f"{at}contact.npz: mu must be ({p},) finite friction coefficients ≥ 0, got "
                              f"shape {mu.shape}" + (f", min {mu.min():.3g}" if mu.size and mu.dtype.kind in "fiu" else ""))
    if c.tie is not None:
        _check_tie(c, n, b.loads.fixed, at)
    if p and not np.allclose(np.einsum("pij,pkj->pik", c.frames(), c.frames()), np.eye(3), atol=1e-8):
        raise BundleError("bundle contact frames (normal, t1, t2) are not orthonormal")
    if np.any(c.area <= 0) or not np.all(np.isfinite(c.area)):
        raise BundleError("bundle contact.area must be positive and finite")
    L = b.loads
    for k in ("static", "harmonic"):
        if np.shape(getattr(L, k)) != (n,):
            raise BundleError(f"bundle loads.{k} has shape {np.shape(getattr(L, k))}, expected ({n},)")
    for k in ("fixed", "observe"):
        d = np.asarray(getattr(L, k))
        if d.ndim != 1:
            raise BundleError(f"{at}loads.npz: '{k}' must be a 1-D array of DOF indices, got shape {d.shape}")
        if d.size and (d.min() < 0 or d.max() >= n):
            raise BundleError(f"bundle loads.{k} indexes outside 0..{n - 1}")
    _check_mass_diagonal(b, at)
    if b.coords is not None and b.coords.shape != (n // 3, 3):
        raise BundleError(f"bundle nodes.coords has shape {b.coords.shape}, expected ({n // 3}, 3)")
    if b.cyclic is not None:
        _check_cyclic(b.cyclic, n, at)


def _check_unique_dofs(c: Contact, at: str) -> None:
    """Every DOF in one pair, once: node-to-node contact. A repeated pair (or a DOF in two
    pairs, or twice in one) gives the relative-displacement map equal rows — rank deficient."""
    rows = np.concatenate([c.blade_dofs, c.disk_dofs], axis=1)   # (p, 6), −1 = grounded
    if rows.shape[0] == 0:
        return
    _, first, inverse = np.unique(rows, axis=0, return_index=True, return_inverse=True)
    again = np.flatnonzero(first[inverse.ravel()] != np.arange(rows.shape[0]))
    if again.size:
        k = int(again[0])
        raise BundleError(f"{at}contact.npz: pair {k} repeats pair {int(first[inverse.ravel()[k]])} (same "
                          f"blade_dofs and disk_dofs; {again.size} repeated pair(s)): each pair must be listed once")
    for side in ("blade_dofs", "disk_dofs"):
        d = getattr(c, side)
        bad = np.flatnonzero(np.any((d[:, :, None] == d[:, None, :]) & (d[:, :, None] >= 0)
                                    & ~np.eye(3, dtype=bool), axis=(1, 2)))
        if bad.size:
            raise BundleError(f"{at}contact.npz: pair {int(bad[0])} repeats a DOF within its {side} row "
                              f"{d[bad[0]].tolist()}: the x, y, z DOFs of a node must be distinct")
    dofs = rows.ravel()
    live = dofs >= 0
    u, idx, counts = np.unique(dofs[live], return_index=True, return_counts=True)
    if np.any(counts > 1):
        dof = int(u[counts > 1][0])
        pairs = sorted({int(i) // 6 for i in np.flatnonzero(dofs == dof)})
        sides = sorted({("blade_dofs", "disk_dofs")[(int(i) % 6) // 3] for i in np.flatnonzero(dofs == dof)})
        raise BundleError(f"{at}contact.npz: DOF {dof} is in {' and '.join(sides)} of pairs "
                          f"{', '.join(map(str, pairs))} ({int(np.sum(counts > 1))} such DOFs): node-to-node contact "
                          "puts each node in one pair (else the contact map is rank deficient)")


def _check_mass_diagonal(b: Bundle, at: str, skeleton_ok: bool = True) -> None:
    """M.npz: a positive mass on every free DOF (its diagonal; a zero or negative one would
    surface later as a Lanczos stall or an indefinite K). ``skeleton_ok``: an M without
    entries is a skeleton (``read_bundle(matrices=False)``) and passes."""
    if skeleton_ok and b.M.nnz == 0:
        return
    d = np.asarray(b.M.diagonal())
    free = np.ones(d.size, dtype=bool)
    free[np.asarray(b.loads.fixed, dtype=np.int64)] = False
    bad = np.flatnonzero(free & ~(d > 0))
    if bad.size:
        shown = ", ".join(f"DOF {int(i)}: {d[i]:.3g}" for i in bad[:5])
        raise BundleError(f"{at}M.npz: the mass matrix has a zero or negative diagonal entry on {bad.size} free "
                          f"DOF(s) ({shown}{', …' if bad.size > 5 else ''}); every DOF not clamped in loads.npz "
                          "'fixed' needs a positive mass (a sign error, or a massless DOF?)")


def _check_cyclic(cy: Cyclic, n: int, at: str) -> None:
    lo, hi = np.asarray(cy.low_dofs), np.asarray(cy.high_dofs)
    if lo.ndim != 2 or lo.shape[1:] != (3,) or hi.shape != lo.shape:
        raise BundleError(f"{at}cyclic.npz: low_dofs and high_dofs must both be (m, 3), got {lo.shape}, {hi.shape}")
    if lo.size and (min(lo.min(), hi.min()) < 0 or max(lo.max(), hi.max()) >= n):
        raise BundleError(f"{at}cyclic.npz: DOF indices outside 0..{n - 1}")
    if np.intersect1d(lo, hi).size:
        raise BundleError(f"{at}cyclic.npz: a DOF is on both cyclic faces")
    if not int(cy.n_sectors) >= 2:
        raise BundleError(f"{at}cyclic.npz: n_sectors must be ≥ 2, got {cy.n_sectors}")


def _check_symmetric(A: sp.spmatrix, where: str) -> None:
    if A.nnz == 0:
        return
    A = sp.csr_matrix(A)
    scale = float(np.abs(A.data).max())
    asym = float(np.abs((A - A.T).data).max(initial=0.0))
    if asym > SYMMETRY_TOL * scale:
        raise BundleError(f"{where} is not symmetric: max |A − Aᵀ| = {asym:.3g}, {asym / scale:.1e} of its "
                          f"largest entry (tolerance {SYMMETRY_TOL:g}); the reduction and the harmonic balance "
                          "need symmetric M, K, C")


def tied_map(b: Bundle) -> sp.csr_matrix:
    """(n, m) map from the DOFs of the *tied* structure to the bundle's DOFs.

    Each contact pair's blade and disk DOFs become one DOF (a grounded side,
    −1, holds the other one), and clamped DOFs (``loads.fixed``) are
    removed: ``Tᵀ K T`` is the stiffness of the structure with its
    interface stuck, which must be positive definite for any static state.
    """
    from scipy.sparse.csgraph import connected_components

    n = b.n_dofs
    c = b.contact
    bd, dd = c.blade_dofs.ravel(), c.disk_dofs.ravel()
    both = (bd >= 0) & (dd >= 0)
    graph = sp.coo_matrix((np.ones(int(both.sum())), (bd[both], dd[both])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    held = np.zeros(n, dtype=bool)
    held[np.asarray(b.loads.fixed, dtype=np.int64)] = True
    held[bd[(bd >= 0) & (dd < 0)]] = True
    held[dd[(dd >= 0) & (bd < 0)]] = True
    held_label = np.zeros(label.max(initial=-1) + 1, dtype=bool)
    np.logical_or.at(held_label, label, held)
    live = np.flatnonzero(~held_label)
    cols = -np.ones(held_label.size, dtype=np.int64)
    cols[live] = np.arange(live.size)
    rows = np.flatnonzero(~held_label[label])
    return sp.csr_matrix((np.ones(rows.size), (rows, cols[label[rows]])), shape=(n, live.size))


def check_definite(b: Bundle) -> dict:
    """Raise :class:`BundleError` (naming ``K.npz`` and ``loads.npz``) unless the
    tied, clamped stiffness ``Tᵀ K T`` (:func:`tied_map`) is positive definite.

    Up to :data:`DENSE_CHECK` DOFs: its eigenvalues (negative ones, and zero
    ones: below 1e-12 of the largest); beyond: the inertia of a MUMPS LDLᵀ
    factorisation (negative and null pivots). Returns ``{"tied_dofs",
    "method", "min_ratio"}`` (smallest / largest eigenvalue, dense only).
    First the mass (:func:`check_mass`), so that a bad M is not blamed on K.
    """
    check_mass(b)
    T = tied_map(b)
    Kt = sp.csr_matrix(T.T @ b.K @ T)
    m = Kt.shape[0]
    where = f"model bundle {b.path}" if b.path is not None else "model bundle"
    if m == 0:
        return {"tied_dofs": 0, "method": "none", "min_ratio": None}
    if Kt.nnz == 0:
        neg, zero, info = 0, m, {}
    elif m <= DENSE_CHECK:
        w = np.linalg.eigvalsh(Kt.toarray())
        top = float(np.abs(w).max())
        neg = int(np.sum(w < -1e-12 * top))
        zero = int(np.sum(np.abs(w) <= 1e-12 * top))
        info = {"tied_dofs": m, "method": "eigenvalues", "min_ratio": float(w[0] / top)}
    else:
        neg, zero = _ldlt_inertia(Kt)
        info = {"tied_dofs": m, "method": "ldlt-inertia", "min_ratio": None}
        if neg or zero:
            # Rigid-body modes show up as tiny pivots of either sign: one message for both causes.
            raise BundleError(f"{where}: the stiffness (K.npz) with the contact tied and loads.fixed clamped "
                              f"is not positive definite: its LDLᵀ factorisation has {neg} negative and {zero} "
                              f"null pivot(s) of {m} — the structure floats (clamp DOFs in loads.npz 'fixed') "
                              "or K is indefinite (a dynamic stiffness K − ω²M, or a sign error?)")
    if neg:
        raise BundleError(f"{where}/K.npz: the stiffness with the contact tied and loads.fixed clamped has {neg} "
                          f"negative eigenvalue(s) of {m}: K is not positive definite (a dynamic stiffness "
                          "K − ω²M, or a sign error?)")
    if zero:
        raise BundleError(f"{where}: the stiffness with the contact tied and loads.fixed clamped is singular "
                          f"({zero} zero eigenvalue(s) of {m}): the structure floats — clamp DOFs in "
                          "loads.npz 'fixed' (or ground a contact side with -1), or check K.npz")
    return info


def check_mass(b: Bundle) -> None:
    """Raise :class:`BundleError` naming ``M.npz`` unless the mass on the free DOFs (not in
    loads.npz 'fixed') has a positive diagonal and is positive semi-definite: no negative
    eigenvalue below −1e-12 of the largest (up to :data:`DENSE_CHECK` free DOFs), or no
    negative pivot of a MUMPS LDLᵀ factorisation (beyond)."""
    at = f"model bundle {b.path}: " if b.path is not None else ""
    _check_mass_diagonal(b, at, skeleton_ok=False)
    free = b.free_dofs
    Mf = sp.csr_matrix(b.M[free][:, free])
    if Mf.shape[0] == 0:
        return
    if Mf.shape[0] <= DENSE_CHECK:
        w, v = np.linalg.eigh(Mf.toarray())
        top = float(np.abs(w).max())
        neg = int(np.sum(w < -1e-12 * top))
        where = f" (the most negative, {w[0]:.3g}, is largest on DOF {int(free[np.argmax(np.abs(v[:, 0]))])})"
    else:
        neg, _ = _ldlt_inertia(Mf)
        where = ""
    if neg:
        raise BundleError(f"{at}M.npz: the mass matrix on the free DOFs is not positive semi-definite: {neg} "
                          f"negative eigenvalue(s) or pivot(s) of {Mf.shape[0]}{where} — a sign error, or "
                          "off-diagonal masses larger than the diagonal?")


def _ldlt_inertia(A: sp.csr_matrix) -> tuple[int, int]:
    """(negative pivots, null pivots) of a MUMPS LDLᵀ factorisation of symmetric ``A``."""
    from petsc4py import PETSc

    from reduction.eigen import to_petsc

    P = to_petsc(A)
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    try:
        ksp.setOperators(P)
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType("cholesky")
        pc.setFactorSolverType("mumps")
        pc.setFactorSetUpSolverType()
        F = pc.getFactorMatrix()
        F.setMumpsIcntl(24, 1)  # null-pivot detection: INFOG(28)
        try:
            ksp.setUp()
        except PETSc.Error:
            return 0, 1
        if F.getMumpsInfog(1) < 0:
            return 0, 1
        return int(F.getMumpsInfog(12)), int(F.getMumpsInfog(28))
    finally:
        ksp.destroy()
        P.destroy()


def _jsonable(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return str(obj)
