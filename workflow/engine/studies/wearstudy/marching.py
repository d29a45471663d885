"""One march to the worn steady state (:func:`march`) and a march along a resonance dwell's stages
(:func:`_replay`): each stage's problem at its frequency, the stages joined into one history."""
from __future__ import annotations

import math

import numpy as np

from workflow.engine.studies.wearstudy.options import WearOptions


def march(wp, x, method: str, opt: WearOptions, track: int, block_tol: float, W0=None,
           max_cycles: float = math.inf, max_increment: float = math.inf, report=None, step_lengths=None):
    """One march of ``wp`` by ``method`` from x and the wear W0 [m] (None: unworn), to the worn
    steady state — or, a stage, to ``max_cycles`` cycles or ``max_increment`` [m] more wear.
    ``report``: the pseudo-time march's progress messages; ``step_lengths`` (cycles): its steps
    given, another march replayed (:func:`~workflow.engine.wear.pseudo_time_wear`)."""
    from workflow.engine.wear import march_reference, pseudo_time_wear

    common = dict(cycles_per_block=opt.cycles_per_block, steady_tol=opt.steady_tol, tol=opt.tol, track=track,
                  max_cycles=max_cycles, max_increment=max_increment)
    wp.set_wear(np.zeros(wp.p) if W0 is None else W0)
    if method == "pseudo-time":
        return pseudo_time_wear(wp, x, max_steps=opt.max_steps, rtol=opt.rtol, dt_max_blocks=opt.dt_max_blocks,
                                report=report, step_lengths=step_lengths, **common)
    if step_lengths is not None:
        raise ValueError(f"march: step_lengths is for the pseudo-time march, not {method!r}")
    return march_reference(wp, x, scheme=method, max_blocks=opt.max_blocks, block_tol=block_tol, **common)


def _stage_problem(wp, rc, omega: float):
    """``wp`` (a :class:`~workflow.engine.wear.WearProblem`) at the frequency ``omega`` [rad/s]: its
    HB problem's linear part condensed there (:meth:`HBProblem.with_linear`: the same law, Nh,
    nit and stick anchor — the blade wears in place), the same wear law."""
    from workflow.engine.linear import condensed
    from workflow.engine.wear import WearProblem

    c = condensed(rc, omega, wp.hb.nh)
    return WearProblem(wp.hb.with_linear(c.Zr, c.Fr), wp.area, wp.k_w, wp.share, eps_path=wp.eps_path,
                       averaging=wp.averaging)


def _replay(wp, x, method: str, opt: WearOptions, track: int, block_tol: float, rc, schedule):
    """``wp`` (at the schedule's first frequency) marched by ``method`` from x and no wear
    through a dwell's stages (:func:`_dwell`): stage k at ω_k for cycles_k cycles, the last to
    its worn steady state — the same excitation history, for another method or a check."""
    from workflow.engine.wear.history import STAGE_END

    stages, W = [], None
    for k, (omega, cycles) in enumerate(schedule):
        q = wp if k == 0 else _stage_problem(wp, rc, omega)
        h = march(q, x, method, opt, track, block_tol, W0=W, max_cycles=cycles)
        stages.append(h)
        if not (h.steady or h.reason.startswith(STAGE_END)):
            break
        W, x = h.W, h.x
    return _join(stages)


def _join(stages: list):
    """One :class:`~workflow.engine.wear.WearHistory` of a march's consecutive stages: the paths
    end to end (cycles counted from the first stage's start), the counts summed, the end state,
    steadiness and reason the last stage's."""
    from workflow.engine.wear import WearHistory

    last = stages[-1]
    out = WearHistory(method=last.method, W=last.W, x=last.x, steady=last.steady,
                      seconds=sum(h.seconds for h in stages), iterations=sum(h.iterations for h in stages),
                      hb_solves=sum(h.hb_solves for h in stages),
                      jacobian_evaluations=sum(h.jacobian_evaluations for h in stages), final_rate=last.final_rate,
                      reason=last.reason if len(stages) == 1 else f"stage {len(stages)}: {last.reason}",
                      persistent_slip=last.persistent_slip, vibration_lost=last.vibration_lost,
                      w_scale=stages[0].w_scale)
    t = 0.0
    for h in stages:
        out.cycles += [t + c for c in h.cycles]
        out.max_wear += list(h.max_wear)
        out.max_rate += list(h.max_rate)
        out.harmonic1 += list(h.harmonic1)
        out.W_history += list(h.W_history)
        t += float(h.cycles[-1]) if h.cycles else 0.0
    return out
