"""The OpenBLAS kernels this machine runs, and what they cost on the whole disk's dense work.

``python -m workflow.bench.blas_kernels [--n 2256] [--out results/bench]``

Prints ``OPENBLAS_CORETYPE`` (chosen by :mod:`workflow.blas_kernels` or the user), the kernels of
every OpenBLAS loaded (NumPy's and SciPy's) and the seconds of one n × n complex inverse
(SciPy, the condensation's ``getrf`` + ``getri``) and one n × n complex product (NumPy), n = 2256
the quick mistuned disk's 752 pairs. Run it twice, once with ``OPENBLAS_CORETYPE=Prescott``, to
see what a misdetected CPU costs. Writes ``blas_kernels.json``.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path


def main(argv=None) -> int:
    import numpy as np
    import scipy.linalg as sla

    from workflow.engine.blas import corenames
    from workflow.io import write_json

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2256, help="matrix size")
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    a = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    A = rng.standard_normal((a.n, a.n)) + 1j * rng.standard_normal((a.n, a.n))
    t = time.perf_counter()
    sla.inv(A, check_finite=False)
    t_inv = time.perf_counter() - t
    t = time.perf_counter()
    A @ A
    t_mul = time.perf_counter() - t
    row = {"coretype": os.environ.get("OPENBLAS_CORETYPE"), "kernels": dict(corenames()), "n": a.n,
           "complex_inverse_s": t_inv, "complex_product_s": t_mul,
           "threads": os.environ.get("OPENBLAS_NUM_THREADS") or os.environ.get("OMP_NUM_THREADS")}
    print(f"OPENBLAS_CORETYPE = {row['coretype']!r}")
    for path, core in row["kernels"].items():
        print(f"  {path}: {core}")
    print(f"{a.n}² complex: inverse {t_inv:.2f} s, product {t_mul:.2f} s")
    write_json(a.out / "blas_kernels.json", row)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
