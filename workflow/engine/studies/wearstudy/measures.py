"""The worn state's measures: the march the checks compare with, the wear measures, the friction
energy per cycle [J] and the resonance shift, and the change of two wear-rate profiles."""
from __future__ import annotations

import numpy as np

from workflow.engine.studies.wearstudy.options import WearOptions, WearStudy


def _measure(study: WearStudy, model, law, wp, opt: WearOptions, log, new=None, worn_wp=None) -> None:
    """The worn state's measures (:func:`workflow.engine.wear.measures.wear_measures`), the
    friction energy per cycle before and after wear [J] and, with ``opt.resonance_shift``, the
    worn − new friction-damped resonance — of the march the checks compare with (pseudo-time
    first), in place; nothing when no march reached a worn steady state. ``new``: (problem,
    unknowns) of the unworn vibration (default ``wp`` and ``study.base.x``); ``worn_wp``: the
    problem at the worn state's frequency (default ``wp``; a dwell's last stage). A mission's
    energy per cycle is its points' weighted with their shares: per cycle of the mission."""
    from workflow.engine.studies.operating import resonance_shift
    from workflow.engine.wear.measures import wear_measures

    h = _steady_history(study.histories)
    if h is None:
        return
    study.measures = {"method": h.method, **wear_measures(h.W, model.position, model.area, model.flank,
                                                          opt.measure_length_m)}
    wp_new, x_new = new or (wp, study.base.x)
    worn_wp = worn_wp or wp
    study.energy_per_cycle_J = {"new": _energy(wp_new, x_new, np.zeros(wp.p)), "worn": _energy(worn_wp, h.x, h.W)}
    wp_new.set_wear(np.zeros(wp.p))
    worn_wp.set_wear(np.zeros(wp.p))
    if opt.resonance_shift:
        new = None
        if study.operating_point.get("resonance_hz") is not None:
            new = {"hz": study.operating_point["resonance_hz"],
                   "amplitude_m": study.operating_point["resonance_amplitude_m"]}
        study.resonance_shift = resonance_shift(model, law, h.W, opt, new=new)
        r = study.resonance_shift
        if log is not None and r.get("hz") is None:
            log.info(f"friction-damped resonance shift not found: {r['reason']}")
        elif log is not None:
            log.info(f"friction-damped resonance new {r['new_hz']:.6g} Hz, worn {r['worn_hz']:.6g} Hz "
                     f"({r['rel']:+.2e}), peak amplitude {r['amplitude_rel']:+.2%} ({r['seconds']:.1f} s)")


def _energy(wp, x, W) -> float:
    """Friction energy per cycle [J] of ``wp``'s vibration x at the wear W: a mission's, its
    points' weighted with their shares."""
    from workflow.engine.dissipation import energy_per_cycle

    st = wp.evaluate(x, W=W)
    one = lambda q: float(energy_per_cycle(q.lam[..., 1:], q.slip).sum())  # noqa: E731
    if getattr(st, "members", None) is None:
        return one(st)
    return float(sum(s * one(q) for s, q in zip(wp.shares, st.members)))


def _steady_history(histories: dict):
    """The march the ε- and Nh-checks compare with (pseudo-time first), or None when it
    did not reach a worn steady state — the checks then compare the unworn wear rates."""
    h = histories.get("pseudo-time") or next(iter(histories.values()), None)
    return h if h is not None and h.steady else None


def _rate_change(rate0, rate1) -> float:
    """``max|Δrate| / max rate`` of two wear-rate profiles (0 when nothing wears)."""
    top = float(np.max(np.abs(rate0)))
    return float(np.max(np.abs(rate1 - rate0)) / top) if top > 0 else 0.0
