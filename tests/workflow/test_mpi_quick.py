"""The README's MPI command on the quick scene finishes and gives the serial results (issue 18, item 1).

``mpirun -n 2 bladewear run quick --fresh`` used to hang in the remap stage:
remap runs on rank 0 alone but read the mesh with a collective call on
COMM_WORLD while rank 1 waited outside MPI. Every launch here has a timeout,
so a regression fails instead of hanging the suite.

Two comparisons:

* the whole chain on 2 ranks (``--fresh``) against 1 rank: the assembly's DOF
  numbering depends on the partition, and so do MUMPS' ordering and the block
  Lanczos start blocks of the reduction, which round off differently. The
  reduced models' first tied frequencies differ by ~1e-10 (as much as moving
  every entry of the assembled M and K by ±1 ulp does). Measured (2026-11-27,
  ``python -m workflow.bench.renumbering --orders 5 --ulps 5``,
  ``results/reference/renumbering``), the quick scene at Nh = 7: FRF ≤ 3.7e-10
  and worn depth ≤ 7.6e-10 (one unit in the last digit written) in 7 fresh
  2-rank runs and 10 perturbed serial ones; at Nh = 5 the worn depth, solved
  at the tied resonance, spread to 1.2e-8. Bounds: 1e-8, issue 18's target.
  Before 2026-11-27 (5f91ee6) the wear was solved at a tied frequency from
  ``eigh(K_yy, M_yy)``, itself 2e-10 off between BLAS thread counts, and
  agreed only to ~1e-6; before 2026-11-27 (b26fc39) the condensation's LU near the tied
  resonance put the FRF at ~1e-7.
* hb, wear and remap on 2 ranks from the *serial* reduced model (cache copied,
  their entries removed): the same problem, so 1e-8.
"""
from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from workflow.mpi import mpirun_command, single_thread_env

# The quick scene end to end three times (~80 s on 2 cores): make test-slow.
pytestmark = [pytest.mark.mpi, pytest.mark.slow]

MPIRUN = mpirun_command(2)
if MPIRUN is None:
    pytest.skip("mpirun/mpiexec not found on PATH", allow_module_level=True)

BIN = Path(sys.executable).parent / "bladewear"
TIGHT = ["--set", "hb.tol=1e-12"]
TIMEOUT = 240  # s: a hang fails the test instead of the suite


def _env():
    env = single_thread_env()
    env.setdefault("OMPI_ALLOW_RUN_AS_ROOT", "1")
    env.setdefault("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
    env.pop("BLADEWEAR_CACHE", None)
    env["PYVISTA_OFF_SCREEN"] = "true"
    return env


def _run(cmd):
    try:
        r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, env=_env(), timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"hang: {' '.join(map(str, cmd))} did not finish in {TIMEOUT} s")
    assert r.returncode == 0, f"{' '.join(map(str, cmd))} failed ({r.returncode}):\n{r.stdout}\n{r.stderr}"
    assert "Traceback" not in r.stderr, r.stderr
    return r


def _columns(path, name):
    with open(path) as fh:
        return np.array([float(r[name]) for r in csv.DictReader(fh)])


def _rel(a, b) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("mpiquick")
    serial = tmp / "serial"
    _run([BIN, "run", "quick", "--out", serial, "--cache", tmp / "c1", "--quiet", *TIGHT])
    return tmp, serial


def _compare(a: Path, b: Path, rel: float, rel_wear: float | None = None) -> None:
    for col in ("frequency_hz", "amplitude_m"):
        assert _rel(_columns(b / "hb" / "frf.csv", col), _columns(a / "hb" / "frf.csv", col)) < rel, col
    w = [_columns(d / "wear" / "wear.csv", "W_pseudo-time_m") for d in (a, b)]
    assert w[0].max() > 0 and _rel(w[1], w[0]) < (rel_wear or rel)
    for d in (a, b):
        s = json.loads((d / "summary.json").read_text())
        assert s["stages"]["remap"] == "computed" and s["unconverged"] == {}
        assert (d / "remap" / "wear_map.xdmf").is_file()


def test_readme_command_two_ranks_finishes_and_matches_serial(runs):
    tmp, serial = runs
    par = tmp / "fresh2"
    _run(MPIRUN + [BIN, "run", "quick", "--out", par, "--cache", tmp / "c2", "--fresh", "--quiet", *TIGHT])
    _compare(serial, par, 1e-8)


def test_serial_stages_on_two_ranks_same_reduced_model(runs):
    tmp, serial = runs
    cache = tmp / "c3"
    shutil.copytree(tmp / "c1", cache, symlinks=True)
    for stage in ("hb", "wear", "remap"):
        shutil.rmtree(cache / stage)
    par = tmp / "same2"
    _run(MPIRUN + [BIN, "run", "quick", "--out", par, "--cache", cache, "--quiet", *TIGHT])
    s = json.loads((par / "summary.json").read_text())
    assert s["stages"]["reduction"] == "cached" and s["stages"]["hb"] == "computed"
    _compare(serial, par, 1e-8)


@pytest.mark.slow  # ~12 s more; the serial case (test_unconverged.py) runs in the default suite
def test_unconverged_exit_3_on_two_ranks(runs):
    """Every rank returns the same status: 3 for a run with unconverged results (μ = 0: the
    wear has no worn steady state; the FRF converges at every point since 2026-11-27, 818974e)."""
    tmp, _ = runs
    cmd = MPIRUN + [BIN, "run", "quick", "--out", tmp / "mu0", "--cache", tmp / "c1", "--quiet",
                    "--set", "contact.mu=0", "--set", 'run.outputs=["wear"]']
    try:
        r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, env=_env(), timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        pytest.fail("hang")
    assert r.returncode == 3, r.stderr
    assert r.stderr.count("exit status 3") == 1 and "Traceback" not in r.stderr   # rank 0 alone prints
    s = json.loads((tmp / "mu0" / "summary.json").read_text())
    assert set(s["unconverged"]) == {"wear"}
