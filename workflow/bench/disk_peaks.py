"""The mistuned disk's largest blade peak, pattern by pattern, against a dense scan (issue 50).

``python -m workflow.bench.disk_peaks [--scene mistuning] [--std 0.02] [--seeds 1,2,3] [--dense 0]
[--out results/bench] [--set KEY=VALUE …]``

For each pattern (:func:`workflow.engine.studies.mistuning.pattern` with that seed) the forced
response on the scene's friction grid (± ``band`` in ``points``) with its peak search
(:mod:`workflow.engine.studies.bladepeak`): the largest blade peak friction-damped and tied, the
search's solves, whether it resolved, and the wall time of the pattern — what one Monte Carlo
sample costs. With ``--dense n`` the same pattern is also solved on n points over the band with no
search, the independent check of the peak found (a scan under-reads a peak between its points, so
the search's peak should lie at or above it). Writes ``disk_peaks.json``.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path


def main(argv=None) -> int:
    import numpy as np

    from reduction.cyclic_reduce import nodal_diameters_needed
    from reduction.mistuned import WholeDiskCoordinates, cyclic_model
    from workflow import engine
    from workflow.bench import scene_disk
    from workflow.engine.studies import mistuning as ms
    from workflow.io import write_json
    from workflow.stages.mistuning import _frf_options, _tuned_sector

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="mistuning")
    ap.add_argument("--std", type=float, default=0.02)
    ap.add_argument("--seeds", default="1,2,3", help="comma-separated pattern seeds")
    ap.add_argument("--dense", type=int, default=0, help="points of a dense friction-damped scan (0: none)")
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a scene override (repeatable)")
    a = ap.parse_args(argv)
    scene, sub = scene_disk(a.scene, a.set, a.out)
    mt, hb, eo, N = scene["mistuning"], scene["hb"], int(scene["cyclic"].engine_order), sub.n_sectors
    nh = int(mt.harmonics)
    v = engine.Variant("hbm", nh, int(mt.time_samples) or ms.time_samples(nh, N, eo))
    cyc = cyclic_model(sub, nodal_diameters_needed(eo, N, nh))
    law, _, (f_t, a_t, _, a_tied), grid, ref = _tuned_sector(scene, sub, v, _Print())
    opt = _frf_options(hb)

    def response(dev, n, refine):
        freqs = grid if n == len(grid) else f_t * np.linspace(1 - mt.band, 1 + mt.band, n)
        run = ref if n == len(grid) else engine.frf(cyc, law, [v], freqs_hz=freqs, options=opt).runs[0]
        seeds = [ms.travelling_wave(U, N, eo) if ok else None for U, ok in zip(run.Ur, run.converged)]
        t = time.perf_counter()
        r = ms.forced_response(WholeDiskCoordinates(sub, dev), ms.tiled_law(law, N, eo), v, freqs, seeds=seeds,
                               tol=hb.tol, maxiter=hb.max_iterations, refine=refine, tied=refine)
        return r, time.perf_counter() - t

    rows = []
    for seed in (int(s) for s in a.seeds.split(",")):
        dev = ms.pattern(N, a.std, seed)
        r, secs = response(dev, int(mt.points), True)
        row = {"seed": seed, "peak": r.peak, "tied_peak": r.tied_peak, "points_solved": r.evaluations,
               "af_friction": ms.amplification(r.peak["amplitude_m"], a_t),
               "af_tied": ms.amplification(r.tied_peak["amplitude_m"], a_tied),
               "seconds": secs, "seconds_per_point": r.seconds_per_point}
        if a.dense:
            d, dsecs = response(dev, a.dense, False)
            ok = d.converged
            i = int(np.argmax(np.where(ok, np.nanmax(np.where(ok[:, None], d.amplitude, 0.0), axis=1), -np.inf)))
            row["dense"] = {"points": a.dense, "hz": float(d.freqs_hz[i]),
                            "amplitude_m": float(np.nanmax(d.amplitude[i])), "blade": int(np.nanargmax(d.amplitude[i])),
                            "converged": int(ok.sum()), "seconds": dsecs}
        rows.append(row)
        print(f"pattern {seed}: peak {r.peak['amplitude_m']:.5g} m at {r.peak['hz']:.3f} Hz (blade {r.peak['blade']}, "
              f"resolved {r.peak.get('resolved')}, {r.peak.get('search_points')} search solves), tied "
              f"{r.tied_peak['amplitude_m']:.5g} m; {r.evaluations} points, {secs:.1f} s"
              + (f"; dense scan {row['dense']['amplitude_m']:.5g} m at {row['dense']['hz']:.3f} Hz" if a.dense else ""),
              flush=True)
    write_json(a.out / "disk_peaks.json", {"scene": a.scene, "std": a.std, "tuned_peak_hz": f_t, "tuned_peak_m": a_t,
                                           "tuned_tied_m": a_tied, "patterns": rows})
    print(a.out / "disk_peaks.json")
    return 0


class _Print:
    """The stage's log, printed."""

    def info(self, msg):
        print(msg, flush=True)


if __name__ == "__main__":
    raise SystemExit(main())
