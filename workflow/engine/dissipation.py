"""Energy dissipated by friction over one period of a harmonic-balance solution.

With the sign convention of :mod:`workflow.engine.contact` (the disk pushes the
blade with −λ), the friction force on the blade is −λ_T and the work it
does over a period is −∮ λ_T · du_T; the energy dissipated per cycle is its
opposite,

    E_i = ∮ λ_T,i · dX_T,i  ≥ 0     [J],

taken along the DLFT slip path X_T (eq. 11), which is constant while a pair
sticks — so stick dissipates exactly nothing, like the wear kernel of
:mod:`workflow.engine.wear` (eq. 21), which integrates the same path. The
integral is the trapezoidal rule over the ``nit`` periodic time samples.
"""
from __future__ import annotations

import numpy as np


def energy_per_cycle(lam_T: np.ndarray, slip: np.ndarray) -> np.ndarray:
    """Friction energy dissipated per cycle by each pair, (p,) [J].

    lam_T: (nit, p, 2) tangential multipliers λ_T [N] over one period;
    slip:  (nit, p, 2) tangential slip path X_T [m] at the same samples.
    Trapezoidal in λ_T with the periodic wrap (sample −1 ↦ nit−1).
    """
    lam_T = np.asarray(lam_T, dtype=float)
    slip = np.asarray(slip, dtype=float)
    if lam_T.shape != slip.shape or lam_T.ndim != 3:
        raise ValueError(f"energy_per_cycle: lam_T {lam_T.shape} and slip {slip.shape} must both be (nit, p, 2)")
    d = slip - np.roll(slip, 1, axis=0)
    mean = 0.5 * (lam_T + np.roll(lam_T, 1, axis=0))
    return np.sum(mean * d, axis=(0, 2))
