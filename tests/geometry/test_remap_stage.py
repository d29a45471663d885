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
    from workflow.wear import write_wear_csv

    root = tmp_path_factory.mktemp("remap_stage")
    p = TwoBlockParams(h=0.004, nodes_along=5, nodes_across=3)
    msh, ct, ft = build_two_block(p)
    info = {"tip_point": [p.length / 2, 0.0, p.height], "excitation_direction": [1.0, 0.0, 0.0]}
    bundle, _ = build_bundle(msh, ct, ft, info, params.Material(), params.Rotation(),
                             params.Damping(modal_ratio=0.0), params.Excitation())
    (root / "stage").mkdir()
    dc.write_mesh_xdmf(msh, ct, ft, root / "stage" / "mesh.xdmf")
    write_bundle(bundle, root / "assembly" / "model",
                 extra_files={"mesh.xdmf": root / "stage" / "mesh.xdmf", "mesh.h5": root / "stage" / "mesh.h5"})
    pos = bundle.contact.position
    W = 15e-6 * np.exp(-((pos[:, 0] - 0.01) / 0.006) ** 2) * (0.5 + pos[:, 2] / p.height)
    write_wear_csv(root / "wear" / "wear.csv", pos, bundle.contact.flank,
                   {"implicit": types.SimpleNamespace(W=W), "pseudo-time": types.SimpleNamespace(W=0.9 * W)}, 0.5)
    scene = {k: cls() for k, cls in params.SECTIONS.items()}
    scene["damping"] = params.Damping(modal_ratio=0.0)
    scene["wear"] = params.Wear(methods=["pseudo-time", "implicit"], blade_share=0.5)
    scene["modes"] = params.Modes(count=3)
    return root, scene, W


def test_remap_stage_outputs(upstream, tmp_path):
    from workflow.stages import remap as stage

    root, scene, W = upstream
    log = types.SimpleNamespace(info=lambda msg: None, progress=lambda it, total=None, label="": it)
    s = stage.run(scene, {"bundle": root / "assembly", "wear": root / "wear"}, tmp_path, log)
    json.dumps(s)  # JSON-serialisable summary
    assert s["wear_column"] == "pseudo-time"  # first of wear.methods present in the CSV
    # Largest node motion = largest share (0.5 × 0.9 × max W on both bodies).
    np.testing.assert_allclose(s["max_node_motion_m"], 0.5 * 0.9 * W.max(), rtol=1e-8)  # CSV: 10 digits
    np.testing.assert_allclose(s["max_node_motion_m"], s["max_wear_share_m"], rtol=1e-12)
    for key in ("worn_mesh", "wear_map", "worn_nodes"):
        assert (tmp_path / s[key]).is_file()
    assert len(s["figures"]) == 2 and all((tmp_path / f).stat().st_size > 50_000 for f in s["figures"])
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
    from workflow.wear import write_wear_csv
    from reduction.bundle import read_bundle

    root, scene, W = upstream
    b = read_bundle(root / "assembly" / "model")
    write_wear_csv(tmp_path / "wear" / "wear.csv", b.contact.position, b.contact.flank,
                   {"implicit": types.SimpleNamespace(W=W * 300)}, 0.5)  # ~4.5 mm of wear
    scene = dict(scene, remap=Remap(reassemble=False))
    log = types.SimpleNamespace(info=lambda msg: None)
    with pytest.raises(GeometryError, match="max_fraction"):
        stage.run(scene, {"bundle": root / "assembly", "wear": tmp_path / "wear"}, tmp_path / "out", log)


def test_zero_wear_reassembly_has_no_frequency_shift(upstream, tmp_path):
    """The shift is caused by the wear alone: zero wear re-assembles the same model."""
    from reduction.bundle import read_bundle
    from workflow.stages import remap as stage
    from workflow.wear import write_wear_csv

    root, scene, _ = upstream
    b = read_bundle(root / "assembly" / "model")
    write_wear_csv(tmp_path / "wear" / "wear.csv", b.contact.position, b.contact.flank,
                   {"implicit": types.SimpleNamespace(W=np.zeros(b.contact.n_pairs))}, 0.5)
    log = types.SimpleNamespace(info=lambda msg: None)
    s = stage.run(scene, {"bundle": root / "assembly", "wear": tmp_path / "wear"}, tmp_path / "out", log)
    assert s["max_node_motion_m"] == 0.0
    np.testing.assert_allclose(s["freq_shift_hz"], 0.0, atol=1e-8 * max(s["freq_new_hz"]))
