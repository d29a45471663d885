"""Issue #47, item 1: do the product's checks see an HB answer that is off its own floor?

``python -m workflow.bench.branch_check [--harmonics 15 25] [--nit-factors 8] [--betas 10]
[--out results/bench]``

Den Hartog's Coulomb oscillator (m = k = F0 = 1; the answer is dimensionless in β = ω/ω_n):
μN/F0 ∈ {0.2, 0.5, 0.7}, ζ ∈ {0, 0.02}, β ∈ [0.5, 1.5] (``--betas`` points), for each Nh and
nit = 2^⌈log2(factor·(2Nh+1))⌉ (``--nit-factors``; 8 gives nit ≥ 8·(2Nh+1): 256 at Nh = 15, 512
at Nh = 25; 4 is :mod:`workflow.bench.coulomb`'s choice). Each (μN/F0, ζ, Nh, nit) is one sweep
through the engine's front door with the product's defaults — automatic penalty sampled at the
band's centre, the ε-check (×10), the Nh-check (1.5×Nh) and the branch check — on the given
frequencies (so no refined peak: the checks look at the grid peak).

Per point: the HB amplitude, the exact answer (Den Hartog's closed form where valid, else the
event-driven integrator: :func:`workflow.verification.runner.reference`), HB's own floor
(Galerkin HB with the exact sign law at the same Nh, non-stop points), whether the *run* is
flagged the way the headline flags it — amber/red: a point not converged, the Nh-check or the
branch check not within tolerance or not run (the ε-check is the penalty's sensitivity, reported,
not a failed check) — and, beyond the product, the branch check at *that* point
(:func:`workflow.engine.studies.epscheck.branch_point`).

Targets (the digest): every converged non-stop point within 1 % of the Galerkin floor, or its run
flagged; no point more than 2 % from the exact answer beyond the floor in a run reported green.

Writes ``branch_check.csv`` (one row per point) and ``branch_check.json`` (per Nh × nit: counts,
the branch check's cost against the sweep's).
"""
from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

#: |HB − floor| / floor above which a converged non-stop point must be flagged.
FLOOR_TOL = 0.01
#: error against the exact answer beyond the floor's above which a point must not be green.
EXCESS_TOL = 0.02


def nit_of(nh: int, factor: float) -> int:
    """2^⌈log2(factor·(2Nh+1))⌉."""
    return int(2 ** np.ceil(np.log2(factor * (2 * nh + 1))))


def run_flags(study) -> tuple[bool, list[str]]:
    """(flagged, why) of a sweep as the headline colours it: any point not converged, the
    Nh-check or the branch check not within tolerance (or not run)."""
    why = []
    r = study.runs[0]
    if not r.converged.all():
        why.append(f"{int((~r.converged).sum())} points not converged")
    for name, chk in (("Nh-check", study.nh_check), ("branch check", study.branch_check)):
        if chk.get("within_tolerance") is not True:
            why.append(f"{name} {'not run' if chk.get('within_tolerance') is None else 'failed'}")
    return bool(why), why


def sweep_rows(ratio: float, zeta: float, nh: int, nit: int, betas, refs: dict, floor: dict, log=print) -> tuple:
    """Rows of one sweep and its summary {"seconds", "branch_seconds", checks}."""
    from workflow.engine.condense import relative_coordinates
    from workflow import engine
    from workflow.engine import penalty
    from workflow.engine.linear import condensed
    from workflow.engine.studies import epscheck
    from workflow.verification import models

    model, _ = models.coulomb(1.0, 1.0, 2 * zeta, 1.0, 1.0, ratio, name=f"coulomb r={ratio} zeta={zeta}")
    f = np.asarray(betas) / (2 * np.pi)
    law = engine.contact_law(model, mu=ratio, omega_hz=0.5 * float(f.min() + f.max()))
    opt = engine.FRFOptions()
    t0 = time.perf_counter()
    study = engine.frf(model, law, [engine.Variant("hbm", nh, nit)], freqs_hz=f, options=opt)
    sec = time.perf_counter() - t0
    run = study.runs[0]
    flagged, why = run_flags(study)
    rc = relative_coordinates(model)
    opt = replace(opt, eps_path=penalty.path_of(law, np.real(condensed(rc, 0.0, 0).Zr[0])))
    tol = epscheck.branch_tolerance(opt.tol)
    rows = []
    t1 = time.perf_counter()
    for i, b in enumerate(betas):
        ref = refs[(ratio, zeta, float(b))]
        g = floor.get((ratio, zeta, float(b), nh))
        a = float(run.amplitude[i]) if run.converged[i] else None
        row = {"ratio": ratio, "zeta": zeta, "beta": float(b), "Nh": nh, "nit": nit, "frequency_hz": float(f[i]),
               "stops": ref.stops, "exact": ref.amplitude, "exact_source": ref.source, "galerkin": g,
               "hb": a, "converged": bool(run.converged[i]), "how": run.how[i] if i < len(run.how) else ""}
        row["hb_error"] = None if a is None else abs(a - ref.amplitude) / ref.amplitude
        row["floor_error"] = None if g is None else abs(g - ref.amplitude) / ref.amplitude
        row["from_floor"] = None if a is None or g is None else abs(a - g) / g
        row["excess"] = None if row["hb_error"] is None else row["hb_error"] - (row["floor_error"] or 0.0)
        row.update(run_flagged=flagged, run_flags="; ".join(why),
                   nh_check=study.nh_check.get("max_rel_change"), eps_check=study.eps_check.get("max_rel_change"),
                   eps_check_within=study.eps_check.get("within_tolerance"),
                   branch_check=study.branch_check.get("max_rel_diff"),
                   point_independent=None, point_rel_diff=None, point_start="", point_flagged=None)
        if a is not None:
            pt = {"role": "bench point", "label": run.variant.label, "method": "hbm", "nh": nh, "nit": nit,
                  "frequency_hz": float(f[i]), "swept_m": a}
            bp = epscheck.branch_point(rc, law, study.static, pt, opt, tol)
            row.update(point_independent=bp["independent_m"], point_rel_diff=bp["rel_diff"], point_start=bp["start"],
                       point_flagged=bp["rel_diff"] is None or bp["rel_diff"] > tol)
        rows.append(row)
    info = {"ratio": ratio, "zeta": zeta, "Nh": nh, "nit": nit, "seconds": sec,
            "branch_seconds": study.branch_check.get("seconds"), "point_checks_seconds": time.perf_counter() - t1,
            "converged": run.converged_points, "flagged": flagged, "why": why,
            "nh_check": study.nh_check.get("max_rel_change"), "eps_check": study.eps_check.get("max_rel_change"),
            "branch_check": study.branch_check.get("max_rel_diff"),
            "branch_within": study.branch_check.get("within_tolerance")}
    log(f"  r={ratio} ζ={zeta} Nh={nh} nit={nit}: {run.converged_points}/{len(f)} converged, {sec:.1f} s "
        f"(branch check {info['branch_seconds']:.2f} s), {'FLAGGED: ' + '; '.join(why) if flagged else 'green'}")
    return rows, info


def digest(rows: list, infos: list) -> dict:
    """Per Nh × nit: the targets' counts (module docstring)."""
    out = {}
    for key in sorted({(r["Nh"], r["nit"]) for r in rows}):
        sel = [r for r in rows if (r["Nh"], r["nit"]) == key]
        ns = [r for r in sel if r["converged"] and not r["stops"] and r["from_floor"] is not None]
        off = [r for r in ns if r["from_floor"] > FLOOR_TOL]
        wrong_green = [r for r in sel if r["converged"] and r["excess"] is not None and r["excess"] > EXCESS_TOL
                       and not r["run_flagged"]]
        runs = [i for i in infos if (i["Nh"], i["nit"]) == key]
        out[f"Nh={key[0]} nit={key[1]}"] = {
            "points": len(sel), "converged": sum(r["converged"] for r in sel), "nonstop_converged": len(ns),
            "nonstop_within_1pct_of_floor": len(ns) - len(off),
            "nonstop_off_floor": len(off),
            "nonstop_off_floor_flagged": sum(r["run_flagged"] for r in off),
            "nonstop_off_floor_flagged_by_branch_check": sum("branch check failed" in r["run_flags"] for r in off),
            "nonstop_off_floor_not_flagged": len(off) - sum(r["run_flagged"] for r in off),
            "points_flagged_by_run": sum(r["run_flagged"] for r in sel),
            "points_disagreeing_pointwise": sum(bool(r.get("point_flagged")) for r in sel if r["converged"]),
            "excess_over_2pct": sum(r["converged"] and r["excess"] is not None and r["excess"] > EXCESS_TOL
                                    for r in sel),
            "excess_over_2pct_green": len(wrong_green),
            "runs": len(runs), "runs_flagged": sum(i["flagged"] for i in runs),
            "runs_branch_failed": sum(i["branch_within"] is False for i in runs),
            "sweep_seconds": sum(i["seconds"] for i in runs),
            "branch_seconds": sum(i["branch_seconds"] or 0.0 for i in runs),
        }
    return out


def main(argv=None) -> int:
    from workflow.bench.coulomb import RATIOS, ZETAS, galerkin_rows, references
    from workflow.io import write_json, write_rows

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--harmonics", nargs="+", type=int, default=[15, 25])
    ap.add_argument("--nit-factors", nargs="+", type=float, default=[8.0])
    ap.add_argument("--betas", type=int, default=10)
    ap.add_argument("--out", default="results/bench")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    betas = np.linspace(0.5, 1.5, a.betas)
    refs = references(betas)
    floor = {(g["ratio"], g["zeta"], g["beta"], g["Nh"]): g["amplitude"]
             for g in galerkin_rows(betas, a.harmonics, refs) if g["converged"]}
    print(f"references and Galerkin floor: {time.perf_counter() - t0:.1f} s")
    rows, infos = [], []
    for nh in a.harmonics:
        for fac in a.nit_factors:
            nit = nit_of(nh, fac)
            for r in RATIOS:
                for z in ZETAS:
                    got, info = sweep_rows(r, z, nh, nit, betas, refs, floor)
                    rows += got
                    infos.append(info)
    out = Path(a.out)
    write_rows(out / "branch_check.csv", rows)
    dg = digest(rows, infos)
    write_json(out / "branch_check.json", {"seconds": time.perf_counter() - t0, "floor_tol": FLOOR_TOL,
                                           "excess_tol": EXCESS_TOL, "per_nh_nit": dg, "runs": infos})
    for k, v in dg.items():
        print(f"{k}: {v['converged']}/{v['points']} converged; non-stop {v['nonstop_within_1pct_of_floor']}/"
              f"{v['nonstop_converged']} within 1 % of the floor, {v['nonstop_off_floor_flagged']}/"
              f"{v['nonstop_off_floor']} of the others flagged ({v['nonstop_off_floor_flagged_by_branch_check']} by "
              f"the branch check); > 2 % beyond the floor: {v['excess_over_2pct']} points, "
              f"{v['excess_over_2pct_green']} of them green; runs flagged {v['runs_flagged']}/{v['runs']} "
              f"(branch check failed {v['runs_branch_failed']}); branch check {v['branch_seconds']:.1f} s of "
              f"{v['sweep_seconds']:.1f} s")
    print(f"total {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
