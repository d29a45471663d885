"""What the matrix runs with (:class:`Settings`) and what every case derives from the model (:func:`setup`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from workflow.engine.condense import condense, relative_coordinates
from workflow.engine.model import ReducedModel
from workflow.engine import penalty
from workflow.engine.linear import tied_modes

METHODS = ("hbm", "tcm", "hdhb")
SOLVERS = ("newton", "powell", "pseudo-time")
GROUPS = ("penalty", "friction", "excitation", "contact", "resolution", "frequency", "wear", "conditioning",
          "divergence")


@dataclass
class Settings:
    """What the matrix runs with (from the scene's [contact], [hb], [extreme], [excitation])."""

    mu: float = 0.5
    eps_n: float = 0.0           # 0: reference stiffness (see :func:`setup`)
    eps_t: float = 0.0
    gap: float = 0.0             # added to the model's gaps (m)
    max_passes: int = 30
    amplitude: float = 0.1       # N: the excitation the model's f_harmonic stands for
    nh: int = 3
    nit: int = 32
    frequency_ratio: float = 0.97  # ω / ω_tied of the base cases
    tol: float = 1e-8
    max_iterations: int = 100
    pseudo_steps: int = 400
    methods: tuple = METHODS
    solvers: tuple = SOLVERS
    groups: tuple = GROUPS
    max_harmonics: int = 31
    max_time_samples: int = 1024
    penalty_decades: int = 3
    excitation_factors: tuple = (1e-6, 1e-4, 1e-2, 1.0, 1e1, 1e2, 1e3)
    wear_blocks: int = 30        # reference march: blocks at most
    wear_k: float = 1e-11        # m²/N: "very large" Archard coefficient (paper-like: 1e-13)
    extra_modes: int = 12        # conditioning case (synthetic models only)
    spread: float = 1e3


@dataclass
class Setup:
    """The model and what every case derives from it."""

    model: ReducedModel
    rc: object
    settings: Settings
    omega_tied: float            # rad/s, first tied resonance (pole of Zr)
    omega_free: float            # rad/s, free-interface resonance nearest above it (zero of Zr)
    omega: float                 # rad/s, base frequency
    eps_ref: np.ndarray          # (p, 2) [ε_N, ε_T] per pair: the reference stiffness (N/m)

    @property
    def p(self) -> int:
        return self.model.n_pairs


def _eig_freqs(K, M) -> np.ndarray:
    w2 = scipy.linalg.eigh(K, M, eigvals_only=True)
    return np.sqrt(np.maximum(w2, 0.0))


def setup(model: ReducedModel, settings: Settings | None = None) -> Setup:
    """Relative coordinates, reference frequencies and penalty of ``model``.

    * ω_tied: lowest eigenfrequency of the structure with the interface tied
      (the y–y block of the relative coordinates; Zr has a pole there,
      bounded only by damping) — "at resonance";
    * ω_free: the free-interface eigenfrequency (the whole K, M) nearest
      above 1.05 ω_tied (Zr is singular there up to damping; the response
      of the separated/slipping structure resonates) — "anti-resonance" of
      the tied response seen from the interface;
    * ε_ref: each pair's static condensed stiffness
      (:func:`workflow.engine.penalty.reference_stiffness`, the bounds of the
      application's automatic penalty are multiples of it), so the penalty
      cases span ε/k = 10⁻³…10³ around the interface's own stiffness; the
      automatic penalty lies between 1× (the dovetail) and 10³× (a bare mass).
    """
    s = settings or Settings()
    model.validate()
    rc = relative_coordinates(model)
    ft = 2 * np.pi * tied_modes(rc)[0]      # the FRF's and the wear's tied frequencies, not a second eigh
    omega_tied = float(ft[ft > 1e-6 * max(ft.max(), 1.0)][0])
    ff = _eig_freqs(rc.K, rc.M)
    above = ff[ff > 1.05 * omega_tied]
    omega_free = float(above[0]) if above.size else 2.0 * omega_tied
    omega = s.frequency_ratio * omega_tied
    eps_ref = penalty.reference_stiffness(condense(rc, 0.0, 0).Zr[0])
    return Setup(model=model, rc=rc, settings=s, omega_tied=omega_tied, omega_free=omega_free,
                 omega=omega, eps_ref=eps_ref)
