"""Row/column equilibration of the HB residual (:func:`scaling`) and the conditioning of its Jacobian."""
from __future__ import annotations

import numpy as np

from workflow.engine.hb import HBProblem


def scaling(prob: HBProblem, x0: np.ndarray, J0: np.ndarray | None = None):
    """Row and column scalings (r, c) of the residual: R̂(z) = r ⊙ R(c ⊙ z).

    Rows: 1/‖F‖ per unknown block … refined by one equilibration pass, so the
    scaled Jacobian diag(r) J diag(c) has unit row and column max-norms;
    columns: a characteristic displacement per unknown. Returned as
    positive (n,) arrays.
    """
    if J0 is None:
        _, J0 = prob.residual_jacobian(x0)
    A = np.abs(J0)
    c = 1.0 / np.sqrt(np.maximum(A.max(axis=0), 1e-300))     # characteristic displacement ~ 1/√k
    A = A * c[None, :]
    r = 1.0 / np.maximum(A.max(axis=1), 1e-300)
    A = A * r[:, None]
    c2 = 1.0 / np.maximum(A.max(axis=0), 1e-300)
    return r, c * c2


def conditioning(prob: HBProblem, x: np.ndarray) -> tuple[float, float]:
    """cond₂(J) and cond₂ of the scaled J at x (see :func:`scaling`)."""
    _, J = prob.residual_jacobian(x)
    r, c = scaling(prob, x, J)
    with np.errstate(all="ignore"):
        return float(np.linalg.cond(J)), float(np.linalg.cond(r[:, None] * J * c[None, :]))
