"""Where a structured Newton sweep spends its time: factorisations, GMRES, the rest (issue #16).

``python -m workflow.bench.structured_split REDUCED.npz --method hdhb [--nh 7] [--nit 64]
[--points 9] [--out split.json]``

One sweep of :func:`workflow.costs.interface_scaling.worker` (the ``interface-scaling``
band, Newton through the cascade, the structured linear solve forced, one BLAS thread except
in the structured solve from :data:`workflow.engine.linsolve.THREADED_MIN_DOFS` contact DOFs up)
with :class:`workflow.engine.linsolve.StructuredSolve` timed from outside: seconds and count of
the harmonic-block factorisations, seconds and iterations of GMRES, the sequence of
GMRES iterations per solve (``F`` marks a factorisation). The rest of ``seconds``
is residuals, DLFT passes, line searches and Levenberg–Marquardt steps. HBM uses
``--nit`` samples, HDHB 2Nh+1. Timings are one process's wall time: compare runs
made one after the other on a quiet machine; the counts are deterministic.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path


def split(reduced: Path, method: str, nh: int = 7, nit: int = 64, points: int = 9) -> dict:
    """The worker's row plus ``factor_s``, ``factorizations``, ``gmres_s``,
    ``gmres_iterations``, ``solves``, ``s_per_iteration`` and ``sequence``."""
    from workflow.engine import linsolve
    from workflow.costs.interface_scaling import worker

    stats = {"factor_s": 0.0, "factorizations": 0, "gmres_s": 0.0, "gmres_iterations": 0, "solves": 0}
    seq = []
    factor, k_solve = linsolve.StructuredSolve._factor_blocks, linsolve.StructuredSolve._k_solve

    def timed_factor(self, op):
        t = time.perf_counter()
        factor(self, op)
        stats["factor_s"] += time.perf_counter() - t
        stats["factorizations"] += 1
        seq.append("F")

    def timed_solve(self, b, *args):
        t = time.perf_counter()
        out = k_solve(self, b, *args)
        stats["gmres_s"] += time.perf_counter() - t
        stats["gmres_iterations"] += out[2]
        stats["solves"] += 1
        seq.append(str(out[2]))
        return out

    linsolve.StructuredSolve._factor_blocks, linsolve.StructuredSolve._k_solve = timed_factor, timed_solve
    try:
        row = worker(Path(reduced), method, nh, 2 * nh + 1 if method == "hdhb" else nit, "newton", points,
                     "structured")
    finally:
        linsolve.StructuredSolve._factor_blocks, linsolve.StructuredSolve._k_solve = factor, k_solve
    row.update(stats, s_per_iteration=row["seconds"] / max(row["iterations"], 1), sequence=" ".join(seq))
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("reduced", type=Path, help="reduced.npz of a sector (interface-scaling's work folder)")
    ap.add_argument("--method", default="hbm", choices=("hbm", "hdhb"))
    ap.add_argument("--nh", type=int, default=7)
    ap.add_argument("--nit", type=int, default=64)
    ap.add_argument("--points", type=int, default=9)
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    row = split(a.reduced, a.method, a.nh, a.nit, a.points)
    text = json.dumps(row, indent=1)
    if a.out:
        from workflow.io import write_json

        write_json(a.out, row)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
