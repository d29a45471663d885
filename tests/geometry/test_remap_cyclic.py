"""The remap stage on a cyclic (tuned-disk) sector: the worn model stays a
cyclic sector, both models are reduced per nodal diameter, and the worn-vs-new
comparison is the cyclic harmonic balance's (docs/cyclic.md, brief 20c)."""
from __future__ import annotations

import json
import types

import numpy as np
import pytest

from workflow.engine.studies.compare import PEAK_XTOL

from workflow.errors import BundleError, GeometryError


# ------------------------------------------------------------ quick: the face check on arrays

def _sector(coords, low, high, n=47):
    from reduction.bundle import Cyclic

    dofs = lambda blocks: 3 * np.asarray(blocks)[:, None] + np.arange(3)  # noqa: E731
    return types.SimpleNamespace(coords=np.asarray(coords, float), cyclic=Cyclic(dofs(low), dofs(high), n))


def test_cyclic_face_check_compares_positions_not_numbering():
    from reduction.worn import check_cyclic_faces

    rng = np.random.default_rng(0)
    x = rng.random((8, 3))
    new = _sector(x, [0, 1, 2], [5, 6, 7])
    perm = rng.permutation(8)                     # the worn mesh numbers its nodes otherwise
    inv = np.argsort(perm)
    worn = _sector(x[perm], inv[[2, 0, 1]], inv[[7, 5, 6]])  # same pairs, other row order
    check_cyclic_faces(new, worn)
    check_cyclic_faces(types.SimpleNamespace(cyclic=None), worn)  # fixed-boundary: nothing to check
    moved = _sector(x[perm] + 0.0, inv[[2, 0, 1]], inv[[7, 5, 6]])
    moved.coords[inv[6]] += 1e-7                  # one high-face node moved by 0.1 µm
    with pytest.raises(GeometryError, match="cyclic face"):
        check_cyclic_faces(new, moved)
    with pytest.raises(GeometryError, match="re-paired"):  # same nodes, other partners
        check_cyclic_faces(new, _sector(x[perm], inv[[0, 1, 2]], inv[[6, 5, 7]]))
    for bad in (_sector(x, [0, 1, 2], [5, 6, 7], n=46), types.SimpleNamespace(coords=x, cyclic=None)):
        with pytest.raises(GeometryError, match="cyclic faces"):
            check_cyclic_faces(new, bad)


def test_a_fixed_boundary_reduced_model_is_refused_for_a_cyclic_bundle():
    from reduction.worn import new_and_worn

    cyclic = _sector(np.zeros((8, 3)), [0], [5])
    with pytest.raises(BundleError, match="cyclic"):
        new_and_worn(cyclic, cyclic, 3, 10, new_model=types.SimpleNamespace())  # a ReducedModel is not cyclic


# ------------------------------------------------------------ slow: the cyclic-frf sector end to end

@pytest.fixture(scope="module")
def upstream(tmp_path_factory):
    """cyclic-frf up to the wear stage: (run folder, scene, summary)."""
    pytest.importorskip("dolfinx")
    pytest.importorskip("pyvista")
    from workflow.pipeline import run_scene
    from workflow.scene import load_scene

    tmp = tmp_path_factory.mktemp("remap_cyclic")
    scene = load_scene("cyclic-frf", ['run.outputs=["frf", "wear"]'])
    run_scene(scene, tmp / "out", cache=tmp / "cache", quiet=True)
    return tmp / "out", scene, json.loads((tmp / "out" / "summary.json").read_text())


def _remap(upstream, tmp, W=None):
    """The remap stage on the upstream bundle with wear ``W(positions)`` per pair [m]
    (None: the wear stage's): (summary, out)."""
    from reduction.bundle import read_bundle
    from workflow.report.wear import write_wear_csv
    from workflow.stages import remap as stage
    from workflow.stages.assembly import bundle_folder

    run, scene, _ = upstream
    wear = run / "wear"
    if W is not None:
        b, wear = read_bundle(bundle_folder(run / "assembly")), tmp / "wear"
        write_wear_csv(wear / "wear.csv", b.contact.position, b.contact.flank,
                       {"pseudo-time": types.SimpleNamespace(W=W(b.contact.position))}, 0.5)
    log = types.SimpleNamespace(info=lambda msg: None, note=lambda msg: None, progress=lambda it, total=None, label="": it)
    s = stage.run(scene, {"bundle": run / "assembly", "wear": wear, "reduced": run / "reduction"},
                  tmp / "out", log)
    return s, tmp / "out"


@pytest.fixture(scope="module")
def zero_wear(upstream, tmp_path_factory):
    return _remap(upstream, tmp_path_factory.mktemp("zero"), lambda pos: np.zeros(len(pos)))


@pytest.mark.slow  # cyclic-frf to its wear stage + 2 remaps (4 ND reductions each): ~45 s
def test_zero_wear_cyclic_reassembly_has_no_shift_and_the_same_frf(upstream, zero_wear):
    from reduction.cyclic_reduce import CyclicReducedModel
    from workflow.engine.model import ReducedModel
    from workflow.stages import remap as stage
    from workflow.stages.reduction import load_model

    run, scene, _ = upstream
    s, out = zero_wear
    assert s["max_node_motion_m"] == 0.0
    assert s["freq_nodal_diameter"] == 3 and "ND 3" in s["freq_family"]  # EO 3 of 47: harmonic 1 on ND 3
    np.testing.assert_allclose(s["freq_shift_hz"], 0.0, atol=1e-8 * max(s["freq_new_hz"]))
    worn = CyclicReducedModel.load(out / s["reduced"])
    new = load_model(run / "reduction")
    assert s["reduced"] == "cyclic_reduced.npz" and sorted(worn.models) == sorted(new.models) == [0, 3, 6, 9, 12, 15]   # cyclic-frf reduces harmonics 0…5
    assert worn.info["modes"] == new.info["modes"] and worn.engine_order == new.engine_order
    # the new model is the ND-3 sector's, not the fixed-boundary one a ReducedModel would be
    assert not isinstance(new, ReducedModel)
    # Zero wear: the worn model is the new one, and so is its whole nonlinear FRF.
    frf = stage.worn_vs_new_frf(scene, new, worn)
    a_new, a_worn = (np.where(frf[k].converged, frf[k].amplitude, np.nan) for k in ("new", "worn"))
    assert frf["new"].converged.all() and frf["worn"].converged.all()
    # same grid and guesses on models equal up to the DOF numbering's round-off: the Newton paths
    # coincide and the FRFs differ by that floor (≤ 1e-8, test_mpi_quick), not by hb.tol (measured 1e-9)
    np.testing.assert_allclose(a_worn, a_new, rtol=1e-7)
    # the refined peaks agree to the bounded search's tolerance
    xtol = PEAK_XTOL * s["frf_tied_hz"]["new"]
    assert abs(s["frf_peak_hz"]["worn"] - s["frf_peak_hz"]["new"]) <= 2 * xtol


@pytest.mark.slow
def test_cyclic_remap_new_peak_is_the_cyclic_hb_peak(upstream, zero_wear):
    """Same model (the reduction stage's), same grid: the remap's "new" peak is the hb stage's."""
    _, _, summary = upstream
    s, _ = zero_wear
    hb = summary["hb"]["runs"][0]
    assert s["frf_points"] == hb["points"] and s["frf_band_hz"][0] < hb["peak_hz"] < s["frf_band_hz"][1]
    # the remap refines the hb stage's grid peak between its grid neighbours: within a grid
    # step of it, and at least as high (the grid point is one of the candidates)
    step = (s["frf_band_hz"][1] - s["frf_band_hz"][0]) / (s["frf_points"] - 1)
    assert abs(s["frf_peak_hz"]["new"] - hb["peak_hz"]) <= step
    assert s["frf_peak_amplitude_m"]["new"] >= hb["peak_amplitude_m"] * (1 - 1e-9)
    assert s["frf_tied_hz"]["new"] == pytest.approx(summary["hb"]["tied_frequency_hz"], rel=1e-12)


@pytest.mark.slow
def test_worn_cyclic_sector_keeps_its_faces_and_carries_the_wear(upstream, tmp_path):
    """The wear stage's µm profile: the worn bundle is still the tuned-disk
    sector, its gap holds W, its ND-3 tied frequencies move by a tiny fraction,
    and its reduced ND-3 model is as accurate as the new one."""
    from reduction.bundle import read_bundle
    from reduction.cyclic_reduce import CyclicReducedModel, reduced_tied_frequencies
    from workflow.report.wear import read_wear_csv
    from workflow.stages.reduction import load_model

    run, _, summary = upstream
    s, out = _remap(upstream, tmp_path)
    b_worn = read_bundle(out / s["worn_bundle"])
    assert b_worn.cyclic is not None and b_worn.cyclic.n_sectors == 47
    W = read_wear_csv(run / "wear" / "wear.csv", ("pseudo-time",))["W"]  # total depth per pair [m]
    assert W.max() == pytest.approx(summary["wear"]["methods"]["pseudo-time"]["max_wear_m"], rel=1e-8)
    np.testing.assert_allclose(np.sort(b_worn.contact.gap), np.sort(W), rtol=1e-8, atol=1e-15)
    shift, f_new = np.array(s["freq_shift_hz"]), np.array(s["freq_new_hz"])
    assert np.any(shift != 0.0) and np.all(np.abs(shift) < 1e-4 * f_new)
    # The reduced ND-3 models against the full sectors: the excited (first) mode to 1e-5; with the scene's
    # 10 modes per ND the next ones are 3e-4 off, the same for the new and the worn model (the basis, not the µm).
    err = {}
    for key, model in (("new", load_model(run / "reduction")), ("worn", CyclicReducedModel.load(out / s["reduced"]))):
        f_full = np.array(s[f"freq_{key}_hz"][:3])
        err[key] = reduced_tied_frequencies(model.models[3], 3) / f_full - 1
        assert np.all(err[key] > -1e-9) and err[key][0] < 1e-5  # Ritz: an upper bound
    np.testing.assert_allclose(err["worn"], err["new"], atol=1e-6)
    assert not s.get("frf_error"), s.get("frf_error")
    assert s["frf_converged"] == {"new": s["frf_points"], "worn": s["frf_points"]} and not s["unconverged"]
