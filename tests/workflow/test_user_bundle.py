"""A user's own bundle through the real reduction and HB stages (issue 18, item 13).

The lattice bundle (tests/reduction/lattice.py: 144 DOFs, 6 pairs) with a
per-pair friction coefficient in contact.npz: the HB stage uses it and says
so; the sections the bundle replaces are not used and leave the cache key;
a preload that lifts the blade is blamed on the bundle's static load, not on
[rotation].
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "reduction"))
import lattice  # noqa: E402

from fakestages import run  # noqa: E402

MU = np.linspace(0.2, 0.6, 6)


def _bundle(path: Path, static_load: float, mu=MU) -> Path:
    from reduction.bundle import Contact, write_bundle

    b = lattice.lattice_bundle(static_load=static_load)
    if mu is not None:
        b.contact = Contact(**{**b.contact.__dict__, "mu": mu})
    write_bundle(b, path)
    return path


def _scene(tmp_path: Path) -> Path:
    p = tmp_path / "user.toml"
    p.write_text("[run]\noutputs = ['frf']\n[model]\nbundle = 'bundle'\n[sweep]\npoints = 5\n"
                 "[hb]\nharmonics = [1]\ntime_samples = [16]\n")
    return p


def _go(capsys, tmp_path, *more):
    return run(capsys, "run", _scene(tmp_path), "--out", tmp_path / "out", "--cache", tmp_path / "cache", "--quiet",
               *more)


@pytest.mark.slow  # ~8 s (a user's bundle through the whole pipeline): make test-slow
def test_per_pair_mu_used_and_reported(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("BLADEWEAR_CACHE", raising=False)
    _bundle(tmp_path / "bundle", static_load=-200.0)
    rc, _, err = _go(capsys, tmp_path)
    assert rc in (0, 3), err                       # 3: some points of this stiff lattice may not converge
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["hb"]["mu_source"] == "bundle contact.npz"
    np.testing.assert_allclose(s["hb"]["mu"], MU)
    assert s["hb"]["excitation_amplitude_N"] is None     # the bundle's load is solved, not [excitation]
    assert s["model"]["mu"] == "per pair (contact.npz)"
    assert s["hb"]["runs"][0]["converged_points"] >= 3
    # [material] / [excitation] are replaced by the bundle: changing them recomputes nothing
    rc, _, err = _go(capsys, tmp_path, "--set", "material.young=2e11", "--set", "excitation.amplitude=5")
    assert rc in (0, 3), err
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["stages"]["hb"] == "cached" and s["stages"]["reduction"] == "cached"
    rc, out, _ = run(capsys, "show", _scene(tmp_path), "--out", tmp_path / "out", "--cache", tmp_path / "cache")
    assert "[excitation]  # not used" in out and "[contact]  # not used" not in out


def test_show_reads_the_bundle_and_refuses_a_missing_one(tmp_path, capsys):
    """``show`` lists the bundle with its size, and where the folder is missing it stops on the
    error ``run`` would stop on (it listed the bundle as the model source and exited 0)."""
    rc, _, err = run(capsys, "show", _scene(tmp_path), "--out", tmp_path / "out", "--cache", tmp_path / "cache")
    assert rc == 2 and err.startswith("error: ") and err.count("\n") == 1 and "bundle" in err
    _bundle(tmp_path / "bundle", static_load=-200.0)
    rc, out, err = run(capsys, "show", _scene(tmp_path), "--out", tmp_path / "out", "--cache", tmp_path / "cache")
    assert rc == 0, err
    assert "144 DOFs, 6 contact pairs" in out


def test_lifting_preload_blames_the_bundle(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("BLADEWEAR_CACHE", raising=False)
    _bundle(tmp_path / "bundle", static_load=10.0, mu=None)
    rc, _, err = _go(capsys, tmp_path)
    assert rc == 2 and err.startswith("error: static contact state") and err.count("\n") == 1
    assert "loads.npz 'static'" in err and "rotation.speed_rpm" not in err


def test_too_many_modes_names_reduction_modes(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("BLADEWEAR_CACHE", raising=False)
    _bundle(tmp_path / "bundle", static_load=-200.0)
    rc, _, err = _go(capsys, tmp_path, "--set", "reduction.modes=500")
    assert rc == 2 and "reduction.modes" in err and err.count("\n") == 1
