"""The real blade–disk sector with periodic cut faces (geometry.cyclic): the
per-ND reduction against the unreduced Hermitian sector operators, and the
cyclic-frf scene end to end (FRF and worn steady state of the tuned disk)."""
from __future__ import annotations

import json

import numpy as np
import pytest

pytestmark = pytest.mark.slow  # meshing, assembly and four complex reductions: ~25 s


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    from workflow.pipeline import run_scene
    from workflow.scene import load_scene

    tmp = tmp_path_factory.mktemp("cyclic")
    scene = load_scene("cyclic-frf", ["sweep.points=7"])
    run_scene(scene, tmp / "out", cache=tmp / "cache", quiet=True)
    return tmp / "out"


def test_scene_runs_frf_and_wear_on_the_nodal_diameters_of_the_harmonics(run):
    s = json.loads((run / "summary.json").read_text())
    red, hb, wear = s["reduction"], s["hb"], s["wear"]
    assert red["nodal_diameters"] == [0, 3, 6, 9, 12, 15] and red["cyclic"]    # harmonics 0…5: the Nh-check's too
    assert hb["cyclic"] == {"n_sectors": 47, "engine_order": 3, "nodal_diameters": [0, 3, 6, 9]}
    r = hb["runs"][0]
    assert r["converged_points"] == r["points"] == 7 and not hb["unconverged"]
    assert abs(r["peak_hz"] - hb["tied_frequency_hz"]) < 0.1 * hb["tied_frequency_hz"]
    assert wear["cyclic"]["nodal_diameters"] == [0, 3, 6, 9] and not wear["unconverged"]
    W = wear["methods"]["pseudo-time"]
    assert W["steady"] and 0 < W["max_wear_m"] < 1e-3       # worn, steady, and a fretting depth (< 1 mm)
    assert (run / "wear" / "wear.csv").exists()


def test_per_nd_reduction_matches_the_unreduced_sector_operators(run):
    """Tied frequencies of the Craig–Bampton ND models (30 modes) against eigsh on
    the full Hermitian ND operators: ND 0 (real) and ND 3 (complex)."""
    from reduction.bundle import read_bundle
    from reduction.cyclic_reduce import reduce_cyclic, reduced_tied_frequencies, tied_frequencies
    from workflow.stages.assembly import bundle_folder

    folder = next(p for p in run.glob("**/assembly") if p.is_dir())
    bundle = read_bundle(bundle_folder(folder))
    cyc = reduce_cyclic(bundle, 3, 1, n_modes=30)
    assert sorted(cyc.models) == [0, 3] and np.iscomplexobj(cyc.models[3].K)
    for k, m in cyc.models.items():
        ref = tied_frequencies(bundle, k, 5)
        red = reduced_tied_frequencies(m, 5)
        assert np.all(red >= ref * (1 - 1e-9))            # a Ritz approximation is an upper bound
        np.testing.assert_allclose(red, ref, rtol=1e-4)
