"""Wear stage: fretting wear of the dovetail pairs to the worn steady state (paper §4, §5.2).

Reads the reduced model, builds the contact law (the one penalty decision)
and :class:`workflow.engine.WearOptions` from the scene — the HB variant is
the first of ``hb.methods``, ``hb.harmonics``, ``hb.time_samples`` — and
calls :func:`workflow.engine.worn_steady_state`; writes ``wear.csv``,
``history_<method>.npz``, ``error_vs_time.csv`` (with ``wear.reference_check``)
and the figures of :mod:`workflow.report.wear` (Figs. 9–12).

On a cyclic sector's model (tuned disk, EO travelling wave) the march is
unchanged on the per-ND condensation; sector s moves as sector 0 shifted in
time by s·EO/N of a period, so its wear per cycle — and its worn steady
state — is sector 0's: the profile written is that of every dovetail.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

NAME = "wear"
SECTIONS = ("contact", "hb", "pseudotime", "wear", "excitation")
NEEDS = ("reduced",)
VIA_BUNDLE = ("excitation",)  # in the reduced load: a user bundle replaces it (#18)
PRODUCES = ("wear",)


def options(scene):
    """:class:`workflow.engine.WearOptions` of a scene."""
    from workflow.engine import WearOptions
    from workflow.engine.studies.variants import resolved_nit
    from workflow.errors import SceneError

    w, pt, hb, ct = scene["wear"], scene["pseudotime"], scene["hb"], scene["contact"]
    if "pseudo-time" in w.methods and pt.scheme != "ser":
        raise SceneError(f"pseudotime.scheme = {pt.scheme!r}: the wear system (U and W together, eq. 22) has one "
                         "pseudo-time integrator, 'ser' (linearly implicit Euler on W with one Jacobian a step); "
                         "the other schemes serve hb.solver = 'pseudo-time'")
    nh = int(hb.harmonics[0])
    return WearOptions(methods=tuple(w.methods), method=hb.methods[0], nh=nh,
                       nit=resolved_nit(hb.methods[0], nh, int(hb.time_samples[0])), tol=hb.tol, max_iterations=hb.max_iterations,
                       max_passes=ct.max_passes, frequency_hz=w.frequency_hz, k_w=w.k_w, blade_share=w.blade_share,
                       cycles_per_block=w.cycles_per_block, max_blocks=w.max_blocks, block_tol=w.block_tol,
                       steady_tol=w.steady_tol, reference_check=w.reference_check, max_steps=pt.max_steps,
                       rtol=pt.wear_rtol, dt_max_blocks=pt.wear_dt_max, eps_check_factor=ct.eps_check,
                       nh_check=hb.nh_check, operating_point=w.operating_point, detuning=w.detuning,
                       measure_length_m=w.measure_length_m, resonance_shift=w.resonance_shift, length_m=w.length_m,
                       length_over=w.length_over,
                       mission=tuple(tuple(float(v) for v in point) for point in w.mission), dwell_tol=w.dwell_tol,
                       dwell_step=w.dwell_step, dwell_stages=w.dwell_stages,
                       control=w.control, tip_amplitude_m=w.tip_amplitude_m)


def run_wear(model, scene, out: Path, log) -> dict:
    """The stage's work on a :class:`workflow.engine.model.ReducedModel` (also used by tests)."""
    from workflow.engine import worn_steady_state
    from workflow.io import write_npz, write_rows
    from workflow.report.wear import tip_cycles, plot_wear, write_wear_csv
    from workflow.stages.hb import clean, law_of
    from workflow.stages.reduction import contact_stiffness

    out = Path(out)
    ct = scene["contact"]
    study = worn_steady_state(model, law_of(scene, model), options(scene), log=log)
    u = study.unworn
    log.info(f"unworn point: newton {u['newton']['iterations']} iterations {u['newton']['seconds']:.3f} s; "
             f"pseudo-time {u['pseudo-time']['iterations']} steps {u['pseudo-time']['seconds']:.3f} s "
             f"({u['pseudo-time']['reason']})")
    for m, h in study.histories.items():
        write_npz(out / f"history_{m}.npz", W=h.W, cycles=np.asarray(h.cycles), max_wear=np.asarray(h.max_wear),
                  harmonic1=np.asarray(h.harmonic1), W_history=np.asarray(h.W_history))
    w = scene["wear"]
    write_wear_csv(out / "wear.csv", model.position, model.flank, study.histories, w.blade_share)
    before, after = tip_cycles(study)
    figures = plot_wear(out, study.histories, tip_before=before, tip_after=after,
                        track_label=f"pair {study.tracked_pair} t1")
    summary = {"frequency_hz": study.omega / 2 / np.pi, "pairs": study.hb.p, "csv": "wear.csv", "figures": figures,
               "unworn_point": u, "tracked_pair": study.tracked_pair,
               "methods": {m: h.summary() for m, h in study.histories.items()},
               "eps_check": study.eps_check, "nh_check": study.nh_check, "unconverged": study.unconverged(), "warnings": study.warnings(),
               "mu_source": model.friction(ct.mu)[1], "contact_stiffness": contact_stiffness(ct),
               "operating_point": study.operating_point, "law_length_m": float(w.length_m),
               "law_length_over": w.length_over, "measures": study.measures,
               "worn_volume_m3": {k: v["worn_volume_m3"] for k, v in (study.measures.get("flanks") or {}).items()},
               "energy_per_cycle_J": study.energy_per_cycle_J, "resonance_shift": study.resonance_shift}
    if w.response_detunings:
        from workflow.engine.studies.wearresponse import wear_response
        from workflow.report.wear import peak_line, plot_wear_response

        resp = wear_response(model, law_of(scene, model), options(scene), w.response_detunings,
                             refine=w.response_refine)
        write_rows(out / "wear_response.csv", resp["rows"])
        summary["response"] = {**resp, "csv": "wear_response.csv",
                               "figure": plot_wear_response(out / "wear_response.png", resp).name}
        log.info(f"wear response curve: {len(resp['rows'])} points around f_r = {resp['resonance_hz']:.6g} Hz, "
                 f"{sum(r['steady'] for r in resp['rows'])} steady, {resp['seconds']:.1f} s; {peak_line(resp['peak'])}")
    if study.profile_max_rel_diff is not None:
        summary["profile_max_rel_diff"] = study.profile_max_rel_diff
        summary["cpu_ratio_pseudo_over_reference"] = study.cpu_ratio_pseudo_over_reference
    if study.reference_check is not None:
        rc = summary["reference_check"] = study.reference_check
        write_rows(out / "error_vs_time.csv", rc["error_vs_time"])
        log.info(f"reference check: block_tol ×4 differs by {rc['self_diff']:.3%} of max W; "
                 + ", ".join(f"{r['method']} {r['seconds']:.2f} s error {r['error']:.3%}" for r in rc["error_vs_time"]))
    return clean(summary)


def run(scene, inputs: dict, out: Path, log) -> dict:
    from workflow.stages.hb import cyclic_check
    from workflow.stages.reduction import load_model

    model = load_model(Path(inputs["reduced"]), scene["contact"])
    cyclic = cyclic_check(model, options(scene).nh)
    summary = run_wear(model, scene, Path(out), log)
    if cyclic is not None:
        # a tuned travelling wave wears every dovetail alike: sector s is sector 0 shifted in time
        summary["cyclic"] = dict(cyclic, worn_dovetails="every sector (tuned disk: sector 0's profile)")
    return summary
