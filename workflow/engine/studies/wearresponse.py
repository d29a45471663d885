"""The wear response curve (issue 48 item 1): the worn steady state against f / f_r, f_r the
model's friction-damped resonance (:mod:`workflow.engine.studies.operating`), each point one
pseudo-time march (:func:`workflow.engine.studies.wearstudy.worn_steady_state`)."""
from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from workflow.engine.studies.operating import friction_damped_resonance, resonance_shift
from workflow.engine.studies.wearstudy import worn_steady_state


def wear_response(model, law, opt, detunings, keep_states: bool = False, report=None) -> dict:
    """The wear response curve: the worn steady state at each ``detunings`` r × the model's
    friction-damped resonance f_r (found once) — what a designer reads instead of one number at
    one frequency. ``opt``: the :class:`~workflow.engine.studies.wearstudy.WearOptions` of each
    march (pseudo-time; the per-point checks and the resonance shift off: a curve of marches).
    {"resonance_hz", "rows": [{"detuning", "frequency_hz", "steady", "max_wear_m",
    "worn_volume_m3", "energy_new_J", "persistent_slip", "reason", "seconds"}], "seconds"}; a point
    without a worn steady state (persistent slip: the wear feeds the vibration) says so, its depth
    where the march stopped. With ``opt.resonance_shift`` each row also gives the worn blade's
    friction-damped resonance ``worn_resonance_hz`` and the detuning it sees, ``worn_detuning``
    = f / f_r,worn (None where it is not found): wear lowers the resonance, and a worn steady
    state next to it ends where the excitation sits above the worn peak. ``keep_states``: each row also holds its worn depth ``"W"`` (p,) [m]
    (for measures of the profile; not JSON); ``report(message)``: one line a point done."""
    t0 = time.perf_counter()
    res = friction_damped_resonance(model, law, method=opt.method, nh=opt.nh, nit=opt.nit, tol=opt.tol,
                                    max_iterations=opt.max_iterations, max_passes=opt.max_passes)
    rows = []
    for r in sorted(float(d) for d in detunings):
        t = time.perf_counter()
        one = replace(opt, methods=("pseudo-time",), operating_point="frequency", frequency_hz=r * res["hz"],
                      eps_check_factor=0.0, nh_check=False, compare_unworn=False, resonance_shift=False)
        st = worn_steady_state(model, law, one)
        h = st.histories["pseudo-time"]
        rows.append({"detuning": r, "frequency_hz": st.omega / (2 * np.pi), "steady": bool(h.steady),
                     "max_wear_m": float(np.max(h.W)), "worn_volume_m3": st.measures.get("worn_volume_m3"),
                     "energy_new_J": st.energy_per_cycle_J.get("new"), "persistent_slip": bool(h.persistent_slip),
                     "reason": h.reason, "seconds": time.perf_counter() - t})
        if opt.resonance_shift:
            worn = resonance_shift(model, law, h.W, opt, new=res).get("worn_hz")
            rows[-1].update({"worn_resonance_hz": worn,
                             "worn_detuning": None if worn is None else rows[-1]["frequency_hz"] / worn,
                             "seconds": time.perf_counter() - t})
        if keep_states:
            rows[-1]["W"] = np.asarray(h.W, float).copy()
        if report is not None:
            report(f"wear response: f/f_r = {r:g}: max W {rows[-1]['max_wear_m']:.4g} m, "
                   f"steady {rows[-1]['steady']}, {rows[-1]['seconds']:.0f} s")
    return {"resonance_hz": res["hz"], "rows": rows, "seconds": time.perf_counter() - t0}
