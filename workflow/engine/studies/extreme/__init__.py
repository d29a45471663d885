"""Stiff and extreme cases: does every solve converge to the right answer or say why not?

A matrix run (issue 8) on any :class:`workflow.engine.model.ReducedModel`: for
each *case* (a change of the penalty, friction, excitation, preload, gap,
resolution, frequency, wear or conditioning) and each formulation
(hbm / tcm / hdhb) and solver (newton / powell / pseudo-time), one
:class:`CaseResult`: converged or not, iterations, seconds, the error against
the limit the case must approach (where one exists) and a diagnosis naming
the cause when it did not converge (empty when it did).

Nothing here trusts a solver's "converged": :func:`verify` re-evaluates the
residual at the returned point, checks it is finite, that the DLFT periodic
passes converged there, and that the contact forces obey Coulomb and
unilaterality; a solve that fails any of these is reported as not converged
with that diagnosis. Non-finite numbers never reach the results (errors are
``None`` when there is nothing to compare).

Limits (all on the relative displacements U_r, harmonics ≥ 1 unless said;
``rel(a, b) = ‖a − b‖ / ‖b‖``):

* penalty ε·s, s ∈ 10⁻³…10³: DLFT's promise — the solution equals the one at
  s = 1 (all harmonics, including the static one);
* μ = 0: the *free* limit — λ_T ≡ 0; if the contact stays closed the normal
  relative motion is tied (U_N,j = 0, j ≥ 1) and the tangential one free:
  ``Z_TT U_T = F_T`` computed directly from Zr (:func:`free_limit`);
* μ → ∞ and excitation → 0: the *tied* limit U_r,j = 0 (j ≥ 1), measured
  relative to the free response at the same excitation;
* contact open all period (gap larger than the static approach, or preload
  pulling the blade out): the linear response without contact
  ``U_j = Zr_j⁻¹ Fr_j`` (all harmonics).

Units SI; frequencies in rad/s inside, Hz in the tables.

Modules, each importing only those above it:

* :mod:`.synthetic` — :func:`synthetic_model`, the small reduced model standing in for the FE one;
* :mod:`.settings` — :class:`Settings`, :class:`Setup` and :func:`setup` (reference frequencies, ε_ref);
* :mod:`.cases` — :class:`Case`, :func:`build_cases` (the case list) and :class:`CaseResult` (a row);
* :mod:`.hbproblem` — the HB problem of a case and method (:func:`condensed`, :func:`problem`);
* :mod:`.limits` — the closed-form limits (constrained, free, tied, open responses);
* :mod:`.checks` — :func:`verify`, :func:`tolerance` and the error against the case's reference;
* :mod:`.equilibration` — row/column scaling (:func:`scaling`) and :func:`conditioning` of the Jacobian;
* :mod:`.diagnosis` — why a solve failed, or converged off its reference;
* :mod:`.runner` — :func:`run_case` (one solve, wear cases included) and :func:`run_matrix`;
* :mod:`.report` — :func:`to_csv`, :func:`to_markdown`, :func:`is_off`, :func:`off_without_diagnosis`.
"""
from __future__ import annotations

# every public name of the former single module stays reachable as ``extreme.<name>``
from workflow.engine.studies.extreme.synthetic import synthetic_model
from workflow.engine.studies.extreme.settings import GROUPS, METHODS, SOLVERS, Settings, Setup, setup
from workflow.engine.studies.extreme.cases import Case, CaseResult, build_cases
from workflow.engine.studies.extreme.hbproblem import condensed, problem
from workflow.engine.studies.extreme.limits import (constrained_response, free_first_order, free_limit, linear_open,
                                                     tied_limit, tied_scale)
from workflow.engine.studies.extreme.checks import FIRST_ORDER_SMALL, TOL_LIMIT, TOL_PENALTY, tolerance, verify
from workflow.engine.studies.extreme.equilibration import conditioning, scaling
from workflow.engine.studies.extreme.runner import run_case, run_matrix
from workflow.engine.studies.extreme.report import is_off, off_without_diagnosis, to_csv, to_markdown

__all__ = ["GROUPS", "METHODS", "SOLVERS", "Settings", "Setup", "Case", "CaseResult", "synthetic_model",
           "setup", "build_cases", "run_case", "run_matrix", "verify", "free_limit", "tied_scale",
           "linear_open", "conditioning", "to_csv", "to_markdown", "tolerance", "free_first_order", "is_off",
           "off_without_diagnosis"]
