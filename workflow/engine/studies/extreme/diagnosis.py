"""Why a solve failed (:func:`_diagnose`) or converged off its reference (:func:`_explain_off`)."""
from __future__ import annotations

import numpy as np

from workflow.engine.contact import SLIP
from workflow.engine.errors import BladewearError
from workflow.engine.hb import HBProblem
from workflow.engine.studies.extreme.cases import Case, CaseResult
from workflow.engine.studies.extreme.checks import FIRST_ORDER_SMALL, _error, verify
from workflow.engine.studies.extreme.limits import _rel
from workflow.engine.studies.extreme.settings import Setup


def _diagnose(res, prob: HBProblem, x, solver: str, facts: dict, cond: float | None) -> str:
    """Name the most likely cause of a failed solve (measured at the final point)."""
    parts = [res.reason or "not converged"]
    if facts.get("residual") is not None:
        parts.append(f"‖R‖/‖F‖ = {facts['residual']:.1e}")
    sep = facts.get("separated") or 0.0
    inter = facts.get("intermittent") or 0.0
    if inter > 0.0:
        parts.append(f"{inter:.0%} of the pairs open and close within the period: stalled at a kink of the "
                     "piecewise-smooth residual (separation/contact switches)")
    if sep >= 1.0:
        parts.append("contact open everywhere (is the blade held without it?)")
    elif facts.get("open_pairs"):
        parts.append(f"{facts['open_pairs']} pair(s) open all period")
    if solver == "pseudo-time" and x is not None and prob.n <= 1500:
        try:
            _, J = prob.residual_jacobian(x)
            neg = int(np.sum(np.linalg.eigvals(J).real < 0))
        except (np.linalg.LinAlgError, ValueError):
            neg = 0
        if neg:
            parts.append(f"J has {neg} eigenvalue(s) with Re < 0 here: the steady state is not an attracting "
                         "equilibrium of ∂x/∂t* = −R (slipping pairs see the free-interface Zr, indefinite above "
                         "its resonances); use newton")
    if cond is not None and cond > 1e12:
        parts.append(f"ill-conditioned Jacobian (cond {cond:.1e})")
    if prob.stats.get("unconverged_passes"):
        parts.append(f"DLFT passes hit the limit {prob.stats['unconverged_passes']}×")
    return "; ".join(parts)


def _explain_off(su: Setup, case: Case, prob: HBProblem, x: np.ndarray, solver: str, out: CaseResult,
                 reference: dict | None, info: dict, facts: dict) -> None:
    """A verified root farther from its reference than its tolerance: a wrong solution or a wrong reference?

    First Newton is run on from the returned point (tolerance 10⁻³·tol): if that moves the solution
    to within the tolerance, the returned point was not the solution (a solver stopping on its own
    step test — ‖F‖ can be dominated by the static load, so ‖R‖/‖F‖ ≤ 10·tol need not resolve the
    vibration) and the row becomes not converged. Otherwise the point is a root and the diagnosis
    names why it is not at the reference (μ not small, separation, ε-dependence, another root).
    """
    from workflow.engine.solvers import newton

    s = su.settings
    e, t = out.error, out.tolerance
    try:
        with np.errstate(all="ignore"):
            pol = newton(prob.residual_jacobian, np.array(x, dtype=float), fun=prob.residual,
                         tol=1e-3 * s.tol, scale=prob.residual_scale(), maxiter=10)
        ok, _, _ = verify(prob, pol.x, s.tol)
        e_p = _error(su, case, prob, prob.harmonics(pol.x), reference) if ok else None
        moved = _rel(prob.harmonics(pol.x)[1:], out.U[1:], scale=max(float(np.linalg.norm(out.U[1:])), 1e-300))
    except (np.linalg.LinAlgError, FloatingPointError, ValueError, BladewearError):
        e_p, moved, pol = None, None, None
    lim = {"free": "free limit (μ = 0)", "tied": "tied limit", "open": "open-contact linear response",
           "penalty": "ε = 1× solution"}.get(case.limit, case.limit)
    head = f"converged {e:.2g} from the {lim} (tolerance {t:.1g})"
    if e_p is not None and e_p <= t:
        out.converged = False
        out.diagnosis = (f"{solver} stopped short of the root at ‖R‖/‖F‖ = {out.residual:.1e} ({head}): Newton "
                         f"from there reaches the reference (error {e_p:.1e}, {pol.iterations} iteration(s), "
                         f"U moved {moved:.1e}) — the returned point is not the solution; ‖F‖ is dominated "
                         "by the static load, so ‖R‖/‖F‖ ≤ 10·tol does not resolve the vibration")
        return
    where = ("Newton from the returned point stays there" if e_p is not None and moved is not None
             and moved <= t else "Newton from the returned point does not settle within the tolerance")
    p = prob.p
    inter = int(round((facts.get("intermittent") or 0.0) * p))
    opn = int(facts.get("open_pairs") or 0)
    if case.limit in ("free", "tied") and inter:
        out.diagnosis = (f"{head}: the limit assumes contact closed or open all period; the solution separates "
                         f"within the period on {inter} of {p} pairs; {where}")
        return
    if case.limit == "free" and case.mu > 0 and info.get("delta") is not None:
        d = info["delta"]
        if d > FIRST_ORDER_SMALL:
            mu_small = case.mu * 0.01 / d
            out.diagnosis = (f"{head}: the reference is not near — μ = {case.mu:g} is not small on this model: "
                             f"the O(μ) distance from the μ = 0 root is δ = {d:.2g} (Coulomb force μ|λ_N| up to "
                             f"{info['friction']:.3g} N: it scales with the static normal load, not μ alone); the free "
                             f"limit is approached for μ ≲ {mu_small:.1g} (δ = 1 %); {opn} of {p} pairs open all period"
                             f" (μ = 0: {info.get('open0')}), none opening within it; {where}")
        else:
            out.diagnosis = (f"{head}: farther than the first-order distance δ = {d:.2g} from the μ = 0 root "
                             f"(distance to it {info.get('mu0_distance') or float('nan'):.2g}); another root? {where}")
        return
    if case.limit == "penalty" and (facts.get("slipping") or 0.0) > 0.0:
        out.diagnosis = (f"{head}: ε-dependent root — {facts['slipping']:.0%} of (instant, pair) slip; DLFT's "
                         "ε-independence holds while pairs stick (HBM at nit > 2Nh+1: the truncated λ; small ε: "
                         f"reverse-slip roots; docs/solver-guide.md); {where}")
        return
    band = 10.0 * s.tol * prob.residual_scale()
    fh = float(np.linalg.norm(prob.Fr[1:]))
    if fh > 0 and band >= 1e-3 * fh:
        st = prob.static
        cone = int(np.sum(st.state == SLIP)) if st is not None else 0
        out.diagnosis = (f"{head}: the tolerance does not resolve the vibration — 10·tol·‖F‖ = {band:.1e} N against "
                         f"a harmonic load of {fh:.1e} N (‖F‖ is the static load), so points this far apart all "
                         f"pass verification; {cone} of {p} pairs slip at the static state (on the Coulomb cone, "
                         f"where the tied limit is not exact); {where}")
        return
    out.diagnosis = (f"{head}: {where} (another root, or a reference that does not apply here); "
                     f"{opn} of {p} pairs open all period, {inter} open and close")
