"""The scaling benchmark as a scene stage (issue 9): rows, the memory guard, bad input."""
from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from workflow.errors import SceneError
from workflow.mpi import mpirun_command, single_thread_env

BIN = Path(sys.executable).parent


def _run(tmp_path, *sets):
    cmd = [str(BIN / "bladewear"), "run", "scaling", "--out", str(tmp_path / "run"), "--cache",
           str(tmp_path / "cache"), "--quiet"]
    for s in sets:
        cmd += ["--set", s]
    # the environment of this Python process, not the C environment that an MPI
    # initialised by earlier tests (dolfinx) may have extended
    return subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=single_thread_env())


@pytest.mark.skipif(mpirun_command(2) is None, reason="mpirun/mpiexec not found: the 2-process rows need it")
@pytest.mark.slow
def test_scaling_scene_measures_one_and_two_processes(tmp_path):
    r = _run(tmp_path, "scaling.factors=[1.6, 1.3]", "scaling.procs=[1, 2]", "scaling.fit_min_dofs=0")
    assert r.returncode == 0, r.stderr
    out = tmp_path / "run" / "scaling"
    rows = list(csv.DictReader(open(out / "scaling.csv")))
    assert [(r["factor"], r["procs"]) for r in rows] == [("1.6", "1"), ("1.6", "2"), ("1.3", "1"), ("1.3", "2")]
    dofs = [int(r["n_dofs"]) for r in rows]
    assert dofs[0] == dofs[1] < dofs[2] == dofs[3]            # finer mesh, more DOFs; same mesh on 1 and 2 ranks
    assert max(float(r["f_rel_err"]) for r in rows) < 1e-8    # 2 ranks reduce to the serial frequencies
    assert all(float(r["assembly_gb"]) > 0.1 and float(r["reduction_s"]) > 0 for r in rows)
    fit = json.loads((out / "scaling.json").read_text())
    assert {"assembly_s@1", "reduction_s@2", "assembly_gb@1"} <= set(fit)
    assert (out / "scaling.png").stat().st_size > 10_000
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())["scaling"]
    assert summary["largest_dofs"] == dofs[-1] and summary["rows"] == 4


@pytest.mark.slow
def test_memory_guard_stops_before_a_mesh_that_would_not_fit(tmp_path):
    r = _run(tmp_path, "scaling.factors=[1.6, 1.3, 1.0]", "scaling.procs=[1]", "scaling.max_gb=0.3")
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader(open(tmp_path / "run" / "scaling" / "scaling.csv")))
    assert [r["factor"] for r in rows] == ["1.6", "1.3"]      # factor 1.0 was predicted above 0.3 GB
    assert "would need" in (tmp_path / "run" / "run.log").read_text()


@pytest.mark.parametrize("key, value", [("scaling.factors", "[-0.5]"), ("scaling.procs", "[0]"),
                                        ("scaling.max_gb", "0")])
def test_bad_scaling_keys_name_the_key(key, value):
    from workflow.scene import load_scene

    with pytest.raises(SceneError, match=key.replace(".", r"\.")):
        load_scene("scaling", [f"{key}={value}"])
