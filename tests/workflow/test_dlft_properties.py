"""Property tests of the DLFT law (workflow/engine/contact.py) on random states.

For random predictor histories λ_u (nit, p, 3), friction μ, penalties and
gaps, the corrected multipliers must satisfy, to round-off:

* Coulomb: ‖λ_T‖ ≤ μ|λ_N| (1 + 1e-12);
* unilaterality: λ_N ≤ 0 always, λ = 0 when separated;
* complementarity: λ_N · g = 0, with g the corrected normal gap
  g = X_N = (λ_u^N − λ^N)/ε_N (zero in contact, ≥ 0 in separation).
"""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings, strategies as st

from workflow.engine.contact import SEPARATION, STICK, ContactLaw, dlft, dlft_pass

SETTINGS = settings(max_examples=60, deadline=None)


@st.composite
def states(draw):
    p = draw(st.integers(1, 4))
    nit = draw(st.integers(1, 24))
    seed = draw(st.integers(0, 2 ** 32 - 1))
    rng = np.random.default_rng(seed)
    scale = 10.0 ** draw(st.floats(-6, 6))
    lam_u = scale * rng.standard_normal((nit, p, 3))
    # bias the normal part so that all regimes (closed, open, mixed) occur
    lam_u[..., 0] += scale * draw(st.floats(-3, 3))
    mu = draw(st.sampled_from([0.0, 1e-6, 0.1, 0.5, 3.0, 1e6]))
    ref = scale * rng.standard_normal((p, 2))
    return lam_u, np.full(p, mu), ref


@SETTINGS
@given(states(), st.booleans())
def test_coulomb_unilateral_complementarity(state, periodic):
    lam_u, mu, ref = state
    r = dlft_pass(lam_u, mu, ref, periodic=periodic, max_passes=5)
    lam = r.lam
    assert np.all(np.isfinite(lam))
    lamN, lamT = lam[..., 0], lam[..., 1:]
    nT = np.linalg.norm(lamT, axis=-1)
    assert np.all(lamN <= 0.0)
    assert np.all(nT <= mu[None, :] * np.abs(lamN) * (1 + 1e-12))
    sep = r.state == SEPARATION
    assert np.all(lam[sep] == 0.0)
    assert np.all(lam_u[sep][:, 0] >= 0.0)          # separated ⇔ predictor λ_N ≥ 0
    # corrected gap g = (λ_u^N − λ^N)/ε_N (any ε_N > 0): zero in contact, ≥ 0 when open
    g = lam_u[..., 0] - lamN
    assert np.all(g >= 0.0)
    assert np.all(np.abs(lamN * g) <= 1e-12 * np.abs(lam_u[..., 0]) ** 2 + 1e-300)


@SETTINGS
@given(states())
def test_stick_keeps_reference_and_slip_lies_on_cone(state):
    lam_u, mu, ref = state
    r = dlft_pass(lam_u, mu, ref, periodic=False)
    lam, st_ = r.lam, r.state
    nT = np.linalg.norm(lam[..., 1:], axis=-1)
    slip = st_ == 2
    # slip: exactly on the cone
    assert np.allclose(nT[slip], (mu[None, :] * np.abs(lam[..., 0]))[slip], rtol=1e-12, atol=0)
    # stick: strictly inside, and λ_x^T unchanged from the previous instant
    stick = st_ == STICK
    assert np.all(nT[stick] < (mu[None, :] * np.abs(lam[..., 0]))[stick] * (1 + 1e-12))
    prev = np.concatenate([ref[None], r.lam_x_T[:-1]], axis=0)
    assert np.array_equal(r.lam_x_T[stick], prev[stick])


@SETTINGS
@given(st.integers(1, 3), st.integers(2, 16), st.integers(0, 10 ** 6),
       st.floats(1e-3, 1e3), st.floats(1e-3, 1e3), st.floats(-1e-5, 1e-5))
def test_through_contact_law_with_gaps(p, nit, seed, sN, sT, gap):
    """Through ContactLaw and dlft(): random u_r histories, gaps, penalties."""
    rng = np.random.default_rng(seed)
    law = ContactLaw(mu=rng.uniform(0, 1, p), eps_n=1e6 * sN, eps_t=1e6 * sT, gap=np.full(p, gap),
                     wear=rng.uniform(0, 1e-6, p))
    u = 1e-6 * rng.standard_normal((nit, p, 3))
    f = 10.0 * rng.standard_normal((nit, p, 3))
    lam_u = f + law.eps()[None] * (u + law.offset()[None])
    r = dlft(law, lam_u, 1e-6 * rng.standard_normal((p, 2)))
    lamN = r.lam[..., 0]
    nT = np.linalg.norm(r.lam[..., 1:], axis=-1)
    assert np.all(lamN <= 0.0)
    assert np.all(nT <= law.mu[None, :] * np.abs(lamN) * (1 + 1e-12))
    gN = (lam_u[..., 0] - lamN) / law.eps_n[None, :]
    assert np.all(gN >= 0.0)
    assert np.all(np.abs(lamN * gN) <= 1e-12 * np.abs(lam_u[..., 0]) ** 2 / law.eps_n[None, :] + 1e-300)
