"""Friction-damped nonlinear modes on a reduced sector (issue #49 items 2–3): the EPMC backbone
(timed) and the single-nonlinear-mode synthesis' peak against the direct HB FRF's.

``python -m workflow.bench.nlmodes [REDUCED.npz] [--mu 0.5] [--nh 7] [--nit 64]
[--forces 0.1 0.5 2.0] [--amplitudes A_MIN A_MAX N] [--max-steps 120] [--out DIR]``

Writes ``DIR/nlmodes_backbone.csv`` (one row per backbone point, :meth:`Backbone.rows`) and
``DIR/nlmodes.json`` (timing, the linear limits, and per force level: the synthesis' peak with
both damping forms, the direct HB peak from ``engine.frf`` — HBM-Nh, nit, refined peak, the
checks off — and their relative errors). Force levels in N are ‖f‖ of the scaled
``f_harmonic`` (the quick sector's is 0.5 N).
"""
from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import numpy as np


def direct_peak(model, law, nh: int, nit: int, band_hz, points: int = 21) -> dict:
    """engine.frf's refined peak over ``band_hz`` (the convergence checks off), with its time."""
    from workflow import engine

    opt = engine.FRFOptions(eps_check_factor=0.0, nh_check=False, reference_check=False, branch_check=False,
                            time_check=False)
    t = time.perf_counter()
    study = engine.frf(model, law, [engine.Variant("hbm", nh, nit)], band_hz=band_hz, points=points, options=opt)
    run = study.runs[0]
    pk = study.peak or {}
    return {"hz": pk.get("hz", float("nan")), "amplitude_m": pk.get("amplitude_m", float("nan")),
            "converged_points": int(run.converged_points), "points": len(run.freqs_hz),
            "at_band_edge": bool(np.isfinite(pk.get("hz", np.nan)) and (
                abs(pk["hz"] - band_hz[0]) < 1e-9 * band_hz[0] or abs(pk["hz"] - band_hz[1]) < 1e-9 * band_hz[1])),
            "seconds": time.perf_counter() - t}


def bench(path: Path, *, mu: float, nh: int, nit: int, forces, amplitudes, max_steps: int) -> dict:
    from dataclasses import replace

    from workflow.engine.model import ReducedModel
    from workflow import engine
    from workflow.engine.studies import nlmodes

    model = ReducedModel.load(path)
    law = engine.contact_law(model, mu=model.friction(mu)[0])
    t = time.perf_counter()
    bb = nlmodes.backbone(model, law, nh=nh, nit=nit, amplitudes=amplitudes, max_steps=max_steps)
    bb_s = time.perf_counter() - t
    out = {"model": str(path), "mu": mu, "nh": nh, "nit": nit, "backbone_seconds": bb_s, "points": len(bb),
           "stopped": bb.stopped, "tied_hz": bb.tied_hz, "tied_damping_ratio": bb.tied_damping_ratio,
           "sliding_hz": bb.sliding_hz, "onset": bb.onset,
           "amplitude_range": [float(bb.amplitude[0]), float(bb.amplitude[-1])],
           "frequency_range_hz": [float(bb.frequency_hz.min()), float(bb.frequency_hz.max())],
           "damping_range": [float(bb.damping_ratio.min()), float(bb.damping_ratio.max())], "levels": []}
    f_norm = float(np.linalg.norm(model.f_harmonic))
    for F in forces:
        scale = float(F) / f_norm
        row = {"force_N": float(F), "scale": scale}
        for form in ("viscous", "split"):
            syn = nlmodes.synthesize(bb, model, scale, damping=form)
            row[f"synthesis_{form}"] = {"hz": syn.peak_hz, "amplitude_m": syn.peak_amplitude_m,
                                        "modal_amplitude": syn.peak_modal_amplitude}
        f0 = row["synthesis_viscous"]["hz"]
        if not np.isfinite(f0):
            row["direct"] = None
            row["note"] = "the synthesis' peak lies beyond the backbone's last point"
            out["levels"].append(row)
            continue
        half = max(6.0 * bb.damping_ratio.max(), 0.004) * f0
        scaled = replace(model, f_harmonic=np.asarray(model.f_harmonic) * scale)
        d = direct_peak(scaled, law, nh, nit, (f0 - half, f0 + half))
        row["direct"] = d
        for form in ("viscous", "split"):
            s = row[f"synthesis_{form}"]
            row[f"error_{form}"] = {"amplitude": s["amplitude_m"] / d["amplitude_m"] - 1.0,
                                    "frequency": s["hz"] / d["hz"] - 1.0}
        out["levels"].append(row)
    out["rows"] = bb.rows()
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model", nargs="?", default="results/quick/reduction/reduced.npz")
    ap.add_argument("--mu", type=float, default=0.5)
    ap.add_argument("--nh", type=int, default=7)
    ap.add_argument("--nit", type=int, default=64)
    ap.add_argument("--forces", type=float, nargs="+", default=[0.1, 0.5, 2.0])
    ap.add_argument("--amplitudes", type=float, nargs=3, default=None, metavar=("A_MIN", "A_MAX", "N"))
    ap.add_argument("--max-steps", type=int, default=120)
    ap.add_argument("--out", default="results/bench")
    a = ap.parse_args(argv)
    amps = None if a.amplitudes is None else (a.amplitudes[0], a.amplitudes[1], int(a.amplitudes[2]))
    res = bench(Path(a.model), mu=a.mu, nh=a.nh, nit=a.nit, forces=a.forces, amplitudes=amps,
                max_steps=a.max_steps)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = res.pop("rows")
    (out / "nlmodes.json").write_text(json.dumps(res, indent=1, default=float))
    if rows:
        with open(out / "nlmodes_backbone.csv", "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    print(f"backbone: {res['points']} points in {res['backbone_seconds']:.1f} s"
          + (f" (stopped: {res['stopped']})" if res["stopped"] else ""))
    for lv in res["levels"]:
        d = lv.get("direct")
        if d is None:
            print(f"{lv['force_N']:g} N: {lv.get('note')}")
            continue
        e, s = lv["error_viscous"], lv["error_split"]
        print(f"{lv['force_N']:g} N: direct {d['hz']:.4f} Hz {d['amplitude_m']:.4e} m; synthesis error amplitude "
              f"{e['amplitude']:+.2e} (split {s['amplitude']:+.2e}), frequency {e['frequency']:+.2e} "
              f"(split {s['frequency']:+.2e})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
