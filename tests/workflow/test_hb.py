"""HBM / TCM / HDHB on hand-condensed models: physics, equivalences, Jacobians."""
import numpy as np
import pytest

from hbmodels import condense, jenkins, law_for, recover, root_model
from workflow.engine.contact import STICK, ContactLaw
from workflow.errors import SceneError
from workflow.engine.hb import HBProblem

W25 = 2 * np.pi * 25.0


def solve(pr, x0=None, tol=1e-10):
    """Newton, then Powell if Newton stalls on a kink (both are public paths)."""
    r = pr.solve(x0, tol=tol)
    if not r.converged:
        r = pr.solve(x0, solver="powell", tol=tol)
    assert r.converged, r.reason
    return r


def root_problem(method="hbm", nit=None, nh=3, p=2, eps_factor=1.0, mu=0.3, gap=None, **model_kw):
    model_kw.setdefault("force", 0.5)
    m = root_model(p, **model_kw)
    Zr, Fr, dZr, dFr = condense(m, W25, nh)
    eref = np.mean(np.diag(Zr[1].real))
    law = law_for(p, mu=mu, eps=eps_factor * eref, gap=gap)
    nit = 2 * nh + 1 if nit is None else nit
    return HBProblem(Zr, Fr, law, nh, nit, method), m


# ---------------------------------------------------------------- physics

@pytest.mark.parametrize("eps_over_k", [0.1, 1.0, 10.0])
def test_jenkins_hb_dissipation(eps_over_k):
    """Grounded Jenkins element driven by d = a cos τ through spring k: the HB
    loop area ∮ λ_T dd = π a Im Λ_1 tends to 4μN(a − μN/k) as Nh grows, for
    any ε (with ε = k the DLFT is the exact Jenkins law at every Nh)."""
    k, kn, N, mu, a = 10.0, 100.0, 1.0, 0.5, 0.2
    exact = 4 * mu * N * (a - mu * N / k)
    errs = []
    for nh in (1, 5, 15):
        Zr, Fr = jenkins(k, kn, N, a, nh)
        law = ContactLaw(mu=[mu], eps_n=kn, eps_t=eps_over_k * k, gap=[0.0])
        pr = HBProblem(Zr, Fr, law, nh, 256, "hbm")
        r = solve(pr, tol=1e-11)
        lam = pr.contact_harmonics(r.x)
        errs.append(abs(np.pi * a * lam[1, 1].imag - exact) / exact)
        assert np.allclose(lam[0, 0], -N)                          # normal load carried
    assert errs[2] <= errs[0] and errs[2] < 2e-3, errs


def test_large_mu_gives_tied_response():
    pr, m = root_problem(mu=1e3, force=2.0)
    r = solve(pr)
    # exact, not to tol: x0 is the tied solution and Newton accepts it at iteration 0 (round-off below)
    assert r.iterations == 0 and np.all(pr.contact_state(r.x) == STICK)
    U = pr.harmonics(r.x)
    assert np.abs(U[1:]).max() < 1e-14
    lam = pr.contact_harmonics(r.x)
    assert np.allclose(lam[1:], pr.Fr[1:], rtol=1e-9, atol=1e-12 * np.abs(pr.Fr).max())
    # static state: stuck from a tied assembly, zero tangential offset
    st = pr.static_state(apply=False)
    assert np.all(st.state == STICK) and np.allclose(st.anchor, 0.0)
    assert np.allclose(U[0].reshape(-1, 3)[:, 1:], 0.0, atol=1e-15)


def test_open_contact_gives_free_response():
    pr, m = root_problem(mu=0.0, gap=np.full(2, 1e-2), preload=0.0, force=2.0)
    r = solve(pr)
    # exact, not to tol: x0 is this linear (open) solution, accepted at iteration 0
    assert r.iterations == 0 and np.all(pr.contact_time(r.x) == 0.0)
    Ufree = np.linalg.solve(pr.Zr, pr.Fr[..., None])[..., 0]
    assert np.allclose(pr.harmonics(r.x), Ufree, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("method", ["hbm", "tcm", "hdhb"])
def test_roots_do_not_depend_on_penalty(method):
    """With nit = 2Nh+1 the DLFT equations at a root are ε-free: a root found
    with one ε is a root for every ε over six decades."""
    pr, _ = root_problem(method, nh=3)
    x = solve(pr, tol=1e-12).x
    eref = pr.law.eps_n[0]
    for f in (1e-3, 1e-1, 1e1, 1e3):
        pr.set_contact(pr.law.with_penalty(f * eref, f * eref))
        assert np.linalg.norm(pr.residual(x)) < 1e-8 * pr.residual_scale(), f


def test_penalty_influence_vanishes_with_harmonics():
    """With nit > 2Nh+1 the AFT projection leaves an O(truncation) ε-dependence,
    which shrinks as Nh grows."""
    spreads = []
    for nh in (3, 15):
        amps = []
        x = None
        for f in (0.3, 3.0, 30.0):
            pr, _ = root_problem("hbm", nit=128, nh=nh, eps_factor=f)
            x = solve(pr, x).x
            amps.append(np.abs(pr.harmonics(x)[1, 1]))
        spreads.append((max(amps) - min(amps)) / max(amps))
    assert spreads[1] < 0.3 * spreads[0], spreads
    assert spreads[1] < 0.02


def test_three_formulations_share_roots():
    sols = {}
    for method in ("hbm", "tcm", "hdhb"):
        pr, _ = root_problem(method, nh=3)
        r = solve(pr, tol=1e-12)
        sols[method] = pr.harmonics(r.x)
    ref = np.abs(sols["hbm"][1:]).max()
    assert np.abs(sols["tcm"] - sols["hbm"]).max() < 1e-8 * ref
    assert np.abs(sols["hdhb"] - sols["hbm"]).max() < 1e-8 * ref


def test_aliasing_of_short_time_grid_shrinks_with_harmonics():
    """HDHB (nit = 2Nh+1) against HBM with nit = 105: apart at low Nh, closer as Nh grows."""
    diffs = []
    for nh in (3, 7, 12):
        a, _ = root_problem("hdhb", nh=nh)
        b, _ = root_problem("hbm", nit=105, nh=nh)
        Ua = a.harmonics(solve(a).x)[1]
        Ub = b.harmonics(solve(b).x)[1]
        diffs.append(np.abs(Ua - Ub).max() / np.abs(Ub).max())
    assert diffs[0] > 0.05
    assert diffs[0] > diffs[1] > diffs[2], diffs


def test_refining_harmonics_converges():
    amp = {}
    for nh in (1, 3, 7, 21):
        pr, _ = root_problem("hbm", nit=128, nh=nh)
        amp[nh] = np.abs(pr.harmonics(solve(pr).x)[1, 1])
    err = [abs(amp[nh] - amp[21]) for nh in (1, 3, 7)]
    assert err[0] > err[1] > err[2], err
    assert err[2] < 0.02 * amp[21]


@pytest.mark.parametrize("method", ["hbm", "tcm", "hdhb"])
def test_balance_and_recovery_at_a_root(method):
    """Zr U + λ̃ = Fr at a root (λ̃ from contact_harmonics), and the physical
    response recovered from λ̃ reproduces U_r."""
    pr, m = root_problem(method, nh=3, nit=None if method == "hdhb" else 21)
    r = solve(pr, tol=1e-12)
    U = pr.harmonics(r.x)
    lam = pr.contact_harmonics(r.x)
    bal = np.einsum("jab,jb->ja", pr.Zr, U) + lam - pr.Fr
    assert np.abs(bal).max() < 1e-8 * np.abs(pr.Fr).max()
    q = recover(m, W25, lam, pr.nh)
    assert np.allclose(q @ m["B"].T, U, atol=1e-8 * np.abs(U).max())


# ------------------------------------------------------------- Jacobians

def _fd_jacobian(pr, x, h):
    J = np.zeros((pr.n, pr.n))
    for i in range(pr.n):
        e = np.zeros(pr.n)
        e[i] = h
        J[:, i] = (pr.residual(x + e) - pr.residual(x - e)) / (2 * h)
    return J


CASES = {
    # name: (problem kwargs, expected states present [sep, stick, slip])
    "stick": (dict(mu=1e3, force=1.0), (False, True, False)),
    "slip": (dict(mu=0.0, force=1.0), (False, False, True)),
    "partial": (dict(mu=0.3, force=0.5), (False, True, True)),
    "separation": (dict(mu=0.3, gap=np.full(2, 1e-2), preload=0.0, force=1.0), (True, False, False)),
    "mixed": (dict(mu=0.3, preload=np.array([10.0, 2.0]), force=0.5, force_n=4.0), (True, True, True)),
}


@pytest.mark.parametrize("method,nit", [("hbm", 7), ("hbm", 32), ("tcm", 7), ("tcm", 30), ("hdhb", 7)])
@pytest.mark.parametrize("case", list(CASES))
def test_jacobian_matches_finite_differences(method, nit, case):
    kw, expect = CASES[case]
    pr, _ = root_problem(method, nit=nit, nh=3, **kw)
    pr.max_passes, pr.pass_tol = 200, 1e-14
    x = pr.x0()
    noise = 2e-5 if case == "mixed" else 1e-6
    x = x + noise * np.random.default_rng(7).normal(size=pr.n)
    if case == "partial":
        x = solve(pr).x + 3e-7 * np.random.default_rng(8).normal(size=pr.n)
    states = pr.contact_state(x)
    present = tuple(bool(np.any(states == s)) for s in (0, 1, 2))
    assert present == expect, np.bincount(states.ravel(), minlength=3)
    R, J = pr.residual_jacobian(x)
    Jfd = _fd_jacobian(pr, x, 1e-11)
    assert np.abs(J - Jfd).max() <= 1e-5 * np.abs(J).max()


@pytest.mark.parametrize("method", ["hbm", "tcm", "hdhb"])
def test_omega_derivative_matches_finite_differences(method):
    m = root_model(2, force=0.5)
    nh = 3
    law = law_for(2, mu=0.3, eps=7e4)
    w, h = W25, 1e-4
    nit = 2 * nh + 1 if method == "hdhb" else 16
    pr = HBProblem(*condense(m, w, nh)[:2], law, nh, nit, method)
    x = solve(pr).x
    _, _, dZr, dFr = condense(m, w, nh)
    R, J, Rw = pr.residual_jacobian_omega(x, dZr, dFr)
    Rp = pr.with_linear(*condense(m, w + h, nh)[:2]).residual(x)
    Rm = pr.with_linear(*condense(m, w - h, nh)[:2]).residual(x)
    assert np.allclose(Rw, (Rp - Rm) / (2 * h), rtol=1e-5, atol=1e-6 * np.abs(Rw).max())


# ------------------------------------------------------- static / errors

def test_static_state_slipping_pair_carries_its_offset():
    """A static tangential load above μN on the lightly preloaded pair makes it
    slip at the static step while the other sticks; the anchors are the static
    offsets and the dynamic solve keeps the stuck pair there."""
    m = root_model(2, preload=np.array([2.0, 20.0]), tangential_static=1.0, force=0.02)
    nh = 3
    Zr, Fr, _, _ = condense(m, W25, nh)
    pr = HBProblem(Zr, Fr, law_for(2, mu=0.3, eps=7e4), nh, 16, "hbm")
    st = pr.static_state()
    assert list(st.state) == [2, 1]
    assert np.allclose(st.anchor, st.u[:, 1:], atol=1e-15)
    assert st.anchor[0, 0] > 1e-7 and np.allclose(st.anchor[1], 0.0)
    assert abs(st.lam[0, 1]) == pytest.approx(0.3 * abs(st.lam[0, 0]))
    r = solve(pr)
    # pair 0 sits on the Coulomb limit and slips at once; pair 1 stays stuck
    # at its static offset (the anchor), not at an arbitrary one
    assert list(pr.stuck_pairs(r.x)) == [False, True]
    U0 = pr.harmonics(r.x)[0].real.reshape(2, 3)
    assert np.allclose(U0[1, 1:], st.anchor[1], atol=1e-15)


def test_stuck_offset_follows_anchor_not_penalty():
    pr, _ = root_problem(mu=1e3)
    pr.set_stick_anchor(np.array([[1e-6, 0.0], [0.0, -2e-6]]))
    x = solve(pr).x
    U0 = pr.harmonics(x)[0].real.reshape(2, 3)
    assert np.allclose(U0[:, 1:], [[1e-6, 0.0], [0.0, -2e-6]], atol=1e-15)


def test_input_errors_name_the_key():
    pr, _ = root_problem()
    with pytest.raises(SceneError, match="hb.time_samples"):
        HBProblem(pr.Zr, pr.Fr, pr.law, 3, 16, "hdhb")
    with pytest.raises(SceneError, match="hb.time_samples"):
        HBProblem(pr.Zr, pr.Fr, pr.law, 3, 5, "hbm")
    with pytest.raises(SceneError, match="hb.method"):
        HBProblem(pr.Zr, pr.Fr, pr.law, 3, 7, "fem")
    with pytest.raises(SceneError, match="Zr"):
        HBProblem(pr.Zr[:, :3, :3], pr.Fr, pr.law, 3, 7, "hbm")


@pytest.mark.parametrize("method", ["hbm", "tcm", "hdhb"])
def test_residual_does_not_keep_a_view_of_the_callers_x(method):
    """MINPACK (Powell) overwrites its x buffer in place: a residual asked again at the same
    values, from another array, must not see what the first array holds now."""
    pr, _ = root_problem(method, nh=3, nit=None if method == "hdhb" else 21, mu=0.3, force=0.5)
    x = pr.x0() + 1e-6 * np.random.default_rng(3).normal(size=pr.n)
    R = pr.residual(x.copy())
    buf = x.copy()
    pr.residual(buf)
    buf[:] = 1e3                     # the solver reuses its buffer
    assert np.array_equal(pr.residual(x.copy()), R)
    at = pr.residual_along(x, np.zeros(pr.n))
    xt, Rt = at(0.5)
    xt[:] = -1e3                     # a line search that overwrites its trial point
    assert np.array_equal(pr.residual(x.copy()), R)


def test_a_load_whose_norm_overflows_is_refused_not_converged():
    """Every tolerance is relative to ‖F‖, so with ‖F‖ = inf any residual would pass: an
    excitation of 1e300 N solved to NaN and was called converged at 0 iterations. The problem
    refuses such a load by name; the solvers' one test never accepts a NaN or infinite norm,
    nor an infinite scale."""
    from workflow.engine.solvers import within_tolerance

    pr, _ = root_problem()
    with pytest.raises(SceneError, match="excitation.amplitude"):
        HBProblem(pr.Zr, 1e300 * pr.Fr, pr.law, 3, 7, "hbm")
    assert within_tolerance(1.0, 1e-8, 1e9) and not within_tolerance(1.0, 1e-8, 1e7)
    for norm, scale in ((np.nan, 1.0), (np.inf, 1.0), (1.0, np.inf), (np.inf, np.inf), (0.0, np.nan)):
        assert not within_tolerance(norm, 1e-8, scale)
