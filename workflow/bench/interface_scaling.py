"""Cost of the harmonic-balance solve against the number of contact pairs (issue #16).

``python -m workflow.bench.interface_scaling [--pairs 16,32,64,128,256,512]
[--methods hbm,hdhb] [--nh 7] [--solvers newton] [--points 9] [--max-gb 8]
[--out results/bench/interface-scaling]``

The study is :mod:`workflow.costs.interface_scaling` (the ``interface_scaling`` stage runs it
from a scene); this script runs it on the ``interface-scaling`` scene and writes to ``--out``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from workflow.costs.interface_scaling import PAIRS, fits, reduced_model, study, write


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", default=",".join(map(str, PAIRS)))
    ap.add_argument("--methods", default="hbm,hdhb")
    ap.add_argument("--solvers", default="newton")
    ap.add_argument("--nh", type=int, default=7)
    ap.add_argument("--nit", type=int, default=64, help="time samples of HBM (HDHB: 2Nh+1)")
    ap.add_argument("--points", type=int, default=9)
    ap.add_argument("--max-gb", type=float, default=8.0)
    ap.add_argument("--out", type=Path, default=Path("results/bench/interface-scaling"))
    ap.add_argument("--cache", type=Path, default=None)
    a = ap.parse_args(argv)
    from workflow.scene import load_scene

    scene = load_scene("interface-scaling")
    work = a.out / "work"
    work.mkdir(parents=True, exist_ok=True)
    rows = study(lambda p: reduced_model(scene, p, work, a.cache), [int(v) for v in a.pairs.split(",")],
                 a.methods.split(","), a.solvers.split(","), a.nh, a.nit, a.points, work, a.max_gb,
                 on_row=lambda rows: write(rows, fits(rows), a.out), mu=scene["contact"].mu,
                 maxiter=scene["hb"].max_iterations)
    for p in write(rows, fits(rows), a.out):
        print(p)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
