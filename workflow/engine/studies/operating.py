"""Where a wear study vibrates: its operating point, and the friction-damped resonance it is
measured against (issue 48 item 1).

At a fixed frequency next to a resonance the wear is ill-conditioned: on the quick sector the
worn depth moves as d ln W / d ln f ≈ −330 at the first tied resonance, so a resonance that one
contact mesh puts 1.7e-4 away from another's moves the worn depth by ~5 %. A frequency tied to
the model's *own* friction-damped resonance (``detuning`` r: f = r · f_r) wears every mesh and
every model at the same place on its own resonance curve; at r = 1 the response is stationary
in frequency (the peak), so a small error in f_r changes the amplitude only to second order.

Two operating points are more than one frequency: the resonance dwell (``"resonance"``, the
excitation follows the peak of the wearing system; the stages are marched by
:func:`workflow.engine.studies.wearstudy.worn_steady_state`, the peak of the worn system found here
by :func:`friction_damped_resonance` with the march's own static state) and the duty cycle
(``"mission"``: :class:`MissionProblem`, one vibration per operating point, the wear rates summed
with the shares of the cycles).
"""
from __future__ import annotations

import math

import numpy as np

from workflow.engine.errors import BundleError, SceneError, SolverError
from workflow.engine.wear.problem import WearProblem, WearState, _newton_parts

OPERATING_POINTS = ("frequency", "detuning", "resonance", "mission")
#: grid of the resonance search: ±10 % around the first tied mode the load excites (the FRF's
#: default band), refined between grid points to 1e-6 of the frequency
RESONANCE_POINTS = 15
#: a mission's shares must sum to 1 within this
SHARE_TOL = 1e-9
#: admissible detunings (f / f_r) of the "detuning" and "mission" operating points
DETUNING_RANGE = (0.5, 2.0)


def friction_damped_resonance(model, law, *, method: str, nh: int, nit: int, tol: float, max_iterations: int,
                              max_passes: int, static=None, what: str = "wear.operating_point = \"detuning\"") -> dict:
    """The friction-damped resonance of ``model`` under ``law`` (its wear, if any, in the gap):
    {"hz", "amplitude_m", "seconds", "Ur"} — the refined peak of an FRF over the default band
    (:func:`workflow.engine.frf`, :data:`RESONANCE_POINTS` points, without its checks: the
    wear study checks its own convergence); ``Ur`` the relative harmonics (Nh+1, 3p) [m] there
    (with ``static`` given, else None).

    ``static``: None — the FRF's own static state, solved with ``law``'s wear in the gap (a worn
    blade assembled afresh: :func:`resonance_shift`'s worn system); or a
    :class:`~workflow.engine.hb.StaticState` whose stick anchor every point keeps (the blade
    that wore in place: the resonance dwell's, whose march keeps the anchor of the new
    assembly). Raises :class:`SceneError` (naming ``what``) when the peak is on the band's edge
    (no resonance inside ±10 % of the tied mode) or the FRF did not converge."""
    import time

    from workflow.engine.studies.variants import Variant, resolved_nit

    t0 = time.perf_counter()
    v = Variant(method, nh, resolved_nit(method, nh, nit))
    if static is None:
        from workflow.engine.studies.study import FRFOptions, frf

        opt = FRFOptions(solver="newton-powell", tol=tol, max_iterations=max_iterations, max_passes=max_passes,
                         eps_check_factor=0.0, reference_check=False, nh_check=False, branch_check=False,
                         time_check=False)
        st = frf(model, law, [v], points=RESONANCE_POINTS, options=opt)
        run, pk = st.runs[0], st.peak
        Ur = None
    else:
        run, pk, Ur = _peak_with_static(model, law, static, v, tol=tol, max_iterations=max_iterations,
                                        max_passes=max_passes)
    ok = np.flatnonzero(run.converged)
    if pk is None or ok.size == 0:
        raise SceneError(f"{what}: the friction-damped FRF around the first tied mode did not converge, so its "
                         "resonance is unknown; use wear.operating_point = \"frequency\"")
    i = int(np.argmax(np.where(run.converged, run.amplitude, -np.inf)))
    if i in (0, len(run.freqs_hz) - 1):
        raise SceneError(f"{what}: the friction-damped peak is on the edge of the band "
                         f"{run.freqs_hz[0]:.4g}–{run.freqs_hz[-1]:.4g} Hz (no resonance within ±10 % of the tied "
                         "mode); use wear.operating_point = \"frequency\"")
    return {"hz": float(pk["hz"]), "amplitude_m": float(pk["amplitude_m"]), "seconds": time.perf_counter() - t0,
            "Ur": Ur}


def _peak_with_static(model, law, static, v, *, tol: float, max_iterations: int, max_passes: int):
    """(sweep, peak {"hz", "amplitude_m"} or None, Ur at the peak) of :func:`friction_damped_resonance`
    with a given static state: the FRF's grid sweep and peak refinement
    (:func:`workflow.engine.studies.frf.sweep_variant`, :func:`workflow.engine.studies.peak.refine_peak`)
    on the same band, points and tolerances, every point keeping ``static``'s stick anchor."""
    from workflow.engine.condense import relative_coordinates
    from workflow.engine import penalty
    from workflow.engine.linear import band, condensed, first_excited_mode
    from workflow.engine.studies.frf import sweep_variant
    from workflow.engine.studies.peak import refine_peak
    from workflow.engine.studies.study import PEAK_XTOL

    rc = relative_coordinates(model)
    f0, f1 = band(0.0, 0.0, first_excited_mode(rc)[0])
    freqs = np.linspace(f0, f1, RESONANCE_POINTS)
    cond = [condensed(rc, 2 * np.pi * f, v.nh) for f in freqs]
    kw = dict(solver="newton-powell", tol=tol, maxiter=max_iterations, max_passes=max_passes,
              eps_path=penalty.path_of(law, np.real(cond[0].Zr[0])))
    run = sweep_variant(rc, cond, law, static, v, **kw)
    if not run.converged.any():
        return run, None, None
    i = int(np.argmax(np.where(run.converged, run.amplitude, -np.inf)))
    pk = refine_peak(rc, run, law, static, v, PEAK_XTOL * float(freqs[i]), **kw)
    return run, {"hz": pk.hz, "amplitude_m": pk.amplitude}, pk.Ur


def mission_points(mission) -> list[tuple[float, float]]:
    """The duty cycle ``wear.mission`` as [(r, share)]: r = f / f_r (f_r the new model's
    friction-damped resonance) within :data:`DETUNING_RANGE`, shares ≥ 0 of the cycles summing
    to 1 within :data:`SHARE_TOL`; :class:`SceneError` naming ``wear.mission`` otherwise."""
    pts = list(mission or ())
    if not pts:
        raise SceneError("wear.mission is empty: with wear.operating_point = \"mission\" give the duty cycle, "
                         "e.g. wear.mission = [[1.0, 0.2], [0.98, 0.8]] ([f / f_r, share of the cycles] each)")
    out = []
    for k, item in enumerate(pts):
        pair = list(item) if isinstance(item, (list, tuple, np.ndarray)) else None
        if (pair is None or len(pair) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in pair)):
            raise SceneError(f"wear.mission[{k}] = {item!r}: each point is [f / f_r, share of the cycles], two numbers")
        r, s = float(pair[0]), float(pair[1])
        if not (math.isfinite(r) and DETUNING_RANGE[0] <= r <= DETUNING_RANGE[1]):
            raise SceneError(f"wear.mission[{k}]: f / f_r = {r:g} is outside {DETUNING_RANGE[0]:g}–"
                             f"{DETUNING_RANGE[1]:g} (f = f / f_r × the friction-damped resonance)")
        if not (math.isfinite(s) and s >= 0.0):
            raise SceneError(f"wear.mission[{k}]: share {s:g} must be ≥ 0 (a fraction of the cycles)")
        out.append((r, s))
    total = math.fsum(s for _, s in out)
    if abs(total - 1.0) > SHARE_TOL:
        raise SceneError(f"wear.mission: the shares sum to {total:.12g}, not 1 (within {SHARE_TOL:g}): they are the "
                         "fractions of the cycles spent at each point")
    if not any(s > 0 for _, s in out):
        raise SceneError("wear.mission: every share is 0")
    return out


def operating_frequency(model, law, opt) -> tuple[float, dict]:
    """(f [Hz] or 0 for the first tied resonance, description) of a wear study's operating point
    (``opt``: :class:`~workflow.engine.studies.wearstudy.WearOptions`). For "resonance" f is where
    the dwell starts (the new model's friction-damped resonance); for "mission" the frequency of
    its point with the largest share (the first of those), every point's in ``points``."""
    kind = opt.operating_point
    if kind not in OPERATING_POINTS:
        raise SceneError(f"wear.operating_point: {kind!r} is not one of {', '.join(OPERATING_POINTS)}")
    if kind == "frequency":
        return float(opt.frequency_hz), {"kind": kind, "frequency_hz": float(opt.frequency_hz) or None}
    pts = mission_points(opt.mission) if kind == "mission" else None
    if kind == "detuning" and not DETUNING_RANGE[0] <= opt.detuning <= DETUNING_RANGE[1]:
        raise SceneError(f"wear.detuning = {opt.detuning:g} is outside 0.5–2 (f = detuning × the friction-damped "
                         "resonance)")
    res = friction_damped_resonance(model, law, method=opt.method, nh=opt.nh, nit=opt.nit, tol=opt.tol,
                                    max_iterations=opt.max_iterations, max_passes=opt.max_passes,
                                    what=f"wear.operating_point = \"{kind}\"")
    common = {"resonance_hz": res["hz"], "resonance_amplitude_m": res["amplitude_m"], "seconds": res["seconds"]}
    if kind == "detuning":
        f = opt.detuning * res["hz"]
        return f, {"kind": kind, "detuning": float(opt.detuning), **common, "frequency_hz": f}
    if kind == "resonance":
        return res["hz"], {"kind": kind, **common, "frequency_hz": res["hz"]}
    head = max(range(len(pts)), key=lambda k: (pts[k][1], -k))
    points = [{"detuning": r, "share": s, "frequency_hz": r * res["hz"]} for r, s in pts]
    return points[head]["frequency_hz"], {"kind": kind, **common, "points": points, "headline": head,
                                          "frequency_hz": points[head]["frequency_hz"]}


def resonance_shift(model, law, W, opt, new: dict | None = None) -> dict:
    """Worn − new friction-damped resonance: {"new_hz", "worn_hz", "hz", "rel", "amplitude_rel",
    "seconds"} with the worn depth W (p,) [m] in the gap (``law.with_wear``), both at the wear
    study's Nh and nit, each model assembled afresh (:func:`friction_damped_resonance` with its
    own static state). ``new``: the unworn resonance if already found (the detuning's). Where
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
                "reason": str(exc).split(": ", 1)[-1] if str(exc).startswith("wear.operating_point") else str(exc)}
    return {"new_hz": new["hz"], "worn_hz": worn["hz"], "hz": worn["hz"] - new["hz"],
            "rel": worn["hz"] / new["hz"] - 1.0, "amplitude_rel": worn["amplitude_m"] / new["amplitude_m"] - 1.0,
            "new_amplitude_m": new["amplitude_m"], "worn_amplitude_m": worn["amplitude_m"],
            "seconds": worn["seconds"] + new.get("seconds", 0.0)}


# ------------------------------------------------------------------ mission

class MissionState(WearState):
    """A :class:`~workflow.engine.wear.WearState` of a :class:`MissionProblem`: the stacked residual,
    the summed rate and their derivatives, with ``members`` the states of its operating points.
    ``newton_parts`` is made from the members' own (one factorisation per point, not one of the
    stacked block-diagonal J) when first read."""

    def __init__(self, members, shares, **kw):
        super().__init__(**kw)
        self.members = members
        self._shares = shares

    @property
    def newton_parts(self):
        if self._parts is None and self.J is not None:
            self._parts = self._member_parts()
        return self._parts

    @newton_parts.setter
    def newton_parts(self, value):
        self._parts = value

    def _member_parts(self):
        """(y0, Y, g0, GY, LU) of :func:`workflow.engine.wear.problem._newton_parts` from each point's: J is
        block-diagonal, so J⁻¹ acts point by point, ∂rate/∂x·J⁻¹ sums the points' with the shares,
        and the points' LU factors side by side are the stacked J's (pivots within each block);
        False if any point's J is singular."""
        parts = [_newton_parts(m) for m in self.members]
        if any(q is None for q in parts):
            return False
        if len(parts) == 1:
            y0, Y, g0, GY, lu = parts[0]
            s = self._shares[0]
            return y0, Y, s * g0, s * GY, lu
        import scipy.linalg

        off = np.cumsum([0] + [q[0].size for q in parts[:-1]])
        lu = (scipy.linalg.block_diag(*[q[4][0] for q in parts]),
              np.concatenate([q[4][1] + o for q, o in zip(parts, off)]))
        return (np.concatenate([q[0] for q in parts]), np.vstack([q[1] for q in parts]),
                sum(s * q[2] for s, q in zip(self._shares, parts)), sum(s * q[3] for s, q in zip(self._shares, parts)),
                lu)


class _MissionHB:
    """What the wear marches read of a problem's ``hb`` (:mod:`workflow.engine.wear`), for a
    :class:`MissionProblem`: the headline point's static stiffness ``Zr`` (harmonic 0, the same at
    every frequency), law and sizes, its harmonics of the stacked unknowns (the tracked first
    harmonic), and the smallest residual scale of the points (a test on the stacked residual
    against it holds for each point)."""

    def __init__(self, mission):
        self._m = mission
        head = mission.members[mission.headline].hb
        self.Zr, self.p, self.nh, self.nit, self.method = head.Zr, head.p, head.nh, head.nit, head.method
        self.n = mission.n

    @property
    def law(self):
        return self._m.members[self._m.headline].hb.law

    def harmonics(self, x):
        m = self._m
        return m.members[m.headline].hb.harmonics(m.split(x)[m.headline])

    def residual_scale(self) -> float:
        return min(w.hb.residual_scale() for w in self._m.members)


class MissionProblem:
    """Fretting wear under a duty cycle (``operating_point = "mission"``): one
    :class:`~workflow.engine.wear.WearProblem` per operating point (``members``, each its own
    frequency ``omegas`` [rad/s] and vibration x_k), all worn by the same W, whose wear rate is
    the share-weighted sum ``Σ_k s_k rate_k(x_k; W)`` [m/cycle] — a cycle of the mission spends
    the fraction s_k of its cycles at point k (Σ s_k = 1). The marches of
    :mod:`workflow.engine.wear` take it for one problem with the stacked unknowns
    ``x = [x_1; …; x_K]``: the residual stacks the points', its Jacobian is block-diagonal, ∂R/∂W
    stacks, ∂rate/∂x = [s_1 ∂rate_1/∂x_1, …] and ∂rate/∂W = Σ s_k ∂rate_k/∂W. J is formed
    (``structured`` False: the matrix-free step assumes one vibration); one point with share 1 is
    its WearProblem exactly. ``headline``: the point the history's tracked harmonic and
    ``hb.law`` belong to."""

    structured = False

    def __init__(self, members, shares, omegas, headline: int = 0):
        self.members = list(members)
        self.shares = np.asarray(shares, dtype=float)
        self.omegas = np.asarray(omegas, dtype=float)
        self.headline = int(headline)
        for m in self.members:
            m.structured = False        # the stacked J is formed: so is each point's
        first = self.members[0]
        self.p, self.area, self.k_w, self.share = first.p, first.area, first.k_w, first.share
        self.averaging, self.eps_path = first.averaging, first.eps_path
        self.sizes = [m.n for m in self.members]
        self.n = int(sum(self.sizes))
        self._cuts = np.cumsum(self.sizes)[:-1]
        self.hb = _MissionHB(self)
        self.evaluations = 0

    def split(self, x) -> list:
        """The points' unknowns of the stacked x."""
        return np.split(np.asarray(x, dtype=float), self._cuts)

    @property
    def W(self) -> np.ndarray:
        return self.members[0].W

    def set_wear(self, W) -> None:
        for m in self.members:
            m.set_wear(W)

    def _combine(self, states, jacobian: bool) -> MissionState:
        import scipy.linalg

        s = self.shares
        head = states[self.headline]
        st = MissionState(states, s, R=np.concatenate([q.R for q in states]),
                          rate=sum(w * q.rate for w, q in zip(s, states)), lam=head.lam, slip=head.slip)
        if jacobian:
            st.J = states[0].J.copy() if len(states) == 1 else scipy.linalg.block_diag(*[q.J for q in states])
            st.R_W = np.vstack([q.R_W for q in states])
            st.G_x = np.hstack([w * q.G_x for w, q in zip(s, states)])
            st.G_W = sum(w * q.G_W for w, q in zip(s, states))
        return st

    def evaluate(self, x, W=None, jacobian: bool = False, dense: bool | None = None) -> MissionState:
        """Every point's :meth:`WearProblem.evaluate` at its part of x and the common W, combined
        (the derivatives always formed)."""
        if W is not None:
            self.set_wear(W)
        self.evaluations += 1
        return self._combine([m.evaluate(xk, jacobian=jacobian, dense=True)
                              for m, xk in zip(self.members, self.split(x))], jacobian)

    def solve_hb(self, x0, W, *, tol, maxiter=50, dense: bool | None = None) -> tuple:
        """Every point's vibration at W (:meth:`WearProblem.solve_hb`, warm start from its part of
        x0): (a SolveResult of the stacked x — converged when every point is, the residual norm
        that of the stacked residual —, MissionState)."""
        from workflow.engine.solvers import SolveResult

        self.set_wear(W)
        out = [m.solve_hb(xk, W, tol=tol, maxiter=maxiter, dense=True) for m, xk in zip(self.members, self.split(x0))]
        res = [r for r, _ in out]
        bad = next((f"point {k}: {r.reason}" for k, r in enumerate(res) if not r.converged), None)
        solved = SolveResult(x=np.concatenate([r.x for r in res]), converged=bad is None,
                             iterations=sum(r.iterations for r in res),
                             residual_norm=math.hypot(*[r.residual_norm for r in res]),
                             reason=res[0].reason if bad is None else bad,
                             seconds=sum(r.seconds for r in res),
                             jacobian_evaluations=sum(r.jacobian_evaluations for r in res),
                             function_evaluations=sum(r.function_evaluations for r in res))
        return solved, self._combine([q for _, q in out], True)

    total_rate_jacobian = WearProblem.total_rate_jacobian
