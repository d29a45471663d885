"""The wear problem at Nh × 1.5 (:func:`_at_finer_nh`) and a lost vibration re-solved there
(:func:`finer_nh_resolve`)."""
from __future__ import annotations

import numpy as np

from workflow.engine.errors import BundleError
from workflow.engine.studies.wearstudy.options import WearOptions
from workflow.engine.studies.wearstudy.points import _held, _points


def _at_finer_nh(rc, omega: float, hb, x):
    """``hb`` at Nh × 1.5 (nit alike, :func:`workflow.engine.studies.epscheck.finer`) on the same law and
    static state, and x's harmonics as its guess: (problem, guess, Nh, nit, None), or (None,
    None, Nh, nit, why) for a cyclic model reduced for no more harmonics."""
    from workflow.engine.studies.epscheck import finer
    from workflow.engine.linear import condensed
    from workflow.engine.hb import HBProblem

    nh2, nit2 = finer(hb.nh, hb.nit)
    try:
        c = condensed(rc, omega, nh2)
    except BundleError as exc:
        return None, None, nh2, nit2, f"{exc}; reduction.cyclic_harmonics"
    # the static state does not depend on Nh: the unworn point's is carried over
    fine = HBProblem(c.Zr, c.Fr, hb.law, nh2, nit2, hb.method, max_passes=hb.max_passes, static=hb.static)
    return fine, fine.unknowns_from_harmonics(hb.harmonics(x)), nh2, nit2, None


def finer_nh_resolve(rc, omega: float, wp, hist, opt: WearOptions, eps_path) -> dict:
    """The vibration at a march's last wear ``hist.W`` re-solved at Nh × 1.5 (nit alike,
    :func:`workflow.engine.studies.epscheck.finer`) through the whole cascade, from the march's last
    x: where the march lost the vibration (``hist.vibration_lost``), this tells a root that
    the truncated balance lacks from one that is not there at all. Measured on the
    interface-scaling sector of 256 pairs (Nh = 3, nit = 64, wear at 212.36 Hz): the march
    lost the vibration at max W = 1.10 µm, where the cascade at Nh = 3 failed after 260
    iterations (nit = 128 alike, 211) while Nh = 5 converged in 6 and Nh = 7 in 7.
    Returns {nh, nit, converged, iterations, reason}."""
    from workflow.engine.cascade import solve_point

    out, its = {}, 0
    for q, om, xk in _points(wp, omega, hist.x):          # a mission: every operating point
        fine, guess, nh2, nit2, why = _at_finer_nh(rc, om, q.hb, xk)
        out = {"nh": nh2, "nit": nit2, "converged": False, "iterations": its}
        if fine is None:
            return {**out, "reason": why}
        W = np.maximum(np.asarray(hist.W, dtype=float), 0.0)
        fine.set_wear(W)
        if _held(wp):                                  # the bordered solve, its load scale
            from workflow.engine.studies.amplitude import AmplitudeProblem
            from workflow.engine.wear import WearProblem

            held = AmplitudeProblem(WearProblem(fine, q.area, q.k_w, q.share, eps_path=q.eps_path), (wp.C, wp.d),
                                    wp.target)
            pr, _ = held.solve_hb(np.append(guess, hist.x[-1]), W, tol=opt.tol, maxiter=opt.max_iterations)
            its += int(pr.iterations)
            out = {**out, "converged": bool(pr.converged), "iterations": its, "reason": pr.reason}
            break
        pr = solve_point(fine, [guess], solver="newton-powell", tol=opt.tol, maxiter=opt.max_iterations,
                         eps_path=eps_path)
        its += int(pr.iterations)
        out = {**out, "converged": bool(pr.converged), "iterations": its, "reason": pr.result.reason}
        if not pr.converged:
            break
    return out
