"""How converged a result is: re-solves with more harmonics, more time samples, a larger ε.

The HB answer converges in Nh (and nit); the DLFT penalty ε is the stiffness
lent to the harmonics above Nh (:mod:`workflow.engine.penalty`), a model whose
influence vanishes as Nh grows. So the *convergence* measure is the Nh-check
(:func:`nh_runs`: Nh × 1.5, nit scaled alike), and the ε-check (ε ×
``eps_check_factor``) reports the model's sensitivity. Each check re-solves
*one* point — the peak, where the friction damping matters most and slip is
largest — from the converged state (so it costs a few Newton steps) and
reports the relative change of the observed first-harmonic amplitude.

Both start from the root they check, so neither can see a *spurious* root — a sweep that
followed another root of the truncated balance (Den Hartog's oscillator, μN/F0 = 0.5, Nh = 15,
nit = 128: 10–24 % off Den Hartog where HB's own floor is ≤ 2 %, the Nh-check 0.3 %). The
*branch check* (:func:`branch_runs`) re-solves the headline peak and the Nh-check's points from
a start that owes nothing to the sweep (:data:`BRANCH_START`) and compares.
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
    # from the converged state at the smaller ε: half a decade, then the full step
    pr = solve_point(prob, [prob.unknowns_from_harmonics(Ur)], solver="newton-powell", tol=opt.tol,
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
    line = f"{name}: {ch:.2e} change in {what}, {verdict} the tolerance {penalty.CHECK_TOL:g}"
    if check.get("estimated_error") is not None:
        line += (f"; its Nh → ∞ estimate (Richardson in 1/Nh) is {100 * abs(check['estimated_error']):.2g} % "
                 f"{'below' if check['estimated_error'] > 0 else 'above'} the reported value")
    return line


def _rel(a, b) -> float | None:
    return None if a is None or b is None or b == 0 else abs(a - b) / abs(b)


def _at_peaks(rc, static, runs: list, opt, trial, at: dict | None = None) -> dict:
    """Each run's peak re-solved from its converged harmonics under ``trial(variant)`` →
    (law, Nh, nit, ε-path, extra row fields); {"max_rel_change", "frequency_hz", "runs"}.
    ``at``: {run label: (frequency [Hz], harmonics Ur, amplitude [m])} of a peak refined between
    the grid points (the headline's), checked there instead of at the run's grid peak."""
    rows = []
    for r in runs:
        v = r.variant
        if at and v.label in at:
            f, Ur, amp = at[v.label]
        else:
            i = _peak_index(r)
            if i is None:
                continue
            f, Ur, amp = float(r.freqs_hz[i]), r.Ur[i], float(r.amplitude[i])
        lw, nh, nit, path, extra = trial(v)
        why = None
        try:
            a, ok = resolve(rc, float(f), Ur, lw, static, method=v.method, nh=nh, nit=nit, opt=opt, eps_path=path)
        except BundleError as exc:  # a cyclic model reduced for no more harmonics than asked
            a, ok, why = None, False, f"{exc}; reduction.cyclic_harmonics"
        rows.append({"label": v.label, **extra, "frequency_hz": float(f),
                     "rel_change": _rel(a, float(amp)), "converged": ok,
                     "amplitude_m": float(amp), "checked_m": a, "base_nh": v.nh,
                     **({"reason": why} if why else {})})
    vals = [(row["rel_change"], row["frequency_hz"]) for row in rows if row["rel_change"] is not None]
    worst = max(vals) if vals else (None, None)
    return {"max_rel_change": worst[0], "frequency_hz": worst[1], "runs": rows}


def frf_runs(rc, law, static, runs: list, opt, at: dict | None = None) -> dict:
    """ε-check of each run at its peak (``at``: :func:`_at_peaks`): ε × ``opt.eps_check_factor``,
    from the converged state by half a decade then the full step.

    Returns {"factor", "max_rel_change", "frequency_hz", "runs": [{"label",
    "frequency_hz", "rel_change", "converged"}]} (``max_rel_change`` None if no
    peak could be re-solved)."""
    fac = float(opt.eps_check_factor)
    big = penalty.scaled(law, fac)
    return {"factor": fac, **_at_peaks(rc, static, runs, opt,
                                       lambda v: (big, v.nh, v.nit, (1.0 / fac, fac ** -0.5), {}), at)}


def nh_runs(rc, law, static, runs: list, opt, at: dict | None = None) -> dict:
    """Nh-check of each run at its peak (``at``: :func:`_at_peaks`): the point re-solved at
    :func:`finer` (Nh, nit) from the converged harmonics, with the same law.

    Returns {"max_rel_change", "frequency_hz", "runs": [{"label", "nh", "nit",
    "frequency_hz", "rel_change", "converged"}]} (``max_rel_change`` None if no
    peak could be re-solved)."""
    def trial(v):
        nh2, nit2 = finer(v.nh, v.nit)
        return law, nh2, nit2, opt.eps_path or (), {"nh": nh2, "nit": nit2}

    return with_nh_limit(_at_peaks(rc, static, runs, opt, trial, at))


#: The order assumed by the Nh-check's limit: HB of a stick–slip contact converges as 1/Nh
#: (light-pad chain against its rigid-ground integration, peak at 0.95 ω₁: 1.25 / 0.44 / 0.32 /
#: 0.26 / 0.18 / 0.11 % at Nh = 3 / 7 / 11 / 17 / 23 / 31); a smooth response converges faster,
#: and then order 1 over-states the error, never under-states it.
NH_ORDER = 1.0


def with_nh_limit(check: dict) -> dict:
    """``check`` (:func:`nh_runs`) with each row's Nh → ∞ estimate from its two solves
    (:func:`workflow.engine.penalty.nh_limit`, Richardson in 1/Nh, order :data:`NH_ORDER`):
    ``nh_limit_m`` and ``estimated_error`` = (A(Nh) − A∞)/A∞, the reported peak's truncation
    error. With order 1 and Nh × 1.5 it is ≈ 3 × the change: the change between Nh and 1.5 Nh
    is a third of the distance to the limit, so the change alone under-states the error (issue 47:
    0.13 % change where the peak was 0.44 % off). Top level: ``estimated_error`` (largest |·|
    over the rows, signed) and ``order``. Pure: no solve."""
    worst = None
    for row in check.get("runs", ()):
        a1, a2 = row.get("amplitude_m"), row.get("checked_m")
        if a1 is None or a2 is None or not row.get("converged"):
            continue
        lim = penalty.nh_limit([row["base_nh"], row["nh"]], [a1, a2], order=NH_ORDER)
        row["nh_limit_m"], row["estimated_error"] = lim["limit"], lim["bias"]
        if worst is None or abs(lim["bias"]) > abs(worst):
            worst = lim["bias"]
    return {**check, "order": NH_ORDER, "estimated_error": worst}


def limit_scale(check: dict | None, label: str) -> float | None:
    """A∞ / A(Nh) of the Nh-check row of run ``label``: the factor that carries a result of that
    run at its peak to its Nh → ∞ estimate; None without one."""
    for row in (check or {}).get("runs", ()):
        if row["label"] == label and row.get("nh_limit_m") is not None and row.get("amplitude_m"):
            return row["nh_limit_m"] / row["amplitude_m"]
    return None


def reference(rc, law, static, ref, opt, checks=(), at: dict | None = None) -> dict:
    """The reference's own convergence at its peak: relative change of the
    amplitude with nit × 2, Nh × 1.5 (nit scaled alike) and ε × the ε-check
    factor; ``max_rel_change`` is the largest of the nit and Nh trials (the reference's
    uncertainty; the ε trial is reported beside it).

    ``checks``: the study's Nh-check and ε-check (:func:`nh_runs`, :func:`frf_runs`), whose
    rows for the reference are the same re-solves as the Nh and ε trials here and are
    taken from them (on paper-frf the two largest solves of the check: Nh = 38 and 25). ``at``:
    the reference's peak refined between grid points, checked there (:func:`_at_peaks`)."""
    v = ref.variant
    if at and v.label in at:
        f, Ur0, a0 = at[v.label]
        f, a0 = float(f), float(a0)
    else:
        i = _peak_index(ref)
        if i is None:
            return {"max_rel_change": None}
        f, Ur0, a0 = float(ref.freqs_hz[i]), ref.Ur[i], float(ref.amplitude[i])
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
        a, _ = resolve(rc, f, Ur0, lw, static, method="hbm", nh=nh, nit=nit, opt=opt, eps_path=path)
        out[key] = _rel(a, a0)
    out = {"frequency_hz": f, "variant": v.label, **{k: out[k] for k in trials}}   # in the trials' order
    # the uncertainty is the discretisation's (nit, Nh); the ε trial is the penalty model's
    # sensitivity, reported beside it (module docstring)
    disc = [k for k in trials if not k.startswith("eps")]
    vals = [out[k] for k in disc if out[k] is not None]
    out["max_rel_change"] = max(vals) if len(vals) == len(disc) else None
    return out


# ------------------------------------------------------------------------------------------ branch check
#: The condition number of the Newton matrix the branch check's tolerance allows for: two solves
#: of the *same* root, each to ‖R‖/‖F‖ ≤ tol, give amplitudes that differ by about κ(J)·tol
#: (measured 2e-8 at tol = 1e-8 on the quick sector, 1e-14 on the Coulomb oscillator).
BRANCH_COND = 1.0e5
#: The branch check's policy, as summary.json states it.
BRANCH_START = ("tied (static state, pairs in contact stuck), Newton along the ε-path; where that does not "
                "reach the swept root, continuation in Nh from Nh = 1 (HBM at Nh = 1 from the tied start, "
                "its root seeding the variant, each level through the whole cascade) decides")


#: How a branch-check row's ``start`` reads in a sentence.
STARTS = {"tied": "tied start", "nh-continuation": "continuation in Nh from Nh = 1", "sliding": "sliding start"}


def branch_tolerance(tol: float) -> float:
    """Largest relative amplitude difference between the swept root and the independent one
    still counted as the same root: the Nh-check's :data:`~workflow.engine.penalty.CHECK_TOL`
    (a difference below it is below what the run already accepts as converged), or
    :data:`BRANCH_COND` × the solver tolerance if that is larger (the most two solves of one
    root can differ by)."""
    return max(penalty.CHECK_TOL, BRANCH_COND * float(tol))


def _sliding_guess(prob):
    """Unknowns of the sliding linear response (μ = 0, :meth:`HBProblem.x0`); None where it
    is singular."""
    with np.errstate(all="ignore"):
        try:
            x = prob.x0(sliding=True)
        except np.linalg.LinAlgError:
            return None
    return x if np.all(np.isfinite(x)) else None


def independent(rc, f_hz: float, law, static, *, method: str, nh: int, nit: int, opt, start: str,
                newton_only: bool = False) -> dict:
    """The point at ``f_hz`` (``method``, ``nh``, ``nit``) solved through the cascade
    (newton-powell, ``opt``'s tolerance, budget and ε-path) from a start that owes nothing to
    a sweep: ``"tied"`` (:meth:`~workflow.engine.hb.HBProblem.x0`: the static state, pairs in
    contact stuck), ``"sliding"`` (the sliding linear response, μ = 0) or ``"nh-continuation"``
    (HBM at Nh = 1 from the tied start, its root seeding Nh, each level through the cascade).
    ``newton_only``: Newton along the ε-path alone (its share of the budget,
    :func:`~workflow.engine.cascade.newton_steps`) instead of the whole cascade — a quick look.
    Returns {"amplitude" (m, None if not converged), "converged", "iterations", "how"
    (+ "reason")}."""
    from workflow.engine.cascade import PointResult, along_eps_path, newton_steps
    from workflow.engine.hb import HBProblem
    from workflow.engine.linear import condensed

    c = condensed(rc, 2 * np.pi * f_hz, nh)
    kw = dict(solver="newton-powell", tol=opt.tol, maxiter=opt.max_iterations, eps_path=opt.eps_path or ())

    def problem(n, m, meth):
        return HBProblem(c.Zr[: n + 1], c.Fr[: n + 1], law, n, m, meth, max_passes=opt.max_passes, static=static)

    levels = [(nh, nit, method)]
    if start == "nh-continuation" and nh > 1:
        # Nh = 1 keeps nit (a collocated variant stays collocated: nit = 3)
        levels = [(1, 3 if nit == 2 * nh + 1 else nit, "hbm")] + levels
    its, how, U = 0, [], None
    for n, m, meth in levels:
        q = problem(n, m, meth)
        if U is None:
            g = _sliding_guess(q) if start == "sliding" else q.x0()
            if g is None:
                return {"amplitude": None, "converged": False, "iterations": its, "how": "no start",
                        "reason": "the sliding linear response is singular here"}
        else:
            g = q.unknowns_from_harmonics(U)
        if newton_only:
            res = along_eps_path(q, g, kw["eps_path"], opt.tol, newton_steps(q, opt.max_iterations))
            pr = PointResult(res, int(res.iterations), "newton")
        else:
            pr = solve_point(q, [g], **kw)
        its += pr.iterations
        how.append(f"Nh={n}: {pr.how}" if len(levels) > 1 else pr.how)
        if not pr.converged:
            return {"amplitude": None, "converged": False, "iterations": its, "how": ", ".join(how),
                    "reason": pr.result.reason}
        U = q.harmonics(pr.result.x)
    return {"amplitude": observed(rc, c.omega, U)[0], "converged": True, "iterations": its, "how": ", ".join(how)}


def branch_point(rc, law, static, point: dict, opt, tolerance: float) -> dict:
    """One point of the branch check: ``point`` {"role", "label", "method", "nh", "nit",
    "frequency_hz", "swept_m"} solved by Newton from the tied start; if that does not reach the
    swept amplitude within ``tolerance``, by continuation in Nh from Nh = 1 through the whole
    cascade, which then decides (the tied start's root, if another, is kept as ``tied_m``). The row: the point's fields plus
    "independent_m", "rel_diff" (None if no independent start converged, with "reason"),
    "start", "how", "iterations", "seconds"."""
    import time

    t0 = time.perf_counter()
    f, swept = float(point["frequency_hz"]), float(point["swept_m"])
    kw = dict(method=point["method"], nh=int(point["nh"]), nit=int(point["nit"]), opt=opt)
    row = {k: point[k] for k in ("role", "label", "frequency_hz")} | {"swept_m": swept}
    tries, its = [], 0
    for start in ("tied", "nh-continuation"):
        try:
            got = independent(rc, f, law, static, start=start, newton_only=start == "tied", **kw)
        except BundleError as exc:  # a cyclic model reduced for fewer harmonics than asked
            got = {"amplitude": None, "converged": False, "iterations": 0, "how": "", "reason": str(exc)}
        its += int(got["iterations"])
        tries.append((start, got))
        rel = _rel(got["amplitude"], swept)
        if rel is not None and rel <= tolerance:
            break
    ok = [(s, g) for s, g in tries if g["converged"]]
    start, got = ok[-1] if ok else tries[-1]
    row.update(independent_m=got["amplitude"], rel_diff=_rel(got["amplitude"], swept), start=start,
               how=got["how"], iterations=its, seconds=round(time.perf_counter() - t0, 4))
    other = [g["amplitude"] for s, g in ok if s != start]
    if other:
        row["tied_m"] = other[0]
    if not ok:
        row["reason"] = "; ".join(f"{s}: {g.get('reason', 'not converged')}" for s, g in tries)
    return row


def branch_runs(rc, law, static, points: list, opt) -> dict:
    """The branch check (:data:`BRANCH_START`): each of ``points`` (:func:`branch_point`)
    re-solved from an independent start and compared with the swept root.

    Returns {"max_rel_diff", "frequency_hz" (of the largest), "tolerance"
    (:func:`branch_tolerance`), "solver_tol", "within_tolerance", "start", "points": [...],
    "seconds"}. ``within_tolerance``: False if any point disagrees; None — with a ``reason`` —
    if nothing could be checked or a point could not be re-solved; True only if every point
    was re-solved and agrees."""
    import time

    t0 = time.perf_counter()
    tolerance = branch_tolerance(opt.tol)
    rows = [branch_point(rc, law, static, p, opt, tolerance) for p in points]
    vals = [(r["rel_diff"], r["frequency_hz"]) for r in rows if r["rel_diff"] is not None]
    worst = max(vals) if vals else (None, None)
    out = {"max_rel_diff": worst[0], "frequency_hz": worst[1], "tolerance": tolerance, "solver_tol": float(opt.tol),
           "start": BRANCH_START, "points": rows}
    if worst[0] is not None and worst[0] > tolerance:
        out["within_tolerance"] = False
    elif not rows:
        out.update(within_tolerance=None, reason="no converged point to check")
    elif len(vals) < len(rows):
        why = next(r["reason"] for r in rows if r["rel_diff"] is None)
        out.update(within_tolerance=None, reason=f"{len(rows) - len(vals)} of {len(rows)} points could not be "
                                                 f"re-solved from an independent start ({why})")
    else:
        out["within_tolerance"] = True
    out["seconds"] = round(time.perf_counter() - t0, 4)
    return out


def branch_line(check: dict) -> str | None:
    """The warning line of a branch check that did not pass (None if it passed or did not
    run), naming both amplitudes of the worst point."""
    if not check or check.get("within_tolerance"):
        return None
    if check.get("within_tolerance") is None:
        return (f"branch check: {check.get('reason', 'could not run')}; whether the sweep followed the right "
                "branch is unknown")
    r = max((p for p in check["points"] if p["rel_diff"] is not None), key=lambda p: p["rel_diff"])
    return (f"branch check: {r['label']} at {r['frequency_hz']:.6g} Hz ({r['role']}): swept branch "
            f"{r['swept_m']:.3e} m, independent start ({STARTS.get(r['start'], r['start'])}) "
            f"{r['independent_m']:.3e} m — "
            f"{r['rel_diff']:.2e} apart (tolerance {check['tolerance']:g}): the truncated balance has two roots "
            "here and the sweep may have followed a spurious one; raise hb.harmonics (and hb.time_samples) and see "
            "which answer the results approach, or check the point in the time domain")
