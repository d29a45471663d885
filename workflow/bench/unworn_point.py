"""Pseudo-time against Newton on one unworn FRF point (issue 5's third target).

``python -m workflow.bench.unworn_point [--scene paper-wear] [--repeat 10] [--out results/bench]``

The scene's model (48 pairs for ``paper-wear``) is built through the
pipeline up to the reduced model (cached like any run), then the unworn HB
problem at the wear frequency is solved from the same start (static state +
tied linear response) by Newton and by pseudo-time — SER with the Jacobian
mass, :func:`workflow.engine.pseudotime.integrate` — both along the default
penalty's ε-path (:func:`workflow.engine.cascade.along_eps_path`),
``--repeat`` times each, interleaved (alternating which goes first, so
neither profits from the other's warm caches), with 1 and with 2 BLAS
threads. Writes ``unworn_point.json`` (median seconds, iterations, Jacobians,
residual evaluations, the ratio, the difference of the two roots).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path


def measure(hb, repeat: int, threads: int, eps_path=()) -> dict:
    import numpy as np

    from workflow.engine.cascade import along_eps_path, run_solver
    from workflow.engine.blas import blas_threads

    pseudo = {"scheme": "ser", "precond": "jacobian", "max_steps": 400}
    run = lambda q, x, s, m: run_solver(q, x, s, 1e-8, m, pseudo)  # noqa: E731
    x0 = hb.x0()
    times = {"newton": [], "pseudo-time": []}
    res = {}
    with blas_threads(threads):
        for k in range(repeat):
            for name in (("newton", "pseudo-time") if k % 2 else ("pseudo-time", "newton")):
                t = time.perf_counter()
                r = along_eps_path(hb, x0, eps_path, 1e-8, 100 if name == "newton" else 400, run=run, solver=name)
                times[name].append(time.perf_counter() - t)
                res[name] = r
    n, p = res["newton"], res["pseudo-time"]
    row = lambda r, ts: {"median_s": float(np.median(ts)), "iterations": int(r.iterations),  # noqa: E731
                         "jacobians": int(r.jacobian_evaluations), "residuals": int(r.function_evaluations),
                         "converged": bool(r.converged)}
    return {"threads": threads, "newton": row(n, times["newton"]), "pseudo-time": row(p, times["pseudo-time"]),
            "ratio_pseudo_over_newton": float(np.median(times["pseudo-time"]) / np.median(times["newton"])),
            "root_max_rel_diff": float(np.abs(p.x - n.x).max() / np.abs(n.x).max())}


def main(argv=None) -> int:
    from workflow.engine.model import ReducedModel
    from workflow.bench import run_to
    from workflow.io import write_json
    from workflow.engine import penalty
    from workflow.engine.studies.wearstudy import build_problem
    from workflow.scene import load_scene
    from workflow.stages.hb import law_of
    from workflow.stages.wear import options

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="paper-wear")
    ap.add_argument("--repeat", type=int, default=10)
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    a = ap.parse_args(argv)
    run_dir = a.out / f"{a.scene}-model"
    run_to(a.scene, "reduced", run_dir)
    model = ReducedModel.load(run_dir / "reduction" / "reduced.npz")
    scene = load_scene(a.scene)
    hb, _, omega = build_problem(model, law_of(scene, model), options(scene))
    path = penalty.path_of(hb.law, np.real(hb.Zr[0]))
    out = {"scene": a.scene, "pairs": hb.p, "unknowns": hb.n, "frequency_hz": omega / 6.283185307179586,
           "repeat": a.repeat, "eps_path_steps": len(path), "runs": [measure(hb, a.repeat, t, path) for t in (1, 2)]}
    write_json(a.out / "unworn_point.json", out)
    for r in out["runs"]:
        print(f"{r['threads']} BLAS thread(s): newton {r['newton']['median_s']:.3f} s "
              f"({r['newton']['iterations']} iterations, {r['newton']['jacobians']} J), pseudo-time "
              f"{r['pseudo-time']['median_s']:.3f} s ({r['pseudo-time']['iterations']} steps, "
              f"{r['pseudo-time']['jacobians']} J): ratio {r['ratio_pseudo_over_newton']:.2f}")
    print(a.out / "unworn_point.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
