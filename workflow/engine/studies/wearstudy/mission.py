"""A duty cycle (``operating_point = "mission"``): its points' problems and unworn vibrations stacked
(:func:`_mission`) and each point's wear rates new and worn [m/cycle] (:func:`_mission_rates`)."""
from __future__ import annotations

import math

import numpy as np

from workflow.engine.studies.wearstudy.marching import _stage_problem
from workflow.engine.studies.wearstudy.measures import _steady_history
from workflow.engine.studies.wearstudy.options import WearOptions
from workflow.engine.studies.wearstudy.unworn import unworn_point


def _mission(rc, wp, base, point: dict, opt: WearOptions, eps_path, log):
    """(:class:`~workflow.engine.studies.operating.MissionProblem`, its unworn SolveResult with the
    stacked unknowns) of the mission ``point``: ``wp`` and ``base`` are its headline point's; every
    other point with a share > 0 gets its HB problem (the same law and static state, condensed at
    its frequency) and unworn vibration. A point of share 0 wears nothing: it is not marched."""
    from workflow.engine.solvers import SolveResult
    from workflow.engine.studies.operating import MissionProblem

    members, bases, omegas, shares, head = [], [], [], [], 0
    for k, pt in enumerate(point["points"]):
        if pt["share"] <= 0:
            continue
        if k == point["headline"]:
            q, b, om = wp, base, 2 * np.pi * point["frequency_hz"]
            head = len(members)
        else:
            om = 2 * np.pi * pt["frequency_hz"]
            q = _stage_problem(wp, rc, om)
            b = unworn_point(q.hb, om, opt, eps_path)
        members.append(q)
        bases.append(b)
        omegas.append(om)
        shares.append(pt["share"])
        if log is not None:
            log.info(f"mission point {k}: {om / 2 / np.pi:.6g} Hz (f / f_r = {pt['detuning']:g}), "
                     f"share {pt['share']:g}")
    stacked = SolveResult(x=np.concatenate([b.x for b in bases]), converged=True,
                          iterations=sum(b.iterations for b in bases),
                          residual_norm=math.hypot(*[b.residual_norm for b in bases]), reason="converged")
    return MissionProblem(members, shares, omegas, head), stacked


def _mission_rates(point: dict, wp, base, histories: dict) -> None:
    """Each mission point's largest wear rate [m/cycle] unworn and at the worn state of the march
    the checks compare with (``max_rate_new_m_per_cycle``, ``max_rate_worn_m_per_cycle``), in
    ``point["points"]``; None for a point of share 0 (not marched)."""
    h = _steady_history(histories) or next(iter(histories.values()))
    new = wp.evaluate(base.x, W=np.zeros(wp.p)).members
    worn = wp.evaluate(h.x, W=h.W).members
    wp.set_wear(np.zeros(wp.p))
    it = iter(zip(new, worn))
    for pt in point["points"]:
        a, b = next(it) if pt["share"] > 0 else (None, None)
        pt["max_rate_new_m_per_cycle"] = float(np.max(a.rate)) if a is not None else None
        pt["max_rate_worn_m_per_cycle"] = float(np.max(b.rate)) if b is not None else None
