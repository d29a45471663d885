"""Closed-form references for friction oscillators (independent of the HB/DLFT code).

* Den Hartog's steady state of the Coulomb oscillator without viscous damping,
  ``m ẍ + k x + F_f sgn(ẋ) = F0 cos(ωt + φ)``, in the non-stop regime (the
  mass reverses twice a period and never stays at rest): J. P. Den Hartog,
  "Forced vibrations with combined Coulomb and viscous friction", Trans. ASME
  APM-53-9 (1931) 107–115, and Phil. Mag. 9 (1930) 801–817. Written out here
  from the half-period boundary-value problem (see :func:`den_hartog`).
* The Jenkins element (spring k in series with a Coulomb slider of limit
  μN) driven at displacement amplitude a: energy dissipated per cycle
  ``4 μN (a − μN/k)`` for ``a > μN/k``, 0 otherwise (the area of the
  parallelogram hysteresis loop).
* The linear limits of the oscillator: tied (μ → ∞, the mass held: x = 0)
  and free (μ = 0), ``|X| = F0 / |k − mω² + i c ω|``.

Units: SI (kg, N/m, N, rad/s, m, J).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: samples of the closed-form waveform for its Fourier coefficients: the
#: waveform is C¹ with jumps of ẍ, so its coefficients decay like j⁻³ and the
#: trapezoidal rule's aliasing error on the first harmonic is ~(4096)⁻³.
WAVEFORM_SAMPLES = 4096


@dataclass(frozen=True)
class DenHartog:
    """The non-stop steady state (all lengths in m, angles in rad).

    peak        X0, the largest displacement over the period
    phase       φ of the forcing ``F0 cos(ωt + φ)`` when t = 0 is the instant
                of the displacement minimum −X0 (ẋ = 0)
    first       |X₁|, amplitude of the first harmonic of x(t)
    valid       True if the non-stop solution exists and is consistent
                (real amplitude, the mass breaks loose at each reversal,
                ẋ > 0 over the whole upward half period)
    reason      why not, when ``valid`` is False
    """

    peak: float
    phase: float
    first: float
    valid: bool
    reason: str


def _u(theta: float, beta: float) -> float:
    """Den Hartog's U(β) = sin θ / (β (1 + cos θ)), θ = π/β (1/1)."""
    return np.sin(theta) / (beta * (1.0 + np.cos(theta)))


def den_hartog(m: float, k: float, friction: float, force: float, omega: float) -> DenHartog:
    """Den Hartog's exact non-stop steady state of ``m ẍ + k x + F_f sgn ẋ = F0 cos(ωt + φ)``.

    With ω_n = √(k/m), β = ω/ω_n, θ = π/β, x_st = F0/k, r = F_f/F0, take t = 0
    at the displacement minimum (x = −X0, ẋ = 0). On the upward half period
    0 < ωt < π the motion is linear with the constant force −F_f:
    ``x = A cos ω_n t + B sin ω_n t + G cos(ωt + φ) − F_f/k``,
    ``G = x_st / (1 − β²)``. The four conditions x(0) = −X0, ẋ(0) = 0,
    x(π/ω) = X0, ẋ(π/ω) = 0 give ``B = G β sin φ``,
    ``A = G β sin φ (1 + cos θ)/sin θ``, ``G sin φ = (F_f/k) U(β)`` and
    ``X0 = −G cos φ``, hence Den Hartog's amplitude

        X0 / x_st = √( 1/(1 − β²)² − r² U(β)² ),   U = sin θ / (β (1 + cos θ)).

    Validity (non-stop), checked on the solution itself: X0 is real; at the
    reversal the net force on the resting mass, ``k β² X0`` (spring plus
    forcing at t = 0), exceeds F_f, so it does not stick; and ẋ > 0 on the
    whole open half period (no intermediate stop). Returns the peak X0, the
    phase φ and the first-harmonic amplitude |X₁| of the waveform.
    """
    wn = np.sqrt(k / m)
    beta = omega / wn
    theta = np.pi / beta
    x_st = force / k
    if abs(1.0 + np.cos(theta)) < 1e-12 or abs(1.0 - beta) < 1e-12:
        return DenHartog(np.nan, np.nan, np.nan, False, "β at a singularity of U(β) or at resonance")
    G = x_st / (1.0 - beta ** 2)
    Gs = friction / k * _u(theta, beta)
    disc = G ** 2 - Gs ** 2
    if disc <= 0.0:
        return DenHartog(np.nan, np.nan, np.nan, False, "1/(1−β²)² < r²U²: no real non-stop amplitude")
    X0 = np.sqrt(disc)
    # X0 = −G cos φ and G sin φ = Gs fix φ in its quadrant
    phase = float(np.arctan2(Gs / G, -X0 / G))
    t, x, v = den_hartog_waveform(m, k, friction, force, omega, X0, phase)
    half = (t > 0) & (t < np.pi / omega)
    reason = ""
    if k * beta ** 2 * X0 <= friction:
        reason = "k β² X0 ≤ F_f: the mass sticks at its reversals (stop regime)"
    elif np.any(v[half][1:-1] <= 0.0):
        reason = "ẋ vanishes inside the half period (multiple stops)"
    first = 2.0 * abs(np.fft.rfft(x)[1]) / len(x)
    return DenHartog(float(X0), phase, float(first), not reason, reason)


def nonstop_boundary(beta: float) -> float:
    """Largest friction ratio r = F_f/F0 for non-stop motion at β = ω/ω_n (dimensionless).

    The break-loose condition ``k β² X0 ≥ F_f`` with Den Hartog's X0 gives
    ``β⁴ (1/(1−β²)² − r² U²) ≥ r²``, i.e.

        r ≤ β² / ( |1 − β²| √(1 + β⁴ U(β)²) ),

    the boundary of Den Hartog's (1931) Fig. of the stop/non-stop regions. It is
    necessary; at low β (≲ 0.5) the motion can also stop inside a half period,
    which :func:`den_hartog` checks on the waveform.
    """
    theta = np.pi / beta
    return float(beta ** 2 / (abs(1.0 - beta ** 2) * np.sqrt(1.0 + beta ** 4 * _u(theta, beta) ** 2)))


def den_hartog_waveform(m, k, friction, force, omega, X0, phase, n: int = WAVEFORM_SAMPLES):
    """(t, x, ẋ) of the non-stop solution at n equally spaced instants of one period.

    The second half period is the first one mirrored, ``x(t + T/2) = −x(t)``
    (the forcing changes sign, and so does the friction force).
    """
    wn = np.sqrt(k / m)
    beta = omega / wn
    theta = np.pi / beta
    G = force / k / (1.0 - beta ** 2)
    B = G * beta * np.sin(phase)
    A = B * (1.0 + np.cos(theta)) / np.sin(theta)
    t = np.arange(n) * (2.0 * np.pi / omega) / n
    th = np.mod(t, np.pi / omega)
    sign = np.where(t < np.pi / omega, 1.0, -1.0)
    x = A * np.cos(wn * th) + B * np.sin(wn * th) + G * np.cos(omega * th + phase) - friction / k
    v = -A * wn * np.sin(wn * th) + B * wn * np.cos(wn * th) - G * omega * np.sin(omega * th + phase)
    return t, sign * x, sign * v


def describing_function(m: float, k: float, friction: float, force: float, omega: float, c: float = 0.0) -> float:
    """First-harmonic amplitude (m) of the one-harmonic balance with the exact sign law.

    The first harmonic of ``F_f sgn(ẋ)`` for ``x = X cos(ωt − ψ)`` is the
    force ``(4F_f/π)`` in phase with the velocity, so
    ``|(k − mω²) X|² + ((cω X + 4F_f/π))² = F0²``, solved for X ≥ 0
    (0 when 4F_f/π ≥ F0: no slipping first-harmonic solution).
    """
    a = (k - m * omega ** 2) ** 2 + (c * omega) ** 2
    b = 2.0 * c * omega * 4.0 * friction / np.pi
    cc = (4.0 * friction / np.pi) ** 2 - force ** 2
    disc = b * b - 4 * a * cc
    if cc >= 0.0 or disc < 0:
        return 0.0
    return float((-b + np.sqrt(disc)) / (2 * a))


def jenkins_energy(amplitude, k: float, slip_force: float):
    """Energy dissipated per cycle (J) by a Jenkins element at displacement amplitude a (m).

    ``4 μN (a − μN/k)`` when the slider slips (``a > μN/k``), else 0:
    the parallelogram loop has height 2μN and slip length 2(a − μN/k).
    """
    a = np.asarray(amplitude, dtype=float)
    return np.where(a > slip_force / k, 4.0 * slip_force * (a - slip_force / k), 0.0)


def free_amplitude(m: float, k: float, force: float, omega, c: float = 0.0):
    """μ = 0 limit: |X| = F0 / |k − mω² + i c ω| (m)."""
    w = np.asarray(omega, dtype=float)
    return force / np.abs(k - m * w ** 2 + 1j * c * w)
