"""The flank-contact bench (workflow.bench.flank_contact) end to end on the coarsest grid: how the
flanks bear under the preload and the held-amplitude worn state, kept per grid."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest


@pytest.mark.slow   # ~7 s (mesh, assembly, reduction and one march): in make test-slow
def test_the_bench_keeps_each_worn_state_with_the_rows_it_reports(tmp_path):
    from workflow.bench import flank_contact

    out, models = tmp_path / "out", tmp_path / "models"
    flank_contact.main(["--grids", "4x2", "--grading", "0.5", "--models", str(models), "--out", str(out)])
    rows = list(csv.DictReader(open(out / "flank_contact.csv")))
    assert [r["flank"] for r in rows] == ["0", "1"] and all(r["flank_grading"] == "0.5" for r in rows)
    # both flanks carry the preload; their loads agree to the flanks' symmetry (measured 1509–1650 N)
    loads = [float(r["normal_load_n"]) for r in rows]
    assert all(1e3 < n < 3e3 for n in loads)
    w = np.load(out / "worn-4x2.npz")
    assert float(rows[0]["worn_volume_m3"]) == pytest.approx(float(w["W"] @ w["area"]), rel=1e-12)
    assert float(rows[0]["max_wear_m"]) == pytest.approx(float(w["W"].max()), rel=1e-12) and w["W"].max() > 0
    assert rows[0]["steady"] == "True"
    for r in rows:          # each row's own flank: Σ W·A over its pairs
        on = w["flank"] == int(r["flank"])
        assert float(r["flank_worn_volume_m3"]) == pytest.approx(float(w["W"][on] @ w["area"][on]), rel=1e-12)
        # the profile seen at ℓ: an average, so no deeper than the flank's deepest pair nor below its RMS
        l2, top = float(r["profile_l2_m"]), float(r["filtered_max_m"])
        assert float(r["measure_length_m"]) > 0 and 0 <= l2 <= top <= w["W"][on].max() * (1 + 1e-12)
        assert (l2 > 0) == (w["W"][on].max() > 0)
    # on this grid the extrados sticks everywhere under the held tip: it wears exactly nothing (a pair
    # on the Coulomb cone to round-off once wore it ~1e-18 m, workflow.engine.contact._ROUND)
    assert float(rows[1]["flank_worn_volume_m3"]) == 0.0 < float(rows[0]["flank_worn_volume_m3"])
    assert (models / "model-4x2-g0.5.npz").exists()      # the model is kept under its grading
    # the march's path: W grows pair by pair (Archard's rates are ≥ 0) and ends at the kept W
    c, Wh = w["cycles"], w["W_history"]
    assert np.all(np.diff(c) > 0) and Wh.shape == (c.size, w["W"].size)
    np.testing.assert_array_equal(Wh[-1], w["W"])
    assert np.all(np.diff(Wh, axis=0) >= -1e-12 * w["W"].max())

    # the same worn state read back: the worn − new resonance and the worn flanks' bearing
    again = tmp_path / "again"
    flank_contact.main(["--grids", "4x2", "--grading", "0.5", "--models", str(models), "--worn", str(out),
                        "--shift", "--out", str(again)])
    back = list(csv.DictReader(open(again / "flank_contact.csv")))
    assert [r["worn_volume_m3"] for r in back] == [r["worn_volume_m3"] for r in rows]
    for r in back:
        # contact worn away softens the root: the friction-damped resonance falls, by far less than 1 %
        assert -1e-2 < float(r["resonance_shift_rel"]) < 0
        on = w["flank"] == int(r["flank"])
        scar = w["area"][on][w["W"][on] >= 0.05 * w["W"].max()].sum()
        assert float(r["scar_area_m2"]) == pytest.approx(scar, rel=1e-12)
        assert 0 <= float(r["worn_open_share"]) <= 1

    # the wear response curve under the scene's force: each point's worn state kept with its row,
    # the cliff's bisection's too; at the grid's own friction-damped resonance the blade wears
    # deeper than 0.5 % below it
    curve = tmp_path / "curve"
    flank_contact.main(["--grids", "4x2", "--grading", "0.5", "--models", str(models), "--response", "1,0.995",
                        "--shift", "--set", 'wear.control="force"', "--set", "wear.response_refine=1",
                        "--out", str(curve)])
    pts = list(csv.DictReader(open(curve / "wear_response.csv")))
    z = np.load(curve / "response-4x2.npz")
    assert [float(r["detuning"]) for r in pts] == [0.995, 0.9975, 1.0] == list(z["detunings"])
    assert [r["refined"] for r in pts] == ["False", "True", "False"]
    for r, W in zip(pts, z["W"]):
        assert r["control"] == "force" and r["steady"] == "True"
        # the csv keeps 9 significant digits
        assert float(r["frequency_hz"]) == pytest.approx(float(r["detuning"]) * float(r["resonance_hz"]), rel=1e-8)
        assert float(r["max_wear_m"]) == pytest.approx(W.max(), rel=1e-8)
        assert float(r["worn_volume_m3"]) == pytest.approx(W @ z["area"], rel=1e-8)
    assert float(pts[-1]["worn_volume_m3"]) > float(pts[0]["worn_volume_m3"]) > 0
    # wear lowers the resonance, so the worn blade sees a higher detuning than the new one; worn at
    # its new peak it wears until that peak has passed below the excitation
    assert all(float(r["worn_detuning"]) > float(r["detuning"]) for r in pts)
    assert float(pts[-1]["worn_detuning"]) > 1.0


def test_a_worn_state_of_other_pairs_is_refused(tmp_path):
    from types import SimpleNamespace

    from workflow.bench.flank_contact import saved_worn

    model = SimpleNamespace(position=np.zeros((3, 3)))
    np.savez(tmp_path / "worn-2x2.npz", W=np.zeros(4), position=np.zeros((4, 3)))
    with pytest.raises(SystemExit, match="worn-2x2.npz holds other pairs"):
        saved_worn(tmp_path / "worn-2x2.npz", model)
    with pytest.raises(SystemExit, match="no worn state"):
        saved_worn(tmp_path / "worn-3x3.npz", model)


def _synthetic_mesh(folder, grid, pairs, q, W, x):
    """One grid's flank_contact.csv (two flank rows) and worn-AxC.npz with chosen values."""
    from workflow.io import write_npz, write_rows

    rows = [{"grid": grid, "pairs": pairs, "flank": f, "worn_volume_m3": q, "max_wear_m": float(W.max()),
             "flank_worn_volume_m3": q / 2, "profile_l2_m": 3.0 * q, "filtered_max_m": 2.0 * q * (1 + f)}
            for f in (0, 1)]
    write_rows(folder / "flank_contact.csv", rows)
    write_npz(folder / f"worn-{grid}.npz", W=W, position=np.column_stack([x, 0 * x, 0 * x]))


def test_the_convergence_summary_recovers_a_known_order_and_leaves_out_the_axial_ends(tmp_path):
    """q(h) = q* + C h^p on h ∝ pairs^(-1/2): the observed order is p and the GCI Roache's closed
    form F_s|q₂ − q₃|/(|q₃|(r^p − 1)); the inner max leaves out the pairs within the end band."""
    from workflow.bench import flank_convergence as fc

    p, qs, C = 1.5, 2.0e-10, 3.0e-10
    folders = []
    for k, (grid, pairs) in enumerate((("a", 100), ("b", 200), ("c", 400), ("d", 800))):
        folder = tmp_path / grid
        folder.mkdir()
        x = np.linspace(0.0, 0.04, 9)
        W = np.full(9, 1e-6)
        W[0], W[4] = 5e-6 - k * 1e-7, 2e-6           # the deepest pair at an axial end, another inside
        _synthetic_mesh(folder, grid, pairs, qs + C * pairs ** (-p / 2), W, x)
        folders.append(folder)
    rows = fc.mesh_rows(folders[::-1], end_band=0.002)       # any order in, sorted by pairs out
    assert [m["pairs"] for m in rows] == [100, 200, 400, 800]
    assert all(m["inner_max_wear_m"] == pytest.approx(2e-6) for m in rows)
    assert rows[0]["max_wear_m"] == pytest.approx(5e-6)
    assert rows[0]["profile_l2_m"] == pytest.approx(np.hypot(3.0 * rows[0]["worn_volume_m3"],
                                                             3.0 * rows[0]["worn_volume_m3"]))
    s = fc.summary(rows)["measures"]["worn_volume_m3"]
    assert s["observed_order"] == pytest.approx(p, rel=1e-6)
    q2, q3, r = s["values"][-2], s["values"][-1], 2.0 ** 0.5
    assert s["gci"] == pytest.approx(1.25 * abs(q2 - q3) / (q3 * (r ** p - 1)), rel=1e-6)
    assert s["change_last"] == pytest.approx(abs(q2 - q3) / q3) and s["difference_last"] == pytest.approx(q3 - q2)


def test_the_convergence_summary_reads_wear_response_curves(tmp_path):
    """A wear response curve's peak is its largest worn volume among the points that reached a
    worn steady state (a point stopped on persistent slip is not a worn state, however deep);
    its measures at each f / f_r line up over the meshes, and a point only one mesh has has no
    change."""
    from workflow.bench import flank_convergence as fc
    from workflow.io import write_rows

    rows = []
    for grid, pairs, top in (("a", 100, 2.0e-9), ("b", 400, 2.1e-9)):
        rows += [{"grid": grid, "pairs": pairs, "detuning": r, "steady": st, "worn_volume_m3": v,
                  "max_wear_m": 1e3 * v, "profile_l2_m": 1e2 * v}
                 for r, st, v in ((0.995, True, 0.5e-9), (0.998, True, top), (1.0, True, 1.0e-9),
                                  (1.005, False, 9.0e-9))]
    rows.append({"grid": "b", "pairs": 400, "detuning": 1.01, "steady": True, "worn_volume_m3": 1e-11,
                 "max_wear_m": 1e-8, "profile_l2_m": 1e-9})
    write_rows(tmp_path / "wear_response.csv", rows)
    meshes = fc.mesh_rows([tmp_path], end_band=0.002)
    assert [m["pairs"] for m in meshes] == [100, 400]
    assert [m["response_peak_volume_m3"] for m in meshes] == [2.0e-9, 2.1e-9]
    assert all(m["response_peak_detuning"] == 0.998 for m in meshes)
    s = fc.summary(meshes)["measures"]
    assert s["response_peak_volume_m3"]["change_last"] == pytest.approx(0.1 / 2.1)
    assert s["response_max_wear_m@1"]["values"] == [pytest.approx(1e-6), pytest.approx(1e-6)]
    assert s["response_worn_volume_m3@1.01"]["values"] == [None, 1e-11]
    assert s["response_worn_volume_m3@1.01"]["change_last"] is None
    assert all(m["response_cliff_low"] is None for m in meshes)      # no worn detunings: no cliff
    fc.main([str(tmp_path), "--out", str(tmp_path / "out")])
    assert (tmp_path / "out" / "wear_response_meshes.png").stat().st_size > 0
    assert json.loads((tmp_path / "out" / "flank_convergence.json").read_text())["pairs"] == [100, 400]


def test_a_bisected_cliff_enters_the_peak_and_the_bracket_not_the_points(tmp_path):
    """Points a mesh's bisection of its cliff added (``refined``) lie at that mesh's own f / f_r:
    they enter its peak and its cliff's bracket, not the per-point measures the meshes share."""
    from workflow.bench import flank_convergence as fc
    from workflow.io import write_rows

    rows = [{"grid": "a", "pairs": 100, "detuning": r, "steady": True, "worn_volume_m3": v, "max_wear_m": 1e4 * v,
             "profile_l2_m": 1e3 * v, "worn_detuning": wd, "refined": ref}
            for r, v, wd, ref in ((0.995, 0.1e-9, 0.9952, False), (0.9965, 0.2e-9, 0.9972, True),
                                  (0.99725, 1.4e-9, 1.0019, True), (0.998, 1.3e-9, 1.0026, False))]
    write_rows(tmp_path / "wear_response.csv", rows)
    (m,) = fc.mesh_rows([tmp_path], end_band=0.002)
    assert (m["response_cliff_low"], m["response_cliff_high"]) == (0.9965, 0.99725)
    assert m["response_peak_volume_m3"] == 1.4e-9 and m["response_peak_detuning"] == 0.99725
    assert "response_worn_volume_m3@0.99725" not in m and m["response_worn_volume_m3@0.998"] == 1.3e-9
