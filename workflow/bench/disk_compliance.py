"""The whole disk's interface stiffness Z_r against its compliance H = Z_r⁻¹, a harmonic each (issue 50).

``python -m workflow.bench.disk_compliance --hz F [--scene mistuning] [--std 0.02] [--harmonics 3]
[--points F1,F2,…] [--out results/bench]``

Z_r = S_b − S_b A⁻¹ S_b (:meth:`reduction.mistuned.WholeDiskCoordinates.condense`) takes one dense
inverse of A = S_b + S_d, (3pN)², a harmonic: what a whole-disk frequency point costs before its
Newton solve. The compliance H = S_b⁻¹ + S_d⁻¹ (:meth:`~reduction.mistuned.WholeDiskCoordinates.compliance`)
takes none. Per harmonic 1…``--harmonics`` at ``--hz`` on the scene's disk, mistuned with ``--std`` and
the scene's seed: both wall times and max|H Z_r − I|. With ``--points`` also the friction-damped
forced response at those frequencies [Hz] in both forms
(:func:`workflow.engine.studies.mistuning.forced_response`, ``form``; seeded with the tuned sector's
travelling wave, no peak search, no tied response): seconds a point and the largest relative
difference of the blade amplitudes. Writes ``disk_compliance.json``.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path


def main(argv=None) -> int:
    import numpy as np

    from reduction.mistuned import WholeDiskCoordinates
    from workflow.bench import scene_disk
    from workflow.engine.studies import mistuning as ms
    from workflow.io import write_json

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="mistuning")
    ap.add_argument("--hz", type=float, required=True, help="frequency [Hz]")
    ap.add_argument("--std", type=float, default=0.02)
    ap.add_argument("--harmonics", type=int, default=3)
    ap.add_argument("--points", default="", help="comma-separated frequencies [Hz] of a forced response in both forms")
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    a = ap.parse_args(argv)
    scene, sub = scene_disk(a.scene, [], a.out)
    mt, hz = scene["mistuning"], a.hz
    wd = WholeDiskCoordinates(sub, ms.pattern(sub.n_sectors, a.std, mt.seed) if a.std else None)
    omega, rows = 2 * np.pi * hz, []
    for j in range(1, a.harmonics + 1):
        t = time.perf_counter()
        Zr = wd._harmonic(j, omega)[0]
        t_z = time.perf_counter() - t
        t = time.perf_counter()
        H = wd.compliance(omega, j)
        t_h = time.perf_counter() - t
        rows.append({"harmonic": j, "stiffness_s": t_z, "compliance_s": t_h,
                     "identity_error": float(np.abs(H @ Zr - np.eye(wd.n_rel)).max())})
        print(f"harmonic {j}: Z_r {t_z:.2f} s, H {t_h:.2f} s, max|H Z_r − I| = {rows[-1]['identity_error']:.1e}",
              flush=True)
    out = {"scene": a.scene, "frequency_hz": hz, "std": a.std, "pairs": int(sub.n_sectors * sub.n_pairs), "rows": rows}
    if a.points:
        out["forced_response"] = _both_forms(scene, sub, wd, [float(f) for f in a.points.split(",")])
    write_json(a.out / "disk_compliance.json", out)
    print(a.out / "disk_compliance.json")
    return 0


def _both_forms(scene, sub, wd, freqs: list) -> dict:
    """Seconds a point of the forced response at ``freqs`` [Hz] in each form, and the largest
    relative difference of the blade amplitudes between them."""
    import numpy as np

    from reduction.cyclic_reduce import nodal_diameters_needed
    from reduction.mistuned import cyclic_model
    from workflow import engine
    from workflow.engine.studies import mistuning as ms
    from workflow.stages.hb import law_of
    from workflow.stages.mistuning import _frf_options

    mt, eo, N = scene["mistuning"], int(scene["cyclic"].engine_order), sub.n_sectors
    nh = int(mt.harmonics)
    v = engine.Variant("hbm", nh, int(mt.time_samples) or ms.time_samples(nh, N, eo))
    cyc = cyclic_model(sub, nodal_diameters_needed(eo, N, nh))
    law = law_of(scene, cyc)
    ref = engine.frf(cyc, law, [v], freqs_hz=freqs, options=_frf_options(scene["hb"])).runs[0]
    seeds = [ms.travelling_wave(U, N, eo) if ok else None for U, ok in zip(ref.Ur, ref.converged)]
    hb, res = scene["hb"], {}
    for form in ("stiffness", "compliance"):
        r = ms.forced_response(wd, ms.tiled_law(law, N, eo), v, freqs, seeds=seeds, tol=hb.tol,
                               maxiter=hb.max_iterations, refine=False, tied=False, form=form)
        res[form] = r
        print(f"{form}: {r.seconds_per_point:.2f} s a point, converged {r.converged.tolist()}", flush=True)
    ok = res["stiffness"].converged & res["compliance"].converged
    diff = float(np.max(np.abs(res["compliance"].amplitude[ok] / res["stiffness"].amplitude[ok] - 1))) if ok.any() else None
    print(f"blade amplitudes apart {diff:.1e}" if diff is not None else "no point converged in both forms", flush=True)
    return {"freqs_hz": freqs, "amplitudes_apart": diff,
            **{f"{k}_seconds_per_point": res[k].seconds_per_point for k in res},
            **{f"{k}_converged": res[k].converged.tolist() for k in res}}


if __name__ == "__main__":
    raise SystemExit(main())
