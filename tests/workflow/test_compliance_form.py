"""The harmonic balance in the interface forces (the compliance form, issue 50) against the
stiffness form on the lumped mistuned disk: the same residual at the same displacements, the same
Jacobian up to the change of unknowns, the same Newton solutions with the dense and the
structured linear solves, and the same blade amplitudes through the mistuned disk's forced
response. The stiffness form is the reference: its Z_r is the lumped disk's own (checked against
the disk assembled in physical coordinates in tests/workflow/test_mistuning.py)."""
from __future__ import annotations

import numpy as np
import pytest

from cyclicmodels import sector_bundle
from workflow.engine.condense import condense, relative_coordinates
from reduction.mistuned import WholeDiskCoordinates, cyclic_model, substructures
from workflow import engine
from workflow.engine import fourier
from workflow.engine.hb import HBProblem, condensed_form
from workflow.engine.linear import first_excited_mode
from workflow.engine.linsolve import StructuredSolve
from workflow.engine.studies import mistuning as ms

N, EO = 5, 2
DEV = np.array([0.04, -0.03, 0.01, 0.05, -0.02])


@pytest.fixture(scope="module")
def disk():
    sub = substructures(sector_bundle(N, amplitude=0.1), EO, blade_modes=50, disk_modes=50)
    cyc = cyclic_model(sub, [0, 1, 2, 3, 4])
    law = engine.contact_law(cyc, mu=0.3)
    f0 = first_excited_mode(relative_coordinates(cyc))[0]
    return sub, cyc, law, f0


def _pair(disk, fac, nh=3):
    """(stiffness-form problem, compliance-form problem, the two condensations) at fac × f₀."""
    sub, _, law, f0 = disk
    omega = 2 * np.pi * fac * f0
    cs = condense(WholeDiskCoordinates(sub, DEV), omega, nh)
    cc = condense(WholeDiskCoordinates(sub, DEV, form="compliance"), omega, nh)
    lw = ms.tiled_law(law, N, EO)
    nit = ms.time_samples(nh, N, EO)
    st = engine.static_state(cs.Zr, cs.Fr, lw)
    return (HBProblem(cs.Zr, cs.Fr, lw, nh, nit, static=st),
            HBProblem(cc.Zr, cc.Fr, lw, nh, nit, static=st, **condensed_form(cc)), cs, cc)


def test_the_condensation_and_the_residual_are_the_stiffness_forms(disk):
    """F_r by the tied solve equals F_r by the dense inverse; H_j Z_j = I; at the same relative
    displacements both forms give the same residual (N), and the compliance form's Jacobian is
    the stiffness form's times the change of unknowns (harmonic 0 as is, H_j above)."""
    hs, hc, cs, cc = _pair(disk, 0.97)
    assert np.abs(cc.Fr - cs.Fr).max() <= 1e-11 * np.abs(cs.Fr).max()
    for j in (1, 2, 3):
        assert np.abs(cc.Zr[j] @ cs.Zr[j] - np.eye(hs.nr)).max() < 1e-10
    U = hs.harmonics(hs.x0()) + 1e-4 * np.random.default_rng(1).standard_normal((4, hs.nr))
    xs, xc = hs.unknowns_from_harmonics(U), hc.unknowns_from_harmonics(U)
    assert np.abs(hc.harmonics(xc) - U).max() <= 1e-10 * np.abs(U).max()
    Rs, Js = hs.residual_jacobian(xs)
    Rc, Jc = hc.residual_jacobian(xc)
    assert np.abs(Rc - Rs).max() <= 1e-9 * np.linalg.norm(hs.r_F)
    Q = hc._dense_parts()[2]
    assert np.abs(Jc - Js @ Q).max() <= 1e-9 * np.abs(Js @ Q).max()
    # the matrix-free operator and its preconditioner's blocks are the formed Jacobian's
    G = hc.contact_blocks(hc.last_dlft.dlam)
    op = hc.operator(G)
    K = op.todense()
    assert np.abs(K - Jc).max() <= 1e-12 * np.abs(Jc).max()
    nr, nc = hc.nr, hc.nc
    for idx, B in op.harmonic_blocks():
        cols = np.concatenate([np.arange(i * nr, (i + 1) * nr) for i in idx])
        assert np.abs(B - K[np.ix_(cols, cols)]).max() <= 1e-12 * np.abs(K).max()
    # the large interfaces' complex harmonic blocks: the stiffness form's times H_h (same Ĝ_h)
    ops = hs.operator(G)
    for (idx, Bc), (_, Bs) in zip(op.complex_harmonic_blocks(), ops.complex_harmonic_blocks()):
        ref = Bs if idx == [0] else Bs @ hc.Zr[(idx[0] + 1) // 2]
        assert np.abs(Bc - ref).max() <= 1e-10 * np.abs(ref).max()
    pairs = np.array([[0, 1], [2, 3]])
    for c, B in zip(pairs, op.cluster_blocks(pairs)):
        dofs = [(q * nr + 3 * i + d) for i in c for q in range(nc) for d in range(3)]
        assert np.abs(B - K[np.ix_(dofs, dofs)]).max() <= 1e-12 * np.abs(K).max()


@pytest.mark.parametrize("linear", ["dense", "structured"])
def test_newton_finds_the_stiffness_forms_solution(disk, linear):
    """From the same guess both forms converge (1e-10 of ‖F‖) to the same relative displacements."""
    hs, hc, _, _ = _pair(disk, 1.02)
    kw = {} if linear == "dense" else {"linsolver": StructuredSolve()}
    rs = hs.solve(hs.x0(), tol=1e-11, maxiter=80, linear=linear, **kw)
    kw = {} if linear == "dense" else {"linsolver": StructuredSolve()}
    rc = hc.solve(hc.x0(), tol=1e-11, maxiter=80, linear=linear, **kw)
    assert rs.converged and rc.converged, (rs.reason, rc.reason)
    Us, Uc = hs.harmonics(rs.x), hc.harmonics(rc.x)
    assert np.abs(Uc - Us).max() <= 1e-7 * np.abs(Us[1:]).max()


@pytest.mark.slow  # 3.5 s: a tuned FRF and two forced responses of three points
def test_the_forced_response_is_the_stiffness_forms(disk):
    """Every blade's amplitude of the mistuned disk at three frequencies (seeded with the tuned
    travelling wave), compliance against stiffness form: to the Newton tolerance."""
    sub, cyc, law, f0 = disk
    v = engine.Variant("hbm", 3, ms.time_samples(3, N, EO))
    freqs = f0 * np.array([0.96, 0.99, 1.04])     # off the top, where this disk needs more iterations
    ref = engine.frf(cyc, law, [v], freqs_hz=freqs,
                     options=engine.FRFOptions(eps_check_factor=0.0, nh_check=False, reference_check=False,
                                               branch_check=False, time_check=False, refine_peak=False)).runs[0]
    seeds = [ms.travelling_wave(U, N, EO) for U in ref.Ur]
    lw = ms.tiled_law(law, N, EO)
    out = [ms.forced_response(WholeDiskCoordinates(sub, DEV), lw, v, freqs, seeds=seeds, refine=False,
                              tied=False, tol=1e-10, form=form) for form in ("stiffness", "compliance")]
    assert out[0].converged.all() and out[1].converged.all()
    assert np.abs(out[1].amplitude / out[0].amplitude - 1).max() < 1e-6
