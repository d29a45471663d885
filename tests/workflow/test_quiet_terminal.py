"""A quiet terminal: libraries' logging and warnings go to run.log, not the screen (issue #46).

On a cold form cache FFCx/cffi/setuptools logged every gcc call at INFO on
the root logger (importing ffcx calls ``logging.basicConfig()``, setuptools
lowers the root level): 60 of the ~100 lines of ``make demo``. A fake stage
here does what those libraries do, inside a run.
"""
from __future__ import annotations

import contextlib
import logging
import sys
import uuid
import warnings

import pytest

import fakestages
from fakestages import run
from workflow.pipeline import run_scene
from workflow.runlog import RunLog, library_logging
from workflow.scene import load_scene

NOISE = '''

_fake_run = run


def run(scene, inputs, out, log):
    import logging, sys, warnings
    tag = os.environ["NOISE_TAG"]
    logging.basicConfig()                      # what importing ffcx does: a no-op during a run
    logging.info("x86_64-linux-gnu-gcc -shared %s", tag)   # setuptools' gcc lines: root, INFO
    logging.getLogger("fake_ffcx_" + tag).info("ffcx compiling " + tag)   # not "ffcx": real ffcx, once imported, sets its own level
    ufl = logging.getLogger("fake_ufl_" + tag)  # UFL: a stdout handler of its own, added mid-run
    ufl.addHandler(logging.StreamHandler(sys.stdout))
    ufl.propagate = False
    ufl.warning("ufl warning " + tag)
    with warnings.catch_warnings():            # shown whatever filters earlier imports set
        warnings.simplefilter("always")
        warnings.warn("library warning " + tag)
    return _fake_run(scene, inputs, out, log)
'''


@pytest.fixture
def noisy(tmp_path, monkeypatch):
    """The fakes, with a geometry stage that logs like ffcx/setuptools/UFL and warns."""
    fakes = fakestages.install(tmp_path, monkeypatch)
    geometry = fakes.root / fakes.pkg / "geometry.py"
    geometry.write_text(geometry.read_text() + NOISE)
    tag = uuid.uuid4().hex[:8]  # warnings are shown once per message: one per test
    monkeypatch.setenv("NOISE_TAG", tag)
    yield fakes, tag
    logging.getLogger("fake_ufl_" + tag).handlers.clear()


@contextlib.contextmanager
def after_form_compile():
    """The root logger as after importing ffcx and one compile: a stderr handler, level INFO.

    Entered in the test itself: capfd's ``sys.stderr`` during fixture set-up is closed by the call.
    """
    root = logging.getLogger()
    console = logging.StreamHandler(sys.stderr)
    old_level = root.level
    root.addHandler(console)
    root.setLevel(logging.INFO)
    try:
        yield
    finally:
        root.removeHandler(console)
        root.setLevel(old_level)


def _scene(tmp_path):
    p = tmp_path / "scene.toml"
    p.write_text("[run]\noutputs = ['mesh']\ntitle = 'noise'\n")
    return p


def _config():
    root = logging.getLogger()
    return (root.level, list(root.handlers), logging.Logger.__dict__["callHandlers"],
            logging.lastResort, warnings.showwarning)


@pytest.mark.parametrize("quiet", [False, True])
def test_library_logging_to_run_log_not_terminal(tmp_path, capfd, noisy, quiet):
    fakes, tag = noisy
    args = ["run", _scene(tmp_path), "--out", tmp_path / "out", "--cache", tmp_path / "cache"]
    with after_form_compile():
        before = _config()
        rc, out, err = run(capfd, *args, *(["--quiet"] if quiet else []))
        after = _config()
    assert rc == 0, err
    terminal = out + err
    assert fakes.ran() == ["geometry"]
    text = (tmp_path / "out" / "run.log").read_text()
    for line in (f"INFO root: x86_64-linux-gnu-gcc -shared {tag}", f"INFO fake_ffcx_{tag}: ffcx compiling {tag}",
                 f"WARNING fake_ufl_{tag}: ufl warning {tag}", "WARNING py.warnings: ",
                 f"UserWarning: library warning {tag}"):
        assert line in text, line
    # Time-stamped like the stage lines.
    assert any(ln.startswith("20") and f"ffcx compiling {tag}" in ln for ln in text.splitlines())
    assert "gcc" not in terminal and "ffcx compiling" not in terminal
    if quiet:
        assert terminal == ""
    else:
        # Warnings once, as warning: lines; the stage lines as before.
        assert terminal.count(f"ufl warning {tag}") == 1
        assert f"warning: fake_ufl_{tag}: ufl warning {tag}" in err
        assert terminal.count(f"library warning {tag}") == 1
        assert "geometry: computed" in err and "geometry: computing" not in err   # run.log has it
    assert after == before  # logging as it was: tests run many scenes in one process


def test_failed_run_logs_to_failed_run_log_and_restores_logging(tmp_path, capfd, noisy, monkeypatch):
    fakes, tag = noisy
    monkeypatch.setenv("FAKE_CRASH", "geometry:interrupt")
    with after_form_compile():
        before = _config()
        with pytest.raises(KeyboardInterrupt):
            run_scene(load_scene(_scene(tmp_path)), tmp_path / "out", cache=tmp_path / "cache", quiet=True)
        out, err = capfd.readouterr()
        assert _config() == before
        # After the run, the root's console handler prints again.
        logging.info("after the run %s", tag)
        assert f"after the run {tag}" in capfd.readouterr().err
    assert out + err == ""
    assert f"x86_64-linux-gnu-gcc -shared {tag}" in (tmp_path / "cache" / "failed-run.log").read_text()


def test_echo_bounded_and_nothing_without_file(tmp_path, capsys):
    import io

    stream = io.StringIO()
    log = RunLog(tmp_path / "log.txt", stream=stream)
    with library_logging(log):
        for i in range(12):
            logging.getLogger("lib").warning("same warning")
            logging.getLogger("lib").warning("warning %d\nsecond line", i)
    log.close()
    lines = stream.getvalue().splitlines()
    assert lines[0] == "warning: lib: same warning"
    assert lines[1] == "warning: lib: warning 0 (more in run.log)"
    assert len(lines) == 6 and "see run.log" in lines[-1]
    assert (tmp_path / "log.txt").read_text().count("WARNING lib: ") == 24
    # The MPI ranks other than 0: no file, no terminal.
    quiet = io.StringIO()
    with library_logging(RunLog(quiet=True, stream=quiet), echo=False):
        logging.getLogger("lib").error("rank 1 error")
    assert quiet.getvalue() == "" and capsys.readouterr() == ("", "")
