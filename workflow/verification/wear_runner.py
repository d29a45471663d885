"""The engine's Archard wear against the references of :mod:`workflow.verification.wear_exact`
(issue 48, item 4 a, b, d): rows (case, quantity, value, exact, error) for the verification
stage (summary.json ``verification.wear_rows``) and ``python -m workflow.bench.wear_references``.
Like :mod:`workflow.verification.runner`, it calls the engine's front door; the references
themselves never do. ``error`` is relative, against the scale named in the quantity.

* (a) ``jenkins``: :class:`~workflow.verification.wear_exact.JenkinsWear` (k_t = 1e5 N/m,
  k_n = 1e7 N/m, μ = 0.5, X = 0.1 mm, N₀ = 15 N, A = 1 mm², k_w = 2.5e-16 m²/N: r = 1e-6 /cycle,
  N_c = 20 N, δ₀ = 1.5 µm), lumped model ``JenkinsWear.model()``, ε = (k_n, k_t) (the
  automatic penalty picks exactly these: massless node), HBM Nh = 3, nit = 64, at
  100/π Hz; through :func:`workflow.engine.worn_steady_state`. Also ε = 10 k_t (the
  ε-check's penalty), where the DLFT predictor is no longer the exact drive.
* (b) ``punch``: :class:`~workflow.verification.wear_exact.PunchWear`, three contacts
  (edges A = 1.5 mm², gap 2 µm; centre 1 mm², no gap), N₀ = 12 N, k_w = 1e-15: persistent
  slip (no worn steady state); the march's W(n), its final rates against the sinking speed V
  and the worn profile's offset against the closed forms.
* (b) ``punch-layer``: the same punch built through the contact's interface layer
  (:func:`~workflow.verification.wear_exact.layered_punch`, :data:`PUNCH_LAYER`).
* (d) ``oscillator`` (slow, ~2 min): :class:`~workflow.verification.wear_exact.OscillatorWear`
  at the tied resonance, reference by event-driven steady states and cycle jumps.
"""
from __future__ import annotations

import time

import numpy as np

from workflow.verification.wear_exact import JenkinsWear, OscillatorWear, PunchWear, layered_punch

JENKINS = JenkinsWear(k_t=1e5, k_n=1e7, mu=0.5, X=1e-4, N0=15.0, A=1e-6, k_w=2.5e-16)
JENKINS_HZ = 100.0 / np.pi          # the witness sits at 100 Hz: no harmonic of 100/π Hz hits it
PUNCH = PunchWear(k_n=(1e7, 1e7, 1e7), k_t=(1e5, 1e5, 1e5), A=(1.5e-6, 1e-6, 1.5e-6), gap=(2e-6, 0.0, 2e-6),
                  mu=0.5, X=1e-4, N0=12.0, k_w=1e-15)
PUNCH_HZ = np.sqrt(3e7) / (2 * np.pi) / np.pi      # the punch (1 kg on 3 × 1e7 N/m) tied at √3e7 rad/s
#: (b) on an interface layer: the contacts' springs k_n A_i (1.5e7 / 1e7 / 1.5e7 N/m) and, in series with
#: the drive's 1e7 N/m, k_t A_i (1.5e5 / 1e5 / 1.5e5 N/m)
PUNCH_LAYER = dict(A=(1.5e-6, 1e-6, 1.5e-6), gap=(2e-6, 0.0, 2e-6), kn=1e13, kt=1e11, Ks=1e7, N0=12.0, X=1e-4,
                   mu=0.5, k_w=1e-15)


def oscillator() -> OscillatorWear:
    """(d): 1 kg, 10 Hz free, pad k_t = k, ζ = 2 %, F = 1 N at the tied resonance √((k + k_t)/m),
    μ = 0.5, N₀ = 10 N, k_n = 1e7 N/m (δ₀ = 1 µm), A = 1 mm², k_w = 1e-16 m²/N."""
    k = (2 * np.pi * 10.0) ** 2
    return OscillatorWear(m=1.0, c=2 * 0.02 * np.sqrt(k), k=k, F=1.0, omega=np.sqrt(2 * k), k_t=k, mu=0.5,
                          N0=10.0, k_n=1e7, A=1e-6, k_w=1e-16)


def row(case, quantity, value, exact, scale=None) -> dict:
    """One row; error = |value − exact| / (scale or |exact|) (absolute where both are 0)."""
    s = abs(exact) if scale is None else scale
    err = abs(value - exact) / s if s > 0 else abs(value - exact)
    return {"case": case, "quantity": quantity, "value": float(value), "exact": float(exact), "error": float(err)}


def _options(methods, k_w, hz, **kw):
    from workflow import engine

    base = dict(methods=tuple(methods), k_w=k_w, nh=3, nit=64, frequency_hz=hz, tol=1e-10, max_blocks=20000,
                max_steps=20000, nh_check=False, eps_check_factor=0.0, compare_unworn=False,
                resonance_shift=False)      # the worn-vs-new FRF search: not a wear question here
    return engine.WearOptions(**{**base, **kw})


def engine_jenkins(ref: JenkinsWear = JENKINS, *, method="implicit", eps_factor=1.0, **kw):
    """(study, history) of the engine on case (a)."""
    from workflow import engine

    model = ref.model()
    law = engine.contact_law(model, mu=ref.mu, eps_n=ref.k_n, eps_t=eps_factor * ref.k_t)
    st = engine.worn_steady_state(model, law, _options((method,), ref.k_w, JENKINS_HZ, **kw))
    return st, st.histories[method]


def history_error(h, exact_W, scale) -> tuple[float, float, float]:
    """(value, exact, error) at the history point where |W − W(n)| is largest (all pairs)."""
    c = np.asarray(h.cycles)
    W = np.asarray(h.W_history)
    ex = exact_W(c).reshape(W.shape)
    e = np.abs(W - ex)
    k, i = np.unravel_index(int(np.argmax(e)), e.shape)
    return float(W[k, i]), float(ex[k, i]), float(e[k, i] / scale)


def cycles_at(h, W_target, pair=0) -> float:
    """Cycles at which the history's W (of ``pair``) reaches W_target (linear interpolation)."""
    W = np.asarray(h.W_history)[:, pair]
    return float(np.interp(W_target, W, np.asarray(h.cycles)))


def jenkins_rows(quick: bool = False) -> list[dict]:
    ref = JENKINS
    rows = []
    for method, kw in (("implicit", dict(block_tol=0.01, steady_tol=1e-7)),
                       ("pseudo-time", dict(rtol=1e-3, steady_tol=1e-7)),
                       ("pseudo-time", dict(rtol=1e-5, steady_tol=1e-7))):
        if quick and kw.get("rtol") == 1e-5:
            continue
        tag = f"{method} " + ", ".join(f"{k}={v:g}" for k, v in kw.items())
        st, h = engine_jenkins(ref, method=method, **kw)
        if method == "implicit":
            rows.append(row("jenkins", "wear rate at W = 0 [m/cycle]", h.max_rate[0], float(ref.rate_of_wear(0.0))))
        rows.append(row("jenkins", f"final W [m] ({tag})", float(h.W[0]), ref.final()["W"]))
        v, e, err = history_error(h, ref.wear, ref.delta0)
        rows.append({**row("jenkins", f"W(n) worst point, error / δ0 ({tag})", v, e), "error": err})
        rows.append(row("jenkins", f"cycles to W = δ0/2 ({tag})", cycles_at(h, 0.5 * ref.delta0),
                        float(ref.cycles_to_load(0.5 * ref.N0))))
    # the rate at the peak load and at ε = 10 k_t (the DLFT predictor no longer the exact drive)
    for fac in (1.0, 10.0):
        st, h = engine_jenkins(ref, method="implicit", eps_factor=fac, block_tol=0.04, steady_tol=1e-4)
        from workflow.engine.wear import WearProblem

        wp = WearProblem(st.hb, [ref.A], ref.k_w)
        Wp = (ref.N0 - 0.5 * ref.Nc) / ref.k_n
        res, s = wp.solve_hb(st.base.x, np.array([Wp]), tol=1e-11)
        rows.append(row("jenkins", f"wear rate at N = N_c/2 [m/cycle] (ε_T = {fac:g} k_t)", float(s.rate[0]),
                        float(ref.rate_of_load(0.5 * ref.Nc))))
    return rows


def engine_punch(ref: PunchWear = PUNCH, *, method="pseudo-time", model=None, hz: float = PUNCH_HZ, **kw):
    """(study, history) of the engine on a punch: ``ref.model()`` unless ``model`` is given, at ``hz``."""
    from workflow import engine

    model = ref.model() if model is None else model
    law = engine.contact_law(model, mu=ref.mu, omega_hz=hz)
    kw = {"steady_tol": 1e-2, "cycles_per_block": 1e5, **kw}
    st = engine.worn_steady_state(model, law, _options((method,), ref.k_w, hz, **kw))
    return st, st.histories[method]


def _punch_march_rows(case: str, ref: PunchWear, h, tag: str) -> list[dict]:
    """A punch march against its closed forms: persistent slip, the worst W(n), the final rates vs V."""
    rows = [row(case, f"stopped as persistent slip (1 = yes) ({tag})", float(h.persistent_slip), 1.0)]
    top = float(np.max(ref.symmetric3([h.cycles[-1]])))
    v, e, err = history_error(h, ref.symmetric3, top)
    rows.append({**row(case, f"W(n) worst point, error / max W at the end ({tag})", v, e), "error": err})
    rate, V = np.asarray(h.final_rate), ref.asymptote()["V"]
    for i, name in ((0, "edge"), (1, "centre")):
        rows.append(row(case, f"final wear rate {name} [m/cycle] vs sinking speed V ({tag})", float(rate[i]), V))
    return rows


def punch_rows(quick: bool = False) -> list[dict]:
    ref = PUNCH
    asy = ref.asymptote()
    rows = []
    runs = [("pseudo-time", dict(rtol=1e-4)), ("pseudo-time", dict(rtol=1e-5))]
    if not quick:
        runs.append(("implicit", dict(block_tol=0.01)))
    for method, kw in runs:
        tag = f"{method} " + ", ".join(f"{k}={v:g}" for k, v in kw.items())
        st, h = engine_punch(ref, method=method, **kw)
        rows += _punch_march_rows("punch", ref, h, tag)
        W = np.asarray(h.W)
        rows.append(row("punch", f"profile W_centre − W_edge [m] ({tag})", float(W[1] - W[0]), float(asy["offsets"][1])))
        # cycles until the edges have worn 1e-3 of their gap (just after they close at n₁)
        grid = np.linspace(ref.closing_cycles(), 3 * ref.closing_cycles(), 20001)
        n_edge = float(np.interp(1e-3 * ref.gap[0], ref.symmetric3(grid)[:, 0], grid))
        rows.append(row("punch", f"cycles to W_edge = 1e-3 gap ({tag})", cycles_at(h, 1e-3 * ref.gap[0], pair=0),
                        n_edge))
    return rows


def punch_layer_rows(quick: bool = False) -> list[dict]:
    """(b) on the contact's interface layer (:func:`~workflow.verification.wear_exact.layered_punch`,
    :data:`PUNCH_LAYER`): pseudo-time (rtol 1e-4) against the closed form, at a third of the
    punch's tied frequency."""
    ref, model = layered_punch(**PUNCH_LAYER)
    hz = np.sqrt(np.sum(ref.k_n)) / (2 * np.pi) / np.pi
    st, h = engine_punch(ref, model=model, hz=hz, rtol=1e-4)
    return _punch_march_rows("punch-layer", ref, h, "pseudo-time rtol=0.0001")


def oscillator_rows(tol: float = 2.5e-4) -> list[dict]:
    """(d): the cycle-jump reference (Heun, ``tol``; 2.5e-4: 85 steps, ~150 s; 1e-3 moves n(W) by
    ~1e-3) against both marches at Nh = 3 (implicit also at block_tol = 0.0025) and pseudo-time at Nh = 7."""
    from workflow import engine

    o = oscillator()
    t0 = time.perf_counter()
    ref = o.march(tol=tol)
    t_ref = time.perf_counter() - t0
    n_ref, W_ref = ref["n"], ref["W"]
    rows = [row("oscillator", f"reference march: cycle-jump steps (tol = {tol:g}, {t_ref:.0f} s)", float(ref["steps"]),
                float(ref["steps"]))]
    model = o.model()
    law = engine.contact_law(model, mu=o.mu)
    runs = [(3, ("pseudo-time", "implicit"), 0.01), (3, ("implicit",), 0.0025), (7, ("pseudo-time",), 0.01)]
    for nh, methods, bt in runs:
        opt = _options(methods, o.k_w, 0.0, nh=nh, steady_tol=1e-5, rtol=1e-4, block_tol=bt)
        st = engine.worn_steady_state(model, law, opt)
        for m, h in st.histories.items():
            tag = f"{m}, Nh = {nh}" + (f", block_tol = {bt:g}" if m == "implicit" else ", rtol = 1e-4")
            if m == "implicit" and bt == 0.01:
                rows.append(row("oscillator", f"wear rate at W = 0 [m/cycle] (Nh = {nh}, nit = 64)", h.max_rate[0],
                                o.steady(o.N0)["rate"]))
            rows.append(row("oscillator", f"final W [m] ({tag})", float(h.W[0]), o.delta0))
            for frac in (0.25, 0.5, 0.9):
                rows.append(row("oscillator", f"cycles to W = {frac:g} δ0 ({tag})", cycles_at(h, frac * o.delta0),
                                float(np.interp(frac * o.delta0, W_ref, n_ref))))
    return rows
