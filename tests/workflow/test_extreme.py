"""The extreme-case runner (workflow/engine/studies/extreme/) on the synthetic reduced model."""
from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from workflow.engine.studies import extreme as X


@pytest.fixture(scope="module")
def su():
    return X.setup(X.synthetic_model(4), X.Settings(max_iterations=30, pseudo_steps=150))


def cases(su, *names):
    by = {c.name: c for c in X.build_cases(su)}
    return [by[n] for n in names]


def finite_or_none(r: X.CaseResult):
    for k, v in r.row().items():
        if isinstance(v, float):
            assert math.isfinite(v), (k, v)
    json.dumps(r.row(), allow_nan=False)


def test_synthetic_model_is_valid_and_partially_slips(su):
    su.model.validate()
    assert su.omega_free > su.omega_tied > 0
    r = X.run_case(su, cases(su, "mu-0.5")[0], "hbm", "newton")
    assert r.converged and r.slipping > 0.2 and r.sticking > 0.2 and r.separated == 0.0


@pytest.mark.parametrize("force, method, nit", [(1e-2, "hbm", None), (1e-2, "hdhb", None), (1e-2, "tcm", None)])
def test_penalty_independence_over_six_decades(su, force, method, nit):
    """ε from 1e-3 to 1e+3 × the reference: the same converged solution while the interface sticks.
    (With slip the measured solution moves with ε — see the next test and docs/solver-guide.md.)"""
    base = [replace(c, force_scale=force, nit=nit) for c in X.build_cases(su) if c.group == "penalty"]
    res = X.run_matrix(replace(su, settings=replace(su.settings, methods=(method,), solvers=("newton",))), base)
    assert len(res) == 7
    done = [r for r in res if r.converged]
    for r in res:
        finite_or_none(r)
        assert r.converged or r.diagnosis
    assert len(done) >= 5, [(r.name, r.diagnosis) for r in res]
    for r in done:
        assert r.error is not None and r.error < 1e-6, (r.name, r.error)


def test_hbm_stick_slip_solution_depends_on_penalty_at_finite_nh(su):
    """Measured, not a wish: with HBM (nit > 2Nh+1) the root satisfies the DLFT law on the
    *projected* λ, so X = U − λ_above_Nh/ε: the converged stick–slip solution moves with ε
    by the truncation error (DLFT's ε-independence holds for HDHB/TCM on 2Nh+1 samples, or
    as Nh → ∞). The runner must report it as an error, not hide it."""
    cs = [c for c in X.build_cases(su) if c.name in ("penalty-1e-1", "penalty-1e+0")]
    res = X.run_matrix(replace(su, settings=replace(su.settings, methods=("hbm",), solvers=("newton",))), cs)
    assert all(r.converged for r in res)
    assert res[0].error > 1e-3


def test_gross_slip_solution_depends_on_penalty_even_at_2nh_plus_1(su):
    """Measured: even with nit = 2Nh+1 (λ band-limited) the slipping root moves with ε. At a root
    X = U at every sample and a slipping sample only needs λ_T ∥ (λ_T + ε ΔU_T): for
    ε‖ΔU_T‖ < μ|λ_N| this admits ΔU_T *against* λ_T (reverse slip, negative dissipation), a
    spurious discrete root that vanishes as ε grows. Reported by the runner as an error."""
    cs = [replace(c, force_scale=10.0, nit=7) for c in X.build_cases(su) if c.name in ("penalty-1e+0", "penalty-1e+3")]
    res = X.run_matrix(replace(su, settings=replace(su.settings, methods=("tcm",), solvers=("newton",))), cs)
    assert all(r.converged for r in res)
    assert res[1].error > 1e-2


@pytest.mark.parametrize("method", ["hbm", "hdhb"])
def test_large_friction_and_tiny_excitation_reach_tied_limit(su, method):
    for c in cases(su, "mu-1e4", "force-1e-06"):
        r = X.run_case(su, c, method, "newton")
        assert r.converged and r.sticking == 1.0
        # exact, not to tol = 1e-8: the first guess is the tied limit, accepted at iteration 0
        assert r.iterations == 0 and r.error is not None and r.error < 1e-10


def test_zero_friction_reaches_free_limit(su):
    r = X.run_case(su, cases(su, "mu-0")[0], "hbm", "newton")
    # linear once sliding: Newton's one step solves it to cond(J)·ε ≈ 1.5e5 × 2.2e-16, not to tol = 1e-8
    assert r.converged and r.iterations <= 1 and r.error < 1e-10


def test_contact_open_all_period_equals_linear_response(su):
    for c in cases(su, "lift-off", "gap-open"):
        r = X.run_case(su, c, "tcm", "newton")
        assert r.converged and r.separated == 1.0 and r.error < 1e-8


@pytest.mark.parametrize("solver", X.SOLVERS)
def test_no_preload_reports_separation_or_diagnosis_never_nan(su, solver):
    r = X.run_case(su, cases(su, "no-preload")[0], "hbm", solver)
    finite_or_none(r)
    assert r.separated is not None and r.separated > 0.0        # the contact opens
    if r.converged:
        assert r.diagnosis == ""
    else:
        assert r.diagnosis and "open and close within the period" in r.diagnosis
    if r.x is not None:
        assert np.all(np.isfinite(r.x))


@pytest.mark.parametrize("solver", X.SOLVERS)
def test_diverging_case_reports_failure_with_diagnosis(su, solver):
    r = X.run_case(su, cases(su, "diverge-maxiter")[0], "hbm", solver)
    assert r.converged is False and r.diagnosis
    finite_or_none(r)


def test_explicit_pseudo_time_beyond_stability_limit_diagnosed(su):
    r = X.run_case(su, cases(su, "diverge-explicit")[0], "hbm", "pseudo-time")
    assert not r.converged and "unstable" in r.diagnosis


def test_verify_refuses_a_wrong_claim(su):
    prob = X.problem(su, cases(su, "mu-0.5")[0], "hbm")
    x = prob.x0()                                   # tied guess: not the stick-slip solution
    ok, why, facts = X.verify(prob, x, 1e-8)
    assert not ok and "residual" in why
    ok, why, _ = X.verify(prob, np.full(prob.n, np.nan), 1e-8)
    assert not ok and "non-finite" in why


def test_scaling_reduces_condition_number(su):
    prob = X.problem(su, cases(su, "mu-0.5")[0], "hbm")
    cj, cs = X.conditioning(prob, prob.x0())
    assert cs <= cj


def test_stage_writes_tables_and_summary(su, tmp_path):
    from workflow.scene import resolve
    from workflow.stages import extreme as stage

    scene = resolve({"extreme": {"cases": ["friction", "divergence"], "methods": ["hdhb"],
                                 "solvers": ["newton", "pseudo-time"], "pseudo_steps": 100},
                     "hb": {"max_iterations": 30}})
    X.synthetic_model(3).save(tmp_path / "reduced.npz")

    class Log:
        def info(self, msg):
            pass

        def progress(self, it, total=None, label=""):
            yield from it

    out = tmp_path / "out"
    out.mkdir()
    s = stage.run(scene, {"reduced": tmp_path}, out, Log())
    json.dumps(s, allow_nan=False)
    assert len(s["cases"]) == 6 * 2
    for row in s["cases"]:
        assert set(row) == {"name", "method", "solver", "converged", "iterations", "seconds", "error", "tolerance",
                            "diagnosis"}
        assert row["converged"] or row["diagnosis"]
        off = row["error"] is not None and row["tolerance"] is not None and row["error"] > row["tolerance"]
        assert (not row["converged"]) or row["diagnosis"] == "" or off
    assert s["off_without_diagnosis"] == 0
    assert (out / "extreme.csv").read_text().startswith("name,group,method,solver,converged")
    assert "| mu-1e4 | hdhb | newton | yes |" in (out / "extreme.md").read_text()


def test_stage_missing_reduced_model_is_bundle_error(tmp_path):
    from workflow.errors import BundleError
    from workflow.scene import resolve
    from workflow.stages import extreme as stage

    with pytest.raises(BundleError, match="reduced.npz"):
        stage.run(resolve({}), {"reduced": tmp_path}, tmp_path, None)


# ---------------------------------------------------------------- issue #47 item 5: off the reference, never silently

def test_no_converged_solve_off_its_reference_without_diagnosis(su):
    s = replace(su.settings, groups=("penalty", "friction", "excitation"), methods=("hbm",))
    res = X.run_matrix(replace(su, settings=s))
    for r in res:
        assert (not r.converged) or r.error is None or r.error <= r.tolerance or r.diagnosis, r.row()
    assert X.off_without_diagnosis(res) == 0
    assert X.is_off(next(r for r in res if r.name == "penalty-1e-1" and r.solver == "newton"))  # ε-dependent root


def test_small_mu_under_a_large_normal_load_is_diagnosed_not_near_the_free_limit():
    """FE sector: μ = 1e-4 converged 70 % from the free limit; the distance is O(μ|λ_N|) (linear in μ:
    7e-2 at 1e-5, 7e-3 at 1e-6), not a wrong solution. Same here with a 4000× preload."""
    s4 = X.setup(X.synthetic_model(4, preload=2000.0), X.Settings(max_iterations=30))
    c = next(c for c in X.build_cases(s4) if c.name == "mu-1e-4")
    r = X.run_case(s4, c, "hbm", "newton")
    assert r.converged and r.error > r.tolerance
    assert "not small on this model" in r.diagnosis and "O(μ)" in r.diagnosis
    r6 = X.run_case(s4, replace(c, mu=1e-7), "hbm", "newton")      # the limit itself is right
    assert r6.converged and r6.error < r6.tolerance and r6.diagnosis == ""


def test_verify_ignores_a_solver_reusing_its_x_buffer(su):
    """MINPACK (powell) mutates the x it passed to the residual; HBProblem memoises a view of it, so the
    next residual at that point was wrong (FE mu-1e4 hbm powell: true 8e-17, re-verified 1e-8…2e16)."""
    c = cases(su, "mu-1e4")[0]
    prob = X.problem(su, c, "hbm")
    x = prob.x0()
    buf = x.copy()
    prob.residual(buf)
    buf[:] = 0.0                                     # what a solver may do with its work array
    ok, why, facts = X.verify(prob, x, 1e-8)
    fresh = X.problem(su, c, "hbm")
    fresh.x0()
    assert ok, why
    assert facts["residual"] == pytest.approx(np.linalg.norm(fresh.residual(x)) / fresh.residual_scale(), abs=1e-15)
    r = X.run_case(su, c, "hbm", "powell")
    assert r.converged and r.error < r.tolerance
