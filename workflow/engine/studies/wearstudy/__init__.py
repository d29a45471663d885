"""The engine's front door for fretting wear: :func:`worn_steady_state` (paper §4, §5.2).

A reduced model, a contact law and :class:`WearOptions` in; a
:class:`WearStudy` out: the unworn HB point (solved by Newton and by
pseudo-time from the same start), one :class:`~workflow.engine.wear.WearHistory`
per method — the physical-time reference march ("explicit" / "implicit"
blocks of cycles, :func:`workflow.engine.wear.march_reference`) and "pseudo-time"
(eq. 22, :func:`workflow.engine.wear.pseudo_time_wear`) — the worn profiles'
agreement, the reference's own convergence in its block size, and the
ε-check of the wear rates.

The operating point (:mod:`workflow.engine.studies.operating`) sets where the vibration is:
one frequency ("frequency", "detuning"); a resonance dwell ("resonance", :func:`.dwell._dwell`: the
march in stages, the excitation moved to the peak of the worn system between them); or a duty
cycle ("mission": one vibration per operating point, the wear rates summed with the shares,
:class:`~workflow.engine.studies.operating.MissionProblem`).

Modules, each importing only those above it:

* :mod:`.options` — :class:`WearOptions`, :class:`WearStudy` and what to change where a march did not settle;
* :mod:`.points` — a held amplitude's or a mission's operating points, and a problem of the same kind from them;
* :mod:`.unworn` — the HB problem at the wear frequency, the unworn point, Newton against pseudo-time;
* :mod:`.marching` — :func:`march` to the worn steady state, and along a dwell's stages;
* :mod:`.finer_nh` — the problem at Nh × 1.5 and :func:`finer_nh_resolve` of a lost vibration;
* :mod:`.measures` — the worn state's measures, friction energy per cycle and resonance shift;
* :mod:`.mission` — a duty cycle's stacked points and their wear rates new and worn;
* :mod:`.dwell` — the resonance dwell: the march in stages following the worn system's peak;
* :mod:`.checks` — :func:`eps_check`, :func:`nh_check` and :func:`reference_check`;
* :mod:`.steady` — :func:`worn_steady_state`, every method's march, the measures and the checks.
"""
from __future__ import annotations

from workflow.engine.studies.wearstudy.checks import CHECK_RTOL, CHECK_STEPS, eps_check, nh_check, reference_check
from workflow.engine.studies.wearstudy.dwell import DWELL_FIRST
from workflow.engine.studies.wearstudy.finer_nh import finer_nh_resolve
from workflow.engine.studies.wearstudy.marching import march
from workflow.engine.studies.wearstudy.options import DWELL_UNFINISHED, METHODS, WearOptions, WearStudy
from workflow.engine.studies.wearstudy.steady import worn_steady_state
from workflow.engine.studies.wearstudy.unworn import (START_SCALES, build_problem, first_tied_frequency,
                                                      unworn_point, unworn_solvers)

__all__ = ["CHECK_RTOL", "CHECK_STEPS", "DWELL_FIRST", "DWELL_UNFINISHED", "METHODS", "START_SCALES", "WearOptions",
           "WearStudy", "build_problem", "eps_check", "finer_nh_resolve", "first_tied_frequency", "march",
           "nh_check", "reference_check", "unworn_point", "unworn_solvers", "worn_steady_state"]
