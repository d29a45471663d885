"""Root finders for the harmonic-balance residuals (paper §3): Newton and hybrid Powell.

Both take ``fun(x) -> R`` and ``fun_jac(x) -> (R, J)`` (analytic J) and
return a :class:`SolveResult` (docs/contracts.md §7).

Convergence test, the same for both: ``‖R‖₂ ≤ tol · scale``, where the
caller passes ``scale`` (for an HB problem ``‖F‖₂`` of the forcing in the
residual's own space, :meth:`workflow.engine.hb.HBProblem.residual_scale`), so
``tol`` is a relative residual independent of the units and the size of the
load. Non-finite residuals or Jacobians never leak: the solver stops, returns
the last finite iterate and says why in ``reason``.
"""
from __future__ import annotations

import inspect
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.sparse.linalg

__all__ = ["DenseLU", "SolveResult", "newton", "powell"]

#: the name SciPy's GMRES gives its relative tolerance ("tol" up to SciPy 1.11, "rtol" after)
_GMRES_TOL = "rtol" if "rtol" in inspect.signature(scipy.sparse.linalg.gmres).parameters else "tol"


def gmres_rtol(value: float) -> dict:
    """``{name: value}``: SciPy's GMRES relative tolerance under the name this SciPy gives it."""
    return {_GMRES_TOL: float(value)}


@dataclass
class SolveResult:
    """Outcome of a nonlinear solve.

    x                    final iterate (the last finite one)
    converged            ‖R‖ ≤ tol·scale reached
    iterations           Newton steps, or residual evaluations for Powell
    residual_norm        ‖R(x)‖₂ (units of the residual)
    reason               "converged", "max iterations", "line search failed",
                         "non-finite residual", "non-finite Jacobian",
                         "singular Jacobian", "stalled: …"
    history              ‖R‖₂ after each accepted step / each evaluation
    seconds              wall time
    jacobian_evaluations analytic Jacobians computed
    function_evaluations residual evaluations (including those with a Jacobian)
    """

    x: np.ndarray
    converged: bool
    iterations: int
    residual_norm: float
    reason: str
    history: list = field(default_factory=list)
    seconds: float = 0.0
    jacobian_evaluations: int = 0
    function_evaluations: int = 0


def _finite(a) -> bool:
    return bool(np.all(np.isfinite(a)))


def within_tolerance(norm: float, tol: float, scale: float) -> bool:
    """‖R‖ ≤ tol·‖F‖ with both finite: the one convergence test of the solvers (a NaN or an
    infinite norm, or an infinite scale that would accept any residual, is never converged)."""
    return bool(np.isfinite(norm) and np.isfinite(scale) and norm <= tol * scale)


class DenseLU:
    """The Newton linear solver on a dense J: LU (least squares if singular).

    Protocol shared with :class:`workflow.engine.linsolve.StructuredSolve`:
    ``factor(J) -> bool`` (False: J not finite), ``solve(R) -> dx | None``
    (``J dx = −R`` with the last factored J), ``lm_scale()`` and
    ``lm_step(R, ν)`` (Levenberg–Marquardt, ``(JᵀJ + νI) dx = −JᵀR``)."""

    name = "dense"

    def __init__(self):
        self.J = self.lu = None
        self._jtj = None
        self.stats = {"factorizations": 0}

    def factor(self, J) -> bool:
        if not _finite(J):
            return False
        self.J, self._jtj = J, None
        try:
            with warnings.catch_warnings():       # ill-conditioned: lstsq below if not finite
                warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
                self.lu = scipy.linalg.lu_factor(J, check_finite=False)
        except (np.linalg.LinAlgError, scipy.linalg.LinAlgError, ValueError):
            self.lu = None
        self.stats["factorizations"] += 1
        return True

    @property
    def reusable(self) -> bool:
        """A factor exists that a chord step can reuse."""
        return self.lu is not None

    def solve(self, R):
        dx = scipy.linalg.lu_solve(self.lu, -R, check_finite=False) if self.lu is not None else None
        if dx is not None and _finite(dx):
            return dx
        dx = np.linalg.lstsq(self.J, -R, rcond=None)[0]
        return dx if _finite(dx) else None

    def _normal(self):
        if self._jtj is None:
            self._jtj = self.J.T @ self.J
        return self._jtj

    def lm_scale(self) -> float:
        return max(float(np.trace(self._normal())) / self.J.shape[0], 1e-300)

    def lm_step(self, R, nu):
        JtJ = self._normal()
        try:
            with warnings.catch_warnings():   # small ν on a singular JᵀJ: ν grows next
                warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
                return -scipy.linalg.solve(JtJ + nu * np.eye(len(R)), self.J.T @ R, assume_a="pos",
                                           check_finite=False)
        except (np.linalg.LinAlgError, scipy.linalg.LinAlgError):
            return None


def _line_search(fun, x, dx, norm, armijo, max_backtracks, count, along=None):
    """Backtracking on ‖R‖₂: (accepted, x_trial, R_trial). ``along(x, dx)``, if given: a callable
    ``α → (x + α dx, R(x + α dx))``, which a residual with a linear part evaluates from two products
    made once (:meth:`workflow.engine.hb.HBProblem.residual_along`)."""
    alpha = 1.0
    xt = Rt = None
    at = None if along is None else along(x, dx)
    for _ in range(max_backtracks):
        if at is None:
            xt = x + alpha * dx
            Rt = fun(xt)
        else:
            xt, Rt = at(alpha)
        count[0] += 1
        if _finite(Rt) and np.linalg.norm(Rt) <= (1.0 - armijo * alpha) * norm:
            return True, xt, Rt
        alpha *= 0.5
    return False, xt, Rt


def _searched_direction(fun, lin, x, R, norm, eta, armijo, max_backtracks, count, along=None):
    """The Newton direction of ``lin`` (to the linear tolerance ``eta`` of :func:`forcing`;
    None: the solver's own) and its line search: (dx or None, accepted, x_trial, R_trial).

    A loose direction that fails is not solved again tight: where the line search fails, the
    iterate sits on a kink of the friction residual and the tight direction failed as well
    (0 of 14 such retries accepted: the interface-scaling sectors at 128 and 256 pairs, HBM and
    HDHB Nh = 7, and the 6-pair test model's 12 hard starts), while each cost 20–27 GMRES
    iterations; the Levenberg–Marquardt fallback takes over at once."""
    dx = lin.solve(R) if eta is None else lin.solve(R, eta)
    accepted, xt, Rt = (False, None, None) if dx is None else \
        _line_search(fun, x, dx, norm, armijo, max_backtracks, count, along)
    return dx, accepted, xt, Rt


def _lm_search(fun, lin, x, R, norm, armijo, max_backtracks, count, nu_last=None):
    """Levenberg–Marquardt steps of growing damping: (accepted, x_trial, R_trial, ν accepted).

    At a stick/slip/separation kink the Newton direction of the active branch
    can point into a branch where ‖R‖ grows; the LM step turns towards
    steepest descent as ν grows and gets the iterate off the kink. The damping
    starts at 1e-8·trace(JᵀJ)/n, or at a tenth of ``nu_last`` (the damping the
    previous search of the same solve accepted) if that is larger — Marquardt's
    update: a solve that creeps along a kink needs about the same ν at every
    step (measured on the 256-pair sector, HDHB Nh = 7: 13 successive searches
    each accepted at 10⁶–10⁸ × the start, 7–9 residuals apiece)."""
    nu = 1e-8 * lin.lm_scale()
    if nu_last is not None:
        nu = max(nu, 0.1 * nu_last)
    for _ in range(max_backtracks):
        dx = lin.lm_step(R, nu)
        if dx is not None and _finite(dx):
            xt = x + dx
            Rt = fun(xt)
            count[0] += 1
            if _finite(Rt) and np.linalg.norm(Rt) < (1.0 - armijo * 1e-3) * norm:
                return True, xt, Rt, nu
        nu *= 10.0
    return False, None, None, None


#: A Newton solve stops as "stalled" when the last this many of a run of Levenberg–Marquardt
#: steps (the Newton direction failed its line search each time) together cut ‖R‖ by less than
#: 1/:data:`STALL_RATIO`: it creeps along a kink of the friction residual, and the budget runs
#: out long before ‖R‖ reaches the tolerance at 1–10 % a step, while the cascade's next attempt
#: (another start, another ε, Powell from the best iterate) gets round it. Measured on the
#: 256-pair sector (HDHB Nh = 7, its resonance point): 24 such steps took ‖R‖ from 1859 to 283
#: N, ~10 s, before the iteration budget ended the attempt; the next attempt converged in 6.
STALL_LM_STEPS = 5
STALL_RATIO = 0.5


class _LMFallback:
    """Newton's Levenberg–Marquardt fallback over one solve: the damping its last search
    accepted (Marquardt's update, :func:`_lm_search`) and ‖R‖ before each step of the current
    run of LM-only steps, which the stall rule watches (:data:`STALL_LM_STEPS`)."""

    def __init__(self):
        self.nu, self.creep = None, []

    def after(self, accepted, xt, Rt, fun, lin, x, R, norm, armijo, max_backtracks, count):
        """After a line search from x: its step if it found one (the LM run ends), else an LM
        search. (accepted, x_trial, R_trial, "stalled: …" or None)."""
        if accepted:
            self.creep = []
            return accepted, xt, Rt, None
        ok, xt, Rt, self.nu = _lm_search(fun, lin, x, R, norm, armijo, max_backtracks, count, self.nu)
        self.creep.append(norm)
        n = len(self.creep)
        if ok and n >= STALL_LM_STEPS and float(np.linalg.norm(Rt)) > STALL_RATIO * self.creep[-STALL_LM_STEPS]:
            return ok, xt, Rt, (f"stalled: the last {STALL_LM_STEPS} of {n} Levenberg–Marquardt steps in a row "
                                f"cut ‖R‖ by less than {1 / STALL_RATIO:g}×")
        return ok, xt, Rt, None


#: Inexact Newton (Eisenstat & Walker 1996, SIAM J. Sci. Comput. 17, "choice 2"): a linear
#: solver that accepts a tolerance (``lin.inexact``, the structured GMRES) solves step k only to
#: the relative linear residual ``η_k = γ (‖R_k‖/‖R_{k−1}‖)^α`` (η_0 = ``ETA_MAX``), kept
#: ≥ γ η_{k−1}^α when that exceeds 0.1 (their safeguard against η falling too fast), ≥ half the
#: step to the tolerance, ``0.5·tol·scale/‖R_k‖`` (a tighter step cannot change the verdict),
#: and ≤ ``ETA_MAX``. Once the last ``CREEP_STEPS`` steps together cut ‖R‖ by less than
#: ``1 − CREEP_RATIO`` the next is solved to the solver's own tolerance: there, on the kinks of
#: the friction residual, loose directions made Newton creep. A loose direction that fails its
#: line search goes straight to the Levenberg–Marquardt fallback (:func:`_searched_direction`).
FORCING_GAMMA, FORCING_ALPHA, ETA_MAX = 0.9, 2.0, 1e-2
CREEP_STEPS, CREEP_RATIO = 3, 0.9


def forcing(history: list, eta_previous: float | None, floor: float) -> float | None:
    """η_k of :data:`ETA_MAX`'s rule from ‖R‖ of x0 and of every accepted iterate
    (``history``, the last is ‖R_k‖), η_{k−1} (None: that step was tight) and the floor
    ``tol·scale`` (units of R); None: solve tight."""
    norm = history[-1]
    if len(history) < 2 or history[-2] <= 0.0:
        eta = ETA_MAX
    elif len(history) > CREEP_STEPS and norm > CREEP_RATIO * history[-1 - CREEP_STEPS]:
        return None
    else:
        eta = FORCING_GAMMA * (norm / history[-2]) ** FORCING_ALPHA
        guard = 0.0 if eta_previous is None else FORCING_GAMMA * eta_previous ** FORCING_ALPHA
        if guard > 0.1:
            eta = max(eta, guard)
    return min(ETA_MAX, max(eta, 0.5 * floor / norm if norm > 0.0 else ETA_MAX))


def newton(fun_jac, x0, *, fun=None, tol: float = 1e-8, scale: float = 1.0, maxiter: int = 50,
           max_backtracks: int = 20, armijo: float = 1e-4, lm_fallback: bool = True,
           reuse_ratio: float = 0.0, callback=None, linear=None, along=None) -> SolveResult:
    """Newton–Raphson with backtracking line search on ‖R‖₂.

    Each step solves ``J dx = −R`` with ``linear`` (default :class:`DenseLU`;
    :class:`workflow.engine.linsolve.StructuredSolve` for the matrix-free J of the HB residual, an
    iterative solve asked only for the accuracy of :func:`forcing`) and halves the step until
    ``‖R(x+α dx)‖ ≤ (1 − armijo·α)‖R(x)‖``, which keeps Newton from cycling across the kinks of
    the friction residual; trial points use ``fun`` (residual only) when given. Where no step
    length decreases ‖R‖ (a kink), ``lm_fallback`` tries Levenberg–Marquardt steps ("line search
    failed" if none does); a run of them that makes no headway stops the solve as "stalled"
    (:class:`_LMFallback`).

    tol, scale: converged when ``‖R‖₂ ≤ tol·scale`` (module docstring).
    reuse_ratio: if > 0, keep the factor of an earlier Jacobian (a chord step)
    while each accepted step cuts ‖R‖ by at least this factor; a fresh one
    otherwise, or when a stale direction fails the line search — pays where
    forming and factoring J dominates (large Nh) and Newton converges only
    linearly anyway. callback(it, x, norm): after every accepted step.
    along: the line search's trial points from x along dx, if given (:func:`_line_search`).
    """
    t0 = time.perf_counter()
    x = np.array(x0, dtype=float)
    fun = fun if fun is not None else (lambda z: fun_jac(z)[0])
    lin = DenseLU() if linear is None else linear
    nfev, nje = [0], [0]
    history: list[float] = []       # ‖R‖ of x0 and of every accepted iterate

    def jac(z):
        nfev[0], nje[0] = nfev[0] + 1, nje[0] + 1
        return fun_jac(z)

    def done(reason, conv, R, it):
        norm = float(np.linalg.norm(R)) if R is not None and _finite(R) else float("nan")
        return SolveResult(x=x, converged=conv, iterations=it, residual_norm=norm, reason=reason,
                           history=history, seconds=time.perf_counter() - t0,
                           jacobian_evaluations=nje[0], function_evaluations=nfev[0])

    R, J = jac(x)
    if not _finite(R):
        return done("non-finite residual", False, None, 0)
    norm = float(np.linalg.norm(R))
    history.append(norm)
    fresh = True        # the factor in ``lin`` is of J at x (False: a chord step)
    lm = _LMFallback() if lm_fallback else None
    inexact, eta = getattr(lin, "inexact", False), None    # eta: the last step's linear tolerance (None: tight)
    for it in range(maxiter + 1):
        if within_tolerance(norm, tol, scale):
            return done("converged", True, R, it)
        if it == maxiter:
            return done("max iterations", False, R, it)
        if J is not None and not lin.factor(J):
            return done("non-finite Jacobian", False, R, it)
        eta = forcing(history, eta, tol * scale) if inexact else None
        dx, accepted, xt, Rt = _searched_direction(fun, lin, x, R, norm, eta, armijo, max_backtracks, nfev, along)
        if not accepted and not fresh:      # a chord direction failed: refresh J, try again
            (R, J), fresh = jac(x), True
            continue
        if dx is None:
            return done("singular Jacobian", False, R, it)
        accepted, xt, Rt, stall = (accepted, xt, Rt, None) if lm is None else \
            lm.after(accepted, xt, Rt, fun, lin, x, R, norm, armijo, max_backtracks, nfev)
        if not accepted:
            return done("line search failed", False, R, it)
        x = xt
        if stall is not None:
            history.append(float(np.linalg.norm(Rt)))
            return done(stall, False, Rt, it + 1)
        if reuse_ratio > 0.0 and lin.reusable and float(np.linalg.norm(Rt)) <= reuse_ratio * norm:
            R, J, fresh = Rt, None, False            # chord step next: keep the factor
        else:
            (R, J), fresh = jac(x), True
        if not _finite(R):  # cannot happen after a finite trial, kept as a guard
            return done("non-finite residual", False, None, it + 1)
        norm = float(np.linalg.norm(R))
        history.append(norm)
        if callback is not None:
            callback(it + 1, x, norm)
    return done("max iterations", False, R, maxiter)  # pragma: no cover


class _NonFinite(Exception):
    pass


_MINPACK = {
    2: "max iterations",
    3: "stalled: xtol too small, no further improvement possible",
    4: "stalled: not making good progress (Jacobian evaluations)",
    5: "stalled: not making good progress (iterations)",
}


def powell(fun, fun_jac, x0, *, tol: float = 1e-8, scale: float = 1.0, maxfev: int = 200,
           xtol: float = 1e-13) -> SolveResult:
    """MINPACK hybrid Powell (trust-region dogleg with Broyden updates), as in the paper.

    Calls ``scipy.optimize.root(method='hybr')`` with the analytic Jacobian
    given as a separate callable (``jac=fun_jac(x)[1]``) rather than
    ``jac=True``: MINPACK evaluates J only when its Broyden update stalls, so
    residual-only calls stay cheap. MINPACK stops on a relative step
    ``xtol``; the result is then judged by our residual test
    ``‖R‖₂ ≤ tol·scale``. ``maxfev`` bounds residual evaluations.
    """
    t0 = time.perf_counter()
    x0 = np.array(x0, dtype=float)
    history: list[float] = []
    counts = {"f": 0, "j": 0}
    last = {"x": x0.copy(), "R": None}

    def f(x):
        R = np.asarray(fun(x), dtype=float)
        counts["f"] += 1
        if not _finite(R):
            raise _NonFinite("residual")
        history.append(float(np.linalg.norm(R)))
        if last["R"] is None or history[-1] <= np.linalg.norm(last["R"]):
            last["x"], last["R"] = np.array(x, copy=True), R
        return R

    def jac(x):
        _, J = fun_jac(x)
        counts["j"] += 1
        if not _finite(J):
            raise _NonFinite("Jacobian")
        return J

    reason = None
    try:
        sol = scipy.optimize.root(f, x0, jac=jac, method="hybr",
                                  options={"xtol": xtol, "maxfev": maxfev})
        x = sol.x
        R = f(x)
        if last["R"] is not None and np.linalg.norm(last["R"]) < np.linalg.norm(R):
            x, R = last["x"], last["R"]
        status = sol.status
    except _NonFinite as exc:
        reason = f"non-finite {exc.args[0]}"
        x, R = last["x"], last["R"]
        status = None
    norm = float(np.linalg.norm(R)) if R is not None else float("nan")
    converged = R is not None and within_tolerance(norm, tol, scale)
    if reason is None:
        reason = "converged" if converged else _MINPACK.get(status, f"stalled: MINPACK status {status}")
        if not converged and status == 1:
            reason = "stalled: step below xtol but residual above tolerance"
    return SolveResult(x=x, converged=bool(converged), iterations=counts["f"], residual_norm=norm,
                       reason=reason, history=history, seconds=time.perf_counter() - t0,
                       jacobian_evaluations=counts["j"], function_evaluations=counts["f"])
