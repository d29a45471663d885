"""Harmonic-balance stage: friction-damped frequency responses (paper §5.1, Figs. 4–8, Table 1).

Reads the reduced model, builds the contact law and the variants from the
scene — formulation (HBM / TCM / HDHB) × Nh × nit — and hands them to the
engine's front door :func:`workflow.engine.frf`; writes what it returns
(:mod:`workflow.report.frf`). The choices (band, condensation once, static
state, cascade, reference, MPI sharing, error, penalties) are the engine's,
documented there.

A cyclic sector's model (:class:`~reduction.cyclic_reduce.CyclicReducedModel`,
``geometry.cyclic``) goes through the same front door: harmonic j is
condensed on its nodal diameter ``(j·EO) mod N`` (the tuned disk under an
engine-order travelling wave); the summary gains ``cyclic``.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

NAME = "hb"
SECTIONS = ("contact", "hb", "sweep", "excitation", "pseudotime")
NEEDS = ("reduced",)
VIA_BUNDLE = ("excitation",)  # in the reduced load: a user bundle replaces it (#18)
PRODUCES = ("frf",)
#: collective under mpirun: the engine shares variants and the reference's
#: frequencies over the ranks; rank 0 writes every output
MPI = True


def options(scene):
    """:class:`workflow.engine.FRFOptions` and the variants of a scene."""
    from workflow.engine import FRFOptions, Variant, variants

    hb, sw, ct, pt = scene["hb"], scene["sweep"], scene["contact"], scene["pseudotime"]
    ref = None
    if hb.reference_harmonics > 0:
        ref = Variant("hbm", int(hb.reference_harmonics),
                      max(int(hb.reference_time_samples), 2 * hb.reference_harmonics + 1))
    return FRFOptions(solver=hb.solver, tol=hb.tol, max_iterations=hb.max_iterations, max_passes=ct.max_passes,
                      sweep=sw.method, max_steps=sw.max_steps, reference=ref, eps_check_factor=ct.eps_check,
                      reference_check=hb.reference_check, refine_peak=hb.refine_peak, nh_check=hb.nh_check,
                      branch_check=hb.branch_check, time_check=hb.time_check, stability=hb.stability,
                      pseudo=pseudo_options(pt)), variants(hb)


def pseudo_options(pt) -> dict:
    """:func:`workflow.engine.pseudotime.integrate` options from ``[pseudotime]``."""
    kw = {"scheme": pt.scheme, "precond": pt.precond, "dt_growth": pt.dt_growth}
    if pt.scheme in ("rk4", "local"):
        kw["cfl"] = pt.cfl
    return kw


def law_of(scene, model, rc=None):
    """The scene's DLFT law on ``model`` (the one penalty decision, :mod:`workflow.engine.penalty`)."""
    from workflow.engine import contact_law

    ct = scene["contact"]
    return contact_law(model, mu=model.friction(ct.mu)[0], eps_n=ct.eps_n, eps_t=ct.eps_t, gap=ct.gap,
                       factor=ct.penalty_factor, rc=rc)


def cyclic_check(model, nh: int) -> dict | None:
    """For a cyclic model: ``{n_sectors, engine_order, nodal_diameters}`` (the ND of
    each harmonic 0…nh); :class:`SceneError` naming ``reduction.cyclic_harmonics``
    if one was not reduced. None for a fixed-boundary model."""
    from workflow.errors import SceneError

    if not getattr(model, "is_cyclic", False):
        return None
    nds = model.nodal_diameters(nh)
    missing = sorted({k for k in nds if k not in model.models})
    if missing:
        raise SceneError(f"harmonics up to {nh} need nodal diameters {missing}, which the cyclic reduction did not "
                         f"prepare (it has {sorted(model.models)}): raise reduction.cyclic_harmonics to ≥ {nh}")
    return {"n_sectors": model.n_sectors, "engine_order": model.engine_order, "nodal_diameters": nds}


def needed_harmonics(opt, todo) -> int:
    """Largest Nh the FRF study condenses: variants, reference and its 1.5×Nh check."""
    nh = max([v.nh for v in todo] + [1])
    if opt.reference is not None:
        nh = max(nh, int(math.ceil(1.5 * opt.reference.nh)) if opt.reference_check else opt.reference.nh)
    return nh


def run(scene, inputs: dict, out: Path, log) -> dict:
    from workflow.engine import frf
    from workflow.errors import BundleError, SolverError
    from workflow.mpi import world
    from workflow.report.frf import write_outputs
    from workflow.stages.reduction import contact_stiffness, load_model

    model = load_model(Path(inputs["reduced"]), scene["contact"])
    if model.n_pairs == 0:
        raise BundleError(f"reduced model in {inputs['reduced']} has no contact pairs")
    t0 = time.perf_counter()
    opt, todo = options(scene)
    cyclic = cyclic_check(model, needed_harmonics(opt, todo))
    sw = scene["sweep"]
    try:
        study = frf(model, law_of(scene, model), todo, band_hz=(sw.f_start_hz, sw.f_stop_hz), points=sw.points,
                    options=opt, comm=world(), log=log)
    except SolverError as exc:
        if "static contact state" in str(exc) and "rotation" in getattr(scene, "unused", ()):
            raise SolverError(str(exc).replace("set rotation.speed_rpm (centrifugal) or excitation.static_force",
                                               "the bundle's loads.npz 'static' load")) from None
        raise
    if study is None:       # MPI rank ≠ 0
        return None
    files = write_outputs(Path(out), study)
    summary = summarise(study, scene)
    summary["mu_source"] = model.friction(scene["contact"].mu)[1]
    summary["contact_stiffness"] = contact_stiffness(scene["contact"])
    summary["peak"] = study.peak
    if cyclic is not None:
        summary["cyclic"] = cyclic
    summary.update(seconds=round(time.perf_counter() - t0, 3), files=files)
    return summary


def summarise(study, scene) -> dict:
    """summary.json entries of an FRF study (NaN → None)."""
    from workflow.engine.studies.sweepstability import turning_point_rows

    runs = [{
        "method": r.variant.method, "harmonics": r.variant.nh, "time_samples": r.variant.nit,
        "solver": r.solver, "seconds": round(r.total_seconds, 4), "cpu_seconds": round(r.cpu_seconds, 4),
        "error": r.error, "converged_points": r.converged_points, "points": len(r.freqs_hz),
        "iterations": int(r.iterations.sum()), "peak_hz": r.peak_hz(),
        "peak_amplitude_m": float(np.nanmax(np.where(r.converged, r.amplitude, np.nan))) if r.converged.any() else None,
        "dlft_max_passes": r.dlft_max_passes,
        "stable": r.stable, "floquet_max": None if r.floquet_max is None else [float(v) for v in r.floquet_max],
        "turning_points": turning_point_rows(r),
    } for r in study.runs]
    ref = study.reference
    reference = None
    if ref is not None:
        reference = {"method": "hbm", "harmonics": ref.variant.nh, "time_samples": ref.variant.nit,
                     "solver": "newton-powell", "seeded": "highest-Nh variant", "seconds": round(ref.total_seconds, 4),
                     "converged_points": ref.converged_points, "points": len(ref.freqs_hz), "peak_hz": ref.peak_hz(),
                     "convergence": study.reference_convergence}
    st, law = study.static, study.law
    return clean({
        "runs": runs, "band_hz": list(study.band_hz), "points": len(study.freqs_hz), "reference": reference,
        "tied_frequency_hz": study.tied_hz, "tied_mode": study.tied_mode,
        "static": {"pairs_in_contact": int(np.count_nonzero(st.state != 0)),
                   "pairs_slipping": int(np.count_nonzero(st.state == 2)),
                   "normal_load_N": float(-st.lam[:, 0].sum())},
        "eps_n": float(np.mean(law.eps_n)), "eps_t": float(np.mean(law.eps_t)),
        "eps_n_range": [float(law.eps_n.min()), float(law.eps_n.max())],
        "eps_t_range": [float(law.eps_t.min()), float(law.eps_t.max())],
        "eps_check": study.eps_check,
        "stuck_peak": study.stuck_peak,
        "nh_check": study.nh_check,
        "branch_check": study.branch_check,
        "time_check": {k: v for k, v in study.time_check.items() if k != "log_line"},
        "mu": [float(m) for m in study.law.mu] if np.ptp(study.law.mu) > 0 else float(study.law.mu[0]),
        "excitation_amplitude_N": None if "excitation" in getattr(scene, "unused", ()) else
        float(scene["excitation"].amplitude),
        "condense_seconds": round(study.condense_seconds, 4),
        "condensation": study.condensation,
        "unconverged": study.unconverged(),
        "warnings": study.warnings(),
    })


def clean(v):
    """NaN/inf → None, recursively, so summary.json stays valid JSON."""
    if isinstance(v, dict):
        return {k: clean(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [clean(x) for x in v]
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    return v
