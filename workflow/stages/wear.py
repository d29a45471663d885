"""Wear stage: fretting wear of the dovetail pairs to the worn steady state (paper §4, §5.2).

Reads the reduced model (``inputs["reduced"]/reduced.npz``), condenses it
onto the relative contact DOFs at the wear frequency (``wear.frequency_hz``,
or the first tied resonance of the reduced model), builds the HB problem
(first entries of ``hb.methods``, ``hb.harmonics``, ``hb.time_samples``) and
runs each method of ``wear.methods``: the physical-time reference
("explicit"/"implicit" block marching) and "pseudo-time" (eq. 22, implicit
scheme of ``pseudotime.scheme``). The excitation amplitude is already in the
reduced model's ``f_harmonic`` (assembly applies ``excitation.amplitude``);
``excitation`` is listed so that the cache follows it.

Writes ``wear.csv`` (pair, flank, position, W per method, blade/disk
shares), ``history_<method>.npz``, ``wear_profile.png``, ``max_wear.png``
(Fig. 11), ``harmonic1.png`` (Fig. 12), ``tip_cycle.png`` (Fig. 10) and
returns ``methods`` {method: seconds, iterations, max_wear_m, steady, …}
and ``profile_max_rel_diff`` (pseudo-time against the reference).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from workflow.errors import SceneError, SolverError

NAME = "wear"
SECTIONS = ("contact", "hb", "pseudotime", "wear", "excitation")
NEEDS = ("reduced",)
VIA_BUNDLE = ("excitation",)  # in the reduced load: a user bundle replaces it (#18)
PRODUCES = ("wear",)

_IMPLICIT = ("ser", "bdf", "radau", "lsoda", "rosenbrock")


def first_tied_frequency(rc) -> float:
    """First natural frequency (rad/s) of the structure with the interface tied (u_r = 0)."""
    import scipy.linalg

    r = rc.n_rel
    K, M = rc.K[r:, r:], rc.M[r:, r:]
    ev = scipy.linalg.eigh(0.5 * (K + K.T), 0.5 * (M + M.T), eigvals_only=True, subset_by_index=[0, 0])
    return float(np.sqrt(max(ev[0], 0.0)))


def automatic_penalty(Zr0: np.ndarray) -> tuple[float, float]:
    """DLFT penalties (N/m) from the static condensed stiffness: mean normal/tangential diagonal."""
    d = np.abs(np.real(np.diag(Zr0))).reshape(-1, 3)
    return float(d[:, 0].mean()), float(d[:, 1:].mean())


def build_problem(model, scene, omega=None):
    """(HBProblem, RelativeCoordinates, ω) of a ReducedModel for the scene's contact/hb sections."""
    from reduction.condense import condense, relative_coordinates
    from workflow.contact import ContactLaw
    from workflow.hb import HBProblem

    rc = relative_coordinates(model)
    w = scene["wear"]
    if omega is None:
        w_tied = first_tied_frequency(rc)
        f_tied = w_tied / (2 * np.pi)
        if w.frequency_hz > 0 and not 0.01 * f_tied <= w.frequency_hz <= 100 * f_tied:  # (#18) a typo, not a study
            raise SceneError(f"wear.frequency_hz = {w.frequency_hz:g} Hz is outside 0.01–100 × the first tied "
                             f"frequency of the model ({f_tied:.4g} Hz); 0 means at that resonance")
        omega = 2 * np.pi * w.frequency_hz if w.frequency_hz > 0 else w_tied
    hbs, con = scene["hb"], scene["contact"]
    nh = int(hbs.harmonics[0])
    method = hbs.methods[0]
    nit = int(hbs.time_samples[0]) or 2 * nh + 1
    if method == "hdhb":
        nit = 2 * nh + 1
    cond = condense(rc, omega, nh)
    en, et = automatic_penalty(cond.Zr[0])
    law = ContactLaw(mu=model.friction(con.mu)[0], eps_n=con.eps_n or en, eps_t=con.eps_t or et,
                     gap=np.asarray(model.gap, dtype=float) + con.gap)
    hb = HBProblem(cond.Zr, cond.Fr, law, nh, nit, method, max_passes=con.max_passes)
    return hb, rc, omega


def unworn_solvers(hb, x0, newton_result, *, tol: float, max_steps: int) -> dict:
    """The unworn HB point solved by Newton (given) and by pseudo-time from the
    same start: SER with the Jacobian mass (:func:`workflow.pseudotime.integrate`),
    each with seconds, iterations (steps), Jacobians, and the relative
    difference of the two solutions (max |Δx| / max |x|)."""
    from workflow.pseudotime import integrate

    pt = integrate(hb.residual, hb.residual_jacobian, x0, "ser", precond="jacobian", tol=tol,
                   scale=hb.residual_scale(), max_steps=max_steps)
    row = lambda r: {"seconds": r.seconds, "iterations": int(r.iterations),  # noqa: E731
                     "jacobian_evaluations": int(r.jacobian_evaluations), "converged": bool(r.converged),
                     "reason": r.reason}
    top = max(float(np.abs(newton_result.x).max()), 1e-300)
    return {"newton": row(newton_result), "pseudo-time": row(pt),
            "max_rel_diff": float(np.abs(pt.x - newton_result.x).max() / top) if pt.converged else None,
            "time_ratio_pseudo_over_newton": pt.seconds / max(newton_result.seconds, 1e-12)}


def run_wear(model, scene, out: Path, log) -> dict:
    """The stage's work on a :class:`reduction.reduced.ReducedModel` (also used by tests)."""
    from reduction.condense import recover
    from workflow.wear import (WearProblem, march_reference, plot_wear, profile_rel_diff, pseudo_time_wear,
                               tip_cycle, write_wear_csv)
    from workflow.io import write_npz, write_rows

    out = Path(out)
    w, pt, hbs = scene["wear"], scene["pseudotime"], scene["hb"]
    hb, rc, omega = build_problem(model, scene)
    log.info(f"wear at {omega / 2 / np.pi:.3f} Hz, {hb.p} pairs, Nh = {hb.nh}, nit = {hb.nit}, {hb.method}")
    x0 = hb.x0()
    base = hb.solve(x0, tol=hbs.tol, maxiter=hbs.max_iterations)
    if not base.converged:
        raise SolverError(f"wear: HB solve of the unworn state failed at {omega / 2 / np.pi:.3f} Hz: "
                          f"{base.reason} (try hb.max_iterations or contact penalties)")
    unworn = unworn_solvers(hb, x0, base, tol=hbs.tol, max_steps=pt.max_steps)
    log.info(f"unworn point: newton {base.iterations} iterations {base.seconds:.3f} s; pseudo-time "
             f"{unworn['pseudo-time']['iterations']} steps {unworn['pseudo-time']['seconds']:.3f} s "
             f"({unworn['pseudo-time']['reason']})")
    wp = WearProblem(hb, model.area, w.k_w, w.blade_share)
    rate0 = wp.evaluate(base.x).rate
    i0 = int(np.argmax(rate0))
    track = 3 * i0 + 1
    common = dict(cycles_per_block=w.cycles_per_block, steady_tol=w.steady_tol, tol=hbs.tol, track=track)
    histories = {}
    for m in w.methods:
        wp.set_wear(np.zeros(hb.p))
        if m in ("explicit", "implicit"):
            h = march_reference(wp, base.x, scheme=m, max_blocks=w.max_blocks, block_tol=w.block_tol, **common)
        else:
            scheme = pt.scheme if pt.scheme in _IMPLICIT else "ser"
            if scheme != pt.scheme:
                log.info(f"pseudotime.scheme = {pt.scheme} is explicit/block: the wear system uses ser")
            h = pseudo_time_wear(wp, base.x, scheme=scheme, max_steps=pt.max_steps, rtol=pt.wear_rtol,
                                 dt_max_blocks=pt.wear_dt_max,
                                 **common)
        log.info(f"{m}: {'steady' if h.steady else 'NOT steady'} after {h.iterations} iterations, "
                 f"{h.seconds:.2f} s, max W = {np.max(h.W):.3e} m ({h.reason})")
        histories[m] = h
        write_npz(out / f"history_{m}.npz", W=h.W, cycles=np.asarray(h.cycles), max_wear=np.asarray(h.max_wear),
                  harmonic1=np.asarray(h.harmonic1), W_history=np.asarray(h.W_history))
    write_wear_csv(out / "wear.csv", model.position, model.flank, histories, w.blade_share)
    tip_before = tip_cycle(recover(rc, omega, hb.harmonics(base.x))) if rc.O.shape[0] else None
    tip_after = {m: tip_cycle(recover(rc, omega, hb.harmonics(h.x))) for m, h in histories.items()} \
        if tip_before is not None else None
    figures = plot_wear(out, histories, tip_before=tip_before, tip_after=tip_after,
                        track_label=f"pair {i0} t1")
    summary = {"frequency_hz": omega / 2 / np.pi, "pairs": hb.p, "csv": "wear.csv", "figures": figures,
               "unworn_point": unworn,
               "tracked_pair": i0, "methods": {m: h.summary() for m, h in histories.items()},
               "mu_source": model.friction(scene["contact"].mu)[1],
               "unconverged": [f"wear {m}: NOT steady after {h.iterations} iterations ({h.reason}); raise "
                               f"{'wear.max_blocks' if m in ('explicit', 'implicit') else 'pseudotime.max_steps'}"
                               for m, h in histories.items() if not h.steady]}
    ref = next((m for m in ("implicit", "explicit") if m in histories), None)
    if ref is not None and "pseudo-time" in histories:
        summary["profile_max_rel_diff"] = profile_rel_diff(histories[ref].W, histories["pseudo-time"].W)
        summary["cpu_ratio_pseudo_over_reference"] = histories["pseudo-time"].seconds / max(
            histories[ref].seconds, 1e-12)
    if ref is not None and w.reference_check and w.block_tol > 0:
        wp.set_wear(np.zeros(hb.p))
        coarse = march_reference(wp, base.x, scheme=ref, max_blocks=w.max_blocks, block_tol=4 * w.block_tol,
                                 **common)
        summary["reference_check"] = reference_check(histories, ref, coarse, w.block_tol)
        write_rows(out / "error_vs_time.csv", summary["reference_check"]["error_vs_time"])
        log.info(f"reference check: block_tol ×4 differs by {summary['reference_check']['self_diff']:.3%} of max W; "
                 + ", ".join(f"{r['method']} {r['seconds']:.2f} s error {r['error']:.3%}"
                             for r in summary["reference_check"]["error_vs_time"]))
    return summary


def reference_check(histories: dict, ref: str, coarse, block_tol: float) -> dict:
    """Convergence of the reference in its block size and every method's error.

    The block marching is first order in the block (explicit or implicit
    Euler on W), so with profiles W_f (``block_tol``) and W_c (4×) the
    Richardson estimate of the converged profile is ``W* = W_f + (W_f − W_c)/3``.
    Errors are :func:`workflow.wear.profile_rel_diff` against W* (fraction of
    max W), next to each method's CPU seconds.
    """
    from workflow.wear import profile_rel_diff

    Wf, Wc = histories[ref].W, coarse.W
    Wstar = Wf + (Wf - Wc) / 3.0
    rows = [{"method": f"{ref} block_tol={4 * block_tol:g}", "seconds": coarse.seconds,
             "error": profile_rel_diff(Wstar, Wc), "steady": bool(coarse.steady)}]
    for m, h in histories.items():
        label = f"{m} block_tol={block_tol:g}" if m == ref else m
        rows.append({"method": label, "seconds": h.seconds, "error": profile_rel_diff(Wstar, h.W),
                     "steady": bool(h.steady)})
    return {"self_diff": profile_rel_diff(Wf, Wc), "coarse_seconds": coarse.seconds,
            "coarse_steady": bool(coarse.steady), "error_vs_time": rows}


def run(scene, inputs: dict, out: Path, log) -> dict:
    from reduction.reduced import ReducedModel

    model = ReducedModel.load(Path(inputs["reduced"]) / "reduced.npz")
    return run_wear(model, scene, Path(out), log)
