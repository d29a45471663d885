"""Where a wear study vibrates: its operating point, and the friction-damped resonance it is
measured against (issue 48 item 1).

At a fixed frequency next to a resonance the wear is ill-conditioned: on the quick sector the
worn depth moves as d ln W / d ln f ≈ −330 at the first tied resonance, so a resonance that one
contact mesh puts 1.7e-4 away from another's moves the worn depth by ~5 %. A frequency tied to
the model's *own* friction-damped resonance (``detuning`` r: f = r · f_r) wears every mesh and
every model at the same place on its own resonance curve; at r = 1 the response is stationary
in frequency (the peak), so a small error in f_r changes the amplitude only to second order.
"""
from __future__ import annotations

import numpy as np

from workflow.engine.errors import BundleError, SceneError, SolverError

OPERATING_POINTS = ("frequency", "detuning")
#: grid of the resonance search: ±10 % around the first tied mode the load excites (the FRF's
#: default band), refined between grid points to 1e-6 of the frequency
RESONANCE_POINTS = 15


def friction_damped_resonance(model, law, *, method: str, nh: int, nit: int, tol: float, max_iterations: int,
                              max_passes: int) -> dict:
    """The friction-damped resonance of ``model`` under ``law`` (its wear, if any, in the gap):
    {"hz", "amplitude_m", "seconds"} — the refined peak of an FRF over the default band
    (:func:`workflow.engine.frf`, :data:`RESONANCE_POINTS` points, without its checks: the
    wear study checks its own convergence). Raises :class:`SceneError` when the peak is on the
    band's edge (no resonance inside ±10 % of the tied mode)."""
    import time

    from workflow.engine.studies.study import FRFOptions, frf
    from workflow.engine.studies.variants import Variant, resolved_nit

    t0 = time.perf_counter()
    opt = FRFOptions(solver="newton-powell", tol=tol, max_iterations=max_iterations, max_passes=max_passes,
                     eps_check_factor=0.0, reference_check=False, nh_check=False, branch_check=False,
                     time_check=False)
    st = frf(model, law, [Variant(method, nh, resolved_nit(method, nh, nit))], points=RESONANCE_POINTS,
             options=opt)
    run = st.runs[0]
    ok = np.flatnonzero(run.converged)
    if st.peak is None or ok.size == 0:
        raise SceneError("wear.operating_point = \"detuning\": the friction-damped FRF around the first tied mode "
                         "did not converge, so its resonance is unknown; use wear.operating_point = \"frequency\"")
    i = int(np.argmax(np.where(run.converged, run.amplitude, -np.inf)))
    if i in (0, len(run.freqs_hz) - 1):
        raise SceneError(f"wear.operating_point = \"detuning\": the friction-damped peak is on the edge of the band "
                         f"{run.freqs_hz[0]:.4g}–{run.freqs_hz[-1]:.4g} Hz (no resonance within ±10 % of the tied "
                         "mode); use wear.operating_point = \"frequency\"")
    return {"hz": float(st.peak["hz"]), "amplitude_m": float(st.peak["amplitude_m"]),
            "seconds": time.perf_counter() - t0}


def operating_frequency(model, law, opt) -> tuple[float, dict]:
    """(f [Hz] or 0 for the first tied resonance, description) of a wear study's operating point
    (``opt``: :class:`~workflow.engine.studies.wearstudy.WearOptions`)."""
    kind = opt.operating_point
    if kind not in OPERATING_POINTS:
        raise SceneError(f"wear.operating_point: {kind!r} is not one of {', '.join(OPERATING_POINTS)}")
    if kind == "frequency":
        return float(opt.frequency_hz), {"kind": kind, "frequency_hz": float(opt.frequency_hz) or None}
    if not 0.5 <= opt.detuning <= 2.0:
        raise SceneError(f"wear.detuning = {opt.detuning:g} is outside 0.5–2 (f = detuning × the friction-damped "
                         "resonance)")
    res = friction_damped_resonance(model, law, method=opt.method, nh=opt.nh, nit=opt.nit, tol=opt.tol,
                                    max_iterations=opt.max_iterations, max_passes=opt.max_passes)
    f = opt.detuning * res["hz"]
    return f, {"kind": kind, "detuning": float(opt.detuning), "resonance_hz": res["hz"],
               "resonance_amplitude_m": res["amplitude_m"], "frequency_hz": f, "seconds": res["seconds"]}


def resonance_shift(model, law, W, opt, new: dict | None = None) -> dict:
    """Worn − new friction-damped resonance: {"new_hz", "worn_hz", "hz", "rel", "amplitude_rel",
    "seconds"} with the worn depth W (p,) [m] in the gap (``law.with_wear``), both at the wear
    study's Nh and nit. ``new``: the unworn resonance if already found (the detuning's). Where
    either resonance cannot be found, the shifts are None and ``reason`` says why."""
    kw = dict(method=opt.method, nh=opt.nh, nit=opt.nit, tol=opt.tol, max_iterations=opt.max_iterations,
              max_passes=opt.max_passes)
    try:
        new = new or friction_damped_resonance(model, law.with_wear(np.zeros(law.p)), **kw)
        worn = friction_damped_resonance(model, law.with_wear(np.maximum(np.asarray(W, float), 0.0)), **kw)
    except (SceneError, BundleError, SolverError) as exc:
        # no resonance inside the band, no tied mode the load excites, an FRF that failed: said,
        # not a failed wear study
        return {"hz": None, "rel": None, "amplitude_rel": None,
                "reason": str(exc).replace('wear.operating_point = "detuning": ', "")}
    return {"new_hz": new["hz"], "worn_hz": worn["hz"], "hz": worn["hz"] - new["hz"],
            "rel": worn["hz"] / new["hz"] - 1.0, "amplitude_rel": worn["amplitude_m"] / new["amplitude_m"] - 1.0,
            "new_amplitude_m": new["amplitude_m"], "worn_amplitude_m": worn["amplitude_m"],
            "seconds": worn["seconds"] + new.get("seconds", 0.0)}

