"""The answers a run was made for, with how far they can be trusted.

:func:`headline` reads the run's summary (stage summaries so far) and the
hb, wear and remap folders' CSV files and returns ``report.headline`` of
summary.json: the friction-damped peak against the tied and sliding linear
peaks, the damping achieved, the deepest wear and where, the worn model's
frequency shift, the run time, and one :class:`Check` per piece of evidence
(green: converged and within tolerance; amber: a warning, with the reason;
red: not converged; grey: no such check in this run).

Equivalent damping ratio (README, "Report"): near an isolated mode the
linear peak amplitude is inversely proportional to the damping ratio,
``A_peak ≈ F / (2 k ζ)``. The friction-damped peak ``A_nl`` is therefore
read as the peak of the same mode with the damping ratio
``ζ_eq = ζ_tied · A_tied / A_nl``, where ``A_tied`` is the tied (stuck)
linear peak and ``ζ_tied = α/(2ω) + β ω/2`` the structural (Rayleigh)
damping ratio at the tied frequency (assembly's ``damping``). ``ζ_eq`` is the
total; the friction adds ``ζ_eq − ζ_tied``. It ignores the stiffness lost
to slip (the friction-damped mode is softer than the tied one), so it is an
amplitude-equivalent figure, not a modal damping ratio.
"""
from __future__ import annotations

import csv
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from workflow.engine.penalty import CHECK_TOL

#: Largest relative peak move under the ε-, nit- and Nh-checks counted as converged:
#: the engine's own tolerance (one decision, one place).
EPS_TOL = CHECK_TOL
#: FRF error against the reference (peak-relative, hb `error`) still marked green.
REFERENCE_TOL = 0.02
#: Relative difference of two wear profiles (pseudo-time vs reference march) still green.
PROFILE_TOL = 0.01
#: Reduction check: relative FRF / frequency error of the reduced model still green.
REDUCTION_TOL = 0.01
ORDER = {"none": 0, "green": 1, "amber": 2, "red": 3}


@dataclass
class Check:
    """One piece of evidence behind a headline number: ``status`` is
    ``green``/``amber``/``red``/``none`` (no such check in this run)."""

    item: str
    name: str
    status: str
    reason: str


def worst(checks) -> str:
    """The worst status among ``checks`` (``none`` only if there is nothing else)."""
    return max((c.status for c in checks), key=ORDER.__getitem__, default="none")


def read_rows(path: Path) -> list[dict]:
    """CSV rows as dicts ([] if the file is absent)."""
    path = Path(path)
    if not path.is_file():
        return []
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def tied_damping_ratio(damping: dict | None, f_hz: float | None) -> float | None:
    """Rayleigh damping ratio ``α/(2ω) + β ω/2`` at ``f_hz`` [Hz] (dimensionless);
    β is the assembly's ``beta_total`` (modal share included)."""
    if not damping or not f_hz:
        return None
    w = 2.0 * math.pi * float(f_hz)
    beta = damping.get("beta_total", damping.get("beta", 0.0)) or 0.0
    return float((damping.get("alpha") or 0.0) / (2.0 * w) + beta * w / 2.0)


def equivalent_damping_ratio(zeta_tied: float | None, amplitude_ratio: float | None) -> float | None:
    """``ζ_eq = ζ_tied / (A_nl / A_tied)``: the damping ratio whose linear peak is
    the friction-damped one (module docstring)."""
    if zeta_tied is None or not amplitude_ratio or amplitude_ratio <= 0:
        return None
    return float(zeta_tied / amplitude_ratio)


def grid_peak(freqs, amps, ok=None) -> tuple[int | None, float | None, float | None]:
    """(index, frequency [Hz], amplitude [m]) of the largest finite amplitude
    among the points where ``ok`` (default all) is true."""
    a = np.asarray(amps, dtype=float)
    good = np.isfinite(a) & (np.ones(len(a), bool) if ok is None else np.asarray(ok, bool))
    if not good.any():
        return None, None, None
    i = int(np.argmax(np.where(good, a, -np.inf)))
    return i, float(np.asarray(freqs, float)[i]), float(a[i])


def headline_run(hb: dict) -> dict | None:
    """The run the headline peak comes from: the reference if there is one (the
    most converged), else the variant with the most harmonics, then time samples."""
    ref = hb.get("reference")
    if ref:
        return dict(ref, role="reference")
    runs = hb.get("runs") or []
    if not runs:
        return None
    return dict(max(runs, key=lambda r: (r.get("harmonics", 0), r.get("time_samples", 0))), role="variant")


def run_points(frf_rows: list[dict], run: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frequencies [Hz], amplitudes [m], converged) of ``run`` in the hb frf.csv."""
    sel = [r for r in frf_rows if r.get("method") == run.get("method") and r.get("role", "variant") == run["role"]
           and int(float(r.get("Nh", -1))) == int(run.get("harmonics", -2))
           and int(float(r.get("nit", -1))) == int(run.get("time_samples", -2))]
    f = np.array([float(r["frequency_hz"]) for r in sel])
    a = np.array([float(r["amplitude_m"]) if r["amplitude_m"] not in ("", "nan") else np.nan for r in sel])
    ok = np.array([r.get("converged", "1") in ("1", "True", "true") for r in sel], dtype=bool)
    return f, a, ok


def peak_checks(f, ok, i_peak, label: str) -> list[Check]:
    """Convergence of the headline FRF around its peak: red if the peak or a
    neighbour did not converge, amber if points elsewhere did not or the peak
    sits on the band's edge (the resonance may lie outside)."""
    if i_peak is None:
        return [Check("peak", "convergence", "red", f"{label}: no point of the FRF converged")]
    bad = np.flatnonzero(~ok)
    near = [j for j in bad if abs(j - i_peak) <= 1]
    if near:
        st, why = "red", (f"{label}: {len(bad)}/{len(ok)} points not converged, next to the peak at "
                          f"{f[i_peak]:.4g} Hz: the true peak may be missed")
    elif bad.size:
        st, why = "amber", f"{label}: {len(bad)}/{len(ok)} points not converged (away from the peak)"
    else:
        st, why = "green", f"{label}: all {len(ok)} points converged"
    out = [Check("peak", "convergence", st, why)]
    if i_peak in (0, len(f) - 1):
        out.append(Check("peak", "band", "amber", f"the peak is on the band's edge ({f[i_peak]:.4g} Hz): "
                                                  "widen sweep.f_start_hz/f_stop_hz"))
    return out


def nh_check(item: str, what: str, stage: dict) -> Check:
    """The Nh check of a stage summary (``nh_check``: the result re-solved with 1.5×Nh,
    the convergence measure; the ε-check beside it is the penalty model's
    sensitivity). When it fails, the reason is the engine's own warning line, so
    the headline's warnings list it once."""
    nc = stage.get("nh_check") or {}
    if not nc:
        return Check(item, "Nh check", "none", "no Nh check in this run (hb.nh_check = false)")
    ch = nc.get("max_rel_change")
    nh = nc.get("nh") or max((r.get("nh", 0) for r in nc.get("runs", [])), default=0)
    est = nc.get("estimated_error")
    limit = "" if est is None else (f"; Nh → ∞ estimate {100 * abs(float(est)):.2g} % "
                                    f"{'below' if float(est) > 0 else 'above'} (Richardson in 1/Nh)")
    if ch is not None and float(ch) <= EPS_TOL:
        return Check(item, "Nh check", "green",
                     f"{what}: change {float(ch):.2e} at Nh = {nh} (tolerance {EPS_TOL:g}){limit}")
    said = next((line for line in stage.get("warnings") or [] if "Nh-check" in line), None)
    if said is None:
        said = (f"{what}: could not be re-solved with more harmonics" if ch is None else
                f"{what}: change {float(ch):.2e} at Nh = {nh} (tolerance {EPS_TOL:g})")
    return Check(item, "Nh check", "amber", said)


def branch_check(hb: dict) -> Check:
    """The branch check of the hb summary (``branch_check``: the headline peak, the Nh-check's
    points and the sweep's last point re-solved from an independent start): green when every point
    agrees with the swept root; red when one does not (the answer may be a spurious root: the run
    lists it as unconverged and exits 3); amber when one could not be re-solved, since then which
    branch the sweep followed is unknown. The reason is the engine's own line."""
    return _check_of(hb, "branch_check", "branch check", "hb.branch_check", lambda c: (
        f"{len(c.get('points') or [])} point{'s' * (len(c.get('points') or []) != 1)} re-solved from an "
        f"independent start: largest difference {float(c['max_rel_diff']):.2e} (tolerance "
        f"{float(c['tolerance']):g})"))


def time_check(hb: dict) -> Check:
    """The time-domain check of the hb summary (``time_check``: the headline peak integrated in
    physical time from its HB state): green when it is a periodic orbit to the check's tolerance,
    red when not (unconverged, exit 3), amber when it could not run."""
    return _check_of(hb, "time_check", "time check", "hb.time_check", lambda c: (
        f"the peak integrated in time from its HB state: first harmonic {float(c['max_rel_diff']):.2e} from the "
        f"HB, periodicity defect {float(c.get('periodicity_defect') or 0.0):.1e} (tolerance "
        f"{float(c['tolerance']):.2e})"))


def _check_of(hb: dict, key: str, name: str, scene_key: str, passed) -> Check:
    c = hb.get(key) or {}
    if not c:
        return Check("peak", name, "none", f"no {name} in this run ({scene_key} = false)")
    if c.get("within_tolerance"):
        return Check("peak", name, "green", passed(c))
    failed = c.get("within_tolerance") is False
    lines = (hb.get("unconverged") if failed else hb.get("warnings")) or []
    said = next((line for line in lines if line.startswith(name)), None)
    return Check("peak", name, "red" if failed else "amber", said or f"{name}: {c.get('reason') or 'failed'}")


def reference_checks(hb: dict, run: dict) -> list[Check]:
    """Nh check of the peaks, the variant's error against the reference, and
    the reference's own convergence (2×nit, 1.5×Nh)."""
    out = []
    out.append(nh_check("peak", "peak", hb))
    out.append(branch_check(hb))
    out.append(time_check(hb))
    ref = hb.get("reference")
    if not ref:
        out.append(Check("peak", "reference", "none", "no converged reference in this scene "
                                                     "(hb.reference_harmonics = 0)"))
        return out
    errs = [r["error"] for r in hb.get("runs", []) if r.get("error") is not None]
    if run["role"] == "variant" and run.get("error") is not None:
        e = float(run["error"])
        out.append(Check("peak", "error vs reference", "green" if e <= REFERENCE_TOL else "amber",
                         f"FRF error of {run.get('method')}-{run.get('harmonics')} against the reference "
                         f"{100 * e:.2g} % of the peak (green ≤ {100 * REFERENCE_TOL:g} %)"))
    elif errs:
        out.append(Check("peak", "error vs reference", "green",
                         f"headline is the reference; variants' FRF errors {100 * min(errs):.2g}–"
                         f"{100 * max(errs):.2g} % of the peak"))
    out += variants_check(hb.get("runs") or [])
    conv = ref.get("convergence") or {}
    if conv.get("max_rel_change") is not None:
        ch = float(conv["max_rel_change"])
        out.append(Check("peak", "reference convergence", "green" if ch <= EPS_TOL else "amber",
                         f"reference peak moves by {ch:.2e} under 2×nit / 1.5×Nh / 10×ε"))
    return out


def variants_check(runs: list[dict]) -> list[Check]:
    """The variants beside the headline (paper-frf: Table 1's cells): amber when some of their
    points did not converge — their errors and times then include solves that gave up."""
    bad = [r for r in runs if r.get("converged_points") is not None and r.get("points")
           and int(r["converged_points"]) < int(r["points"])]
    if not runs or not any(r.get("points") for r in runs):
        return []
    if not bad:
        return [Check("peak", "variants converged", "green", f"every point of the {len(runs)} variants converged")]
    n = sum(int(r["points"]) - int(r["converged_points"]) for r in bad)
    worst_run = max(bad, key=lambda r: int(r["points"]) - int(r["converged_points"]))
    return [Check("peak", "variants converged", "amber",
                  f"{len(bad)} of {len(runs)} variants have points that did not converge ({n} points in all; most: "
                  f"{worst_run.get('method', '?').upper()}-{worst_run.get('harmonics')} nit={worst_run.get('time_samples')}, "
                  f"{int(worst_run['points']) - int(worst_run['converged_points'])}/{worst_run['points']}): their FRF "
                  "errors and times include solves that gave up")]


def hb_headline(hb: dict, folder: Path | None, damping: dict | None) -> tuple[dict, list[Check]]:
    """Peak (Hz, m), tied, sliding and stuck linear peaks (m), amplitude ratios (to the tied
    and to the stuck peak) and equivalent damping ratio, with their checks."""
    run = headline_run(hb)
    vals = dict(peak_hz=None, peak_amplitude_m=None, peak_source=None, tied_peak_hz=None,
                tied_peak_amplitude_m=None, sliding_peak_hz=None, sliding_peak_amplitude_m=None,
                stuck_peak_hz=None, stuck_peak_amplitude_m=None, amplitude_ratio_stuck=None, eps_sensitivity=None,
                amplitude_ratio=None, equivalent_damping_ratio=None, tied_damping_ratio=None,
                peak_amplitude_nh_limit_m=None)
    if run is None or folder is None:
        return vals, [Check("peak", "convergence", "none", "no FRF in this run")]
    label = f"{run.get('method', '?').upper()}-{run.get('harmonics')} nit={run.get('time_samples')}"
    f, a, ok = run_points(read_rows(Path(folder) / "frf.csv"), run)
    i, vals["peak_hz"], vals["peak_amplitude_m"] = grid_peak(f, a, ok)
    vals["peak_source"] = f"{run['role']} {label}"
    checks = peak_checks(f, ok, i, label) + reference_checks(hb, run)
    pk = hb.get("peak")
    if pk and pk.get("hz") is not None:   # the engine refined the grid peak between grid points
        vals["peak_hz"], vals["peak_amplitude_m"] = float(pk["hz"]), float(pk["amplitude_m"])
        vals["peak_source"] += f", refined between grid points (±{pk['xtol_hz']:.1g} Hz)"
        vals["peak_amplitude_nh_limit_m"] = pk.get("amplitude_nh_limit_m")
        checks.append(Check("peak", "peak search", "green",
                            f"grid peak {pk['grid_hz']:.6g} Hz / {pk['grid_amplitude_m']:.4g} m refined to "
                            f"{pk['hz']:.6g} Hz / {pk['amplitude_m']:.4g} m ({pk['evaluations']} frequencies solved)"))
    layer = hb.get("contact_stiffness")
    if layer:   # "tied" then means the interface stuck on its elastic layer, not welded
        vals["peak_source"] += (f"; contact stiffness k_n = {layer['normal_n_per_m3']:.3g}, "
                                f"k_t = {layer['tangential_n_per_m3']:.3g} N/m³")
    lin = read_rows(Path(folder) / "linear.csv")
    if lin:
        fl = np.array([float(r["frequency_hz"]) for r in lin])
        _, vals["tied_peak_hz"], vals["tied_peak_amplitude_m"] = grid_peak(fl, [float(r["tied_m"]) for r in lin])
        i_s, vals["sliding_peak_hz"], vals["sliding_peak_amplitude_m"] = grid_peak(
            fl, [float(r["sliding_m"]) for r in lin])
        if i_s in (0, len(fl) - 1):     # the largest value at an end of the band is no peak
            vals["sliding_peak_hz"] = vals["sliding_peak_amplitude_m"] = None
        check = tied_peak_check(fl, hb.get("tied_frequency_hz"), damping)
        if check.status == "amber":  # the grid misses the tied peak: read it off the mode instead
            ft, zeta = hb["tied_frequency_hz"], tied_damping_ratio(damping, hb["tied_frequency_hz"])
            vals["tied_peak_hz"], vals["tied_peak_amplitude_m"] = ft, single_mode_peak(
                fl, [float(r["tied_m"]) for r in lin], ft, zeta)
            check.reason += (f"; tied peak {vals['tied_peak_amplitude_m']:.3g} m taken from the single-mode "
                             "response through the nearest grid point")
        checks.append(check)
    ec = hb.get("eps_check") or {}
    if ec.get("max_rel_change") is not None:    # the penalty model's sensitivity, reported (not a pass/fail)
        vals["eps_sensitivity"] = {"factor": ec.get("factor"), "rel_change": float(ec["max_rel_change"]),
                                   "frequency_hz": ec.get("frequency_hz")}
    sp = hb.get("stuck_peak") or {}
    if sp.get("hz") is not None:    # the engine refined it: the μ → ∞ limit of this contact state
        vals["stuck_peak_hz"], vals["stuck_peak_amplitude_m"] = float(sp["hz"]), float(sp["amplitude_m"])
        if vals["peak_amplitude_m"]:
            vals["amplitude_ratio_stuck"] = vals["peak_amplitude_m"] / vals["stuck_peak_amplitude_m"]
    if vals["peak_amplitude_m"] and vals["tied_peak_amplitude_m"]:
        vals["amplitude_ratio"] = vals["peak_amplitude_m"] / vals["tied_peak_amplitude_m"]
        vals["tied_damping_ratio"] = tied_damping_ratio(damping, hb.get("tied_frequency_hz") or vals["tied_peak_hz"])
        vals["equivalent_damping_ratio"] = equivalent_damping_ratio(vals["tied_damping_ratio"],
                                                                    vals["amplitude_ratio"])
    return vals, checks


def single_mode_peak(freqs, amps, f_mode: float, zeta: float) -> float:
    """Peak amplitude [m] of a mode at ``f_mode`` [Hz] with damping ratio ``zeta``
    through the grid point nearest to it: near an isolated resonance
    ``A(f) = C / √((1 − r²)² + (2ζr)²)``, ``r = f/f_mode``, whose maximum is
    ``C / (2ζ√(1 − ζ²))``. Used when the grid misses the tied peak."""
    f, a = np.asarray(freqs, dtype=float), np.asarray(amps, dtype=float)
    i = int(np.argmin(np.abs(f - f_mode)))
    r = f[i] / f_mode
    c = a[i] * math.sqrt((1.0 - r * r) ** 2 + (2.0 * zeta * r) ** 2)
    return float(c / (2.0 * zeta * math.sqrt(1.0 - zeta * zeta)))


def tied_peak_check(freqs, f_tied: float | None, damping: dict | None) -> Check:
    """Is the tied linear peak on the grid? A point must lie within the
    half-power half-width ``ζ f`` of the tied frequency, else the grid
    under-reads the tied peak (the damping achieved would be understated) and
    :func:`hb_headline` takes it from :func:`single_mode_peak` (amber)."""
    zeta = tied_damping_ratio(damping, f_tied)
    if not f_tied or zeta is None:
        return Check("damping", "tied peak resolved", "none", "tied frequency or damping unknown")
    gap = float(np.min(np.abs(np.asarray(freqs) - f_tied)))
    half = zeta * f_tied
    if gap <= half:
        return Check("damping", "tied peak resolved", "green",
                     f"a grid point lies {gap:.3g} Hz from the tied mode (half-power half-width {half:.3g} Hz)")
    return Check("damping", "tied peak resolved", "amber",
                 f"nearest grid point {gap:.3g} Hz from the tied mode > half-power half-width {half:.3g} Hz: "
                 "the grid under-reads the tied peak")


def wear_headline(wear: dict, folder: Path | None, method: str | None) -> tuple[dict, list[Check]]:
    """Deepest wear [m] (blade + disk, the ``W`` of eq. 20) and where, with the
    wear study's checks: steady state reached, unconverged solves, ε check,
    and the agreement of the pseudo-time and reference profiles."""
    vals = dict(max_wear_m=None, max_wear_where=None, max_wear_position_m=None, wear_method=None,
                worn_volume_m3=None, wear_frequency_hz=None, wear_operating_point=None)
    if not wear:
        return vals, [Check("wear", "steady state", "none", "no wear study in this run")]
    vals["worn_volume_m3"] = (wear.get("measures") or {}).get("worn_volume_m3")
    op = wear.get("operating_point") or {}
    vals["wear_frequency_hz"] = op.get("frequency_hz", wear.get("frequency_hz"))
    vals["wear_operating_point"] = (f"{op['detuning']:g} × the friction-damped resonance" if op.get("kind") == "detuning"
                                    else "fixed frequency" if op else None)
    rows = read_rows(Path(folder) / "wear.csv") if folder is not None else []
    cols = [c for c in (rows[0] if rows else {}) if c.startswith("W_") and c.endswith("_m")
            and not c.startswith(("W_blade_", "W_disk_"))]
    col = f"W_{method}_m" if method and f"W_{method}_m" in cols else (cols[0] if cols else None)
    if col:
        w = np.array([float(r[col]) for r in rows])
        i = int(np.argmax(w))
        vals.update(max_wear_m=float(w[i]), wear_method=col[2:-2],
                    max_wear_where=f"pair {rows[i].get('pair', i)}, {rows[i].get('flank', '?')} flank",
                    max_wear_position_m=[float(rows[i][k]) for k in ("x_m", "y_m", "z_m") if k in rows[i]] or None)
    checks = []
    for name, m in (wear.get("methods") or {}).items():
        st = "green" if m.get("steady") else "red"
        checks.append(Check("wear", f"steady state ({name})", st, f"{name}: {m.get('reason', '')}"))
    for line in wear.get("unconverged") or []:
        checks.append(Check("wear", "convergence", "red", line))
    checks.append(nh_check("wear", (wear.get("nh_check") or {}).get("measure", "unworn wear rates"), wear))
    # Nh and ε are checked in every run; the contact mesh is not (one march per mesh costs minutes
    # to an hour), and the worn steady state is the result that moves most with it
    checks.append(Check("wear", "contact mesh", "none",
                        f"worn profile on {wear.get('pairs', '?')} contact pairs; its contact-mesh convergence "
                        "is not checked in a run (scene contact-convergence, docs/contact-layout.md)"))
    d = wear.get("profile_max_rel_diff")
    if d is not None:
        checks.append(Check("wear", "pseudo-time vs reference", "green" if d <= PROFILE_TOL else "amber",
                            f"wear profiles differ by {100 * d:.2g} % of the deepest wear "
                            f"(green ≤ {100 * PROFILE_TOL:g} %)"))
    return vals, checks


def remap_headline(remap: dict, tied_mode: int | None) -> tuple[dict, list[Check]]:
    """Frequency shift of the worn model [Hz]: the nonlinear FRF peak worn − new
    when the remap reassembled the worn model, else the tied mode's shift."""
    vals = dict(worn_frequency_shift_hz=None, worn_frequency_shift_source=None, worn_tied_shift_hz=None)
    if not remap:
        return vals, [Check("worn", "frequency shift", "none",
                            "no worn model in this run (the scene's outputs have no “wear_map”)")]
    checks = []
    frac, allowed = remap.get("max_motion_fraction"), remap.get("max_fraction_allowed")
    if frac is not None and allowed:
        checks.append(Check("wear", "mesh motion", "green" if frac <= allowed and (remap.get("min_det_ratio") or 1) > 0
                            else "red", f"largest node motion {frac:.2g} × the local element size "
                                        f"(allowed {allowed:g}); smallest det ratio {remap.get('min_det_ratio', 1):.3g}"))
    shifts = remap.get("freq_shift_hz") or []
    k = max(int(tied_mode or 1) - 1, 0)
    if k < len(shifts):
        vals["worn_tied_shift_hz"] = float(shifts[k])
    pk = remap.get("frf_peak_hz") or {}
    if pk.get("new") is not None and pk.get("worn") is not None:
        vals["worn_frequency_shift_hz"] = float(pk["worn"]) - float(pk["new"])
        vals["worn_frequency_shift_source"] = "nonlinear FRF peak, worn − new"
        conv, n = remap.get("frf_converged") or {}, remap.get("frf_points")
        full = all(conv.get(key) == n for key in ("new", "worn"))
        checks.append(Check("worn", "convergence", "green" if full else "amber",
                            f"new/worn FRF points converged: {conv.get('new')}/{n}, {conv.get('worn')}/{n}"))
    elif vals["worn_tied_shift_hz"] is not None:
        vals["worn_frequency_shift_hz"] = vals["worn_tied_shift_hz"]
        vals["worn_frequency_shift_source"] = f"tied mode {k + 1}, worn − new"
    else:
        why = remap.get("frf_error") or "remap.reassemble is off: the worn model was not assembled"
        checks.append(Check("worn", "frequency shift", "none", why))
    return vals, checks


def model_checks(summary: dict) -> list[Check]:
    """Mesh validity (geometry stage) and the reduction check (if the scene ran it)."""
    out = []
    g = summary.get("geometry") or {}
    if g.get("jacobian_ratio_min") is not None:
        ok = g["jacobian_ratio_min"] > 0
        out.append(Check("model", "mesh", "green" if ok else "red",
                         f"{g.get('n_elements')} elements, smallest Jacobian ratio {g['jacobian_ratio_min']:.3g}, "
                         f"smallest quality {g.get('quality_min', float('nan')):.3g}; "
                         "mesh convergence is not checked in a run (tests/…/mesh convergence, make test-slow)"))
    rc = summary.get("reduction_check") or {}
    if rc.get("frf_max_rel_error") is not None:
        e = max(float(rc["frf_max_rel_error"]), float((rc.get("tied") or {}).get("max_rel_freq_error") or 0.0))
        out.append(Check("model", "reduction", "green" if e <= REDUCTION_TOL else "amber",
                         f"reduced vs full model: largest relative frequency/FRF error {e:.2g}"))
    else:
        out.append(Check("model", "reduction", "none",
                         "no reduction check in this scene (scene reduction-check compares reduced and full)"))
    return out


def stage_lines(summary: dict, key: str) -> list[str]:
    """Every ``key`` ("unconverged"/"warnings") line of the summary: top level and per stage.
    The top level's ``unconverged`` is ``{stage: [lines]}`` (workflow/pipeline.py); a stage's is a list."""
    top = summary.get(key) or []
    lines = [str(x) for v in top.values() for x in (v if isinstance(v, list) else [v])] \
        if isinstance(top, dict) else [str(x) for x in top]
    for entry in summary.values():
        if isinstance(entry, dict) and isinstance(entry.get(key), list):
            lines += [str(x) for x in entry[key] if str(x) not in lines]
    return lines


def headline(summary: dict, folders: dict) -> dict:
    """``report.headline`` of summary.json from the summary so far and the
    product folders (``folders["frf"]``, ``["wear"]`` …, Paths or None)."""
    hb, wear, remap = summary.get("hb") or {}, summary.get("wear") or {}, summary.get("remap") or {}
    damping = (summary.get("assembly") or {}).get("damping")
    v1, c1 = hb_headline(hb, folders.get("frf"), damping) if hb else ({}, [])
    v2, c2 = wear_headline(wear, folders.get("wear"), remap.get("wear_column"))
    v3, c3 = remap_headline(remap, hb.get("tied_mode"))
    checks = c1 + c2 + c3 + model_checks(summary)
    timings = summary.get("timings") or {}
    warnings = [f"{c.item} — {c.name}: {c.reason}" for c in checks if c.status in ("amber", "red")]
    warnings += [line for line in stage_lines(summary, "unconverged") + stage_lines(summary, "warnings")
                 if not any(line in w for w in warnings)]
    out = {"peak_hz": None, "peak_amplitude_m": None, "tied_peak_amplitude_m": None, "amplitude_ratio": None,
           "equivalent_damping_ratio": None, "max_wear_m": None, "worn_frequency_shift_hz": None}
    out.update(v1)
    out.update(v2)
    out.update(v3)
    out["run_seconds"] = float(sum(float(t) for t in timings.values() if isinstance(t, (int, float))))
    out["status"] = worst(checks) if any(c.status != "none" for c in checks) else "none"
    out["warnings"] = warnings
    out["checks"] = [asdict(c) for c in checks]
    return out
