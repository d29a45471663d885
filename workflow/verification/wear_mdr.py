"""Partial-slip fretting wear of an elastic sphere: the worn steady state (issue 48, item 4 c).

A reference for the contact layer that uses none of the project's HB/DLFT code: the final,
no-wear state of an axisymmetric elastic contact under a fixed indentation and a tangential
oscillation in partial slip, in closed form, and an independent incremental march of the
method of dimensionality reduction (MDR) that reaches it.

Units SI (m, N, Pa, m²/N, cycles). References:

* [PH15]  V. L. Popov, M. Heß, *Method of Dimensionality Reduction in Contact Mechanics and
  Friction*, Springer 2015 — ch. 3 (normal contact of axisymmetric profiles), ch. 4
  (tangential contact, Cattaneo–Mindlin), ch. 13 (wear).
* [P14]   V. L. Popov, "Analytic solution for the limiting shape of profiles due to fretting
  wear", Sci. Rep. 4, 3749 (2014) — the MDR form of the final state below.
* [DDCP14] A. V. Dimaki, A. I. Dmitriev, Y. S. Chai, V. L. Popov, "Rapid simulation procedure
  for fretting wear on the basis of the method of dimensionality reduction", Int. J. Solids
  Struct. 51 (2014) 4215–4220 (cited in the issue as "Dimaki, Dmitriev, Chai, Popov 2016").
* [DVPP16] A. I. Dmitriev, L. B. Voll, S. G. Psakhie, V. L. Popov, "Universal limiting shape of
  worn profile under multiple-mode fretting conditions", Sci. Rep. 6, 23231 (2016).
* [CH99]  M. Ciavarella, D. A. Hills, "Some observations on oscillating tribological tests and
  the implications for fretting", Tribology International 32 (1999) — the existence of the final
  state (plane contacts): the slip zone unloads.

**MDR** ([PH15] ch. 3–4). A rigid axisymmetric indenter with gap profile f(r) on an elastic
half-space (effective moduli E* = [Σ(1−νᵢ²)/Eᵢ]⁻¹, G* = [Σ(2−νᵢ)/(4Gᵢ)]⁻¹) is replaced by a
Winkler bed of independent springs at spacing Δx, normal stiffness k_z = E*Δx, tangential
k_x = G*Δx, pressed onto the 1D profile

    g(x) = |x| ∫_0^|x| f'(r)/√(x²−r²) dr = |x| ∫_0^{π/2} f'(|x| sin θ) dθ,            (M1)
    f(r) = (2/π) ∫_0^r g(x)/√(r²−x²) dx = (2/π) ∫_0^{π/2} g(r sin θ) dθ   (the inverse), (M2)

with, at indentation d: spring compression w(x) = d − g(x) for |x| < a, g(a) = d (the contact
radius is the same in 1D and 3D), line load q(x) = E* w(x), normal force N = ∫ q dx, and

    p(r) = −(1/π) ∫_r^∞ q'(x)/√(x²−r²) dx                   (3D pressure),            (M3)
    u_z(r) = (2/π) ∫_0^a w(x)/√(r²−x²) dx,  r > a         (3D surface deflection outside). (M4)

Parabola f = r²/(2R): g = x²/R, a = √(Rd), N = (4/3)E*R^½d^{3/2}, p = (2E*/πR)√(a²−r²) (Hertz).

**Partial slip** ([PH15] ch. 4). Each spring is a Jenkins element: k_x in series with a Coulomb
slider of limit μ k_z w(x); the indenter moves tangentially u(t) = u₀ sin ωt. A spring slips iff
k_x u₀ > μ k_z w(x), so the stick radius c is where

    u₀ = μ (E*/G*) (d − g(c)),  parabola: c = a √(1 − G*u₀/(μE*d)),                      (C1)

and the tangential force at u₀ is Q = 2G*u₀c + 2μE*∫_c^a w dx = μN (1 − (c/a)³): Cattaneo–Mindlin,
exact in the MDR (c/a = (1 − Q/μN)^{1/3}). Over a steady cycle a slipping spring slides
s(x) = 4(u₀ − μE*w(x)/G*)₊ (the Jenkins slip (J) of :mod:`workflow.verification.wear_exact`).

**The worn steady state** ([CH99], [P14], [DVPP16]). Wear changes nothing where nothing slips:
the springs |x| < c keep their load, and with it (C1) keeps c (u₀, d fixed). A spring |x| > c
slips whatever its load (its load only falls as it wears), so it wears as long as it carries
load — under *any* law that wears where p > 0 and slip > 0 — and stops when it just touches
(assumed, as in [P14]: wear never lifts an annulus spring's load back above the stick threshold,
so the slip zone stays c < |x|; true in the independent-spring march, where loads only fall):

    g_∞(x) = g(x)  (|x| ≤ c),     g_∞(x) = d  (c < |x| ≤ a).                              (F1)

By (M2), which at r uses g on |x| < r only, the final 3D profile for r ≤ a is, for r > c,

    f_∞(r) = (2/π)[∫_0^c g(x)/√(r²−x²) dx + d arccos(c/r)]                              (F2)

(r < c: f_∞ = f) — a function of c and d alone, whatever the wear law or its coefficient. It is
the deflected half-space surface under the final load (M4) (touching at zero pressure; checked
without the MDR, by Boussinesq's kernel, :func:`boussinesq_deflection`). For the parabola the worn
depth h = f_∞ − f is

    h(r) = (1/π)[(2d − r²/R) arccos(c/r) − (c/R)√(r²−c²)],   c < r,                      (F3)

h(c) = 0 with an infinite slope (a punch-like edge), and the final load and pressure, by (M3)
with the jump of q at c (q = E*(d − x²/R) on |x| < c, 0 beyond),

    N_∞ = 2E*(dc − c³/(3R)),     p_∞(r) = E*(a² + c² − 2r²) / (πR √(c²−r²)),  r < c,       (F4)

square-root singular at the stick edge (the worn step acts as a punch corner), zero in the slip
annulus. The tangential force
amplitude falls to Q_∞ = 2G*u₀c (the stick zone alone; nothing slips, nothing dissipates).

*Beyond a.* As the annulus unloads, the half-space around the contact springs back towards the
indenter (M4 with a smaller load): the contact spreads and the wear scar with it. In 3D the
final profile is f_∞ = max(f, T) for r ≥ c, T the right side of (F2) for every r > c, so the
scar reaches the *touching radius* a_∞ > a where T(a_∞) = f(a_∞), i.e. h(a_∞) = 0 in (F3)
(a_∞ → a as c → a; → √2 a as c → 0). The independent-spring march below cannot follow this
(its springs |x| > a never touch; its per-spring law is not a local 3D law there), but the
profile on r ≤ a depends on g on |x| ≤ a only, so there its final state is (F2) exactly; its
a_∞ is read from its final loads by (M4) (:func:`touching_radius_from_loads`).

Limits: c → a (u₀ → 0, stick): h → 0, nothing wears; c → 0 (gross slip onset): f_∞ → d on
r ≤ √2 a — the indenter flattened to the indentation, unloaded (N_∞ → 0).

**The march** (:func:`march`), independent of (F1)–(F4): springs on 0 ≤ x ≤ 1.1a (the problem
is even in x: each spring stands for ±x), each a Jenkins element integrated incrementally over
each cycle of u₀ sin ωt (return mapping, ``steps_per_cycle`` samples; any multiple of 4
samples the turning points and gives the exact slip of a rate-independent element), and per
spring the wear per cycle

    dW/dn = k_w p_ref s_ref (p/p_ref)^α (s/s_ref)^β,   p = k_z(d − g − W)₊/(Δx ℓ),         (W)

ℓ = πa/2 (so the 1D pressure at the centre is Hertz's p₀), p_ref = p₀, s_ref = 4u₀; α = β = 1
is Archard's law, k_w p s. The wear opens the spring's gap (g → g + W). Cycle jumps: Heun's RK2
in the cycle count n, each stage one settling and one measured cycle of the element states,
local error ½h·max|r(W + hr) − r(W)| ≤ ``tol``·d; W is kept ≤ d − g (a spring wears no further
than to zero load: the ODE's own invariant). It stops when no slipping spring has a compression
above ``stop``·d: no law that wears only under load can wear any spring more than that.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import quad, trapezoid
from scipy.optimize import brentq
from scipy.special import ellipk

__all__ = ["MDRFretting", "CASE", "mdr_forward", "mdr_inverse", "mdr_pressure", "cells_inverse", "cells_pressure",
           "hertz", "stick_radius", "amplitude_for_stick", "cattaneo_mindlin_force", "worn_depth", "worn_profile",
           "worn_profile_quadrature", "touching_radius", "final_load", "final_pressure", "boussinesq_deflection",
           "spring_bed", "jenkins_cycle", "march", "touching_radius_from_loads", "compare", "mdr_rows"]

_GL = {}


def _gauss(n):
    """Gauss–Legendre nodes and weights on [0, 1] (cached)."""
    if n not in _GL:
        t, w = np.polynomial.legendre.leggauss(n)
        _GL[n] = (0.5 * (t + 1.0), 0.5 * w)
    return _GL[n]


def _panels(lo, hi, breaks, n):
    """Nodes and weights of n-point Gauss–Legendre on [lo, hi] split at the ``breaks`` inside."""
    edges = np.unique(np.r_[lo, [b for b in breaks if lo < b < hi], hi])
    t, w = _gauss(n)
    nodes = edges[:-1, None] + np.diff(edges)[:, None] * t
    return nodes.ravel(), (np.diff(edges)[:, None] * w).ravel()


# ------------------------------------------------------------------ MDR transforms
def mdr_forward(fprime, x, n: int = 64):
    """(M1): the 1D profile g(x) = |x| ∫_0^{π/2} f'(|x| sin θ) dθ (m) of a 3D profile with slope
    ``fprime(r)``; r = x sin θ removes the Abel kernel's singularity, so n-point Gauss–Legendre
    converges exponentially for an analytic f' (parabola: exact to rounding at n = 64)."""
    x = np.abs(np.atleast_1d(np.asarray(x, float)))
    th, w = _panels(0.0, 0.5 * np.pi, (), n)
    return x * (fprime(x[:, None] * np.sin(th)) @ w)


def mdr_inverse(g, r, n: int = 64, kinks=()):
    """(M2): the 3D profile f(r) = (2/π) ∫_0^{π/2} g(r sin θ) dθ (m) of a 1D profile ``g(x)``;
    the θ range is split where r sin θ crosses a kink or jump of g (``kinks``, m), so each panel
    is analytic and Gauss–Legendre converges exponentially."""
    r = np.atleast_1d(np.asarray(r, float))
    out = np.empty(r.size)
    for i, ri in enumerate(r):
        if ri == 0.0:
            out[i] = float(g(np.array([0.0]))[0])
            continue
        br = [math.asin(k / ri) for k in kinks if 0.0 < k < ri]
        th, w = _panels(0.0, 0.5 * np.pi, br, n)
        out[i] = 2.0 / np.pi * (g(ri * np.sin(th)) @ w)
    return out


def mdr_pressure(qprime, r, a, n: int = 64):
    """(M3) for a line load vanishing at |x| ≥ a with slope ``qprime(x)`` (N/m²): with
    x² = r² + t², p(r) = −(1/π) ∫_0^{√(a²−r²)} q'(x)/x dt (Pa) — no singular kernel left;
    Gauss–Legendre (Hertz: q'/x is constant, exact to rounding)."""
    r = np.atleast_1d(np.asarray(r, float))
    out = np.zeros(r.size)
    for i, ri in enumerate(r):
        if ri >= a:
            continue
        t, w = _panels(0.0, math.sqrt(a * a - ri * ri), (), n)
        x = np.sqrt(ri * ri + t * t)
        out[i] = -(qprime(x) / x) @ w / np.pi
    return out


def _arcsin_cells(faces, r):
    """(m, k) matrix A_ij = arcsin(min(X_{j+1}, r_i)/r_i) − arcsin(min(X_j, r_i)/r_i): the exact
    ∫ dx/√(r²−x²) over cell j cut at r (0 for r = 0 except the cell holding 0, weight π/2)."""
    r = np.atleast_1d(np.asarray(r, float))[:, None]
    X = np.asarray(faces, float)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        S = np.where(r > 0, np.arcsin(np.minimum(X / np.where(r > 0, r, 1.0), 1.0)), np.where(X > 0, 0.5 * np.pi, 0.0))
    return np.diff(S, axis=1)


def cells_inverse(faces, values, r):
    """(M2) for a 1D function constant on the cells [X_j, X_{j+1}] (``values`` per cell):
    (2/π) Σ_j v_j ∫_cell∩[0,r] dx/√(r²−x²), exact — no quadrature error. Used for the march's
    worn depth (values W) and, with r > a, its deflection (M4) (values the compressions)."""
    return 2.0 / np.pi * (_arcsin_cells(faces, r) @ np.asarray(values, float))


def cells_pressure(faces, q, r):
    """(M3) for a line load q (N/m) constant on the cells (0 beyond the last face): q' is the
    jumps at the faces, p(r) = (1/π) Σ_{X_j > r} (q_{j−1} − q_j)/√(X_j² − r²) (Pa). Exact for the
    step function; for a sampled smooth q its error is O(Δx) away from the faces."""
    X = np.asarray(faces, float)[1:]
    q = np.asarray(q, float)
    jump = q - np.r_[q[1:], 0.0]                 # q_left − q_right at face X_{j+1}
    r = np.atleast_1d(np.asarray(r, float))[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(X[None, :] > r, 1.0 / np.sqrt(np.maximum(X[None, :] ** 2 - r ** 2, 1e-300)), 0.0)
    return (k @ jump) / np.pi


# ------------------------------------------------------------------ closed forms, parabola f = r²/(2R)
def hertz(E_star, R, d) -> dict:
    """Unworn Hertz contact: {a (m), N (N), p0 (Pa)}: a = √(Rd), N = (4/3)E*R^½d^{3/2},
    p0 = 2E*a/(πR)."""
    a = math.sqrt(R * d)
    return {"a": a, "N": 4.0 / 3.0 * E_star * math.sqrt(R) * d ** 1.5, "p0": 2.0 * E_star * a / (np.pi * R)}


def stick_radius(E_star, G_star, R, d, mu, u0) -> float:
    """(C1): c = a √(1 − G*u₀/(μE*d)) (m); 0 at and above the gross-slip amplitude μE*d/G*."""
    return math.sqrt(R * d) * math.sqrt(max(1.0 - G_star * u0 / (mu * E_star * d), 0.0))


def amplitude_for_stick(E_star, G_star, R, d, mu, c) -> float:
    """(C1) inverted: the amplitude u₀ = μ(E*/G*)(d − c²/R) (m) that gives the stick radius c."""
    return mu * E_star / G_star * (d - c * c / R)


def cattaneo_mindlin_force(E_star, G_star, R, d, mu, u0) -> float:
    """Tangential force at u₀ (first loading or turning point, N): μN(1 − (c/a)³)."""
    h = hertz(E_star, R, d)
    c = stick_radius(E_star, G_star, R, d, mu, u0)
    return mu * h["N"] * (1.0 - (c / h["a"]) ** 3)


def worn_depth(r, R, d, c):
    """(F3), the final worn depth h(r) = f_∞(r) − f(r) (m): 0 for r ≤ c, (T − f)₊ beyond,
    (1/π)[(2d − r²/R) arccos(c/r) − (c/R)√(r²−c²)] up to the touching radius, 0 past it."""
    r = np.atleast_1d(np.asarray(r, float))
    out = np.zeros(r.size)
    m = r > c
    rm = r[m]
    acos = np.arccos(np.clip(c / rm, -1.0, 1.0))
    out[m] = ((2.0 * d - rm * rm / R) * acos - c / R * np.sqrt(rm * rm - c * c)) / np.pi
    return np.maximum(out, 0.0)


def worn_profile(r, R, d, c):
    """(F2), the final 3D gap profile f_∞(r) = r²/(2R) + h(r) (m)."""
    r = np.atleast_1d(np.asarray(r, float))
    return r * r / (2.0 * R) + worn_depth(r, R, d, c)


def worn_profile_quadrature(r, g, d, c, n: int = 64):
    """(F2) for any 1D profile ``g`` by (M2) of (F1) — g on |x| ≤ c, d beyond — split at c
    (the jump) and max'd with the unworn f = (M2) of g (beyond the touching radius): the general
    closed form, by Gauss–Legendre in θ on analytic panels (exponential convergence)."""
    G = lambda x: np.where(np.abs(x) <= c, g(x), d)  # noqa: E731
    T = mdr_inverse(G, r, n, kinks=(c,))
    return np.maximum(T, mdr_inverse(g, r, n))


def touching_radius(R, d, c) -> float:
    """a_∞ (m): where the final scar ends, h(a_∞) = 0 in (F3) on (a, √2a]; a at c = a."""
    a = math.sqrt(R * d)
    if c >= a:
        return a
    if c <= 0.0:
        return math.sqrt(2.0) * a
    f = lambda rr: (2 * d - rr * rr / R) * math.acos(c / rr) - c / R * math.sqrt(rr * rr - c * c)  # noqa: E731
    if f(a) <= 0.0:                  # c within rounding of a: h(a) = O((a − c)^{3/2}) is lost to rounding
        return a
    return brentq(f, a, math.sqrt(2.0) * a, xtol=1e-15 * a, rtol=1e-15)


def final_load(E_star, R, d, c) -> float:
    """(F4), the final normal force N_∞ = 2E*(dc − c³/(3R)) (N): the stick zone's, unchanged."""
    return 2.0 * E_star * (d * c - c ** 3 / (3.0 * R))


def final_pressure(r, E_star, R, d, c):
    """(F4), p_∞(r) = E*(Rd + c² − 2r²)/(πR√(c²−r²)) for r < c, 0 beyond (Pa)."""
    r = np.atleast_1d(np.asarray(r, float))
    out = np.zeros(r.size)
    m = r < c
    out[m] = E_star * (R * d + c * c - 2 * r[m] ** 2) / (np.pi * R * np.sqrt(c * c - r[m] ** 2))
    return out


def boussinesq_deflection(r, p_regular, c, E_star, epsabs=0.0, epsrel=1e-11):
    """Surface deflection (m) of a half-space under an axisymmetric pressure on r < c, by
    Boussinesq's ring kernel — 3D elasticity, no MDR: w(r) = (4/(πE*)) ∫_0^c p(s) s/(r+s)
    K(4rs/(r+s)²) ds, K the complete elliptic integral (parameter m). ``p_regular(s)`` =
    p(s)√(c²−s²) (regular for a square-root-singular p); s = c sin θ absorbs the singularity,
    the kernel's log singularity at s = r is a break point of ``quad``."""
    out = []
    for ri in np.atleast_1d(np.asarray(r, float)):
        def f(th, ri=ri):
            s = c * math.sin(th)
            m = 4.0 * ri * s / (ri + s) ** 2 if ri + s > 0 else 0.0
            return float(p_regular(s)) * s / (ri + s) * float(ellipk(min(m, 1.0 - 1e-16))) if ri + s > 0 else 0.0

        pts = [math.asin(ri / c)] if 0.0 < ri < c else None
        val, _ = quad(f, 0.0, 0.5 * np.pi, points=pts, limit=400, epsabs=epsabs, epsrel=epsrel)
        out.append(4.0 / (np.pi * E_star) * val)
    return np.array(out)


# ------------------------------------------------------------------ the case
@dataclass(frozen=True)
class MDRFretting:
    """A parabolic indenter (radius R) at indentation d, tangential amplitude u₀; E*, G* (Pa)
    effective moduli, μ, Archard k_w (m²/N)."""

    E_star: float
    G_star: float
    R: float
    d: float
    mu: float
    u0: float
    k_w: float

    @classmethod
    def with_stick_ratio(cls, ratio, **kw):
        """The case whose unworn stick radius is ``ratio``·a (u₀ by (C1))."""
        a = math.sqrt(kw["R"] * kw["d"])
        u0 = amplitude_for_stick(kw["E_star"], kw["G_star"], kw["R"], kw["d"], kw["mu"], ratio * a)
        return cls(u0=u0, **kw)

    @property
    def a(self) -> float:
        return math.sqrt(self.R * self.d)

    @property
    def c(self) -> float:
        return stick_radius(self.E_star, self.G_star, self.R, self.d, self.mu, self.u0)

    @property
    def unworn(self) -> dict:
        return hertz(self.E_star, self.R, self.d)

    def final(self) -> dict:
        """The worn steady state in closed form: {c, a_inf (m), N (N), p_centre (Pa), Q (N)}."""
        c = self.c
        return {"c": c, "a_inf": touching_radius(self.R, self.d, c), "N": final_load(self.E_star, self.R, self.d, c),
                "p_centre": float(final_pressure(0.0, self.E_star, self.R, self.d, c)[0]),
                "Q": 2.0 * self.G_star * self.u0 * c}

    def depth(self, r):
        return worn_depth(r, self.R, self.d, self.c)

    def profile(self, r):
        return worn_profile(r, self.R, self.d, self.c)


def _ti64() -> dict:
    """Ti-6Al-4V on Ti-6Al-4V (fan-blade dovetails): E = 115 GPa, ν = 0.32, two elastic bodies."""
    E, nu = 115e9, 0.32
    G = E / (2 * (1 + nu))
    return {"E_star": E / (2 * (1 - nu * nu)), "G_star": 4 * G / (2 * (2 - nu))}


#: R = 10 mm, d = 1 µm (a = 100 µm, N₀ = 8.5 N, p₀ = 408 MPa), μ = 0.6, c/a = 0.6 (u₀ = 0.47 µm),
#: k_w = 1e-15 m²/N.
CASE = MDRFretting.with_stick_ratio(0.6, R=1e-2, d=1e-6, mu=0.6, k_w=1e-15, **_ti64())


# ------------------------------------------------------------------ the march (independent of F1–F4)
def spring_bed(case: MDRFretting, n_springs: int, extent: float = 1.1) -> dict:
    """The 1D bed on 0 ≤ x ≤ extent·a, n cells: {faces (n+1,), x (n,) midpoints, dx, g (n,) =
    x²/R, k_z = E*Δx, k_x = G*Δx (N/m), delta (n,) = (d − g)₊ the unworn compressions (m)}."""
    faces = np.linspace(0.0, extent * case.a, n_springs + 1)
    x = 0.5 * (faces[1:] + faces[:-1])
    dx = faces[1] - faces[0]
    g = x * x / case.R
    return {"faces": faces, "x": x, "dx": dx, "g": g, "k_z": case.E_star * dx, "k_x": case.G_star * dx,
            "delta": np.maximum(case.d - g, 0.0)}


def jenkins_cycle(z, limit, k_x, u0, steps: int):
    """One period of u(t) = u₀ sin(2πk/steps), k = 1..steps, on Jenkins elements (slider
    positions z (m), slider limits μF (N), spring k_x): return mapping per sample. Returns
    (z, slip path (m), tangential force at u = u₀ (N), friction work (J))."""
    z = np.array(z, float)
    slip = np.zeros_like(z)
    tau_peak = None
    for k in range(1, steps + 1):
        u = u0 * math.sin(2.0 * math.pi * k / steps)
        tau = k_x * (u - z)
        over = np.abs(tau) - limit
        m = over > 0.0
        dz = np.where(m, np.sign(tau) * over / k_x, 0.0)
        z += dz
        slip += np.abs(dz)
        if 4 * k == steps:
            tau_peak = k_x * (u - z)
    return z, slip, tau_peak, float(np.sum(limit * slip))


def _rates(case, bed, W, z, steps, alpha, beta, k_w, p_ref, s_ref, ell):
    """Wear per cycle (m/cycle) of every spring at depths W (law W), from one settling and one
    measured cycle starting from the slider states z. Returns (rate, z, slip, Q, work)."""
    F = bed["k_z"] * np.maximum(bed["delta"] - W, 0.0)
    lim = case.mu * F
    z, _, _, _ = jenkins_cycle(z, lim, bed["k_x"], case.u0, steps)      # the state after a jump settles
    z, s, tau, work = jenkins_cycle(z, lim, bed["k_x"], case.u0, steps)
    p = F / (bed["dx"] * ell)
    rate = k_w * p_ref * s_ref * (p / p_ref) ** alpha * (s / s_ref) ** beta
    return np.where((F > 0) & (s > 0), rate, 0.0), z, s, 2.0 * float(np.sum(tau)), 2.0 * work


def march(case: MDRFretting = CASE, n_springs: int = 400, *, tol: float = 1e-4, stop: float = 1e-4,
          steps_per_cycle: int = 16, alpha: float = 1.0, beta: float = 1.0, k_w: float | None = None,
          max_steps: int = 5000) -> dict:
    """The incremental MDR march to the worn steady state (module docstring, law (W)).

    Returns {bed, W (n,) final depths (m), F (n,) final spring loads (N), stick (n,) bool (no slip
    in the last cycle), n (k,) cycles, N (k,) normal force (N, both sides), Q (k,) tangential
    force at u₀ (N), work (k,) friction energy per cycle (J), worn_area (k,) 2ΣW Δx (m²),
    stick_load (k,) the load of the springs stuck at the start (N), steps, rejected, evaluations,
    seconds}."""
    if steps_per_cycle % 4:
        raise ValueError("steps_per_cycle must be a multiple of 4 (the turning points must be sampled)")
    t0 = time.perf_counter()
    k_w = case.k_w if k_w is None else k_w
    bed = spring_bed(case, n_springs)
    un = case.unworn
    law = dict(alpha=alpha, beta=beta, k_w=k_w, p_ref=un["p0"], s_ref=4.0 * case.u0, ell=0.5 * np.pi * case.a)
    d, delta = case.d, bed["delta"]
    W = np.zeros(n_springs)
    z = np.zeros(n_springs)
    r, z, s, Q, work = _rates(case, bed, W, z, steps_per_cycle, **law)
    stuck0 = (s == 0.0) & (delta > 0)
    evals = 1
    hist = {k: [] for k in ("n", "N", "Q", "work", "worn_area", "stick_load")}

    def record(n):
        F = bed["k_z"] * np.maximum(delta - W, 0.0)
        hist["n"].append(n), hist["N"].append(2.0 * F.sum()), hist["Q"].append(Q), hist["work"].append(work)
        hist["worn_area"].append(2.0 * W.sum() * bed["dx"]), hist["stick_load"].append(2.0 * F[stuck0].sum())

    n, steps, rejected = 0.0, 0, 0
    record(n)
    h = 0.01 * d / max(float(r.max()), 1e-300)
    while steps < max_steps:
        left = np.where(s > 0, delta - W, 0.0)          # compressions still to wear, slipping springs
        if float(left.max()) <= stop * d:
            break
        Wp = np.minimum(W + h * r, delta)
        rp, _, _, _, _ = _rates(case, bed, Wp, z, steps_per_cycle, **law)
        evals += 1
        err = 0.5 * h * float(np.max(np.abs(rp - r)))
        if err <= tol * d:
            W = np.minimum(W + 0.5 * h * (r + rp), delta)
            n += h
            r, z, s, Q, work = _rates(case, bed, W, z, steps_per_cycle, **law)
            evals += 1
            steps += 1
            record(n)
        else:
            rejected += 1
        # RK2: error ∝ h³ → step factor (tol/err)^{1/3}, bounded like OscillatorWear.march
        h *= min(4.0, max(0.2, 0.9 * (tol * d / max(err, 1e-300)) ** (1.0 / 3.0)))
    F = bed["k_z"] * np.maximum(delta - W, 0.0)
    return {"bed": bed, "W": W, "F": F, "stick": (s == 0.0) & (F > 0), **{k: np.array(v) for k, v in hist.items()},
            "steps": steps, "rejected": rejected, "evaluations": evals, "converged": steps < max_steps,
            "seconds": time.perf_counter() - t0}


def touching_radius_from_loads(case: MDRFretting, faces, F, k_z) -> float:
    """a_∞ (m) read from a final 1D state: the unworn f = r²/(2R) meets the surface deflected by
    the final compressions w_j = F_j/k_z (M4, exact per cell) at r > a: d − w(r) = f(r)."""
    w = np.asarray(F, float) / k_z
    gap = lambda rr: case.d - float(cells_inverse(faces, w, rr)[0]) - rr * rr / (2.0 * case.R)  # noqa: E731
    a = case.a
    return brentq(gap, a * (1 + 1e-9), math.sqrt(2.0) * a, xtol=1e-12 * a)


def _l2(r, y):
    """RMS over the disc 0 ≤ r ≤ r_max (area-weighted), √(∫ y² 2πr dr / (π r_max²)) (trapezoid)."""
    return math.sqrt(float(trapezoid(y * y * 2 * r, r)) / float(r[-1]) ** 2)


def compare(case: MDRFretting, result: dict, n_r: int = 4001) -> dict:
    """The march's final state against (F1)–(F4): {depth_l2 (relative RMS error over the disc
    r ≤ a, area-weighted), profile_l2 (the same for f_∞), depth_rms, profile_rms (m), c, a_inf (m),
    N (N), p_centre (Pa), Q (N) — each a pair (march, exact)}. The march's 3D depth is (M2) of
    its W, exact per cell (:func:`cells_inverse`); its c the first face past the stuck springs,
    its p(0) (M3) of its cell loads, its a_∞ by :func:`touching_radius_from_loads`."""
    bed = result["bed"]
    r = np.linspace(0.0, case.a, n_r)
    hm = cells_inverse(bed["faces"], result["W"], r)
    he = case.depth(r)
    fm, fe = r * r / (2 * case.R) + hm, case.profile(r)
    ex = case.final()
    stick = result["stick"]
    c_m = float(bed["faces"][np.argmin(stick)]) if not stick.all() else float(bed["faces"][-1])
    q = result["F"] / bed["dx"]
    return {"depth_l2": _l2(r, hm - he) / _l2(r, he), "profile_l2": _l2(r, fm - fe) / _l2(r, fe),
            "depth_rms": (_l2(r, hm), _l2(r, he)), "profile_rms": (_l2(r, fm), _l2(r, fe)),
            "c": (c_m, ex["c"]),
            "a_inf": (touching_radius_from_loads(case, bed["faces"], result["F"], bed["k_z"]), ex["a_inf"]),
            "N": (float(result["N"][-1]), ex["N"]),
            "p_centre": (float(cells_pressure(bed["faces"], q, 0.0)[0]), ex["p_centre"]),
            "Q": (float(result["Q"][-1]), ex["Q"])}


# ------------------------------------------------------------------ rows
def _row(case, quantity, value, exact, scale=None) -> dict:
    """One row (the format of :func:`workflow.verification.wear_runner.row`)."""
    s = abs(exact) if scale is None else scale
    err = abs(value - exact) / s if s > 0 else abs(value - exact)
    return {"case": case, "quantity": quantity, "value": float(value), "exact": float(exact), "error": float(err)}


def mdr_rows(quick: bool = False) -> list[dict]:
    """Rows (case "mdr_partial_slip", quantity, value, exact, error) of the MDR march against the
    closed form (CASE: c/a = 0.6; 1600 springs, 400 with ``quick``; ≈ 1.4 s, 0.3 s quick). Not quick:
    also the march under a non-Archard law (α = 2, β = ½) against the same closed form ("whatever
    the wear law"). The errors are first order in the spring spacing Δx (the stick edge c falls
    inside a cell: the worn-depth L2 error is ≈ 5|Δc|/c). Measured (2026-11-28, one core): quick
    0.3 s, worn depth 4.4e-3, profile 1.5e-3, c 8.3e-4, a_∞ 1.8e-4, N_∞ 6.1e-4, p_∞(0) 8.2e-4,
    Q_∞ 8.3e-4; full 1.4 s, Archard 1.6e-3 / 5.4e-4 / 3.1e-4 / 6.9e-5 / 2.3e-4 / 4.5e-4 / 3.1e-4,
    α = 2, β = ½ 1.7e-3 / 5.8e-4 / 3.1e-4 / 9.1e-5 / 2.9e-4 / 4.7e-4 / 4.0e-4."""
    K = "mdr_partial_slip"
    case = CASE
    rows = []
    n_springs = 400 if quick else 1600
    bed = spring_bed(case, n_springs)
    un = case.unworn
    # the unworn bed: Hertz's load and Cattaneo–Mindlin's force (the first quarter cycle)
    F0 = bed["k_z"] * bed["delta"]
    rows.append(_row(K, f"unworn normal force [N] vs Hertz ({n_springs} springs)", 2 * F0.sum(), un["N"]))
    _, _, tau, _ = jenkins_cycle(np.zeros(n_springs), case.mu * F0, bed["k_x"], case.u0, 4)
    rows.append(_row(K, "unworn tangential force at u0 [N] vs Cattaneo-Mindlin", 2 * tau.sum(),
                     cattaneo_mindlin_force(case.E_star, case.G_star, case.R, case.d, case.mu, case.u0)))
    laws = [("Archard", 1.0, 1.0)] + ([] if quick else [("alpha=2, beta=0.5", 2.0, 0.5)])
    for name, al, be in laws:
        res = march(case, n_springs, alpha=al, beta=be)
        cmp_ = compare(case, res)
        tag = f"{name}, {n_springs} springs"
        rel = "error: relative RMS of the difference"
        rows.append({**_row(K, f"final worn depth, RMS over r <= a [m] ({rel}) ({tag})", *cmp_["depth_rms"]),
                     "error": cmp_["depth_l2"]})
        rows.append({**_row(K, f"final profile f_inf, RMS over r <= a [m] ({rel}) ({tag})", *cmp_["profile_rms"]),
                     "error": cmp_["profile_l2"]})
        rows.append(_row(K, f"final stick radius c [m] ({tag})", *cmp_["c"]))
        rows.append(_row(K, f"final touching radius a_inf [m] (contact spreads from a) ({tag})", *cmp_["a_inf"]))
        rows.append(_row(K, f"final normal force [N] ({tag})", *cmp_["N"]))
        rows.append(_row(K, f"final centre pressure [Pa] ({tag})", *cmp_["p_centre"]))
        rows.append(_row(K, f"final tangential force at u0 [N] ({tag})", *cmp_["Q"]))
        rows.append(_row(K, f"march: cycle-jump steps ({tag}, {res['seconds']:.1f} s)", float(res["steps"]),
                         float(res["steps"])))
    return rows
