"""Condensation onto the contact DOFs (eq. 3): one LU per harmonic, the tied basis's rank
update, and the tied basis with its high modes summed as a series.

``python -m workflow.bench.condense REDUCED.npz [REDUCED.npz ...] [--nh 7] [--out DIR]``

For each reduced model and path (``lu``: :data:`workflow.engine.condense.TIED_BASIS` off;
``tied_basis``: on, the rank update over every mode; ``series``: on, with
:class:`workflow.engine.condense.HighModeSeries`): seconds to make its basis (and series) once,
seconds per frequency of condensing harmonics 0…Nh (best of 200, 212 and 224 Hz) without
and with the ω-derivatives, and of one :func:`workflow.engine.condense.recover`; and the largest
relative difference of Z_r and dZ_r/dω of each tied path from the LU's (per harmonic, over its
largest entry). Wall times of this process with the BLAS threads it is given. Writes
``condense.jsonl`` (one line a model).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def compare(path: Path, nh: int = 7, freqs_hz=(200.0, 212.0, 224.0)) -> dict:
    import workflow.engine.condense as cd
    from workflow.engine.model import ReducedModel

    model = ReducedModel.load(path)
    row, Z = {"pairs": int(model.n_pairs), "nh": nh}, {}
    flags = cd.TIED_BASIS, cd.SERIES_MIN_DOFS
    try:
        for name, tied, series in (("lu", False, False), ("tied_basis", True, False), ("series", True, True)):
            cd.TIED_BASIS, cd.SERIES_MIN_DOFS = tied, (flags[1] if series else np.inf)
            rc = cd._relative(model)[0]     # fresh coordinates: no basis kept from the other path
            t = time.perf_counter()
            tm = cd.tied_basis(rc)
            if tm is not None:
                cd._high_mode_series(rc, tm)
            made = time.perf_counter() - t
            times, dtimes = [], []
            for f in freqs_hz:
                t = time.perf_counter()
                c = cd.condense(rc, 2 * np.pi * f, nh)
                times.append(time.perf_counter() - t)
                t = time.perf_counter()
                dc = cd.condense(rc, 2 * np.pi * f, nh, derivative=True)
                dtimes.append(time.perf_counter() - t)
            t = time.perf_counter()
            cd.recover(rc, 2 * np.pi * freqs_hz[-1], np.full_like(c.Fr, 1e-6))
            row[name] = dict(basis_s=made, condense_s=min(times), condense_derivative_s=min(dtimes),
                             recover_s=time.perf_counter() - t)
            Z[name] = dc
    finally:
        cd.TIED_BASIS, cd.SERIES_MIN_DOFS = flags
    for name in ("tied_basis", "series"):
        for q in ("Zr", "dZr"):
            A, B = getattr(Z[name], q), getattr(Z["lu"], q)
            row[f"{name}_{q}_max_rel_diff"] = float(max(np.abs(A[j] - B[j]).max() / np.abs(B[j]).max()
                                                        for j in range(nh + 1) if np.abs(B[j]).max() > 0))
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
