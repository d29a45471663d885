"""Friction energy per cycle: closed forms of a macroslip loop and of a viscous ellipse, and zero in stick."""
import numpy as np
import pytest

from workflow.engine.dissipation import energy_per_cycle


def _pair(a):
    """One pair, motion along t1 only: (nit,) → (nit, 1, 2)."""
    out = np.zeros((len(a), 1, 2))
    out[:, 0, 0] = a
    return out


def test_coulomb_macroslip_loop_is_4_mu_N_X():
    # Gross slip between ±X with the friction force reversing at the ends: a
    # rectangle in the (X_T, λ_T) plane of area 2X × 2μN = 4μNX (Den Hartog).
    nit, X, muN = 400, 2e-6, 150.0
    tau = 2 * np.pi * np.arange(nit) / nit
    x = X * np.cos(tau)
    lam = np.where(np.sin(tau) > 0, -muN, muN)  # λ_T = −(friction force on the blade) ∝ sign(ẋ)
    lam[np.isclose(np.sin(tau), 0.0, atol=1e-12)] = 0.0
    E = energy_per_cycle(_pair(lam), _pair(x))
    assert E[0] > 0
    assert E[0] == pytest.approx(4 * muN * X, rel=1e-3)


def test_viscous_ellipse_is_pi_c_omega_X2():
    # λ_T = c ẋ with x = X cos τ (ω = 1): E = π c X², second-order in 1/nit.
    X, c = 3e-6, 2e5
    errs = []
    for nit in (32, 64):
        tau = 2 * np.pi * np.arange(nit) / nit
        E = energy_per_cycle(_pair(-c * X * np.sin(tau)), _pair(X * np.cos(tau)))[0]
        errs.append(abs(E - np.pi * c * X ** 2) / (np.pi * c * X ** 2))
    assert errs[1] < 1e-2
    assert errs[0] / errs[1] == pytest.approx(4.0, rel=0.05)


def test_stick_dissipates_nothing_and_pairs_add():
    nit = 16
    lam = np.random.default_rng(0).normal(size=(nit, 2, 2))
    slip = np.zeros((nit, 2, 2))
    slip[:, 0] = [1e-6, -2e-6]          # pair 0 stuck at an offset: constant path
    slip[:, 1, 0] = 1e-6 * np.cos(2 * np.pi * np.arange(nit) / nit)
    E = energy_per_cycle(lam, slip)
    assert E[0] == 0.0
    assert E[1] == pytest.approx(energy_per_cycle(lam[:, 1:], slip[:, 1:])[0])


def test_shapes_must_match():
    with pytest.raises(ValueError, match="energy_per_cycle"):
        energy_per_cycle(np.zeros((8, 2, 2)), np.zeros((8, 3, 2)))
