"""Archard fretting wear on the harmonic-balance solution, to the worn steady state (paper eqs. 20–22).

* :mod:`.law` — the wear per cycle of every pair (eq. 21/22b) and the law with a length scale;
* :mod:`.problem` — the coupled problem R(x; W) = 0 with the rates, one state and its derivatives;
* :mod:`.history` — a march's path and its worn-steady-state test;
* :mod:`.reference` — the reference march in physical time by blocks of cycles (paper refs. 5, 7);
* :mod:`.pseudotime` — the pseudo-time march (eq. 22), with :mod:`.structured` its matrix-free step;
* :mod:`.measures` — measures of a worn state that can converge with the contact mesh.
"""
from workflow.engine.wear.history import WearHistory
from workflow.engine.wear.law import pressure, profile_rel_diff, slip_increments, tip_cycle, wear_per_cycle
from workflow.engine.wear.problem import WearProblem, WearState
from workflow.engine.wear.pseudotime import pseudo_time_wear
from workflow.engine.wear.reference import march_reference

__all__ = ["slip_increments", "wear_per_cycle", "pressure", "WearProblem", "WearState", "WearHistory",
           "march_reference", "pseudo_time_wear", "profile_rel_diff", "tip_cycle"]
