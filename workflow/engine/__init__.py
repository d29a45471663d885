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
  the reference wear march and pseudo-time to the worn steady state.

Everything takes a :class:`reduction.reduced.ReducedModel` (the seam with the
finite-element half) and returns arrays and result objects; nothing here
reads a scene or writes a file.
"""
from workflow.engine import penalty
from workflow.engine.cascade import PointResult, solve_point
from workflow.engine.studies.frf import SweepResult
from workflow.engine.studies.study import FRFOptions, FRFStudy, contact_law, frf, static_state
from workflow.engine.studies.variants import Variant, variants
from workflow.engine.studies.wearstudy import WearOptions, WearStudy, worn_steady_state

__all__ = ["FRFOptions", "FRFStudy", "PointResult", "SweepResult", "Variant", "contact_law", "frf",
           "WearOptions", "WearStudy", "penalty", "solve_point", "static_state", "variants",
           "worn_steady_state"]
