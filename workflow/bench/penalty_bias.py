"""Issue 47 item 3: the DLFT penalty's bias on a chain of light pads on rigid ground.

``python -m workflow.bench.penalty_bias [--part ref curve nh band rich default] [--out results/bench]``

``--part default`` (alone) runs the engine's default FRF study at Nh = 3, 7, 11 against the
rigid-ground references of an earlier ``--part ref`` in the same ``--out``.

References (independent of the HB code):

* :func:`rigid_steady_state` — event-driven integration of the structure with the pads
  *on rigid ground*: a stuck pad is held (ẋ_p = 0, its contact force whatever holds it),
  a slipping one feels μN·sgn ẋ_p; stick while |holding force| ≤ μN. The exact model the
  HB solves (ε → ∞ is the rigid contact).
* :func:`workflow.verification.timeint.jenkins_steady_state` on the same spec — the
  pads' contact a Jenkins element 10³ × stiffer than the pad springs (slow: the
  contact's own vibration, ~650 cycles a period, is resolved; one point only).

Writes ``results/bench/penalty_bias.json`` and ``penalty_bias.csv``.
"""
from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from workflow.errors import SolverError
from workflow.verification import timeint

RTOL = 1e-11


class _Rigid:
    """Structure (M diagonal on the pad DOFs) + pads on rigid ground, Coulomb stops."""

    def __init__(self, M, C, K, f, omega, pads):
        self.M, self.C, self.K, self.f, self.w, self.P = M, C, K, f, omega, pads
        self.n = K.shape[0]
        self.Minv = np.linalg.inv(M)
        xs = max(float(np.abs(np.linalg.solve(K + np.diag(np.bincount(pads.dof, pads.k, self.n)), f)).max()),
                 1e-300)
        self.xs = xs
        self.atol = 1e-13 * np.concatenate([np.full(self.n, xs), np.full(self.n, xs * omega)])

    def hold(self, t, x, v):
        """Force each pad's contact must exert on it to keep it at rest (ẍ_p = 0)."""
        d = self.P.dof
        return (self.f[d] * np.cos(self.w * t) - (self.K @ x)[d] - (self.C @ v)[d])

    def normal(self, x):
        return self.P.N0 + self.P.cN @ x

    def period(self, z, t_samples=None):
        n, P, T = self.n, self.P, 2 * np.pi / self.w
        d = P.dof
        y = np.array(z, float)
        vs = self.xs * self.w
        v = y[n:]
        stick = np.abs(v[d]) <= 1e-12 * vs
        stick &= np.abs(self.hold(0.0, y[:n], v)) <= P.mu * self.normal(y[:n])
        y[n + d[stick]] = 0.0
        s = np.where(stick, 0.0, np.sign(np.where(stick, 1.0, v[d])))
        leaving = np.zeros(len(d), bool)
        t, out, stuck = 0.0, [], np.zeros(len(d))
        guard = 0
        while t < T * (1 - 1e-14):
            guard += 1
            if guard > 20000:
                raise SolverError("rigid pads: too many events in one period (chattering)")
            # a pad that just left stick slips in the direction of the force that no longer holds it
            for i in np.where(~stick & (s == 0))[0]:
                s[i] = np.sign(self.hold(t, y[:n], y[n:])[i])

            def rhs(tt, yy, stick=stick.copy(), s=s.copy()):
                xx, vv = yy[:n], yy[n:]
                fc = np.zeros(n)
                fc[d] = np.where(stick, 0.0, s * P.mu * self.normal(xx))
                acc = self.Minv @ (self.f * np.cos(self.w * tt) - self.C @ vv - self.K @ xx - fc)
                acc[d[stick]] = 0.0
                vdot = vv.copy()
                vdot[d[stick]] = 0.0
                return np.concatenate([vdot, acc])

            events, who = [], []
            for i in range(len(d)):
                if stick[i]:
                    g = lambda tt, yy, i=i: abs(self.hold(tt, yy[:n], yy[n:])[i]) - P.mu * self.normal(yy[:n])[i]  # noqa: E731
                    g.direction = 1
                else:
                    g = lambda tt, yy, i=i, si=s[i]: si * yy[n + d[i]]  # noqa: E731
                    g.direction = -1
                g.terminal = True
                events.append(g)
                who.append(i)
            sol = solve_ivp(rhs, (t, T), y, method="DOP853", events=events, rtol=RTOL, atol=self.atol,
                            dense_output=True, max_step=T / 64)
            hit = [e for e, te in enumerate(sol.t_events) if te.size]
            t_end = min((sol.t_events[e][0] for e in hit), default=T)
            if t_samples is not None:
                sel = (t_samples >= t) & (t_samples < t_end)
                if sel.any():
                    out.append(sol.sol(t_samples[sel]).T[:, :n])
            stuck += stick * (t_end - t)
            y = sol.sol(t_end) if hit else sol.y[:, -1]
            for e in hit:
                if sol.t_events[e][0] > t_end + 1e-13 * T:
                    continue
                i = who[e]
                if stick[i]:
                    stick[i], s[i] = False, 0.0          # slips next phase in the hold force's direction
                else:
                    y[n + d[i]] = 0.0
                    hf = self.hold(t_end, y[:n], y[n:])[i]
                    if abs(hf) <= P.mu * self.normal(y[:n])[i]:
                        stick[i] = True
                    else:
                        s[i] = np.sign(hf)               # reverses at once
            t = t_end
        return y, (np.concatenate(out) if out else None), stuck / T


def rigid_steady_state(spec, omega: float, *, n_transient: int = 20, max_periods: int = 600):
    """Periodic steady state (:class:`timeint.SteadyState`) of ``spec`` with each pad's contact
    rigid: ``spec.pads.dof`` are the pads' own DOFs (with mass), ``spec.pads.k`` is ignored."""
    sys = _Rigid(np.asarray(spec.M, float), np.asarray(spec.C, float), np.asarray(spec.K, float),
                 np.asarray(spec.f, float), float(omega), spec.pads)
    n = sys.n
    scale = np.concatenate([np.full(n, sys.xs), np.full(n, sys.xs * omega)])
    z, res, periods = timeint._steady(lambda y: sys.period(y)[0], np.zeros(2 * n), scale, n_transient,
                                      max_periods)
    ts = np.arange(timeint.SAMPLES) * 2 * np.pi / omega / timeint.SAMPLES
    _, x, stick = sys.period(z, ts)
    return timeint.SteadyState(t=ts, x=x, first=timeint._first_harmonic(x), stick_fraction=stick, residual=res,
                               periods=periods + 1)


def hb_point(model, law, f_hz: float, nh: int, nit: int, factor: float) -> dict:
    """One HB point through the engine's front door at ``factor`` × ``law``'s penalties
    (the cascade's own ε-path): amplitude, converged, Newton iterations, seconds."""
    from workflow import engine
    from workflow.engine import penalty

    opt = engine.FRFOptions(solver="newton-powell", tol=1e-10, max_iterations=100, max_passes=20,
                            eps_check_factor=0.0)
    t0 = time.perf_counter()
    st = engine.frf(model, penalty.scaled(law, factor), [engine.Variant("hbm", nh, nit)],
                    freqs_hz=np.atleast_1d(f_hz), options=opt)
    r = st.runs[0]
    return {"amplitude": float(r.amplitude[0]), "converged": bool(r.converged[0]),
            "iterations": int(r.iterations[0]), "seconds": time.perf_counter() - t0}


def default_study(model, law, spec, refs: dict, nhs=(3, 7, 11)) -> list[dict]:
    """The engine's default FRF study (default options and nit, every check on) at the reference
    ratios, one row per (Nh, point): the HB amplitude and its error, and at the grid peak the
    Nh-check's Nh → ∞ estimate (:func:`workflow.engine.studies.epscheck.with_nh_limit`) and its
    error — what a user of the defaults reads."""
    from workflow import engine
    from workflow.engine.fourier import default_nit

    ratios = sorted(float(r) for r in refs)
    w1 = spec.omega_n
    rows = []
    for nh in nhs:
        t0 = time.perf_counter()
        st = engine.frf(model, law, [engine.Variant("hbm", nh, default_nit(nh))],
                        freqs_hz=np.array(ratios) * w1 / 2 / np.pi, options=engine.FRFOptions())
        secs = time.perf_counter() - t0
        r = st.runs[0]
        nhrow = next(iter((st.nh_check or {}).get("runs", ())), {})
        for k, ratio in enumerate(ratios):
            ref = refs[str(ratio)]["amp"]
            row = {"Nh": nh, "nit": r.variant.nit, "ratio": ratio, "amplitude": float(r.amplitude[k]),
                   "converged": bool(r.converged[k]), "error": float(r.amplitude[k] / ref - 1.0),
                   "study_seconds": round(secs, 2)}
            if nhrow.get("nh_limit_m") is not None and math.isclose(nhrow["frequency_hz"], float(r.freqs_hz[k])):
                row.update(nh_limit=nhrow["nh_limit_m"], limit_error=nhrow["nh_limit_m"] / ref - 1.0,
                           nh_check_change=nhrow["rel_change"], estimated_error=nhrow["estimated_error"])
            rows.append(row)
            print(row, flush=True)
    return rows


def main(argv=None) -> int:
    from workflow import engine
    from workflow.engine import penalty
    from workflow.verification import models

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", nargs="+", default=["ref", "curve", "nh", "band", "rich"])
    ap.add_argument("--ratios", nargs="+", type=float, default=[0.875, 0.90, 0.925, 0.95])
    ap.add_argument("--out", default="results/bench")
    a = ap.parse_args(argv)
    model, spec = models.light_pad_chain()
    w1 = spec.omega_n
    law = engine.contact_law(model, mu=spec.mu, omega_hz=w1 / 2 / np.pi)
    res = {"model": "light_pad_chain()", "omega1": w1, "eps_t": law.eps_t.tolist()}
    rows = []
    if "default" in a.part:   # the reference amplitudes from a previous --part ref (this file)
        prev = json.loads((Path(a.out) / "penalty_bias.json").read_text())
        res = {**prev, "default": default_study(model, law, spec, prev["ref"])}
        (Path(a.out) / "penalty_bias.json").write_text(json.dumps(res, indent=1))
        return 0
    if "ref" in a.part:
        res["ref"] = {}
        for r in a.ratios:
            t0 = time.perf_counter()
            s = rigid_steady_state(spec, r * w1)
            res["ref"][str(r)] = {"amplitude": float(s.first[spec.observe]), "stick": s.stick_fraction.tolist(),
                                  "periods": s.periods, "seconds": time.perf_counter() - t0}
            print("ref", r, res["ref"][str(r)], flush=True)
    plan = []
    if "curve" in a.part:     # A(ε) at 0.95 ω₁, nit = 2Nh+1, 4(2Nh+1), 16(2Nh+1)
        plan += [(0.95, nh, (2 * nh + 1) * m, fac) for nh in (3, 7) for m in (1, 4, 16)
                 for fac in (1, 3, 10, 30, 100, 1000)]
    if "nh" in a.part:
        plan += [(0.95, nh, 4 * (2 * nh + 1), fac) for nh in (1, 3, 5, 11, 15, 23, 31) for fac in (1, 10, 100)]
    if "band" in a.part:
        plan += [(r, nh, 4 * (2 * nh + 1), fac) for r in a.ratios if r != 0.95 for nh in (3, 7)
                 for fac in (1, 10, 100)]
    if "rich" in a.part:      # the Nh-check's pair at the default penalty: Richardson in 1/Nh
        from workflow.engine.studies.epscheck import finer
        plan += [(r, *nn, 1.0) for r in a.ratios for nh in (3, 7, 11) for nn in ((nh, 4 * (2 * nh + 1)),
                                                                                finer(nh, 4 * (2 * nh + 1)))]
    seen = set()
    plan = [x for x in plan if not (x in seen or seen.add(x))]
    for r, nh, nit, fac in plan:
        row = {"ratio": r, "Nh": nh, "nit": nit, "factor": fac, **hb_point(model, law, r * w1 / 2 / np.pi, nh, nit, fac)}
        ref = res.get("ref", {}).get(str(r))
        row["error"] = None if ref is None else (row["amplitude"] - ref["amplitude"]) / ref["amplitude"]
        rows.append(row)
        print(row, flush=True)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    from workflow.io import write_rows
    write_rows(out / "penalty_bias.csv", rows)
    res["limit"] = {}
    for key in sorted({(x["ratio"], x["Nh"], x["nit"]) for x in rows}):
        sel = [x for x in rows if (x["ratio"], x["Nh"], x["nit"]) == key and x["factor"] in penalty.LIMIT_FACTORS]
        if len(sel) == len(penalty.LIMIT_FACTORS):
            res["limit"]["/".join(map(str, key))] = penalty.eps_limit([x["factor"] for x in sel],
                                                                       [x["amplitude"] for x in sel])
    if "rich" in a.part:
        from workflow.engine.studies.epscheck import finer
        res["nh_limit"] = {}
        for r in a.ratios:
            for nh in (3, 7, 11):
                nn = [(nh, 4 * (2 * nh + 1)), finer(nh, 4 * (2 * nh + 1))]
                v = [next(x["amplitude"] for x in rows if (x["ratio"], x["Nh"], x["nit"], x["factor"]) == (r, *m, 1.0))
                     for m in nn]
                res["nh_limit"][f"{r}/{nh}"] = penalty.nh_limit([m[0] for m in nn], v)
    (out / "penalty_bias.json").write_text(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
