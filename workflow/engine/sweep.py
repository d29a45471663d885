"""Frequency sweeps of harmonic-balance problems: stepped with a secant predictor,
and pseudo-arclength continuation in (x, ω) that follows turning points.

The linear part comes from ``linear(omega) -> (Zr, Fr, dZr, dFr)`` (omega in
rad/s; contracts §5: condensed stiffness/forcing per harmonic and their
ω-derivatives) and the problem from ``make_problem(Zr, Fr) -> HBProblem``.
The contact law does not depend on ω; ∂R/∂ω comes from dZr, dFr through
:meth:`workflow.engine.hb.HBProblem.residual_jacobian_omega`.

``observe(problem, x) -> float`` gives the amplitude reported per point (e.g.
the tip displacement recovered from the contact forces); the sweep sets
``problem.omega`` (rad/s) before calling it. ``progress(i, n)``
is called after each point when given.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from workflow.engine.errors import SolverError
from workflow.engine.solvers import SolveResult, newton, powell

__all__ = ["SweepPoint", "secant_guesses", "stepped_sweep", "continuation", "arclength_sweep"]

TWO_PI = 2.0 * np.pi


@dataclass
class SweepPoint:
    """One frequency point.

    frequency_hz  excitation frequency (Hz)
    omega         the same in rad/s
    x             unknowns of the HB problem at this point
    amplitude     observe(problem, x) (units of the observed quantity)
    iterations    solver iterations spent on this point
    seconds       wall time for this point (s)
    converged     the corrector met its tolerance
    reason        solver's reason string
    """

    frequency_hz: float
    omega: float
    x: np.ndarray
    amplitude: float
    iterations: int
    seconds: float
    converged: bool
    reason: str = ""


def _solve(fun, fun_jac, x0, solver, tol, scale, maxiter) -> SolveResult:
    if solver == "newton":
        return newton(fun_jac, x0, fun=fun, tol=tol, scale=scale, maxiter=maxiter)
    if solver == "powell":
        return powell(fun, fun_jac, x0, tol=tol, scale=scale, maxfev=40 * maxiter)
    raise SolverError(f"sweep.solver: {solver!r} is not one of newton, powell")


def secant_guesses(prev: list, omega: float) -> list:
    """Guesses at ``omega`` [rad/s] from the converged neighbours ``prev`` [(ω, x), …]
    (the nearest last): the secant through the last two, then the nearest root itself."""
    out = []
    if len(prev) >= 2:
        (w1, x1), (w2, x2) = prev[-2], prev[-1]
        out.append(x2 + (omega - w2) / (w2 - w1) * (x2 - x1))
    if prev:
        out.append(prev[-1][1])
    return out


def stepped_sweep(frequencies_hz, linear, make_problem, observe, *, x0=None, solver: str = "newton",
                  fallback: str | None = "powell", tol: float = 1e-9, maxiter: int = 50,
                  carry_stick: bool = True, progress=None) -> list[SweepPoint]:
    """Solve at each frequency in turn, predicting from the previous points.

    Predictor: the previous solution for the second point, then the secant
    through the last two (linear extrapolation in ω). A point that fails is
    retried from the previous solution, then from ``problem.x0()``, then with
    the ``fallback`` solver; it is recorded with ``converged=False`` if all
    fail and the sweep continues (the next predictor skips it).
    ``carry_stick``: hand the converged stick anchor of each point to the next
    (the history of a slow sweep); otherwise each point starts from its own
    static state.
    """
    freqs = np.asarray(frequencies_hz, dtype=float)
    points: list[SweepPoint] = []
    good: list[tuple[float, np.ndarray]] = []
    anchor = None
    for i, f in enumerate(freqs):
        t0 = time.perf_counter()
        w = TWO_PI * f
        Zr, Fr, _, _ = linear(w)
        pr = make_problem(Zr, Fr)
        pr.omega = w                      # for observe(); the problem itself is ω-free
        if anchor is not None:
            pr.set_stick_anchor(anchor)
        guesses = secant_guesses(good, w)
        if not good and x0 is not None:
            guesses.append(np.asarray(x0, dtype=float))
        guesses.append(pr.x0())
        scale = pr.residual_scale()
        its = 0
        res = None
        for solv in [solver] + ([fallback] if fallback and fallback != solver else []):
            for g in guesses:
                res = _solve(pr.residual, pr.residual_jacobian, g, solv, tol, scale, maxiter)
                its += res.iterations
                if res.converged:
                    break
            if res.converged:
                break
        if res.converged:
            good.append((w, res.x))
            if carry_stick:
                anchor = pr.stick_anchor_of(res.x)
        points.append(SweepPoint(frequency_hz=float(f), omega=w, x=res.x,
                                 amplitude=float(observe(pr, res.x)), iterations=its,
                                 seconds=time.perf_counter() - t0, converged=res.converged,
                                 reason=res.reason))
        if progress is not None:
            progress(i + 1, len(freqs))
    return points


def continuation(fun_jac_omega, x0, omega0: float, omega_end: float, *, ds: float = 0.05,
                 ds_min: float = 1e-5, ds_max: float = 0.5, max_steps: int = 500,
                 tol: float = 1e-9, scale: float = 1.0, maxiter: int = 15, solver: str = "newton",
                 x_scale: float | None = None, progress=None, callback=None):
    """Pseudo-arclength continuation of ``R(x, ω) = 0`` from ω0 towards ω_end.

    ``fun_jac_omega(x, omega) -> (R, J, dR/dω)``. Works on scaled unknowns
    ``z = (x/x_s, ω/ω0)`` (``x_s`` = ‖x_start‖∞ unless given) so that the arclength
    mixes dimensionless quantities (``x_s`` from the converged start point;
    give ``x_scale`` where that can be zero, e.g. an interface stuck at the start). Each step: tangent ``t`` from
    ``[J  R_ω; t_prevᵀ] t = [0; 1]`` (normalised), oriented along the secant
    of the last step, predictor
    ``z + ds·t``, corrector on ``R = 0`` plus the hyperplane
    ``tᵀ(z − z_pred) = 0`` with the chosen solver (Newton with line search, or
    Powell). ``ds`` (dimensionless arclength) halves on failure, grows ×1.5
    after an easy step, within [ds_min, ds_max]. Stops when ω passes
    ω_end, after ``max_steps``, or when ds falls below ds_min.

    The step that passes ω_end is replaced by the solution at ω_end itself
    (fixed ω, guessed between the last two points), so that the trace ends
    where the band does. A trace that did not reach ω_end ends with a record
    ``converged=False`` at its last point: ``reason`` starts with ``step below
    ds_min`` or with :data:`MAX_STEPS_REASON` — the band was not covered.

    Returns a list of dicts ``{x, omega, iterations, seconds, converged, reason}``,
    the first being the start point (solved at fixed ω0).
    """
    x = np.asarray(x0, dtype=float).copy()
    n = x.size
    w0 = float(omega0)
    direction = np.sign(omega_end - omega0) or 1.0
    ws = abs(w0) if w0 != 0 else 1.0

    def fx(x_, w_):
        return fun_jac_omega(x_, w_)

    # 1. converge the start point at fixed ω0
    t0 = time.perf_counter()
    start = _solve(lambda v: fx(v, w0)[0], lambda v: fx(v, w0)[:2], x, solver, tol, scale, 4 * maxiter)
    out = [dict(x=start.x, omega=w0, iterations=start.iterations, seconds=time.perf_counter() - t0,
                converged=start.converged, reason=start.reason)]
    if not start.converged:
        return out
    x, w = start.x, w0
    # from the converged start, not the guess: a stuck interface starts at u_r = 0
    xs = float(x_scale) if x_scale else max(float(np.abs(x).max()), 1e-30)
    _, J, Rw = fx(x, w)
    # initial tangent: J dx + R_ω dω = 0 with dω along the sweep direction
    dx = -np.linalg.solve(J, Rw)
    t = np.concatenate([dx * direction / xs, [direction / ws]]) * ws
    t /= np.linalg.norm(t)
    steps = 0
    while steps < max_steps:
        steps += 1
        ts = time.perf_counter()
        z = np.concatenate([x / xs, [w / ws]])
        res, ds = _correct(fx, z, t, ds, (xs, ws), ds_min, solver, tol, scale, maxiter)
        if not res.converged:
            out.append(dict(x=x, omega=w, iterations=res.iterations, seconds=time.perf_counter() - ts,
                            converged=False, reason=f"step below ds_min: {res.reason}"))
            return out
        znew = res.x
        x, w = znew[:n] * xs, znew[n] * ws
        t = _tangent(fx, x, w, znew - z, t, (xs, ws))
        rec = dict(x=x, omega=w, iterations=res.iterations, seconds=time.perf_counter() - ts,
                   converged=True, reason=res.reason)
        out.append(rec)
        if callback is not None:
            callback(rec)
        if progress is not None:
            progress(steps, max_steps)
        if res.iterations <= 3:
            ds = min(ds * 1.5, ds_max)
        if (w - omega_end) * direction >= 0:
            _land(fx, out, float(omega_end), solver, tol, scale, maxiter)
            return out
    out.append(dict(x=x, omega=w, iterations=0, seconds=0.0, converged=False,
                    reason=f"{MAX_STEPS_REASON} ({max_steps})"))
    return out


#: reason of the record that ends a continuation which ran out of steps before ω_end
MAX_STEPS_REASON = "continuation stopped after max_steps"


def _land(fx, out: list, omega_end: float, solver, tol, scale, maxiter) -> None:
    """Replace the last record of ``out`` (past ω_end) by the solution at ω_end, solved at
    fixed ω from the point between the last two records; kept as it is if that fails."""
    last, prev = out[-1], out[-2]
    if last["omega"] == omega_end or last["omega"] == prev["omega"]:
        return
    t0 = time.perf_counter()
    a = (omega_end - prev["omega"]) / (last["omega"] - prev["omega"])
    guess = prev["x"] + a * (last["x"] - prev["x"])
    res = _solve(lambda v: fx(v, omega_end)[0], lambda v: fx(v, omega_end)[:2], guess, solver, tol, scale, maxiter)
    if res.converged:
        out[-1] = dict(x=res.x, omega=omega_end, iterations=last["iterations"] + res.iterations,
                       seconds=last["seconds"] + time.perf_counter() - t0, converged=True, reason=res.reason)


def _correct(fx, z, t, ds: float, scales, ds_min: float, solver, tol, scale, maxiter) -> tuple[SolveResult, float]:
    """One arclength step from the scaled point ``z`` along the tangent ``t``:
    predictor ``z + ds·t``, corrector on ``R = 0`` plus the hyperplane
    ``tᵀ(z − z_pred) = 0``; ``ds`` halves on failure. Returns the solver's
    result and the ``ds`` used (not converged: ds fell below ``ds_min``).
    ``scales`` = (x_s, ω_s) of the scaled unknowns."""
    xs, ws = scales
    n = z.size - 1
    while True:
        zp = z + ds * t

        def aug(zz, with_jac):
            xx, ww = zz[:n] * xs, zz[n] * ws
            R, Jx, Rw_ = fx(xx, ww)
            ra = np.concatenate([R, [t @ (zz - zp) * scale]])
            if not with_jac:
                return ra
            Ja = np.empty((n + 1, n + 1))
            Ja[:n, :n] = Jx * xs
            Ja[:n, n] = Rw_ * ws
            Ja[n] = t * scale
            return ra, Ja

        res = _solve(lambda zz: aug(zz, False), lambda zz: aug(zz, True), zp, solver, tol, scale, maxiter)
        if res.converged:
            return res, ds
        ds *= 0.5
        if ds < ds_min:
            return res, ds


def _tangent(fx, x, w, sec, t, scales) -> np.ndarray:
    """Unit tangent at the converged (x, ω) from ``[J  R_ω; tᵀ] t_new = [0; 1]``
    (scaled by ``scales`` = (x_s, ω_s)), oriented along the secant ``sec`` of
    the last step; the secant itself when the bordered system is singular."""
    xs, ws = scales
    n = x.size
    _, J, Rw = fx(x, w)
    A = np.zeros((n + 1, n + 1))
    A[:n, :n] = J * xs
    A[:n, n] = Rw * ws
    A[n] = t
    rhs = np.zeros(n + 1)
    rhs[n] = 1.0
    try:
        tn = np.linalg.solve(A, rhs)
    except np.linalg.LinAlgError:
        tn = sec
    if not np.all(np.isfinite(tn)):
        tn = sec
    # Orientation from the path actually travelled: at the stick/slip kinks
    # of the friction residual the bordered tangent can come out reversed
    # (measured on the sector: HBM-1 turned back at the resonance peak and
    # walked to −192 Hz). A secant predictor alone does not do either: at
    # the top of a sharp peak its hyperplane cuts the curve on both sides.
    if tn @ sec < 0:
        tn = -tn
    return tn / np.linalg.norm(tn)


def arclength_sweep(f_start_hz: float, f_end_hz: float, linear, make_problem, observe, *, x0=None,
                    carry_stick: bool = True, **kw) -> list[SweepPoint]:
    """Pseudo-arclength continuation of an HB problem between two frequencies (Hz).

    A problem is built (and cached) per ω visited by the corrector; its stick
    anchor is the one of the start point (the static state unless
    ``carry_stick`` carries the last converged point's). Other keywords go to
    :func:`continuation`. Returns :class:`SweepPoint` records; their
    frequencies are not monotonic past a fold.
    """
    cache: dict[float, object] = {}
    state = {"anchor": None}

    def problem(w):
        pr = cache.get(w)
        if pr is None:
            Zr, Fr, dZr, dFr = linear(w)
            pr = make_problem(Zr, Fr)
            pr.omega = w
            if state["anchor"] is not None:
                pr.set_stick_anchor(state["anchor"])
            pr._dZ = (dZr, dFr)
            if len(cache) > 8:
                cache.clear()
            cache[w] = pr
        return pr

    def fjw(x, w):
        pr = problem(w)
        return pr.residual_jacobian_omega(x, *pr._dZ)

    w0 = TWO_PI * f_start_hz
    pr0 = problem(w0)
    if x0 is None:
        x0 = pr0.x0()
    state["anchor"] = pr0.stick_anchor.copy()

    def on_point(rec):
        if carry_stick:
            state["anchor"] = problem(rec["omega"]).stick_anchor_of(rec["x"])
            cache.clear()

    recs = continuation(fjw, x0, w0, TWO_PI * f_end_hz, scale=pr0.residual_scale(),
                        callback=on_point, **kw)
    return [SweepPoint(frequency_hz=r["omega"] / TWO_PI, omega=r["omega"], x=r["x"],
                       amplitude=float(observe(problem(r["omega"]), r["x"])),
                       iterations=r["iterations"], seconds=r["seconds"], converged=r["converged"],
                       reason=r["reason"]) for r in recs]
