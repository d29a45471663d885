"""Single-nonlinear-mode synthesis of the forced response from a backbone (:func:`synthesize`)."""
from __future__ import annotations

import numpy as np

from workflow.engine.errors import SceneError
from workflow.engine.studies.nlmodes.results import Backbone, Synthesis


def _curve(p, W, DC, DF, g, aa):
    """The synthesised FRF as a curve in the modal amplitude: the two Ω (Hz) of |L(Ω)| = g/a at
    each sample where the branches exist (``p`` = min_Ω |L| a − g ≤ 0), NaN elsewhere."""
    lo, hi = np.full(W.size, np.nan), np.full(W.size, np.nan)
    for i in np.flatnonzero(p <= 0):
        # |L|² − (g/a)² as a quartic in Ω
        c4 = [1.0, 0.0, 4 * W[i] ** 2 * DC[i] ** 2 - 2 * W[i] ** 2, 8 * W[i] ** 3 * DC[i] * DF[i],
              W[i] ** 4 + 4 * W[i] ** 4 * DF[i] ** 2 - (g[i] / aa[i]) ** 2]
        r = np.roots(c4)
        r = np.sort(r[(np.abs(r.imag) <= 1e-9 * W[i]) & (r.real > 0)].real)
        if r.size:
            lo[i], hi[i] = r[0] / (2 * np.pi), r[-1] / (2 * np.pi)
    return lo, hi


def _at_frequencies(freqs, tt, W, DC, DF, aa, g, at) -> np.ndarray:
    """(n_freq, k) observed amplitudes (m) where |L(Ω)| a = g along the backbone samples ``tt``
    (linear interpolation between the samples that bracket it), ascending, NaN-padded."""
    if not freqs.size:
        return np.zeros((0, 1))
    rows = []
    for F in freqs:
        Omg = 2 * np.pi * F
        h = np.abs(W ** 2 - Omg ** 2 + 1j * (2 * Omg * W * DC + 2 * W ** 2 * DF)) * aa - g
        cross = np.flatnonzero(np.sign(h[:-1]) * np.sign(h[1:]) < 0)
        vals = []
        for k in cross:
            x = tt[k] + h[k] / (h[k] - h[k + 1]) * (tt[k + 1] - tt[k])
            a_, *_, o_ = at(x)
            vals.append(float(o_[0] * a_[0]))
        rows.append(sorted(vals))
    out = np.full((freqs.size, max([len(r) for r in rows] + [1])), np.nan)
    for i, r in enumerate(rows):
        out[i, :len(r)] = r
    return out


def _min_over_frequency(W, Dc, Df):
    """(min_Ω |L|, argmin Ω) of ``L = ω² − Ω² + i(2ΩωD_c + 2ω²D_f)`` per sample: Newton on
    ∂|L|²/∂Ω = 4Ω³ + 2Ω(4ω²D_c² − 2ω²) + 8ω³D_cD_f from Ω = ω√(1 − 2D_c²) (the root for
    D_f = 0, the peak of the viscous form)."""
    Om = W * np.sqrt(np.maximum(1 - 2 * Dc ** 2, 1e-12))
    for _ in range(30):
        g = 4 * Om ** 3 + 2 * Om * (4 * W ** 2 * Dc ** 2 - 2 * W ** 2) + 8 * W ** 3 * Dc * Df
        h = 12 * Om ** 2 + 2 * (4 * W ** 2 * Dc ** 2 - 2 * W ** 2)
        step = g / np.where(h > 0, h, np.inf)
        Om = Om - step
        if np.all(np.abs(step) <= 1e-14 * W):
            break
    L = np.abs(W ** 2 - Om ** 2 + 1j * (2 * Om * W * Dc + 2 * W ** 2 * Df))
    return L, Om


def synthesize(bb: Backbone, model, force_scale: float = 1.0, freqs_hz=None, *, damping: str = "viscous",
               samples: int = 4000) -> Synthesis:
    """Single-nonlinear-mode synthesis of the forced response to ``force_scale × f_harmonic``
    (the model's cos ωt load) from the backbone ``bb`` of ``model``.

    Along the backbone (interpolated over its points, monotone cubic, ``samples`` points — a
    backbone that turns back in a is followed as it is) the modal equation
    ``|L(Ω)| a = |ψᴴ f|`` gives 0 or 2 frequencies per amplitude (the FRF's two branches); at
    each of ``freqs_hz`` the amplitudes where it holds (one, or three where the FRF folds).
    The observed amplitude is ``a ‖O ψ(a)‖``. The peak: the first amplitude (from small a)
    where the branches meet, ``min_Ω |L| a = |ψᴴ f|``; NaN if they never do on the backbone.

    ``damping``: "viscous" — Krack et al. (2014), ``L = −Ω² + 2iΩDω + ω²``: all the
    dissipation as a viscous term, peak at ``Ω = ω√(1 − 2D²)``; "split" — the structural part
    (``energy_structural_J``) viscous and the friction part rate-independent (hysteretic,
    ``2iD_f ω²``), as the Jenkins element's is: ``L = ω² − Ω² + i(2ΩωD_c + 2ω²D_f)``. The two
    differ by O(D²) in the peak frequency: 1e-5 on the quick sector (D < 0.6 %), 3 % at the
    Jenkins oscillator's D = 0.17."""
    from workflow.engine.condense import relative_coordinates
    from scipy.interpolate import PchipInterpolator
    from scipy.optimize import brentq

    if len(bb) < 2:
        raise SceneError("synthesis: the backbone has fewer than 2 points")
    if damping not in ("viscous", "split"):
        raise SceneError(f"synthesis: damping {damping!r} is not one of viscous, split")
    rc = relative_coordinates(model)
    f = float(force_scale) * np.asarray(rc.f_harmonic)
    a = bb.amplitude
    w = 2 * np.pi * bb.frequency_hz
    share = np.zeros(len(bb)) if damping == "viscous" else \
        bb.energy_friction_hb_J / np.maximum(bb.energy_xi_J, 1e-300)
    Dc, Df = bb.damping_ratio * (1 - share), bb.damping_ratio * share
    modal_force = np.abs(bb.z1.conj() @ f) / a                 # |ψᴴ f| (N/√kg)
    obs_per_a = np.linalg.norm(bb.observed[:, 1, :], axis=1) / a
    t = np.arange(len(bb), dtype=float)
    interp = {k: PchipInterpolator(t, v) for k, v in (("s", np.log(a)), ("w", w), ("Dc", Dc), ("Df", Df),
                                                         ("g", modal_force), ("o", obs_per_a))}
    tt = np.linspace(0.0, t[-1], max(int(samples), 20 * len(bb)))

    def at(x):
        x = np.atleast_1d(x)
        return (np.exp(interp["s"](x)),) + tuple(interp[k](x) for k in ("w", "Dc", "Df", "g", "o"))

    aa, W, DC, DF, g, o = at(tt)
    Lmin, Om = _min_over_frequency(W, DC, DF)
    p = Lmin * aa - g
    up = np.flatnonzero((p[:-1] < 0) & (p[1:] >= 0))
    peak_hz = peak_m = peak_a = float("nan")
    if up.size:
        k = int(up[0])

        def pf(x):
            a_, w_, dc, df, g_, _ = at(x)
            return float(_min_over_frequency(w_, dc, df)[0][0] * a_[0] - g_[0])
        xp = brentq(pf, tt[k], tt[k + 1], xtol=1e-12)
        a_, w_, dc, df, _, o_ = at(xp)
        peak_a = float(a_[0])
        peak_hz = float(_min_over_frequency(w_, dc, df)[1][0]) / (2 * np.pi)
        peak_m = float(o_[0]) * peak_a
    lo, hi = _curve(p, W, DC, DF, g, aa)
    freqs = np.zeros(0) if freqs_hz is None else np.asarray(freqs_hz, dtype=float).ravel()
    out_amp = _at_frequencies(freqs, tt, W, DC, DF, aa, g, at)
    return Synthesis(freqs_hz=freqs, amplitude=out_amp, peak_hz=float(peak_hz), peak_amplitude_m=float(peak_m),
                     peak_modal_amplitude=peak_a, curve_amplitude=aa, curve_low_hz=lo, curve_high_hz=hi,
                     curve_observed_m=o * aa,
                     force_norm_N=float(np.linalg.norm(float(force_scale) * np.asarray(model.f_harmonic))))
