"""The resonance dwell (``operating_point = "resonance"``): the march in stages, the excitation
moved to the peak of the worn system between them (:func:`_dwell`), and its record."""
from __future__ import annotations

import math

import numpy as np

from workflow.engine.errors import BundleError, SceneError, SolverError
from workflow.engine.studies.wearstudy.marching import _join, _stage_problem, march
from workflow.engine.studies.wearstudy.options import DWELL_UNFINISHED, WearOptions


#: The resonance dwell's first stage wears this fraction of the unworn normal interpenetration
#: (:func:`workflow.engine.wear.history.penetration_scale`); the budget then adapts by × 0.25 … 4 a stage.
#: Where a pad's whole load is one interpenetration (a Jenkins pad on its own normal spring) its
#: peak moves 7.5 % over that wear; on the quick sector 2e-4 over 2.6 µm: small enough for the
#: first, two stages of growth for the second.
DWELL_FIRST = 1.0 / 16.0


def _dwell(model, law, wp, rc, omega: float, x, method: str, opt: WearOptions, track: int, log):
    """The resonance dwell (``operating_point = "resonance"``) marched by ``method`` from the
    unworn vibration x of ``wp`` at ``omega`` [rad/s] (the new model's friction-damped peak).

    The excitation follows the peak of the wearing system, in stages: each stage marches at one
    frequency (:func:`_march`) until its deepest pair has worn a budget more — or to the worn
    steady state —, then the peak of the system with the reached wear is found again
    (:func:`workflow.engine.studies.operating.friction_damped_resonance` with the march's own
    static state: the blade wore in place, its stick anchors are the new assembly's) and the next
    stage starts there from that peak's vibration. The budget starts at :data:`DWELL_FIRST` of the
    unworn state's normal interpenetration (:func:`workflow.engine.wear.history.penetration_scale`, the W
    scale of the dynamics) and adapts so that a stage moves the peak by about ``opt.dwell_step``
    (× 0.25 … 4 a stage): the peak is the worst case only if the excitation stays on it as the
    wear moves it, and the end state depends on the path (quick sector, Nh = 3: max wear 1.261 /
    1.173 mm at ``dwell_step`` 1e-3 / 3e-4, docs/wear.md). It ends when a stage reaches its worn
    steady state and the peak then lies within ``opt.dwell_tol`` of that stage's frequency: a
    worn steady state at the peak of its own worn system, by the march's own convergence test;
    after ``opt.dwell_stages``, or where the peak cannot be found, it stops, not steady
    (:data:`DWELL_UNFINISHED`).

    Returns (the stages' history joined, the schedule [(ω_k [rad/s], cycles_k)] — the last
    stage's cycles ∞: its march runs to the steady state — for :func:`_replay`, the operating
    point's record, the last stage's problem)."""
    import time

    from workflow.engine.studies.operating import friction_damped_resonance
    from workflow.engine.wear.history import STAGE_END, penetration_scale

    t0 = time.perf_counter()
    kw = dict(method=opt.method, nh=opt.nh, nit=opt.nit, tol=opt.tol, max_iterations=opt.max_iterations,
              max_passes=opt.max_passes, static=wp.hb.static, what='wear.operating_point = "resonance"')
    W = np.zeros(wp.p)
    budget = DWELL_FIRST * penetration_scale(wp, wp.evaluate(x, W=W))
    q, f, stages, rows, schedule, done, t_peak = wp, omega / (2 * np.pi), [], [], [], False, 0.0
    stopped = f"after {opt.dwell_stages} stages (wear.dwell_stages)"
    for k in range(opt.dwell_stages):
        h = march(q, x, method, opt, track, opt.block_tol, W0=W, max_increment=budget)
        stages.append(h)
        row = {"stage": k, "frequency_hz": f, "cycles": float(h.cycles[-1]), "max_wear_m": float(np.max(h.W)),
               "steady": bool(h.steady)}
        rows.append(row)
        if not (h.steady or h.reason.startswith(STAGE_END)):
            schedule.append((2 * np.pi * f, math.inf))     # no steady state, no peak to move to: stop
            break
        t = time.perf_counter()
        try:
            pk = friction_damped_resonance(model, law.with_wear(h.W), **kw)
        except (SceneError, BundleError, SolverError) as exc:
            # the peak of the worn system left the band or its FRF failed: the dwell cannot go on,
            # and what it reached so far is said, not thrown away
            row["peak_error"] = str(exc)
            schedule.append((2 * np.pi * f, math.inf))
            stopped = f"no peak of the worn system to move to ({exc})"
            break
        finally:
            t_peak += time.perf_counter() - t
        move = pk["hz"] / f - 1.0
        row.update(peak_hz=pk["hz"], peak_amplitude_m=pk["amplitude_m"], move_rel=move)
        if log is not None:
            log.info(f"dwell stage {k}: {f:.6g} Hz, {h.cycles[-1]:.3g} cycles, max W = {np.max(h.W):.3e} m"
                     f"{', steady' if h.steady else ''}; peak of the worn system {pk['hz']:.6g} Hz ({move:+.2e})")
        if h.steady and abs(move) <= opt.dwell_tol:
            schedule.append((2 * np.pi * f, math.inf))
            done = True
            break
        schedule.append((2 * np.pi * f, float(h.cycles[-1])))
        budget *= min(4.0, max(0.25, opt.dwell_step / abs(move))) if move else 4.0
        f, W = pk["hz"], h.W
        q = _stage_problem(wp, rc, 2 * np.pi * f)
        x = q.hb.unknowns_from_harmonics(pk["Ur"])         # the peak's vibration at this wear
    hist = _join(stages)
    if not done and (hist.steady or hist.reason.startswith(STAGE_END)):
        last = rows[-1].get("move_rel")
        hist.steady, hist.persistent_slip = False, False
        moves = "" if last is None else f": the peak still moves by {last:+.2e} of the frequency"
        hist.reason = f"{DWELL_UNFINISHED} {stopped}{moves}; {hist.reason}"
    return hist, schedule, _dwell_record(opt, done, stages, rows, t_peak, time.perf_counter() - t0), q


def _dwell_record(opt: WearOptions, done: bool, stages: list, rows: list, peak_seconds: float, seconds: float) -> dict:
    """The operating point's record of a resonance dwell (summary.json ``wear.operating_point.dwell``)."""
    return {"dwell": {"converged": done, "stages": len(stages), "relocations": sum("peak_hz" in r for r in rows),
                      "tol": opt.dwell_tol, "step": opt.dwell_step, "final_move_rel": rows[-1].get("move_rel"),
                      "frequencies_hz": [r["frequency_hz"] for r in rows], "history": rows,
                      "peak_search_seconds": peak_seconds, "seconds": seconds}}
