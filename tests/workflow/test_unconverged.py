"""Unconverged results: listed per stage, exit status 3 (issue 18, item 6).

The README's contract: a run that finishes with results that did not
converge exits 3 and says which (summary.json "unconverged", log, report).
The end-to-end case is the issue's: μ = 0 on the quick scene, where the
wear march has no worn steady state (HB missed 2 of 15 frequencies there
until the continuation in Nh ran the whole cascade at each level; it now
converges at all 15, and an unconverged HB line is checked in
test_cache_integrity and by :func:`test_hb_lines_name_variant_and_frequencies`).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from workflow.stages import remap


def test_hb_lines_name_variant_and_frequencies():
    from workflow.engine import FRFStudy

    r = SimpleNamespace(variant=SimpleNamespace(label="HBM-3 nit=64"), solver="newton",
                        freqs_hz=np.array([190.0, 200.0, 210.0]), converged=np.array([True, False, True]),
                        reasons=["converged", "stalled", "converged"])

    def lines(runs, ref):
        return FRFStudy(freqs_hz=r.freqs_hz, band_hz=(190.0, 210.0), tied_hz=None, tied_mode=None, runs=runs,
                        reference=ref, tied=None, sliding=None, static=None, law=None,
                        condense_seconds=0.0).unconverged()

    line, = lines([r], None)
    assert "HBM-3 nit=64" in line and "1/3" in line and "200.00" in line and "hb.max_iterations" in line
    assert lines([], r)[0].startswith("reference ")
    r.converged[:] = True
    assert lines([r], None) == []


def test_remap_lines():
    assert remap._unconverged({"frf_error": "no equilibrium"}) == ["new-vs-worn FRF not computed: no equilibrium"]
    s = {"frf_points": 9, "frf_converged": {"new": 9, "worn": 7}}
    assert remap._unconverged(s) == ["new-vs-worn FRF, worn model: 2/9 frequencies did not converge"]
    assert remap._unconverged({"frf_points": 9, "frf_converged": {"new": 9, "worn": 9}}) == []


@pytest.mark.slow
def test_frictionless_quick_scene_exits_3(tmp_path):
    env = dict(os.environ, OMP_NUM_THREADS="1", PYVISTA_OFF_SCREEN="true")
    env.pop("BLADEWEAR_CACHE", None)
    r = subprocess.run([str(Path(sys.executable).parent / "bladewear"), "run", "quick", "--out", str(tmp_path / "o"),
                        "--cache", str(tmp_path / "c"), "--quiet", "--set", "contact.mu=0",
                        "--set", 'run.outputs=["frf","wear"]'], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 3, r.stderr
    assert "Traceback" not in r.stderr and "exit status 3" in r.stderr
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    # μ = 0 inside the tied mode's band: the truncated balance has several roots there (the
    # sliding resonance is far below), and the checks that can see a wrong branch say so —
    # the branch check (independent start) and the time check (not a periodic orbit)
    assert set(s["unconverged"]) == {"hb", "wear"}
    assert {line.split(":")[0] for line in s["unconverged"]["hb"]} <= {"branch check", "time check"}
    # μ = 0: the pairs slide freely, and the wear accelerates as it moves the contact pressure
    # (max W as t^1.7 over the last decade at the scene's 200 steps: not a settled pace, so not
    # persistent slip); the line says the steps ran out while it grew, and what to raise.
    # (Marched on, 1548 steps, it ends with every rate 0 at 5.5 mm.)
    line = s["unconverged"]["wear"][0]
    assert "NOT steady" in line and "max steps (200)" in line and "persistent slip" not in line
    assert "as fast in its later half" in line and "raise pseudotime.max_steps" in line
    # what the lines say agrees with the stage's own numbers
    run = s["hb"]["runs"][0]
    assert run["converged_points"] == run["points"] == 15
    assert not s["wear"]["methods"]["pseudo-time"]["steady"]


def test_wear_frequency_far_from_the_model_is_refused():
    """wear.frequency_hz = 1e9 used to be accepted without a word (issue 18, item 5)."""
    from workflow.engine.studies import extreme as X
    from workflow.errors import SceneError
    from workflow.engine.studies.wearstudy import build_problem as engine_build
    from workflow.scene import load_scene
    from workflow.stages.hb import law_of
    from workflow.stages.wear import options

    def build_problem(model, scene):
        return engine_build(model, law_of(scene, model), options(scene))

    model = X.synthetic_model(2)
    with pytest.raises(SceneError, match=r"wear\.frequency_hz = 1e\+09 Hz is outside"):
        build_problem(model, load_scene("quick", ["wear.frequency_hz=1e9"]))
    _, _, omega = build_problem(model, load_scene("quick"))
    f = omega / 2 / np.pi
    _, _, omega2 = build_problem(model, load_scene("quick", [f"wear.frequency_hz={1.05 * f}"]))
    assert omega2 == pytest.approx(2 * np.pi * 1.05 * f)

