"""Mistuning stage: the friction-damped forced response of the whole mistuned disk from one
cyclic sector, blade by blade (issue 50).

Reads the cyclic sector bundle, builds its blade and disk-per-ND substructures
(:mod:`reduction.mistuned`), solves the tuned disk on the sector (the cyclic model rebuilt from
the same substructures) and the mistuned whole disk with every blade's contact pairs
(:mod:`workflow.engine.studies.mistuning`), and writes each blade's FRF and peak, the
amplification factors (tied and friction-damped), the localisation figure, the checks and,
with ``mistuning.samples``, a Monte Carlo over patterns (each finished pattern kept in the
stage's progress folder, :mod:`workflow.progress`, so an interrupted run resumes). docs/mistuning.md.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

NAME = "mistuning"
SECTIONS = ("mistuning", "cyclic", "contact", "hb", "wear", "pseudotime")
NEEDS = ("bundle",)
VIA_BUNDLE = ("excitation",)
PRODUCES = ("mistuning",)
MPI = True
#: grid of the tuned sector's FRF that locates its friction-damped peak (± 10 % of the tied
#: mode, refined between grid points)
TUNED_POINTS = 15


def _frf_options(hb):
    from workflow import engine

    return engine.FRFOptions(solver="newton-powell", tol=hb.tol, max_iterations=hb.max_iterations,
                             eps_check_factor=0.0, reference_check=False, nh_check=False, branch_check=False,
                             time_check=False)


def _tied_amplitude(rc, f: float) -> float:
    """The tuned sector's tied (u_r = 0) first-harmonic tip amplitude [m] at f [Hz]."""
    from workflow.engine.condense import recover

    return float(np.linalg.norm(recover(rc, 2 * np.pi * f, np.zeros((2, rc.n_rel), complex))[1]))


def _tied_peak(rc, f_lo: float, f_hi: float) -> tuple[float, float]:
    """The tuned sector's tied (linear) peak (Hz, m) between f_lo and f_hi, refined to 1e-7."""
    from scipy.optimize import minimize_scalar

    def minus(f):
        return -_tied_amplitude(rc, f)

    grid = np.linspace(f_lo, f_hi, 41)
    a = [-minus(f) for f in grid]
    i = int(np.argmax(a))
    r = minimize_scalar(minus, bounds=(grid[max(i - 1, 0)], grid[min(i + 1, 40)]), method="bounded",
                        options={"xatol": 1e-7 * grid[i]})
    return float(r.x), float(-r.fun)


def _full_disk_tied(sub, dev, mass, omega: float) -> np.ndarray:
    """Every blade's tied first-harmonic amplitude (N,) [m] from the assembled whole-disk model
    (:func:`reduction.mistuned.whole_disk`) by one dense constrained solve ``[D Bᵀ; B 0]`` — the
    independent path the substructure condensation is checked against."""
    import scipy.linalg as sla

    from reduction.mistuned import whole_disk
    from workflow.engine.studies.mistuning import blade_amplitudes

    wd = whole_disk(sub, dev, mass)
    r, m = wd.B.shape
    A = np.zeros((m + r, m + r), complex)      # 1 GB at 752 pairs: built in place, factored in place
    A[:m, :m] = wd.K
    A[:m, :m] -= omega ** 2 * wd.M
    A[:m, :m] += 1j * omega * wd.C
    # constraint rows in the stiffness's units: unscaled, B (entries ~1) against K (~1e8 N/m) made
    # LAPACK's condition estimate 3e-21 and its warning, with the same solution
    s = float(np.abs(wd.K).max()) / max(float(np.abs(wd.B).max()), 1e-300)
    A[:m, m:], A[m:, :m] = s * wd.B.T, s * wd.B
    q = sla.solve(A, np.concatenate([wd.f_harmonic, np.zeros(r)]), overwrite_a=True, check_finite=False)[:m]
    obs = wd.O @ q
    return blade_amplitudes(np.stack([np.zeros_like(obs), obs]), sub.n_sectors)


def run(scene, inputs: dict, out: Path, log) -> dict:
    from reduction.bundle import read_bundle
    from reduction.mistuned import WholeDiskCoordinates, substructures
    from workflow import engine
    from workflow.engine.studies import mistuning as ms
    from workflow.mpi import rank
    from workflow.stages.assembly import bundle_folder
    from workflow.stages.hb import clean
    from workflow.stages.reduction import rigid_contact_only

    rigid_contact_only(scene["contact"], "mistuning")
    t0 = time.perf_counter()
    out = Path(out)
    mt, hb = scene["mistuning"], scene["hb"]
    if mt.wear:
        _wear_point(scene["wear"])
    eo = int(scene["cyclic"].engine_order)
    bundle = read_bundle(bundle_folder(inputs["bundle"]))
    sub = substructures(bundle, eo, mt.blade_modes, mt.disk_modes)
    N = sub.n_sectors
    log.info(f"substructures: blade {sub.blade.size} coordinates, disk {sub.disk[0].size} per ND × "
             f"{len(sub.disk)} NDs, {sub.info['seconds']['total']:.1f} s")
    dev, mass = _pattern(mt, N)
    nh = int(mt.harmonics)
    nit = int(mt.time_samples) or ms.time_samples(nh, N, eo)
    v = engine.Variant("hbm", nh, nit)

    law, rcc, (f_t, a_t, ft_tied, a_tied), freqs, ref = _tuned_sector(scene, sub, v, log)
    seeds = [ms.travelling_wave(U, N, eo) if ok else None for U, ok in zip(ref.Ur, ref.converged)]
    law_w = ms.tiled_law(law, N, eo)

    if mt.samples and rank() != 0:
        # rank 0 alone solves the scene's own pattern, its checks and its wear (only its summary is
        # kept); the other ranks start on the Monte Carlo, whose patterns are dealt after that work
        _monte_carlo(mt, sub, mass, law_w, v, freqs, seeds, (a_t, a_tied), hb, {}, log)
        return {}
    rc = WholeDiskCoordinates(sub, dev, mass)
    resp = ms.forced_response(rc, law_w, v, freqs, seeds=seeds, tol=hb.tol, maxiter=hb.max_iterations,
                              progress=getattr(log, "progress", None))
    af = {"friction": ms.amplification(resp.peak["amplitude_m"], a_t),
          "tied": ms.amplification(resp.tied_peak["amplitude_m"], a_tied)}
    log.info(f"mistuned disk ({3 * sub.n_pairs * N} relative DOFs, Nh = {nh}, nit = {nit}): largest blade peak "
             f"{resp.peak['amplitude_m']:.4g} m at {resp.peak['hz']:.3f} Hz (blade {resp.peak['blade']}); "
             f"amplification friction {af['friction']:.3f}, tied {af['tied']:.3f}; "
             f"{resp.seconds_per_point:.1f} s a frequency point ({resp.evaluations} points)")

    checks = {}
    if mt.checks:
        checks = _checks(sub, law_w, v, ref, freqs, seeds, dev, mass, resp, af, hb, log)
    worn = _wear(scene, sub, rc, rcc, law, law_w, v, resp, f_t, ref, log, checks) if mt.wear else None
    mc_rows = _monte_carlo(mt, sub, mass, law_w, v, freqs, seeds, (a_t, a_tied), hb, af, log) if mt.samples else []
    bound = ms.whitehead_bound(N)
    figures = _write(out, sub, dev, mass, resp, ref, rcc, (a_t, a_tied), worn, mc_rows, bound) if rank() == 0 else []
    warnings = []
    if worn is not None and not worn["disk"].history.steady:
        warnings.append(f"mistuning: the whole disk's wear march stopped before its worn steady state "
                        f"({worn['disk'].history.reason})")
    if not resp.converged.all():
        warnings.append(f"mistuning: {int((~resp.converged).sum())} of {len(resp.converged)} whole-disk "
                        "frequencies did not converge")
    warnings += _peak_warnings(resp, mc_rows)
    return clean({"amplification": af, "whitehead_bound": bound,
                  "tied_ratio_to_bound": af["tied"] / bound if af["tied"] else None,
                  "blade_peaks_m": resp.blade_peaks_m.tolist(), "blade_tied_peaks_m": resp.tied_blade_peaks_m.tolist(),
                  "peak": resp.peak, "tied_peak": resp.tied_peak,
                  "tuned": {"hz": f_t, "amplitude_m": a_t, "tied_hz": ft_tied, "tied_amplitude_m": a_tied},
                  "stiffness_mistuning": dev.tolist(), "mass_mistuning": None if mass is None else mass.tolist(),
                  "std": float(mt.std) if not mt.stiffness else float(np.std(dev)),
                  "n_sectors": N, "pairs": int(sub.n_pairs * N), "harmonics": nh, "time_samples": nit,
                  "seconds_per_point": resp.seconds_per_point, "points_solved": resp.evaluations,
                  "substructures": sub.info, "checks": checks, "monte_carlo": mc_rows or None,
                  "wear": None if worn is None else worn["summary"],
                  "warnings": warnings,
                  "unconverged": ([] if resp.converged.all() else ["mistuning"])
                  + ([] if worn is None or worn["disk"].history.steady else ["mistuning.wear"]),
                  "files": {"blades": "blades.csv", "blade_frf": "blade_frf.csv",
                            "figures": [Path(f).name for f in figures]},
                  "seconds": round(time.perf_counter() - t0, 3)})


def _monte_carlo(mt, sub, mass, law_w, v, freqs, seeds, tuned: tuple, hb, af: dict, log) -> list[dict]:
    """The Monte Carlo's rows over ``mt.samples`` patterns (shared over the MPI ranks, each kept in the
    stage's progress folder as it comes), and its p95s with their 95 % intervals added to ``af``."""
    from reduction.mistuned import WholeDiskCoordinates
    from workflow import progress
    from workflow.engine.studies import mistuning as ms
    from workflow.mpi import world

    store = progress.current()
    rows = ms.monte_carlo(lambda d: WholeDiskCoordinates(sub, d, mass), law_w, v, freqs, n_sectors=sub.n_sectors,
                          std=mt.std, samples=mt.samples, seed=mt.seed, tuned_peak_m=tuned[0], tuned_tied_m=tuned[1],
                          seeds=seeds, comm=world(), log=log.note if hasattr(log, "note") else None,
                          store=store, offset=1, tol=hb.tol, maxiter=hb.max_iterations)
    _log_kept(store, len(rows), world(), log)
    for kind in ("tied", "friction"):
        values = [r[f"af_{kind}"] for r in rows]
        af[f"{kind}_p95"] = ms.percentile(values)
        af[f"{kind}_p95_ci"] = ms.percentile_interval(values)
    log.info(f"Monte Carlo, {len(rows)} patterns at σ = {mt.std:g}: p95 amplification "
             f"tied {_p95_text(af, 'tied')}, friction {_p95_text(af, 'friction')}")
    return rows


def _log_kept(store, samples: int, comm, log) -> None:
    """Say how many Monte Carlo patterns came from an interrupted run's progress folder (summed
    over the ranks), and how many kept files were damaged and computed again."""
    if store is None:
        return
    found, damaged = store.found, len(store.damaged)
    if comm is not None:
        found, damaged = comm.allreduce(found), comm.allreduce(damaged)
    if found or damaged:
        log.info(f"Monte Carlo: {found} of {samples} patterns kept from an interrupted run ({store.folder})"
                 + (f"; {damaged} kept files damaged, computed again" if damaged else ""))


def _p95_text(af: dict, kind: str) -> str:
    """The Monte Carlo's p95 of one amplification factor with its 95 % interval, for the log."""
    p, ci = af[f"{kind}_p95"], af[f"{kind}_p95_ci"]
    if p is None:
        return "none"
    bound = lambda x: "?" if x is None else f"{x:.3f}"  # noqa: E731
    return f"{p:.3f} (95 % interval {bound(ci['lo'])} … {bound(ci['hi'])})"


def _peak_warnings(resp, mc_rows) -> list:
    """What is not resolved among the largest blade peaks: the pattern's (friction-damped, tied)
    and the Monte Carlo's; a peak at the tied band's edge needs a wider ``mistuning.band``."""
    out = []
    for name, pk in (("friction-damped", resp.peak), ("tied", resp.tied_peak)):
        if pk.get("hz") is None or pk.get("resolved") is not False:
            continue
        gain = pk.get("predicted_gain")
        gain = f"{100 * gain:.2g} %" if gain is not None and np.isfinite(gain) else "an unbounded amount"
        why = ("at the edge of the searched band: widen mistuning.band" if pk.get("at_band_edge") else
               f"its search left a peak predicted up to {gain} higher open")
        out.append(f"mistuning: the largest {name} blade peak ({pk['amplitude_m']:.4g} m at {pk['hz']:.3f} Hz) "
                   f"is not resolved, {why}")
    edge = sum(bool(r.get("peak_at_band_edge")) for r in mc_rows)
    loose = sum(r.get("peak_resolved") is False for r in mc_rows) - edge
    if edge:
        out.append(f"mistuning: {edge} of {len(mc_rows)} Monte Carlo patterns peak at the edge of the searched "
                   "band (their amplification is a lower bound): widen mistuning.band")
    if loose:
        out.append(f"mistuning: {loose} of {len(mc_rows)} Monte Carlo patterns' largest blade peaks are not "
                   "resolved (monte_carlo.csv peak_resolved)")
    return out


def _pattern(mt, N: int):
    """The blades' (stiffness, mass or None) deviations from ``[mistuning]``: the lists given,
    else a seeded pattern of standard deviation ``std``; a list of the wrong length is one
    error naming its key."""
    from workflow.engine.studies import mistuning as ms
    from workflow.errors import SceneError

    for key in ("stiffness", "mass"):
        if getattr(mt, key) and len(getattr(mt, key)) != N:
            raise SceneError(f"mistuning.{key} has {len(getattr(mt, key))} values; the disk has {N} blades")
    dev = np.asarray(mt.stiffness, float) if mt.stiffness else ms.pattern(N, mt.std, mt.seed)
    return dev, (np.asarray(mt.mass, float) if mt.mass else None)


def _tuned_sector(scene, sub, v, log):
    """The tuned disk on one sector, from the same substructures: (the sector's law, its
    relative coordinates, (friction-damped peak Hz, m; tied peak Hz, m), the whole disk's grid
    [Hz] around the friction-damped peak, the sector's sweep on that grid)."""
    from workflow.engine.condense import relative_coordinates
    from reduction.cyclic_reduce import nodal_diameters_needed
    from reduction.mistuned import cyclic_model
    from workflow import engine
    from workflow.errors import SceneError
    from workflow.stages.hb import law_of

    mt, N, eo = scene["mistuning"], sub.n_sectors, int(scene["cyclic"].engine_order)
    cyc = cyclic_model(sub, nodal_diameters_needed(eo, N, v.nh))
    law = law_of(scene, cyc)
    opt = _frf_options(scene["hb"])
    tuned = engine.frf(cyc, law, [v], points=TUNED_POINTS, options=opt)
    if not tuned.peak or tuned.peak.get("hz") is None:
        raise SceneError("mistuning: the tuned sector's FRF has no converged point; check contact and hb settings")
    f_t, a_t = float(tuned.peak["hz"]), float(tuned.peak["amplitude_m"])
    rcc = relative_coordinates(cyc)
    band = float(mt.band)
    ft_tied, a_tied = _tied_peak(rcc, f_t * (1 - 3 * band), f_t * (1 + 3 * band))
    log.info(f"tuned sector (ND {eo % N}): friction-damped peak {f_t:.3f} Hz {a_t:.4g} m; tied {ft_tied:.3f} Hz "
             f"{a_tied:.4g} m")
    freqs = f_t * np.linspace(1 - band, 1 + band, int(mt.points))
    ref = engine.frf(cyc, law, [v], freqs_hz=freqs, options=opt).runs[0]
    return law, rcc, (f_t, a_t, ft_tied, a_tied), freqs, ref


def _write(out: Path, sub, dev, mass, resp, ref, rcc, tuned_m, worn, mc_rows, bound: float) -> list:
    """The stage's CSV files and figures (rank 0); ``tuned_m`` the tuned peaks (friction, tied) [m].
    Returns the figures' paths."""
    from workflow.io import write_rows
    from workflow.report.mistuning import plot_amplification, plot_blade_frf, plot_localisation, plot_wear_map

    N = sub.n_sectors
    write_rows(out / "blades.csv", [{"blade": s, "stiffness_deviation": float(dev[s]),
                                     "mass_deviation": float(mass[s]) if mass is not None else 0.0,
                                     "peak_friction_m": float(resp.blade_peaks_m[s]),
                                     "peak_tied_m": float(resp.tied_blade_peaks_m[s])} for s in range(N)])
    write_rows(out / "blade_frf.csv", [{"frequency_hz": float(f), "converged": bool(c),
                                        **{f"blade_{s}_m": float(a[s]) for s in range(N)}}
                                       for f, a, c in zip(resp.freqs_hz, resp.amplitude, resp.converged)])
    figures = [plot_blade_frf(out / "blade_frf.png", resp, ref.freqs_hz, np.where(ref.converged, ref.amplitude, np.nan),
                              np.array([_tied_amplitude(rcc, f) for f in resp.tied_freqs_hz])),
               plot_localisation(out / "localisation.png", dev, resp.blade_peaks_m, resp.tied_blade_peaks_m,
                                 *tuned_m)]
    if worn is not None:
        write_rows(out / "wear_blades.csv", [{"blade": b, "pair": i, "flank": int(sub.pairs["flank"][i]),
                                              "worn_depth_m": float(worn["disk"].W[b, i])}
                                             for b in range(N) for i in range(sub.n_pairs)])
        figures.append(plot_wear_map(out / "wear_map.png", worn["disk"].W, sub.pairs["flank"],
                                     sub.pairs["position"], worn["sector"].W))
    if mc_rows:
        write_rows(out / "monte_carlo.csv", mc_rows)
        figures.append(plot_amplification(out / "amplification.png", mc_rows, bound))
    return figures


def _wear_point(w) -> None:
    """The disk wears at its largest blade's friction-damped peak (the tuned sector at its own):
    a ``[wear]`` operating point of its own is one clear error, not a key silently not read."""
    from workflow.errors import SceneError

    if w.operating_point != "frequency" or w.frequency_hz > 0:
        raise SceneError(f"wear.operating_point = {w.operating_point!r}, wear.frequency_hz = {w.frequency_hz:g}: "
                         "with mistuning.wear the disk wears at its largest blade's friction-damped peak; "
                         "leave them at \"frequency\" and 0 (wear.control = \"amplitude\" holds that blade's tip)")


def _wear(scene, sub, rc, rcc, law, law_w, v, resp, f_t: float, ref, log, checks: dict) -> dict | None:
    """The worn steady state of every blade at the largest blade's friction-damped peak, the
    tuned sector's at its own peak (what the wear amplification divides by) and, with the
    checks, the tuned whole disk's, marched on the sector's steps, against the sector's
    (``checks["worn_tuned_vs_cyclic"]``)."""
    from dataclasses import replace

    from reduction.mistuned import WholeDiskCoordinates
    from workflow.engine.studies import mistuning as ms
    from workflow.errors import SceneError
    from workflow.stages.wear import options

    if resp.peak["hz"] is None:
        raise SceneError("mistuning.wear: the whole disk's forced response has no converged point to wear at")
    opt = replace(options(scene), method="hbm", nh=v.nh, nit=v.nit)
    N, area = sub.n_sectors, sub.pairs["area"]
    note = log.info
    sector = ms.worn_blades(rcc, law, v, 2 * np.pi * f_t, area, opt, n_sectors=1,
                            U0=_sector_solution(ref, f_t), log=note)
    disk = ms.worn_blades(rc, law_w, v, 2 * np.pi * resp.peak["hz"], area, opt, n_sectors=N, U0=resp.peak_U,
                          log=note)
    w_t = float(sector.W.max())
    log.info(f"wear: deepest point per blade {disk.blade_max_m.min():.3e} … {disk.blade_max_m.max():.3e} m "
             f"(blade {int(np.argmax(disk.blade_max_m))}), tuned sector {w_t:.3e} m; march "
             f"{'steady' if disk.history.steady else 'NOT steady'} after {disk.history.iterations} steps, "
             f"{disk.history.seconds:.1f} s")
    if checks:
        U0 = ms.travelling_wave(_sector_solution(ref, f_t), N, int(scene["cyclic"].engine_order))
        # on the sector's own steps: the two models compared, not the step control's round-off decisions
        tw = ms.worn_blades(WholeDiskCoordinates(sub), law_w, v, 2 * np.pi * f_t, area, opt, n_sectors=N, U0=U0,
                            log=note, step_lengths=np.diff(sector.history.cycles))
        checks["worn_tuned_vs_cyclic"] = float(np.abs(tw.W - sector.W).max() / max(w_t, 1e-300))
        log.info(f"check: tuned whole disk's worn state against the sector's {checks['worn_tuned_vs_cyclic']:.1e}")
    summary = {"hz": float(resp.peak["hz"]), "blade_max_m": disk.blade_max_m.tolist(),
               "blade_volume_m3": disk.blade_volume_m3.tolist(), "tuned_max_m": w_t,
               "amplification": float(disk.blade_max_m.max()) / w_t if w_t > 0 else None,
               "disk": disk.history.summary(), "sector": sector.history.summary(),
               "control": {"kind": opt.control, "disk": disk.control, "sector": sector.control},
               "law": {"k_w": opt.k_w, "blade_share": opt.blade_share, "steady_tol": opt.steady_tol,
                       "rtol": opt.rtol}}
    return {"disk": disk, "sector": sector, "summary": summary}


def _sector_solution(run, f: float):
    """The tuned sector's relative harmonics at f [Hz]: those of the band's converged point nearest
    f (the band is centred on the tuned peak, so with an odd ``points`` they are f's own)."""
    ok = np.flatnonzero(run.converged)
    return run.Ur[int(ok[np.argmin(np.abs(np.asarray(run.freqs_hz)[ok] - f))])]


def _checks(sub, law_w, v, ref, freqs, seeds, dev, mass, resp, af, hb, log) -> dict:
    """tuned_vs_cyclic, linear_vs_full_disk, whitehead_bound_ok and the two-blade check."""
    from reduction.mistuned import WholeDiskCoordinates
    from workflow.engine.studies import mistuning as ms
    from workflow.verification import mistuning_lumped as lumped

    N = sub.n_sectors
    i = int(np.nanargmax(np.where(ref.converged, ref.amplitude, -np.inf)))
    r0 = ms.forced_response(WholeDiskCoordinates(sub), law_w, v, [freqs[i]], seeds=[seeds[i]], refine=False,
                            tied=False, tol=hb.tol, maxiter=hb.max_iterations)
    tuned_vs_cyclic = float(np.max(np.abs(r0.amplitude[0] / ref.amplitude[i] - 1))) if r0.converged[0] else None
    f_tied = resp.tied_peak["hz"]
    rc = WholeDiskCoordinates(sub, dev, mass)
    sub_path = ms.blade_amplitudes(np.stack([np.zeros(N * sub.blade.O.shape[0]), rc.tied_response(2 * np.pi * f_tied)]), N)
    full = _full_disk_tied(sub, dev, mass, 2 * np.pi * f_tied)
    linear = float(np.max(np.abs(sub_path / full - 1)))
    rows = lumped.monte_carlo(min(N, 24), 0.02, 50, 3)
    lumped_max = float(np.max(rows))
    two = lumped.two_blade_errors(nhs=(7,))
    two_err = max(r["error"] for r in two)
    two_ok = all(r["error"] <= r["budget"] for r in two)
    bound_lumped = ms.whitehead_bound(min(N, 24))
    log.info(f"checks: tuned whole disk against the cyclic sector {tuned_vs_cyclic if tuned_vs_cyclic is None else f'{tuned_vs_cyclic:.1e}'}; "
             f"tied response, substructures against the assembled whole disk {linear:.1e}; lumped one-family disk "
             f"(N = {min(N, 24)}, σ = 0.02, 50 patterns) largest AF {lumped_max:.3f} ≤ Whitehead {bound_lumped:.3f}; "
             f"two blades with friction against time integration {two_err:.1e}")
    return {"tuned_vs_cyclic": tuned_vs_cyclic, "linear_vs_full_disk": linear,
            "whitehead_bound_ok": bool(lumped_max <= bound_lumped and (af["tied"] or 0) <= ms.whitehead_bound(N)),
            "lumped_max_af": lumped_max, "lumped_bound": bound_lumped,
            "two_blade_vs_time": two_err, "two_blade_within_budget": two_ok}
