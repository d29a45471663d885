"""bladewear's numerical engine: harmonic balance with DLFT friction contact and fretting wear.

The front door — what a user of the library calls (``examples/`` shows it
on a user's bundle; ``docs/architecture.md`` shows where everything lives):

* :func:`contact_law` (model, μ, ε, gap) → :class:`~workflow.engine.contact.ContactLaw`
  with the penalties chosen once (:mod:`workflow.engine.penalty`);
* :func:`frf` (model, law, variants, band, options) → :class:`FRFStudy`:
  swept FRFs (grid or arc-length), seeded reference, error against run
  time, linear tied/sliding limits, ε-check and the reference's convergence;
* :func:`solve_point` — one frequency through the solver cascade;
* :func:`worn_steady_state` (model, law, options) → :class:`WearStudy`:
  the reference wear march and pseudo-time to the worn steady state, at a fixed
  frequency or a detuning of the friction-damped resonance, with its measures;
* :func:`backbone` (model, law) → :class:`~workflow.engine.studies.nlmodes.Backbone`: the
  friction-damped nonlinear mode by EPMC, and :func:`synthesize` the forced
  response from it (single-nonlinear-mode synthesis);
* :func:`hill_stability` (model, hb, x, ω) → :class:`~workflow.engine.stability.Stability`:
  the Floquet multipliers of a periodic HB solution.

Everything takes a :class:`ReducedModel` (:mod:`workflow.engine.model`, the
seam with the finite-element half; :mod:`workflow.engine.condense` condenses it
onto the relative contact coordinates) and returns arrays and result objects;
nothing here reads a scene, and the only file it writes is a model's own
(:meth:`ReducedModel.save`). The engine imports nothing of the application.
"""
from workflow.engine import penalty
from workflow.engine.cascade import PointResult, solve_point
from workflow.engine.model import ReducedModel
from workflow.engine.studies.frf import SweepResult
from workflow.engine.studies.study import FRFOptions, FRFStudy, contact_law, frf, static_state
from workflow.engine.studies.variants import Variant, variants
from workflow.engine.studies.wearstudy import WearOptions, WearStudy, worn_steady_state
from workflow.engine.studies.nlmodes import backbone, synthesize
from workflow.engine.stability import hill_stability

__all__ = ["FRFOptions", "FRFStudy", "PointResult", "ReducedModel", "SweepResult", "Variant", "contact_law", "frf",
           "WearOptions", "WearStudy", "backbone", "hill_stability", "penalty", "solve_point", "static_state",
           "synthesize", "variants", "worn_steady_state"]
