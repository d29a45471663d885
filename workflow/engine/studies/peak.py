"""The friction-damped peak of a swept FRF: the largest grid point, refined between its neighbours.

The FRF study's headline peak, the contact-mesh study and the new-vs-worn
comparison of the remap stage all refine their peak here.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Peak:
    """A refined friction-damped peak: ``hz`` [Hz], ``amplitude`` [m] (first harmonic at the
    observed DOFs), ``Ur`` its relative harmonics, ``cond`` its condensed point, ``evaluations``
    (frequencies solved, grid included), ``grid_index`` of the largest grid point."""

    hz: float
    amplitude: float
    Ur: np.ndarray
    cond: object
    evaluations: int
    grid_index: int


#: Solved points on either side closer than this many grid steps seed the peak search's
#: next point by interpolation (:func:`refine_peak`).
SEED_SPAN = 0.1


def refine_peak(rc, sweep, law, static, variant, xtol_hz: float, **kw) -> Peak | None:
    """The friction-damped peak of a grid ``sweep`` refined by a bounded scalar search
    (Brent, :func:`scipy.optimize.minimize_scalar`, to ``xtol_hz`` [Hz]) between the
    grid neighbours of its largest converged point; each evaluation is one
    :func:`workflow.engine.studies.frf.sweep_variant` point seeded by the nearest solved one (or the
    interpolation between the two around it, once they are close).
    ``kw``: sweep_variant's solver options. None if no grid point converged.

    The evaluations share one structured linear solve where the problem takes it: the points
    are close, so the last one's lagged blocks precondition the next, which then needs no
    factorisation of its own (512 pairs, 16 points: 55.1 → 39.7 s, the peak the same to 4e-11)."""
    from scipy.optimize import minimize_scalar

    from workflow.engine.cascade import linear_solver
    from workflow.engine.linear import condensed
    from workflow.engine.studies.frf import sweep_variant
    from workflow.engine.linsolve import StructuredSolve

    if not sweep.converged.any():
        return None
    grid = np.asarray(sweep.freqs_hz, dtype=float)
    solved = {float(f): (float(a), U, None) for f, a, U, ok in
              zip(grid, sweep.amplitude, sweep.Ur, sweep.converged) if ok}

    step = float(np.min(np.diff(grid))) if len(grid) > 1 else 0.0
    n = (2 * variant.nh + 1) * 3 * law.p                   # unknowns of one point
    shared = StructuredSolve() if linear_solver(n) == "structured" else None

    def seed(f):
        """The nearest solved harmonics, or, once solved points on either side of f are within
        :data:`SEED_SPAN` grid steps of each other, the linear interpolation between them.
        Measured on paper-frf's reference (HBM-25 nit = 128): the search's later points took
        1–2 Newton iterations from the interpolation where they took 2–4 from the nearest
        point; across a whole grid step near the resonance the interpolation is worse
        (one point fell to Powell, 157 iterations)."""
        below = max((g for g in solved if g <= f), default=None)
        above = min((g for g in solved if g >= f), default=None)
        if below is None or above is None or not 0.0 < above - below <= SEED_SPAN * step:
            return solved[min(solved, key=lambda g: abs(g - f))][1]
        w = (f - below) / (above - below)
        return (1.0 - w) * solved[below][1] + w * solved[above][1]

    def minus_amplitude(f):
        c = condensed(rc, 2 * np.pi * f, variant.nh)
        seed_ = seed(f)
        r = sweep_variant(rc, [c], law, static, variant, seeds=[seed_], linsolver=shared, **kw)
        if not r.converged[0]:
            return 0.0  # an unconverged point cannot be the peak
        a = float(r.amplitude[0])
        if a > max(v[0] for v in solved.values()):
            # only the highest point keeps its condensation, the one Peak returns: 302 MB a
            # point at 512 pairs, which the search's 16 points used to hold all at once
            for g, v in solved.items():
                solved[g] = v[:2] + (None,)
        else:
            c = None
        solved[float(f)] = (a, r.Ur[0], c)
        return -a

    i = int(np.argmax(np.where(sweep.converged, sweep.amplitude, -np.inf)))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    if hi > lo:
        minimize_scalar(minus_amplitude, bounds=(lo, hi), method="bounded", options={"xatol": xtol_hz})
    f_pk = max(solved, key=lambda g: solved[g][0])
    a_pk, U_pk, c_pk = solved[f_pk]
    c_pk = condensed(rc, 2 * np.pi * f_pk, variant.nh) if c_pk is None else c_pk
    return Peak(hz=f_pk, amplitude=a_pk, Ur=U_pk, cond=c_pk, evaluations=len(solved), grid_index=i)


def peak(r) -> tuple[float | None, float | None]:
    """(frequency [Hz], amplitude [m]) of the largest converged point of a
    :class:`~workflow.engine.studies.frf.SweepResult`; (None, None) if none converged."""
    if not r.converged.any():
        return None, None
    a = np.where(r.converged, r.amplitude, -np.inf)
    i = int(np.argmax(a))
    return float(r.freqs_hz[i]), float(a[i])
