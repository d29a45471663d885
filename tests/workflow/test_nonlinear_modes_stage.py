"""The nonlinear-modes stage on a Jenkins oscillator (workflow/stages/nonlinear_modes.py): the
backbone from the tied mode into slip, the synthesis against the direct HB FRF, the checks."""
from __future__ import annotations

import json

import numpy as np
import pytest

from workflow.verification import modes_runner as J


def _scene(**nm):
    from workflow import params

    scene = {k: getattr(params, c)() for k, c in (("contact", "Contact"), ("excitation", "Excitation"),
                                                    ("nonlinear_modes", "NonlinearModes"))}
    scene["contact"].mu = J.MU
    scene["excitation"].amplitude = 1.0
    for k, v in nm.items():
        setattr(scene["nonlinear_modes"], k, v)
    scene["nonlinear_modes"].check()
    return scene


def test_stage_backbone_synthesis_and_checks(tmp_path):
    from workflow.stages import nonlinear_modes as stage
    from workflow.verification import models
    from workflow.verification.timeint import Pads

    pads = Pads(dof=np.array([0]), k=np.array([J.KT]), mu=J.MU, N0=np.array([J.N]), cN=np.zeros((1, 1)))
    # a unit load, scaled by the stage to each synthesis force (excitation.amplitude = 1 N)
    model, _ = models.jenkins([[J.M]], [[J.C]], [[J.K]], [1.0], 0, pads, "jenkins-1")
    model.save(tmp_path / "reduced.npz")

    class Log:
        def info(self, msg):
            pass

    # 2e-5 N: the tied peak F/(cω) = 5.8e-3 m, far below the slip onset μN/k_t = 0.15 m (linear);
    # 2e-4 N: 5.8e-2 m, still stuck — the synthesis of a linear mode is its exact FRF
    s = stage.run(_scene(harmonics=5, time_samples=64, amplitude_range=[0.01, 30.0], points=15,
                         synthesis_forces=[2e-5, 2e-4]), {"reduced": tmp_path}, tmp_path / "nm", Log())
    json.dumps(s)
    w_t, w_s = np.sqrt((J.K + J.KT) / J.M), np.sqrt(J.K / J.M)
    bb = s["backbone"]
    assert s["tied_hz"] == pytest.approx(w_t / (2 * np.pi), rel=1e-9)
    assert bb[0]["frequency_hz"] == pytest.approx(w_t / (2 * np.pi), rel=1e-8)
    # into slip the frequency falls towards the sliding one and friction adds damping
    assert w_s / (2 * np.pi) < bb[-1]["frequency_hz"] < bb[0]["frequency_hz"]
    assert bb[-1]["damping_ratio"] > 5 * bb[0]["damping_ratio"] and not s["stopped"]
    # linear regime: the peak by the refined direct FRF (xtol 1e-6 of f) and by the synthesis
    for lv in s["synthesis"]:
        assert lv["frequency_error"] < 1e-5 and lv["amplitude_error"] < 1e-4, lv
    c = s["checks"]
    assert c["jenkins_frequency_error"] < 1e-3 and c["jenkins_damping_error"] < 5e-3   # test_nlmodes' bounds
    assert c["floquet_vs_shooting"] < 1e-3          # test_stability's bound (switches located between samples)
    for f in ("backbone.csv", "synthesis.csv", "backbone.png", "synthesis.png"):
        assert (tmp_path / "nm" / f).stat().st_size > 100
