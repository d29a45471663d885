"""How many BLAS threads the engine's dense work may use, and whether an MPI launcher started us.

Small HB systems run on one OpenBLAS thread (threads only spin on a shared
2-core machine); large dense work (condensation, penalties, big structured
solves) takes every core this process may use, shared among the MPI ranks of
its node so that ranks never oversubscribe.
"""
from __future__ import annotations

import contextlib
import ctypes
import os
import sys

__all__ = ["blas_cores", "blas_threads", "corenames", "large_blas", "launched"]

#: Environment variables set by MPI launchers (Open MPI, MPICH/Hydra, PMIx, Slurm's PMI).
LAUNCHER_ENV = ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "PMI_RANK", "MPI_LOCALNRANKS")


def launched() -> bool:
    """True when this process was started by an MPI launcher (or ``BLADEWEAR_MPI=1``)."""
    return os.environ.get("BLADEWEAR_MPI") == "1" or any(k in os.environ for k in LAUNCHER_ENV)


#: Variables MPI launchers set to the number of ranks on this node (Open MPI, MPICH/Hydra).
_LOCAL_RANKS_ENV = ("OMPI_COMM_WORLD_LOCAL_SIZE", "MPI_LOCALNRANKS")


def _openblas_handles():
    """(set, get) function pairs of every OpenBLAS loaded in this process (Linux
    only; NumPy's wheel and Debian's SciPy each bring their own), found again only when a
    module has been imported since the last call: reading /proc/self/maps took 2.3 ms a call,
    152 calls (0.35 s, 1.4 %) of a 512-pair sweep's :func:`workflow.engine.blas.large_blas`."""
    key = len(sys.modules)
    if _HANDLES[0] != key:
        _HANDLES[:] = [key, _find_openblas()]
    return _HANDLES[1]


#: (len(sys.modules) when found, the handles of :func:`_find_openblas`)
_HANDLES: list = [None, []]


def _openblas_libs():
    """(file, ctypes library) of every OpenBLAS loaded in this process (Linux: /proc/self/maps)."""
    try:
        with open("/proc/self/maps") as fh:
            paths = sorted({ln.split()[-1] for ln in fh if "openblas" in ln.lower() and ln.split()[-1].startswith("/")})
    except OSError:
        return
    for path in paths:
        try:
            yield path, ctypes.CDLL(path)
        except OSError:
            continue


def corenames() -> list[tuple[str, str]]:
    """(file name, kernels) of every OpenBLAS loaded in this process (``openblas_get_corename``):
    "Prescott" on a CPU with AVX2 means OpenBLAS did not know the CPU and took its SSE3 kernels."""
    out = []
    for path, lib in _openblas_libs():
        for name in ("openblas_get_corename", "openblas_get_corename64_", "scipy_openblas_get_corename64_"):
            fn = getattr(lib, name, None)
            if fn is not None:
                fn.restype = ctypes.c_char_p
                out.append((os.path.basename(path), fn().decode()))
                break
    return out


def _find_openblas():
    out = []
    for _, lib in _openblas_libs():
        for suffix in ("", "64_"):
            for prefix in ("openblas", "scipy_openblas"):
                try:
                    s = getattr(lib, f"{prefix}_set_num_threads{suffix}")
                    g = getattr(lib, f"{prefix}_get_num_threads{suffix}")
                except AttributeError:
                    continue
                g.restype = ctypes.c_int
                out.append((s, g))
    return out


@contextlib.contextmanager
def blas_threads(n: int = 1):
    """Limit OpenBLAS to ``n`` threads inside the block (restored after).

    The HB Jacobians are small (n ≲ 2500): on a shared 2-core machine,
    threaded BLAS spins on contended cores and multiplies the process CPU
    time (measured 2.5× on the HBM Nh = 1 sweep) for little or no wall-time
    gain. A no-op where no OpenBLAS is found.
    """
    handles = _openblas_handles()
    old = []
    for s, g in handles:
        try:
            old.append((s, int(g())))
            s(int(n))
        except Exception:  # pragma: no cover - unexpected ABI
            pass
    try:
        yield
    finally:
        for s, k in reversed(old):      # reversed: one library may be listed twice
            s(k)


def blas_cores() -> int:
    """BLAS threads this process may use for a large product: ``OPENBLAS_NUM_THREADS`` or
    ``OMP_NUM_THREADS`` if set (a user's, or a benchmark's one-thread protocol), else
    the cores of its CPU affinity shared among the MPI ranks on this node (1 under an
    MPI launcher that does not say how many), so that ranks never oversubscribe."""
    for key in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
        try:
            return max(1, int(os.environ[key]))
        except (KeyError, ValueError):
            continue
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if not launched():
        return max(1, cores)
    for key in _LOCAL_RANKS_ENV:
        try:
            return max(1, cores // max(1, int(os.environ[key])))
        except (KeyError, ValueError):
            continue
    return 1


#: From this many contact DOFs (3p) up, the structured solve's BLAS runs on every core the
#: process may use (:func:`blas_cores`). Measured on the 512-pair sector
#: (HBM Nh = 7, 9 points, alone, 2 cores): 28.1 s a point against 32.1 s on one thread (GMRES
#: 201 → 173 s, factorisations 45 → 36 s); at 256 pairs 35.8 → 35.0 s a sweep (12 % with the
#: double-precision preconditioner of 2026-11-27); smaller products only spin.
THREADED_MIN_DOFS = 768


def large_blas(dofs: int):
    """BLAS threads for dense work on ``dofs`` contact DOFs: every core this process may use
    (:func:`blas_cores`) from :data:`THREADED_MIN_DOFS` up, else the
    caller's setting (one thread inside :func:`workflow.engine.frf`)."""
    n = blas_cores() if dofs >= THREADED_MIN_DOFS else 1
    return blas_threads(n) if n > 1 else contextlib.nullcontext()
