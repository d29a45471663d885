"""The report's headline (peak, damping achieved, wear, status), its formatting,
the paper side by side and the self-contained 3D view — without a browser
(tests/workflow/test_report_browser.py opens the page in Chromium)."""
from __future__ import annotations

import base64
import os
import json
import re
import types

import numpy as np
import pytest

from workflow.report import format as fmt
from workflow.report import headline as hl
from workflow.report import paper, viewer3d


def sdof(f, fn, zeta, k=1.0e4, force=1.0):
    """|x| [m] of a single-DOF oscillator (stiffness k [N/m], damping ratio ζ) at f [Hz]."""
    r = np.asarray(f) / fn
    return force / k / np.sqrt((1 - r ** 2) ** 2 + (2 * zeta * r) ** 2)


@pytest.mark.parametrize("z2", [0.004, 0.02, 0.08])
def test_equivalent_damping_ratio_recovers_the_damping_of_a_linear_peak(z2):
    # The friction-damped peak replaced by the same mode with more damping:
    # ζ_eq from the peak amplitudes must give that damping back (module docstring).
    fn, z1 = 200.0, 0.002
    f = np.linspace(150.0, 250.0, 400_001)
    _, _, a_tied = hl.grid_peak(f, sdof(f, fn, z1))
    _, _, a_nl = hl.grid_peak(f, sdof(f, fn, z2))
    z_eq = hl.equivalent_damping_ratio(z1, a_nl / a_tied)
    # Exact peak 1/(2ζ√(1−ζ²)): the estimate is off by O(ζ²) only.
    assert z_eq == pytest.approx(z2, rel=z2 ** 2 + 1e-6)


def test_tied_damping_ratio_is_rayleigh_at_the_tied_frequency():
    w = 2 * np.pi * 212.0
    assert hl.tied_damping_ratio({"alpha": 3.0, "beta_total": 0.0}, 212.0) == pytest.approx(3.0 / (2 * w))
    assert hl.tied_damping_ratio({"alpha": 0.0, "beta_total": 3e-6}, 212.0) == pytest.approx(3e-6 * w / 2)
    assert hl.tied_damping_ratio(None, 212.0) is None and hl.equivalent_damping_ratio(None, 0.5) is None


def _hb_folder(tmp_path, converged, tied_at_mode=True):
    """frf.csv / linear.csv of an SDOF-like run: friction peak ζ = 0.01, tied ζ = 0.002."""
    f = np.linspace(190.0, 230.0, 15) if tied_at_mode else np.linspace(190.0, 230.0, 14)
    a = sdof(f, 209.0, 0.01)
    rows = ["method,Nh,nit,solver,frequency_hz,amplitude_m,iterations,seconds,converged,amplitude_max_m,role,reason"]
    rows += [f"hbm,3,64,newton,{fi!r},{ai!r},5,0.1,{int(c)},{ai!r},variant," for fi, ai, c in zip(f, a, converged)]
    (tmp_path / "frf.csv").write_text("\n".join(rows) + "\n")
    lin = ["frequency_hz,tied_m,sliding_m"] + [f"{fi!r},{ti!r},{si!r}" for fi, ti, si in
                                               zip(f, sdof(f, 210.0, 0.002), sdof(f, 203.0, 0.002))]
    (tmp_path / "linear.csv").write_text("\n".join(lin) + "\n")
    hb = {"runs": [{"method": "hbm", "harmonics": 3, "time_samples": 64, "error": None}], "reference": None,
          "tied_frequency_hz": 210.0, "tied_mode": 1, "eps_check": {"factor": 10.0, "max_rel_change": 2e-4},
          "nh_check": {"max_rel_change": 2e-4, "runs": [{"nh": 5, "rel_change": 2e-4}]}}
    return hb, f, a


def test_headline_peak_and_status_follow_convergence(tmp_path):
    damping = {"alpha": 0.0, "beta_total": 2 * 0.002 / (2 * np.pi * 210.0)}
    ok = np.ones(15, bool)
    hb, f, a = _hb_folder(tmp_path, ok)
    v, checks = hl.hb_headline(hb, tmp_path, damping)
    i = int(np.argmax(a))
    assert v["peak_hz"] == f[i] and v["peak_amplitude_m"] == a[i]
    assert v["tied_peak_hz"] == 210.0 and v["amplitude_ratio"] == pytest.approx(a[i] / sdof(210.0, 210.0, 0.002))
    assert v["tied_damping_ratio"] == pytest.approx(0.002)
    assert hl.worst(checks) == "green"
    # A point next to the peak not converged: red (the peak may be missed); elsewhere: amber.
    for bad, status in ((i + 1, "red"), (0 if i > 2 else 14, "amber")):
        conv = ok.copy()
        conv[bad] = False
        hb, _, _ = _hb_folder(tmp_path, conv)
        assert hl.worst(hl.hb_headline(hb, tmp_path, damping)[1]) == status
    # Nh check over tolerance: amber with its reason; the ε sensitivity alone does not make amber
    # (at a finite Nh the rigid limit is not the answer): it is reported beside the peak.
    hb, _, _ = _hb_folder(tmp_path, ok)
    hb["eps_check"]["max_rel_change"] = 5e-3
    v, checks = hl.hb_headline(hb, tmp_path, damping)
    assert hl.worst(checks) == "green" and v["eps_sensitivity"]["rel_change"] == 5e-3
    hb["nh_check"]["max_rel_change"] = 5e-3
    c = [c for c in hl.hb_headline(hb, tmp_path, damping)[1] if c.name == "Nh check"][0]
    assert c.status == "amber" and "5.00e-03" in c.reason and "Nh = 5" in c.reason


def test_a_sliding_curve_rising_to_the_band_edge_has_no_peak(tmp_path):
    """The sliding (μ = 0) curve's largest value at an end of the band is no resonance peak: the
    headline reports none there (it reported the band's first frequency), and its peak inside."""
    damping = {"alpha": 0.0, "beta_total": 2 * 0.002 / (2 * np.pi * 210.0)}
    hb, f, _ = _hb_folder(tmp_path, np.ones(15, bool))
    v, _ = hl.hb_headline(hb, tmp_path, damping)
    assert v["sliding_peak_hz"] == f[np.argmin(abs(f - 203.0))]
    lin = ["frequency_hz,tied_m,sliding_m"] + [f"{fi!r},{ti!r},{si!r}" for fi, ti, si in
                                               zip(f, sdof(f, 210.0, 0.002), sdof(f, 185.0, 0.002))]
    (tmp_path / "linear.csv").write_text("\n".join(lin) + "\n")
    v, _ = hl.hb_headline(hb, tmp_path, damping)
    assert v["sliding_peak_hz"] is None and v["sliding_peak_amplitude_m"] is None
    assert v["tied_peak_hz"] == 210.0
    # the stuck reference's peak, refined by the engine, and the ratio to it
    assert v["stuck_peak_hz"] is None and v["amplitude_ratio_stuck"] is None
    hb["stuck_peak"] = {"hz": 209.5, "amplitude_m": 2 * v["peak_amplitude_m"], "grid_hz": 209.0}
    v, _ = hl.hb_headline(hb, tmp_path, damping)
    assert v["stuck_peak_hz"] == 209.5 and v["amplitude_ratio_stuck"] == pytest.approx(0.5)


def test_tied_peak_missed_by_the_grid_is_amber(tmp_path):
    # An even number of points around the tied mode leaves no point at it.
    damping = {"alpha": 0.0, "beta_total": 2 * 0.002 / (2 * np.pi * 210.0)}
    hb, _, _ = _hb_folder(tmp_path, np.ones(14, bool), tied_at_mode=False)
    v, checks = hl.hb_headline(hb, tmp_path, damping)
    c = [c for c in checks if c.name == "tied peak resolved"][0]
    assert c.status == "amber" and "under-read" in c.reason
    # … and the tied peak is read off the mode through the nearest point: the SDOF's exact peak.
    exact = 1.0 / 1.0e4 / (2 * 0.002 * np.sqrt(1 - 0.002 ** 2))
    assert v["tied_peak_hz"] == 210.0 and v["tied_peak_amplitude_m"] == pytest.approx(exact, rel=1e-9)


def test_headline_of_a_whole_summary(tmp_path):
    hb, f, a = _hb_folder(tmp_path, np.ones(15, bool))
    (tmp_path / "wear").mkdir()
    (tmp_path / "wear" / "wear.csv").write_text(
        "pair,flank,x_m,y_m,z_m,W_pseudo-time_m\n0,intrados,0,-0.004,0.23,1e-6\n1,extrados,0,0.004,0.23,3e-6\n")
    summary = {"hb": hb, "assembly": {"damping": {"alpha": 0.0, "beta_total": 3e-6}},
               "wear": {"methods": {"pseudo-time": {"steady": True, "reason": "steady"}}, "unconverged": [],
                        "warnings": ["something odd"], "eps_check": {"factor": 10, "max_rel_change": 0.0}},
               "remap": {"wear_column": "pseudo-time", "frf_peak_hz": {"new": 209.0, "worn": 209.4},
                         "frf_converged": {"new": 9, "worn": 9}, "frf_points": 9, "freq_shift_hz": [0.1, 0.2]},
               "timings": {"hb": 2.5, "wear": 1.5}, "unconverged": []}
    h = hl.headline(summary, {"frf": tmp_path, "wear": tmp_path / "wear"})
    json.dumps(h)
    assert set(h) >= {"peak_hz", "peak_amplitude_m", "tied_peak_amplitude_m", "amplitude_ratio",
                      "equivalent_damping_ratio", "max_wear_m", "worn_frequency_shift_hz", "status", "warnings"}
    assert h["max_wear_m"] == 3e-6 and h["max_wear_where"] == "pair 1, extrados flank"
    assert h["worn_frequency_shift_hz"] == pytest.approx(0.4) and h["run_seconds"] == 4.0
    assert "something odd" in h["warnings"]
    assert h["status"] == "green"  # stage warnings are listed; the status comes from the checks
    mesh = [c for c in h["checks"] if (c["item"], c["name"]) == ("wear", "contact mesh")]
    assert [c["status"] for c in mesh] == ["none"] and "contact-convergence" in mesh[0]["reason"]
    summary["wear"]["methods"]["pseudo-time"]["steady"] = False
    assert hl.headline(summary, {"frf": tmp_path, "wear": tmp_path / "wear"})["status"] == "red"


def test_a_wear_only_scene_says_what_it_did_not_compute(tmp_path):
    """paper-wear has no FRF and no worn model: the cards say so (not a row of dashes), the §5.2 side by side
    names the reference march and its times, and the status stands on the wear checks alone."""
    (tmp_path / "wear").mkdir()
    (tmp_path / "wear" / "wear.csv").write_text("pair,flank,W_implicit_m,W_pseudo-time_m\n0,intrados,2e-6,2.01e-6\n")
    wear = {"methods": {"implicit": {"steady": True, "reason": "steady", "seconds": 500.0},
                        "pseudo-time": {"steady": True, "reason": "steady", "seconds": 50.0}},
            "profile_max_rel_diff": 0.005, "cpu_ratio_pseudo_over_reference": 0.1}
    h = hl.headline({"wear": wear, "timings": {"wear": 550.0}}, {"wear": tmp_path / "wear"})
    assert h["peak_hz"] is None and h["max_wear_m"] == 2e-6 and h["status"] == "green"
    worn = [c for c in h["checks"] if c["item"] == "worn"]
    assert [c["status"] for c in worn] == ["none"] and "wear_map" in worn[0]["reason"]
    from workflow.report import html as html_page
    from workflow.report import markdown as md_page

    ratio = paper.cpu_ratio_52(wear)
    assert ratio["reference"] == "implicit" and (ratio["pseudo_seconds"], ratio["reference_seconds"]) == (50.0, 500.0)
    args = ("t", h, (None, None), ([], ratio), [], {}, [], {})
    page, md = html_page.page(*args), md_page.page(*args)
    assert "no FRF in this run" in page and "no FRF in this run" in md and "data-key='tied_peak_amplitude_m'" in page
    assert "pseudo-time / implicit march [–]" in page and "| time ratio pseudo-time / implicit march [–] | 0.1 | 0.29 |" in md
    assert "50, 500" in page and "| wear profiles apart [% of max W] | 0.5 |" in md


def test_formatting_puts_units_where_engineers_read_them():
    assert fmt.si(6.37356e-4, "m") == "637 µm" and fmt.si(2.2932e-6, "m") == "2.29 µm"
    assert fmt.si(None, "m") == "—" and fmt.si(0.0, "m") == "0 m"
    assert fmt.header("frequency_hz") == "frequency [Hz]"
    assert fmt.header("W_pseudo-time_m") == "W pseudo-time [m]"
    assert fmt.header("omega_rad_s") == "omega [rad/s]" and fmt.header("seconds") == "time [s]"
    assert fmt.signed_hz(-0.1234) == "-0.123 Hz"


def test_table1_side_by_side_pairs_our_cells_with_the_papers():
    rows = [{"method": "hbm", "Nh": "1", "nit": "105", "nit_label": "105", "normalised": "1"},
            {"method": "hdhb", "Nh": "17", "nit": "35", "nit_label": "2Nh+1", "normalised": "30.8"},
            {"method": "hbm", "Nh": "25", "nit": "128", "nit_label": "128", "normalised": "99"}]
    t = paper.table1_side_by_side(rows)
    assert [(r["Nh"], r["column"], r["ours"], r["paper"], r["paper_text"]) for r in t] == \
        [(1, "HBM nit=105", 1.0, 1.0, "1"), (17, "HDHB nit=2Nh+1", 30.8, 46.70, "46.70")]
    # A variant whose points gave up is marked: its CPU includes the solves that hit the iteration limit.
    runs = [{"method": "hdhb", "harmonics": 17, "time_samples": 35, "points": 50, "converged_points": 41}]
    t = paper.table1_side_by_side(rows, runs)
    assert [r["not_converged"] for r in t] == [0, 9]
    from workflow.report import html as html_page
    from workflow.report import markdown as md_page

    args = ("t", {"status": "none"}, (None, None), (t, None), [], {}, [], {})
    assert "<b>30.8</b><sup>*&nbsp;(9)</sup> / 46.70" in html_page.page(*args)  # the paper's digits, not a rounding
    assert "| 17 | HDHB nit=2Nh+1 | 30.8 * (9) | 46.70 |" in md_page.page(*args)
    assert paper.cpu_ratio_52({"cpu_ratio_pseudo_over_reference": 0.08})["paper"] == 0.29
    assert paper.caption("wear_profile")[1] == "Fig. 9"
    # The paper's FRF figures by their harmonic groups (Fig. 4: Nh = 1, 3; Fig. 5: Nh = 7, 17), else both.
    assert paper.caption("frf_nh1_3")[1] == "Fig. 4" and paper.caption("frf_nh7_17")[1] == "Fig. 5"
    assert paper.caption("frf_nh3")[1] == "Figs. 4–5" and paper.caption("frf_nh1_35")[1] == "Figs. 4–5"


def cube_tets():
    """The unit cube as 6 tetrahedra around the diagonal 0–6 (VTK linear tets)."""
    pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    tets = np.array([[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]])
    return pts, tets


def test_boundary_of_a_meshed_cube_is_closed_and_encloses_its_volume():
    pts, tets = cube_tets()
    cells = np.hstack([np.full((len(tets), 1), 4), tets]).ravel()
    corners = viewer3d.tet_corners(cells, np.full(len(tets), 10))
    tri = viewer3d.boundary_triangles(corners)
    assert len(tri) == 12  # 6 faces × 2 triangles; interior faces cancel
    edges = np.sort(np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    assert (np.unique(edges, axis=0, return_counts=True)[1] == 2).all()  # closed, manifold
    # Divergence theorem: |Σ (a·(b×c))/6| over the surface = the cube's volume.
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    assert abs(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6) == pytest.approx(1.0)
    from workflow.errors import GeometryError

    with pytest.raises(GeometryError, match="not tetrahedra"):
        viewer3d.tet_corners(np.array([8, *range(8)]), np.array([12]))


def test_viewer_page_is_self_contained_and_carries_the_wear(tmp_path):
    pts, tets = cube_tets()
    pts = pts * 0.01  # m
    cells = np.hstack([np.full((len(tets), 1), 4), tets]).ravel()
    body = np.array([1, 1, 1, 2, 2, 2])
    flank = types.SimpleNamespace(points=pts[[0, 1, 2, 3]], triangles=np.array([[0, 1, 2], [0, 2, 3]]),
                                  wear=np.array([0.0, 1e-6, 2e-6, 0.5e-6]), normal=np.array([0.0, 0.0, 1.0]),
                                  body="blade")
    path = viewer3d.write_viewer(tmp_path / "v.html", pts, cells, np.full(6, 10), body, [flank], "t", "note")
    page = path.read_text()
    assert "http://" not in page and "https://" not in page and "<script src" not in page
    data = json.loads(re.search(r"const DATA = (\{.*?\});", page).group(1))
    tri = np.frombuffer(base64.b64decode(data["triangles"]), np.uint32).reshape(-1, 3)
    col = np.frombuffer(base64.b64decode(data["colours"]), np.uint8).reshape(-1, 3)
    part = np.frombuffer(base64.b64decode(data["part"]), np.uint8)
    pos = np.frombuffer(base64.b64decode(data["positions"]), np.float32).reshape(-1, 3)
    assert len(tri) == data["n_triangles"] and tri.max() < len(pos) == len(col) == len(part)
    # The flank's four vertices come last, flagged blade + flank, coloured on viridis 0…max.
    assert (part[-4:] == 3).all()
    np.testing.assert_array_equal(col[-4:], viewer3d.viridis_rgb(flank.wear, 2e-6))
    assert ">2<" in page  # colour bar's top label: max wear 2 µm
    assert float(np.ptp(pos[:, 0])) == pytest.approx(10.0, rel=1e-6)  # mm
    # read_viewer decodes what the page carries (the pyvista comparison exports the same data).
    d = viewer3d.read_viewer(path)
    np.testing.assert_array_equal(d["triangles"], tri)
    np.testing.assert_array_equal(d["colours"], col)
    np.testing.assert_array_equal(d["positions"], pos)
    assert d["wear_max_um"] == 2.0 and d["view_side"] in (-1.0, 1.0)
    from workflow.errors import GeometryError

    with pytest.raises(GeometryError, match="not a 3D view"):
        viewer3d.read_viewer(tmp_path / "plain.html") if (tmp_path / "plain.html").write_text("<p>x</p>") else None


PAPER = os.environ.get("BLADEWEAR_PAPER", "/work/shared/reference/salles-2012-dual-time-stepping-hb-fretting-wear.md")


@pytest.mark.skipif(not os.path.isfile(PAPER), reason="the paper's text is not on this machine (BLADEWEAR_PAPER)")
def test_paper_numbers_quoted_by_the_report_are_the_papers():
    """Table 1 and the §5.2 CPU share in workflow/report/paper.py, read again from the paper's text."""
    text = open(PAPER, encoding="utf-8").read()
    table = {}
    for line in text[text.index("$nit = 105$"):text.index("Table 1:")].splitlines():
        cells = line.split()
        if len(cells) == 6 and cells[0].isdigit():
            table[int(cells[0])] = tuple(cells[1:])
    assert table == paper.TABLE1_TEXT  # digit for digit, as the report prints them
    assert "pseudo time method requires 29%" in text and paper.CPU_RATIO_52 == 0.29
    for fig, words in (("Fig. 4", "Nh = 1, 3"), ("Fig. 5", "Nh = 7, 17")):
        assert re.search(re.escape(fig) + r":[^\n]*" + r"\$Nh = " + words.split("= ")[1], text), fig
    for stem in ("frf_nit_aliasing", "iterations", "tangential", "wear_profile", "tip_cycle", "max_wear", "harmonic1"):
        fig = paper.caption(stem)[1]
        assert re.search(rf"\n{re.escape(fig)}:", text), (stem, fig)


def test_viewer_benchmark_counts_only_network_requests_and_real_errors():
    """The offline check of the 3D views (workflow/bench/viewer3d_compare.py): local URLs are not network
    requests; software-GL performance notes are not errors; a failed fetch and an exception are."""
    from workflow.bench import viewer3d_compare as vc

    ev = [{"method": "Network.requestWillBeSent", "params": {"request": {"url": u}}}
          for u in ("file:///r/wear_3d.html", "data:image/png;base64,AA", "https://kitware.github.io/x.png")]
    ev += [{"method": "Log.entryAdded", "params": {"entry": {"level": "error", "text": t}}}
           for t in ("Failed to load resource: net::ERR_INTERNET_DISCONNECTED", "GL Driver Message (OpenGL, x)")]
    ev.append({"method": "Runtime.exceptionThrown", "params": {"exceptionDetails": {"text": "Uncaught",
                                                                                     "exception": {"description": "E"}}}})
    assert vc._requests(ev) == ["https://kitware.github.io/x.png"]
    assert vc._errors(ev) == ["Failed to load resource: net::ERR_INTERNET_DISCONNECTED", "E"]
    loads = [{"first_frame_ms": f, "first_draw_ms": f, "webgl_context_ms": [1.0, g], "requests": [],
              "errors": [], "drawn_fraction": 0.3} for f, g in ((700.0, 650.0), (900.0, 800.0), (None, 700.0))]
    row = vc.summarise(__file__, loads)
    assert row["first_frame_ms_median"] == 800.0 and row["first_frame_ms_range"] == [700.0, 900.0]
    assert row["page_work_ms_median"] == 75.0  # median of 50 and 100 ms: the page's own work after its context


def test_unconverged_variants_are_listed_once_each_and_make_a_check():
    """summary.json's top-level ``unconverged`` is {stage: [lines]}: the warnings list the lines (not the
    stage name), and variants beside a reference with points that gave up make an amber check."""
    runs = [{"method": "hbm", "harmonics": 1, "time_samples": 105, "converged_points": 50, "points": 50},
            {"method": "tcm", "harmonics": 7, "time_samples": 105, "converged_points": 43, "points": 50},
            {"method": "tcm", "harmonics": 3, "time_samples": 105, "converged_points": 47, "points": 50}]
    line = "TCM-7 nit=105 (newton-powell): 7/50 frequencies did not converge (…)"
    summary = {"unconverged": {"hb": [line]}, "hb": {"unconverged": [line], "runs": runs}}
    assert hl.stage_lines(summary, "unconverged") == [line]
    c = hl.variants_check(runs)[0]
    assert c.status == "amber" and "2 of 3 variants" in c.reason and "10 points" in c.reason and "TCM-7" in c.reason
    assert hl.variants_check(runs[:1])[0].status == "green" and hl.variants_check([]) == []
