"""Independent Floquet references for Hill's method (:mod:`workflow.engine.stability`, issue #49).

Nothing here uses the project's harmonic balance or contact law:

* :func:`duffing_monodromy` — ``m ẍ + c ẋ + k x + k3 x³ = F cos ωt``: the periodic orbit by
  shooting (period map, :func:`scipy.optimize.fsolve`) and its monodromy matrix from the
  variational equations integrated with it (DOP853, :data:`RTOL`);
* :func:`duffing_hb` / :func:`duffing_branch` — a small HB of the same oscillator (Galerkin on
  real Fourier coefficients, Newton with the analytic Jacobian, AFT by FFT) and its
  pseudo-arclength continuation over the folds, with the turning points located;
* :func:`jenkins_monodromy` — a structure with massless grounded Jenkins pads (spring in
  series with an exact Coulomb slider, normal load varying with the motion), integrated event
  by event (:class:`workflow.verification.timeint._Jenkins`: no regularisation), its steady
  state by shooting and its monodromy matrix by central finite differences of the period map
  over the state ``[x, v, w]`` (w the sliders' positions). The map is piecewise smooth; at a
  generic orbit the order of the stick/slip events does not change under the perturbation,
  so the difference quotient is its derivative (the saltation at the events included).

Units SI (m, s, N, kg); multipliers dimensionless.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

from workflow.verification.timeint import Pads, _Jenkins, jenkins_steady_state

RTOL = 1e-12
#: relative step of the finite-difference monodromy (central differences: error O(step²) from
#: the map's curvature, O(rtol/step) from the event-driven integration, rtol 1e-11 in
#: :mod:`workflow.verification.timeint`). Measured on the Jenkins oscillator of
#: tests/workflow/test_stability.py (2026-11-28; steps 1e-4…1e-8, rtol 1e-9…1e-12): at 1e-5
#: the largest multiplier moves by 1.2e-8 (ω = 1.3) and 8.5e-9 (ω = 1.2) when rtol goes to
#: 1e-12, and steps 1e-4…1e-6 agree to 2.4e-7; at 1e-8 the integration noise is 2.4e-5
FD_STEP = 1e-5


@dataclass
class Floquet:
    """A periodic orbit's state z0 at t = 0 and its monodromy matrix (dimensionless),
    multipliers sorted by decreasing modulus."""

    z0: np.ndarray
    monodromy: np.ndarray
    multipliers: np.ndarray
    residual: float

    @property
    def floquet_max(self) -> float:
        return float(np.abs(self.multipliers).max())


def _sorted_eig(Phi):
    mu = np.linalg.eigvals(Phi)
    return mu[np.argsort(-np.abs(mu))]


# ------------------------------------------------------------------ Duffing
def _duffing_rhs(p):
    m, c, k, k3, F, w = p

    def rhs(t, y):
        x, v = y[0], y[1]
        out = [v, (F * np.cos(w * t) - c * v - k * x - k3 * x ** 3) / m]
        if len(y) > 2:
            P = y[2:].reshape(2, 2)
            J = np.array([[0.0, 1.0], [-(k + 3 * k3 * x * x) / m, -c / m]])
            out = np.concatenate([out, (J @ P).ravel()])
        return out
    return rhs


def duffing_monodromy(m, c, k, k3, F, omega, z0) -> Floquet:
    """The periodic orbit of the Duffing oscillator near ``z0 = (x, ẋ)`` at t = 0 (shooting)
    and its monodromy from the variational equations."""
    p = (m, c, k, k3, F, omega)
    T = 2 * np.pi / omega
    rhs = _duffing_rhs(p)
    scale = np.array([1.0, omega]) * max(abs(z0[0]), 1e-300)

    def flow(z, var=False):
        y0 = np.concatenate([z, np.eye(2).ravel()]) if var else np.asarray(z, float)
        sol = solve_ivp(rhs, (0.0, T), y0, method="DOP853", rtol=RTOL, atol=RTOL * np.concatenate(
            [scale, np.ones(4)]) if var else RTOL * scale)
        return sol.y[:, -1]

    z = fsolve(lambda y: (flow(y) - y) / scale, np.asarray(z0, float), xtol=1e-13)
    end = flow(z, var=True)
    Phi = end[2:].reshape(2, 2)
    res = float(np.linalg.norm((end[:2] - z) / scale))
    return Floquet(z0=z, monodromy=Phi, multipliers=_sorted_eig(Phi), residual=res)


def _duffing_residual(a, omega, p, nh, nit):
    """Galerkin HB residual R(a) (2nh+1,) and dR/da, dR/dω of the Duffing oscillator;
    a = [x0, x1c, x1s, …] real coefficients (m), τ = ωt."""
    m, c, k, k3, F = p
    tau = 2 * np.pi * np.arange(nit) / nit
    j = np.arange(1, nh + 1)
    E = np.empty((nit, 2 * nh + 1))
    E[:, 0] = 1.0
    E[:, 1::2], E[:, 2::2] = np.cos(np.outer(tau, j)), np.sin(np.outer(tau, j))
    P = 2.0 / nit * E.T
    P[0] *= 0.5
    x = E @ a
    # linear part per harmonic on (c_j, s_j): (k − m(jω)²) I + cjω [[0, 1], [−1, 0]]
    L = np.zeros((2 * nh + 1, 2 * nh + 1))
    dL = np.zeros_like(L)
    L[0, 0] = k
    for h in j:
        i = 2 * h - 1
        L[i:i + 2, i:i + 2] = [[k - m * (h * omega) ** 2, c * h * omega], [-c * h * omega, k - m * (h * omega) ** 2]]
        dL[i:i + 2, i:i + 2] = [[-2 * m * h * h * omega, c * h], [-c * h, -2 * m * h * h * omega]]
    f = np.zeros(2 * nh + 1)
    f[1] = F
    R = L @ a + P @ (k3 * x ** 3) - f
    J = L + P @ ((3 * k3 * x * x)[:, None] * E)
    return R, J, dL @ a


def duffing_hb(m, c, k, k3, F, omega, nh=7, nit=64, a0=None, tol=1e-12, maxiter=50):
    """HB coefficients (2nh+1,) of the Duffing oscillator at ω by Newton (a0: start)."""
    p = (m, c, k, k3, F)
    a = np.zeros(2 * nh + 1) if a0 is None else np.array(a0, float)
    if a0 is None:
        a[1] = F / (k - m * omega ** 2)
    for _ in range(maxiter):
        R, J, _ = _duffing_residual(a, omega, p, nh, nit)
        if np.linalg.norm(R) <= tol * F:
            return a
        a = a - np.linalg.solve(J, R)
    raise RuntimeError("duffing_hb: Newton did not converge")


@dataclass
class Branch:
    """A continued HB branch: omegas (n,) rad/s, coefficients (n, 2nh+1) m, and the indices
    after which the branch turns in ω (a fold lies between point i and i+1)."""

    omegas: np.ndarray
    coef: np.ndarray
    turns: list

    def amplitude(self) -> np.ndarray:
        return np.hypot(self.coef[:, 1], self.coef[:, 2])


def duffing_branch(m, c, k, k3, F, w0, w1, *, nh=7, nit=64, ds=None, max_steps=2000) -> Branch:
    """Pseudo-arclength continuation (Keller) of the Duffing HB from ω = w0 to w1 (rad/s):
    tangent from the null vector of [J, dR/dω], predictor–corrector with the arclength
    constraint, the step halved on failure. The unknowns are scaled (a/A, ω/w0) with A the
    amplitude at the start, so the step ``ds`` is dimensionless (default |w1 − w0|/w0/100)."""
    p = (m, c, k, k3, F)
    a = duffing_hb(m, c, k, k3, F, w0, nh, nit)
    A = max(float(np.abs(a).max()), 1e-300)
    sc = np.concatenate([np.full(2 * nh + 1, A), [w0]])
    ds = abs(w1 - w0) / w0 / 100 if ds is None else ds
    y = np.concatenate([a, [w0]]) / sc
    direction = np.sign(w1 - w0)
    tprev = None
    ys = [y.copy()]
    for _ in range(max_steps):
        R, J, Rw = _duffing_residual(y[:-1] * A, y[-1] * w0, p, nh, nit)
        G = np.hstack([J * A, Rw[:, None] * w0])
        t = sla_null(G)
        if tprev is None:
            t = t * direction * np.sign(t[-1])
        elif t @ tprev < 0:
            t = -t
        h = ds
        while True:
            z = y + h * t
            ok = False
            for _ in range(20):
                R, J, Rw = _duffing_residual(z[:-1] * A, z[-1] * w0, p, nh, nit)
                G = np.hstack([J * A, Rw[:, None] * w0])
                r = np.concatenate([R / F, [t @ (z - y) - h]])
                if np.linalg.norm(r) < 1e-11:
                    ok = True
                    break
                z = z - np.linalg.solve(np.vstack([G / F, t]), r)
            if ok:
                break
            h /= 2
            if h < 1e-8 * ds:
                raise RuntimeError("duffing_branch: step too small")
        y, tprev = z, t
        ys.append(y.copy())
        if (y[-1] * w0 - w1) * direction >= 0:
            break
    Y = np.array(ys) * sc
    w = Y[:, -1]
    dw = np.diff(w)
    turns = [i for i in range(1, len(dw)) if np.sign(dw[i]) != np.sign(dw[i - 1])]
    return Branch(omegas=w, coef=Y[:, :-1], turns=turns)


def sla_null(G):
    """Unit null vector of the (n, n+1) matrix G (the last right singular vector)."""
    return np.linalg.svd(G)[2][-1]


def duffing_time(coef, omega, t):
    """x(t) (m) of HB coefficients at times t (s)."""
    nh = (len(coef) - 1) // 2
    j = np.arange(1, nh + 1)
    tau = omega * np.asarray(t)[:, None] * j
    return coef[0] + np.cos(tau) @ coef[1::2] + np.sin(tau) @ coef[2::2]


# ------------------------------------------------------------------ Jenkins pads
def jenkins_monodromy(M, C, K, f, omega: float, pads: Pads, *, fd_step: float = FD_STEP) -> tuple[Floquet, object]:
    """Monodromy of the steady state of a structure with massless grounded Jenkins pads
    (:func:`workflow.verification.timeint.jenkins_steady_state`, exact stick–slip) by central
    finite differences of the period map on ``[x, v, w]``; returns (Floquet, SteadyState)."""
    sys = _Jenkins(np.asarray(M, float), np.asarray(C, float), np.asarray(K, float), np.asarray(f, float),
                   omega, pads)
    n, p = sys.n, len(pads.dof)
    xs = sys.xs
    scale = np.concatenate([np.full(n, xs), np.full(n, xs * omega), np.full(p, xs)])
    ss = jenkins_steady_state(M, C, K, f, omega, pads)
    z = _periodic_state(sys, scale)
    Phi = np.empty((len(z), len(z)))
    for i in range(len(z)):
        h = fd_step * scale[i]
        e = np.zeros(len(z))
        e[i] = h
        Phi[:, i] = (sys.period(z + e)[0] - sys.period(z - e)[0]) / (2 * h)
    res = float(np.linalg.norm((sys.period(z)[0] - z) / scale))
    return Floquet(z0=z, monodromy=Phi, multipliers=_sorted_eig(Phi), residual=res), ss


def _periodic_state(sys, scale):
    """The steady state [x, v, w] at t = 0: march, then shoot on the period map."""
    z = np.zeros(len(scale))
    for _ in range(10):
        z = sys.period(z)[0]
    zs = fsolve(lambda y: (sys.period(y)[0] - y) / scale, z, xtol=1e-13)
    for _ in range(3):      # polish: the fixed point of an attracting orbit
        if np.linalg.norm((sys.period(zs)[0] - zs) / scale) < 1e-9:
            break
        zs = sys.period(zs)[0]
    return zs
