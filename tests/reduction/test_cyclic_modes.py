"""ND folding, EO crossings and ZZENF (closed forms), and the cyclic_modes stage on the coarse N = 47 sector."""
from __future__ import annotations

import math

import numpy as np
import pytest

from workflow import params as P


class _Log:
    def info(self, msg):
        pass

    def warning(self, msg):
        pass

    def progress(self, iterable, total=None, label=""):
        return iterable


def test_fold_nd_and_the_nd_of_an_engine_order():
    from workflow.engine.condense import nodal_diameter_of_harmonic
    from reduction.cyclic_modes import fold_nd, nodal_diameters

    N = 47
    assert nodal_diameters(N) == list(range(24)) and nodal_diameters(8) == list(range(5))
    for eo in range(0, 3 * N):
        k = fold_nd(eo, N)
        assert 0 <= k <= N // 2
        # harmonic 1 of an EO wave lives on ND EO mod N, which has the spectrum of fold(EO)
        assert k in (nodal_diameter_of_harmonic(1, eo, N), N - nodal_diameter_of_harmonic(1, eo, N))
    assert [fold_nd(e, 8) for e in (0, 4, 5, 8, 9, 12, 13)] == [0, 4, 3, 0, 1, 4, 3]


def test_eo_crossings_of_straight_campbell_lines_are_exact():
    """f(Ω) = a + b·rpm: the crossing with f = EO·rpm/60 is at rpm = a / (EO/60 − b) (linear interpolation is exact)."""
    from reduction.cyclic_modes import eo_crossings

    N, nds, rpm = 12, [0, 1, 2, 3, 4, 5, 6], np.array([0.0, 3000.0, 6000.0, 9000.0])
    a, b = 100.0 + 10 * np.arange(len(nds)), 0.01
    F = (a[None, :] + b * rpm[:, None])[:, :, None]                  # (speeds, nds, 1 mode)
    cross = eo_crossings(rpm, F, nds, [2, 3, 10, 14], N)
    assert {c["eo"] for c in cross} == {2, 3, 10, 14}
    for c in cross:
        nd = min(c["eo"] % N, N - c["eo"] % N)
        assert c["nd"] == nd
        assert c["speed_rpm"] == pytest.approx(a[nd] / (c["eo"] / 60 - b), rel=1e-12)
        assert c["f_hz"] == pytest.approx(c["eo"] * c["speed_rpm"] / 60, rel=1e-12)
    assert not eo_crossings(rpm, F, nds, [1], N)   # EO 1 crosses ND 1 above 9000 rpm: a/(1/60 − b) = 16500


def test_zzenf_lists_the_modes_on_the_zigzag():
    from reduction.cyclic_modes import zzenf_orders, zzenf_resonances

    N, nds = 10, [0, 1, 2, 3, 4, 5]
    F = np.array([[99.0, 300.0]] * 6)               # two flat families
    res = zzenf_resonances(F, nds, None, N, speed_rpm=6000.0, band=0.02)   # f_EO = 100·EO Hz
    assert zzenf_orders(F, 6000.0) == [1, 2, 3]
    assert [(r["eo"], r["nd"], r["mode"]) for r in res] == [(1, 1, 1), (3, 3, 2)]
    assert res[0]["detuning"] == pytest.approx(-0.01)
    assert zzenf_resonances(F, nds, None, N, 0.0) == []


@pytest.fixture(scope="module")
def stage_run(tmp_path_factory):
    """geometry → assembly → cyclic_modes on the coarse 47-sector (3 NDs, 2 modes, Campbell at 0 and 6000 rpm)."""
    from geometry.params import SectorParams
    from workflow.stages import assembly, cyclic_modes, geometry, load

    assert load("cyclic_modes") is cyclic_modes
    tmp = tmp_path_factory.mktemp("cyclic_stage")
    scene = {"geometry": SectorParams(cyclic=True, h_blade=0.006, h_disk=0.010, h_airfoil=0.009),
             "material": P.Material(), "rotation": P.Rotation(speed_rpm=6000.0),
             "damping": P.Damping(modal_ratio=0.0), "excitation": P.Excitation(),
             "cyclic": P.Cyclic(modes_per_nd=2, nodal_diameters=[0, 1, 46, 23], campbell_speeds_rpm=[6000.0, 0.0],
                                engine_order=8, engine_order_lines=[1, 24])}
    geometry.run(scene, {}, tmp / "geometry", _Log())
    assembly.run(scene, {"mesh": tmp / "geometry"}, tmp / "assembly", _Log())
    s = cyclic_modes.run(scene, {"mesh": tmp / "geometry", "bundle": tmp / "assembly"}, tmp / "cm", _Log())
    return scene, s, tmp


@pytest.mark.slow  # the stage on a meshed 47-sector (~12 s): make test-slow
def test_stage_writes_the_nd_map_campbell_and_figures(stage_run):
    scene, s, tmp = stage_run
    assert s["n_sectors"] == 47 and s["nodal_diameters"] == [0, 1, 23]     # 46 folded onto 1
    assert len(s["rows"]) == 3 * 2 and all(r["f_hz"] > 0 for r in s["rows"])
    for f in ("nd_map.csv", "campbell.csv", "nd_map.png", "campbell.png", "zzenf.png"):
        assert (tmp / "cm" / f).is_file(), f
    assert s["campbell_speeds_rpm"] == [0.0, 6000.0]
    # Campbell at the bundle's speed re-assembles the bundle's K(Ω): the same frequencies as the ND map
    F = np.array(s["campbell_first_family_hz"])        # (speeds, nds)
    np.testing.assert_allclose(F[1], s["first_family_hz"], rtol=1e-9)
    # stress stiffening raises the first (flap) family with speed
    assert (F[1] > F[0] * 1.05).all()


@pytest.mark.slow  # the stage on a meshed 47-sector (~12 s): make test-slow
def test_stage_refuses_a_bundle_without_cyclic_faces(stage_run, tmp_path):
    import shutil

    from workflow.errors import BundleError
    from workflow.stages import cyclic_modes

    scene, _, tmp = stage_run
    shutil.copytree(tmp / "assembly" / "model", tmp_path / "model")
    (tmp_path / "model" / "cyclic.npz").unlink()
    with pytest.raises(BundleError, match="geometry.cyclic = true"):
        cyclic_modes.run(scene, {"mesh": tmp / "geometry", "bundle": tmp_path / "model"}, tmp_path / "o", _Log())


def test_nodal_diameters_beyond_n_are_a_scene_error():
    from workflow.errors import SceneError
    from workflow.stages.cyclic_modes import _nodal_diameters

    with pytest.raises(SceneError, match="cyclic.nodal_diameters contains 47"):
        _nodal_diameters(P.Cyclic(nodal_diameters=[1, 47]), 47)
    assert _nodal_diameters(P.Cyclic(), 8) == [0, 1, 2, 3, 4]


@pytest.mark.slow  # the stage on a meshed 47-sector (~12 s): make test-slow
def test_campbell_reassembly_at_the_bundle_speed_is_the_bundle_stiffness(stage_run):
    from reduction.bundle import read_bundle
    from reduction.cyclic_modes import stiffness_function

    scene, _, tmp = stage_run
    b = read_bundle(tmp / "assembly" / "model")
    K = stiffness_function(tmp / "geometry" / "sector.msh", scene["material"], scene["rotation"], b)(
        2 * math.pi * 6000.0 / 60)
    assert abs(K - b.K).max() <= 1e-10 * abs(b.K).max()
