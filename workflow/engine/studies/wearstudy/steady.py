"""The front door :func:`worn_steady_state`: the unworn point, every method's march, the measures
and the checks → :class:`WearStudy`."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from workflow.engine import penalty
from workflow.engine.errors import SceneError
from workflow.engine.studies.wearstudy.checks import _penalty_and_truncation_checks, reference_check
from workflow.engine.studies.wearstudy.dwell import _dwell
from workflow.engine.studies.wearstudy.finer_nh import finer_nh_resolve
from workflow.engine.studies.wearstudy.marching import _replay, march
from workflow.engine.studies.wearstudy.measures import _measure
from workflow.engine.studies.wearstudy.mission import _mission, _mission_rates
from workflow.engine.studies.wearstudy.options import METHODS, WearOptions, WearStudy, _lost_hint
from workflow.engine.studies.wearstudy.points import _held_amplitude
from workflow.engine.studies.wearstudy.unworn import _unworn_at, _unworn_start, build_problem, unworn_solvers


def worn_steady_state(model, law, opt: WearOptions | None = None, *, eps_path=None,
                      log=None, report=None) -> WearStudy:
    """Fretting wear of ``model``'s pairs under ``law`` to the worn steady state
    by each of ``opt.methods`` (see the module docstring); ``eps_path`` as in
    :func:`workflow.engine.cascade.along_eps_path` (None: the law's own,
    :func:`workflow.engine.penalty.path_of`). ``report(message)``: a long pseudo-time march's
    progress (:data:`workflow.engine.wear.pseudotime.REPORT_SECONDS`; None: ``log.info``).

    A resonance dwell's study is at its last frequency (``omega``, ``hb``, ``base`` the unworn
    vibration there); its first method that :func:`_steady_history` would pick dwells
    (:func:`_dwell`), the others, the reference check and the ε- and Nh-checks march along the
    same stages (:func:`_replay`). A mission's study is at its headline point (``hb`` answers for
    the stacked unknowns, ``base`` stacks every point's unworn vibration)."""
    from workflow.engine.wear import WearProblem, profile_rel_diff

    opt = opt or WearOptions()
    bad = [m for m in opt.methods if m not in METHODS]
    if bad:
        raise SceneError(f"wear.methods: {bad} not among {', '.join(METHODS)}")
    from workflow.engine.studies.operating import operating_frequency

    f_op, point = operating_frequency(model, law, opt)
    hb, rc, omega = build_problem(model, law, replace(opt, frequency_hz=f_op))
    point["frequency_hz"] = omega / 2 / np.pi
    if eps_path is None:
        eps_path = penalty.path_of(law, np.real(hb.Zr[0]))
    if log is not None:
        log.info(f"wear at {omega / 2 / np.pi:.3f} Hz, {hb.p} pairs, Nh = {hb.nh}, nit = {hb.nit}, {hb.method}; "
                 f"{penalty.describe(law)}")
    base, scale = _unworn_start(hb, omega, opt, eps_path, log)
    # the paper's comparison at the unworn point: Newton and pseudo-time from the same start
    unworn = unworn_solvers(hb, hb.x0(), tol=opt.tol, max_steps=min(opt.max_steps, 400), eps_path=eps_path) \
        if opt.compare_unworn else {}
    from workflow.engine.wear.law import averaging

    wp = WearProblem(hb, model.area, opt.k_w, opt.blade_share, eps_path=eps_path,
                     averaging=averaging(model.position, model.area, model.flank, opt.length_m, opt.length_over))
    if point["kind"] == "mission":
        wp, base = _mission(rc, wp, base, point, opt, eps_path, log)
    if opt.control == "amplitude":
        wp, base = _held_amplitude(rc, wp, base, omega, opt, point, log, scale)
    i0 = int(np.argmax(wp.evaluate(base.x).rate))
    track = 3 * i0 + 1
    histories, schedule, last = {}, None, wp
    if point["kind"] == "resonance":
        lead = "pseudo-time" if "pseudo-time" in opt.methods else opt.methods[0]
        histories[lead], schedule, dwell, last = _dwell(model, law, wp, rc, omega, base.x, lead, opt, track, log)
        point.update(dwell)
        point["frequency_hz"] = schedule[-1][0] / 2 / np.pi
    w_end = omega if schedule is None else schedule[-1][0]
    if report is None and log is not None:
        report = log.info
    histories = _every_method(wp, base.x, opt, track, rc, schedule, histories, w_end, eps_path, log, report)
    study = WearStudy(omega=w_end, hb=wp.hb, rc=rc, base=base, unworn=unworn, histories=histories, tracked_pair=i0,
                      operating_point=point)
    if schedule is not None:
        # the figures' unworn vibration at the dwell's last frequency, if it solves there
        study.hb = last.hb
        study.base = _unworn_at(last, base.x, opt, eps_path) or base
    if point["kind"] == "mission":
        _mission_rates(point, wp, base, histories)
    if opt.control == "amplitude":
        point["control"]["load_scale_worn"] = {m: float(h.x[-1]) for m, h in histories.items()}
    _measure(study, model, law, wp, opt, log, new=(wp, base.x), worn_wp=last)
    ref = next((m for m in ("implicit", "explicit") if m in histories), None)
    if ref is not None and "pseudo-time" in histories:
        study.profile_max_rel_diff = profile_rel_diff(histories[ref].W, histories["pseudo-time"].W)
        study.cpu_ratio_pseudo_over_reference = histories["pseudo-time"].seconds / max(histories[ref].seconds, 1e-12)
    if ref is not None and opt.reference_check and opt.block_tol > 0:
        coarse = march(wp, base.x, ref, opt, track, 4 * opt.block_tol) if schedule is None else \
            _replay(wp, base.x, ref, opt, track, 4 * opt.block_tol, rc, schedule)
        study.reference_check = reference_check(histories, ref, coarse, opt.block_tol)
    wp.set_wear(np.zeros(wp.p))     # the unworn point: the marches left the worn W in wp
    _penalty_and_truncation_checks(study, wp, base.x, opt, track, rc, omega, schedule, eps_path, log)
    return study


def _every_method(wp, x0, opt: WearOptions, track: int, rc, schedule, histories: dict, w_end: float,
                  eps_path, log, report=None) -> dict:
    """Each of ``opt.methods``'s march from ``x0`` (``histories`` holds the ones already run: a
    dwell's lead), along a dwell's ``schedule`` if any; a march that lost the vibration is
    re-solved at a finer Nh at ``w_end`` [rad/s] (:func:`finer_nh_resolve`). {method: history}."""
    for m in opt.methods:
        if m not in histories:
            histories[m] = march(wp, x0, m, opt, track, opt.block_tol, report=report) if schedule is None else \
                _replay(wp, x0, m, opt, track, opt.block_tol, rc, schedule)
        h = histories[m]
        if log is not None:
            log.info(f"{m}: {'steady' if h.steady else 'NOT steady'} after {h.iterations} iterations, "
                     f"{h.seconds:.2f} s, max W = {np.max(h.W):.3e} m ({h.reason})")
    histories = {m: histories[m] for m in opt.methods}
    for m, h in histories.items():
        if h.vibration_lost:
            h.finer_nh = finer_nh_resolve(rc, w_end, wp, h, opt, eps_path)
            if log is not None:
                log.info(f"{m}: the vibration lost at max W = {np.max(h.W):.3e} m; {_lost_hint(h)}")
    return histories
