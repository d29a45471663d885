"""Nonlinear-modes stage: the friction-damped backbone of one tied mode by EPMC, and the
single-nonlinear-mode synthesis against the direct HB FRF (issue 49 items 2–3).

Reads the reduced model, calls :func:`workflow.engine.studies.nlmodes.backbone` and
:func:`~workflow.engine.studies.nlmodes.synthesize` (the method and its choices are documented there
and in docs/stability-and-modes.md), solves the direct FRF at each synthesis force with the
engine's front door (:func:`workflow.engine.frf`) and writes ``backbone.csv``,
``synthesis.csv``, ``backbone.png`` and ``synthesis.png``.
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

NAME = "nonlinear_modes"
SECTIONS = ("contact", "excitation", "nonlinear_modes")
NEEDS = ("reduced",)
VIA_BUNDLE = ("excitation",)
PRODUCES = ("nonlinear_modes",)
#: grid of the direct FRF a synthesis is compared with: ±10 % of the tied mode (the FRF's
#: default band), its peak refined between grid points
DIRECT_POINTS = 21


def direct_peak(model, law, nh: int, nit: int) -> dict:
    """The direct HB FRF's refined peak (HBM-Nh, the convergence checks off: this is the
    synthesis' reference at the same Nh, nit): {"hz", "amplitude_m", "freqs_hz", "amplitude"}."""
    from workflow import engine

    opt = engine.FRFOptions(eps_check_factor=0.0, nh_check=False, reference_check=False, branch_check=False,
                            time_check=False)
    st = engine.frf(model, law, [engine.Variant("hbm", nh, nit)], points=DIRECT_POINTS, options=opt)
    r = st.runs[0]
    pk = st.peak or {}
    return {"hz": pk.get("hz"), "amplitude_m": pk.get("amplitude_m"), "freqs_hz": r.freqs_hz,
            "amplitude": np.where(r.converged, r.amplitude, np.nan)}


def run(scene, inputs: dict, out: Path, log) -> dict:
    from workflow.engine.studies import nlmodes
    from workflow.engine.fourier import default_nit
    from workflow.io import write_rows
    from workflow.report.modes import plot_backbone, plot_synthesis
    from workflow.stages.hb import clean, law_of
    from workflow.stages.reduction import load_model

    out = Path(out)
    nm, exc = scene["nonlinear_modes"], scene["excitation"]
    model = load_model(Path(inputs["reduced"]), scene["contact"])
    law = law_of(scene, model)
    nh = int(nm.harmonics)
    nit = int(nm.time_samples) or default_nit(nh)
    t0 = time.perf_counter()
    bb = nlmodes.backbone(model, law, mode=nm.mode, nh=nh, nit=nit, max_steps=nm.max_steps,
                          onset_range=(*nm.amplitude_range, int(nm.points)),
                          log=log.note if hasattr(log, "note") else None)
    onset = bb.onset
    log.info(f"backbone of tied mode {nm.mode} ({bb.tied_hz:.2f} Hz tied, {bb.sliding_hz:.2f} Hz sliding): "
             f"{len(bb)} points, a = {bb.amplitude[0]:.3g} … {bb.amplitude[-1]:.3g} m·√kg, "
             f"{bb.frequency_hz.min():.3f}–{bb.frequency_hz.max():.3f} Hz, D = {bb.damping_ratio.min():.3%}–"
             f"{bb.damping_ratio.max():.3%}, {bb.seconds:.1f} s" + (f"; stopped: {bb.stopped}" if bb.stopped else ""))
    write_rows(out / "backbone.csv", bb.rows())
    forces = list(nm.synthesis_forces) or [float(exc.amplitude)]
    levels, curves = [], []
    for F in forces:
        scaled = replace(model, f_harmonic=model.f_harmonic * (F / float(exc.amplitude)))
        d = direct_peak(scaled, law, nh, nit)
        syn = nlmodes.synthesize(bb, model, force_scale=F / float(exc.amplitude), freqs_hz=d["freqs_hz"])
        row = {"force_N": F, "synthesis_hz": syn.peak_hz, "synthesis_amplitude_m": syn.peak_amplitude_m,
               "direct_hz": d["hz"], "direct_amplitude_m": d["amplitude_m"]}
        ok = d["hz"] is not None and np.isfinite(syn.peak_hz)
        row["frequency_error"] = abs(syn.peak_hz / d["hz"] - 1) if ok else None
        row["amplitude_error"] = abs(syn.peak_amplitude_m / d["amplitude_m"] - 1) if ok else None
        levels.append(row)
        curves.append((F, d, syn))
        log.info(f"synthesis at {F:g} N: peak {syn.peak_hz:.4f} Hz {syn.peak_amplitude_m:.4g} m; direct HB "
                 + (f"{d['hz']:.4f} Hz {d['amplitude_m']:.4g} m (errors {row['frequency_error']:.1e} in frequency, "
                    f"{row['amplitude_error']:.1e} in amplitude)" if ok else
                    "peak not comparable (the response lies outside the backbone's amplitudes)"))
    write_rows(out / "synthesis.csv", levels)
    checks = {"snm_peak_error": _max(r["amplitude_error"] for r in levels),
              "snm_frequency_error": _max(r["frequency_error"] for r in levels), "floquet_vs_shooting": None}
    # the Jenkins checks (nonlinear_modes.jenkins_check): the EPMC against its multi-harmonic
    # reference, the Floquet multiplier against event-driven shooting
    if nm.jenkins_check:
        from workflow.verification.modes_runner import jenkins_errors

        j = jenkins_errors(nh=nh, nit=nit)
        checks.update(jenkins_frequency_error=j["jenkins_frequency_error"],
                      jenkins_damping_error=j["jenkins_damping_error"])
        from workflow.verification.modes_runner import floquet_error

        fl = floquet_error()
        checks["floquet_vs_shooting"] = fl["floquet_vs_shooting"]
        log.info(f"Floquet multiplier of a Jenkins oscillator: {fl['engine']:.6f} against event-driven shooting's "
                 f"{fl['shooting']:.6f} ({fl['floquet_vs_shooting']:.1e})")
        log.info(f"Jenkins oscillator against its Nh = 25 Galerkin reference: frequency "
                 f"{j['jenkins_frequency_error']:.1e}, damping {j['jenkins_damping_error']:.1e}")
    figures = [plot_backbone(out / "backbone.png", bb), plot_synthesis(out / "synthesis.png", curves)]
    warnings = []
    if bb.stopped and not bb.walks:     # a mode that ends where the blade walks is a result, not a failure
        warnings.append(f"nonlinear modes: the backbone stopped at a = {bb.amplitude[-1]:.3g} m·√kg "
                        f"({bb.amplitude[-1] / onset:.3g} × the slip onset) before the "
                        f"{nm.amplitude_range[1]:g} × asked: {bb.stopped}" if onset else
                        f"nonlinear modes: the backbone stopped early: {bb.stopped}")
    for r in levels:
        if r["amplitude_error"] is None:
            warnings.append(f"nonlinear modes: the synthesis at {r['force_N']:g} N has no peak on the backbone "
                            "(the forced response lies outside its amplitudes: widen nonlinear_modes.amplitude_range)")
    rows = [{k: r[k] for k in ("amplitude", "frequency_hz", "damping_ratio", "energy_per_cycle_J")} for r in bb.rows()]
    return clean({"backbone": rows, "mode": int(nm.mode), "harmonics": nh, "time_samples": nit,
                  "tied_hz": bb.tied_hz, "tied_damping_ratio": bb.tied_damping_ratio, "sliding_hz": bb.sliding_hz,
                  "slip_onset": onset, "stopped": bb.stopped or None, "backbone_seconds": bb.seconds,
                  "walks_beyond_amplitude": float(bb.amplitude[-1]) if bb.walks else None,
                  "synthesis": levels, "checks": checks, "warnings": warnings, "unconverged": [],
                  "files": {"backbone": "backbone.csv", "synthesis": "synthesis.csv",
                            "figures": [Path(f).name for f in figures]},
                  "seconds": round(time.perf_counter() - t0, 3)})


def _max(vals):
    v = [x for x in vals if x is not None]
    return max(v) if v else None
