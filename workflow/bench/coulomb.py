"""Issue 15's verification targets: the project's HB on the Coulomb oscillator and a pad chain.

``python -m workflow.bench.coulomb [--penalty default|1e3|1e4 ...] [--harmonics 1 3 7 15 25]
[--betas 10] [--chain] [--out results/bench]``

Coulomb oscillator (m = k = 1, F0 = 1): μN/F0 ∈ {0.2, 0.5, 0.7}, β ∈ [0.5, 1.5]
(``--betas`` points, an even count keeps β = 1 out: at c = 0 and μN/F0 < π/4 the
resonant amplitude is unbounded), ζ ∈ {0, 0.02}; each (μN/F0, ζ, Nh, penalty) is
one plain sweep upwards in β through :func:`workflow.verification.runner.hb_first_harmonic`.
References: Den Hartog's closed form where valid, else event-driven time
integration; the Galerkin floor (HB with the exact sign law) on the non-stop
points. ``--chain``: the 8-pad lumped cantilever against time integration,
Nh ∈ {1, 3, 5, 7}, 7 frequencies over ±8 % of the tied resonance.

Writes ``coulomb_<penalty>.csv`` (one row per point), ``coulomb_galerkin.csv``,
``chain_<penalty>.csv`` and ``coulomb_<penalty>.json`` (per Nh: converged
fraction, max / median error on non-stop and stop points, the Galerkin floor).
The penalty is the project's default, or 1e3 / 1e4 × the case's stiffness.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

RATIOS = (0.2, 0.5, 0.7)
ZETAS = (0.0, 0.02)


def references(betas, log=print) -> dict:
    """{(r, ζ, β): Reference} for the whole grid."""
    from workflow.verification import models, runner

    refs = {}
    for r in RATIOS:
        for z in ZETAS:
            _, spec = models.coulomb(1.0, 1.0, 2 * z, 1.0, 1.0, r)
            t0 = time.perf_counter()
            for b in betas:
                refs[(r, z, float(b))] = runner.reference(spec, float(b))
            log(f"references μN/F0 = {r}, ζ = {z}: {time.perf_counter() - t0:.1f} s")
    return refs


def coulomb_rows(betas, nhs, penalty: float | None, refs: dict, log=print) -> list[dict]:
    from workflow.verification import models, runner

    rows = []
    for r in RATIOS:
        for z in ZETAS:
            model, spec = models.coulomb(1.0, 1.0, 2 * z, 1.0, 1.0, r, name=f"coulomb r={r} zeta={z}")
            for nh in nhs:
                t0 = time.perf_counter()
                got = runner.compare(model, spec, np.asarray(betas) / 2 / np.pi, [nh], eps=penalty,
                                     refs=[refs[(r, z, float(b))] for b in betas])
                sec = time.perf_counter() - t0
                for g, b in zip(got, betas):
                    rows.append({**g, "ratio": r, "zeta": z, "beta": float(b), "sweep_seconds": sec})
                log(f"  r={r} ζ={z} Nh={nh}: {sum(g['converged'] for g in got)}/{len(got)} converged, "
                    f"{sec:.1f} s")
    return rows


def galerkin_rows(betas, nhs, refs: dict) -> list[dict]:
    from workflow.verification import galerkin

    rows = []
    for (r, z, b), ref in refs.items():
        if ref.stops:
            continue
        start = None
        for nh in sorted(nhs):
            coef, ok = galerkin.galerkin_hb(1.0, 1.0, 2 * z, r, 1.0, b, nh, start=start)
            start = coef
            a = galerkin.first_amplitude(coef)
            rows.append({"ratio": r, "zeta": z, "beta": b, "Nh": nh, "amplitude": a, "exact": ref.amplitude,
                         "error": abs(a - ref.amplitude) / ref.amplitude, "converged": ok})
    return rows


def digest(rows: list, floor: list) -> dict:
    """Per Nh: converged fraction, max / median error (converged points) non-stop and with stops,
    Galerkin floor (max / median over non-stop points; max over the non-stop points where the
    HB converged, and the largest HB error in excess of the floor there)."""
    out = {}
    for nh in sorted({r["Nh"] for r in rows}):
        sel = [r for r in rows if r["Nh"] == nh]
        ns = [r["error"] for r in sel if r["converged"] and not r["stops"]]
        st = [r["error"] for r in sel if r["converged"] and r["stops"]]
        fl = [g["error"] for g in floor if g["Nh"] == nh and g["converged"]]
        # the floor on exactly the non-stop points where the HB converged: like for like
        fmap = {(g["ratio"], g["zeta"], round(g["beta"], 12)): g["error"] for g in floor if g["Nh"] == nh}
        both = [(r["error"], fmap[(r["ratio"], r["zeta"], round(r["beta"], 12))]) for r in sel
                if r["converged"] and not r["stops"] and (r["ratio"], r["zeta"], round(r["beta"], 12)) in fmap]
        out[str(nh)] = {"converged": sum(r["converged"] for r in sel), "points": len(sel),
                        "max_error_nonstop": max(ns) if ns else None,
                        "median_error_nonstop": float(np.median(ns)) if ns else None,
                        "max_error_stops": max(st) if st else None,
                        "median_error_stops": float(np.median(st)) if st else None,
                        "galerkin_floor_max": max(fl) if fl else None,
                        "galerkin_floor_median": float(np.median(fl)) if fl else None,
                        "floor_at_converged_max": max(b for _, b in both) if both else None,
                        "hb_minus_floor_max": max(a - b for a, b in both) if both else None}
    return out


def chain_rows(nhs, penalty_factor: float | None, log=print) -> list[dict]:
    from workflow.verification import models, runner

    model, spec = models.pad_chain()
    ws = spec.omega_n * np.linspace(0.92, 1.08, 7)
    t0 = time.perf_counter()
    refs = [runner.reference(spec, w) for w in ws]
    log(f"chain references: {time.perf_counter() - t0:.1f} s")
    eps = None if penalty_factor is None else penalty_factor * float(spec.pads.k.max())
    rows = runner.compare(model, spec, ws / 2 / np.pi, nhs, eps=eps, refs=refs)
    peak = max(refs, key=lambda r: r.amplitude).amplitude
    for r in rows:
        r["error_vs_peak"] = abs(r["amplitude"] - r["exact"]) / peak
    return rows


def main(argv=None) -> int:
    from workflow.io import write_json, write_rows

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--penalty", nargs="+", default=["default", "1e3", "1e4"])
    ap.add_argument("--harmonics", nargs="+", type=int, default=[1, 3, 5, 7, 11, 15, 25])
    ap.add_argument("--betas", type=int, default=10)
    ap.add_argument("--chain", action="store_true")
    ap.add_argument("--no-coulomb", action="store_true")
    ap.add_argument("--out", default="results/bench")
    a = ap.parse_args(argv)
    out = Path(a.out)
    betas = np.linspace(0.5, 1.5, a.betas)
    refs = None if a.no_coulomb else references(betas)
    if refs is not None:
        floor = galerkin_rows(betas, a.harmonics, refs)
        write_rows(out / "coulomb_galerkin.csv", floor)
        write_rows(out / "coulomb_references.csv", [{"ratio": r, "zeta": z, "beta": b, "amplitude": v.amplitude,
                                                     "source": v.source, "stops": v.stops}
                                                    for (r, z, b), v in refs.items()])
    for pen in a.penalty:
        factor = None if pen == "default" else float(pen)
        if refs is not None:
            print(f"penalty {pen}")
            t0 = time.perf_counter()
            rows = coulomb_rows(betas, a.harmonics, factor, refs)
            write_rows(out / f"coulomb_{pen}.csv", rows)
            write_json(out / f"coulomb_{pen}.json", {"penalty": pen, "seconds": time.perf_counter() - t0,
                                                      "per_nh": digest(rows, floor)})
        if a.chain:
            rows = chain_rows([1, 3, 5, 7], factor)
            write_rows(out / f"chain_{pen}.csv", rows)
            for nh in (1, 3, 5, 7):
                sel = [r for r in rows if r["Nh"] == nh]
                print(f"chain {pen} Nh={nh}: {sum(r['converged'] for r in sel)}/{len(sel)} converged, max error "
                      f"{max(r['error'] for r in sel if r['converged']) if any(r['converged'] for r in sel) else None}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
