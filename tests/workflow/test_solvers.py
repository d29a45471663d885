"""Newton and hybrid Powell: same roots, honest failure reports, no NaN leaks."""
import numpy as np
import pytest

from hbmodels import condense, law_for, root_model
from workflow.engine.hb import HBProblem
from workflow.engine import solvers
from workflow.engine.solvers import forcing, newton, powell


def _problem():
    m = root_model(2, force=0.5)
    nh = 3
    Zr, Fr, _, _ = condense(m, 2 * np.pi * 25.0, nh)
    return HBProblem(Zr, Fr, law_for(2, mu=0.3, eps=7e4), nh, 32, "hbm")


def test_newton_and_powell_reach_the_same_solution():
    pr = _problem()
    x0 = pr.x0()
    rn = newton(pr.residual_jacobian, x0, fun=pr.residual, tol=1e-11, scale=pr.residual_scale())
    rp = powell(pr.residual, pr.residual_jacobian, x0, tol=1e-11, scale=pr.residual_scale())
    assert rn.converged and rp.converged, (rn.reason, rp.reason)
    assert rn.reason == rp.reason == "converged"
    # each stops at ‖R‖ ≤ tol·scale, i.e. within ‖J⁻¹‖·tol·scale of the root (3.6e-6·max|x| here, not 1e-7)
    bound = 2 * np.linalg.norm(np.linalg.inv(pr.residual_jacobian(rn.x)[1]), 2) * 1e-11 * pr.residual_scale()
    assert np.linalg.norm(rn.x - rp.x) <= bound
    assert rn.residual_norm <= 1e-11 * pr.residual_scale()
    assert rn.jacobian_evaluations >= 1 and rn.seconds > 0 and len(rn.history) == rn.iterations + 1


def test_chord_steps_reach_the_same_root_with_fewer_jacobians():
    """reuse_ratio keeps the LU of an old Jacobian while ‖R‖ keeps falling:
    same friction-damped root as full Newton, fewer Jacobians formed."""
    pr = _problem()
    x0 = pr.x0()
    full = newton(pr.residual_jacobian, x0, fun=pr.residual, tol=1e-11, scale=pr.residual_scale())
    chord = newton(pr.residual_jacobian, x0, fun=pr.residual, tol=1e-11, scale=pr.residual_scale(),
                   reuse_ratio=0.8, maxiter=200)
    assert full.converged and chord.converged, (full.reason, chord.reason)
    # both stop at ‖R‖ ≤ tol·scale: within ‖J⁻¹‖·tol·scale of the root each
    bound = 2 * np.linalg.norm(np.linalg.inv(pr.residual_jacobian(full.x)[1]), 2) * 1e-11 * pr.residual_scale()
    assert np.linalg.norm(chord.x - full.x) <= bound
    assert chord.jacobian_evaluations < full.jacobian_evaluations


def test_chord_steps_cross_a_kink_with_a_stale_slope():
    """The slope changes at x = 1 (as at a stick/slip switch) after the only
    Jacobian was formed: chord steps with the stale factor still converge."""
    def fj(x):  # piecewise-linear: the slope changes at x = 1, as at a stick/slip switch
        R = np.array([np.where(x[0] > 1.0, 10.0 * (x[0] - 1.0) + 1.0, x[0]) - 5.0])
        return R, np.array([[10.0 if x[0] > 1.0 else 1.0]])
    r = newton(fj, [0.0], tol=1e-12, scale=5.0, reuse_ratio=0.99)
    assert r.converged and np.isclose(r.x[0], 1.4) and r.jacobian_evaluations == 1


def test_newton_converges_quadratically_on_a_smooth_system():
    def fj(x):
        R = np.array([x[0] ** 2 + x[1] ** 2 - 4.0, x[0] - x[1]])
        return R, np.array([[2 * x[0], 2 * x[1]], [1.0, -1.0]])
    r = newton(fj, [3.0, 1.0], tol=1e-14, scale=4.0)
    assert r.converged and np.allclose(r.x, [np.sqrt(2), np.sqrt(2)])
    h = r.history
    assert h[-2] < 1e-5 * h[0] and r.iterations <= 7


def test_tolerance_is_relative_to_scale():
    fj = lambda x: (np.array([x[0] - 1e6]), np.array([[1.0]]))  # noqa: E731
    r = newton(fj, [0.0], tol=1e-9, scale=1e6)
    assert r.converged and r.iterations == 1


def test_max_iterations_reported_without_nan():
    pr = _problem()
    r = newton(pr.residual_jacobian, pr.x0(), fun=pr.residual, tol=1e-14, scale=pr.residual_scale(),
               maxiter=1)
    assert not r.converged and r.reason == "max iterations"
    assert np.all(np.isfinite(r.x)) and np.isfinite(r.residual_norm)


@pytest.mark.parametrize("which", ["newton", "powell"])
def test_no_root_is_reported(which):
    fun = lambda x: np.array([x[0] ** 2 + 1.0])  # noqa: E731
    fj = lambda x: (fun(x), np.array([[2 * x[0]]]))  # noqa: E731
    r = newton(fj, [1.0], fun=fun, maxiter=30) if which == "newton" else powell(fun, fj, [1.0], maxfev=50)
    assert not r.converged and r.reason != "converged"
    assert np.all(np.isfinite(r.x)) and np.isfinite(r.residual_norm)


@pytest.mark.parametrize("which", ["newton", "powell"])
def test_non_finite_residual_stops_with_diagnosis(which):
    # finite at the start, NaN once x leaves (−1, 1): the solvers must not return NaN
    def fun(x):
        return np.array([np.sqrt(1.0 - x[0] ** 2) - 2.0 + 0 * x[0]]) if abs(x[0]) < 1 else np.array([np.nan])

    def fj(x):
        return fun(x), np.array([[-x[0] / np.sqrt(max(1 - x[0] ** 2, 1e-300))]])

    r = newton(fj, [0.5], fun=fun, maxiter=20) if which == "newton" else powell(fun, fj, [0.5])
    assert not r.converged
    assert np.all(np.isfinite(r.x))
    assert r.reason != "converged"
    if which == "powell":
        r2 = powell(lambda x: np.array([np.nan]), lambda x: (np.array([np.nan]), np.eye(1)), [0.0])
        assert r2.reason == "non-finite residual" and np.all(np.isfinite(r2.x))
    else:
        r2 = newton(lambda x: (np.array([np.nan]), np.eye(1)), [0.0])
        assert r2.reason == "non-finite residual" and np.all(np.isfinite(r2.x))


def test_lm_search_starts_from_the_damping_last_accepted():
    """Marquardt's update: a second Levenberg–Marquardt search of the same solve starts at a
    tenth of the ν the first accepted, not again at 1e-8·trace(JᵀJ)/n (a solve creeping along
    a kink needs about the same ν at every step)."""
    from workflow.engine.solvers import _lm_search

    class Lin:                       # a step that only lowers ‖R‖ once ν ≥ 1e3
        tried = []

        def lm_scale(self):
            return 1.0

        def lm_step(self, R, nu):
            self.tried.append(nu)
            return -R / (1.0 + nu) if nu >= 1e3 else R.copy()

    fun = lambda z: z                                      # noqa: E731
    x = np.array([1.0, -2.0])
    ok, xt, Rt, nu = _lm_search(fun, Lin(), x, fun(x), np.linalg.norm(x), 1e-4, 20, [0])
    assert ok and np.linalg.norm(Rt) < np.linalg.norm(x)
    first = len(Lin.tried)
    assert first == 12 and nu == pytest.approx(1e3)       # 1e-8, 1e-7, …, 1e3
    Lin.tried.clear()
    ok, _, _, nu2 = _lm_search(fun, Lin(), xt, fun(xt), np.linalg.norm(xt), 1e-4, 20, [0], nu_last=nu)
    assert ok and Lin.tried == pytest.approx([1e2, 1e3]) and nu2 == pytest.approx(1e3)


def test_newton_creeping_on_levenberg_marquardt_steps_stops_as_stalled(monkeypatch):
    """A Newton direction that fails its line search every time (here: a wrong Jacobian, as at
    a kink of the friction residual, where the active branch's slope points the wrong way)
    leaves only Levenberg–Marquardt steps, a few % each. The solve stops as "stalled" after
    STALL_LM_STEPS of them, with the iterate it reached (the cascade's next attempt starts
    there or elsewhere); with the rule switched off the path is the same up to that step (this
    toy then escapes the bad region and converges at step 11: the rule trades such escapes
    for the budget a creep would take on the sector)."""
    import workflow.engine.solvers as S

    J = np.array([[1.0, 10.0], [0.0, 1.0]])    # R(x) = x: the true Jacobian is I
    x0 = np.array([1.0, 1.0])
    r = newton(lambda x: (x.copy(), J), x0, maxiter=50, tol=1e-10)
    assert not r.converged and r.reason.startswith("stalled")
    assert r.iterations == S.STALL_LM_STEPS and len(r.history) == r.iterations + 1
    assert r.residual_norm == pytest.approx(np.linalg.norm(r.x)) and r.residual_norm < np.linalg.norm(x0)
    assert r.history[-1] > S.STALL_RATIO * r.history[0]
    monkeypatch.setattr(S, "STALL_LM_STEPS", 10 ** 9)
    full = newton(lambda x: (x.copy(), J), x0, maxiter=50, tol=1e-10)
    assert np.allclose(full.history[:len(r.history)], r.history, rtol=1e-12)


def test_forcing_terms_follow_eisenstat_walker():
    """η_k = γ(‖R_k‖/‖R_{k−1}‖)^α, their safeguard γη_{k−1}^α above 0.1, the floor
    0.5·tol·scale/‖R_k‖, the cap ETA_MAX (Eisenstat & Walker 1996, choice 2); tight
    (None) once the last CREEP_STEPS steps cut ‖R‖ by less than 1 − CREEP_RATIO."""
    g, a, cap = solvers.FORCING_GAMMA, solvers.FORCING_ALPHA, solvers.ETA_MAX
    assert forcing([1.0], None, 1e-12) == cap                            # the first step
    assert np.isclose(forcing([1.0, 0.01], 1e-3, 1e-15), g * 0.01 ** a)  # fast decrease: tighter
    assert forcing([1.0, 0.5], 1e-3, 1e-15) == cap                       # slower: the cap
    assert np.isclose(forcing([1.0, 1e-6], 0.5, 1e-15), min(cap, g * 0.5 ** a))  # the safeguard
    assert np.isclose(forcing([1.0, 1e-3], 1e-3, 1e-8), 0.5 * 1e-8 / 1e-3)  # never past the tolerance
    creep = [1.0] + [1.0 - 0.01 * k for k in range(1, solvers.CREEP_STEPS + 1)]
    assert forcing(creep, 1e-3, 1e-15) is None                           # creeping: solve tight
    assert forcing(creep[:-1], 1e-3, 1e-15) == cap                       # not yet CREEP_STEPS steps of it


class _LooseSolve(solvers.DenseLU):
    """An inexact linear solver: the exact step plus an error of relative size rtol in
    the residual (the worst a Krylov solver stopped at rtol may leave)."""
    inexact = True

    def __init__(self):
        super().__init__()
        self.rtols = []

    def solve(self, R, rtol=None):
        dx = super().solve(R)
        self.rtols.append(rtol)
        if rtol is None:
            return dx
        e = np.linalg.solve(self.J, np.ones_like(R))
        return dx + rtol * np.linalg.norm(R) / np.linalg.norm(np.ones_like(R)) * e


def test_inexact_newton_keeps_superlinear_convergence():
    def fj(x):
        R = np.array([x[0] ** 2 + x[1] ** 2 - 4.0, x[0] - x[1]])
        return R, np.array([[2 * x[0], 2 * x[1]], [1.0, -1.0]])
    lin = _LooseSolve()
    r = newton(fj, [3.0, 1.0], tol=1e-14, scale=4.0, linear=lin)
    # ‖R‖ ≤ tol·scale = 4e-14 and ‖J⁻¹‖ = 0.71 at the root: x within 2e-14 relative
    assert r.converged and np.allclose(r.x, [np.sqrt(2), np.sqrt(2)], rtol=1e-13)
    loose = [e for e in lin.rtols if e is not None]
    assert lin.rtols[0] == solvers.ETA_MAX and min(loose) < 1e-5     # tightens as Newton converges
    h = r.history
    assert h[-2] < 1e-5 * h[0] and r.iterations <= 8
