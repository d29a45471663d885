"""Floquet stability of periodic harmonic-balance solutions (issue #49).

* :mod:`.tangent` — the DLFT contact law linearised along the period (anchors as states);
* :mod:`.switches` — that law on the monodromy's pieces, every switch located in its interval;
* :mod:`.monodromy_matrix` — the monodromy matrix by backward Euler, Richardson-extrapolated;
* :mod:`.hill` — Hill's method (the frequency-domain pencil and its exponent selection);
* :mod:`.floquet` — :func:`hill_stability`, the front door on a reduced model.
"""
from workflow.engine.stability.floquet import EPS_FACTOR, STABLE_TOL, Stability, hill_stability
from workflow.engine.stability.hill import HillResult, hill_descriptor, hill_exponents
from workflow.engine.stability.monodromy_matrix import monodromy
from workflow.engine.stability.tangent import contact_tangent, tangent_blocks

__all__ = ["Stability", "HillResult", "hill_exponents", "hill_descriptor", "hill_stability",
           "contact_tangent", "tangent_blocks", "monodromy", "EPS_FACTOR", "STABLE_TOL"]
