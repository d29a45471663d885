"""Verification stage: the project's HB against exact friction solutions (issue 15, item 6).

Runs :func:`workflow.verification.suite.run` on the cases of ``verification.cases``
for every Nh of ``verification.harmonics`` and writes ``verification.csv``
(case, Nh, nit, eps, amplitude, exact, error, converged, frequency, source of
the reference, stops), ``galerkin.csv`` (HB's own truncation floor on the
non-stop Coulomb points: Galerkin HB with the exact sign law) and
``verification.png`` (error against Nh), and ``wear_references.csv`` — the engine's wear
against the closed forms and the cycle-jump integration of ``verification.wear_cases``
(:mod:`workflow.verification.wear_runner`; summary ``wear_rows``). Needs no other product:
the cases are built in :mod:`workflow.verification.models` and ``wear_exact``.
"""
from __future__ import annotations

from pathlib import Path

NAME = "verification"
SECTIONS = ("verification",)
NEEDS = ()
PRODUCES = ("verification",)


def run(scene, inputs: dict, out: Path, log) -> dict:
    import math
    import time

    from workflow.io import write_rows
    from workflow.verification import suite
    from workflow.verification.plot import error_figure

    cfg = scene["verification"]
    out = Path(out)
    t0 = time.perf_counter()
    rows, floor = suite.run(cfg.cases, list(cfg.harmonics), nit=cfg.time_samples,
                            penalty_factor=cfg.penalty_factor,
                            progress=lambda it: log.progress(it, total=len(it), label="verification cases"))
    rows = [{k: r[k] for k in suite.COLUMNS} for r in rows]
    write_rows(out / "verification.csv", rows)
    files = {"table": "verification.csv"}
    if floor:
        write_rows(out / "galerkin.csv", floor)
        files["galerkin"] = "galerkin.csv"
    error_figure(rows, floor, out / "verification.png")
    files["figure"] = "verification.png"
    wear_rows = wear_references(cfg.wear_cases)
    if wear_rows:
        write_rows(out / "wear_references.csv", wear_rows)
        files["wear"] = "wear_references.csv"
        worst = max(wear_rows, key=lambda r: r["error"])
        log.info(f"wear references: {len(wear_rows)} rows, largest error {worst['error']:.2e} "
                 f"({worst['case']}: {worst['quantity']})")
    s = suite.summary(rows, floor)
    log.info(f"verification: {s['converged']}/{s['total']} HB points converged; largest non-stop error at "
             f"Nh = {s['largest_harmonics']}: {s['max_error_nonstop']}; Galerkin floor {s['galerkin_floor']}")
    clean = lambda v: None if isinstance(v, float) and not math.isfinite(v) else v  # noqa: E731
    return {"rows": [{k: clean(v) for k, v in r.items()} for r in rows], **s, "files": files, "wear_rows": wear_rows,
            "seconds": round(time.perf_counter() - t0, 3)}


def wear_references(cases) -> list[dict]:
    """Rows (case, quantity, value, exact, error) of the wear references named in ``cases``."""
    from workflow.verification import wear_mdr, wear_runner

    make = {"jenkins": wear_runner.jenkins_rows, "punch": wear_runner.punch_rows,
            "punch-layer": wear_runner.punch_layer_rows,
            "oscillator": wear_runner.oscillator_rows, "mdr": wear_mdr.mdr_rows}
    return [r for c in cases for r in make[c]()]
