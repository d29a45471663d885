"""The runner: one (case, method, solver) solved and measured (:func:`run_case`), wear cases, the matrix."""
from __future__ import annotations

import time
from typing import Callable

import numpy as np

from workflow.engine.errors import BladewearError
from workflow.engine.hb import HBProblem
from workflow.engine.studies.extreme.cases import Case, CaseResult, _static_free_normal, build_cases
from workflow.engine.studies.extreme.checks import _error, tolerance, verify
from workflow.engine.studies.extreme.diagnosis import _diagnose, _explain_off
from workflow.engine.studies.extreme.equilibration import conditioning, scaling
from workflow.engine.studies.extreme.hbproblem import problem
from workflow.engine.studies.extreme.settings import Setup


def _solve(prob: HBProblem, x0, solver: str, *, tol: float, maxiter: int, pseudo: dict, scaled: bool):
    """Run one solver; returns (SolveResult in the problem's unknowns, cond of the final J as solved)."""
    from workflow.engine.pseudotime import integrate
    from workflow.engine.solvers import newton, powell

    scale = prob.residual_scale()
    if scaled:
        r, c = scaling(prob, x0)
        fun = lambda z: r * prob.residual(c * z)                       # noqa: E731
        fun_jac = lambda z: _scaled_rj(prob, r, c, z)                  # noqa: E731
        z0 = x0 / c
        # the convergence test stays on the true residual: ‖r⊙R‖ ≥ min(r)‖R‖
        sc = scale * float(np.min(r))
    else:
        c = None
        fun, fun_jac, z0, sc = prob.residual, prob.residual_jacobian, x0, scale
    if solver == "newton":
        res = newton(fun_jac, z0, fun=fun, tol=tol, scale=sc, maxiter=maxiter)
    elif solver == "powell":
        res = powell(fun, fun_jac, z0, tol=tol, scale=sc, maxfev=40 * maxiter)
    elif solver == "pseudo-time":
        opts = {"scheme": "ser", "precond": "jacobian", "max_steps": 400}
        opts.update(pseudo)
        if prob.method == "hdhb" and opts["scheme"] == "block-jacobi":
            opts.setdefault("blocks", prob.nit)
        res = integrate(fun, fun_jac, z0, tol=tol, scale=sc, **opts)
    else:
        raise ValueError(f"unknown solver {solver!r}")
    if scaled:
        res.x = c * res.x
    return res


def _scaled_rj(prob, r, c, z):
    R, J = prob.residual_jacobian(c * z)
    return r * R, r[:, None] * J * c[None, :]


def run_case(su: Setup, case: Case, method: str, solver: str, reference: dict | None = None) -> CaseResult:
    """Solve one (case, method, solver) and measure it; never raises on numerical failure."""
    s = su.settings
    t0 = time.perf_counter()
    out = CaseResult(case.name, case.group, method, solver, False, 0, 0.0, None, "", note=case.note)
    try:
        if case.wear is not None:
            return _run_wear(su, case, method, solver, out, t0)
        prob = problem(su, case, method)
        with np.errstate(all="ignore"):
            x0 = prob.x0()
        if not np.all(np.isfinite(x0)):
            out.diagnosis = "initial guess not finite (static problem singular: the blade floats?)"
            out.seconds = time.perf_counter() - t0
            return out
        maxiter = s.max_iterations if case.maxiter is None else case.maxiter
        pseudo = dict(case.pseudo)
        pseudo.setdefault("max_steps", s.pseudo_steps)
        with np.errstate(all="ignore"):
            res = _solve(prob, x0, solver, tol=s.tol, maxiter=maxiter, pseudo=pseudo, scaled=case.scaled)
        out.iterations = int(res.iterations)
        x = res.x
        ok, why, facts = verify(prob, x, s.tol)
        cond = None
        try:
            if prob.n <= 1500:
                cj, cs = conditioning(prob, x)
                cond = cs if case.scaled else cj
                out.note = (out.note + "; " if out.note else "") + f"cond(J) {cj:.1e}, scaled {cs:.1e}"
        except (np.linalg.LinAlgError, ValueError):
            pass
        out.cond = cond
        out.residual = facts.get("residual")
        out.separated, out.slipping, out.sticking = (facts.get("separated"), facts.get("slipping"),
                                                     facts.get("sticking"))
        if res.converged and ok:
            out.converged = True
        elif res.converged:
            out.diagnosis = f"solver claimed convergence but {why}"
        else:
            out.diagnosis = _diagnose(res, prob, x if np.all(np.isfinite(x)) else None, solver, facts, cond) \
                if not why.startswith("DLFT") else f"{res.reason}; {why}"
        if np.all(np.isfinite(x)):
            out.x = x
            out.U = prob.harmonics(x)
        if out.converged:
            info: dict = {}
            out.error = _error(su, case, prob, out.U, reference, info)
            out.tolerance = tolerance(su, case, info.get("delta"))
            if out.error is not None and out.tolerance is not None and out.error > out.tolerance:
                try:
                    _explain_off(su, case, prob, x, solver, out, reference, info, facts)
                except Exception as exc:          # noqa: BLE001 — an off row never goes out without a diagnosis
                    out.diagnosis = (f"converged {out.error:.2g} from the reference (tolerance {out.tolerance:.1g}); "
                                     f"diagnosing it failed: {type(exc).__name__}: {exc}")
    except (np.linalg.LinAlgError, FloatingPointError, ValueError, BladewearError) as exc:
        out.diagnosis = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    out.seconds = time.perf_counter() - t0
    return out


def _run_wear(su: Setup, case: Case, method: str, solver: str, out: CaseResult, t0: float) -> CaseResult:
    """Wear cases: the reference march (newton/powell rows: explicit/implicit) or pseudo-time (eq. 22)."""
    try:
        from workflow.engine import wear as wmod
    except ImportError as exc:
        out.diagnosis = f"not run: workflow/engine/wear not available ({exc})"
        out.seconds = time.perf_counter() - t0
        return out
    s = su.settings
    prob = problem(su, case, method)
    x0 = prob.x0()
    wp = wmod.WearProblem(prob, su.model.area if case.model is None else case.model.area, case.wear["k_w"])
    cycles = 1e5
    if solver == "pseudo-time":
        h = wmod.pseudo_time_wear(wp, x0, cycles_per_block=cycles, tol=s.tol, max_steps=s.pseudo_steps)
    else:
        scheme = "implicit" if solver == "powell" else "explicit"
        out.solver = f"march-{scheme}"
        h = wmod.march_reference(wp, x0, scheme=scheme, cycles_per_block=cycles, max_blocks=s.wear_blocks,
                                 tol=s.tol)
    out.iterations = int(h.iterations)
    W = np.asarray(h.W)
    if not np.all(np.isfinite(W)) or not np.all(np.isfinite(h.x)):
        out.diagnosis = "non-finite wear or unknowns"
    ok, why, facts = verify(prob, h.x, s.tol) if np.all(np.isfinite(h.x)) else (False, "non-finite", {})
    out.residual = facts.get("residual")
    out.separated, out.slipping, out.sticking = facts.get("separated"), facts.get("slipping"), facts.get("sticking")
    out.converged = bool(h.steady and ok)
    if not out.converged and not out.diagnosis:
        out.diagnosis = h.reason if not h.steady else f"wear steady but {why}"
    elif out.converged:
        rate = np.asarray(h.final_rate)
        out.error = float(np.max(rate) * cycles / max(float(np.max(W)), 1e-300)) if W.max() > 0 else 0.0
        # yardstick: the static normal relative displacement without contact (m)
        approach = float(np.max(np.abs(_static_free_normal(su))))
        if approach > 0 and W.max() > 10.0 * approach:
            out.converged = False
            out.diagnosis = (f"wear overshoot: max W = {W.max():.3g} m is {W.max() / approach:.3g}× the static "
                             "approach; the contact was opened by one long step, not by wear (the steady state "
                             "with zero rates is not the physical one)")
        sep = facts.get("separated", 0.0)
        out.note += f"; max W {W.max():.3e} m, separated {sep:.0%} of (instant, pair)"
    out.x = h.x
    out.seconds = time.perf_counter() - t0
    return out


def run_matrix(su: Setup, cases: list[Case] | None = None, *, progress: Callable | None = None) -> list[CaseResult]:
    """All (case, method, solver) of the set-up; penalty errors against the 1× solution."""
    s = su.settings
    cases = build_cases(su) if cases is None else cases
    # wear cases: one formulation (the first) — the wear drivers are formulation-agnostic and slow
    jobs = [(c, m, v) for c in cases for m in (s.methods[:1] if c.wear is not None else s.methods)
            for v in s.solvers]
    # the ε = 1× solutions first: they are the penalty cases' reference
    order = sorted(range(len(jobs)), key=lambda i: not (jobs[i][0].limit == "penalty" and jobs[i][0].eps_scale == 1.0))
    refs: dict = {}
    results: dict[int, CaseResult] = {}
    it = progress(order, len(order)) if progress else order
    for i in it:
        case, method, solver = jobs[i]
        ref = refs.get((method, solver), refs.get(method))
        r = run_case(su, case, method, solver, reference={"penalty": ref})
        if case.limit == "penalty" and case.eps_scale == 1.0:
            if r.converged:
                refs[(method, solver)] = r.U
                refs.setdefault(method, r.U)
                r.error = 0.0
        results[i] = r
    return [results[i] for i in range(len(jobs))]
