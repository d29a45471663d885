"""The solver cascade for one frequency: every stage solves a HB point through here.

:func:`solve_point` tries, in order, until one converges (the cheap and
usual first; each later attempt exists because a measured case needed it):

0. a *collocated* problem (nit = 2Nh+1, :func:`collocated`) goes through this whole
   cascade at the ε-path's first, moderate level; its root is accepted at the law's ε
   by its residual there (:func:`_at_law`), and only if that fails does the cascade
   below run at the law's ε;
1. a guess that already satisfies R = 0 (one residual, no Jacobian);
2. ``newton-powell`` only: Newton from each guess, the smallest residual
   first, *along the ε-path* (``eps_path``: the root at a moderate ε, then
   ε up by decades, each from the last root — :func:`along_eps_path`), then
   (between the structured and the matrix-free sizes) Newton on the dense J,
   then MINPACK's Powell from Newton's best iterate, then (below the matrix-free
   size, where Powell already is the matrix-free pseudo-time) pseudo-transient
   continuation from the best guess (:func:`_ptc`);
3. the solver from each guess in turn, the smallest residual first (``short`` iterations each;
   Newton resumed once where it stopped if it ran out of iterations while converging,
   :data:`RESUME_RATIO`);
4. ``smooth`` (aliased variants): a guess from the same Nh with many time
   samples, whose residual is far smoother;
5. **continuation in ε** from ε·10⁻³ by decades, starting at the stuck
   guess: a large penalty is right (:mod:`workflow.engine.penalty`) but
   makes Newton's basin small; at a small ε the stick/slip pattern is found
   easily and each decade moves the root a little (Den Hartog, Nh = 7:
   158 direct iterations → 16; Nh = 15, ε = 10⁴k: no convergence → 34);
6. **continuation in Nh**: the same point at Nh//2 (recursively, through
   this cascade) seeds the full problem, solved from that seed through this
   cascade again;
7. a homotopy in the excitation from the stuck state (forcing ×0.2…1);
8. Powell from the best iterate;
9. Newton (``newton`` only) from the guess with the smallest residual with the whole
   budget, where attempt 3 gave it only ``short`` iterations (:data:`FULL_BUDGET`).

The result carries ``how`` (which attempt converged) and, when none did,
the reason of the best iterate.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from workflow.engine import penalty
from workflow.engine.errors import SceneError

#: Newton keeps its LU factor (chord steps) while ‖R‖ falls by ≥ 20 % a step,
#: from this many unknowns up. Measured on the sector (16 pairs, 50 points, after
#: the shakedown-Jacobian fix, one core): HBM-17 nit=105 (n = 1680) 30.8 → 10.3 s,
#: nit=35 17.1 → 9.9 s; HBM-7 (n = 720) nit=105 2.4 → 2.1 s, nit=15 1.7 → 1.2 s;
#: HBM-3 (n = 336) 0.55 → 0.46 s; every point converged either way.
CHORD_MIN_UNKNOWNS = 300
CHORD_RATIO = 0.8
#: MINPACK's Powell is costly from this many unknowns up (see :func:`newton_steps`).
POWELL_COSTLY_UNKNOWNS = 1200
#: Newton steps of ``newton-powell`` before Powell takes over. Newton converges
#: only linearly (ratio 0.3–0.7) near resonance — the DLFT residual is not
#: differentiable where a pair touches the Coulomb cone — but a step (one LU)
#: is still cheaper than MINPACK's unblocked QR: 30 instead of 10 measured 28 %
#: less CPU on HBM-7/nit=105 at the 16 points around resonance (12.5 s vs 17.5 s).
NEWTON_STEPS = 30
#: forcing fractions of the homotopy attempt (harmonics ≥ 1 of F_r scaled).
HOMOTOPY = (0.2, 0.4, 0.6, 0.8, 1.0)
#: decades of the ε-continuation (from ε·10^-EPS_DECADES up to ε).
EPS_DECADES = 3
#: The ε-path of :func:`along_eps_path` comes from :func:`workflow.engine.penalty.path`.
#: Measured on the quick sector (HBM-3 nit=64, 15 points, ε = 10³× stiffness):
#: Newton straight at ε from the secant predictor 4.1 s with 15 points lost
#: after the first failure; from the root at ε·10⁻³ by decades 0.53 s, 3
#: failures before the rest of the cascade; by one jump 0.85 s, 2 failures;
#: by half decades 0.47 s, none.
#: Tolerance (relative to ‖F‖) of the ε-path's intermediate levels: their roots only
#: start the next level. Measured on paper-frf's model (HBM-3 nit=105, 50 points):
#: 1e-8 → 1e-3 took the Newton iterations from 4001 to 1328 with the FRF equal to
#: 1e-9 (wall time about the same: the line search's residuals dominate). Also
#: measured and dropped: 3–6 Newton steps straight at the target ε before the
#: path (9.5–11.1 s vs 11.2 s, more iterations).
PATH_TOL = 1e-3
#: Newton steps at the law's ε that polish a collocated root found at a smaller ε
#: (:func:`_at_law`) before the full cascade runs at the law's ε instead.
POLISH_STEPS = 8
SOLVERS = ("newton", "powell", "newton-powell", "pseudo-time")
#: From this many unknowns up, Newton's linear solve is the structured one
#: (:mod:`workflow.engine.linsolve`: matrix-free J, GMRES, pair- and harmonic-block
#: LUs) instead of the LU of the formed (n × n) J; see :func:`linear_solver`.
#: Measured at the automatic penalty on paper-frf's sector (16 pairs, 50 points,
#: one BLAS thread, one run beside two other jobs), dense / structured sweep:
#: HBM-7 nit=105 (n = 720) 4.6 / 11.9 s; HBM-11 nit=105 (n = 1104) 16.5 / 13.7 s;
#: HDHB-11 (n = 1104) 20.7 / 3.9 s; HBM-13 (n = 1296) 11.4 / 6.6 s; HBM-17 nit=35
#: (n = 1680) 22.3 / 8.5 s, nit=105 23.6 / 9.4 s, HDHB-17 27.8 / 7.0 s — the same
#: peaks to 7 digits. (At the earlier 10³× penalty GMRES needed more iterations
#: and the switch sat at 2000.) 2026-11-27 (2a307cc), with the small-interface preconditioner
#: (explicit harmonic-block inverses, pair inverses renewed only where G̃ changed), the
#: same model and four runs each, dense / structured sweep: HBM-4 nit=105 (n = 432)
#: 1.1–1.3 / 1.9 s; HBM-5 nit=105 (n = 528) 3.7–4.0 / 1.3–1.7 s, nit=11 2.4–2.8 / 0.8–1.1 s;
#: HBM-6 nit=13 (n = 624) 2.5–3.0 / 0.8–1.3 s; HBM-7 nit=105 (n = 720) 2.5–2.8 / 2.2 s,
#: nit=15 2.2–2.5 / 1.5 s; the quick sector's HBM-5 nit=64 1.5–2.1 / 1.2 s, HDHB-5 1.9–2.3 /
#: 0.6–0.7 s. Structured Newton needs fewer iterations (no chord steps: 297 → 126 on HBM-5).
STRUCTURED_MIN_UNKNOWNS = 500
#: From this many unknowns up nothing forms the (n × n) J: Powell's place is taken by the
#: matrix-free block pseudo-time, and there is no dense pseudo-transient continuation.
#: Below it the dense fallbacks stay, also behind a structured Newton: on the quick
#: sector's HBM-8 nit=97 (n = 816) the hardest point took 2.6 s by the matrix-free
#: fallbacks (129 iterations, down to the Nh-continuation) and 0.24 s by dense Newton.
MATRIX_FREE_MIN_UNKNOWNS = 1000


def collocated(prob) -> bool:
    """nit = 2Nh+1 (HDHB always; HBM and TCM when so sampled). The DFT between the 2Nh+1
    samples and the harmonics is then a bijection, so at a root the corrected displacement
    X equals U_r at every sample and the DLFT's decisions (eqs. 13–17) see ε only through
    slipping samples, as λ_pre^T = λ^T + ε ΔU_T. Hence every root at the law's ε is a root
    at any smaller ε, and a root at a smaller ε is the law's root exactly when its residual
    at the law's ε vanishes (the discrete roots that slip against λ^T, ε‖ΔU_T‖ < μ|λ_N|, fail
    that test; docs/solver-guide.md, "Penalty ε"). Such a problem is therefore solved at the
    ε-path's first, moderate level, where Newton's basin is large, and the root is checked
    (and if need be polished) at the law's ε (:func:`_at_law`)."""
    return prob.nit == 2 * prob.nh + 1


def linear_solver(n: int) -> str:
    """Newton's linear solve for n unknowns: "dense" or "structured" (automatic)."""
    return "structured" if n >= STRUCTURED_MIN_UNKNOWNS else "dense"


def matrix_free(n: int) -> bool:
    """True if the fallbacks of a problem of n unknowns must not form the (n × n) J
    (:data:`MATRIX_FREE_MIN_UNKNOWNS`; never below the structured Newton's own size)."""
    return n >= max(MATRIX_FREE_MIN_UNKNOWNS, STRUCTURED_MIN_UNKNOWNS)


def _linsolver(prob):
    """The problem's :class:`~workflow.engine.linsolve.StructuredSolve`, created on first
    use and shared by the solves of one frequency (its blocks are lagged)."""
    from workflow.engine.linsolve import StructuredSolve

    if getattr(prob, "linsolver", None) is None:
        prob.linsolver = StructuredSolve()
    return prob.linsolver


@dataclass
class PointResult:
    """One frequency solved: ``result`` (the best :class:`SolveResult`), total
    ``iterations`` over every attempt, and ``how`` — "guess0", "guess1", …,
    "resumed", "newton", "newton-dense", "powell", "pseudo-time", "smooth", "eps-continuation",
    "nh-continuation", "homotopy", "full-budget" or "failed"."""

    result: object
    iterations: int
    how: str

    @property
    def converged(self) -> bool:
        return bool(self.result.converged)


def newton_steps(prob, maxiter: int) -> int:
    """Newton steps before Powell takes over in ``newton-powell``.

    MINPACK's hybrid Powell factors its n×n Jacobian with an unblocked QR:
    ~10 s a call at n = 1680 (Nh = 17, 16 pairs; profiled: two such calls
    were 21 of the variant's 25 s), while a chord step there costs ~0.02 s.
    Large problems therefore get three times the Newton budget first.
    """
    return min(maxiter, NEWTON_STEPS * (3 if prob.n >= POWELL_COSTLY_UNKNOWNS else 1))


def run_solver(prob, x0, solver: str, tol: float, maxiter: int, pseudo: dict | None = None,
               linear: str | None = None):
    """One solver from ``x0``: a :class:`~workflow.engine.solvers.SolveResult`.

    ``pseudo``: keyword arguments of :func:`workflow.engine.pseudotime.integrate`
    for ``solver = "pseudo-time"`` (the scene's ``[pseudotime]``); default
    SER with the Jacobian mass — pseudo-transient continuation, a damped
    Newton — while ``precond = "none"`` is eq. 18 as printed. From
    :data:`STRUCTURED_MIN_UNKNOWNS` up, Newton's linear solve is the structured
    one; from :data:`MATRIX_FREE_MIN_UNKNOWNS` up Powell and pseudo-time are the
    matrix-free pair/harmonic block-Jacobi of :mod:`workflow.engine.pseudotime_blocks`
    (``pseudo`` is then not used). ``linear``: Newton's linear solve, "dense" or
    "structured" (default :func:`linear_solver`)."""
    if solver == "newton" and (linear or linear_solver(prob.n)) == "structured":
        # no chord steps: J costs no factorisation here, the blocks are lagged instead
        return prob.solve(x0, solver="newton", tol=tol, maxiter=maxiter, max_backtracks=10,
                          linear="structured", linsolver=_linsolver(prob))
    if solver == "newton":
        return prob.solve(x0, solver="newton", tol=tol, maxiter=maxiter, max_backtracks=10,
                          reuse_ratio=CHORD_RATIO if prob.n >= CHORD_MIN_UNKNOWNS else 0.0)
    if solver == "powell" and matrix_free(prob.n):
        # MINPACK's Powell needs the dense J and factors it by an unblocked QR: at
        # 64 pairs, Nh = 7 (n = 2880) one call ran for minutes — and the structured
        # size promises no (n × n) array. The matrix-free pseudo-time takes its
        # place as the last resort (the paper's method for large systems).
        from workflow.engine.pseudotime_blocks import integrate_pairs

        return integrate_pairs(prob.residual, prob.residual_operator, x0, tol=tol, scale=prob.residual_scale(),
                               max_steps=max(maxiter, 200), blocks="pairs+harmonics")
    if solver == "powell":
        return prob.solve(x0, solver="powell", tol=tol, maxiter=maxiter, maxfev=4 * maxiter)
    if solver == "pseudo-time" and matrix_free(prob.n):
        # the dense schemes would form the (n × n) J: the matrix-free block-Jacobi instead
        from workflow.engine.pseudotime_blocks import integrate_pairs

        return integrate_pairs(prob.residual, prob.residual_operator, x0, tol=tol, scale=prob.residual_scale(),
                               max_steps=max(maxiter, 200), blocks="pairs+harmonics")
    if solver == "pseudo-time":
        from workflow.engine.pseudotime import integrate

        kw = {"scheme": "ser", "precond": "jacobian", "max_steps": max(maxiter, 200), **(pseudo or {})}
        if kw["scheme"] == "block-jacobi":
            kw.setdefault("blocks", prob.nc)        # one block per harmonic (HDHB: per instant)
        return integrate(prob.residual, prob.residual_jacobian, x0, tol=tol, scale=prob.residual_scale(), **kw)
    raise SceneError(f"hb.solver: {solver!r} is not one of {', '.join(SOLVERS)}")


def along_eps_path(prob, x0, eps_path, tol: float, maxiter: int, run=None, solver: str = "newton",
                   linear: str | None = None):
    """``solver`` (Newton by default; ``run`` the cascade's runner, for its
    pseudo-time options) from ``x0`` along ``eps_path`` (factors < 1 of the
    law's ε, rising), then at the law's own ε: the large penalty's root from
    a moderate one's. A step that fails is skipped (the next starts from the
    last root); the result is the final solve's, at the law's ε. ``linear``:
    see :func:`run_solver` (without ``run``)."""
    run = run or (lambda q, x, s, m: run_solver(q, x, s, tol, m, linear=linear))
    its = 0
    x = x0
    for f in eps_path:
        # the intermediate roots only start the next level: a loose tolerance will do;
        # the structured linear solver (large interfaces) is carried from level to level
        q = _with_penalty(prob, f)
        q.linsolver = getattr(prob, "linsolver", None)
        res = run_solver(q, x, solver, PATH_TOL, maxiter, getattr(run, "pseudo", None), linear=linear)
        prob.linsolver = getattr(q, "linsolver", None)
        its += int(res.iterations)
        if res.converged:
            x = res.x
    res = run(prob, x, solver, maxiter)
    return replace(res, iterations=its + int(res.iterations))


def _ptc(prob, x0, eps_path, tol: float, maxiter: int):
    """Attempt 2b: pseudo-transient continuation (SER steps, Jacobian mass: a damped Newton
    whose step control is the residual's, not a line search) from the best guess, along the
    ε-path. Newton and Powell both stop at a kink of the DLFT residual where a pair touches
    the Coulomb cone; from the *guess* (not their stuck iterate, where the first step is
    refused) PTC walks round it. Measured on paper-frf's collocated HBM-1 (nit = 3) at the
    peak, 192.57 Hz: Newton and Powell stalled at ‖R‖/‖F‖ = 1.2e-3 and the rest of the
    cascade failed after 502 iterations (1.9 s); PTC converged in 50–110 steps (0.1–0.2 s)
    from the stuck start and from the nit = 105 root, both to the same root."""
    return along_eps_path(prob, x0, eps_path, tol, maxiter, lambda q, x, s, m: run_solver(q, x, s, tol, m),
                          "pseudo-time")


class _Best:
    """The best iterate over the attempts, and the iterations they cost."""

    def __init__(self):
        self.res, self.total = None, 0

    def keep(self, res, count: bool = True):
        if count:
            self.total += int(res.iterations)
        if self.res is None or res.converged or not (res.residual_norm >= self.res.residual_norm):
            self.res = res
        return bool(res.converged)


#: A Newton attempt from a guess that ran out of iterations is resumed once from where it stopped
#: (attempt 3) when it had cut ‖R‖ to this fraction of the best guess's: it was converging, and the
#: attempts after it start again from far. Measured on the 512-pair sector at the library's
#: default budget (50, so 15 a guess; HBM-7 nit=64, 9 points): at the resonance both guesses
#: (‖R‖ = 10^7.6 × the tolerance) ended at 10^3.5 and 10^1.4 × after 15 steps, and the
#: smooth guess, the ε-continuation and its re-solve took 50 more (80 in all, 45 s).
RESUME_RATIO = 1e-3


#: Attempt 9 of the module docstring. Some starts need one long Newton run that no shorter
#: attempt replaces: on the 6-pair test model from its linear solution at 24 Hz (HBM, nit = 64)
#: Newton creeps for 30 steps before its pattern of stick and slip settles and converges at
#: step 40, while attempts 3–8 (25 steps each at a budget of 100) all failed after 352
#: iterations. It runs only where every other attempt failed.
FULL_BUDGET = True


def _resumable(res, norms: dict) -> bool:
    """Whether attempt 3 resumes ``res`` (a guess's result): it stopped at its iteration budget,
    not on a kink or a failed search, well below the guesses' ‖R‖."""
    return res is not None and not res.converged and res.reason == "max iterations" and bool(norms) \
        and res.residual_norm <= RESUME_RATIO * min(norms.values())


def _satisfied(prob, guesses, tol):
    """(a converged result for a guess with R = 0 already or None, {index: ‖R‖})."""
    from workflow.engine.solvers import SolveResult, within_tolerance

    norms = {}
    for k, x0 in enumerate(guesses):
        if x0 is None:
            continue
        norms[k] = float(np.linalg.norm(prob.residual(x0)))
        if within_tolerance(norms[k], tol, prob.residual_scale()):
            return SolveResult(x=np.asarray(x0, float), converged=True, iterations=0, residual_norm=norms[k],
                               reason="converged", function_evaluations=1), k, norms
    return None, None, norms


def _chain(problems, run, solver: str, maxiter: int, best: _Best, x=None) -> bool:
    """Solve each problem of ``problems`` from the previous root (the first from
    ``x``, or its own stuck guess); stop at the first failure. The last problem is
    the one wanted: its root is kept."""
    res = None
    for q in problems:
        res = run(q, q.x0() if x is None else x, solver, maxiter)
        best.total += int(res.iterations)
        if not res.converged:
            return False
        x = res.x
    return best.keep(res, count=False)


def _with_penalty(prob, factor: float):
    q = prob.with_linear(prob.Zr, prob.Fr)
    if factor != 1.0:
        q.set_contact(penalty.scaled(prob.law, factor))
    return q


def eps_continuation(prob, run, solver: str, tol: float, maxiter: int, best: _Best, x=None) -> bool:
    """Attempt 5: from ``x`` (default: the stuck guess) at ε·10⁻³, up by decades to ε."""
    return _chain([_with_penalty(prob, 10.0 ** -d) for d in range(EPS_DECADES, -1, -1)], run, solver, maxiter,
                  best, x)


def nh_continuation(prob, run, solver: str, tol: float, maxiter: int, best: _Best) -> bool:
    """Attempt 6: the point at Nh//2 (HBM, through the whole cascade) seeds Nh: Newton and
    the ε-continuation from that seed, and if both fail the whole cascade again from it (all
    but this attempt; its best iterate is kept only if it converges, so that attempt 8 still
    starts from the best of the attempts before — a TCM test point converged there by Powell
    and was lost when the nested cascade's stuck iterate replaced it).

    Why the whole cascade at Nh: in the stop regime the seeded Newton alone is not enough.
    Measured on the Coulomb oscillator (μN/F0 = 0.7, ζ = 0, β = 0.5, the mass sticking twice
    a period, ε = 10³k, Nh = 7, nit = 64): Newton and the ε-continuation from the Nh = 3
    seed failed, and Nh = 3 itself failed from its Nh = 1 seed, so the point was lost;
    with the cascade at each level, Nh = 3 converges by the forcing homotopy and Nh = 7 by
    pseudo-transient continuation (each seed is then a point the cascade's own attempts reach)."""
    from workflow.engine.hb import HBProblem

    nh_low = prob.nh // 2
    if nh_low < 1:
        return False
    low = HBProblem(prob.Zr, prob.Fr, prob.law, nh_low, prob.nit, "hbm", max_passes=prob.max_passes,
                    stick_anchor=prob.stick_anchor, static=prob.static, **prob.linear_form())
    pr = solve_point(low, [low.x0()], solver=run.solver, tol=tol, maxiter=run.maxiter, eps_path=run.eps_path,
                     pseudo=run.pseudo)
    best.total += pr.iterations
    if not pr.converged:
        return False
    x = prob.unknowns_from_harmonics(low.harmonics(pr.result.x))
    if best.keep(run(prob, x, solver, maxiter)) or eps_continuation(prob, run, solver, tol, maxiter, best, x=x):
        return True
    seeded = _cascade(prob, [x], run.solver, tol, run.maxiter, None, run.eps_path, run.pseudo, with_nh=False)
    best.total += seeded.iterations
    # a failed nested cascade leaves the best iterate alone: attempt 8 starts from it
    return seeded.converged and best.keep(seeded.result, count=False)


def homotopy(prob, run, solver: str, tol: float, maxiter: int, best: _Best) -> bool:
    """Attempt 7: the dynamic forcing scaled by :data:`HOMOTOPY` from the stuck state."""
    def scaled_forcing(frac):
        F = prob.Fr.copy()
        F[1:] *= frac
        return prob.with_linear(prob.Zr, F) if frac < 1.0 else prob

    return _chain([scaled_forcing(f) for f in HOMOTOPY], run, solver, maxiter, best)


def _once(fn):
    """``fn`` (a ``smooth`` guess callable, or None) computed at most once: later calls
    return its guess again at no iteration cost."""
    if fn is None:
        return None
    memo = []

    def once():
        if not memo:
            memo.append(fn())
            return memo[0]
        return memo[0][0], 0
    return once


def _at_law(prob, pr: PointResult, tol: float) -> PointResult:
    """A collocated problem's root at a smaller ε (:func:`collocated`) as the root at the
    law's own ε: accepted by its residual there, else polished by Newton from it."""
    if not pr.converged:
        return pr
    from workflow.engine.solvers import SolveResult, within_tolerance

    norm = float(np.linalg.norm(prob.residual(pr.result.x)))
    if within_tolerance(norm, tol, prob.residual_scale()):
        return replace(pr, result=replace(pr.result, residual_norm=norm))
    res = run_solver(prob, pr.result.x, "newton", tol, POLISH_STEPS)
    if not res.converged:
        res = SolveResult(x=pr.result.x, converged=False, iterations=res.iterations, residual_norm=norm,
                          reason=f"the root at the moderate ε leaves ‖R‖/‖F‖ = "
                                 f"{norm / prob.residual_scale():.1e} at the law's ε")
    return PointResult(res, pr.iterations + int(res.iterations), pr.how)


def solve_point(prob, guesses, *, solver: str, tol: float, maxiter: int, smooth=None,
                eps_path=(), pseudo: dict | None = None) -> PointResult:
    """Solve one frequency of ``prob`` (:class:`~workflow.engine.hb.HBProblem`) from
    ``guesses`` (unknown vectors; None entries skipped) through the cascade
    of the module docstring. ``tol`` is relative to ‖F‖. ``smooth``
    (optional) is a callable returning ``(x or None, iterations)``.
    ``eps_path``: see :func:`along_eps_path` (empty or None: Newton at the law's ε);
    ``pseudo``: see :func:`run_solver`."""
    if solver not in SOLVERS:
        raise SceneError(f"hb.solver: {solver!r} is not one of {', '.join(SOLVERS)}")
    eps_path = tuple(eps_path or ())
    if collocated(prob) and len(eps_path):
        # measured on the hb-stage tests' blade (Nh = 5, nit = 11, 41 points through the
        # resonance): along the ε-path 21/41 (HBM), 17/41 (HDHB, TCM) points converged in
        # 5–7 s; the whole cascade at the path's first level, 41/41 in 0.6 s, the three
        # forms equal to 1e-9 and every root a root at the law's ε to 1e-13
        # (on the same blade with milder slip, Nh = 2, the first level lost 3 of 7 points
        # that the path finds: it is the fallback)
        low = _with_penalty(prob, eps_path[0])
        smooth = _once(smooth)      # its guess does not depend on the ε it seeds: made once for both
        pr = _at_law(prob, _cascade(low, guesses, solver, tol, maxiter, smooth, (), pseudo), tol)
        if pr.converged:
            return pr
        rest = _cascade(prob, guesses, solver, tol, maxiter, smooth, eps_path, pseudo)
        return replace(rest, iterations=rest.iterations + pr.iterations)
    return _cascade(prob, guesses, solver, tol, maxiter, smooth, eps_path, pseudo)


def _cascade(prob, guesses, solver: str, tol: float, maxiter: int, smooth, eps_path, pseudo,
             with_nh: bool = True) -> PointResult:
    """Attempts 1–8 of the module docstring (:func:`solve_point` has the arguments;
    ``with_nh`` False leaves attempt 6 out, for the seeded solve it makes itself)."""
    done, k, norms = _satisfied(prob, guesses, tol)
    if done is not None:
        return PointResult(done, 0, f"guess{k}")
    def run(q, x, how: str, iterations: int):
        return run_solver(q, x, how, tol, iterations, pseudo)

    # what attempt 6 needs to run the whole cascade again
    run.pseudo, run.solver, run.maxiter, run.eps_path = pseudo, solver, maxiter, eps_path
    best = _Best()
    short = min(maxiter, max(15, maxiter // 4))
    inner = "newton" if solver == "newton-powell" else solver
    if solver == "newton-powell":
        for k in sorted(norms, key=norms.get):
            if best.keep(along_eps_path(prob, guesses[k], eps_path, tol, newton_steps(prob, maxiter))):
                return PointResult(best.res, best.total, "newton")
        if norms and linear_solver(prob.n) == "structured" and not matrix_free(prob.n):
            # J is still cheap to form: Newton on it (exact Levenberg–Marquardt fallback, chord
            # steps) takes another path round the kink that stopped the structured one —
            # on the quick sector's HBM-8 nit=97 hardest point 19 iterations, where MINPACK
            # and the fallbacks after it took 5.5 s
            k = min(norms, key=norms.get)
            if best.keep(along_eps_path(prob, guesses[k], eps_path, tol, newton_steps(prob, maxiter),
                                        linear="dense")):
                return PointResult(best.res, best.total, "newton-dense")
        if best.res is not None and best.keep(run(prob, best.res.x, "powell", maxiter)):
            return PointResult(best.res, best.total, "powell")
        if norms and not matrix_free(prob.n) and best.keep(_ptc(prob, guesses[min(norms, key=norms.get)],
                                                                        eps_path, tol, maxiter)):
            return PointResult(best.res, best.total, "pseudo-time")
        solver = "powell"
    for k in sorted(norms, key=norms.get):
        x0 = guesses[k]
        res = along_eps_path(prob, x0, eps_path, tol, short, run, solver) if solver != "powell" else \
            run(prob, x0, solver, short)
        if best.keep(res):
            return PointResult(best.res, best.total, f"guess{k}")
        if solver == "newton" and _resumable(res, norms) and best.keep(run(prob, res.x, solver, short)):
            return PointResult(best.res, best.total, "resumed")
    if smooth is not None:
        xs, its = smooth()
        best.total += its
        if xs is not None and best.keep(run(prob, xs, solver, short)):
            return PointResult(best.res, best.total, "smooth")
    attempts = (("eps-continuation", eps_continuation),
                *((("nh-continuation", nh_continuation),) if with_nh else ()),
                ("homotopy", homotopy))
    for how, attempt in attempts:
        if attempt(prob, run, inner, tol, short, best):
            return PointResult(best.res, best.total, how)
    if inner == "newton" and best.keep(run(prob, best.res.x, "powell", maxiter)):
        return PointResult(best.res, best.total, "powell")
    if FULL_BUDGET and solver == "newton" and short < maxiter and norms:
        x0 = guesses[min(norms, key=norms.get)]
        if best.keep(along_eps_path(prob, x0, eps_path, tol, maxiter, run, solver)):
            return PointResult(best.res, best.total, "full-budget")
    return PointResult(best.res, best.total, "failed")
