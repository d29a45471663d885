"""The engine's front door for frequency responses: :func:`frf`.

A reduced model (:class:`workflow.engine.model.ReducedModel`), a contact law
(:func:`contact_law`) and options in; an :class:`FRFStudy` out, with every
result's convergence status: points converged, the ε-check (how much the
peak moves when ε grows, :mod:`workflow.engine.studies.epscheck`), the reference's
own convergence in ε, nit and Nh, and the unbounded-response diagnosis.

Choices (and why):

* **Condensation once.** ``Zr``, ``Fr`` are computed once per frequency for
  the largest Nh of the study and sliced for each variant (``condense`` is
  harmonic by harmonic, so a slice equals a fresh condensation); its time is
  reported apart (``condense_seconds``), not charged to the variants.
* **Static state once** (:func:`static_state`): harmonic 0 does not depend
  on ω; its tangential stick anchor is carried into every dynamic solve,
  which fixes the otherwise non-unique static offset of pairs that stick all
  period (DESIGN §3). Assumption: the interface was assembled stress-free
  and tied, and the preload is applied in one step.
* **Reference.** Swept after the variants, each frequency seeded by the
  converged variant of highest Nh (Newton then needs 1–2 Jacobians).
* **MPI.** With ``comm`` of size N the variants are shared over the ranks
  (largest first) and the reference's band is cut into N chunks; rank 0
  gathers and gets the study, the others None.
* **Error.** ``max_f |A − A_ref| / max_f A_ref`` where both converged.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from workflow.engine import penalty
from workflow.engine.studies import epscheck
from workflow.engine.studies.frf import (SweepResult, arclength_scale, frf_error, join_sweeps, seeds_from, sweep_variant,
                                 trace_variant)
from workflow.engine.linear import band as band_of, first_excited_mode, linear_frfs, stuck_peak
from workflow.engine.studies.variants import Variant, cost, share
from workflow.engine.errors import BundleError, SolverError

#: reason given to a point that did not converge where the sliding interface is
#: at an undamped resonance (Den Hartog: no bounded steady state if μN < πF/4).
UNBOUNDED = ("unbounded response: undamped resonance of the sliding interface and too little friction "
             "(no bounded steady state exists)")


def contact_law(model, *, mu, eps_n: float = 0.0, eps_t: float = 0.0, gap: float = 0.0,
                factor: float = 0.0, rc=None, omega_hz: float | None = None):
    """The DLFT law of ``model``: μ (scalar or (p,)), penalties chosen by
    :func:`workflow.engine.penalty.choose` (``eps_n``/``eps_t`` > 0 are a
    user's values in N/m; ``factor`` > 0 means factor × the static stiffness;
    otherwise the automatic rule, sampled at ``omega_hz`` — default the first
    excited tied mode), ``gap`` (m) added to the model's own gaps.
    ``rc``: the model's relative coordinates if already computed."""
    from workflow.engine.condense import relative_coordinates
    from workflow.engine.linear import condensed
    from workflow.engine.contact import ContactLaw

    rc = relative_coordinates(model) if rc is None else rc
    k_unres = None
    if factor <= 0 and not (eps_n > 0 and eps_t > 0):
        if omega_hz is None:
            try:
                omega_hz = first_excited_mode(rc)[0]
            except BundleError:
                omega_hz = None     # no tied mode to sample at: the large penalty (penalty.choose)
        if omega_hz:
            k_unres = penalty.unresolved_stiffness(rc, 2 * np.pi * float(omega_hz))
    en, et = penalty.choose(condensed(rc, 0.0, 0).Zr[0], eps_n, eps_t, factor, k_unres)
    mu = np.broadcast_to(np.asarray(mu, dtype=float), (model.n_pairs,)).copy()
    return ContactLaw(mu=mu, eps_n=en, eps_t=et, gap=np.asarray(model.gap, dtype=float) + float(gap))


def static_state(Zr, Fr, law, max_passes: int = 20):
    """The harmonic-0 (preload) contact state from the condensed ``Zr[0]``,
    ``Fr[0]`` (any ω: harmonic 0 does not depend on it); :class:`SolverError`
    if it has no equilibrium or every pair separates.

    Solved directly, and if that fails by continuation in ε from ε·10⁻³ by
    decades (the large default penalty shrinks Newton's basin from u = 0:
    measured on the quick sector, 60 iterations without convergence at
    10³× the stiffness). Stick and separation do not depend on ε, so the
    continuation lands on the same state the direct solve would.
    """
    from workflow.engine.cascade import EPS_DECADES
    from workflow.engine.hb import HBProblem

    def solve(lw, u0=None):
        return HBProblem(Zr[:1], Fr[:1], lw, 0, 1, "hbm", max_passes=max_passes).static_state(u0=u0)

    def attempt(u0=None):
        st = solve(law, u0)
        if not st.result.converged:
            u = u0
            for d in range(EPS_DECADES, -1, -1):
                st = solve(penalty.scaled(law, 10.0 ** -d) if d else law, u)
                if not st.result.converged:
                    break
                u = st.u
        return st

    st = attempt()
    f0 = float(np.linalg.norm(Fr[0]))
    if st.result.converged and not np.any(st.state != 0) and f0 > 0:
        # Every pair open under a load is no equilibrium of a blade held only by its flanks: the
        # open structure floats, Zr[0] is singular up to round-off there, and Newton's "solution"
        # throws the blade through the disk (measured: contact.gap = 20 µm on the quick sector,
        # u_N ≈ +0.2 m, Zr[0]'s smallest eigenvalue −890 N/m of 8.5e8). Start again with every
        # gap just closed (g = 0), where the contact stiffness holds it.
        closed = attempt(-law.offset())
        if closed.result.converged and np.any(closed.state != 0):
            return closed
        raise SolverError(
            f"static contact state: every pair separated under a static load of ‖F_0‖ = {f0:.3g} N — no bounded "
            f"equilibrium: the blade touches the disk only at the flanks, so with every pair open nothing carries "
            f"that load (largest |u_r| of the open 'solution' {float(np.abs(st.u).max()):.3g} m), and no state with "
            "the gaps closed converged either. The preload must press the blade into its slot: check its direction "
            "(set rotation.speed_rpm (centrifugal) or excitation.static_force) and the initial gaps (up to "
            f"{float(np.max(law.gap)):.3g} m: contact.gap plus the bundle's gap)")
    if not st.result.converged or not np.any(st.state != 0):
        raise SolverError(
            f"static contact state: {'no equilibrium' if not st.result.converged else 'every pair separated'} "
            f"({st.result.reason}; ‖F_0‖ = {np.linalg.norm(Fr[0]):.3g} N). The blade touches the disk "
            "only at the flanks: it needs a preload pressing it into its slot — set rotation.speed_rpm "
            "(centrifugal) or excitation.static_force, or a negative contact.gap (interference)")
    return st


#: Frequency tolerance of the refined peak, relative to the peak frequency: ~2e-4 Hz at 200 Hz,
#: far below any grid step and the peak's width, in ~20 extra points of one sweep.
PEAK_XTOL = 1e-6


@dataclass
class FRFOptions:
    """How to solve: ``solver`` (newton, powell, newton-powell, pseudo-time),
    ``tol`` (relative to ‖F‖), ``max_iterations`` per attempt, DLFT
    ``max_passes``; ``sweep`` "grid" or "arclength" (``max_steps``);
    ``reference`` (a :class:`Variant` or None); ``eps_check_factor`` (0: no
    ε-check); ``nh_check`` (each run's peak re-solved at 1.5×Nh, the
    convergence measure; with a reference only the reference's, the variants being
    measured by their error against it); ``reference_check`` (the reference's own nit/Nh/ε check);
    ``eps_path`` (:func:`workflow.engine.penalty.path`; None: the law's own,
    :func:`workflow.engine.penalty.path_of`);
    ``pseudo``: :func:`workflow.engine.pseudotime.integrate` options of the
    ``pseudo-time`` solver; ``refine_peak``: refine the peak of the most
    converged grid sweep of a band between its grid points, to ``peak_xtol``
    × its frequency (:attr:`FRFStudy.peak`; not done for explicit
    ``freqs_hz``); ``branch_check``: re-solve the headline peak, the Nh-check's points and the
    headline sweep's last point from an independent start (:func:`_branch_points`,
    :func:`workflow.engine.studies.epscheck.branch_runs`); ``time_check``: the headline peak
    integrated in physical time from its HB state (:func:`workflow.engine.timecheck.time_check`:
    is it a periodic orbit of the time-domain model?); ``stability``: the Floquet multipliers of
    every converged point of every run (:mod:`workflow.engine.studies.sweepstability`), in
    :attr:`SweepResult.stable` and :attr:`SweepResult.floquet_max`."""

    solver: str = "newton-powell"
    tol: float = 1e-8
    max_iterations: int = 50
    max_passes: int = 20
    sweep: str = "grid"
    max_steps: int = 300
    reference: Variant | None = None
    eps_check_factor: float = penalty.CHECK_FACTOR
    reference_check: bool = True
    eps_path: tuple | None = None
    pseudo: dict = field(default_factory=dict)
    refine_peak: bool = True
    peak_xtol: float = PEAK_XTOL
    nh_check: bool = True
    branch_check: bool = True
    time_check: bool = True
    stability: bool = False


@dataclass
class FRFStudy:
    """What :func:`frf` found (Hz, m, s). ``runs`` one :class:`SweepResult`
    per variant, ``reference`` or None; ``tied``/``sliding``/``stuck`` the linear
    limits on ``freqs_hz`` (:func:`workflow.engine.linear.linear_frfs`), ``stuck_peak`` the
    stuck response's peak refined ({"hz", "amplitude_m", "grid_hz"}, or None outside the band);
    ``eps_check`` {"factor", "max_rel_change", "frequency_hz", "runs": [...]} (the penalty
    model's sensitivity);
    ``nh_check`` {"max_rel_change", "frequency_hz", "runs": [...]} (convergence
    in Nh, :func:`workflow.engine.studies.epscheck.nh_runs`; with a reference its row only,
    and ``"variants"`` says how they are measured); ``reference_convergence`` or None;
    ``peak``: the friction-damped peak of the most converged sweep (the
    reference, else the variant with the most harmonics, then time samples)
    refined between its grid points — {"hz", "amplitude_m", "run",
    "evaluations", "xtol_hz", "grid_hz", "grid_amplitude_m"} — or None; ``branch_check``: that peak,
    the Nh-check's points and the headline sweep's last point re-solved from an independent start
    (:func:`workflow.engine.studies.epscheck.branch_runs`); ``time_check``: that peak integrated in
    physical time from its HB state (:meth:`workflow.engine.timecheck.TimeCheck.as_dict`)."""

    freqs_hz: np.ndarray
    band_hz: tuple
    tied_hz: float | None
    tied_mode: int | None
    runs: list
    reference: SweepResult | None
    tied: np.ndarray
    sliding: np.ndarray
    static: object
    law: object
    condense_seconds: float
    condensation: str = ""                      # workflow.engine.condense.condensation: the path it took
    eps_check: dict = field(default_factory=dict)
    nh_check: dict = field(default_factory=dict)
    reference_convergence: dict | None = None
    seconds: float = 0.0
    peak: dict | None = None
    branch_check: dict = field(default_factory=dict)
    time_check: dict = field(default_factory=dict)
    stuck: np.ndarray | None = None
    stuck_peak: dict | None = None

    def unconverged(self) -> list[str]:
        """One line per sweep with points whose solver gave up: where, and why; and one per
        check that saw a converged answer that is not the model's (another branch from an
        independent start, not a periodic orbit in time): those are not results either."""
        out = [line(c) for c, line in ((self.branch_check, epscheck.branch_line), (self.time_check, _time_line))
               if c and c.get("within_tolerance") is False]
        for r in self.runs + ([self.reference] if self.reference is not None else []):
            bad = np.flatnonzero(~np.asarray(r.converged, bool))
            if bad.size:
                hz = ", ".join(f"{r.freqs_hz[i]:.2f}" for i in bad[:8]) + (", …" if len(bad) > 8 else "")
                why = "; ".join(sorted({r.reasons[i] for i in bad}))
                role = "reference " if r is self.reference else ""
                out.append(f"{role}{r.variant.label} ({r.solver}): {bad.size}/{len(r.freqs_hz)} frequencies did "
                           f"not converge ({hz} Hz: {why}; raise hb.max_iterations or change hb.solver)")
        return out

    def warnings(self) -> list[str]:
        """Converged results whose convergence checks exceed their tolerance: the
        Nh-check of the peaks and the reference's own check (2×nit, 1.5×Nh); and the
        checks that could not run. The ε-check is the penalty model's sensitivity,
        reported, not a convergence test: at a finite Nh the rigid limit ε → ∞ is not
        the answer (:mod:`workflow.engine.studies.epscheck`,
        :data:`workflow.engine.penalty.LIMIT_FACTORS`)."""
        out = []
        nc = self.nh_check or {}
        if nc and nc.get("max_rel_change") is None:
            why = next((r["reason"] for r in nc.get("runs", []) if r.get("reason")), "the solver gave up")
            out.append(f"Nh-check: the peak could not be re-solved with more harmonics ({why}; how converged "
                       "the answer is in Nh is unknown)")
        if nc.get("max_rel_change") is not None and nc["max_rel_change"] > penalty.CHECK_TOL:
            worst = max((r for r in nc["runs"] if r["rel_change"] is not None), key=lambda r: r["rel_change"])
            out.append(f"Nh-check: the peak of {worst['label']} moves by {nc['max_rel_change']:.2e} "
                       f"(> {penalty.CHECK_TOL:g}) at Nh = {worst['nh']}, nit = {worst['nit']}; raise hb.harmonics")
        # a check that failed is in unconverged(); one that could not run is a warning
        for c, line in ((self.branch_check, epscheck.branch_line), (self.time_check, _time_line)):
            if c and c.get("within_tolerance") is None:
                out.append(line(c))
        rc = self.reference_convergence or {}
        if rc.get("max_rel_change") is not None and rc["max_rel_change"] > penalty.CHECK_TOL:
            out.append(f"reference {rc.get('variant')}: its peak moves by {rc['max_rel_change']:.2e} under "
                       "2×nit / 1.5×Nh — errors below that are not resolved")
        return out


def _condense_grid(rc, freqs, nh_max):
    """The band's :class:`~workflow.engine.linear.CondensedGrid`, made whole now where it is
    kept whole (else each point when a sweep reaches it), and the grid at Nh = 1 that the
    linear FRFs and the arclength scale read (the grid itself where it is kept whole)."""
    from workflow.engine.linear import CondensedGrid

    cond = CondensedGrid(rc, 2 * np.pi * np.asarray(freqs, dtype=float), nh_max)
    if cond.keep_all:
        for _ in cond:
            pass
        return cond, cond
    return cond, CondensedGrid(rc, cond.omegas, 1, keep_bytes=0.0)     # read once, in order


def _variants(rc, cond, freqs, law, static, todo, opt, comm, log):
    """Every variant swept (shared over the ranks); all ranks get all runs."""
    from workflow.engine.blas import blas_threads

    size, rank = (1, 0) if comm is None else (comm.Get_size(), comm.Get_rank())
    kw = dict(solver=opt.solver, tol=opt.tol, maxiter=opt.max_iterations, max_passes=opt.max_passes)
    done = {}
    mine = share(todo, size)[rank]
    progress = log.progress if log is not None else (lambda it, **k: it)  # noqa: E731
    for i in progress(mine, total=len(mine), label="hb variants", weights=[cost(todo[i]) for i in mine]):
        v = todo[i]
        if opt.sweep == "arclength":
            r = trace_variant(rc, freqs[0], freqs[-1], law, static, v, max_steps=opt.max_steps,
                              x_scale=arclength_scale(cond), eps_path=opt.eps_path, **kw)
        else:
            r = sweep_variant(rc, cond, law, static, v, eps_path=opt.eps_path, pseudo=opt.pseudo, **kw)
        done[i] = r
        if log is not None:
            log.info(f"{v.label}: {r.total_seconds:.2f} s, {r.converged_points}/{len(r.freqs_hz)} converged, "
                     f"{int(r.iterations.sum())} iterations, peak {r.peak_hz():.2f} Hz")
    if comm is not None:
        done = {i: r for part in comm.allgather(done) for i, r in part.items()}
    return [done[i] for i in range(len(todo))]


def _reference(rc, cond, freqs, law, static, runs, opt, comm, log=None):
    """The reference sweep (rank 0 gets it, others None), in the log's progress bar."""
    size, rank = (1, 0) if comm is None else (comm.Get_size(), comm.Get_rank())
    kw = dict(tol=opt.tol, maxiter=opt.max_iterations, max_passes=opt.max_passes)
    if opt.sweep == "arclength":
        if rank != 0:
            return None
        return trace_variant(rc, freqs[0], freqs[-1], law, static, opt.reference, max_steps=opt.max_steps,
                             x_scale=arclength_scale(cond), solver="newton", eps_path=opt.eps_path, **kw)
    # seeded points need no neighbour, so the band is cut in one chunk per rank
    seeds = seeds_from(runs, len(freqs))
    cuts = np.linspace(0, len(freqs), size + 1).round().astype(int)
    lo, hi = cuts[rank], cuts[rank + 1]
    part = sweep_variant(rc, cond[lo:hi], law, static, opt.reference, seeds=seeds[lo:hi], solver="newton-powell",
                         eps_path=opt.eps_path, progress=log.progress if log is not None else None,
                         **kw) if hi > lo else None
    parts = [part] if comm is None else comm.gather(part, root=0)
    return join_sweeps([p for p in parts if p is not None]) if rank == 0 else None


def frf(model, law, variants: list, *, band_hz=(0.0, 0.0), points: int = 50, freqs_hz=None,
        options: FRFOptions | None = None, comm=None, log=None) -> FRFStudy | None:
    """Friction-damped FRFs of ``model`` under ``law`` for each :class:`Variant`.

    ``band_hz`` (f_start, f_stop), 0 = ∓10 % of the first tied mode the tip
    load excites; ``points`` frequencies — or ``freqs_hz``, the frequencies
    themselves (swept in the order given). Returns the :class:`FRFStudy`
    (None on MPI ranks other than 0).
    """
    from workflow.engine.condense import condensation, relative_coordinates
    from workflow.engine.blas import blas_threads

    opt = options or FRFOptions()
    t0 = time.perf_counter()
    if comm is not None:
        # PetscInitialize is collective, and a rank's first structured solve (PETSc's FGMRES,
        # workflow.engine.linsolve) would otherwise import petsc4py on that rank alone
        from petsc4py import PETSc  # noqa: F401 - the import initialises PETSc (collective)
    rc = relative_coordinates(model)
    if freqs_hz is not None:
        freqs_hz = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
        band_hz = (float(freqs_hz.min()), float(freqs_hz.max()) if freqs_hz.ptp() > 0 else 2 * float(freqs_hz.max()))
    try:
        f_mode, mode_index = first_excited_mode(rc)
    except BundleError:
        if not (band_hz[0] and band_hz[1]):
            raise
        # a model whose only motion is at the interface (Den Hartog's oscillator) has
        # no tied mode: fine when the band is given
        f_mode, mode_index = None, None
    f0, f1 = band_of(band_hz[0], band_hz[1], f_mode)
    if freqs_hz is not None:
        freqs = freqs_hz
    else:
        freqs = np.linspace(f0, f1, points) if points > 1 else np.array([0.5 * (f0 + f1)])
    nh_max = max([v.nh for v in variants] + ([opt.reference.nh] if opt.reference else []) + [1])
    cond, first = _condense_grid(rc, freqs, nh_max)
    static = static_state(cond[0].Zr, cond[0].Fr, law, opt.max_passes)
    if opt.eps_path is None:
        opt = replace(opt, eps_path=penalty.path_of(law, np.real(cond[0].Zr[0])))
    if log is not None:
        tied = f"#{mode_index + 1} at {f_mode:.2f} Hz" if f_mode is not None else "none"
        log.info(f"{model.n_pairs} contact pairs, {model.size} reduced DOFs; first excited tied mode "
                 f"{tied}; band {f0:.2f}–{f1:.2f} Hz, {len(freqs)} points; "
                 f"condensation to Nh = {nh_max} ({condensation(rc)}, "
                 + (f"{cond.seconds:.2f} s" if cond.keep_all else "each point when swept: the band would "
                    "not fit in engine.linear.KEEP_BYTES") + f"); {penalty.describe(law)}; "
                 "static state: "
                 f"{int(np.count_nonzero(static.state))}/{model.n_pairs} pairs in contact")
    tied, sliding, stuck = linear_frfs(rc, first, static)
    with blas_threads(1):   # small dense systems: threads only add spinning CPU time
        _warm_up(cond[0], law, static)
        runs = _variants(rc, cond, freqs, law, static, variants, opt, comm, log)
        ref = _reference(rc, cond, freqs, law, static, runs, opt, comm, log) if opt.reference else None
        # only the stability reads the grid's condensations after the sweeps (302 MB a frequency
        # at 512 pairs): the checks and the peak search condense their own points
        t_cond = cond.seconds + (first.seconds if first is not cond else 0.0)
        grid = cond if opt.stability and getattr(cond, "keep_all", False) else None
        del cond, first
        if comm is not None and comm.Get_rank() != 0:
            return None
        for r in runs + ([ref] if ref is not None else []):
            _mark_unbounded(r, sliding)
            if ref is not None and r is not ref:
                r.error = frf_error(r, ref)
        study = FRFStudy(freqs_hz=freqs, band_hz=(f0, f1), tied_hz=f_mode,
                         tied_mode=None if mode_index is None else mode_index + 1, runs=runs,
                         reference=ref, tied=tied, sliding=sliding, static=static, law=law,
                         condense_seconds=t_cond, condensation=condensation(rc), stuck=stuck,
                         stuck_peak=stuck_peak(rc, static, freqs, stuck, opt.peak_xtol))
        Ur_peak = _peak(study, rc, opt, refine=freqs_hz is None and len(freqs) > 1)
        _check(study, rc, opt, log, Ur_peak)
        _headline(study, model, rc, opt, Ur_peak, log=log)
        if opt.stability:
            _stability(study, model, rc, log, grid)
    study.seconds = time.perf_counter() - t0
    return study


def _stability(study: FRFStudy, model, rc, log, grid=None) -> None:
    """Stable / unstable and the largest Floquet multiplier of every converged point, in place;
    ``grid``: the sweeps' condensations (read where kept)."""
    from workflow.engine.studies.sweepstability import sweep_stability

    for r in study.runs + ([study.reference] if study.reference is not None else []):
        st = sweep_stability(model, rc, study.law, study.static, r, grid=grid)
        r.stable, r.floquet_max = st["stable"], st["floquet_max"]
        if log is not None:
            bad = [f for f, s in zip(r.freqs_hz, st["stable"]) if s is False]
            log.info(f"stability of {r.variant.label} ({st['seconds']:.1f} s): "
                     + (f"{len(bad)} unstable points, {min(bad):.6g}–{max(bad):.6g} Hz" if bad else
                        f"every converged point stable (largest multiplier {np.nanmax(st['floquet_max']):.6f})"
                        if np.isfinite(st["floquet_max"]).any() else "not computed"))


def _check(study: FRFStudy, rc, opt, log, Ur_peak=None) -> None:
    """The study's convergence checks, in place: the ε-check of every run, the Nh-check, the
    reference's own check (:mod:`workflow.engine.studies.epscheck`); the headline run's at its
    refined peak (``Ur_peak``, :func:`_peak`), the others' at their grid peaks."""
    law, static, runs, ref = study.law, study.static, study.runs, study.reference
    pk = study.peak
    at = {pk["run"]: (pk["hz"], Ur_peak, pk["amplitude_m"])} if pk is not None and Ur_peak is not None else None
    if opt.eps_check_factor > 0:
        every = runs + ([ref] if ref is not None else [])
        study.eps_check = epscheck.judged(epscheck.frf_runs(rc, law, static, every, opt, at))
        if log is not None:
            log.info(epscheck.log_line(f"ε-check (ε × {opt.eps_check_factor:g}, the penalty's sensitivity)",
                                       "the worst peak", study.eps_check))
    if opt.nh_check:
        # with a reference, a variant's error against it is its convergence measure (and a
        # stronger one than 1.5×Nh): only the reference is re-solved. On paper-frf the 20
        # variants' re-solves took 60 of the stage's 130 s, the collocated Nh = 26 ones
        # 11–20 s each where Newton creeps at ‖R‖/‖F‖ ≈ 1e-4 (2026-11-27)
        checked = [ref] if ref is not None else runs
        study.nh_check = epscheck.judged(epscheck.nh_runs(rc, law, static, checked, opt, at))
        if ref is not None:
            study.nh_check["variants"] = "against the reference (error)"
        if log is not None:
            log.info(epscheck.log_line("Nh-check (1.5×Nh, convergence)", "the worst peak", study.nh_check))
    if ref is not None and opt.reference_check and opt.sweep == "grid":
        study.reference_convergence = epscheck.reference(rc, law, static, ref, opt,
                                                         checks=[c for c in (study.eps_check, study.nh_check) if c],
                                                         at=at)


def _peak(study: FRFStudy, rc, opt, refine: bool):
    """The headline peak refined between its grid points (:attr:`FRFStudy.peak`), in place;
    its relative harmonics, or None where it is not refined."""
    ref = study.reference
    head = ref if ref is not None else _most_harmonics(study.runs)
    if not (opt.refine_peak and opt.sweep == "grid" and refine):
        return None
    study.peak, Ur_peak = _refined_peak(rc, study.law, study.static, head, opt, reference=ref is not None)
    return Ur_peak


def _headline(study: FRFStudy, model, rc, opt, Ur_peak, log) -> None:
    """The checks that can see a wrong headline peak, in place: its Nh → ∞ estimate, the
    branch check (independent starts), the time check."""
    law, static, ref = study.law, study.static, study.reference
    head = ref if ref is not None else _most_harmonics(study.runs)
    if study.peak is not None:
        scale = epscheck.limit_scale(study.nh_check, head.variant.label)
        study.peak["amplitude_nh_limit_m"] = None if scale is None else study.peak["amplitude_m"] * scale
    if opt.branch_check:
        study.branch_check = epscheck.branch_runs(rc, law, static, _branch_points(study, opt), opt)
        if log is not None:
            log.info(_branch_log(study.branch_check))
    if opt.time_check:
        study.time_check = _time_check(model, rc, law, study, head, Ur_peak)
        if log is not None and study.time_check:
            log.info(_time_line(study.time_check) or study.time_check.get("log_line", ""))


def _branch_points(study: FRFStudy, opt) -> list[dict]:
    """The points the branch check re-solves, once each: the headline peak (refined, else the
    headline sweep's grid peak), each point the Nh-check re-solved (each run's grid peak, or the
    reference's), and the headline sweep's last converged point — the branch the upward sweep
    ends on: a sweep that stepped onto a spurious root stays on it (Den Hartog's oscillator,
    Nh = 25, nit = 512, μN/F0 = 0.2: from β = 1.06 to the band's end, 1 % off the independent
    root, while the peak at β = 0.94 agrees)."""
    ref = study.reference
    head = ref if ref is not None else _most_harmonics(study.runs)
    checked = ([ref] if ref is not None else study.runs) if opt.nh_check else []
    pts = []

    def add(role, sweep, f_hz, amp):
        v = sweep.variant
        if amp is None or not np.isfinite(amp) or any(p["label"] == v.label and p["frequency_hz"] == f_hz for p in pts):
            return
        pts.append({"role": role, "label": v.label, "method": v.method, "nh": v.nh, "nit": v.nit,
                    "frequency_hz": float(f_hz), "swept_m": float(amp)})

    pk = study.peak
    if pk is not None and head is not None:
        add("headline peak (refined)", head, pk["hz"], pk["amplitude_m"])
    for r in ([head] if head is not None and pk is None else []) + checked:
        i = epscheck._peak_index(r)
        if i is not None:
            # the headline run's Nh-check is at its refined peak (:func:`_check`) when it has one
            nh_here = any(r is c for c in checked) and not (pk is not None and r is head)
            role = "grid peak (Nh-check)" if nh_here else "headline grid peak"
            add(role, r, r.freqs_hz[i], r.amplitude[i])
    ok = np.flatnonzero(head.converged) if head is not None else []
    if len(ok) > 1:
        add("last point of the sweep", head, head.freqs_hz[ok[-1]], head.amplitude[ok[-1]])
    return pts


def _branch_log(check: dict) -> str:
    """The log line of the branch check."""
    line = epscheck.branch_line(check)
    if line is not None:
        return line
    n = len(check["points"])
    return (f"branch check (independent start, {n} point{'s' * (n != 1)}, {check['seconds']:.2f} s): "
            f"{check['max_rel_diff']:.2e} largest difference from the swept roots, within the tolerance "
            f"{check['tolerance']:g}")


def _most_harmonics(runs):
    """The variant with the most harmonics, then time samples (the headline's choice without a reference)."""
    return max(runs, key=lambda r: (r.variant.nh, r.variant.nit)) if runs else None


def _refined_peak(rc, law, static, sweep, opt, reference: bool) -> dict | None:
    """:attr:`FRFStudy.peak` of ``sweep`` (:func:`workflow.engine.studies.peak.refine_peak`)."""
    from workflow.engine.studies.peak import refine_peak

    if sweep is None or not sweep.converged.any():
        return None, None
    i = int(np.argmax(np.where(sweep.converged, sweep.amplitude, -np.inf)))
    xtol = opt.peak_xtol * float(sweep.freqs_hz[i])
    solver = dict(solver="newton-powell") if reference else dict(solver=opt.solver, pseudo=opt.pseudo)
    pk = refine_peak(rc, sweep, law, static, sweep.variant, xtol, tol=opt.tol, maxiter=opt.max_iterations,
                     max_passes=opt.max_passes, eps_path=opt.eps_path, **solver)
    return ({"hz": pk.hz, "amplitude_m": pk.amplitude, "run": sweep.variant.label, "evaluations": pk.evaluations,
             "xtol_hz": xtol, "grid_hz": float(sweep.freqs_hz[i]), "grid_amplitude_m": float(sweep.amplitude[i])},
            pk.Ur)


def _time_check(model, rc, law, study: FRFStudy, head, Ur_peak) -> dict:
    """:attr:`FRFStudy.time_check`: the headline peak (refined, else the headline sweep's grid
    peak) integrated in physical time from its HB state, charged with that sweep's Nh-check change."""
    from workflow.engine.timecheck import time_check

    if study.peak is not None and Ur_peak is not None:
        hz, Ur = study.peak["hz"], Ur_peak
    else:
        i = epscheck._peak_index(head) if head is not None else None
        if i is None:
            return {"within_tolerance": None, "reason": "no converged point to check"}
        hz, Ur = float(head.freqs_hz[i]), head.Ur[i]
    label = head.variant.label
    change = next((r.get("rel_change") for r in (study.nh_check or {}).get("runs", []) if r.get("label") == label),
                  None)
    tc = time_check(model, law, 2.0 * np.pi * hz, Ur, nh_change=change, rc=rc)
    return {**tc.as_dict(), "run": label, "log_line": tc.log_line()}


def _time_line(check: dict) -> str | None:
    """The warning of a time-domain check that failed or could not run; None when it passed."""
    if not check or check.get("within_tolerance"):
        return None
    if check.get("within_tolerance") is None:
        return f"time check: could not run ({check.get('reason')})"
    return (f"time check: the HB peak of {check.get('run')} at {check['frequency_hz']:.2f} Hz is not a periodic "
            f"orbit of the time-domain model: first harmonic {check['max_rel_diff']:.2e} from the HB "
            f"(> {check['tolerance']:.2e}) — {check.get('verdict', '')}; raise hb.harmonics, check the branch")


def _warm_up(c, law, static):
    """The first DLFT call loads numba's compiled pass and BLAS its kernels
    (measured: the first variant of a run took 0.45 s where the same sweep
    takes 0.25–0.34 s later), which would skew a CPU table normalised by it."""
    from workflow.engine.hb import HBProblem

    HBProblem(c.Zr, c.Fr, law, 1, 8, "hbm", static=static).residual_jacobian(np.zeros(9 * law.p))


def _mark_unbounded(r: SweepResult, sliding: np.ndarray) -> None:
    """Points that did not converge where the sliding response is unbounded."""
    if not np.isfinite(sliding).all() and len(r.freqs_hz) == len(sliding):
        for i in np.flatnonzero(~r.converged & ~np.isfinite(sliding)):
            r.reasons[i] = UNBOUNDED
