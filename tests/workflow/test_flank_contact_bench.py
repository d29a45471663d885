"""The flank-contact bench (workflow.bench.flank_contact) end to end on the coarsest grid: how the
flanks bear under the preload and the held-amplitude worn state, kept per grid."""
from __future__ import annotations

import csv

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
    assert (models / "model-4x2-g0.5.npz").exists()      # the model is kept under its grading
