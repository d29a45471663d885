"""Floquet stability of HB solutions: errors against shooting and cost against the HB solve (issue #49).

``python -m workflow.bench.stability --out DIR [--quick PATH] [--big PATH] [--points 9]``

1. Jenkins oscillators (:func:`workflow.verification.models.jenkins`, 1 DOF, pad k_d = 1, μN0 =
   0.15, with and without normal-load coupling) solved by the engine: the largest multiplier
   of :func:`workflow.engine.stability.hill_stability` (monodromy with anchors, the default;
   the memoryless tangent; Hill's method with anchors at 8 and 16 harmonics) against event-driven
   shooting (:func:`workflow.verification.floquet.jenkins_monodromy`), and its change with nit
   and ε.
2. The quick sector (16 pairs, ``--quick``): ``points`` frequencies through the first tied
   resonance, HBM-3 nit=64 solved by :func:`workflow.engine.solve_point` from the previous
   point; per point the solve's seconds and the stability's (full δq, and on the Ritz basis
   of the modes below 6ω), the largest multiplier and its change nit → 2·nit.
3. A 128-pair sector (``--big``, a reduced.npz) the same, if given.
4. An FRF with stability (``--frf``, a reduced.npz, e.g. the 128-pair sector): ``engine.frf`` of
   ``--frf-points`` points through the first tied resonance (HBM-3, nit = 64, no checks), then
   :func:`workflow.engine.studies.sweepstability.sweep_stability` on its points with the sweep's
   condensations (as ``engine.frf(..., stability=True)`` hands them over), both timed in
   the same run: the sweep's seconds, the stability's, their ratio (issue #49: ≤ 25 %) and per
   point |μ|max; with ``--frf-compare`` also |μ|max at 2048 samples, switches cut into 64,
   2 substeps, one Richardson halving (the settings before 2026-11-29) and at nit = 8192.

Output: ``stability.json`` (every row) and ``stability.md`` (the summary). One BLAS thread.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def jenkins_rows() -> list:
    from workflow.engine.condense import relative_coordinates
    from workflow import engine
    from workflow.engine import stability
    from workflow.engine.hb import HBProblem
    from workflow.engine.linear import condensed
    from workflow.verification import floquet, models
    from workflow.verification.timeint import Pads

    rows = []
    for omega, cN in ((1.3, 0.0), (1.2, 0.1), (0.9, 0.0)):
        M, K = np.array([[1.0]]), np.array([[1.0]])
        C = 0.02 * K
        pads = Pads(dof=np.array([0]), k=np.array([1.0]), mu=0.5, N0=np.array([0.3]), cN=np.array([[cN]]))
        model, _ = models.jenkins(M, C, K, [0.1], 0, pads, "jenkins-1dof")
        law = engine.contact_law(model, mu=0.5)
        t0 = time.perf_counter()
        ref, ss = floquet.jenkins_monodromy(M, C, K, np.array([0.1]), omega, pads)
        t_ref = time.perf_counter() - t0
        rc = relative_coordinates(model)
        c = condensed(rc, omega, 15)
        hb = HBProblem(c.Zr, c.Fr, law, 15, 128)
        t0 = time.perf_counter()
        pr = engine.solve_point(hb, [hb.x0()], solver="newton-powell", tol=1e-10, maxiter=100)
        t_hb = time.perf_counter() - t0
        x = pr.result.x
        base = dict(case=f"jenkins ω={omega} cN={cN}", reference=ref.floquet_max, stick=float(ss.stick_fraction[0]),
                    shooting_s=t_ref, hb_s=t_hb)
        variants = [("monodromy", dict(nit=n)) for n in (512, 2048, 4096)]
        variants += [("monodromy eps", dict(eps_factor=e)) for e in (1e3, 1e5)]
        variants += [("memoryless monodromy", dict(memory=False)), ("memoryless hill", dict(method="hill", memory=False))]
        variants += [("hill", dict(method="hill", nh_hill=n)) for n in (8, 16)]
        for name, kw in variants:
            st = stability.hill_stability(model, hb, x, omega, rc=rc, nh_check=None, **kw)
            rows.append({**base, "variant": name, **{k: v for k, v in kw.items() if k != "method"},
                         "floquet_max": st.floquet_max, "error": st.floquet_max - ref.floquet_max,
                         "seconds": st.seconds})
    return rows


def sector_rows(path: Path, points: int, label: str, full: bool = True, nit: int | None = None) -> list:
    from workflow.engine.condense import relative_coordinates
    from workflow.engine.model import ReducedModel
    from workflow import engine
    from workflow.engine import penalty, stability
    from workflow.engine.hb import HBProblem
    from workflow.engine.linear import condensed
    from workflow.engine.studies.study import first_excited_mode

    model = ReducedModel.load(path)
    law = engine.contact_law(model, mu=0.5)
    rc = relative_coordinates(model)
    f0 = first_excited_mode(rc)[0]
    rows, prev = [], None
    for f in np.linspace(0.94 * f0, 1.04 * f0, points):
        w = 2 * np.pi * f
        c = condensed(rc, w, 3)
        hb = HBProblem(c.Zr, c.Fr, law, 3, 64)
        t0 = time.perf_counter()
        guesses = [hb.x0()] if prev is None else [prev, hb.x0()]
        pr = engine.solve_point(hb, guesses, solver="newton-powell", tol=1e-8, maxiter=100,
                                eps_path=penalty.path_of(law, np.real(c.Zr[0])))
        t_hb = time.perf_counter() - t0
        if not pr.converged:
            rows.append(dict(case=label, f_hz=float(f), converged=False))
            continue
        prev = pr.result.x
        row = dict(case=label, f_hz=float(f), converged=True, hb_s=t_hb, pairs=int(model.n_pairs), m=int(model.size))
        variants = ([("full nit512", dict(nit=512))] if full else []) + [("ritz6", dict(modes=6.0)),
                                                                       ("ritz6 nit512", dict(modes=6.0, nit=512))]
        if nit is not None:         # a large model: the Ritz basis at that resolution only
            variants = [(f"ritz6 nit{nit}", dict(modes=6.0, nit=nit))]
        for name, kw in variants:
            st = stability.hill_stability(model, hb, prev, w, rc=rc, **kw)
            row[name] = dict(floquet_max=st.floquet_max, change=st.truncation_change, seconds=st.seconds,
                             stable=st.stable, method=st.method, anchors=st.anchors)
            # the cost of one analysis without the nit → 2nit check
            t0 = time.perf_counter()
            stability.hill_stability(model, hb, prev, w, rc=rc, nh_check=None, **kw)
            row[name]["seconds_nocheck"] = time.perf_counter() - t0
        rows.append(row)
    return rows


def frf_rows(path: Path, points: int, compare: bool = False) -> list:
    """The sweep and its stability on the model at ``path``, timed in one run (module docstring, 4)."""
    from workflow.engine.condense import relative_coordinates
    from workflow.engine.model import ReducedModel
    from workflow import engine
    from workflow.engine.hb import HBProblem
    from workflow.engine.linear import CondensedGrid, condensed
    from workflow.engine.stability import hill_stability
    from workflow.engine.studies.sweepstability import RITZ_FACTOR, sweep_stability

    model = ReducedModel.load(path)
    law = engine.contact_law(model, mu=0.5)
    opt = engine.FRFOptions(eps_check_factor=0.0, nh_check=False, branch_check=False, time_check=False,
                            refine_peak=False)
    study = engine.frf(model, law, [engine.Variant("hbm", 3, 64)], points=points, options=opt)
    r = study.runs[0]
    rc = relative_coordinates(model)
    # the sweep's condensations, as engine.frf(stability=True) hands them to the stability
    grid = CondensedGrid(rc, 2 * np.pi * r.freqs_hz, r.variant.nh)
    for _ in grid:
        pass
    st = sweep_stability(model, rc, study.law, study.static, r, grid=grid)
    row = dict(case="frf", pairs=int(model.n_pairs), m=int(model.size), points=points,
               converged=int(r.converged.sum()), sweep_s=float(r.total_seconds), stability_s=st["seconds"],
               ratio=st["seconds"] / float(r.total_seconds), f_hz=r.freqs_hz.tolist(),
               floquet_max=st["floquet_max"].tolist(), stable=st["stable"])
    if compare:
        old = dict(nit=2048, refine=64, substeps=2, levels=1)
        for name, kw in (("before", old), ("nit8192", dict(nit=8192))):
            fm, secs, cache = [], [], {}
            for i in np.flatnonzero(r.converged):
                w = 2 * np.pi * float(r.freqs_hz[i])
                c = condensed(rc, w, 3)
                hb = HBProblem(c.Zr, c.Fr, study.law, 3, 64, "hbm", static=study.static)
                s = hill_stability(model, hb, hb.unknowns_from_harmonics(r.Ur[i]), w, rc=rc, modes=RITZ_FACTOR,
                                   nh_check=None, cache=cache, **kw)
                fm.append(s.floquet_max)
                secs.append(s.seconds)
            row[f"floquet_max_{name}"], row[f"seconds_{name}"] = fm, sum(secs)
    return [row]


def frf_summary(r: dict) -> list:
    out = ["", f"## FRF with stability: {r['pairs']} pairs, m = {r['m']}, {r['points']} points "
           f"({r['converged']} converged), HBM-3 nit = 64", "",
           f"sweep {r['sweep_s']:.2f} s, stability {r['stability_s']:.2f} s: {100 * r['ratio']:.0f} % of the sweep", "",
           "| f (Hz) | |μ|max | " + " | ".join(k[12:] for k in r if k.startswith("floquet_max_")) + " |",
           "|---|---|" + "---|" * sum(k.startswith("floquet_max_") for k in r)]
    extra = [k for k in r if k.startswith("floquet_max_")]
    conv = [i for i, f in enumerate(r["floquet_max"]) if np.isfinite(f)]
    for j, i in enumerate(conv):
        out.append(f"| {r['f_hz'][i]:.2f} | {r['floquet_max'][i]:.8f} | "
                   + " | ".join(f"{r[k][j]:.8f}" for k in extra) + " |")
    for k in extra:
        name = k[12:]
        d = max(abs(r[k][j] - r["floquet_max"][i]) for j, i in enumerate(conv))
        out.append(f"\n{name}: {r['seconds_' + name]:.1f} s; max |Δ|μ|max| from the defaults {d:.1e}")
    return out


def summary(rows: list) -> str:
    out = ["# Floquet stability bench", "", "## Jenkins oscillators vs event-driven shooting", "",
           "| case | variant | setting | largest multiplier | shooting | error | s |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["case"].startswith("jenkins"):
            setting = ", ".join(f"{k}={r[k]}" for k in ("nit", "eps_factor", "nh_hill", "memory") if k in r)
            out.append(f"| {r['case']} | {r['variant']} | {setting} | {r['floquet_max']:.6f} | {r['reference']:.6f} "
                       f"| {r['error']:+.2e} | {r['seconds']:.2f} |")
    for r in rows:
        if r["case"] == "frf":
            out += frf_summary(r)
    for label in sorted({r["case"] for r in rows if not r["case"].startswith("jenkins") and r["case"] != "frf"}):
        rs = [r for r in rows if r["case"] == label and r.get("converged")]
        if not rs:
            continue
        keys = [k for k in rs[0] if isinstance(rs[0][k], dict)]
        out += ["", f"## {label}: {rs[0]['pairs']} pairs, m = {rs[0]['m']}", "",
                "| f (Hz) | HB s | " + " | ".join(f"{k}: ρmax, change, s (no check)" for k in keys) + " |",
                "|---|---|" + "---|" * len(keys)]
        for r in rs:
            cells = [f"{r[k]['floquet_max']:.6f}, {r[k]['change']:.1e}, {r[k]['seconds_nocheck']:.2f}" for k in keys]
            out.append(f"| {r['f_hz']:.1f} | {r['hb_s']:.2f} | " + " | ".join(cells) + " |")
        hb = sum(r["hb_s"] for r in rs)
        for k in keys:
            st = sum(r[k]["seconds_nocheck"] for r in rs)
            out.append(f"\n{k}: stability {st:.2f} s for {len(rs)} points = {100 * st / hb:.0f} % of the HB solves "
                       f"({hb:.2f} s); largest multiplier {max(r[k]['floquet_max'] for r in rs):.6f}")
        if "full nit512" in keys and "ritz6 nit512" in keys:
            d = max(abs(r["full nit512"]["floquet_max"] - r["ritz6 nit512"]["floquet_max"]) for r in rs)
            out.append(f"\nRitz basis (6ω) vs full δq (nit = 512): max |Δρmax| = {d:.1e}")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    from workflow.engine.blas import blas_threads

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--quick", type=Path, default=Path("results/quick/reduction/reduced.npz"))
    ap.add_argument("--big", type=Path, default=None)
    ap.add_argument("--points", type=int, default=9)
    ap.add_argument("--skip-jenkins", action="store_true")
    ap.add_argument("--big-nit", type=int, default=256, help="samples of the big sector's monodromy")
    ap.add_argument("--frf", type=Path, default=None, help="reduced.npz: an FRF and its stability, timed")
    ap.add_argument("--frf-points", type=int, default=5)
    ap.add_argument("--frf-compare", action="store_true", help="also |μ|max at the pre-2026-11-29 settings and nit 8192")
    ap.add_argument("--skip-quick", action="store_true")
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    rows = []
    with blas_threads(1):
        if not a.skip_jenkins:
            rows += jenkins_rows()
        if a.quick and a.quick.is_file() and not a.skip_quick:
            rows += sector_rows(a.quick, a.points, "quick sector")
        if a.big and a.big.is_file():
            rows += sector_rows(a.big, a.points, "big sector", full=False, nit=a.big_nit)
        if a.frf and a.frf.is_file():
            rows += frf_rows(a.frf, a.frf_points, a.frf_compare)
    (a.out / "stability.json").write_text(json.dumps(rows, indent=1, default=float))
    text = summary(rows)
    (a.out / "stability.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
