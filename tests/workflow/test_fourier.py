"""Harmonic conventions (contracts §3): round trips, known signals, operators."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from workflow.engine import fourier


@settings(max_examples=30, deadline=None)
@given(nh=st.integers(0, 8), extra=st.integers(0, 40), seed=st.integers(0, 10_000))
def test_time_freq_round_trip(nh, extra, seed):
    rng = np.random.default_rng(seed)
    nit = 2 * nh + 1 + extra
    x = rng.normal(size=(2 * nh + 1, 4, 3))
    U = fourier.real_to_complex(x)
    assert np.allclose(fourier.complex_to_real(U), x)
    u = fourier.to_time(U, nit)
    assert u.shape == (nit, 4, 3)
    assert np.allclose(fourier.to_freq(u, nh), U, atol=1e-12)
    # the small matrices are the same maps
    E = fourier.time_from_coef_matrix(nh, nit)
    P = fourier.coef_from_time_matrix(nh, nit)
    assert np.allclose(np.einsum("kj,jab->kab", E, x), u)
    assert np.allclose(P @ E, np.eye(2 * nh + 1))


def test_known_signal():
    # u(τ) = 2 + 3 cos τ − 0.5 sin 2τ  →  U0 = 2, U1 = 3, U2 = +0.5i  (U_j = u_jc − i u_js)
    nit = 16
    tau = fourier.sample_times(nit)
    u = 2 + 3 * np.cos(tau) - 0.5 * np.sin(2 * tau)
    U = fourier.to_freq(u, 3)
    assert np.allclose(U, [2, 3, 0.5j, 0])
    x = fourier.complex_to_real(U)
    assert np.allclose(x, [2, 3, 0, 0, -0.5, 0, 0])
    assert np.allclose(fourier.to_time(U, nit), u)
    assert np.allclose(np.real(np.sum(U[:, None] * np.exp(1j * np.arange(4)[:, None] * tau), 0)), u)


def test_aliasing_guard():
    with pytest.raises(ValueError, match="2·Nh\\+1"):
        fourier.to_time(np.zeros(4, complex), 6)
    with pytest.raises(ValueError, match="nit"):
        fourier.to_freq(np.zeros(6), 3)


def test_higher_harmonics_are_projected_out():
    nit = 64
    tau = fourier.sample_times(nit)
    u = np.cos(tau) + np.cos(5 * tau)
    assert np.allclose(fourier.to_freq(u, 3), [0, 1, 0, 0], atol=1e-13)


def test_derivative_operator():
    nh, nit = 4, 32
    rng = np.random.default_rng(1)
    x = rng.normal(size=2 * nh + 1)
    D = fourier.derivative_matrix(nh)
    tau = fourier.sample_times(nit)
    # exact derivative of the series, sampled
    du = sum(j * (-x[2 * j - 1] * np.sin(j * tau) + x[2 * j] * np.cos(j * tau)) for j in range(1, nh + 1))
    assert np.allclose(fourier.time_from_coef_matrix(nh, nit) @ (D @ x), du)
    assert np.allclose(fourier.complex_to_real(fourier.derivative(fourier.real_to_complex(x))), D @ x)


def test_hdhb_operators_inverse():
    for nh in (0, 1, 3, 7):
        T, Tinv = fourier.hdhb_operators(nh)
        assert np.allclose(T @ Tinv, np.eye(2 * nh + 1))
        assert np.allclose(Tinv @ T, np.eye(2 * nh + 1))


def test_real_block_matches_complex_product():
    rng = np.random.default_rng(2)
    nh, m = 3, 4
    Z = rng.normal(size=(nh + 1, m, m)) + 1j * rng.normal(size=(nh + 1, m, m))
    Z[0] = Z[0].real
    U = rng.normal(size=(nh + 1, m)) + 1j * rng.normal(size=(nh + 1, m))
    U[0] = U[0].real
    F = np.einsum("jab,jb->ja", Z, U)
    Zb = fourier.real_block_diag(Z)
    assert np.allclose(Zb @ fourier.complex_to_real(U).ravel(), fourier.complex_to_real(F).ravel())
    assert np.allclose(fourier.real_block(Z[2]), Zb.reshape(7, m, 7, m)[3:5, :, 3:5, :].reshape(2 * m, 2 * m))
