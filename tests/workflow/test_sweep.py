"""Frequency sweeps: stepped with a secant predictor, and arclength through folds."""
import numpy as np
import pytest

from hbmodels import condense, gap_model, law_for, root_model
from workflow.engine.hb import HBProblem
from workflow.engine.sweep import arclength_sweep, continuation, stepped_sweep


def _tip_amplitude(model, nh):
    """Observed quantity: first-harmonic amplitude of the tip DOF, recovered
    from the contact-force harmonics (contracts §5, q_j = H_j (f_j − Bᵀ λ_j))."""
    def observe(pr, x):
        lam = pr.contact_harmonics(x)
        w = pr.omega
        D = model["K"] - w ** 2 * model["M"] + 1j * w * model["C"]
        q1 = np.linalg.solve(D, model["f1"] - model["B"].T @ lam[1])
        return abs(q1[model["tip"]])
    return observe


def _sweep(mu, freqs, progress=None):
    model = root_model(2, force=0.5)
    nh, nit = 3, 32
    law = law_for(2, mu=mu, eps=7e4)

    return stepped_sweep(freqs, lambda w: condense(model, w, nh),
                         lambda Zr, Fr: HBProblem(Zr, Fr, law, nh, nit, "hbm"),
                         _tip_amplitude(model, nh), progress=progress)


def test_stepped_sweep_through_friction_damped_resonance():
    freqs = np.linspace(20.0, 30.0, 21)
    calls = []
    pts = _sweep(0.3, freqs, progress=lambda i, n: calls.append((i, n)))
    assert calls[-1] == (21, 21) and len(calls) == 21
    assert all(p.converged for p in pts), [p.reason for p in pts if not p.converged]
    amp = np.array([p.amplitude for p in pts])
    k = int(np.argmax(amp))
    assert 0 < k < len(freqs) - 1                    # a resonance peak inside the band
    stuck = np.array([p.amplitude for p in _sweep(1e3, freqs)])
    assert amp.max() < 0.9 * stuck.max()             # friction damps the peak
    assert all(p.seconds > 0 and p.iterations >= 0 for p in pts)
    assert pts[3].frequency_hz == pytest.approx(freqs[3])


def _duffing(m=1.0, c=0.05, k=1.0, g=0.5, F=0.2):
    """One-harmonic HB of m x'' + c x' + k x + g x³ = F cos ωt, x = a cos + b sin."""
    def fjw(x, w):
        a, b = x
        A2 = a * a + b * b
        kk = k - m * w * w
        R = np.array([kk * a + c * w * b + 0.75 * g * A2 * a - F, kk * b - c * w * a + 0.75 * g * A2 * b])
        J = np.array([[kk + 0.75 * g * (A2 + 2 * a * a), c * w + 1.5 * g * a * b],
                      [-c * w + 1.5 * g * a * b, kk + 0.75 * g * (A2 + 2 * b * b)]])
        Rw = np.array([-2 * m * w * a + c * b, -2 * m * w * b - c * a])
        return R, J, Rw
    return fjw


def test_arclength_follows_the_duffing_fold():
    fjw = _duffing()
    out = continuation(fjw, np.array([0.2 / 0.75, 0.0]), 0.5, 3.0, ds=0.05, scale=0.2, tol=1e-12)
    assert all(o["converged"] for o in out)
    w = np.array([o["omega"] for o in out])
    amp = np.array([np.hypot(*o["x"]) for o in out])
    for o in out:
        assert np.linalg.norm(fjw(o["x"], o["omega"])[0]) < 1e-10
    k = int(np.argmax(np.diff(w) < 0))                   # first turning point
    assert k > 0 and w[k] > 1.6 and w[k:].min() < w[k] - 0.3   # went back below the fold
    assert w[-1] >= 3.0                                  # and came out at the far end
    # three coexisting amplitudes at ω = 1.4 inside the fold
    crossings = np.sum(np.diff(np.sign(w - 1.4)) != 0)
    assert crossings == 3
    assert amp.max() == pytest.approx(0.2 / (0.05 * w[np.argmax(amp)]), rel=0.05)  # peak ≈ F/(cω)


@pytest.mark.slow
def test_arclength_follows_a_contact_hardening_fold():
    """A mass hitting the disk after a gap: piecewise-linear hardening bends the
    resonance to the right; continuation goes over the fold and back."""
    model = gap_model(force=1.0)
    nh, nit = 5, 64
    law = law_for(1, mu=0.2, eps=3e4, gap=np.array([1e-3]))
    f_open = np.sqrt(1e4) / (2 * np.pi)
    pts = arclength_sweep(0.8 * f_open, 2.0 * f_open, lambda w: condense(model, w, nh),
                          lambda Zr, Fr: HBProblem(Zr, Fr, law, nh, nit, "hbm"),
                          lambda pr, x: abs(pr.harmonics(x)[1, 0]),
                          ds=0.05, ds_max=0.2, max_steps=300)
    assert all(p.converged for p in pts)
    f = np.array([p.frequency_hz for p in pts])
    amp = np.array([p.amplitude for p in pts])
    top = int(np.argmax(f[: int(np.argmax(amp)) + 20]))
    assert f[top] > 1.15 * f_open                     # hardened beyond the open resonance
    assert f[top:].min() < f[top] - 1.0                # came back down the unstable branch
    assert f[-1] >= 2.0 * f_open
    assert amp.max() > 1e-3                            # the gap closed
