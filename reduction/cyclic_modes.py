"""Linear modes of a tuned bladed disk per nodal diameter: ND map, Campbell diagram, ZZENF crossings.

A sector with cyclic faces (``bundle.cyclic``, :mod:`reduction.cyclic`)
stands for the whole tuned disk. For ND k the sector operators are
``K_k = T_kᴴ K T_k``, ``M_k = T_kᴴ M T_k`` with ``T_k`` the cyclic map
composed with the clamp and the tied interface (``u = T_tie T_k v``: the
linear, stuck dovetail — the tied limit of contracts §2). Their eigenpairs
``K_k φ = ω² M_k φ`` (Hermitian, complex for 0 < k < N/2, real for k = 0 and
k = N/2) are the disk's modes with k nodal diameters (Thomas 1979; Petrov
2004 §2); ND k and N − k share them (backward/forward travelling waves).
Solved by :func:`scipy.sparse.linalg.eigsh` in shift-invert mode.

* ND map: the lowest modes of k = 0 … ⌊N/2⌋ at one speed;
* Campbell: the same at several rotation speeds, K(Ω) = K₀ + K_σ(σ₀(Ω)) −
  Ω²M_⊥ re-assembled at each (prestress under ND 0: the spinning tuned disk,
  :func:`reduction.assemble.assemble_operators`), against the engine-order
  lines f = EO·Ω/2π;
* ZZENF (zig-zag excitation nodal-diameter frequency diagram, akin to Singh's SAFE diagram;
  Wildheim 1979): an EO travelling wave excites only ND ``fold(EO mod N)``;
  its resonances are that ND's modes where they meet f = EO·Ω/2π.

Units: Ω rad/s (rpm at the interfaces), frequencies Hz, ω² rad²/s².
"""
from __future__ import annotations

import time
from typing import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from reduction.cyclic import constrain_map, sector_operator
from workflow.errors import SolverError

#: Shift [rad²/s²] of the shift-invert solves: just below 0, as reduction.modes.SIGMA.
SIGMA = -(2 * np.pi * 10.0) ** 2


def fold_nd(n: int, n_sectors: int) -> int:
    """The ND 0 … ⌊N/2⌋ that carries ND (or engine order) ``n``: min(n mod N, N − n mod N)."""
    r = int(n) % int(n_sectors)
    return min(r, int(n_sectors) - r)


def nodal_diameters(n_sectors: int) -> list[int]:
    """All distinct NDs 0 … ⌊N/2⌋."""
    return list(range(int(n_sectors) // 2 + 1))


def nd_operators(K: sp.spmatrix, M: sp.spmatrix, base: sp.spmatrix, cyclic, nd: int):
    """``(K_k, M_k, T)`` of ND ``nd``: ``T = base ∘ T_k`` (n_dofs × n_k) and the sector operators ``Tᴴ A T``.

    ``base``: the clamp/tie map (:func:`reduction.constraints.constraint_map`);
    ``cyclic``: a :class:`reduction.bundle.Cyclic`.
    """
    T = constrain_map(base, cyclic.low_dofs, cyclic.high_dofs, cyclic.n_sectors, nd)
    return sector_operator(K, T), sector_operator(M, T), T


def hermitian_eigs(K: sp.spmatrix, M: sp.spmatrix, n_modes: int, sigma: float = SIGMA, vectors: bool = False):
    """Lowest ``n_modes`` eigenpairs of the Hermitian pencil (K, M) above ``sigma``: ``(omega2, Phi | None)``.

    Phi is M-orthonormal (n, n_modes). :class:`SolverError` when the pencil
    is too small or ARPACK fails.
    """
    n = K.shape[0]
    if n_modes >= n - 1:
        raise SolverError(f"cannot compute {n_modes} modes of a {n}-DOF sector operator")
    try:
        # K − σM is Hermitian positive definite (σ < 0 below every mode): a symmetric fill-reducing order and
        # no pivoting halve SuperLU's time against eigsh's own factorisation (COLAMD), measured 0.18 vs 0.49 s.
        lu = sla.splu((K - sigma * M).tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                      options=dict(SymmetricMode=True))
        op = sla.LinearOperator(K.shape, matvec=lu.solve, dtype=lu.L.dtype)
        w, v = sla.eigsh(K.tocsc(), k=n_modes, M=M.tocsc(), sigma=sigma, which="LM", OPinv=op, tol=1e-12)
    except (sla.ArpackError, RuntimeError) as exc:
        raise SolverError(f"cyclic eigen-solve failed: {exc}") from exc
    order = np.argsort(w.real)
    return w.real[order], (v[:, order] if vectors else None)


def nd_modes(K, M, base, cyclic, nd: int, n_modes: int, sigma: float = SIGMA, vectors: bool = False):
    """``(f_hz, Phi)`` of ND ``nd``: frequencies [Hz] and, with ``vectors``, the sector-0 complex
    amplitudes in full DOFs (n_dofs × n_modes; physical motion of sector s:
    ``Re(e^{isφ_k} R^s φ e^{iωt})``)."""
    Kk, Mk, T = nd_operators(K, M, base, cyclic, nd)
    w2, phi = hermitian_eigs(Kk, Mk, n_modes, sigma, vectors)
    f = np.sqrt(np.clip(w2, 0.0, None)) / (2 * np.pi)
    return f, (T @ phi if phi is not None else None)


def nd_map(K, M, base, cyclic, nds, n_modes: int, sigma: float = SIGMA) -> tuple[np.ndarray, float]:
    """ND map at one speed: ``(F, seconds)`` with F[i, j] [Hz] mode j of ND ``nds[i]``."""
    t0 = time.perf_counter()
    F = np.array([nd_modes(K, M, base, cyclic, int(k), n_modes, sigma)[0] for k in nds])
    return F, time.perf_counter() - t0


def campbell(stiffness_at: Callable[[float], sp.spmatrix], M, base, cyclic, nds, n_modes: int,
             speeds_rad_s, sigma: float = SIGMA) -> tuple[np.ndarray, float]:
    """Campbell diagram: ``(F, seconds)``, F[s, i, j] [Hz] mode j of ND ``nds[i]`` at speed s.

    ``stiffness_at(Ω)`` returns K(Ω) [N/m] (re-assembled, prestress under ND 0).
    """
    t0 = time.perf_counter()
    F = np.array([nd_map(stiffness_at(float(om)), M, base, cyclic, nds, n_modes, sigma)[0] for om in speeds_rad_s])
    return F, time.perf_counter() - t0


def eo_crossings(speeds_rpm, F: np.ndarray, nds, engine_orders, n_sectors: int) -> list[dict]:
    """Resonances of each engine order on the Campbell diagram.

    EO excites ND ``fold_nd(EO, N)`` only; a crossing is a speed where
    ``f_mode(Ω) = EO·Ω/2π`` (linear interpolation between the computed
    speeds). Returns dicts ``eo, nd, mode, speed_rpm, f_hz`` (mode 1-based).
    """
    rpm = np.asarray(speeds_rpm, float)
    out = []
    for eo in engine_orders:
        nd = fold_nd(eo, n_sectors)
        if nd not in list(nds):
            continue
        i = list(nds).index(nd)
        for j in range(F.shape[2]):
            g = F[:, i, j] - eo * rpm / 60.0
            for s in np.flatnonzero(np.sign(g[:-1]) != np.sign(g[1:])):
                a = g[s] / (g[s] - g[s + 1])
                speed = rpm[s] + a * (rpm[s + 1] - rpm[s])
                out.append(dict(eo=int(eo), nd=nd, mode=j + 1, speed_rpm=float(speed), f_hz=float(eo * speed / 60.0)))
    return out


def zzenf_orders(F: np.ndarray, speed_rpm: float) -> list[int]:
    """Engine orders 1 … EO_max whose excitation f = EO·Ω/2π stays below 1.05 × the highest mode of ``F``."""
    if speed_rpm <= 0:
        return []
    return list(range(1, int(1.05 * float(np.max(F)) / (speed_rpm / 60.0)) + 1))


def zzenf_resonances(F: np.ndarray, nds, engine_orders, n_sectors: int, speed_rpm: float,
                     band: float = 0.05) -> list[dict]:
    """ZZENF at one speed: for each EO, its ND's modes within ``band`` (relative) of f = EO·Ω/2π.

    ``engine_orders`` None: every EO of :func:`zzenf_orders` (the whole zig-zag).
    Returns dicts ``eo, nd, mode, f_hz, f_eo_hz, detuning`` (f/f_eo − 1).
    """
    engine_orders = zzenf_orders(F, speed_rpm) if engine_orders is None else engine_orders
    out = []
    for eo in engine_orders:
        nd, f_eo = fold_nd(eo, n_sectors), eo * speed_rpm / 60.0
        if nd not in list(nds) or f_eo <= 0:
            continue
        for j, f in enumerate(F[list(nds).index(nd)]):
            if abs(f / f_eo - 1.0) <= band:
                out.append(dict(eo=int(eo), nd=nd, mode=j + 1, f_hz=float(f), f_eo_hz=f_eo, detuning=float(f / f_eo - 1)))
    return out


def stiffness_function(msh_path, material, rotation, bundle, comm=None) -> Callable[[float], sp.csr_matrix]:
    """``Ω ↦ K(Ω)`` [N/m] of the sector mesh, prestress under ND 0 with ``bundle``'s clamp, pairs and
    cyclic faces; the rotation flags (stress_stiffening, spin_softening, prestress_iterations) of the
    scene. Serial (``comm`` default COMM_SELF); the mesh is read once."""
    from mpi4py import MPI

    from reduction import dolfinx_compat as dc
    from reduction.assemble import _get, assemble_operators

    mesh, ct, ft = dc.read_msh(msh_path, comm or MPI.COMM_SELF)
    V = dc.vector_space(mesh, 2)
    coords = dc.gather_block_coordinates(V)
    if bundle.coords is None or coords.shape != bundle.coords.shape or not np.allclose(coords, bundle.coords,
                                                                                        atol=1e-12, rtol=0):
        # A bundle assembled under mpirun numbers its DOFs by partition; this serial re-assembly would not match.
        raise SolverError("the Campbell re-assembly numbers the DOFs differently from the bundle (was the bundle "
                          "assembled under mpirun?): run the assembly serially for cyclic.campbell_speeds_rpm")

    def K_of(omega: float) -> sp.csr_matrix:
        ops, _ = assemble_operators(
            mesh, ct, ft, material, omega, V=V, fixed=bundle.loads.fixed,
            stress_stiffening=bool(_get(rotation, "stress_stiffening", True)),
            spin_softening=bool(_get(rotation, "spin_softening", True)),
            prestress_iterations=int(_get(rotation, "prestress_iterations", 0)),
            blade_dofs=bundle.contact.blade_dofs, disk_dofs=bundle.contact.disk_dofs, cyclic=bundle.cyclic)
        if ops.K.shape != bundle.K.shape:
            raise SolverError(f"re-assembled K has {ops.K.shape[0]} DOFs, the bundle {bundle.n_dofs}: "
                              "the mesh is not the bundle's")
        return ops.K

    return K_of
