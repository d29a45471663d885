"""Optional numba compilation of the engine's sequential loops.

One switch for all of them: ``BLADEWEAR_NUMBA=0`` (or numba missing) leaves every caller on its
NumPy path, which is also what the tests compare the compiled loops with.
"""
from __future__ import annotations

import os


def compiled(fn, fastmath: bool = False):
    """``fn`` compiled by numba (``njit``, cached on disk beside the module), or None where numba
    is switched off or not importable: the caller then runs its NumPy path. ``fastmath``: sums
    may be reassociated (vectorised), so they differ from the NumPy path by round-off."""
    if os.environ.get("BLADEWEAR_NUMBA", "1") == "0":
        return None
    try:
        import numba
    except Exception:  # pragma: no cover - numba missing or incompatible with this NumPy
        return None
    return numba.njit(cache=True, fastmath=fastmath)(fn)
