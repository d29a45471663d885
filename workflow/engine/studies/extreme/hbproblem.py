"""The HB problem of one case and formulation: its condensation, contact law and loads."""
from __future__ import annotations

import numpy as np

from workflow.engine.condense import condense, relative_coordinates
from workflow.engine.model import ReducedModel
from workflow.engine import penalty
from workflow.engine.contact import ContactLaw
from workflow.engine.hb import HBProblem
from workflow.engine.studies.extreme.cases import Case
from workflow.engine.studies.extreme.settings import Setup


def _model_for(su: Setup, case: Case):
    if case.model is None:
        return su.model, su.rc
    return case.model, relative_coordinates(case.model)


def _law(su: Setup, case: Case, model: ReducedModel) -> ContactLaw:
    s = su.settings
    p = model.n_pairs
    ref = su.eps_ref if model is su.model else penalty.reference_stiffness(
        condense(relative_coordinates(model), 0.0, 0).Zr[0])
    eN = s.eps_n if s.eps_n > 0 else ref[:, 0]
    eT = s.eps_t if s.eps_t > 0 else ref[:, 1]
    gap = np.asarray(model.gap, dtype=float) + s.gap + np.broadcast_to(case.gap, (p,))
    return ContactLaw(mu=np.full(p, case.mu), eps_n=eN * case.eps_scale, eps_t=eT * case.eps_scale, gap=gap)


def condensed(su: Setup, case: Case):
    """(Zr, Fr) of the case: the condensation at ω with loads scaled (Nh+1 harmonics)."""
    model, rc = _model_for(su, case)
    nh = su.settings.nh if case.nh is None else case.nh
    c = condense(rc, case.omega, nh)
    Zr, Fr = c.Zr.copy(), c.Fr.copy()
    Fr[0] = np.real(Fr[0]) * case.static_scale
    Fr[1:] *= case.force_scale
    return model, Zr, Fr, nh


def problem(su: Setup, case: Case, method: str) -> HBProblem:
    """The HB problem of one case and method."""
    s = su.settings
    model, Zr, Fr, nh = condensed(su, case)
    nit = s.nit if case.nit is None else case.nit
    nit = max(nit, 2 * nh + 1)
    if method == "hdhb":
        nit = 2 * nh + 1
    law = _law(su, case, model)
    return HBProblem(Zr, Fr, law, nh, nit, method, max_passes=s.max_passes)
