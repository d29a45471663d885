"""Pipeline: plan closure, lazy imports, content-addressed cache, crash safety.

The stages are fakes (tests/workflow/fakestages.py) with the real stages'
dependency shape, so these tests need no FE code.
"""
from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import fakestages
from workflow import io as wio
from workflow.errors import OutputError, SceneError
from workflow.pipeline import clean_stale, plan, run_scene
from workflow.runlog import RunLog
from workflow.scene import load_scene


@pytest.fixture
def fakes(tmp_path, monkeypatch):
    return fakestages.install(tmp_path, monkeypatch)


def scene(tmp_path, outputs, extra="", overrides=()):
    p = tmp_path / "scene.toml"
    p.write_text(f"[run]\noutputs = {json.dumps(outputs)}\ntitle = 'test'\n{extra}")
    return load_scene(p, overrides)


def go(tmp_path, sc, **kw):
    kw.setdefault("quiet", True)
    return run_scene(sc, tmp_path / "out", cache=tmp_path / "cache", **kw)


def test_reduction_check_runs_only_its_closure(tmp_path, fakes):
    sc = scene(tmp_path, ["reduction_check"])
    assert plan(sc).stages == ["geometry", "assembly", "reduction", "reduction_check"]
    s = go(tmp_path, sc)
    assert fakes.ran() == ["geometry", "assembly", "reduction", "reduction_check"]
    assert list(s["stages"]) == ["geometry", "assembly", "reduction", "reduction_check"]
    assert set(s["stages"].values()) == {"computed"}
    # The harmonic-balance stage module was never imported.
    assert "hb" not in fakestages.loaded(fakes.pkg) and "wear" not in fakestages.loaded(fakes.pkg)
    assert f"{fakes.pkg}.hb" not in sys.modules


def test_outputs_readable_in_run_folder(tmp_path, fakes):
    s = go(tmp_path, scene(tmp_path, ["modes"]))
    out = tmp_path / "out"
    assert (out / "modes" / "data.txt").read_text().startswith("modes")
    assert (out / "geometry" / "figure.png").is_file()
    on_disk = json.loads((out / "summary.json").read_text())
    assert on_disk["geometry"]["contact_pairs"] == 8
    assert on_disk["stages"] == s["stages"] and set(on_disk["timings"]) == set(s["stages"])
    assert on_disk["scene"] == str(tmp_path / "scene.toml")
    assert json.loads((out / "scene.json").read_text())["run"]["outputs"] == ["modes"]
    assert "modes: computing" in (out / "run.log").read_text()
    # Only what the run needs: no partial files, no temporaries.
    assert not list(out.glob(".*")) and not list((tmp_path / "cache").glob("*/.*.tmp"))


def test_second_run_all_cached_then_one_change_reruns_downstream(tmp_path, fakes):
    go(tmp_path, scene(tmp_path, ["reduction_check", "frf"]))
    fakes.ran()
    s = go(tmp_path, scene(tmp_path, ["reduction_check", "frf"]))
    assert fakes.ran() == [] and set(s["stages"].values()) == {"cached"}

    # contact.mu is read by hb only.
    s = go(tmp_path, scene(tmp_path, ["reduction_check", "frf"], overrides=["contact.mu=0.3"]))
    assert fakes.ran() == ["hb"]
    assert s["stages"] == {"geometry": "cached", "assembly": "cached", "reduction": "cached",
                           "reduction_check": "cached", "hb": "computed"}
    # reduction.modes: reduction and everything downstream of it.
    s = go(tmp_path, scene(tmp_path, ["reduction_check", "frf"], overrides=["reduction.modes=12"]))
    assert sorted(fakes.ran()) == ["hb", "reduction", "reduction_check"]
    # A geometry change reaches everything.
    go(tmp_path, scene(tmp_path, ["reduction_check", "frf"], extra="[geometry]\nh_disk = 0.008\n"))
    assert len(fakes.ran()) == 5
    # Going back to an earlier scene finds its entries again.
    s = go(tmp_path, scene(tmp_path, ["reduction_check", "frf"]))
    assert fakes.ran() == [] and set(s["stages"].values()) == {"cached"}


def test_fresh_recomputes_all(tmp_path, fakes):
    go(tmp_path, scene(tmp_path, ["modes"]))
    fakes.ran()
    s = go(tmp_path, scene(tmp_path, ["modes"]), fresh=True)
    assert fakes.ran() == ["geometry", "assembly", "modes"] and set(s["stages"].values()) == {"computed"}


def test_report_runs_last_with_figures_and_tables(tmp_path, fakes):
    s = go(tmp_path, scene(tmp_path, ["report", "modes"]))
    assert list(s["stages"]) == ["geometry", "assembly", "modes", "report"]
    rep = tmp_path / "out" / "report"
    md = (rep / "report.md").read_text()
    assert "| geometry | computed |" in md and "![figure.png](figures/modes/figure.png)" in md
    assert "first 12 of 30 rows" in md
    assert (rep / "figures" / "modes" / "figure.png").is_file()
    assert "<img src='figures/mesh/figure.png'" in (rep / "report.html").read_text()
    assert s["report"]["figures"] == 3
    # summary.json carries the headline even when the run has no FRF or wear (values null, said so).
    h = s["report"]["headline"]
    assert h["peak_hz"] is None and h["max_wear_m"] is None and h["status"] in ("none", "green")
    # The report is rewritten each run (it shows this run's timings), the rest is cached.
    s = go(tmp_path, scene(tmp_path, ["report", "modes"]))
    assert s["stages"]["report"] == "computed" and s["stages"]["modes"] == "cached"
    assert "| modes | cached |" in (rep / "report.md").read_text()


def test_unknown_stage_module_is_scene_error(tmp_path, fakes, monkeypatch):
    from workflow import stages

    monkeypatch.setitem(stages.MODULES, "extreme", "no_such_package_xyz.extreme")
    with pytest.raises(SceneError, match="stage 'extreme' is not available"):
        plan(scene(tmp_path, ["extreme"]))


def test_interrupt_inside_stage_leaves_no_partial_entry(tmp_path, fakes, monkeypatch):
    sc = scene(tmp_path, ["modes"])
    monkeypatch.setenv("FAKE_CRASH", "assembly:interrupt")
    with pytest.raises(KeyboardInterrupt):
        go(tmp_path, sc)
    cache = tmp_path / "cache"
    assert [p.name for p in (cache / "geometry").iterdir()] != []           # geometry done, kept
    assert not (cache / "assembly").exists() or all(p.name.endswith(".progress")    # only what it finished
                                                      for p in (cache / "assembly").iterdir())
    assert not (tmp_path / "out" / "summary.json").exists()
    monkeypatch.delenv("FAKE_CRASH")
    fakes.ran()
    s = go(tmp_path, sc)
    assert fakes.ran() == ["assembly", "modes"] and s["stages"]["geometry"] == "cached"


def test_an_interrupted_stage_keeps_its_finished_pieces_for_the_next_run(tmp_path, fakes, monkeypatch, capsys):
    """What a stage finished before an interruption (a Monte Carlo's patterns) is in its progress
    folder, beside its entry and named by its key; the next run finds it, and the folder goes once
    the entry is written. A damaged piece is not used."""
    sc = scene(tmp_path, ["modes"])
    monkeypatch.setenv("FAKE_CRASH", "assembly:interrupt")
    with pytest.raises(KeyboardInterrupt):
        go(tmp_path, sc)
    kept = list((tmp_path / "cache" / "assembly").glob("*.progress/first-half.json"))
    assert len(kept) == 1
    from workflow.cli import main

    main(["show", str(tmp_path / "scene.toml"), "--cache", str(tmp_path / "cache"), "--out", str(tmp_path / "out")])
    shown = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("#   assembly")]
    assert shown and "(1 finished piece kept from an interrupted run)" in shown[0]
    monkeypatch.delenv("FAKE_CRASH")
    s = go(tmp_path, sc)
    key = kept[0].parent.name.removesuffix(".progress")
    assert (tmp_path / "cache" / "assembly" / key / ".stage.json").is_file()        # the same computation's key
    assert (tmp_path / "fakes" / "assembly.resumed").exists() and s["stages"]["modes"] == "computed"
    assert not kept[0].parent.exists()                                               # gone with the entry written
    assert not (tmp_path / "fakes" / "modes.resumed").exists()                       # never interrupted

    # a damaged piece (its data edited, its checksum not) is computed again
    monkeypatch.setenv("FAKE_CRASH", "modes:interrupt")
    sc2 = scene(tmp_path, ["modes"], extra="[modes]\ncount = 7\n")
    with pytest.raises(KeyboardInterrupt):
        go(tmp_path, sc2)
    piece = next((tmp_path / "cache" / "modes").glob("*.progress/first-half.json"))
    piece.write_text(piece.read_text().replace('"stage": "modes"', '"stage": "mode5"'))
    monkeypatch.delenv("FAKE_CRASH")
    go(tmp_path, sc2)
    assert not (tmp_path / "fakes" / "modes.resumed").exists()


def test_killed_process_leaves_previous_entry_and_next_run_recovers(tmp_path, fakes):
    """os._exit inside a stage (like SIGKILL): no clean-up code runs at all."""
    sc = tmp_path / "scene.toml"
    sc.write_text("[run]\noutputs = ['modes']\n")
    driver = tmp_path / "driver.py"
    driver.write_text(fakes.driver())
    args = [sys.executable, str(driver), "run", str(sc), "--out", str(tmp_path / "out"),
            "--cache", str(tmp_path / "cache"), "--quiet"]
    env = dict(os.environ, FAKE_TRACE=str(fakes.trace))
    assert subprocess.run(args, env=env).returncode == 0
    before = json.loads((tmp_path / "out" / "summary.json").read_text())
    fakes.ran()
    # Change what modes reads, and kill the process inside the modes stage.
    r = subprocess.run(args + ["--set", "modes.count=4"], env=dict(env, FAKE_CRASH="modes:exit"))
    assert r.returncode == 9
    assert fakes.ran() == ["modes"]
    leftovers = list((tmp_path / "cache" / "modes").glob(".*.tmp"))
    assert leftovers and (leftovers[0] / "part1.txt").exists()                # the half-written entry
    entries = [p for p in (tmp_path / "cache" / "modes").iterdir()
               if not p.name.startswith(".") and not p.name.endswith(".progress")]
    assert len(entries) == 1                                                   # only the old complete one
    assert json.loads((tmp_path / "out" / "summary.json").read_text()) == before
    assert (tmp_path / "out" / "modes" / "data.txt").is_file()
    # The next run cleans the temporary and computes the entry whole.
    r = subprocess.run(args + ["--set", "modes.count=4"], env=env)
    assert r.returncode == 0 and fakes.ran() == ["modes"]
    assert not list((tmp_path / "cache" / "modes").glob(".*.tmp"))
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["stages"]["modes"] == "computed"


def test_sigterm_cleans_up(tmp_path, fakes):
    """`kill` (SIGTERM) inside a stage: temporaries removed at once, exit 130."""
    sc = tmp_path / "scene.toml"
    sc.write_text("[run]\noutputs = ['modes']\n")
    stage = Path(fakes.root / fakes.pkg / "modes.py")
    stage.write_text(stage.read_text().replace(
        'crash = os.environ.get("FAKE_CRASH", "")',
        'import signal; os.kill(os.getpid(), signal.SIGTERM); crash = ""'))
    driver = tmp_path / "driver.py"
    driver.write_text(fakes.driver())
    r = subprocess.run([sys.executable, str(driver), "run", str(sc), "--out", str(tmp_path / "out"),
                        "--cache", str(tmp_path / "cache"), "--quiet"],
                       env=dict(os.environ, FAKE_TRACE=str(fakes.trace)), capture_output=True, text=True)
    assert r.returncode == 130 and r.stderr.startswith("error: interrupted")
    assert not list((tmp_path / "cache" / "modes").glob(".*"))
    assert (tmp_path / "cache" / "assembly").is_dir()


def test_disk_full_keeps_previous_summary(tmp_path, fakes, monkeypatch):
    go(tmp_path, scene(tmp_path, ["modes"]))
    summary = (tmp_path / "out" / "summary.json").read_text()

    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(wio.os, "fsync", full)
    with pytest.raises(OutputError, match="No space left on device"):
        go(tmp_path, scene(tmp_path, ["modes"], overrides=["modes.count=3"]))
    assert (tmp_path / "out" / "summary.json").read_text() == summary
    assert not list((tmp_path / "cache" / "modes").glob(".*"))


def test_unwritable_out(tmp_path, fakes):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(OutputError, match=f"cannot write output folder {blocker}/out"):
        run_scene(scene(tmp_path, ["modes"]), blocker / "out", cache=tmp_path / "cache", quiet=True)


def test_external_bundle_replaces_geometry_and_assembly(tmp_path, fakes, monkeypatch):
    from workflow import pipeline

    bundle = tmp_path / "mybundle"
    bundle.mkdir()
    (bundle / "data.txt").write_text("v1")
    monkeypatch.setattr(pipeline, "_check_bundle", lambda folder: {"bundle": str(folder), "n_dofs": 6})
    sc = scene(tmp_path, ["reduced"], extra=f"[model]\nbundle = '{bundle.name}'\n")
    s = go(tmp_path, sc)
    assert fakes.ran() == ["reduction"]
    assert s["stages"] == {"model": "external", "reduction": "computed"}
    assert (tmp_path / "out" / "model" / "data.txt").read_text() == "v1"
    assert not (tmp_path / "out" / "geometry").exists()
    # Editing the bundle's content invalidates what was computed from it.
    (bundle / "data.txt").write_text("v2")
    s = go(tmp_path, sc)
    assert fakes.ran() == ["reduction"]


def test_stale_links_removed(tmp_path, fakes):
    go(tmp_path, scene(tmp_path, ["frf"]))
    assert (tmp_path / "out" / "hb").is_symlink()
    go(tmp_path, scene(tmp_path, ["modes"]))
    assert not (tmp_path / "out" / "hb").exists() and (tmp_path / "out" / "modes").is_symlink()


def test_clean_stale(tmp_path):
    (tmp_path / "a" / ".k.x1.tmp").mkdir(parents=True)
    (tmp_path / "a" / "keep").mkdir()
    (tmp_path / ".summary.json.x.tmp").write_text("")
    removed = clean_stale(tmp_path, depth=2)
    assert len(removed) == 2 and (tmp_path / "a" / "keep").is_dir()


def test_log_progress_lines(tmp_path):
    import io

    buf = io.StringIO()
    log = RunLog(tmp_path / "run.log", stream=buf)
    assert list(log.progress(range(50), label="sweep")) == list(range(50))
    log.child("hb").info("hello")
    log.close()
    lines = buf.getvalue().splitlines()
    assert sum("sweep:" in line for line in lines) == 10       # one per 10 %, not a bar
    assert "ETA" in lines[0] and lines[-1] == "[hb] hello"
    assert "[hb] hello" in (tmp_path / "run.log").read_text()
    quiet = io.StringIO()
    RunLog(None, quiet=True, stream=quiet).info("x")
    assert quiet.getvalue() == ""


def test_unplannable_scene_does_not_touch_out(tmp_path, fakes, monkeypatch):
    from workflow import stages

    go(tmp_path, scene(tmp_path, ["mesh"]))
    log_before = (tmp_path / "out" / "run.log").read_text()
    monkeypatch.setitem(stages.MODULES, "extreme", "no_such_package_xyz.extreme")
    with pytest.raises(SceneError):
        go(tmp_path, scene(tmp_path, ["extreme"]))
    assert (tmp_path / "out" / "run.log").read_text() == log_before


def test_bad_external_bundle_is_bundle_error(tmp_path, fakes):
    from workflow.errors import BundleError

    (tmp_path / "empty").mkdir()
    with pytest.raises(BundleError, match="lacks M.npz"):
        go(tmp_path, scene(tmp_path, ["reduced"], extra="[model]\nbundle = 'empty'\n"))
    assert not (tmp_path / "out").exists()


def test_real_bundle_checked(tmp_path, fakes):
    """A real (tiny) bundle through reduction.bundle: two nodes, one contact pair."""
    import numpy as np
    import scipy.sparse as sp
    from reduction.bundle import Bundle, Contact, Loads, write_bundle

    n = 6
    eye = sp.identity(n, format="csr")
    contact = Contact(blade_dofs=np.array([[0, 1, 2]]), disk_dofs=np.array([[3, 4, 5]]),
                      normal=np.array([[0.0, 0.0, 1.0]]), t1=np.array([[1.0, 0.0, 0.0]]),
                      t2=np.array([[0.0, 1.0, 0.0]]), area=np.array([1e-6]), gap=np.array([0.0]))
    loads = Loads(fixed=np.array([3, 4, 5]), static=np.zeros(n), harmonic=np.zeros(n), observe=np.array([2]))
    write_bundle(Bundle(M=eye, K=eye, C=0 * eye, contact=contact, loads=loads), tmp_path / "b")
    (tmp_path / "b" / "data.txt").write_text("fake stages look for this")
    s = go(tmp_path, scene(tmp_path, ["reduced"], extra="[model]\nbundle = 'b'\n"))
    assert s["model"]["n_dofs"] == 6 and s["model"]["contact_pairs"] == 1


def test_foreign_out_folder_refused(tmp_path, fakes):
    """`--out .` in a source tree must not replace its geometry/ package by a link."""
    src = tmp_path / "src"
    (src / "geometry").mkdir(parents=True)
    (src / "geometry" / "keep.py").write_text("x = 1\n")
    with pytest.raises(OutputError, match="not a bladewear run folder"):
        run_scene(scene(tmp_path, ["mesh"]), src, cache=tmp_path / "cache", quiet=True)
    assert (src / "geometry" / "keep.py").is_file() and not (src / "run.log").exists()
    # Even in a run folder, a real folder in a link's place is left alone.
    (src / "run.log").write_text("")
    with pytest.raises(OutputError, match="in the way"):
        run_scene(scene(tmp_path, ["mesh"]), src, cache=tmp_path / "cache", quiet=True)
    assert (src / "geometry" / "keep.py").is_file()
