"""Extreme stage: the stiff/extreme-case matrix of :mod:`workflow.engine.studies.extreme` on the reduced model.

Reads ``<reduced>/reduced.npz`` (a :class:`workflow.engine.model.ReducedModel`),
runs every selected case × method × solver and writes ``extreme.csv``,
``extreme.md``; the summary entry ``cases`` has one row per solve
(name, method, solver, converged, iterations, seconds, error, tolerance, diagnosis);
``off_reference`` counts converged solves farther from their reference than their
tolerance and ``off_without_diagnosis`` those of them without a diagnosis (must be 0).
"""
from __future__ import annotations

from pathlib import Path

NAME = "extreme"
SECTIONS = ("contact", "hb", "extreme", "excitation")
NEEDS = ("reduced",)
PRODUCES = ("extreme",)

REDUCED_FILE = "reduced.npz"


def settings_from_scene(scene):
    """:class:`workflow.engine.studies.extreme.Settings` from the scene's sections."""
    from workflow.engine.studies.extreme import GROUPS, Settings

    c, hb, ex, exc = scene["contact"], scene["hb"], scene["extreme"], scene["excitation"]
    groups = GROUPS if "all" in ex.cases else tuple(g for g in GROUPS if g in ex.cases)
    return Settings(mu=c.mu, eps_n=c.eps_n, eps_t=c.eps_t, gap=c.gap, max_passes=c.max_passes,
                    amplitude=exc.amplitude, nh=ex.harmonics, nit=max(ex.time_samples, 2 * ex.harmonics + 1),
                    frequency_ratio=ex.frequency_ratio, tol=hb.tol, max_iterations=hb.max_iterations,
                    pseudo_steps=ex.pseudo_steps, methods=tuple(ex.methods), solvers=tuple(ex.solvers),
                    groups=groups, max_harmonics=ex.max_harmonics, max_time_samples=ex.max_time_samples,
                    penalty_decades=ex.penalty_decades, wear_k=ex.wear_k, wear_blocks=ex.wear_blocks)


def run(scene, inputs: dict, out: Path, log) -> dict:
    from workflow.engine.model import ReducedModel
    from workflow.engine.studies import extreme as X
    from workflow.errors import BundleError
    from workflow.io import write_text
    from workflow.stages.reduction import rigid_contact_only

    rigid_contact_only(scene["contact"], "extreme")
    path = Path(inputs["reduced"]) / REDUCED_FILE
    if not path.is_file():
        raise BundleError(f"reduced model {path} is missing")
    model = ReducedModel.load(path)
    su = X.setup(model, settings_from_scene(scene))
    cases = X.build_cases(su)
    results = X.run_matrix(su, cases, progress=lambda it, n: log.progress(it, total=n, label="extreme cases"))
    out = Path(out)
    write_text(out / "extreme.csv", X.to_csv(results))
    write_text(out / "extreme.md", X.to_markdown(results, su))
    failed = [r for r in results if not r.converged]
    log.info(f"extreme: {len(results) - len(failed)} of {len(results)} solves converged")
    rows = [r.row() for r in results]
    off = sum(X.is_off(r) for r in results)
    bare = X.off_without_diagnosis(results)
    log.info(f"extreme: {off} converged solve(s) farther from the reference than the tolerance, "
             f"{bare} without a diagnosis")
    return {"cases": [{k: row[k] for k in ("name", "method", "solver", "converged", "iterations", "seconds",
                                             "error", "tolerance", "diagnosis")} for row in rows],
            "converged": len(results) - len(failed), "total": len(results),
            "off_reference": off, "off_without_diagnosis": bare,
            "omega_tied_hz": su.omega_tied / (2 * 3.141592653589793),
            "table": "extreme.md", "csv": "extreme.csv"}
