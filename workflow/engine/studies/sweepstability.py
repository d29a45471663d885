"""Stability of every point of a swept FRF (issue 49 item 1): the Floquet multipliers of each
converged HB solution (:func:`workflow.engine.stability.hill_stability`, the monodromy of its
linearisation with the stick anchors as states, on a Ritz basis of the modes below
:data:`RITZ_FACTOR` × ω with the pairs stuck and sliding)."""
from __future__ import annotations

import time

import numpy as np

#: the Ritz basis: modes with the pairs stuck and sliding below this multiple of ω. Measured on the
#: quick sector (5 points 200–221 Hz): within 1e-4 of the full model's largest multiplier, 1.5e-3
#: at the peak, at a tenth of its cost (workflow/bench/stability.py)
RITZ_FACTOR = 6.0


def sweep_stability(model, rc, law, static, sweep, *, nit: int | None = None, grid=None) -> dict:
    """Per point of ``sweep`` (:class:`~workflow.engine.studies.frf.SweepResult`): ``stable``
    (True / False; None where the point did not converge or the check could not run),
    ``floquet_max`` (largest |multiplier|, NaN where not computed), ``seconds``.

    ``grid``: the sweep's own condensations (a kept :class:`~workflow.engine.linear.CondensedGrid`
    at Nh ≥ the variant's), read where a point lies on it instead of condensing it again
    (0.17 s of a 128-pair point's 0.45 s, 2026-11-29)."""
    from workflow.engine.errors import BladewearError
    from workflow.engine.hb import HBProblem
    from workflow.engine.linear import condensed
    from workflow.engine.stability import hill_stability

    v = sweep.variant
    n = len(sweep.freqs_hz)
    stable = [None] * n
    fmax = np.full(n, np.nan)
    cache = {}          # the Ritz basis's eigenproblems, the same at every point
    t0 = time.perf_counter()
    for i in np.flatnonzero(sweep.converged):
        omega = 2 * np.pi * float(sweep.freqs_hz[i])
        c = _on_grid(grid, omega, v.nh) or condensed(rc, omega, v.nh)
        hb = HBProblem(c.Zr, c.Fr, law, v.nh, v.nit, v.method, static=static)
        x = hb.unknowns_from_harmonics(sweep.Ur[i])
        st = None
        # the Ritz basis needs a positive mass on the contact DOFs; a model with massless contact
        # nodes (the lumped verification cases) is small and takes the full δq instead
        for modes in (RITZ_FACTOR, None):
            try:
                st = hill_stability(model, hb, x, omega, rc=rc, modes=modes, nh_check=None, nit=nit, cache=cache)
                break
            except (BladewearError, np.linalg.LinAlgError, ValueError):
                continue
        if st is None:
            continue
        fmax[i] = st.floquet_max
        stable[i] = bool(st.stable)
    return {"stable": stable, "floquet_max": fmax, "seconds": time.perf_counter() - t0}


def _on_grid(grid, omega: float, nh: int):
    """The condensation of ``grid`` (kept whole) at ω [rad/s], harmonics 0…nh, or None."""
    from workflow.engine.condense import Condensed

    if grid is None or not grid.keep_all or grid.nh < nh:
        return None
    hit = np.flatnonzero(grid.omegas == omega)
    if not hit.size:
        return None
    c = grid[int(hit[0])]
    return Condensed(omega=c.omega, Zr=c.Zr[:nh + 1], Fr=c.Fr[:nh + 1])


def turning_points(freqs_hz, converged=None) -> list[int]:
    """Indices of the turning points (folds) of a swept path: the points where the frequency
    reverses, f[i] an extremum of f[i−1], f[i], f[i+1] along the path (an arc-length sweep
    passes them; a grid sweep never has one). Only converged neighbours count."""
    f = np.asarray(freqs_hz, dtype=float)
    ok = np.ones(len(f), bool) if converged is None else np.asarray(converged, bool)
    out = []
    for i in range(1, len(f) - 1):
        if ok[i - 1] and ok[i] and ok[i + 1] and (f[i] - f[i - 1]) * (f[i + 1] - f[i]) < 0:
            out.append(i)
    return out


def turning_point_rows(sweep) -> list[dict]:
    """Per turning point of ``sweep``: its frequency (Hz), amplitude (m) and, where the sweep's
    stability is known, whether it changes within one continuation step of it — a fold of a
    branch of periodic solutions is where a real Floquet multiplier crosses 1 (saddle-node), so
    the two sides of it differ in stability."""
    rows = []
    for i in turning_points(sweep.freqs_hz, sweep.converged):
        row = {"index": int(i), "frequency_hz": float(sweep.freqs_hz[i]), "amplitude_m": float(sweep.amplitude[i]),
               "stability_changes": None}
        if sweep.stable is not None:
            near = [sweep.stable[j] for j in range(max(i - 1, 0), min(i + 2, len(sweep.stable)))]
            if all(s is not None for s in near):
                row["stability_changes"] = len(set(near)) > 1
        rows.append(row)
    return rows
