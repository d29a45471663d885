"""Bad input through the command line: one line naming the problem, exit status ≠ 0,
nothing previously written damaged.

Complements tests/workflow/test_cli.py (malformed TOML, unknown key, wrong
type, NaN/negative friction, unwritable folder, disk full at fsync and at
summary.json) and test_pipeline.py (empty bundle folder): here the other
physical parameters, HDHB sampling, impossible geometry, gmsh failures,
inconsistent bundles and a disk filling up while a *stage* writes.
"""
from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import numpy as np
import pytest

from fakestages import fakes, run  # noqa: F401 (fakes is a fixture)
from workflow import io as wio




def previous_run(tmp_path, capsys):
    """A successful earlier run in tmp_path/out (fake stages); returns its summary text."""
    p = tmp_path / "ok.toml"
    p.write_text("[run]\noutputs = ['modes']\n")
    rc, _, err = run(capsys, "run", p, "--out", tmp_path / "out", "--cache", tmp_path / "cache", "--quiet")
    assert rc == 0, err
    return (tmp_path / "out" / "summary.json").read_text()


def one_line_error(rc, err, *needles):
    assert rc != 0
    assert err.startswith("error: ") and err.count("\n") == 1, err
    for n in needles:
        assert n in err, (n, err)


@pytest.mark.parametrize("text, needles", [
    ("[material]\ndensity = -4430.0\n", ["material.density", "must be ≥ 1.0"]),
    ("[material]\ndensity = nan\n", ["material.density"]),
    ("[material]\nyoung = inf\n", ["material.young", "finite"]),
    ("[sweep]\nf_start_hz = -100.0\n", ["sweep.f_start_hz", "≥ 0"]),
    ("[wear]\nfrequency_hz = nan\n", ["wear.frequency_hz"]),
    ("[sweep]\nf_start_hz = 200.0\nf_stop_hz = 100.0\n", ["sweep.f_stop_hz", "must exceed"]),
    ("[geometry]\nh_blade = -0.004\n", ["h_blade", "> 0"]),
    ("[geometry]\nh_disk = nan\n", ["h_disk"]),
    ("[geometry]\nh_airfoil = 1e-6\n", ["h_airfoil", "elements"]),
    ("[hb]\nmethods = ['hdhb']\nharmonics = [5]\ntime_samples = [7]\n", ["hb.time_samples = 7", "2Nh+1 = 11"]),
    ("[hb]\nharmonics = [5]\ntime_samples = [8]\n", ["hb.time_samples = 8 < 2·Nh+1 = 11"]),
    ("[extreme]\nharmonics = 8\nmax_time_samples = 9\n", ["extreme.max_time_samples = 9"]),
    ("[extreme]\ncases = ['everything']\n", ["extreme.cases contains 'everything'"]),
    ("[contact]\neps_n = -1.0\n", ["contact.eps_n = -1.0 must be ≥ 0"]),
    ("[excitation]\namplitude = nan\n", ["excitation.amplitude"]),
    ("[geometry]\nflank_angle = 1.5\n", ["flank_angle", "between 10° and 80°"]),
    ("[geometry]\nlobe_width = 0.006\n", ["lobe_width", "must exceed neck_width"]),
    ("[geometry]\nn_sectors = 400\n", ["lobe_width", "wider than the sector"]),
    ("[geometry]\nplatform_width = 0.2\n", ["platform_width", "wider than the sector"]),
    ("[geometry]\nclearance = 0.005\n", ["clearance", "must be < neck_width/2"]),
    ("[geometry]\nflank_length = 0.05\n", ["flank_length", "longer than the inclined face"]),
    # an unquoted date is TOML's date, not text: said as written, never as datetime.date(…)
    ("[model]\nbundle = 2026-01-01\n", ["model.bundle must be a string, got the TOML date/time 2026-01-01",
                                        'quote it: "2026-01-01"']),
    ("[sweep]\npoints = 12:30:00\n", ["sweep.points must be an integer, got the TOML date/time 12:30:00"]),
    ("[rotation]\nspeed_rpm = 3000.0\nstress_stiffening = false\n",
     ["rotation.spin_softening = true with rotation.stress_stiffening = false", "set both"]),
])
def test_bad_values_one_line_previous_run_intact(tmp_path, capsys, fakes, text, needles):
    before = previous_run(tmp_path, capsys)
    listing = sorted(os.listdir(tmp_path / "out"))
    p = tmp_path / "bad.toml"
    p.write_text("[run]\noutputs = ['modes']\n" + text)
    for cmd in ("run", "show"):
        rc, _, err = run(capsys, cmd, p, "--out", tmp_path / "out", "--cache", tmp_path / "cache")
        one_line_error(rc, err, *needles)
    assert (tmp_path / "out" / "summary.json").read_text() == before
    assert sorted(os.listdir(tmp_path / "out")) == listing
    assert fakes.ran() == ["geometry", "assembly", "modes"]      # only the first, good run


def test_gmsh_failure_one_line(tmp_path, capsys, fakes, monkeypatch):
    """A gmsh error inside meshing (the real geometry stage) → 'gmsh failed: …', previous run intact."""
    import gmsh

    from workflow import stages

    before = previous_run(tmp_path, capsys)
    monkeypatch.setitem(stages.MODULES, "geometry", "workflow.stages.geometry")

    def broken(*a, **k):
        raise Exception("Invalid boundary mesh (overlapping facets) on surface 7")

    monkeypatch.setattr(gmsh.model.mesh, "generate", broken)
    p = tmp_path / "mesh.toml"
    p.write_text("[run]\noutputs = ['modes']\n[geometry]\nh_blade = 0.008\nh_disk = 0.012\nh_airfoil = 0.012\n")
    rc, _, err = run(capsys, "run", p, "--out", tmp_path / "out", "--cache", tmp_path / "cache", "--quiet")
    one_line_error(rc, err, "gmsh failed", "overlapping facets")
    assert (tmp_path / "out" / "summary.json").read_text() == before
    assert not list((tmp_path / "cache" / "geometry").glob("*.tmp")) if (tmp_path / "cache" / "geometry").exists() else True


def tiny_bundle(path: Path, *, n=6, k_size=None, drop=None):
    import scipy.sparse as sp

    from reduction.bundle import Bundle, Contact, Loads, write_bundle

    eye = sp.identity(n, format="csr")
    K = sp.identity(k_size or n, format="csr")
    contact = Contact(blade_dofs=np.array([[0, 1, 2]]), disk_dofs=np.array([[3, 4, 5]]),
                      normal=np.array([[0.0, 0.0, 1.0]]), t1=np.array([[1.0, 0.0, 0.0]]),
                      t2=np.array([[0.0, 1.0, 0.0]]), area=np.array([1e-6]), gap=np.array([0.0]))
    loads = Loads(fixed=np.array([3, 4, 5]), static=np.zeros(n), harmonic=np.zeros(n), observe=np.array([2]))
    try:
        write_bundle(Bundle(M=eye, K=K, C=0 * eye, contact=contact, loads=loads), path)
    except Exception:
        # the writer validates: write a good one and break it on disk, as a user's tool might
        write_bundle(Bundle(M=eye, K=eye, C=0 * eye, contact=contact, loads=loads), path)
        sp.save_npz(path / "K.npz", K)
    if drop:
        (path / drop).unlink()
    return path


@pytest.mark.parametrize("kind, needles", [
    ("mismatched", ["bundle matrix K is 9x9, expected 6x6"]),
    ("missing", ["lacks loads.npz"]),
    ("truncated", ["cannot be read"]),
])
def test_bad_bundle_one_line(tmp_path, capsys, fakes, kind, needles):
    before = previous_run(tmp_path, capsys)
    b = tmp_path / "bundle"
    if kind == "mismatched":
        tiny_bundle(b, k_size=9)
    elif kind == "missing":
        tiny_bundle(b, drop="loads.npz")
    else:
        tiny_bundle(b)
        (b / "M.npz").write_bytes((b / "M.npz").read_bytes()[:40])
    p = tmp_path / "bundle.toml"
    p.write_text("[run]\noutputs = ['modes']\n[model]\nbundle = 'bundle'\n")
    rc, _, err = run(capsys, "run", p, "--out", tmp_path / "out", "--cache", tmp_path / "cache", "--quiet")
    one_line_error(rc, err, *needles)
    assert (tmp_path / "out" / "summary.json").read_text() == before


def test_disk_full_inside_stage_write(tmp_path, capsys, fakes, monkeypatch):
    """ENOSPC raised by a stage's own write (workflow.io.write_text), not the pipeline's."""
    from workflow import stages

    before = previous_run(tmp_path, capsys)
    # the real extreme stage on a synthetic reduced model, fed through a fake 'reduction'
    from workflow.engine.studies import extreme as X

    red = tmp_path / "red"
    red.mkdir()
    X.synthetic_model(2).save(red / "reduced.npz")
    pkg = tmp_path / "fakes" / fakes.pkg
    (pkg / "reduction.py").write_text(
        "import shutil\nNAME='reduction'\nSECTIONS=('reduction',)\nNEEDS=('bundle',)\nPRODUCES=('reduced',)\n"
        f"def run(scene, inputs, out, log):\n    shutil.copy({str(red / 'reduced.npz')!r}, out / 'reduced.npz')\n"
        "    return {}\n")
    monkeypatch.setitem(stages.MODULES, "extreme", "workflow.stages.extreme")
    real = wio.os.replace

    def replace(src, dst):
        if str(dst).endswith("extreme.csv"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(src, dst)

    monkeypatch.setattr(wio.os, "replace", replace)
    p = tmp_path / "x.toml"
    p.write_text("[run]\noutputs = ['extreme']\n[extreme]\ncases = ['friction']\nmethods = ['hbm']\n"
                 "solvers = ['newton']\n")
    rc, _, err = run(capsys, "run", p, "--out", tmp_path / "out", "--cache", tmp_path / "cache", "--quiet")
    one_line_error(rc, err, "cannot write", "extreme.csv", "No space left on device")
    assert (tmp_path / "out" / "summary.json").read_text() == before
    assert not list((tmp_path / "cache").glob("extreme/*/extreme.csv"))
    monkeypatch.setattr(wio.os, "replace", real)
    rc, _, err = run(capsys, "run", p, "--out", tmp_path / "out", "--cache", tmp_path / "cache", "--quiet")
    assert rc == 0, err
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["stages"]["extreme"] == "computed"
    assert {r["name"] for r in s["extreme"]["cases"]} == {"mu-0", "mu-1e-4", "mu-0.5", "mu-1e4"}


def test_truncated_reduced_model_is_bundle_error(tmp_path):
    from workflow.engine.model import ReducedModel
    from workflow.engine.studies import extreme as X
    from workflow.errors import BundleError

    X.synthetic_model(2).save(tmp_path / "reduced.npz")
    data = (tmp_path / "reduced.npz").read_bytes()
    (tmp_path / "reduced.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(BundleError, match="cannot be read"):
        ReducedModel.load(tmp_path / "reduced.npz")


def test_unreadable_scene_file(tmp_path, capsys):
    p = tmp_path / "scene.toml"
    p.write_bytes(b"[run]\ntitle = '\xff\xfe'\n")
    rc, _, err = run(capsys, "show", p)
    one_line_error(rc, err, "not UTF-8")


def test_scene_is_a_folder(tmp_path, capsys):
    (tmp_path / "d").mkdir()
    rc, _, err = run(capsys, "show", tmp_path / "d")
    one_line_error(rc, err, "is not a file")
