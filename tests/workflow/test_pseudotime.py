"""Pseudo-time integration to R = 0 (paper eq. 18, 19) on HB problems and toys."""
import numpy as np
import pytest

from wearmodels import hb_problem
from workflow.engine.pseudotime import SCHEMES, integrate, rk4_stability_limit


@pytest.fixture(scope="module", params=[("hbm", 16), ("hdhb", 5)])
def solved(request):
    method, nit = request.param
    hb = hb_problem(20.0, nh=2, nit=nit, method=method)  # edge pairs slip, centre sticks
    x0 = hb.x0()
    ref = hb.solve(x0, tol=1e-11)
    assert ref.converged
    assert np.any(hb.contact_state(ref.x) == 2), "the case must slip somewhere"
    return hb, x0, ref


@pytest.mark.parametrize("precond", ["none", "jacobian"])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_each_scheme_reaches_the_newton_solution(solved, scheme, precond):
    hb, x0, ref = solved
    if scheme == "block-jacobi" and precond != "none":
        pytest.skip("block-Jacobi is its own (block-diagonal) preconditioner")
    kw = {"blocks": hb.nc} if scheme == "block-jacobi" else {}
    r = integrate(hb.residual, hb.residual_jacobian, x0, scheme, precond=precond, tol=1e-10,
                  scale=hb.residual_scale(), max_steps=3000, **kw)
    assert r.converged, r.reason
    assert r.reason == "converged"
    assert r.residual_norm <= 1e-10 * hb.residual_scale()
    # ‖R‖ ≤ tol·‖F‖ (1e-10 here, 1e-11 the reference): ‖J⁻¹‖‖F‖ ≤ 550·max|x| ⇒ 6e-8·max|x| apart at most
    np.testing.assert_allclose(r.x, ref.x, atol=1e-7 * np.abs(ref.x).max())
    assert r.jacobian_evaluations >= 1 and r.seconds > 0 and len(r.history) == r.steps + 1
    assert all(np.isfinite(r.history))


def _linear_toy(n=30, seed=0):
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    lam = np.logspace(0, 3, n)
    A = Q @ np.diag(lam) @ Q.T
    b = rng.standard_normal(n)
    return (lambda x: A @ x - b), (lambda x: (A @ x - b, A)), A, b


def test_measured_stability_limit_is_rk4s():
    # real spectrum: the RK4 limit on the negative real axis is 2.7853
    assert rk4_stability_limit(np.array([1.0, 10.0])) * 10 == pytest.approx(2.785293, rel=1e-5)
    # imaginary axis: 2√2
    assert rk4_stability_limit(np.array([1e-9 + 1j])) == pytest.approx(2 * np.sqrt(2), rel=1e-4)


@pytest.mark.parametrize("scheme", ["rk4", "local"])
def test_explicit_beyond_its_limit_is_detected_and_within_converges(scheme):
    fun, fun_jac, A, b = _linear_toy()
    # local steps equalise a diagonal spread but not a rotated one: still stiff, so only check detection
    bad = integrate(fun, fun_jac, np.zeros(b.size), scheme, cfl=1.2, tol=1e-9, scale=np.linalg.norm(b),
                    max_steps=20000)
    assert not bad.converged
    assert bad.reason.startswith("unstable") and "stability limit" in bad.reason
    assert np.all(np.isfinite(bad.x)) and np.isfinite(bad.residual_norm)
    if scheme == "rk4":
        assert bad.dt_stable == pytest.approx(2.785293 / 1e3, rel=1e-4)
    good = integrate(fun, fun_jac, np.zeros(b.size), scheme, cfl=0.9, tol=1e-9, scale=np.linalg.norm(b),
                     max_steps=20000)
    assert good.converged, good.reason
    # ‖Ax − b‖ ≤ 1e-9‖b‖ and ‖A⁻¹‖ = 1 (eigenvalues 1…1e3): ‖x − A⁻¹b‖ ≤ 1e-9‖b‖ = 4.6e-9
    np.testing.assert_allclose(good.x, np.linalg.solve(A, b), atol=1e-8)


def test_eq18_is_repelled_near_resonance_and_the_jacobian_mass_fixes_it():
    """Above a natural frequency J has eigenvalues with Re < 0: eq. 18 as written diverges
    (detected, finite), the frozen-Jacobian pseudo-time mass converges."""
    hb = hb_problem(24.0, nh=3, nit=32, force=3.0, preload=(10.0, 5.0, 10.0))
    x0 = hb.x0()
    bad = integrate(hb.residual, hb.residual_jacobian, x0, "rk4", precond="none", tol=1e-9,
                    scale=hb.residual_scale(), max_steps=500)
    assert not bad.converged and bad.reason.startswith("unstable")
    assert np.all(np.isfinite(bad.x))
    good = integrate(hb.residual, hb.residual_jacobian, x0, "ser", precond="jacobian", tol=1e-9,
                     scale=hb.residual_scale(), max_steps=200)
    assert good.converged, good.reason


def test_nan_residual_is_reported_not_returned():
    def fun(x):
        return np.where(np.abs(x) > 0.5, np.nan, x - 1.0)

    r = integrate(fun, lambda x: (fun(x), np.eye(x.size)), np.zeros(3), "ser", dt0=10.0, tol=1e-12,
                  max_steps=50)
    assert np.all(np.isfinite(r.x))
    assert not r.converged and r.reason


def test_ser_jacobian_mass_is_one_lu_per_step_and_the_same_iteration(solved):
    # the fast path solves (J0/Δt* + J) dx = −R; the generic mass path solves
    # (I/Δt* + J0⁻¹J) dx = −J0⁻¹R: the same steps in exact arithmetic
    hb, x0, ref = solved
    _, J0 = hb.residual_jacobian(x0)
    kw = dict(tol=1e-10, scale=hb.residual_scale(), max_steps=500)
    fast = integrate(hb.residual, hb.residual_jacobian, x0, "ser", precond="jacobian", dt0=3.0, **kw)
    slow = integrate(hb.residual, hb.residual_jacobian, x0, "ser", precond=J0, dt0=3.0, **kw)
    assert fast.converged and slow.converged
    assert fast.steps == slow.steps
    np.testing.assert_allclose(fast.history, slow.history, rtol=1e-6, atol=1e-9 * hb.residual_scale())
    np.testing.assert_allclose(fast.x, ref.x, atol=1e-7 * np.abs(ref.x).max())


def test_a_singular_step_matrix_is_none_without_a_warning():
    """An exactly singular step matrix (the undamped resonance of test_engine) gives None,
    which the integrators handle, and no LinAlgWarning reaches the user's terminal."""
    import warnings

    from workflow.engine.pseudotime import _lu_solve

    A = np.diag([1.0, 2.0, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _lu_solve(A, np.ones(3)) is None
        np.testing.assert_allclose(_lu_solve(np.diag([1.0, 2.0, 4.0]), np.ones(3)), [1.0, 0.5, 0.25])
