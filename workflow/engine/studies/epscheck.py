"""How converged a result is: re-solves with more harmonics, more time samples, a larger ε.

The HB answer converges in Nh (and nit); the DLFT penalty ε is the stiffness
lent to the harmonics above Nh (:mod:`workflow.engine.penalty`), a model whose
influence vanishes as Nh grows. So the *convergence* measure is the Nh-check
(:func:`nh_runs`: Nh × 1.5, nit scaled alike), and the ε-check (ε ×
``eps_check_factor``) reports the model's sensitivity. Each check re-solves
*one* point — the peak, where the friction damping matters most and slip is
largest — from the converged state (so it costs a few Newton steps) and
reports the relative change of the observed first-harmonic amplitude.
"""
from __future__ import annotations

import numpy as np

from workflow.engine import penalty
from workflow.engine.cascade import solve_point
from workflow.engine.studies.frf import observed
from workflow.engine.errors import BundleError


def _peak_index(r) -> int | None:
    a = np.where(r.converged, r.amplitude, -np.inf)
    return int(np.argmax(a)) if np.isfinite(a).any() else None


def resolve(rc, f_hz: float, Ur: np.ndarray, law, static, *, method: str, nh: int, nit: int, opt,
            eps_path=()) -> tuple:
    """Observed amplitude (m) at ``f_hz`` solved from the harmonics ``Ur`` with
    ``law``, ``method``, ``nh``, ``nit``; (amplitude or None, converged)."""
    from workflow.engine.linear import condensed
    from workflow.engine.hb import HBProblem

    c = condensed(rc, 2 * np.pi * f_hz, nh)
    prob = HBProblem(c.Zr, c.Fr, law, nh, nit, method, max_passes=opt.max_passes, static=static)
    U = np.zeros((nh + 1, prob.nr), dtype=complex)
    m = min(nh + 1, Ur.shape[0])
    U[:m] = Ur[:m]
    # from the converged state at the smaller ε: half a decade, then the full step
    pr = solve_point(prob, [prob.unknowns_from_harmonics(U)], solver="newton-powell", tol=opt.tol,
                     maxiter=opt.max_iterations, eps_path=eps_path)
    if not pr.converged:
        return None, False
    return observed(rc, c.omega, prob.harmonics(pr.result.x))[0], True


def finer(nh: int, nit: int) -> tuple[int, int]:
    """(Nh, nit) of the Nh-check: Nh × 1.5 rounded up (at least Nh + 1), nit scaled alike
    (a collocated variant, nit = 2Nh+1, stays collocated)."""
    nh2 = max(nh + 1, int(np.ceil(1.5 * nh)))
    if nit == 2 * nh + 1:
        return nh2, 2 * nh2 + 1
    return nh2, max(2 * nh2 + 1, int(np.ceil(nit * nh2 / max(nh, 1))))


def judged(check: dict) -> dict:
    """``check`` with ``tolerance`` (:data:`~workflow.engine.penalty.CHECK_TOL`) and
    ``within_tolerance`` (None where nothing could be re-solved): every check says
    whether it passed, in the summary and, through :func:`log_line`, in the log."""
    ch = check.get("max_rel_change")
    return {**check, "tolerance": penalty.CHECK_TOL,
            "within_tolerance": None if ch is None else bool(ch <= penalty.CHECK_TOL)}


def log_line(name: str, what: str, check: dict) -> str:
    """One log line for a :func:`judged` check, e.g. ``ε-check (ε × 10): the peak moves by …``."""
    ch = check.get("max_rel_change")
    if ch is None:
        why = next((r["reason"] for r in check.get("runs", []) if r.get("reason")), check.get("reason"))
        return f"{name}: {what} could not be re-solved" + (f" ({why})" if why else "")
    verdict = "within" if check.get("within_tolerance") else "ABOVE"
    return f"{name}: {ch:.2e} change in {what}, {verdict} the tolerance {penalty.CHECK_TOL:g}"


def _rel(a, b) -> float | None:
    return None if a is None or b is None or b == 0 else abs(a - b) / abs(b)


def _at_peaks(rc, static, runs: list, opt, trial) -> dict:
    """Each run's peak re-solved from its converged harmonics under ``trial(variant)`` →
    (law, Nh, nit, ε-path, extra row fields); {"max_rel_change", "frequency_hz", "runs"}."""
    rows = []
    for r in runs:
        i = _peak_index(r)
        if i is None:
            continue
        v = r.variant
        lw, nh, nit, path, extra = trial(v)
        why = None
        try:
            a, ok = resolve(rc, float(r.freqs_hz[i]), r.Ur[i], lw, static, method=v.method, nh=nh, nit=nit,
                            opt=opt, eps_path=path)
        except BundleError as exc:  # a cyclic model reduced for no more harmonics than asked
            a, ok, why = None, False, f"{exc}; reduction.cyclic_harmonics"
        rows.append({"label": v.label, **extra, "frequency_hz": float(r.freqs_hz[i]),
                     "rel_change": _rel(a, float(r.amplitude[i])), "converged": ok,
                     **({"reason": why} if why else {})})
    vals = [(row["rel_change"], row["frequency_hz"]) for row in rows if row["rel_change"] is not None]
    worst = max(vals) if vals else (None, None)
    return {"max_rel_change": worst[0], "frequency_hz": worst[1], "runs": rows}


def frf_runs(rc, law, static, runs: list, opt) -> dict:
    """ε-check of each run at its peak: ε × ``opt.eps_check_factor``, from the converged
    state by half a decade then the full step.

    Returns {"factor", "max_rel_change", "frequency_hz", "runs": [{"label",
    "frequency_hz", "rel_change", "converged"}]} (``max_rel_change`` None if no
    peak could be re-solved)."""
    fac = float(opt.eps_check_factor)
    big = penalty.scaled(law, fac)
    return {"factor": fac, **_at_peaks(rc, static, runs, opt,
                                       lambda v: (big, v.nh, v.nit, (1.0 / fac, fac ** -0.5), {}))}


def nh_runs(rc, law, static, runs: list, opt) -> dict:
    """Nh-check of each run at its peak: the point re-solved at :func:`finer` (Nh, nit)
    from the converged harmonics, with the same law.

    Returns {"max_rel_change", "frequency_hz", "runs": [{"label", "nh", "nit",
    "frequency_hz", "rel_change", "converged"}]} (``max_rel_change`` None if no
    peak could be re-solved)."""
    def trial(v):
        nh2, nit2 = finer(v.nh, v.nit)
        return law, nh2, nit2, opt.eps_path or (), {"nh": nh2, "nit": nit2}

    return _at_peaks(rc, static, runs, opt, trial)


def reference(rc, law, static, ref, opt, checks=()) -> dict:
    """The reference's own convergence at its peak: relative change of the
    amplitude with nit × 2, Nh × 1.5 (nit scaled alike) and ε × the ε-check
    factor; ``max_rel_change`` is the largest of the nit and Nh trials (the reference's
    uncertainty; the ε trial is reported beside it).

    ``checks``: the study's Nh-check and ε-check (:func:`nh_runs`, :func:`frf_runs`), whose
    rows for the reference are the same re-solves as the Nh and ε trials here and are
    taken from them (on paper-frf the two largest solves of the check: Nh = 38 and 25)."""
    i = _peak_index(ref)
    if i is None:
        return {"max_rel_change": None}
    v, f, a0 = ref.variant, float(ref.freqs_hz[i]), float(ref.amplitude[i])
    nh2, nit2 = finer(v.nh, v.nit)
    eps_key = "eps_x%g" % opt.eps_check_factor
    trials = {"nit_x2": (law, v.nh, 2 * v.nit),
              f"nh_{nh2}": (law, nh2, nit2),
              eps_key: (penalty.scaled(law, opt.eps_check_factor), v.nh, v.nit)}
    out = {}
    for check in checks:
        key = eps_key if "factor" in check else f"nh_{nh2}"
        if "factor" in check and check["factor"] != opt.eps_check_factor:
            continue
        row = next((r for r in check.get("runs", ()) if r["label"] == v.label and r["frequency_hz"] == f
                    and r.get("nh", nh2) == nh2 and r.get("nit", nit2) == nit2), None)
        if row is not None and row["converged"]:
            out[key] = row["rel_change"]
    fac = opt.eps_check_factor
    for key, (lw, nh, nit) in trials.items():
        if key in out:
            continue
        # ε × fac starts from the converged state; a new Nh or nit starts from a state that is
        # not its root, so it climbs the sweep's ε-path (Newton straight at ε failed at Nh 5 → 8
        # on the MPI test's sector and fell to Powell: 1.55 s of the stage's 5.5 s)
        path = (1.0 / fac, fac ** -0.5) if key.startswith("eps") else opt.eps_path
        a, _ = resolve(rc, f, ref.Ur[i], lw, static, method="hbm", nh=nh, nit=nit, opt=opt, eps_path=path)
        out[key] = _rel(a, a0)
    out = {"frequency_hz": f, "variant": v.label, **{k: out[k] for k in trials}}   # in the trials' order
    # the uncertainty is the discretisation's (nit, Nh); the ε trial is the penalty model's
    # sensitivity, reported beside it (module docstring)
    disc = [k for k in trials if not k.startswith("eps")]
    vals = [out[k] for k in disc if out[k] is not None]
    out["max_rel_change"] = max(vals) if len(vals) == len(disc) else None
    return out
