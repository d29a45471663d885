"""The remap stage end to end on the two-block dovetail: bundle + wear.csv →
wear map XDMF, worn mesh, figures, worn bundle and frequency shifts."""
from __future__ import annotations

import json
import types

import numpy as np
import pytest

pytest.importorskip("dolfinx")
pytest.importorskip("pyvista")


@pytest.fixture(scope="module")
def upstream(tmp_path_factory):
    from geometry.twoblock import TwoBlockParams, build_two_block
    from reduction import dolfinx_compat as dc
    from reduction.assemble import build_bundle
    from reduction.bundle import write_bundle
    from workflow import params
    from workflow.report.wear import write_wear_csv

    root = tmp_path_factory.mktemp("remap_stage")
    p = TwoBlockParams(h=0.004, nodes_along=5, nodes_across=3)
    msh, ct, ft = build_two_block(p)
    info = {"tip_point": [p.length / 2, 0.0, p.height], "excitation_direction": [1.0, 0.0, 0.0]}
    # A static tip force presses the trapezoidal root into its slot (preload for the FRF).
    excitation = params.Excitation(amplitude=0.5, static_force=2000.0)
    bundle, _ = build_bundle(msh, ct, ft, info, params.Material(), params.Rotation(),
                             params.Damping(modal_ratio=0.01), excitation)
    (root / "stage").mkdir()
    dc.write_mesh_xdmf(msh, ct, ft, root / "stage" / "mesh.xdmf")
    write_bundle(bundle, root / "assembly" / "model",
                 extra_files={"mesh.xdmf": root / "stage" / "mesh.xdmf", "mesh.h5": root / "stage" / "mesh.h5"})
    pos = bundle.contact.position
    # µm-scale, like the quick sector: the worn pairs stay pressed by the preload.
    W = 1e-6 * np.exp(-((pos[:, 0] - 0.01) / 0.006) ** 2) * (0.5 + pos[:, 2] / p.height)
    write_wear_csv(root / "wear" / "wear.csv", pos, bundle.contact.flank,
                   {"implicit": types.SimpleNamespace(W=W), "pseudo-time": types.SimpleNamespace(W=0.9 * W)}, 0.5)
    scene = {k: cls() for k, cls in params.SECTIONS.items()}
    scene["damping"] = params.Damping(modal_ratio=0.01)
    scene["excitation"] = excitation
    scene["reduction"] = params.Reduction(modes=20)
    scene["sweep"] = params.Sweep(points=9)
    scene["wear"] = params.Wear(methods=["pseudo-time", "implicit"], blade_share=0.5)
    scene["modes"] = params.Modes(count=3)
    return root, scene, W


def _reduced_new(root, scene):
    """The reduction stage's product for the upstream bundle (same settings as the stage's)."""
    from reduction.bundle import read_bundle
    from reduction.reduce import reduce_bundle

    folder = root / "reduction"
    if not (folder / "reduced.npz").is_file():
        folder.mkdir(exist_ok=True)
        reduce_bundle(read_bundle(root / "assembly" / "model"), n_modes=scene["reduction"].modes).save(
            folder / "reduced.npz")
    return folder


@pytest.fixture(scope="module")
def worn_run(upstream, tmp_path_factory):
    """The stage run once on the upstream wear (reassemble on): (summary, out folder, logged lines)."""
    from workflow.stages import remap as stage

    root, scene, _ = upstream
    out = tmp_path_factory.mktemp("remap_out")
    lines = []
    log = types.SimpleNamespace(info=lines.append, note=lines.append, progress=lambda it, total=None, label="": it)
    s = stage.run(scene, {"bundle": root / "assembly", "wear": root / "wear", "reduced": _reduced_new(root, scene)},
                  out, log)
    return s, out, lines


@pytest.mark.slow  # 4–9 s on the 2-core machine: make test-slow keeps make test within 3 min
def test_remap_stage_outputs(upstream, worn_run):
    root, scene, W = upstream
    s, tmp_path, lines = worn_run
    json.dumps(s)  # JSON-serialisable summary
    assert s["wear_column"] == "pseudo-time"  # first of wear.methods present in the CSV
    # Largest node motion = largest share (0.5 × 0.9 × max W on both bodies).
    np.testing.assert_allclose(s["max_node_motion_m"], 0.5 * 0.9 * W.max(), rtol=1e-8)  # CSV: 10 digits
    np.testing.assert_allclose(s["max_node_motion_m"], s["max_wear_share_m"], rtol=1e-12)
    for key in ("worn_mesh", "wear_map", "worn_nodes"):
        assert (tmp_path / s[key]).is_file()
    assert len(s["figures"]) == 3, lines
    assert all((tmp_path / f).stat().st_size > 20_000 for f in s["figures"])
    assert "figures/frf_worn_vs_new.png" in s["figures"]
    # The interactive 3D view: one self-contained page (no network), small.
    page = (tmp_path / s["viewer_3d"]).read_text()
    assert s["viewer_3d_bytes"] == len(page.encode()) < 10e6
    assert "http://" not in page and "https://" not in page
    # Every figure's path is logged (make demo shows where the maps are).
    for f in s["figures"]:
        assert any(f"remap/{f}" in line for line in lines)
    # The worn reduced model is saved for a wear study on the worn geometry.
    from workflow.engine.model import ReducedModel

    red = ReducedModel.load(tmp_path / s["reduced"])
    np.testing.assert_allclose(np.sort(red.gap), np.sort(0.9 * W), rtol=1e-8)
    for key in ("frf_peak_hz", "frf_peak_amplitude_m"):
        assert set(s[key]) == {"new", "worn"} and all(np.isfinite(v) and v > 0 for v in s[key].values())
    # Re-assembled worn model: a bundle that reads back, wear carried into the gap.
    from reduction.bundle import read_bundle

    worn = read_bundle(tmp_path / s["worn_bundle"])
    assert worn.meta["gap_includes_wear"]
    np.testing.assert_allclose(np.sort(worn.contact.gap), np.sort(0.9 * W), rtol=1e-8)  # CSV: 10 digits
    shift = np.array(s["freq_shift_hz"])
    assert len(shift) == 3 and np.all(np.isfinite(shift))
    # Removing µm of material from mm-sized bodies shifts frequencies by a tiny fraction.
    assert np.all(np.abs(shift) < 1e-3 * np.array(s["freq_new_hz"]))


def test_remap_stage_refuses_excessive_wear(upstream, tmp_path):
    from workflow.errors import GeometryError
    from workflow.params import Remap
    from workflow.stages import remap as stage
    from workflow.report.wear import write_wear_csv
    from reduction.bundle import read_bundle

    root, scene, W = upstream
    b = read_bundle(root / "assembly" / "model")
    write_wear_csv(tmp_path / "wear" / "wear.csv", b.contact.position, b.contact.flank,
                   {"implicit": types.SimpleNamespace(W=W * 4500)}, 0.5)  # ~4.5 mm of wear
    scene = dict(scene, remap=Remap(reassemble=False))
    log = types.SimpleNamespace(info=lambda msg: None, note=lambda msg: None)
    with pytest.raises(GeometryError, match="max_fraction"):
        stage.run(scene, {"bundle": root / "assembly", "wear": tmp_path / "wear"}, tmp_path / "out", log)


@pytest.mark.slow   # ~10 s: in make test-slow, to keep make test within 3 minutes on 2 cores
def test_zero_wear_reassembly_has_no_frequency_shift(upstream, tmp_path):
    """The shift is caused by the wear alone: zero wear re-assembles the same model."""
    from reduction.bundle import read_bundle
    from workflow.stages import remap as stage
    from workflow.report.wear import write_wear_csv

    root, scene, _ = upstream
    b = read_bundle(root / "assembly" / "model")
    write_wear_csv(tmp_path / "wear" / "wear.csv", b.contact.position, b.contact.flank,
                   {"implicit": types.SimpleNamespace(W=np.zeros(b.contact.n_pairs))}, 0.5)
    log = types.SimpleNamespace(info=lambda msg: None, note=lambda msg: None)
    s = stage.run(scene, {"bundle": root / "assembly", "wear": tmp_path / "wear",
                          "reduced": _reduced_new(root, scene)}, tmp_path / "out", log)
    assert s["max_node_motion_m"] == 0.0
    np.testing.assert_allclose(s["freq_shift_hz"], 0.0, atol=1e-8 * max(s["freq_new_hz"]))
    # Zero wear: the worn model is the new one, so is its nonlinear FRF peak.
    assert s["frf_converged"]["new"] == s["frf_converged"]["worn"] > 0
    # refined peaks (bounded search): equal to its tolerance
    from workflow.engine.studies.compare import PEAK_XTOL

    assert abs(s["frf_peak_hz"]["worn"] - s["frf_peak_hz"]["new"]) <= 2 * PEAK_XTOL * s["frf_tied_hz"]["new"]
    np.testing.assert_allclose(s["frf_peak_amplitude_m"]["worn"], s["frf_peak_amplitude_m"]["new"], rtol=1e-6)


@pytest.mark.slow  # 4–9 s on the 2-core machine: make test-slow keeps make test within 3 min
def test_worn_reduced_model_keeps_the_full_worn_tied_frequencies(upstream, worn_run):
    """The worn reduced model's tied frequencies are those of the re-assembled
    full worn model (the freq shift computation) to reduction accuracy."""
    from workflow.engine.condense import relative_coordinates
    from workflow.engine.model import ReducedModel
    from workflow.engine.linear import tied_modes

    root, scene, _ = upstream
    s, out, _ = worn_run

    def tied(path, f_full):
        f = np.sort(tied_modes(relative_coordinates(ReducedModel.load(path)))[0])
        return f[f > 1e-3 * f_full[0]][:len(f_full)]  # drop rigid-body zeros, if any

    f_new, f_worn = np.array(s["freq_new_hz"]), np.array(s["freq_worn_hz"])
    err_new = tied(_reduced_new(root, scene) / "reduced.npz", f_new) / f_new - 1.0
    err_worn = tied(out / s["reduced"], f_worn) / f_worn - 1.0
    # Reduction accuracy: the worn reduction errs exactly as the new one (same
    # modes kept, a µm-changed geometry), and both are small.
    assert np.all(np.abs(err_worn) < 3e-3)
    np.testing.assert_allclose(err_worn, err_new, atol=1e-6)
    # The FRF grid is centred on the new model's first excited tied mode, which the worn one barely moves.
    assert abs(s["frf_tied_hz"]["worn"] - s["frf_tied_hz"]["new"]) < 1e-3 * s["frf_tied_hz"]["new"]


@pytest.mark.slow  # 4–9 s on the 2-core machine: make test-slow keeps make test within 3 min
def test_worn_static_state_is_the_new_one_with_wear_as_gap(upstream, worn_run):
    """The worn bundle's gap carries W and its geometry the removed material:
    its static contact state equals the new model's with the wear applied in
    the contact law (gap + W), up to the O(W/h) stiffness change — not with
    the wear counted twice."""
    from workflow.engine.condense import condense, relative_coordinates
    from workflow.engine.model import ReducedModel
    from workflow.engine.contact import ContactLaw
    from workflow.engine import contact_law, static_state
    from workflow.engine.linear import first_excited_mode

    root, scene, W = upstream
    s, out, _ = worn_run
    new = ReducedModel.load(_reduced_new(root, scene) / "reduced.npz")
    worn = ReducedModel.load(out / s["reduced"])
    np.testing.assert_allclose(worn.position, new.position, atol=2 * W.max())  # same pair order
    W_pairs = worn.gap - new.gap
    assert W_pairs.max() > 0 and np.all(W_pairs >= 0)

    def state(model, gap, wear):
        rc = relative_coordinates(model)
        c = condense(rc, 2 * np.pi * first_excited_mode(rc)[0], 0)
        ct = scene["contact"]
        base = contact_law(new, mu=ct.mu, factor=ct.penalty_factor)
        law = ContactLaw(mu=base.mu, eps_n=base.eps_n, eps_t=base.eps_t, gap=gap, wear=wear)
        return static_state(c.Zr, c.Fr, law)

    worn_st = state(worn, worn.gap, np.zeros_like(W_pairs))
    new_st = state(new, new.gap, W_pairs)
    twice = state(worn, worn.gap, W_pairs)
    lam_w, lam_n, lam_2 = worn_st.lam[:, 0], new_st.lam[:, 0], twice.lam[:, 0]
    top = np.abs(lam_n).max()
    assert np.array_equal(worn_st.state != 0, new_st.state != 0)
    assert np.abs(lam_w - lam_n).max() < 0.02 * top
    # Counting the wear twice is visibly different (the check is sensitive).
    assert np.abs(lam_2 - lam_n).max() > 5 * np.abs(lam_w - lam_n).max()
