"""The run folder shows exactly one run (issue 18, items 8 and 12). Fake stages."""
from __future__ import annotations

import json
import os

import pytest

from fakestages import fakes, run  # noqa: F401 (fakes is a fixture)
from workflow.pipeline import lock_out


def _scene(tmp_path, outputs):
    p = tmp_path / "scene.toml"
    p.write_text(f"[run]\noutputs = {json.dumps(outputs)}\n")
    return p


def _run(capsys, tmp_path, outputs):
    return run(capsys, "run", _scene(tmp_path, outputs), "--out", tmp_path / "out", "--cache", tmp_path / "cache",
               "--quiet")


def test_report_of_an_earlier_run_is_removed(tmp_path, capsys, fakes):
    rc, _, err = _run(capsys, tmp_path, ["frf", "report"])
    assert rc == 0, err
    assert (tmp_path / "out" / "report" / "report.md").is_file()
    rc, _, err = _run(capsys, tmp_path, ["frf"])
    assert rc == 0, err
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert "report" not in s["stages"]
    assert not (tmp_path / "out" / "report").exists()
    assert not [c for c in os.listdir(tmp_path / "out") if c.endswith(".old")]
    # and back: the report is written again
    rc, _, _ = _run(capsys, tmp_path, ["frf", "report"])
    assert rc == 0 and (tmp_path / "out" / "report" / "report.md").is_file()


def test_failed_run_keeps_the_previous_report(tmp_path, capsys, fakes, monkeypatch):
    assert _run(capsys, tmp_path, ["frf", "report"])[0] == 0
    monkeypatch.setenv("FAKE_CRASH", "hb:interrupt")
    rc, _, _ = run(capsys, "run", _scene(tmp_path, ["frf"]), "--out", tmp_path / "out", "--cache", tmp_path / "cache",
                   "--quiet", "--fresh")
    assert rc == 130
    assert (tmp_path / "out" / "report" / "report.md").is_file()


def test_second_run_on_a_busy_out_folder_is_refused(tmp_path, capsys, fakes):
    assert _run(capsys, tmp_path, ["modes"])[0] == 0
    before = (tmp_path / "out" / "summary.json").read_text()
    fd = lock_out(tmp_path / "out")  # another run holds the folder
    try:
        fakes.ran()
        rc, _, err = _run(capsys, tmp_path, ["modes"])
        assert rc == 2 and err.startswith("error: ") and err.count("\n") == 1
        assert "in use by another bladewear run" in err and str(tmp_path / "out") in err
        assert fakes.ran() == [] and (tmp_path / "out" / "summary.json").read_text() == before
    finally:
        os.close(fd)
    assert _run(capsys, tmp_path, ["modes"])[0] == 0   # the lock dies with its holder


def test_two_runs_share_a_cache(tmp_path, capsys, fakes):
    """Different run folders, one cache: allowed (shared lock); the second finds the first's entries."""
    sc = _scene(tmp_path, ["frf"])
    for out in ("a", "b"):
        rc, _, err = run(capsys, "run", sc, "--out", tmp_path / out, "--cache", tmp_path / "cache", "--quiet")
        assert rc == 0, err
    assert json.loads((tmp_path / "b" / "summary.json").read_text())["stages"]["hb"] == "cached"


def test_heartbeat_lines_while_a_stage_is_silent(tmp_path):
    import io
    import time

    from workflow.runlog import RunLog, heartbeat

    buf = io.StringIO()
    log = RunLog(tmp_path / "log", stream=buf)
    with heartbeat(log, "assembly", every=0.05):
        time.sleep(0.3)
    n = buf.getvalue().count("assembly: still computing")
    assert 3 <= n <= 7, buf.getvalue()
    after = buf.getvalue()
    time.sleep(0.15)
    assert buf.getvalue() == after          # stopped with the block
    assert "still computing" in (tmp_path / "log").read_text()


@pytest.mark.slow  # 1.5–5 s on a cold 2-core clone: make test-slow keeps make test within 3 min
def test_quiet_silences_library_logging(tmp_path, fakes):
    """The form compiler logs its gcc calls at INFO on the root logger (cold cache): they go to
    run.log, never to the terminal, quiet or not."""
    import subprocess
    import sys
    from pathlib import Path

    stage = Path(fakes.root / fakes.pkg / "geometry.py")
    stage.write_text(stage.read_text().replace(
        'crash = os.environ.get("FAKE_CRASH", "")',
        'import logging; logging.basicConfig(level=logging.INFO); logging.info("x86_64-linux-gnu-gcc -O2"); '
        'crash = ""'))
    driver = tmp_path / "driver.py"
    driver.write_text(fakes.driver())
    sc = _scene(tmp_path, ["modes"])
    errs = {}
    for quiet in (True, False):
        r = subprocess.run([sys.executable, str(driver), "run", str(sc), "--out", str(tmp_path / "out"),
                            "--cache", str(tmp_path / f"cache{quiet}")] + (["--quiet"] if quiet else []),
                           env=dict(os.environ, FAKE_TRACE=str(fakes.trace)), capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        errs[quiet] = r.stderr
    assert "gcc" not in errs[True] and errs[True] == ""
    assert "gcc" not in errs[False]
    assert "INFO root: x86_64-linux-gnu-gcc -O2" in (tmp_path / "out" / "run.log").read_text()


def test_weighted_progress_counts_work_not_items(tmp_path):
    """Cheap items first (HB variants by Nh): the percentage follows the work (issue 18, item 9)."""
    import io

    from workflow.runlog import RunLog

    buf = io.StringIO()
    log = RunLog(tmp_path / "log", stream=buf)
    assert list(log.progress([0, 1, 2], total=3, label="v", weights=[1.0, 1.0, 8.0])) == [0, 1, 2]
    lines = [ln for ln in buf.getvalue().splitlines() if ln.startswith("v: ")]
    assert lines[0].startswith("v: 1/3 ( 10 %)") and lines[1].startswith("v: 2/3 ( 20 %)")
    assert lines[-1].startswith("v: 3/3 (100 %)")
    buf = io.StringIO()
    log = RunLog(tmp_path / "log2", stream=buf)
    list(log.progress([0, 1, 2], total=3, label="v"))
    assert buf.getvalue().splitlines()[0].startswith("v: 1/3 ( 33 %)")
    # a cost model that does not fit is ignored rather than trusted
    buf = io.StringIO()
    list(RunLog(tmp_path / "log3", stream=buf).progress([0, 1], total=2, label="v", weights=[1.0]))
    assert buf.getvalue().splitlines()[0].startswith("v: 1/2 ( 50 %)")


def test_first_run_killed_hard_does_not_block_the_next(tmp_path, capsys, fakes):
    """SIGKILL during a first run leaves only .run.log.tmp in the new folder: not a foreign folder."""
    out = tmp_path / "out"
    out.mkdir()
    (out / ".run.log.tmp").write_text("killed")
    rc, _, err = _run(capsys, tmp_path, ["modes"])
    assert rc == 0, err
    assert not (out / ".run.log.tmp").exists() and (out / "run.log").is_file()


@pytest.mark.parametrize("where", ["same", "inside"])
def test_a_run_folder_in_the_cache_is_refused_before_any_stage(tmp_path, capsys, fakes, where):
    """The run folder links each stage to its cache entry: --out equal to --cache (or inside
    it) was found only after every stage had run, by a link in the way. One error, nothing run."""
    out = tmp_path / "c" if where == "same" else tmp_path / "c" / "run"
    rc, _, err = run(capsys, "run", _scene(tmp_path, ["modes"]), "--out", out, "--cache", tmp_path / "c", "--quiet")
    assert rc == 2 and err.startswith("error: ") and err.count("\n") == 1 and "--cache" in err
    assert fakes.ran() == [] and not out.exists()
