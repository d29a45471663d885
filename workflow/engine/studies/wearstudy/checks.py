"""The wear checks: ε × the factor and Nh × 1.5 (:func:`eps_check`, :func:`nh_check`, marched again at
:data:`CHECK_RTOL` × the tolerance) and the reference's convergence in its block size (:func:`reference_check`)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from workflow.engine import penalty
from workflow.engine.studies.wearstudy.finer_nh import _at_finer_nh
from workflow.engine.studies.wearstudy.marching import _replay, march
from workflow.engine.studies.wearstudy.measures import _rate_change, _steady_history
from workflow.engine.studies.wearstudy.options import WearOptions, WearStudy
from workflow.engine.studies.wearstudy.points import _like, _points


#: The wear checks' second marches (Nh × 1.5, ε × 10) run at this fraction of ``WearOptions.rtol``
#: (and ``CHECK_STEPS`` × its step budget): at the march's own tolerance their end on the
#: worn-steady-state manifold moved by ~0.1 % of max W with changes that only touch round-off,
#: the order of the checks' 1e-3 tolerance. Measured on paper-wear (48 pairs, Nh = 3, alone):
#: the Nh-check read 0.21 %, 0.117 % and 0.098 % at 1e-3 (2026-11-28, J formed and
#: not), 0.0446 % and 0.0447 % at 1e-4 (J not formed / formed); ε × 10 0.14 / 0.136 / 0.075 %
#: at 1e-3, 0.0855 / 0.0881 % at 1e-4. The march at 1e-4 took 621 steps against 186.
CHECK_RTOL = 0.1


CHECK_STEPS = 4


def nh_check(rc, omega: float, wp, x, opt: WearOptions, eps_path, *, worn=None, track: int = 1,
             schedule=None) -> dict:
    """The wear at ``omega`` (rad/s) with Nh × 1.5 (nit alike,
    :func:`workflow.engine.studies.epscheck.finer`), on the same law and static state.

    The unworn point is re-solved from ``x``; ``unworn_rate_change`` is the change of
    the wear-rate profile, ``max|Δrate| / max rate``. With ``worn`` (a
    :class:`~workflow.engine.wear.WearHistory` of this study) the pseudo-time march then runs
    (at :data:`CHECK_RTOL` × the tolerance) to the worn steady state at the finer Nh and
    ``max_rel_change`` is the change of the worn profile, :func:`workflow.engine.wear.profile_rel_diff`
    — the convergence of the result itself. Measured on the quick sector (16 pairs): the unworn rates move 2.1 %
    from Nh = 5 to 8, the worn steady state 1.3133 → 1.3144 µm (Nh = 7); without
    ``worn``, ``max_rel_change`` is the unworn rates' change. A mission: every point at Nh × 1.5;
    a dwell (``schedule``, :func:`_replay`): the march along its stages."""
    from workflow.engine.cascade import solve_point
    from workflow.engine.wear import WearProblem

    fines, xs = [], []
    for q, om, xk in _points(wp, omega, x):
        fine, guess, nh2, nit2, why = _at_finer_nh(rc, om, q.hb, xk)
        out = {"nh": nh2, "nit": nit2, "max_rel_change": None}
        if fine is None:
            return {**out, "reason": why}
        pr = solve_point(fine, [guess], solver="newton-powell", tol=opt.tol, maxiter=opt.max_iterations,
                         eps_path=eps_path)
        if not pr.converged:
            return {**out, "measure": "unworn wear rates"}
        fines.append(WearProblem(fine, q.area, q.k_w, q.share, eps_path=q.eps_path, averaging=q.averaging))
        xs.append(pr.result.x)
    wfine, x2 = _like(wp, fines, xs)
    return {**out, **_changes(wp.evaluate(x).rate, wfine, x2, opt, worn, track, f"at Nh = {nh2}", rc, schedule)}


def eps_check(wp, x, opt: WearOptions, *, worn=None, track: int = 1, rc=None, schedule=None) -> dict:
    """The wear with ε × ``opt.eps_check_factor``: the unworn point re-solved from
    ``x`` (``unworn_rate_change``: ``max|Δrate| / max rate``) and, with ``worn`` (a
    :class:`~workflow.engine.wear.WearHistory` of this study), the pseudo-time march (at
    :data:`CHECK_RTOL` × the tolerance) to the worn steady state at that ε (``max_rel_change``:
    the worn profile's change, :func:`workflow.engine.wear.profile_rel_diff`; without ``worn`` the
    unworn rates'). A mission: every point at ε × the factor; a dwell (``schedule``, with the
    model's ``rc``, :func:`_replay`): the march along its stages."""
    from workflow.engine.cascade import solve_point
    from workflow.engine.wear import WearProblem

    fac = float(opt.eps_check_factor)
    rate0 = wp.evaluate(x).rate
    out = {"factor": fac, "max_rel_change": None}
    bigs, xs = [], []
    for q, _, xk in _points(wp, None, x):
        hb = q.hb
        big = hb.with_linear(hb.Zr, hb.Fr)
        big.set_contact(penalty.scaled(hb.law, fac))
        pr = solve_point(big, [xk], solver="newton-powell", tol=opt.tol, maxiter=opt.max_iterations,
                         eps_path=(1.0 / fac, fac ** -0.5))
        if not pr.converged:
            return {**out, "measure": "unworn wear rates"}
        bigs.append(WearProblem(big, q.area, q.k_w, q.share, eps_path=(1.0 / fac, fac ** -0.5),
                                averaging=q.averaging))
        xs.append(pr.result.x)
    wbig, x2 = _like(wp, bigs, xs)
    return {**out, **_changes(rate0, wbig, x2, opt, worn, track, f"at ε × {fac:g}", rc, schedule)}


def _changes(rate0, wp2, x2, opt: WearOptions, worn, track: int, where: str, rc=None, schedule=None) -> dict:
    """The check's measures on the modified problem ``wp2`` solved at ``x2``: the unworn
    rates' change against ``rate0`` and, with ``worn``, the worn profile's change after a
    pseudo-time march of ``wp2`` from ``x2`` — along a dwell's ``schedule`` if given
    (:func:`_replay`) — (``max_rel_change``: the worn profile's when there is one, else the
    rates')."""
    from workflow.engine.wear import profile_rel_diff

    rates = _rate_change(rate0, wp2.evaluate(x2).rate)
    if worn is None:
        return {"measure": "unworn wear rates", "max_rel_change": rates, "unworn_rate_change": rates}
    check = replace(opt, rtol=opt.rtol * CHECK_RTOL, max_steps=opt.max_steps * CHECK_STEPS)
    h = march(wp2, x2, "pseudo-time", check, track, opt.block_tol) if schedule is None else \
        _replay(wp2, x2, "pseudo-time", check, track, opt.block_tol, rc, schedule)
    wp2.set_wear(np.zeros(wp2.p))
    out = {"measure": "worn profile", "unworn_rate_change": rates, "seconds": h.seconds, "steady": bool(h.steady)}
    if h.steady:
        out["max_rel_change"] = profile_rel_diff(worn.W, h.W)
    else:
        out["reason"] = f"the march {where} did not reach its worn steady state ({h.reason})"
    return out


def reference_check(histories: dict, ref: str, coarse, block_tol: float) -> dict:
    """Convergence of the reference in its block size and every method's error.

    The block marching is first order in the block (explicit or implicit
    Euler on W), so with profiles W_f (``block_tol``) and W_c (4×) the
    Richardson estimate of the converged profile is ``W* = W_f + (W_f − W_c)/3``.
    Errors are :func:`workflow.engine.wear.profile_rel_diff` against W* (fraction of
    max W), next to each method's CPU seconds.
    """
    from workflow.engine.wear import profile_rel_diff

    Wf, Wc = histories[ref].W, coarse.W
    Wstar = Wf + (Wf - Wc) / 3.0
    rows = [{"method": f"{ref} block_tol={4 * block_tol:g}", "seconds": coarse.seconds,
             "error": profile_rel_diff(Wstar, Wc), "steady": bool(coarse.steady)}]
    for m, h in histories.items():
        label = f"{m} block_tol={block_tol:g}" if m == ref else m
        rows.append({"method": label, "seconds": h.seconds, "error": profile_rel_diff(Wstar, h.W),
                     "steady": bool(h.steady)})
    return {"self_diff": profile_rel_diff(Wf, Wc), "coarse_seconds": coarse.seconds,
            "coarse_steady": bool(coarse.steady), "error_vs_time": rows}


def _penalty_and_truncation_checks(study: WearStudy, wp, x0, opt: WearOptions, track: int, rc, omega: float,
                                   schedule, eps_path, log) -> None:
    """The wear ε- and Nh-checks of ``study`` (in place), marching again from the unworn ``x0``
    at ω [rad/s] only where the study's own march ended steady."""
    from workflow.engine.studies.epscheck import judged, log_line

    worn = _steady_history(study.histories)
    if opt.eps_check_factor > 0:
        study.eps_check = judged({**eps_check(wp, x0, opt, worn=worn, track=track, rc=rc, schedule=schedule),
                                  "frequency_hz": omega / 2 / np.pi})
        if log is not None:
            log.info(log_line(f"wear ε-check (ε × {opt.eps_check_factor:g}, the penalty's sensitivity)",
                              f"the {study.eps_check['measure']}", study.eps_check))
    if opt.nh_check:
        study.nh_check = judged({**nh_check(rc, omega, wp, x0, opt, eps_path, worn=worn, track=track,
                                            schedule=schedule),
                                 "frequency_hz": omega / 2 / np.pi})
        if log is not None:
            log.info(log_line("wear Nh-check (1.5×Nh, convergence)", f"the {study.nh_check['measure']}",
                              study.nh_check))
