"""The backbone by pseudo-arclength continuation in the modal amplitude: :func:`backbone` and its path."""
from __future__ import annotations

import time

import numpy as np

from workflow.engine import fourier
from workflow.engine.contact import ContactLaw
from workflow.engine.errors import SceneError, SolverError
from workflow.engine.solvers import newton
from workflow.engine.studies.nlmodes.epmc import _EPMC
from workflow.engine.studies.nlmodes.limits import _onset, _static, linear_limits
from workflow.engine.studies.nlmodes.results import Backbone, _backbone_of
from workflow.engine.studies.nlmodes.structure import _Structure
from workflow.engine.studies.nlmodes.walk import WALK_ITERATIONS, WALKS, _unbalanced_mean_slip

#: Newton's tolerance on the scaled residual (dimensionless: forces over the point's inertia
#: force ω² a ‖Mφ‖, the static rows over ‖F_0‖, the normalisation rows over a²)
TOL = 1e-9
#: shortest continuation step tried after a failure, relative to the longest
MIN_SHORT = 1.0 / 16
#: then longer steps, in units of the longest, before the backbone stops
JUMPS = (0.125, 0.25, 0.5, 1.0)
#: default range of the backbone in units of the first slip onset (:func:`_onset`)
DEFAULT_RANGE = (0.1, 3000.0)
#: default number of backbone points (log-spaced over the range)
DEFAULT_POINTS = 41


def backbone(model, law: ContactLaw, *, mode: int = 0, nh: int = 7, nit: int = 64, amplitudes=None,
             onset_range=None, max_passes: int = 30, maxiter: int = 15, tol: float = TOL, max_steps: int = 400,
             log=None) -> Backbone:
    """The EPMC backbone of tied mode ``mode`` (0: the lowest tied mode) of ``model`` under ``law``.

    ``amplitudes``: the range of modal amplitudes a (m·√kg) and the least number of points,
    ``(a_min, a_max, n)``; an increasing array means ``(first, last, len)``; None: from 0.1× to
    3000× the first slip onset of the tied mode (:func:`_onset`) in at least
    ``DEFAULT_POINTS`` — or ``onset_range`` = (from, to, n) in units of that onset. ``nh``, ``nit``: harmonics and DLFT time samples (HBM, nit ≥ 2Nh+1).
    ``log``: a callable taking a message, or None.

    Pseudo-arclength continuation from the tied linear mode at a_min, in the plane of
    (log a, log ω, log ξ) (dimensionless; a secant predictor on the harmonics / a): the points
    are where it stepped, at most ``log(a_max/a_min)/(n − 1)`` apart in that plane, closer where
    Newton needed it; it stops past a_max, after ``max_steps`` steps, or where even short steps
    fail (``stopped`` says why). A blade held only by its contacts has no periodic motion once
    every pair in contact slips during the cycle and the mean friction force cannot balance the
    static load: its mean position drifts (it walks); the path ends there, and ``stopped`` says
    so (:func:`_unbalanced_mean_slip`). On the quick sector that is a = 7.45e-4 m·√kg, 1.56 × the
    slip onset (2026-11-29; at Nh = 7 and at Nh = 11 alike). Raises :class:`SceneError` on bad
    options."""
    t_start = time.perf_counter()
    if not isinstance(law, ContactLaw):
        raise TypeError("law must be a ContactLaw")
    if law.p != model.n_pairs:
        raise SceneError(f"nonlinear modes: the law has {law.p} pairs, the model {model.n_pairs}")
    nh, nit = int(nh), int(nit)
    if nh < 1:
        raise SceneError(f"nonlinear modes: Nh = {nh} must be ≥ 1")
    fourier.check_nit(nit, nh)
    st = _Structure(model, mode)
    static, x0a, F0 = _static(st, law, max_passes)
    prob = _EPMC(st, law, nh, nit, static.anchor, F0, max_passes)
    onset = _onset(st, law, static)
    a_min, a_max, npts = _amplitude_range(amplitudes, onset_range, onset)
    lim = linear_limits(model, law, mode=mode, static=static)
    path = _Path(prob, st)
    out, stopped, steps = path.follow(x0a, a_min, a_max, npts, tol=tol, maxiter=maxiter, max_steps=max_steps,
                                      log=log)
    bb = _backbone_of(prob, st, law, out["a"], out["v"])
    n = len(out["a"])
    return Backbone(**bb, converged=np.ones(n, bool), residual=np.array(out["res"]),
                    iterations=np.array(out["it"], int), nh=nh, nit=nit, mode=st.mode,
                    tied_hz=lim["tied_hz"], tied_damping_ratio=lim["tied_damping_ratio"],
                    sliding_hz=lim["sliding_hz"], onset=onset, seconds=time.perf_counter() - t_start,
                    stopped=stopped, walks=stopped.startswith(WALKS), unknowns=np.array(out["v"]).reshape(n, prob.n),
                    info={"unknowns": prob.n, "tied_hz_undamped": st.omega_tied / (2 * np.pi),
                          "sliding_damping_ratio": lim["sliding_damping_ratio"], "range": (a_min, a_max, npts),
                          "steps": steps})


def _amplitude_range(amplitudes, onset_range, onset: float) -> tuple[float, float, int]:
    """(a_min, a_max, n) of :func:`backbone` from its ``amplitudes`` / ``onset_range`` (m·√kg)."""
    if amplitudes is None:
        if not np.isfinite(onset) or onset <= 0:
            raise SolverError("nonlinear modes: no slip onset of the tied mode (no pair in contact, or none "
                              "loaded by the mode): give the amplitudes")
        lo, hi, npts = onset_range or (*DEFAULT_RANGE, DEFAULT_POINTS)
        a_min, a_max, npts = float(lo) * onset, float(hi) * onset, int(npts)
    elif isinstance(amplitudes, tuple) and len(amplitudes) == 3:
        a_min, a_max, npts = float(amplitudes[0]), float(amplitudes[1]), int(amplitudes[2])
    else:
        arr = np.asarray(amplitudes, dtype=float).ravel()
        if arr.size == 0 or np.any(np.diff(arr) <= 0):
            raise SceneError("nonlinear modes: amplitudes must be increasing")
        a_min, a_max, npts = float(arr[0]), float(arr[-1]), arr.size
    if not (0 < a_min <= a_max and np.isfinite(a_max)):
        raise SceneError(f"nonlinear modes: amplitudes must be positive and increasing (got {a_min:g} … {a_max:g})")
    return a_min, a_max, npts


class _Path:
    """The continuation's unknowns z = [X / a on the scaled rows, ω, ξ, log a] and its
    arclength equation in the plane (log a, log ω, log ξ)."""

    def __init__(self, prob: "_EPMC", st: "_Structure"):
        self.prob, self.st = prob, st
        self.na, self.nx, self.nr = prob.na, prob.nx, prob.nr

    def denorm(self, z):
        a = float(np.exp(z[-1]))
        v = z[:-1].copy()
        v[self.na:self.nx] *= a
        return v, a

    def plane(self, z):
        """(log a, log ω, log ξ) of z and its gradient rows (3, n + 1)."""
        nx = self.nx
        _, w, xi = self.prob.split(z[:-1])
        G = np.zeros((3, z.size))
        G[0, -1] = 1.0
        G[1, nx] = 1.0 / w
        G[2, nx + 1] = 1.0 / xi
        # a Newton trial may step to ξ ≤ 0 (below the structural damping): its NaN row is the
        # line search's signal to shorten the step, not something to warn about
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.array([z[-1], np.log(w), np.log(xi)]), G

    def augmented(self, z, p_prev, t, ds, jac=True):
        """The EPMC residual and the arclength row ``t · (plane(z) − p_prev) = ds``, with their Jacobian."""
        prob, na, nx, nr = self.prob, self.na, self.nx, self.nr
        v, a = self.denorm(z)
        prob.a = a
        R, J, _ = prob.evaluate(v, jacobian=jac)
        pz, G = self.plane(z)
        Ra = np.concatenate([R, [t @ (pz - p_prev) - ds]])
        if not jac:
            return Ra, None
        dv = np.ones(prob.n)
        dv[na:nx] = a
        Ja = np.empty((prob.n + 1, prob.n + 1))
        Ja[:-1, :-1] = J * dv[None, :]
        X, omega, xi = prob.split(v)
        w1 = prob.first_harmonic(X, prob.cond(omega, xi))
        f = float(np.real(np.vdot(w1, self.st.Mt @ w1)))
        vs = np.zeros(prob.n)
        vs[na:nx] = v[na:nx]
        Js = J @ vs
        Js[nx] -= 2.0 * f / a ** 2
        Js[nx + 1] -= X[2, nr] / a
        Ja[:-1, -1] = Js
        Ja[-1] = t @ G
        return Ra, Ja

    def first(self, x0a, a_min: float, tol: float, maxiter: int):
        """The first point: natural parameter at a_min from the tied mode; (z, SolveResult)."""
        prob, st = self.prob, self.st
        X = np.zeros((prob.nc, self.na))
        X[0] = x0a
        X[1, self.nr] = a_min
        v0 = np.concatenate([X.ravel(), [st.omega_tied, st.xi_tied]])
        prob.weights(a_min)
        prob.a = a_min
        r = newton(lambda v: prob.evaluate(v)[:2], v0, fun=lambda v: prob.evaluate(v, False)[0],
                   tol=tol, scale=1.0, maxiter=maxiter)
        if not r.converged:
            raise SolverError(f"nonlinear modes: the first point (a = {a_min:.3g}, the tied mode) did not converge: "
                              f"{r.reason}")
        z = r.x.copy()
        z[self.na:self.nx] /= a_min
        return np.concatenate([z, [np.log(a_min)]]), r

    def follow(self, x0a, a_min, a_max, npts, *, tol, maxiter, max_steps, log):
        """Pseudo-arclength from a_min to past a_max (see :func:`backbone`): ({"a", "v", "res",
        "it"} over the points, why it stopped early or "", steps made)."""
        prob = self.prob
        s_min, s_max = np.log(a_min), np.log(a_max)
        ds_max = (s_max - s_min) / max(npts - 1, 1) if npts > 1 else 1.0
        z0, r = self.first(x0a, a_min, tol, maxiter)
        path = [z0]
        out = {"res": [r.residual_norm], "it": [r.iterations]}
        stopped = ""
        ds = min(ds_max, s_max - s_min) if s_max > s_min else 0.0
        steps = 0
        jumps, jumping = list(JUMPS), False
        # Newton's effort a step; cut once the blade is found to walk: the shorter steps that then
        # locate the mode's end converge in a few iterations or not at all (a failed full-effort
        # solve there spent ~5 s in line searches on the quick sector)
        effort, walk = dict(maxiter=maxiter), ""
        while ds > 0 and path[-1][-1] < s_max - 1e-12:
            steps += 1
            if steps > max_steps:
                stopped = f"{max_steps} continuation steps made (max_steps) before a_max"
                break
            p_prev, _ = self.plane(path[-1])
            if len(path) >= 2:
                d = self.plane(path[-1])[0] - self.plane(path[-2])[0]
                t = d / np.linalg.norm(d)
                zp = path[-1] + (path[-1] - path[-2]) * (ds / np.linalg.norm(d))
            else:
                t = np.array([1.0, 0.0, 0.0])
                zp = path[-1].copy()
                zp[-1] += ds
            prob.weights(float(np.exp(path[-1][-1])))
            r = newton(lambda zz: self.augmented(zz, p_prev, t, ds), zp,
                       fun=lambda zz: self.augmented(zz, p_prev, t, ds, False)[0], tol=tol, scale=1.0,
                       **effort)
            if r.converged:
                jumping = False
                path.append(r.x)
                out["res"].append(r.residual_norm)
                out["it"].append(r.iterations)
                if log is not None:
                    _, a = self.denorm(r.x)
                    _, w, xi = prob.split(r.x[:-1])
                    log(f"a = {a:.4g}: {w / (2 * np.pi):.4f} Hz, D = {xi / (2 * w):.3e}, {r.iterations} iterations")
                ds = min(ds * (1.5 if r.iterations <= 4 else 1.0), ds_max)
                jumps = list(JUMPS)
                continue
            # a failed step: shorter ones down to MIN_SHORT × ds_max, then longer ones (JUMPS × ds_max)
            # unless the blade walks there: a longer step cannot cross the end of the mode
            # once seen, the walking holds for the shorter steps: their cheap solves stop where
            # their own residual says less
            walk = _unbalanced_mean_slip(prob, *self.denorm(r.x)) or walk
            if walk:
                effort = dict(maxiter=min(maxiter, WALK_ITERATIONS), max_backtracks=WALK_ITERATIONS,
                              lm_fallback=False)
            if ds > MIN_SHORT * ds_max and not jumping:
                ds *= 0.5
                continue
            if jumps and not walk:
                jumping = True
                ds = jumps.pop(0) * ds_max
                continue
            stopped = (f"{WALKS} a = {np.exp(path[-1][-1]):.4g}: {walk}" if walk else
                       f"no convergence beyond a = {np.exp(path[-1][-1]):.4g} ({r.reason})")
            break
        out["a"] = [float(np.exp(z[-1])) for z in path]
        out["v"] = [self.denorm(z)[0] for z in path]
        return out, stopped, steps
