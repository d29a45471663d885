"""A wear march's path (:class:`WearHistory`) and when it has reached the worn steady state.

Both marches stop when the wear still to come, extrapolated from the decay of the largest rate
(:func:`remaining_wear`), is at most ``steady_tol·max W``; a march whose rate keeps growing has
no worn steady state (persistent slip).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from workflow.engine.wear.problem import WearProblem, WearState

#: The first sign of persistent slip (:func:`_trend`): max W still growing as t^γ, γ ≥ this, over
#: the last decade of cycles; constant-rate wear has γ = 1.
PERSISTENT_GROWTH = 0.5
#: … at a steady pace: the mean rate over the decade's later half within these shares of that
#: over its earlier half (:func:`_pace`; constant-rate wear gives 1, t^γ 10^((γ−1)/2): within
#: the band for 0.81 ≤ γ ≤ 1.19; a jump in progress or ended, an acceleration or a decay, outside)
PERSISTENT_RATE = (0.8, 1.25)


PERSISTENT = ": persistent slip, no worn steady state"


#: How a pseudo-time march that lost the vibration says so (:func:`_resolve_vibration`).
UNSOLVABLE = "vibration not solvable at the reached wear"


#: How a march stopped by its ``max_cycles`` or ``max_increment`` says so: one stage of a march
#: whose frequency changes between stages (:mod:`workflow.engine.studies.operating`: the
#: resonance dwell), not a verdict on the wear.
STAGE_END = "end of stage"


#: A stage's wear budget counts as spent when less than this fraction of it is left (the last
#: steps are shortened to land on it, :func:`_stage_end`).
STAGE_SLACK = 0.05


@dataclass
class WearHistory:
    """Result of a wear computation (either method).

    W             final wear depth (p,) [m]
    x             final HB unknowns
    steady        every rate within tolerance at the end
    seconds       wall time; iterations: blocks (reference) or pseudo-time steps
    hb_solves     Newton solves (reference) / Jacobian evaluations (pseudo-time)
    cycles        (k,) physical cycles (reference) or pseudo-time in cycles
    max_wear      (k,) max W [m] at each iteration (Fig. 11)
    max_rate      (k,) largest wear rate [m/cycle] at each iteration
    harmonic1     (k,) |first harmonic| of the tracked tangential DOF [m] (Fig. 12)
    W_history     (k, p) W at each iteration
    reason        why it stopped
    persistent_slip  stopped because the wear settled into a constant pace (:func:`_trend`):
                  no worn steady state at this load
    vibration_lost   stopped because no periodic vibration was found at the reached wear
                  (the whole solver cascade failed); ``finer_nh``: the same wear re-solved at
                  1.5×Nh by :func:`workflow.engine.studies.wearstudy.finer_nh_resolve` (nh, nit,
                  converged, iterations), which tells a truncation artefact from the physics
    """

    method: str
    W: np.ndarray
    x: np.ndarray
    steady: bool
    seconds: float
    iterations: int
    hb_solves: int
    jacobian_evaluations: int
    cycles: list = field(default_factory=list)
    max_wear: list = field(default_factory=list)
    max_rate: list = field(default_factory=list)
    harmonic1: list = field(default_factory=list)
    W_history: list = field(default_factory=list)
    final_rate: np.ndarray | None = None
    reason: str = ""
    persistent_slip: bool = False
    vibration_lost: bool = False
    finer_nh: dict | None = None
    #: the W scale of the dynamics [m] (:func:`penetration_scale` at the march's start): the
    #: least growth of max W over a decade that :func:`_trend` calls persistent (0: any)
    w_scale: float = 0.0

    def summary(self) -> dict:
        return {"seconds": self.seconds, "iterations": self.iterations, "max_wear_m": float(np.max(self.W)),
                "steady": bool(self.steady), "hb_solves": self.hb_solves,
                "jacobian_evaluations": self.jacobian_evaluations,
                "cycles": float(self.cycles[-1]) if self.cycles else 0.0, "reason": self.reason,
                "persistent_slip": bool(self.persistent_slip), "vibration_lost": bool(self.vibration_lost),
                **({"finer_nh": self.finer_nh} if self.finer_nh is not None else {})}


def remaining_wear(hist: WearHistory) -> float:
    """Wear [m] the most-wearing pair has still to gain, extrapolated from the decay of the
    largest rate over the last doubling of the path's time t (cycles): locally
    ``r(t') = r·(t'/t)^−α``, so ``∫_t^∞ r = r·t/(α − 1)`` for α > 1, and ∞ for a rate that
    decays no faster than 1/t (no finite limit in sight). 0 once every rate is 0.

    For an exponential decay (time constant τ) this gives 2 ln 2·r·τ·t/(t − 2τ ln 2), 1.6×
    the true remainder at t = 10τ and 1.4× as t/τ → ∞: it errs on the side of marching
    on. Measured on the contact-convergence dovetail (0.5 N, 16…80 pairs): the max rate decays as t^−0.8 … t^−1.5 for
    decades of t, so a test on the rate alone (N·r ≤ tol·max W, before this function)
    stopped at 1e8 cycles with max W 20–60 % short of its limit."""
    c, r = hist.cycles, hist.max_rate
    if not r or r[-1] == 0.0:
        return 0.0
    t = c[-1]
    j = int(np.searchsorted(c, 0.5 * t, side="right")) - 1
    if j < 0 or c[j] <= 0.0 or r[j] <= 0.0:
        return math.inf
    alpha = math.log(r[j] / r[-1]) / math.log(t / c[j])
    return r[-1] * t / (alpha - 1.0) if alpha > 1.0 else math.inf


def _decade(hist: WearHistory):
    """(c, W) [cycles, m]: the path's worn points (c > 0, max W > 0) over its last decade of time
    (from its first worn point, if that is later and at least a doubling back); None on a
    shorter path."""
    c, w = np.asarray(hist.cycles, float), np.asarray(hist.max_wear, float)
    ok = (c > 0) & (w > 0)
    if ok.sum() < 2:
        return None
    c, w = c[ok], w[ok]
    j = max(int(np.searchsorted(c, 0.1 * c[-1], side="right")) - 1, 0)
    if c[-1] < 2.0 * c[j]:
        return None
    return c[j:], w[j:]


def _pace(c, w) -> float | None:
    """The mean rate of max W over the later half of the decade (c, w) [cycles, m], split at
    the recorded point nearest its middle in log time, over that of the earlier half; None
    without a point inside. Constant-rate wear gives 1, t^γ split at the middle 10^((γ−1)/2)."""
    if c.size < 3:
        return None
    k = 1 + int(np.argmin(np.abs(np.log(c[1:-1] / math.sqrt(c[0] * c[-1])))))
    early = (w[k] - w[0]) / (c[k] - c[0])
    return (w[-1] - w[k]) / (c[-1] - c[k]) / early if early > 0 else None


def _trend(hist: WearHistory) -> tuple[bool, str]:
    """(persistent, text): has the wear settled into growing without relieving the contact?
    Archard under persistent slip wears at a constant rate (the flanks sink as a body, the
    contact forces do not change): max W grows as t^γ, γ = 1, and no worn steady state. Three
    things are asked of the last decade of cycles:

    * γ ≥ :data:`PERSISTENT_GROWTH` (a rate decaying as t^−α gives γ = 1 − α; measured on the
      quick sector (0.5 N) 0.16–0.22 along the path);
    * the wear goes on at a steady pace: the mean rate over the decade's later half within
      :data:`PERSISTENT_RATE` × that over its earlier half (:func:`_pace`). Wear that
      accelerates is the vibration still growing with it, not a state it has settled in, and a
      jump is a transient, in progress or ended. Measured on the quick sector at 0.998 f_r: max
      W went 1.6 → 11.4 µm between 2.5e8 and 2.9e8 cycles, the largest rate up ~900× and back
      (the resonance dragged through the excitation); called persistent on γ alone (0.94), it
      reaches its worn steady state, 11.7 µm, when marched on.
    * max W has grown over the decade by at least the W scale of the dynamics (``hist.w_scale``,
      :func:`penetration_scale`), the wear that unloads a pair through the structure's own
      stiffness: less cannot have relieved a contact yet, and a constant pace then is the slow
      start of a relief, not its absence (quick sector at 0.99 and 1.005 f_r: t^1.15 and t^1.07
      at a steady pace at 0.08 and 0.49 µm, the scale ~2.5 µm; marched on, steady at 0.15 and
      0.55 µm).

    A phase where the rate rises again while W grows little over the decade
    (contact-convergence dovetail, 42 pairs, 4e9 cycles: γ = 0.16) is not persistent slip — the
    reason this reads W over a decade and not the rate now."""
    d = _decade(hist)
    if d is None:
        return False, ""
    c, w = d
    g = math.log(w[-1] / w[0]) / math.log(c[-1] / c[0])
    text = f"max W grows as t^{g:.2f} over the last decade of cycles"
    if g < PERSISTENT_GROWTH or w[-1] - w[0] < hist.w_scale:
        return False, text
    pace = _pace(c, w)
    if pace is None:
        return False, text
    text += f", {pace:.2g} × as fast in its later half"
    low, high = PERSISTENT_RATE
    return (True, text + PERSISTENT) if low <= pace <= high else (False, text)


def _steady_or_persistent(hist: WearHistory, cycles_per_block, steady_tol) -> tuple[bool, str | None]:
    """(steady, stop reason or None) after the path's last point: steady when the wear
    still to come (:func:`remaining_wear`) is at most ``steady_tol``·max W; stopped, not
    steady, when past the horizon of ``cycles_per_block/steady_tol`` cycles the wear shows
    persistent slip (:func:`_trend`)."""
    if remaining_wear(hist) <= steady_tol * (hist.max_wear[-1] if hist.max_wear else 0.0):
        return True, "steady"
    if hist.cycles[-1] >= cycles_per_block / steady_tol:
        persistent, text = _trend(hist)
        if persistent:
            return False, text
    return False, None


def _close(hist: WearHistory, steady: bool, reason: str) -> None:
    """``hist.steady`` and ``hist.reason`` at the end of a march; one stopped short of the
    steady state (steps or blocks spent) says how its wear was still growing
    (:func:`_trend`) and is flagged ``persistent_slip`` if it grew as under persistent slip."""
    hist.steady, hist.reason = steady, reason
    if not (steady or hist.persistent_slip or reason.startswith(STAGE_END)):
        hist.persistent_slip, text = _trend(hist)
        hist.reason = "; ".join(filter(None, (reason, text)))


def _h1(wp: WearProblem, x, track: int) -> float:
    """|U_1| of relative DOF ``track`` (pair-major index 3i + c) [m]."""
    return float(np.abs(wp.hb.harmonics(x)[1, track])) if wp.hb.nh >= 1 else 0.0


def penetration_scale(wp: WearProblem, st: WearState) -> float:
    """Largest ``−⟨λ_N⟩ / k_N`` [m] over the pairs, with k_N each pair's static condensed
    normal stiffness (:func:`workflow.engine.penalty.reference_stiffness`): the W scale
    of the dynamics.

    A wear depth of that order unloads a pair through the structure's own
    stiffness, so it is the natural absolute scale of W for the step controls
    (W starts at 0, where a purely relative control is undefined). It used to
    be ``−⟨λ_N⟩/ε_N`` — the penalty's interpenetration, which shrank 1000× when
    ε became 10³× the stiffness and made the reference march take thousands of
    blocks to leave W ≈ 0 (paper-wear: not steady after 1000 blocks).
    """
    from workflow.engine.penalty import reference_stiffness

    k_n = reference_stiffness(np.real(wp.hb.Zr[0]))[:, 0]
    pen = np.maximum(-np.mean(st.lam[..., 0], axis=0), 0.0) / k_n
    return max(float(np.max(pen)) if pen.size else 0.0, 1e-300)


def _wscale(W, pen) -> float:
    return max(float(np.max(W)) if W.size else 0.0, pen)


def _stage_end(h: float, t: float, dW, rate, max_cycles: float, max_increment: float) -> tuple[float, str]:
    """(step or block h [cycles] shortened to land on the stage's end, "" or why the stage ends
    here): at ``t`` cycles into the stage with the deepest pair ``max(dW)`` [m] deeper than at its
    start, the stage ends at ``max_cycles`` or, within :data:`STAGE_SLACK`, at ``max_increment``;
    a step wears about h·max rate, so h ≤ (what is left) / max rate lands near it."""
    if t >= max_cycles * (1.0 - 1e-12):
        return h, f"{STAGE_END} ({max_cycles:.4g} cycles)"
    left = max_increment - (float(np.max(dW)) if np.size(dW) else 0.0)
    if math.isfinite(max_increment) and left <= STAGE_SLACK * max_increment:
        return h, f"{STAGE_END} (wear +{max_increment:.3g} m)"
    top = float(np.max(rate)) if np.size(rate) else 0.0
    return min(h, max_cycles - t, left / top if top > 0 else math.inf), ""


def _hb_ok(wp, res, tol) -> bool:
    """A block's HB solve is usable: converged, or stopped within 10³ × ``tol`` (scaled residual)."""
    return bool(res.converged or (np.isfinite(res.residual_norm)
                                  and res.residual_norm <= 1e3 * tol * wp.hb.residual_scale()))


def _record(hist: WearHistory, wp: WearProblem, cycles: float, x, W, rate, track: int) -> None:
    """Append one point of the wear path to ``hist``: cycles, max W [m], max rate [m/cycle],
    tracked first harmonic [m], W."""
    hist.cycles.append(cycles)
    hist.max_wear.append(float(W.max()))
    hist.max_rate.append(float(np.max(rate)) if np.size(rate) else 0.0)
    hist.harmonic1.append(_h1(wp, x, track))
    hist.W_history.append(W.copy())
