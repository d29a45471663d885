"""Reduced vs full in the tied and free limits; the reduction stages end to end."""
import numpy as np
import pytest

import lattice
from reduction import validate as va
from reduction.reduce import reduce_with_basis


@pytest.fixture(scope="module")
def bundle():
    return lattice.lattice_bundle()


@pytest.fixture(scope="module")
def ref(bundle):
    return va.reference(bundle, n_check=8, frf_points=12)


def _all_modes(bundle):
    return bundle.free_dofs.size - reduce_with_basis(bundle, 2)[1].boundary.size


def test_full_free_modes_skip_the_six_rigid_body_modes(ref):
    assert ref.free_rigid == 6
    assert ref.free_hz[0] > 10.0


def test_limits_recover_the_full_frfs_exactly_with_all_modes(bundle, ref):
    """λ = 0 gives the free FRF, u_r = 0 the tied one (reduction exact with all modes)."""
    model, basis = reduce_with_basis(bundle, _all_modes(bundle))
    row = va.evaluate(model, ref, basis)
    for key in ("tied", "free"):
        assert row[key]["frf_max_rel_error"] < 1e-8
        assert row[key]["max_rel_freq_error"] < 1e-9
        assert row[key]["min_mac"] > 1 - 1e-9
    assert row["free"]["rigid_skipped"] == 6


def test_truncated_model_frf_close(bundle, ref):
    model, basis = reduce_with_basis(bundle, 40)
    row = va.evaluate(model, ref, basis)
    assert row["frf_max_rel_error"] < 1e-3
    assert row["tied"]["min_mac"] > 0.999


def test_frequencies_converge_from_above(bundle, ref):
    """Rayleigh–Ritz: reduced ≥ full, and more modes never make a frequency worse."""
    previous = {}
    for count in (5, 10, 20, 40):
        model, _ = reduce_with_basis(bundle, count)
        for key, f_ref in (("tied", ref.tied_hz), ("free", ref.free_hz)):
            f, _, _ = va.reduced_modes(model, key == "tied", ref.n_check)
            f = f[:f_ref.size]
            assert np.all(f >= f_ref * (1 - 1e-12))
            if key in previous:
                assert np.all(f <= previous[key] * (1 + 1e-12))
            previous[key] = f


def test_iterative_full_frf_matches_direct(bundle, ref):
    for tied, H in ((True, ref.frf_tied), (False, ref.frf_free)):
        stats = {}
        Hi = va.full_frf(bundle, ref.omegas, tied, ref.beta, method="iterative", stats=stats)
        assert va.frf_error(Hi, H) < 1e-8
        assert stats["subspace"] < bundle.n_dofs


class _Log:
    def __init__(self):
        self.lines = []

    def info(self, msg):
        self.lines.append(msg)

    def progress(self, it, total=None, label=""):
        return it


def test_stages_write_reduced_model_table_and_plot(tmp_path, bundle):
    from reduction.bundle import write_bundle
    from workflow.params import Reduction
    from workflow.stages import reduction as st_red
    from workflow.stages import reduction_check as st_chk

    write_bundle(bundle, tmp_path / "bundle" / "model")
    scene = {"reduction": Reduction(modes=20, check_modes=6, check_mode_counts=[5, 10], frf_points=8)}
    log = _Log()
    s = st_red.run(scene, {"bundle": tmp_path / "bundle"}, tmp_path / "red", log)
    assert s["modes"] == 20 and (tmp_path / "red" / "reduced.npz").is_file()
    c = st_chk.run(scene, {"bundle": tmp_path / "bundle", "reduced": tmp_path / "red"}, tmp_path / "chk", log)
    for f in ("convergence.csv", "convergence.png", "modes.csv", "frf.csv"):
        assert (tmp_path / "chk" / f).stat().st_size > 0
    assert c["modes"] == 20 and c["boundary_dofs"] == s["boundary_dofs"]
    assert 0 < c["tied"]["max_rel_freq_error"] < 0.05 and c["tied"]["min_mac"] > 0.99
    assert c["free"]["rigid_skipped"] == 6 and c["frf_max_rel_error"] < 0.01
    assert [r["modes"] for r in c["convergence"]] == [5, 10, 20]
    import json
    json.dumps(c)
