"""The HB problem at the wear frequency and its unworn vibration: the first tied frequency, the
cascade's unworn point, Newton against pseudo-time, and a held amplitude's start under a smaller load."""
from __future__ import annotations

import numpy as np

from workflow.engine.errors import SceneError, SolverError
from workflow.engine.studies.wearstudy.options import WearOptions


def first_tied_frequency(rc) -> float:
    """First natural frequency (rad/s) of the structure with the interface tied (u_r = 0)
    (harmonic 1's ND for a cyclic model), from :func:`workflow.engine.linear.tied_modes` —
    the condensation's K-orthonormal tied modes, the frequencies the FRF's band is built on.
    (``eigh(K_yy, M_yy)``, used here before, put the quick sector's first tied frequency
    2e-10 apart between 1 and 2 BLAS threads, and the worn depth at that frequency 1e-6
    apart; the tied modes agree to 3e-14.)"""
    from workflow.engine.linear import tied_modes

    return float(2 * np.pi * tied_modes(rc)[0][0])


def build_problem(model, law, opt: WearOptions, rc=None):
    """(HBProblem, RelativeCoordinates, ω) at the wear frequency, with the
    static state solved once (:func:`workflow.engine.static_state`)."""
    from workflow.engine.condense import relative_coordinates
    from workflow.engine.linear import condensed
    from workflow.engine.studies.study import static_state
    from workflow.engine.hb import HBProblem
    from workflow.engine.studies.variants import resolved_nit

    rc = relative_coordinates(model) if rc is None else rc
    w_tied = first_tied_frequency(rc)
    f_tied = w_tied / (2 * np.pi)
    if opt.frequency_hz > 0 and not 0.01 * f_tied <= opt.frequency_hz <= 100 * f_tied:   # a typo, not a study
        raise SceneError(f"wear.frequency_hz = {opt.frequency_hz:g} Hz is outside 0.01–100 × the first tied "
                         f"frequency of the model ({f_tied:.4g} Hz); 0 means at that resonance")
    omega = 2 * np.pi * opt.frequency_hz if opt.frequency_hz > 0 else w_tied
    nit = resolved_nit(opt.method, opt.nh, opt.nit)
    cond = condensed(rc, omega, opt.nh)
    st = static_state(cond.Zr, cond.Fr, law, opt.max_passes)
    return HBProblem(cond.Zr, cond.Fr, law, opt.nh, nit, opt.method, max_passes=opt.max_passes, static=st), rc, omega


def unworn_solvers(hb, x0, *, tol: float, max_steps: int, eps_path=()) -> dict:
    """The unworn HB point by Newton and by pseudo-time (SER with the Jacobian
    mass: pseudo-transient continuation) from the same start ``x0`` along the
    same ε-path (:func:`workflow.engine.cascade.along_eps_path`), each with
    seconds, iterations (steps), Jacobians, and the relative difference of
    the two solutions (max |Δx| / max |x|)."""
    import time

    from workflow.engine.cascade import along_eps_path, run_solver

    pseudo = {"scheme": "ser", "precond": "jacobian", "max_steps": max_steps}
    out = {}
    for name, solver in (("newton", "newton"), ("pseudo-time", "pseudo-time")):
        t0 = time.perf_counter()
        r = along_eps_path(hb, x0, eps_path, tol, max_steps,
                           run=lambda q, x, s, m: run_solver(q, x, s, tol, m, pseudo), solver=solver)
        out[name] = (r, time.perf_counter() - t0)
    row = lambda r, s: {"seconds": s, "iterations": int(r.iterations),  # noqa: E731
                        "jacobian_evaluations": int(r.jacobian_evaluations), "converged": bool(r.converged),
                        "reason": r.reason}
    (n, tn), (pt, tp) = out["newton"], out["pseudo-time"]
    top = max(float(np.abs(n.x).max()), 1e-300)
    return {"newton": row(n, tn), "pseudo-time": row(pt, tp), "eps_path_steps": len(eps_path),
            "max_rel_diff": float(np.abs(pt.x - n.x).max() / top) if pt.converged and n.converged else None,
            "time_ratio_pseudo_over_newton": tp / max(tn, 1e-12)}


def unworn_point(hb, omega: float, opt: WearOptions, eps_path):
    """The unworn HB solution through the cascade, from the stuck guess."""
    from workflow.engine.cascade import solve_point

    pr = solve_point(hb, [hb.x0()], solver="newton-powell", tol=opt.tol, maxiter=opt.max_iterations,
                     eps_path=eps_path)
    if not pr.converged:
        raise SolverError(f"wear: HB solve of the unworn state failed at {omega / 2 / np.pi:.3f} Hz: "
                          f"{pr.result.reason} (try hb.max_iterations or contact.penalty_factor)")
    return pr.result


#: Load scales tried, in order, for the start of a held amplitude whose unworn point does not
#: solve under the load as built (:func:`_unworn_start`).
START_SCALES = (0.1, 0.01)


def _unworn_start(hb, omega: float, opt: WearOptions, eps_path, log=None) -> tuple:
    """(the unworn SolveResult the march starts from, the load scale it is under).

    Under a held tip amplitude (``tip_amplitude_m`` > 0) the load as built only starts the
    search for the load that holds the tip, so where its point does not solve — a tied
    resonance's load from the stuck guess drives the flanks far into slip (a crowned 144-pair
    flank at 0.5 N, 2026-11-29) — the point under :data:`START_SCALES` × that load, nearer to
    stick, starts it instead (:meth:`~workflow.engine.studies.amplitude.AmplitudeProblem.start`
    continues in amplitude from there). Otherwise scale 1 or the unworn point's SolverError."""
    try:
        return unworn_point(hb, omega, opt, eps_path), 1.0
    except SolverError as err:
        if opt.control != "amplitude" or not opt.tip_amplitude_m > 0:
            raise
        first = err
    for s in START_SCALES:
        hb.scale_load(s)
        try:
            base = unworn_point(hb, omega, opt, eps_path)
        except SolverError:
            continue
        finally:
            hb.scale_load(1.0)
        if log is not None:
            log.info(f"the unworn point did not solve under the load as built; the held amplitude starts "
                     f"from {s:g} × it")
        return base, s
    raise first


def _unworn_at(wp, x, opt: WearOptions, eps_path):
    """The unworn vibration of ``wp`` from x (a SolveResult), or None if it does not solve."""
    from workflow.engine.cascade import solve_point

    wp.set_wear(np.zeros(wp.p))
    pr = solve_point(wp.hb, [x], solver="newton-powell", tol=opt.tol, maxiter=opt.max_iterations, eps_path=eps_path)
    return pr.result if pr.converged else None
