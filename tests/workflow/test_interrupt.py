"""Ctrl-C always ends with the 'interrupted' line and status 130 (issue 18, item 11).

Importing gmsh sets SIGINT to SIG_DFL until ``gmsh.finalize``; Ctrl-C in the
geometry or remap stage then killed the process with no message. The fake
stage imports gmsh too, with OpenBLAS's threads running, then works in
Python (a loop: KeyboardInterrupt at once, with the usual clean-up) or inside
a blocking call (``time.sleep``: the watcher ends the process after the
grace time).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from fakestages import fakes  # noqa: F401 (fixture)


@pytest.mark.parametrize("how", ["loop", "sleep"])
def test_ctrl_c_after_a_library_reset_sigint(tmp_path, fakes, how):
    sc = tmp_path / "scene.toml"
    sc.write_text("[run]\noutputs = ['modes']\n")
    driver = tmp_path / "driver.py"
    # the sleep variant waits out the watcher's grace (5 s in a run): a shorter one here
    driver.write_text(fakes.driver().replace("from workflow.cli import main",
                                             "import workflow.cli\nworkflow.cli.INTERRUPT_GRACE = 0.5\n"
                                             "from workflow.cli import main"))
    # OpenBLAS's worker threads, started at NumPy's import before SIGINT is blocked, take the
    # signal too: with them a SIG_DFL left by gmsh's import ended the run with no message
    env = dict(os.environ, FAKE_TRACE=str(fakes.trace), FAKE_CRASH=f"geometry:sigdfl-{how}",
               OMP_NUM_THREADS="2", OPENBLAS_NUM_THREADS="2")
    env.pop("BLADEWEAR_MPI", None)
    proc = subprocess.Popen([sys.executable, str(driver), "run", str(sc), "--out", str(tmp_path / "out"),
                             "--cache", str(tmp_path / "cache"), "--quiet"], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    busy = fakes.trace.parent / "busy"
    t0 = time.monotonic()
    while not busy.exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() - t0 < 60, "the fake stage never started"
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    try:
        out, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("Ctrl-C did not stop the run")
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1].startswith("error: interrupted"), err
    assert "Traceback" not in err
    if how == "loop":  # stopped in Python: the temporary entry was removed on the way out
        assert not list((tmp_path / "cache" / "geometry").glob(".*.tmp"))
    assert not (tmp_path / "cache" / "geometry").exists() or not [
        d for d in (tmp_path / "cache" / "geometry").iterdir()
        if not d.name.startswith(".") and not d.name.endswith(".progress")]      # no entry, only its progress
