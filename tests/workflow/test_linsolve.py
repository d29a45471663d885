"""The structured Newton linear solve (workflow/engine/linsolve.py) against the dense one.

Physics checked: the matrix-free J is the same ∂R/∂x as the dense analytic
Jacobian (and its transpose the transpose); GMRES steps equal the LU steps;
Newton with either reaches the same root within the solver tolerance for
HBM, TCM and HDHB on a friction-damped root model with stick, slip and
separation; the cascade switches automatically and keeps no (n × n) array.
"""
from __future__ import annotations

import numpy as np
import pytest

from tests.workflow.hbmodels import condense, law_for, root_model
from workflow.engine import cascade
from workflow.engine.hb import HBProblem
from workflow.engine.linsolve import StructuredSolve, zb_apply
from workflow.engine.solvers import DenseLU

P = 6
NH = 5
NIT = {"hbm": 32, "tcm": 33, "hdhb": 2 * NH + 1}


def _problem(method, omega_hz=24.0, eps=1e7, force=6.0, force_n=40.0):
    model = root_model(P, force=force, force_n=force_n, seed=1, preload=np.linspace(4.0, 20.0, P))
    Zr, Fr, _, _ = condense(model, 2 * np.pi * omega_hz, NH)
    return HBProblem(Zr, Fr, law_for(P, mu=0.3, eps=eps), NH, NIT[method], method)


def _slipping_state(prob):
    """The HBM root of the same model in ``prob``'s unknowns: a state with
    separation, stick and slip (TCM/HDHB roots lie close to it)."""
    hbm = HBProblem(prob.Zr, prob.Fr, prob.law, prob.nh, NIT["hbm"], "hbm")
    res = hbm.solve(hbm.x0(), tol=1e-10, maxiter=80)
    assert res.converged
    return prob.unknowns_from_harmonics(hbm.harmonics(res.x))


@pytest.mark.parametrize("method", ["hbm", "tcm", "hdhb"])
def test_operator_is_the_dense_jacobian(method):
    prob = _problem(method)
    x = _slipping_state(prob)
    x = x + 0.05 * np.abs(x).max() * np.random.default_rng(3).standard_normal(prob.n)
    R, J = prob.residual_jacobian(x)
    R2, op = prob.residual_operator(x)
    assert np.array_equal(R, R2) or np.allclose(R, R2, rtol=0, atol=1e-12 * np.abs(R).max())
    Jop = op.todense()
    assert np.abs(Jop - J).max() <= 1e-12 * np.abs(J).max()
    V = np.random.default_rng(4).standard_normal((prob.n, 3))
    assert np.allclose(op.rmatmat(V), J.T @ V, rtol=0, atol=1e-12 * np.abs(J.T @ V).max())


@pytest.mark.parametrize("method", ["hbm", "tcm", "hdhb"])
def test_a_bordered_solve_is_the_dense_bordered_solution(method):
    """``StructuredSolve.solve(R, border=(col, c, c_s))``: one GMRES on ``[[J, col], [cᵀ, c_s]]``
    (a held amplitude's load scale, workflow/engine/studies/amplitude.py), its border taken to
    K's coefficient space (TCM and HDHB: J = L K R). Against LAPACK on the formed matrix, to
    GMRES's tolerance (1e-10) times the bordered matrix's condition number (~1e3 here)."""
    prob = _problem(method)
    x = _slipping_state(prob)
    R, J = prob.residual_jacobian(x)
    _, op = prob.residual_operator(x)
    rng = np.random.default_rng(5)
    n = prob.n
    col = rng.standard_normal(n) * np.abs(J).max()
    c = rng.standard_normal(n) * np.abs(J).max()
    c_s = float(np.abs(J).max())
    rhs = rng.standard_normal(n + 1)
    Jt = np.block([[J, col[:, None]], [c[None, :], np.array([[c_s]])]])
    exact = np.linalg.solve(Jt, -rhs)
    lin = StructuredSolve()
    assert lin.factor(op)
    step = lin.solve(rhs, border=(col, c, c_s))
    assert step.shape == (n + 1,)
    assert np.abs(step - exact).max() <= 1e-6 * np.abs(exact).max()
    plain = lin.solve(R)                    # the same solver without a border: J dx = −R
    assert np.abs(J @ plain + R).max() <= 1e-8 * np.abs(R).max()


def test_zb_apply_is_the_real_block_matrix():
    from workflow.engine import fourier

    rng = np.random.default_rng(0)
    Zr = rng.standard_normal((4, 5, 5)) + 1j * rng.standard_normal((4, 5, 5))
    Zr[0] = Zr[0].real
    y = rng.standard_normal((7, 5))
    Zb = fourier.real_block_diag(Zr)
    assert np.allclose(zb_apply(Zr, y).ravel(), Zb @ y.ravel(), rtol=1e-13, atol=0)
    assert np.allclose(zb_apply(Zr, y, conj_transpose=True).ravel(), Zb.T @ y.ravel(), rtol=1e-13, atol=0)


def test_zb_apply_stays_in_single_precision():
    """The preconditioner's products run in complex64/float32 (half the bytes of a
    memory-bound product) and equal the double ones to float32 round-off."""
    rng = np.random.default_rng(0)
    Zr = rng.standard_normal((4, 5, 5)) + 1j * rng.standard_normal((4, 5, 5))
    y = rng.standard_normal((7, 5))
    ref = zb_apply(Zr, y)
    out = zb_apply(Zr.astype(np.complex64), y.astype(np.float32))
    assert out.dtype == np.float32
    assert np.abs(out - ref).max() <= 1e-5 * np.abs(ref).max()


def test_hdhb_operator_applied_with_ffts_equals_dense_h():
    prob = _problem("hdhb")
    y = np.random.default_rng(1).standard_normal((prob.nc, prob.nr))
    ref = prob.A @ y.ravel()
    assert np.linalg.norm(prob._apply_A(y).ravel() - ref) <= 1e-13 * np.linalg.norm(ref)


@pytest.mark.parametrize("method", ["hbm", "hdhb"])
@pytest.mark.parametrize("small", [True, False])
@pytest.mark.parametrize("clusters", [False, True])
def test_gmres_step_equals_lu_step(method, small, clusters, monkeypatch):
    """Both layouts of the preconditioner: explicit inverses and real harmonic blocks (small
    interfaces, the test model) and the LUs with the complex Zr of large ones; blocks of one
    pair (small interfaces) and of clusters of pairs (large ones: here 5 + 1 of the 6 pairs)."""
    from workflow.engine import linsolve

    if not small:
        monkeypatch.setattr(linsolve, "INVERSE_MAX_DOFS", 0)
    if clusters:
        monkeypatch.setattr(linsolve, "CLUSTER_MIN_DOFS", 0)
    prob = _problem(method)
    x = _slipping_state(prob) * 1.05
    states = prob.contact_state(x)
    assert (states == 2).any() and np.unique(states).size >= 2 + (method == "hbm")   # mixed states
    R, J = prob.residual_jacobian(x)
    _, op = prob.residual_operator(x)
    dense, lin = DenseLU(), StructuredSolve()
    assert dense.factor(J) and lin.factor(op)
    dx_d, dx_s = dense.solve(R), lin.solve(R)
    # the preconditioner in single precision, the step the double-precision one (FGMRES)
    assert lin.stats["precision"] == "single"
    assert np.linalg.norm(dx_s - dx_d) <= 1e-7 * np.linalg.norm(dx_d)
    assert lin.stats["gmres_iterations"] < prob.n        # the preconditioner does the work
    assert [g.shape for g in lin._groups[1]] == ([(1, 5), (1, 1)] if clusters else [(P, 1)])
    # the next Newton step at the same frequency reuses the single-precision copy of Zr (a small
    # interface: its real harmonic blocks, linsolve.real_blocks)
    zr32 = lin._pre[0]
    if small:
        assert lin._inv is not None and all(z.dtype == np.float32 for z in zr32)
    else:
        assert lin._inv is None and zr32.dtype == np.complex64
    assert lin.factor(prob.residual_operator(x * 1.01)[1]) and lin._pre[0] is zr32


def test_real_blocks_equal_the_complex_product():
    from workflow.engine.linsolve import k_apply, k_apply_blocks, real_blocks, zb_apply, zb_apply_blocks

    rng = np.random.default_rng(3)
    nh, p, k = 4, 3, 2
    nr, nc = 3 * p, 2 * nh + 1
    Zr = rng.normal(size=(nh + 1, nr, nr)) + 1j * rng.normal(size=(nh + 1, nr, nr))
    Y = rng.normal(size=(nc, nr, k))
    Gt, eps = rng.normal(size=(p, 3 * nc, 3 * nc)), rng.uniform(1.0, 2.0, nr)
    assert np.allclose(zb_apply_blocks(real_blocks(Zr), Y), zb_apply(Zr, Y), rtol=0, atol=1e-12)
    assert np.allclose(k_apply_blocks(real_blocks(Zr), Gt, eps, Y, nc, p), k_apply(Zr, Gt, eps, Y, nc, p),
                       rtol=0, atol=1e-11)


def test_single_precision_blocks_out_of_range_fall_back_to_double():
    """ε beyond float32's range (3.4e38) overflows the single-precision preconditioner:
    the solver switches to double for good and its step is the double-precision solver's."""
    x = _slipping_state(_problem("hbm")) * 1.05
    prob = _problem("hbm", eps=1e39)
    R, op = prob.residual_operator(x)
    single, double = StructuredSolve(), StructuredSolve(single=False)
    assert single.factor(op) and double.factor(op)
    dx, ref = single.solve(R), double.solve(R)
    assert single.stats["precision"] == "double" and single.stats["factorizations"] == 2
    assert dx is not None and np.array_equal(dx, ref)


@pytest.mark.parametrize("method", ["hbm", "tcm", "hdhb"])
@pytest.mark.parametrize("omega_hz", [25.0, 27.0, 29.0])
def test_newton_roots_agree_within_tolerance(method, omega_hz):
    prob = _problem(method, omega_hz)
    tol = 1e-9
    ref = cascade.solve_point(prob, [_slipping_state(prob)], solver="newton", tol=tol, maxiter=60)
    assert ref.converged
    x0 = ref.result.x * 1.03          # a start off the root, the same for both
    rd = prob.solve(x0, tol=tol, maxiter=80)
    rs = prob.solve(x0, tol=tol, maxiter=80, linear="structured")
    assert rd.converged and rs.converged
    scale = prob.residual_scale()
    assert np.linalg.norm(prob.residual(rs.x)) <= tol * scale
    # both roots of the same well-posed system: their gap is bounded by the
    # residual tolerance through the Jacobian's conditioning (J⁻¹ of the root)
    _, J = prob.residual_jacobian(rd.x)
    bound = 2 * tol * scale * np.linalg.norm(np.linalg.inv(J), 2)
    assert np.linalg.norm(rs.x - rd.x) <= max(bound, 1e-12 * np.linalg.norm(rd.x))


def test_structured_solve_keeps_no_dense_matrix():
    prob = _problem("hbm")
    res = prob.solve(prob.x0(), tol=1e-9, maxiter=80, linear="structured")
    assert res.converged
    assert prob._dense is None and prob._pen is None


def test_cascade_switches_automatically(monkeypatch):
    assert cascade.linear_solver(cascade.STRUCTURED_MIN_UNKNOWNS - 1) == "dense"
    assert cascade.linear_solver(cascade.STRUCTURED_MIN_UNKNOWNS) == "structured"
    prob = _problem("hbm", 25.0)
    dense = cascade.solve_point(prob, [prob.x0()], solver="newton", tol=1e-9, maxiter=60)
    monkeypatch.setattr(cascade, "STRUCTURED_MIN_UNKNOWNS", 0)
    prob2 = _problem("hbm", 25.0)
    structured = cascade.solve_point(prob2, [prob2.x0()], solver="newton", tol=1e-9, maxiter=60)
    assert dense.converged and structured.converged
    assert isinstance(prob2.linsolver, StructuredSolve) and prob2.linsolver.stats["solves"] > 0
    assert prob2._dense is None
    U_d, U_s = prob.harmonics(dense.result.x), prob2.harmonics(structured.result.x)
    assert np.abs(U_s - U_d).max() <= 1e-6 * np.abs(U_d).max()


def test_bad_linear_solver_name():
    from workflow.errors import SceneError

    prob = _problem("hbm")
    with pytest.raises(SceneError, match="linear_solver"):
        prob.solve(prob.x0(), linear="cholesky")


@pytest.mark.parametrize("method", ["hbm", "hdhb"])
@pytest.mark.parametrize("omega_hz", [20.0, 29.0])
def test_block_jacobi_pseudo_time_reaches_the_newton_root(method, omega_hz):
    from workflow.engine.pseudotime_blocks import integrate_pairs

    prob = _problem(method, omega_hz)
    tol = 1e-9
    ref = cascade.solve_point(prob, [_slipping_state(prob)], solver="newton", tol=tol, maxiter=60)
    assert ref.converged
    r = integrate_pairs(prob.residual, prob.residual_operator, ref.result.x * 1.03, tol=tol,
                        scale=prob.residual_scale(), max_steps=300, blocks="pairs+harmonics")
    assert r.converged and r.steps > 1          # a march, not one Newton step
    assert np.linalg.norm(r.x - ref.result.x) <= 1e-6 * np.linalg.norm(ref.result.x)
    with pytest.raises(ValueError, match="pseudotime.blocks"):
        integrate_pairs(prob.residual, prob.residual_operator, ref.result.x, blocks="instants")


def test_matrix_free_size_is_never_below_the_structured_one(monkeypatch):
    """Between the two sizes Newton's solve is structured and its fallbacks still dense."""
    n = cascade.STRUCTURED_MIN_UNKNOWNS
    assert cascade.STRUCTURED_MIN_UNKNOWNS <= cascade.MATRIX_FREE_MIN_UNKNOWNS
    assert cascade.linear_solver(n) == "structured" and not cascade.matrix_free(n)
    assert cascade.matrix_free(cascade.MATRIX_FREE_MIN_UNKNOWNS)
    monkeypatch.setattr(cascade, "MATRIX_FREE_MIN_UNKNOWNS", 0)
    assert not cascade.matrix_free(n - 1) and cascade.matrix_free(n)


def test_dense_newton_follows_a_structured_newton_that_stops_below_the_matrix_free_size(monkeypatch):
    """A structured Newton that gives up (here: its linear solve refuses every step) is followed,
    below the matrix-free size, by Newton on the dense J from the best guess, before MINPACK;
    the point is reported "newton-dense" and equals the plain dense Newton root."""
    monkeypatch.setattr(cascade, "STRUCTURED_MIN_UNKNOWNS", 0)
    monkeypatch.setattr(StructuredSolve, "solve", lambda self, R, rtol=None: None)
    prob = _problem("hbm", 29.0)
    assert not cascade.matrix_free(prob.n)
    calls = []
    run = cascade.run_solver

    def spy(q, x, solver, tol, maxiter, pseudo=None, linear=None):
        calls.append((solver, linear))
        return run(q, x, solver, tol, maxiter, pseudo, linear=linear)

    monkeypatch.setattr(cascade, "run_solver", spy)
    x0 = _slipping_state(prob) * 1.03
    pr = cascade.solve_point(prob, [x0], solver="newton-powell", tol=1e-9, maxiter=60)
    assert pr.converged and pr.how == "newton-dense"
    assert calls == [("newton", None), ("newton", "dense")]
    ref = _problem("hbm", 29.0).solve(x0, tol=1e-9, maxiter=60)
    assert np.abs(pr.result.x - ref.x).max() <= 1e-8 * np.abs(ref.x).max()


def test_cascade_pseudo_time_is_matrix_free_when_structured(monkeypatch):
    monkeypatch.setattr(cascade, "STRUCTURED_MIN_UNKNOWNS", 0)
    monkeypatch.setattr(cascade, "MATRIX_FREE_MIN_UNKNOWNS", 0)
    prob = _problem("hbm", 29.0)
    ref = prob.solve(_slipping_state(prob), tol=1e-9, maxiter=80)
    fresh = _problem("hbm", 29.0)
    res = cascade.run_solver(fresh, ref.x * 1.03, "pseudo-time", 1e-9, 300)
    assert res.scheme == "block-jacobi-pairs" and res.converged
    assert fresh._dense is None


def test_powell_is_replaced_by_matrix_free_pseudo_time_at_the_matrix_free_size(monkeypatch):
    monkeypatch.setattr(cascade, "STRUCTURED_MIN_UNKNOWNS", 0)
    monkeypatch.setattr(cascade, "MATRIX_FREE_MIN_UNKNOWNS", 0)
    prob = _problem("hbm", 25.0)
    res = cascade.run_solver(prob, prob.x0(), "powell", 1e-9, 50)
    assert res.scheme == "block-jacobi-pairs"
    assert prob._dense is None


@pytest.mark.parametrize("method", ["hbm", "hdhb"])
def test_lm_steps_share_one_bidiagonalisation_and_equal_lsqr(method, monkeypatch):
    """The matrix-free Levenberg–Marquardt step is LSQR's iterate after LM_ITERS
    steps (the same Krylov space, damped), for every damping of a search; the
    dampings share one Golub–Kahan bidiagonalisation (2·LM_ITERS products of J);
    a large damping turns it into the scaled steepest-descent direction −JᵀR/ν."""
    import scipy.sparse.linalg

    from workflow.engine import linsolve

    prob = _problem(method)
    x = _slipping_state(prob) * 1.05
    R, J = prob.residual_jacobian(x)
    _, op = prob.residual_operator(x)
    lin = StructuredSolve()
    assert lin.factor(op)
    scale = lin.lm_scale()
    products = []
    for name in ("_matvec", "_rmatvec"):
        real = getattr(op, name)
        monkeypatch.setattr(op, name, lambda v, real=real: products.append(1) or real(v))
    steps = {nu: lin.lm_step(R, nu * scale) for nu in (1e-2, 1e-1, 1.0, 1e4)}
    assert len(products) == 2 * linsolve.LM_ITERS
    monkeypatch.undo()
    for nu, dx in steps.items():
        ref = scipy.sparse.linalg.lsqr(op, -R, damp=np.sqrt(nu * scale), atol=0, btol=0,
                                       iter_lim=linsolve.LM_ITERS)[0]
        assert np.linalg.norm(dx - ref) <= 1e-6 * np.linalg.norm(ref)
    sd = -J.T @ R / (1e4 * scale)
    assert np.linalg.norm(steps[1e4] - sd) <= 1e-3 * np.linalg.norm(sd)


def test_lagged_blocks_are_renewed_when_their_extra_gmres_iterations_cost_a_factorisation(monkeypatch):
    """The preconditioner's blocks are refactored once the GMRES iterations beyond
    REFRESH_ITERS add up to one factorisation's cost (FACTOR_ITERS, by 3p),
    not at the first slow solve; a fresh factorisation starts the count again."""
    from workflow.engine import linsolve

    prob = _problem("hbm")
    _, op = prob.residual_operator(_slipping_state(prob) * 1.05)
    # this 6-pair model's blocks cost < 1 iteration; give them the 128-pair sector's ~10
    monkeypatch.setattr(linsolve, "FACTOR_ITERS", (float(op.nr), 10.0, 1.4))
    lin = StructuredSolve()
    assert lin.factor(op) and lin.stats["factorizations"] == 1
    budget = 10.0
    extra = max(1, int(np.ceil(budget / 3)))
    over = linsolve.REFRESH_ITERS + extra
    lin._account(linsolve.REFRESH_ITERS)            # at the threshold: free
    lin._account(5, 1e-2)                            # a solve to 1e-2: its share, 25·2/10 = 5, is free too
    assert lin._excess < 1e-9
    for _ in range(int(np.ceil(budget / extra)) - 1):
        lin._account(over)
        assert lin.factor(op) and lin.stats["factorizations"] == 1    # blocks kept
    lin._account(over)                               # the excess reaches one factorisation
    assert lin.factor(op) and lin.stats["factorizations"] == 2
    lin._account(over)
    assert lin.factor(op) and lin.stats["factorizations"] == 2


def test_blas_cores_respects_the_environment_and_the_ranks_on_the_node(monkeypatch):
    from workflow.engine import blas

    for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "OMPI_COMM_WORLD_LOCAL_SIZE", "MPI_LOCALNRANKS",
              "OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "PMI_RANK", "BLADEWEAR_MPI"):
        monkeypatch.delenv(k, raising=False)
    monkeypatch.setattr(blas.os, "sched_getaffinity", lambda pid: {0, 1, 2, 3})
    assert blas.blas_cores() == 4
    monkeypatch.setenv("OMPI_COMM_WORLD_SIZE", "2")
    monkeypatch.setenv("OMPI_COMM_WORLD_LOCAL_SIZE", "2")
    assert blas.blas_cores() == 2                   # two ranks share the node's cores
    monkeypatch.delenv("OMPI_COMM_WORLD_LOCAL_SIZE")
    assert blas.blas_cores() == 1                   # a launcher that does not say: never oversubscribe
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "3")
    assert blas.blas_cores() == 3                   # a user's (or a benchmark's) setting wins


def test_large_structured_solves_run_blas_on_the_cores_and_restore_the_count(monkeypatch):
    from workflow.engine import blas

    handles = blas._openblas_handles()
    if not handles:
        pytest.skip("no OpenBLAS in this process")
    get = handles[0][1]
    prob = _problem("hbm")
    R, op = prob.residual_operator(_slipping_state(prob) * 1.05)
    seen = []
    k_solve = StructuredSolve._k_solve
    monkeypatch.setattr(StructuredSolve, "_k_solve", lambda self, b, *a: (seen.append(get()), k_solve(self, b, *a))[1])
    monkeypatch.setattr(blas, "blas_cores", lambda: 2)
    with blas.blas_threads(1):
        lin = StructuredSolve()
        assert lin.factor(op) and lin.solve(R) is not None
        assert seen == [1] and get() == 1             # a small interface: the caller's one thread
        monkeypatch.setattr(blas, "THREADED_MIN_DOFS", op.nr)
        assert lin.solve(R) is not None
        assert seen[-1] == 2 and get() == 1           # a large one: the cores, then the caller's count again


def test_pair_clusters_partition_the_pairs_into_coupled_neighbours():
    """Every pair in exactly one cluster of at most ``size``; on a chain of pairs coupled only
    to their neighbours (a row of flank nodes) the clusters are runs of neighbours."""
    from workflow.engine.linsolve import cluster_groups, pair_clusters

    p = 11
    Z0 = np.zeros((3 * p, 3 * p))
    for q in range(p):
        Z0[3 * q:3 * q + 3, 3 * q:3 * q + 3] = 4.0 * np.eye(3)
        if q + 1 < p:
            Z0[3 * q:3 * q + 3, 3 * q + 3:3 * q + 6] = Z0[3 * q + 3:3 * q + 6, 3 * q:3 * q + 3] = -np.eye(3)
    order = np.random.default_rng(0).permutation(p)            # pairs numbered in any order
    Zp = Z0.reshape(p, 3, p, 3)[order][:, :, order].reshape(3 * p, 3 * p)
    clusters = pair_clusters(Zp, 4)
    assert sorted(np.concatenate(clusters).tolist()) == list(range(p))
    assert [len(c) for c in clusters] == [4, 4, 3]
    for c in clusters:                                          # neighbours on the chain
        pos = np.sort(order[c])
        assert np.all(np.diff(pos) == 1)
    groups = cluster_groups(clusters)
    assert [g.shape for g in groups] == [(2, 4), (1, 3)]
    assert [len(c) for c in pair_clusters(Zp, 1)] == [1] * p


@pytest.mark.parametrize("method", ["hbm", "hdhb"])
def test_cluster_blocks_are_the_blocks_of_the_dense_k(method):
    """K_CC = Zb_CC + G̃_C (E_C − Zb_CC) is K restricted to a cluster's unknowns (all harmonics of
    its pairs), for clusters of several pairs and of one (the pair blocks of the block-Jacobi
    pseudo-time)."""
    from workflow.engine.linsolve import ContactJacobian

    prob = _problem(method)
    x = _slipping_state(prob) * 1.05
    _, op = prob.residual_operator(x)
    K = ContactJacobian(op.Zr, op.eps, op.Gt).todense()       # coefficient space, no L_r, L_p
    nc, p = op.nc, op.p
    idx = np.array([[0, 2, 5], [1, 3, 4]])
    blocks = op.cluster_blocks(idx)
    K6 = K.reshape(nc, p, 3, nc, p, 3)
    for b, c in zip(blocks, idx):
        ref = K6[:, c][:, :, :, :, c].transpose(1, 0, 2, 4, 3, 5).reshape(b.shape)
        assert np.abs(b - ref).max() <= 1e-12 * np.abs(ref).max()
    pairs = op.pair_blocks()                                   # one pair per cluster
    for q in range(p):
        ref = K6[:, q, :, :, q, :].reshape(pairs[q].shape)
        assert np.abs(pairs[q] - ref).max() <= 1e-12 * np.abs(ref).max()



@pytest.mark.parametrize("method", ["hbm", "hdhb"])
def test_harmonic_blocks_are_the_blocks_of_the_dense_k(method):
    """K_hh = (I − G̃_hh) Zb_hh + G̃_hh E is K restricted to one harmonic's (cos, sin)
    coefficients of every pair; formed in float32 it equals them to float32 round-off."""
    from workflow.engine.linsolve import ContactJacobian

    prob = _problem(method)
    x = _slipping_state(prob) * 1.05
    _, op = prob.residual_operator(x)
    assert np.any(np.abs(op.Gt) > 0) and np.any(op.Gt != np.eye(op.Gt.shape[1]))   # slipping pairs
    K = ContactJacobian(op.Zr, op.eps, op.Gt).todense()       # coefficient space, no L_r, L_p
    K4 = K.reshape(op.nc, op.nr, op.nc, op.nr)
    for dtype, rtol in ((np.float64, 1e-12), (np.float32, 1e-6)):
        for idx, b in op.harmonic_blocks(dtype):
            assert b.dtype == dtype
            ref = K4[idx][:, :, idx].reshape(b.shape)
            assert np.abs(b - ref).max() <= rtol * np.abs(ref).max()


def test_complex_harmonic_blocks_are_k_with_the_complex_linear_part_of_g():
    """The LUs' complex blocks B_h (h ≥ 1) are K_hh with each pair's (cos, sin) block of G̃_hh
    replaced by its complex-linear part (ĝ = (g_cc + g_ss)/2 + i (g_cs − g_sc)/2): exactly
    the real K_hh of that G̃, in the real form [[Re B, Im B], [−Im B, Re B]]; harmonic 0's block
    is K_00 itself. Slipping pairs have an anti-linear part, so B_h is not K_hh there."""
    from workflow.engine import fourier
    from workflow.engine.linsolve import ContactJacobian

    prob = _problem("hbm")
    _, op = prob.residual_operator(_slipping_state(prob) * 1.05)
    nc, p = op.nc, op.p
    G = op.Gt.reshape(p, nc, 3, nc, 3).copy()
    for h in range(1, op.nh + 1):
        c, s = 2 * h - 1, 2 * h
        a = 0.5 * (G[:, c, :, c, :] + G[:, s, :, s, :])
        b = 0.5 * (G[:, c, :, s, :] - G[:, s, :, c, :])
        G[:, c, :, c, :], G[:, s, :, s, :], G[:, c, :, s, :], G[:, s, :, c, :] = a, a, b, -b
    linear = ContactJacobian(op.Zr, op.eps, G.reshape(op.Gt.shape))
    gap = 0.0
    for (idx, B), (_, K), (_, K_true) in zip(op.complex_harmonic_blocks(), linear.harmonic_blocks(),
                                             op.harmonic_blocks()):
        R = B.real if len(idx) == 1 else fourier.real_block(B)
        assert np.abs(R - K).max() <= 1e-12 * np.abs(K).max()
        gap = max(gap, np.abs(K_true - K).max() / np.abs(K_true).max())
    assert gap > 1e-3                                           # the slipping pairs' anti-linear part
    for (_, B64), (_, B32) in zip(op.complex_harmonic_blocks(), op.complex_harmonic_blocks(np.float32)):
        assert B32.dtype in (np.float32, np.complex64)
        assert np.abs(B32 - B64).max() <= 1e-6 * np.abs(B64).max()


@pytest.mark.parametrize("omega_hz", [25.0, 27.0, 29.0])
def test_inexact_newton_steps_reach_the_same_root(omega_hz, monkeypatch):
    """Newton with the structured solve takes Eisenstat–Walker linear tolerances
    (workflow.engine.solvers.forcing): GMRES stops at each step's own tolerance, and the root
    equals the one of steps solved to GMRES_RTOL within the residual tolerance."""
    from workflow.engine import linsolve, solvers

    prob = _problem("hbm", omega_hz)
    tol = 1e-9
    x0 = _slipping_state(prob) * 1.03
    seen = []
    k_solve = StructuredSolve._k_solve

    def spy(self, b, rtol=linsolve.GMRES_RTOL):
        out = k_solve(self, b, rtol)
        seen.append((rtol, out[1]))
        return out

    roots = {}
    for eta_max in (0.0, solvers.ETA_MAX):
        monkeypatch.setattr(solvers, "ETA_MAX", eta_max)
        monkeypatch.setattr(StructuredSolve, "_k_solve", spy)
        seen.clear()
        res = prob.solve(x0, tol=tol, maxiter=80, linear="structured", linsolver=StructuredSolve())
        assert res.converged
        roots[eta_max] = res.x
        assert all(rel <= rtol for rtol, rel in seen)              # each solve to its own tolerance
        assert seen[0][0] == max(eta_max, linsolve.GMRES_RTOL)     # the first step: η_0
    exact, loose = roots[0.0], roots[solvers.ETA_MAX]
    scale = prob.residual_scale()
    assert np.linalg.norm(prob.residual(loose)) <= tol * scale
    _, J = prob.residual_jacobian(exact)
    bound = 2 * tol * scale * np.linalg.norm(np.linalg.inv(J), 2)
    assert np.linalg.norm(loose - exact) <= max(bound, 1e-12 * np.linalg.norm(exact))


def test_cascade_tries_the_guess_with_the_smaller_residual_first():
    """The cascade's solver attempts go through its guesses smallest ‖R‖ first: from [far,
    near] it converges from the near one and pays only that solve's iterations (the
    sweep's secant guess first cost 25 wasted Newton steps at a 512-pair resonance point
    whose nearest root converged in 8)."""
    prob = _problem("hbm", 27.0)
    tol = 1e-9
    root = cascade.solve_point(prob, [_slipping_state(prob)], solver="newton", tol=tol, maxiter=60)
    assert root.converged
    near, far = root.result.x * 1.01, prob.x0()
    assert np.linalg.norm(prob.residual(near)) < 0.1 * np.linalg.norm(prob.residual(far))
    alone = cascade.solve_point(prob, [near], solver="newton", tol=tol, maxiter=60)
    both = cascade.solve_point(prob, [far, near], solver="newton", tol=tol, maxiter=60)
    assert alone.converged and both.converged and alone.iterations > 0
    assert both.how == "guess1" and both.iterations == alone.iterations
    assert np.array_equal(both.result.x, alone.result.x)


def test_cascade_resumes_a_guess_that_ran_out_of_iterations_while_converging(monkeypatch):
    """Attempt 3: a guess's Newton that stops at its budget (15 here) well below the guesses'
    ‖R‖ is resumed where it stopped — the same iterates as one longer Newton, to the bit —
    instead of the cascade starting again from far. Gated by RESUME_RATIO: here ‖R‖ fell to
    1.4e-2 of the start in 15 steps, so the default 1e-3 leaves it to the later attempts."""
    prob = _problem("hbm", 25.0)
    tol, far = 1e-9, prob.x0()
    longer = prob.solve(far, tol=tol, maxiter=60, max_backtracks=10)
    assert longer.converged and 15 < longer.iterations <= 30
    pr = cascade.solve_point(prob, [far], solver="newton", tol=tol, maxiter=60)
    assert pr.converged and pr.how != "resumed"
    monkeypatch.setattr(cascade, "RESUME_RATIO", 0.1)
    pr = cascade.solve_point(prob, [far], solver="newton", tol=tol, maxiter=60)
    assert pr.converged and pr.how == "resumed"
    assert pr.iterations == longer.iterations and np.array_equal(pr.result.x, longer.x)


@pytest.mark.slow  # 4–9 s on the 2-core machine: make test-slow keeps make test within 3 min
def test_cascade_ends_with_newton_on_the_whole_budget(monkeypatch):
    """Attempt 9: from the 6-pair model's linear solution at 24 Hz, Newton creeps for some
    30 steps before its stick/slip pattern settles; every shorter attempt fails (the point
    was lost), one Newton run with the whole budget converges — to the root of a plain
    Newton from the same start, within the residual tolerance."""
    prob = _problem("hbm", 24.0)
    tol, far = 1e-9, prob.x0()
    plain = prob.solve(far, tol=tol, maxiter=100, max_backtracks=10)
    assert plain.converged and plain.iterations > 25
    monkeypatch.setattr(cascade, "FULL_BUDGET", False)
    lost = cascade.solve_point(prob, [far], solver="newton", tol=tol, maxiter=100)
    assert not lost.converged and lost.how == "failed"
    monkeypatch.setattr(cascade, "FULL_BUDGET", True)
    pr = cascade.solve_point(prob, [far], solver="newton", tol=tol, maxiter=100)
    assert pr.converged and pr.how == "full-budget" and pr.iterations > lost.iterations
    scale = prob.residual_scale()
    assert np.linalg.norm(prob.residual(pr.result.x)) <= tol * scale
    _, J = prob.residual_jacobian(plain.x)
    bound = 2 * tol * scale * np.linalg.norm(np.linalg.inv(J), 2)
    assert np.linalg.norm(pr.result.x - plain.x) <= max(bound, 1e-12 * np.linalg.norm(plain.x))


@pytest.mark.parametrize("method", ["hbm", "tcm", "hdhb"])
def test_line_search_points_from_two_products_equal_the_residual(method, monkeypatch):
    """:meth:`HBProblem.residual_along`: R(x + α dx) from A x and A dx (A linear) equals the
    residual evaluated afresh to round-off, makes one product with Zb for all its trial points,
    and the Jacobian at the last trial point makes none."""
    import workflow.engine.hb as hbmod

    prob = _problem(method)
    x = _slipping_state(prob)
    rng = np.random.default_rng(5)
    x = x + 0.05 * np.abs(x).max() * rng.standard_normal(prob.n)
    dx = 0.1 * np.abs(x).max() * rng.standard_normal(prob.n)
    fresh = {a: prob.residual(x + a * dx) for a in (1.0, 0.5, 0.125)}
    calls = []
    zb = hbmod.zb_apply
    monkeypatch.setattr(hbmod, "zb_apply", lambda *a, **k: calls.append(1) or zb(*a, **k))
    prob.residual(x)
    calls.clear()
    at = prob.residual_along(x, dx)
    for a, R in fresh.items():
        xt, Rt = at(a)
        assert np.array_equal(xt, x + a * dx)
        assert np.abs(Rt - R).max() <= 1e-12 * np.abs(R).max()
    assert len(calls) == 1                       # A dx; A x was the last residual's
    prob.residual_operator(xt)
    assert len(calls) == 1                       # the accepted point's A x is kept


def test_structured_newton_line_search_makes_one_product_a_direction(monkeypatch):
    """A structured Newton solve with backtracking makes one product with Zb per direction
    (and one at the start), and reaches the root of a solve whose every trial point is
    evaluated afresh (the same iterates to round-off)."""
    import workflow.engine.hb as hbmod
    from workflow.engine import solvers

    prob = _problem("hbm", 27.0)
    x0 = _slipping_state(prob) * 1.5          # far enough that the line search backtracks
    tol = 1e-9
    calls, trials = [], []
    zb = hbmod.zb_apply
    monkeypatch.setattr(hbmod, "zb_apply", lambda *a, **k: calls.append(1) or zb(*a, **k))
    ls = solvers._line_search
    monkeypatch.setattr(solvers, "_line_search", lambda *a: trials.append(1) or ls(*a))
    res = prob.solve(x0, tol=tol, maxiter=80, linear="structured")
    assert res.converged and res.function_evaluations > len(trials) + 1   # some step backtracked
    assert len(calls) == len(trials) + 1
    monkeypatch.setattr(prob, "residual_along", None)
    ref = solvers.newton(prob.residual_operator, x0, fun=prob.residual, tol=tol, scale=prob.residual_scale(),
                         maxiter=80, linear=StructuredSolve())
    assert ref.converged and ref.iterations == res.iterations
    assert np.abs(ref.x - res.x).max() <= 1e-9 * np.abs(ref.x).max()


def test_dropping_negligible_entries_keeps_the_solve():
    """Entries below ε(dtype)² of their row and column scale are dropped from the preconditioner's
    blocks (their subnormal products slowed a 2256² complex64 LU 70×): a block with round-off
    entries 1e-30 of its scale solves, in float32, as the block without them does — to float32's
    own precision, the bound of anything factored in it."""
    from workflow.engine.linsolve import drop_negligible

    rng = np.random.default_rng(0)
    n = 60
    A = np.triu(np.tril(rng.standard_normal((n, n)), 3), -3) + 8 * np.eye(n)     # banded: zeros elsewhere
    noise = 1e-30 * rng.standard_normal((n, n)) * (A == 0)
    B = (A + noise).astype(np.float32)
    kept = drop_negligible(B.copy(), np.float32)
    assert np.count_nonzero(kept) == np.count_nonzero(A)            # only the round-off went
    b = rng.standard_normal(n)
    exact = np.linalg.solve(A, b)
    x = np.linalg.solve(kept, b.astype(np.float32))
    assert np.abs(x - exact).max() <= 50 * np.finfo(np.float32).eps * np.abs(exact).max()


def test_a_solver_and_its_blocks_are_freed_after_its_solves():
    """PETSc keeps a solve's Python contexts (operator, preconditioner) alive past destroy();
    they must not keep the solver, whose Z_r copy and LU factors are 0.67 GB a point on the
    47-blade disk: a solver dropped after a few solves is collected."""
    import gc
    import weakref

    prob = _problem("hbm")
    x = _slipping_state(prob) * 1.05
    lin = StructuredSolve()
    for k in range(3):
        R, _ = prob.residual_jacobian(x * (1 + 0.01 * k))
        assert lin.factor(prob.residual_operator(x * (1 + 0.01 * k))[1])
        assert lin.solve(R) is not None
    gone = weakref.ref(lin)
    del lin
    gc.collect()
    assert gone() is None


def test_dropping_negligible_entries_of_a_stack_is_per_matrix():
    """A stack (g, m, m) — the cluster inverses — drops each matrix's round-off against its own
    row and column scales, as each matrix alone does: a matrix 1e12 larger does not make the
    other's entries negligible."""
    from workflow.engine.linsolve import drop_negligible

    rng = np.random.default_rng(1)
    A = np.triu(np.tril(rng.standard_normal((2, 30, 30)), 2), -2) + 6 * np.eye(30)
    A[1] *= 1e12
    A += 1e-30 * rng.standard_normal(A.shape) * (A == 0) * np.array([1.0, 1e12])[:, None, None]
    one = [drop_negligible(A[i].copy(), np.float32) for i in range(2)]
    both = drop_negligible(A.copy(), np.float32)
    assert all(np.array_equal(both[i], one[i]) for i in range(2))
    assert np.count_nonzero(both[0]) == np.count_nonzero(np.triu(np.tril(np.ones((30, 30)), 2), -2))
