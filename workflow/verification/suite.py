"""The verification suite: named cases, their frequencies, and one run over them.

Cases (unit oscillator m = k = 1 kg, N/m, F0 = 1 N, so ω_n = 1 rad/s; β = ω/ω_n):

* ``coulomb`` — Den Hartog, c = 0, μN/F0 = 0.5, β = 0.8, 1.2: non-stop, exact closed form;
* ``coulomb-damped`` — ζ = 0.02, μN/F0 = 0.5, β = 0.8, 1.0, 1.2: time integration;
* ``coulomb-stop`` — c = 0, μN/F0 = 0.7, β = 0.5, 1.5: the mass stops twice a period;
* ``2dof-damper`` — :func:`~workflow.verification.models.two_dof_damper` (normal load
  varying with the motion), ω/ω_tied = 0.9, 1.0, 1.1: time integration;
* ``pad-chain`` — :func:`~workflow.verification.models.pad_chain` (10 masses, 8 root
  pads), ω/ω_tied = 0.95, 1.0, 1.05: time integration (≈ 4 s per frequency).

The penalty is ``factor × the case's stiffness`` (k, or the largest pad stiffness),
or the project's default when the factor is 0.
"""
from __future__ import annotations

import numpy as np

from workflow.verification import galerkin, models, runner

CASES = ("coulomb", "coulomb-damped", "coulomb-stop", "2dof-damper", "pad-chain")
_COULOMB = {"coulomb": (0.5, 0.0, (0.8, 1.2)), "coulomb-damped": (0.5, 0.02, (0.8, 1.0, 1.2)),
            "coulomb-stop": (0.7, 0.0, (0.5, 1.5))}
COLUMNS = ("case", "Nh", "nit", "eps", "amplitude", "exact", "error", "converged", "frequency_hz", "source", "stops")


def build(name: str):
    """(ReducedModel, Spec, ω list in rad/s, reference stiffness N/m) of a named case."""
    if name in _COULOMB:
        r, zeta, betas = _COULOMB[name]
        model, spec = models.coulomb(1.0, 1.0, 2 * zeta, 1.0, 1.0, r, name=name)
        return model, spec, np.array(betas), 1.0
    if name == "2dof-damper":
        model, spec = models.two_dof_damper()
        ratios = (0.9, 1.0, 1.1)
    elif name == "pad-chain":
        model, spec = models.pad_chain()
        ratios = (0.95, 1.0, 1.05)
    else:
        from workflow.errors import SceneError

        raise SceneError(f"verification.cases: unknown case {name!r} (known: {', '.join(CASES)})")
    return model, spec, spec.omega_n * np.array(ratios), float(spec.pads.k.max())


def galerkin_floor(spec, omegas, refs, nhs) -> list[dict]:
    """Galerkin HB with the exact sign law (HB's truncation floor) on the non-stop points of a
    Coulomb case (``refs``: their :class:`~workflow.verification.runner.Reference`): rows
    (case, Nh, frequency_hz, amplitude, exact, error, converged)."""
    if spec.pads is not None:
        return []
    p = spec.coulomb
    rows = []
    for w, ref in zip(omegas, refs):
        if ref.stops:
            continue
        start = None
        for nh in sorted(nhs):
            coef, ok = galerkin.galerkin_hb(p["m"], p["k"], p["c"], p["friction"], p["force"], w, nh, start=start)
            start = coef
            a = galerkin.first_amplitude(coef)
            rows.append({"case": spec.name, "Nh": int(nh), "frequency_hz": w / 2 / np.pi, "amplitude": a,
                         "exact": ref.amplitude, "error": abs(a - ref.amplitude) / ref.amplitude, "converged": ok})
    return rows


def run(cases, nhs, *, nit: int = 0, penalty_factor: float = 0.0, progress=None) -> tuple[list, list]:
    """(HB rows, Galerkin rows) over the cases; ``progress`` wraps the case loop."""
    rows, floor = [], []
    it = progress(list(cases)) if progress else cases
    for name in it:
        model, spec, omegas, k_ref = build(name)
        refs = [runner.reference(spec, w) for w in omegas]
        eps = penalty_factor * k_ref if penalty_factor > 0 else None
        rows += runner.compare(model, spec, omegas / 2 / np.pi, nhs, nit=nit or None, eps=eps, refs=refs)
        floor += galerkin_floor(spec, omegas, refs, nhs)
    return rows, floor


def summary(rows: list, floor: list) -> dict:
    """``max_error_nonstop``: largest error over the converged non-stop rows at the largest Nh
    (None if there are none); counts; the Galerkin floor at the largest Nh."""
    top = max((r["Nh"] for r in rows), default=0)
    last = [r for r in rows if r["Nh"] == top and not r["stops"]]
    ok = [r["error"] for r in last if r["converged"]]
    fl = [r["error"] for r in floor if r["Nh"] == top and r["converged"]]
    return {"max_error_nonstop": max(ok) if ok else None, "largest_harmonics": top,
            "unconverged_nonstop": len(last) - len(ok),
            "converged": sum(bool(r["converged"]) for r in rows), "total": len(rows),
            "galerkin_floor": max(fl) if fl else None}

