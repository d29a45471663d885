"""The friction-damped forced response of a mistuned bladed disk, blade by blade (issue 50).

The whole disk's relative coordinates (:class:`reduction.mistuned.WholeDiskCoordinates`: every
blade's contact pairs physical, N × p pairs) go through the same sweep and solver cascade as a
sector (:func:`workflow.engine.studies.frf.sweep_variant`); what is new is what a mistuned disk
is read by:

* each blade's tip amplitude (first harmonic, ‖·‖ of its observed DOFs) at every frequency, and
  the largest blade peak found by a search on every blade's own resonance, started where the
  tied response's highest blades peak (:mod:`workflow.engine.studies.bladepeak`);
* the **amplification factor**: the largest blade peak over the tuned disk's peak (Whitehead
  1966 bounds it by (1 + √N)/2 for a linear one-family disk), with the interface tied (linear)
  and friction-damped (:func:`amplification`);
* mistuning patterns (:func:`pattern`) for a Monte Carlo over them (:func:`monte_carlo`).

Units: SI; frequencies in Hz unless named ω (rad/s).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from workflow.engine.errors import SceneError
from workflow.engine.studies.bladepeak import peak_of, search_blade_peaks, tied_candidates

#: the tied response's grid is this many times denser than the friction-damped one: a tied point
#: is one linear solve (0.1 s on the 752-pair disk, iterative, against 6–20 s a friction-damped
#: point), and mistuned blades peak between the friction grid's points
TIED_REFINEMENT = 4
#: the tied response spans this many times the friction-damped grid's band (about its centre), and the
#: friction-damped peak search may go as far: a mistuned disk's highest blade can peak outside the band
#: its grid was laid on (the quick disk at σ = 0.02, 101 patterns: 5 highest tied peaks below the
#: ±3 % band about the tuned peak, at −3.1 … −3.0 %, where the search was clipped; none beyond −3.2 %)
TIED_BAND = 2.0
#: a standard deviation's patterns are truncated here: a stiffness factor 1 + δ must stay > 0
MAX_DEVIATION = 0.5


def pattern(n: int, std: float, seed: int) -> np.ndarray:
    """(n,) stiffness deviations δ_s, normal with standard deviation ``std`` (seeded: the same
    seed gives the same disk on every machine), clipped to ±:data:`MAX_DEVIATION`."""
    if std < 0:
        raise SceneError(f"mistuning.std = {std}: a standard deviation is ≥ 0")
    rng = np.random.default_rng(int(seed))
    return np.clip(float(std) * rng.standard_normal(int(n)), -MAX_DEVIATION, MAX_DEVIATION)


def time_samples(nh: int, n_sectors: int, engine_order: int) -> int:
    """nit of a whole-disk HB: the smallest multiple of N / gcd(N, EO) at or above the engine's
    default (:func:`workflow.engine.fourier.default_nit`). Sector s of a tuned travelling wave is
    sector 0 delayed by s·EO/N of a period; on such a grid every delay is a whole number of
    samples, so the DLFT of the tuned disk is exactly the cyclic sector's (measured on a lumped
    5-sector disk, Nh = 3: nit = 32, 0.1 % apart and blades unequal near resonance; nit = 40,
    1.4e-10, the solver's tolerance)."""
    from math import gcd

    from workflow.engine.fourier import default_nit

    step = int(n_sectors) // gcd(int(n_sectors), int(engine_order))
    base = default_nit(int(nh))
    return -(-base // step) * step


def travelling_wave(U, n_sectors: int, engine_order: int) -> np.ndarray:
    """A tuned sector's relative harmonics U (Nh+1, 3p) on every sector: (Nh+1, 3pN), sector s
    harmonic j times ``e^{i j s 2π EO/N}`` (the engine-order wave of :mod:`reduction.cyclic`)."""
    U = np.asarray(U)
    j = np.arange(U.shape[0])[:, None]
    ph = np.exp(2j * np.pi * engine_order * np.arange(int(n_sectors)) / n_sectors)
    return np.concatenate([U * ph[s] ** j for s in range(int(n_sectors))], axis=1)


def tiled_law(law, n: int, engine_order: int):
    """The sector's DLFT law on every one of ``n`` sectors (the same μ, penalties and gaps per
    pair: the penalty decision is the sector's, made once). Sector s's pairs begin their DLFT
    passes at its engine-order delay, phase ``−s·EO/n`` of the period
    (:attr:`workflow.engine.contact.ContactLaw.phase`): the instant of its own excitation the
    cyclic sector begins at, so a pair that shakes down lands where the sector's does (measured
    on a lumped 5-sector disk whose pairs slip under the preload: with every pass from instant 0
    the tuned travelling wave left residuals of 1–2.5 % of ‖F‖ on sectors 1–4)."""
    from workflow.engine.contact import ContactLaw

    tile = lambda a: np.tile(np.broadcast_to(np.asarray(a, float), (law.p,)), n)  # noqa: E731
    phase = np.repeat(np.mod(-np.arange(n) * engine_order / n, 1.0), law.p)
    return ContactLaw(mu=tile(law.mu), eps_n=tile(law.eps_n), eps_t=tile(law.eps_t), gap=tile(law.gap),
                      wear=tile(law.wear), phase=phase)


def blade_amplitudes(observed: np.ndarray, n_sectors: int) -> np.ndarray:
    """(N,) first-harmonic amplitude [m] of each blade from observed harmonics (Nh+1, N·n_obs):
    the Euclidean norm of its observed DOFs' complex amplitudes."""
    h1 = np.asarray(observed)[1].reshape(int(n_sectors), -1)
    return np.linalg.norm(h1, axis=1)


@dataclass
class MistunedResponse:
    """Every blade's forced response over a band.

    ``freqs_hz`` (n_f,); ``amplitude`` (n_f, N) friction-damped first-harmonic tip amplitude [m]
    (NaN where unconverged); ``tied`` (n_t, N) with the interface tied [m] on ``tied_freqs_hz``
    (:data:`TIED_REFINEMENT` × denser over :data:`TIED_BAND` × the band: a tied point is one linear
    solve); ``peak`` {"hz", "amplitude_m", "blade", "resolved", "at_band_edge", …} the refined largest
    blade peak (:func:`~workflow.engine.studies.bladepeak.peak_of`; at the tied band's edge it is not
    resolved: the band is too narrow for the pattern), ``blade_peaks_m`` (N,) each blade's
    largest amplitude over the points solved (grid and search), ``tied_peak`` likewise for the
    tied response; ``seconds_per_point`` the mean wall time [s] of one friction-damped frequency
    (condensation included); ``nh``, ``nit``, ``converged`` (n_f,)."""

    freqs_hz: np.ndarray
    amplitude: np.ndarray
    converged: np.ndarray
    tied: np.ndarray
    tied_freqs_hz: np.ndarray
    peak: dict
    blade_peaks_m: np.ndarray
    tied_peak: dict
    tied_blade_peaks_m: np.ndarray
    seconds: float
    seconds_per_point: float
    nh: int
    nit: int
    evaluations: int = 0
    #: (Nh+1, 3pN) relative harmonics [m] at ``peak["hz"]`` (a wear march starts from them)
    peak_U: np.ndarray | None = None
    #: every friction-damped frequency solved, grid and search, sorted [Hz], and its (n_s, N) blade amplitudes [m]
    solved_hz: np.ndarray | None = None
    solved_amplitude: np.ndarray | None = None
    extra: dict = field(default_factory=dict)


def _solve_at(rc, law, static, variant, freqs_hz, seeds, **kw):
    """One sweep over ``freqs_hz`` → (converged, (n, N) blade amplitudes, Ur list, seconds)."""
    from workflow.engine.linear import CondensedGrid
    from workflow.engine.studies.frf import sweep_variant

    t0 = time.perf_counter()
    omegas = 2 * np.pi * np.asarray(freqs_hz, float)
    grid = CondensedGrid(rc, omegas, variant.nh, keep_bytes=0.0)
    sw = sweep_variant(rc, grid, law, static, variant, seeds=seeds, **kw)
    amp = np.full((len(omegas), rc.N), np.nan)
    for i, w in enumerate(omegas):
        if sw.converged[i]:
            amp[i] = blade_amplitudes(rc.observed_at[float(w)], rc.N)
    return sw.converged.copy(), amp, list(sw.Ur), time.perf_counter() - t0


def forced_response(rc, law, variant, freqs_hz, *, seeds=None, solver: str = "newton-powell", tol: float = 1e-8,
                    maxiter: int = 60, refine: bool = True, tied: bool = True, progress=None,
                    form: str | None = None) -> MistunedResponse:
    """The mistuned disk's friction-damped response of every blade over ``freqs_hz`` (Hz), the
    tied (linear) response on a :data:`TIED_REFINEMENT` × denser grid, and each one's largest
    blade peak (:mod:`~workflow.engine.studies.bladepeak`; the friction-damped search first
    evaluates where the tied response's highest blades peak). ``refine`` False: the grids'
    largest points are the peaks.

    ``rc``: :class:`reduction.mistuned.WholeDiskCoordinates`; ``law``: the whole disk's DLFT law
    (:func:`tiled_law`); ``variant``: HB method, Nh, nit (:class:`~workflow.engine.Variant`);
    ``seeds``: one (Nh+1, 3pN) guess per frequency or None — the tuned disk's travelling wave
    (:func:`travelling_wave`) is the natural one: measured on a lumped 5-sector disk, the
    secant predictor alone lost the three points at the resonance that the tuned seeds find.
    ``progress`` wraps the grid's frequency loop (e.g. ``log.progress``); ``form``: the HB's
    unknowns, "stiffness" or "compliance" (:meth:`reduction.mistuned.WholeDiskCoordinates.in_form`;
    None: the disk's own). Both give the same amplitudes to the Newton tolerance. The compliance
    form drops the condensation's dense inverses, but its Newton solve costs more (its
    preconditioner holds less of its Jacobian) and is less robust at the peak: on the quick disk
    with the scene's law (two threads, 2026-11-29) a point took 23.1 s against 20.7 s in the
    stiffness form (docs/mistuning.md).
    """
    from workflow.engine.condense import condense
    from workflow.engine.studies.study import static_state

    rc = rc.in_form(form) if form is not None else rc
    t0 = time.perf_counter()
    freqs = np.asarray(freqs_hz, float)
    c0 = condense(rc, 2 * np.pi * freqs[0], 0)
    static = static_state(c0.Zr, c0.Fr, law)
    kw = dict(solver=solver, tol=tol, maxiter=maxiter)
    conv, amp, Ur, secs = _solve_at(rc, law, static, variant, freqs, seeds, progress=progress, **kw)
    solved = {float(f): a for f, a, ok in zip(freqs, amp, conv) if ok}
    states = {float(f): U for f, U, ok in zip(freqs, Ur, conv) if ok}
    n_points, t_points = len(freqs), secs

    def blade_peaks_at(f):
        nonlocal n_points, t_points
        near = min(states, key=lambda g: abs(g - f))
        ok, a, U, s = _solve_at(rc, law, static, variant, [f], [states[near]], **kw)
        n_points, t_points = n_points + 1, t_points + s
        if not ok[0]:
            return None
        states[float(f)] = U[0]
        return a[0]

    tied_freqs = tied_band(freqs) if tied else freqs[:0]
    tied_amp = np.full((len(tied_freqs), rc.N), np.nan)
    tied_peak, tied_blades, candidates = {"hz": None, "amplitude_m": None, "blade": None}, np.full(rc.N, np.nan), []
    limits = (tied_freqs[0], tied_freqs[-1]) if tied else None
    if tied:
        tied_amp, tied_peak, tied_blades = tied_response(rc, tied_freqs, refine=refine)
        candidates = tied_candidates(tied_freqs, tied_amp)
    search = (search_blade_peaks(blade_peaks_at, solved, candidates=candidates, limits=limits)
              if refine and solved else None)
    if solved:
        peak = peak_of(solved, search, limits)
        blade_peaks = np.max(np.array(list(solved.values())), axis=0)
        peak_U = np.asarray(states[peak["hz"]])
    else:
        peak, blade_peaks = {"hz": None, "amplitude_m": None, "blade": None}, np.full(rc.N, np.nan)
        peak_U = None
    return MistunedResponse(freqs_hz=freqs, amplitude=amp, converged=conv, tied=tied_amp, tied_freqs_hz=tied_freqs,
                            peak=peak,
                            blade_peaks_m=blade_peaks, tied_peak=tied_peak, tied_blade_peaks_m=tied_blades,
                            seconds=time.perf_counter() - t0, seconds_per_point=t_points / max(n_points, 1),
                            nh=variant.nh, nit=variant.nit, evaluations=n_points, peak_U=peak_U,
                            solved_hz=np.array(sorted(solved)),
                            solved_amplitude=np.array([solved[f] for f in sorted(solved)]).reshape(-1, rc.N))


def tied_response(rc, freqs_hz, refine: bool = True):
    """((n_f, N) tied blade amplitudes [m], the refined largest blade peak {"hz", "amplitude_m",
    "blade"}, (N,) each blade's largest over the points solved)."""
    freqs = np.asarray(freqs_hz, float)

    def at(f):
        t = rc.tied_response(2 * np.pi * f)
        return blade_amplitudes(np.stack([np.zeros_like(t), t]), rc.N)

    amp = np.array([at(f) for f in freqs])
    solved = {float(f): a for f, a in zip(freqs, amp)}
    search = search_blade_peaks(at, solved) if refine else None
    return amp, peak_of(solved, search, (freqs[0], freqs[-1])), np.max(np.array(list(solved.values())), axis=0)


def tied_band(freqs_hz) -> np.ndarray:
    """The tied response's frequencies [Hz] for a friction-damped grid ``freqs_hz`` (sorted):
    :data:`TIED_BAND` × its span about its centre, :data:`TIED_REFINEMENT` × its spacing."""
    f = np.asarray(freqs_hz, float)
    mid, half = 0.5 * (f[0] + f[-1]), 0.5 * TIED_BAND * (f[-1] - f[0])
    n = int(round(TIED_BAND * TIED_REFINEMENT * (len(f) - 1))) + 1
    return np.linspace(max(mid - half, 0.5 * f[0]), mid + half, n)      # never down to 0 Hz


def amplification(mistuned_peak_m: float | None, tuned_peak_m: float | None) -> float | None:
    """The amplification factor: the largest blade peak of the mistuned disk over the tuned
    disk's peak (both [m], the same excitation and interface law); None if either is missing."""
    if not mistuned_peak_m or not tuned_peak_m:
        return None
    return float(mistuned_peak_m) / float(tuned_peak_m)


def whitehead_bound(n_sectors: int) -> float:
    """Whitehead's (1966) bound (1 + √N)/2 of a linear one-family disk's amplification factor."""
    return 0.5 * (1.0 + np.sqrt(float(n_sectors)))


def monte_carlo(make_rc, law, variant, freqs_hz, *, n_sectors: int, std: float, samples: int, seed: int,
                tuned_peak_m: float, tuned_tied_m: float, seeds=None, comm=None, log=None, store=None,
                offset: int = 0, **solve) -> list[dict]:
    """Amplification factors of ``samples`` patterns (:func:`pattern` with seeds ``seed + 1 + i``):
    rows {"pattern", "seed", "af_tied", "af_friction", "peak_hz", "blade", "converged",
    "peak_resolved", "tied_peak_resolved", "peak_at_band_edge", "seconds"}, each a peak tracking on the grid
    ``freqs_hz`` refined (:func:`forced_response`), not a full sweep.
    ``make_rc(deviations)`` → the disk's whole-disk coordinates; ``tuned_*_m`` [m]: the tuned
    peaks the factors divide by; ``solve``: :func:`forced_response`'s ``tol``, ``maxiter``, … (the
    scene's, as for its own pattern). Patterns are shared over the ranks of ``comm`` (every rank
    gets every row): pattern i to rank ``(i + offset) mod size``, as if ``offset`` items of other
    work (rank 0's own pattern and checks) had been dealt first. ``store``: where finished rows
    are kept as they come and found again after an interruption — ``get(name)`` → the row or
    None, ``put(name, row)`` (the pipeline's
    :class:`workflow.progress.Progress`); a kept row whose seed is not its pattern's is computed
    again."""
    size, rank = (1, 0) if comm is None else (comm.Get_size(), comm.Get_rank())
    rows = []
    for i in (k for k in range(int(samples)) if (k + int(offset)) % size == rank):
        name = f"pattern-{i}"
        kept = None if store is None else store.get(name)
        if isinstance(kept, dict) and kept.get("pattern") == i and kept.get("seed") == seed + 1 + i:
            rows.append(kept)
            if log is not None:
                log(f"pattern {i}: kept from an interrupted run")
            continue
        t0 = time.perf_counter()
        dev = pattern(n_sectors, std, seed + 1 + i)
        r = forced_response(make_rc(dev), law, variant, freqs_hz, seeds=seeds, **solve)
        rows.append({"pattern": i, "seed": seed + 1 + i, "af_tied": amplification(r.tied_peak["amplitude_m"], tuned_tied_m),
                     "af_friction": amplification(r.peak["amplitude_m"], tuned_peak_m), "peak_hz": r.peak["hz"],
                     "blade": r.peak["blade"], "converged": bool(r.converged.all()),
                     "peak_resolved": r.peak.get("resolved"), "tied_peak_resolved": r.tied_peak.get("resolved"),
                     "peak_at_band_edge": r.peak.get("at_band_edge"),
                     "seconds": time.perf_counter() - t0})
        if store is not None:
            store.put(name, rows[-1])
        if log is not None:
            log(f"pattern {i}: AF tied {rows[-1]['af_tied']:.3f}, friction {rows[-1]['af_friction'] or float('nan'):.3f} "
                f"({rows[-1]['seconds']:.1f} s)")
    if comm is not None:
        rows = sorted((r for part in comm.allgather(rows) for r in part), key=lambda r: r["pattern"])
    return rows


@dataclass
class WornDisk:
    """The worn steady state of every blade's dovetail at one frequency.

    ``W`` (N, p) worn depth per blade and pair [m]; ``blade_max_m`` (N,) its deepest point,
    ``blade_volume_m3`` (N,) Σ W·area; ``omega`` [rad/s]; ``history`` the march
    (:class:`workflow.engine.wear.WearHistory`: steady, iterations, reason); ``unworn_x`` the
    HB unknowns it started from; ``control`` with a held amplitude (:func:`held_blade`) the
    blade held, its amplitude [m] and the load scales new and worn, else None."""

    W: np.ndarray
    blade_max_m: np.ndarray
    blade_volume_m3: np.ndarray
    omega: float
    history: object
    unworn_x: np.ndarray
    control: dict | None = None


def held_blade(rc, wp, x, omega: float, opt, n_sectors: int):
    """The whole disk's wear problem with one blade's tip held (``wear.control = "amplitude"``):
    the blade whose tip vibrates most in the unworn vibration x at ω [rad/s], held at
    ``opt.tip_amplitude_m`` (0: its own unworn amplitude) while the engine-order load's scale
    follows (:class:`~workflow.engine.studies.amplitude.AmplitudeProblem` on that blade's rows
    of :func:`~workflow.engine.studies.amplitude.tip_map`). On a tuned disk every blade holds
    the sector's amplitude, so its worn state is the sector's held one. Returns (the problem,
    its unknowns ``[x; s]``, ``{"blade", "tip_amplitude_m", "load_scale_new"}``); SolverError
    where the held vibration does not solve (:func:`~workflow.engine.studies.amplitude.hold`)."""
    from workflow.engine.studies.amplitude import hold

    ap, res, b = hold(rc, wp, x, omega, float(opt.tip_amplitude_m), tol=opt.tol, maxiter=opt.max_iterations,
                      blades=n_sectors)
    return ap, res.x, {"blade": b, "tip_amplitude_m": ap.target, "load_scale_new": float(res.x[-1])}


def worn_blades(rc, law, variant, omega: float, area, opt, *, n_sectors: int, U0=None, log=None,
                step_lengths=None) -> WornDisk:
    """Fretting wear of every blade's pairs at ω [rad/s] to the worn steady state: the sector's
    wear law and march (:class:`workflow.engine.wear.WearProblem`, pseudo-time, eq. 22) on the
    whole disk's relative coordinates, every pair its own wear depth.

    ``rc``: whole-disk coordinates (or any relative coordinates: with ``n_sectors`` = 1 the
    sector's own march on the same path, what the tuned check compares with); ``law`` the
    whole disk's DLFT law (:func:`tiled_law`); ``area`` (p,) one blade's pair areas [m²];
    ``opt`` a :class:`~workflow.engine.studies.wearstudy.WearOptions` (``k_w``, ``blade_share``,
    ``tol``, the march's ``steady_tol``, ``rtol``, ``max_steps``, ``cycles_per_block``);
    ``U0`` (Nh+1, n_rel) relative harmonics [m] of a converged vibration at ω to start from
    (the forced response's); if it is not converged here the solver cascade starts from it and
    from the stuck guess. The node-wise law only (``opt.length_m`` = 0): the averaging needs every
    blade's pair positions, which the whole disk's coordinates do not carry. With ``opt.control`` "amplitude"
    the most vibrating blade's tip is held (:func:`held_blade`) and the load follows.
    ``step_lengths`` (cycles): the march's steps given — another march's, replayed on the same
    path (:func:`~workflow.engine.wear.pseudo_time_wear`): the tuned disk against the sector."""
    from workflow.engine import penalty
    from workflow.engine.cascade import solve_point
    from workflow.engine.errors import SolverError
    from workflow.engine.hb import HBProblem
    from workflow.engine.linear import condensed
    from workflow.engine.studies.study import static_state
    from workflow.engine.studies.wearstudy import march, unworn_point
    from workflow.engine.wear import WearProblem

    if opt.length_m > 0:
        raise SceneError(f"wear.length_m = {opt.length_m:g}: the whole disk's wear takes the node-wise law "
                         "(wear.length_m = 0)")
    N = int(n_sectors)
    cond = condensed(rc, omega, variant.nh)
    st = static_state(cond.Zr, cond.Fr, law, opt.max_passes)
    hb = HBProblem(cond.Zr, cond.Fr, law, variant.nh, variant.nit, variant.method, max_passes=opt.max_passes,
                   static=st)
    eps_path = penalty.path_of(law, np.real(hb.Zr[0]))
    x = None if U0 is None else hb.unknowns_from_harmonics(np.asarray(U0))
    if x is None:
        x = unworn_point(hb, omega, opt, eps_path).x
    elif not np.linalg.norm(hb.residual(x)) <= opt.tol * hb.residual_scale():
        pr = solve_point(hb, [x, hb.x0()], solver="newton-powell", tol=opt.tol, maxiter=opt.max_iterations,
                         eps_path=eps_path)
        if not pr.converged:
            raise SolverError(f"mistuning wear: no unworn vibration at {omega / 2 / np.pi:.3f} Hz from the forced "
                              f"response's solution or the stuck state ({pr.result.reason})")
        x = pr.result.x
    blade_area = np.asarray(area, float)
    wp = WearProblem(hb, np.tile(blade_area, N), opt.k_w, opt.blade_share, eps_path=eps_path)
    track = 3 * int(np.argmax(wp.evaluate(x).rate)) + 1
    control, z = None, x
    if opt.control == "amplitude":
        wp, z, control = held_blade(rc, wp, x, omega, opt, N)
    if log is not None:
        held = "" if control is None else (f", blade {control['blade']}'s tip held at "
                                           f"{control['tip_amplitude_m']:.4g} m")
        log(f"wear of {N} blades × {blade_area.size} pairs at {omega / 2 / np.pi:.3f} Hz (Nh = {variant.nh}, "
            f"nit = {variant.nit}{held}): pseudo-time march")
    h = march(wp, z, "pseudo-time", opt, track, opt.block_tol, report=log, step_lengths=step_lengths)
    if control is not None:
        control["load_scale_worn"] = float(h.x[-1])
    W = np.asarray(h.W, float).reshape(N, -1)
    return WornDisk(W=W, blade_max_m=W.max(axis=1), blade_volume_m3=W @ blade_area, omega=float(omega),
                    history=h, unworn_x=x, control=control)


def _finite(values) -> np.ndarray:
    return np.asarray([x for x in values if x is not None and np.isfinite(x)], float)


def percentile(values, q: float = 95.0) -> float | None:
    """The q-th percentile of the finite values, or None."""
    v = _finite(values)
    return float(np.percentile(v, q)) if v.size else None


def percentile_interval(values, q: float = 95.0, confidence: float = 0.95) -> dict:
    """A distribution-free confidence interval of the q-th percentile ξ from the finite values
    (a Monte Carlo's amplification factors): two order statistics x₍r₎ ≤ ξ < x₍s₎. The number K
    of samples at or below ξ is binomial (n, q/100) whatever the distribution, so
    P(x₍r₎ ≤ ξ < x₍s₎) = P(r ≤ K ≤ s − 1); r and s leave at most (1 − confidence)/2 in each tail.
    Returns {"lo", "hi", "coverage", "n"}: ``lo`` None when too few samples bound ξ from below,
    ``hi`` None from above (at q = 95 and 95 % confidence that takes n ≥ 72: below, even the
    largest sample is under ξ more often than 2.5 %), ``coverage`` the interval's exact
    probability (≥ ``confidence``; more, since K is discrete)."""
    from scipy.stats import binom

    v = np.sort(_finite(values))
    n, p, tail = v.size, float(q) / 100.0, 0.5 * (1.0 - float(confidence))
    if n == 0:
        return {"lo": None, "hi": None, "coverage": 0.0, "n": 0}
    F = binom.cdf(np.arange(n + 1), n, p)                  # F[k] = P(K ≤ k)
    below = np.flatnonzero(F <= tail)                       # r − 1 = the largest such k
    r = int(below[-1]) + 1 if below.size else 0
    above = np.flatnonzero(F >= 1.0 - tail)                 # s − 1 = the smallest such k
    s = int(above[0]) + 1 if above.size else n + 1
    lo = float(v[r - 1]) if r >= 1 else None
    hi = float(v[s - 1]) if s <= n else None
    coverage = float((F[s - 1] if s <= n else 1.0) - (F[r - 1] if r >= 1 else 0.0))
    return {"lo": lo, "hi": hi, "coverage": coverage, "n": int(n)}
