"""The engine's front door for fretting wear: :func:`worn_steady_state` (paper §4, §5.2).

A reduced model, a contact law and :class:`WearOptions` in; a
:class:`WearStudy` out: the unworn HB point (solved by Newton and by
pseudo-time from the same start), one :class:`~workflow.engine.wear.WearHistory`
per method — the physical-time reference march ("explicit" / "implicit"
blocks of cycles, :func:`workflow.engine.wear.march_reference`) and "pseudo-time"
(eq. 22, :func:`workflow.engine.wear.pseudo_time_wear`) — the worn profiles'
agreement, the reference's own convergence in its block size, and the
ε-check of the wear rates.

The operating point (:mod:`workflow.engine.studies.operating`) sets where the vibration is:
one frequency ("frequency", "detuning"); a resonance dwell ("resonance", :func:`_dwell`: the
march in stages, the excitation moved to the peak of the worn system between them); or a duty
cycle ("mission": one vibration per operating point, the wear rates summed with the shares,
:class:`~workflow.engine.studies.operating.MissionProblem`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from workflow.engine import penalty
from workflow.engine.errors import BundleError, SceneError, SolverError

METHODS = ("explicit", "implicit", "pseudo-time")
#: The wear checks' second marches (Nh × 1.5, ε × 10) run at this fraction of ``WearOptions.rtol``
#: (and ``CHECK_STEPS`` × its step budget): at the march's own tolerance their end on the
#: worn-steady-state manifold moved by ~0.1 % of max W with changes that only touch round-off,
#: the order of the checks' 1e-3 tolerance. Measured on paper-wear (48 pairs, Nh = 3, alone):
#: the Nh-check read 0.21 %, 0.117 % and 0.098 % at 1e-3 (2026-11-28, J formed and
#: not), 0.0446 % and 0.0447 % at 1e-4 (J not formed / formed); ε × 10 0.14 / 0.136 / 0.075 %
#: at 1e-3, 0.0855 / 0.0881 % at 1e-4. The march at 1e-4 took 621 steps against 186.
CHECK_RTOL = 0.1
CHECK_STEPS = 4


@dataclass
class WearOptions:
    """``methods`` ⊂ :data:`METHODS`; HB: ``method``, ``nh``, ``nit``,
    ``tol``, ``max_iterations``, ``max_passes``; ``frequency_hz`` (0: first
    tied resonance); Archard ``k_w`` (m²/N) and ``blade_share``; the march:
    ``cycles_per_block``, ``max_blocks``, ``block_tol``, ``steady_tol``,
    ``reference_check``; pseudo-time: ``max_steps``, ``rtol``,
    ``dt_max_blocks``; ``eps_check_factor`` (0: off); ``nh_check``: the
    unworn wear rates re-solved at 1.5×Nh (:func:`nh_check`); ``compare_unworn``:
    also solve the unworn point by Newton and by pseudo-time (the paper's
    comparison); ``operating_point`` "frequency" (``frequency_hz``) or "detuning"
    (``detuning`` × the friction-damped resonance, :mod:`workflow.engine.studies.operating`);
    ``length_m``: the wear law's length scale ℓ [m] (0: node-wise, eq. 21;
    :func:`workflow.engine.wear.law.averaging`); ``measure_length_m``: ℓ [m] of the filtered profile among the wear measures
    (:mod:`workflow.engine.wear.measures`); ``resonance_shift``: find the friction-damped
    resonance of the worn and the new model (two FRF searches).

    ``operating_point`` "resonance" (the dwell, :func:`_dwell`): ``dwell_tol`` — it ends when a
    stage is steady and the peak of the worn system lies within this fraction of the stage's
    frequency; ``dwell_step`` — the relative move of the peak a stage aims at (its wear budget
    adapts to it); ``dwell_stages`` — stages at most. "mission": ``mission`` ((r, share), …), r =
    f / f_r (f_r the new model's friction-damped resonance), shares of the cycles ≥ 0 summing to 1
    (:func:`workflow.engine.studies.operating.mission_points`). ``control`` "force" (the load as
    built) or "amplitude": the tip held at ``tip_amplitude_m`` [m] (0: the unworn response),
    :mod:`workflow.engine.studies.amplitude`."""

    methods: tuple = ("pseudo-time", "implicit")
    method: str = "hbm"
    nh: int = 3
    nit: int = 64
    tol: float = 1e-8
    max_iterations: int = 100
    max_passes: int = 20
    frequency_hz: float = 0.0
    k_w: float = 1e-13
    blade_share: float = 0.5
    cycles_per_block: float = 1e5
    max_blocks: int = 400
    block_tol: float = 0.01
    steady_tol: float = 1e-4
    reference_check: bool = False
    max_steps: int = 2000
    rtol: float = 1e-3
    dt_max_blocks: float = 0.0
    eps_check_factor: float = penalty.CHECK_FACTOR
    nh_check: bool = True
    compare_unworn: bool = True
    operating_point: str = "frequency"
    detuning: float = 1.0
    measure_length_m: float = 2e-3
    length_m: float = 0.0
    resonance_shift: bool = True
    mission: tuple = ()
    dwell_tol: float = 1e-5
    dwell_step: float = 3e-4
    dwell_stages: int = 100
    control: str = "force"
    tip_amplitude_m: float = 0.0


@dataclass
class WearStudy:
    """What :func:`worn_steady_state` found. ``omega`` (rad/s), ``base`` the
    unworn :class:`SolveResult`, ``histories`` {method: WearHistory},
    ``tracked_pair``; ``unworn`` the Newton/pseudo-time comparison;
    ``profile_max_rel_diff`` and ``cpu_ratio_pseudo_over_reference`` (None
    without both); ``reference_check`` or None; ``eps_check``."""

    omega: float
    hb: object
    rc: object
    base: object
    unworn: dict
    histories: dict
    tracked_pair: int
    profile_max_rel_diff: float | None = None
    cpu_ratio_pseudo_over_reference: float | None = None
    reference_check: dict | None = None
    eps_check: dict = field(default_factory=dict)
    nh_check: dict = field(default_factory=dict)
    operating_point: dict = field(default_factory=dict)
    measures: dict = field(default_factory=dict)
    energy_per_cycle_J: dict = field(default_factory=dict)
    resonance_shift: dict | None = None

    def unconverged(self) -> list[str]:
        """One line per wear method that did not reach the steady state, with what to change:
        the step or block budget — unless the wear rate is not decaying (persistent slip),
        where no budget reaches a worn steady state."""
        def hint(m, h):
            if h.vibration_lost:
                return _lost_hint(h)
            if h.persistent_slip:
                return ("no worn steady state at this load and friction: more steps or blocks "
                        "only wear deeper")
            if h.reason.startswith(DWELL_UNFINISHED):
                return ("raise wear.dwell_stages" if "wear.dwell_stages" in h.reason else
                        "the dwell lost the peak: use wear.operating_point = \"detuning\"")
            return f"raise {'wear.max_blocks' if m in ('explicit', 'implicit') else 'pseudotime.max_steps'}"

        return [f"wear {m}: NOT steady after {h.iterations} iterations ({h.reason}); {hint(m, h)}"
                for m, h in self.histories.items() if not h.steady]

    def warnings(self) -> list[str]:
        """Converged results whose Nh-check exceeds its tolerance or could not be made
        (the ε-check is reported, not tested: :mod:`workflow.engine.studies.epscheck`)."""
        nc = self.nh_check or {}
        ch = nc.get("max_rel_change")
        what = nc.get("measure", "unworn wear rates")
        if nc and ch is None:
            return [f"wear Nh-check: the {what} could not be computed at Nh = {nc['nh']} "
                    f"({nc.get('reason') or 'the solver gave up'}); how converged the wear is in Nh is unknown"]
        if ch is not None and ch > penalty.CHECK_TOL:
            return [f"wear Nh-check: the {what} moves by {ch:.2e} (> {penalty.CHECK_TOL:g}) at "
                    f"Nh = {nc['nh']}, nit = {nc['nit']}; raise hb.harmonics"]
        return []


def _lost_hint(h) -> str:
    """What to change for a march that lost the vibration (``h.vibration_lost``), from its
    re-solve at 1.5×Nh (``h.finer_nh``, :func:`finer_nh_resolve`): more steps or blocks
    cannot help either way."""
    f = h.finer_nh
    if f is None:
        return "more steps or blocks do not help"
    if f["converged"]:
        return (f"at Nh = {f['nh']} (nit = {f['nit']}) the same wear solves in {f['iterations']} iterations: "
                "the vibration was lost to the harmonic truncation — raise hb.harmonics")
    return (f"nor at Nh = {f['nh']} (nit = {f['nit']}) ({f['reason']}): more steps, blocks or harmonics "
            "do not help")


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


def _held(wp) -> bool:
    """Whether ``wp`` holds a tip amplitude (:class:`~workflow.engine.studies.amplitude.AmplitudeProblem`:
    its unknowns end with the load scale)."""
    return getattr(wp, "target", None) is not None


def _points(wp, omega, x) -> list:
    """[(WearProblem, ω [rad/s], its unknowns)] of each operating point of ``wp``: a
    :class:`~workflow.engine.studies.operating.MissionProblem`'s points, else ``wp`` itself at ω."""
    if _held(wp):                                     # the vibration at its load
        wp.set_scale(x[-1])
        return [(wp.wp, omega, np.asarray(x)[:-1])]
    if getattr(wp, "members", None) is None:
        return [(wp, omega, x)]
    return list(zip(wp.members, wp.omegas, wp.split(x)))


def _like(wp, problems: list, xs: list):
    """(problem, unknowns) of the same kind as ``wp`` from its points' modified problems and
    solutions (:func:`_points`): a mission of them, or the one."""
    if _held(wp):
        return wp.like(problems[0], xs[0])
    if getattr(wp, "members", None) is None:
        return problems[0], xs[0]
    from workflow.engine.studies.operating import MissionProblem

    return MissionProblem(problems, wp.shares, wp.omegas, wp.headline), np.concatenate(xs)


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
    from reduction.condense import relative_coordinates
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


def march(wp, x, method: str, opt: WearOptions, track: int, block_tol: float, W0=None,
           max_cycles: float = math.inf, max_increment: float = math.inf, report=None):
    """One march of ``wp`` by ``method`` from x and the wear W0 [m] (None: unworn), to the worn
    steady state — or, a stage, to ``max_cycles`` cycles or ``max_increment`` [m] more wear.
    ``report``: the pseudo-time march's progress messages (:func:`~workflow.engine.wear.pseudo_time_wear`)."""
    from workflow.engine.wear import march_reference, pseudo_time_wear

    common = dict(cycles_per_block=opt.cycles_per_block, steady_tol=opt.steady_tol, tol=opt.tol, track=track,
                  max_cycles=max_cycles, max_increment=max_increment)
    wp.set_wear(np.zeros(wp.p) if W0 is None else W0)
    if method == "pseudo-time":
        return pseudo_time_wear(wp, x, max_steps=opt.max_steps, rtol=opt.rtol, dt_max_blocks=opt.dt_max_blocks,
                                report=report, **common)
    return march_reference(wp, x, scheme=method, max_blocks=opt.max_blocks, block_tol=block_tol, **common)


def worn_steady_state(model, law, opt: WearOptions | None = None, *, eps_path=None,
                      log=None) -> WearStudy:
    """Fretting wear of ``model``'s pairs under ``law`` to the worn steady state
    by each of ``opt.methods`` (see the module docstring); ``eps_path`` as in
    :func:`workflow.engine.cascade.along_eps_path` (None: the law's own,
    :func:`workflow.engine.penalty.path_of`).

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
                     averaging=averaging(model.position, model.area, model.flank, opt.length_m))
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
    histories = _every_method(wp, base.x, opt, track, rc, schedule, histories, w_end, eps_path, log)
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
                  eps_path, log) -> dict:
    """Each of ``opt.methods``'s march from ``x0`` (``histories`` holds the ones already run: a
    dwell's lead), along a dwell's ``schedule`` if any; a march that lost the vibration is
    re-solved at a finer Nh at ``w_end`` [rad/s] (:func:`finer_nh_resolve`). {method: history}."""
    for m in opt.methods:
        if m not in histories:
            histories[m] = march(wp, x0, m, opt, track, opt.block_tol) if schedule is None else \
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


#: How a resonance dwell that spent ``WearOptions.dwell_stages`` says so (:func:`_dwell`).
DWELL_UNFINISHED = "resonance dwell unfinished"
#: The resonance dwell's first stage wears this fraction of the unworn normal interpenetration
#: (:func:`workflow.engine.wear.history.penetration_scale`); the budget then adapts by × 0.25 … 4 a stage.
#: Where a pad's whole load is one interpenetration (a Jenkins pad on its own normal spring) its
#: peak moves 7.5 % over that wear; on the quick sector 2e-4 over 2.6 µm: small enough for the
#: first, two stages of growth for the second.
DWELL_FIRST = 1.0 / 16.0


def _stage_problem(wp, rc, omega: float):
    """``wp`` (a :class:`~workflow.engine.wear.WearProblem`) at the frequency ``omega`` [rad/s]: its
    HB problem's linear part condensed there (:meth:`HBProblem.with_linear`: the same law, Nh,
    nit and stick anchor — the blade wears in place), the same wear law."""
    from workflow.engine.linear import condensed
    from workflow.engine.wear import WearProblem

    c = condensed(rc, omega, wp.hb.nh)
    return WearProblem(wp.hb.with_linear(c.Zr, c.Fr), wp.area, wp.k_w, wp.share, eps_path=wp.eps_path,
                       averaging=wp.averaging)


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
                      persistent_slip=last.persistent_slip, vibration_lost=last.vibration_lost)
    t = 0.0
    for h in stages:
        out.cycles += [t + c for c in h.cycles]
        out.max_wear += list(h.max_wear)
        out.max_rate += list(h.max_rate)
        out.harmonic1 += list(h.harmonic1)
        out.W_history += list(h.W_history)
        t += float(h.cycles[-1]) if h.cycles else 0.0
    return out


def _unworn_at(wp, x, opt: WearOptions, eps_path):
    """The unworn vibration of ``wp`` from x (a SolveResult), or None if it does not solve."""
    from workflow.engine.cascade import solve_point

    wp.set_wear(np.zeros(wp.p))
    pr = solve_point(wp.hb, [x], solver="newton-powell", tol=opt.tol, maxiter=opt.max_iterations, eps_path=eps_path)
    return pr.result if pr.converged else None


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


def _held_amplitude(rc, wp, base, omega: float, opt: WearOptions, point: dict, log, scale: float = 1.0):
    """(:class:`~workflow.engine.studies.amplitude.AmplitudeProblem`, its unworn SolveResult with
    the unknowns [x; s]) of ``wp`` with the tip held at ``opt.tip_amplitude_m`` (0: the amplitude
    of the unworn vibration ``base`` under the load as built), started from ``base`` under
    ``scale`` × that load; records ``point["control"]``."""
    from workflow.engine.studies.amplitude import hold

    if point["kind"] in ("resonance", "mission"):
        raise SceneError(f"wear.control = \"amplitude\" with wear.operating_point = \"{point['kind']}\": a held "
                         "amplitude wears at one frequency (\"frequency\" or \"detuning\")")
    ap, res, _ = hold(rc, wp, base.x, omega, max(float(opt.tip_amplitude_m), 0.0), tol=opt.tol,
                      maxiter=opt.max_iterations, scale=scale)
    target = ap.target
    point["control"] = {"kind": "amplitude", "tip_amplitude_m": target, "load_scale_new": float(res.x[-1])}
    if log is not None:
        log.info(f"tip held at {target:.4g} m: the load × {res.x[-1]:.4g} on the new blade")
    return ap, res


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
