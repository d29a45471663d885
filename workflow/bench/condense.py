"""Condensation onto the contact DOFs (eq. 3): the tied basis against one LU per harmonic.

``python -m workflow.bench.condense REDUCED.npz [REDUCED.npz ...] [--nh 7] [--out DIR]``

For each reduced model: seconds to make its tied basis once
(:func:`reduction.condense.tied_basis`), seconds per frequency of condensing harmonics
0…Nh (best of 200, 212 and 224 Hz) and of one :func:`reduction.condense.recover`, by
both paths (:data:`reduction.condense.TIED_BASIS` on and off), and the largest relative
difference of Z_r between them (per harmonic, over its largest entry). Wall times of this
process with the BLAS threads it is given. Writes ``condense.jsonl`` (one line a model).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def compare(path: Path, nh: int = 7, freqs_hz=(200.0, 212.0, 224.0)) -> dict:
    import reduction.condense as cd
    from reduction.reduced import ReducedModel

    model = ReducedModel.load(path)
    row, Z = {"pairs": int(model.n_pairs), "nh": nh}, {}
    flag = cd.TIED_BASIS
    try:
        for tied in (False, True):
            cd.TIED_BASIS = tied
            rc = cd._relative(model)        # fresh coordinates: no basis kept from the other path
            t = time.perf_counter()
            cd.tied_basis(rc)
            made = time.perf_counter() - t
            times = []
            for f in freqs_hz:
                t = time.perf_counter()
                c = cd.condense(rc, 2 * np.pi * f, nh)
                times.append(time.perf_counter() - t)
            t = time.perf_counter()
            cd.recover(rc, 2 * np.pi * freqs_hz[-1], np.full_like(c.Fr, 1e-6))
            row["tied_basis" if tied else "lu"] = dict(basis_s=made, condense_s=min(times),
                                                       recover_s=time.perf_counter() - t)
            Z[tied] = c.Zr
    finally:
        cd.TIED_BASIS = flag
    row["max_rel_diff"] = float(max(np.abs(Z[True][j] - Z[False][j]).max() / np.abs(Z[False][j]).max()
                                    for j in range(nh + 1)))
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("reduced", nargs="+", type=Path)
    ap.add_argument("--nh", type=int, default=7)
    ap.add_argument("--out", type=Path, default=Path("results/bench/condense"))
    a = ap.parse_args(argv)
    from workflow.io import write_text

    lines = []
    for p in a.reduced:
        lines.append(json.dumps(compare(p, a.nh)))
        print(lines[-1], flush=True)
    a.out.mkdir(parents=True, exist_ok=True)
    write_text(a.out / "condense.jsonl", "\n".join(lines) + "\n")
    print(a.out / "condense.jsonl")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
