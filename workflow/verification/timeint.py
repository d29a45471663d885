"""Event-driven time integration of stick–slip oscillators (independent of the HB/DLFT code).

No regularisation: between events the motion is a linear ODE (one slip
direction, or stuck), integrated by :func:`scipy.integrate.solve_ivp`
(DOP853, tight tolerances) until an event of the current phase fires
(:data:`RTOL`, :data:`ATOL`); the phase then switches exactly as Coulomb's law says.

* :func:`coulomb_steady_state` — the 1-DOF oscillator
  ``m ẍ + c ẋ + k x + F_f sgn ẋ = F0 cos ωt`` of Den Hartog, with stops: the mass
  sticks (ẋ = 0) while ``|F0 cos ωt − k x| ≤ F_f``.
* :func:`jenkins_steady_state` — a linear structure ``M ẍ + C ẋ + K x + Σ f_i e_{a_i}
  = f cos ωt`` with massless Jenkins pads (spring k_i in series with a
  slider) grounded at DOF a_i, normal load ``N_i(t) = N0_i + c_iᵀ x`` (one-way
  normal coupling to the motion); stuck while ``|k_i (x_a − w_i)| ≤ μ N_i``.

Both run to a periodic steady state: a few forced periods, then shooting on the
period map (:func:`scipy.optimize.fsolve`), then more marching if the periodicity
residual is not small. The first-harmonic amplitude is taken by FFT of one
period sampled at :data:`SAMPLES` instants.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

from workflow.errors import SolverError

RTOL, ATOL_REL = 1e-11, 1e-13
SAMPLES = 1024
#: relative periodicity residual accepted as steady state ‖z(T) − z(0)‖ / ‖z‖
PERIODIC_TOL = 1e-7


@dataclass
class SteadyState:
    """One period of a steady state (SI units).

    t (n,) s, x (n, ndof) m sampled on [0, T); first (ndof,) first-harmonic
    amplitudes |X₁| (m); stick_fraction (n_elements,) share of the period
    each friction element is stuck; residual: relative periodicity residual;
    periods: forced periods integrated in all.
    """

    t: np.ndarray
    x: np.ndarray
    first: np.ndarray
    stick_fraction: np.ndarray
    residual: float
    periods: int


def _first_harmonic(x: np.ndarray) -> np.ndarray:
    return 2.0 * np.abs(np.fft.rfft(x, axis=0)[1]) / x.shape[0]


# ------------------------------------------------------------------ Coulomb, 1 DOF
def _coulomb_period(p, z0, t_samples=None):
    """Integrate one period from (x, v) = z0 at t = 0; returns (z(T), samples, stuck time)."""
    m, c, k, ff, f0, w = p
    T = 2 * np.pi / w
    t, z = 0.0, np.array(z0, float)
    out, stuck = [], 0.0
    scale = max(abs(f0) / k, 1e-300)
    leaving = False   # just left a stick phase: |drive| = F_f to rounding, slip in its direction
    while t < T * (1 - 1e-14):
        x, v = z
        drive = f0 * np.cos(w * t) - k * x
        if v != 0.0 or abs(drive) > ff or leaving:
            s = np.sign(v) if v != 0.0 else np.sign(drive)
            rhs = lambda tt, y, s=s: [y[1], (f0 * np.cos(w * tt) - k * y[0] - c * y[1] - s * ff) / m]  # noqa: E731
            ev = lambda tt, y, s=s: s * y[1]  # noqa: E731
            ev.terminal, ev.direction = True, -1
        else:
            stuck_x = x
            rhs = lambda tt, y: [0.0, 0.0]  # noqa: E731
            ev = lambda tt, y, x=stuck_x: abs(f0 * np.cos(w * tt) - k * x) - ff  # noqa: E731
            ev.terminal, ev.direction = True, 1
        # a stick phase has ẏ = 0: without a step limit the solver would stride
        # over the whole period and miss the exit (events are found between steps)
        sol = solve_ivp(rhs, (t, T), z, method="DOP853", events=ev, rtol=RTOL, atol=ATOL_REL * scale * np.array(
            [1.0, w]), dense_output=t_samples is not None, max_step=T / 256 if ev.direction == 1 else np.inf)
        t_end = sol.t_events[0][0] if sol.t_events[0].size else T
        if t_samples is not None:
            sel = (t_samples >= t) & (t_samples < t_end)
            if sel.any():
                out.append(sol.sol(t_samples[sel]).T[:, :1])
        leaving = ev.direction == 1 and bool(sol.t_events[0].size)
        if ev.direction == 1:   # a stick phase
            stuck += t_end - t
        z = sol.y_events[0][0] if sol.t_events[0].size else sol.y[:, -1]
        if sol.t_events[0].size and ev.direction == -1:
            z = np.array([z[0], 0.0])   # exactly at rest: the next phase is decided by the force
        if sol.t_events[0].size and t_end <= t + 1e-15 * T:
            raise SolverError("coulomb time integration: zero-length phase (chattering)")
        t = t_end
    samples = np.concatenate(out) if out else None
    return z, samples, stuck / T


def _steady(period_map, z0, scale, n_transient, max_periods):
    """March ``n_transient`` periods, shoot on the period map, march on until periodic.

    The shooting result is kept only if it is a fixed point to :data:`PERIODIC_TOL`
    (fsolve stops on small steps too, e.g. at a kink of the piecewise-smooth map);
    a state that is still not periodic after ``max_periods`` is a :class:`SolverError`.
    """
    rel = lambda a, b: float(np.linalg.norm((a - b) / scale) / max(np.linalg.norm(b / scale), 1e-300))  # noqa: E731
    z = np.array(z0, float)
    for _ in range(n_transient):
        z = period_map(z)
    periods = n_transient
    try:
        zs, info, _, _ = fsolve(lambda y: (period_map(y) - y) / scale, z, full_output=True, xtol=1e-12)
        periods += info["nfev"]
        # whatever ier says: at round-off fsolve reports "xtol not achievable" (ier = 5) on
        # some BLAS kernels for a fixed point that is exact to 1e-15
        if np.all(np.isfinite(zs)) and rel(period_map(zs), zs) <= PERIODIC_TOL:
            z = zs
    except SolverError:
        pass
    while True:
        z1 = period_map(z)
        periods += 1
        res = rel(z1, z)
        if res <= PERIODIC_TOL:
            return z, res, periods
        if periods >= max_periods:
            raise SolverError(f"time integration: no periodic steady state after {periods} periods "
                              f"(periodicity residual {res:.2e})")
        z = z1


def coulomb_steady_state(m: float, k: float, c: float, friction: float, force: float, omega: float, *,
                         n_transient: int = 8, max_periods: int = 4000, z0=None) -> SteadyState:
    """Periodic steady state of ``m ẍ + c ẋ + k x + F_f sgn ẋ = F0 cos ωt`` (stops included).

    Starts from ``z0 = (x, ẋ)`` at t = 0 (default: rest at the origin).
    """
    p = (m, c, k, friction, force, omega)
    scale = np.array([max(force / k, 1e-300), max(force / k, 1e-300) * omega])
    z, res, periods = _steady(lambda y: _coulomb_period(p, y)[0], np.zeros(2) if z0 is None else z0, scale,
                              n_transient, max_periods)
    ts = np.arange(SAMPLES) * 2 * np.pi / omega / SAMPLES
    _, x, stick = _coulomb_period(p, z, ts)
    return SteadyState(t=ts, x=x, first=_first_harmonic(x), stick_fraction=np.array([stick]), residual=res,
                       periods=periods + 1)


# ------------------------------------------------------------ Jenkins pads, n DOF
@dataclass(frozen=True)
class Pads:
    """Massless grounded Jenkins pads: pad i acts on DOF ``dof[i]`` through a spring
    ``k[i]`` (N/m) in series with a slider of limit ``mu·N_i``, ``N_i = N0[i] + cN[i]·x`` (N)."""

    dof: np.ndarray
    k: np.ndarray
    mu: float
    N0: np.ndarray
    cN: np.ndarray      # (p, n)


class _Jenkins:
    """The piecewise-linear ODE of a structure with Jenkins pads, one period at a time."""

    def __init__(self, M, C, K, f, omega, pads: Pads):
        self.Minv, self.C, self.K, self.f, self.w, self.pads = np.linalg.inv(M), C, K, f, omega, pads
        self.n = K.shape[0]
        xs = max(float(np.abs(np.linalg.solve(K, f)).max()), 1e-300)   # static deflection scale (m)
        self.xs = xs
        self.atol = ATOL_REL * np.concatenate([np.full(self.n, xs), np.full(self.n, xs * omega)])
        self.E = np.zeros((self.n, len(pads.dof)))
        self.E[pads.dof, np.arange(len(pads.dof))] = 1.0

    def normal(self, x):
        N = self.pads.N0 + self.pads.cN @ x
        return N

    def forces(self, x, stick, w, s):
        P = self.pads
        return np.where(stick, P.k * (x[P.dof] - w), s * P.mu * self.normal(x))

    def modes(self, x, v, w):
        """Stick flags and slip signs at a state with anchors w (slip: force at the limit, moving out)."""
        P = self.pads
        f = P.k * (x[P.dof] - w)
        lim = P.mu * self.normal(x)
        s = np.sign(f)
        out = s * (v[P.dof] - s * P.mu * (P.cN @ v) / P.k)
        if P.mu == 0.0:
            return np.zeros(len(P.dof), bool), s
        # beyond the cone (a perturbed shooting state) the pad cannot stick: slip
        return ~(((np.abs(f) >= lim * (1 - 1e-9)) & (out > 0)) | (np.abs(f) > lim * (1 + 1e-9))), s

    def period(self, z, t_samples=None):
        """z = [x, v, w] at t = 0 → z(T); with t_samples also x at those instants and stuck time per pad."""
        n, P, T = self.n, self.pads, 2 * np.pi / self.w
        x, v, w = z[:n], z[n:2 * n], np.array(z[2 * n:], float)
        stick, s = self.modes(x, v, w)
        t, y, out, stuck = 0.0, np.concatenate([x, v]), [], np.zeros(len(P.dof))
        while t < T * (1 - 1e-14):
            def rhs(tt, yy, stick=stick, w=w, s=s):
                xx, vv = yy[:n], yy[n:]
                acc = self.Minv @ (self.f * np.cos(self.w * tt) - self.C @ vv - self.K @ xx
                                   - self.E @ self.forces(xx, stick, w, s))
                return np.concatenate([vv, acc])
            events, pad_of = [], []
            for i in range(len(P.dof)):
                if P.mu == 0.0:     # a frictionless slider never sticks: no event, zero force
                    continue
                if stick[i]:
                    g = lambda tt, yy, i=i, w=w: abs(P.k[i] * (yy[P.dof[i]] - w[i])) - P.mu * self.normal(yy[:n])[i]  # noqa: E731
                    g.direction = 1
                else:
                    g = lambda tt, yy, i=i, s=s: s[i] * (yy[n + P.dof[i]] - s[i] * P.mu * (P.cN[i] @ yy[n:]) / P.k[i])  # noqa: E731
                    g.direction = -1
                g.terminal = True
                events.append(g)
                pad_of.append(i)
            sep = lambda tt, yy: float(np.min(self.normal(yy[:n])))  # noqa: E731
            sep.terminal, sep.direction = True, -1
            sol = solve_ivp(rhs, (t, T), y, method="DOP853", events=events + [sep], rtol=RTOL,
                            atol=self.atol, dense_output=True)
            hit = [i for i, te in enumerate(sol.t_events) if te.size]
            t_end = min((sol.t_events[i][0] for i in hit), default=T)
            if t_samples is not None:
                sel = (t_samples >= t) & (t_samples < t_end)
                if sel.any():
                    out.append(sol.sol(t_samples[sel]).T[:, :n])
            stuck += stick * (t_end - t)
            y = sol.sol(t_end) if hit else sol.y[:, -1]
            if len(events) in hit and sol.t_events[len(events)][0] <= t_end:
                raise SolverError("jenkins time integration: a pad's normal load reached 0 (separation is not "
                                  "modelled by this reference; lower the excitation or raise N0)")
            for e in hit:
                i = pad_of[e]
                if sol.t_events[e][0] > t_end * (1 + 1e-13) + 1e-300:
                    continue
                xx = y[:n]
                if stick[i]:
                    stick[i], s[i] = False, np.sign(P.k[i] * (xx[P.dof[i]] - w[i]))
                else:
                    stick[i], w[i] = True, xx[P.dof[i]] - s[i] * P.mu * self.normal(xx)[i] / P.k[i]
            if hit and t_end <= t + 1e-14 * T:
                raise SolverError("jenkins time integration: zero-length phase (chattering)")
            t = t_end
        x, v = y[:n], y[n:]
        w = np.where(stick, w, x[P.dof] - s * P.mu * self.normal(x) / P.k)
        return np.concatenate([x, v, w]), (np.concatenate(out) if out else None), stuck / T


def jenkins_steady_state(M, C, K, f, omega: float, pads: Pads, *, n_transient: int = 10,
                         max_periods: int = 2000) -> SteadyState:
    """Periodic steady state of a structure (M, C, K in SI, f the cos(ωt) force amplitude, N)
    with grounded Jenkins pads, from rest with the pads stuck at zero anchors. ``max_periods``:
    the pad chain at 1.027 ω₁ needs 455 periods to reach :data:`PERIODIC_TOL` (its slowest
    stick–slip transient; 400, the bound before, stopped it at a residual of 1.2e-5)."""
    sys = _Jenkins(np.asarray(M, float), np.asarray(C, float), np.asarray(K, float), np.asarray(f, float),
                   omega, pads)
    n, p = sys.n, len(pads.dof)
    xs = sys.xs
    scale = np.concatenate([np.full(n, xs), np.full(n, xs * omega), np.full(p, xs)])
    z, res, periods = _steady(lambda y: sys.period(y)[0], np.zeros(2 * n + p), scale, n_transient, max_periods)
    ts = np.arange(SAMPLES) * 2 * np.pi / omega / SAMPLES
    _, x, stick = sys.period(z, ts)
    return SteadyState(t=ts, x=x, first=_first_harmonic(x), stick_fraction=stick, residual=res,
                       periods=periods + 1)
