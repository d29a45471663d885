"""The matrix as tables: CSV and Markdown, and the converged-but-off rows."""
from __future__ import annotations

import csv
import io

import numpy as np

from workflow.engine.studies.extreme.cases import CaseResult
from workflow.engine.studies.extreme.settings import Setup

_COLUMNS = ("name", "group", "method", "solver", "converged", "iterations", "seconds", "error", "tolerance",
            "diagnosis", "residual", "separated", "slipping", "sticking", "cond", "note")


def is_off(r: CaseResult) -> bool:
    """A converged solve farther from its reference than its tolerance (it must carry a diagnosis)."""
    return bool(r.converged and r.error is not None and r.tolerance is not None and r.error > r.tolerance)


def off_without_diagnosis(results: list[CaseResult]) -> int:
    """Converged solves farther from their reference than their tolerance with no diagnosis (must be 0)."""
    return sum(1 for r in results if is_off(r) and not r.diagnosis)


def to_csv(results: list[CaseResult]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=_COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in results:
        row = r.row()
        w.writerow({k: ("" if row[k] is None else (f"{row[k]:.6g}" if isinstance(row[k], float) else row[k]))
                    for k in _COLUMNS})
    return buf.getvalue()


def _fmt(v, spec=".2e") -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "**no**"
    if isinstance(v, float):
        return format(v, spec)
    return str(v)


def to_markdown(results: list[CaseResult], su: Setup | None = None) -> str:
    lines = ["# Stiff and extreme cases", ""]
    if su is not None:
        s = su.settings
        lines += [f"Model: {su.p} contact pairs, {su.model.size} reduced DOFs. Base: Nh = {s.nh}, nit = {s.nit}, "
                  f"f = {su.omega / 2 / np.pi:.2f} Hz ({s.frequency_ratio:g} × tied resonance "
                  f"{su.omega_tied / 2 / np.pi:.2f} Hz; free-interface resonance {su.omega_free / 2 / np.pi:.2f} Hz), "
                  f"μ = {s.mu:g}, ε_ref = ({su.eps_ref[:, 0].mean():.3g}, {su.eps_ref[:, 1].mean():.3g}) N/m (mean "
                  f"static stiffness per pair), tol = {s.tol:g}.", ""]
    n_ok = sum(r.converged for r in results)
    off = [r for r in results if is_off(r)]
    lines += [f"{n_ok} of {len(results)} solves converged (each verified independently: finite, "
              f"‖R‖/‖F‖ ≤ 10·tol, DLFT periodic, Coulomb and λ_N ≤ 0). Error: distance to the case's "
              f"reference; tol.: how far a right solution may be from it. {len(off)} converged solve(s) "
              f"farther than that, each with a diagnosis ({sum(not r.diagnosis for r in off)} without).", "",
              "| case | method | solver | conv. | iter. | s | error | tol. | ‖R‖/‖F‖ | sep/slip/stick | diagnosis |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        st = "–" if r.separated is None else f"{r.separated:.2f}/{r.slipping:.2f}/{r.sticking:.2f}"
        diag = (r.diagnosis or "").replace("|", "\\|")
        lines.append(f"| {r.name} | {r.method} | {r.solver} | {_fmt(r.converged)} | {r.iterations} | "
                     f"{r.seconds:.2f} | {_fmt(r.error)} | {_fmt(r.tolerance, '.0e')} | {_fmt(r.residual, '.1e')} | {st} | "
                     f"{diag} |")
    notes = {}
    for r in results:
        if r.note and r.name not in notes:
            notes[r.name] = r.note
    if notes:
        lines += ["", "Notes (first method/solver of each case):", ""]
        lines += [f"* **{k}**: {v}" for k, v in notes.items()]
    return "\n".join(lines) + "\n"
