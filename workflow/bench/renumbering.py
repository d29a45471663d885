"""How far a serial run moves when only the DOF numbering changes: the floor for "2 ranks = serial".

``python -m workflow.bench.renumbering [--scene quick] [--orders 3] [--ranks 2] [--out results/bench]``

A run on N MPI ranks numbers the DOFs by partition, so the sparse LU of the
reduction (MUMPS' fill-reducing ordering follows the numbering) and the block
Lanczos start blocks see another order than the serial run and round off
differently. This script measures what that alone does in one process: the
serial chain (``--fresh``, ``hb.tol = 1e-12``) once as numbered, then
once more as a control (it must agree exactly), then
``--orders`` times with the free DOFs handed to the Craig–Bampton reduction
in a random order (seeds 1, 2, …; the basis is mapped back, so the model is
the same up to round-off), ``--ulps`` times with every entry of the assembled
M and K moved by −1, 0 or +1 ulp at random (what another summation order of
the element contributions — a parallel assembly — does), and — when ``--ranks`` > 1 and mpirun exists — the
README's ``mpirun -n N`` command. Each is compared with the first serial run:
max |ΔA| / max |A| over the FRF amplitude and over the pseudo-time worn depth.

Writes ``renumbering.csv`` (run, frf_rel, wear_rel, seconds) to ``--out``.
"""
from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

TIGHT = ["--set", "hb.tol=1e-12"]


def _column(path: Path, name: str) -> np.ndarray:
    with open(path) as fh:
        return np.array([float(r[name]) for r in csv.DictReader(fh)])


def _rel(a: Path, b: Path) -> tuple[float, float]:
    out = []
    for rel, col in (("hb/frf.csv", "amplitude_m"), ("wear/wear.csv", "W_pseudo-time_m")):
        x, y = _column(a / rel, col), _column(b / rel, col)
        out.append(float(np.max(np.abs(x - y)) / np.max(np.abs(x))))
    return out[0], out[1]


def _permuted_reduction(seed: int) -> None:
    """Make :func:`reduction.reduce.craig_bampton` see the free DOFs in a random order (this process only)."""
    import reduction.reduce as rr

    plain = rr.craig_bampton

    def permuted(M, K, boundary, *args, loads=None, **kwargs):
        p = np.random.default_rng(seed).permutation(K.shape[0])
        back = np.argsort(p)
        V, omega = plain(M[p][:, p], K[p][:, p], back[boundary], *args,
                         loads=None if loads is None else loads[p], **kwargs)
        return V[back], omega

    rr.craig_bampton = permuted


def _symmetric_ulp(A, rng):
    """``A`` (sparse, symmetric) with each upper-triangle entry moved by one ulp up, down or not at all,
    mirrored: what another summation order of the element contributions does to an assembled matrix."""
    U = sp.triu(sp.csr_matrix(A), format="csr")
    step = rng.integers(-1, 2, U.nnz)
    U.data = np.where(step > 0, np.nextafter(U.data, np.inf), np.where(step < 0, np.nextafter(U.data, -np.inf),
                                                                       U.data))
    return (U + sp.triu(U, k=1, format="csr").T).tocsr()


def _ulp_reduction(seed: int) -> None:
    """Make :func:`reduction.reduce.craig_bampton` see M and K moved by ±1 ulp per entry (this process only)."""
    import reduction.reduce as rr

    plain = rr.craig_bampton

    def perturbed(M, K, boundary, *args, **kwargs):
        rng = np.random.default_rng(seed)
        return plain(_symmetric_ulp(M, rng), _symmetric_ulp(K, rng), boundary, *args, **kwargs)

    rr.craig_bampton = perturbed


def _run(argv: list[str]) -> float:
    """Run ``argv`` with one BLAS thread per process (serial and MPI runs alike); seconds."""
    from workflow.mpi import single_thread_env

    t0 = time.perf_counter()
    r = subprocess.run(argv, capture_output=True, text=True, env=single_thread_env())
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({r.returncode}):\n{r.stderr}")
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="quick")
    ap.add_argument("--orders", type=int, default=3, help="random DOF orders to try")
    ap.add_argument("--ulps", type=int, default=0,
                    help="also run this many times with M and K moved by ±1 ulp per entry (random seeds)")
    ap.add_argument("--ranks", type=int, default=2, help="also run on this many MPI ranks (≤ 1: no)")
    ap.add_argument("--out", default="results/bench")
    ap.add_argument("--seed", type=int, default=None, help=argparse.SUPPRESS)  # internal: one permuted run
    ap.add_argument("--ulp-seed", type=int, default=None, help=argparse.SUPPRESS)  # internal: one ulp run
    ap.add_argument("--run-out", default=None, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.seed is not None or a.ulp_seed is not None:  # child process: one perturbed chain
        if a.seed is not None:
            _permuted_reduction(a.seed)
        else:
            _ulp_reduction(a.ulp_seed)
        from workflow.cli import main as cli

        return cli(["run", a.scene, "--out", a.run_out, "--cache", a.run_out + "-cache", "--fresh", "--quiet",
                    *TIGHT])

    from workflow.mpi import mpirun_command

    out = Path(a.out)
    work = out / "renumbering-runs"
    bin_ = str(Path(sys.executable).parent / "bladewear")
    base = work / "serial"
    rows = [("serial", 0.0, 0.0, _run([bin_, "run", a.scene, "--out", str(base), "--cache", str(work / "c0"),
                                        "--fresh", "--quiet", *TIGHT]))]

    def compare(label: str, d: Path, argv: list[str]) -> None:
        t = _run(argv)
        rows.append((label, *_rel(base, d), t))
        print(f"{label}: FRF {rows[-1][1]:.2e}, wear {rows[-1][2]:.2e}")

    again = work / "serial-again"  # the control: the same chain twice must agree exactly
    compare("serial, again", again, [bin_, "run", a.scene, "--out", str(again), "--cache", str(work / "c1"),
                                     "--fresh", "--quiet", *TIGHT])
    child = [sys.executable, "-m", "workflow.bench.renumbering", "--scene", a.scene]
    for s in range(1, a.orders + 1):
        compare(f"serial, DOF order {s}", work / f"order{s}", child + ["--seed", str(s), "--run-out",
                                                                     str(work / f"order{s}")])
    for s in range(1, a.ulps + 1):
        compare(f"serial, M and K ±1 ulp {s}", work / f"ulp{s}", child + ["--ulp-seed", str(s), "--run-out",
                                                                         str(work / f"ulp{s}")])
    mpirun = mpirun_command(a.ranks) if a.ranks > 1 else None
    if mpirun:
        d = work / f"ranks{a.ranks}"
        compare(f"{a.ranks} MPI ranks", d, mpirun + [bin_, "run", a.scene, "--out", str(d), "--cache",
                                                     str(work / "cmpi"), "--fresh", "--quiet", *TIGHT])
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "renumbering.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["run", "frf_rel", "wear_rel", "seconds"])
        w.writerows([(r, f"{x:.3e}", f"{y:.3e}", f"{t:.1f}") for r, x, y, t in rows])
    print(f"wrote {out / 'renumbering.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
