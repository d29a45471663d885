"""The reference wear march (paper refs. 5, 7): physical time by blocks of N cycles.

Per block the HB problem is solved at the current W (Newton, warm start), then ``W += N·rate``
(explicit) or ``W⁺ = W + N·rate(x(W⁺), W⁺)`` is solved by Newton on W with the exact
sensitivity ``d rate/dW = ∂rate/∂W − ∂rate/∂x J⁻¹ ∂R/∂W`` (implicit).
"""
from __future__ import annotations

import math
import time

import numpy as np

from workflow.engine.errors import SolverError
from workflow.engine.wear.history import (WearHistory, _close, _hb_ok, _record, _stage_end, _steady_or_persistent,
                                          _wscale, penetration_scale)
from workflow.engine.wear.problem import WearProblem, WearState

#: times the reference march halves a block whose HB solve fails before it stops
MAX_BLOCK_HALVINGS = 4


#: the implicit reference block's wear equation ``W_n = W + N·rate(W_n)`` holds to this
#: fraction of max W when the block is accepted (:func:`_reference_block`)
W_EQ_TOL = 1e-6


def march_reference(wp: WearProblem, x0, *, scheme: str = "explicit", cycles_per_block: float = 1e5,
                    max_blocks: int = 400, steady_tol: float = 1e-3, tol: float = 1e-9,
                    track: int = 1, newton_w_iterations: int = 8, block_tol: float = 0.0,
                    max_cycles: float = math.inf, max_increment: float = math.inf) -> WearHistory:
    """Wear marched in physical time by blocks of N cycles (refs. 5, 7).

    explicit: ``W_{k+1} = W_k + N·rate(x_k, W_k)``;
    implicit: ``W_{k+1} = W_k + N·rate(x(W_{k+1}), W_{k+1})`` by Newton on W
    (Jacobian ``I − N d rate/dW`` along the HB solutions), W never decreasing.
    Each W needs a converged HB solve (Newton, warm start).

    Block size: ``block_tol`` = 0: fixed, N = ``cycles_per_block``;
    ``block_tol`` > 0: adaptive, the block wears at most ``block_tol`` of the
    current W scale, ``N·max rate ≤ block_tol·max(max W, pen)`` (pen: the
    largest normal interpenetration at W = 0, :func:`penetration_scale`), so
    the slow time step resolves the wear dynamics; the profile converges
    (first order) as ``block_tol`` → 0 where the rates decay smoothly. Where
    a pair's rate drops to 0 at a jump, the implicit blocks locate it
    (:func:`_reference_block`): paper-wear's worn steady state is set by such
    jumps, and block_tol = 0.01 and 0.0025 agree to 6.4e-7. Stops at the steady state
    (:func:`_steady_or_persistent`: the wear still to come within ``steady_tol`` of max W) or after
    ``max_blocks`` — or, not steady, after ``max_cycles`` cycles or once the deepest pair has worn
    ``max_increment`` [m] more than at the start (the last blocks shortened to land there: one
    stage of a march whose frequency changes, :func:`_stage_end`).
    """
    if scheme not in ("explicit", "implicit"):
        raise ValueError(f"wear reference scheme {scheme!r}: explicit or implicit")
    t0 = time.perf_counter()
    Nref = float(cycles_per_block)
    W = np.zeros(wp.p) if wp.W is None else wp.W
    res, st = wp.solve_hb(x0, W, tol=tol, dense=True if scheme == "implicit" else None)   # see _reference_block
    solves, nje = 1, res.jacobian_evaluations + 1
    if not res.converged:
        raise SolverError(f"wear reference: HB solve at W = 0 failed: {res.reason}")
    pen = penetration_scale(wp, st)
    x = res.x
    hist = WearHistory(method=f"reference-{scheme}", W=W, x=x, steady=False, seconds=0.0, iterations=0,
                       hb_solves=0, jacobian_evaluations=0, w_scale=pen)
    cyc = 0.0
    _record(hist, wp, cyc, x, W, st.rate, track)
    reason = f"max blocks ({max_blocks})"
    steady = False
    k = 0
    for k in range(1, max_blocks + 1):
        if k > 1 or st.rate.max() == 0:
            steady, why = _steady_or_persistent(hist, Nref, steady_tol)
            if why is not None:
                reason, hist.persistent_slip = why, not steady
                k -= 1
                break
        N = Nref
        if block_tol > 0:
            N = block_tol * _wscale(W, pen) / max(float(st.rate.max()), 1e-300)
        N, end = _stage_end(N, cyc, W - hist.W_history[0], st.rate, max_cycles, max_increment)
        if end:
            reason = end
            break
        res, stn, Wn, N, used = _halved_block(wp, x, W, st, N, scheme, tol, newton_w_iterations)
        solves, nje = solves + used[0], nje + used[1]
        if Wn is None:
            reason, hist.vibration_lost = f"HB solve failed at block {k}, {MAX_BLOCK_HALVINGS} halvings: {res.reason}", True
            break
        W, x, st = np.maximum(Wn, W), res.x, stn
        cyc += N
        _record(hist, wp, cyc, x, W, st.rate, track)
    hist.W, hist.x = W, x
    hist.final_rate = st.rate
    hist.iterations = len(hist.cycles) - 1
    hist.hb_solves, hist.jacobian_evaluations = solves, nje
    _close(hist, steady, reason)
    hist.seconds = time.perf_counter() - t0
    return hist


def _halved_block(wp: WearProblem, x, W, st: WearState, N: float, scheme: str, tol: float, newton_w_iterations: int):
    """One block of :func:`march_reference` of N cycles, halved up to :data:`MAX_BLOCK_HALVINGS`
    times: a block that crosses a contact-state change can leave the HB solver at a kink, and a
    smaller wear step gets past it. (HB result, state, W⁺ or None if every halving failed, the
    block's cycles, (HB solves, Jacobian evaluations))."""
    solves = nje = 0
    for halving in range(MAX_BLOCK_HALVINGS + 1):
        res, stn, Wn, used, w_solved = _reference_block(wp, x, W, st, N, scheme, tol, newton_w_iterations)
        if _hb_ok(wp, res, tol) and not w_solved and halving == MAX_BLOCK_HALVINGS:
            # still no root in the shortest block: a jump of the rate (an event) lies within
            # N·rate; cross it with the explicit step, as the march in physical time would
            solves, nje = solves + used[0], nje + used[1]
            res, stn, Wn, used, w_solved = _reference_block(wp, x, W, st, N, "explicit", tol, 0)
        solves, nje = solves + used[0], nje + used[1]
        if _hb_ok(wp, res, tol) and w_solved:
            return res, stn, Wn, N, (solves, nje)
        N *= 0.5
    return res, stn, None, N, (solves, nje)


def _reference_block(wp, x, W, st, N, scheme, tol, newton_w_iterations):
    """One block of N cycles from wear W: ``(res, state, W_next, (solves, jacobians), solved)``.

    Explicit: ``W + N·rate(W)`` (``solved`` always). Implicit: ``W_n = W + N·rate(W_n)`` by
    Newton on W, each residual an HB solve at the trial wear; ``solved`` says whether that
    equation holds to :data:`W_EQ_TOL` of max W at the end. It may have no root at all: a
    pair whose rate *grows* with its own wear and then drops to 0 when the HB solution
    jumps to a sticking state (paper-wear, 48 pairs, block_tol = 0.01: rate 6.7e-18 →
    9.3e-18 m/cycle over +1 nm of wear, 0 at +10 nm, against N·rate = 18 nm) — a block
    must then be shorter than the way to the jump, not accepted unsolved (it was, and the
    march then sat for 870 blocks at W + 1e-18 m with the same rate, never steady; now it
    ends steady in 157 blocks). :func:`march_reference` halves such a block, and crosses
    the jump with the explicit step if even the shortest block has no root.
    """
    solves = nje = 0
    Wn = W + N * st.rate          # explicit step, or the implicit predictor
    dense = True if scheme == "implicit" else None       # total_rate_jacobian forms J⁻¹∂R/∂W
    res, stn = wp.solve_hb(x, Wn, tol=tol, dense=dense)
    solves, nje = 1, res.jacobian_evaluations + 1
    if scheme == "explicit":
        return res, stn, Wn, (solves, nje), True

    F = Wn - W - N * stn.rate
    for _ in range(newton_w_iterations):
        if _w_solved(F, Wn):
            break
        Jw = np.eye(wp.p) - N * wp.total_rate_jacobian(stn)
        try:
            dW = np.linalg.solve(Jw, -F)
        except np.linalg.LinAlgError:
            dW = -F
        Wn = np.maximum(Wn + dW, W)
        res, stn = wp.solve_hb(res.x, Wn, tol=tol, dense=dense)
        solves += 1
        nje += res.jacobian_evaluations + 1
        F = Wn - W - N * stn.rate
    return res, stn, Wn, (solves, nje), _w_solved(F, Wn)


def _w_solved(F, Wn) -> bool:
    """The implicit block's residual ``F = W_n − W − N·rate(W_n)`` is within :data:`W_EQ_TOL` of max W."""
    return bool(np.max(np.abs(F)) <= W_EQ_TOL * max(float(np.max(Wn)), 1e-300))
