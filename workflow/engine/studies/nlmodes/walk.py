"""Where the backbone ends because the blade walks: the mean friction force can no longer balance the
static load (:func:`_unbalanced_mean_slip`)."""
from __future__ import annotations

import numpy as np

from workflow.engine.studies.nlmodes.epmc import _EPMC

#: How a backbone that ends because the blade walks says so (:attr:`Backbone.walks`).
WALKS = "no periodic motion beyond"
#: :func:`_unbalanced_mean_slip`: a Jacobian direction counts as null below this fraction of
#: the largest singular value (measured on the quick sector where the path ends: 4e-16)
NULL_RATIO = 1e-10
#: ... and the residual as lying in it when this fraction of ‖R‖ does (measured there: 0.95)
NULL_SHARE = 0.5
#: Newton iterations (and backtracks) a step once the blade walks: every converged point of the
#: quick sector's backbone took ≤ 7 iterations (2026-11-29)
WALK_ITERATIONS = 8
#: the SVD behind the diagnosis is dense: done up to this many unknowns
NULL_MAX_UNKNOWNS = 4000


def _unbalanced_mean_slip(prob: "_EPMC", v, a: float) -> str:
    """Why Newton cannot go on at (v, a) [m·√kg], if it is this (else ""): every pair in
    contact slips at some instant of the cycle, so the interface no longer holds the mean
    tangential position — shifting every pair's harmonic-0 tangential displacement alike moves
    its stick anchors with it and changes no force, a null direction of the Jacobian — and the
    residual left lies in the matching mean tangential force, which no unknown then changes:
    the mean friction force cannot balance the static load, and the blade's mean position
    drifts cycle after cycle (walks). Measured on the quick sector at a = 7.47e-4 (1.56 × the
    slip onset, all 8 loaded pairs slipping through part of the cycle): σ_min/σ_max = 4e-16,
    the right singular vector the pairs' mean t₁ displacement, 95 % of ‖R‖ in its left one; at
    Nh = 11, nit = 128 at the same a."""
    if prob.n > NULL_MAX_UNKNOWNS:
        return ""
    prob.a = a
    R, J, _ = prob.evaluate(v)
    U, S, Vt = np.linalg.svd(J)
    rn = float(np.linalg.norm(R))
    if not (rn > 0 and S[-1] <= NULL_RATIO * S[0] and abs(U[:, -1] @ R) >= NULL_SHARE * rn):
        return ""
    # the null direction is a mean (harmonic-0) motion whose contact part is tangential (the
    # structure's own coordinate moves with it where the tied mode carries the shift)
    mean = Vt[-1][:prob.nx].reshape(prob.nc, prob.na)[0]
    pairs = mean[:prob.nr].reshape(prob.p, 3)
    if np.sum(mean ** 2) < 0.9 or np.sum(pairs[:, 1:] ** 2) < 0.9 * np.sum(pairs ** 2):
        return ""
    c = 1 + int(np.argmax(np.sum(pairs[:, 1:] ** 2, axis=0)))
    return (f"every pair in contact slips during the cycle and the interface no longer holds its mean position "
            f"along t{c}; {abs(U[:, -1] @ R) / rn:.0%} of Newton's residual is the mean friction force along it, "
            "which no unknown changes: it cannot balance, and the blade's mean position would drift (walk)")
