"""The case list of issue 8 (:func:`build_cases`) and one row of the matrix (:class:`CaseResult`)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from workflow.engine.condense import condense
from workflow.engine.model import ReducedModel
from workflow.engine.studies.extreme.settings import Setup
from workflow.engine.studies.extreme.synthetic import synthetic_model


@dataclass
class Case:
    """One point of the matrix (before choosing method and solver).

    ``limit``: how the error is measured — "penalty" (vs the ε = 1× solution
    of the same method/solver), "free", "tied", "open" (linear response
    without contact), or "" (no limit: converge or diagnose).
    """

    name: str
    group: str
    omega: float
    mu: float
    eps_scale: float = 1.0
    force_scale: float = 1.0          # × f_harmonic
    static_scale: float = 1.0         # × f_static
    gap: float | np.ndarray = 0.0     # added to model gaps (m)
    nh: int | None = None
    nit: int | None = None
    limit: str = ""
    maxiter: int | None = None        # override (divergence cases)
    pseudo: dict = field(default_factory=dict)   # options for the pseudo-time solver
    wear: dict | None = None          # wear cases: {"k_w": …, "mode": …}
    model: ReducedModel | None = None  # a different model (conditioning)
    scaled: bool = False              # solve with row/column scaling
    note: str = ""


def _static_free_normal(su: Setup) -> np.ndarray:
    """Normal relative displacement (p,) of the static state without contact (m)."""
    c = condense(su.rc, su.omega, 0)
    u0 = np.linalg.solve(np.real(c.Zr[0]), np.real(c.Fr[0]))
    return u0.reshape(-1, 3)[:, 0]


def build_cases(su: Setup) -> list[Case]:
    """The case list of issue 8 for this model, restricted to ``settings.groups``."""
    s = su.settings
    w = su.omega
    mu = s.mu
    out: list[Case] = []
    g = set(s.groups)
    if "penalty" in g:
        for e in range(-s.penalty_decades, s.penalty_decades + 1):
            out.append(Case(f"penalty-1e{e:+d}", "penalty", w, mu, eps_scale=10.0 ** e, limit="penalty"))
    if "friction" in g:
        out += [Case("mu-0", "friction", w, 0.0, limit="free"),
                Case("mu-1e-4", "friction", w, 1e-4, limit="free"),
                Case("mu-0.5", "friction", w, 0.5),
                Case("mu-1e4", "friction", w, 1e4, limit="tied")]
    if "excitation" in g:
        for f in s.excitation_factors:
            out.append(Case(f"force-{f:.0e}", "excitation", w, mu, force_scale=f,
                            limit="tied" if f <= 1e-6 else "",
                            note=f"{f * s.amplitude:.3g} N"))
    if "contact" in g:
        u0 = _static_free_normal(su)          # < 0: the preload pushes the blade into the disk
        approach = float(np.max(-u0))
        out += [Case("no-preload", "contact", w, mu, static_scale=0.0,
                     note="grazing at rest: the excitation opens and closes the contact"),
                Case("lift-off", "contact", w, mu, static_scale=-1.0, limit="open",
                     note="static load pulls the blade out: contact open all period"),
                Case("grazing", "contact", w, mu, gap=-u0, note="gap = static approach: zero normal force"),
                Case("gap-open", "contact", w, mu, gap=-u0 + 10.0 * approach + 1e-9, limit="open",
                     note="gap far larger than the static approach"),
                Case("gap-small", "contact", w, mu, gap=0.5 * approach, note="initial gap, closes under preload"),
                Case("interference", "contact", w, mu, gap=-approach, note="initial interference")]
    if "resolution" in g:
        nh_hi = s.max_harmonics
        out += [Case(f"nh-{nh_hi}", "resolution", w, mu, nh=nh_hi, nit=max(2 * nh_hi + 2, 64)),
                Case(f"nit-{s.max_time_samples}", "resolution", w, mu, nit=s.max_time_samples)]
    if "frequency" in g:
        out += [Case("at-resonance", "frequency", su.omega_tied, mu, note="first tied resonance: Zr pole"),
                Case("at-anti-resonance", "frequency", su.omega_free, mu,
                     note="free-interface resonance: Zr singular")]
    if "wear" in g:
        out += [Case("wear-large-k", "wear", w, mu, wear={"k_w": s.wear_k, "mode": "steady"},
                     note="huge Archard coefficient: steady state in a few blocks"),
                Case("wear-opens", "wear", w, mu, force_scale=30.0, static_scale=0.02,
                     wear={"k_w": 10.0 * s.wear_k, "mode": "open"},
                     note="light preload, gross slip: wear opens the contact")]
    if "conditioning" in g and su.model.info.get("synthetic"):
        ill = synthetic_model(su.p, extra_modes=s.extra_modes, spread=s.spread)
        out += [Case("ill-conditioned", "conditioning", w, mu, model=ill,
                     note=f"{s.extra_modes} extra modes over ×{s.spread:g} in frequency, unscaled"),
                Case("ill-conditioned-scaled", "conditioning", w, mu, model=ill, scaled=True,
                     note="same, residual / ‖F‖ and unknowns / characteristic displacement")]
    elif "conditioning" in g:
        out += [Case("conditioning", "conditioning", w, mu, note="this model, unscaled"),
                Case("conditioning-scaled", "conditioning", w, mu, scaled=True, note="this model, scaled")]
    if "divergence" in g:
        out += [Case("diverge-maxiter", "divergence", w, mu, force_scale=100.0, maxiter=1,
                     pseudo={"max_steps": 2}, note="deliberately starved of iterations"),
                Case("diverge-explicit", "divergence", su.omega_tied, mu, force_scale=10.0,
                     pseudo={"scheme": "rk4", "cfl": 3.0, "precond": "none"},
                     note="explicit pseudo-time at 3× its stability limit")]
    return out


@dataclass
class CaseResult:
    """One row of the matrix."""

    name: str
    group: str
    method: str
    solver: str
    converged: bool
    iterations: int
    seconds: float
    error: float | None
    diagnosis: str
    tolerance: float | None = None     # how far from its limit a right solution may be (see :func:`tolerance`)
    residual: float | None = None      # ‖R‖/‖F‖ at the end
    separated: float | None = None     # fraction of (instant, pair) separated
    slipping: float | None = None
    sticking: float | None = None
    cond: float | None = None          # condition number of the final Jacobian (as solved)
    note: str = ""
    x: np.ndarray | None = field(default=None, repr=False)
    U: np.ndarray | None = field(default=None, repr=False)

    def row(self) -> dict:
        keys = ("name", "group", "method", "solver", "converged", "iterations", "seconds", "error",
                "tolerance", "diagnosis", "residual", "separated", "slipping", "sticking", "cond", "note")
        return {k: _clean(getattr(self, k)) for k in keys}


def _clean(v):
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    return v
