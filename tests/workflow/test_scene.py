"""Scene loading: TOML errors, unknown sections/keys, types, ranges, overrides, paths."""
from __future__ import annotations

import json
import math

import pytest

from workflow.errors import SceneError
from workflow.scene import (field_rows, find_scene, load_scene, markdown_reference, parse_override, resolve,
                            sections, shipped_scenes)


def scene_file(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_defaults_fill_every_section(tmp_path):
    s = load_scene(scene_file(tmp_path, "[contact]\nmu = 0.3\n"))
    assert set(s) == set(sections())
    assert s["contact"].mu == 0.3
    assert s["hb"].harmonics == [3]
    assert s["geometry"].n_sectors == 47


def test_malformed_toml_names_file_and_line(tmp_path):
    p = scene_file(tmp_path, "[contact]\nmu = 0.3\nbad = = 1\n")
    with pytest.raises(SceneError) as e:
        load_scene(p)
    msg = str(e.value)
    assert f"{p}:3:" in msg and "malformed TOML" in msg and "\n" not in msg


def test_unknown_section_named(tmp_path):
    with pytest.raises(SceneError, match=r"unknown sections? \[contactt\]"):
        load_scene(scene_file(tmp_path, "[contactt]\nmu = 0.3\n"))


def test_top_level_key_rejected(tmp_path):
    with pytest.raises(SceneError, match="'mu' must be inside a"):
        load_scene(scene_file(tmp_path, "mu = 0.3\n"))


def test_unknown_key_named(tmp_path):
    with pytest.raises(SceneError, match=r"unknown key contact\.muu \(did you mean contact\.mu\?\)"):
        load_scene(scene_file(tmp_path, "[contact]\nmuu = 0.3\n"))


def test_unknown_geometry_key_named(tmp_path):
    with pytest.raises(SceneError, match=r"geometry\.spann"):
        load_scene(scene_file(tmp_path, "[geometry]\nspann = 0.1\n"))


@pytest.mark.parametrize("text, match", [
    ('[contact]\nmu = "high"\n', r"contact\.mu must be a number"),
    ("[hb]\nmax_iterations = 2.5\n", r"hb\.max_iterations must be an integer"),
    ("[contact]\nmu = nan\n", r"contact\.mu must be finite"),
    ("[contact]\nmu = -0.1\n", r"contact\.mu = -0\.1 must be ≥ 0"),
    ("[material]\nyoung = 0.0\n", r"material\.young = 0\.0 must be ≥ 1000\.0"),
    ('[hb]\nmethods = ["hbm", "magic"]\n', r"hb\.methods contains 'magic'"),
    ('[run]\noutputs = ["everything"]\n', r"run\.outputs contains 'everything'"),
    ("[geometry]\nspan = inf\n", r"geometry\.span must be finite"),
    ('[geometry]\nn_sectors = "47"\n', r"geometry\.n_sectors must be an integer"),
])
def test_wrong_values_one_line(tmp_path, text, match):
    with pytest.raises(SceneError, match=match) as e:
        load_scene(scene_file(tmp_path, text))
    assert "\n" not in str(e.value)


def test_int_accepted_for_float_and_canonical_form(tmp_path):
    a = load_scene(scene_file(tmp_path, "[contact]\nmu = 1\n", "a.toml"))
    b = load_scene(scene_file(tmp_path, "[hb]\nharmonics = [3]\n[contact]\nmu = 1.0\n", "b.toml"))
    assert a.canonical() == b.canonical()
    assert json.loads(a.canonical(["contact"]))["contact"]["mu"] == 1.0


@pytest.mark.parametrize("text, expected", [
    ("contact.mu=0.3", ("contact", "mu", 0.3)),
    ("hb.harmonics=[1,3]", ("hb", "harmonics", [1, 3])),
    ("hb.solver=powell", ("hb", "solver", "powell")),
    ('hb.solver="powell"', ("hb", "solver", "powell")),
    ("rotation.stress_stiffening=false", ("rotation", "stress_stiffening", False)),
    ("model.bundle=some/dir", ("model", "bundle", "some/dir")),
    ("hb.harmonics=[3,\n5]", ("hb", "harmonics", [3, 5])),        # a TOML array may span lines
])
def test_parse_override(text, expected):
    assert parse_override(text) == expected


@pytest.mark.parametrize("bad", ["contact", "contact.mu", "mu=0.3", "a.b.c=1", ".mu=1"])
def test_malformed_override(bad):
    with pytest.raises(SceneError, match="section.key=value"):
        parse_override(bad)


@pytest.mark.parametrize("bad", ["contact.mu=0.3\n[hb]\ntol=5", "contact.mu=0.3\nw = 1"])
def test_an_override_carrying_more_toml_is_refused(bad):
    """The rest of the value after a line break was parsed and dropped without a word."""
    with pytest.raises(SceneError, match="more than one TOML value"):
        parse_override(bad)


def test_overrides_applied_and_checked(tmp_path):
    p = scene_file(tmp_path, "[contact]\nmu = 0.5\n")
    s = load_scene(p, ["contact.mu=0.3", "hb.harmonics=[1,3]", "hb.solver=powell"])
    assert (s["contact"].mu, s["hb"].harmonics, s["hb"].solver) == (0.3, [1, 3], "powell")
    assert s.overrides == ["contact.mu=0.3", "hb.harmonics=[1,3]", "hb.solver=powell"]
    with pytest.raises(SceneError, match=r"contact\.mu must be finite"):
        load_scene(p, ["contact.mu=nan"])
    with pytest.raises(SceneError, match=r"unknown section \[contac\]"):
        load_scene(p, ["contac.mu=0.3"])
    with pytest.raises(SceneError, match=r"unknown key contact\.nu"):
        load_scene(p, ["contact.nu=0.3"])


def test_cross_key_check(tmp_path):
    with pytest.raises(SceneError, match=r"hb\.time_samples = 4 < 2·Nh\+1"):
        load_scene(scene_file(tmp_path, "[hb]\nharmonics = [3]\ntime_samples = [4]\n"))


def test_relative_bundle_path_against_scene_folder(tmp_path, monkeypatch):
    sub = tmp_path / "scenes"
    sub.mkdir()
    p = scene_file(sub, '[model]\nbundle = "../bundles/b1"\n')
    monkeypatch.chdir(tmp_path / "scenes")
    assert load_scene(p)["model"].bundle == str((tmp_path / "bundles" / "b1").resolve())
    monkeypatch.chdir(tmp_path)
    # From --set: relative to the current folder.
    assert load_scene(p, ["model.bundle=mine"])["model"].bundle == str((tmp_path / "mine").resolve())


def test_shipped_scenes_resolve():
    names = dict(shipped_scenes())
    assert {"quick", "sector-modes"} <= set(names)
    for name in names:
        if name in ("quick", "sector-modes"):
            s = load_scene(name)
            assert s.path == find_scene(name)
    assert load_scene("sector-modes")["run"].outputs == ["modes"]


def test_unknown_scene_name():
    with pytest.raises(SceneError, match="no-such-scene not found.*quick"):
        find_scene("no-such-scene")
    for empty in ("", "  "):        # was "scene . is not a file": the current folder
        with pytest.raises(SceneError, match="no scene given.*quick"):
            find_scene(empty)


def test_resolve_without_file():
    s = resolve({"contact": {"mu": 0.2}})
    assert s.path is None and s["contact"].mu == 0.2 and s.title == "scene"


def test_reference_documents_every_key():
    doc = markdown_reference()
    for name, cls in sections().items():
        assert f"## {name}" in doc
        for row in field_rows(cls):
            assert f"`{row['key']}`" in doc
    # Plain SectorParams fields get their unit from the docstring.
    rows = {r["key"]: r for r in field_rows(sections()["geometry"])}
    assert rows["span"]["unit"] == "m" and rows["flank_angle"]["unit"] == "rad" and rows["span"]["doc"]
    assert not math.isnan(rows["span"]["default"])
