"""Verification of the friction solves against references written from the literature (issue 15, item 6).

Nothing here uses the project's HB/DLFT code except :mod:`workflow.verification.runner`,
whose one function :func:`~workflow.verification.runner.hb_first_harmonic` is the
single call into it.

* :mod:`.exact` — closed forms: Den Hartog's non-stop Coulomb oscillator, the
  Jenkins element's energy per cycle, the linear (tied / free) limits;
* :mod:`.timeint` — event-driven stick–slip time integration to the periodic
  steady state (1-DOF with stops and viscous damping; structures with
  grounded Jenkins pads and motion-dependent normal load);
* :mod:`.galerkin` — Galerkin HB with the exact sign law (HB's own truncation floor);
* :mod:`.models` — the cases as :class:`workflow.engine.model.ReducedModel`;
* :mod:`.runner` — the project's HB on those models, compared with the references.
"""
