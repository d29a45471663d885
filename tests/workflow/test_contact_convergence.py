"""Contact-convergence stage: its convergence arithmetic, the common flank points,
no interpenetration at the midside nodes with every node in contact, and a
small run of the stage."""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from workflow.errors import SceneError
from geometry.flankmap import common_points, profile_at
from workflow.engine.studies.meshstudy import grid_convergence_index, observed_order, rel_change, summarise
from workflow.stages import contact_convergence as cc


def test_observed_order_recovers_the_exponent_for_uneven_ratios():
    h = np.array([1.0, 0.5, 1 / 3, 0.25])
    for p in (1.0, 2.0, 0.5):
        q = 3.0 + 0.7 * h ** p
        assert observed_order(h, q) == pytest.approx(p, rel=1e-9)
    assert observed_order(h, [1.0, 2.0, 1.5, 1.7]) is None     # oscillating: no asymptotic range
    assert observed_order(h[:2], [1.0, 2.0]) is None
    assert rel_change(1.0, 1.25) == pytest.approx(0.2)
    assert rel_change(None, 1.0) is None


def test_the_grid_convergence_index_bounds_the_error_of_the_finest_mesh():
    """q = q∞ + C hᵖ on meshes in the asymptotic range: the GCI (F_s = 1.25) is 1.25 × the
    Richardson estimate of the finest mesh's error, so it holds the exact error with that margin;
    oscillating changes or an order below ½ give none."""
    h = np.array([0.02, 0.013, 0.009])
    for p in (0.7, 1.0, 2.0):
        q = 5.0 + 0.8 * h ** p
        err = abs(q[-1] - 5.0) / q[-1]
        assert grid_convergence_index(h, q) == pytest.approx(1.25 * err, rel=1e-9)
    assert grid_convergence_index(h, [1.0, 1.2, 1.1]) is None
    assert grid_convergence_index(h, 5.0 + 0.8 * h ** 0.3) is None


def test_summarise_reports_the_two_finest_meshes():
    h = [0.02, 0.01, 0.005]
    rows = [dict(h_contact_m=x, peak_hz=100 + x, peak_amplitude_m=1e-3 * (1 + x ** 2), energy_J=1e-4 * (1 + x),
                 max_wear_m=1e-6 * (1 + 10 * x), wear_volume_m3=1e-11 * (1 + x ** 1.5)) for x in h]
    W = np.array([[0.0, 1.0], [0.0, 2.0], [0.0, 2.1]])
    s = summarise(rows, W)
    assert s["observed_order"]["wear_volume_m3"] == pytest.approx(1.5, rel=1e-9)
    assert s["wear_volume_change_last"] == pytest.approx(abs(h[1] ** 1.5 - h[2] ** 1.5) / (1 + h[2] ** 1.5))
    assert s["peak_change_last"] == pytest.approx(abs(h[1] ** 2 - h[2] ** 2) / (1 + h[2] ** 2))
    assert s["observed_order"]["peak_amplitude_m"] == pytest.approx(2.0, rel=1e-9)
    assert s["observed_order"]["energy_J"] == pytest.approx(1.0, rel=1e-9)
    assert s["gci"]["wear_volume_m3"] == pytest.approx(1.25 * h[2] ** 1.5 / (1 + h[2] ** 1.5), rel=1e-9)
    mw = s["spread"]["max_wear_m"]                                   # 1e-6 × (1.2, 1.1, 1.05)
    assert (mw["median"], mw["min"], mw["max"], mw["meshes"]) == pytest.approx((1.1e-6, 1.05e-6, 1.2e-6, 3))
    assert mw["range_rel"] == pytest.approx(0.15 / 1.1)
    assert s["spread"]["energy_new_J"] is None                      # no wear energies in these rows
    assert s["profile_change_last"] == pytest.approx(0.1 / 2.1)
    for r, e in zip(rows, (2.0e-4, 2.1e-4, 2.04e-4)):
        r["energy_new_J"] = e
    en = summarise(rows, W)["spread"]["energy_new_J"]
    assert (en["median"], en["range_rel"]) == pytest.approx((2.04e-4, 0.1e-4 / 2.04e-4))


def test_wear_changes_are_between_the_finest_meshes_that_have_it():
    """contact_convergence.wear_max_pairs: the wear stops short of the finest mesh; its
    changes and order come from the meshes that have it, the peak's from all."""
    h = [0.04, 0.02, 0.01, 0.005]
    rows = [dict(h_contact_m=x, pairs=int(1 / x), peak_hz=100.0, peak_amplitude_m=1e-3 * (1 + x ** 2),
                 energy_J=1e-4, max_wear_m=1e-6 * (1 + x) if x > 0.005 else None,
                 wear_volume_m3=1e-11 * (1 + x) if x > 0.005 else None) for x in h]
    s = summarise(rows, np.array([[1.0], [2.0], [2.1]]))
    assert s["max_wear_change_last"] == pytest.approx(0.01 / 1.01)
    assert s["wear_pairs_last"] == [50, 100]
    assert s["observed_order"]["max_wear_m"] == pytest.approx(1.0, rel=1e-9)
    assert s["peak_change_last"] == pytest.approx(abs(h[2] ** 2 - h[3] ** 2) / (1 + h[3] ** 2))
    assert summarise(rows[-2:], None)["max_wear_change_last"] is None


@pytest.mark.slow  # 1.5–5 s on a cold 2-core clone: make test-slow keeps make test within 3 min
def test_figures_with_the_wear_on_the_coarser_meshes_only(tmp_path):
    from workflow.report.convergence import plot

    pts, pf = _flank_grid(5, 3)
    rows = [dict(h_contact_m=x, pairs=n, peak_hz=100.0 + x, peak_amplitude_m=1e-3 * (1 + x), energy_J=1e-4 * (1 + x),
                 max_wear_m=None if n == 130 else 1e-6 * (1 + x)) for x, n in ((0.02, 16), (0.01, 42), (0.005, 130))]
    W = np.vstack([1e-6 * (1 + pts[:, 0]), 1.1e-6 * (1 + pts[:, 0])])
    files = plot(tmp_path, rows, pts, pf, W)
    assert sorted(files) == ["convergence.png", "profiles.png"]
    assert all((tmp_path / f).stat().st_size > 0 for f in files)


def test_unconverged_lines_name_the_mesh_and_the_key():
    """A wear march that stopped short of its steady state, or peak-bracket points that did
    not converge, are listed (the pipeline's exit status 3) with the key to raise."""
    rows = [dict(pairs=16, grid_converged=9, grid_points=9, wear_steady=True),
            dict(pairs=192, grid_converged=8, grid_points=9, wear_steady=False),
            dict(pairs=42, grid_converged=9, grid_points=9, wear_steady=None)]      # no wear study
    lines = cc.unconverged(rows)
    assert len(lines) == 2 and lines[0].startswith("192 pairs: 1/9 ") and "hb.max_iterations" in lines[0]
    assert "pseudotime.max_steps" in lines[1] and cc.unconverged(rows[:1]) == []


def _flank_grid(na, nc):
    """Two planar 40 mm × 5 mm flanks inclined at ±45° (positions, flank ids)."""
    u, v = np.meshgrid(np.linspace(0, 0.04, na), np.linspace(0, 0.005, nc), indexing="ij")
    out, fl = [], []
    for f, s in ((0, -1.0), (1, 1.0)):
        out.append(np.column_stack([u.ravel(), s * (0.01 + v.ravel() / np.sqrt(2)), 0.2 + v.ravel() / np.sqrt(2)]))
        fl.append(np.full(u.size, f))
    return np.concatenate(out), np.concatenate(fl)


def test_profiles_of_a_linear_field_agree_on_the_common_points():
    """A wear field linear on the flank is carried exactly from any contact mesh to the common points."""
    coarse, fc = _flank_grid(4, 2)
    fine, ff = _flank_grid(13, 5)
    pts, pf = common_points(coarse, fc, (11, 4))
    assert len(pts) == 2 * 11 * 4
    field = lambda x, f: 1e-6 * (1 + 20 * x[:, 0] + 100 * (x[:, 2] - 0.2)) * (1 + f)  # noqa: E731
    a = profile_at(pts, pf, coarse, fc, field(coarse, fc))
    b = profile_at(pts, pf, fine, ff, field(fine, ff))
    np.testing.assert_allclose(a, field(pts, pf), rtol=1e-10)
    np.testing.assert_allclose(b, a, rtol=1e-10)


def test_section_checks_name_the_keys():
    from workflow.scene import resolve

    with pytest.raises(SceneError, match="contact_convergence.nodes_along"):
        resolve({"contact_convergence": {"nodes_along": [4, 7], "nodes_across": [2]}})
    with pytest.raises(SceneError, match="contact_convergence.time_samples"):
        resolve({"contact_convergence": {"harmonics": 3, "time_samples": 5}})
    with pytest.raises(SceneError, match="contact_convergence.time_samples .*wear_harmonics"):
        resolve({"contact_convergence": {"harmonics": 1, "wear_harmonics": 3, "time_samples": 5}})


def test_bad_layout_names_the_geometry_key():
    from workflow.errors import GeometryError
    from workflow.scene import resolve

    with pytest.raises((SceneError, GeometryError), match="contact_nodes"):
        resolve({"geometry": {"contact_nodes": "edges"}})


# ------------------------------------------------------------ on the sector

@pytest.fixture(scope="module")
def scene():
    from workflow.scene import load_scene

    return load_scene("contact-convergence", ["contact_convergence.nodes_along=[3, 4]",
                                              "contact_convergence.nodes_across=[2, 2]",
                                              "contact_convergence.points=5", "contact_convergence.wear=false",
                                              'geometry.contact_nodes="all"'])


@pytest.fixture(scope="module")
def quick_model(scene, tmp_path_factory):
    return cc.build_model(scene, 4, 2, tmp_path_factory.mktemp("cc"))


@pytest.mark.slow  # 4–9 s on the 2-core machine: make test-slow keeps make test within 3 min
def test_every_node_layout_closes_the_midside_interpenetration(scene, quick_model):
    """Under the centrifugal preload, contact at the vertices alone lets the flanks
    interpenetrate at midside nodes (by µm: the order of the wear depth); with
    every node in contact the midside gaps are ≥ 0 to round-off."""
    model, vertex, info = quick_model
    assert model.n_pairs == 2 * 7 * 3 and vertex.sum() == 2 * 4 * 2
    assert abs(model.area.sum() - info["flank_area_m2"]) <= 1e-12 * info["flank_area_m2"]
    s = cc._static_gaps(model, scene["contact"], vertex)
    assert s["pairs_in_contact"] > 0
    assert s["midside_gap_min_m"] >= -1e-15
    assert s["vertex_only_midside_gap_min_m"] < -1e-7
    assert 0.0 < s["vertex_load_share"] < 1.0


@pytest.mark.slow  # 1.5–5 s on a cold 2-core clone: make test-slow keeps make test within 3 min
def test_linear_layout_closes_the_midside_interpenetration_with_the_vertex_pairs(tmp_path_factory):
    """The scene's layout ("linear"): the vertex pairs only, P1 areas summing to the flank area, and
    under the preload the midside gaps — the means of their edges' vertex gaps — are ≥ 0 to round-off
    where the vertex-only layout interpenetrates by µm."""
    from workflow.scene import load_scene

    scene = load_scene("contact-convergence")
    assert scene["geometry"].contact_nodes == "linear"
    model, vertex, info = cc.build_model(scene, 4, 2, tmp_path_factory.mktemp("lin"))
    assert model.n_pairs == 2 * 4 * 2 and vertex.all()
    assert abs(model.area.sum() - info["flank_area_m2"]) <= 1e-12 * info["flank_area_m2"]
    assert len(model.info["tie_pairs"]) == 2 * (7 * 3 - 4 * 2)      # every midside node of both flanks
    s = cc._static_gaps(model, scene["contact"], vertex)
    assert s["pairs_in_contact"] > 0
    assert s["midside_gap_min_m"] >= -1e-15
    assert s["vertex_only_midside_gap_min_m"] is None
    # Under the preload the root rocks onto one long edge of each flank (docs/contact-layout.md):
    # on this 4 × 2 grid each flank bears on one of its two rows (the other lifts off), so half
    # of each flank's tributary area is open, and some gap is open.
    for f in s["flanks"]:
        assert f["open_share"] == pytest.approx(0.5, abs=1e-12)
        assert f["max_lift_off_m"] > 0 and f["max_pressure_pa"] > 0 and f["normal_load_n"] > 0


@pytest.mark.slow
def test_stage_writes_table_and_figures(scene, tmp_path):
    log = SimpleNamespace(info=lambda m: None, note=lambda m: None, progress=lambda it, total=None, label="": it)
    s = cc.run(scene, {}, tmp_path, log)
    json.dumps(s)
    assert [r["pairs"] for r in s["rows"]] == [2 * 5 * 3, 2 * 7 * 3]
    for r in s["table"]:
        assert r["peak_amplitude_m"] > 0 and r["energy_J"] > 0
        assert r["midside_gap_min_m"] >= -1e-15 and r["area_sum_rel_err"] < 1e-12
        # Friction softens the tied interface: the peak sits at or below the tied resonance.
        assert 0.9 * r["tied_hz"] < r["peak_hz"] <= r["tied_hz"] * (1 + 1e-3)
    assert s["peak_change_last"] is not None
    assert s["worst_midside_gap_min_m"] >= -1e-15 > s["worst_vertex_only_midside_gap_min_m"]
    assert all(r["grid_converged"] == r["grid_points"] == 5 for r in s["table"]) and s["unconverged"] == []
    for f in s["figures"] + [s["csv"]]:
        assert (tmp_path / f).is_file()


def test_a_mesh_of_an_interrupted_study_is_kept_and_read_back(tmp_path, monkeypatch):
    """Each contact mesh's row and worn profile are kept as the study goes (workflow.progress): a
    run after an interruption reads a finished mesh back instead of meshing and wearing it again,
    with the same row and arrays (NumPy scalars stored as numbers)."""
    from workflow.progress import Progress

    calls = []

    def fake_level(scene, na, nc, work, log):
        calls.append((na, nc))
        p = na * nc
        model = SimpleNamespace(position=np.arange(3.0 * p).reshape(p, 3) / 7, flank=np.arange(p) % 2)
        row = {"pairs": np.int64(p), "max_wear_m": np.float64(1.25e-6), "wear_steady": True, "peak_at_band_edge": None}
        return (row, {"model": model, "W": np.linspace(0, 1e-6, p) / 3, "flank_area_m2": 2.5e-4})

    monkeypatch.setattr(cc, "run_level", fake_level)

    class Log:
        def info(self, msg):
            pass

    first = cc.kept_level(None, 4, 2, tmp_path, Log(), Progress(tmp_path / "p", "k"))
    again = cc.kept_level(None, 4, 2, tmp_path, Log(), Progress(tmp_path / "p", "k"))
    assert calls == [(4, 2)]                                   # the second read it back
    assert again[0] == {k: (v.item() if isinstance(v, np.generic) else v) for k, v in first[0].items()}
    for key in ("position", "flank"):
        assert np.array_equal(getattr(again[1]["model"], key), getattr(first[1]["model"], key))
    assert np.array_equal(again[1]["W"], first[1]["W"]) and again[1]["flank_area_m2"] == 2.5e-4
    cc.kept_level(None, 4, 2, tmp_path, Log(), None)        # outside a pipeline run: computed
    assert calls == [(4, 2), (4, 2)]


def test_each_flanks_worn_volume_changes_on_its_own():
    """The flanks can trade wear between meshes: the total holds while each moves. changes_last
    gives each flank's change and the larger of the two."""
    rows = [dict(h_contact_m=x, pairs=int(1 / x), peak_hz=100.0, peak_amplitude_m=1e-3, energy_J=1e-4,
                 max_wear_m=1e-6, wear_volume_m3=3e-10, worn_volume_intrados_m3=a, worn_volume_extrados_m3=3e-10 - a)
            for x, a in ((0.02, 2.0e-10), (0.01, 2.1e-10))]
    c = summarise(rows, None)["changes_last"]
    assert c["worn_volume"] == 0.0
    assert c["worn_volume_flanks"]["intrados"] == pytest.approx(0.1 / 2.1)
    assert c["worn_volume_flanks"]["extrados"] == pytest.approx(0.1 / 0.9)
    assert c["worn_volume_flanks"]["largest"] == pytest.approx(0.1 / 0.9)
    rows = [{k: v for k, v in r.items() if not k.startswith("worn_volume_")} for r in rows]
    assert summarise(rows, None)["changes_last"]["worn_volume_flanks"] is None


def test_a_meshs_row_carries_each_flanks_worn_volume():
    """The row's per-flank volumes are Σ W·A over each flank's pairs, and sum to the interface's."""
    from workflow.engine.wear.measures import wear_measures

    rng = np.random.default_rng(3)
    W, A = rng.uniform(0, 2e-6, 12), rng.uniform(1e-6, 3e-6, 12)
    flank, pos = np.repeat([0, 1], 6), rng.uniform(0, 0.02, (12, 3))
    worn = {"measures": wear_measures(W, pos, A, flank, 0.002), "energy_per_cycle_J": {"new": 1.0, "worn": 0.0}}
    row = cc._wear_measures(worn)
    assert row["worn_volume_intrados_m3"] == pytest.approx(W[:6] @ A[:6], rel=1e-14)
    assert row["worn_volume_extrados_m3"] == pytest.approx(W[6:] @ A[6:], rel=1e-14)
    assert cc._wear_measures(None)["worn_volume_intrados_m3"] is None

