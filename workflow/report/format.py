"""Numbers and column names as an engineer reads them: SI prefixes, units in headers."""
from __future__ import annotations

import math
import re

_PREFIX = ((1e-9, "n"), (1e-6, "µ"), (1e-3, "m"), (1.0, ""), (1e3, "k"), (1e6, "M"), (1e9, "G"))


def si(value, unit: str, digits: int = 3) -> str:
    """``value`` in ``unit`` with an SI prefix and ``digits`` significant digits
    (``si(6.37e-4, "m")`` → ``"637 µm"``); ``"—"`` for None/NaN."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    v = float(value)
    if v == 0.0:
        return f"0 {unit}"
    scale, p = next(((s, p) for s, p in reversed(_PREFIX) if abs(v) >= s), _PREFIX[0])
    return f"{v / scale:.{digits}g} {p}{unit}"


def hz(value, digits: int = 5) -> str:
    """A frequency in Hz with ``digits`` significant digits (no prefix: engineers read Hz)."""
    return "—" if value is None else f"{float(value):.{digits}g} Hz"


def signed_hz(value, digits: int = 3) -> str:
    """A frequency shift in Hz with its sign."""
    return "—" if value is None else f"{float(value):+.{digits}g} Hz"


def percent(value, digits: int = 3) -> str:
    return "—" if value is None else f"{100.0 * float(value):.{digits}g} %"


def seconds(value) -> str:
    if value is None:
        return "—"
    v = float(value)
    return f"{v:.3g} s" if v < 120 else f"{int(v // 60)} min {v % 60:.0f} s"


#: Column-name suffix → unit, longest first (``_rad_s`` before ``_s``).
_UNITS = (("_rad_s", "rad/s"), ("_m2", "m²"), ("_m3", "m³"), ("_hz", "Hz"), ("_kg", "kg"), ("_pa", "Pa"),
          ("_n", "N"), ("_m", "m"), ("_s", "s"))
_WHOLE = {"seconds": "time [s]", "cpu_seconds": "CPU time [s]", "cpu_seconds_per_50": "CPU per 50 frequencies [s]",
          "normalised": "normalised CPU [–]", "Nh": "Nh", "nit": "nit",
          # hb: FRF error / peak amplitude; wear: profile error / max W (both relative)
          "error": "error [–]", "reference_uncertainty": "reference uncertainty [–]"}


def header(name: str) -> str:
    """A CSV column name with its unit moved into brackets:
    ``frequency_hz`` → ``frequency [Hz]``, ``W_pseudo-time_m`` → ``W pseudo-time [m]``."""
    if name in _WHOLE:
        return _WHOLE[name]
    low = name.lower()
    for suffix, unit in _UNITS:
        if low.endswith(suffix) and len(name) > len(suffix):
            return re.sub(r"_+", " ", name[: -len(suffix)]).strip() + f" [{unit}]"
    return name.replace("_", " ")
