"""Mesh size is estimated before meshing (issue 18, item 9): a warning past
WARN_ELEMENTS, a refusal naming the keys past MAX_ELEMENTS."""
from __future__ import annotations

import io

import pytest

from geometry.params import MAX_ELEMENTS, estimate_elements
from workflow.errors import GeometryError, SceneError
from workflow.runlog import RunLog
from workflow.scene import load_scene


def test_estimate_scales_with_span_and_size():
    base = estimate_elements(load_scene("quick")["geometry"])
    long = estimate_elements(load_scene("quick", ["geometry.span=1.2"])["geometry"])
    assert long["h_airfoil"] == pytest.approx(10 * base["h_airfoil"], rel=1e-12)   # volume ∝ span
    assert long["h_disk"] == base["h_disk"]
    fine = estimate_elements(load_scene("quick", ["geometry.h_disk=0.005"])["geometry"])
    assert fine["h_disk"] == pytest.approx(8 * base["h_disk"], rel=1e-12)          # ∝ h⁻³


def test_geometry_stage_warns_before_meshing(tmp_path, monkeypatch):
    import geometry.sector
    from workflow.stages import geometry as stage

    meshed = []
    monkeypatch.setattr(geometry.sector, "build_sector", lambda p, path: meshed.append(p) or {"n_elements": 1})
    buf = io.StringIO()
    scene = load_scene("quick", ["geometry.span=40"])
    est = sum(estimate_elements(scene["geometry"]).values())
    assert stage.WARN_ELEMENTS < est < MAX_ELEMENTS
    summary = stage.run(scene, {}, tmp_path, RunLog(stream=buf))
    text = buf.getvalue()
    assert "warning: a large mesh" in text and "geometry.h_airfoil" in text and "GB" in text
    assert summary["estimated_elements"] == round(est) and meshed
    buf = io.StringIO()
    stage.run(load_scene("quick"), {}, tmp_path, RunLog(stream=buf))
    assert "meshing ~" in buf.getvalue() and "warning" not in buf.getvalue()


def test_too_big_is_refused_when_the_scene_is_read():
    with pytest.raises((SceneError, GeometryError), match=r"h_airfoil.*elements.*reduce span"):
        load_scene("quick", ["geometry.span=1000"])
