"""The pseudo-time wear march's linear algebra without (n × n) arrays (issue #16).

A step of :func:`workflow.engine.wear.pseudo_time_wear` solves the augmented system

    [ J          ∂R/∂W        ] [Δx]   [ −R     ]
    [ −h ∂r/∂x   I − h ∂r/∂W  ] [ΔW] = [ h·rate ],

and the dense path factors J (2n³/3 flops) for it. Both couplings are per pair:
∂R/∂W's column i lives on pair i's residual rows (``w_i``, pair i's contact block
times ∂a_i/∂W_i), ∂rate_i/∂x = g_i · ∂a_i/∂x with ``∂a/∂x = diag ε − A``, and
∂rate/∂W is diagonal (``D = I − h diag ∂r/∂W``). Eliminating ΔW,

    ΔW = D⁻¹ (h·rate + h ∂r/∂x Δx),
    (J + h ∂R/∂W D⁻¹ ∂r/∂x) Δx = −R − ∂R/∂W D⁻¹ h·rate,

and since ``J = Rlin + G (diag ε − A)`` with G block-diagonal over pairs, the
matrix on the left is ``Rlin + (G + B)(diag ε − A)`` with the rank-one pair
blocks ``B_i = (h/D_i) w_i g_iᵀ``: the HB Jacobian's own structure
(:class:`workflow.engine.linsolve.ContactJacobian`), solved by the structured GMRES of
Newton (:class:`workflow.engine.linsolve.StructuredSolve`) to its tight tolerance. Each
step length tried is one such solve; the vibration corrections and the
trapezoidal shift are solves with J itself.
"""
from __future__ import annotations

import numpy as np


def use(n: int) -> bool:
    """Whether a march on n HB unknowns runs matrix-free: where Newton's linear solve is the
    structured one (:func:`workflow.engine.cascade.linear_solver`, one switch for both).
    Measured to the worn steady state on the interface-scaling sectors (HBM Nh = 3, nit = 64,
    μ = 0.5, pseudo-time only, ``wear_rtol`` 1e-3, one run each, alone), J formed and
    factored → matrix-free: 16 pairs (336 unknowns) 0.6 → 0.8 s; 32 pairs (672) 4.2 → 2.7 s;
    64 pairs (1344) 12.5 → 4.6 s; 128 pairs (2688) 128.8 → 29.1 s and 0.80 → 0.36 GB; the
    same steps to ±3 % and worn profiles 0.001–0.05 % apart (the march's own path noise at
    this tolerance: 0.04–0.12 %, docs/contact-layout.md)."""
    from workflow.engine.cascade import linear_solver

    return linear_solver(n) == "structured"


def r_w_times(st, v) -> np.ndarray:
    """``∂R/∂W · v`` (n,) for v (p,) [m]: pair i's rows take ``w_i v_i`` (N); a bordered state's
    (a held amplitude, :class:`workflow.engine.studies.amplitude.Border`) has a constraint row
    that W does not enter."""
    p, m = st.w.shape
    out = (st.w * np.asarray(v, dtype=float)[:, None]).reshape(p, m // 3, 3).transpose(1, 0, 2).ravel()
    return out if getattr(st, "border", None) is None else np.append(out, 0.0)


def rate_x_times(wp, st, v, border: bool = True, g=None) -> np.ndarray:
    """``∂q/∂x · v`` (p,) [m/cycle] of the local rates q (before any averaging) for unknowns v
    (n,): g_i · (∂a/∂x v) on pair i's rows (and, if ``border``, ∂rate/∂s · v_s for a bordered
    state's load scale); ``g`` (p, 3nc) another per-pair sensitivity than ``st.g``."""
    b = getattr(st, "border", None)
    v = np.asarray(v, dtype=float)
    da = wp.hb.penalty_apply(v if b is None else v[:-1]).ravel()[wp._rows]          # (p, 3nc)
    out = np.einsum("pa,pa->p", st.g if g is None else g, da)
    return out if b is None or not border else out + b.rate_s * v[-1]


def _factored(wp, G):
    """The problem's structured solve with K = ``wp.hb.operator(G)`` factored, or None if it is
    not finite."""
    lin = wp.linsolver()
    return lin if lin.factor(wp.hb.operator(G)) else None


def _finite(dx):
    return None if dx is None or not np.all(np.isfinite(dx)) else dx


def solve(wp, st, b):
    """``J⁻¹ b`` (n,) with J of the state ``st`` (its blocks G, bordered if ``st.border``: one
    GMRES on the bordered system), or None if GMRES gave nothing finite."""
    lin = _factored(wp, st.G)
    if lin is None:
        return None
    border = getattr(st, "border", None)
    return _finite(lin.solve(-np.asarray(b, dtype=float), border=None if border is None else border.bordered()))


def augmented_step(wp, st, h: float):
    """(Δx, ΔW) of the linearly implicit step (module docstring), or None where a solve failed.
    A bordered state's load scale s enters the wear rate too: ΔW takes ∂rate/∂s Δs, and the
    border's column takes ∂R/∂W D⁻¹ h ∂rate/∂s.

    With a length scale (the rate couples the pairs, :class:`workflow.engine.wear.law.Averaging`)
    the step keeps the averaged rate and the vibration rows exact and takes only each pair's own
    part of the averaged rate's derivatives into the wear rows
    (:meth:`workflow.engine.wear.problem.WearState.own`) — a
    W-method: the step stays consistent (first order, as the linearly implicit step is), its
    error estimate judges it, and the rank-one pair blocks keep the matrix-free solve."""
    g, gw = st.own()
    D = 1.0 - h * gw
    if not np.all(np.abs(D) > 0):
        return None
    hm = h / D
    B = hm[:, None, None] * st.w[:, :, None] * g[:, None, :]
    lin = _factored(wp, st.G + B)
    if lin is None:
        return None
    c = h * st.rate / D
    b = getattr(st, "border", None)
    border = None if b is None else b.bordered(b.R_s + r_w_times(st, h * b.rate_s / D)[:-1])
    dx = _finite(lin.solve(st.R + r_w_times(st, c), border=border))  # (J + B-part) dx = −R − ∂R/∂W c
    if dx is None:
        return None
    return dx, c + hm * rate_x_times(wp, st, dx, border=False, g=g) + (0.0 if b is None else h * b.rate_s * dx[-1] / D)
