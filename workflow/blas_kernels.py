"""Which OpenBLAS kernels this process loads: chosen from the CPU's own flags where OpenBLAS
would guess wrong.

OpenBLAS built with DYNAMIC_ARCH picks its kernels from the CPU model when it is loaded.
Debian 12's (0.3.21, SciPy's BLAS and LAPACK) and NumPy 1.26's wheel (0.3.23) do not know the
Intel server CPUs that came after them (Sapphire and Emerald Rapids, models 143 and 207) and fall
back to their oldest x86-64 kernels, "Prescott" (SSE3). Measured on a 2-core Emerald Rapids
machine (one thread, 2026-11-30): a 2256² complex inverse 8.5 s on Prescott, 1.8 s on SkylakeX;
a 2256² complex product 7.1 s against 1.3 s (``python -m workflow.bench.blas_kernels`` prints the
kernels loaded and times both).

The choice reads only the instruction sets (/proc/cpuinfo's flags): an Intel CPU with the
AVX-512 subsets the SkylakeX kernels use gets them, one with AVX2 and FMA the Haswell ones. It
is made before NumPy loads OpenBLAS (``import workflow`` does it) and never overrides an
``OPENBLAS_CORETYPE`` the user set; other vendors are left to OpenBLAS's own detection.
No NumPy here: this module runs before OpenBLAS is loaded.
"""
from __future__ import annotations

import os
import sys

#: the AVX-512 subsets OpenBLAS's SkylakeX kernels execute
SKYLAKEX_FLAGS = frozenset({"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"})
#: what its Haswell kernels execute
HASWELL_FLAGS = frozenset({"avx2", "fma"})


def coretype(cpuinfo: str) -> str | None:
    """The OpenBLAS core type (``OPENBLAS_CORETYPE``) for a CPU described by ``cpuinfo`` (the
    text of /proc/cpuinfo): "SkylakeX" or "Haswell" for an Intel CPU with their instruction
    sets, else None (leave the choice to OpenBLAS)."""
    vendor, flags = "", set()
    for line in cpuinfo.splitlines():
        key, _, value = line.partition(":")
        key = key.strip()
        if key == "vendor_id" and not vendor:
            vendor = value.strip()
        elif key == "flags" and not flags:
            flags = set(value.split())
    if vendor != "GenuineIntel":
        return None
    if SKYLAKEX_FLAGS <= flags:
        return "SkylakeX"
    if HASWELL_FLAGS <= flags:
        return "Haswell"
    return None


def choose(environ=os.environ, cpuinfo_path: str = "/proc/cpuinfo") -> str | None:
    """Set ``OPENBLAS_CORETYPE`` in ``environ`` from the CPU (:func:`coretype`) unless it is set
    or NumPy is already loaded (OpenBLAS reads it once, when it is loaded; child processes
    inherit it) — then warn where NumPy's OpenBLAS runs kernels older than the CPU's. Returns
    the core type in force (None: OpenBLAS's own detection)."""
    if "OPENBLAS_CORETYPE" in environ:
        return environ["OPENBLAS_CORETYPE"] or None
    try:
        with open(cpuinfo_path) as fh:
            core = coretype(fh.read())
    except OSError:
        return None
    if core is None:
        return None
    if "numpy" in sys.modules:
        _warn_if_outdated(core)
        return None
    environ["OPENBLAS_CORETYPE"] = core
    return core


#: OpenBLAS's kernels for CPUs without AVX2: on a CPU that has it, OpenBLAS did not know the model
OUTDATED = frozenset({"prescott", "core2", "penryn", "dunnington", "nehalem", "atom", "northwood", "banias"})


def _warn_if_outdated(core: str) -> None:
    """NumPy came first (a notebook's ``import numpy``): say so if its OpenBLAS runs kernels
    older than the CPU's, and how to choose them (the variable is read only at load)."""
    import warnings

    from workflow.engine.blas import corenames

    old = sorted({name for _, name in corenames() if name.lower() in OUTDATED})
    if old:
        warnings.warn(f"OpenBLAS runs its {', '.join(old)} kernels on a CPU with {core}'s instruction sets: "
                      f"dense linear algebra ~5x slower. Set OPENBLAS_CORETYPE={core} before NumPy is imported, "
                      "or import workflow first (docs/performance.md, \"The BLAS kernels\")", RuntimeWarning,
                      stacklevel=3)
