"""The bladewear command: one-line errors with exit status 2, run/show/scenes."""
from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import fakestages
from fakestages import fakes, run  # noqa: F401 (fakes is a fixture)
from workflow import io as wio

BLADEWEAR = Path(sys.executable).parent / "bladewear"




def scene(tmp_path, text, name="scene.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("text, match", [
    ("[run]\noutputs = ['modes'\n", "malformed TOML"),
    ("[runn]\n", "unknown section [runn]"),
    ("[contact]\nmuu = 1.0\n", "unknown key contact.muu"),
    ("[contact]\nmu = 'a lot'\n", "contact.mu must be a number"),
    ("[contact]\nmu = nan\n", "contact.mu must be finite"),
    ("[contact]\nmu = -1.0\n", "contact.mu = -1.0 must be ≥ 0"),
])
def test_bad_scene_one_line_exit_2(tmp_path, capsys, fakes, text, match):
    p = scene(tmp_path, text)
    for cmd in ("run", "show"):
        rc, out, err = run(capsys, cmd, p, "--out", tmp_path / "out", "--cache", tmp_path / "cache")
        assert rc == 2 and err.startswith("error: ") and match in err and err.count("\n") == 1, err
    assert not (tmp_path / "out").exists() and fakes.ran() == []


def test_bad_override_exit_2(tmp_path, capsys, fakes):
    p = scene(tmp_path, "[run]\noutputs = ['modes']\n")
    rc, _, err = run(capsys, "run", p, "--set", "contact.mu=-0.5", "--out", tmp_path / "out")
    assert rc == 2 and "contact.mu = -0.5 must be ≥ 0" in err and err.count("\n") == 1


def test_console_script_exit_code(tmp_path):
    """The installed entry point, not just main(): exit status and stderr."""
    p = scene(tmp_path, "[contact]\nmu = nan\n")
    r = subprocess.run([str(BLADEWEAR), "run", str(p), "--out", str(tmp_path / "o")], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.startswith("error: ") and r.stderr.count("\n") == 1, r.stderr


def test_run_with_overrides_and_cache(tmp_path, capsys, fakes):
    p = scene(tmp_path, "[run]\noutputs = ['frf']\n")
    args = ["run", p, "--out", tmp_path / "out", "--cache", tmp_path / "cache", "--quiet"]
    rc, out, err = run(capsys, *args, "--set", "contact.mu=0.3", "--set", "hb.harmonics=[1,3]")
    assert rc == 0 and err == ""
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["overrides"] == ["contact.mu=0.3", "hb.harmonics=[1,3]"]
    data = (tmp_path / "out" / "hb" / "data.txt").read_text()
    assert "mu=0.3" in data and "harmonics=[1, 3]" in data
    fakes.ran()
    assert run(capsys, *args, "--set", "contact.mu=0.3", "--set", "hb.harmonics=[1,3]")[0] == 0
    assert fakes.ran() == []
    assert run(capsys, *args, "--fresh")[0] == 0
    assert fakes.ran() == ["geometry", "assembly", "reduction", "hb"]


def test_cache_from_environment(tmp_path, capsys, fakes, monkeypatch):
    monkeypatch.setenv("BLADEWEAR_CACHE", str(tmp_path / "envcache"))
    p = scene(tmp_path, "[run]\noutputs = ['mesh']\n")
    assert run(capsys, "run", p, "--out", tmp_path / "out", "--quiet")[0] == 0
    assert (tmp_path / "envcache" / "geometry").is_dir()
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["cache"] == str(tmp_path / "envcache")


def test_default_cache_beside_out(tmp_path, capsys, fakes):
    p = scene(tmp_path, "[run]\noutputs = ['mesh']\n")
    assert run(capsys, "run", p, "--out", tmp_path / "results" / "x", "--quiet")[0] == 0
    assert (tmp_path / "results" / ".cache" / "geometry").is_dir()


def test_progress_printed_unless_quiet(tmp_path, capsys, fakes):
    p = scene(tmp_path, "[run]\noutputs = ['mesh']\n")
    rc, out, err = run(capsys, "run", p, "--out", tmp_path / "out", "--cache", tmp_path / "c")
    assert rc == 0 and "[geometry] fake work: 20/20 (100 %)" in err and "geometry: computed" in err
    assert str(tmp_path / "out" / "summary.json") in out


def test_unwritable_out(tmp_path, capsys, fakes):
    blocker = tmp_path / "blocker"
    blocker.write_text("")
    p = scene(tmp_path, "[run]\noutputs = ['mesh']\n")
    rc, _, err = run(capsys, "run", p, "--out", blocker / "out", "--cache", tmp_path / "c")
    assert rc == 2 and err.startswith(f"error: cannot write output folder {blocker}/out")


def test_disk_full_one_line_previous_summary_intact(tmp_path, capsys, fakes, monkeypatch):
    p = scene(tmp_path, "[run]\noutputs = ['modes']\n")
    args = ["run", p, "--out", tmp_path / "out", "--cache", tmp_path / "c", "--quiet"]
    assert run(capsys, *args)[0] == 0
    before = (tmp_path / "out" / "summary.json").read_text()

    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(wio.os, "fsync", full)
    rc, _, err = run(capsys, *args, "--set", "modes.count=2")
    assert rc == 2 and "No space left on device" in err and err.count("\n") == 1
    assert (tmp_path / "out" / "summary.json").read_text() == before
    # Disk full at the very end (summary.json itself): previous one still intact.
    monkeypatch.undo()
    fakestages.install(tmp_path / "again", monkeypatch)
    real_replace = os.replace

    def replace(src, dst):
        if str(dst).endswith("summary.json"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real_replace(src, dst)

    monkeypatch.setattr(wio.os, "replace", replace)
    rc, _, err = run(capsys, *args, "--set", "modes.count=3")
    assert rc == 2 and f"cannot write {tmp_path / 'out' / 'summary.json'}" in err
    assert (tmp_path / "out" / "summary.json").read_text() == before
    assert not list((tmp_path / "out").glob(".summary.json*"))


def test_scenes_lists_shipped(capsys):
    rc, out, _ = run(capsys, "scenes")
    assert rc == 0
    names = [line.split()[0] for line in out.splitlines()]
    assert {"quick", "sector-modes"} <= set(names)
    assert "Sector modes" in out


def test_show_resolved_scene_and_stages(tmp_path, capsys, fakes):
    rc, out, err = run(capsys, "show", "sector-modes", "--set", "contact.mu=0.25", "--cache", tmp_path / "c")
    assert rc == 0, err
    assert "[contact]" in out and "mu " in out and "= 0.25" in out
    assert "young " in out and "# Pa" in out                     # defaults filled, with units
    assert "[geometry]" in out and "n_sectors" in out
    stage_lines = [line.split()[1] for line in out.splitlines() if line.startswith("#   ")]
    assert stage_lines == ["geometry", "assembly", "modes"] and "to compute" in out


def test_unknown_shipped_name(capsys):
    rc, _, err = run(capsys, "run", "nope-not-a-scene")
    assert rc == 2 and "nope-not-a-scene not found" in err
