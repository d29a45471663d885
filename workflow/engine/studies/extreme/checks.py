"""Is a claimed solution right? Independent verification, the tolerance of each case and the error
against its reference."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from workflow.engine.contact import SEPARATION, SLIP, STICK
from workflow.engine.hb import HBProblem
from workflow.engine.studies.extreme.cases import Case
from workflow.engine.studies.extreme.hbproblem import problem
from workflow.engine.studies.extreme.limits import (_open_pairs, _rel, free_first_order, free_limit, linear_open,
                                                     tied_limit, tied_scale)
from workflow.engine.studies.extreme.settings import Setup


def verify(prob: HBProblem, x: np.ndarray, tol: float) -> tuple[bool, str, dict]:
    """Independent check of a claimed solution: (ok, diagnosis, facts).

    ok means: x finite; ‖R(x)‖ ≤ 10·tol·‖F‖ (a solver's own test is tol);
    the DLFT periodic passes converged at x; the corrected forces satisfy
    Coulomb ‖λ_T‖ ≤ μ|λ_N|(1 + 1e-9) and λ_N ≤ 0. ``facts``: ‖R‖/‖F‖,
    state fractions, DLFT passes.
    """
    facts: dict = {}
    x = np.array(x, dtype=float, copy=True)
    if not np.all(np.isfinite(x)):
        return False, "non-finite unknowns", facts
    with np.errstate(all="ignore"):
        R = prob.residual(x)
    res = prob.last_dlft
    scale = prob.residual_scale()
    rel = float(np.linalg.norm(R)) / scale
    facts["residual"] = rel
    facts["passes"] = res.passes
    st = res.state
    facts["separated"] = float(np.mean(st == SEPARATION))
    facts["slipping"] = float(np.mean(st == SLIP))
    facts["sticking"] = float(np.mean(st == STICK))
    sep = st == SEPARATION
    facts["intermittent"] = float(np.mean(np.any(sep, axis=0) & ~np.all(sep, axis=0)))   # pairs that open and close
    facts["open_pairs"] = int(np.sum(np.all(sep, axis=0)))
    if not math.isfinite(rel):
        return False, "non-finite residual at the returned point", facts
    if not res.converged:
        return False, (f"DLFT stick reference not periodic after {res.passes} passes "
                       f"(change {res.ref_change:.2e} N; raise contact.max_passes)"), facts
    lam = res.lam
    mu = prob.law.mu
    nT = np.sqrt(lam[..., 1] ** 2 + lam[..., 2] ** 2)
    if np.any(lam[..., 0] > 0) or np.any(nT > mu[None, :] * np.abs(lam[..., 0]) * (1 + 1e-9) + 1e-300):
        return False, "contact forces violate Coulomb or unilaterality", facts
    if rel > 10.0 * tol:
        return False, f"residual ‖R‖/‖F‖ = {rel:.2e} above the tolerance {tol:.0e}", facts
    return True, "", facts


TOL_LIMIT = 100.0          # × settings.tol: free (μ = 0), tied and open limits (a verified root: ‖R‖/‖F‖ ≤ 10·tol)
TOL_PENALTY = 1e-4         # penalty cases: the ε = 1× solution, to the accuracy of two solves
FIRST_ORDER_SMALL = 0.1    # "μ small": the O(μ) distance to the free limit below 10 % of it


def tolerance(su: Setup, case: Case, delta: float | None = None) -> float | None:
    """How far from its reference a right solution of ``case`` may be (relative, as the error).

    free (μ = 0), tied, open: ``TOL_LIMIT·tol``. free at μ > 0: that plus 2δ, δ = ‖δU‖/‖U_free‖ the
    first-order distance (:func:`free_first_order`) — but at most 2·``FIRST_ORDER_SMALL``: a case whose
    δ is larger is not near its limit, and is diagnosed as such. penalty: ``max(TOL_PENALTY, 10⁴·tol)``.
    None: no limit.
    """
    t = su.settings.tol
    if case.limit in ("free", "tied", "open"):
        base = TOL_LIMIT * t
        if case.limit == "free" and case.mu > 0 and delta is not None:
            return base + 2.0 * min(delta, FIRST_ORDER_SMALL)
        return base
    if case.limit == "penalty":
        return max(TOL_PENALTY, 1e4 * t)
    return None


def _free_root(su: Setup, case: Case, method: str):
    """The μ = 0 HB root of the case (problem, x) by Newton, or (problem, None) if it fails verification."""
    from workflow.engine.solvers import newton

    p0 = problem(su, replace(case, mu=0.0), method)
    x0 = p0.x0()
    r = newton(p0.residual_jacobian, x0, fun=p0.residual, tol=su.settings.tol,
               scale=p0.residual_scale(), maxiter=su.settings.max_iterations)
    ok, _, _ = verify(p0, r.x, su.settings.tol)
    return p0, (r.x if r.converged and ok else None)


def _error(su: Setup, case: Case, prob: HBProblem, U: np.ndarray, reference: dict | None,
           info: dict | None = None) -> float | None:
    """Relative distance of U to the case's reference; ``info`` gets what the diagnosis needs
    (free limit at μ > 0: δ, the μ = 0 root's open pairs and friction force)."""
    info = {} if info is None else info
    if case.limit == "penalty":
        ref = (reference or {}).get("penalty")
        if ref is None:
            return None
        # a fully stuck interface has U ≡ 0: measure against the free-response yardstick then
        return _rel(U, ref, scale=max(float(np.linalg.norm(ref)), tied_scale(prob.Zr, prob.Fr)))
    if case.limit in ("free", "tied"):
        x = prob.unknowns_from_harmonics(U)
        op = _open_pairs(prob, x)
        if case.limit == "free":
            Uf = free_limit(prob.Zr, prob.Fr, op)
            info["open"] = int(np.sum(op))
            if case.mu > 0:
                p0, x0 = _free_root(su, case, prob.method)
                if x0 is not None:
                    op0 = _open_pairs(p0, x0)
                    Uf0 = free_limit(p0.Zr, p0.Fr, op0)
                    dU = free_first_order(p0, x0, case.mu)
                    nf = float(np.linalg.norm(Uf0[1:]))
                    lamN = np.abs(p0.contact_time(x0)[..., 0])
                    info.update(delta=float(np.linalg.norm(dU[1:])) / nf if nf > 0 else None,
                                open0=int(np.sum(op0)), friction=float(case.mu * lamN.max()),
                                mu0_distance=_rel(U[1:], p0.harmonics(x0)[1:]))
            return _rel(U[1:], Uf[1:])
        return _rel(U[1:], tied_limit(prob.Zr, prob.Fr, op)[1:], scale=tied_scale(prob.Zr, prob.Fr))
    if case.limit == "open":
        return _rel(U, linear_open(prob.Zr, prob.Fr))
    return None
