"""The branch check (issue #47, item 1): the headline peak and the Nh-check's points re-solved
from a start that owes nothing to the sweep (tied; continuation in Nh from Nh = 1 where that
disagrees), so that a sweep that followed a spurious root of the truncated balance is seen.

The case with a known spurious branch: Den Hartog's oscillator (m = k = F0 = 1, μN/F0 = 0.5,
ζ = 0), HBM Nh = 15, nit = 128, swept upwards over β = 0.5, 0.61, 0.72, 0.83 (measured
2026-11-28): from β = 0.61 on the sweep stays on a root 18.6 % below Den Hartog at β = 0.83
(2.207 against 2.712), while the continuation in Nh from Nh = 1 reaches 2.639
(Galerkin HB with the exact sign law at Nh = 15: 2.690). The Nh-check (Nh = 23 from the swept
root) moves that peak by 0.3 %. With nit = 256, or μN/F0 = 0.2, the sweep is on the
independent start's root.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from workflow import engine
from workflow.engine import penalty
from workflow.engine.studies import epscheck
from workflow.params import HB, Contact, Excitation, PseudoTime, Sweep
from workflow.report import headline as hl
from workflow.runlog import RunLog
from workflow.verification import exact, models

BETAS = np.array([0.5, 0.6111, 0.7222, 0.8333])


def coulomb_study(ratio: float, nit: int, *, nh: int = 15, **opt):
    """HBM sweep of Den Hartog's oscillator (ω_n = 1 rad/s) over :data:`BETAS`; penalty 10³ k."""
    model, _ = models.coulomb(1.0, 1.0, 0.0, 1.0, 1.0, ratio)
    law = engine.contact_law(model, mu=ratio, omega_hz=1.0 / (2 * np.pi))
    kw = dict(eps_check_factor=0.0, nh_check=False) | opt
    return engine.frf(model, law, [engine.Variant("hbm", nh, nit)], freqs_hz=BETAS / (2 * np.pi),
                      options=engine.FRFOptions(**kw))


def den_hartog(ratio: float, beta: float) -> float:
    return exact.den_hartog(1.0, 1.0, ratio, 1.0, beta).first


def test_branch_check_flags_the_spurious_branch_of_den_hartogs_oscillator():
    study = coulomb_study(0.5, 128)
    bc = study.branch_check
    assert bc["within_tolerance"] is False and bc["max_rel_diff"] > 0.1
    (pt,) = bc["points"]                     # the headline grid peak (no refined peak for given frequencies)
    assert pt["frequency_hz"] == pytest.approx(0.8333 / (2 * np.pi)) and pt["start"] == "nh-continuation"
    exact_m = den_hartog(0.5, 0.8333)
    # the sweep is on the wrong root; the continuation in Nh from Nh = 1 reaches the one near Den Hartog
    # (Newton from the tied start — the mass at rest — does not converge here)
    assert pt["swept_m"] == pytest.approx(study.runs[0].amplitude[-1]) and abs(pt["swept_m"] / exact_m - 1) > 0.15
    assert abs(pt["independent_m"] / exact_m - 1) < 0.03
    # a warning naming both amplitudes and the advice
    (line,) = [w for w in study.unconverged() if w.startswith("branch check")]
    assert f"{pt['swept_m']:.3e} m" in line and f"{pt['independent_m']:.3e} m" in line
    assert "hb.harmonics" in line and "time domain" in line


@pytest.mark.parametrize("ratio, nit", [(0.2, 128), (0.5, 256)])
def test_branch_check_passes_where_the_sweep_is_on_the_independent_root(ratio, nit):
    """μN/F0 = 0.2 (Den Hartog within 1.2 %), and the spurious case with twice the time samples."""
    study = coulomb_study(ratio, nit)
    bc = study.branch_check
    assert bc["within_tolerance"] is True and bc["max_rel_diff"] < 1e-6
    (pt,) = bc["points"]
    assert pt["start"] in ("tied", "nh-continuation") and "tied_m" not in pt
    assert abs(pt["swept_m"] / den_hartog(ratio, 0.8333) - 1) < 0.025
    assert not [w for w in study.warnings() + study.unconverged() if w.startswith("branch check")]


def test_the_tied_start_confirms_a_damped_jenkins_sweep():
    """The 2-DOF damper (a Jenkins pad, normal load varying with the motion, ζ = 1 %) through
    its resonance: Newton from the tied start reaches the swept roots (to 1e-15), so the
    continuation in Nh is not needed; the FRF is within 0.1 % of the event-driven integrator."""
    model, spec = models.two_dof_damper()
    w = spec.omega_n * np.linspace(0.9, 1.1, 5)
    law = engine.contact_law(model, mu=spec.mu, omega_hz=spec.omega_n / (2 * np.pi))
    study = engine.frf(model, law, [engine.Variant("hbm", 7, 64)], freqs_hz=w / (2 * np.pi),
                       options=engine.FRFOptions(eps_check_factor=0.0, nh_check=False))
    bc = study.branch_check
    assert bc["within_tolerance"] is True and bc["max_rel_diff"] < 1e-9
    assert [p["role"] for p in bc["points"]] == ["headline grid peak", "last point of the sweep"]
    assert all(p["start"] == "tied" and "tied_m" not in p for p in bc["points"])


def test_branch_tolerance_is_stated_from_the_solver_tolerance():
    """The same root solved twice to ‖R‖/‖F‖ ≤ tol differs by about κ(J)·tol: the tolerance is
    the Nh-check's 1e-3 unless BRANCH_COND × tol is larger, and the summary states both."""
    assert epscheck.branch_tolerance(1e-8) == penalty.CHECK_TOL
    assert epscheck.branch_tolerance(1e-6) == pytest.approx(epscheck.BRANCH_COND * 1e-6)
    study = coulomb_study(0.2, 64, nh=7, tol=1e-6)
    bc = study.branch_check
    assert bc["solver_tol"] == 1e-6 and bc["tolerance"] == pytest.approx(0.1)
    assert bc["within_tolerance"] is True and "tied" in bc["start"] and "Nh = 1" in bc["start"]


def test_a_branch_check_that_cannot_run_is_never_true(monkeypatch):
    def lost(*a, **k):
        return {"amplitude": None, "converged": False, "iterations": 3, "how": "failed", "reason": "stalled"}

    monkeypatch.setattr(epscheck, "independent", lost)
    study = coulomb_study(0.2, 64, nh=3)
    bc = study.branch_check
    assert bc["within_tolerance"] is None and bc["max_rel_diff"] is None
    assert "could not be re-solved" in bc["reason"] and "stalled" in bc["reason"]
    assert bc["points"][0]["rel_diff"] is None and bc["points"][0]["start"] == "nh-continuation"
    (line,) = [w for w in study.warnings() if w.startswith("branch check")]        # could not run: a warning
    assert "unknown" in line and not [u for u in study.unconverged() if u.startswith("branch check")]
    # no point to check at all: None as well
    empty = epscheck.branch_runs(None, None, None, [], engine.FRFOptions())
    assert empty["within_tolerance"] is None and empty["reason"]


def test_headline_colours_of_the_branch_check():
    assert hl.branch_check({}).status == "none"
    ok = {"branch_check": {"within_tolerance": True, "max_rel_diff": 3e-9, "tolerance": 1e-3, "points": [{}, {}]}}
    c = hl.branch_check(ok)
    assert c.status == "green" and "2 points" in c.reason and "3.00e-09" in c.reason
    line = "branch check: HBM-15 nit=128 at 0.132629 Hz (grid peak): swept branch 2.207e+00 m, …"
    bad = {"branch_check": {"within_tolerance": False, "max_rel_diff": 0.16, "tolerance": 1e-3, "points": []},
           "unconverged": ["Nh-check: …", line]}
    c = hl.branch_check(bad)
    assert c.status == "red" and c.reason == line
    unknown = {"branch_check": {"within_tolerance": None, "reason": "1 of 1 points could not be re-solved"}}
    assert hl.branch_check(unknown).status == "amber"


def test_hb_stage_reports_the_spurious_branch_red(tmp_path: Path, monkeypatch):
    """Through the stage (scene key, summary.json's hb.branch_check, the headline) on the spurious
    case; the figures, which this test does not read, are not drawn."""
    from workflow.report import frf as frf_report
    from workflow.stages import hb as stage

    monkeypatch.setattr(frf_report, "_figures", lambda *a, **k: {})
    model, _ = models.coulomb(1.0, 1.0, 0.0, 1.0, 1.0, 0.5)
    src = tmp_path / "reduced"
    src.mkdir()
    model.save(src / "reduced.npz")
    lean = dict(methods=["hbm"], harmonics=[15], time_samples=[128], refine_peak=False, reference_check=False,
                nh_check=False)
    scene = {"contact": Contact(mu=0.5, eps_check=0.0), "hb": HB(**lean),
             "sweep": Sweep(f_start_hz=BETAS[0] / (2 * np.pi), f_stop_hz=BETAS[-1] / (2 * np.pi), points=len(BETAS)),
             "excitation": Excitation(), "pseudotime": PseudoTime()}
    assert stage.options(scene)[0].branch_check is True
    out = tmp_path / "out"
    out.mkdir()
    summary = stage.run(scene, {"reduced": src}, out, RunLog(file=out / "stage.log", quiet=True))
    bc = summary["branch_check"]
    assert bc["within_tolerance"] is False and bc["points"][0]["role"] == "headline grid peak"
    # a spurious root is not a result: unconverged (exit 3), red
    assert any(w.startswith("branch check: ") for w in summary["unconverged"])
    _, checks = hl.hb_headline(summary, out, None)
    (c,) = [c for c in checks if c.name == "branch check"]
    assert c.status == "red" and "swept branch" in c.reason and hl.worst(checks) == "red"
    assert "branch check: " in (out / "stage.log").read_text()
    # hb.branch_check = false reaches the engine's options
    scene["hb"] = HB(**lean, branch_check=False)
    assert stage.options(scene)[0].branch_check is False


def test_points_are_the_headline_peak_and_the_nh_checks_once_each():
    """With a reference: its refined peak, its grid peak (the Nh-check's point) and its last
    point; without: the headline's refined peak, every variant's grid peak and the headline's
    last point; a point already listed is not re-solved twice; no Nh-check and no refined peak:
    the headline's grid peak (and last point)."""
    from workflow.engine.studies import study as st

    def sweep(nh, amps):
        a = np.asarray(amps, float)
        return engine.SweepResult(variant=engine.Variant("hbm", nh, 64), solver="newton",
                                  freqs_hz=np.array([10.0, 11.0, 12.0]), amplitude=a, amplitude_max=a,
                                  iterations=np.zeros(3, int), seconds=np.zeros(3), converged=np.ones(3, bool))

    lo, hi, ref = sweep(3, [1.0, 3.0, 2.0]), sweep(5, [1.0, 2.0, 4.0]), sweep(9, [1.0, 5.0, 2.0])
    study = engine.FRFStudy(freqs_hz=lo.freqs_hz, band_hz=(10.0, 12.0), tied_hz=None, tied_mode=None, runs=[lo, hi],
                            reference=ref, tied=None, sliding=None, static=None, law=None, condense_seconds=0.0,
                            peak={"hz": 11.2, "amplitude_m": 5.5})
    pts = st._branch_points(study, engine.FRFOptions())
    assert [(p["label"], p["frequency_hz"], p["swept_m"], p["role"]) for p in pts] == [
        ("HBM-9 nit=64", 11.2, 5.5, "headline peak (refined)"), ("HBM-9 nit=64", 11.0, 5.0, "headline grid peak"),
        ("HBM-9 nit=64", 12.0, 2.0, "last point of the sweep")]
    study.reference = None
    study.peak = {"hz": 12.0, "amplitude_m": 4.0}           # the refined peak on a grid point: once
    pts = st._branch_points(study, engine.FRFOptions())
    assert [(p["label"], p["frequency_hz"]) for p in pts] == [("HBM-5 nit=64", 12.0), ("HBM-3 nit=64", 11.0)]
    study.peak = None
    pts = st._branch_points(study, engine.FRFOptions(nh_check=False))
    assert [(p["label"], p["frequency_hz"], p["role"]) for p in pts] == [("HBM-5 nit=64", 12.0, "headline grid peak")]
