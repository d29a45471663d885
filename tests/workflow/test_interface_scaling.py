"""The interface-scaling benchmark (issue #16): pair grids, memory guard, fits, scene keys."""
from __future__ import annotations

import math

import pytest

from workflow.costs import interface_scaling as bench
from workflow.errors import SceneError
from workflow.params import flank_grid


@pytest.mark.parametrize("pairs, expected", [(16, (4, 2)), (32, (4, 4)), (64, (8, 4)), (128, (8, 8)),
                                             (256, (16, 8)), (512, (16, 16)), (8, (2, 2)), (24, (4, 3))])
def test_grid_gives_the_pair_count(pairs, expected):
    along, across = flank_grid(pairs)
    assert (along, across) == expected
    assert 2 * along * across == pairs and along >= across


@pytest.mark.parametrize("bad", [0, 3, 6, 14, 15, 2.5])
def test_grid_rejects_odd_counts(bad):
    with pytest.raises(SceneError, match="interface_scaling.pairs"):
        flank_grid(bad)


def _rows(b_time=1.5, b_mem=1.0):
    return [dict(pairs=p, method="hbm", solver="newton", s_per_point=0.01 * p ** b_time,
                 peak_gb=0.002 * p ** b_mem) for p in (16, 64, 128, 256)]


def test_fits_recover_power_laws():
    fit = bench.fits(_rows(1.5, 1.0), min_pairs=64)
    t, m = fit["s_per_point:hbm:newton"], fit["peak_gb:hbm:newton"]
    assert t["b"] == pytest.approx(1.5, abs=1e-9) and t["points"] == 3
    assert m["b"] == pytest.approx(1.0, abs=1e-9) and m["a"] == pytest.approx(0.002, rel=1e-9)


def test_memory_guard_extrapolates_the_last_two_counts():
    rows = _rows(1.5, 2.0)
    gb = bench.predicted_gb(rows, 512)
    assert gb == pytest.approx(0.002 * 512 ** 2, rel=1e-9)
    assert bench.predicted_gb(rows[:1], 512) is None


def test_study_stops_before_a_case_over_the_memory_limit(tmp_path):
    made = []

    def reduced_for(p):
        made.append(p)
        raise AssertionError("must not be reached")

    import workflow.costs.interface_scaling as mod

    rows_in = [dict(pairs=16, peak_gb=1.0), dict(pairs=32, peak_gb=2.0)]
    logs = []
    # two cases measured (1 → 2 GB for 16 → 32 pairs): 64 pairs extrapolate to 4 GB > 3 GB
    orig = mod._launch
    try:
        mod._launch = lambda path, m, nh, nit, s, pts, out, mu=0.5, maxiter=100: rows_in.pop(0) | dict(
            method=m, solver=s, linear_solver="dense", unknowns=0, s_per_point=1.0, converged=1, points=1,
            iterations=1, seconds=60.0)
        rows = bench.study(lambda p: tmp_path, [16, 32, 64], ["hbm"], ["newton"], 7, 64, 1, tmp_path,
                           max_gb=3.0, log=logs.append)
    finally:
        mod._launch = orig
    assert [r["pairs"] for r in rows] == [16, 32]
    assert "64 pairs would need ~4.0 GB > 3 GB: stop" in logs[-1]
    assert not made


def test_a_short_sweep_is_repeated_and_its_fastest_run_kept(tmp_path, monkeypatch):
    """Sweeps under REPEAT_BELOW_S run REPEATS times (a noisy sub-second sweep moved the fitted growth
    by ±0.05); a long one runs once."""
    import workflow.costs.interface_scaling as mod

    times = {16: [0.9, 0.7, 0.8], 512: [25.0]}
    calls = []

    def launch(path, m, nh, nit, s, pts, out, mu=0.5, maxiter=100):
        p = int(path.name)
        t = times[p][sum(1 for c in calls if c == p)]
        calls.append(p)
        return dict(pairs=p, peak_gb=1.0, method=m, solver=s, linear_solver="structured", unknowns=0, points=9,
                    converged=9, iterations=40, seconds=9 * t, s_per_point=t)

    monkeypatch.setattr(mod, "_launch", launch)
    rows = bench.study(lambda p: tmp_path / str(p), [16, 512], ["hbm"], ["newton"], 7, 64, 9, tmp_path,
                       log=lambda *_: None)
    assert calls == [16, 16, 16, 512]
    assert [(r["pairs"], r["s_per_point"], r["runs"]) for r in rows] == [(16, 0.7, 3), (512, 25.0, 1)]


def test_scene_section_checks():
    from workflow.scene import load_scene

    sc = load_scene("interface-scaling")
    cfg = sc["interface_scaling"]
    assert cfg.harmonics == 7 and list(cfg.pairs) == [16, 32, 64, 128, 256, 512]
    with pytest.raises(SceneError, match="interface_scaling.time_samples"):
        load_scene("interface-scaling", ["interface_scaling.time_samples=9"])
    with pytest.raises(SceneError, match="interface_scaling.pairs"):
        load_scene("interface-scaling", ["interface_scaling.pairs=[16, 33]"])
    with pytest.raises(SceneError, match="interface_scaling"):
        load_scene("interface-scaling", ["interface_scaling.methods=['xyz']"])


@pytest.mark.slow
def test_stage_end_to_end(tmp_path):
    """Two tiny cases through the pipeline: rows, files, physical sanity."""
    from workflow.pipeline import run_scene
    from workflow.scene import load_scene

    sc = load_scene("interface-scaling", ["interface_scaling.pairs=[8, 16]", "interface_scaling.methods=['hbm']",
                                          "interface_scaling.harmonics=1", "interface_scaling.time_samples=16",
                                          "interface_scaling.points=2"])
    summary = run_scene(sc, tmp_path / "run", cache=tmp_path / "cache", quiet=True)
    rows = summary["interface_scaling"]["scaling"]["rows"]
    assert [r["pairs"] for r in rows] == [8, 16]
    for r in rows:
        assert r["unknowns"] == 3 * 3 * r["pairs"] and r["linear_solver"] == "dense"
        assert 0 < r["converged"] <= r["points"] == 2
        assert math.isfinite(r["s_per_point"]) and r["peak_gb"] > 0
    for f in ("interface_scaling.csv", "interface_scaling.json", "interface_scaling.png"):
        assert (tmp_path / "run" / "interface_scaling" / f).is_file()


@pytest.mark.slow
def test_structured_equals_dense_on_the_quick_sector(tmp_path, monkeypatch):
    """The quick sector (16 pairs), HBM Nh = 3: the sweep's points with the
    structured Newton equal the dense ones within the solver tolerance."""
    import numpy as np

    from workflow.engine.model import ReducedModel
    from workflow.engine import FRFOptions, Variant, cascade, contact_law, frf
    from workflow.scene import load_scene

    path = bench.reduced_model(load_scene("interface-scaling"), 16, tmp_path, tmp_path / "cache", log=lambda s: None)
    model = ReducedModel.load(path)
    law = contact_law(model, mu=0.5)
    opt = FRFOptions(solver="newton", eps_check_factor=0.0, reference=None)
    runs = {}
    for name, threshold in (("dense", 10 ** 9), ("structured", 0)):
        monkeypatch.setattr(cascade, "STRUCTURED_MIN_UNKNOWNS", threshold)
        runs[name] = frf(model, law, [Variant("hbm", 3, 32)], points=5, options=opt).runs[0]
    d, s = runs["dense"], runs["structured"]
    assert s.linear_solver == "structured" and d.linear_solver == "dense"
    both = d.converged & s.converged
    assert both.sum() >= 4
    for i in np.flatnonzero(both):
        # roots to ‖R‖ ≤ 1e-8‖F‖ each: the amplitudes agree far below the FRF's accuracy
        assert abs(s.amplitude[i] - d.amplitude[i]) <= 1e-5 * d.amplitude[i]


@pytest.mark.slow  # 4–9 s on the 2-core machine: make test-slow keeps make test within 3 min
def test_structured_split_accounts_for_the_linear_solves(tmp_path):
    """workflow.bench.structured_split on the 8-pair sector: the factorisations and GMRES
    iterations it counts are those of the sequence it records, their seconds lie
    within the sweep's, and the sweep is the worker's (structured solve forced)."""
    from workflow.bench import structured_split
    from workflow.scene import load_scene

    path = bench.reduced_model(load_scene("interface-scaling"), 8, tmp_path, tmp_path / "cache", log=lambda s: None)
    from workflow.engine import cascade

    threshold = cascade.STRUCTURED_MIN_UNKNOWNS
    row = structured_split.split(path, "hbm", nh=1, nit=16, points=2)
    assert cascade.STRUCTURED_MIN_UNKNOWNS == threshold      # forced for the sweep only
    seq = row["sequence"].split()
    assert row["linear_solver"] == "structured" and row["converged"] >= 1
    assert row["factorizations"] == seq.count("F") >= 1
    assert row["gmres_iterations"] == sum(int(s) for s in seq if s != "F")
    assert row["solves"] == len(seq) - seq.count("F")
    # every factorisation and GMRES solve runs inside the sweep's clock interval, and the sweep's
    # seconds leave out its grid's condensation (timed apart, inside the same interval): the parts
    # are bounded by the two together, up to the clock reads' own microseconds
    whole = row["seconds"] + row["condense_s_per_point"] * row["points"]
    assert 0 < row["factor_s"] + row["gmres_s"] <= whole + 1e-4
    assert row["s_per_iteration"] == pytest.approx(row["seconds"] / row["iterations"])
