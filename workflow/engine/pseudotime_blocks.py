"""Matrix-free implicit block-Jacobi pseudo-time for large contact interfaces (paper §3, issue #16).

The paper proposes, for large systems, dual time stepping with an implicit
block-Jacobi scheme and local pseudo-time steps (after Sicot et al. 2008,
paper ref. 4). Here the blocks are the contact pairs: in harmonic
coefficients (:mod:`workflow.engine.linsolve`) the Jacobian is
``K = Zb + G̃ (E − Zb)`` and each pseudo-time step solves, pair by pair,

    (D_p/Δτ + K_pp) δ_p = −R̃_p − Σ_{q≠p} K_pq δ_q        (couplings lagged)

with ``D = |diag K|`` (local pseudo-time steps ``Δt*_i = Δτ/|K_ii|``,
Δτ dimensionless) and ``sweeps`` Jacobi sweeps (1: couplings fully lagged,
the classic scheme). Δτ grows by switched evolution relaxation as ‖R‖
falls; a step raising ‖R‖ by more than ``reject`` is refused and Δτ
divided by 4. The pair blocks cost p·(3(2Nh+1))³ — nothing of size n² is
formed — and the inter-pair coupling (the condensed stiffness Zb, dense over
pairs) is only applied, matrix-free.

It converges where the pair-block Jacobi iteration does (spectral radius of
``I − (D/Δτ + K_bd)⁻¹K`` below one, i.e. where the contact terms dominate the
inter-pair stiffness: stuck and slipping pairs at a large penalty); where
separated pairs couple through Zb it stalls — measured against Newton in the
interface-scaling benchmark.
"""
from __future__ import annotations

import math
import time

import numpy as np

from workflow.engine.pseudotime import PseudoTimeResult

__all__ = ["integrate_pairs"]


def _step(op, R, dtau, sweeps, harmonic=None):
    """The block-Jacobi update dx (J's unknowns) for residual R at pseudo-step Δτ, or None.
    ``harmonic``: a :class:`~workflow.engine.linsolve.StructuredSolve` whose (lagged)
    harmonic blocks follow each pair sweep (pair, harmonic, pair)."""
    nc, nr, p = op.nc, op.nr, op.p
    b = -np.asarray(R, float).reshape(nc, nr)
    if op._left_inv is not None:
        b = op._left_inv @ b
    B = op.pair_blocks()                                            # (p, 3nc, 3nc)
    d = np.abs(np.einsum("pii->pi", B))
    d = np.maximum(d, 1e-12 * max(float(d.max()), 1e-300))
    A = B.copy()
    A[:, np.arange(3 * nc), np.arange(3 * nc)] += d / dtau
    try:
        Ainv = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return None
    to_p = lambda v: np.moveaxis(v.reshape(nc, p, 3), 1, 0).reshape(p, 3 * nc)      # noqa: E731
    to_c = lambda v: np.moveaxis(v.reshape(p, nc, 3), 0, 1).reshape(nc, nr)         # noqa: E731
    k_apply = lambda v: to_p(op.k_apply(to_c(v)[..., None])[..., 0])                # noqa: E731
    bp = to_p(b)
    z = np.zeros((p, 3 * nc))
    for _ in range(max(1, sweeps)):
        rhs = bp - k_apply(z) + np.einsum("pij,pj->pi", B, z)       # own block implicit, others lagged
        z = np.einsum("pij,pj->pi", Ainv, rhs)
        if harmonic is not None:                                     # the inter-pair coupling, per harmonic
            z = z + to_p(harmonic._harmonic_solve(to_c(bp - k_apply(z)).ravel()))
            z = z + np.einsum("pij,pj->pi", Ainv, bp - k_apply(z))
    z = to_c(z)
    dx = z if op._right_inv is None else op._right_inv @ z
    return dx.ravel() if np.all(np.isfinite(dx)) else None


def integrate_pairs(fun, fun_op, x0, *, tol: float = 1e-8, scale: float = 1.0, max_steps: int = 500,
                    dtau0: float = 1.0, dtau_max: float = 1e8, sweeps: int = 1, reject: float = 2.0,
                    window: int = 50, blocks: str = "pairs") -> PseudoTimeResult:
    """Pseudo-time march to R = 0 by matrix-free pair-block Jacobi (module docstring).

    fun(x) -> R; fun_op(x) -> (R, :class:`~workflow.engine.linsolve.ContactJacobian`)
    (:meth:`workflow.engine.hb.HBProblem.residual_operator`). Converged when
    ``‖R‖₂ ≤ tol·scale``; stops after ``max_steps`` accepted steps, or when
    the best ‖R‖ has not dropped 1 % in ``window`` steps ("stalled").
    ``blocks``: "pairs" (pair blocks only) or "pairs+harmonics" (each pair
    sweep followed by the harmonic blocks of K — factored once, at x0, and
    again only after a refused step — and a second pair sweep).
    """
    from workflow.engine.linsolve import StructuredSolve

    if blocks not in ("pairs", "pairs+harmonics"):
        raise ValueError(f"pseudotime.blocks: {blocks!r} is not one of pairs, pairs+harmonics")
    t0 = time.perf_counter()
    x = np.array(x0, dtype=float)
    R, op = fun_op(x)
    nfev = nje = 1
    norm = float(np.linalg.norm(R))
    hist, dts = [norm], []
    best, best_x, best_k = norm, x.copy(), 0
    dtau, rejected, k = float(dtau0), 0, 0
    reason = None
    harm = None
    if blocks == "pairs+harmonics":
        harm = StructuredSolve(single=False)    # a stationary iteration: no flexible Krylov to absorb float32
        harm._factor_blocks(op)
    while reason is None:
        if norm <= tol * scale:
            reason = "converged"
            break
        if k >= max_steps:
            reason = f"max steps: ‖R‖ = {norm:.3g} after {max_steps} steps"
            break
        dx = _step(op, R, dtau, sweeps, harm)
        Rn = fun(x + dx) if dx is not None else None
        nfev += dx is not None
        nn = float(np.linalg.norm(Rn)) if Rn is not None and np.all(np.isfinite(Rn)) else math.inf
        if nn > reject * norm:
            rejected += 1
            dtau *= 0.25
            if harm is not None:
                harm._factor_blocks(op)
            if dtau < 1e-12:
                reason = f"stalled: step refused down to Δτ = {dtau:.3g}"
            continue
        x = x + dx
        R, op = fun_op(x)
        nfev += 1
        nje += 1
        k += 1
        dts.append(dtau)
        prev, norm = norm, float(np.linalg.norm(R))
        hist.append(norm)
        if norm < 0.99 * best:
            best, best_x, best_k = norm, x.copy(), k
        elif k - best_k >= window:
            reason = f"stalled: ‖R‖ did not drop 1 % in {window} steps (best {best:.3g})"
        dtau = min(dtau * max(prev / max(norm, 1e-300), 1.0), dtau_max)
    conv = reason == "converged"
    if not conv and best < norm:
        x, norm = best_x, best
    return PseudoTimeResult(x=x, converged=conv, iterations=k, residual_norm=norm, reason=reason, history=hist,
                            seconds=time.perf_counter() - t0, jacobian_evaluations=nje, function_evaluations=nfev,
                            steps=k, rejected=rejected, dt_history=dts, t_final=float(sum(dts)),
                            scheme="block-jacobi-pairs")
