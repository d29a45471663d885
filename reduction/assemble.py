"""FE assembly of the sector into the model bundle (contracts §2).

Pipeline of :func:`assemble_bundle`::

    .msh ─read─► mesh + tags ─► M, K₀, f_c ─► pairs, clamp ─► u₀ (tied, clamped)
         ─► K_σ(σ₀), M_⊥ ─► K(Ω) ─► tied modes ─► C ─► bundle folder

P2 vector Lagrange, isotropic linear elasticity, SI units. Forms are in
:mod:`reduction.elasticity`, pairs in :mod:`reduction.pairs`, the static
prestress in :mod:`reduction.prestress`; every dolfinx call goes through
:mod:`reduction.dolfinx_compat`. Assembly is distributed (dolfinx as usual);
the scipy matrices live on rank 0, where the bundle is written; other ranks
get ``None``.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp

from reduction import dolfinx_compat as dc
from reduction import elasticity as el
from reduction.bundle import Bundle, Contact, Cyclic, Loads, write_bundle
from reduction.pairs import bundle_keys, contact_pairs, layout_of
from reduction.prestress import static_displacement, tie_map
from workflow.errors import BundleError, GeometryError, SceneError

#: Physical-group tags of contracts §1; the cyclic faces of geometry/cyclic.py.
CLAMP, TIP = 31, 41
CYCLIC_LOW, CYCLIC_HIGH = 51, 52
DEGREE = 2


def rpm_to_rad_s(rpm: float) -> float:
    return float(rpm) * 2.0 * math.pi / 60.0


def _get(obj, key, default=None):
    """Attribute or dict key (scene dataclasses and plain dicts both work)."""
    if obj is None:
        return default
    if isinstance(obj, dict):
        return obj.get(key, default)
    return getattr(obj, key, default)


@dataclass
class Operators:
    """Matrices and loads on rank 0 (global DOF numbering; ``None`` on other ranks).

    ``M``, ``K0``, ``K_sigma``, ``M_perp`` [kg, N/m]; ``f_static`` [N];
    ``u0`` the tied static displacement [m]; ``K`` = K₀ + K_σ − Ω² M_⊥ with
    the terms switched by the flags used.
    """

    M: sp.csr_matrix | None
    K0: sp.csr_matrix | None
    K: sp.csr_matrix | None
    K_sigma: sp.csr_matrix | None = None
    M_perp: sp.csr_matrix | None = None
    f_static: np.ndarray | None = None
    u0: np.ndarray | None = None
    prestress_change: list = field(default_factory=list)  # ‖Δu₀‖/‖u₀‖ per prestress iteration
    timings: dict = field(default_factory=dict)


# -------------------------------------------------------------- small pieces

def elastic_matrices(V, material, dx):
    """(M, K₀) as global scipy CSR on rank 0 (no BCs)."""
    E, nu, rho = _material(material)
    return dc.assemble_matrix_scipy(el.mass(V, rho, dx)), dc.assemble_matrix_scipy(el.stiffness(V, E, nu, dx))


def static_load(V, material, omega: float, dx, ds, static_force: float = 0.0, tip_area: float | None = None):
    """Static load vector [N] on rank 0: centrifugal ρΩ²r_⊥ + static_force along +z on the tip (group 41).

    The tip force is a uniform traction ``static_force / tip_area`` so it sums to ``static_force``.
    """
    _, _, rho = _material(material)
    f = dc.assemble_vector_numpy(el.centrifugal_load(V, dc.constant(V.mesh, rho * omega ** 2), dx))
    if static_force:
        if not tip_area:
            raise GeometryError(f"excitation.static_force = {static_force} N needs a blade_tip facet group "
                                f"(tag {TIP}) in the mesh")
        g = dc.assemble_vector_numpy(el.traction_load(V, dc.constant(V.mesh, [0.0, 0.0, static_force / tip_area]), ds(TIP)))
        f = None if f is None else f + g
    return f


def clamped_dofs(V, facet_tags, tag: int = CLAMP) -> np.ndarray | None:
    """All DOFs (x, y, z) of the blocks on the facets tagged ``tag`` (rank 0)."""
    g = dc.gather_owned_blocks(V, dc.blocks_on_facets(V, facet_tags, tag))
    if g is None:
        return None
    bs = dc.block_size(V)
    return np.sort((bs * g[0][:, None] + np.arange(bs)).ravel())


def cyclic_faces(V, facet_tags, geometry_info: dict, coords: np.ndarray | None) -> Cyclic | None:
    """The matched cyclic faces (rank 0; None elsewhere or for a non-cyclic sector). Collective.

    Cyclic when ``geometry_info["params"]["cyclic"]`` is true; the mesh must
    then carry both facet groups 51/52 (:class:`GeometryError` otherwise).
    """
    from reduction.cyclic import face_dofs

    params = geometry_info.get("params", {}) if isinstance(geometry_info, dict) else {}
    if not params.get("cyclic", False):
        return None
    present = dc.tag_values(facet_tags)
    if CYCLIC_LOW not in present or CYCLIC_HIGH not in present:
        raise GeometryError(f"geometry.cyclic = true but the mesh lacks the cyclic facet groups "
                            f"{CYCLIC_LOW}/{CYCLIC_HIGH} (cyclic_low/cyclic_high): re-run the geometry stage")
    lo = dc.gather_owned_blocks(V, dc.blocks_on_facets(V, facet_tags, CYCLIC_LOW))
    hi = dc.gather_owned_blocks(V, dc.blocks_on_facets(V, facet_tags, CYCLIC_HIGH))
    if lo is None:
        return None
    n_sectors = int(params["n_sectors"])
    low, high = face_dofs(lo[0], hi[0], coords, n_sectors, dc.block_size(V))
    return Cyclic(low_dofs=low, high_dofs=high, n_sectors=n_sectors)


def nearest_block(coords: np.ndarray, point) -> int:
    """Index of the DOF block closest to ``point`` [m]."""
    return int(np.argmin(np.linalg.norm(coords - np.asarray(point, dtype=float), axis=1)))


def point_load(n_dofs: int, block: int, amplitude: float, direction, bs: int = 3) -> np.ndarray:
    """Force vector [N] with ``amplitude`` × unit ``direction`` on one DOF block."""
    d = np.asarray(direction, dtype=float)
    if d.shape != (bs,) or not np.linalg.norm(d):
        raise GeometryError(f"excitation_direction {direction!r} must be a non-zero {bs}-vector")
    f = np.zeros(n_dofs)
    f[bs * block: bs * block + bs] = amplitude * d / np.linalg.norm(d)
    return f


def _material(material):
    E, nu, rho = (_get(material, k) for k in ("young", "poisson", "density"))
    if E is None or nu is None or rho is None:
        raise SceneError("material needs young, poisson and density")
    return float(E), float(nu), float(rho)


def _facet_area(mesh, ds, tag) -> float:
    """Area [m²] of the facets tagged ``tag``."""
    return dc.assemble_scalar(dc.constant(mesh, 1.0) * ds(tag))


# ----------------------------------------------------------------- operators

def assemble_operators(mesh, cell_tags, facet_tags, material, omega: float = 0.0, *, stress_stiffening=True,
                       spin_softening=True, static_force: float = 0.0, fixed=None, blade_dofs=None,
                       disk_dofs=None, tie=None, V=None, prestress_iterations: int = 0,
                       cyclic: Cyclic | None = None) -> tuple[Operators, object]:
    """M, K(Ω) and the static load of the mesh; returns ``(Operators, V)``.

    ``omega`` [rad/s] about x. ``fixed`` (clamped DOFs) and the pair DOFs
    (p×3) define the tied prestress problem; they are only needed when there
    is a static load and ``stress_stiffening`` is on (``fixed=None`` → the
    facets tagged 31). Flags switch K_σ and −Ω²M_⊥ independently.
    ``prestress_iterations`` > 0 re-solves the static state with K_σ of the
    previous one (stress-stiffened static solve, fixed point); 0 = linear.
    ``cyclic`` (rank 0): the sector's matched cyclic faces; the prestress is
    then solved under the ND-0 constraint ``u_high = R u_low`` as well (the
    whole tuned disk spinning: the rim carries its hoop stress).
    """
    t = {}
    V = V or dc.vector_space(mesh, DEGREE)
    dx, ds = dc.measures(mesh, cell_tags, facet_tags)
    E, nu, rho = _material(material)
    t0 = time.perf_counter()
    M, K0 = elastic_matrices(V, material, dx)
    tip_area = _facet_area(mesh, ds, TIP) if static_force else None
    f = static_load(V, material, omega, dx, ds, static_force, tip_area)
    t["assembly_s"] = time.perf_counter() - t0
    root = mesh.comm.rank == dc.ROOT
    ops = Operators(M=M, K0=K0, K=None, f_static=f, timings=t)
    t0 = time.perf_counter()
    if spin_softening and omega:
        ops.M_perp = dc.assemble_matrix_scipy(el.spin_mass(V, rho, dx))
    Kstat = None
    if root:
        Kstat = K0 - omega ** 2 * ops.M_perp if ops.M_perp is not None else K0
    has_load = mesh.comm.bcast(bool(root and np.any(f)), root=dc.ROOT)
    if stress_stiffening and has_load:
        if mesh.comm.bcast(fixed is None, root=dc.ROOT):  # collective: decided on rank 0 for all
            fixed = clamped_dofs(V, facet_tags)
        T = None
        no_clamp = bool(root and (fixed is None or len(fixed) == 0))
        if mesh.comm.bcast(no_clamp, root=dc.ROOT):
            raise GeometryError(f"the prestress needs a clamp: no facets tagged {CLAMP} (disk_clamp)")
        if root:
            n = K0.shape[0]
            bd = np.zeros((0, 3), np.int64) if blade_dofs is None else blade_dofs
            dd = np.zeros((0, 3), np.int64) if disk_dofs is None else disk_dofs
            T = tie_map(n, fixed, bd, dd, tied=True, tie=tie)
            if cyclic is not None:
                from reduction.cyclic import constrain_map

                T = constrain_map(T, cyclic.low_dofs, cyclic.high_dofs, cyclic.n_sectors, nd=0)
        # Spin softening belongs in the static operator too: equilibrium in the rotating frame.
        # Collective: the factorisation runs on every rank (parallel MUMPS).
        ops.u0 = static_displacement(Kstat, f, T, comm=mesh.comm)
        u0 = dc.function(V, "u0")
        a_sigma = dc.form(el.geometric_stiffness(V, el.stress(u0, E, nu), dx))
        for it in range(int(prestress_iterations) + 1):
            dc.set_function_from_global(u0, ops.u0)
            ops.K_sigma = dc.assemble_matrix_scipy(a_sigma)
            if it < prestress_iterations:
                # Picard step on (K₀ − Ω²M_⊥ + K_σ(u₀)) u₀ = f: the tension straightens a blade that
                # the linear prestress bends too far (a lateral centrifugal component on a lean).
                u_new = static_displacement(Kstat + ops.K_sigma if root else None, f, T, comm=mesh.comm)
                if root:
                    ops.prestress_change.append(float(np.linalg.norm(u_new - ops.u0) / np.linalg.norm(u_new)))
                    ops.u0 = u_new
    t["prestress_s"] = time.perf_counter() - t0
    if root:
        K = Kstat.copy()
        if ops.K_sigma is not None:
            K = K + ops.K_sigma
        ops.K = K.tocsr()
        ops.K.eliminate_zeros()
    return ops, V


# -------------------------------------------------------------------- bundle

def rayleigh(M: sp.spmatrix, K: sp.spmatrix, alpha: float, beta: float) -> sp.csr_matrix:
    """C = αM + βK [N·s/m]; α [1/s], β [s]."""
    return (alpha * M + beta * K).tocsr()


def modal_beta(ratio: float, omega1: float) -> float:
    """β [s] giving damping ratio ``ratio`` at ω₁ [rad/s] (stiffness-proportional: ζ = βω/2)."""
    return 2.0 * ratio / omega1 if ratio > 0 else 0.0


def build_bundle(mesh, cell_tags, facet_tags, geometry_info: dict, material, rotation=None, damping=None,
                 excitation=None, pairs: dict | None = None) -> tuple[Bundle | None, dict]:
    """Assemble everything into an in-memory :class:`Bundle` (rank 0; ``None`` elsewhere).

    ``pairs``: contact arrays as returned by
    :func:`reduction.pairs.contact_pairs` (on rank 0) to use instead of
    matching the flank nodes of ``mesh`` — e.g. the unworn pairs of a worn
    mesh, whose flank nodes no longer coincide. Without it the pairs follow
    the layout ``geometry_info["params"]["contact_nodes"]`` (default
    "vertices"; :mod:`reduction.pairs`). Returns ``(bundle, info)``
    with ``info`` the summary (timings, mass…).
    """
    t = {}
    comm = mesh.comm
    root = comm.rank == dc.ROOT
    omega = rpm_to_rad_s(_get(rotation, "speed_rpm", 0.0))
    for key in ("tip_point", "excitation_direction"):
        if key not in geometry_info:
            raise GeometryError(f"geometry info lacks {key!r} (needed for the harmonic load)")
    V = dc.vector_space(mesh, DEGREE)
    bs = dc.block_size(V)
    t0 = time.perf_counter()
    if comm.bcast(pairs is None, root=dc.ROOT):
        pairs = contact_pairs(V, facet_tags, nodes=layout_of(geometry_info))
    fixed = clamped_dofs(V, facet_tags)
    coords = dc.gather_block_coordinates(V)
    cyclic = cyclic_faces(V, facet_tags, geometry_info, coords)
    t["pairs_s"] = time.perf_counter() - t0
    ops, _ = assemble_operators(
        mesh, cell_tags, facet_tags, material, omega,
        stress_stiffening=bool(_get(rotation, "stress_stiffening", True)),
        spin_softening=bool(_get(rotation, "spin_softening", True)),
        static_force=float(_get(excitation, "static_force", 0.0)), fixed=fixed,
        prestress_iterations=int(_get(rotation, "prestress_iterations", 0)),
        blade_dofs=pairs["blade_dofs"] if root else None, disk_dofs=pairs["disk_dofs"] if root else None,
        tie=pairs.get("tie") if root else None, V=V,
        cyclic=cyclic)
    t.update(ops.timings)
    bundle = None
    if root:
        n = ops.M.shape[0]
        tip = nearest_block(coords, geometry_info["tip_point"])
        harmonic = point_load(n, tip, float(_get(excitation, "amplitude", 0.1)),
                              geometry_info["excitation_direction"], bs)
        loads = Loads(fixed=fixed, static=ops.f_static, harmonic=harmonic, observe=bs * tip + np.arange(bs))
        contact = Contact(**bundle_keys(pairs))
        bundle = Bundle(M=ops.M, K=ops.K, C=sp.csr_matrix(ops.M.shape), contact=contact, loads=loads, coords=coords,
                        cyclic=cyclic)
    # Damping: Rayleigh plus β for a modal ratio on the first tied mode.
    t0 = time.perf_counter()
    alpha, beta = float(_get(damping, "alpha", 0.0)), float(_get(damping, "beta", 0.0))
    ratio = float(_get(damping, "modal_ratio", 0.0))
    f1 = _first_tied_hz(bundle, comm, rotation) if ratio > 0 else None
    if not root:
        return None, {}
    b_modal = modal_beta(ratio, 2 * math.pi * f1) if f1 else 0.0
    bundle.C = rayleigh(ops.M, ops.K, alpha, beta + b_modal)
    t["damping_s"] = time.perf_counter() - t0
    mass = float(ops.M[0::bs, 0::bs].sum())
    info = dict(n_dofs=n, n_pairs=contact.n_pairs, mass_kg=mass, volume_fe_m3=mass / _material(material)[2],
                omega_rad_s=omega, tip_block=tip, tip_position=coords[tip].tolist(),
                static_force_sum_N=ops.f_static.reshape(-1, bs).sum(axis=0).tolist(),
                flank_area_m2=float(contact.area.sum()), first_tied_hz=f1,
                damping=dict(alpha=alpha, beta=beta, beta_modal=b_modal, beta_total=beta + b_modal,
                             modal_ratio=ratio),
                cyclic=None if cyclic is None else dict(n_sectors=cyclic.n_sectors,
                                                        face_nodes=int(cyclic.low_dofs.shape[0])),
                prestress=dict(stress_stiffening=ops.K_sigma is not None, spin_softening=ops.M_perp is not None,
                               max_u0_m=float(np.abs(ops.u0).max()) if ops.u0 is not None else 0.0,
                               iterations=len(ops.prestress_change), change=ops.prestress_change),
                timings=t)
    bundle.meta = dict(
        code="bladewear.reduction.assemble", dolfinx=dc.VERSION, element=f"P{DEGREE} vector Lagrange",
        material=dict(young=_material(material)[0], poisson=_material(material)[1], density=_material(material)[2]),
        speed_rpm=float(_get(rotation, "speed_rpm", 0.0)), **info, geometry=geometry_info)
    return bundle, info


def _first_tied_hz(bundle, comm, rotation) -> float:
    """First tied frequency [Hz] of ``bundle`` for ``damping.modal_ratio``
    (collective under MPI: SLEPc + MUMPS on every rank); :class:`BundleError`
    if it is not positive."""
    if comm.Get_size() > 1:
        from reduction.parallel import frequencies_mpi

        f1 = float(frequencies_mpi(bundle, 1, tied=True, comm=comm)[0])
    else:
        from reduction.modes import frequencies

        f1 = float(frequencies(bundle, 1, tied=True)[0])
    if f1 <= 0:
        rpm = float(_get(rotation, "speed_rpm", 0.0))
        raise BundleError(f"the first tied frequency is not positive (f1 = {f1:.4g} Hz): K(Ω) is not positive "
                          "definite" + (f" — rotation.speed_rpm = {rpm:g} softens the sector past zero "
                                        "(spin softening); lower it" if rpm > 0 else
                                        " (is the disk clamped?)") + "; damping.modal_ratio needs it")
    return f1


def assemble_bundle(msh_path, geometry_info: dict, material, rotation=None, damping=None, excitation=None,
                    out_dir=None, comm=None, xdmf: bool = True) -> dict:
    """Read ``msh_path``, assemble, write the bundle folder ``out_dir``; return the summary.

    ``material``/``rotation``/``damping``/``excitation`` are the scene
    sections (dataclasses or dicts with the same keys, workflow/params.py).
    """
    from mpi4py import MPI

    comm = comm or MPI.COMM_WORLD
    t0 = time.perf_counter()
    mesh, ct, ft = dc.read_msh(msh_path, comm)
    t_read = time.perf_counter() - t0
    bundle, info = build_bundle(mesh, ct, ft, geometry_info, material, rotation, damping, excitation)
    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    extra = {}
    if xdmf:
        # Written beside the bundle first, then moved in by write_bundle (atomic folder).
        stage = out_dir.parent / f".{out_dir.name}.mesh"
        if comm.rank == dc.ROOT:
            stage.mkdir(parents=True, exist_ok=True)
        comm.barrier()
        dc.write_mesh_xdmf(mesh, ct, ft, stage / "mesh.xdmf")
        extra = {"mesh.xdmf": stage / "mesh.xdmf", "mesh.h5": stage / "mesh.h5"}
    t_xdmf = time.perf_counter() - t0
    if comm.rank == dc.ROOT:
        info["timings"]["mesh_read_s"] = t_read
        info["timings"]["xdmf_s"] = t_xdmf
        t0 = time.perf_counter()
        bundle.meta["timings"] = info["timings"]
        write_bundle(bundle, out_dir, extra_files=extra)
        if xdmf:
            stage.rmdir()
        info["timings"]["bundle_write_s"] = time.perf_counter() - t0
        info["bundle"] = str(out_dir)
    return comm.bcast(info if comm.rank == dc.ROOT else None, root=dc.ROOT)


def as_section(d: dict | None):
    """A dict as an attribute namespace (for callers without the scene dataclasses)."""
    return SimpleNamespace(**(d or {}))
