"""The results: :class:`Backbone` (and its arrays from the continuation's points) and :class:`Synthesis`."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workflow.engine import fourier
from workflow.engine.contact import SEPARATION, STICK
from workflow.engine.dissipation import energy_per_cycle
from workflow.engine.studies.nlmodes.epmc import _EPMC
from workflow.engine.studies.nlmodes.structure import _Structure


@dataclass
class Backbone:
    """The EPMC backbone of one friction-damped mode (arrays over the points, SI).

    amplitude           modal amplitude a = √(q̂₁ᴴ M q̂₁) (m·√kg)
    frequency_hz        ω/2π of the periodic motion
    damping_ratio       D = ξ / (2ω)
    xi                  the negative mass-proportional damping ξ (1/s)
    energy_per_cycle_J  dissipated per cycle: structural (C) + friction (DLFT slip path)
    energy_friction_J, energy_structural_J: its two parts; energy_xi_J the work of ξM;
    energy_friction_hb_J the friction work of the truncated harmonics, ``∮ λ·u̇_r dt =
                        −π Σ_j j Im(Λ_jᴴ U_j)`` (the Galerkin energy balance: energy_xi_J =
                        energy_structural_J + energy_friction_hb_J to the solver's tolerance;
                        energy_friction_J, on the DLFT slip path by the trapezoidal rule, differs
                        from it by the rule's error, 1.6e-3 at nit = 64 on the Jenkins oscillator)
    observed            (n, Nh+1, n_obs) complex harmonics of the observed DOFs O q (m)
    Ur                  (n, Nh+1, 3p) complex harmonics of the relative contact DOFs (m)
    z1                  (n, m) complex first harmonic in the relative coordinates of
                        :func:`workflow.engine.condense.relative_coordinates` (z = [u_r; y], q = T z)
    stuck_pairs, separating_pairs, slipping_pairs (n,) pairs stuck all period, open at some
                        instant, slipping at some instant (and never open)
    converged, residual (scaled, dimensionless), iterations (Newton steps), nh, nit
    tied_hz, tied_damping_ratio: the linear tied mode (ω, D of the EPMC's small-amplitude limit)
    sliding_hz          the linear sliding mode (μ = 0, normal contact kept) closest to it (MAC)
    onset               modal amplitude of the first slip estimated from the tied mode
    seconds             wall time of :func:`backbone`; stopped: why it ended before the last
                        amplitude asked for ("" if it did not); walks: it ended because the
                        mode has no periodic motion beyond (the blade walks,
                        :func:`_unbalanced_mean_slip`) — the mode's end, not the solver's
    unknowns            (n, (2Nh+1)(3p+1) + 2) the solver's unknowns [X, ω, ξ] per point
    """

    amplitude: np.ndarray
    frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    xi: np.ndarray
    energy_per_cycle_J: np.ndarray
    energy_friction_J: np.ndarray
    energy_structural_J: np.ndarray
    energy_xi_J: np.ndarray
    energy_friction_hb_J: np.ndarray
    observed: np.ndarray
    Ur: np.ndarray
    z1: np.ndarray
    stuck_pairs: np.ndarray
    separating_pairs: np.ndarray
    slipping_pairs: np.ndarray
    converged: np.ndarray
    residual: np.ndarray
    iterations: np.ndarray
    nh: int
    nit: int
    mode: int
    tied_hz: float
    tied_damping_ratio: float
    sliding_hz: float
    onset: float
    seconds: float = 0.0
    stopped: str = ""
    walks: bool = False
    unknowns: np.ndarray | None = None
    info: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.amplitude)

    def rows(self) -> list[dict]:
        """One dict per point (for a CSV)."""
        obs = np.linalg.norm(self.observed[:, 1, :], axis=1) if len(self) else np.zeros(0)
        return [{"amplitude": float(self.amplitude[i]), "frequency_hz": float(self.frequency_hz[i]),
                 "damping_ratio": float(self.damping_ratio[i]), "xi_per_s": float(self.xi[i]),
                 "energy_per_cycle_J": float(self.energy_per_cycle_J[i]),
                 "energy_friction_J": float(self.energy_friction_J[i]),
                 "energy_structural_J": float(self.energy_structural_J[i]),
                 "energy_xi_J": float(self.energy_xi_J[i]), "observed_first_harmonic_m": float(obs[i]),
                 "stuck_pairs": int(self.stuck_pairs[i]), "slipping_pairs": int(self.slipping_pairs[i]),
                 "separating_pairs": int(self.separating_pairs[i]), "converged": bool(self.converged[i]),
                 "residual": float(self.residual[i]), "iterations": int(self.iterations[i]),
                 "nh": self.nh, "nit": self.nit} for i in range(len(self))]


@dataclass
class Synthesis:
    """Single-nonlinear-mode synthesis of the forced response (SI).

    freqs_hz         the frequencies asked for
    amplitude        (n_freq, k) observed first-harmonic amplitude ‖O q̂₁‖ (m) of each branch at
                     each frequency, ascending, NaN where fewer (k = most branches met)
    peak_hz, peak_amplitude_m, peak_modal_amplitude: the resonance (NaN if the force drives the
                     response beyond the backbone's last point)
    curve_amplitude  (n,) modal amplitudes of the backbone-parametrised FRF, with
    curve_low_hz, curve_high_hz (n,) its two frequencies (NaN where none), curve_observed_m (n,)
    force_norm_N     ‖f‖ of the load used
    """

    freqs_hz: np.ndarray
    amplitude: np.ndarray
    peak_hz: float
    peak_amplitude_m: float
    peak_modal_amplitude: float
    curve_amplitude: np.ndarray
    curve_low_hz: np.ndarray
    curve_high_hz: np.ndarray
    curve_observed_m: np.ndarray
    force_norm_N: float


def _states(res) -> tuple[int, int, int]:
    s = res.state
    stuck = int(np.sum(np.all(s == STICK, axis=0)))
    sep = int(np.sum(np.any(s == SEPARATION, axis=0)))
    return stuck, sep, int(s.shape[1]) - stuck - sep


def _backbone_of(prob: "_EPMC", st: "_Structure", law, amplitudes, unknowns) -> dict:
    """The :class:`Backbone` arrays of the points (a, v): frequency, damping, the energies per
    cycle, the deflections and the contact states."""
    nh, nit, nr = prob.nh, prob.nit, prob.nr
    n = len(amplitudes)
    f_hz, D, xi_ = np.zeros(n), np.zeros(n), np.zeros(n)
    e_f, e_c, e_x, e_h = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    obs = np.zeros((n, nh + 1, st.Ot.shape[0]), complex)
    Ur = np.zeros((n, nh + 1, nr), complex)
    z1 = np.zeros((n, st.m), complex)
    stuck, sep, slip = (np.zeros(n, int) for _ in range(3))
    j = np.arange(nh + 1)
    for i, (a, v) in enumerate(zip(amplitudes, unknowns)):
        prob.at(a)
        X, omega, xi = prob.split(v)
        c = prob.cond(omega, xi)
        _, _, res = prob.evaluate(v, jacobian=False)
        W = prob.harmonics_w(X, c)
        f_hz[i], xi_[i], D[i] = omega / (2 * np.pi), xi, xi / (2 * omega)
        e_f[i] = float(energy_per_cycle(res.lam[..., 1:], res.lam_x_T / law.eps_t[None, :, None]).sum())
        mq = np.real(np.einsum("jm,mn,jn->j", W.conj(), st.Mt, W))
        cq = np.real(np.einsum("jm,mn,jn->j", W.conj(), st.Ct, W))
        e_c[i] = np.pi * omega * float(np.sum(j ** 2 * cq))
        e_x[i] = xi * np.pi * omega * float(np.sum(j ** 2 * mq))
        Lh = fourier.to_freq(res.lam.reshape(nit, nr), nh)
        e_h[i] = -np.pi * float(np.sum(j * np.imag(np.sum(Lh.conj() * W[:, :nr], axis=1))))
        obs[i] = W @ st.Ot.T
        Ur[i] = W[:, :nr]
        z1[i] = st.T @ W[1]
        stuck[i], sep[i], slip[i] = _states(res)
    return dict(amplitude=np.array(amplitudes), frequency_hz=f_hz, damping_ratio=D, xi=xi_,
                energy_per_cycle_J=e_f + e_c, energy_friction_J=e_f, energy_structural_J=e_c, energy_xi_J=e_x,
                energy_friction_hb_J=e_h, observed=obs, Ur=Ur, z1=z1, stuck_pairs=stuck, separating_pairs=sep,
                slipping_pairs=slip)
