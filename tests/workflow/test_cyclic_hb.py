"""Harmonic balance of a tuned disk on one sector (per-ND condensation, EO wave)
against the whole disk solved by the ordinary engine (independent reference).

The lumped disk of :mod:`cyclicmodels` (N = 5 sectors of 3D point masses on a
circle, random anisotropic springs, two friction pairs per sector): the
full disk is an ordinary ReducedModel with N× the pairs and the tip forces
``R^s F e^{i s 2π EO/N}``; the cyclic model is the sector bundle reduced per
ND (:func:`reduction.cyclic_reduce.reduce_cyclic`). Both go through the same
front door :func:`workflow.engine.frf` with the same ε.

What must agree and what need not: the dynamic harmonics (j ≥ 1) are unique,
and so is the mean (harmonic 0) of a pair that slips during the period; a
pair stuck the whole period has a non-unique static offset (the "stuck
zeroth harmonic", DESIGN §3), which Newton may land anywhere on — on the
full disk differently in every sector — and through the static coupling it
moves the other pairs' means too: harmonic 0 is compared where every pair
slips. The AFT time
grid must map onto itself under the inter-sector shift (nit a multiple of N):
otherwise the sector's DLFT samples the wave at other instants than sector
s's, and the two agree only to the time-grid error (measured: 1e-2 at a
stick–slip point with nit = 32, N = 5; 1e-8 with nit = 40).
"""
from __future__ import annotations

import numpy as np
import pytest

from cyclicmodels import full_disk, sector_bundle
from workflow.engine.condense import recover, relative_coordinates
from reduction.cyclic import rotation_x
from reduction.cyclic_reduce import reduce_cyclic
from workflow import engine
from workflow.engine.contact import ContactLaw
from workflow.engine.linear import first_excited_mode

N, NH, NIT, AMP, MU = 5, 3, 40, 0.1, 0.3
#: each solve stops at ‖R‖ ≤ tol·‖F‖, within ‖J⁻¹‖·tol·‖F‖ ≤ 150·tol·max|U| of its root at these points
#: (measured ‖J⁻¹‖ at the roots, tol = 1e-10): cyclic and full agree to ≤ 3e-8·max|U| < TOL
TOL = 1e-7
OPT = engine.FRFOptions(tol=1e-10, max_iterations=100, eps_check_factor=0, reference=None, reference_check=False)


def _models(eo, nh=NH, mu=MU):
    cyc = reduce_cyclic(sector_bundle(N, amplitude=AMP), eo, nh)
    full = full_disk(N, eo, amplitude=AMP)
    law_c = engine.contact_law(cyc, mu=mu)
    # the same ε on every sector's pairs (the engine's choice would differ: Zr[0] of the disk is not ND 0's)
    law_f = ContactLaw(mu=np.tile(law_c.mu, N), eps_n=np.tile(law_c.eps_n, N), eps_t=np.tile(law_c.eps_t, N),
                       gap=np.tile(law_c.gap, N))
    return cyc, full, law_c, law_f


def _phase(eo, nh):
    """(Nh+1, N): e^{i j s 2π EO/N}, harmonic j of sector s relative to sector 0."""
    return np.exp(2j * np.pi * np.outer(np.arange(nh + 1), np.arange(N)) * eo / N)


@pytest.mark.parametrize("eo, ratios", [(3, (0.97, 0.99, 1.01, 1.03)),      # aliasing: 2·3, 3·3 ≥ 5
                                        (1, (0.97, 0.995, 1.006, 1.03))])
def test_cyclic_hb_equals_full_disk_through_the_resonance(eo, ratios):
    cyc, full, law_c, law_f = _models(eo)
    assert cyc.nodal_diameters(NH) == [(j * eo) % N for j in range(NH + 1)]
    rc_c, rc_f = relative_coordinates(cyc), relative_coordinates(full)
    f0 = first_excited_mode(rc_c)[0]
    ph = _phase(eo, NH)
    slipping_points = 0
    for f in f0 * np.array(ratios):
        v = [engine.Variant("hbm", NH, NIT)]
        rc_run = engine.frf(cyc, law_c, v, freqs_hz=[f], options=OPT).runs[0]
        rf_run = engine.frf(full, law_f, v, freqs_hz=[f], options=OPT).runs[0]
        assert rc_run.converged[0] and rf_run.converged[0], f
        Uc, Uf = rc_run.Ur[0], rf_run.Ur[0].reshape(NH + 1, N, -1)
        scale = np.abs(Uf).max()
        # dynamic harmonics of every relative DOF: sector 0 = the cyclic solution, sector s = its EO wave
        assert np.abs(Uc[1:] - Uf[1:, 0]).max() <= TOL * scale
        assert np.abs(Uf[1:] - Uf[1:, :1] * ph[1:, :, None]).max() <= TOL * scale
        # the means (harmonic 0) are unique when every pair slips (moves tangentially) at some instant
        moving = np.abs(Uc[1:]).reshape(NH, -1, 3)[:, :, 1:].max(axis=(0, 2)) > 1e-9 * scale
        slipping_points += bool(moving.any())
        if moving.all():
            assert np.abs(Uc[0] - Uf[0, 0]).max() <= TOL * scale
            assert np.abs(Uf[0] - Uf[0, :1]).max() <= TOL * scale
        # tip (observed, physical DOFs): sector s's tip is R^s · sector 0's · phase
        w = 2 * np.pi * f
        tip_c = recover(rc_c, w, Uc)[1:]
        tip_f = recover(rc_f, w, rf_run.Ur[0])[1:].reshape(NH, N, 3)
        top = np.abs(tip_f).max()
        assert np.abs(tip_c - tip_f[:, 0]).max() <= TOL * top
        for s in range(N):
            expect = tip_c @ rotation_x(2 * np.pi * s / N).T * ph[1:, s, None]
            assert np.abs(tip_f[:, s] - expect).max() <= TOL * top
    assert slipping_points >= 2  # the band crosses the stick–slip region, not only the stuck flanks


@pytest.mark.slow  # ~12 s: make test-slow (the sector = the full lumped disk is also test_cyclic_ring's)
def test_linear_limits_tied_and_sliding_equal_the_full_disk():
    """Tied (u_r = 0) and sliding (μ = 0: normal contact kept, tangential free)
    FRFs of the cyclic model = those of the full disk; each of the N tips of
    the EO wave has the sector-0 amplitude, so the full disk's norm over all
    tips is √N times the sector's. And the HB with μ → ∞ gives the tied FRF."""
    cyc, full, law_c, law_f = _models(3)
    f0 = first_excited_mode(relative_coordinates(cyc))[0]
    freqs = f0 * np.linspace(0.8, 1.2, 7)
    opt = engine.FRFOptions(tol=1e-10, eps_check_factor=0, reference=None, reference_check=False,
                            branch_check=False)   # the linear limits are under test, not the sweep's branch
    v = [engine.Variant("hbm", 1, 40)]
    sc = engine.frf(cyc, law_c, v, freqs_hz=freqs, options=opt)
    sf = engine.frf(full, law_f, v, freqs_hz=freqs, options=opt)
    np.testing.assert_allclose(sf.tied, np.sqrt(N) * sc.tied, rtol=1e-9)
    np.testing.assert_allclose(sf.sliding, np.sqrt(N) * sc.sliding, rtol=1e-9)
    assert np.max(sc.tied) > 3 * np.max(sc.sliding)  # the tied resonance is in the band, the sliding one not
    # μ → ∞ and an interference large enough that no pair opens at the peak
    stuck = engine.frf(cyc, engine.contact_law(cyc, mu=1e3, gap=-1.0), v, freqs_hz=freqs, options=opt).runs[0]
    assert stuck.converged.all()
    np.testing.assert_allclose(stuck.amplitude, sc.tied, rtol=1e-8)


def test_aliased_harmonics_use_their_own_nodal_diameter():
    """Harmonic 2 of EO 3 on 5 sectors lives on ND 1: its condensed stiffness is
    ND 1's, which the ND-3 model (harmonic 1's) does not have."""
    cyc = reduce_cyclic(sector_bundle(N), 3, 2)
    rc = relative_coordinates(cyc)
    assert sorted(cyc.models) == [0, 1, 3]
    assert rc.harmonic(2) is rc.by_nd[1] and rc.harmonic(1) is rc.by_nd[3]
    from workflow.engine.condense import condense
    c = condense(rc, 3.0, 2)
    assert not np.allclose(c.Zr[2], c.Zr[2].T)        # Hermitian-based, not complex symmetric
    with pytest.raises(Exception, match="no nodal diameter 4"):
        condense(rc, 3.0, 3)
