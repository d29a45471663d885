"""The whole disk's interface stiffness Z_r against its compliance H = Z_r⁻¹, a harmonic each (issue 50).

``python -m workflow.bench.disk_compliance --hz F [--scene mistuning] [--std 0.02] [--harmonics 3]
[--out results/bench]``

Z_r = S_b − S_b A⁻¹ S_b (:meth:`reduction.mistuned.WholeDiskCoordinates.condense`) takes one dense
inverse of A = S_b + S_d, (3pN)², a harmonic: what a whole-disk frequency point costs before its
Newton solve. The compliance H = S_b⁻¹ + S_d⁻¹ (:meth:`~reduction.mistuned.WholeDiskCoordinates.compliance`)
takes none. Per harmonic 1…``--harmonics`` at ``--hz`` on the scene's disk, mistuned with ``--std`` and
the scene's seed: both wall times and max|H Z_r − I|. Writes ``disk_compliance.json``.
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
    write_json(a.out / "disk_compliance.json", {"scene": a.scene, "frequency_hz": hz, "std": a.std,
                                                "pairs": int(sub.n_sectors * sub.n_pairs), "rows": rows})
    print(a.out / "disk_compliance.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
