"""Galerkin harmonic balance of the Coulomb oscillator with the exact sign law.

The truncation floor of HB itself: ``m ẍ + c ẋ + k x + F_f sgn ẋ = F0 cos ωt``
balanced on harmonics 0…Nh, the friction force projected *exactly* — the
zeros of the trigonometric polynomial ẋ(τ) are found (a fine scan, then
:func:`scipy.optimize.brentq`) and ``sgn ẋ`` is integrated analytically
between them — and the equations solved by :func:`scipy.optimize.root`.
No penalty, no time grid, nothing of the project's DLFT: what remains is the
error of truncating the Fourier series. Valid where the mass never rests
(non-stop motion): the single-valued sign law cannot hold the mass stuck.

Real coefficients ``[a0, a1, b1, …, aN, bN]`` of ``x(τ) = a0 + Σ a_j cos jτ +
b_j sin jτ``, τ = ωt (m); residuals in N.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq, root

from workflow.verification.exact import describing_function


def _velocity(coef: np.ndarray, tau):
    """ẋ/ω at τ (m/rad)."""
    nh = (len(coef) - 1) // 2
    j = np.arange(1, nh + 1)
    a, b = coef[1::2], coef[2::2]
    tau = np.asarray(tau, float)[..., None]
    return np.sum(j * (-a * np.sin(j * tau) + b * np.cos(j * tau)), axis=-1)


def sign_projection(coef: np.ndarray) -> np.ndarray:
    """Fourier coefficients of ``sgn ẋ(τ)`` (dimensionless), exact up to root finding.

    ``[s0, s1c, s1s, …]`` with s0 = (1/2π)∫sgn, s_jc = (1/π)∫sgn cos jτ,
    s_js = (1/π)∫sgn sin jτ over one period.
    """
    nh = (len(coef) - 1) // 2
    grid = np.linspace(0.0, 2 * np.pi, 64 * nh + 65)
    v = _velocity(coef, grid)
    zeros = [brentq(lambda t: float(_velocity(coef, t)), grid[i], grid[i + 1], xtol=1e-15)
             for i in range(len(grid) - 1) if v[i] * v[i + 1] < 0]
    edges = np.concatenate([[0.0], zeros, [2 * np.pi]])
    mids = 0.5 * (edges[:-1] + edges[1:])
    sg = np.sign(_velocity(coef, mids))
    out = np.zeros(2 * nh + 1)
    out[0] = np.sum(sg * np.diff(edges)) / (2 * np.pi)
    for j in range(1, nh + 1):
        out[2 * j - 1] = np.sum(sg * (np.sin(j * edges[1:]) - np.sin(j * edges[:-1]))) / (j * np.pi)
        out[2 * j] = -np.sum(sg * (np.cos(j * edges[1:]) - np.cos(j * edges[:-1]))) / (j * np.pi)
    return out


def residual(coef, m, k, c, friction, force, omega):
    """Galerkin residual (N): linear part + F_f × projection of sgn ẋ − forcing."""
    nh = (len(coef) - 1) // 2
    r = np.empty_like(coef)
    r[0] = k * coef[0]
    for j in range(1, nh + 1):
        a, b = coef[2 * j - 1], coef[2 * j]
        d = k - (j * omega) ** 2 * m
        r[2 * j - 1] = d * a + c * j * omega * b
        r[2 * j] = d * b - c * j * omega * a
    r += friction * sign_projection(coef)
    r[1] -= force
    return r


def galerkin_hb(m: float, k: float, c: float, friction: float, force: float, omega: float, nh: int,
                start=None) -> tuple[np.ndarray, bool]:
    """(coefficients (2Nh+1,), converged) of the Galerkin HB with the exact sign law.

    Start: ``start`` (coefficients of any length, padded/truncated), else the
    describing-function first harmonic in quadrature with the friction force.
    """
    x0 = np.zeros(2 * nh + 1)
    if start is not None:
        s = np.asarray(start, float)[: 2 * nh + 1]
        x0[: len(s)] = s
    else:
        # x = X cos(τ − ψ): (k − mω²) X = F0 cos ψ and 4F_f/π + cωX = F0 sin ψ
        X = describing_function(m, k, friction, force, omega, c) or force / max(abs(k - m * omega ** 2), 1e-300)
        psi = np.arctan2(4 * friction / np.pi + c * omega * X, (k - m * omega ** 2) * X)
        x0[1], x0[2] = X * np.cos(psi), X * np.sin(psi)
    scale = max(abs(force), 1e-300)
    fun = lambda y: residual(y, m, k, c, friction, force, omega) / scale  # noqa: E731
    sol = root(fun, x0, method="hybr", options={"xtol": 1e-13})
    if not sol.success:   # the projection is only piecewise smooth: Levenberg–Marquardt as a fall-back
        sol = root(fun, sol.x, method="lm", options={"xtol": 1e-14, "ftol": 1e-14})
    ok = bool(sol.success) and float(np.linalg.norm(residual(sol.x, m, k, c, friction, force, omega))) <= 1e-8 * scale
    return sol.x, ok


def first_amplitude(coef: np.ndarray) -> float:
    """|X₁| = √(a1² + b1²) (m)."""
    return float(np.hypot(coef[1], coef[2]))
