"""The project's HB on the verification cases, compared with the independent references.

:func:`hb_first_harmonic` is the ONE call into the project's HB/DLFT code (the
engine's front door). Everything else here only builds cases and references.
"""
from __future__ import annotations

from dataclasses import dataclass
import numpy as np

from workflow.verification import exact, timeint
from workflow.verification.models import Spec


def hb_first_harmonic(model, freqs_hz, *, mu: float, nh: int, nit: int, method: str = "hbm",
                      eps: float | None = None, solver: str = "newton-powell", tol: float = 1e-8,
                      maxiter: int = 100, max_passes: int = 20):
    """The project's HB sweep over ``freqs_hz`` (Hz, in that order) on a reduced model,
    through the engine's front door (:func:`workflow.engine.frf`) with its defaults.

    Returns ``(amplitude (n,) m, converged (n,) bool, eps_t N/m)``: the
    first-harmonic amplitude at the observed DOF(s) (norm), and the tangential
    penalty used (the first pair's). ``eps`` (N/m) sets ε_N = ε_T; None is the
    project's default penalty (:mod:`workflow.engine.penalty`).
    """
    from workflow import engine

    f = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
    # the automatic penalty is sampled at the band's centre (these models may have no tied mode)
    law = engine.contact_law(model, mu=mu, eps_n=eps or 0.0, eps_t=eps or 0.0,
                             omega_hz=0.5 * float(f.min() + f.max()))
    opt = engine.FRFOptions(solver=solver, tol=tol, max_iterations=maxiter, max_passes=max_passes,
                            eps_check_factor=0.0)
    study = engine.frf(model, law, [engine.Variant(method, int(nh), int(nit))], freqs_hz=freqs_hz, options=opt)
    r = study.runs[0]
    return r.amplitude, r.converged, float(law.eps_t[0])


@dataclass
class Reference:
    """First-harmonic amplitude (m) of the exact steady state, how it was obtained
    ("den-hartog", "time-integration"), and whether the motion has stops."""

    amplitude: float
    source: str
    stops: bool


def reference(spec: Spec, omega: float) -> Reference:
    """The independent reference at ω (rad/s): Den Hartog's closed form where it is
    valid (Coulomb oscillator, c = 0, non-stop), else event-driven time integration."""
    if spec.pads is None:
        p = spec.coulomb
        if p["c"] == 0.0:
            d = exact.den_hartog(p["m"], p["k"], p["friction"], p["force"], omega)
            if d.valid:
                return Reference(d.first, "den-hartog", False)
        s = timeint.coulomb_steady_state(p["m"], p["k"], p["c"], p["friction"], p["force"], omega)
        return Reference(float(s.first[0]), "time-integration", bool(s.stick_fraction[0] > 0))
    s = timeint.jenkins_steady_state(spec.M, spec.C, spec.K, spec.f, omega, spec.pads)
    return Reference(float(s.first[spec.observe]), "time-integration", bool(np.any(s.stick_fraction > 0)))


def compare(model, spec: Spec, freqs_hz, nhs, *, nit: int | None = None, eps: float | None = None,
            refs: list | None = None, **kw) -> list[dict]:
    """Rows (case, Nh, nit, eps, frequency_hz, amplitude, exact, error, converged, source, stops)
    of the project's HB against the references, one per Nh × frequency.

    ``nit`` None: the engine's default (:func:`workflow.engine.fourier.default_nit`: 4·(2Nh+1)
    rounded up to a power of 2, at least 64) — enough samples that the DLFT's time grid is
    not the error being measured.
    ``refs``: precomputed :class:`Reference` per frequency (else computed).
    """
    from workflow.engine.fourier import default_nit

    freqs = np.atleast_1d(np.asarray(freqs_hz, float))
    refs = refs or [reference(spec, 2 * np.pi * f) for f in freqs]
    rows = []
    for nh in nhs:
        n_t = nit or default_nit(nh)
        amp, ok, e = hb_first_harmonic(model, freqs, mu=spec.mu, nh=nh, nit=n_t, eps=eps, **kw)
        for f, a, c, r in zip(freqs, amp, ok, refs):
            err = abs(a - r.amplitude) / r.amplitude if r.amplitude > 0 else abs(a)
            rows.append({"case": spec.name, "Nh": int(nh), "nit": n_t, "eps": e, "frequency_hz": float(f),
                         "amplitude": float(a), "exact": r.amplitude, "error": float(err), "converged": bool(c),
                         "source": r.source, "stops": r.stops})
    return rows
