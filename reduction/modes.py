"""Eigenfrequencies of the full model, interface tied or free (contracts §2).

``u = T v`` (:func:`reduction.constraints.constraint_map`) drops the clamped
DOFs and, when tied, bonds each blade flank DOF to its disk partner; the
eigenproblem is then ``Tᵀ K T φ = ω² Tᵀ M T φ`` solved by shift-invert SLEPc
(:func:`reduction.eigen.eigs`).
"""
from __future__ import annotations

import numpy as np

from reduction.bundle import Bundle
from reduction.constraints import constrain, constraint_map
from reduction.eigen import eigs, frequencies_hz

#: Default shift [rad²/s²]: slightly negative so that rigid-body modes (a free
#: blade when the interface is not tied) sit at ω² = 0 without a singular
#: factorisation, yet small next to any elastic mode of a blade (≥ ~10 Hz).
SIGMA = -(2 * np.pi * 10.0) ** 2


def modes(bundle: Bundle, n_modes: int, tied: bool = True, sigma: float = SIGMA, vectors: bool = True):
    """Lowest ``n_modes`` modes: ``(f_hz, omega2, Phi)``, Phi (n_dofs, n_modes) in full DOFs (or None)."""
    T = constraint_map(bundle, tied=tied)
    omega2, phi = eigs(constrain(bundle.K, T), constrain(bundle.M, T), n_modes, sigma=sigma, vectors=vectors)
    return frequencies_hz(omega2), omega2, (T @ phi if phi is not None else None)


def frequencies(bundle: Bundle, n_modes: int, tied: bool = True, sigma: float = SIGMA) -> np.ndarray:
    """Lowest ``n_modes`` eigenfrequencies [Hz] of the constrained full model."""
    return modes(bundle, n_modes, tied, sigma, vectors=False)[0]
