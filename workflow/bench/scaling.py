"""Scaling of assembly and reduction with the mesh, on 1 and on N MPI processes.

``python -m workflow.bench.scaling [--factors 1.6,1.3,1,0.8,0.65] [--procs 1,2]
[--modes 30] [--max-gb 20] [--out results/bench]``

The study is :mod:`workflow.costs.scaling` (the ``scaling`` stage runs it from a scene);
this script writes its table, fits and figure to ``--out`` and can append to an earlier table.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from workflow.costs.scaling import MODES, read_rows, study, summarise, write


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--factors", default="1.6,1.3,1,0.8,0.65", help="mesh-size factors, coarse to fine")
    ap.add_argument("--procs", default="1,2", help="process counts (the first is the reference)")
    ap.add_argument("--modes", type=int, default=MODES)
    ap.add_argument("--fit-min-dofs", type=int, default=20000, help="fit the power laws on meshes this large")
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    ap.add_argument("--max-gb", type=float, default=20.0,
                    help="stop before a mesh whose extrapolated peak memory exceeds this")
    ap.add_argument("--work", type=Path, default=None, help="scratch folder for meshes and bundles")
    ap.add_argument("--append", action="store_true",
                    help="add to the rows already in OUT/scaling.csv (with --factors '' only refit and redraw)")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()

    def summary(rows):
        return summarise(rows, a.fit_min_dofs, time.perf_counter() - t0, procs=a.procs, modes=a.modes,
                         max_gb=a.max_gb)

    old = read_rows(a.out / "scaling.csv") if a.append else []
    rows = old + study([float(v) for v in a.factors.split(",") if v.strip()],
                       tuple(int(v) for v in a.procs.split(",")),
                       a.modes, work=a.work, max_gb=a.max_gb, prior=old,
                       on_row=lambda rows: write(old + rows, summary(old + rows), a.out))
    rows.sort(key=lambda r: (r["n_dofs"], r["procs"]))
    fit = summary(rows)
    for p in write(rows, fit, a.out):
        print(p)
    for k, f in fit.items():
        if not k.startswith("_"):
            print(f"{k:>18}: {f['a']:.3g}·n^{f['b']:.2f} → {f['at_1e6']:.3g} at 10⁶ DOFs ({f['points']} meshes)")
    print(f"study: {fit['_study']['seconds']:.0f} s, largest model {fit['_study']['largest_dofs']} DOFs")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
