"""Interface-scaling stage: HB cost against the number of contact pairs (issue #16).

Runs :func:`workflow.costs.interface_scaling.study`: for each pair count of
``interface_scaling.pairs`` the scene's sector with ``nodes_along ×
nodes_across`` contact vertices per flank (two flanks) is meshed, assembled
and reduced (the pipeline, in a private cache under the stage folder), then
each method × solver sweeps ``points`` frequencies through the first tied
resonance in a fresh process (its own peak memory). Stops before a pair
count whose extrapolated peak memory exceeds ``max_gb``. Writes
``interface_scaling.csv`` (pairs, unknowns, method, solver, linear solver,
seconds per converged point, iterations, peak memory, converged/points),
``interface_scaling.json`` (power laws ``y = a·pairs^b``) and
``interface_scaling.png``; summary ``rows`` repeats the table. A benchmark:
timings mean something only on a quiet machine (``--fresh`` to measure again).
"""
from __future__ import annotations

import time
from pathlib import Path

NAME = "interface_scaling"
SECTIONS = ("interface_scaling", "geometry", "material", "rotation", "damping", "excitation", "reduction",
            "contact", "hb")
NEEDS = ()
PRODUCES = ("interface_scaling",)


def run(scene, inputs: dict, out: Path, log) -> dict:
    import shutil

    from workflow.costs import interface_scaling as bench
    from workflow.errors import SolverError
    from workflow.stages.reduction import rigid_contact_only

    rigid_contact_only(scene["contact"], "interface-scaling")
    cfg = scene["interface_scaling"]
    out = Path(out)
    work = out / "work"
    work.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    try:
        rows = bench.study(lambda p: bench.reduced_model(scene, p, work, work / "cache", log=log.info),
                           list(cfg.pairs), list(cfg.methods), list(cfg.solvers), cfg.harmonics, cfg.time_samples,
                           cfg.points, work, cfg.max_gb, log=log.info,
                           on_row=lambda rows: bench.write(rows, bench.fits(rows, cfg.fit_min_pairs), out),
                           mu=scene["contact"].mu, maxiter=scene["hb"].max_iterations)
    except RuntimeError as exc:
        raise SolverError(f"interface_scaling: a case failed ({str(exc).strip().splitlines()[0]})") from exc
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if not rows:
        raise SolverError("interface_scaling: no case ran (interface_scaling.max_gb too small?)")
    fit = bench.fits(rows, cfg.fit_min_pairs)
    bench.write(rows, fit, out)
    for k, f in fit.items():
        log.info(f"{k}: ∝ pairs^{f['b']:.2f} over {f['points']} pair counts ≥ {f['min_pairs']}")
    return {"scaling": {"rows": rows, "fits": fit}, "seconds": round(time.perf_counter() - t0, 3),
            "files": {"csv": "interface_scaling.csv", "json": "interface_scaling.json",
                      "png": "interface_scaling.png"}}
