"""Closed forms and an independent multi-harmonic reference for the friction-damped nonlinear
mode of a mass on a spring with a Jenkins element (independent of the project's HB/DLFT code).

The oscillator: ``m ẍ + c ẋ + k x + f_J(x) = 0`` where the Jenkins element is a tangential
spring k_t in series with a Coulomb slider of limit ``F_s = μN``; its force follows the
Masing (play-operator) hysteresis: ``f_J = k_t (x − w)`` with the slider position w stuck
while ``|f_J| < F_s``.

* :func:`describing_function` — single-harmonic (describing function) equivalent stiffness
  and the equivalent "hysteretic" stiffness of the Jenkins element at displacement amplitude
  X: with ``x = X cos θ``, ``X_s = F_s/k_t`` and, for X > X_s, ``cos θ* = 1 − 2X_s/X``
  (θ* ∈ (0, π) the stick arc after each reversal),

      k_eq = (k_t/π) (θ* − ½ sin 2θ*),     h_eq = 4 F_s (X − X_s) / (π X²),

  the first harmonic of f_J being ``(k_eq + i h_eq) X̂`` (complex amplitude, h_eq in phase
  with the velocity: the parallelogram loop's area ``π h_eq X² = 4 F_s (X − X_s)``). For
  X ≤ X_s the element sticks: k_eq = k_t, h_eq = 0. (Griffin 1980; Krack & Gross 2019,
  'Harmonic Balance for Nonlinear Vibration Problems', §2 — derived here from the loop:
  on the descending branch from the maximum, ``f = F_s − k_t X (1 − cos θ)`` for θ < θ*,
  ``f = −F_s`` after; the cosine coefficient of f over the half-wave-symmetric period.)
* :func:`epmc_single_harmonic` — the EPMC (Krack 2015) of that oscillator in the same
  approximation: ``M q̈ + (C − ξM) q̇ + K q + f_J = 0`` balanced on the first harmonic gives
  ``ω² = (k + k_eq)/m``, ``ξ = (c ω + h_eq)/(m ω)``, ``D = ξ/(2ω)``; the modal amplitude
  (mass-weighted first-harmonic norm) ``a = √m X``.
* :func:`epmc_galerkin` — the same EPMC balanced on harmonics 0…N (default 25) with the
  exact hysteresis: the play operator run on 4096 samples of x(τ) per period, its Fourier
  coefficients by FFT, the equations solved by :func:`scipy.optimize.root`. What remains is
  the truncation at N (and the sampling of the loop's reversal, ~(2π/4096)² relative): the
  reference the project's EPMC at Nh ≥ 7 is held to where the single harmonic is not close
  enough (the describing function ignores the higher harmonics, which shift ω by up to a few
  tenths of a per cent in the transition from stick to gross slip).

Units SI (kg, N/m, N·s/m, N, m, rad/s).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import root

#: samples per period of the play operator in :func:`epmc_galerkin`
SAMPLES = 4096


def describing_function(amplitude, k_t: float, slip_force: float):
    """(k_eq, h_eq) in N/m of a Jenkins element (k_t, F_s) at displacement amplitude X (m)."""
    X = np.asarray(amplitude, dtype=float)
    xs = slip_force / k_t
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.clip(1.0 - 2.0 * xs / X, -1.0, 1.0)
        th = np.arccos(c)
        k_eq = np.where(X > xs, k_t / np.pi * (th - 0.5 * np.sin(2 * th)), k_t)
        h_eq = np.where(X > xs, 4.0 * slip_force * (X - xs) / (np.pi * X * X), 0.0)
    return k_eq, h_eq


@dataclass(frozen=True)
class ModalPoint:
    """One point of a backbone: modal amplitude a = √m X (m·√kg), displacement amplitude X
    (m), ω (rad/s), ξ (1/s), D = ξ/(2ω), and (Galerkin only) the harmonics' relative size
    ``higher`` = ‖X_{j≥2}‖/|X_1| and whether the solve converged."""

    amplitude: float
    displacement: float
    omega: float
    xi: float
    damping_ratio: float
    higher: float = 0.0
    converged: bool = True


def epmc_single_harmonic(X, m: float, k: float, c: float, k_t: float, slip_force: float) -> list[ModalPoint]:
    """The describing-function EPMC at displacement amplitudes X (m): one :class:`ModalPoint` each."""
    out = []
    for x in np.atleast_1d(np.asarray(X, dtype=float)):
        ke, he = describing_function(x, k_t, slip_force)
        w = float(np.sqrt((k + ke) / m))
        xi = float((c * w + he) / (m * w))
        out.append(ModalPoint(float(np.sqrt(m) * x), float(x), w, xi, xi / (2 * w)))
    return out


def play(x: np.ndarray, k_t: float, slip_force: float) -> np.ndarray:
    """The Jenkins force over one period of the sampled periodic displacement x (n,): the play
    operator started at the sample of largest x with the slider slipping forward (f = F_s),
    run over the period (exact at the samples for a path with one maximum and one minimum a
    period whose peak-to-peak exceeds 2F_s/k_t; otherwise the stuck element's force about the
    period's mean)."""
    x = np.asarray(x, dtype=float)
    n = len(x)
    if np.ptp(x) <= 2.0 * slip_force / k_t:
        return k_t * (x - x.mean())
    i0 = int(np.argmax(x))
    xr = np.roll(x, -i0)
    i1 = int(np.argmin(xr))
    if np.all(np.diff(xr[:i1 + 1]) <= 0) and np.all(np.diff(np.append(xr[i1:], xr[0])) >= 0):
        # one maximum, one minimum: the two branches of the loop in closed form
        f = np.empty(n)
        f[:i1 + 1] = np.maximum(slip_force - k_t * (xr[0] - xr[:i1 + 1]), -slip_force)
        f[i1:] = np.minimum(-slip_force + k_t * (xr[i1:] - xr[i1]), slip_force)
        return np.roll(f, i0)
    f = np.empty(n)
    f[0] = slip_force
    for i in range(1, n):
        f[i] = min(max(f[i - 1] + k_t * (xr[i] - xr[i - 1]), -slip_force), slip_force)
    return np.roll(f, i0)


def _coefficients(u: np.ndarray, nh: int) -> np.ndarray:
    """Complex harmonics 0…nh of samples u (n,) on τ_k = 2πk/n, ``u = Re Σ U_j e^{ijτ}``."""
    U = np.fft.rfft(u)[: nh + 1] * (2.0 / len(u))
    U[0] *= 0.5
    return U


def _samples(U: np.ndarray, n: int) -> np.ndarray:
    full = np.zeros(n // 2 + 1, complex)
    full[0] = U[0].real * n
    full[1:len(U)] = 0.5 * n * U[1:]
    return np.fft.irfft(full, n=n)


def epmc_galerkin(X, m: float, k: float, c: float, k_t: float, slip_force: float, *, nh: int = 25,
                  samples: int = SAMPLES) -> list[ModalPoint]:
    """The EPMC balanced on harmonics 0…nh with the exact Jenkins hysteresis, at first-harmonic
    displacement amplitudes X (m), phase ``Im X̂_1 = 0``: unknowns X̂_0, X̂_2…X̂_nh, ω, ξ;
    equations ``(k − (jω)²m + ijω(c − ξm)) X̂_j + F̂_j = 0``, j = 0…nh (complex; j = 0 real),
    scaled by k X. Each point starts from the describing function's ω, ξ."""
    out = []
    for x in np.atleast_1d(np.asarray(X, dtype=float)):
        guess = epmc_single_harmonic(x, m, k, c, k_t, slip_force)[0]

        def unpack(v):
            U = np.zeros(nh + 1, complex)
            U[0] = v[0]
            U[1] = x
            U[2:] = v[1:2 * nh - 1:2] + 1j * v[2:2 * nh:2]
            return U, v[-2], v[-1]

        def residual(v):
            U, w, xi = unpack(v)
            f = play(_samples(U, samples), k_t, slip_force)
            F = _coefficients(f, nh)
            j = np.arange(nh + 1)
            R = (k - (j * w) ** 2 * m + 1j * j * w * (c - xi * m)) * U + F
            return np.concatenate([[R[0].real], np.column_stack([R[1:].real, R[1:].imag]).ravel()]) / (k * x)

        v0 = np.zeros(2 * nh + 1)
        v0[-2], v0[-1] = guess.omega, guess.xi
        sol = root(residual, v0, method="hybr", options={"xtol": 1e-13})
        U, w, xi = unpack(sol.x)
        ok = bool(sol.success) and float(np.abs(residual(sol.x)).max()) < 1e-9
        out.append(ModalPoint(float(np.sqrt(m) * x), float(x), float(w), float(xi), float(xi / (2 * w)),
                              float(np.linalg.norm(U[2:]) / x), ok))
    return out


def sliding_frequency(m: float, k: float) -> float:
    """ω (rad/s) of the gross-slip limit: the slider transmits only F_s, the mode is √(k/m)."""
    return float(np.sqrt(k / m))


def tied_frequency(m: float, k: float, k_t: float) -> float:
    """ω (rad/s) of the stuck limit: √((k + k_t)/m)."""
    return float(np.sqrt((k + k_t) / m))
