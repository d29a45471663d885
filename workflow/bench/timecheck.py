"""The time-domain check of the headline HB result (issue #47 item 2): its cost against the FRF
study, its agreement, its sensitivity to the step, and that it flags a wrong state.

``python -m workflow.bench.timecheck REDUCED.npz [REDUCED.npz ...] [--mu 0.5] [--nh 7]
[--nit 64] [--points 15] [--steps 128 256] [--out results/bench]``

For each reduced model: the FRF study of the quick scene's HB settings (``engine.frf`` with
its defaults: refined peak, ε-check, Nh-check; wall seconds), the refined peak's harmonics
(re-made with :func:`workflow.engine.studies.peak.refine_peak`, not timed), then
:func:`workflow.engine.timecheck.time_check` at the peak with the study's Nh-check change for
each ``--steps`` (its wall seconds and their share of the study's), once with ``halving``, and
once from the peak state with its harmonics ×1.2 (must be flagged). Writes
``timecheck.json`` (every row, with the per-period trends) and ``timecheck.csv``.

Measured (2026-11-28, two shared cores under a load of 6–8, one BLAS thread), quick sector
(16 pairs, 110 DOFs, peak 212.15 Hz, HBM-7 nit = 64; the tied mode ζ = 0.2 %):

* the first harmonic of the rigid-contact time model at the HB peak against the HB, settled
  by Anderson mixing (settle 2e-8), ρ∞ = 0, prewarped: 64 steps 1.7e-4, 128: 2.8e-4,
  256: 2.1e-3, 512: 5.3e-3, 1024: 7.8e-3, 2048: 7.1e-3 (amplitude 2e-5 … 4.5e-3). The 4 pairs
  that lift off 50–70 % of the period re-close with an impact the rigid model dissipates and
  the HB does not model: converged in the step, the two differ by 0.7 % (0.45 % in amplitude)
  while the HB's Nh-check moves 3e-5 — the reason for ``TOL_FLOOR`` = 1 %;
* ρ∞ = 0.8 instead of 0 (the contact nodes rattle after re-closing): 4e-3 at 128 steps, 1.2 %
  at 256 (not converged in the step);
* without prewarping at 256 steps: +1.4e-4 per period of drift, 1 % when settled (the scheme's
  period error (ωh)²/12 over ζ);
* a compliant penalty instead of rigid contact (``stiffening``): 10× the static stiffness 8.5 %,
  100× 0.5–0.8 % (the tied estimate, ``regularisation``, 6.4e-2 and 6.2e-3);
* without the Anderson mixing the plain march needs ~1/(2πζ) = 80 periods per e-fold; with it
  the HB state settles in 6 periods, the state ×1.2 is flagged after 20.

Cost, this bench (results/bench/timecheck.csv, load ~3): quick sector, study 2.2 s; the check
0.27 s (12 %) at 128 steps, 0.78 s (35 %) at 256, 0.30 s with ``halving``, 0.69 s from the
state ×1.2 (flagged, 9.1 % off). 128 pairs (782 DOFs, nodes_along = nodes_across = 8), study
39.8 s; 4.5 s (11 %), 11.9 s (30 %), 7.2 s (18 %), 13.7 s (flagged, 12 % off); the HB peak
agrees to 3.4e-5 at 128 steps, 1.2e-4 at 256. Before the Woodbury update of the contact
Jacobian (an LU a Newton iteration) the 128-pair check took 15.9 s.
"""
from __future__ import annotations

import argparse
import csv
import io
import json
import time
from pathlib import Path

import numpy as np


def peak_state(model, law, study, variant):
    """The study's refined peak again, with its harmonics (:class:`~workflow.engine.studies.peak.Peak`)."""
    from workflow.engine.condense import relative_coordinates
    from workflow.engine import FRFOptions, penalty
    from workflow.engine.linear import condensed
    from workflow.engine.studies.peak import refine_peak

    rc = relative_coordinates(model)
    opt = FRFOptions()
    run = study.runs[0]
    i = int(np.nanargmax(np.where(run.converged, run.amplitude, np.nan)))
    return refine_peak(rc, run, law, study.static, variant, opt.peak_xtol * float(run.freqs_hz[i]), tol=opt.tol,
                       maxiter=opt.max_iterations, max_passes=opt.max_passes, solver=opt.solver,
                       eps_path=penalty.path_of(law, np.real(condensed(rc, 0.0, 0).Zr[0])))


def bench(path: Path, *, mu: float, nh: int, nit: int, points: int, steps: list) -> list:
    from workflow.engine.model import ReducedModel
    from workflow import engine
    from workflow.engine.blas import blas_threads
    from workflow.engine.timecheck import TimeCheckOptions, time_check

    model = ReducedModel.load(path)
    law = engine.contact_law(model, mu=model.friction(mu)[0])
    v = engine.Variant("hbm", nh, nit)
    t = time.perf_counter()
    study = engine.frf(model, law, [v], points=points)
    study_s = time.perf_counter() - t
    nh_change = study.nh_check.get("max_rel_change")
    with blas_threads(1):
        pk = peak_state(model, law, study, v)
        omega = 2 * np.pi * pk.hz
        base = {"model": str(path), "pairs": int(model.n_pairs), "dofs": int(model.size), "nh": nh, "nit": nit,
                "points": points, "study_s": study_s, "peak_hz": pk.hz, "peak_amplitude_m": pk.amplitude,
                "study_peak_hz": (study.peak or {}).get("hz"), "nh_change": nh_change}
        rows = []
        cases = [(f"steps={n}", pk.Ur, TimeCheckOptions(steps_per_period=n)) for n in steps]
        cases.append(("halving", pk.Ur, TimeCheckOptions(steps_per_period=steps[0], halving=True)))
        bad = pk.Ur.copy()
        bad[1:] *= 1.2
        cases.append(("harmonics x1.2", bad, TimeCheckOptions(steps_per_period=steps[0])))
        for name, Ur, opt in cases:
            tc = time_check(model, law, omega, Ur, nh_change=nh_change, options=opt)
            rows.append({**base, "case": name, **tc.as_dict(), "share_of_study": tc.seconds / study_s})
            print(f"{model.n_pairs} pairs, {name}: {tc.log_line()} [{tc.seconds / study_s:.0%} of the study's "
                  f"{study_s:.1f} s]", flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("reduced", nargs="+", type=Path)
    ap.add_argument("--mu", type=float, default=0.5)
    ap.add_argument("--nh", type=int, default=7)
    ap.add_argument("--nit", type=int, default=64)
    ap.add_argument("--points", type=int, default=15)
    ap.add_argument("--steps", type=int, nargs="+", default=[128, 256])
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    a = ap.parse_args(argv)
    from workflow.io import write_text

    rows = []
    for p in a.reduced:
        rows += bench(p, mu=a.mu, nh=a.nh, nit=a.nit, points=a.points, steps=a.steps)
    a.out.mkdir(parents=True, exist_ok=True)
    write_text(a.out / "timecheck.json", json.dumps(rows, indent=1, default=float) + "\n")
    cols = ["pairs", "dofs", "case", "study_s", "seconds", "share_of_study", "peak_hz", "within_tolerance",
            "max_rel_diff", "amplitude_rel_diff", "periodicity_defect", "hb_defect", "tolerance", "periods",
            "steps_per_period", "newton_iterations", "max_newton", "nh_change", "reason"]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols, extrasaction="ignore")
    w.writeheader()
    w.writerows(rows)
    write_text(a.out / "timecheck.csv", buf.getvalue())
    print(a.out / "timecheck.json", a.out / "timecheck.csv")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
