"""Harmonic-balance stage: friction-damped frequency responses (paper §5.1, Figs. 4–8, Table 1).

Reads the reduced model (``<reduced>/reduced.npz``), rewrites it once in
relative coordinates (:func:`reduction.condense.relative_coordinates`) and
sweeps a frequency band for every *variant* — formulation (HBM / TCM /
HDHB, :mod:`workflow.hb`) × number of harmonics Nh × time samples nit —
with the solver of ``hb.solver``. Optionally a converged *reference*
(HBM, ``hb.reference_harmonics``, ``hb.reference_time_samples``) measures
every variant's error against its run time.

Choices made here (and why):

* **Band.** Default ±10 % around the first tied *bending* frequency: the
  eigenfrequencies of the reduced model with ``u_r = 0`` (the interface tied),
  and the first mode whose modal response at the observed DOFs to the
  harmonic load is at least ``SIGNIFICANT`` of the largest one (so a mode the
  tip force barely excites, e.g. an axial or torsion mode, is skipped).
* **Condensation once.** ``Zr``, ``Fr`` are computed once per frequency for
  the largest Nh of the run (reference included) and sliced for each variant:
  ``condense`` is harmonic-by-harmonic, so a slice equals a fresh condensation
  at lower Nh. Its wall time is reported separately (``condense_seconds``),
  not charged to the variants.
* **Static state.** Harmonic 0 does not depend on ω: the static (preload)
  contact state is solved once (:meth:`workflow.hb.HBProblem.static_state`)
  and its tangential stick anchor is carried into every dynamic solve, which
  fixes the otherwise non-unique static offset of pairs that stick all period
  (DESIGN §3, "stuck zeroth harmonic"). Assumption: the interface was
  assembled stress-free and tied, and the preload is applied in one step.
  A static problem with no equilibrium (no preload: the blade only touches
  the disk at the flanks) is a :class:`SolverError` that says so.
* **Sweep.** Sequential in frequency with a secant predictor from the two
  previous converged points; fall-backs, in order: the previous point, the
  problem's own initial guess (static + tied linear response), then Powell.
  With ``sweep.method = "arclength"`` each variant is traced instead by
  pseudo-arclength continuation (:func:`trace_variant`), which follows
  turning points; the error table then interpolates between the curves'
  own points (measured on the sector: fine for nit = 105; the aliased
  variants fold at the DLFT kinks and exhaust ``sweep.max_steps``).
* **Observed amplitude.** ``amplitude_m`` is the Euclidean norm over the
  observed DOFs of the first-harmonic complex amplitude (= |U₁| for a single
  observed DOF); ``amplitude_max_m`` the largest norm over the period of the
  dynamic part (harmonics ≥ 1).
* **Reference.** Swept after the variants, each frequency seeded by the
  converged variant of highest Nh (Newton then needs 1–2 Jacobians).
* **MPI.** Under ``mpirun -n N`` the variants are shared over the ranks
  (:func:`share`, largest first) and the reference's band is cut into N
  contiguous chunks; every rank sweeps on one core, rank 0 gathers and
  writes. Serial runs are the one-rank case of the same code.
* **Error.** ``max_f |A(f) − A_ref(f)| / max_f A_ref(f)`` over the points
  where both converged: relative to the reference peak, so that small
  absolute errors far from resonance do not dominate.
* **ε_N, ε_T = 0 (automatic).** The mean diagonal of ``Re Zr`` at harmonic
  1, at the band centre, over the normal / tangential relative DOFs (the
  converged solution does not depend on ε, only the iteration does).
"""
from __future__ import annotations

import csv
import io
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

NAME = "hb"
SECTIONS = ("contact", "hb", "sweep", "excitation")
NEEDS = ("reduced",)
VIA_BUNDLE = ("excitation",)  # in the reduced load: a user bundle replaces it (#18)
PRODUCES = ("frf",)
#: collective under mpirun: the variants, then the reference's frequencies, are
#: spread over the ranks (each rank sweeps its share on one core); rank 0 gathers
#: the sweeps and writes every output
MPI = True

#: a tied mode is "excited" if its modal response at the observed DOFs is at
#: least this fraction of the largest one.
SIGNIFICANT = 0.05
#: samples per period for the max-over-period amplitude and the Fig. 8 curves.
PERIOD_SAMPLES = 128

FRF_COLUMNS = ("method", "Nh", "nit", "solver", "frequency_hz", "amplitude_m", "iterations", "seconds",
               "converged", "amplitude_max_m", "role")


# ---------------------------------------------------------------- variants
@dataclass(frozen=True)
class Variant:
    """One HB formulation to sweep: method, Nh, nit (already resolved, ≥ 2Nh+1)."""

    method: str
    nh: int
    nit: int

    @property
    def collocated(self) -> bool:
        """nit = 2Nh+1 (the HDHB grid)."""
        return self.nit == 2 * self.nh + 1

    @property
    def nit_label(self) -> str:
        return "2Nh+1" if self.collocated else str(self.nit)

    @property
    def label(self) -> str:
        return f"{self.method.upper()}-{self.nh} nit={self.nit}"


def variants(hb) -> list[Variant]:
    """method ∈ hb.methods × Nh ∈ hb.harmonics × nit ∈ hb.time_samples (0 → 2Nh+1).

    HDHB runs only with nit = 2Nh+1 (other nit values are skipped for it);
    duplicates (e.g. nit = 0 and nit = 2Nh+1 both listed) are dropped. Order:
    as listed in the scene (method-major).
    """
    out: list[Variant] = []
    for method in hb.methods:
        for nh in hb.harmonics:
            for nit in hb.time_samples:
                n = 2 * int(nh) + 1 if int(nit) == 0 else int(nit)
                if n < 2 * int(nh) + 1:
                    from workflow.errors import SceneError

                    raise SceneError(f"hb.time_samples = {nit} < 2·Nh+1 = {2 * int(nh) + 1} for hb.harmonics = {nh}")
                if method == "hdhb" and n != 2 * int(nh) + 1:
                    continue
                v = Variant(method, int(nh), n)
                if v not in out:
                    out.append(v)
    return out


# ---------------------------------------------------------- linear helpers
def tied_modes(rc) -> tuple[np.ndarray, np.ndarray]:
    """Eigenfrequencies (Hz) of the model with the interface tied (u_r = 0), and
    each mode's modal response at the observed DOFs to the harmonic load,
    ``‖O φ‖ |φᵀ f| / ω²`` (m), normalised so the largest is 1."""
    import scipy.linalg as sla

    r = rc.n_rel
    K, M = rc.K[r:, r:], rc.M[r:, r:]
    w2, phi = sla.eigh(K, M)
    w2 = np.maximum(w2, 0.0)
    f = np.sqrt(w2) / (2 * np.pi)
    obs = np.linalg.norm(rc.O[:, r:] @ phi, axis=0)
    force = np.abs(phi.T @ rc.f_harmonic[r:])
    with np.errstate(divide="ignore", invalid="ignore"):
        resp = np.where(w2 > 0, obs * force / np.where(w2 > 0, w2, 1.0), 0.0)
    top = resp.max() if resp.size and resp.max() > 0 else 1.0
    return f, resp / top


def first_excited_mode(rc) -> tuple[float, int]:
    """(frequency in Hz, index) of the first tied mode significantly excited and observed."""
    from workflow.errors import BundleError

    f, s = tied_modes(rc)
    idx = np.flatnonzero((s >= SIGNIFICANT) & (f > 0))
    if not idx.size:
        raise BundleError("reduced model: no tied mode responds at the observed DOFs to the harmonic load "
                          "(f_harmonic or O is zero?)")
    return float(f[idx[0]]), int(idx[0])


def band(sweep, f_mode: float) -> tuple[float, float]:
    """(f_start, f_stop) in Hz from the sweep section (0 → ∓10 % of f_mode)."""
    from workflow.errors import SceneError

    f0 = sweep.f_start_hz or 0.9 * f_mode
    f1 = sweep.f_stop_hz or 1.1 * f_mode
    if f1 <= f0:
        raise SceneError(f"sweep: band [{f0:g}, {f1:g}] Hz is empty (sweep.f_start_hz / sweep.f_stop_hz; "
                         f"first tied bending frequency {f_mode:g} Hz)")
    return float(f0), float(f1)


def auto_penalty(Zr1: np.ndarray) -> tuple[float, float]:
    """(ε_N, ε_T) N/m: mean diagonal of Re Zr over normal / tangential relative DOFs."""
    d = np.abs(np.real(np.diagonal(Zr1)))
    eps_n = float(np.mean(d[0::3]))
    eps_t = float(np.mean(np.concatenate([d[1::3], d[2::3]])))
    return max(eps_n, 1e-300), max(eps_t, 1e-300)


def contact_law(contact, model, Zr1):
    """The :class:`~workflow.contact.ContactLaw` of the scene's contact section on ``model``."""
    from workflow.contact import ContactLaw

    en, et = auto_penalty(Zr1)
    p = model.n_pairs
    return ContactLaw(mu=model.friction(contact.mu)[0], eps_n=contact.eps_n or en, eps_t=contact.eps_t or et,
                      gap=np.asarray(model.gap, dtype=float) + float(contact.gap))


def linear_frfs(rc, cond: list, static) -> tuple[np.ndarray, np.ndarray]:
    """First-harmonic observed amplitude (m) with the interface tied and sliding.

    Tied: u_r = 0. Sliding (μ = 0): pairs in contact in the static state keep
    u_N = 0, tangential DOFs are free (λ_T = 0); separated pairs are free.
    The friction-damped peak lies between the two resonances.
    """
    from reduction.condense import recover

    r = rc.n_rel
    free_n = np.repeat(static.state == 0, 3)
    fixed = np.zeros(r, bool)
    fixed[0::3] = ~free_n[0::3]
    free = ~fixed
    tied, slide = [], []
    for c in cond:
        z = np.zeros((2, r), complex)
        tied.append(np.linalg.norm(recover(rc, c.omega, z)[1]))
        z[1, free] = np.linalg.solve(c.Zr[1][np.ix_(free, free)], c.Fr[1, free])
        slide.append(np.linalg.norm(recover(rc, c.omega, z)[1]))
    return np.array(tied), np.array(slide)


# ------------------------------------------------------------------ sweep
@dataclass
class SweepResult:
    """One variant swept over the band (arrays over frequencies)."""

    variant: Variant
    solver: str
    freqs_hz: np.ndarray
    amplitude: np.ndarray
    amplitude_max: np.ndarray
    iterations: np.ndarray
    seconds: np.ndarray
    converged: np.ndarray
    Ur: list = field(default_factory=list)       # (Nh+1, 3p) complex per frequency
    reasons: list = field(default_factory=list)
    how: list = field(default_factory=list)      # which attempt converged, per frequency
    total_seconds: float = 0.0
    cpu_seconds: float = 0.0                     # process CPU time (all threads)
    error: float | None = None
    dlft_max_passes: int = 0

    @property
    def converged_points(self) -> int:
        return int(np.count_nonzero(self.converged))

    def peak_hz(self) -> float:
        a = np.where(self.converged, self.amplitude, -np.inf)
        return float(self.freqs_hz[int(np.argmax(a))]) if np.isfinite(a).any() else float("nan")


def _observed(rc, omega, Ur) -> tuple[float, float]:
    """(first-harmonic amplitude, max over the period) at the observed DOFs (m)."""
    from reduction.condense import recover
    from workflow import fourier

    obs = recover(rc, omega, Ur)
    a1 = float(np.linalg.norm(obs[1])) if obs.shape[0] > 1 else 0.0
    dyn = obs.copy()
    dyn[0] = 0.0
    t = fourier.to_time(dyn, max(PERIOD_SAMPLES, 4 * (obs.shape[0] - 1) + 4))
    return a1, float(np.max(np.linalg.norm(np.atleast_2d(t.reshape(t.shape[0], -1)), axis=1)))


#: Newton keeps its LU factor (chord steps) while ‖R‖ falls by ≥ 20 % a step,
#: from this many unknowns up. Measured on the sector (16 pairs, 50 points, after
#: the shakedown-Jacobian fix, one core): HBM-17 nit=105 (n = 1680) 30.8 → 10.3 s,
#: nit=35 17.1 → 9.9 s; HBM-7 (n = 720) nit=105 2.4 → 2.1 s, nit=15 1.7 → 1.2 s;
#: HBM-3 (n = 336) 0.55 → 0.46 s; every point converged either way.
CHORD_MIN_UNKNOWNS = 300
#: MINPACK's Powell is costly from this many unknowns up (see :func:`_newton_steps`).
POWELL_COSTLY_UNKNOWNS = 1200
CHORD_RATIO = 0.8


def _newton_steps(prob, maxiter: int) -> int:
    """Newton steps before Powell takes over in ``newton-powell``.

    MINPACK's hybrid Powell factors its n×n Jacobian with an unblocked QR:
    ~10 s a call at n = 1680 (Nh = 17, 16 pairs; profiled: two such calls
    were 21 of the variant's 25 s), while a chord step there costs ~0.02 s.
    Large problems therefore get three times the Newton budget first.
    """
    return min(maxiter, NEWTON_STEPS * (3 if prob.n >= POWELL_COSTLY_UNKNOWNS else 1))


def _run_solver(prob, x0, s: str, tol: float, maxiter: int):
    from workflow.errors import SceneError

    if s == "newton":
        return prob.solve(x0, solver="newton", tol=tol, maxiter=maxiter, max_backtracks=10,
                          reuse_ratio=CHORD_RATIO if prob.n >= CHORD_MIN_UNKNOWNS else 0.0)
    if s == "powell":
        return prob.solve(x0, solver="powell", tol=tol, maxiter=maxiter, maxfev=4 * maxiter)
    if s == "pseudo-time":
        from workflow.pseudotime import integrate

        return integrate(prob.residual, prob.residual_jacobian, x0, "ser", precond="jacobian", tol=tol,
                         scale=prob.residual_scale(), max_steps=max(maxiter, 200))
    raise SceneError(f"hb.solver: {s!r} is not one of newton, powell, newton-powell, pseudo-time")


#: Newton steps of the ``newton-powell`` cascade before Powell takes over. Newton
#: converges only linearly (ratio 0.3–0.7) near resonance — the DLFT residual is
#: not differentiable where a pair touches the Coulomb cone — but a step (one LU)
#: is still cheaper than MINPACK's unblocked QR: 30 instead of 10 measured 28 %
#: less CPU on HBM-7/nit=105 at the 16 points around resonance (12.5 s vs 17.5 s).
NEWTON_STEPS = 30

#: forcing fractions of the homotopy fall-back (harmonics ≥ 1 of F_r scaled).
HOMOTOPY = (0.2, 0.4, 0.6, 0.8, 1.0)


def _solve_point(prob, guesses, solver: str, tol: float, maxiter: int, smooth=None):
    """Solve one frequency; returns (best SolveResult, total iterations, how).

    1. ``solver`` from each of ``guesses`` in turn (predictor, previous point),
       at most ``short = min(maxiter, max(15, maxiter // 4))`` iterations each
       (a Newton run on these problems converges within ~15 iterations or
       not at all: it stalls at a kink of the friction residual);
    2. a homotopy in the excitation from the stuck state: the dynamic forcing
       (harmonics ≥ 1 of F_r) scaled by :data:`HOMOTOPY`, each step warm-started
       from the last (near a resonance the tied linear guess is far off and
       Newton stalls in a local minimum of ‖R‖; the homotopy walks from the
       trivially stuck solution along the slip onset), ``short`` iterations
       per step;
    3. Powell (``4·maxiter`` residual evaluations) from the best iterate if
       ``solver`` was Newton.

    With ``solver = "newton-powell"`` step 1 is replaced by at most
    :data:`NEWTON_STEPS` Newton steps from each guess in turn, the one with
    the smallest residual first, then Powell from Newton's best iterate;
    1–3 follow with Powell if both fail.

    ``smooth`` (optional, tried between 1 and 2): a callable returning
    ``(x, iterations)`` — a guess from the same Nh solved with many time
    samples (HBM), whose residual is far smoother than an aliased one
    (nit = 2Nh+1): the DLFT residual is piecewise linear, so Newton from a
    point with the right stick/slip pattern converges in one step, and the
    smooth solution usually has it. ``how``: "guess0", "guess1", …, "smooth",
    "homotopy", "powell" or "failed".
    """
    total = 0
    best = None
    short = min(maxiter, max(15, maxiter // 4))

    def keep(res):
        nonlocal best, total
        total += int(res.iterations)
        if best is None or res.converged or not (res.residual_norm >= best.residual_norm):
            best = res

    # a guess that already satisfies R = 0 costs one residual, no Jacobian
    norms = {}
    for k, x0 in enumerate(guesses):
        if x0 is None:
            continue
        R = prob.residual(x0)
        norms[k] = float(np.linalg.norm(R))
        if norms[k] <= tol * prob.residual_scale():
            from workflow.solvers import SolveResult

            return SolveResult(x=np.asarray(x0, float), converged=True, iterations=0,
                               residual_norm=norms[k], reason="converged",
                               function_evaluations=1), 0, f"guess{k}"
    if solver == "newton-powell":
        # cheap cascade: Newton from each guess, the smallest residual first (one
        # or two steps when the stick/slip pattern is right: the DLFT residual is
        # piecewise smooth; near resonance the secant predictor can be the worse
        # start and lead Newton into a local minimum of ‖R‖), then Powell from
        # the best iterate when Newton stalls at a kink
        for k in sorted(norms, key=norms.get):
            keep(_run_solver(prob, guesses[k], "newton", tol, _newton_steps(prob, maxiter)))
            if best.converged:
                return best, total, "newton"
        if best is not None:
            keep(_run_solver(prob, best.x, "powell", tol, maxiter))
            if best.converged:
                return best, total, "powell"
        solver = "powell"
    for k, x0 in enumerate(guesses):
        if x0 is None:
            continue
        keep(_run_solver(prob, x0, solver, tol, short))
        if best.converged:
            return best, total, f"guess{k}"
    if smooth is not None:
        xs, its = smooth()
        total += its
        if xs is not None:
            keep(_run_solver(prob, xs, solver, tol, short))
            if best.converged:
                return best, total, "smooth"
    # homotopy in the excitation amplitude from the stuck (static + tied) state
    x = None
    Zr, Fr = prob.Zr, prob.Fr
    for frac in HOMOTOPY:
        F = Fr.copy()
        F[1:] *= frac
        q = prob.with_linear(Zr, F) if frac < 1.0 else prob
        res = _run_solver(q, q.x0() if x is None else x, solver, tol, short)
        total += int(res.iterations)
        if not res.converged:
            break
        x = res.x
    else:
        keep(res)
        return best, total, "homotopy"
    if solver == "newton":
        keep(_run_solver(prob, best.x, "powell", tol, maxiter))
        if best.converged:
            return best, total, "powell"
    return best, total, "failed"


def sweep_variant(rc, cond: list, law, anchor, v: Variant, *, solver: str, tol: float, maxiter: int,
                  max_passes: int = 20, progress=None, log=None,
                  smooth_nit: int = 64, seeds: list | None = None) -> SweepResult:
    """Sweep ``v`` over the precomputed condensations ``cond`` (one per frequency).

    ``anchor`` (p, 2) is the static tangential stick anchor carried in.
    ``progress`` wraps the frequency loop (e.g. ``log.progress``).
    ``smooth_nit``: variants with fewer samples fall back on a guess from
    HBM with this many (see :func:`_solve_point`); its cost is charged to
    the variant.
    ``seeds`` (optional, one per frequency): complex harmonics (≥1, 3p) of
    U_r from another solve at that frequency (e.g. a lower Nh), tried first;
    missing harmonics are zero.
    """
    from workflow.hb import HBProblem

    n = len(cond)
    out = SweepResult(variant=v, solver=solver, freqs_hz=np.array([c.omega / (2 * np.pi) for c in cond]),
                      amplitude=np.full(n, np.nan), amplitude_max=np.full(n, np.nan),
                      iterations=np.zeros(n, int), seconds=np.zeros(n), converged=np.zeros(n, bool))
    t_all = time.perf_counter()
    c_all = time.process_time()
    prev: list[tuple[float, np.ndarray]] = []   # (ω, x) of the last converged points
    prob = None
    idx = range(n)
    for i in (progress(idx, total=n, label=v.label) if progress else idx):
        c = cond[i]
        t0 = time.perf_counter()
        if prob is None:
            prob = HBProblem(c.Zr, c.Fr, law, v.nh, v.nit, v.method, max_passes=max_passes, stick_anchor=anchor)
        else:
            prob = prob.with_linear(c.Zr, c.Fr)
        guesses = []
        if seeds is not None and seeds[i] is not None:
            U = np.zeros((v.nh + 1, prob.nr), dtype=complex)
            m = min(len(seeds[i]), v.nh + 1)
            U[:m] = seeds[i][:m]
            guesses.append(prob.unknowns_from_harmonics(U))
        if len(prev) >= 2:
            (w1, x1), (w2, x2) = prev[-2], prev[-1]
            guesses.append(x2 + (c.omega - w2) / (w2 - w1) * (x2 - x1))
        if prev:
            guesses.append(prev[-1][1])
        if not guesses:
            guesses.append(prob.x0())             # static + tied linear response
        smooth = None
        if v.nit < smooth_nit:
            def smooth(c=c, guess=guesses[-1], prob=prob):
                sp = HBProblem(c.Zr, c.Fr, law, v.nh, smooth_nit, "hbm", max_passes=max_passes,
                               stick_anchor=anchor)
                rs, its_s, _ = _solve_point(sp, [sp.unknowns_from_harmonics(prob.harmonics(guess))], solver,
                                            tol, maxiter)
                return (prob.unknowns_from_harmonics(sp.harmonics(rs.x)) if rs.converged else None), its_s
        res, its, how = _solve_point(prob, guesses, solver, tol, maxiter, smooth=smooth)
        out.how.append(how)
        Ur = prob.harmonics(res.x)
        a1, amax = _observed(rc, c.omega, Ur)
        out.seconds[i] = time.perf_counter() - t0
        out.iterations[i] = its
        out.converged[i] = bool(res.converged)
        out.amplitude[i], out.amplitude_max[i] = a1, amax
        out.Ur.append(Ur)
        out.reasons.append(res.reason)
        if res.converged:
            prev = (prev + [(c.omega, res.x)])[-2:]
        out.dlft_max_passes = max(out.dlft_max_passes, prob.stats["max_passes"])
    out.total_seconds = time.perf_counter() - t_all
    out.cpu_seconds = time.process_time() - c_all
    return out


def share(todo: list, size: int) -> list[list[int]]:
    """Indices of ``todo`` per rank: the most expensive variant first, each onto
    the rank with the least work so far (cost ~ (2Nh+1)², measured 0.24 / 0.55 /
    2.2 / 9.5 s for HBM nit=105 at Nh = 1/3/7/17). Deterministic: every rank
    computes the same split."""
    cost = [(2 * v.nh + 1) ** 2 * (1.0 + v.nit / 400.0) for v in todo]
    load = [0.0] * size
    out: list[list[int]] = [[] for _ in range(size)]
    for i in sorted(range(len(todo)), key=lambda k: (-cost[k], k)):
        r = min(range(size), key=lambda k: (load[k], k))
        out[r].append(i)
        load[r] += cost[i]
    return [sorted(o) for o in out]


def join_sweeps(parts: list) -> SweepResult:
    """One :class:`SweepResult` from contiguous frequency chunks of the same variant
    (in order); wall time the longest chunk's (they ran at once), CPU time summed."""
    first = parts[0]
    cat = lambda name: np.concatenate([getattr(p, name) for p in parts])  # noqa: E731
    out = SweepResult(variant=first.variant, solver=first.solver, freqs_hz=cat("freqs_hz"),
                      amplitude=cat("amplitude"), amplitude_max=cat("amplitude_max"),
                      iterations=cat("iterations"), seconds=cat("seconds"), converged=cat("converged"))
    for p in parts:
        out.Ur += p.Ur
        out.reasons += p.reasons
        out.how += p.how
    out.total_seconds = max(p.total_seconds for p in parts)
    out.cpu_seconds = sum(p.cpu_seconds for p in parts)
    out.dlft_max_passes = max(p.dlft_max_passes for p in parts)
    return out


def _seeds(runs: list, n: int) -> list:
    """Per frequency, the harmonics U_r of the converged run with the most
    harmonics (HBM first among equals), or None."""
    order = sorted(runs, key=lambda r: (-r.variant.nh, r.variant.method != "hbm", -r.variant.nit))
    out = []
    for i in range(n):
        out.append(next((r.Ur[i] for r in order if r.converged[i]), None))
    return out


def frf_error(v: SweepResult, ref: SweepResult) -> float | None:
    """max |A − A_ref| / max A_ref over the points where both converged (None if none).

    On different frequencies (arc-length continuation) the variant is
    interpolated linearly at the reference's frequencies inside its own range;
    a curve that turns back in frequency (a fold) has no single-valued
    amplitude to compare, so the error is None there.
    """
    if v.freqs_hz.shape == ref.freqs_hz.shape and np.allclose(v.freqs_hz, ref.freqs_hz, rtol=1e-12, atol=0):
        ok = v.converged & ref.converged
        a, b = v.amplitude[ok], ref.amplitude[ok]
    else:
        fv, av = v.freqs_hz[v.converged], v.amplitude[v.converged]
        fr, ar = ref.freqs_hz[ref.converged], ref.amplitude[ref.converged]
        if len(fv) < 2 or np.any(np.diff(fv) <= 0) or np.any(np.diff(fr) <= 0):
            return None
        inside = (fr >= fv[0]) & (fr <= fv[-1])
        a, b = np.interp(fr[inside], fv, av), ar[inside]
    if not len(b):
        return None
    top = float(np.max(ref.amplitude[ref.converged]))
    return float(np.max(np.abs(a - b)) / top) if top > 0 else None


def arclength_scale(cond: list) -> float:
    """Displacement scale (m) for the arc-length: the largest first-harmonic relative
    displacement over the band with the interface free (``Z_r,1 U = F_r,1``), an
    upper bound of the friction-damped response. The start point's own scale
    is useless where the interface is stuck (u_r = 0 there), and a scale far
    below the resonant amplitude makes the arclength all displacement and the
    frequency crawl (measured: 300 steps for 2 of 10 Hz)."""
    return max(max(float(np.abs(np.linalg.solve(c.Zr[1], c.Fr[1])).max()) for c in cond), 1e-30)


def trace_variant(rc, f0: float, f1: float, law, anchor, v: Variant, *, solver: str, tol: float, maxiter: int,
                  max_passes: int = 20, max_steps: int = 300, x_scale: float | None = None,
                  log=None) -> SweepResult:
    """``v`` traced from ``f0`` to ``f1`` (Hz) by pseudo-arclength continuation
    (:func:`workflow.sweep.arclength_sweep`): the step follows the curve, so a
    fold (turning point) is passed instead of jumped; the points are where the
    step control put them. The condensation (with its ω-derivatives, for
    ∂R/∂ω) is recomputed at every ω the corrector visits. ``solver``
    newton-powell and pseudo-time correct with Newton (the corrector is a
    bordered system). ``x_scale`` (m): the displacement scale of the
    arclength (:func:`arclength_scale`). The stick anchor stays the static
    state's at every point, as in the grid sweep: carrying it from point to
    point makes the static offset of stuck pairs a free direction, and the
    continuation walks along that family at constant ω (measured: 36 steps
    for 0.1 Hz on the synthetic blade)."""
    from reduction.condense import condense
    from workflow.hb import HBProblem
    from workflow.sweep import arclength_sweep

    def linear(w):
        c = condense(rc, w, v.nh, derivative=True)
        return c.Zr, c.Fr, c.dZr, c.dFr

    seen: dict[float, tuple] = {}

    def observe(pr, x):
        Ur = pr.harmonics(x)
        a1, amax = _observed(rc, pr.omega, Ur)
        seen[pr.omega] = (amax, Ur)
        return a1

    t0, c0 = time.perf_counter(), time.process_time()
    # steps in the scaled (x/x_scale, ω/ω0) arclength: at most half the band
    # in frequency, so the continuation cannot stride over the whole resonance
    band = abs(f1 - f0) / f0
    pts = arclength_sweep(f0, f1, linear, lambda Zr, Fr: HBProblem(Zr, Fr, law, v.nh, v.nit, v.method,
                                                                   max_passes=max_passes, stick_anchor=anchor),
                          observe, solver="powell" if solver == "powell" else "newton", tol=tol,
                          maxiter=min(maxiter, 30), max_steps=max_steps, ds=band / 40, ds_max=band / 2,
                          ds_min=band * 1e-6, x_scale=x_scale, carry_stick=False)
    out = SweepResult(variant=v, solver=f"arclength-{'powell' if solver == 'powell' else 'newton'}",
                      freqs_hz=np.array([p.frequency_hz for p in pts]),
                      amplitude=np.array([p.amplitude for p in pts]),
                      amplitude_max=np.array([seen[p.omega][0] for p in pts]),
                      iterations=np.array([p.iterations for p in pts], dtype=int),
                      seconds=np.array([p.seconds for p in pts]),
                      converged=np.array([p.converged for p in pts], dtype=bool),
                      Ur=[seen[p.omega][1] for p in pts], reasons=[p.reason for p in pts],
                      how=["arclength"] * len(pts))
    out.total_seconds = time.perf_counter() - t0
    out.cpu_seconds = time.process_time() - c0
    return out


# ------------------------------------------------------------------ stage
def run(scene, inputs: dict, out: Path, log) -> dict:
    from reduction.condense import condense, relative_coordinates
    from reduction.reduced import ReducedModel
    from workflow.errors import BundleError, SolverError
    from workflow.hb import HBProblem
    from workflow.mpi import world
    from workflow.solvers import blas_threads

    out = Path(out)
    hb, sw, ct, ex = scene["hb"], scene["sweep"], scene["contact"], scene["excitation"]
    path = Path(inputs["reduced"]) / "reduced.npz"
    if not path.exists():
        raise BundleError(f"reduced model {path} is missing (the reduction stage writes it)")
    model = ReducedModel.load(path)
    if model.n_pairs == 0:
        raise BundleError(f"reduced model {path} has no contact pairs")
    t0 = time.perf_counter()
    rc = relative_coordinates(model)
    f_mode, mode_index = first_excited_mode(rc)
    f0, f1 = band(sw, f_mode)
    freqs = np.linspace(f0, f1, sw.points) if sw.points > 1 else np.array([0.5 * (f0 + f1)])
    todo = variants(hb)
    ref_v = None
    if hb.reference_harmonics > 0:
        nit = max(int(hb.reference_time_samples), 2 * hb.reference_harmonics + 1)
        ref_v = Variant("hbm", int(hb.reference_harmonics), nit)
    nh_max = max([v.nh for v in todo] + ([ref_v.nh] if ref_v else []) + [1])
    t_c = time.perf_counter()
    cond = [condense(rc, 2 * np.pi * f, nh_max, derivative=False) for f in freqs]
    condense_seconds = time.perf_counter() - t_c
    log.info(f"{model.n_pairs} contact pairs, {model.size} reduced DOFs; first excited tied mode "
             f"#{mode_index + 1} at {f_mode:.2f} Hz; band {f0:.2f}–{f1:.2f} Hz, {len(freqs)} points; "
             f"condensation to Nh = {nh_max}: {condense_seconds:.2f} s")

    mid = cond[len(cond) // 2]
    law = contact_law(ct, model, mid.Zr[1])
    # --- static (preload) state, once
    sp = HBProblem(mid.Zr[:1], mid.Fr[:1], law, 0, 1, "hbm", max_passes=ct.max_passes)
    static = sp.static_state()
    n_contact = int(np.count_nonzero(static.state != 0))
    if not static.result.converged or n_contact == 0:
        raise SolverError(
            f"static contact state: {'no equilibrium' if not static.result.converged else 'every pair separated'} "
            f"({static.result.reason}; ‖F_0‖ = {np.linalg.norm(mid.Fr[0]):.3g} N). The blade touches the disk "
            "only at the flanks: it needs a preload pressing it into its slot — "
            + ("the bundle's loads.npz 'static' load" if "rotation" in getattr(scene, "unused", ()) else
               "set rotation.speed_rpm (centrifugal) or excitation.static_force")
            + ", or a negative contact.gap (interference)")
    log.info(f"static state: {n_contact}/{model.n_pairs} pairs in contact "
             f"({int(np.count_nonzero(static.state == 2))} slipping), normal load "
             f"{-static.lam[:, 0].sum():.4g} N; ε_N = {law.eps_n[0]:.3g}, ε_T = {law.eps_t[0]:.3g} N/m")
    tied, slide = linear_frfs(rc, cond, static)

    kw = dict(solver=hb.solver, tol=hb.tol, maxiter=hb.max_iterations, max_passes=ct.max_passes,
              log=log)
    comm = world()
    size, rank = (1, 0) if comm is None else (comm.Get_size(), comm.Get_rank())
    if size > 1:
        log.info(f"variants and reference frequencies spread over {size} ranks")
    mine = share(todo, size)[rank]
    done: dict[int, SweepResult] = {}
    with blas_threads(1):   # small dense systems: threads only add spinning CPU time
        # warm-up outside the timings: the first DLFT call loads numba's compiled
        # pass and BLAS its kernels (measured: the first variant of a run took
        # 0.45 s where the same sweep takes 0.25–0.34 s later), which would skew
        # the CPU table normalised by that variant
        HBProblem(mid.Zr, mid.Fr, law, 1, 8, "hbm", stick_anchor=static.anchor).residual_jacobian(
            np.zeros(3 * 3 * model.n_pairs))
        for i in log.progress(mine, total=len(mine), label="hb variants",
                              weights=[(2 * todo[i].nh + 1) ** 2 * (1.0 + todo[i].nit / 400.0) for i in mine]):
            v = todo[i]
            if sw.method == "arclength":
                r = done[i] = trace_variant(rc, f0, f1, law, static.anchor, v, max_steps=sw.max_steps,
                                            x_scale=arclength_scale(cond), **kw)
            else:
                r = done[i] = sweep_variant(rc, cond, law, static.anchor, v, **kw)
            log.info(f"{v.label}: {r.total_seconds:.2f} s, {r.converged_points}/{len(r.freqs_hz)} converged, "
                     f"{int(r.iterations.sum())} iterations, peak {r.peak_hz():.2f} Hz")
    if comm is not None:
        parts = comm.allgather(done)           # every rank needs them: they seed the reference
        done = {i: r for part in parts for i, r in part.items()}
    runs: list[SweepResult] = [done[i] for i in range(len(todo))]
    ref = None
    if ref_v is not None and sw.method == "arclength":
        if rank != 0:
            return None
        with blas_threads(1):
            ref = trace_variant(rc, f0, f1, law, static.anchor, ref_v, max_steps=sw.max_steps,
                                x_scale=arclength_scale(cond), **{**kw, "solver": "newton"})
        log.info(f"reference {ref_v.label}: {ref.total_seconds:.2f} s, {len(ref.freqs_hz)} continuation points")
        for r in runs:
            r.error = frf_error(r, ref)
    elif ref_v is not None:
        # seeded at each frequency by the converged variant of highest Nh: from
        # there Newton needs 1–2 Jacobians, where the reference's own sweep met
        # local minima near resonance and fell back on MINPACK's dense QR
        # (n = 2448: 230 s for 50 points, seeded 15 s); seeded points need no
        # neighbour, so the band is cut in one contiguous chunk per rank
        seeds = _seeds(runs, len(freqs))
        cuts = np.linspace(0, len(freqs), size + 1).round().astype(int)
        lo, hi = cuts[rank], cuts[rank + 1]
        with blas_threads(1):
            part = sweep_variant(rc, cond[lo:hi], law, static.anchor, ref_v, seeds=seeds[lo:hi],
                                 **{**kw, "solver": "newton-powell"}) if hi > lo else None
        parts = [part] if comm is None else comm.gather(part, root=0)
        if rank != 0:
            return None
        ref = join_sweeps([p for p in parts if p is not None])
        log.info(f"reference {ref_v.label}: {ref.total_seconds:.2f} s, "
                 f"{ref.converged_points}/{len(freqs)} converged")
        for r in runs:
            r.error = frf_error(r, ref)
    elif rank != 0:
        return None

    files = write_outputs(out, runs, ref, freqs, tied, slide, static, law)
    summary_runs = [{
        "method": r.variant.method, "harmonics": r.variant.nh, "time_samples": r.variant.nit,
        "solver": r.solver, "seconds": round(r.total_seconds, 4), "cpu_seconds": round(r.cpu_seconds, 4),
        "error": r.error,
        "converged_points": r.converged_points, "points": len(freqs), "iterations": int(r.iterations.sum()),
        "peak_hz": r.peak_hz(), "peak_amplitude_m": float(np.nanmax(r.amplitude)) if r.converged.any() else None,
        "dlft_max_passes": r.dlft_max_passes,
    } for r in runs]
    reference = None
    if ref is not None:
        reference = {"method": "hbm", "harmonics": ref.variant.nh, "time_samples": ref.variant.nit,
                     "solver": "newton-powell", "seeded": "highest-Nh variant", "seconds": round(ref.total_seconds, 4),
                     "converged_points": ref.converged_points, "points": len(freqs), "peak_hz": ref.peak_hz()}
    return {
        "runs": runs_json(summary_runs),
        "band_hz": [f0, f1],
        "points": len(freqs),
        "reference": reference,
        "tied_frequency_hz": f_mode,
        "tied_mode": mode_index + 1,
        "static": {"pairs_in_contact": n_contact, "pairs_slipping": int(np.count_nonzero(static.state == 2)),
                   "normal_load_N": float(-static.lam[:, 0].sum())},
        "eps_n": float(law.eps_n[0]), "eps_t": float(law.eps_t[0]),
        "mu": float(ct.mu) if model.mu is None else [float(m) for m in model.mu], "mu_source": model.friction(ct.mu)[1],
        "excitation_amplitude_N": None if "excitation" in getattr(scene, "unused", ()) else float(ex.amplitude),
        "condense_seconds": round(condense_seconds, 4),
        "seconds": round(time.perf_counter() - t0, 3),
        "files": files,
        "unconverged": [line for r in runs + ([ref] if ref is not None else []) if (line := _unconverged(r, ref))],
    }


def _unconverged(r, ref) -> str | None:
    """One line naming the frequencies of sweep ``r`` that did not converge (None if all did)."""
    bad = np.flatnonzero(~np.asarray(r.converged, bool))
    if not len(bad):
        return None
    hz = ", ".join(f"{r.freqs_hz[i]:.2f}" for i in bad[:8]) + (", …" if len(bad) > 8 else "")
    role = "reference " if r is ref else ""
    return (f"{role}{r.variant.label} ({r.solver}): {len(bad)}/{len(r.freqs_hz)} frequencies did not converge "
            f"({hz} Hz; raise hb.max_iterations or change hb.solver)")


def runs_json(rows: list[dict]) -> list[dict]:
    """NaN → None so summary.json stays valid JSON."""
    def clean(v):
        return None if isinstance(v, float) and not math.isfinite(v) else v
    return [{k: clean(v) for k, v in row.items()} for row in rows]


# ---------------------------------------------------------------- outputs
def _csv(rows, header) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()


def _g(x) -> str:
    return "" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.9g}"


def write_outputs(out: Path, runs, ref, freqs, tied, slide, static, law) -> dict:
    """All files of the stage; returns {name: path relative to out}."""
    from workflow.io import write_text

    files = {}
    rows = []
    for r, role in [(r, "variant") for r in runs] + ([(ref, "reference")] if ref else []):
        v = r.variant
        for i, f in enumerate(r.freqs_hz):
            rows.append([v.method, v.nh, v.nit, r.solver, _g(float(f)), _g(float(r.amplitude[i])),
                         int(r.iterations[i]), f"{r.seconds[i]:.6f}", int(r.converged[i]),
                         _g(float(r.amplitude_max[i])), role])
    write_text(out / "frf.csv", _csv(rows, FRF_COLUMNS))
    files["frf"] = "frf.csv"
    write_text(out / "linear.csv", _csv([[_g(float(f)), _g(float(a)), _g(float(b))]
                                         for f, a, b in zip(freqs, tied, slide)],
                                        ("frequency_hz", "tied_m", "sliding_m")))
    files["linear"] = "linear.csv"

    # --- CPU table (paper Table 1): seconds for 50 frequencies, normalised
    base = next((r for r in runs if r.variant.method == "hbm" and r.variant.nh == 1 and r.variant.nit == 105),
                runs[0] if runs else None)
    cpu_rows = []
    for r in runs:
        s50 = r.cpu_seconds * 50.0 / max(len(r.freqs_hz), 1)
        cpu_rows.append((r, s50, s50 / (base.cpu_seconds * 50.0 / max(len(base.freqs_hz), 1))
                         if base and base.cpu_seconds > 0 else float("nan")))
    write_text(out / "cpu_table.csv", _csv(
        [[r.variant.method, r.variant.nh, r.variant.nit, r.variant.nit_label, f"{s:.6g}", f"{nrm:.6g}"]
         for r, s, nrm in cpu_rows],
        ("method", "Nh", "nit", "nit_label", "cpu_seconds_per_50", "normalised")))
    files["cpu_table"] = "cpu_table.csv"
    write_text(out / "cpu_table.md", _cpu_markdown(cpu_rows, base))
    files["cpu_table_md"] = "cpu_table.md"

    # --- error against run time
    if ref is not None:
        write_text(out / "error_vs_time.csv", _csv(
            [[r.variant.method, r.variant.nh, r.variant.nit, r.solver, f"{r.total_seconds:.6g}", _g(r.error),
              r.converged_points, len(r.freqs_hz)] for r in runs],
            ("method", "Nh", "nit", "solver", "seconds", "error", "converged_points", "points")))
        files["error_vs_time"] = "error_vs_time.csv"

    try:
        files.update(_figures(out, runs, ref, freqs, tied, slide))
    except ImportError:  # pragma: no cover - matplotlib is a dependency
        pass
    return files


def _cpu_markdown(cpu_rows, base) -> str:
    cols = []
    for r, _, _ in cpu_rows:
        key = (r.variant.method, r.variant.nit_label)
        if key not in cols:
            cols.append(key)
    nhs = sorted({r.variant.nh for r, _, _ in cpu_rows})
    cell = {(r.variant.method, r.variant.nit_label, r.variant.nh): nrm for r, _, nrm in cpu_rows}
    head = "| Nh | " + " | ".join(f"{m.upper()} nit={lab}" for m, lab in cols) + " |"
    sep = "|---|" + "---|" * len(cols)
    lines = [head, sep]
    for nh in nhs:
        vals = [cell.get((m, lab, nh)) for m, lab in cols]
        lines.append(f"| {nh} | " + " | ".join("" if v is None else f"{v:.3g}" for v in vals) + " |")
    ref = f"{base.variant.label}" if base else "—"
    secs = f"{base.cpu_seconds * 50.0 / max(len(base.freqs_hz), 1):.3g} s" if base else ""
    n = len(base.freqs_hz) if base else 0
    return (f"Process CPU time (all threads) scaled to 50 frequencies (from the {n} computed), normalised by "
            f"{ref} ({secs}) — cf. paper Table 1.\n\n"
            + "\n".join(lines) + "\n")


_STYLE = {"hbm": "-", "tcm": "--", "hdhb": ":"}


def _figures(out: Path, runs, ref, freqs, tied, slide) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from workflow import fourier
    from workflow.io import atomic_path

    files = {}

    def save(fig, name):
        with atomic_path(out / name, suffix=".png") as tmp:
            fig.savefig(tmp, dpi=110, format="png")
        plt.close(fig)
        files[name.removesuffix(".png")] = name

    def frf_axes(sel, title, name):
        fig, ax = plt.subplots(figsize=(7, 4.5))
        ax.semilogy(freqs, tied, color="0.6", lw=1, ls="-.", label="linear, tied")
        ax.semilogy(freqs, slide, color="0.8", lw=1, ls="-.", label="linear, sliding (μ = 0)")
        if ref is not None:
            ax.semilogy(ref.freqs_hz, ref.amplitude, "k-", lw=2.5, alpha=0.35, label=f"reference {ref.variant.label}")
        for r in sel:
            m = np.where(r.converged, r.amplitude, np.nan)
            ax.semilogy(r.freqs_hz, m, ls=_STYLE.get(r.variant.method, "-"), marker=".", ms=3, label=r.variant.label)
        top = max([np.nanmax(r.amplitude) for r in sel if np.isfinite(r.amplitude).any()] + [1e-300])
        ax.set_ylim(top / 30, top * 3)
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("tip amplitude, 1st harmonic (m)")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        save(fig, name)

    nhs = sorted({r.variant.nh for r in runs})
    for k in range(0, len(nhs), 2):
        grp = nhs[k:k + 2]
        frf_axes([r for r in runs if r.variant.nh in grp], "FRF, Nh = " + ", ".join(map(str, grp)) + " (cf. Figs. 4–5)",
                 "frf_nh" + "_".join(map(str, grp)) + ".png")
    if nhs:
        frf_axes([r for r in runs if r.variant.nh == nhs[0]],
                 f"Aliasing at Nh = {nhs[0]}: nit = 2Nh+1 vs larger nit (cf. Fig. 6)", "frf_nit_aliasing.png")

    # iterations (Fig. 7)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for r in runs:
        ax.plot(r.freqs_hz, r.iterations, ls=_STYLE.get(r.variant.method, "-"), marker=".", ms=3,
                label=r.variant.label)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("solver iterations")
    ax.set_title("Iterations against frequency (cf. Fig. 7)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    save(fig, "iterations.png")

    # tangential displacement of one pair over a period at resonance (Fig. 8)
    base = ref if ref is not None else max(runs, key=lambda r: (r.variant.nh, r.variant.nit))
    if base.converged.any():
        i_res = int(np.nanargmax(np.where(base.converged, base.amplitude, np.nan)))
        U = base.Ur[i_res]
        amp_t = np.linalg.norm(np.abs(U[1:]).reshape(U.shape[0] - 1, -1, 3)[:, :, 1:], axis=(0, 2))
        pair = int(np.argmax(amp_t))
        f_res = base.freqs_hz[i_res]
        # each run's point nearest to that frequency (the same index on a grid;
        # arc-length runs have points of their own)
        at = {id(r): int(np.argmin(np.abs(r.freqs_hz - f_res))) for r in runs + [base]}
        wanted = [("hbm", 7), ("hdhb", 7), ("hdhb", 17)]
        sel = [r for r in runs if (r.variant.method, r.variant.nh) in wanted and r.converged[at[id(r)]]]
        if not sel:
            sel = [r for r in runs if r.converged[at[id(r)]]][:4]
        tau = fourier.sample_times(256)
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for r in ([base] if ref is not None else []) + sel:
            k = at[id(r)]
            ut = fourier.to_time(r.Ur[k], 256).reshape(256, -1, 3)[:, pair, 1]
            lab = f"reference {r.variant.label}" if r is ref else r.variant.label
            ax.plot(tau, ut * 1e6, ls=_STYLE.get(r.variant.method, "-") if r is not ref else "-",
                    lw=2.5 if r is ref else 1.2, alpha=0.4 if r is ref else 1.0, color="k" if r is ref else None,
                    label=lab)
            if r.variant.method == "hdhb":  # its unknowns: the samples themselves
                ts = fourier.sample_times(r.variant.nit)
                us = fourier.to_time(r.Ur[k], r.variant.nit).reshape(r.variant.nit, -1, 3)[:, pair, 1]
                ax.plot(ts, us * 1e6, "o", ms=3, color=ax.lines[-1].get_color())
        ax.set_xlabel("τ = ωt (rad)")
        ax.set_ylabel(f"u_t1 of pair {pair} (µm)")
        ax.set_title(f"Tangential relative displacement over a period at {base.freqs_hz[i_res]:.2f} Hz (cf. Fig. 8)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        save(fig, "tangential.png")

    if ref is not None:
        fig, ax = plt.subplots(figsize=(7, 4.5))
        marker = {"hbm": "o", "tcm": "s", "hdhb": "^"}
        for r in runs:
            if r.error is None:
                continue
            ax.loglog(max(r.total_seconds, 1e-4), max(r.error, 1e-12), marker.get(r.variant.method, "o"),
                      label=r.variant.label)
            ax.annotate(f"{r.variant.method.upper()}-{r.variant.nh}/{r.variant.nit_label}",
                        (max(r.total_seconds, 1e-4), max(r.error, 1e-12)), fontsize=6, xytext=(3, 3),
                        textcoords="offset points")
        ax.set_xlabel("wall time of the sweep (s)")
        ax.set_ylabel("max |A − A_ref| / max A_ref")
        ax.set_title(f"FRF error against run time (reference {ref.variant.label})")
        ax.grid(True, which="both", alpha=0.3)
        fig.tight_layout()
        save(fig, "error_vs_time.png")
    return files
