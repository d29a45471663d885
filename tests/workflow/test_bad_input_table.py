"""The bad-input table (issue 18): scene keys, scene files, model bundles and CLI flags.

Every case runs ``bladewear run`` after a good run into the same folder and
asserts: exit status 2, exactly one line on stderr, starting ``error:`` and
naming the key or file at fault, no traceback, nothing on stdout, and the
previous run folder byte-identical (files, links, the log). The stages are
fakes (tests/workflow/fakestages.py): everything here is caught before a
stage runs, which is the point — a bad input costs no computation.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from fakestages import fakes, run  # noqa: F401 (fakes is a fixture)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "reduction"))
import lattice  # noqa: E402  (tests/reduction/lattice.py: a small two-body bundle)

OK_SCENE = "[run]\noutputs = ['modes']\n"

# (id, --set value, words the error line must contain)
SET_CASES = [
    ("young-zero", "material.young=0", ["--set material.young=0", "material.young", "≥ 1000.0"]),
    ("density-tiny", "material.density=1e-300", ["material.density", "≥ 1.0"]),
    ("harmonics-huge", "hb.harmonics=[10000]", ["hb.harmonics", "≤ 256"]),
    ("samples-huge", "hb.time_samples=[1000000]", ["hb.time_samples", "≤ 16384"]),
    ("points-huge", "sweep.points=1000000000000", ["sweep.points", "≤ 100000"]),
    ("image-huge", "remap.image_width=1000000", ["remap.image_width", "≤ 8192"]),
    ("aspect-along", "geometry.nodes_along=1000", ["--set geometry.nodes_along=1000", "geometry.nodes_along and"]),
    ("aspect-across", "geometry.nodes_across=100", ["--set geometry.nodes_across=100", "slivers"]),
    ("methods-bare-words", "hb.methods=[hbm, tcm]", ['e.g. hb.methods=["hbm", "tcm"]']),
    ("set-more-toml", "contact.mu=0.3\n[hb]\ntol=5", ["contact.mu", "more than one TOML value"]),
    ("young-negative", "material.young=-1e9", ["material.young"]),
    ("young-string", "material.young='abc'", ["material.young", "must be a number"]),
    ("poisson-half", "material.poisson=0.5", ["material.poisson", "≤ 0.499"]),
    ("density-zero", "material.density=0", ["material.density"]),
    ("rpm-negative", "rotation.speed_rpm=-1", ["rotation.speed_rpm"]),
    ("rpm-huge", "rotation.speed_rpm=1e6", ["rotation.speed_rpm", "≤ 100000"]),
    ("stiffening-int", "rotation.stress_stiffening=1", ["rotation.stress_stiffening", "true or false"]),
    ("prestress-negative", "rotation.prestress_iterations=-1", ["rotation.prestress_iterations"]),
    ("prestress-fraction", "rotation.prestress_iterations=1.5", ["rotation.prestress_iterations", "integer"]),
    ("modal-ratio-2", "damping.modal_ratio=2", ["damping.modal_ratio", "≤ 1"]),
    ("alpha-negative", "damping.alpha=-1", ["damping.alpha"]),
    ("amplitude-zero", "excitation.amplitude=0", ["excitation.amplitude", "> 0"]),
    ("amplitude-negative", "excitation.amplitude=-0.1", ["excitation.amplitude"]),
    ("amplitude-nan", "excitation.amplitude=nan", ["excitation.amplitude"]),
    ("modes-zero", "modes.count=0", ["modes.count"]),
    ("reduction-modes-negative", "reduction.modes=-1", ["reduction.modes"]),
    ("mode-counts-scalar", "reduction.check_mode_counts=5", ["reduction.check_mode_counts", "must be a list"]),
    ("frf-points-1", "reduction.frf_points=1", ["reduction.frf_points"]),
    ("no-modes-no-cutoff", "reduction.modes=0", ["reduction.modes = 0", "reduction.cutoff_hz"]),
    ("mu-negative", "contact.mu=-1", ["--set contact.mu=-1", "contact.mu"]),
    ("mu-inf", "contact.mu=inf", ["contact.mu", "finite"]),
    ("mu-garbage", "contact.mu=0.3.4", ["contact.mu", "must be a number"]),
    ("passes-zero", "contact.max_passes=0", ["contact.max_passes"]),
    ("eps-t-negative", "contact.eps_t=-5", ["contact.eps_t"]),
    ("harmonics-zero", "hb.harmonics=[0]", ["hb.harmonics", "≥ 1"]),
    ("harmonics-empty", "hb.harmonics=[]", ["hb.harmonics", "at least 1"]),
    ("harmonics-fraction", "hb.harmonics=[1.5]", ["hb.harmonics", "integers"]),
    ("harmonics-scalar", "hb.harmonics=3", ["hb.harmonics", "must be a list", "[3]"]),
    ("methods-empty", "hb.methods=[]", ["hb.methods", "at least 1"]),
    ("methods-unknown", "hb.methods=['xyz']", ["hb.methods", "'xyz'"]),
    ("time-samples-empty", "hb.time_samples=[]", ["hb.time_samples", "at least 1"]),
    ("time-samples-few", "hb.time_samples=[4]", ["hb.time_samples = 4", "2·Nh+1"]),
    ("solver-unknown", "hb.solver=bogus", ["hb.solver", "not one of"]),
    ("tol-zero", "hb.tol=0", ["hb.tol", "> 0"]),
    ("iterations-zero", "hb.max_iterations=0", ["hb.max_iterations"]),
    ("reference-nit", "hb.reference_time_samples=2", ["hb.reference_time_samples"]),
    ("sweep-points-zero", "sweep.points=0", ["sweep.points"]),
    ("sweep-method", "sweep.method=foo", ["sweep.method"]),
    ("scheme-unknown", "pseudotime.scheme=euler", ["pseudotime.scheme"]),
    ("cfl-zero", "pseudotime.cfl=0", ["pseudotime.cfl"]),
    ("dt-growth", "pseudotime.dt_growth=0.5", ["pseudotime.dt_growth", "≥ 1"]),
    ("k-w-negative", "wear.k_w=-1", ["wear.k_w"]),
    ("blade-share", "wear.blade_share=1.5", ["wear.blade_share"]),
    ("wear-methods", "wear.methods=['magic']", ["wear.methods", "'magic'"]),
    ("cycles-zero", "wear.cycles_per_block=0", ["wear.cycles_per_block"]),
    ("wear-frequency-negative", "wear.frequency_hz=-1", ["wear.frequency_hz"]),
    ("max-fraction", "remap.max_fraction=2", ["remap.max_fraction"]),
    ("smoothing", "remap.smoothing=cubic", ["remap.smoothing"]),
    ("image-width", "remap.image_width=10", ["remap.image_width"]),
    ("extreme-cases", "extreme.cases=['everything']", ["extreme.cases", "'everything'"]),
    ("outputs-empty", "run.outputs=[]", ["run.outputs"]),
    ("outputs-unknown", "run.outputs=['nonsense']", ["run.outputs", "'nonsense'"]),
    ("scaling-procs", "scaling.procs=[0]", ["scaling.procs"]),
    ("scaling-factors-empty", "scaling.factors=[]", ["scaling.factors"]),
    ("h-blade-negative", "geometry.h_blade=-0.004", ["h_blade"]),
    ("h-airfoil-tiny", "geometry.h_airfoil=1e-6", ["h_airfoil", "elements"]),
    ("span-huge", "geometry.span=1000", ["h_airfoil", "elements", "reduce span"]),
    ("unknown-section", "nosuch.key=1", ["--set nosuch.key=1", "unknown section [nosuch]"]),
    ("unknown-key", "hb.nosuchkey=1", ["unknown key hb.nosuchkey"]),
    ("misspelt-key", "contact.muu=0.3", ["contact.muu", "did you mean contact.mu"]),
    ("no-equals", "hb.harmonics", ["--set 'hb.harmonics'", "section.key=value"]),
]

# (id, scene text, words) — scene files
FILE_CASES = [
    ("malformed-toml", "[run\noutputs = ['modes']\n", ["malformed TOML", "bad.toml:1"]),
    ("top-level-key", "title = 'x'\n[run]\noutputs = ['modes']\n", ["bad.toml", "'title' must be inside a [section]"]),
    ("unknown-table", OK_SCENE + "[frobnicate]\nx = 1\n", ["bad.toml", "unknown section [frobnicate]"]),
    ("file-value", OK_SCENE + "[contact]\nmu = -0.5\n", ["bad.toml", "contact.mu = -0.5"]),
    ("table-not-list", OK_SCENE + "[hb]\nharmonics = 5\n", ["bad.toml", "hb.harmonics must be a list"]),
    ("missing-bundle", OK_SCENE + "[model]\nbundle = 'no-such-bundle'\n", ["no-such-bundle", "not a folder"]),
    # issue 47 item 4.6: used to be raised to 2Nh+1 silently while hb.time_samples was an error
    ("reference-nit-few", OK_SCENE + "[hb]\nreference_harmonics = 5\nreference_time_samples = 8\n",
     ["bad.toml", "hb.reference_time_samples = 8 < 2·Nh+1 = 11", "hb.reference_harmonics = 5"]),
]


def snapshot(folder: Path) -> dict:
    """Every entry under ``folder``: file bytes, link targets, folders (links not followed)."""
    snap = {}
    for root, dirs, files in os.walk(folder, followlinks=False):
        for name in dirs + files:
            p = Path(root) / name
            rel = str(p.relative_to(folder))
            if p.is_symlink():
                snap[rel] = ("link", os.readlink(p))
            elif p.is_dir():
                snap[rel] = ("dir",)
            else:
                snap[rel] = ("file", p.read_bytes())
    return snap


@pytest.fixture
def previous(tmp_path, capsys, fakes):
    """A good earlier run in tmp_path/out; returns its snapshot."""
    p = tmp_path / "ok.toml"
    p.write_text(OK_SCENE)
    rc, _, err = run(capsys, "run", p, "--out", tmp_path / "out", "--cache", tmp_path / "cache", "--quiet")
    assert rc == 0, err
    fakes.ran()
    return snapshot(tmp_path / "out")


def check(tmp_path, capsys, fakes, before, argv, needles):
    rc, out, err = run(capsys, *argv)
    assert rc == 2, (rc, err)
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err and out == "", (out, err)
    for n in needles:
        assert n in err, (n, err)
    assert snapshot(tmp_path / "out") == before
    assert fakes.ran() == []


def _run_argv(tmp_path, scene, *more):
    return ["run", scene, "--out", tmp_path / "out", "--cache", tmp_path / "cache", "--quiet", *more]


@pytest.mark.parametrize("text, needles", [c[1:] for c in SET_CASES], ids=[c[0] for c in SET_CASES])
def test_bad_set_value(tmp_path, capsys, fakes, previous, text, needles):
    check(tmp_path, capsys, fakes, previous, _run_argv(tmp_path, tmp_path / "ok.toml", "--set", text), needles)


@pytest.mark.parametrize("text, needles", [c[1:] for c in FILE_CASES], ids=[c[0] for c in FILE_CASES])
def test_bad_scene_file(tmp_path, capsys, fakes, previous, text, needles):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    check(tmp_path, capsys, fakes, previous, _run_argv(tmp_path, p), needles)


# ------------------------------------------------------------------ bundles

def _break_bundle(folder: Path, kind: str) -> None:
    """Write the lattice bundle to ``folder`` and damage it on disk as ``kind`` says."""
    from reduction.bundle import write_bundle

    b = lattice.lattice_bundle()
    write_bundle(b, folder)

    def save(name, A):
        sp.save_npz(folder / f"{name}.npz", sp.csr_matrix(A))

    def contact(**kw):
        with np.load(folder / "contact.npz") as z:
            arrays = {k: z[k] for k in z.files}
        arrays.update(kw)
        for k in [k for k, v in kw.items() if v is None]:
            del arrays[k]
        np.savez(folder / "contact.npz", **arrays)

    if kind == "K-nonsymmetric":
        K = b.K.tolil()
        K[3, 40] += 1e-2 * abs(b.K).max()
        save("K", K)
    elif kind == "C-nonsymmetric":
        C = b.C.tolil()
        C[3, 40] += 1e-2 * abs(b.C).max()
        save("C", C)
    elif kind == "K-negative":
        save("K", -b.K)
    elif kind == "K-dynamic":
        save("K", b.K - (2 * np.pi * 1e3) ** 2 * b.M)
    elif kind == "no-clamp":
        with np.load(folder / "loads.npz") as z:
            arrays = {k: z[k] for k in z.files}
        arrays["fixed"] = np.zeros(0, dtype=np.int64)
        np.savez(folder / "loads.npz", **arrays)
    elif kind == "same-dofs":
        contact(disk_dofs=b.contact.blade_dofs)
    elif kind == "mu-negative":
        contact(mu=np.full(b.contact.n_pairs, -0.2))
    elif kind == "mu-shape":
        contact(mu=np.full(b.contact.n_pairs + 1, 0.3))
    elif kind == "no-gap":
        contact(gap=None)
    elif kind == "M-truncated":
        (folder / "M.npz").write_bytes((folder / "M.npz").read_bytes()[:60])
    elif kind == "repeated-pair":       # issue 47 item 4.1: used to crash in condense (B rank deficient)
        c = b.contact
        contact(**{k: np.concatenate([getattr(c, k), getattr(c, k)[1:2]])
                   for k in ("blade_dofs", "disk_dofs", "normal", "t1", "t2", "area", "gap", "flank", "position")})
    elif kind == "fixed-fraction":      # float indices are converted only when they are exact integers
        with np.load(folder / "loads.npz") as z:
            arrays = {k: z[k] for k in z.files}
        arrays["fixed"] = arrays["fixed"] + 0.5
        np.savez(folder / "loads.npz", **arrays)
    elif kind == "flank-2":             # issue 47 item 4.5
        contact(flank=np.full(b.contact.n_pairs, 2))
    elif kind == "M-zero-mass":         # issue 47 item 4.4: was a Lanczos stall or blamed on K
        M = b.M.tolil()
        M[7, 7] = 0.0
        save("M", M)
    elif kind == "K-nan":
        K = b.K.tolil()
        K[0, 0] = np.nan
        save("K", K)
    else:
        raise ValueError(kind)


BUNDLE_CASES = [
    ("K-nonsymmetric", ["K.npz", "not symmetric"]),
    ("C-nonsymmetric", ["C.npz", "not symmetric"]),
    ("K-negative", ["K.npz", "negative eigenvalue", "not positive definite"]),
    ("K-dynamic", ["K.npz", "negative eigenvalue"]),
    ("no-clamp", ["loads.npz", "fixed", "floats"]),
    ("same-dofs", ["contact.npz", "same DOF in blade_dofs and disk_dofs"]),
    ("mu-negative", ["contact.npz", "mu must be"]),
    ("mu-shape", ["contact.npz", "mu must be"]),
    ("no-gap", ["contact.npz", "lacks gap"]),
    ("M-truncated", ["M.npz", "cannot be read"]),
    ("K-nan", ["K.npz", "non-finite"]),
    ("repeated-pair", ["contact.npz", "pair 6 repeats pair 1"]),
    ("fixed-fraction", ["loads.npz 'fixed'", "must hold integers"]),
    ("flank-2", ["contact.npz", "'flank' must be", "[2]"]),
    ("M-zero-mass", ["M.npz", "DOF 7"]),
]


@pytest.mark.parametrize("kind, needles", BUNDLE_CASES, ids=[c[0] for c in BUNDLE_CASES])
def test_bad_bundle(tmp_path, capsys, fakes, previous, kind, needles):
    _break_bundle(tmp_path / "bundle", kind)
    p = tmp_path / "bundle.toml"
    p.write_text(OK_SCENE + "[model]\nbundle = 'bundle'\n")
    check(tmp_path, capsys, fakes, previous, _run_argv(tmp_path, p), needles + ["bundle"])


def test_good_lattice_bundle_runs(tmp_path, capsys, fakes, previous):
    """The control: the same bundle undamaged passes the checks."""
    from reduction.bundle import write_bundle

    write_bundle(lattice.lattice_bundle(), tmp_path / "bundle")
    (tmp_path / "bundle" / "data.txt").write_text("what the fake modes stage checks for")
    p = tmp_path / "bundle.toml"
    p.write_text(OK_SCENE + "[model]\nbundle = 'bundle'\n")
    rc, _, err = run(capsys, *_run_argv(tmp_path, p))
    assert rc == 0, err
    import json

    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["model"]["tied_stiffness_check"]["method"] == "eigenvalues"
    assert s["model"]["mu"] == "scene contact.mu"


# ------------------------------------------------------------------ command line

def _cli_cases(tmp_path):
    ok = tmp_path / "ok.toml"
    a_file = tmp_path / "a-file"
    a_file.write_text("x")
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("x")
    return {
        "no-scene": (["run"], ["scene"]),
        "unknown-flag": (["run", ok, "--bogus"], ["--bogus"]),
        "unknown-command": (["frobnicate"], ["frobnicate"]),
        "set-without-value": (["run", ok, "--set"], ["--set"]),
        "scene-not-found": (["run", "no-such-scene", "--out", tmp_path / "out"], ["no-such-scene", "not found"]),
        "scene-is-folder": (["run", tmp_path, "--out", tmp_path / "out"], [str(tmp_path), "not a file"]),
        "out-is-file": (["run", ok, "--out", a_file, "--cache", tmp_path / "cache", "--quiet"],
                        [str(a_file), "output folder"]),
        "out-foreign": (["run", ok, "--out", foreign, "--cache", tmp_path / "cache", "--quiet"],
                        [str(foreign), "not a bladewear run folder"]),
        "cache-is-file": (["run", ok, "--out", tmp_path / "out", "--cache", a_file, "--quiet"],
                          [str(a_file), "cache folder"]),
    }


CLI_IDS = ["no-scene", "unknown-flag", "unknown-command", "set-without-value", "scene-not-found",
           "scene-is-folder", "out-is-file", "out-foreign", "cache-is-file"]


@pytest.mark.parametrize("case", CLI_IDS)
def test_bad_command_line(tmp_path, capsys, fakes, previous, case):
    argv, needles = _cli_cases(tmp_path)[case]
    try:
        check(tmp_path, capsys, fakes, previous, argv, needles)
    except SystemExit as exc:  # argparse exits; the console script turns that into the status
        assert exc.code == 2
        err = capsys.readouterr().err
        assert err.startswith("error: ") and err.count("\n") == 1 and all(n in err for n in needles), err
        assert snapshot(tmp_path / "out") == previous


def test_table_has_at_least_60_cases():
    assert len(SET_CASES) + len(FILE_CASES) + len(BUNDLE_CASES) + len(CLI_IDS) >= 60
