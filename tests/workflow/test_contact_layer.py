"""The contact's interface layer in the stages (``contact.stiffness_n``, ``stiffness_t``; reduction/layer.py)."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

from workflow.errors import SceneError
from workflow.scene import load_scene


@pytest.mark.parametrize("stage", ["mistuning", "extreme", "interface_scaling"])
def test_stages_without_a_layer_refuse_one_naming_the_keys(stage, tmp_path):
    """A stage that takes the rigid contact only says so before it computes anything, rather than
    silently dropping the layer."""
    import importlib

    scene = load_scene("quick", ["contact.stiffness_t=1e14"])
    run = importlib.import_module(f"workflow.stages.{stage}").run
    with pytest.raises(SceneError, match=r"contact\.stiffness_n = 0, contact\.stiffness_t = 1e\+14"):
        run(scene, {"reduced": str(tmp_path / "none")}, tmp_path, None)


@pytest.mark.slow
def test_quick_sector_with_a_layer_is_softer_and_says_so(tmp_path):
    """The quick scene end to end with k_n = k_t = 1e14 N/m³: the FRF and the wear report the
    layer, the tied resonance (interface stuck on its springs) lies below the rigid one the assembly
    reports, by a fraction of the layer's compliance share (here ~2e-4), and the worn steady state
    passes its own Nh- and ε-checks (≤ 1e-3, the stage's tolerance)."""
    out = tmp_path / "q"
    r = subprocess.run([str(Path(sys.executable).parent / "bladewear"), "run", "quick", "--out", str(out),
                        "--cache", str(tmp_path / "c"), "--quiet", "--set", 'run.outputs=["frf", "wear"]',
                        "--set", "contact.stiffness_n=1e14", "--set", "contact.stiffness_t=1e14"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    s = json.loads((out / "summary.json").read_text())
    layer = {"normal_n_per_m3": 1e14, "tangential_n_per_m3": 1e14}
    assert s["hb"]["contact_stiffness"] == layer and s["wear"]["contact_stiffness"] == layer
    rigid, soft = s["assembly"]["first_tied_hz"], s["hb"]["tied_frequency_hz"]
    assert 0 < (rigid - soft) / rigid < 1e-2, (rigid, soft)
    w = s["wear"]
    assert w["methods"]["pseudo-time"]["steady"]
    for chk in (w["nh_check"], w["eps_check"]):
        assert chk["steady"] and chk["max_rel_change"] < 1e-3, chk


def test_cyclic_sector_gets_the_layer_on_every_nodal_diameter():
    """A tuned disk's sector (complex Hermitian ND operators): each harmonic's Z_r on its own ND is
    the series of the bare ND's Z_r and the (real) springs k·A, to round-off."""
    import numpy as np

    from cyclicmodels import sector_bundle
    from workflow.engine.condense import condense, relative_coordinates
    from reduction.cyclic_reduce import reduce_cyclic
    from reduction.layer import layer_stiffness, with_interface_layer

    cyc = reduce_cyclic(sector_bundle(5), 3, 2)
    kn, kt, omega = 3e2, 1e2, 2.7
    layered = with_interface_layer(cyc, kn, kt)
    assert sorted(layered.models) == sorted(cyc.models)
    c0 = condense(relative_coordinates(cyc), omega, 2)
    c1 = condense(relative_coordinates(layered), omega, 2)
    k = layer_stiffness(cyc.area, kn, kt)
    for j in (1, 2):
        beta = layered.models[cyc.nodal_diameters(2)[j]].info["interface_layer"]["damping_beta"] or 0.0
        Z = np.linalg.inv(np.linalg.inv(c0.Zr[j]) + np.diag(1.0 / (k * (1 + 1j * j * omega * beta))))
        np.testing.assert_allclose(c1.Zr[j], Z, rtol=0, atol=1e-9 * np.abs(Z).max())


def test_punch_on_an_interface_layer_wears_as_the_closed_form_punch():
    """Reference (b) built through the layer (:func:`workflow.verification.wear_exact.layered_punch`):
    a rigid punch whose three contacts are layer springs k_n·A_i, each contact's structure side
    driven along t1 through a spring K_s, is the :class:`PunchWear` with k_n,i = k_n A_i and
    k_t,i = (1/K_s + 1/(k_t A_i))⁻¹. The engine's pseudo-time march (rtol 1e-4) stops as persistent
    slip, follows the closed form W(n) within the bound the rigid punch test holds it to (1e-4 of
    max W; measured 4.1e-6), and its final rates are the closed-form sinking speed V within the
    march's tolerance (3e-3, the same test's; measured 2.3e-4)."""
    from workflow.verification.wear_runner import punch_layer_rows

    rows = {r["quantity"].split(" (")[0]: r for r in punch_layer_rows()}
    assert rows["stopped as persistent slip"]["value"] == 1.0
    assert rows["W(n) worst point, error / max W at the end"]["error"] < 1e-4
    for name in ("edge", "centre"):
        assert rows[f"final wear rate {name} [m/cycle] vs sinking speed V"]["error"] < 3e-3
