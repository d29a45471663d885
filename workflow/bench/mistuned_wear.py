"""Every blade's worn steady state on the whole disk against the cyclic sector's (issue 50).

``python -m workflow.bench.mistuned_wear [--scene mistuning] [--hz 0] [--std 0] [--own-steps]
[--set SECTION.KEY=VALUE ...] [--out results/bench]``

The scene's sector bundle is built through the pipeline (cached like any run), split into its
blade and disk-per-ND substructures, and the tuned sector's friction-damped HB solution at
``--hz`` (0: the tuned peak of the scene's band, its centre point) starts two wear marches with
the scene's wear law and march: the sector's (cyclic coordinates) and the whole disk's, tuned
(``--std 0``: on the sector's own steps, or its own with ``--own-steps``) or mistuned with the
scene's seed. Writes ``mistuned_wear.json``: each march's
steps, seconds, steady flag, every blade's deepest point and, tuned, the largest difference of
the disk's worn state from the sector's, relative to its deepest point. ``--set`` overrides scene
keys, e.g. ``--set 'wear.control="amplitude"'`` holds the most vibrating blade's tip (and the
sector's) instead of the force.
"""
from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path


def main(argv=None) -> int:
    import numpy as np

    from workflow.engine.condense import relative_coordinates
    from reduction.cyclic_reduce import nodal_diameters_needed
    from reduction.mistuned import WholeDiskCoordinates, cyclic_model
    from workflow import engine
    from workflow.engine.studies import mistuning as ms
    from workflow.bench import scene_disk
    from workflow.io import write_json
    from workflow.stages.hb import law_of
    from workflow.stages.mistuning import _frf_options
    from workflow.stages.wear import options

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="mistuning")
    ap.add_argument("--hz", type=float, default=0.0)
    ap.add_argument("--std", type=float, default=0.0)
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                    help="a scene override, e.g. 'wear.control=\"amplitude\"' (repeatable)")
    ap.add_argument("--own-steps", action="store_true",
                    help="tuned: the disk's march controls its own steps (default: it takes the sector's)")
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    a = ap.parse_args(argv)
    scene, sub = scene_disk(a.scene, a.set, a.out)
    mt, eo = scene["mistuning"], int(scene["cyclic"].engine_order)
    N, nh = sub.n_sectors, int(mt.harmonics)
    v = engine.Variant("hbm", nh, int(mt.time_samples) or ms.time_samples(nh, N, eo))
    cyc = cyclic_model(sub, nodal_diameters_needed(eo, N, nh))
    law = law_of(scene, cyc)
    f = a.hz or float(engine.frf(cyc, law, [v], points=15, options=_frf_options(scene["hb"])).peak["hz"])
    ref = engine.frf(cyc, law, [v], freqs_hz=[f], options=_frf_options(scene["hb"])).runs[0]
    opt = replace(options(scene), method="hbm", nh=v.nh, nit=v.nit)
    area, w = sub.pairs["area"], 2 * np.pi * f
    t = time.perf_counter()
    sector = ms.worn_blades(relative_coordinates(cyc), law, v, w, area, opt, n_sectors=1, U0=ref.Ur[0], log=print)
    t_sector = time.perf_counter() - t
    dev = ms.pattern(N, a.std, mt.seed) if a.std else None
    t = time.perf_counter()
    steps = None if a.std or a.own_steps else np.diff(sector.history.cycles)     # tuned: on the sector's path
    disk = ms.worn_blades(WholeDiskCoordinates(sub, dev), ms.tiled_law(law, N, eo), v, w, area, opt, n_sectors=N,
                          U0=ms.travelling_wave(ref.Ur[0], N, eo), log=lambda m: print(m, flush=True),
                          step_lengths=steps)
    t_disk = time.perf_counter() - t
    out = {"scene": a.scene, "frequency_hz": f, "std": a.std, "pairs": int(N * sub.n_pairs), "nh": v.nh, "nit": v.nit,
           "sector": {**sector.history.summary(), "wall_s": t_sector, "max_m": float(sector.W.max())},
           "disk": {**disk.history.summary(), "wall_s": t_disk, "blade_max_m": disk.blade_max_m.tolist(),
                    "control": disk.control},
           "sector_control": sector.control, "overrides": a.set, "on_sector_steps": steps is not None,
           "disk_vs_sector": float(np.abs(disk.W - sector.W).max() / sector.W.max()) if not a.std else None}
    write_json(a.out / "mistuned_wear.json", out)
    print(f"sector: {sector.history.iterations} steps {t_sector:.1f} s, deepest {sector.W.max():.4e} m; disk: "
          f"{disk.history.iterations} steps {t_disk:.1f} s ({'steady' if disk.history.steady else 'NOT steady'}), "
          f"deepest {disk.blade_max_m.min():.4e} … {disk.blade_max_m.max():.4e} m"
          + (f"; disk against sector {out['disk_vs_sector']:.1e}" if not a.std else ""))
    print(a.out / "mistuned_wear.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
