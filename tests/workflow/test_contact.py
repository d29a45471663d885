"""The DLFT law (eqs. 13–17) on prescribed predictors: physics and derivatives."""
import numpy as np
import pytest

from workflow.engine import fourier
from workflow.engine.contact import SEPARATION, SLIP, STICK, ContactLaw, dlft, dlft_pass
from workflow.errors import SceneError


def _jenkins_energy(nit, k=10.0, N=1.0, mu=0.5, a=0.2):
    """Prescribed u_T = a cos τ with Z = 0, F = 0: λ_u^T = ε u_T, so the DLFT law is a
    Jenkins element of stiffness ε = k; returns ∮ λ_T du_T and the exact loop area."""
    tau = fourier.sample_times(nit)
    lam_u = np.zeros((nit, 1, 3))
    lam_u[:, 0, 0] = -N
    lam_u[:, 0, 1] = k * a * np.cos(tau)
    r = dlft_pass(lam_u, mu, np.zeros((1, 2)))
    assert r.converged
    energy = 2 * np.pi / nit * np.sum(r.lam[:, 0, 1] * (-a * np.sin(tau)))
    return energy, 4 * mu * N * (a - mu * N / k), r


def test_jenkins_loop_area_converges_with_nit():
    errors = []
    for nit in (16, 64, 256):
        e, exact, r = _jenkins_energy(nit)
        errors.append(abs(e - exact) / exact)
        assert set(np.unique(r.state)) == {STICK, SLIP}
        # Coulomb bound everywhere, reached in slip
        lt = np.abs(r.lam[:, 0, 1])
        assert np.all(lt <= 0.5 * 1.0 * (1 + 1e-12))
        assert np.allclose(lt[r.state[:, 0] == SLIP], 0.5)
    assert errors[-1] < 1e-4
    assert errors[0] > errors[1] > errors[2]


def test_jenkins_below_slip_limit_dissipates_nothing():
    e, _, r = _jenkins_energy(64, a=0.04)  # k a = 0.4 < μN = 0.5
    assert np.all(r.state == STICK) and abs(e) < 1e-12


def test_circular_orbit_two_tangential_directions():
    """u_T = a (cos τ, sin τ): the slider settles on a circle of radius
    sqrt(a² − (μN/k)²) and dissipates μN·2π·that radius per cycle."""
    k, N, mu, a = 10.0, 1.0, 0.5, 0.2
    exact = mu * N * 2 * np.pi * np.sqrt(a ** 2 - (mu * N / k) ** 2)
    errors = []
    for nit in (64, 256, 1024):
        tau = fourier.sample_times(nit)
        lam_u = np.zeros((nit, 1, 3))
        lam_u[:, 0, 0] = -N
        lam_u[:, 0, 1] = k * a * np.cos(tau)
        lam_u[:, 0, 2] = k * a * np.sin(tau)
        r = dlft_pass(lam_u, mu, np.zeros((1, 2)), max_passes=50)
        assert r.converged and np.all(r.state == SLIP)
        assert np.allclose(np.linalg.norm(r.lam[:, 0, 1:], axis=1), mu * N)
        du = np.stack([-a * np.sin(tau), a * np.cos(tau)], 1)
        energy = 2 * np.pi / nit * np.sum(np.einsum("ka,ka->k", r.lam[:, 0, 1:], du))
        errors.append(abs(energy - exact) / exact)
    # the sequential return mapping lags the continuous slider by O(1/nit)
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 1.0 / 1024


def test_separation_and_varying_normal_load():
    nit = 128
    tau = fourier.sample_times(nit)
    lam_u = np.zeros((nit, 1, 3))
    lam_u[:, 0, 0] = -1.0 + 1.5 * np.cos(tau)      # opens around τ = 0
    lam_u[:, 0, 1] = 2.0 * np.sin(tau)
    r = dlft_pass(lam_u, 0.4, np.zeros((1, 2)))
    sep = lam_u[:, 0, 0] >= 0
    assert np.all(r.state[sep, 0] == SEPARATION)
    assert np.all(r.lam[sep] == 0)
    cont = ~sep
    assert np.allclose(r.lam[cont, 0, 0], lam_u[cont, 0, 0])  # λ_N = λ_u^N in contact (g = 0)
    lt = np.linalg.norm(r.lam[:, 0, 1:], axis=1)
    assert np.all(lt <= 0.4 * np.abs(r.lam[:, 0, 0]) * (1 + 1e-12) + 1e-15)
    assert set(np.unique(r.state)) == {SEPARATION, STICK, SLIP}


def test_vectorised_over_pairs_equals_one_by_one():
    rng = np.random.default_rng(3)
    nit, p = 40, 6
    lam_u = rng.normal(size=(nit, p, 3)).cumsum(0) * 0.3
    lam_u[:, :, 0] -= 1.0
    mu = rng.uniform(0.1, 0.8, p)
    ref = rng.normal(size=(p, 2))
    r = dlft_pass(lam_u, mu, ref, max_passes=100, tol=1e-13)
    for i in range(p):
        ri = dlft_pass(lam_u[:, i:i + 1], mu[i], ref[i:i + 1], max_passes=100, tol=1e-13)
        assert np.allclose(ri.lam[:, 0], r.lam[:, i], atol=1e-9)


def test_passes_are_counted_and_limited():
    _, _, r = _jenkins_energy(64)
    assert r.passes == 2 and r.converged   # one pass to find the reference, one to confirm
    nit = 64
    tau = fourier.sample_times(nit)
    lam_u = np.zeros((nit, 1, 3))
    lam_u[:, 0, 0] = -1.0
    lam_u[:, 0, 1] = 2.0 * np.cos(tau)
    r1 = dlft_pass(lam_u, 0.5, np.array([[5.0, 0.0]]), max_passes=1)
    assert r1.passes == 1 and not r1.converged
    r0 = dlft_pass(lam_u, 0.5, np.array([[5.0, 0.0]]), periodic=False)
    assert r0.passes == 1 and r0.converged


def _fd_check(a, E, mu, ref, atol=1e-6):
    p = a.shape[1]

    def run(a):
        return dlft_pass(np.einsum("kj,jic->kic", E, a), mu, ref, basis=E, jacobian=True,
                         tol=1e-14, max_passes=200)

    r = run(a)
    h = 1e-7
    J = r.dlam
    Jfd = np.zeros_like(J)
    for j in range(a.shape[0]):
        for c in range(3):
            ap, am = a.copy(), a.copy()
            ap[j, :, c] += h
            am[j, :, c] -= h      # pairs are independent: perturb all at once
            Jfd[..., 3 * j + c] = (run(ap).lam - run(am).lam) / (2 * h)
    assert np.abs(J - Jfd).max() <= atol * max(1.0, np.abs(J).max())
    return r


@pytest.mark.parametrize("case", ["stick", "slip", "partial", "separation", "mixed", "shakedown"])
def test_sensitivity_matches_finite_differences(case):
    rng = np.random.default_rng({"stick": 1, "slip": 2, "partial": 3, "separation": 4, "mixed": 5,
                                 "shakedown": 6}[case])
    nh, nit, p = 3, 32, 4
    E = fourier.time_from_coef_matrix(nh, nit)
    a = np.zeros((2 * nh + 1, p, 3))
    a[0, :, 0] = -3.0
    a[1:3, :, 1:] = rng.normal(size=(2, p, 2))
    a[3:5, :, 1:] = 0.3 * rng.normal(size=(2, p, 2))
    mu = np.full(p, 0.5)
    ref = np.zeros((p, 2))
    if case == "stick":
        mu[:] = 10.0
        ref = rng.normal(size=(p, 2)) * 0.1
    elif case == "slip":   # circular orbits: never reverse, always slip
        a[1:5, :, 1:] = 0.0
        a[1, :, 1] = a[2, :, 2] = 1.0 + rng.random(p)
        a[0, :, 1:] = rng.normal(size=(p, 2))
        mu[:] = 0.1
    elif case == "separation":
        a[1, :, 0] = 5.0
    elif case == "mixed":
        a[1, :2, 0] = 5.0
        mu[2] = 10.0
    elif case == "shakedown":
        # the start anchor lies far outside the cone in 2D: the pairs slip once,
        # then stick touching it — a non-isolated periodic reference whose
        # direction, and derivative across the slip direction, come from the anchor
        a[1:, :, 1:] *= 0.2
        ref = 4.0 * rng.normal(size=(p, 2))
    r = _fd_check(a, E, mu, ref)
    counts = np.bincount(r.state.ravel(), minlength=3)
    expect = {"stick": [0, 1, 0], "slip": [0, 0, 1], "partial": [0, 1, 1],
              "separation": [1, 1, 1], "mixed": [1, 1, 1], "shakedown": [0, 1, 1]}[case]
    assert list(counts > 0) == [bool(e) for e in expect], counts


def test_fully_stuck_pair_keeps_its_reference():
    nit = 16
    lam_u = np.zeros((nit, 1, 3))
    lam_u[:, 0, 0] = -10.0
    lam_u[:, 0, 1] = 0.1 * np.cos(fourier.sample_times(nit))
    ref = np.array([[0.7, -0.2]])
    r = dlft_pass(lam_u, 0.5, ref)
    assert np.all(r.state == STICK)
    assert np.array_equal(r.ref_T, ref)
    assert np.allclose(r.lam[:, 0, 1:], lam_u[:, 0, 1:] - ref)


@pytest.mark.parametrize("compiled", [True, False])
def test_a_pre_slip_force_on_the_cone_to_round_off_sticks(compiled, monkeypatch):
    """A pair whose pre-slip force reaches the Coulomb cone to within the round-off of its
    operands (λ_pre^T = λ_u^T − λ_x^T, two forces of 1e5 N here, whose last bit is 1.5e-11 N)
    sticks — here 1e-10 N over the 5 N limit:
    its reference stays bit-for-bit and its force is the predictor's, on the cone to round-off.
    (Counted as slip, a reference moved by round-off each period wore a stuck interface at
    ~1e-29 m/cycle.) Beyond the band — here 5e-6 N over the 5 N limit — it slips as before and
    its reference moves by that much."""
    from workflow.engine import contact

    if not compiled:
        monkeypatch.setattr(contact, "_one_pass_numba", None)
    nit = 16
    t = fourier.sample_times(nit)
    ref = np.array([[1e5, 0.0]])
    for excess in (2e-11, 1e-6):
        lam_u = np.zeros((nit, 1, 3))
        lam_u[:, 0, 0] = -10.0
        lam_u[:, 0, 1] = 1e5 + 5.0 * (1.0 + excess) * np.cos(t)
        r = dlft_pass(lam_u, 0.5, ref, periodic=False)
        if excess < 1e-9:
            touching = np.isin(np.arange(nit), (0, nit // 2))        # |cos| = 1: on the cone
            assert np.array_equal(r.state[:, 0], np.where(touching, SLIP, STICK))
            assert np.array_equal(r.lam_x_T[:, 0], np.broadcast_to(ref[0], (nit, 2)))
            # over the cone by at most the band, 64 ε (‖λ_u^T‖ + ‖λ_x^T‖) = 2.8e-9 N here
            assert r.lam[0, 0, 1] == pytest.approx(5.0, abs=64 * np.finfo(float).eps * 2e5)
        else:
            moved = r.lam_x_T[0, 0] - ref[0]
            assert moved[0] == pytest.approx(5e-6, rel=1e-4) and moved[1] == 0.0
            assert r.lam[0, 0, 1] == pytest.approx(5.0, abs=1e-10)


def test_dlft_uses_anchor_displacement():
    law = ContactLaw(mu=[0.5], eps_n=1e3, eps_t=2e3, gap=[0.0])
    lam_u = np.zeros((4, 1, 3))
    lam_u[:, 0, 0] = -10.0
    r = dlft(law, lam_u, np.array([[1e-3, 0.0]]))
    assert np.allclose(r.lam[:, 0, 1], -2.0)   # λ^T = λ_u^T − ε_T·anchor


@pytest.mark.parametrize("field,value", [("mu", -0.1), ("mu", np.nan), ("eps_n", 0.0),
                                         ("eps_t", -1.0), ("wear", -1e-6), ("gap", np.inf)])
def test_contact_law_validation_names_the_key(field, value):
    kw = dict(mu=[0.3, 0.3], eps_n=1e5, eps_t=1e5, gap=[0.0, 0.0])
    if field in ("mu", "wear", "gap"):
        kw[field] = [0.3, value]
    else:
        kw[field] = value
    with pytest.raises(SceneError, match=f"contact.{field}"):
        ContactLaw(**kw)


def test_contact_law_broadcasts_and_offsets():
    law = ContactLaw(mu=0.3, eps_n=1e5, eps_t=[1e4, 2e4], gap=[1e-6, -2e-6], wear=[1e-7, 0.0])
    assert law.p == 2 and law.mu.shape == (2,)
    assert np.allclose(law.offset()[:, 0], [1.1e-6, -2e-6])
    assert np.allclose(law.eps()[1], [1e5, 2e4, 2e4])
    assert np.allclose(law.with_wear([0, 1e-6]).offset()[:, 0], [1e-6, -1e-6])
    with pytest.raises(SceneError, match="contact.mu"):
        ContactLaw(mu=[0.3, 0.3, 0.3], eps_n=1e5, eps_t=1e5, gap=[0.0, 0.0])


# ------------------------------------------------- compiled pass vs NumPy oracle
def _pass_cases():
    rng = np.random.default_rng(7)
    for nh, nit, p in [(1, 3, 5), (3, 32, 6), (7, 105, 16)]:
        E = fourier.time_from_coef_matrix(nh, nit)
        m = E.shape[1]
        a = rng.normal(size=(m, p, 3))
        a[0, :, 0] = -3.0
        a[1, :2, 0] = 5.0                          # pairs 0, 1 separate part of the period
        mu = np.full(p, 0.5)
        mu[2] = 10.0                               # pair 2 sticks
        mu[3] = 0.0                                # frictionless: slips with a zero bound
        a[1:, 4, 1:] = 0.0                         # pair 4: λ_pre^T = 0 at start (‖·‖ = 0 in slip)
        ref = 0.1 * rng.normal(size=(p, 2))
        ref[4] = a[0, 4, 1:]
        yield E, np.einsum("kj,jic->kic", E, a), mu, ref


def _dlu(E, jacobian):
    nit, m = E.shape
    if not jacobian:
        return np.zeros((nit, 3, 2))
    d = np.zeros((nit, 3, m, 3))
    for c in range(3):
        d[:, c, :, c] = E
    return np.concatenate([d.reshape(nit, 3, 3 * m), np.zeros((nit, 3, 2))], axis=2)


@pytest.mark.parametrize("jacobian", [False, True])
def test_loop_pass_matches_numpy_pass(jacobian):
    """The loop kernel (what numba compiles), run as plain Python, against the NumPy pass."""
    from workflow.engine import contact

    rng = np.random.default_rng(3)
    for E, lam_u, mu, ref in _pass_cases():
        nit, p = lam_u.shape[:2]
        for start in (np.zeros(p, np.int64), rng.integers(0, nit, p)):
            a = contact._one_pass_numpy(lam_u, mu, ref, _dlu(E, jacobian), start)
            b = contact._one_pass_loops(lam_u, mu, ref, _dlu(E, jacobian), start)
            assert np.array_equal(a[2], b[2])
            for x, y in zip(a, b):
                assert np.allclose(x, y, rtol=1e-13, atol=1e-13 * np.abs(lam_u).max())


def test_pass_started_later_is_the_pass_of_the_shifted_predictor():
    """A pass begun at instant s of λ_u is the pass begun at 0 of λ_u advanced by s samples,
    read back s samples later (what a whole disk's sectors rely on: ContactLaw.phase). Equal to
    round-off: the same operations in the same order."""
    for E, lam_u, mu, ref in _pass_cases():
        nit, p = lam_u.shape[:2]
        for s in (1, nit // 3, nit - 1):
            late = dlft_pass(lam_u, mu, ref, basis=E, jacobian=True, max_passes=40, tol=1e-12,
                             start=np.full(p, s))
            early = dlft_pass(np.roll(lam_u, -s, axis=0), mu, ref, basis=np.roll(E, -s, axis=0), jacobian=True,
                              max_passes=40, tol=1e-12)
            scale = np.abs(lam_u).max()
            assert np.abs(np.roll(early.lam, s, axis=0) - late.lam).max() <= 1e-12 * scale
            assert np.array_equal(np.roll(early.state, s, axis=0), late.state)
            assert np.abs(np.roll(early.dlam, s, axis=0) - late.dlam).max() <= 1e-12 * max(np.abs(early.dlam).max(), 1.0)


@pytest.mark.parametrize("jacobian", [False, True])
def test_numba_dlft_matches_numpy_dlft(jacobian, monkeypatch):
    """Full periodic DLFT (passes, acceleration, Jacobian columns) compiled vs NumPy."""
    from workflow.engine import contact

    if contact._one_pass_numba is None:
        pytest.skip("numba not importable: the NumPy pass is in use")
    for E, lam_u, mu, ref in _pass_cases():
        kw = dict(basis=E, jacobian=jacobian, max_passes=40, tol=1e-12)
        fast = contact.dlft_pass(lam_u, mu, ref, **kw)
        # the shaken-down state (pairs touching the cone) is exercised too
        fast2 = contact.dlft_pass(lam_u, mu, fast.ref_T, **kw)
        monkeypatch.setattr(contact, "_one_pass_numba", None)
        slow = contact.dlft_pass(lam_u, mu, ref, **kw)
        slow2 = contact.dlft_pass(lam_u, mu, slow.ref_T, **kw)
        monkeypatch.undo()
        scale = np.abs(lam_u).max()
        for f, s in ((fast, slow), (fast2, slow2)):
            assert f.passes == s.passes and f.converged == s.converged
            assert np.array_equal(f.state, s.state)
            assert np.allclose(f.lam, s.lam, rtol=1e-12, atol=1e-12 * scale)
            assert np.allclose(f.lam_x_T, s.lam_x_T, rtol=1e-12, atol=1e-12 * scale)
            if jacobian:
                assert np.allclose(f.dlam, s.dlam, rtol=1e-10, atol=1e-10 * max(1.0, np.abs(s.dlam).max()))


def test_rows_of_the_jacobian_equal_the_rows_times_the_full_jacobian():
    """``dlft_pass(rows=Q)`` (HBM's Galerkin projection applied before the periodic correction)
    equals Q times the per-instant dλ/da, on the pass cases (stick, slip, separation, the
    shaken-down state whose reference derivative is carried along the passes)."""
    checked = 0
    for E, lam_u, mu, ref in _pass_cases():
        nit = E.shape[0]
        m = E.shape[1]
        Q = np.linalg.pinv(E)               # (m, nit): the least-squares coefficients of samples
        for start in (ref, dlft_pass(lam_u, mu, ref, basis=E, max_passes=40, tol=1e-12).ref_T):
            kw = dict(basis=E, jacobian=True, max_passes=40, tol=1e-12)
            full = dlft_pass(lam_u, mu, start, **kw)
            rows = dlft_pass(lam_u, mu, start, rows=Q, **kw)
            want = np.tensordot(Q, full.dlam, axes=(1, 0))
            assert rows.dlam.shape == (m,) + full.dlam.shape[1:]
            assert np.abs(rows.dlam - want).max() <= 1e-12 * max(1.0, np.abs(want).max())
            assert np.array_equal(rows.lam, full.lam)
            checked += int(np.any(full.state == SLIP))
    assert checked
