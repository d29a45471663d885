"""Friction-damped nonlinear modes (EPMC) and single-nonlinear-mode synthesis (issue #49).

Extended periodic motion concept (Krack 2015, J. Sound Vib. 343, 'Nonlinear modal analysis
of nonconservative systems: extension of the periodic motion concept'): the autonomous system

    M q̈ + (C − ξ M) q̇ + K q + Bᵀ λ(B q) = f_static

(the static preload stays, the harmonic load is removed) has, for every modal amplitude a,
a periodic motion of frequency ω whose dissipation — structural (C) and friction (λ) — is
exactly compensated by the artificial negative mass-proportional damping ξ M. The mode's
damping ratio is D = ξ / (2ω). Unknowns: the harmonics 0…Nh of the motion, ω and ξ;
two more equations: the amplitude ``a² = q̂₁ᴴ M q̂₁`` (Krack's mass-weighted first-harmonic
norm) and a phase condition.

Formulation (why, measured on the quick sector, m = 110, 16 pairs, Nh = 7):

* **Not the condensed relative DOFs alone.** At small amplitude every pair sticks and the
  relative harmonics U_r vanish: the motion is the tied structure's, at the pole of Z_r(ω).
  A residual on U_r alone (as :class:`~workflow.engine.hb.HBProblem`) has no amplitude there.
* **Not the full q either**: (2Nh+1)·m = 1650 unknowns, a dense LU of ~0.3 s per Newton step.
* **U_r plus one tied modal coordinate η.** With ``z = [u_r; y]`` the relative coordinates of
  :mod:`workflow.engine.condense` and ``y = Φ η`` the tied structure's modes (``M_yy``-normalised,
  the one of ``mode`` first), the unknowns are, per harmonic, the 3p relative DOFs and η of
  the chosen tied mode; every other tied mode is condensed out exactly (Schur complement,
  one LU of a (m − 3p − 1) block per harmonic, recomputed for each (ω, ξ) with its
  ω- and ξ-derivatives). (2Nh+1)(3p+1) + 2 = 737 unknowns on the quick sector: a dense LU
  of ~10 ms. η carries the amplitude at the tied limit and the phase condition
  (sine coefficient of η's first harmonic = 0), and the other modes stay regular near ω.
* **The DLFT** is the engine's (:func:`workflow.engine.contact.dlft`, the periodic passes and
  their exact Jacobian, HBM Galerkin projection Q), on the predictor
  ``a = F − Z x + ε (u_r + gap)`` of the contact rows, with the static state's stick anchor
  (:func:`workflow.engine.studies.study.static_state`), exactly as the forced HB.
* **Continuation** in log a, natural parameter (the backbone is single-valued in a), a secant
  predictor on (harmonics / a, ω, ξ), steps halved where Newton fails.

Energies per cycle (J): ``energy_xi_J`` the work the negative damping ξM feeds in,
``ξ π ω Σ_j j² q̂_jᴴ M q̂_j``; ``energy_structural_J`` dissipated by C,
``π ω Σ_j j² q̂_jᴴ C q̂_j``; ``energy_friction_J`` dissipated by friction along the DLFT slip
path (:func:`workflow.engine.dissipation.energy_per_cycle`); ``energy_per_cycle_J`` = structural
+ friction (equal to ``energy_xi_J`` at a root: the Galerkin energy balance, up to the DLFT
slip path's difference from the truncated harmonics).

Single-nonlinear-mode synthesis (Krack, Panning-von Scheidt, Wallaschek 2014, J. Sound Vib.
332, 'A method for nonlinear modal analysis and synthesis'): near the mode's resonance the
forced response is ``q̂₁ ≈ a ψ(a)`` with ψ the mass-normalised first-harmonic deflection and

    [−Ω² + 2iΩ D(a) ω(a) + ω(a)²] a = ψ(a)ᴴ f,

solved here for every backbone amplitude (the FRF as a curve in a, both branches), the peak
where the two branches meet (``Ω = ω √(1 − 2D²)``, ``|ψᴴ f| = 2Dω² √(1 − D²) a``).

Units SI; the modal amplitude a in m·√kg (``q̂₁ᴴ M q̂₁``).

Modules, each importing only those above it:

* :mod:`.structure` — the model in tied-mode coordinates and its condensation at (ω, ξ);
* :mod:`.epmc` — the EPMC residual and Jacobian at one modal amplitude;
* :mod:`.limits` — the static state, the slip onset and :func:`linear_limits` (tied and sliding modes);
* :mod:`.walk` — the diagnosis of a backbone that ends because the blade walks;
* :mod:`.results` — :class:`Backbone` (its arrays from the points) and :class:`Synthesis`;
* :mod:`.continuation` — :func:`backbone`: pseudo-arclength continuation from the tied mode;
* :mod:`.synthesis` — :func:`synthesize`: the forced response from the backbone.
"""
from __future__ import annotations

# every public name of the former single module stays reachable as ``nlmodes.<name>``
from workflow.engine.studies.nlmodes.walk import NULL_MAX_UNKNOWNS, NULL_RATIO, NULL_SHARE, WALK_ITERATIONS, WALKS
from workflow.engine.studies.nlmodes.limits import linear_limits
from workflow.engine.studies.nlmodes.results import Backbone, Synthesis
from workflow.engine.studies.nlmodes.continuation import DEFAULT_POINTS, DEFAULT_RANGE, JUMPS, MIN_SHORT, TOL
from workflow.engine.studies.nlmodes.continuation import backbone
from workflow.engine.studies.nlmodes.synthesis import synthesize

__all__ = ["Backbone", "Synthesis", "backbone", "synthesize", "linear_limits"]
