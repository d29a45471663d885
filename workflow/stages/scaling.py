"""Scaling stage: assembly and reduction cost against DOFs on 1 and N processes (issue 9).

Runs :func:`workflow.costs.scaling.study` on the default sector refined by
``scaling.factors`` — each mesh made once (gmsh), then assembled and reduced
in fresh processes, under ``mpirun -n P`` for every P of ``scaling.procs`` —
and stops before a mesh whose extrapolated peak memory exceeds
``scaling.max_gb``. Writes ``scaling.csv`` (one row per mesh × P: DOFs, wall
times, peak memory summed over the ranks, per-step timings, the P-rank tied
frequencies against the serial ones), ``scaling.json`` (power laws
``cost = a·n^b`` and their value at 10⁶ DOFs) and ``scaling.png``; the table
grows on disk as the study runs. It is a benchmark: its timings are only
meaningful on an otherwise idle machine, and the cache keeps the first run's
(``--fresh`` measures again).
"""
from __future__ import annotations

import time
from pathlib import Path

NAME = "scaling"
SECTIONS = ("scaling",)
NEEDS = ()
PRODUCES = ("scaling",)


def run(scene, inputs: dict, out: Path, log) -> dict:
    from workflow.costs import scaling as bench
    from workflow.errors import SolverError

    sc = scene["scaling"]
    out = Path(out)
    t0 = time.perf_counter()

    def summary(rows):
        return bench.summarise(rows, sc.fit_min_dofs, time.perf_counter() - t0, procs=list(sc.procs),
                               modes=sc.modes, max_gb=sc.max_gb)

    (out / "work").mkdir(parents=True, exist_ok=True)
    try:
        rows = bench.study(list(sc.factors), tuple(sc.procs), sc.modes, work=out / "work", log=log.info,
                           max_gb=sc.max_gb, on_row=lambda rows: bench.write(rows, summary(rows), out))
    except RuntimeError as exc:
        raise SolverError(f"scaling: a step failed ({str(exc).strip().splitlines()[0]})") from exc
    finally:
        import shutil

        shutil.rmtree(out / "work", ignore_errors=True)
    if not rows:
        raise SolverError("scaling: no mesh could be made for scaling.factors "
                          f"{list(sc.factors)} (gmsh refused every size)")
    fit = summary(rows)
    bench.write(rows, fit, out)
    for k, f in fit.items():
        if not k.startswith("_"):
            log.info(f"{k}: {f['a']:.3g}·n^{f['b']:.2f} → {f['at_1e6']:.3g} at 10⁶ DOFs ({f['points']} meshes)")
    return {"rows": len(rows), "largest_dofs": fit["_study"]["largest_dofs"], "peak_gb": fit["_study"]["peak_gb"],
            "fits": {k: v for k, v in fit.items() if not k.startswith("_")},
            "max_rel_frequency_error": max(r["f_rel_err"] for r in rows),
            "files": {"csv": "scaling.csv", "json": "scaling.json", "png": "scaling.png"}}
