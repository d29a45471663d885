"""Cyclic symmetry against the full ring built by index bookkeeping (tests/reduction/ring.py).

The blade–disk sector at N = 6 (coarse: ~8.5k DOFs, the ring ~50k) is
assembled once; the ring is N rotated copies of its matrices with sector
s's high face identified with sector s+1's low face.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

import ring as rg

N = 6
RPM = 10000.0
TI = dict(young=110e9, poisson=0.33, density=4430.0)
COARSE = dict(n_sectors=N, h_blade=0.008, h_disk=0.02, h_airfoil=0.012, cyclic=True)


@pytest.fixture(scope="module")
def cyclic_sector(tmp_path_factory):
    """(bundle with cyclic faces, Operators of assemble_operators at RPM) of the coarse N = 6 sector."""
    from geometry.params import SectorParams
    from geometry.sector import build_sector
    from reduction import dolfinx_compat as dc
    from reduction.assemble import as_section, assemble_bundle, assemble_operators, rpm_to_rad_s
    from reduction.bundle import read_bundle

    tmp = tmp_path_factory.mktemp("cyclic6")
    info = json.loads(json.dumps(build_sector(SectorParams(**COARSE), tmp / "s.msh")))
    assemble_bundle(tmp / "s.msh", info, as_section(TI), as_section(dict(speed_rpm=RPM)),
                    as_section(dict(modal_ratio=0.0)), as_section(dict(amplitude=0.1)), tmp / "model", xdmf=False)
    bundle = read_bundle(tmp / "model")
    mesh, ct, ft = dc.read_msh(tmp / "s.msh")
    ops, _ = assemble_operators(mesh, ct, ft, TI, rpm_to_rad_s(RPM), fixed=bundle.loads.fixed,
                                blade_dofs=bundle.contact.blade_dofs, disk_dofs=bundle.contact.disk_dofs,
                                cyclic=bundle.cyclic)
    return bundle, ops


@pytest.fixture(scope="module")
def full_ring(cyclic_sector):
    bundle, _ = cyclic_sector
    return rg.ring_from_bundle(bundle)


def test_bundle_carries_matched_faces(cyclic_sector):
    bundle, _ = cyclic_sector
    from reduction.cyclic import rotation_x

    cy = bundle.cyclic
    assert cy.n_sectors == N and cy.low_dofs.shape[0] > 10
    x_low, x_high = bundle.coords[cy.low_dofs[:, 0] // 3], bundle.coords[cy.high_dofs[:, 0] // 3]
    np.testing.assert_allclose(x_low @ rotation_x(2 * math.pi / N).T, x_high, atol=1e-12)
    # low = the +y cut, high = the −y cut (geometry/cyclic.py)
    assert (x_low[:, 1] > 0).all() and (x_high[:, 1] < 0).all()


@pytest.mark.slow  # 4–9 s on the 2-core machine: make test-slow keeps make test within 3 min
def test_nd0_prestress_equals_the_full_ring_static_state(cyclic_sector, full_ring):
    """(c) The sector's ND-0 static displacement under rotation is the spinning ring's, restricted to sector 0."""
    bundle, ops = cyclic_sector
    ids, G, free = full_ring
    Kstat = ops.K0 - (2 * math.pi * RPM / 60) ** 2 * ops.M_perp
    Kr, fr = rg.assemble_ring(Kstat, G), sum(g @ ops.f_static for g in G)
    u = np.zeros(Kr.shape[0])
    u[free] = sla.spsolve(Kr[free][:, free].tocsc(), fr[free])
    u_sector0 = G[0].T @ u
    err = np.linalg.norm(u_sector0 - ops.u0) / np.linalg.norm(u_sector0)
    assert err < 1e-8, err
    # the cyclic constraint matters: the rim of a sector with free cuts expands differently
    from reduction.prestress import static_displacement, tie_map

    T = tie_map(bundle.n_dofs, bundle.loads.fixed, bundle.contact.blade_dofs, bundle.contact.disk_dofs)
    u_free_cuts = static_displacement(Kstat, ops.f_static, T)
    faces = np.concatenate([bundle.cyclic.low_dofs.ravel(), bundle.cyclic.high_dofs.ravel()])
    change = np.linalg.norm((u_free_cuts - ops.u0)[faces]) / np.linalg.norm(ops.u0[faces])
    print(f"ring vs ND-0 sector: {err:.2e}; free cuts vs ND 0 on the faces: {change:.2e}")
    assert change > 1e-2


MODES_PER_ND = 4


@pytest.fixture(scope="module")
def nd_spectra(cyclic_sector):
    """Frequencies [Hz] of ND k = 0 … N−1 (every k, not folded) of the tied, clamped sector at RPM."""
    from reduction.constraints import constraint_map
    from reduction.cyclic_modes import nd_modes

    bundle, _ = cyclic_sector
    base = constraint_map(bundle, tied=True)
    return np.array([nd_modes(bundle.K, bundle.M, base, bundle.cyclic, k, MODES_PER_ND)[0] for k in range(N)])


@pytest.mark.slow   # ~10 s: in make test-slow, to keep make test within 3 minutes on 2 cores
def test_nd_spectra_are_the_full_ring_spectrum(cyclic_sector, full_ring, nd_spectra):
    """(a) The sorted union of the ND spectra equals the ring's lowest eigenvalues (same M, K(Ω), tie, clamp)."""
    bundle, _ = cyclic_sector
    ids, G, free = full_ring
    K = rg.assemble_ring(bundle.K, G)[free][:, free]
    M = rg.assemble_ring(bundle.M, G)[free][:, free]
    # complete below the lowest "last computed" mode of any ND
    limit = nd_spectra[:, -1].min()
    union = np.sort(nd_spectra.ravel())
    union = union[union < limit * (1 - 1e-9)]
    w2 = sla.eigsh(K.tocsc(), k=union.size + 2, M=M.tocsc(), sigma=-(2 * np.pi * 10) ** 2, which="LM",
                   tol=1e-12, return_eigenvectors=False)
    ring = np.sort(np.sqrt(w2) / (2 * np.pi))[:union.size]
    err = np.abs(ring / union - 1).max()
    print(f"{union.size} ring frequencies {ring[0]:.2f} … {ring[-1]:.2f} Hz; max relative error {err:.2e}")
    assert union.size >= 2 * N
    assert err < 1e-8, err


def test_nd_and_n_minus_nd_have_the_same_frequencies(nd_spectra):
    """(b) ND k and N − k are complex conjugates: the same spectrum."""
    for k in range(1, N):
        np.testing.assert_allclose(nd_spectra[k], nd_spectra[N - k], rtol=1e-10)
    # the NDs do differ (weakly: a thick clamped rim couples the blades little; measured ~1e-5)
    assert np.abs(nd_spectra[N // 2] / nd_spectra[0] - 1).max() > 1e-6


def test_sector_operators_are_hermitian_and_real_for_nd_0_and_n_half(cyclic_sector):
    """(b) T_kᴴ K T_k is Hermitian to round-off; ND 0 and N/2 give real operators, others complex."""
    from reduction.constraints import constraint_map
    from reduction.cyclic_modes import nd_operators

    bundle, _ = cyclic_sector
    base = constraint_map(bundle, tied=True)
    for k in (0, 1, 3, N // 2):
        Kk, Mk, T = nd_operators(bundle.K, bundle.M, base, bundle.cyclic, k)
        for A in (Kk, Mk):
            scale = abs(A).max()
            assert abs(A - A.conj().T).max() <= 1e-12 * scale
        is_real = not np.iscomplexobj(Kk.data) or abs(Kk.imag).max() == 0
        assert is_real == (k in (0, N // 2)), k
